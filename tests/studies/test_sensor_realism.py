"""Depth-sensor artefacts (ancsh.studies.sensor_realism): measured on images whose artefacts are known, and the
benchmark command on a real-frame folder laid out as the shared ones."""

import json

import numpy as np
import pytest
from PIL import Image

from ancsh.cli import main
from ancsh.data.noise import DepthNoise, apply_noise
from ancsh.data.render import Intrinsics
from ancsh.studies.sensor_realism import BLOB_PIXELS, depth_artefacts


def _step_image():
    """A wall at 1.5 m with a box face at 1.0 m in front of it (columns 40-119): two vertical depth jumps."""
    depth = np.full((80, 160), 1.5)
    depth[:, 40:120] = 1.0
    return depth


def test_jumps_count_dropped_and_mixed_pixels_and_a_steep_slope_is_no_jump():
    depth = _step_image()
    clean = depth_artefacts(depth)
    assert clean["jump_pixels"] > 0 and clean["dropped"] == 0.0 and clean["mixed"] == 0.0
    mixed = depth.copy()
    mixed[:, 40] = 1.25  # the first column of the face sees both surfaces
    dropped = depth.copy()
    dropped[:, 119] = 0.0
    m, d = depth_artefacts(mixed), depth_artefacts(dropped)
    assert m["mixed"] > 0 and m["dropped"] == 0.0
    assert d["dropped"] > 0 and d["mixed"] == 0.0
    # per row: the clean jump counts the 4 middles whose sides straddle it; the altered one 3 (its odd column is no
    # flat side for the windows reaching it from outside), one of them the mixed or dropped pixel: 1 of 7
    assert clean["jump_pixels"] == 2 * 4 * 80
    assert m["mixed"] == pytest.approx(1 / 7) and d["dropped"] == pytest.approx(1 / 7)
    ramp = np.tile(np.linspace(0.5, 3.0, 160), (80, 1))  # 1.6 cm per pixel: 6 cm over the window, but no edge
    assert depth_artefacts(ramp)["jump_pixels"] == 0


def test_holes_are_told_from_the_border_and_steps_from_a_continuous_depth():
    depth = _step_image()
    depth[:5, :] = 0.0  # out of range along the top: not a hole inside
    depth[30:45, 60:75] = 0.0  # one hole of 225 pixels
    depth[60, 10] = 0.0  # and one lost pixel
    a = depth_artefacts(depth)
    inside = 225 + 1
    assert a["missing_inside"] == pytest.approx(inside / (depth.size - 5 * 160))
    assert 225 > BLOB_PIXELS and a["holes_in_blobs"] == pytest.approx(225 / inside)
    rng = np.random.default_rng(0)
    noisy = apply_noise(_step_image(), DepthNoise(edge_dropout=0.0), rng)
    stepped = apply_noise(_step_image(), DepthNoise(edge_dropout=0.0, quantisation=0.001), rng)
    assert depth_artefacts(noisy)["step_mm"] < 0.1 and depth_artefacts(stepped)["step_mm"] == pytest.approx(1.0)
    rgb = np.full(depth.shape + (3,), 200, dtype=np.uint8)
    rgb[30:45, 60:75] = 10  # the hole is dark
    assert depth_artefacts(depth, rgb)["dark_missing"] == 1.0 and np.isnan(a["dark_missing"])
    with pytest.raises(ValueError, match="no pixel has a measurement"):
        depth_artefacts(np.zeros((4, 4)))
    with pytest.raises(ValueError, match="rgb: expected the depth's size"):
        depth_artefacts(depth, rgb[:10])


def test_the_command_measures_a_real_frame_folder_beside_rendered_scenes(tmp_path, capsys):
    folder = tmp_path / "wall_and_box"
    folder.mkdir()
    intr = Intrinsics(fx=150.0, fy=150.0, cx=79.5, cy=39.5, width=160, height=80)
    noisy = apply_noise(_step_image(), DepthNoise(), np.random.default_rng(1))
    Image.fromarray(np.round(noisy * 1000).astype(np.uint16)).save(folder / "depth.png")  # whole millimetres
    (folder / "K.json").write_text(json.dumps(intr.to_json()))
    (folder / "truth.json").write_text(json.dumps({"schema": "real-frame-truth/1", "objects": []}))
    out = tmp_path / "report" / "sensor_realism.md"
    assert main(["bench", "sensor-realism", str(folder), "--categories", "laptop", "--frames", "1", "--out", str(out),
                 "--quiet"]) == 0
    text = out.read_text()
    assert "| real | wall_and_box | 1 |" in text and "| rendered (dataset noise) | laptop | 1 |" in text
    assert "| rendered (real_frames noise) | laptop | 1 |" in text
    data = json.loads(out.with_suffix(".json").read_text())
    assert data["command"].startswith(f"ancsh bench sensor-realism {folder} --categories laptop --frames 1")
    rows = {(r["source"], r["name"]): r for r in data["rows"]}
    assert rows[("real", "wall_and_box")]["step_mm"] == pytest.approx(1.0)
    assert rows[("rendered (real_frames noise)", "laptop")]["step_mm"] == pytest.approx(1.0)
    assert main(["bench", "sensor-realism", str(folder), "--categories", "nothing", "--out", str(out)]) == 2
    assert "--categories: unknown ['nothing']" in capsys.readouterr().err
