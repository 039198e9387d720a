"""Category-level tracking over a depth sequence: warm starts, fusion over time, carried correspondences.

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

This module is the loop (:class:`CategoryTracker`); its settings are :mod:`ancsh.tracking.config`, its filter
(predictions, fusion) :mod:`ancsh.tracking.fusion`, its cold fits and checks :mod:`ancsh.tracking.cold_fit`.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from ..solvers.fit import FitConfig, fit
from ..solvers.terms import PreviousSolution
from ..solvers.types import FitResult, FitStatus, Observation
from .cold_fit import check_fit, cold_fit, fit_frame, tracked_category
from .config import TrackerConfig, with_provider_fit
from .fusion import fitted_canonical, fused_canonical, predicted_fit, previous_solution, recentred
from .instance import InstanceTracker
from .records import TrackedFrame, TrackStatus, joint_state_std

__all__ = ["CategoryTracker", "TrackStatus", "TrackedFrame", "TrackerConfig", "check_fit", "fit_frame",
           "fitted_canonical", "joint_state_std", "predicted_fit", "previous_solution"]


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
    category : str, Path or Category, optional
        The object's category (a name, spec file, built folder or loaded
        :class:`~ancsh.learned.inference.category.Category`, loaded once): its size range and residual limit join the
        plausibility checks, its measured uncertainty factors apply, and its spec says whether tracks carry its
        template (``TrackerConfig.template_categories``).
    rng : int or numpy.random.Generator
        RANSAC randomness of the cold fits.

    Examples
    --------
    >>> tracker = CategoryTracker(LearnedProvider("laptop"), TrackerConfig(network_every=2), category="laptop")
    >>> for points in frames:                                  # doctest: +SKIP
    ...     tracked = tracker.step(Observation(points))
    ...     tracked.status, tracked.joint_states
    """

    def __init__(self, provider, config: TrackerConfig | None = None, *, category=None, rng=0):
        from ..geometry._checks import check_generator

        if not hasattr(provider, "correspond"):
            raise ValueError(f"provider: expected a correspondence provider (with .correspond), got {type(provider).__name__}")
        self.provider = provider
        self.config = TrackerConfig() if config is None else config
        if not isinstance(self.config, TrackerConfig):
            raise ValueError(f"config: expected a TrackerConfig, got {type(self.config).__name__}")
        self.config = with_provider_fit(self.config, provider)  # its fits' FitConfig: the provider's by default
        if self.config.refine_network and getattr(provider, "refine_option", None) != "network":
            raise ValueError("config.refine_network: the provider has no refinement network (LearnedProvider(..., "
                             "refine='network'))")
        #: The loaded :class:`~ancsh.learned.inference.category.Category` (``None`` without one) and its name.
        self.category_info = tracked_category(category, provider)
        self.category = None if self.category_info is None else self.category_info.name
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

    @property
    def correspondences(self):
        """The correspondences of the last accepted fit (the network's or carried ones; ``None`` before a fit, after a
        loss, or while a category template is carried)."""
        return None if self._track is None else self._track.correspondences

    def start_from(self, observation: Observation, result: FitResult, correspondences) -> None:
        """Carry ``result`` (a successful fit of ``observation`` on ``correspondences``, e.g. a verified detection of
        ``ancsh predict``, or a filtered state) to the next frame as if this tracker had made it on a network frame:
        the next frame starts warm from it. A carried category template is dropped."""
        if not isinstance(observation, Observation):
            raise ValueError(f"observation: expected an Observation, got {type(observation).__name__}")
        if not isinstance(result, FitResult) or not result.ok:
            raise ValueError("result: expected a successful FitResult")
        self._template = None
        self._track = None
        self._started = True
        self._advance(observation, result, correspondences, True, refined=False)

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
        result, corr, by_refiner = cold_fit(self.provider, observation, cfg, self.category_info, self.rng)
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
        info = self.category_info
        if info is None or not info.has_templates() or not cfg.carries_template(info.convention):
            return result, "", False
        from ..solvers.icp.category import RefineConfig, refine_fit
        from ..solvers.icp.template import ArticulatedPose

        library = info.template_library()
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
        net = check_fit(net, observation.points_cam, corr, self.category_info, cfg.max_relative_residual)
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
            return check_fit(result, observation.points_cam, corr, self.category_info, cfg.max_relative_residual), corr, "network"
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
        return check_fit(result, observation.points_cam, corr, self.category_info, cfg.max_relative_residual), corr, "carried"

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
        if getattr(result, "uncertainty", None) is not None and self.category_info is not None and hasattr(self.provider, "network"):
            from ..learned.inference.predict import inflate_uncertainty  # as ancsh predict: the factors measured for these weights

            result = inflate_uncertainty(result, self.category_info, self.provider, template=template, network=refined,
                                         tracked=source if status == TrackStatus.TRACKED else None)
        return TrackedFrame(index, status, message, result, np.asarray(result.joint_states, dtype=np.float64).copy(), source,
                            int(result.iterations), time.perf_counter() - t0)

    def _lost(self, index, message, t0) -> TrackedFrame:
        return TrackedFrame(index, TrackStatus.LOST, message, None, np.full(self._num_joints, np.nan), "none", 0,
                            time.perf_counter() - t0)
