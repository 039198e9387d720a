"""Oracle provider: exact ground truth, and each corruption knob changes only its own target."""

import numpy as np
import pytest

from ancsh.geometry.lines import axis_angle_error, line_distance
from ancsh.model.canonical import ancsh_ground_truth
from ancsh.model.synthetic import random_articulated_model, sample_frame
from ancsh.solvers.providers import CORRUPTION_PRESETS, Corruption, OracleProvider, corrupt_ground_truth
from ancsh.solvers.types import CorrespondenceProvider, Correspondences, Observation

FIELDS = ("part_labels", "npcs", "npcs_scale", "npcs_translation", "joint_axes_naocs", "joint_pivots_naocs")


def _frame(seed=3, parts=3, points=300):
    """A random 3-part chain (revolute and prismatic joints) seen from a random camera."""
    model = random_articulated_model(seed, num_parts=parts, joint_types=["revolute", "prismatic"][: parts - 1])
    fr = sample_frame(model, seed, points_per_part=points)
    gt = ancsh_ground_truth(model, fr.q, fr.T_cam_base, fr.points_cam, fr.part_labels)
    return gt, Observation(fr.points_cam)


@pytest.fixture(scope="module")
def frame():
    return _frame()


def _changed(a: Correspondences, b: Correspondences) -> set:
    return {f for f in FIELDS if not np.array_equal(getattr(a, f), getattr(b, f))}


def test_none_reproduces_ground_truth_exactly(frame):
    gt, obs = frame
    provider = OracleProvider(gt, "none", rng=0)
    assert isinstance(provider, CorrespondenceProvider)
    corr = provider.correspond(obs)
    exact = Correspondences.from_ground_truth(gt)
    assert _changed(corr, exact) == set()
    assert corr.joint_types == exact.joint_types
    np.testing.assert_array_equal(corr.npcs_extents, exact.npcs_extents)
    # the exact NPCS map back onto the observed points through the ground-truth poses
    for j, T in enumerate(gt.T_cam_npcs):
        sel = corr.part_labels == j
        np.testing.assert_allclose(T.apply(corr.npcs[sel]), obs.points_cam[sel], atol=1e-12)


@pytest.mark.parametrize(
    "knob, value, expected",
    [
        ("npcs_sigma", 0.05, {"npcs"}),
        ("npcs_warp", 0.05, {"npcs"}),
        ("outlier_fraction", 0.1, {"npcs"}),
        ("flip_radius", 0.05, {"part_labels", "npcs"}),
        ("axis_sigma_deg", 3.0, {"joint_axes_naocs"}),
        ("pivot_sigma", 0.02, {"joint_pivots_naocs"}),
        ("naocs_sigma", 0.02, {"npcs_scale", "npcs_translation"}),
    ],
)
def test_each_knob_changes_only_its_target(frame, knob, value, expected):
    gt, obs = frame
    sample = OracleProvider(gt, Corruption(**{knob: value}), rng=1).sample(obs)
    assert _changed(sample.correspondences, Correspondences.from_ground_truth(gt)) == expected
    assert sample.outliers.any() == (knob == "outlier_fraction")
    assert sample.flipped.any() == (knob == "flip_radius")


def test_knobs_draw_from_independent_streams(frame):
    gt, obs = frame
    alone = corrupt_ground_truth(gt, obs.points_cam, Corruption(axis_sigma_deg=2.0), 7).correspondences
    mixed = corrupt_ground_truth(gt, obs.points_cam, Corruption(axis_sigma_deg=2.0, npcs_sigma=0.1, pivot_sigma=0.1), 7)
    np.testing.assert_array_equal(alone.joint_axes_naocs, mixed.correspondences.joint_axes_naocs)


def test_npcs_noise_magnitude(frame):
    gt, obs = frame
    sigma = 0.04
    corr = OracleProvider(gt, Corruption(npcs_sigma=sigma), rng=2).correspond(obs)
    d = corr.npcs - gt.npcs
    assert abs(d.mean()) < 4 * sigma / np.sqrt(d.size)
    assert d.std() == pytest.approx(sigma, rel=0.05)


def test_npcs_warp_is_linear_per_part(frame):
    gt, obs = frame
    w = 0.05
    corr = OracleProvider(gt, Corruption(npcs_warp=w), rng=3).correspond(obs)
    for j in range(gt.num_parts):
        sel = gt.part_labels == j
        A, *_ = np.linalg.lstsq(gt.npcs[sel], corr.npcs[sel], rcond=None)
        np.testing.assert_allclose(gt.npcs[sel] @ A, corr.npcs[sel], atol=1e-10)
        assert 0 < np.abs(A - np.eye(3)).max() < 6 * w


def test_outliers_count_and_distribution(frame):
    gt, obs = frame
    n = len(gt.part_labels)
    sample = OracleProvider(gt, Corruption(outlier_fraction=0.25), rng=4).sample(obs)
    assert sample.outliers.sum() == round(0.25 * n)
    out = sample.correspondences.npcs[sample.outliers]
    assert np.all(np.abs(out) <= 0.5)
    assert out.std(axis=0) == pytest.approx(np.full(3, np.sqrt(1 / 12)), rel=0.15)
    np.testing.assert_array_equal(sample.correspondences.npcs[~sample.outliers], gt.npcs[~sample.outliers])


