"""Category-template refinement: articulated ICP of a learned fit against a stand-in CAD model.

After a category-level fit (e.g. the learned ANCSH fit, ``exact_reduced``), the object's exact
model is unknown, but a *category template* is at hand: the training instance whose part boxes
are nearest to the fitted ones (:class:`~ancsh.data.templates.TemplateLibrary`). It is reshaped
to the fit (:func:`fitted_template`): the whole template scaled uniformly to the fitted object box
(``box_scaling="object"``, default), or each part's mesh scaled per axis from its own box to the fitted
part box and placed where the fit puts that box at rest (``"parts"``); joints follow the child part.
Then, for a few global scales around the fitted size (the learned fit tends to overestimate it),
articulated ICP (:func:`~ancsh.solvers.icp.articulated.articulated_icp`, one local start from the
fit) refines the object pose and joint states.

Every candidate is scored with one :class:`~ancsh.solvers.icp.articulated.FitScorer` on the observed
points (never the ground truth), the input fit included -- the template posed part by part at the
fit's own part poses -- so all are compared on the same terms. Candidates per scale:

``articulated``
    the ICP result: object pose and joint states of the template;
``base``
    the ICP object pose and scale, with the input fit's own joint configuration (its parts moved
    rigidly with the base): for doors whose template hinge or door shape differ from the object's.

The best-scoring candidate replaces the input only when its score is below the input's by
``margin`` and no part's observed-point term got worse by more than ``part_tolerance``; otherwise
the input fit is returned unchanged (:attr:`TemplateRefinement.accepted` is ``False``).

An accepted ``articulated`` candidate carries the covariance of its ICP (Gauss-Newton at the ICP
solution, :func:`~ancsh.solvers.icp.articulated.icp_uncertainty`) mapped to the refined fit's NPCS
frames, the scale unknown (``nan``: chosen by the scale search); a ``base`` candidate carries none.
Its standard deviations describe the template's fit to the points, not the template's shape error
(the inflation measured by ``ancsh bench uncertainty --providers learned-template`` covers that).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field, replace

import numpy as np

from ...geometry._checks import check_bool, check_choice, check_generator, check_number
from ...geometry.boxes import OrientedBox, unit_diagonal
from ...geometry.rotations import axis_angle_matrix
from ...geometry.transforms import Sim3
from ...model.articulated import ArticulatedModel, Joint, JointType, Part
from ...model.edit import scaled_states
from ..types import Correspondences, FitResult, FitStatus, Observation
from .articulated import ArticulatedIcpConfig, FitScore, FitScorer, articulated_icp
from .template import ArticulatedPose, ModelSurface

__all__ = [
    "BOX_SCALINGS",
    "CarriedTemplateFit",
    "FittedTemplate",
    "RefineConfig",
    "TemplateRefinement",
    "fitted_layout",
    "fitted_template",
    "local_icp",
    "refine_fit",
    "template_fit_uncertainty",
]

BOX_SCALINGS = ("parts", "object")


def local_icp() -> ArticulatedIcpConfig:
    """Articulated ICP from one estimate (the fit's): one local start, no joint-range starts or restarts, no rescue, a
    short gate schedule (:func:`ancsh.solvers.twin.align_config` runs it longer)."""
    return ArticulatedIcpConfig(max_iterations=10, gate_start=0.04, gate_end=0.02, gate_decay=0.7, joint_starts=0,
                                joint_restarts=False, candidates=1, rescue_angle=0.0, start_iterations=3, num_points=400,
                                solver_iterations=5)


def _continuation_icp() -> ArticulatedIcpConfig:
    """A few iterations at the final gate, from the first scale's result."""
    return replace(local_icp(), max_iterations=4, gate_start=0.02, start_iterations=2)


@dataclass(frozen=True)
class RefineConfig:
    """Settings of :func:`refine_fit`.

    Attributes
    ----------
    scales : tuple of float
        Global scale factors applied to the reshaped template (1 = the fitted object size): ICP runs
        at the first from the fit (:attr:`icp`), then continues at each other one from that result
        (:attr:`continuation`); the best score wins.
    box_scaling : str
        ``"object"`` (default): the whole template scaled uniformly to the fitted object box (its own
        part proportions kept); ``"parts"``: every template part scaled per axis to its fitted box and
        placed at the fitted box centre. On learned fits of the shipped networks (10-12 frames each of
        oven and laptop), ``"object"`` gave lower rotation errors (median oven 6.1/5.1 vs 10.2/10.5 deg,
        laptop 2.4/1.3 vs 3.0/1.5) at a higher translation error (laptop 0.034 vs 0.026 object units):
        the network's part boxes are too poor to reshape the template by.
    max_ratio : float
        Per-axis part scale factors (``"parts"``) are kept within ``[1/max_ratio, max_ratio]`` of the
        object's scale factor, so a wrong fitted box cannot crush a part.
    candidates : tuple of str
        Which candidates each scale offers: ``"articulated"`` (ICP joints) and/or ``"base"``
        (ICP object pose with the input's joints); see the module docstring.
    margin : float
        A candidate must score at least this much below the input fit (score units, ``>= 0``).
    part_tolerance : float
        ... and no part's observed-point term may exceed the input's by more than this (``>= 0``;
        ``inf`` turns the check off).
    templates : int
        The nearest library entries tried (each with every scale).
    icp : ArticulatedIcpConfig
        Articulated ICP at the first scale (default: one local start from the fit, see :func:`local_icp`).
    continuation : ArticulatedIcpConfig
        Articulated ICP at the other scales, from the first scale's result (default: a few iterations).
    release_revolute : bool
        The template's revolute joints turn half a turn either side of rest (:func:`released`) instead of
        stopping at the template's own limits, which are one training instance's and not the observed
        object's (a procedural laptop's lid opens to 110-175 degrees). Default ``False`` (the committed
        single-frame evaluations); tracking's carried template sets it (``ancsh.tracking.tracker``).
    """

    scales: tuple = (1.0, 0.94, 0.88)
    box_scaling: str = "object"
    max_ratio: float = 1.5
    candidates: tuple = ("articulated", "base")
    margin: float = 0.0
    part_tolerance: float = 0.02
    templates: int = 1
    icp: ArticulatedIcpConfig = field(default_factory=local_icp)
    continuation: ArticulatedIcpConfig = field(default_factory=_continuation_icp)
    release_revolute: bool = False

    def __post_init__(self):
        scales = tuple(float(s) for s in self.scales)
        if not scales or not all(np.isfinite(s) and s > 0 for s in scales):
            raise ValueError(f"scales: expected positive finite factors, got {self.scales!r}")
        object.__setattr__(self, "scales", scales)
        check_choice(self.box_scaling, "box_scaling", BOX_SCALINGS)
        check_number(self.max_ratio, "max_ratio", minimum=1.0)
        cands = tuple(self.candidates)
        if not cands or any(c not in ("articulated", "base") for c in cands):
            raise ValueError(f"candidates: expected a non-empty subset of ('articulated', 'base'), got {self.candidates!r}")
        object.__setattr__(self, "candidates", cands)
        check_number(self.margin, "margin", minimum=0.0)
        if not (isinstance(self.part_tolerance, (int, float)) and self.part_tolerance >= 0):
            raise ValueError(f"part_tolerance: expected a number >= 0 (inf = off), got {self.part_tolerance!r}")
        if isinstance(self.templates, bool) or int(self.templates) != self.templates or self.templates < 1:
            raise ValueError(f"templates: expected a positive integer, got {self.templates!r}")
        check_bool(self.release_revolute, "release_revolute")
        for name in ("icp", "continuation"):
            if not isinstance(getattr(self, name), ArticulatedIcpConfig):
                raise ValueError(f"{name}: expected an ArticulatedIcpConfig, got {type(getattr(self, name)).__name__}")


# ---------------------------------------------------------------------------------------------
# the fit at rest
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FittedLayout:
    """A fit's parts at rest, in a metric frame ``B`` with NAOCS axes centred on the object box.

    Attributes
    ----------
    T_cam_B : Sim3
        Rigid ``B`` -> camera at the fit's object pose.
    T_B_npcs : tuple of Sim3
        ``(M,)`` each part's NPCS -> ``B`` at rest (the fit's part boxes are the NPCS boxes).
    npcs_extents : (M, 3) float64
        The fit's part box side lengths in NPCS.
    diagonal : float
        The fitted object box diagonal (metres).
    centres, sizes : (M, 3) float64
        Part box centres and side lengths in NAOCS units (``B`` / ``diagonal``).
    undo_cam : tuple of Sim3
        ``(M,)`` per part, the camera-frame motion taking it from the fitted joint states back to rest.
    """

    T_cam_B: Sim3
    T_B_npcs: tuple
    npcs_extents: np.ndarray
    diagonal: float
    centres: np.ndarray
    sizes: np.ndarray
    undo_cam: tuple = ()


def _joint_motion_cam(axis, pivot, state: float, revolute: bool) -> Sim3:
    """The camera-frame rigid motion of joint state ``state`` about the line ``(pivot, axis)``."""
    if revolute:
        R = axis_angle_matrix(axis, state)
        return Sim3(R, pivot - R @ pivot)
    return Sim3(np.eye(3), state * np.asarray(axis))


def fitted_layout(fit: FitResult, corr: Correspondences, *, box_extents: str = "fit") -> FittedLayout:
    """The parts of a successful articulated fit moved back to rest (see :class:`FittedLayout`).

    Parameters
    ----------
    fit : FitResult
        A successful fit with part poses, boxes, camera joints and joint states.
    corr : Correspondences
        The correspondences it was fitted to (joint tree and types).
    box_extents : str
        ``"fit"``: the part boxes as fitted; ``"unit_diagonal"``: their NPCS sides scaled to the unit diagonal every
        NPCS box has by definition (as :attr:`~ancsh.solvers.fit.FitConfig.box_extents` ``"unit_diagonal"`` does;
        the same for a fit made with it; ``docs/results/box_extents.md``: closer to the truth on the cabinets).

    Raises
    ------
    ValueError
        When ``fit`` failed, lacks boxes or joints, or does not match ``corr``'s structure.
    """
    if not isinstance(fit, FitResult):
        raise ValueError(f"fit: expected a FitResult, got {type(fit).__name__}")
    if not isinstance(corr, Correspondences):
        raise ValueError(f"corr: expected Correspondences, got {type(corr).__name__}")
    check_choice(box_extents, "box_extents", ("fit", "unit_diagonal"))
    if not fit.ok:
        raise ValueError(f"fit: only a successful fit can be refined, got status {fit.status.value!r}")
    M, K = corr.num_parts, corr.num_joints
    if len(fit.T_cam_npcs) != M or len(fit.boxes_cam) != M or fit.joint_states.shape != (K,):
        raise ValueError(f"fit: expected {M} part poses and boxes and {K} joint states (the correspondences' structure), "
                         f"got {len(fit.T_cam_npcs)}, {len(fit.boxes_cam)} and {fit.joint_states.shape}")
    if not (np.all(np.isfinite(fit.joint_axes_cam)) and np.all(np.isfinite(fit.joint_pivots_cam))
            and np.all(np.isfinite(fit.joint_states))):
        raise ValueError("fit: needs finite camera-frame joints and joint states (an articulated formulation)")
    root = corr.root_part
    undo = [None] * M
    undo[root] = Sim3()
    for k in corr.topological_joints:
        p, c = int(corr.joint_parents[k]), int(corr.joint_children[k])
        revolute = corr.joint_types[k] == JointType.REVOLUTE
        U = _joint_motion_cam(fit.joint_axes_cam[k], fit.joint_pivots_cam[k], float(fit.joint_states[k]), revolute)
        undo[c] = undo[p] @ U.inverse()
    rest = [undo[j] @ T for j, T in enumerate(fit.T_cam_npcs)]
    ext = np.array([b.extents / T.scale for b, T in zip(fit.boxes_cam, fit.T_cam_npcs)])
    if box_extents == "unit_diagonal":
        ext = unit_diagonal(ext)
    R = fit.T_cam_npcs[root].rotation
    corners = []
    for T, e in zip(rest, ext):
        c = np.array(np.meshgrid(*[(-0.5 * x, 0.5 * x) for x in e])).reshape(3, -1).T
        corners.append(T.apply(c) @ R)  # camera -> B axes
    allc = np.concatenate(corners)
    lo, hi = allc.min(axis=0), allc.max(axis=0)
    T_cam_B = Sim3(R, R @ (0.5 * (lo + hi)))
    T_B_cam = T_cam_B.inverse()
    T_B_npcs = tuple(T_B_cam @ T for T in rest)
    diag = float(np.linalg.norm(hi - lo))
    centres = np.array([T.translation for T in T_B_npcs]) / diag
    sizes = np.array([T.scale * e for T, e in zip(T_B_npcs, ext)]) / diag
    return FittedLayout(T_cam_B, T_B_npcs, ext, diag, centres, sizes, tuple(undo))


# ---------------------------------------------------------------------------------------------
# the reshaped template
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FittedTemplate:
    """A template reshaped to a fit: every part frame is ``B`` (metric) at rest.

    Attributes
    ----------
    model : ArticulatedModel
        The reshaped template (joint conventions, rest and limits of the category).
    source : str
        The template's name.
    """

    model: ArticulatedModel
    source: str


def fitted_template(template: ArticulatedModel, layout: FittedLayout, *, box_scaling: str = "object",
                    max_ratio: float = 1.5) -> FittedTemplate:
    """``template`` reshaped to a fitted layout (see the module docstring).

    Parameters
    ----------
    template : ArticulatedModel
        A category instance with the fit's part and joint structure (every part meshed).
    layout : FittedLayout
        :func:`fitted_layout` of the fit.
    box_scaling : str
        ``"parts"`` or ``"object"`` (see :class:`RefineConfig`).
    max_ratio : float
        Bound of the per-axis part factors relative to the object factor (``>= 1``).

    Raises
    ------
    ValueError
        When the template's part count differs from the layout's or a part has no mesh.
    """
    from ...model.canonical import canonical_space

    if not isinstance(template, ArticulatedModel):
        raise ValueError(f"template: expected an ArticulatedModel, got {type(template).__name__}")
    check_choice(box_scaling, "box_scaling", BOX_SCALINGS)
    check_number(max_ratio, "max_ratio", minimum=1.0)
    M = template.num_parts
    if M != len(layout.T_B_npcs):
        raise ValueError(f"template: {template.name!r} has {M} parts, the fit {len(layout.T_B_npcs)}")
    cs = canonical_space(template)  # raises for a part without mesh
    rest = template.forward_kinematics(template.rest_states)
    D = layout.diagonal
    t_sizes = cs.npcs_scale[:, None] * cs.npcs_extents
    maps = []  # per part: NAOCS (template) -> B (metres): v_B = offset + gain * v_naocs
    for j in range(M):
        if box_scaling == "object":
            maps.append((np.zeros(3), np.full(3, D)))
            continue
        gain = np.divide(layout.sizes[j], t_sizes[j], out=np.ones(3), where=t_sizes[j] > 1e-9)
        gain = D * np.clip(gain, 1.0 / max_ratio, max_ratio)
        maps.append((D * layout.centres[j] - gain * cs.npcs_translation[j], gain))
    parts = []
    for j, part in enumerate(template.parts):
        mesh = part.mesh.copy()
        v = cs.T_naocs_base.apply(rest[j].apply(np.asarray(mesh.vertices, dtype=np.float64)))
        mesh.vertices = maps[j][0] + maps[j][1] * v
        parts.append(Part(part.name, mesh))
    joints = []
    mpu = 1.0 / cs.T_naocs_base.scale  # template metres per NAOCS unit
    for k, jt in enumerate(template.joints):
        _, c = template.joint_parts(k)
        off, gain = maps[c]
        a = gain * cs.joint_axes_naocs[k]
        along = float(np.linalg.norm(a))
        axis = a / along
        pivot = off + gain * cs.joint_pivots_naocs[k]
        f = 1.0 if jt.is_revolute else along / mpu
        lo, hi, r = f * jt.lower, f * jt.upper, f * jt.rest
        probe = Joint(jt.name, jt.type, jt.parent, jt.child, axis, pivot, lo, hi, r)
        joints.append(Joint(jt.name, jt.type, jt.parent, jt.child, axis, pivot, lo, hi, r, origin=probe.motion(r).inverse()))
    model = ArticulatedModel(tuple(parts), tuple(joints), name=f"{template.name}@fit", category=template.category)
    return FittedTemplate(model, template.name)


# ---------------------------------------------------------------------------------------------
# refinement
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TemplateRefinement:
    """The outcome of :func:`refine_fit`.

    Attributes
    ----------
    result : FitResult
        The refined fit when :attr:`accepted`, else the input fit unchanged.
    accepted : bool
    choice : str
        ``"input"``, ``"articulated"`` or ``"base"`` (see the module docstring).
    reason : str
        Why (scores, or the failure that kept the input).
    template : str
        The template instance used (empty when none was tried).
    scale : float
        Global scale factor of the chosen candidate (1 for the input).
    score_input, score_refined : float
        The input's and the best candidate's :attr:`FitScore.score` (NaN when not scored).
    time_s : float
        Wall time of the refinement alone (seconds).
    carried : CarriedTemplateFit or None
        When :attr:`accepted`: the template (reshaped to the fit and scaled) and its articulated ICP
        estimate at the chosen scale, for tracking the object on with it (:meth:`CarriedTemplateFit.fit_of`).
    """

    result: FitResult
    accepted: bool
    choice: str
    reason: str
    template: str = ""
    scale: float = 1.0
    score_input: float = float("nan")
    score_refined: float = float("nan")
    time_s: float = 0.0
    carried: "CarriedTemplateFit | None" = None


@dataclass(frozen=True)
class CarriedTemplateFit:
    """A category template fitted to one frame, to be tracked on (instance-level warm ICP).

    Attributes
    ----------
    model : ArticulatedModel
        The template reshaped to the fitted object box and scaled by ``scale`` (metres).
    pose : ArticulatedPose
        Its articulated ICP estimate on the refined frame (camera frame, absolute joint states).
    layout : FittedLayout
        The input fit's layout (the NPCS frames of the parts relative to the template's base).
    scale : float
        The global scale factor of the template (1 = the fitted object size).
    fit : FitResult
        The input fit (its structure, boxes' NPCS extents and message are reused).
    """

    model: ArticulatedModel
    pose: ArticulatedPose
    layout: "FittedLayout"
    scale: float
    fit: FitResult

    def fit_of(self, pose: ArticulatedPose, uncertainty=None) -> FitResult:
        """The category-level fit (NPCS part poses, joints, boxes) of the template at ``pose``.

        Parameters
        ----------
        pose : ArticulatedPose
            The template's estimate (camera frame, absolute joint states).
        uncertainty : FitUncertainty, optional
            Its articulated ICP covariance (template part frames,
            :func:`~ancsh.solvers.icp.articulated.icp_uncertainty` at ``pose``): mapped to the fit's NPCS
            and NAOCS frames (:func:`template_fit_uncertainty`). ``None``: the fit has none (the input
            fit's covariances were of other poses).
        """
        fitted = _articulated(self.fit, self.model, self.layout, self.scale, pose)
        return dataclasses.replace(fitted, uncertainty=template_fit_uncertainty(uncertainty, self.model, pose, self.layout,
                                                                                self.scale))


@dataclass(frozen=True)
class _Candidate:
    """A refined fit, its score, and the score of the input fit against the same template."""

    choice: str
    scale: float
    result: FitResult
    score: FitScore
    baseline: FitScore
    template: str
    model: ArticulatedModel | None = None  # the scaled template and its ICP estimate
    pose: ArticulatedPose | None = None
    icp_uncertainty: object = None  # FitUncertainty of the ICP estimate (template part frames), articulated only


def _scaled(model: ArticulatedModel, factor: float) -> ArticulatedModel:
    from ...model.edit import scaled

    return model if factor == 1.0 else scaled(model, factor)


def _moved(fit: FitResult, G: Sim3, f: float, corr: Correspondences) -> FitResult:
    """``fit`` moved by the similarity ``G`` (poses, boxes, joints), prismatic states scaled by ``f``."""
    poses = tuple(G @ T for T in fit.T_cam_npcs)
    boxes = tuple(OrientedBox(T.translation, T.rotation, b.extents * (T.scale / T0.scale))
                  for T, T0, b in zip(poses, fit.T_cam_npcs, fit.boxes_cam))
    prism = np.array([t == JointType.PRISMATIC for t in corr.joint_types], dtype=bool)
    states = np.where(prism, f * fit.joint_states, fit.joint_states)
    axes = G.apply_direction(fit.joint_axes_cam)
    return dataclasses.replace(fit, T_cam_npcs=poses, boxes_cam=boxes, joint_axes_cam=axes,
                               joint_pivots_cam=G.apply(fit.joint_pivots_cam), joint_states=states)


def _articulated(fit: FitResult, model: ArticulatedModel, layout: FittedLayout, f: float, est: ArticulatedPose) -> FitResult:
    """The fit re-expressed by the template's ICP estimate ``est`` (model scaled by ``f``)."""
    S = Sim3(np.eye(3), np.zeros(3), f)
    parts = est.part_poses(model)
    poses = tuple(P @ S @ layout.T_B_npcs[j] for j, P in enumerate(parts))
    boxes = tuple(OrientedBox(T.translation, T.rotation, T.scale * e) for T, e in zip(poses, layout.npcs_extents))
    K = model.num_joints
    axes, pivots = np.empty((K, 3)), np.empty((K, 3))
    for k in range(K):
        a, p = model.joint_line_in_base(k, est.q)
        axes[k], pivots[k] = est.T_cam_base.apply_direction(a), est.T_cam_base.apply(p)
    states = est.q - model.rest_states
    return dataclasses.replace(fit, T_cam_npcs=poses, boxes_cam=boxes, joint_axes_cam=axes, joint_pivots_cam=pivots,
                               joint_states=states, canonical=None)


def template_fit_uncertainty(uncertainty, model: ArticulatedModel, pose: ArticulatedPose, layout: "FittedLayout",
                             scale: float):
    """An articulated ICP covariance of a category template mapped to the category-level fit it gives.

    The ICP's covariance (object pose and joint states of the template, its scale fixed;
    :func:`~ancsh.solvers.icp.articulated.icp_uncertainty`) describes the template's part and base
    frames; the fit (:meth:`CarriedTemplateFit.fit_of`) reports NPCS and NAOCS frames, constant maps
    away (the maps of :func:`_articulated`). The part and object scales were chosen by the scale
    search, not fitted: their variances are ``nan`` (unknown).

    Parameters
    ----------
    uncertainty : FitUncertainty or None
        The ICP's covariance at ``pose`` (``None`` gives ``None``).
    model : ArticulatedModel
        The scaled template the ICP fitted (metres).
    pose : ArticulatedPose
        Its estimate (camera frame).
    layout : FittedLayout
        The NPCS frames of the fit's parts relative to the template's base.
    scale : float
        The template's global scale factor.
    """
    if uncertainty is None:
        return None
    S = Sim3(np.eye(3), np.zeros(3), scale)
    u = uncertainty.composed(pose.part_poses(model), [S @ T for T in layout.T_B_npcs], pose.T_cam_base,
                             S @ Sim3(np.eye(3), np.zeros(3), layout.diagonal))

    def unknown_scale(v):
        if v is None:
            return None
        P, O = v.part_covariances.copy(), v.object_covariance.copy()
        P[:, 6, :] = P[:, :, 6] = np.nan
        O[6, :] = O[:, 6] = np.nan
        return replace(v, part_covariances=P, object_covariance=O, correlated=unknown_scale(v.correlated),
                       base=unknown_scale(v.base))

    return unknown_scale(u)


def _refined_uncertainty(best: _Candidate, layout: FittedLayout):
    """The covariance of an ``articulated`` candidate (:func:`template_fit_uncertainty` of its ICP's);
    ``None`` for a ``base`` candidate (its joints are the input fit's, its object pose the ICP's: no
    single program holds both) and where the ICP computed none."""
    if best.choice != "articulated":
        return None
    return template_fit_uncertainty(best.icp_uncertainty, best.model, best.pose, layout, best.scale)


def _score(scorer: FitScorer, surface: ModelSurface, result: FitResult, layout: FittedLayout, f: float, gate: float) -> FitScore:
    """The template (scaled by ``f``) posed part by part at ``result``'s part poses, scored."""
    S_inv = Sim3(np.eye(3), np.zeros(3), 1.0 / f)
    parts = [T @ layout.T_B_npcs[j].inverse() @ S_inv for j, T in enumerate(result.T_cam_npcs)]
    parts = [Sim3(P.rotation, P.translation) for P in parts]  # rigid up to rounding
    return scorer.score(surface, parts, gate)


def released(model: ArticulatedModel) -> ArticulatedModel:
    """``model`` with each revolute joint's limits widened to half a turn either side of its rest state (its own
    limits kept where wider); prismatic joints unchanged (:attr:`RefineConfig.release_revolute`)."""
    from ...model.edit import with_limits

    revolute = np.array([j.is_revolute for j in model.joints], dtype=bool)
    if not revolute.any():
        return model
    rest = model.rest_states
    lo = np.where(revolute, np.minimum(model.lower_limits, rest - np.pi), model.lower_limits)
    hi = np.where(revolute, np.maximum(model.upper_limits, rest + np.pi), model.upper_limits)
    return with_limits(model, lo, hi)


def refine_fit(observation: Observation, fit: FitResult, corr: Correspondences, templates, *,
               config: RefineConfig | None = None, rng=0) -> TemplateRefinement:
    """Refine a category-level fit by articulated ICP against a category template.

    Parameters
    ----------
    observation : Observation
        The observed points the fit was made from (camera frame, metres).
    fit : FitResult
        A fit of ``corr`` with an articulated formulation (``exact_reduced`` in the learned pipeline).
    corr : Correspondences
        Its correspondences (joint tree and types).
    templates : TemplateLibrary or ArticulatedModel
        The category's template library (the nearest entries by part boxes are tried), or one template.
    config : RefineConfig, optional
    rng : numpy.random.Generator or int
        Seeds ICP's point subsample and the scorer's surface samples.

    Returns
    -------
    TemplateRefinement
        The refined fit if a candidate scored better than the input on the observed points, else the
        input (a failed input fit, or an ICP that lost the points, is returned unchanged with the reason).

    Raises
    ------
    ValueError
        For bad arguments: wrong types, a fit whose structure does not match ``corr``, a template of
        another part count.
    """
    from ...data.templates import TemplateLibrary

    t0 = time.perf_counter()
    config = RefineConfig() if config is None else config
    if not isinstance(config, RefineConfig):
        raise ValueError(f"config: expected a RefineConfig, got {type(config).__name__}")
    if not isinstance(observation, Observation):
        raise ValueError(f"observation: expected an Observation, got {type(observation).__name__}")
    if not isinstance(templates, (TemplateLibrary, ArticulatedModel)):
        raise ValueError(f"templates: expected a TemplateLibrary or an ArticulatedModel, got {type(templates).__name__}")
    if isinstance(fit, FitResult) and not fit.ok:
        return TemplateRefinement(fit, False, "input", f"input fit failed ({fit.status.value}); nothing to refine",
                                  time_s=time.perf_counter() - t0)
    layout = fitted_layout(fit, corr)
    if isinstance(templates, TemplateLibrary):
        if templates.num_parts != corr.num_parts:
            raise ValueError(f"templates: the {templates.category} library has {templates.num_parts} parts, "
                             f"the fit {corr.num_parts}")
        chosen = [templates.model(i) for i in templates.nearest(layout.centres, layout.sizes, count=config.templates)]
        if not chosen:
            return TemplateRefinement(fit, False, "input", f"no {templates.category} template is available here (real "
                                      "templates need the shared data folder)", time_s=time.perf_counter() - t0)
    else:
        chosen = [templates]
    rng = check_generator(rng)
    if observation.num_points < 6 or np.any(observation.points_cam[:, 2] <= 0):
        return TemplateRefinement(fit, False, "input", "too few points in front of the camera to refine",
                                  time_s=time.perf_counter() - t0)
    scorer = FitScorer(observation.points_cam, rng)
    gate = max(config.icp.gate_end * layout.diagonal, config.icp.gate_floor)
    cands: list[_Candidate] = []
    name, s_first = "", None
    for template in chosen:
        if config.release_revolute:
            template = released(template)
        ft = fitted_template(template, layout, box_scaling=config.box_scaling, max_ratio=config.max_ratio)
        model = ft.model
        surface1 = ModelSurface(model)
        s_in = _score(scorer, surface1, fit, layout, 1.0, gate)
        if s_first is None:
            name, s_first = ft.source, s_in
        q0 = np.clip(model.rest_states + fit.joint_states, model.lower_limits, model.upper_limits)
        start, start_f = ArticulatedPose(layout.T_cam_B, q0), 1.0
        for i, f in enumerate(config.scales):
            m_f = _scaled(model, f)
            surface = surface1 if f == 1.0 else ModelSurface(m_f)
            # The first scale runs the whole ICP from the fit; the others continue from its result.
            g = f / start_f
            T = start.T_cam_base
            init = ArticulatedPose(Sim3(T.rotation, T.translation), scaled_states(model, start.q, g))
            icp = articulated_icp(m_f, observation, init, config=config.icp if i == 0 else config.continuation, rng=rng,
                                  surface=surface)
            if icp.status not in (FitStatus.SUCCESS, FitStatus.MAX_ITER):
                continue
            est = ArticulatedPose(icp.T_cam_base, icp.q)
            if i == 0:
                start, start_f = est, f
            if "articulated" in config.candidates:
                r = _articulated(fit, m_f, layout, f, est)
                cands.append(_Candidate("articulated", f, r, _score(scorer, surface, r, layout, f, gate), s_in, ft.source,
                                        m_f, est, icp.uncertainty))
            if "base" in config.candidates:
                G = est.T_cam_base @ Sim3(np.eye(3), np.zeros(3), f) @ layout.T_cam_B.inverse()
                r = _moved(fit, G, f, corr)
                cands.append(_Candidate("base", f, r, _score(scorer, surface, r, layout, f, gate), s_in, ft.source, m_f, est))
    if not cands:
        return TemplateRefinement(fit, False, "input", "articulated ICP lost the points at every scale", name,
                                  score_input=s_first.score, time_s=time.perf_counter() - t0)
    best = min(cands, key=lambda c: (c.score.score - c.baseline.score, c.score.score))
    s_in = best.baseline
    worse = np.nan_to_num(best.score.part_observed - s_in.part_observed, nan=0.0)
    dt = time.perf_counter() - t0
    common = dict(template=best.template, score_input=s_in.score, score_refined=best.score.score, time_s=dt)
    if not best.score.score < s_in.score - config.margin:
        return TemplateRefinement(fit, False, "input", f"no candidate scores below the input ({best.score.score:.4f} vs "
                                  f"{s_in.score:.4f})", **common)
    if np.any(worse > config.part_tolerance):
        j = int(np.argmax(worse))
        return TemplateRefinement(fit, False, "input", f"the best candidate ({best.choice}, scale {best.scale:g}) fits "
                                  f"part {j} worse by {worse[j]:.4f} (tolerance {config.part_tolerance:g})", **common)
    result = dataclasses.replace(best.result, message=(fit.message + "; " if fit.message else "")
                                 + f"refined by the category template {best.template} ({best.choice}, scale {best.scale:g})",
                                 time_s=fit.time_s + dt, uncertainty=_refined_uncertainty(best, layout))
    carried = CarriedTemplateFit(best.model, best.pose, layout, best.scale, fit)
    return TemplateRefinement(result, True, best.choice, f"score {best.score.score:.4f} < input {s_in.score:.4f}",
                              scale=best.scale, carried=carried, **common)
