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
