"""Measuring ``ancsh evaluate-cad``: articulated ICP vs rigid ICP baselines on rendered view sequences.

Protocol (like the real-data sequences of the paper, Michel et al. 2015): every object is
held at one fixed articulation (joint states drawn uniformly in their limits) while a
camera orbits it -- azimuth swept over 120 degrees around the direction that shows all
parts best, elevation 20-40 degrees, distance 1.6-2.2 object diagonals. Each view is
rendered noise-free and with Kinect-like sensor noise (:class:`ancsh.data.noise.DepthNoise`),
back-projected and subsampled. Every method starts from the same realistic
initialisation per frame: the true object pose perturbed by a rotation of 15-30 degrees
about a random axis and a translation of 5% of the object diagonal, with every joint
state drawn anywhere in its range (no tracking: frames are independent).

Metric: AD (Michel et al.): part ``j`` is correct when the mean distance of its surface
points under the estimated and the true pose is below 10% of the part's diameter; the
whole chain is correct when all parts are.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..._machine import machine_facts
from ...geometry.metrics import AD_THRESHOLD, ad_error, joint_state_error
from ...geometry.rotations import exp_so3
from ...geometry.transforms import Sim3
from ...model.articulated import ArticulatedModel, sample_surface
from ...solvers.icp.template import ArticulatedPose

__all__ = ["EvalConfig", "FrameRecord", "SequenceFrame", "PartPoints", "METHODS", "AD_THRESHOLD", "ad_correct",
           "evaluation_objects", "perturbed_init", "render_sequence", "run_evaluation"]

METHODS = ("articulated_icp", "per_part_icp", "whole_object_icp", "per_part_icp_gt_labels")


@dataclass(frozen=True)
class EvalConfig:
    """Size of an evaluation run.

    Attributes
    ----------
    frames : int
        Views per sequence (per object and noise setting).
    points : int
        Observed points per frame (random subsample of the back-projected depth).
    procedural : tuple of (category, seed)
        Procedural instances to include.
    shared : bool
        Include every URDF of the shared data folder (objects without a movable joint are skipped).
    max_shared : int or None
        Keep only the first ``max_shared`` shared objects (quick runs).
    image_size : (int, int)
        Rendered ``(width, height)`` in pixels (Kinect field of view).
    seed : int
    """

    frames: int = 6
    points: int = 1000
    procedural: tuple = (("eyeglasses", 0), ("oven", 0), ("washing_machine", 0), ("laptop", 0), ("drawer", 0))
    shared: bool = True
    max_shared: int | None = None
    image_size: tuple = (320, 240)
    seed: int = 0

    @classmethod
    def quick(cls) -> "EvalConfig":
        """About 2 minutes: 2 procedural and 3 shared objects, 3 views per sequence."""
        return cls(frames=3, points=1000, procedural=(("laptop", 0), ("drawer", 0)), max_shared=3)


@dataclass(frozen=True)
class SequenceFrame:
    """One rendered view: observed points and the truth."""

    points_cam: np.ndarray
    T_cam_base: Sim3
    q: np.ndarray
    part_labels: np.ndarray


@dataclass(frozen=True)
class FrameRecord:
    """Scores of one method on one frame (see ``docs/REPORT_SCHEMAS.md``).

    Attributes
    ----------
    object, method : str
    noise : bool
        Whether the frame has sensor noise.
    frame : int
    part_correct : list of bool
        AD test per part.
    chain_correct : bool
        Every part correct.
    joint_errors : list of float
        Joint-state error per joint (degrees / hundredths of the model unit; NaN when unknown).
    time_s : float
    status : str
        The fit's status value.
    ad_over_diameter : list of float
        AD error over the part diameter, per part.
    """

    object: str
    noise: bool
    frame: int
    method: str
    part_correct: list
    chain_correct: bool
    joint_errors: list
    time_s: float
    status: str
    ad_over_diameter: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return asdict(self)


# --------------------------------------------------------------------------------------
# objects and sequences
# --------------------------------------------------------------------------------------
def evaluation_objects(config: EvalConfig) -> tuple[list[tuple[str, ArticulatedModel]], list[str]]:
    """``([(name, model), ...], skipped messages)``: procedural instances, then shared URDFs."""
    objects, skipped = [], []
    if config.procedural:
        from ...data.procedural import make_object

        for category, seed in config.procedural:
            objects.append((f"procedural/{category}_{seed}", make_object(category, seed)))
    if config.shared:
        from ...data.paths import shared_data_dir, shared_objects
        from ...data.urdf import load_urdf

        root = shared_data_dir()
        paths = list(shared_objects())
        count = 0
        for path in paths:
            if config.max_shared is not None and count >= config.max_shared:
                break
            name = str(Path(path).relative_to(root)) if Path(path).is_relative_to(root) else Path(path).name
            try:
                model = load_urdf(path)
            except ValueError as exc:
                skipped.append(f"{name}: {exc}")
                continue
            if model.num_joints == 0:
                skipped.append(f"{name}: no movable joint")
                continue
            meshless = [p.name for p in model.parts if p.mesh is None]
            if meshless:
                skipped.append(f"{name}: part(s) {meshless} have no geometry (their pose cannot be observed)")
                continue
            objects.append((name, model))
            count += 1
    return objects, skipped


def _orbit_pose(model: ArticulatedModel, q, center_base, diagonal, azimuth, elevation, distance) -> Sim3:
    from ...data.render import look_at

    R = model.R_canon_base  # base -> canonical (+y up, +z front)
    d = np.array([np.cos(elevation) * np.sin(azimuth), np.sin(elevation), np.cos(elevation) * np.cos(azimuth)])
    eye = center_base + R.T @ (distance * diagonal * d)
    return look_at(eye, center_base, R.T @ np.array([0.0, 1.0, 0.0]))


def render_sequence(model: ArticulatedModel, q, frames: int, rng, *, noise: bool, intrinsics=None,
                    points: int = 2000, min_part_pixels: int = 100) -> list[SequenceFrame]:
    """Views of ``model`` at fixed joint states ``q`` from a camera orbiting it.

    The orbit is centred on the azimuth (of 8 candidates) whose view shows the least
    visible part best; azimuths sweep +-60 degrees around it. A view in which some part
    covers fewer than ``min_part_pixels`` pixels moves halfway towards the centre azimuth
    (at most 3 times), so every part is observable in (nearly) every view.

    Parameters
    ----------
    model : ArticulatedModel
    q : (K,) float64
        Absolute joint states, fixed for the sequence.
    frames : int
    rng : numpy.random.Generator or int
    noise : bool
        Apply :class:`ancsh.data.noise.DepthNoise` (Kinect-like) to every depth image.
    intrinsics : Intrinsics, optional
    points : int
        Subsample size per frame (all points when fewer).
    """
    from ...data.noise import DepthNoise, apply_noise
    from ...data.render import Intrinsics, ModelRenderer, backproject, object_extent
    from ...geometry._checks import check_generator

    rng = check_generator(rng)
    intr = intrinsics if intrinsics is not None else Intrinsics.kinect(320, 240)
    renderer = ModelRenderer(model)
    center, diag = object_extent(model, q)
    best_az, best_vis = 0.0, -1.0
    for az in np.radians(np.arange(0, 360, 45)):
        vis = renderer.render(q, _orbit_pose(model, q, center, diag, az, np.radians(30), 1.9), intr, visibility=True).visibility
        if vis.min() > best_vis + 1e-9:
            best_az, best_vis = az, float(vis.min())
    out = []
    azimuths = best_az + np.radians(np.linspace(-60, 60, frames)) if frames > 1 else np.array([best_az])
    for i, az in enumerate(azimuths):
        el = np.radians(30 + 10 * np.sin(2 * np.pi * i / max(frames, 1)))
        dist = rng.uniform(1.6, 2.2)
        # Every part must show at least min_part_pixels pixels (an unseen part's pose is not
        # observable); otherwise the view moves halfway towards the centre azimuth, up to 3 times.
        for _ in range(4):
            T = _orbit_pose(model, q, center, diag, az, el, dist)
            fr = renderer.render(q, T, intr)
            if fr.part_pixels(model.num_parts).min() >= min_part_pixels:
                break
            az = 0.5 * (az + best_az)
        depth = apply_noise(fr.depth, DepthNoise(), rng) if noise else fr.depth
        mask = depth > 0
        pts = backproject(depth, intr, mask)
        labels = fr.part_ids[mask].astype(np.int64)
        if pts.shape[0] > points:
            keep = rng.choice(pts.shape[0], points, replace=False)
            pts, labels = pts[keep], labels[keep]
        out.append(SequenceFrame(pts, T, np.asarray(q, dtype=float), labels))
    return out


def perturbed_init(model: ArticulatedModel, T_cam_base: Sim3, rng, *, angle_deg=(15.0, 30.0),
                   translation_fraction: float = 0.05) -> ArticulatedPose:
    """A realistic initial estimate: the true base pose perturbed, joint states anywhere.

    The rotation is perturbed by an angle uniform in ``angle_deg`` about a random axis
    through the object's centre, the translation by ``translation_fraction`` of the
    object's diagonal in a random direction; joint states are uniform in their limits
    (``+-pi`` for unlimited revolute joints).
    """
    from ...data.render import object_extent

    q_rand = model.random_states(rng)
    center, diag = object_extent(model, model.rest_states)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    dR = exp_so3(axis * np.radians(rng.uniform(*angle_deg)))
    dt = rng.normal(size=3)
    dt *= translation_fraction * diag / np.linalg.norm(dt)
    c_cam = T_cam_base.apply(center)
    # rotate about the object's centre in the camera, then shift
    R = dR @ T_cam_base.rotation
    t = dR @ (T_cam_base.translation - c_cam) + c_cam + dt
    return ArticulatedPose(Sim3(R, t), q_rand)


# --------------------------------------------------------------------------------------
# metric
# --------------------------------------------------------------------------------------
class PartPoints:
    """Surface samples of every part (part frame) and the part diameters, for AD."""

    def __init__(self, model: ArticulatedModel, count: int = 500, seed: int = 0):
        rng = np.random.default_rng(seed)
        self.points = [sample_surface(p.mesh, count, rng) for p in model.parts]
        self.diameters = np.array([_diameter(p) for p in self.points])


def _diameter(points: np.ndarray) -> float:
    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)
    return float(d.max())


def ad_correct(part_points: PartPoints, T_est_parts, T_gt_parts, threshold: float = AD_THRESHOLD):
    """``(correct (M,) bool, ad / diameter (M,))`` of the AD criterion for every part."""
    ratios = np.array([ad_error(p, Te, Tg) / d for p, Te, Tg, d in
                       zip(part_points.points, T_est_parts, T_gt_parts, part_points.diameters)])
    return ratios < threshold, ratios


# --------------------------------------------------------------------------------------
# run
# --------------------------------------------------------------------------------------
class _ObjectEvaluator:
    """A worker of :func:`run_evaluation`: ``worker(oi)`` -> the records of object ``oi`` (both noise settings),
    a pure function of the configuration and ``oi`` (its random stream is seeded by ``(config.seed, oi)``)."""

    def __init__(self, config: EvalConfig, methods: tuple):
        self.config, self.methods = config, tuple(methods)
        self.objects, _ = evaluation_objects(config)

    def __call__(self, oi: int) -> list:
        from ...data.render import Intrinsics, object_extent
        from ...solvers.icp.articulated import articulated_icp
        from ...solvers.icp.rigid import RigidIcpConfig, per_part_icp, whole_object_icp
        from ...solvers.icp.template import ModelSurface

        config = self.config
        name, model = self.objects[oi]
        intr = Intrinsics.kinect(*config.image_size)
        records: list[FrameRecord] = []
        rng = np.random.default_rng([config.seed, oi])
        q_seq = model.random_states(rng)
        part_points = PartPoints(model)
        surface = ModelSurface(model)
        # The baselines gate correspondences at 10% of the object diagonal (the initial error
        # is 5% of the diagonal plus 15-30 degrees), like articulated ICP's first gate.
        rigid = RigidIcpConfig(max_distance=0.1 * object_extent(model, model.rest_states)[1])
        for noise in (False, True):
            seq = render_sequence(model, q_seq, config.frames, rng, noise=noise, intrinsics=intr, points=config.points)
            for fi, fr in enumerate(seq):
                init = perturbed_init(model, fr.T_cam_base, rng)
                gt_parts = [fr.T_cam_base @ T for T in model.forward_kinematics(fr.q)]
                for method in self.methods:
                    t0 = time.perf_counter()
                    if method == "articulated_icp":
                        res = articulated_icp(model, fr.points_cam, init, rng=fi, surface=surface)
                    elif method == "per_part_icp":
                        res = per_part_icp(model, fr.points_cam, init, config=rigid, rng=fi, surface=surface)
                    elif method == "per_part_icp_gt_labels":
                        res = per_part_icp(model, fr.points_cam, init, labels=fr.part_labels, config=rigid, rng=fi)
                    else:  # whole_object_icp (methods are checked by run_evaluation)
                        res = whole_object_icp(model, fr.points_cam, init, config=rigid, rng=fi)
                    dt = time.perf_counter() - t0
                    ok, ratios = ad_correct(part_points, res.T_cam_parts, gt_parts)
                    jerr = [
                        joint_state_error(res.q[k] - j.rest, fr.q[k] - j.rest, j.type.value)
                        if np.isfinite(res.q[k]) else float("nan")
                        for k, j in enumerate(model.joints)
                    ]
                    records.append(FrameRecord(name, noise, fi, method, ok.tolist(), bool(ok.all()), jerr, dt,
                                               str(res.status.value if hasattr(res.status, "value") else res.status),
                                               ratios.tolist()))
        return records


def run_evaluation(config: EvalConfig = EvalConfig(), *, methods=METHODS, progress=None, executor=None):
    """Evaluate ``methods`` on every object and noise setting; returns ``(records, meta)``.

    ``executor`` (:mod:`ancsh.executors`; default: in this process) evaluates one object per task;
    the records (all but ``time_s``) do not depend on it. ``progress(name, noise, records)`` is called
    for each object and noise setting as its records arrive (in object order).
    """
    from ...executors import LocalExecutor, RayExecutor

    bad = [m for m in methods if m not in METHODS]
    if bad:
        raise ValueError(f"methods: unknown method(s) {bad}; known: {METHODS}")
    if executor is None:
        executor = LocalExecutor(1)
    elif not isinstance(executor, (LocalExecutor, RayExecutor)):
        raise ValueError(f"executor: expected a LocalExecutor or RayExecutor, got {type(executor).__name__}")
    objects, skipped = evaluation_objects(config)
    records: list[FrameRecord] = []
    for (name, _), recs in zip(objects, executor.imap(_ObjectEvaluator, (config, tuple(methods)), range(len(objects)))):
        records += recs
        if progress is not None:
            for noise in (False, True):
                progress(name, noise, [r for r in recs if r.noise == noise])
    meta = {
        "machine": machine_facts(),
        "objects": [
            {"name": n, "parts": m.part_names, "joints": [(j.name, j.type.value) for j in m.joints]} for n, m in objects
        ],
        "skipped": skipped,
        "config": {
            "frames": config.frames, "points": config.points, "procedural": [list(p) for p in config.procedural],
            "shared": config.shared, "max_shared": config.max_shared, "image_size": list(config.image_size),
            "seed": config.seed,
        },
    }
    return records, meta


