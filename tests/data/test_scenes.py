"""Rendered scenes around a test frame (ancsh.data.scenes)."""

import numpy as np
import pytest

from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.data.scenes import curtain_mesh, render_scene


@pytest.fixture(scope="module")
def gen():
    return FrameGenerator(GenerationConfig(category="laptop", split="test", seed=3))


def test_a_curtain_folds_about_its_plane_and_a_flat_one_is_a_wall():
    mesh = curtain_mesh(2.0, 1.5, 0.05, 0.4)
    assert np.allclose(mesh.bounds[:, :2], [[-1.0, 0.0], [1.0, 1.5]])
    assert 0.045 < mesh.vertices[:, 2].max() <= 0.05 and -0.05 <= mesh.vertices[:, 2].min() < -0.045
    assert 2.0 * 1.5 < mesh.area < 1.2 * 2.0 * 1.5  # the folds add area
    assert np.ptp(curtain_mesh(2.0, 1.5, 0.0, 0.4).vertices[:, 2]) == 0.0
    with pytest.raises(ValueError, match="wavelength"):
        curtain_mesh(2.0, 1.5, 0.05, 0.0)


@pytest.mark.parametrize("stairs", [False, True])
def test_the_object_stands_in_front_of_its_surroundings_and_leaves_them_unchanged(gen, stairs):
    frame = gen.frame(0)
    _, renderer = gen.instance(frame.instance_index)
    bare = renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth
    scene = render_scene(gen, 0, 7, stairs=stairs)
    empty = render_scene(gen, 0, 7, stairs=stairs, with_object=False)
    assert scene.support == empty.support == ("stairs" if stairs else "floor") and not empty.visible.any()
    v = scene.visible
    assert np.array_equal(scene.depth[v], bare[v]) and v.sum() > 0.8 * (bare > 0).sum()
    assert (scene.depth > 0).mean() > 0.9  # support and wall fill the view around the object
    assert np.array_equal(scene.depth[~v], empty.depth[~v])  # the same surroundings, with and without the object
    assert np.all(empty.depth[v] >= scene.depth[v] - 1e-9)  # what the object hides lies behind it
    again = render_scene(gen, 0, 7, stairs=stairs)
    assert np.array_equal(again.depth, scene.depth) and scene.frame.frame_index == frame.frame_index


def test_clutter_pixels_are_labelled_with_the_piece_they_show(gen):
    """The clutter label image marks each piece's nearest pixels; every kind is one of clutter_model's."""
    found = False
    for seed in range(12):
        scene = render_scene(gen, 0, seed, with_object=False)
        assert scene.clutter.shape == scene.depth.shape and scene.clutter.min() >= -1
        assert scene.clutter.max() < len(scene.clutter_kinds)
        for kind in scene.clutter_kinds:
            assert set(kind.split("+")) <= {"box", "slab", "cylinder", "sphere", "wall"}
        if len(scene.clutter_kinds) and (scene.clutter >= 0).any():
            found = True
            labelled = scene.clutter >= 0
            assert np.all(scene.depth[labelled] > 0)
    assert found


def test_the_nearest_surface_is_seen_and_labelled_with_its_thing():
    from ancsh.data.scenes import nearest_surface

    a = np.array([[1.0, 0.0, 2.0], [0.0, 0.0, 3.0]])
    b = np.array([[1.5, 0.7, 1.0], [0.0, 0.0, 3.0]])
    depth, nearest = nearest_surface([a, b])
    assert np.array_equal(depth, [[1.0, 0.7, 1.0], [0.0, 0.0, 3.0]])
    assert np.array_equal(nearest, [[0, 1, 1], [-1, -1, 0]])  # a tie goes to the first
