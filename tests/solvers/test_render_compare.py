"""Render-and-compare (ancsh.solvers.render_compare): what a fitted model explains of the observed depth."""

import numpy as np
import pytest

from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.learned.inference.predict import predict_depth
from ancsh.solvers.render_compare import aligned_comparison, compare_depth, crop_intrinsics, mask_window, occluding_pixels


def test_explained_see_through_and_occlusion_are_told_apart():
    observed = np.full((10, 10), 1.0)
    observed[:, 8:] = 0.0  # no measurement
    mask = np.zeros((10, 10), dtype=bool)
    mask[:, :6] = True
    model = np.zeros((10, 10))
    model[:, :4] = 1.005  # explains 4 of the 6 object columns
    model[:, 4:6] = 0.7  # the sensor sees 30 cm beyond: see-through
    model[:, 6:8] = 1.3  # the sensor saw something nearer: an occlusion, neither explained nor see-through: hidden
    c = compare_depth(model, observed, mask)
    assert c.object_pixels == 60 and c.model_pixels == 80
    assert c.explained == pytest.approx(40 / 60)
    assert c.see_through == pytest.approx(20 / 80)
    assert c.hidden == pytest.approx(20 / 80) and c.to_dict()["hidden"] == c.hidden
    assert c.median_abs_residual_m == pytest.approx(0.005)
    assert np.isnan(c.residual[0, 9]) and c.residual[0, 5] == pytest.approx(0.3)
    with pytest.raises(ValueError, match="one shape"):
        compare_depth(model[:5], observed, mask)


def test_pixels_in_front_of_the_model_are_occluders_measured_from_its_offset():
    H, W = 60, 80
    mask = np.zeros((H, W), dtype=bool)
    mask[20:40, 20:60] = True
    u0, v0, u1, v1 = mask_window(mask)
    observed = np.full((H, W), 1.0)
    observed[25:32, 30:38] = 0.9  # a toy in the box, 10 cm in front of its surface
    observed[35, 50] = 0.0  # a hole
    for behind in (0.0, 0.03):  # a model on the surface, and one fitted 3 cm behind it throughout
        model = np.zeros((H, W))
        model[20:40, 20:60] = 1.0 + behind
        c = compare_depth(model[v0:v1, u0:u1], observed[v0:v1, u0:u1], mask[v0:v1, u0:u1])
        occluded = occluding_pixels(c, observed, mask)
        expected = np.zeros((H, W), dtype=bool)
        expected[25:32, 30:38] = True
        assert np.array_equal(occluded, expected), behind
    # a model in front of the observed surface takes no object pixel for an occluder
    flat = np.full((H, W), 1.0)
    c = compare_depth((model - 0.09)[v0:v1, u0:u1], flat[v0:v1, u0:u1], mask[v0:v1, u0:u1])
    assert c.see_through > 0.9 and not occluding_pixels(c, flat, mask).any()
    with pytest.raises(ValueError, match="comparison"):  # compared in another mask's window
        occluding_pixels(c, flat, np.roll(mask, 5, axis=1) | np.roll(mask, 12, axis=0))
    with pytest.raises(ValueError, match="depth, object_mask"):
        occluding_pixels(c, flat[:50], mask)


def test_an_aligned_comparison_is_the_comparison_of_the_model_moved_along_the_depth_axis():
    rng = np.random.default_rng(5)
    H, W = 40, 50
    mask = np.zeros((H, W), dtype=bool)
    mask[10:30, 12:40] = True
    u0, v0, u1, v1 = mask_window(mask)
    observed = 2.0 + 0.01 * rng.standard_normal((H, W))
    observed[rng.random((H, W)) < 0.1] = 0.0  # holes
    model = np.zeros((H, W))
    model[8:32, 10:42] = 1.9 + 0.01 * rng.standard_normal((24, 32))  # ~10 cm before the surface, a bit wider
    window = (slice(v0, v1), slice(u0, u1))
    raw = compare_depth(model[window], observed[window], mask[window])
    assert raw.see_through > 0.7 and raw.explained < 0.3 and raw.shift_m == 0.0
    aligned = aligned_comparison(raw, observed, mask, max_shift_m=1.0)
    on = mask & (observed > 0) & (model > 0)
    shift = float(np.median((observed - model)[on]))
    assert aligned.shift_m == pytest.approx(shift) and 0.08 < shift < 0.12
    moved = compare_depth(np.where(model > 0, model + shift, 0.0)[window], observed[window], mask[window])
    for field in ("explained", "see_through", "hidden", "median_abs_residual_m", "object_pixels", "model_pixels"):
        assert getattr(aligned, field) == pytest.approx(getattr(moved, field)), field
    assert aligned.explained > 0.8 and aligned.to_dict()["shift_m"] == aligned.shift_m
    clipped = aligned_comparison(raw, observed, mask, max_shift_m=0.02)  # moved at most 2 cm: still mostly before it
    assert clipped.shift_m == pytest.approx(0.02) and clipped.see_through > 0.5
    elsewhere = np.zeros((H, W), dtype=bool)
    elsewhere[0:2, 0:2] = True  # no object pixel with model depth: nothing to align on
    e0, f0, e1, f1 = mask_window(elsewhere)
    far = compare_depth(np.zeros((H, W))[f0:f1, e0:e1], observed[f0:f1, e0:e1], elsewhere[f0:f1, e0:e1])
    assert aligned_comparison(far, observed, elsewhere, max_shift_m=1.0) is far
    with pytest.raises(ValueError, match="max_shift_m"):
        aligned_comparison(raw, observed, mask, max_shift_m=-0.1)
    with pytest.raises(ValueError, match="comparison"):
        aligned_comparison(raw, observed, elsewhere, max_shift_m=1.0)


