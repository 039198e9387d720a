"""Rendering, viewpoints, visibility ratios, back-projection and the sensor-noise model."""

import numpy as np
import pytest
import trimesh

from ancsh.data.noise import DepthNoise, apply_noise, depth_edges
from ancsh.data.render import (
    Intrinsics,
    ModelRenderer,
    ViewpointRange,
    backproject,
    look_at,
    project,
    render_depth,
    sample_points,
    sample_viewpoint,
)
from ancsh.geometry.rotations import axis_angle_matrix
from ancsh.geometry.transforms import SE3, Sim3
from ancsh.model import ArticulatedModel, Joint, Part

SMALL = Intrinsics.kinect(160, 120)
# The analytic tests below run on both ray-casting backends.
backends = pytest.mark.parametrize("backend", ["open3d", "numpy"])


def one_part(mesh):
    return ArticulatedModel(parts=(Part("base", mesh),), joints=())


# Camera pose of two_plates(): the front plate spans x in [-0.2, 0] at z = 1 and, at q = 0,
# the back plate spans x in [-0.1, 0.1] at z = 1.5, half hidden; q slides it along x.
T_PLATES = SE3(translation=[-0.1, 0.0, 1.0])


def two_plates(offset_x=-0.1, lower=-1.0, upper=1.0):
    """Two 0.2 m square plates 0.5 m apart in depth, the back one on a prismatic joint."""
    plate = trimesh.creation.box((0.2, 0.2, 0.002))
    return ArticulatedModel(
        parts=(Part("front", plate), Part("back", plate.copy())),
        joints=(
            Joint("slide", "prismatic", "front", "back", axis=[1, 0, 0], lower=lower, upper=upper, rest=0.0,
                  origin=SE3(translation=[-offset_x, 0.0, 0.5])),
        ),
    )


# --- intrinsics -----------------------------------------------------------------------
def test_intrinsics_round_trip_and_errors():
    intr = Intrinsics(500.0, 510.0, 300.0, 200.0, 600, 400)
    assert Intrinsics.from_json(intr.to_json()) == intr
    assert Intrinsics.from_array(intr.as_array()) == intr
    np.testing.assert_allclose(intr.matrix(), [[500, 0, 300], [0, 510, 200], [0, 0, 1]])
    with pytest.raises(ValueError, match="fx"):
        Intrinsics(fx=-1.0)
    with pytest.raises(ValueError, match="width"):
        Intrinsics(width=0)
    with pytest.raises(ValueError, match="keys"):
        Intrinsics.from_json({"fx": 1.0})


# --- depth ----------------------------------------------------------------------------
@backends
def test_depth_of_fronto_parallel_plate_is_its_distance(backend):
    """A 4 m wide plate 2 m ahead fills the view; every pixel sees its front face."""
    d, t = 2.0, 0.01
    model = one_part(trimesh.creation.box((4.0, 4.0, t)))
    frame = render_depth(model, [], SE3(translation=[0.0, 0.0, d]), SMALL, backend=backend)
    np.testing.assert_allclose(frame.depth, d - t / 2, rtol=0, atol=1e-6)
    assert np.all(frame.part_ids == 0)


@backends
def test_depth_of_tilted_plane_matches_ray_plane_intersection(backend):
    rng = np.random.default_rng(3)
    R = axis_angle_matrix(np.array([1.0, 0.3, 0.0]) / np.hypot(1.0, 0.3), 0.5)
    T = Sim3(R, [0.05, -0.02, 3.0])
    model = one_part(trimesh.creation.box((6.0, 6.0, 0.02)))
    frame = render_depth(model, [], T, SMALL, backend=backend)
    n = R @ np.array([0.0, 0.0, 1.0])  # plate normal in the camera frame
    face_z = 0.01 * np.sign(T.inverse().apply(np.zeros(3))[2])  # the face towards the camera
    point = T.apply(np.array([0.0, 0.0, face_z]))
    v, u = np.nonzero(frame.depth > 0)
    assert len(u) == SMALL.width * SMALL.height
    rays = np.stack([(u - SMALL.cx) / SMALL.fx, (v - SMALL.cy) / SMALL.fy, np.ones(len(u))], axis=1)
    z_expected = (n @ point) / (rays @ n)
    pick = rng.choice(len(u), 500, replace=False)
    np.testing.assert_allclose(frame.depth[v[pick], u[pick]], z_expected[pick], rtol=1e-5)