def test_label_flips_near_boundaries_reexpress_npcs(frame):
    gt, obs = frame
    radius = 0.05
    scale = gt.T_cam_naocs.scale
    sample = OracleProvider(gt, Corruption(flip_radius=radius, flip_fraction=1.0), rng=5).sample(obs)
    corr, flipped = sample.correspondences, sample.flipped
    assert flipped.any()
    np.testing.assert_array_equal(flipped, corr.part_labels != gt.part_labels)
    pts = obs.points_cam
    for i in np.nonzero(flipped)[0][:50]:
        new = corr.part_labels[i]
        d_new = np.linalg.norm(pts[gt.part_labels == new] - pts[i], axis=1).min()
        assert d_new / scale < radius
        np.testing.assert_allclose(gt.T_cam_npcs[new].apply(corr.npcs[i]), pts[i], atol=1e-12)
    # points far from every other part keep their label
    half = OracleProvider(gt, Corruption(flip_radius=radius, flip_fraction=0.5), rng=6).sample(obs)
    assert 0.3 < half.flipped.sum() / flipped.sum() < 0.7


def test_joint_noise_magnitudes(frame):
    gt, obs = frame
    sigma_deg, sigma_p = 2.0, 0.03
    provider = OracleProvider(gt, Corruption(axis_sigma_deg=sigma_deg, pivot_sigma=sigma_p), rng=8)
    angles, offsets = [], []
    only_pivot = OracleProvider(gt, Corruption(pivot_sigma=sigma_p), rng=9)
    for _ in range(150):
        c = provider.correspond(obs)
        angles += [np.degrees(axis_angle_error(a, b)) for a, b in zip(c.joint_axes_naocs, gt.joint_axes_naocs)]
        p = only_pivot.correspond(obs)
        for k in range(gt.num_joints):
            off = p.joint_pivots_naocs[k] - gt.joint_pivots_naocs[k]
            assert abs(off @ gt.joint_axes_naocs[k]) < 1e-12  # perpendicular to the axis
            offsets.append(line_distance(p.joint_pivots_naocs[k], gt.joint_axes_naocs[k],
                                         gt.joint_pivots_naocs[k], gt.joint_axes_naocs[k]))
    assert np.mean(angles) == pytest.approx(sigma_deg * np.sqrt(2 / np.pi), rel=0.12)  # half-normal mean
    assert np.mean(offsets) == pytest.approx(sigma_p * np.sqrt(np.pi / 2), rel=0.12)  # Rayleigh mean


def test_naocs_noise_magnitude(frame):
    gt, obs = frame
    sigma = 0.02
    provider = OracleProvider(gt, Corruption(naocs_sigma=sigma), rng=10)
    logs, dts = [], []
    for _ in range(200):
        c = provider.correspond(obs)
        logs.append(np.log(c.npcs_scale / gt.npcs_scale))
        dts.append(c.npcs_translation - gt.npcs_translation)
    assert np.std(logs) == pytest.approx(sigma, rel=0.1)
    assert np.std(dts) == pytest.approx(sigma, rel=0.1)


def test_same_seed_same_corruption_and_fresh_draws_per_call(frame):
    gt, obs = frame
    a = OracleProvider(gt, "realistic", rng=11)
    b = OracleProvider(gt, "realistic", rng=11)
    first = a.correspond(obs)
    np.testing.assert_array_equal(first.npcs, b.correspond(obs).npcs)
    assert not np.array_equal(first.npcs, a.correspond(obs).npcs)


def test_presets_are_ordered():
    names = ["none", "low", "realistic", "high"]
    assert list(CORRUPTION_PRESETS) == names
    assert Corruption.preset("none").is_clean
    for lo, hi in zip(names, names[1:]):
        a, b = Corruption.preset(lo), Corruption.preset(hi)
        assert a.npcs_sigma <= b.npcs_sigma and a.outlier_fraction <= b.outlier_fraction
        assert a.axis_sigma_deg <= b.axis_sigma_deg and a.flip_radius <= b.flip_radius


def test_errors(frame):
    gt, obs = frame
    with pytest.raises(ValueError, match="unknown preset 'medium'"):
        Corruption.preset("medium")
    with pytest.raises(ValueError, match="npcs_sigma"):
        Corruption(npcs_sigma=-0.1)
    with pytest.raises(ValueError, match="outlier_fraction"):
        Corruption(outlier_fraction=1.5)
    with pytest.raises(ValueError, match="axis_sigma_deg"):
        Corruption(axis_sigma_deg=float("nan"))
    with pytest.raises(ValueError, match="corruption"):
        OracleProvider(gt, 3, rng=0)
    with pytest.raises(ValueError, match="frame_or_ground_truth"):
        OracleProvider(object(), "none", rng=0)
    with pytest.raises(ValueError, match="observation: has 5 points"):
        OracleProvider(gt, "none", rng=0).correspond(Observation(np.zeros((5, 3))))
    with pytest.raises(ValueError, match="observation: expected an Observation"):
        OracleProvider(gt, "none", rng=0).correspond(obs.points_cam)


def test_frame_like_source(frame):
    gt, obs = frame

    class FrameLike:
        def __init__(self):
            self.gt = gt
            self.points = obs.points_cam

    corr = OracleProvider(FrameLike(), "none", rng=0).correspond(obs)
    np.testing.assert_array_equal(corr.npcs, gt.npcs)