def test_a_crop_keeps_the_projection():
    from ancsh.data.render import Intrinsics, project

    intr = Intrinsics()
    mask = np.zeros((intr.height, intr.width), dtype=bool)
    mask[100:140, 200:260] = True
    box = mask_window(mask)
    assert box == (170, 80, 290, 160)
    crop = crop_intrinsics(intr, box)
    p = np.array([[0.1, -0.05, 1.2]])
    assert project(p, crop)[0] + np.array([box[0], box[1]]) == pytest.approx(project(p, intr)[0])


def test_a_coarse_render_sees_block_centres_and_spreads_back_over_the_window():
    from ancsh.data.render import Intrinsics, project
    from ancsh.geometry.transforms import Sim3
    from ancsh.solvers.render_compare import (COMPARE_RAYS, coarse_intrinsics, compare_stride, upsample_depth)

    assert compare_stride(COMPARE_RAYS) == 1 and compare_stride(COMPARE_RAYS + 1) == 2
    assert compare_stride(9 * COMPARE_RAYS) == 3 and compare_stride(0) == 1
    with pytest.raises(ValueError, match="rays"):
        compare_stride(10, rays=0)
    intr = Intrinsics(fx=600.0, fy=590.0, cx=301.3, cy=243.7, width=641, height=479)
    for s in (1, 2, 3):
        coarse = coarse_intrinsics(intr, s)
        assert (coarse.width, coarse.height) == (-(-641 // s), -(-479 // s))
        p = np.random.default_rng(s).uniform([-0.2, -0.2, 0.8], [0.2, 0.2, 1.5], size=(20, 3))
        # a point seen at coarse pixel x is seen at full pixel s x + (s - 1) / 2: the centre of its block
        assert project(p, coarse)[0] * s + 0.5 * (s - 1) == pytest.approx(project(p, intr)[0])
        full = upsample_depth(np.arange(coarse.width * coarse.height, dtype=float).reshape(coarse.height, -1), s,
                              (479, 641))
        assert full.shape == (479, 641) and full[s * 7 + s - 1, s * 5] == 7 * coarse.width + 5
    with pytest.raises(ValueError, match="does not cover"):
        upsample_depth(np.zeros((10, 10)), 2, (30, 20))
    # the shares of a comparison at a coarse render are the full one's to within the blocks on the silhouette
    gen = FrameGenerator(GenerationConfig(category="box", split="test", seed=3))
    frame = gen.frame(0)
    _, renderer = gen.instance(frame.instance_index)
    big = Intrinsics(fx=1200.0, fy=1200.0, cx=639.5, cy=479.5, width=1280, height=960)
    T = Sim3(frame.T_cam_base.rotation, frame.T_cam_base.translation * 0.6)
    observed = renderer.render(frame.joint_states_abs, T, big).depth
    mask = observed > 0
    moved = Sim3(T.rotation, T.translation + np.array([0.01, 0.0, 0.02]))  # a fit 1 cm aside, 2 cm behind
    exact = compare_depth(renderer.render(frame.joint_states_abs, moved, big).depth, observed, mask)
    s = compare_stride(int(mask.sum()) * 4)
    assert s >= 2
    coarse = renderer.render(frame.joint_states_abs, moved, coarse_intrinsics(big, s))
    approx = compare_depth(upsample_depth(coarse.depth, s, mask.shape), observed, mask)
    assert 0.1 < exact.explained < 0.9 and exact.hidden > 0.05  # a comparison with something to measure
    assert approx.explained == pytest.approx(exact.explained, abs=0.02)
    assert approx.see_through == pytest.approx(exact.see_through, abs=0.02)
    assert approx.hidden == pytest.approx(exact.hidden, abs=0.02)


def test_a_good_fit_explains_its_object_and_a_displaced_scene_does_not():
    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=5))
    frame = gen.frame(0)
    _, renderer = gen.instance(frame.instance_index)
    depth = renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth
    mask = depth > 0
    pred = predict_depth(depth, frame.intrinsics, "laptop", mask=mask)
    assert pred.result.ok and pred.render_compare is not None
    assert pred.render_compare.explained > 0.6 and pred.render_compare.see_through < 0.2
    data = pred.to_json()
    assert data["render_compare"]["explained"] == pytest.approx(pred.render_compare.explained)
    # the same fit against the scene pushed 30 cm back: the sensor sees through the model everywhere
    from ancsh.solvers.render_compare import compare_depth as cmp

    far = np.where(mask, depth + 0.3, 0.0)
    from ancsh.data.templates import load_template_library
    from ancsh.learned.inference.predict import infer
    from ancsh.learned.inference.provider import LearnedProvider
    from ancsh.solvers import Observation
    from ancsh.solvers.twin import render_fit

    provider = LearnedProvider("laptop", seed=0)
    corr, _ = infer(provider, Observation(pred.points_cam))
    model_depth, _ = render_fit(pred.result, corr, load_template_library("laptop"), frame.intrinsics)
    moved = cmp(model_depth, far, mask)
    assert moved.explained < 0.05 and moved.see_through > 0.8
