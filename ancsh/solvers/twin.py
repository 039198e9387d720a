"""A fit as a simulation-ready articulated model (its "digital twin") and its URDF export.

The model is the category template nearest to the fit (:func:`ancsh.data.templates.load_template_library`:
procedural and imported real training instances), reshaped to the fitted part boxes
(:func:`ancsh.solvers.icp.category.fitted_template`): its meshes, joint conventions and limits, at the fitted
object pose and joint states. Render-and-compare (:mod:`ancsh.solvers.render_compare`) renders the same model.
Given the depth the fit was made from (:class:`ObservedDepth`), :func:`fitted_model` may instead render several of
the nearest templates and keep the one that explains that depth best (the lowest median |residual| on the object's
pixels; ``docs/results/twin.md``), and align the best of them to that depth by articulated ICP (:func:`align_model`:
the template is not the instance, so the pose and states that fit the instance's correspondences are not the ones
that put the template's surface on the observed one).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..geometry.transforms import Sim3
from .types import Correspondences, FitResult

__all__ = ["ALIGN_POINTS", "ALIGN_SCALES", "EXPORT_BOX_EXTENTS", "FIT_CAD_INIT", "FittedModel", "ObservedDepth",
           "align_config", "align_model", "compare_fit", "depth_residual", "export_fit_urdf", "fitted_model",
           "render_fit", "write_fit_cad_init"]

#: :func:`align_model` uses at most this many of the object's observed pixels (a seeded random subsample).
ALIGN_POINTS = 1500
#: :func:`align_model` also tries the model scaled by these factors (about its base frame's origin) and keeps the one
#: that explains the depth best (``docs/results/twin.md``: the learned boxes are a few per cent off in size).
ALIGN_SCALES = (1.0, 0.96, 1.04)
#: The file beside an exported URDF that starts ``ancsh fit-cad --init`` at the twin (:func:`write_fit_cad_init`).
FIT_CAD_INIT = "init.json"
#: The part boxes an exported model is shaped from (:func:`~ancsh.solvers.icp.category.fitted_layout`'s
#: ``box_extents``): the NPCS sides scaled to the unit diagonal (the learned cabinets' "max" boxes overshoot).
EXPORT_BOX_EXTENTS = "unit_diagonal"


@dataclass(frozen=True)
class ObservedDepth:
    """The depth image a fit was made from, to choose its model by render-and-compare.

    Attributes
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
        The camera (``width`` x ``height`` = ``W`` x ``H``).
    object_mask : (H, W) bool
        The object's pixels (a user's mask or the isolated segment).
    """

    depth: np.ndarray
    intrinsics: object
    object_mask: np.ndarray

    def __post_init__(self):
        d = np.asarray(self.depth, dtype=np.float64)
        m = np.asarray(self.object_mask, dtype=bool)
        if d.ndim != 2:
            raise ValueError(f"depth: expected an (H, W) image, got shape {d.shape}")
        if m.shape != d.shape:
            raise ValueError(f"object_mask: expected the depth's shape {d.shape}, got {m.shape}")
        if (self.intrinsics.height, self.intrinsics.width) != d.shape:
            raise ValueError(f"intrinsics: {self.intrinsics.width}x{self.intrinsics.height}, but the depth is "
                             f"{d.shape[1]}x{d.shape[0]}")
        if not m.any():
            raise ValueError("object_mask: no object pixel")
        object.__setattr__(self, "depth", d)
        object.__setattr__(self, "object_mask", m)


@dataclass(frozen=True)
class FittedModel:
    """A fit's articulated model.

    Attributes
    ----------
    model : ArticulatedModel
        The reshaped template (metres; its base frame ``B``: NAOCS axes, centred on the object box at rest).
    T_cam_B : Sim3
        Rigid pose of the base frame in the camera.
    states : (K,) float64
        The fitted joint states in the model's parameterisation (the category's: 0 = closed), radians / metres.
    template : str
        The template's name.
    median_residual_m : float or None
        Where the model was chosen by render-and-compare: its median |observed - model depth| on the object's
        pixels (metres); else ``None``.
    aligned : bool
        ``T_cam_B`` and ``states`` are the fit's moved by :func:`align_model` onto the observed depth (``False``: the
        fit's own).
    """

    model: object
    T_cam_B: Sim3
    states: np.ndarray
    template: str
    median_residual_m: float | None = None
    aligned: bool = False


def fitted_model(fit: FitResult, corr: Correspondences, templates, *, joints: str = "fitted",
                 observed: ObservedDepth | None = None, candidates: int = 1, align: int = 0, box_extents: str = "fit",
                 rng=0) -> FittedModel | None:
    """The model of a successful articulated fit, or ``None`` when no template is available here.

    ``joints``: ``"fitted"`` (the default) gives every joint the fit's axis and pivot, so that the model at the
    fitted states has the fit's part poses; ``"template"`` keeps the reshaped template's own joint lines (what
    render-and-compare and the ``p_object`` calibrations measured: the template's hinge on the fitted parts).

    ``observed`` and ``candidates > 1``: the ``candidates`` templates nearest to the fitted part boxes are each
    reshaped, posed and rendered from the observed camera, and the one with the lowest median
    ``|observed - model|`` depth on the object's pixels is kept (its residual in
    :attr:`FittedModel.median_residual_m`); without ``observed``, the nearest one.

    ``align`` > 0 (needs ``observed``): the ``align`` candidates with the lowest residuals are each moved onto the
    observed depth by :func:`align_model`; where one of them explains it better, the remaining candidates are ranked
    again at that aligned pose and states, and the ``align`` best of those aligned too; the model with the lowest
    residual of all, aligned or not, is kept (``docs/results/twin.md``: with 3 of 20, the learned fits' median
    residual 2-4x lower).
    ``box_extents``: the part boxes the template is shaped from (:func:`~ancsh.solvers.icp.category.fitted_layout`;
    an export uses :data:`EXPORT_BOX_EXTENTS`). ``rng`` seeds the alignment's point subsample.

    Raises
    ------
    ValueError
        A failed fit, or one without the boxes, joints or states an articulated fit has (naming it); a
        ``candidates`` that is not a positive integer; an ``align`` that is negative, or positive without
        ``observed``.
    """
    from .icp.category import fitted_layout, fitted_template

    if joints not in ("fitted", "template"):
        raise ValueError(f"joints: expected 'fitted' or 'template', got {joints!r}")
    if isinstance(candidates, bool) or not isinstance(candidates, (int, np.integer)) or candidates < 1:
        raise ValueError(f"candidates: expected a positive integer, got {candidates!r}")
    if observed is not None and not isinstance(observed, ObservedDepth):
        raise ValueError(f"observed: expected an ObservedDepth, got {type(observed).__name__}")
    if isinstance(align, bool) or not isinstance(align, (int, np.integer)) or align < 0:
        raise ValueError(f"align: expected a non-negative integer, got {align!r}")
    if align and observed is None:
        raise ValueError("align: aligning the model needs the observed depth (observed=)")
    layout = fitted_layout(fit, corr, box_extents=box_extents)
    nearest = templates.nearest(layout.centres, layout.sizes, count=int(candidates) if observed is not None else 1)
    if not nearest:
        return None
    states = np.asarray(fit.joint_states, dtype=np.float64)

    def build(index: int) -> FittedModel:
        ft = fitted_template(templates.model(index), layout)
        model = _with_fitted_joints(ft.model, fit, corr, layout) if joints == "fitted" else ft.model
        return FittedModel(model, layout.T_cam_B, model.rest_states + states, ft.source)

    if observed is None:
        return build(nearest[0])
    ranked = []
    for index in nearest:
        twin = build(index)
        ranked.append(replace(twin, median_residual_m=depth_residual(twin, observed)))  # inf: nothing in view
    ranked.sort(key=lambda t: t.median_residual_m)  # stable: the nearer template wins a tie
    best = ranked[0]
    if not align:
        return best
    best = _aligned_best(ranked[:int(align)], best, observed, rng)
    if best.aligned and len(ranked) > align:
        # The aligned pose is nearer the object than the fit's: the other templates, ranked again there (the same
        # states relative to rest; all share the frame B and the fitted joint lines), compete for the same alignment.
        opening = np.asarray(best.states) - best.model.rest_states
        moved = [replace(t, T_cam_B=best.T_cam_B, states=t.model.rest_states + opening) for t in ranked[int(align):]]
        again = sorted((replace(t, median_residual_m=depth_residual(t, observed)) for t in moved),
                       key=lambda t: t.median_residual_m)  # align_model starts from these residuals
        best = _aligned_best(again[:int(align)], best, observed, rng)
    return best


def _aligned_best(twins, best: FittedModel, observed: ObservedDepth, rng) -> FittedModel:
    """``best`` or whichever of ``twins``, each aligned (:func:`align_model`), explains ``observed`` better."""
    for twin in twins:
        aligned = align_model(twin, observed, rng=rng)
        if aligned.median_residual_m < best.median_residual_m:
            best = aligned
    return best


def align_config():
    """The articulated ICP of :func:`align_model`: one local start from the model's pose and states, 15 iterations
    with the correspondence gate shrinking from 4 % to 2 % of the model's diagonal, no restarts
    (:class:`~ancsh.solvers.icp.ArticulatedIcpConfig`)."""
    from .icp.category import local_icp

    return replace(local_icp(), max_iterations=15, num_points=ALIGN_POINTS, uncertainty=False)


def align_model(twin: FittedModel, observed: ObservedDepth, *, config=None, scales=ALIGN_SCALES,
                rng=0) -> FittedModel:
    """Move a fitted model onto the depth it should explain: articulated ICP of ``twin.model`` (object pose and joint
    states; the joint lines stay the model's) against the object's observed points, from ``twin``'s pose and
    states; the same for the model scaled by each further factor of ``scales`` (about the origin of its base frame;
    prismatic states scale with it), each continuing briefly from the first size's aligned pose and states; the one
    whose render explains the depth best is kept.

    The category template is not the observed instance: the pose and states that fit the instance's
    correspondences leave the template's surface off the observed one by its shape difference (and by the fit's own
    error), which this takes up.

    Parameters
    ----------
    twin : FittedModel
    observed : ObservedDepth
        The depth and the object's pixels (back-projected; at most :data:`ALIGN_POINTS` of them, drawn with ``rng``).
    config : ArticulatedIcpConfig, optional
        Default :func:`align_config`.
    scales : sequence of float
        Positive scale factors of the model (1 = as given; default :data:`ALIGN_SCALES`).
    rng : numpy.random.Generator or int

    Returns
    -------
    FittedModel
        The aligned model (:attr:`FittedModel.aligned`; a scaled copy of the model where a factor other than 1
        won) with its :attr:`~FittedModel.median_residual_m`, when its render explains the depth better than
        ``twin``'s; else ``twin`` with its residual (an ICP that lost the points changes nothing).
    """
    from ..data.render import backproject
    from ..model.edit import with_limits
    from .icp import ArticulatedPose, articulated_icp
    from .types import FitStatus

    if not isinstance(twin, FittedModel):
        raise ValueError(f"twin: expected a FittedModel, got {type(twin).__name__}")
    if not isinstance(observed, ObservedDepth):
        raise ValueError(f"observed: expected an ObservedDepth, got {type(observed).__name__}")
    scales = tuple(float(f) for f in np.atleast_1d(np.asarray(scales, dtype=np.float64)))
    if not scales or not all(np.isfinite(f) and f > 0 for f in scales):
        raise ValueError(f"scales: expected positive finite factors, got {scales!r}")
    config = align_config() if config is None else config
    if twin.median_residual_m is None:
        twin = replace(twin, median_residual_m=depth_residual(twin, observed))
    points = backproject(observed.depth, observed.intrinsics, observed.object_mask)
    if len(points) < 6:
        return twin
    # The first size is aligned from twin's pose and states; the others continue from where that landed (where it
    # explained the depth better) for a few iterations at the final gate: as good as aligning each from the start
    # (seed-1 cabinet frames of docs/results/twin_seed1.md, within 1 mm per frame) for 70 % of the CPU.
    short = replace(config, max_iterations=5, gate_start=config.gate_end, start_iterations=2)
    best, start, start_factor = twin, twin, 1.0
    for k, factor in enumerate(scales):
        model, q = _scaled_model(start, factor / start_factor)
        wide = with_limits(model, np.minimum(model.lower_limits, q), np.maximum(model.upper_limits, q))  # as exported
        icp = articulated_icp(wide, points, ArticulatedPose(start.T_cam_B, q), config=short if k else config, rng=rng)
        if icp.status not in (FitStatus.SUCCESS, FitStatus.MAX_ITER):
            continue
        moved = FittedModel(model, icp.T_cam_base, np.asarray(icp.q, dtype=np.float64), twin.template, aligned=True)
        residual = depth_residual(moved, observed)
        if residual < best.median_residual_m:
            best = replace(moved, median_residual_m=residual)
            if k == 0:
                start, start_factor = best, factor
    return best


def _scaled_model(twin: FittedModel, factor: float):
    """``twin``'s model scaled by ``factor`` about its base frame's origin and its states there
    (:func:`~ancsh.model.edit.scaled_states`); the model itself at 1."""
    from ..model.edit import scaled, scaled_states

    model = twin.model if factor == 1.0 else scaled(twin.model, factor)
    return model, scaled_states(twin.model, twin.states, factor)


def depth_residual(twin: FittedModel, observed: ObservedDepth) -> float:
    """The median ``|observed - model|`` depth (metres) on the object's pixels of ``twin`` rendered at its states from
    the observed camera (in the window around the mask, :func:`~ancsh.solvers.render_compare.mask_window`); ``inf``
    where the model covers none of them."""
    from ..data.render import ModelRenderer
    from ..model.edit import with_limits
    from .render_compare import compare_depth, crop_intrinsics, mask_window

    u0, v0, u1, v1 = mask_window(observed.object_mask)
    model, q = twin.model, twin.states
    model = with_limits(model, np.minimum(model.lower_limits, q), np.maximum(model.upper_limits, q))  # as exported
    rendered = ModelRenderer(model).render(q, twin.T_cam_B, crop_intrinsics(observed.intrinsics, (u0, v0, u1, v1))).depth
    cmp = compare_depth(rendered, observed.depth[v0:v1, u0:u1], observed.object_mask[v0:v1, u0:u1])
    return float(cmp.median_abs_residual_m) if np.isfinite(cmp.median_abs_residual_m) else float("inf")


def _with_fitted_joints(model, fit: FitResult, corr: Correspondences, layout):
    """``model`` (every part frame ``B`` at rest) with the fit's joint lines: each joint's axis and pivot are the
    fitted camera-frame ones, carried back to rest (``layout.undo_cam``) and into ``B``; the origin keeps the child
    at ``B`` at rest."""
    import dataclasses

    from ..model.articulated import ArticulatedModel

    undo, T_B_cam = layout.undo_cam, layout.T_cam_B.inverse()
    joints = list(model.joints)
    for k in corr.topological_joints:
        p = int(corr.joint_parents[k])
        axis, pivot = np.asarray(fit.joint_axes_cam[k]), np.asarray(fit.joint_pivots_cam[k])
        j = model.joints[k]
        a_B = T_B_cam.apply_direction(undo[p].apply_direction(axis))
        p_B = T_B_cam.apply(undo[p].apply(pivot))
        line = dataclasses.replace(j, axis=a_B / np.linalg.norm(a_B), pivot=p_B, origin=Sim3())
        joints[k] = dataclasses.replace(line, origin=line.motion(j.rest).inverse())  # the child at B at rest
    return ArticulatedModel(model.parts, tuple(joints), name=model.name, category=model.category,
                            R_canon_base=model.R_canon_base)


def export_fit_urdf(fit: FitResult, corr: Correspondences, templates, folder, *, T_frame_cam: Sim3 | None = None,
                    root: str = "camera", name: str | None = None, overwrite: bool = False,
                    observed: ObservedDepth | None = None, candidates: int = 1, align: int = 0,
                    box_extents: str = EXPORT_BOX_EXTENTS, rng=0):
    """Write a fit as a URDF folder (:func:`ancsh.model.urdf_export.write_urdf`): one link per part, the template's
    meshes reshaped to the fit, joints with the fitted axes and pivots, the template's limits (widened to the
    exported states where they lie outside), the fitted states in ``joint_states.json``, the base placed in the camera
    frame (``root="camera"``) or in a frame the user gives. The file names its base link, orientation, rest states
    and category, so that :func:`ancsh.data.urdf.load_urdf` (``ancsh data import``, ``ancsh fit-cad``) reads back
    the model written, its base frame ``B`` and not the root's; ``init.json`` beside it holds that frame's pose in the
    input camera and the states, ``{"T_cam_base": 4x4, "q": [...]}``, what ``ancsh fit-cad --init`` reads to start
    at the twin on the same depth (:data:`FIT_CAD_INIT`).

    Parameters
    ----------
    fit : FitResult
        A successful articulated fit.
    corr : Correspondences
        What it was fitted to (its joint tree and types).
    templates : TemplateLibrary
        The category's templates.
    folder : str or Path
    T_frame_cam : Sim3, optional
        Rigid camera pose in the frame the base is to be placed in (default: the camera frame itself).
    root : str
        Name of the root link (that frame).
    name : str, optional
        Robot name and file stem (default: the template's category).
    overwrite : bool
        Replace the files of an existing non-empty folder.
    observed, candidates, align, box_extents, rng
        Choose the template by render-and-compare against the depth the fit was made from, and align it to that
        depth; the part boxes it is shaped from (:func:`fitted_model`).

    Returns
    -------
    (Path, FittedModel)
        The ``.urdf`` file and the model written.

    Raises
    ------
    ValueError
        A failed fit ("a failed fit is not exported"), no template available, an existing folder without
        ``overwrite``.
    """
    from ..model.urdf_export import write_urdf

    if not isinstance(fit, FitResult):
        raise ValueError(f"fit: expected a FitResult, got {type(fit).__name__}")
    if not fit.ok:
        raise ValueError(f"fit: a failed fit (status {fit.status.value}: {fit.message}) is not exported")
    twin = fitted_model(fit, corr, templates, observed=observed, candidates=candidates, align=align,
                        box_extents=box_extents, rng=rng)
    if twin is None:
        raise ValueError(f"templates: no template of {templates.category!r} is available here to give the parts shapes")
    T = twin.T_cam_B if T_frame_cam is None else T_frame_cam @ twin.T_cam_B
    path = write_urdf(twin.model, folder, states=twin.states, T_root_base=Sim3(T.rotation, T.translation), root=root,
                      name=name or templates.category, overwrite=overwrite)
    write_fit_cad_init(path.parent / FIT_CAD_INIT, twin)
    return path, twin


def write_fit_cad_init(path, twin: FittedModel):
    """Write ``twin``'s base pose in the camera (rigid) and joint states as ``ancsh fit-cad --init`` reads them
    (``{"T_cam_base": 4x4, "q": [...]}``, metres and radians); returns the path."""
    import json
    from pathlib import Path

    from ..outputs import write_bytes_atomically

    T = Sim3(twin.T_cam_B.rotation, twin.T_cam_B.translation)
    data = {"T_cam_base": T.matrix().tolist(), "q": [float(v) for v in twin.states]}
    write_bytes_atomically(Path(path), (json.dumps(data, indent=1) + "\n").encode())
    return Path(path)


def compare_fit(fit, corr, templates, depth, intrinsics, object_mask):
    """:func:`render_fit` in the window around ``object_mask`` (:func:`~ancsh.solvers.render_compare.mask_window`),
    with at most :data:`~ancsh.solvers.render_compare.COMPARE_RAYS` rays (a large window at every few pixels, spread
    back over it), and :func:`~ancsh.solvers.render_compare.compare_depth` there.

    Returns
    -------
    (DepthComparison or None, str)
        ``None`` when no template is available; the template's name. The residual map covers the window.
    """
    from .render_compare import (coarse_intrinsics, compare_depth, compare_stride, crop_intrinsics, mask_window,
                                 upsample_depth)

    u0, v0, u1, v1 = mask_window(object_mask)
    stride = compare_stride((u1 - u0) * (v1 - v0))
    window = crop_intrinsics(intrinsics, (u0, v0, u1, v1))
    model_depth, name = render_fit(fit, corr, templates, coarse_intrinsics(window, stride))
    if model_depth is None:
        return None, name
    model_depth = upsample_depth(model_depth, stride, (v1 - v0, u1 - u0))
    return compare_depth(model_depth, np.asarray(depth)[v0:v1, u0:u1], np.asarray(object_mask)[v0:v1, u0:u1]), name


def render_fit(fit, corr, templates, intrinsics):
    """Depth image ``(H, W)`` (metres, 0 = background) of the category template nearest to ``fit``, reshaped to
    its part boxes and posed at its object pose and joint states, seen from ``intrinsics``; and the template's name.

    Parameters
    ----------
    fit : FitResult
        A successful articulated fit (part poses, boxes, camera joints and states).
    corr : Correspondences
        What it was fitted to (joint tree and types).
    templates : TemplateLibrary
        The category's templates (:func:`ancsh.data.templates.load_template_library`).
    intrinsics : Intrinsics

    Returns
    -------
    (ndarray or None, str)
        ``None`` when no template is available here.
    """
    from ..data.render import ModelRenderer

    twin = fitted_model(fit, corr, templates, joints="template")  # as the p_object calibrations measured it
    if twin is None:
        return None, "none"
    model = twin.model
    q = np.clip(twin.states, model.lower_limits, model.upper_limits)
    return ModelRenderer(model).render(q, twin.T_cam_B, intrinsics).depth, twin.template
