"""URDF import into category conventions: known state 0, direction, restored and frozen joints,
rejections with reasons, overrides, catalogs and mixed datasets.

Synthetic URDF objects with known ground truth are written into a temporary folder, so these
tests need no shared data; the tests on the shared PartNet-Mobility objects skip without it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from ancsh.data.catalog import (
    Catalog,
    build_catalog,
    builtin_catalog_path,
    draw_preview_sheet,
    load_catalog,
    write_catalog,
)
from ancsh.data.conventions import convention, convention_violations, rest_diagonal
from ancsh.data.importer import ImportedObject, ImportRejected, assign_splits, import_object, load_overrides
from ancsh.data.paths import shared_data_dir
from ancsh.studies.catalog_reports import write_import_report

def test_state_zero_direction_and_scale_are_found_from_geometry(tmp_path, make_oven_urdf):
    urdf = make_oven_urdf(tmp_path / "oven_a")
    obj = import_object(urdf, "oven")
    conv = convention("oven")
    assert obj.zero[0] == pytest.approx(-make_oven_urdf.open_at_file_zero, abs=0.02)  # the closed door, not the file's 0
    assert obj.sign == (1,)
    assert obj.joint_types == {"knob_joint": "fixed"}  # the knob is frozen
    model = obj.model()
    assert model.part_names == list(conv.part_names) and model.num_joints == 1
    assert convention_violations(model, conv) == []
    lo, hi = conv.diagonal_range
    assert lo <= rest_diagonal(model) <= hi
    # the same draw for the same object: the scale is a function of the name
    assert import_object(urdf, "oven").scale == obj.scale


def test_a_frozen_joint_is_restored_from_the_semantics(tmp_path, make_oven_urdf):
    urdf = make_oven_urdf(tmp_path / "oven_b", door_fixed=True)
    obj = import_object(urdf, "oven")
    assert obj.joint_types["door_joint"] == "revolute"
    assert obj.moving_links == ("door",)
    assert convention_violations(obj.model(), convention("oven")) == []


def test_a_structure_the_category_cannot_hold_is_rejected_with_the_reason(tmp_path, make_oven_urdf):
    urdf = make_oven_urdf(tmp_path / "drawer_a", drawer=True)
    with pytest.raises(ImportRejected, match=r"has 1 moving part\(s\).*needs 3"):
        import_object(urdf, "drawer")
    bare = make_oven_urdf(tmp_path / "oven_c", base_geometry=False, knob=False)
    with pytest.raises(ImportRejected, match="no geometry"):
        import_object(bare, "oven")
    with pytest.raises(ValueError, match="no convention"):
        import_object(urdf, "teapot")


def test_bad_files_and_overrides_name_the_object(tmp_path, make_oven_urdf):
    folder = tmp_path / "oven_bad"
    urdf = make_oven_urdf(folder)
    urdf.write_text(urdf.read_text()[:-20])  # truncated XML
    with pytest.raises(ImportRejected, match="oven_bad: model.urdf is not a URDF file \\(not readable as XML"):
        import_object(urdf, "oven")
    good = make_oven_urdf(tmp_path / "oven_d")
    with pytest.raises(ValueError, match="oven_d.*unknown joint 'lid'"):
        import_object(good, "oven", override={"zero": {"lid": 0.0}})
    with pytest.raises(ImportRejected, match="by override: broken hinge"):
        import_object(good, "oven", override={"reject": "broken hinge"})
    bad = tmp_path / "override.json"
    bad.write_text(json.dumps({"oven_d": {"zeroo": 1}}))
    with pytest.raises(ValueError, match="oven_d.*unknown key"):
        load_overrides(bad)
    with pytest.raises(ValueError, match="not among the imported"):
        build_catalog([good], "oven", overrides={"oven_zz": {"flip_front": True}})
    bad.write_text(json.dumps({"oven_d": {"flip_front": "no"}}))  # a string is not a bool ("no" used to read as True)
    with pytest.raises(ValueError, match="override.json.*oven_d.*flip_front: expected a bool, got 'no'"):
        load_overrides(bad)
    with pytest.raises(ValueError, match="oven_d: override flip_front: expected a bool"):
        import_object(good, "oven", override={"flip_front": 1})
    entry = import_object(good, "oven").to_dict()
    assert ImportedObject.from_dict(entry).flip_front is entry["flip_front"]
    with pytest.raises(ValueError, match="malformed object entry 'oven_d'.*flip_front: expected a bool, got 'no'"):
        ImportedObject.from_dict(dict(entry, flip_front="no"))


def test_a_missing_mesh_names_the_object_and_a_catalog_records_it(tmp_path, make_oven_urdf):
    urdf = make_oven_urdf(tmp_path / "objs" / "oven_m")
    urdf.write_text(urdf.read_text().replace('<box size="0.02 0.56 0.58"/>', '<mesh filename="door.obj"/>'))
    with pytest.raises(ValueError, match="oven_m.*door.obj.*not found"):
        import_object(urdf, "oven")
    good = make_oven_urdf(tmp_path / "objs" / "oven_g")
    catalog = build_catalog([urdf, good], "oven")
    assert [o.name for o in catalog.objects] == ["oven_g"]
    assert catalog.rejected[0].name == "oven_m" and "unreadable" in catalog.rejected[0].reason


def test_a_mixed_dataset_resumes_like_a_procedural_one(tmp_path, make_oven_urdf):
    from ancsh.data.generate import GenerationConfig, generate_dataset

    objs = [import_object(make_oven_urdf(tmp_path / f"oven_{i}"), "oven") for i in range(2)]
    path = write_catalog(Catalog(tuple(assign_splits(objs))), tmp_path / "catalog.json")
    cfg = GenerationConfig(category="oven", split="test", real=str(path), real_fraction=0.5, shard_size=2,
                           min_part_pixels=5, min_part_fraction=0.0)
    first = generate_dataset(cfg, 4, tmp_path / "ds", workers=1, progress=False)
    assert len(first.written) == 2
    (tmp_path / "ds" / first.paths[1].name).unlink()  # an interrupted run: the second shard is missing
    again = generate_dataset(cfg, 4, tmp_path / "ds", workers=1, progress=False)
    assert again.skipped == (0,) and again.written == (1,)


def test_an_override_replaces_the_automatic_rule(tmp_path, make_oven_urdf):
    urdf = make_oven_urdf(tmp_path / "oven_e")
    obj = import_object(urdf, "oven", override={"zero": {"door_hinge": -make_oven_urdf.open_at_file_zero}, "diagonal_m": 1.0})
    assert obj.zero == (-make_oven_urdf.open_at_file_zero,)
    assert rest_diagonal(obj.model()) == pytest.approx(1.0, rel=1e-9)
    assert any("override" in n for n in obj.notes)
    # an override that breaks the convention is refused, not imported
    with pytest.raises(ImportRejected, match="not closed"):
        import_object(urdf, "oven", override={"zero": {"door_hinge": 0.0}})


def test_catalog_round_trip_report_preview_and_split(tmp_path, make_oven_urdf):
    urdfs = [make_oven_urdf(tmp_path / "objs" / f"oven_{i}") for i in range(4)]
    make_oven_urdf(tmp_path / "objs" / "drawer_x", drawer=True)
    catalog = build_catalog([tmp_path / "objs" / f"oven_{i}" / "model.urdf" for i in range(4)], "oven", command="test")
    assert len(catalog.objects) == 4 and not catalog.rejected
    path = write_catalog(catalog, tmp_path / "out" / "catalog.json")
    again = load_catalog(path)
    assert [o.to_dict() for o in again.objects] == [o.to_dict() for o in catalog.objects]
    # split: more than two objects of a category -> by the name's hash; two or fewer -> all test
    import zlib

    for o in again.objects:
        assert o.split == ("test" if zlib.crc32(o.name.encode()) % 4 == 0 else "train")
    few = assign_splits(catalog.objects[:2])
    assert all(o.split == "test" for o in few)
    report = write_import_report(catalog, tmp_path / "out" / "import_report.md").read_text()
    assert all(o.name in report for o in catalog.objects)
    png = draw_preview_sheet(catalog.objects[:2], tmp_path / "out" / "oven.png")
    assert png.stat().st_size > 1000
    with pytest.raises(ValueError, match="no catalog file"):
        load_catalog(tmp_path / "missing.json")
    assert urdfs


def test_import_cli_writes_catalog_report_and_previews(tmp_path, make_oven_urdf):
    from ancsh.cli import main

    make_oven_urdf(tmp_path / "objs" / "oven_1")
    make_oven_urdf(tmp_path / "objs" / "oven_2", drawer=True)
    out = tmp_path / "cat"
    assert main(["data", "import", str(tmp_path / "objs" / "oven_1" / "model.urdf"),
                 str(tmp_path / "objs" / "oven_2" / "model.urdf"), "--category", "drawer", "--out", str(out)]) == 1
    catalog = load_catalog(out)  # written all the same: the report says why each was rejected
    assert not catalog.objects and len(catalog.rejected) == 2  # an oven is not a drawer cabinet: nothing imported, exit 1
    assert "needs 3" in (out / "import_report.md").read_text()


def test_mixed_generation_renders_real_objects_and_keeps_procedural_frames(tmp_path, make_oven_urdf):
    from ancsh.data.generate import FrameGenerator, GenerationConfig

    objs = [import_object(make_oven_urdf(tmp_path / f"oven_{i}"), "oven") for i in range(2)]
    catalog = Catalog(tuple(assign_splits(objs)))
    path = write_catalog(catalog, tmp_path / "catalog.json")
    real = FrameGenerator(GenerationConfig(category="oven", split="test", real=str(path), real_fraction=1.0,
                                           min_part_pixels=5, min_part_fraction=0.0))
    frame = real.frame(0)
    assert frame.instance in {o.name for o in objs} and frame.instance_seed == -1
    assert frame.part_names == convention("oven").part_names
    # procedural frames of a config without real objects are unchanged by the feature
    plain = FrameGenerator(GenerationConfig(category="oven", split="test")).frame(3)
    none_real = FrameGenerator(GenerationConfig(category="oven", split="train", real=str(path), real_fraction=0.5))
    assert not none_real.real_instances  # both objects are test objects (two or fewer)
    again = FrameGenerator(GenerationConfig(category="oven", split="test")).frame(3)
    np.testing.assert_array_equal(plain.points, again.points)
    with pytest.raises(ValueError, match="real_fraction"):
        GenerationConfig(category="oven", real_fraction=0.5)


# --- the shared PartNet-Mobility objects -------------------------------------------------------
needs_shared = pytest.mark.skipif(not (shared_data_dir() / "partnet_mobility").is_dir(),
                                  reason="needs ../shared/data/partnet_mobility beside the repository")


@needs_shared
@pytest.mark.parametrize("name", ["laptop_10101", "eyeglasses_101328", "safe_101623", "microwave_7128"])
def test_the_builtin_catalog_is_what_the_importer_gives(name):
    builtin = {o.name: o for o in load_catalog().objects}
    fresh = import_object(shared_data_dir() / "partnet_mobility" / name / "mobility.urdf")
    ours = builtin[name]
    assert fresh.to_dict() | {"split": ours.split} == ours.to_dict()


@needs_shared
@pytest.mark.slow
def test_every_shared_object_is_imported_or_rejected_with_a_reason():
    catalog = load_catalog()
    names = {p.name for p in (shared_data_dir() / "partnet_mobility").iterdir() if (p / "mobility.urdf").is_file()}
    assert {o.name for o in catalog.objects} | {r.name for r in catalog.rejected} == names
    assert all(r.reason for r in catalog.rejected)
    for obj in catalog.objects:
        assert convention_violations(obj.model(), convention(obj.category)) == [], obj.name


@needs_shared
def test_every_shared_box_imports_with_its_lid_aligned_at_zero_and_rising_as_it_opens():
    """The arched lid of box_100174 makes a slightly smaller box with its base when tilted open a
    little (the old choice of state 0, 6 degrees open); the lid of box_100243 closes on a sloping top."""
    from ancsh.data.conventions import _aligned_child_volume, _box_volumes, _child_vertices_at

    boxes = {o.name: o for o in load_catalog().objects if o.category == "box"}
    assert sorted(boxes) == sorted(p.name for p in (shared_data_dir() / "partnet_mobility").glob("box_*"))
    for name, obj in boxes.items():
        model = obj.model()
        q_open = min(model.joints[0].upper, np.pi / 2)
        lid = _child_vertices_at(model, 0, np.array([0.0, q_open]))
        assert _box_volumes(lid[:1])[0] <= 1.05 * _aligned_child_volume(model, 0), name
        assert lid[1][:, 1].mean() > lid[0][:, 1].mean(), name


def test_the_builtin_catalog_is_shipped():
    assert builtin_catalog_path().is_file()
    catalog = load_catalog()
    assert {"laptop", "microwave", "safe"} <= set(catalog.categories)
    assert all(isinstance(o, ImportedObject) for o in catalog.objects)


def test_ranges_report_puts_real_objects_beside_the_generator(tmp_path, make_oven_urdf):
    from ancsh.studies.catalog_reports import ranges_report

    objs = [import_object(make_oven_urdf(tmp_path / f"oven_{i}"), "oven") for i in range(2)]
    text = ranges_report(Catalog(tuple(assign_splits(objs))), procedural_instances=3, command="test")
    assert "## oven" in text and "| real (2) | procedural (3) |" in text
    assert "door_on | front 100 %" in text  # the synthetic ovens' doors are on the front


def test_a_dataset_of_other_generators_is_not_resumed(tmp_path, monkeypatch):
    import ancsh.data.procedural as procedural
    from ancsh.data.generate import GenerationConfig, generate_dataset

    cfg = GenerationConfig(category="oven", split="test", shard_size=1)
    older = dict(procedural.GENERATOR_VERSIONS, oven=procedural.generator_version("oven") - 1)
    monkeypatch.setattr(procedural, "GENERATOR_VERSIONS", older)
    generate_dataset(cfg, 1, tmp_path / "ds", workers=1, progress=False)
    monkeypatch.undo()
    with pytest.raises(ValueError, match="generator_version"):
        generate_dataset(cfg, 1, tmp_path / "ds", workers=1, progress=False)


def test_the_import_hands_over_the_model_its_record_rebuilds(tmp_path, make_oven_urdf):
    """The model built during import is kept (no second mesh load) and equals the record's rebuild."""
    obj = assign_splits([import_object(make_oven_urdf(tmp_path / "oven_k"), "oven")])[0]
    fresh = ImportedObject.from_dict(obj.to_dict()).model()
    carried = obj.model()
    assert carried.part_names == fresh.part_names
    for a, b in zip(carried.parts, fresh.parts):
        np.testing.assert_array_equal(a.vertices, b.vertices)
    for a, b in zip(carried.joints, fresh.joints):
        assert (a.lower, a.upper, a.rest) == (b.lower, b.upper, b.rest) and a.origin.allclose(b.origin, atol=0)
        np.testing.assert_array_equal(a.axis, b.axis)