@backends
def test_part_ids_follow_the_joint_state(backend):
    """Two plates side by side at the same depth; the right one slides by q along x, so the
    id boundary sits at the column u = fx * x_boundary / z + cx."""
    plate = trimesh.creation.box((0.4, 0.4, 0.01))
    model = ArticulatedModel(
        parts=(Part("left", plate), Part("right", plate.copy())),
        joints=(Joint("slide", "prismatic", "left", "right", axis=[1, 0, 0], lower=0.0, upper=0.2,
                      origin=SE3(translation=[0.4, 0.0, 0.0])),),
    )
    z = 2.0
    for q in (0.0, 0.1):
        T = SE3(translation=[-0.2, 0.0, z])  # left plate spans x in [-0.4, 0], right [q, 0.4 + q]
        frame = render_depth(model, [q], T, SMALL, backend=backend)
        row = frame.part_ids[int(SMALL.cy)]
        u = np.arange(SMALL.width)
        x = (u - SMALL.cx) / SMALL.fx * (z - 0.005)
        assert np.all(row[(x < -0.001) & (x > -0.399)] == 0)
        assert np.all(row[(x > q + 0.001) & (x < 0.399 + q)] == 1)
        assert np.all(row[(x > 0.001) & (x < q - 0.001)] == -1)
        assert np.all(frame.depth[frame.part_ids == -1] == 0)


@backends
def test_crop_window_matches_full_image_cast(backend):
    """The renderer casts rays only inside the projected bounding rectangle; a helper part
    behind the camera forces a whole-image cast, which must give the same image."""
    rng = np.random.default_rng(0)
    box = trimesh.creation.box((0.3, 0.2, 0.25))
    T = Sim3.from_rotvec(rng.normal(size=3) * 0.5, [0.02, 0.01, 1.2])
    behind = T.inverse().apply(np.array([0.0, 0.0, -1.0]))
    model = ArticulatedModel(
        parts=(Part("box", box), Part("behind", trimesh.creation.box((0.01, 0.01, 0.01)))),
        joints=(Joint("fixed", "prismatic", "box", "behind", axis=[1, 0, 0], lower=0.0, upper=0.0,
                      origin=SE3(translation=behind)),),
    )
    cropped = render_depth(one_part(box), [], T, SMALL, backend=backend)
    full = render_depth(model, [0.0], T, SMALL, backend=backend)
    assert 0 < (cropped.depth > 0).sum() < SMALL.width * SMALL.height / 2
    np.testing.assert_array_equal(full.part_ids, cropped.part_ids)
    np.testing.assert_allclose(full.depth, cropped.depth, atol=1e-6)


def test_renderer_errors():
    model = one_part(trimesh.creation.box((1, 1, 1)))
    r = ModelRenderer(model)
    with pytest.raises(ValueError, match="T_cam_base"):
        r.render([], np.eye(4), SMALL)
    with pytest.raises(ValueError, match="T_cam_base"):
        r.render([], Sim3(scale=2.0), SMALL)
    with pytest.raises(ValueError, match="intrinsics"):
        r.render([], SE3(translation=[0, 0, 3]), "640x480")
    with pytest.raises(ValueError, match="no part of 'object' has a mesh"):
        ModelRenderer(ArticulatedModel(parts=(Part("base"),), joints=()))
    with pytest.raises(ValueError, match="visibility_samples"):
        ModelRenderer(model, visibility_samples=0)


