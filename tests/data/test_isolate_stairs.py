"""Isolation on a staircase seen from above, as in the real frames: thin risers, a sensor's dead band along one side,
depth smoothed like a real sensor's, a box whose open lid leans back toward the riser behind it."""

import numpy as np
import pytest
import trimesh
from scipy.ndimage import gaussian_filter

from ancsh.data.conventions import CONVENTIONS
from ancsh.data.isolate import isolate_object
from ancsh.data.isolate.planes import view_border
from ancsh.data.procedural import load_instance
from ancsh.data.render import Intrinsics, ModelRenderer, look_at
from ancsh.data.scenes import nearest_surface
from ancsh.learned.inference.predict import MAX_VERIFIED
from ancsh.model.articulated import ArticulatedModel, Part


def _smoothed(depth, sigma):
    """Depth blurred within its valid pixels (a real sensor's depth is smooth across edges)."""
    valid = depth > 0
    num = gaussian_filter(np.where(valid, depth, 0.0), sigma)
    den = gaussian_filter(valid.astype(float), sigma)
    return np.where(valid, num / np.maximum(den, 1e-9), 0.0)


def stairs_scene(eye, *, opening_deg=110.0, dead_band=10, sigma=4.0):
    """Depth (1280x720, metres), intrinsics and the box's pixels: a box of the test split on the lowest tread of five
    steps (0.17 m rise, 0.3 m going), its back 0.1 m from the riser behind it, seen from ``eye``."""
    box = load_instance("box", "test", 0)
    meshes = []
    for k in range(5):  # treads (+y up) stepping back (-z), a riser in front of each but the lowest
        tread = trimesh.creation.box((2.4, 0.03, 0.3 if k else 0.9))
        tread.apply_translation([0, 0.17 * k - 0.015, -0.2 - 0.3 * k + 0.15 if k else 0.25])
        riser = trimesh.creation.box((2.4, 0.17, 0.03))
        riser.apply_translation([0, 0.17 * k + 0.085, -0.2 - 0.3 * k - 0.015])
        meshes += [tread, riser]
    stairs = ArticulatedModel((Part("stairs", trimesh.util.concatenate(meshes)),), (), name="stairs")
    T_cam_world = look_at(list(eye), [0.0, 0.12, -0.15], [0, 1, 0])
    intr = Intrinsics.kinect(1280, 720)
    views = [ModelRenderer(box).render(np.array([np.radians(opening_deg)]), T_cam_world, intr),
             ModelRenderer(stairs).render(np.zeros(0), T_cam_world, intr)]
    depth, nearest = nearest_surface([v.depth for v in views])
    is_box = nearest == 0
    depth[:, :dead_band] = 0.0  # a depth sensor's dead band along the left edge
    return _smoothed(depth, sigma) if sigma else depth, intr, is_box & (depth > 0)


def _best_iou(iso, truth, first: int) -> float:
    return max(float(np.count_nonzero(iso.mask_of(c) & truth) / np.count_nonzero(iso.mask_of(c) | truth))
               for c in iso.order[:first])


@pytest.mark.parametrize("eye", [(0.35, 1.0, 0.95), (0.3, 1.3, 0.6)])
def test_a_box_on_smoothed_stairs_is_one_of_the_verified_candidates(eye):
    depth, intr, truth = stairs_scene(eye)
    iso = isolate_object(depth, intr, CONVENTIONS["box"].diagonal_range, rng=0)
    # the risers run into the dead band and out of the image: removed with the treads, the box comes apart whole
    assert _best_iou(iso, truth, MAX_VERIFIED) >= 0.85


def test_the_view_border_includes_a_dead_band_joined_to_the_edge_but_not_holes_inside():
    gv = np.ones((40, 60), dtype=bool)
    gv[:, :5] = False  # dead band along the left edge
    gv[18:22, 28:32] = False  # a hole inside the image
    border = view_border(gv)
    assert not border[~gv].any()
    assert border[20, 5] and border[20, 7]  # beside the dead band
    assert not border[20, 26] and not border[17, 30]  # beside the inner hole: no border
    assert border[0, 30] and border[39, 30] and border[20, 59]


def test_a_wall_seen_around_nearer_things_lies_behind_them_and_an_object_before_a_wall_does_not():
    from ancsh.data.isolate import behind_surroundings

    depth = np.full((120, 160), 2.0)  # a wall
    depth[30:90, 20:60] = 1.2  # a cabinet in front of it
    depth[30:90, 100:140] = 1.0  # and another
    wall_between = np.zeros(depth.shape, dtype=bool)
    wall_between[30:90, 60:100] = True  # the strip of wall between them: jumps to nearer surfaces on both sides
    background, jumps, behind = behind_surroundings(depth, wall_between)
    assert background and behind == 1.0 and jumps >= 0.2
    cabinet = np.zeros(depth.shape, dtype=bool)
    cabinet[30:90, 20:60] = True
    assert behind_surroundings(depth, cabinet)[:1] == (False,) and behind_surroundings(depth, cabinet)[2] == 0.0
    flat = np.full((120, 160), 1.5)  # no jump around a patch: nothing says it is behind
    assert behind_surroundings(flat, cabinet) == (False, 0.0, pytest.approx(float("nan"), nan_ok=True))
    with pytest.raises(ValueError, match="depth, mask"):
        behind_surroundings(depth[:100], cabinet)


