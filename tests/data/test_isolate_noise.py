"""Isolation far from the camera: the sensor's noise measured in the image, planes found on smoothed points within it
(ancsh.data.isolate.noise), so that a cabinet standing on a floor 4.5 m away comes apart from the floor."""

import numpy as np
import pytest
import trimesh

from ancsh.data.conventions import CONVENTIONS
from ancsh.data.isolate import isolate_object
from ancsh.data.isolate.noise import noise_sigma, plane_points, smooth_grid
from ancsh.data.noise import DepthNoise, apply_noise
from ancsh.data.render import Intrinsics, ModelRenderer, look_at
from ancsh.data.scenes import nearest_surface
from ancsh.model.articulated import ArticulatedModel, Part


def _noisy_plane(sigma_of_z, rng, shape=(120, 160)):
    """Grid points of a tilted plane from 1 to 5 m deep (rows), with Gaussian depth noise ``sigma_of_z(z)``."""
    h, w = shape
    z = np.linspace(1.0, 5.0, h)[:, None] * np.ones((1, w))
    x = (np.arange(w)[None, :] - w / 2) * 0.01 * z
    y = np.zeros_like(z)
    noisy = z + rng.normal(size=z.shape) * sigma_of_z(z)
    return np.stack([x, y, noisy], axis=-1), np.ones(shape, dtype=bool)


def test_the_noise_measured_on_a_plane_follows_its_depth():
    rng = np.random.default_rng(3)
    model = lambda z: 0.001 + 0.002 * z ** 2  # noqa: E731 - the sensor's noise (metres) at depth z
    P, gv = _noisy_plane(model, rng)
    smoothed, counts = smooth_grid(P, gv, np.full(gv.shape, 1.0))
    sigma = noise_sigma(P, smoothed, counts, gv)
    for row in (20, 60, 100):  # about 1.7, 3.0 and 4.4 m
        true = model(np.median(P[row, :, 2]))
        assert sigma[row].mean() == pytest.approx(true, rel=0.25)


def test_points_stay_as_measured_where_the_noise_is_within_the_plane_tolerance():
    rng = np.random.default_rng(4)
    P, gv = _noisy_plane(lambda z: 0.001 + 0.0015 * z ** 2, rng)
    Q, tolerance = plane_points(P, gv, np.full(gv.shape, 1.0), 0.012)
    near = P[..., 2] < 1.15  # 3 sigma below 12 mm (it reaches 12 mm at about 1.3 m)
    far = P[..., 2] > 3.0
    assert np.array_equal(Q[near], P[near]) and np.all(tolerance[near] == 0.012)
    assert not np.allclose(Q[far], P[far])
    # the smoothed far points scatter less about the plane (y = 0 before the depth noise: their x/z ratio is exact)
    assert np.std(Q[far][:, 2] - np.median(Q[far][:, 2])) < np.std(P[far][:, 2] - np.median(P[far][:, 2]))
    assert np.all(tolerance >= 0.012)


def test_a_clean_plane_has_no_noise_and_no_smoothing():
    P, gv = _noisy_plane(lambda z: 0.0 * z, np.random.default_rng(0))
    Q, tolerance = plane_points(P, gv, np.full(gv.shape, 1.0), 0.012)
    assert np.array_equal(Q, P) and np.all(tolerance == 0.012)


def _far_cabinet(distance, noise):
    """Depth (1280x960), intrinsics and the cabinet's pixels: a 0.6 x 0.9 x 0.6 m cabinet on a 12 x 12 m floor,
    seen from ``distance`` metres at a downward slant, with the dataset's sensor noise (or none)."""
    floor = trimesh.creation.box((12.0, 0.02, 12.0))
    floor.apply_translation([0, -0.01, 0])
    cabinet = trimesh.creation.box((0.6, 0.9, 0.6))
    cabinet.apply_translation([0.3, 0.45, 0.2])
    intr = Intrinsics(fx=1050.0, fy=1050.0, cx=639.5, cy=479.5, width=1280, height=960)
    T_cam_world = look_at([0.0, 0.45 * distance, distance], [0.0, 0.3, 0.0], [0, 1, 0])
    views = [ModelRenderer(ArticulatedModel((Part(n, m),), (), name=n)).render(np.zeros(0), T_cam_world, intr)
             for n, m in (("cabinet", cabinet), ("floor", floor))]
    depth, nearest = nearest_surface([v.depth for v in views])
    is_cabinet = nearest == 0
    if noise:
        depth = apply_noise(depth, DepthNoise(), np.random.default_rng(7))
    return depth, intr, is_cabinet & (depth > 0)


@pytest.mark.parametrize("distance", [2.0, 4.5])
def test_a_cabinet_far_on_a_noisy_floor_is_a_candidate_of_its_own(distance):
    depth, intr, truth = _far_cabinet(distance, noise=True)
    iso = isolate_object(depth, intr, CONVENTIONS["washing_machine"].diagonal_range, rng=0)
    assert iso.planes >= 1
    best = max(np.count_nonzero(iso.mask_of(c) & truth) / np.count_nonzero(iso.mask_of(c) | truth) for c in iso.order)
    assert best >= 0.8