# --- back-projection --------------------------------------------------------------------
def test_backprojection_inverts_projection():
    rng = np.random.default_rng(1)
    model = one_part(trimesh.creation.box((0.3, 0.2, 0.25)))
    T = Sim3.from_rotvec(rng.normal(size=3), [0.0, 0.0, 1.0])
    frame = render_depth(model, [], T, SMALL)
    pts = backproject(frame.depth, SMALL)
    v, u = np.nonzero(frame.depth > 0)
    uv, z = project(pts, SMALL)
    np.testing.assert_allclose(uv, np.stack([u, v], axis=1), atol=1e-9)
    np.testing.assert_allclose(z, frame.depth[v, u])
    # every back-projected point lies on the box surface
    local = T.inverse().apply(pts)
    dist = np.abs(np.abs(local) - 0.5 * np.array([0.3, 0.2, 0.25])).min(axis=1)
    assert dist.max() < 1e-5


def test_backproject_mask_and_errors():
    depth = np.zeros((SMALL.height, SMALL.width))
    depth[10:20, 30:40] = 2.0
    mask = np.zeros_like(depth, dtype=bool)
    mask[10:15] = True
    assert len(backproject(depth, SMALL)) == 100
    assert len(backproject(depth, SMALL, mask)) == 50
    with pytest.raises(ValueError, match="depth"):
        backproject(depth[:-1], SMALL)
    with pytest.raises(ValueError, match="mask"):
        backproject(depth, SMALL, mask.astype(int))
    with pytest.raises(ValueError, match="in front"):
        project(np.array([[0.0, 0.0, -1.0]]), SMALL)


def test_sample_points_is_seeded_and_labelled():
    model = two_plates()
    frame = render_depth(model, [0.0], T_PLATES, SMALL)
    a = sample_points(frame.depth, frame.part_ids, SMALL, 200, 7)
    b = sample_points(frame.depth, frame.part_ids, SMALL, 200, np.random.default_rng(7))
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    points, labels, pixels = a
    assert len(np.unique(pixels)) == 200  # without replacement
    np.testing.assert_array_equal(labels, frame.part_ids.ravel()[pixels])
    np.testing.assert_allclose(points[:, 2], frame.depth.ravel()[pixels])
    many = sample_points(frame.depth, frame.part_ids, SMALL, 10 * SMALL.width * SMALL.height, 0)
    assert len(many[0]) == 10 * SMALL.width * SMALL.height
    with pytest.raises(ValueError, match="count"):
        sample_points(frame.depth, frame.part_ids, SMALL, 0, 0)
    with pytest.raises(ValueError, match="no valid"):
        sample_points(np.zeros_like(frame.depth), frame.part_ids, SMALL, 5, 0)


# --- visibility -----------------------------------------------------------------------
def _front_fraction(w, h, t):
    return (w * h) / (2 * w * h + 2 * w * t + 2 * h * t)


@backends
def test_visibility_of_free_and_half_occluded_plate(backend):
    """The back plate is half hidden behind the front plate at q = 0 and free at q = 0.6."""
    model = two_plates()
    r = ModelRenderer(model, visibility_samples=4000, backend=backend)
    front = _front_fraction(0.2, 0.2, 0.002)
    se = 3 * np.sqrt(0.25 / 4000)
    occluded = r.render([0.0], T_PLATES, SMALL, visibility=True)
    np.testing.assert_allclose(occluded.visibility, [front, 0.5 * front], atol=se)
    free = r.render([0.6], T_PLATES, SMALL, visibility=True)
    np.testing.assert_allclose(free.visibility, [front, front], atol=se)
    # pixels agree: the occluded back plate shows about half its free pixel count
    ratio = occluded.part_pixels(2)[1] / free.part_pixels(2)[1]
    assert abs(ratio - 0.5) < 0.05
    hidden = r.render([-0.12], T_PLATES, SMALL, visibility=True)  # fully behind the front plate
    assert hidden.visibility[1] == 0.0 and hidden.part_pixels(2)[1] == 0


