"""Predictions a user can trust: object isolation without a mask, plausibility as status,
provenance in the JSON, non-zero exit codes on failure, inputs in the wrong units."""

import hashlib
import json

import numpy as np
import pytest
import trimesh
from PIL import Image

from ancsh.cli import main
from ancsh.data.conventions import CONVENTIONS
from ancsh.data.isolate import ObjectHint, isolate_object, parse_hint
from ancsh.data.procedural import CATEGORY_INFO, load_instance
from ancsh.data.render import Intrinsics, ModelRenderer, look_at
from ancsh.data.scenes import nearest_surface
from ancsh.geometry.transforms import Sim3
from ancsh.learned.inference.predict import MIN_POINTS, predict_depth, read_depth
from ancsh.learned.inference.provider import LearnedProvider
from ancsh.learned.network.weights import weights_path
from ancsh.model.articulated import ArticulatedModel, Part


@pytest.fixture(scope="module")
def table_scene():
    """A laptop (110 deg open) on a table plane, with a box-shaped distractor beside it; noise-free depth.

    Returns the depth, intrinsics, the per-pixel source (0 laptop, 1 table, 2 distractor) and the true opening.
    """
    laptop = load_instance("laptop", "test", 0)
    q = np.array([np.radians(110.0)])
    ymin = min(p.vertices[:, 1].min() for p in laptop.parts)
    table = ArticulatedModel((Part("table", trimesh.creation.box((1.8, 0.03, 1.2))),), (), name="table")
    bottle = ArticulatedModel((Part("bottle", trimesh.creation.box((0.1, 0.24, 0.1))),), (), name="bottle")
    T_cam_world = look_at([0.1, 0.55, 0.75], [0.0, 0.05, 0.0], [0, 1, 0])
    intr = Intrinsics.kinect(320, 240)
    views = [ModelRenderer(laptop).render(q, T_cam_world, intr),
             ModelRenderer(table).render(np.zeros(0), T_cam_world @ Sim3(np.eye(3), [0, ymin - 0.015, -0.1]), intr),
             ModelRenderer(bottle).render(np.zeros(0), T_cam_world @ Sim3(np.eye(3), [0.45, ymin + 0.12, -0.05]), intr)]
    depth, source = nearest_surface([v.depth for v in views])
    return depth, intr, source, q


@pytest.fixture(scope="module")
def provider():
    return LearnedProvider("laptop", seed=0)


def _files(folder, depth, intr):
    np.save(folder / "d.npy", depth)
    (folder / "K.json").write_text(json.dumps(intr.to_json()))
    return ["--depth", str(folder / "d.npy"), "--intrinsics", str(folder / "K.json")]


# --- object isolation --------------------------------------------------------------------------
def test_isolation_finds_the_laptop_on_a_table_beside_a_distractor(table_scene):
    depth, intr, source, _ = table_scene
    iso = isolate_object(depth, intr, CONVENTIONS["laptop"].diagonal_range)
    laptop = source == 0
    assert iso.planes >= 1 and len(iso.clusters) >= 2
    assert np.count_nonzero(iso.mask & laptop) > 0.9 * np.count_nonzero(laptop)
    assert np.count_nonzero(iso.mask & ~laptop) < 0.02 * np.count_nonzero(laptop)
    # a hint pixel on the distractor chooses the distractor; a box around the laptop the laptop
    v, u = np.argwhere(source == 2).mean(axis=0)
    picked = isolate_object(depth, intr, CONVENTIONS["laptop"].diagonal_range, hint=ObjectHint(pixel=(u, v))).mask
    assert np.count_nonzero(picked & (source == 2)) > 0.9 * np.count_nonzero(source == 2)
    vs, us = np.nonzero(laptop)
    boxed = isolate_object(depth, intr, CONVENTIONS["laptop"].diagonal_range, hint=ObjectHint(box=(us.min(), vs.min(), us.max(), vs.max()))).mask
    assert np.count_nonzero(boxed & laptop) > 0.9 * np.count_nonzero(laptop)


