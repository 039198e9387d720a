"""The numpy ray caster against open3d's RaycastingScene, and the renderer's two backends against each other."""

import numpy as np
import open3d as o3d
import pytest

from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.data.raycast import CameraRayCaster
from ancsh.data.render import ModelRenderer, sample_viewpoint, viewpoint_range


def _open3d_cast(meshes, directions):
    scene = o3d.t.geometry.RaycastingScene()
    ids = [scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
           for v, f in meshes]
    rays = np.zeros((len(directions), 6), dtype=np.float32)
    rays[:, 3:] = directions
    hit = scene.cast_rays(o3d.core.Tensor(rays))
    t = hit["t_hit"].numpy().astype(np.float64)
    gid = hit["geometry_ids"].numpy().astype(np.int64)
    geometry = np.full(len(t), -1)
    for j, g in enumerate(ids):
        geometry[np.isfinite(t) & (gid == g)] = j
    return t, geometry


def _triangle_soup(rng, count, z_range):
    centres = np.column_stack([rng.uniform(-0.5, 0.5, count), rng.uniform(-0.4, 0.4, count), rng.uniform(*z_range, count)])
    v = (centres[:, None, :] + rng.normal(scale=0.15, size=(count, 3, 3))).reshape(-1, 3)
    return v, np.arange(3 * count).reshape(-1, 3)


@pytest.mark.parametrize("near", [False, True])
def test_nearest_hits_match_open3d_on_random_triangles(near):
    """Random triangles in three meshes; with ``near`` some reach behind the camera plane (the brute-force path)."""
    rng = np.random.default_rng(7 + near)
    meshes = [_triangle_soup(rng, 60, (0.1, 0.6) if near else (0.8, 2.0)) for _ in range(3)]
    if near:
        assert any(np.any(v[:, 2] <= 0) for v, _ in meshes)
    directions = np.column_stack([rng.uniform(-0.8, 0.8, 20000), rng.uniform(-0.6, 0.6, 20000), np.ones(20000)])
    directions *= rng.uniform(0.5, 2.0, (len(directions), 1))  # not only z = 1 directions
    t, geometry = CameraRayCaster(meshes).cast(directions)
    t_ref, geometry_ref = _open3d_cast(meshes, directions)
    same = np.isfinite(t) == np.isfinite(t_ref)
    assert same.mean() > 0.999  # rays grazing a triangle's edge may differ in float32 vs float64
    both = np.isfinite(t) & np.isfinite(t_ref)
    assert both.sum() > 5000
    np.testing.assert_allclose(t[both], t_ref[both], rtol=1e-4)
    assert (geometry[both] == geometry_ref[both]).mean() > 0.999
    assert np.all(geometry[~np.isfinite(t)] == -1)


def test_cast_keeps_the_shape_and_handles_rays_behind_the_camera():
    square = (np.array([[-1, -1, 2], [1, -1, 2], [1, 1, 2], [-1, 1, 2]], float), np.array([[0, 1, 2], [0, 2, 3]]))
    caster = CameraRayCaster([(np.empty((0, 3)), np.empty((0, 3), int)), square])
    d = np.zeros((2, 3, 3))
    d[..., 2] = 1.0
    d[1, :, 2] = -1.0  # looking backwards: no hit
    d[0, 2] = [0.2, -0.15, 0.5]  # through (0.8, -0.6, 2) on the square: t = 4
    t, geometry = caster.cast(d)
    assert t.shape == geometry.shape == (2, 3)
    np.testing.assert_allclose(t[0], [2.0, 2.0, 4.0])
    assert np.all(geometry[0] == 1) and np.all(geometry[1] == -1) and np.all(np.isinf(t[1]))


def test_caster_errors():
    with pytest.raises(ValueError, match=r"meshes\[0\]"):
        CameraRayCaster([(np.zeros((3, 3)), np.array([[0, 1, 3]]))])
    with pytest.raises(ValueError, match="directions"):
        CameraRayCaster([]).cast(np.zeros((4, 2)))
    t, g = CameraRayCaster([]).cast(np.ones((4, 3)))
    assert np.all(np.isinf(t)) and np.all(g == -1)


@pytest.mark.parametrize("category", ["laptop", "eyeglasses", "drawer"])
def test_renderer_backends_agree_on_procedural_objects(category):
    gen = FrameGenerator(GenerationConfig(category=category, split="test"))
    rng = np.random.default_rng(3)
    for index in range(2):
        model, _ = gen.instance(index)
        q = model.random_states(rng)
        T = sample_viewpoint(viewpoint_range(category), rng, model, q)
        a = ModelRenderer(model, backend="open3d").render(q, T, visibility=True)
        b = ModelRenderer(model, backend="numpy").render(q, T, visibility=True)
        assert (a.part_ids >= 0).sum() > 1000
        assert np.mean(a.part_ids != b.part_ids) < 1e-3
        both = (a.depth > 0) & (b.depth > 0)
        np.testing.assert_allclose(b.depth[both], a.depth[both], atol=1e-5)
        np.testing.assert_allclose(b.visibility, a.visibility, atol=0.01)


def test_renderer_backend_errors():
    gen = FrameGenerator(GenerationConfig(category="laptop", split="test"))
    model, _ = gen.instance(0)
    with pytest.raises(ValueError, match="backend"):
        ModelRenderer(model, backend="embree")
    assert ModelRenderer(model, backend="auto").backend == "open3d"  # open3d is installed here