@backends
def test_visibility_counts_only_the_inside_of_the_image(backend):
    model = one_part(trimesh.creation.box((4.0, 4.0, 0.002)))  # much wider than the view
    frame = render_depth(model, [], SE3(translation=[0, 0, 1.0]), SMALL, visibility=True, backend=backend)
    # the view covers |x| <= z * (W/2) / fx of the 4 m plate's front face
    half_w = 1.0 * (SMALL.width / 2) / SMALL.fx
    half_h = 1.0 * (SMALL.height / 2) / SMALL.fy
    expected = _front_fraction(4.0, 4.0, 0.002) * (2 * half_w * 2 * half_h) / 16.0
    assert abs(frame.visibility[0] - expected) < 3 * np.sqrt(expected / 1024)


# --- viewpoints -----------------------------------------------------------------------
def test_sample_viewpoint_looks_at_the_target_from_the_requested_direction():
    az, el, d = 0.3, 0.2, 2.0
    vr = ViewpointRange(distance=(d, d), azimuth=(az, az), elevation=(el, el), roll=0.0, target_jitter=0.0)
    c = np.array([0.1, 0.2, -0.3])
    T = sample_viewpoint(vr, 0, center=c, diagonal=1.0)
    np.testing.assert_allclose(T.apply(c), [0.0, 0.0, d], atol=1e-12)
    eye = T.inverse().translation
    np.testing.assert_allclose(eye - c, d * np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)]))
    up_in_cam = T.apply_direction(np.array([0.0, 1.0, 0.0]))
    assert abs(up_in_cam[0]) < 1e-12 and up_in_cam[1] < 0  # image up = -y


def test_sample_viewpoint_of_a_model_keeps_it_in_view():
    model = two_plates()
    rng = np.random.default_rng(5)
    for _ in range(10):
        q = model.random_states(rng)
        T = sample_viewpoint("laptop", rng, model, q)
        frame = render_depth(model, q, T, SMALL)
        assert (frame.part_ids >= 0).sum() > 0
    with pytest.raises(ValueError, match="category"):
        sample_viewpoint("toaster", 0)
    with pytest.raises(ValueError, match="elevation"):
        ViewpointRange(elevation=(0.0, 2.0))
    with pytest.raises(ValueError, match="up"):
        look_at([0, 0, 0], [0, 1, 0], [0, 1, 0])


# --- noise ----------------------------------------------------------------------------
def _plane(z, shape=(120, 160)):
    return np.full(shape, float(z))


def test_noise_off_is_exact():
    depth = _plane(1.5)
    depth[:10] = 0.0
    np.testing.assert_array_equal(apply_noise(depth, DepthNoise.off(), 0), depth)
    np.testing.assert_array_equal(apply_noise(depth, None, 0), depth)


@pytest.mark.parametrize("z", [0.8, 2.5])
def test_axial_noise_has_the_model_standard_deviation(z):
    noise = DepthNoise(edge_dropout=0.0)
    out = apply_noise(_plane(z), noise, 0)
    residual = out - z
    expected = 0.0012 + 0.0019 * (z - 0.4) ** 2
    assert abs(residual.std() / expected - 1) < 0.03  # 19200 samples: ~0.5 % standard error
    assert abs(residual.mean()) < 3 * expected / np.sqrt(residual.size)
    np.testing.assert_allclose(noise.sigma(z), expected)


def test_noise_is_seeded():
    depth = _plane(1.0)
    depth[40:80, 60:100] = 1.3
    a = apply_noise(depth, DepthNoise(random_dropout=0.1), 11)
    b = apply_noise(depth, DepthNoise(random_dropout=0.1), np.random.default_rng(11))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, apply_noise(depth, DepthNoise(random_dropout=0.1), 12))


def test_edge_dropout_hits_only_discontinuities():
    depth = np.zeros((120, 160))
    depth[30:90, 40:120] = 1.0
    depth[50:70, 60:100] = 1.2  # a step of 0.2 m inside the object
    edges = depth_edges(depth, 0.02)
    assert edges[30, 50] and edges[50, 70] and edges[49, 70] and not edges[40, 50]
    out = apply_noise(depth, DepthNoise(edge_dropout=1.0, sigma_a=0.0, sigma_b=0.0), 0)
    np.testing.assert_array_equal(out > 0, (depth > 0) & ~edges)
    half = apply_noise(depth, DepthNoise(edge_dropout=0.5, sigma_a=0.0, sigma_b=0.0), 0)
    dropped = (depth > 0) & (half == 0)
    assert not np.any(dropped & ~edges)
    assert abs(dropped.sum() / edges.sum() - 0.5) < 0.1