def test_prediction_without_a_mask_is_plausible_on_the_table_scene(table_scene, provider, tmp_path):
    depth, intr, source, q = table_scene
    pred = predict_depth(depth, intr, "laptop", provider=provider)
    assert pred.result.ok, pred.result.message
    opening = pred.to_json()["joints"][0]["state_abs"]
    assert abs(np.degrees(opening - q[0])) < 20
    # without isolation the table and the distractor join the cloud: never a success
    raw = predict_depth(depth, intr, "laptop", provider=provider, isolate=False)
    assert not raw.result.ok
    # a mask wins over isolation
    masked = predict_depth(depth, intr, "laptop", provider=provider, mask=source == 2)
    assert np.all(source[masked.pixels[:, 1], masked.pixels[:, 0]] == 2)


def test_a_hint_outside_the_image_is_refused_naming_the_option(table_scene, tmp_path, capsys):
    depth, intr, _, _ = table_scene
    with pytest.raises(ValueError, match=r"--pixel: \(400, 10\) lies outside the 320x240 image"):
        isolate_object(depth, intr, CONVENTIONS["laptop"].diagonal_range, hint=ObjectHint(pixel=(400, 10)))
    with pytest.raises(ValueError, match="--box: .* does not overlap the 320x240 image"):
        isolate_object(depth, intr, CONVENTIONS["laptop"].diagonal_range, hint=ObjectHint(box=(330, 10, 400, 50)))
    args = _files(tmp_path, depth, intr)
    assert main(["predict", *args, "--category", "laptop", "--pixel", "-5,-5"]) == 2
    assert "--pixel: (-5, -5) lies outside the 320x240 image" in capsys.readouterr().err


def test_hint_parsing_names_the_option():
    assert parse_hint("10,20", None).pixel == (10.0, 20.0)
    assert parse_hint(None, "1,2,30,40").box == (1.0, 2.0, 30.0, 40.0)
    assert parse_hint(None, None) is None
    with pytest.raises(ValueError, match="--pixel"):
        parse_hint("10", None)
    with pytest.raises(ValueError, match="--box"):
        parse_hint(None, "5,5,1,1")
    with pytest.raises(ValueError, match="not both"):
        parse_hint("1,2", "1,2,3,4")


# --- plausibility as status -------------------------------------------------------------------
def test_a_bare_wall_never_reports_success(tmp_path, capsys):
    intr = Intrinsics.kinect(160, 120)
    v, u = np.mgrid[0:120, 0:160]
    depth = 1.8 + 0.002 * (u - 80)  # a slanted wall filling the image
    args = _files(tmp_path, depth, intr)
    code = main(["predict", *args, "--category", "laptop", "--out", str(tmp_path / "r.json"), "--png", str(tmp_path / "w.png")])
    data = json.loads((tmp_path / "r.json").read_text())
    assert code == 1 and data["status"] != "success" and not data["ok"]
    code = main(["predict", *args, "--category", "laptop", "--no-isolate", "--out", str(tmp_path / "r2.json")])
    assert code == 1 and json.loads((tmp_path / "r2.json").read_text())["status"] == "implausible_size"


def test_a_table_with_a_bottle_but_no_laptop_is_no_laptop(table_scene, provider):
    """Without the laptop the candidates are the bottle and pieces of the table: each fails a check
    (its size, or p_object: it does not look like a laptop), so the answer is no_object, listing them."""
    depth, intr, source, _ = table_scene
    empty = np.where(source == 0, 0.0, depth)  # the laptop's pixels without a measurement
    pred = predict_depth(empty, intr, "laptop", provider=provider)
    assert pred.result.status.value in ("no_object", "too_few_points") and not pred.result.ok
    if pred.result.status.value == "no_object":
        assert "segment" in pred.result.message and pred.isolation.verified
        assert all(v["status"] != "success" for v in pred.isolation.verified)


def test_candidates_come_from_every_depth_of_plane_removal_and_a_hint_box_chooses(table_scene):
    depth, intr, source, _ = table_scene
    iso = isolate_object(depth, intr, CONVENTIONS["laptop"].diagonal_range)
    assert sorted(iso.order) == list(range(len(iso.clusters))) and iso.order[0] == iso.chosen
    assert len({c.level for c in iso.clusters}) >= 1 and iso.stride >= 1
    for c in range(len(iso.clusters)):
        m = iso.mask_of(c)
        assert m.shape == depth.shape and m.any() and not (m & (depth <= 0)).any()
    bottle = source == 2
    vs, us = np.nonzero(bottle)
    boxed = isolate_object(depth, intr, CONVENTIONS["laptop"].diagonal_range, hint=ObjectHint(box=(us.min(), vs.min(), us.max(), vs.max())))
    assert np.count_nonzero(boxed.mask & bottle) > 0.9 * np.count_nonzero(bottle)


