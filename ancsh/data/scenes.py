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

__all__ = ["SceneFrame", "clutter_model", "curtain_mesh", "render_scene"]

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
        The test frame the scene is built around (its object's ground truth, ``frame.gt``).
    support : str
        ``"floor"`` or ``"stairs"``.
    with_object : bool
    clutter : (H, W) int
        Which clutter piece each pixel shows (``-1``: none; ``k``: the ``k``-th of ``clutter_kinds``).
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


def render_scene(gen, index: int, rng, *, with_object: bool = True, stairs: bool | None = None) -> SceneFrame:
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
    """
    import trimesh

    from ..geometry._checks import check_generator
    from ..model.articulated import ArticulatedModel, Part
    from .conventions import part_vertices_canonical
    from .render import ModelRenderer

    rng = check_generator(rng)
    frame = gen.frame(index)
    model, renderer = gen.instance(frame.instance_index)
    verts = np.concatenate(part_vertices_canonical(model, frame.joint_states_abs))
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    centre = (lo + hi) / 2
    eye = model.R_canon_base @ frame.T_cam_base.inverse().translation  # the camera in the canonical frame
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
    views = [renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth] if with_object else []
    for group in [pieces] + [[c] for c in clutter_pieces]:  # the walls and supports, then each clutter piece
        mesh = trimesh.util.concatenate(group)
        mesh.apply_transform(to_base)
        surroundings = ArticulatedModel((Part("surroundings", mesh),), (), name="surroundings")
        views.append(ModelRenderer(surroundings).render(np.zeros(0), frame.T_cam_base, frame.intrinsics).depth)
    stack = np.stack([np.where(v > 0, v, np.inf) for v in views])
    depth = stack.min(axis=0)
    nearest = np.where(np.isfinite(depth), np.argmin(stack, axis=0), -1)
    visible = nearest == 0 if with_object else np.zeros(depth.shape, bool)
    first_clutter = len(views) - len(clutter_pieces)
    clutter = np.where(nearest >= first_clutter, nearest - first_clutter, -1)
    return SceneFrame(np.where(np.isfinite(depth), depth, 0.0), frame.intrinsics, visible, frame,
                      "stairs" if stairs else "floor", bool(with_object), clutter, tuple(kinds))
