"""Category-level tracking over a depth sequence: warm starts, fusion over time, carried correspondences.
Long: one tracker whose steps (warm fits, carried and fused correspondences, carried templates) share its state.

:class:`CategoryTracker` turns one observation after another into a :class:`TrackedFrame`:

1. **Warm start**: the previous frame's fit replaces RANSAC as the start of the solve
   (:func:`ancsh.solvers.fit` with ``warm_start=``), and the program gets the
   :class:`~ancsh.solvers.terms.TemporalPriorTerm` toward the constant-velocity prediction of
   the last two fits (:meth:`~ancsh.solvers.terms.PreviousSolution.constant_velocity`; pose and
   joint-state weights in :class:`TrackerConfig`; by default the pose part only). Predictions and
   carried correspondences use the canonical parameters each fit was solved with
   (:attr:`~ancsh.solvers.types.FitResult.canonical`, :func:`fitted_canonical`).
2. **Correspondences**: the provider (the network) runs on every ``network_every``-th frame; in
   between, correspondences are carried by the previous fit (:class:`~ancsh.tracking.carried.CarriedTemplate`:
   nearest points of the last network frame's surface, in the fit's NPCS), re-matched
   ``carried_iterations`` times (default once: one match and one warm solve, without the
   covariances); their object pose is predicted from the network frames (``predict_from``).
3. **Fusion over time** (``fusion_weight > 0``, the default): a network frame is fitted on the
   network's correspondences *and*, with weight ``fusion_weight``, the carried ones of the same
   points (one solve of the same data term on both sets of rows, :func:`~ancsh.tracking.carried.stack_correspondences`).
   The carried rows hold the previous fused estimate moved by the observed motion, so the estimate is a
   recursive weighted mean of the network frames' measurements -- with weight ``w`` the past keeps
   ``w / (1 + w)``: uncorrelated per-frame errors shrink (steady-state variance ``1 / (1 + 2 w)`` of one
   frame's for a still object), a per-instance bias of the network does not. The carried rows are re-centred
   on the network's positions part by part along the directions their closest-point matches cannot see
   (:func:`recentred`: along a thin part, within a flat one, by the normals of its observed points), so there
   the network gives the positions, elsewhere both; and the canonical parameters are averaged alike
   (:func:`fused_canonical`). The price: on exact correspondences a fused
   frame keeps part of the carried frames' error (about half a degree on the test laptop).
4. **Carried category template** (categories in ``TrackerConfig.template_categories``, default the
   laptop): at every (re-)initialisation the cold fit is refined against the category template
   (:func:`~ancsh.solvers.icp.category.refine_fit`, a fraction of a second, once; its revolute joints released
   from the template's own limits, ``RefineConfig.release_revolute``), and where the refinement is
   accepted the track follows that template by warm articulated ICP (an
   :class:`~ancsh.tracking.instance.InstanceTracker` on it, source ``"template"``) instead of network
   or carried-correspondence frames: the network then runs to re-initialise and, on every ``network_every``-th
   template frame, to correct the template's joint states (below). Where the template
   ICP stops explaining the points, the frame is fitted cold (and refined) again -- first against the template
   chosen before, at its scale (``template_reuse``: the object is assumed the same). The network frames'
   joint states correct the template's by a slow offset (``template_states``).
5. **Lost and re-initialised**: a warm fit that fails its solve or a plausibility check
   (:func:`check_fit`: too few inliers -- the points no longer lie where the object was --,
   the category's size range, a large residual) is retried cold on the same frame (network +
   RANSAC, :func:`fit_frame`); a frame with fewer than ``min_points`` points, or whose cold fit
   fails as well, is ``lost``, and the next frame starts cold.

Per-frame statuses (:class:`TrackStatus`): ``initialised`` (the first cold fit), ``tracked``
(a warm fit), ``reinitialised`` (a cold fit after the track was lost or a warm fit failed),
``lost`` (no acceptable fit this frame).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from ..geometry._checks import check_bool, check_choice, check_int, check_number
from ..geometry.transforms import Sim3
from ..solvers.fit import FORMULATIONS, FitConfig, fit
from ..solvers.terms import PreviousSolution
from ..solvers.types import FitResult, FitStatus, Observation
from .instance import InstanceTracker, InstanceTrackerConfig
from .records import TrackedFrame, TrackStatus, joint_state_std

__all__ = ["CategoryTracker", "TrackStatus", "TrackedFrame", "TrackerConfig", "check_fit", "fit_frame",
           "fitted_canonical", "joint_state_std", "predicted_fit", "previous_solution"]


@dataclass(frozen=True)
class TrackerConfig:
    """Settings of :class:`CategoryTracker` (validated on construction).

    Attributes
    ----------
    network_every : int
        Run the provider on every ``k``-th frame (1: every frame); frames in between use
        correspondences carried by the previous fit.
    formulation : str
        A formulation with a program (:data:`ancsh.solvers.FORMULATIONS`).
    solver : str or None
        Its backend (default: the formulation's first).
    temporal_weight : float
        Weight of the pose part of the temporal prior (0: none), ``>= 0``.
    temporal_state_weight : float
        Weight of its joint-state part, ``>= 0``. Default 0: the constant-velocity prediction of a joint
        state is poor where the joint swings (a laptop lid: 4-7 degrees off where the fits are 1-2), and the
        prior pulled the fits toward it; measured with fusion on (``ancsh bench tracking``, k = 3, no
        template), tracking / per-frame joint-state error 0.01 -> 0: laptop learned 1.61 -> 0.90, oracle
        0.92 -> 0.49; drawer 1.0-1.1 either way.
    fusion_weight : float
        Weight of the carried correspondences in a network frame's fit, relative to the network's
        (module docstring, item 3), ``>= 0``; 0: a network frame is fitted on the network's
        correspondences alone (each network frame then a per-frame measurement). Default 2, measured with
        ``ancsh bench tracking`` (k = 3, two sequences per object; tracking / per-frame rotation, translation,
        joint state; laptop without its template) without -> with fusion: oracle drawer 1.12 / 1.56 / 1.68 ->
        0.80 / 1.20 / 1.08, eyeglasses 0.98 / 1.97 / 1.03 -> 0.55 / 1.61 / 0.76, laptop 1.01 / 1.75 / 0.86 ->
        0.67 / 1.41 / 0.49; learned drawer 1.04 / 1.07 / 1.05 -> 0.99 / 1.08 / 1.05, eyeglasses 0.91 / 0.96 /
        0.86 -> 0.88 / 0.96 / 0.85, laptop 0.90 / 1.03 / 0.98 -> 0.84 / 1.02 / 0.90 (the learned errors are
        mostly a per-instance bias, which no fusion removes). A fused network frame costs about a tenth more
        than an unfused one (twice the rows, one closest-point match).
    fusion_recentre : bool
        Re-centre the carried rows of a fused fit on the network's (:func:`recentred`). Measured on oracle
        laptop frames (re-centred along every direction): translation 2.07x per-frame without, 1.56x with.
        Default ``True``.
    recentre_threshold : float or None
        Re-centre only along the directions a part's observed normals see less than this share of
        (:func:`~ancsh.geometry.normals.sliding_projector`), ``> 0``; ``None``: along every direction.
        Default 0.15, measured with ``ancsh bench tracking --categories drawer,eyeglasses --urdf none`` (two
        sequences, k = 3; tracking / per-frame rotation, translation, joint state) ``None`` -> 0.15: oracle
        drawer 0.80 / 1.20 / 1.08 -> 0.84 / 0.97 / 1.01, eyeglasses 0.55 / 1.61 / 0.74 -> 0.56 / 1.53 / 0.77;
        learned drawer 1.00 / 1.06 / 1.07 -> 0.96 / 0.95 / 0.96, eyeglasses 0.99 / 0.99 / 0.84 -> 0.99 / 1.00 /
        0.85; thresholds 0.08 and 0.3 alike. A normal estimate of the frame's points (a few milliseconds) per
        fused frame. (With ``carried_iterations`` 3 as well: oracle translation 0.90 and 1.35, learned 0.93 and
        1.01, at about twice a carried frame's cost.)
    velocity : float
        ``damping`` of the constant-velocity prediction, in ``[0, 1]`` (0: zero velocity).
    carried_iterations : int
        Closest-point matches and solves per frame on carried correspondences, ``>= 1`` (default
        1: one match and one warm solve; 3 measured no more accurate on noisy frames at 3x the
        cost, ``docs/results/tracking.md``).
    carried_gate : float
        Matches farther than this many object diagonals get weight 0, ``> 0``.
    carried_uncertainty : bool
        Compute the fit covariances (``FitConfig.uncertainty``) of carried frames (on their last
        solve only; intermediate solves never do). Default ``True``: every tracked frame reports its
        standard deviations (``ancsh bench tracking`` measures their coverage and the cost); ``False``
        saves a fifth to a third of a carried frame's time (``docs/results/tracking.md``), and carried frames then report no
        ``joint_states_std``. A carried frame's raw covariance counts the carried rows as data, which
        they are not (they repeat the last network frame's errors): its inflation is measured per
        source (``learned-tracked-carried``).
    predict_from : str
        Where the constant-velocity prediction (warm start and temporal prior) of a carried frame
        takes its *object pose*: ``"network"`` (default) from the last two network frames of the track,
        extrapolated by the frames since (``ahead`` of
        :meth:`~ancsh.solvers.terms.PreviousSolution.constant_velocity`); ``"frames"`` from the last two
        fits whatever their source. Joint states, and network frames, always use the last two fits.
        (Measured on realistic oracle laptop frames: carried-frame translation error 0.015 vs 0.031
        object diagonals; the carried ICP step hardly moves a thin part tangentially, so the prediction's
        error stays, and two carried fits are a noisier velocity than two network fits.)
    warm_rescore_rounds : int
        Warm fits (network and carried frames) re-select their inliers with the solved poses and solve
        again, at most this many times (``FitConfig.rescore_rounds`` of warm fits; the larger of the
        two applies), ``>= 0``. A warm start's inliers are the points near the *predicted* pose: where the
        prediction is off (a swinging eyeglasses temple) a part keeps too few of them and the fit fails
        the plausibility check. Measured with the network on every frame (learned provider, benchmark
        sequences): eyeglasses re-initialisations 22 -> 0 with 2 rounds (default), errors unchanged or lower.
    network_scale : bool
        Warm network frames re-estimate the object scale (its log-scale a variable of the solve,
        ``FitConfig.optimize_scale``), pulled toward the predicted scale by the temporal prior's scale
        part; carried frames keep the last fit's scale. ``False``: the scale of the (re-)initialisation
        is kept for the whole track (one frame's scale error on every frame). Default ``True``.
    template_categories : tuple of str
        Categories whose tracks carry the category template refined at (re-)initialisation (see the
        module docstring; the provider's category is ``category`` of :class:`CategoryTracker`). Default
        ``("laptop",)``, measured on the benchmark's learned sequences (tracking / per-frame error, rotation,
        translation, joint state): laptop 0.09, 0.68, 0.39; drawer 16, 2.9, 1.8 (the template ICP slid off the
        drawers); eyeglasses 1.10, 1.22, 1.29. ``()``: never.
    template_icp : InstanceTrackerConfig or None
        The template's warm ICP (default: :class:`~ancsh.tracking.instance.InstanceTrackerConfig` without
        its own cold multi-start: a frame it loses is re-initialised by the network). With its
        ``uncertainty`` (default on) a template frame reports the ICP's covariance mapped to the fit's
        frames (:func:`~ancsh.solvers.icp.category.template_fit_uncertainty`; scale variances unknown),
        inflated for a learned provider by the factors measured on tracked template frames
        (``learned-tracked-template``, ``ancsh bench tracking --calibration-sequences``), else by those of
        single-frame template refinements (``learned-template``, ``ancsh bench uncertainty``).
    template_reuse : bool
        A re-initialisation after a loss first refines against the template chosen before the loss, at its scale
        only (one articulated ICP run, about half the cost of the nearest-template choice with its scale search),
        and falls back to the full refinement where that is not accepted: the object is assumed the same
        when it comes back. Default ``True``, measured with ``ancsh bench tracking --categories laptop`` (learned,
        two sequences, one loss each; tracking / per-frame rotation, translation, joint state and frame rate)
        without -> with: 0.29 / 0.92 / 1.13 at 0.59x the per-frame rate -> 0.24 / 0.96 / 0.94 at 0.71x.
    template_states : bool
        While a category template is carried, the network still runs on every ``network_every``-th frame and a
        quick fit warm from the template's gives its joint states; the template frames report their revolute
        joint states moved by the recursive weighted mean (``fusion_weight`` on the past, the refinement the first)
        of the differences, kept across a re-initialisation that reuses the template. The template's lid is not
        the object's, and its ICP can settle degrees off the network's fit (on 2 of 10 learned test laptops 7-9
        degrees at the refinement); the network's states are the slow part, the template's motion the fast one.
        Default ``True``, measured with ``ancsh bench tracking --categories laptop --sequences 10`` (tracking /
        per-frame rotation, joint state) without -> with: learned 0.37 / 1.69 -> 0.33 / 1.27, oracle 0.33 / 0.53
        -> 0.49 / 0.49 (the oracle's noisier lid rotation pulls the template's), at a network pass and a quick fit
        every ``network_every``-th template frame (laptop frames/s 0.7x of per-frame, 0.95x before). These
        biased templates were real laptops of the library (the shared data); without the shared data the library
        holds procedural laptops only, and there it bought nothing: learned joint-state error of frames 10-20 of
        the first 16 test sequences 1.08 degrees without, 1.24 with.
        ``False``: the network only re-initialises.
    refine_network : bool
        The provider's refinement network (``LearnedProvider(..., refine="network")``) sees each network frame's
        points rotated into the predicted object orientation (CAPTRA's set-up: the previous frames' pose
        canonicalises the input) instead of the first stage's camera-frame input; cold fits are refined by it
        (:func:`~ancsh.learned.inference.refine_network.refine_with_network`). Default ``False``.
    min_points : int
        Fewer observed points: the frame is lost (no fit is tried).
    max_relative_residual : float
        A part whose median point-to-fit distance exceeds this many object diagonals makes a fit
        implausible (``large_residual``), ``> 0``.
    fit : FitConfig
        Settings of every fit (RANSAC settings apply to the cold ones).
    """

    network_every: int = 1
    formulation: str = "exact_reduced"
    solver: str | None = None
    temporal_weight: float = 0.01
    temporal_state_weight: float = 0.0
    velocity: float = 1.0
    carried_iterations: int = 1
    carried_gate: float = 0.1
    carried_uncertainty: bool = True
    predict_from: str = "network"
    warm_rescore_rounds: int = 2
    network_scale: bool = True
    fusion_weight: float = 2.0
    fusion_recentre: bool = True
    recentre_threshold: float | None = 0.15
    template_categories: tuple = ("laptop",)
    template_icp: object = None
    template_reuse: bool = True
    template_states: bool = True
    refine_network: bool = False
    min_points: int = 100
    max_relative_residual: float = 0.1
    fit: FitConfig = field(default_factory=FitConfig)

    def __post_init__(self):
        for name, lo in (("network_every", 1), ("carried_iterations", 1), ("min_points", 3), ("warm_rescore_rounds", 0)):
            object.__setattr__(self, name, check_int(getattr(self, name), name, minimum=lo))
        check_choice(self.formulation, "formulation", tuple(n for n, f in FORMULATIONS.items() if f.parameterisation))
        if self.solver is not None:
            check_choice(self.solver, "solver", FORMULATIONS[self.formulation].solvers)
        for name in ("temporal_weight", "temporal_state_weight", "fusion_weight"):
            check_number(getattr(self, name), name, minimum=0.0)
        check_number(self.velocity, "velocity", minimum=0.0, maximum=1.0)
        check_bool(self.carried_uncertainty, "carried_uncertainty")
        check_bool(self.network_scale, "network_scale")
        check_bool(self.fusion_recentre, "fusion_recentre")
        if self.recentre_threshold is not None:
            check_number(self.recentre_threshold, "recentre_threshold", minimum=0.0, lower_open=True)
        check_bool(self.template_reuse, "template_reuse")
        check_bool(self.template_states, "template_states")
        check_bool(self.refine_network, "refine_network")
        check_choice(self.predict_from, "predict_from", ("network", "frames"))
        for name in ("carried_gate", "max_relative_residual"):
            check_number(getattr(self, name), name, minimum=0.0, lower_open=True)
        if not isinstance(self.fit, FitConfig):
            raise ValueError(f"fit: expected a FitConfig, got {type(self.fit).__name__}")
        if isinstance(self.template_categories, str) or not all(isinstance(c, str) for c in self.template_categories):
            raise ValueError(f"template_categories: expected a tuple of category names, got {self.template_categories!r}")
        object.__setattr__(self, "template_categories", tuple(self.template_categories))

        if self.template_icp is None:
            object.__setattr__(self, "template_icp", InstanceTrackerConfig(reinitialise=False))
        elif not isinstance(self.template_icp, InstanceTrackerConfig):
            raise ValueError(f"template_icp: expected an InstanceTrackerConfig, got {type(self.template_icp).__name__}")


def previous_solution(result: FitResult, correspondences, weight: float, state_weight: float) -> PreviousSolution:
    """The :class:`PreviousSolution` of a fit: its object pose through the root part and its joint states.

    Parameters
    ----------
    result : FitResult
        A successful fit.
    correspondences : Correspondences
        The correspondences it was fitted on (their NPCS -> NAOCS map of the root part).
    """
    r = correspondences.root_part
    T = result.T_cam_npcs[r]
    sigma = T.scale / float(correspondences.npcs_scale[r])
    origin = T.translation - sigma * (T.rotation @ np.asarray(correspondences.npcs_translation[r]))
    return PreviousSolution(Sim3.unchecked(T.rotation, origin, sigma), np.asarray(result.joint_states), weight, state_weight)


def fitted_canonical(correspondences, result: FitResult):
    """``correspondences`` with the canonical parameters ``result`` was solved with (:attr:`FitResult.canonical`).

    A fit with free canonical parameters (``FitConfig.naocs_prior_weight > 0``, the default) moves each
    part's NPCS -> NAOCS translation and each pivot by solved offsets; the tracker's predictions
    (:func:`previous_solution`, :func:`predicted_fit`) and carried correspondences must use the moved
    ones, or forward kinematics of the object pose and joint states does not give back the fitted part
    poses (measured on oracle eyeglasses: the temples moved by 3-6 mm along their length, which the
    carried frames' closest-point matches cannot correct). Unchanged where the fit reports none.
    """
    c = getattr(result, "canonical", None)
    if c is None:
        return correspondences
    return dataclasses.replace(correspondences, npcs_translation=c.npcs_translation, joint_pivots_naocs=c.joint_pivots_naocs)


def recentred(carried, network, points_cam, T_cam_npcs, gate: float, threshold: float | None = None):
    """``carried`` correspondences restricted to the points the network's rows keep and shifted to agree with
    them on each part's position along the directions their closest-point matches cannot see.

    A point keeps its carried weight where the carried and the network's label agree and the network's
    NPCS coordinate, posed at ``T_cam_npcs`` (the warm start), lies within ``gate`` metres of it (the
    warm fit's own inlier rule); each part's carried NPCS coordinates are then shifted so that their
    mean over those points equals the network's. The data term's translation of a part is then the
    same for either set of rows at any rotation and scale: in a fused fit the carried rows inform the
    parts' rotations (and the joint states through them), the network's rows their positions -- closest-
    point matches reproduce the predicted pose along a thin part (they cannot see a slide along it),
    where the network's positions are unbiased. Along the directions the part's surface normals do see
    (:func:`~ancsh.geometry.normals.sliding_projector` of the normals of its observed points, ``threshold``),
    the carried rows keep their position: there the closest-point matches hold the previous estimate moved
    by the observed motion, and the fused fit averages positions over time. ``threshold`` ``None``: every
    direction is re-centred.

    Parameters
    ----------
    carried, network : Correspondences
        Of the same ``N`` points.
    points_cam : (N, 3) float64
        The points (camera frame, metres).
    T_cam_npcs : sequence of Sim3
        ``(M,)`` part poses at which the network's inliers are judged.
    gate : float
        Metres.
    threshold : float or None
        Of :func:`~ancsh.geometry.normals.sliding_projector`, ``> 0`` (``None``: re-centre along every direction).
    """
    from ..geometry.normals import estimate_normals, sliding_projector

    if threshold is not None:
        threshold = check_number(threshold, "threshold", minimum=0.0, lower_open=True)
    pts = np.asarray(points_cam, dtype=np.float64)
    normals = None if threshold is None or pts.shape[0] < 3 else estimate_normals(pts)
    npcs = np.array(carried.npcs, dtype=np.float64, copy=True)
    w = np.ones(carried.num_points) if carried.weights is None else np.array(carried.weights, dtype=np.float64)
    keep = np.zeros(carried.num_points, dtype=bool)
    for j, T in enumerate(T_cam_npcs):
        sel = (carried.part_labels == j) & (network.part_labels == j) & (w > 0)
        sel[sel] = np.linalg.norm(T.apply(network.npcs[sel]) - pts[sel], axis=1) <= gate
        keep |= sel
        if np.count_nonzero(sel) >= 3:
            shift = network.npcs[sel].mean(axis=0) - carried.npcs[sel].mean(axis=0)
            if normals is not None:  # the sliding directions, camera frame -> this part's NPCS
                shift = T.rotation.T @ sliding_projector(normals[sel], threshold) @ T.rotation @ shift
            npcs[sel] += shift
    return dataclasses.replace(carried, npcs=npcs, weights=np.where(keep, w, 0.0))


def fused_canonical(network, previous, weight: float):
    """``network`` correspondences with canonical parameters averaged with ``previous``'s (weight ``weight``
    on them): NPCS -> NAOCS scales and translations, joint pivots, and joint axes (normalised) --
    the recursive fusion of tracking applied to the per-frame estimates of the canonical parameters
    (``TrackerConfig.fusion_weight``). ``network`` unchanged where the joint types differ."""
    if previous.num_parts != network.num_parts or tuple(previous.joint_types) != tuple(network.joint_types):
        return network
    a = 1.0 / (1.0 + weight)
    mix = lambda new, old: a * np.asarray(new, dtype=np.float64) + (1.0 - a) * np.asarray(old, dtype=np.float64)  # noqa: E731
    axes = mix(network.joint_axes_naocs, previous.joint_axes_naocs)
    norms = np.linalg.norm(axes, axis=1, keepdims=True)
    axes = np.where(norms > 1e-9, axes / np.maximum(norms, 1e-12), network.joint_axes_naocs)
    return dataclasses.replace(network, npcs_scale=mix(network.npcs_scale, previous.npcs_scale),
                               npcs_translation=mix(network.npcs_translation, previous.npcs_translation),
                               joint_pivots_naocs=mix(network.joint_pivots_naocs, previous.joint_pivots_naocs),
                               joint_axes_naocs=axes)


def predicted_fit(result: FitResult, correspondences, prediction: PreviousSolution) -> FitResult:
    """``result`` with its part poses moved to a predicted object pose and joint states (forward
    kinematics of the reduced program with ``correspondences``' canonical parameters), as a warm start."""
    from ..solvers.program import ProgramKey, get_program
    from ..solvers.terms import CanonicalParameters, KinematicStructure, ProgramInputs, ProgramStart

    prog = get_program(ProgramKey(KinematicStructure.from_correspondences(correspondences), "reduced", False, ()))
    canonical = CanonicalParameters.of(correspondences, correspondences.joint_limits)
    T = prediction.T_cam_naocs
    states = prediction.joint_states
    if correspondences.joint_limits is not None:
        states = np.clip(states, correspondences.joint_limits[:, 0], correspondences.joint_limits[:, 1])
    p = prog.pack(ProgramInputs(T.scale, canonical, ProgramStart(T_cam_naocs=T)))
    poses = prog.unpack(prog.initial_x(states), p).T_cam_npcs
    return dataclasses.replace(result, T_cam_npcs=tuple(poses))


def check_fit(result: FitResult, points_cam, correspondences, category: str | None, max_relative_residual: float) -> FitResult:
    """The fit, or a copy with the failed status of the first plausibility check it fails.

    The checks of ``ancsh predict`` (:func:`ancsh.learned.inference.predict.check_plausibility`: inliers,
    the category's size range, its residual limit), then a residual limit relative to the
    fitted object: a part (with at least 20 points) whose median distance between its points and
    their fitted NPCS exceeds ``max_relative_residual`` object diagonals is ``large_residual``.
    """

    from ..learned.inference.predict import check_plausibility, part_quality

    if not result.ok:
        return result
    quality = part_quality(result, points_cam, correspondences)
    checked = check_plausibility(result, correspondences.part_labels, category, quality)
    if not checked.ok:
        return checked
    L = float(np.median([T.scale / g for T, g in zip(result.T_cam_npcs, correspondences.npcs_scale)]))
    for j, q in enumerate(quality):
        if q["points"] >= 20 and q["residual_m"] > max_relative_residual * L:
            return dataclasses.replace(result, status=FitStatus.LARGE_RESIDUAL, message=(
                f"check residual: part {j}'s points lie {q['residual_m'] / L:.3g} object diagonals (median) from the fit, "
                f"above {max_relative_residual}"))
    return result


def fit_frame(provider, observation: Observation, config: TrackerConfig, category: str | None = None, rng=0):
    """An independent (cold) fit of one frame: the provider, RANSAC + the formulation, the checks.

    Returns ``(FitResult, Correspondences or None)``; fewer than ``config.min_points`` points give
    ``too_few_points`` without calling the provider. This is the per-frame baseline of tracking
    and the tracker's re-initialisation.
    """
    result, corr, _ = _cold_fit(provider, observation, config, category, rng)
    return result, corr


def _cold_fit(provider, observation: Observation, config: TrackerConfig, category: str | None, rng):
    """:func:`fit_frame` and whether its result rests on the refinement network's correspondences:
    ``(FitResult, Correspondences or None, refined)``."""
    if observation.num_points < config.min_points:
        return FitResult.failure(FitStatus.TOO_FEW_POINTS, f"{observation.num_points} points, at least {config.min_points} "
                                 "are needed for a fit", formulation=config.formulation, solver="none",
                                 num_points=observation.num_points), None, False
    corr = provider.correspond(observation)
    result = fit(observation, corr, config.formulation, config.solver, config.fit, rng=rng)
    checked = check_fit(result, observation.points_cam, corr, category, config.max_relative_residual)
    if config.refine_network and checked.ok:  # the refined fit where it passes the checks too
        from ..learned.inference.refine_network import refine_with_network

        ref = refine_with_network(provider.refiner, observation, result, formulation=config.formulation,
                                  config=config.fit, rng=rng)
        if ref.accepted:
            refined = check_fit(ref.result, observation.points_cam, ref.inference.correspondences, category,
                                config.max_relative_residual)
            if refined.ok:
                return refined, ref.inference.correspondences, True
    return checked, corr, False


@dataclass
class _Track:
    """What the tracker carries from frame to frame."""

    result: FitResult
    correspondences: object  # the Correspondences the result was fitted on
    template: object  # CarriedTemplate of the last network frame
    since_network: int
    prior: PreviousSolution
    before: PreviousSolution | None = None
    anchor: PreviousSolution | None = None  # the solution of the last network frame
    anchor_before: PreviousSolution | None = None  # and of the network frame before it (same track)
    anchor_gap: int = 1  # frames between the two
    refined: bool = False  # the last network frame's correspondences are the refinement network's


class CategoryTracker:
    """Tracks a category-level articulated object through a sequence of observations.

    Parameters
    ----------
    provider : CorrespondenceProvider
        Turns an observation into correspondences (e.g. :class:`~ancsh.learned.inference.provider.LearnedProvider`);
        called on network frames and re-initialisations only.
    config : TrackerConfig, optional
    category : str, optional
        A procedural category: its size range and residual limit join the plausibility checks.
    rng : int or numpy.random.Generator
        RANSAC randomness of the cold fits.

    Examples
    --------
    >>> tracker = CategoryTracker(LearnedProvider("laptop"), TrackerConfig(network_every=2), category="laptop")
    >>> for points in frames:                                  # doctest: +SKIP
    ...     tracked = tracker.step(Observation(points))
    ...     tracked.status, tracked.joint_states
    """

    def __init__(self, provider, config: TrackerConfig | None = None, *, category: str | None = None, rng=0):
        from ..geometry._checks import check_generator

        if not hasattr(provider, "correspond"):
            raise ValueError(f"provider: expected a correspondence provider (with .correspond), got {type(provider).__name__}")
        self.provider = provider
        self.config = TrackerConfig() if config is None else config
        if not isinstance(self.config, TrackerConfig):
            raise ValueError(f"config: expected a TrackerConfig, got {type(self.config).__name__}")
        if self.config.refine_network and getattr(provider, "refine_option", None) != "network":
            raise ValueError("config.refine_network: the provider has no refinement network (LearnedProvider(..., "
                             "refine='network'))")
        self.category = category
        self.rng = check_generator(rng)
        self._track: _Track | None = None
        self._index = 0
        self._started = False
        self._num_joints = int(getattr(provider, "num_joints", 0))
        self._template = None  # (InstanceTracker, CarriedTemplateFit) of a carried category template
        self._template_choice = None  # (template name, scale) of the last accepted refinement: kept across losses
        self._template_offset = None  # (K,) joint-state offset of the carried template (template_states)
        self._template_since = 0  # template frames since the network last ran

    def reset(self) -> None:
        """Forget the track (the next frame starts cold). The category template chosen at the last
        (re-)initialisation is remembered: the object is assumed the same when it comes back
        (``TrackerConfig.template_reuse``)."""
        self._track = None
        self._template = None

    def step(self, observation: Observation) -> TrackedFrame:
        """Track one more frame (see the module docstring)."""
        if not isinstance(observation, Observation):
            raise ValueError(f"observation: expected an Observation, got {type(observation).__name__}")
        t0 = time.perf_counter()
        index = self._index
        self._index += 1
        cfg = self.config
        if observation.num_points < cfg.min_points:
            self.reset()
            return self._lost(index, f"too_few_points: {observation.num_points} points, at least {cfg.min_points} are "
                                     "needed (object out of view or an empty frame)", t0)
        why = ""
        if self._template is not None:
            result, why = self._template_step(observation)
            if result is not None:
                return self._frame(index, TrackStatus.TRACKED, result.message, result, "template", t0, template=True)
        elif self._track is not None:
            result, corr, source = self._warm(observation)
            if result.ok:
                network = source == "network"
                self._advance(observation, result, corr, network, refined=cfg.refine_network if network else None)
                return self._frame(index, TrackStatus.TRACKED, result.message, result, source, t0,
                                   refined=self._track.refined)
            why = f"warm fit failed ({result.status.value}: {result.message}); "
        result, corr, by_refiner = _cold_fit(self.provider, observation, cfg, self.category, self.rng)
        if not result.ok:
            self._track = None
            return self._lost(index, f"{why}cold fit failed ({result.status.value}: {result.message})", t0)
        status = TrackStatus.REINITIALISED if self._started else TrackStatus.INITIALISED
        self._started = True
        self._track = None
        self._advance(observation, result, corr, True, refined=by_refiner)
        result, how, from_template = self._start_template(observation, result, corr)
        return self._frame(index, status, why + "cold fit (network + RANSAC)" + how, result, "network", t0,
                           template=from_template, refined=by_refiner and not from_template)

    def _start_template(self, observation, result: FitResult, corr):
        """Refine a cold fit against the category template and carry it (``template_categories``):
        ``(fit to report, message suffix, whether it is the template's)``."""
        cfg = self.config
        if self.category not in cfg.template_categories:
            return result, "", False
        from ..data.templates import load_template_library
        from ..solvers.icp.category import RefineConfig, refine_fit
        from ..solvers.icp.template import ArticulatedPose

        library = load_template_library(self.category)
        ref, reused = None, ""
        if cfg.template_reuse and self._template_choice is not None:
            # the object seen before the loss: its template at its scale only (one ICP run instead of the
            # nearest-template choice and the scale search); the full refinement where it is not accepted
            name, scale = self._template_choice
            index = next((i for i, e in enumerate(library.entries) if e.name == name), None)
            if index is not None:
                ref = refine_fit(observation, result, corr, library.model(index),
                                 config=RefineConfig(scales=(scale,), release_revolute=True), rng=self.rng)
                reused = ", the template of the track before the loss" if ref.accepted else ""
        if ref is None or not ref.accepted:
            ref = refine_fit(observation, result, corr, library, config=RefineConfig(release_revolute=True), rng=self.rng)
        if not ref.accepted:
            return result, f"; category template not carried ({ref.reason})", False
        self._template_choice = (ref.template, ref.scale)
        c = ref.carried
        self._template = (InstanceTracker(c.model, cfg.template_icp, rng=self.rng, initial=c.pose), c)
        if not reused or self._template_offset is None or len(self._template_offset) != len(c.pose.q):
            self._template_offset = np.zeros(len(c.pose.q))  # a new template: its joint-state offset starts again
        self._template_since = 0
        # an articulated refinement's covariance is the ICP's at c.pose (refine_fit); a base one has none
        pose = ArticulatedPose(c.pose.T_cam_base, c.pose.q + self._template_offset)  # the reused template's offset kept
        fitted = dataclasses.replace(c.fit_of(pose),
                                     uncertainty=ref.result.uncertainty if ref.choice == "articulated" else None)
        return fitted, (f"; carrying the category template {ref.template} (scale {ref.scale:g}, {ref.choice} "
                        f"refinement{reused})"), True

    def _template_step(self, observation):
        """A warm ICP frame of the carried category template: ``(FitResult or None, why it was lost)``."""
        from ..solvers.icp.template import ArticulatedPose

        tracker, carried = self._template
        tracked = tracker.step(observation)
        if not tracked.ok:
            self.reset()
            return None, f"category template lost ({tracked.message}); "
        r = tracked.result
        pose = ArticulatedPose(r.T_cam_base, r.q)
        cfg = self.config
        if cfg.template_states:
            self._template_since += 1
            if self._template_since >= cfg.network_every:
                self._template_since = 0
                self._update_template_offset(observation, carried.fit_of(pose))  # the template's own states
            pose = ArticulatedPose(r.T_cam_base, r.q + self._template_offset)
        fitted = carried.fit_of(pose, r.uncertainty)
        fitted = dataclasses.replace(fitted, iterations=int(r.iterations), message=r.message)
        self._num_joints = len(fitted.joint_states)
        return fitted, ""

    def _update_template_offset(self, observation, fitted: FitResult) -> None:
        """A network fit of a template frame (warm from the template's, ``TrackerConfig.template_states``): the
        recursive weighted mean (``fusion_weight`` on the past, the refinement's state the first) of its revolute
        joint states' differences from the template's."""
        from ..model.articulated import JointType

        cfg = self.config
        corr = self.provider.correspond(observation)
        quick = dataclasses.replace(cfg.fit, uncertainty=False,
                                    rescore_rounds=max(cfg.fit.rescore_rounds, cfg.warm_rescore_rounds))
        net = fit(observation, corr, cfg.formulation, cfg.solver, quick, rng=self.rng, warm_start=fitted)
        net = check_fit(net, observation.points_cam, corr, self.category, cfg.max_relative_residual)
        if not net.ok or len(net.joint_states) != len(self._template_offset):
            return
        revolute = np.array([t == JointType.REVOLUTE for t in corr.joint_types], dtype=bool)
        diff = np.where(revolute, np.asarray(net.joint_states) - np.asarray(fitted.joint_states), 0.0)
        w = cfg.fusion_weight
        self._template_offset = (w * self._template_offset + diff) / (1.0 + w)

    def _prediction(self) -> PreviousSolution:
        """The constant-velocity prediction of the next frame (see ``TrackerConfig.predict_from``)."""
        cfg, tr = self.config, self._track
        prior = PreviousSolution.constant_velocity(tr.prior, tr.before, damping=cfg.velocity)
        carried = tr.since_network + 1 < cfg.network_every
        if cfg.predict_from == "network" and carried and tr.anchor_before is not None:
            anchored = PreviousSolution.constant_velocity(tr.anchor, tr.anchor_before, damping=cfg.velocity,
                                                          ahead=(tr.since_network + 1) / tr.anchor_gap)
            prior = dataclasses.replace(prior, T_cam_naocs=anchored.T_cam_naocs)
        return prior

    def _warm(self, observation: Observation):
        """The warm fit of a frame: ``(result, correspondences, source)``."""
        cfg, tr = self.config, self._track
        network = tr.since_network + 1 >= cfg.network_every
        prior = self._prediction()
        use_prior = cfg.temporal_weight > 0 or cfg.temporal_state_weight > 0
        start = predicted_fit(tr.result, tr.correspondences, prior)
        kwargs = dict(warm_start=start, previous=prior if use_prior else None)
        warm = dataclasses.replace(cfg.fit, rescore_rounds=max(cfg.fit.rescore_rounds, cfg.warm_rescore_rounds))
        L = float(np.median([T.scale / g for T, g in zip(start.T_cam_npcs, tr.correspondences.npcs_scale)]))
        if network:
            if cfg.refine_network:  # the input in the predicted orientation of the root part (= of the NAOCS)
                corr = self.provider.refiner.correspond(observation, input_rotation=prior.T_cam_naocs.rotation.T)
            else:
                corr = self.provider.correspond(observation)
            if cfg.network_scale:
                warm = dataclasses.replace(warm, optimize_scale=True)
            if cfg.fusion_weight > 0:
                result = self._fused(observation, corr, start, warm, kwargs, L)
            else:
                result = fit(observation, corr, cfg.formulation, cfg.solver, warm, rng=self.rng, **kwargs)
            return check_fit(result, observation.points_cam, corr, self.category, cfg.max_relative_residual), corr, "network"
        result, corr = start, tr.correspondences
        iterations = 0
        quick = dataclasses.replace(warm, uncertainty=False)
        for i in range(cfg.carried_iterations):
            corr = tr.template.correspond(observation.points_cam, result.T_cam_npcs, cfg.carried_gate * L)
            if np.count_nonzero(corr.weights) < cfg.min_points:
                return FitResult.failure(FitStatus.TOO_FEW_INLIERS, f"{np.count_nonzero(corr.weights)} points lie within "
                                         f"{cfg.carried_gate} object diagonals of the tracked object", formulation=cfg.formulation,
                                         solver="none", num_points=observation.num_points), corr, "carried"
            last = i == cfg.carried_iterations - 1
            result = fit(observation, corr, cfg.formulation, cfg.solver,
                         warm if last and cfg.carried_uncertainty else quick, rng=self.rng,
                         **{**kwargs, "warm_start": result})
            iterations += result.iterations
            if not result.ok:
                break
        if result.ok:
            result = dataclasses.replace(result, iterations=iterations)
        return check_fit(result, observation.points_cam, corr, self.category, cfg.max_relative_residual), corr, "carried"

    def _fused(self, observation: Observation, corr, start: FitResult, warm: FitConfig, kwargs: dict, L: float) -> FitResult:
        """The fused warm fit of a network frame (``TrackerConfig.fusion_weight``): the network's
        correspondences and, with that weight, the carried ones of the same points (matched at the
        predicted poses ``start``), in one solve; the result's inliers are those of the network's rows."""
        from .carried import stack_correspondences

        cfg, n = self.config, observation.num_points
        corr = fused_canonical(corr, self._track.correspondences, cfg.fusion_weight)
        carried = self._track.template.correspond(observation.points_cam, start.T_cam_npcs, cfg.carried_gate * L)
        if cfg.fusion_recentre:
            carried = recentred(carried, corr, observation.points_cam, start.T_cam_npcs, cfg.fit.inlier_threshold * L,
                                cfg.recentre_threshold)
        both = Observation(np.concatenate([observation.points_cam, observation.points_cam]))
        result = fit(both, stack_correspondences(corr, carried, cfg.fusion_weight), cfg.formulation, cfg.solver, warm,
                     rng=self.rng, **kwargs)
        return dataclasses.replace(result, inliers=result.inliers[:n]) if result.inliers.shape[0] == 2 * n else result

    def _advance(self, observation, result: FitResult, corr, network: bool, refined: bool | None = None) -> None:
        """Carry an accepted fit to the next frame; ``refined``: whether a network frame's correspondences are the
        refinement network's (``None``: as the last network frame's)."""
        from .carried import CarriedTemplate

        cfg = self.config
        corr = fitted_canonical(corr, result)
        prior = previous_solution(result, corr, cfg.temporal_weight, cfg.temporal_state_weight)
        tr = self._track
        self._num_joints = len(result.joint_states)
        if network or tr is None:
            template, since = CarriedTemplate(observation.points_cam, corr, result), 0
            anchor, anchor_before, gap = prior, None if tr is None else tr.anchor, 1 if tr is None else tr.since_network + 1
        else:
            template, since = tr.template, tr.since_network + 1
            anchor, anchor_before, gap = tr.anchor, tr.anchor_before, tr.anchor_gap
        if refined is None:
            refined = bool(tr is not None and tr.refined)
        self._track = _Track(result, corr, template, since, prior, None if tr is None else tr.prior, anchor, anchor_before,
                             gap, bool(refined))

    def _frame(self, index, status, message, result, source, t0, template: bool = False,
               refined: bool = False) -> TrackedFrame:
        """``template``: the fit is the carried category template's (its covariance the template ICP's).
        ``refined``: it rests on the refinement network's correspondences (of this frame, or carried from the last
        network frame). A learned provider's covariances are inflated by the factors measured for these weights: of
        tracked frames of this source (``learned-tracked-<source>``) for a warm frame, of single-frame
        fits (``learned``, ``learned-template``) for a cold one or where none were measured; a refined fit's by those
        measured for the refinement network's single-frame fits (``learned-network``: no tracked frames were
        measured with it)."""
        if getattr(result, "uncertainty", None) is not None and self.category is not None and hasattr(self.provider, "network"):
            from ..learned.inference.predict import inflate_uncertainty  # as ancsh predict: the factors measured for these weights

            result = inflate_uncertainty(result, self.category, self.provider, template=template, network=refined,
                                         tracked=source if status == TrackStatus.TRACKED else None)
        return TrackedFrame(index, status, message, result, np.asarray(result.joint_states, dtype=np.float64).copy(), source,
                            int(result.iterations), time.perf_counter() - t0)

    def _lost(self, index, message, t0) -> TrackedFrame:
        return TrackedFrame(index, TrackStatus.LOST, message, None, np.full(self._num_joints, np.nan), "none", 0,
                            time.perf_counter() - t0)
