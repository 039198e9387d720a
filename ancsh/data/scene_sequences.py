"""Rendered depth sequences of several objects of one category in a scene, with truth per frame and object.

The benchmark of multi-object tracking (``ancsh bench track-scenes``) runs on these. A sequence
(:func:`render_scene_sequence`, everything drawn from ``(seed, index)``):

- **Objects**: ``objects`` test instances of the category on one floor, beside or touching each other (the placement
  of :func:`~ancsh.data.scenes.render_scene`'s companions, seen from the first frame's camera); a wall behind them.
- **Motion**: object 0 is opened and closed (each joint ``q(i) = a + (b - a) (1 - cos(2 pi i / P + phase)) / 2`` on frame
  ``i``, over a sub-range ``[a, b]`` of its limits, ``P`` = ``period`` frames, default the sequence's length); the
  others are static.
- **Camera**: it turns about the vertical axis through the objects' centre by up to ``azimuth_drift_deg`` over the
  sequence (a smooth ease) and moves ``distance_drift`` of its distance closer.
- **Occluder**: a hand-sized box (``OCCLUDER_SIZE_M``) crosses the view in front of the objects during the middle
  ``occluder_share`` of the sequence.
- **Translucent**: object ``translucent`` (or none) keeps only :data:`~ancsh.data.scenes.TRANSLUCENT_KEEP` of its
  visible pixels' depth, in blobs redrawn every frame.
- **Sensor**: the category's depth noise model (:class:`~ancsh.data.noise.DepthNoise` of the generator) on every frame.

``objects=0`` renders the same scene without objects (a negative sequence).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry._checks import check_int, check_number

__all__ = ["OCCLUDER_SIZE_M", "SceneSequenceConfig", "SequenceFrame", "SequenceObject", "render_scene_sequence"]

#: The occluder's side lengths (metres): a hand-sized box.
OCCLUDER_SIZE_M = (0.09, 0.18, 0.05)


@dataclass(frozen=True)
class SceneSequenceConfig:
    """One sequence (module docstring).

    Attributes
    ----------
    category : str
    objects : int
        Objects in the scene, ``0..3`` (0: a negative sequence).
    length : int
        Frames, ``>= 2``.
    translucent : int or None
        Index of the translucent object.
    occluder : bool
    azimuth_drift_deg : float
        Largest camera turn over the sequence (degrees).
    distance_drift : float
        Share of its distance the camera moves closer over the sequence, ``[0, 0.5]``.
    occluder_share : float
        Share of the sequence the occluder takes to cross, ``(0, 1]``.
    opening_share : float
        Smallest share of a moving joint's limits it sweeps, ``(0, 1]``.
    period : int or None
        Frames of one open/close cycle of object 0 (default: ``length``), ``>= 2``.
    seed : int
    """

    category: str
    objects: int = 2
    length: int = 60
    translucent: int | None = None
    occluder: bool = True
    azimuth_drift_deg: float = 20.0
    distance_drift: float = 0.15
    occluder_share: float = 0.3
    opening_share: float = 0.5
    period: int | None = None
    seed: int = 0

    def __post_init__(self):
        object.__setattr__(self, "objects", check_int(self.objects, "objects", minimum=0))
        if self.objects > 3:
            raise ValueError(f"objects: expected 0 to 3 objects, got {self.objects}")
        object.__setattr__(self, "length", check_int(self.length, "length", minimum=2))
        object.__setattr__(self, "seed", check_int(self.seed, "seed", minimum=0))
        if self.period is not None:
            object.__setattr__(self, "period", check_int(self.period, "period", minimum=2))
        if self.translucent is not None:
            if self.objects == 0:
                raise ValueError("translucent: a sequence without objects has no translucent one")
            object.__setattr__(self, "translucent", check_int(self.translucent, "translucent", minimum=0))
            if self.translucent >= self.objects:
                raise ValueError(f"translucent: expected an object index 0..{self.objects - 1}, got {self.translucent}")
        check_number(self.azimuth_drift_deg, "azimuth_drift_deg", minimum=0.0, maximum=90.0)
        check_number(self.distance_drift, "distance_drift", minimum=0.0, maximum=0.5)
        check_number(self.occluder_share, "occluder_share", minimum=0.0, maximum=1.0, lower_open=True)
        check_number(self.opening_share, "opening_share", minimum=0.0, maximum=1.0, lower_open=True)


@dataclass(frozen=True)
class SequenceObject:
    """One object on one frame.

    Attributes
    ----------
    visible : (H, W) bool
        Its pixels with depth (in front of everything else; a translucent object's holes excluded).
    gt : AncshGroundTruth or None
        Its truth (:func:`ancsh.model.canonical.ancsh_ground_truth` on points of its visible pixels); ``None`` with
        fewer than 3 of them.
    q : (K,) float64
        Absolute joint states.
    moving : bool
        Its joints move in this sequence.
    translucent : bool
    """

    visible: np.ndarray
    gt: object
    q: np.ndarray
    moving: bool
    translucent: bool


@dataclass(frozen=True)
class SequenceFrame:
    """One frame: its noisy depth, the intrinsics, every object's truth and the occluder's pixels."""

    index: int
    depth: np.ndarray
    intrinsics: object
    objects: tuple
    occluded: np.ndarray


def _ease(t: float) -> float:
    return 0.5 - 0.5 * np.cos(np.pi * t)


class _Scene:
    """The scene of one sequence, built once; :meth:`frame` renders a time."""

    def __init__(self, config: SceneSequenceConfig, index: int):
        import trimesh

        from ..geometry.rotations import axis_angle_matrix
        from ..geometry.transforms import Sim3
        from ..model.articulated import ArticulatedModel, Part
        from .conventions import part_vertices_canonical
        from .generate import FrameGenerator, GenerationConfig
        from .render import ModelRenderer
        from .scenes import COMPANION_STEP_BACK, _companions, curtain_mesh

        self.config = config
        rng = np.random.default_rng([config.seed, index, 7])
        self.gen = gen = FrameGenerator(GenerationConfig(category=config.category, split="test", seed=config.seed))
        base = int(index) * 13 + 1
        frame = gen.frame(base)
        self.intrinsics = frame.intrinsics
        model, renderer = gen.instance(frame.instance_index)
        verts = np.concatenate(part_vertices_canonical(model, frame.joint_states_abs))
        lo, hi = verts.min(axis=0), verts.max(axis=0)
        size = float(np.linalg.norm(hi - lo))
        T0 = frame.T_cam_base
        if config.objects > 1:
            T0 = Sim3(T0.rotation, COMPANION_STEP_BACK * T0.translation)
        placed = _companions(gen, base, max(config.objects - 1, 0), model, T0, frame.intrinsics, lo, hi, size, rng)
        self.objects = []  # per object: renderer, model, q0, T_cam0_base, moving sub-range
        if config.objects > 0:
            self.objects.append({"renderer": renderer, "model": model, "q": np.asarray(frame.joint_states_abs, float),
                                 "T_cam_base": T0})
            self.objects += [{k: c[k] for k in ("renderer", "model", "q", "T_cam_base")} for c in placed]
        for c in placed:
            lo, hi = np.minimum(lo, c["lo"]), np.maximum(hi, c["hi"])
        R1 = model.R_canon_base
        centre = (lo + hi) / 2
        self.centre_cam0 = T0.apply((centre @ R1)[None])[0]  # canonical -> base (c @ R1 = R1^T c) -> camera 0
        self.up_cam0 = T0.rotation @ (R1.T @ np.array([0.0, 1.0, 0.0]))
        # the floor and a wall behind the objects, in the first object's base frame
        eye = R1 @ T0.inverse().translation  # the camera in the canonical frame
        floor = trimesh.creation.box((8.0, 0.02, 8.0))
        floor.apply_translation([centre[0], lo[1] - 0.01, centre[2]])
        # the wall faces the camera behind the objects (perpendicular to the horizontal line of sight)
        sight = centre - eye
        sight[1] = 0.0
        sight /= max(np.linalg.norm(sight), 1e-9)
        wall = curtain_mesh(4.0, 3.0, rng.uniform(0.0, 0.05) * size, rng.uniform(0.15, 0.6), rng.uniform(0, 2 * np.pi))
        turn = np.eye(4)
        turn[:3, :3] = axis_angle_matrix(np.array([0.0, 1.0, 0.0]), float(np.arctan2(sight[0], sight[2])))
        wall.apply_transform(turn)
        reach = 0.5 * float(np.linalg.norm(hi - lo)) + rng.uniform(0.2, 1.0) * size
        wall.apply_translation(np.array([centre[0], lo[1], centre[2]]) + reach * sight)
        mesh = trimesh.util.concatenate([floor, wall])
        to_base = np.eye(4)
        to_base[:3, :3] = R1.T
        mesh.apply_transform(to_base)
        self.surroundings = ModelRenderer(ArticulatedModel((Part("surroundings", mesh),), (), name="surroundings"))
        self.T_cam0_base0 = T0
        occ = trimesh.creation.box(OCCLUDER_SIZE_M)
        self.occluder = ModelRenderer(ArticulatedModel((Part("occluder", occ),), (), name="occluder"))
        # the opening of object 0: a sub-range of each joint's limits, one period over the sequence
        self.sweep = None
        if self.objects:
            m = self.objects[0]["model"]
            lo_q, hi_q = m.lower_limits, m.upper_limits
            span = hi_q - lo_q
            share = rng.uniform(config.opening_share, 1.0, size=len(span))
            a = lo_q + rng.uniform(0.0, 1.0 - share) * span
            self.sweep = (a, a + share * span, rng.uniform(0, 2 * np.pi))
        self.occluder_start = rng.uniform(0.2, 1.0 - config.occluder_share - 0.05) if config.occluder_share < 0.75 else 0.0
        self.occluder_side = float(rng.choice([-1.0, 1.0]))
        self.azimuth = np.deg2rad(config.azimuth_drift_deg) * float(rng.choice([-1.0, 1.0]))

    def camera(self, t: float):
        """``T_camt_cam0``: camera 0's frame to camera ``t``'s (the turn about the vertical through the centre)."""
        from ..geometry.rotations import axis_angle_matrix
        from ..geometry.transforms import Sim3

        e = _ease(t)
        Rz = axis_angle_matrix(self.up_cam0, self.azimuth * e)
        c = self.centre_cam0
        position = c - Rz @ c  # camera t in camera 0: turned about the vertical through c ...
        position = position + self.config.distance_drift * e * (c - position)  # ... and moved towards c
        T_cam0_camt = Sim3(Rz, position)
        return T_cam0_camt.inverse()

    def states(self, k: int, i: int) -> np.ndarray:
        """Absolute joint states of object ``k`` on frame ``i``."""
        q = self.objects[k]["q"]
        if k != 0 or self.sweep is None:
            return q
        a, b, phase = self.sweep
        period = self.config.period or self.config.length
        return a + (b - a) * (1.0 - np.cos(2 * np.pi * i / period + phase)) / 2.0

    def frame(self, i: int) -> SequenceFrame:
        from ..geometry.transforms import Sim3
        from .noise import apply_noise
        from .scenes import TRANSLUCENT_KEEP, _blobs, _truth, nearest_surface

        cfg = self.config
        t = i / max(cfg.length - 1, 1)
        rng = np.random.default_rng([cfg.seed, i, 11])
        C = self.camera(t)
        intr = self.intrinsics
        views, poses, states = [], [], []
        for k, o in enumerate(self.objects):
            T = C @ o["T_cam_base"]
            q = self.states(k, i)
            views.append(o["renderer"].render(q, T, intr))
            poses.append(T)
            states.append(q)
        depths = [v.depth for v in views]
        depths.append(self.surroundings.render(np.zeros(0), C @ self.T_cam0_base0, intr).depth)
        occluder_on = False
        if cfg.occluder:
            s = (t - self.occluder_start) / cfg.occluder_share
            if 0.0 <= s <= 1.0:  # it crosses in front of the objects, halfway between them and the camera
                occluder_on = True
                c = 0.5 * self.centre_cam0
                half_width = 0.6 * np.linalg.norm(self.centre_cam0) * intr.width / (2 * intr.fx)
                x = self.occluder_side * (2 * s - 1) * half_width
                T_occ = Sim3(C.rotation, C.apply((c + np.array([x, 0.0, 0.0]))[None])[0])
                depths.append(self.occluder.render(np.zeros(0), T_occ, intr).depth)
        depth, nearest = nearest_surface(depths)
        occluded = (nearest == len(depths) - 1) if occluder_on else np.zeros(depth.shape, dtype=bool)
        seen = [nearest == k for k in range(len(views))]
        if cfg.translucent is not None:
            k = cfg.translucent
            holes = seen[k] & ~_blobs(depth.shape, rng.uniform(*TRANSLUCENT_KEEP), rng)
            depth[holes] = 0.0
            seen[k] = seen[k] & ~holes
        depth = apply_noise(depth, self.gen.config.noise, rng)
        seen = [s & (depth > 0) for s in seen]
        objects = []
        for k, o in enumerate(self.objects):
            gt = None
            if np.count_nonzero(seen[k]) >= 3:
                gt = _truth({"model": o["model"], "q": states[k], "T_cam_base": poses[k]}, views[k], seen[k], intr, rng)
            objects.append(SequenceObject(seen[k], gt, np.asarray(states[k]), k == 0, cfg.translucent == k))
        return SequenceFrame(i, depth, intr, tuple(objects), occluded)


def render_scene_sequence(config: SceneSequenceConfig, index: int = 0):
    """The frames of sequence ``index`` of ``config`` (module docstring), one after another (a generator of
    :class:`SequenceFrame`)."""
    if not isinstance(config, SceneSequenceConfig):
        raise ValueError(f"config: expected a SceneSequenceConfig, got {type(config).__name__}")
    scene = _Scene(config, check_int(index, "index", minimum=0))
    for i in range(config.length):
        yield scene.frame(i)