def test_moving_links_must_be_a_list_of_names(tmp_path, make_oven_urdf):
    """A bare string used to be iterated letter by letter."""
    good = make_oven_urdf(tmp_path / "oven_d")
    with pytest.raises(ValueError, match="oven_d: override moving_links: expected a list of link names"):
        import_object(good, "oven", override={"moving_links": "door"})
    bad = tmp_path / "override.json"
    bad.write_text(json.dumps({"oven_d": {"moving_links": "link_1"}}))
    with pytest.raises(ValueError, match="override.json.*'oven_d': moving_links: expected a list of link names"):
        load_overrides(bad)


def test_a_folder_given_twice_is_imported_once(tmp_path, make_oven_urdf):
    urdf = make_oven_urdf(tmp_path / "objects" / "oven_a")
    catalog = build_catalog([urdf.parent, urdf.parent, urdf], "oven")
    assert [o.name for o in catalog.objects] + [r.name for r in catalog.rejected] == ["oven_a"]
    other = make_oven_urdf(tmp_path / "elsewhere" / "oven_a")  # another object of the same name
    with pytest.raises(ValueError, match="both object 'oven_a'"):
        build_catalog([urdf.parent, other.parent], "oven")



@pytest.mark.parametrize("door_limits, kind", [("continuous", "continuous"), ("huge", "more than a full turn")])
def test_an_unlimited_hinge_is_limited_to_where_its_part_stays_out_of_the_base(tmp_path, make_oven_urdf, door_limits,
                                                                                kind):
    """The door hinges at the cube's bottom front edge: from closed (0) it swings out and down, hangs, and lies
    along the cube's bottom at 270 deg; further, it would enter the cube. Closing past 0 enters it at once."""
    urdf = make_oven_urdf(tmp_path / "oven_u", door_limits=door_limits)
    obj = import_object(urdf, "oven")
    reference = import_object(make_oven_urdf(tmp_path / "oven_r"), "oven")
    assert obj.zero[0] == pytest.approx(reference.zero[0], abs=0.02) and obj.sign == reference.sign
    lo, hi = obj.limits["door_hinge"]
    assert lo == 0.0 and np.radians(268) <= hi <= np.radians(300)
    assert any(kind in n and "limited to [0, " in n for n in obj.notes)
    joint = obj.model().joints[0]
    assert (joint.lower, joint.upper) == (lo, hi)
    back = ImportedObject.from_dict(json.loads(json.dumps(obj.to_dict())))
    assert back.limits == obj.limits and (back.model().joints[0].lower, back.model().joints[0].upper) == (lo, hi)
    assert "limits" not in reference.to_dict() and reference.limits == {}