def test_noise_parameter_errors():
    with pytest.raises(ValueError, match="edge_dropout"):
        DepthNoise(edge_dropout=1.5)
    with pytest.raises(ValueError, match="sigma_a"):
        DepthNoise(sigma_a=-1.0)
    with pytest.raises(ValueError, match="edge_threshold"):
        DepthNoise(edge_threshold=0.0)
    assert DepthNoise.from_json(DepthNoise(random_dropout=0.2).to_json()) == DepthNoise(random_dropout=0.2)
    with pytest.raises(ValueError, match="edge_mixing"):
        DepthNoise(edge_mixing=2.0)
    with pytest.raises(ValueError, match="quantisation"):
        DepthNoise(quantisation=-0.001)
    assert DepthNoise.from_json(DepthNoise.real_frames().to_json()) == DepthNoise.real_frames()
    # the settings datasets carry: the default model reads as before the mixing and quantisation existed
    assert all(k not in DepthNoise().to_json() for k in ("edge_mixing", "quantisation", "blob_holes", "blob_size_px"))


def test_mixed_pixels_lie_between_the_surfaces_of_a_jump_and_depths_come_in_steps():
    depth = np.zeros((120, 160))
    depth[30:90, 40:120] = 1.0
    depth[50:70, 60:100] = 1.2  # a step of 0.2 m inside the object; its outline is a silhouette against nothing
    edges = depth_edges(depth, 0.02)
    inner = edges & (depth > 0)
    inner[30:31, :] = inner[89:90, :] = False
    inner[:, 40:41] = inner[:, 119:120] = False  # edge pixels of the silhouette: no measured neighbour across
    out = apply_noise(depth, DepthNoise(edge_dropout=0.0, edge_mixing=1.0, sigma_a=0.0, sigma_b=0.0), 0)
    moved = out != depth
    assert not np.any(moved & ~inner) and moved[inner].all()
    assert np.all((out[inner] > 1.0 + 0.2 * 0.2 - 1e-9) & (out[inner] < 1.2 - 0.2 * 0.2 + 1e-9))
    steps = apply_noise(depth, DepthNoise(edge_dropout=0.0, quantisation=0.001), 3)
    on = steps > 0
    np.testing.assert_allclose(steps[on] * 1000, np.round(steps[on] * 1000), atol=1e-9)
    assert len(np.unique(steps[on])) > 5  # the noise is still there, in millimetre steps


def test_blob_holes_drop_the_share_asked_for_in_blobs_and_only_where_measured():
    from scipy.ndimage import label

    depth = np.zeros((240, 320))
    depth[20:220, 30:290] = 1.0
    measured = np.count_nonzero(depth)
    plain = DepthNoise(edge_dropout=0.0, sigma_a=0.0, sigma_b=0.0)
    out = apply_noise(depth, DepthNoise(edge_dropout=0.0, sigma_a=0.0, sigma_b=0.0, blob_holes=0.05), 4)
    holes = (out == 0) & (depth > 0)
    assert np.count_nonzero(holes) == pytest.approx(0.05 * measured, rel=0.02)
    assert not np.any(out[depth == 0]) and np.array_equal(apply_noise(depth, plain, 4), depth)
    lab, n = label(holes)
    sizes = np.bincount(lab.ravel())[1:]
    assert sizes[sizes > 100].sum() > 0.7 * sizes.sum()  # blobs, not single pixels
    small = apply_noise(depth, DepthNoise(edge_dropout=0.0, sigma_a=0.0, sigma_b=0.0, blob_holes=0.05,
                                          blob_size_px=2.0), 4)
    assert label((small == 0) & (depth > 0))[1] > 3 * n  # a shorter length scale: more, smaller holes
    for bad in ({"blob_holes": 1.0}, {"blob_holes": -0.1}, {"blob_size_px": 0.0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            DepthNoise(**bad)
