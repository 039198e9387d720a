"""Rendered scenes around a test frame: the object on a floor or a staircase, a wall or a curtain behind it,
clutter beside it -- what ``ancsh predict`` meets without a mask, with the truth of every pixel.

:func:`render_scene` keeps the frame's object, pose, joint states and camera (:class:`~ancsh.data.generate.FrameGenerator`)
and adds, in the object's canonical frame (+y up, +z front, :mod:`ancsh.data.conventions`):

- a support under its lowest point: a floor, or (``stairs``) the lowest tread of a staircase whose risers rise behind
  the object (0.17 m rise, 0.3 m going, five steps), as on the real frames;
- a wall on the far side from the camera, 0.05-1 object sizes behind it: flat, or a curtain in vertical folds
  (:func:`curtain_mesh`);
- up to two pieces of clutter (:func:`clutter_model`) on the support beside it.

With ``with_object=False`` the same scene is rendered without the object: a scene where the category is not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SceneFrame", "SceneObject", "clutter_model", "curtain_mesh", "nearest_surface", "render_scene"]

#: Companions (more objects of the category, :func:`render_scene`) stand this far beside the frame's object (a share
#: of its size), or touch it (``TOUCHING_SHARE`` of them).
COMPANION_GAP = (0.02, 0.3)
TOUCHING_SHARE = 0.3
#: A companion is placed where the camera sees its whole box, this share of the image inside the border (at most
#: COMPANION_ATTEMPTS draws; else it is left out).
COMPANION_MARGIN = 0.02
COMPANION_ATTEMPTS = 8
#: With companions the camera stands this many times further from the frame's object (along its line of sight), so
#: that there is room for them in the view; the frame's object's truth is then measured again.
COMPANION_STEP_BACK = 1.6
#: A translucent object keeps this share of its visible pixels' depth (in blobs; the rest reads 0).
TRANSLUCENT_KEEP = (0.2, 0.5)

#: Staircase: riser height, tread depth (metres) and number of steps.
STAIR_RISE_M = 0.17
STAIR_GOING_M = 0.3
STAIR_STEPS = 5


def clutter_model(rng, size: float):
    """A rigid clutter object about ``size`` metres across: a box, slab, cylinder, sphere or a piece of wall, or two of them.

    The model's name says which: ``"clutter:box"``, ``"clutter:wall+sphere"``, ...
    """
    import trimesh

    from ..model.articulated import ArticulatedModel, Part

    kinds = []

    def piece():
        kind = str(rng.choice(["box", "slab", "cylinder", "sphere", "wall", "wall"]))
        kinds.append(kind)
        s = size * rng.uniform(0.4, 1.0)
        if kind == "box":
            return trimesh.creation.box(s * rng.uniform(0.3, 1.0, 3))
        if kind == "wall":  # a piece of a wall, a board or a table top the size of the objects
            return trimesh.creation.box(s * np.array([rng.uniform(0.8, 2.0), 0.02, rng.uniform(0.6, 1.4)]))
        if kind == "slab":
            return trimesh.creation.box(s * np.array([1.0, rng.uniform(0.02, 0.1), rng.uniform(0.5, 1.0)]))
        if kind == "cylinder":
            return trimesh.creation.cylinder(radius=s * rng.uniform(0.1, 0.4), height=s, sections=24)
        return trimesh.creation.icosphere(subdivisions=2, radius=s * rng.uniform(0.2, 0.5))

    meshes = [piece()]
    if rng.random() < 0.5:
        m = piece()
        m.apply_translation(rng.normal(0.0, 0.3 * size, 3))
        meshes.append(m)
    mesh = trimesh.util.concatenate(meshes)
    mesh.apply_translation(-mesh.bounds.mean(axis=0))
    return ArticulatedModel((Part("clutter", mesh),), (), name="clutter:" + "+".join(kinds))


def curtain_mesh(width: float, height: float, amplitude: float, wavelength: float, phase: float = 0.0):
    """A wall ``width`` x ``height`` metres in the x-y plane (from y = 0 up, z = 0 at its mean), in vertical folds
    ``z = amplitude * sin(2 pi x / wavelength + phase)`` (a curtain; ``amplitude`` 0: a flat wall); a trimesh."""
    import trimesh

    for name, value in (("width", width), ("height", height), ("wavelength", wavelength)):
        if not value > 0:
            raise ValueError(f"{name}: expected a positive length, got {value!r}")
    nx = max(2, int(np.ceil(width / max(wavelength / 8.0, 0.02))) + 1)
    x = np.linspace(-width / 2, width / 2, nx)
    xx, yy = np.meshgrid(x, np.array([0.0, height]), indexing="ij")
    zz = amplitude * np.sin(2 * np.pi * xx / wavelength + phase)
    vertices = np.stack([xx.ravel(), yy.ravel(), zz.ravel()], axis=1)
    i = np.arange(nx - 1) * 2
    faces = np.concatenate([np.stack([i, i + 2, i + 3], axis=1), np.stack([i, i + 3, i + 1], axis=1)])
    return trimesh.Trimesh(vertices, faces, process=False)


@dataclass(frozen=True)
class SceneFrame:
    """A rendered scene (:func:`render_scene`).

    Attributes
    ----------
    depth : (H, W) float64
        Noise-free depth (metres, 0 = nothing).
    intrinsics : Intrinsics
    visible : (H, W) bool
        The object's visible pixels (all ``False`` without the object).
    frame : Frame
        The test frame the scene is built around (without companions, its object's ground truth is ``frame.gt``;
        with them the camera stands further back: the truth is in :attr:`objects`).
    support : str
        ``"floor"`` or ``"stairs"``.
    with_object : bool
    clutter : (H, W) int
        Which clutter piece each pixel shows (``-1``: none; ``k``: the ``k``-th of ``clutter_kinds``).
    objects : tuple of SceneObject
        Every object of the scene, the frame's own first (its ``visible`` is :attr:`visible`); empty without objects.
    clutter_kinds : tuple of str
        What each clutter piece is (:func:`clutter_model`'s name without ``"clutter:"``, e.g. ``"box"``).
    """

    depth: np.ndarray
    intrinsics: object
    visible: np.ndarray
    frame: object
    support: str
    with_object: bool = True
    clutter: np.ndarray | None = None
    clutter_kinds: tuple = ()
    objects: tuple = ()


@dataclass(frozen=True)
class SceneObject:
    """One object of a :class:`SceneFrame`: its visible pixels ``(H, W)`` bool, its ground truth
    (:class:`~ancsh.model.canonical.AncshGroundTruth`, camera frame; ``None`` when it is hidden), its joint states (absolute), whether its depth is
    mostly missing (``translucent``: a translucent or dark object the sensor sees through) and how it stands to the
    frame's object (``placement``: ``"frame"``, ``"beside"`` or ``"touching"``)."""

    visible: np.ndarray
    gt: object
    joint_states_abs: np.ndarray
    translucent: bool = False
    placement: str = "frame"


def nearest_surface(depths) -> tuple[np.ndarray, np.ndarray]:
    """Composite depth images of separately rendered things into what one sensor sees.

    Parameters
    ----------
    depths : sequence of (H, W) float64
        Metres, 0 where a thing covers no pixel.

    Returns
    -------
    (depth, nearest) : ((H, W) float64, (H, W) int64)
        The nearest surface at each pixel (metres, 0 where none), and the index in ``depths`` of the thing it belongs to
        (-1 where none).
    """
    stack = np.stack([np.where(np.asarray(d) > 0, d, np.inf) for d in depths])
    depth = stack.min(axis=0)
    seen = np.isfinite(depth)
    return np.where(seen, depth, 0.0), np.where(seen, np.argmin(stack, axis=0), -1)


def render_scene(gen, index: int, rng, *, with_object: bool = True, stairs: bool | None = None, companions: int = 0,
                 translucent: int | None = None, pixel_scale: int = 1) -> SceneFrame:
    """Test frame ``index`` of ``gen`` (a :class:`~ancsh.data.generate.FrameGenerator`) in a scene (module docstring).

    Parameters
    ----------
    gen : FrameGenerator
    index : int
    rng : numpy.random.Generator or int
        The scene's walls, folds and clutter.
    with_object : bool
        Render the object (``False``: the same scene without it).
    stairs : bool, optional
        A staircase instead of a floor (default: one scene in three, drawn from ``rng``).
    companions : int
        More objects of the category (other test instances at other joint states, test frames ``index + 7919 k``) on
        the same support beside the frame's object, left or right of it, turned up to 25 deg about the vertical,
        :data:`COMPANION_GAP` of its size apart or (:data:`TOUCHING_SHARE`) touching it, where the camera sees their
        whole box (a companion with no such place is left out); the surroundings are placed around them all. Their truth is in :attr:`SceneFrame.objects`.
    translucent : int, optional
        The index in :attr:`SceneFrame.objects` of an object whose depth is mostly missing (:data:`TRANSLUCENT_KEEP`
        of its visible pixels kept, in blobs): a translucent or dark object.
    pixel_scale : int
        The image has this many times the frame's pixels along each side (the same field of view: a 640x480 frame at 2
        is 1280x960, as the real frames' 1280x720 sensors see); the truth is measured on it.
    """
    import trimesh

    from ..geometry._checks import check_generator
    from ..geometry.transforms import Sim3
    from ..model.articulated import ArticulatedModel, Part
    from .conventions import part_vertices_canonical
    from .render import ModelRenderer

    rng = check_generator(rng)
    if isinstance(pixel_scale, bool) or int(pixel_scale) != pixel_scale or pixel_scale < 1:
        raise ValueError(f"pixel_scale: expected a positive integer, got {pixel_scale!r}")
    if isinstance(companions, bool) or int(companions) != companions or companions < 0:
        raise ValueError(f"companions: expected a non-negative integer, got {companions!r}")
    if translucent is not None and not 0 <= int(translucent) <= int(companions):
        raise ValueError(f"translucent: expected an object index 0..{int(companions)}, got {translucent!r}")
    frame = gen.frame(index)
    if pixel_scale != 1:
        import dataclasses

        k, i0 = int(pixel_scale), frame.intrinsics
        intr = dataclasses.replace(i0, fx=k * i0.fx, fy=k * i0.fy, cx=k * (i0.cx + 0.5) - 0.5, cy=k * (i0.cy + 0.5) - 0.5,
                                   width=k * i0.width, height=k * i0.height)
        frame = dataclasses.replace(frame, intrinsics=intr)
    model, renderer = gen.instance(frame.instance_index)
    verts = np.concatenate(part_vertices_canonical(model, frame.joint_states_abs))
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    T_cam_base = frame.T_cam_base
    if companions:  # the camera steps back along its line of sight to see the companions too
        T_cam_base = Sim3(T_cam_base.rotation, COMPANION_STEP_BACK * T_cam_base.translation)
    # placed also without the objects: the empty scene's surroundings are the same
    placed = _companions(gen, index, int(companions), model, T_cam_base, frame.intrinsics, lo, hi, size, rng)
    for c in placed:  # the surroundings go around every object
        lo, hi = np.minimum(lo, c["lo"]), np.maximum(hi, c["hi"])
    centre = (lo + hi) / 2
    eye = model.R_canon_base @ T_cam_base.inverse().translation  # the camera in the canonical frame
    back = -1.0 if eye[2] > centre[2] else 1.0  # behind the object, seen from the camera
    stairs = bool(rng.random() < 1 / 3) if stairs is None else bool(stairs)
    pieces, clutter_pieces, kinds = [], [], []
    if stairs:
        edge = (lo[2] if back < 0 else hi[2]) + back * rng.uniform(0.02, 0.3)  # the first riser behind the object
        ground = trimesh.creation.box((8.0, 0.02, 4.0))
        ground.apply_translation([centre[0], lo[1] - 0.01, edge - back * 2.0])
        pieces.append(ground)
        for k in range(1, STAIR_STEPS + 1):
            riser = trimesh.creation.box((8.0, STAIR_RISE_M, 0.02))
            z = edge + back * (k - 1) * STAIR_GOING_M
            riser.apply_translation([centre[0], lo[1] + (k - 0.5) * STAIR_RISE_M, z + back * 0.01])
            tread = trimesh.creation.box((8.0, 0.02, STAIR_GOING_M))
            tread.apply_translation([centre[0], lo[1] + k * STAIR_RISE_M - 0.01, z + back * STAIR_GOING_M / 2])
            pieces += [riser, tread]
        wall_z = edge + back * (STAIR_STEPS * STAIR_GOING_M + rng.uniform(0.0, 0.5))
    else:
        floor = trimesh.creation.box((8.0, 0.02, 8.0))
        floor.apply_translation([centre[0], lo[1] - 0.01, centre[2]])
        pieces.append(floor)
        wall_z = (lo[2] if back < 0 else hi[2]) + back * rng.uniform(0.05, 1.0) * size
    folds = rng.random() < 0.5
    wall = curtain_mesh(8.0, 3.0, rng.uniform(0.02, 0.1) * size if folds else 0.0, rng.uniform(0.15, 0.6),
                        rng.uniform(0, 2 * np.pi))
    wall.apply_translation([centre[0], lo[1], wall_z])
    pieces.append(wall)
    for side in rng.permutation([-1.0, 1.0])[: rng.integers(0, 3)]:
        piece = clutter_model(rng, size * rng.uniform(0.3, 1.0))
        clutter = piece.parts[0].mesh.copy()
        b = clutter.bounds
        x = (hi[0] if side > 0 else lo[0]) + side * (rng.uniform(0.02, 0.3) * size + (b[1, 0] - b[0, 0]) / 2)
        clutter.apply_translation([x, lo[1] - b[0, 1], rng.uniform(lo[2], hi[2])])
        clutter_pieces.append(clutter)
        kinds.append(piece.name.split(":", 1)[1])
    to_base = np.eye(4)
    to_base[:3, :3] = model.R_canon_base.T  # canonical axes -> the base frame
    object_views = [renderer.render(frame.joint_states_abs, T_cam_base, frame.intrinsics)] if with_object else []
    object_views += [c["renderer"].render(c["q"], c["T_cam_base"], frame.intrinsics) for c in placed] if with_object else []
    views = [v.depth for v in object_views]
    for group in [pieces] + [[c] for c in clutter_pieces]:  # the walls and supports, then each clutter piece
        mesh = trimesh.util.concatenate(group)
        mesh.apply_transform(to_base)
        surroundings = ArticulatedModel((Part("surroundings", mesh),), (), name="surroundings")
        views.append(ModelRenderer(surroundings).render(np.zeros(0), T_cam_base, frame.intrinsics).depth)
    depth, nearest = nearest_surface(views)
    first_clutter = len(views) - len(clutter_pieces)
    clutter = np.where(nearest >= first_clutter, nearest - first_clutter, -1)
    objects = []
    for k, view in enumerate(object_views):
        seen = nearest == k
        if translucent is not None and k == int(translucent):
            holes = seen & ~_blobs(depth.shape, rng.uniform(*TRANSLUCENT_KEEP), rng)
            depth[holes] = 0.0  # the sensor sees through it: no measurement (as on the real translucent lid)
            seen &= ~holes
        objects.append((seen, view))
    visible = objects[0][0] if with_object else np.zeros(depth.shape, bool)
    truth = []
    for k, (seen, view) in enumerate(objects):
        if k == 0:
            gt = frame.gt if not companions and pixel_scale == 1 else _truth(
                {"model": model, "q": frame.joint_states_abs, "T_cam_base": T_cam_base}, view, seen, frame.intrinsics,
                rng) if np.count_nonzero(seen) >= 3 else None
            truth.append(SceneObject(seen, gt, np.asarray(frame.joint_states_abs), translucent == 0, "frame"))
            continue
        c = placed[k - 1]
        gt = _truth(c, view, seen, frame.intrinsics, rng) if np.count_nonzero(seen) >= 3 else None
        truth.append(SceneObject(seen, gt, np.asarray(c["q"]),
                                 translucent == k, c["placement"]))
    return SceneFrame(depth, frame.intrinsics, visible, frame, "stairs" if stairs else "floor", bool(with_object),
                      clutter, tuple(kinds), tuple(truth))


def _companions(gen, index, count, model, T_cam_base, intr, lo, hi, size, rng) -> list:
    """Placements of ``count`` more objects of ``gen``'s category beside the frame's object (:func:`render_scene`):
    per companion its renderer, model, absolute states ``q``, ``T_cam_base`` and canonical bounds (``lo``, ``hi``) in
    the frame object's canonical frame, and whether it touches."""
    from ..geometry.rotations import axis_angle_matrix
    from ..geometry.transforms import Sim3
    from .conventions import part_vertices_canonical
    from .render import project

    if count == 0:  # no draw: scenes without companions stay as they were
        return []
    out, sides = [], list(rng.permutation([-1.0, 1.0]))
    edges = {-1.0: lo[0], 1.0: hi[0]}
    R1 = model.R_canon_base
    for k in range(count):
        other = gen.frame(index + 7919 * (k + 1))
        m2, r2 = gen.instance(other.instance_index)
        q2 = np.asarray(other.joint_states_abs, dtype=np.float64)
        v2_own = np.concatenate(part_vertices_canonical(m2, q2))
        for attempt in range(COMPANION_ATTEMPTS):  # a place where the camera sees all of it
            Ry = axis_angle_matrix(np.array([0.0, 1.0, 0.0]), np.deg2rad(rng.uniform(-25.0, 25.0)))
            v2 = v2_own @ Ry.T  # its canonical frame, turned
            side = sides[(k + attempt) % 2]
            touching = bool(rng.random() < TOUCHING_SHARE)
            gap = 0.0 if touching else rng.uniform(*COMPANION_GAP) * size
            x = edges[side] + side * gap - (v2[:, 0].min() if side > 0 else v2[:, 0].max())
            shift = np.array([x, lo[1] - v2[:, 1].min(), (lo[2] + hi[2]) / 2 - (v2[:, 2].min() + v2[:, 2].max()) / 2
                              + rng.uniform(-0.1, 0.1) * size])
            placed = v2 + shift
            # base2 -> canonical2 (R2) -> turned (Ry) -> shifted, in the frame object's canonical frame -> base1 (R1^T)
            T = T_cam_base @ Sim3(R1.T @ Ry @ m2.R_canon_base, R1.T @ shift)
            box = np.array(np.meshgrid(*[(placed[:, i].min(), placed[:, i].max()) for i in range(3)])).reshape(3, -1).T
            cam = T_cam_base.apply(box @ R1)  # canonical -> base1 (row vectors: c @ R1 = R1^T c) -> camera
            if np.all(cam[:, 2] > 0.1):
                uv = project(cam, intr)[0]
                mu, mv = COMPANION_MARGIN * intr.width, COMPANION_MARGIN * intr.height
                if np.all((uv[:, 0] > mu) & (uv[:, 0] < intr.width - mu) & (uv[:, 1] > mv) & (uv[:, 1] < intr.height - mv)):
                    break
        else:
            continue  # no place in view: one companion fewer
        edges[side] = placed[:, 0].max() if side > 0 else placed[:, 0].min()
        out.append({"renderer": r2, "model": m2, "q": q2, "T_cam_base": Sim3(T.rotation, T.translation),
                    "lo": placed.min(axis=0), "hi": placed.max(axis=0), "placement": "touching" if touching else "beside"})
    return out


def _blobs(shape, keep: float, rng) -> np.ndarray:
    """``(H, W)`` bool: ``keep`` of the pixels, in smooth blobs (a coarse random field, thresholded)."""
    from scipy.ndimage import zoom

    coarse = rng.random((max(2, shape[0] // 24), max(2, shape[1] // 24)))
    field = zoom(coarse, (shape[0] / coarse.shape[0], shape[1] / coarse.shape[1]), order=1)[: shape[0], : shape[1]]
    field = np.pad(field, ((0, shape[0] - field.shape[0]), (0, shape[1] - field.shape[1])), mode="edge")
    return field <= np.quantile(field, keep)


def _truth(placed: dict, view, seen, intrinsics, rng):
    """A companion's ground truth from points of its visible pixels (:func:`ancsh.model.canonical.ancsh_ground_truth`)."""
    from ..model.canonical import ancsh_ground_truth
    from .render import sample_points

    ids = np.where(seen, view.part_ids, -1)
    depth = np.where(seen, view.depth, 0.0)
    points, labels, _ = sample_points(depth, ids, intrinsics, 1024, rng)
    return ancsh_ground_truth(placed["model"], placed["q"], placed["T_cam_base"], points, labels)