def test_an_oven_with_two_door_hinges_keeps_the_door_the_convention_chooses(tmp_path, make_oven_urdf):
    urdf = make_oven_urdf(tmp_path / "oven_two", hatch=True)
    obj = import_object(urdf, "oven")
    reference = import_object(make_oven_urdf(tmp_path / "oven_one"), "oven")
    assert obj.moving_links == ("door",) and obj.joint_types["hatch_joint"] == "fixed"
    assert obj.zero == pytest.approx(reference.zero) and obj.sign == reference.sign
    assert any("['door'] chosen by the convention" in n and "['hatch'] frozen" in n for n in obj.notes), obj.notes
    assert any(n.startswith("joint types replaced: ") and "hatch_joint revolute -> fixed" in n for n in obj.notes)
    assert not any(n.startswith("moving links ") for n in obj.notes)
    assert convention_violations(obj.model(), convention("oven")) == []
    forced = import_object(urdf, "oven", override={"moving_links": ["door"]})  # the same choice by hand is noted
    assert "moving links ['door'] from override" in forced.notes


def test_a_file_that_is_no_urdf_says_so(tmp_path):
    (tmp_path / "foo").mkdir()
    (tmp_path / "foo" / "model.urdf").write_text("<foo/>")
    with pytest.raises(ImportRejected, match=r"not a URDF file \(its root element is <foo>, not <robot>\)"):
        import_object(tmp_path / "foo" / "model.urdf")
    (tmp_path / "passwd").write_text("root:x:0:0:root:/root:/bin/bash\n")
    with pytest.raises(ImportRejected, match="passwd is not a URDF file \\(not readable as XML"):
        import_object(tmp_path / "passwd")
    (tmp_path / "thing").mkdir()
    (tmp_path / "thing" / "model.urdf").write_text('<robot name="r"><link name="a"/></robot>')
    with pytest.raises(ImportRejected, match="no meta.json beside it and its folder name 'thing' names no category"):
        import_object(tmp_path / "thing" / "model.urdf")


