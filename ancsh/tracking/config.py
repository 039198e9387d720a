"""The settings of category-level tracking (:class:`TrackerConfig`), validated on construction."""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..geometry._checks import check_bool, check_choice, check_int, check_number
from ..solvers.fit import FORMULATIONS, FitConfig
from ..solvers.formulations import provider_fit_config
from .instance import InstanceTrackerConfig

__all__ = ["TrackerConfig", "with_provider_fit"]


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
    template_categories : tuple of str or None
        Categories whose tracks carry the category template refined at (re-)initialisation (see the
        module docstring; the provider's category is ``category`` of :class:`CategoryTracker`). Default
        ``None``: those whose spec sets ``track_template`` (:attr:`CategoryConvention.track_template`; of the
        built-in ones the laptop, measured on the benchmark's learned sequences, tracking / per-frame error,
        rotation, translation, joint state: laptop 0.09, 0.68, 0.39; drawer 16, 2.9, 1.8, the template ICP slid
        off the drawers; eyeglasses 1.10, 1.22, 1.29). ``()``: never.
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
    fit : FitConfig or None
        Settings of every fit (RANSAC settings apply to the cold ones). ``None`` (default): the provider's
        (:func:`with_provider_fit`: a learned provider's :meth:`~ancsh.learned.inference.provider.LearnedProvider.fit_config`,
        the default objective of its category's shipped network; else the ``"tracked"`` entry of
        :data:`ancsh.solvers.formulations.DEFAULT_OBJECTIVES`).
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
    template_categories: tuple | None = None
    template_icp: object = None
    template_reuse: bool = True
    template_states: bool = True
    refine_network: bool = False
    min_points: int = 100
    max_relative_residual: float = 0.1
    fit: FitConfig | None = None

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
        if self.fit is not None and not isinstance(self.fit, FitConfig):
            raise ValueError(f"fit: expected a FitConfig or None, got {type(self.fit).__name__}")
        if self.template_categories is not None:
            if isinstance(self.template_categories, str) or not all(isinstance(c, str) for c in self.template_categories):
                raise ValueError("template_categories: expected a tuple of category names or None, got "
                                 f"{self.template_categories!r}")
            object.__setattr__(self, "template_categories", tuple(self.template_categories))

        if self.template_icp is None:
            object.__setattr__(self, "template_icp", InstanceTrackerConfig(reinitialise=False))
        elif not isinstance(self.template_icp, InstanceTrackerConfig):
            raise ValueError(f"template_icp: expected an InstanceTrackerConfig, got {type(self.template_icp).__name__}")

    def carries_template(self, convention) -> bool:
        """Whether tracks of the category of ``convention`` (a
        :class:`~ancsh.data.category_types.CategoryConvention`, or ``None`` for a category without one) carry the
        category template: :attr:`template_categories`, or where it is ``None`` the spec's ``track_template``."""
        if convention is None:
            return False
        if self.template_categories is None:
            return bool(convention.track_template)
        return convention.name in self.template_categories


def with_provider_fit(config: TrackerConfig, provider) -> TrackerConfig:
    """``config`` with its :attr:`TrackerConfig.fit` resolved for ``provider`` where it is ``None``: the provider's
    ``fit_config()`` (a :class:`~ancsh.learned.inference.provider.LearnedProvider`: its category's default objective,
    :data:`ancsh.solvers.formulations.DEFAULT_OBJECTIVES` ``["learned"]``), else that table's ``["tracked"]`` entry."""
    return config if config.fit is not None else replace(config, fit=provider_fit_config(provider, fallback="tracked"))
