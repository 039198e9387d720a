"""URDF parsing pulls in no other file (no external entities, no DTD) and refuses non-finite origins."""

import pytest

from ancsh.data.urdf import load_urdf


def test_external_entities_are_not_expanded(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("0.25 0 0")
    path = tmp_path / "xxe.urdf"
    path.write_text(
        f'<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY leak SYSTEM "file://{secret}">]>\n'
        "<robot name='x'><link name='a'><visual><origin xyz='&leak;'/>"
        "<geometry><box size='1 1 1'/></geometry></visual></link></robot>"
    )
    try:
        model = load_urdf(path)
    except ValueError as exc:  # refusing the file outright is fine too
        assert "xxe.urdf" in str(exc)
        return
    # had the entity been expanded, the box would be shifted by 0.25 along x
    assert model.parts[0].vertices[:, 0].min() == pytest.approx(-0.5)


def test_nan_in_a_joint_origin_names_the_joint(tmp_path):
    path = tmp_path / "nan.urdf"
    path.write_text(
        "<robot name='n'><link name='a'><visual><geometry><box size='1 1 1'/></geometry></visual></link>"
        "<joint name='hinge' type='revolute'><origin xyz='0 nan 0'/><parent link='a'/><child link='b'/>"
        "<axis xyz='0 0 1'/><limit lower='0' upper='1'/></joint>"
        "<link name='b'><visual><geometry><box size='1 1 1'/></geometry></visual></link></robot>"
    )
    with pytest.raises(ValueError, match=r"nan\.urdf.*joint name='hinge'.*origin.*non-finite"):
        load_urdf(path)


@pytest.mark.parametrize("filename", ["{outside}", "../outside.obj", "file://{outside}", "package://x/../../outside.obj",
                                      "sub/../../outside.obj"])
def test_a_mesh_outside_the_objects_folder_is_refused_naming_the_link(tmp_path, filename):
    import trimesh

    outside = tmp_path / "outside.obj"
    trimesh.creation.box().export(outside)
    folder = tmp_path / "object"
    (folder / "sub").mkdir(parents=True)
    path = folder / "mobility.urdf"
    path.write_text(f"<robot name='r'><link name='lid'><visual><geometry><mesh filename='{filename.format(outside=outside)}'/>"
                    "</geometry></visual></link></robot>")
    with pytest.raises(ValueError, match=r"<link name='lid'>.*lies outside the object's folder"):
        load_urdf(path)


def test_a_mesh_inside_the_folder_still_loads_and_a_link_out_of_it_does_not(tmp_path):
    import trimesh

    folder = tmp_path / "object"
    (folder / "meshes").mkdir(parents=True)
    trimesh.creation.box().export(folder / "meshes" / "a.obj")
    (tmp_path / "elsewhere.obj").write_text((folder / "meshes" / "a.obj").read_text())
    (folder / "meshes" / "b.obj").symlink_to(tmp_path / "elsewhere.obj")
    for name, ok in (("meshes/a.obj", True), ("package://obj/meshes/a.obj", True), ("meshes/b.obj", False)):
        path = folder / "m.urdf"
        path.write_text(f"<robot name='r'><link name='a'><visual><geometry><mesh filename='{name}'/></geometry></visual>"
                        "</link></robot>")
        if ok:
            assert load_urdf(path).parts[0].mesh is not None
        else:
            with pytest.raises(ValueError, match="outside the object's folder"):
                load_urdf(path)


def test_a_catalog_entry_leaving_the_shared_folder_is_refused(tmp_path, monkeypatch):
    from ancsh.data.importer import ImportedObject

    monkeypatch.setenv("ANCSH_SHARED_DATA", str(tmp_path / "shared"))
    obj = ImportedObject(name="x", category="laptop", urdf="shared:../../etc/passwd", joint_types={}, moving_links=("a",),
                         zero=(0.0,), sign=(1,), flip_front=False, scale=1.0, split="test")
    with pytest.raises(ValueError, match="x: catalog urdf 'shared:../../etc/passwd' leaves the shared data folder"):
        obj.urdf_path