@pytest.mark.parametrize("entry, message", [
    ("link_0", "entry 'o' must be an object of settings such as"),
    ({"zero": 0.5}, "entry 'o': zero: expected an object {joint name: a number (file units)}"),
    ({"sign": {"door_hinge": "up"}}, "entry 'o': sign: expected an object {joint name: 1 or -1}"),
    ({"diagonal_m": "big"}, "entry 'o': diagonal_m: expected a positive number of metres, got 'big'"),
    ({"diagonal_m": -1}, "diagonal_m: expected a positive number"),
    ({"reject": 1}, "entry 'o': reject: expected the reason"),
    ({"moving_links": "link_1"}, "moving_links: expected a list of link names"),
])
def test_override_values_of_the_wrong_kind_are_refused_naming_file_entry_and_key(tmp_path, entry, message):
    path = tmp_path / "over.json"
    path.write_text(json.dumps({"o": entry}))
    import re

    with pytest.raises(ValueError, match=re.escape(f"override: {path}: ") + ".*" + re.escape(message)):
        load_overrides(path)


@pytest.mark.parametrize("scale", ["abc", -1.0, 0, None, True])
def test_a_catalog_entry_with_a_bad_scale_names_the_catalog_and_the_object(tmp_path, make_oven_urdf, scale):
    entry = import_object(make_oven_urdf(tmp_path / "oven_s"), "oven").to_dict()
    entry["scale"] = scale
    with pytest.raises(ValueError, match=r"my.json: object 'oven_s': scale: expected a positive number"):
        ImportedObject.from_dict(entry, where="my.json")