def test_a_table_running_out_of_the_image_is_a_support_even_for_a_large_category(table_scene):
    """The table (1.8 x 1.2 m, cut by the image border) is narrower than the largest oven times 1.5, but wider
    than a typical oven and it runs out of the image: it is removed, and the laptop is a segment of its own."""
    depth, intr, source, _ = table_scene
    iso = isolate_object(depth, intr, CONVENTIONS["oven"].diagonal_range)
    assert iso.planes >= 1
    laptop = source == 0
    best = max(range(len(iso.clusters)), key=lambda c: np.count_nonzero(iso.mask_of(c) & laptop))
    m = iso.mask_of(best)
    assert np.count_nonzero(m & laptop) > 0.8 * np.count_nonzero(laptop) and np.count_nonzero(m & (source == 1)) < 0.1 * m.sum()


def test_twenty_valid_pixels_are_too_few_points(table_scene, provider):
    depth, intr, source, _ = table_scene
    few = np.zeros_like(depth)
    idx = np.argwhere(source == 0)[:: max(1, np.count_nonzero(source == 0) // 20)][:20]
    few[idx[:, 0], idx[:, 1]] = depth[idx[:, 0], idx[:, 1]]
    pred = predict_depth(few, intr, "laptop", provider=provider, isolate=False)
    assert pred.result.status.value == "too_few_points" and "min_points" in pred.result.message
    assert pred.valid_pixels == 20 < MIN_POINTS


def test_an_object_three_times_too_large_is_implausible(table_scene, provider):
    depth, intr, source, _ = table_scene
    big = np.where(source == 0, 3.0 * depth, 0.0)  # same image, 3x the size at 3x the distance
    pred = predict_depth(big, intr, "laptop", provider=provider, isolate=False)
    assert pred.result.status.value == "implausible_size"
    assert "check size" in pred.result.message and str(CATEGORY_INFO["laptop"].diagonal_range[1]) in pred.result.message


def test_millimetres_in_a_npy_get_an_error_with_the_hint(tmp_path, table_scene, capsys):
    depth, intr, _, _ = table_scene
    np.save(tmp_path / "mm.npy", depth * 1000.0)
    with pytest.raises(ValueError, match="looks like millimetres.*divide it by 1000"):
        read_depth(tmp_path / "mm.npy")
    with pytest.raises(ValueError, match="millimetres"):
        predict_depth(depth * 1000.0, intr, "laptop")
    (tmp_path / "K.json").write_text(json.dumps(intr.to_json()))
    assert main(["predict", "--depth", str(tmp_path / "mm.npy"), "--intrinsics", str(tmp_path / "K.json"),
                 "--category", "laptop"]) == 2
    assert "millimetres" in capsys.readouterr().err


# --- output -------------------------------------------------------------------------------
def test_json_carries_version_weights_hash_and_both_joint_states(table_scene, tmp_path, capsys):
    from ancsh import __version__

    depth, intr, _, _ = table_scene
    code = main(["predict", *_files(tmp_path, depth, intr), "--category", "laptop", "--out", str(tmp_path / "r.json"),
                 "--png", str(tmp_path / "v.png")])
    data = json.loads((tmp_path / "r.json").read_text())
    assert code == 0 and data["ok"]
    assert data["schema"] == "ancsh.prediction/2" and data["ancsh_version"] == __version__
    assert data["weights_sha256"] == hashlib.sha256(weights_path("laptop").read_bytes()).hexdigest()
    joint = data["joints"][0]
    assert joint["rest"] == pytest.approx(np.pi / 2)
    assert joint["state_abs"] == pytest.approx(joint["state"] + joint["rest"])
    assert "right angles" in data["rest_state"]
    assert data["isolation"]["planes_removed"] >= 1 and data["isolation"]["chosen"] is not None
    for part in data["parts"]:  # evidence per part: points, inliers, residual, segmentation margin
        q = part["quality"]
        assert q["points"] == part["points"] > 0 and q["inlier_ratio"] >= 0.5
        assert 0 <= q["residual_m"] < 0.05 and 0 < q["seg_margin"] <= 1
    assert "absolute" in capsys.readouterr().out


def test_points_above_the_valid_pixels_are_noted(table_scene, provider):
    depth, intr, source, _ = table_scene
    pred = predict_depth(depth, intr, "laptop", provider=provider, mask=source == 0, num_points=50000)
    assert pred.points_cam.shape[0] == pred.valid_pixels == np.count_nonzero(source == 0)
    assert len(np.unique(pred.pixels, axis=0)) == len(pred.pixels)  # no duplicates
    assert any("fewer than the 50000 points" in n for n in pred.notes)


def test_eight_bit_png_is_refused_by_predict_and_fit_cad_alike(tmp_path, capsys):
    Image.fromarray(np.full((6, 8), 200, dtype=np.uint8)).save(tmp_path / "d8.png")
    (tmp_path / "K.json").write_text(json.dumps({"fx": 8.0, "fy": 8.0, "cx": 4.0, "cy": 3.0, "width": 8, "height": 6}))
    urdf = tmp_path / "hinge.urdf"
    urdf.write_text(
        "<robot name='h'><link name='a'><visual><geometry><box size='.1 .1 .1'/></geometry></visual></link>"
        "<joint name='j' type='revolute'><parent link='a'/><child link='b'/><axis xyz='0 0 1'/>"
        "<limit lower='0' upper='1'/></joint>"
        "<link name='b'><visual><origin xyz='.1 0 0'/><geometry><box size='.1 .1 .1'/></geometry></visual></link></robot>")
    common = ["--depth", str(tmp_path / "d8.png"), "--intrinsics", str(tmp_path / "K.json")]
    assert main(["predict", *common, "--category", "laptop"]) == 2
    err_predict = capsys.readouterr().err
    assert main(["fit-cad", "--urdf", str(urdf), *common]) == 2
    err_fit = capsys.readouterr().err
    assert "16-bit" in err_predict and "16-bit" in err_fit


def test_the_one_call_api_reads_files_and_predicts(table_scene, tmp_path):
    import ancsh

    depth, intr, source, _ = table_scene
    Image.fromarray(np.round(depth * 1000).astype(np.uint16)).save(tmp_path / "d.png")
    (tmp_path / "K.json").write_text(json.dumps(intr.to_json()))
    np.save(tmp_path / "mask.npy", source == 0)
    pred = ancsh.predict(tmp_path / "d.png", tmp_path / "K.json", "laptop", mask=tmp_path / "mask.npy")
    assert pred.result.ok and pred.to_json()["ancsh_version"] == ancsh.__version__


def test_a_folder_of_depth_images_gives_one_result_each(table_scene, tmp_path, capsys):
    depth, intr, _, _ = table_scene
    folder = tmp_path / "frames"
    folder.mkdir()
    Image.fromarray(np.round(depth * 1000).astype(np.uint16)).save(folder / "a_scene.png")
    np.save(folder / "b_wall.npy", np.full(depth.shape, 1.5))
    np.save(folder / "c_millimetres.npy", depth * 1000.0)
    (tmp_path / "K.json").write_text(json.dumps(intr.to_json()))
    code = main(["predict", "--depth", str(folder), "--intrinsics", str(tmp_path / "K.json"), "--category", "laptop",
                 "--out", str(tmp_path / "out"), "--png", str(tmp_path / "pics")])
    out = capsys.readouterr().out
    assert code == 1  # not every image succeeded
    assert json.loads((tmp_path / "out" / "a_scene.json").read_text())["ok"]
    assert not json.loads((tmp_path / "out" / "b_wall.json").read_text())["ok"]
    assert "c_millimetres.npy: error" in out and "millimetres" in out
    assert (tmp_path / "pics" / "a_scene.png").is_file() and (tmp_path / "pics" / "b_wall.png").is_file()


def test_picture_names_the_parts_and_draws_over_the_colour_image(table_scene, provider, tmp_path, capsys):
    from ancsh.learned.inference.predict import draw_prediction

    depth, intr, _, _ = table_scene
    pred = predict_depth(depth, intr, "laptop", provider=provider)
    rgb = np.zeros(depth.shape + (3,), dtype=np.uint8)
    rgb[..., 1] = 200
    fig = draw_prediction(depth, pred, intr, rgb=rgb)
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["base", "display"]
    assert any(np.asarray(im.get_array()).shape == rgb.shape for im in fig.axes[-1].get_images())
    Image.fromarray(rgb).save(tmp_path / "c.png")
    Image.fromarray(rgb[:10]).save(tmp_path / "small.png")
    args = ["predict", *_files(tmp_path, depth, intr), "--category", "laptop", "--png", str(tmp_path / "v.png")]
    assert main(args + ["--rgb", str(tmp_path / "small.png")]) == 2
    assert "rgb: expected an image" in capsys.readouterr().err
    assert main(args + ["--rgb", str(tmp_path / "c.png")]) == 0 and (tmp_path / "v.png").stat().st_size > 0


def test_a_residual_far_above_validation_fails_the_fit(table_scene, provider):
    import dataclasses

    from ancsh.learned.inference.predict import MAX_RELATIVE_RESIDUAL, check_plausibility

    depth, intr, _, _ = table_scene
    pred = predict_depth(depth, intr, "laptop", provider=provider)
    assert pred.result.ok
    typical = CATEGORY_INFO["laptop"].typical_size
    assert all(q["residual_m"] < MAX_RELATIVE_RESIDUAL * typical for q in pred.part_quality)
    bad = list(pred.part_quality)
    bad[1] = dict(bad[1], residual_m=2 * MAX_RELATIVE_RESIDUAL * typical)
    laptop = CONVENTIONS["laptop"]
    checked = check_plausibility(pred.result, pred.part_labels, laptop, bad)
    assert checked.status.value == "large_residual" and "display" in checked.message
    assert check_plausibility(dataclasses.replace(pred.result), pred.part_labels, laptop, pred.part_quality).ok
    with pytest.raises(ValueError, match="convention: expected a CategoryConvention or None, got 'laptop'"):
        check_plausibility(pred.result, pred.part_labels, "laptop", bad)  # a name is resolved once, by the caller


# --- nearly closed hinges ----------------------------------------------------------------------
def test_a_nearly_closed_laptop_gets_the_hinge_note_and_an_open_one_does_not(table_scene, provider):
    from ancsh.learned.inference.predict import NEAR_CLOSED_DEG

    laptop = load_instance("laptop", "test", 0)
    q = np.array([np.radians(6.0)])
    view = ModelRenderer(laptop).render(q, look_at([0.1, 0.55, 0.75], [0.0, 0.05, 0.0], [0, 1, 0]),
                                        Intrinsics.kinect(320, 240))
    pred = predict_depth(view.depth, view.intrinsics, "laptop", provider=provider, mask=view.depth > 0)
    opening = np.degrees(pred.to_json()["joints"][0]["state_abs"])
    assert pred.result.ok and opening <= NEAR_CLOSED_DEG
    assert sum("from closed" in n for n in pred.notes) == 1
    assert any(n.startswith(f"display_hinge fitted {opening:.1f} deg from closed") for n in pred.notes)
    depth, intr, _, _ = table_scene  # 110 deg open
    assert not any("from closed" in n for n in predict_depth(depth, intr, "laptop", provider=provider).notes)


def test_the_hinge_note_follows_the_convention_closed_state_and_joint_type(table_scene, provider):
    import dataclasses

    from ancsh.data.conventions import convention
    from ancsh.learned.inference.checks import NEAR_CLOSED_DEG, near_closed_notes

    depth, intr, _, _ = table_scene
    result = predict_depth(depth, intr, "laptop", provider=provider).result
    rest = convention("laptop").joints[0].rest  # display at right angles to the base: states are relative to it
    assert rest > np.radians(45)

    def notes(category, opening_deg, K=1):
        states = np.full(K, np.radians(opening_deg) - (rest if category == "laptop" else 0.0))
        return near_closed_notes(CONVENTIONS.get(category), dataclasses.replace(result, joint_states=states),
                                 [f"j{k}" for k in range(K)])

    assert len(notes("laptop", NEAR_CLOSED_DEG - 0.1)) == 1 and notes("laptop", NEAR_CLOSED_DEG + 0.1) == []
    assert len(notes("laptop", -3.0)) == 1  # folded past closed: the distance from closed counts
    assert len(notes("oven", 2.0)) == 1 and len(notes("box", 2.0)) == 1
    assert notes("eyeglasses", 0.0, K=2) == []  # state 0 is perpendicular, not closed
    assert notes("drawer", 0.0, K=3) == []  # prismatic
    assert notes("laptop", 2.0, K=2) == [] and notes("no_such_category", 2.0) == []  # joints do not match