def _grid_points(g):
    """Points of a grid of depths ``g`` seen 1 cm apart (a stand-in for the back-projected grid)."""
    vv, uu = np.mgrid[0:g.shape[0], 0:g.shape[1]]
    return np.stack([0.01 * uu, 0.01 * vv, g], axis=-1)


def test_a_door_parted_by_a_depth_step_is_attached_to_its_object_in_a_second_candidate():
    from ancsh.data.isolate.proposals import component_members, with_attached

    seg = np.full((30, 30), -1)
    g = np.full((30, 30), 2.0)
    seg[2:14, 2:14], g[2:14, 2:14] = 0, 1.0  # the object's body
    seg[6:12, 14:18], g[6:12, 14:18] = 1, 1.08  # a door ajar beside it, 8 cm nearer
    seg[2:6, 14:18], g[2:6, 14:18] = 2, 1.6  # something far behind, touching it in the image
    seg[14:30, :], g[14:30, :] = 3, 1.02  # a larger neighbour close by: not attached to the smaller body
    sizes = np.bincount(seg[seg >= 0])
    P = _grid_points(g)
    with_door = with_attached(seg, 0, sizes, P, 0.15)
    assert np.array_equal(with_door, np.isin(seg, [0, 1]))
    assert np.array_equal(with_attached(seg, 0, sizes, P, 0.05), seg == 0)  # a tighter gap: the body alone
    assert np.array_equal(with_attached(seg, 0, sizes, P, 0.15, largest=0.15), seg == 0)  # body and door too wide
    assert np.array_equal(with_attached(seg, 2, sizes, P, 0.15), seg == 2)  # nothing smaller touches it closely
    assert np.array_equal(with_attached(seg, 3, sizes, P, 0.15), np.isin(seg, [3, 0]))  # the body is smaller
    # the components' members given (as isolation passes them) or computed: one answer
    members = component_members(seg, len(sizes))
    assert [m.size for m in members] == sizes.tolist()
    assert np.array_equal(with_attached(seg, 0, sizes, P, 0.15, members=members), with_door)


def test_a_lid_behind_a_depth_jump_is_attached_by_its_nearest_points_in_3d():
    from ancsh.data.isolate.proposals import with_attached

    seg = np.full((30, 30), -1)
    g = np.full((30, 30), 3.0)
    seg[2:14, 2:20], g[2:14, 2:20] = 0, 1.0  # the body
    # a lid below it in the image: 30 cm behind the body where they touch in the image, rising to 5 cm at its far rows
    seg[14:18, 2:20], g[14:18, 2:20] = 1, np.array([1.3, 1.2, 1.1, 1.05])[:, None]
    sizes = np.bincount(seg[seg >= 0])
    P = _grid_points(g)
    # every step across the boundary is 30 cm, but the lid's far rows come within 7 cm of the body's edge
    assert np.array_equal(with_attached(seg, 0, sizes, P, 0.1), np.isin(seg, [0, 1]))
    assert np.array_equal(with_attached(seg, 0, sizes, P, 0.06), seg == 0)


def test_a_wide_region_without_depth_is_no_dead_band():
    gv = np.ones((40, 60), dtype=bool)
    gv[:, 30:] = False  # everything right of the middle beyond the sensor's range
    border = view_border(gv)
    assert not border[20, 28] and not border[20, 29]  # an object's edge against the background: not the view's end
    assert border[0, 10] and border[20, 0]


def test_a_segment_reaching_the_image_edge_runs_out_of_the_view_and_one_inside_does_not():
    from ancsh.data.isolate import OUT_OF_VIEW_SHARE, out_of_view

    inside = np.zeros((60, 80), dtype=bool)
    inside[20:40, 30:50] = True
    assert out_of_view(inside) == (False, 0.0)
    sliver = np.zeros((60, 80), dtype=bool)
    sliver[0:6, 10:40] = True  # cut by the top edge: its top row and the first pixels of its sides are outline there
    cut, share = out_of_view(sliver)
    assert cut and share >= OUT_OF_VIEW_SHARE
    outline = sliver & ~np.pad(sliver, 1)[2:, 1:-1] | sliver & ~np.pad(sliver, 1)[:-2, 1:-1] \
        | sliver & ~np.pad(sliver, 1)[1:-1, 2:] | sliver & ~np.pad(sliver, 1)[1:-1, :-2]
    assert share == pytest.approx(np.count_nonzero(outline[:3]) / np.count_nonzero(outline))
    grazing = inside.copy()
    grazing[39, 79] = True  # one outline pixel of many near the edge: below the share
    assert out_of_view(grazing)[0] is False
    empty = out_of_view(np.zeros((10, 10), dtype=bool))
    assert empty[0] is False and np.isnan(empty[1])
    stops_short = np.roll(sliver, 3, axis=0)  # 3 pixels short of the edge: out of view on a grid of stride 2
    assert out_of_view(stops_short)[0] is False and out_of_view(stops_short, stride=2)[0] is True
    with pytest.raises(ValueError, match="mask"):
        out_of_view(np.zeros(10, dtype=bool))
    for bad in (0, 1.5, "2", True):
        with pytest.raises(ValueError, match="stride"):
            out_of_view(sliver, stride=bad)
    with pytest.raises(ValueError, match="stride"):  # checked before an empty mask's early answer too
        out_of_view(np.zeros((10, 10), dtype=bool), stride=0)