@needs_shared
def test_a_shared_oven_given_a_second_hinged_flap_keeps_its_door(tmp_path):
    """oven_7138 with part of its door frame copied onto a second, side-hinged link (the trait of the held-out ovens
    whose files keep two door hinges): imported without overrides, the door and its state 0 as without the flap."""
    import shutil

    source = shared_data_dir() / "partnet_mobility" / "oven_7138"
    folder = tmp_path / "oven_7138_flap"
    shutil.copytree(source, folder)
    text = (folder / "mobility.urdf").read_text()
    flap = """	<link name="link_2">
		<visual name="flap">
			<origin xyz="-0.7010470000000004 0.45892809949621766 -0.5537792117459065"/>
			<geometry>
				<mesh filename="textured_objs/original-19.obj"/>
			</geometry>
		</visual>
	</link>
	<joint name="joint_2" type="revolute">
		<origin xyz="0.7010470000000004 -0.45892809949621766 0.5537792117459065"/>
		<axis xyz="0 1 0"/>
		<child link="link_2"/>
		<parent link="link_1"/>
		<limit lower="0" upper="1.5707963267948966"/>
	</joint>
"""
    assert text.count("</robot>") == 1
    (folder / "mobility.urdf").write_text(text.replace("</robot>", flap + "</robot>"))
    with open(folder / "semantics.txt", "a") as f:  # a door by its label too: the convention must choose
        f.write("link_2 hinge door\n")
    reference = import_object(source / "mobility.urdf", "oven")
    obj = import_object(folder / "mobility.urdf", "oven")
    assert obj.moving_links == reference.moving_links == ("link_0",)
    assert obj.joint_types["joint_2"] == "fixed"
    assert obj.zero == pytest.approx(reference.zero) and obj.sign == reference.sign
    assert any("['link_2'] frozen" in n for n in obj.notes), obj.notes
    assert convention_violations(obj.model(), convention("oven")) == []


