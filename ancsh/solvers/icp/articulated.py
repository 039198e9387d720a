"""Articulated ICP: template correspondences + the reduced-coordinate solve, alternated.

Each iteration

1. matches every observed point to the closest point of the model posed at the current
   estimate (:class:`~ancsh.solvers.icp.template.TemplateProvider`: part label, NPCS
   coordinates, normal; gated and robustly weighted);
2. solves the solver core's **reduced-coordinate program** (object pose + one state per
   joint, part poses by forward kinematics in NAOCS, joint limits as bounds; see
   :mod:`ancsh.solvers.program`) on these correspondences, starting from the current
   estimate, with the object scale fixed to the model's (a CAD model is metric);
3. stops when no part moves by more than the tolerance.

The data energy is the core's point-to-point :class:`~ancsh.solvers.terms.DataTerm`, plus
(``point_to_plane=True``) the point-to-plane term of :mod:`ancsh.solvers.terms.data`. Both
live on per-part moments, and each part's energy is weighted by its share of the weights,
so the total is the classic ICP sum over points.

This is a thin wrapper over the core's public pieces (:func:`~ancsh.solvers.program.get_program`,
:func:`~ancsh.solvers.backends.solve`, :func:`~ancsh.solvers.terms.part_moments`) because
:func:`ancsh.solvers.fit` always initialises from RANSAC/per-part Umeyama and estimates the
object scale, whereas ICP starts from a given estimate with a known scale.

Multi-start, in three stages:

1. every start -- each initial estimate, with the joint states as given and at
   ``joint_starts`` states spread over their ranges, and with optional extra orientations --
   runs ``start_iterations`` iterations and is scored symmetrically (observed points far
   from the model, plus model surface the camera should see where nothing was observed);
2. the best-scoring start is refined, then every joint is restarted over its range (one
   at a time, the others kept) and the best-scoring state is kept: with the object pose
   settled this escapes joint local minima, e.g. a drawer front matched to the drawer's
   side walls;
3. the result is iterated to convergence. When it explains fewer than ``accept_inliers``
   of the points, the next best start from another basin goes through stages 2-3 (at
   most ``candidates`` starts), and the best-scoring result wins.

Then, with ``symmetric_starts``, the turns of the result that a near-symmetric shape allows (its parts
swapped, half turns) are finished too and the fit the depth supports best is kept; with ``noise_status`` the
status says whether that fit explains the depth to the sensor noise and whether a distinct fit explains it
as well (see :class:`ArticulatedIcpConfig`). ``ancsh fit-cad`` uses both (:meth:`ArticulatedIcpConfig.instance`).

Visibility: correspondences are restricted to model surface the camera can see (see
:meth:`~ancsh.solvers.icp.template.ModelSurface.closest`), so front-face points of a thin
part are never matched to its back face.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ...geometry._checks import as_array, check_bool, check_choice, check_generator, check_int, check_number, check_positive
from ...geometry.robust import ROBUST_LOSSES
from ...geometry.rotations import exp_so3, geodesic_angle
from ...geometry.transforms import Sim3
from ...model.articulated import ArticulatedModel
from ..types import FitStatus, Observation
from .result import CadFitResult, IcpIteration
from .template import ArticulatedPose, ModelSurface, ModelTemplate, TemplateProvider
from .reduced import icp_uncertainty, reduced_step
from .scoring import FitScore, FitScorer
from .verdict import NoiseJudge

__all__ = ["ArticulatedIcpConfig", "FitScore", "FitScorer", "MIN_PART_INLIERS", "articulated_icp", "auto_init",
           "icp_uncertainty", "part_evidence", "reduced_step", "symmetric_hypotheses", "unsupported_parts"]


@dataclass(frozen=True)
class ArticulatedIcpConfig:
    """Settings of :func:`articulated_icp`; distances are fractions of the model's diagonal
    (the diagonal of its box at rest) with a floor in metres.

    Attributes
    ----------
    max_iterations : int
        ICP iterations of the final (best) start.
    gate_start, gate_end : float
        Correspondence gating distance of the first and the final iterations (diagonals);
        it shrinks geometrically by ``gate_decay`` per iteration.
    gate_decay : float
        In ``(0, 1]``.
    gate_floor : float
        Minimum gating distance (metres), about 3x the sensor noise.
    loss : str
        Robust loss of the correspondence weights (``none``, ``huber``, ``cauchy``, ``tukey``).
    loss_scale : float
        Its scale (diagonals), floored at ``gate_floor / 3``.
    point_to_plane : bool
        Add the point-to-plane data term (faster, more accurate convergence on planar parts).
    point_weight : float
        Weight of the point-to-point term relative to point-to-plane (when enabled). Pure
        point-to-plane (0) converges fastest but lets a part that shows one plane slide in
        it (a sliding door); a small weight pins it through its edges.
    tolerance : float
        Convergence: every part moves less than ``tolerance`` diagonals (at its farthest
        model point) between two iterations.
    joint_starts : int
        Extra starts with every joint at ``(i + 0.5) / joint_starts`` of its range.
    orientations : tuple of (3,) rotation vectors
        Extra starts with the initial base orientation turned by these rotations (about
        the object's centre, camera axes, radians).
    start_iterations : int
        ICP iterations of every start before the best one is continued.
    joint_restarts : bool
        After ``refine_iterations`` more iterations of the best start, restart every joint
        (one at a time, the rest kept) at ``joint_starts`` states over its range for
        ``start_iterations`` iterations and continue whichever scores best.
    refine_iterations : int
    candidates : int
        The best-scoring starts (one per basin: starts that ended near a tried one are
        skipped) are finished one after another (refine, joint restarts, convergence) until one explains ``accept_inliers`` of the observed points within
        the final gate; at most ``candidates`` of them. The best-scoring result is returned.
    accept_inliers : float
        In ``(0, 1]``.
    rescue_angle : float
        When no start explains ``accept_inliers`` of the points, the initial and the best
        estimates turned by this angle (radians) about each camera axis, both signs, are
        searched as well; 0 turns this off.
    num_points : int or None
        Random subsample of the observation used by ICP (``None``: all points).
    solver : str
        Backend of the reduced solve (``"lsq"`` or ``"ipopt"``).
    solver_iterations : int
        Backend iterations per ICP iteration.
    uncertainty : bool
        Compute :attr:`CadFitResult.uncertainty` at the result (:func:`icp_uncertainty`; one more
        closest-point match and a linearisation).
    symmetric_starts : bool
        After the search, finish the turns of its result that the model's shape allows as well
        (:func:`symmetric_hypotheses`: each revolute joint's two parts swapped, 180 degree turns about the
        model's principal axes) and keep the one the depth supports best (:func:`~.scoring.depth_support`,
        scored with surface samples drawn from a fixed seed, so the choice does not depend on ``rng``).
    noise_status : bool
        Judge the result at the scale of the sensor noise, estimated from the points
        (:func:`~.scoring.noise_tolerance`): ``LARGE_RESIDUAL`` when fewer than ``accept_inliers`` of the
        points lie within the tolerance of the model (or more than ``1 - accept_inliers`` of its visible
        surface is unobserved); ``AMBIGUOUS`` when an AD-distinct fit (another part pose more than
        :data:`~ancsh.geometry.metrics.AD_THRESHOLD` of the part's diameter away) explains the points too and
        not significantly worse (:data:`~.verdict.AMBIGUITY_Z`); a fit stopped by ``max_iterations`` that explains the
        points and whose last step moved every part by less than the tolerance is ``SUCCESS`` (converged to
        the noise) rather than ``MAX_ITER``; a chosen fit still moving at the limit first gets
        ``max_iterations`` more iterations. When no fit explains the points, up to ``candidates`` more of the
        basins the searches left unfinished are finished first (best-scoring first, until one does).
    """

    max_iterations: int = 40
    gate_start: float = 0.15
    gate_end: float = 0.02
    gate_decay: float = 0.8
    gate_floor: float = 0.01
    loss: str = "huber"
    loss_scale: float = 0.01
    point_to_plane: bool = True
    point_weight: float = 0.05
    tolerance: float = 1e-4
    joint_starts: int = 3
    orientations: tuple = ()
    start_iterations: int = 5
    joint_restarts: bool = True
    refine_iterations: int = 8
    candidates: int = 4
    accept_inliers: float = 0.8
    rescue_angle: float = np.radians(25.0)
    num_points: int | None = 1500
    solver: str = "lsq"
    solver_iterations: int = 8
    uncertainty: bool = True
    symmetric_starts: bool = False
    noise_status: bool = False

    @classmethod
    def instance(cls, **changes) -> "ArticulatedIcpConfig":
        """The settings of ``ancsh fit-cad``: the exact model of the observed object, so its symmetric starts and
        the status at the sensor noise are on (``changes`` override any field)."""
        return cls(**{"symmetric_starts": True, "noise_status": True, **changes})

    def __post_init__(self):
        for name in ("max_iterations", "start_iterations", "solver_iterations", "refine_iterations", "candidates"):
            check_int(getattr(self, name), name, minimum=1)
        check_int(self.joint_starts, "joint_starts", minimum=0)
        for name in ("gate_start", "gate_end", "gate_floor", "loss_scale", "tolerance"):
            check_positive(getattr(self, name), name)
        if self.gate_end > self.gate_start:
            raise ValueError(f"gate_end: {self.gate_end} exceeds gate_start {self.gate_start}")
        check_number(self.rescue_angle, "rescue_angle", minimum=0.0)
        check_number(self.accept_inliers, "accept_inliers", minimum=0.0, maximum=1.0, lower_open=True)
        check_number(self.gate_decay, "gate_decay", minimum=0.0, maximum=1.0, lower_open=True)
        check_number(self.point_weight, "point_weight", minimum=0.0)
        for name in ("point_to_plane", "joint_restarts", "uncertainty", "symmetric_starts", "noise_status"):
            check_bool(getattr(self, name), name)
        if not self.point_to_plane and self.point_weight == 0:
            raise ValueError("point_weight: must be positive without the point-to-plane term")
        if self.num_points is not None:
            check_int(self.num_points, "num_points", minimum=3)
        check_choice(self.solver, "solver", ("lsq", "ipopt"))
        check_choice(self.loss, "loss", ROBUST_LOSSES)
        rots = []
        for i, r in enumerate(self.orientations):
            rots.append(as_array(r, f"orientations[{i}]", (3,)))
        object.__setattr__(self, "orientations", tuple(rots))


# ---------------------------------------------------------------------------------------------
# the ICP loop
# ---------------------------------------------------------------------------------------------
def _pose_change(parts_a, parts_b, radii) -> float:
    """Largest displacement of any part's farthest point between two pose sets (metres)."""
    worst = 0.0
    for A, B, r in zip(parts_a, parts_b, radii):
        d = np.linalg.norm(A.translation - B.translation) + r * geodesic_angle(A.rotation, B.rotation)
        worst = max(worst, d)
    return worst


class _Run:
    def __init__(self, model, points, config, provider, diagonal, radii, rng):
        self.model, self.points, self.config, self.provider = model, points, config, provider
        self.diagonal, self.radii = diagonal, radii
        self.scorer = FitScorer(points, rng)
        self.scorer.samples(provider.surface)  # draws the samples now, as before (keeps the random stream)

    def gate(self, i: int) -> float:
        c = self.config
        frac = max(c.gate_end, c.gate_start * c.gate_decay**i)
        return max(frac * self.diagonal, c.gate_floor)

    def iterate(self, estimate: ArticulatedPose, start_iter: int, iterations: int, history: list):
        c = self.config
        status = FitStatus.MAX_ITER
        it = start_iter
        for it in range(start_iter, start_iter + iterations):
            gate = self.gate(it)
            prov = self.provider.at(estimate, max_distance=gate)
            prov_parts = estimate.part_poses(self.model)
            corr = prov.correspond(self.points)
            if np.count_nonzero(corr.weights > 0) < 6:
                return estimate, FitStatus.TOO_FEW_POINTS, it, corr
            new, out = reduced_step(prov, self.points, corr, point_to_plane=c.point_to_plane,
                                    point_weight=c.point_weight, solver=c.solver, max_iterations=c.solver_iterations)
            if out.status not in (FitStatus.SUCCESS, FitStatus.MAX_ITER):
                return estimate, out.status, it, corr
            new_parts = new.part_poses(self.model)
            move = _pose_change(prov_parts, new_parts, self.radii)
            estimate = new
            inl = corr.weights > 0
            history.append(IcpIteration(tuple(new_parts), new.q.copy(), float(inl.mean()),
                                        float(np.sqrt(np.mean(corr.distances[inl] ** 2))), gate))
            if move < c.tolerance * self.diagonal and gate <= max(c.gate_end * self.diagonal, c.gate_floor) + 1e-12:
                status = FitStatus.SUCCESS
                break
        return estimate, status, it + 1, None

    def score(self, estimate: ArticulatedPose) -> tuple[float, float, float]:
        """``(score, inlier ratio, inlier rmse)`` of an estimate at the final gate (:class:`FitScorer`)."""
        gate = max(self.config.gate_end * self.diagonal, self.config.gate_floor)
        sc = self.scorer.score(self.provider.surface, estimate.part_poses(self.model), gate)
        return sc.score, sc.inlier_ratio, sc.rmse


@dataclass(frozen=True)
class _Candidate:
    """A start after stage 1: its score, its rank among the starts, the estimate reached, the
    iterations so far and their history."""

    score: float
    order: int
    estimate: ArticulatedPose
    history: list
    iterations: int


@dataclass(frozen=True)
class _Finished:
    """A candidate after stages 2-3: score, inlier ratio and RMSE (see :meth:`_Run.score`),
    final estimate, status and history."""

    score: float
    inlier_ratio: float
    rmse: float
    estimate: ArticulatedPose
    status: FitStatus
    history: list


def _search(run: _Run, model, config, starts, untried: list | None = None) -> tuple[_Finished | None, int]:
    """Stages 1-3 (see the module docstring) from ``starts``: ``(best finished or None, iterations)``; the
    candidates left unfinished (best first) are appended to ``untried`` when given."""
    iterations = 0
    candidates = []
    for s in starts:
        hist: list = []
        est, status, n, _ = run.iterate(s, 0, config.start_iterations, hist)
        iterations += n
        if status != FitStatus.TOO_FEW_POINTS:
            candidates.append(_Candidate(run.score(est)[0], len(candidates), est, hist, n))
    if not candidates:
        return None, 0
    candidates.sort(key=lambda c: (c.score, c.order))
    final = None
    tried: list = []
    for ci, cand in enumerate(candidates):
        if len(tried) >= config.candidates:
            if untried is not None:
                untried.extend(candidates[ci:])
            break
        if any(_same_basin(cand.estimate, other, run.diagonal) for other in tried):
            continue  # finishing a start that sits where a tried one sat would end where it ended
        tried.append(cand.estimate)
        out, used = _finish_candidate(run, model, config, cand)
        iterations += used
        if out is not None and (final is None or out.score < final.score):
            final = out
        if final is not None and final.inlier_ratio >= config.accept_inliers:
            if untried is not None:
                untried.extend(candidates[ci + 1:])
            break
    return final, max(iterations, 1)


def _same_basin(a: ArticulatedPose, b: ArticulatedPose, diagonal: float) -> bool:
    """Base poses within 10 degrees and 5% of the diagonal, joint states within 0.1 rad / 5%."""
    return (
        geodesic_angle(a.T_cam_base.rotation, b.T_cam_base.rotation) < np.radians(10.0)
        and np.linalg.norm(a.T_cam_base.translation - b.T_cam_base.translation) < 0.05 * diagonal
        and bool(np.all(np.abs(a.q - b.q) < 0.1))
    )


def _finish_candidate(run: _Run, model, config, cand: _Candidate) -> tuple[_Finished | None, int]:
    """Refine a start, restart its joints (stage 2), iterate to convergence.

    Returns the finished candidate (``None`` when every correspondence was lost) and the
    number of iterations used.
    """
    est, hist, n = cand.estimate, cand.history, cand.iterations
    used = 0
    if config.joint_restarts and model.num_joints:
        # Stage 2: with the object pose settled, restart each joint over its range (the
        # others kept) and keep whatever scores best; this escapes joint local minima such
        # as a drawer front matched to the drawer's side walls.
        est, status, n2, _ = run.iterate(est, n, config.refine_iterations, hist)
        used += n2 - n
        n = n2
        if status == FitStatus.TOO_FEW_POINTS:
            return None, used
        best = (run.score(est)[0], est, hist, n)
        for q in _joint_grid(model, est.q, config.joint_starts):
            h2: list = []
            e2, st2, m, _ = run.iterate(ArticulatedPose(est.T_cam_base, q), 0, config.start_iterations, h2)
            used += m
            if st2 == FitStatus.TOO_FEW_POINTS:
                continue
            sc = run.score(e2)[0]
            if sc < best[0]:
                best = (sc, e2, hist + h2, m)
        _, est, hist, n = best
    est, status, n2, _ = run.iterate(est, n, max(config.max_iterations - n, 1), hist)
    used += n2 - n
    if status == FitStatus.TOO_FEW_POINTS:
        return None, used
    score, ratio, rmse = run.score(est)
    return _Finished(score, ratio, rmse, est, status, hist), used


def _joint_grid(model: ArticulatedModel, q, count: int) -> list:
    """States ``q`` with one joint at a time moved to ``(i + 0.5) / count`` of its range."""
    lo = np.maximum(model.lower_limits, -np.pi)
    hi = np.minimum(model.upper_limits, np.pi)
    out = []
    for k in range(model.num_joints):
        for i in range(count):
            q2 = np.array(q, dtype=float)
            q2[k] = lo[k] + (i + 0.5) / count * (hi[k] - lo[k])
            out.append(q2)
    return out


def _starts(model: ArticulatedModel, inits: list, config: ArticulatedIcpConfig, center_base) -> list:
    """Every initial estimate, with the joint-state starts and the extra orientations."""
    lo = np.maximum(model.lower_limits, -np.pi)
    hi = np.minimum(model.upper_limits, np.pi)
    joint_qs = [lo + (i + 0.5) / config.joint_starts * (hi - lo) for i in range(config.joint_starts)]
    starts = []
    for init in inits:
        poses = [init.T_cam_base]
        c = init.T_cam_base.apply(center_base)
        for rv in config.orientations:
            dR = exp_so3(rv)
            poses.append(Sim3(dR @ init.T_cam_base.rotation, dR @ (init.T_cam_base.translation - c) + c))
        for T in poses:
            starts.append(ArticulatedPose(T, init.q))
            starts.extend(ArticulatedPose(T, q) for q in joint_qs)
    return starts


def _turned(T: Sim3, R: np.ndarray, origin: np.ndarray) -> Sim3:
    """``T`` turned by ``R`` about the camera-frame point ``origin``."""
    return Sim3(R @ T.rotation, R @ (T.translation - origin) + origin)


def symmetric_hypotheses(model: ArticulatedModel, estimate: ArticulatedPose, diagonal: float) -> list:
    """The turns of ``estimate`` that a near-symmetric shape allows, joint states kept.

    - for each revolute joint, its two parts swapped: a half turn about the line through the joint's pivot,
      perpendicular to its axis and halfway between the directions to the two parts' centres (mean of their mesh
      vertices; a laptop's base where its display was and vice versa);
    - half turns about the three principal axes of the posed model's mesh vertices, through their mean (a box
      turned by its symmetry).

    Turns that land in the basin of ``estimate`` or of an earlier turn (in this order) are dropped (deduplicated).

    Parameters
    ----------
    model : ArticulatedModel
    estimate : ArticulatedPose
    diagonal : float
        The model's diagonal (metres; the basin test's scale).
    """
    parts = estimate.part_poses(model)
    posed = [T.apply(np.asarray(p.vertices, dtype=np.float64)) for T, p in zip(parts, model.parts)]
    cloud = np.concatenate(posed)
    centre = cloud.mean(axis=0)
    _, vecs = np.linalg.eigh(np.cov((cloud - centre).T))
    lines = []
    T = estimate.T_cam_base
    for k, joint in enumerate(model.joints):
        if not joint.is_revolute:
            continue
        axis_b, pivot_b = model.joint_line_in_base(k, estimate.q)
        a, o = T.apply_direction(axis_b), T.apply(pivot_b)
        a = a / np.linalg.norm(a)
        p, c = model.joint_parts(k)
        dirs = []
        for j in (p, c):
            u = posed[j].mean(axis=0) - o
            u -= a * (a @ u)
            dirs.append(u / max(np.linalg.norm(u), 1e-12))
        b = dirs[0] + dirs[1]
        if np.linalg.norm(b) < 1e-6:  # the parts opposite each other (flat): turn about the line across them
            b = np.cross(a, dirs[0])
        lines.append((o, b / np.linalg.norm(b)))
    lines += [(centre, vecs[:, i]) for i in range(3)]  # after the swaps: a near-copy of a swap is dropped
    out: list = []
    for origin, axis in lines:
        h = ArticulatedPose(_turned(T, exp_so3(np.pi * axis), origin), estimate.q)
        if not any(_same_basin(h, other, diagonal) for other in [estimate, *out]):
            out.append(h)
    return out


def auto_init(model: ArticulatedModel, points_cam, *, azimuths: int = 8, elevation_deg: float = 30.0) -> list:
    """Initial estimates without prior knowledge: ``azimuths`` views of the upright model.

    Assumes an upright camera (the model's canonical up, ``R_canon_base^T e_y``, appears as
    image up) looking down by ``elevation_deg``; the model's box centre is placed behind the
    centroid of the observed points (by a quarter of the model diagonal along the viewing
    ray), joints at rest. Pass the list as ``init`` of :func:`articulated_icp`.

    Parameters
    ----------
    model : ArticulatedModel
    points_cam : (N, 3) array_like
        Observed points (metres, camera frame), ``N >= 1``.
    """
    from ...data.render import look_at, object_extent
    from ...geometry._checks import as_points

    pts = as_points(points_cam, "points_cam", min_points=1)
    if isinstance(azimuths, bool) or int(azimuths) < 1:
        raise ValueError(f"azimuths: expected an integer >= 1, got {azimuths!r}")
    center, diag = object_extent(model, model.rest_states)
    R = model.R_canon_base
    el = np.radians(float(elevation_deg))
    centroid = pts.mean(axis=0)
    target = centroid + 0.25 * diag * centroid / max(np.linalg.norm(centroid), 1e-12)
    out = []
    for az in 2 * np.pi * np.arange(int(azimuths)) / int(azimuths):
        d = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
        T = look_at(center + R.T @ (2.0 * diag * d), center, R.T @ np.array([0.0, 1.0, 0.0]))
        out.append(ArticulatedPose(Sim3(T.rotation, T.translation + target - T.apply(center)), model.rest_states))
    return out


def articulated_icp(model: ArticulatedModel, observation, init: ArticulatedPose, *,
                    config: ArticulatedIcpConfig | None = None, rng=0,
                    surface: ModelSurface | None = None) -> CadFitResult:
    """Fit a known articulated model (pose + joint states) to observed points by articulated ICP.

    Parameters
    ----------
    model : ArticulatedModel
        The instance (e.g. from :func:`ancsh.data.urdf.load_urdf`); needs a movable joint.
    observation : Observation or (N, 3) array_like
        Observed points in the camera frame (metres), e.g. a back-projected depth image.
    init : ArticulatedPose or sequence of ArticulatedPose
        Initial base pose(s) and joint states (within the limits), e.g. the previous frame's
        result (tracking), a perturbed guess, or :func:`auto_init`. Every one is a start.
    config : ArticulatedIcpConfig, optional
    rng : numpy.random.Generator or int
        Seeds the point subsample.
    surface : ModelSurface, optional
        A reusable closest-point structure of ``model`` (saves building it per call).

    Returns
    -------
    CadFitResult
        ``method="articulated_icp"``; ``history`` holds the per-iteration estimates of the
        chosen start. Status ``SUCCESS`` (converged), ``MAX_ITER``, or ``TOO_FEW_POINTS`` when
        no observed point lies within the gating distance of the model (e.g. an empty
        observation or one far from the initial estimate).

    Raises
    ------
    ValueError
        Bad arguments: a model without movable joints, points behind the camera, ``init`` not an
        :class:`ArticulatedPose` or outside the joint limits, points not ``(N, 3)`` finite.
    """
    t0 = time.perf_counter()
    config = ArticulatedIcpConfig() if config is None else config
    if not isinstance(config, ArticulatedIcpConfig):
        raise ValueError(f"config: expected an ArticulatedIcpConfig, got {type(config).__name__}")
    template = ModelTemplate(model, surface)  # validates the model (movable joints, meshes)
    points = observation.points_cam if isinstance(observation, Observation) else Observation(observation).points_cam
    if points.shape[0] and np.any(points[:, 2] <= 0):
        raise ValueError("observation: every point must be in front of the camera (z > 0); points are camera-frame")
    inits = [init] if isinstance(init, ArticulatedPose) else list(init) if isinstance(init, (list, tuple)) else None
    if not inits or not all(isinstance(i, ArticulatedPose) for i in inits):
        raise ValueError(f"init: expected an ArticulatedPose or a non-empty sequence of them, got {type(init).__name__}")
    for i in inits:
        model.check_states(i.q, "init.q")
    init = inits[0]
    rng = check_generator(rng)
    if config.num_points is not None and points.shape[0] > config.num_points:
        points = points[np.sort(rng.choice(points.shape[0], int(config.num_points), replace=False))]

    def failed(status, message, estimate=init, history=()):
        return CadFitResult("articulated_icp", tuple(estimate.part_poses(model)), estimate.q.copy(), estimate.T_cam_base,
                            status, message, time_s=time.perf_counter() - t0, history=tuple(history))

    if points.shape[0] < 6:
        return failed(FitStatus.TOO_FEW_POINTS, f"need at least 6 observed points, got {points.shape[0]}")
    diagonal = template.T_cam_naocs_scale
    provider = TemplateProvider(template, max_distance=1.0, loss=config.loss,
                                loss_scale=max(config.loss_scale * diagonal, config.gate_floor / 3))
    rest = model.forward_kinematics(model.rest_states)
    radii = [float(np.max(np.linalg.norm(p.vertices, axis=1))) for p in model.parts]
    run = _Run(model, points, config, provider, diagonal, radii, rng)
    center_base = np.mean(np.concatenate([T.apply(p.vertices) for T, p in zip(rest, model.parts)]), axis=0)

    starts = _starts(model, inits, config, center_base)
    untried: list = []  # candidates of the searches left unfinished, for the status at the sensor noise
    final, iterations = _search(run, model, config, starts, untried)
    if final is None and iterations == 0:
        return failed(FitStatus.TOO_FEW_POINTS,
                      f"no observed point within {run.gate(0):.3g} (model units) of the model at any start "
                      "(observation far from the estimate?)")
    if config.rescue_angle > 0 and (final is None or final.inlier_ratio < config.accept_inliers):
        # Rescue: no start explained the data; try the initial and the best estimates turned
        # by rescue_angle about each camera axis (both signs), with the joint-state starts.
        bases = [inits[0]] + ([final.estimate] if final is not None else [])
        rescue = []
        for b in bases:
            c = b.T_cam_base.apply(center_base)
            for rv in config.rescue_angle * np.vstack([np.eye(3), -np.eye(3)]):
                dR = exp_so3(rv)
                T = Sim3(dR @ b.T_cam_base.rotation, dR @ (b.T_cam_base.translation - c) + c)
                rescue.extend(_starts(model, [ArticulatedPose(T, b.q)], replace(config, orientations=()), center_base))
        second, used = _search(run, model, config, rescue, untried)
        iterations += used
        starts = starts + rescue
        if second is not None and (final is None or second.score < final.score):
            final = second
    if final is None:
        return failed(FitStatus.TOO_FEW_POINTS, "lost every correspondence while iterating")
    judge = None
    if config.symmetric_starts or config.noise_status:
        judge = NoiseJudge(model, points, provider.surface, config.tolerance * diagonal, config.accept_inliers)
    finished = [final]
    if config.symmetric_starts:
        hyps = symmetric_hypotheses(model, final.estimate, diagonal)
        for h in hyps:
            hist: list = []
            e, st, n, _ = run.iterate(h, 0, config.start_iterations, hist)
            iterations += n
            if st == FitStatus.TOO_FEW_POINTS:
                continue
            out, used = _finish_candidate(run, model, config, _Candidate(run.score(e)[0], 0, e, hist, n))
            iterations += used
            if out is not None:
                finished.append(out)
        starts = starts + hyps
    est = final.estimate
    status = final.status
    msg = "converged" if final.status == FitStatus.SUCCESS else f"not converged after {config.max_iterations} iterations"
    if judge is not None:
        supports = [judge.support(f.estimate) for f in finished]
        best = min(range(len(finished)), key=lambda i: (supports[i].score, i))  # ties: the search's own result
        if config.noise_status and not judge.explains(supports[best]):
            # Nothing found explains the depth: finish further basins the searches left (best first, at most
            # ``candidates``) until one does.
            tried = [f.estimate for f in finished]
            for cand in sorted(untried, key=lambda c: c.score):
                if len(tried) >= len(finished) + config.candidates:
                    break
                if any(_same_basin(cand.estimate, other, diagonal) for other in tried):
                    continue
                tried.append(cand.estimate)
                out, used = _finish_candidate(run, model, config, cand)
                iterations += used
                if out is None:
                    continue
                finished.append(out)
                supports.append(judge.support(out.estimate))
                if judge.explains(supports[-1]):
                    break
            best = min(range(len(finished)), key=lambda i: (supports[i].score, i))
        final = finished[best]
        limit = config.max_iterations
        if config.noise_status and final.status == FitStatus.MAX_ITER:
            # Still moving at the limit: one more budget of iterations for the chosen fit alone, so that
            # ``max_iter`` means it really has not converged.
            hist = list(final.history)
            e2, st2, n2, _ = run.iterate(final.estimate, len(hist), config.max_iterations, hist)
            iterations += n2 - len(final.history)
            if st2 != FitStatus.TOO_FEW_POINTS:
                sc, ratio, rmse = run.score(e2)
                finished[best] = final = _Finished(sc, ratio, rmse, e2, st2, hist)
                supports[best] = judge.support(e2)
                limit = 2 * config.max_iterations
        est, status = final.estimate, final.status
        msg = "converged" if status == FitStatus.SUCCESS else f"not converged after {limit} iterations"
        if config.symmetric_starts:
            msg += f" (best of {len(finished)} symmetric hypotheses by depth support)"
        if config.noise_status and status in (FitStatus.SUCCESS, FitStatus.MAX_ITER):
            h = final.history
            step = _pose_change(h[-2].T_cam_parts, h[-1].T_cam_parts, radii) if len(h) >= 2 else float("inf")
            status, msg = judge.verdict([f.estimate for f in finished], supports, best, status, msg, step, limit)
    inlier_gate = max(config.gate_end * diagonal, config.gate_floor)
    near, inl = part_evidence(provider, est, points, run.gate(0), inlier_gate)
    weak = unsupported_parts(model, near, inl, inlier_gate)
    if weak and status in (FitStatus.SUCCESS, FitStatus.MAX_ITER):
        status, msg = FitStatus.TOO_FEW_INLIERS, f"{msg}, but {weak}"
    uncertainty = None
    if config.uncertainty:
        prov = provider.at(est, max_distance=max(config.gate_end * diagonal, config.gate_floor))
        uncertainty = icp_uncertainty(prov, points, prov.correspond(points), point_to_plane=config.point_to_plane,
                                      point_weight=config.point_weight)
    return CadFitResult(
        method="articulated_icp", T_cam_parts=tuple(est.part_poses(model)), q=est.q.copy(), T_cam_base=est.T_cam_base,
        status=status, message=msg, inlier_ratio=final.inlier_ratio, rmse=final.rmse, iterations=iterations,
        time_s=time.perf_counter() - t0, history=tuple(final.history), starts=len(starts), uncertainty=uncertainty,
        part_points=tuple(int(n) for n in near), part_inliers=tuple(int(n) for n in inl),
    )


MIN_PART_INLIERS = 3
"""A part needs at least this many inliers (and half of the points near it) to count as supported."""


def part_evidence(provider: TemplateProvider, estimate: ArticulatedPose, points: np.ndarray, near_gate: float,
                  inlier_gate: float) -> tuple[np.ndarray, np.ndarray]:
    """Per part: observed points nearest to it within ``near_gate``, and those within ``inlier_gate``.

    Parameters
    ----------
    provider : TemplateProvider
    estimate : ArticulatedPose
    points : (N, 3) float64
        Observed points (camera frame, model units).
    near_gate, inlier_gate : float
        Distances (model units): points farther than ``near_gate`` from the model are no evidence for any
        part; an inlier lies within ``inlier_gate``.

    Returns
    -------
    near, inliers : (M,) int64
    """
    corr = provider.at(estimate, max_distance=near_gate).correspond(points)
    M = provider.model.num_parts
    labels, dist = np.asarray(corr.part_labels), np.asarray(corr.distances)
    near = np.bincount(labels[dist <= near_gate], minlength=M)
    inliers = np.bincount(labels[dist <= inlier_gate], minlength=M)
    return near, inliers


def unsupported_parts(model: ArticulatedModel, near, inliers, inlier_gate: float) -> str:
    """A sentence naming every part with fewer than :data:`MIN_PART_INLIERS` inliers or fewer inliers than half the
    points near it; ``""`` when every part is supported."""
    weak = [j for j in range(model.num_parts) if inliers[j] < max(MIN_PART_INLIERS, 0.5 * near[j])]
    if not weak:
        return ""
    parts = ", ".join(f"part {model.parts[j].name!r} has {int(inliers[j])} inliers among the {int(near[j])} points "
                      "near it" for j in weak)
    return (f"{parts} (within {inlier_gate:.3g}; at least {MIN_PART_INLIERS} and half are needed): its pose and joint "
            "state rest on no evidence")
