"""``ancsh fit-cad`` end to end and its error paths."""

import json

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.data.paths import shared_data_dir
from ancsh.data.render import Intrinsics, ModelRenderer, object_extent
from ancsh.geometry.rotations import exp_so3
from ancsh.geometry.transforms import Sim3
from ancsh.studies.cad.measure import _orbit_pose

URDF = shared_data_dir() / "partnet_mobility" / "drawer_20453" / "mobility.urdf"
pytestmark = pytest.mark.skipif(not URDF.is_file(), reason="shared PartNet-Mobility data not available")


@pytest.fixture()
def scene(tmp_path):
    from ancsh.data.urdf import load_urdf

    model = load_urdf(URDF)
    q = np.array([0.6 * model.upper_limits[0] + 0.4 * model.lower_limits[0]])
    center, diag = object_extent(model, q)
    T = _orbit_pose(model, q, center, diag, np.radians(25), np.radians(30), 1.8)
    intr = Intrinsics.kinect(320, 240)
    depth = ModelRenderer(model).render(q, T, intr).depth
    np.save(tmp_path / "depth.npy", depth)
    (tmp_path / "K.json").write_text(json.dumps(intr.to_json()))
    T0 = Sim3(exp_so3([0.2, -0.15, 0.1]) @ T.rotation, T.translation + 0.03 * diag)
    (tmp_path / "init.json").write_text(json.dumps({"T_cam_base": T0.matrix().tolist(), "q": model.lower_limits.tolist()}))
    return model, q, T, tmp_path


def test_fit_cad_writes_result_and_picture(scene, capsys):
    model, q, T, d = scene
    code = main(["fit-cad", "--urdf", str(URDF), "--depth", str(d / "depth.npy"), "--intrinsics", str(d / "K.json"),
                 "--init", str(d / "init.json"), "--points", "800", "--out", str(d / "r.json"), "--png", str(d / "v.png")])
    assert code == 0, capsys.readouterr()
    result = json.loads((d / "r.json").read_text())
    assert result["status"] == "success"
    np.testing.assert_allclose(result["q"], q, atol=1e-3)
    np.testing.assert_allclose(result["T_cam_base"]["translation"], T.translation, atol=1e-3)
    u = result["uncertainty"]  # standard deviations of the fit (a noise-free rendering: small but not zero)
    assert u["status"] == "ok" and u["inflation"]["source"] == "raw"
    assert 0 < u["joints"][0]["state_std"] < 1e-3 and len(u["parts"]) == model.num_parts
    assert all(p["scale_std"] == 0 for p in u["parts"])  # the model's scale is known
    assert (d / "v.png").stat().st_size > 0
    capsys.readouterr()
    main(["fit-cad", "--urdf", str(URDF), "--depth", str(d / "depth.npy"), "--intrinsics", str(d / "K.json"),
          "--init", str(d / "init.json"), "--points", "800", "--png", str(d / "view")])
    assert f"wrote {d / 'view.png'}" in capsys.readouterr().out and (d / "view.png").is_file()  # the path it wrote


def test_fit_cad_errors(scene, capsys):
    model, q, T, d = scene
    np.save(d / "empty.npy", np.zeros((240, 320)))
    args = ["fit-cad", "--urdf", str(URDF), "--intrinsics", str(d / "K.json")]
    assert main(args + ["--depth", str(d / "empty.npy")]) == 2
    assert "no valid depth" in capsys.readouterr().err
    np.save(d / "small.npy", np.zeros((10, 10)))
    assert main(args + ["--depth", str(d / "small.npy")]) == 2
    assert "is 10x10 pixels, the intrinsics say 320x240" in capsys.readouterr().err
    for init, message in (({"T_cam_base": np.eye(3).tolist()}, "T_cam_base must be a 4x4 matrix, got shape (3, 3)"),
                          ({"T_cam_base": np.eye(4).tolist(), "q": [0.1] * (model.num_joints + 1)},
                           f"q must hold {model.num_joints} joint state(s)"),
                          ({"T_cam_base": [["a"] * 4] * 4}, "T_cam_base must be a 4x4 matrix of numbers")):
        (d / "bad_init.json").write_text(json.dumps(init))
        assert main(args + ["--depth", str(d / "depth.npy"), "--init", str(d / "bad_init.json")]) == 2
        err = capsys.readouterr().err
        assert f"--init: {d / 'bad_init.json'}: {message}" in err and "Traceback" not in err and " M:" not in err
    rigid = d / "box.urdf"
    rigid.write_text('<robot name="box"><link name="b"><visual><geometry><box size="1 1 1"/></geometry></visual></link></robot>')
    assert main(["fit-cad", "--urdf", str(rigid), "--depth", str(d / "depth.npy"), "--intrinsics", str(d / "K.json")]) == 2
    assert "no movable joint" in capsys.readouterr().err


def test_fit_cad_writes_the_posed_model_as_urdf(scene, capsys):
    import yourdfpy

    model, q, T, d = scene
    args = ["fit-cad", "--urdf", str(URDF), "--depth", str(d / "depth.npy"), "--intrinsics", str(d / "K.json"),
            "--init", str(d / "init.json"), "--points", "800", "--out", str(d / "r.json")]
    assert main([*args, "--urdf-out", str(d / "twin")]) == 0
    result = json.loads((d / "r.json").read_text())
    (path,) = (d / "twin").glob("*.urdf")
    robot = yourdfpy.URDF.load(str(path))
    robot.update_cfg(json.loads((d / "twin" / "joint_states.json").read_text()))
    for name, T_fit in zip(result["parts"], result["T_cam_parts"]):
        pose = robot.get_transform(name, "camera") @ robot.link_map[name].visuals[0].origin
        assert np.abs(pose[:3, :3] - np.array(T_fit["rotation"])).max() < 1e-9
        assert np.abs(pose[:3, 3] - np.array(T_fit["translation"])).max() < 1e-9
    capsys.readouterr()
    assert main([*args, "--urdf-out", str(d / "twin")]) == 2
    assert "--urdf-out: " in capsys.readouterr().err
    assert main([*args, "--overwrite"]) == 2