@needs_shared
def test_a_shared_box_turned_into_a_side_hinged_top_loader_imports_without_overrides(tmp_path):
    """box_100141's lid laid closed on the top and hinged along its right edge, front to back (the trait of the
    top-loading washing machines whose lid hinges sideways), its file limits on the negative side: imported as a
    washing machine without overrides, closed at 0 on top of the body, the state opening the lid upwards about a
    front-to-back axis, every convention rule met."""
    import shutil

    from ancsh.data.conventions import part_vertices_canonical

    source = shared_data_dir() / "partnet_mobility" / "box_100141"
    folder = tmp_path / "top_loader_side_hinge"
    shutil.copytree(source, folder)
    text = (folder / "mobility.urdf").read_text()
    start = text.index('<link name="link_0">')
    lid = text[start:text.index("</link>", start)]
    # the lid's meshes (object coordinates, y up) turned 90 deg about the old back hinge (x at y 0.191, z -0.23) onto
    # the top, then expressed in the new hinge's frame at (0.536, 0.2, 0.095): xyz = h - P - R_x(90) h
    old = '<origin xyz="-0.5125540000000001 -0.191 0.23"/>'
    assert old in lid
    text = text.replace(lid, lid.replace(old, '<origin xyz="-0.536 -0.239 -0.516" rpy="1.5707963267948966 0 0"/>'))
    hinge = '<origin xyz="0.5125540000000001 0.191 -0.23"/>\n\t\t<axis xyz="-1 0 0"/>'
    limits = '<limit lower="-1.5707963267948966" upper="1.3962634015954636"/>'
    assert text.count(hinge) == 1 and text.count(limits) == 1
    text = text.replace(hinge, '<origin xyz="0.536 0.2 0.095"/>\n\t\t<axis xyz="0 0 1"/>')
    (folder / "mobility.urdf").write_text(text.replace(limits, '<limit lower="-1.9" upper="0"/>'))
    (folder / "semantics.txt").write_text("link_0 hinge door\nlink_1 free washing_machine_body\n")

    obj = import_object(folder / "mobility.urdf", "washing_machine")
    model = obj.model()
    assert obj.moving_links == ("link_0",) and obj.sign == (-1,) and obj.zero == pytest.approx((0.0,), abs=0.02)
    assert convention_violations(model, convention("washing_machine")) == []
    base, door = part_vertices_canonical(model, model.rest_states)
    size = base.max(axis=0) - base.min(axis=0)
    assert door.min(axis=0)[1] > base.max(axis=0)[1] - 0.05 * size[1]  # closed: the lid lies on the top
    axis = model.R_canon_base @ model.joints[0].axis
    assert abs(axis[2]) > 0.99  # hinged front to back
    _, opened = part_vertices_canonical(model, model.rest_states + 0.5)
    assert opened.max(axis=0)[1] > door.max(axis=0)[1] + 0.2 * size[1]  # a positive state lifts it


def test_moving_links_naming_the_base_say_so(tmp_path, make_oven_urdf):
    good = make_oven_urdf(tmp_path / "oven_b")
    with pytest.raises(ValueError, match=r"oven_b: override moving_links: link\(s\) \['body'\] .*the base cannot move"):
        import_object(good, "oven", override={"moving_links": ["body"]})
