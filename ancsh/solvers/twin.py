"""A fit as a simulation-ready articulated model (its "digital twin") and its URDF export.

The model is the category template nearest to the fit (:func:`ancsh.data.templates.load_template_library`:
procedural and imported real training instances), reshaped to the fitted part boxes
(:func:`ancsh.solvers.icp.category.fitted_template`): its meshes, joint conventions and limits, at the fitted
object pose and joint states. Render-and-compare (:mod:`ancsh.solvers.render_compare`) renders the same model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.transforms import Sim3
from .types import Correspondences, FitResult

__all__ = ["FittedModel", "fitted_model", "export_fit_urdf"]


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
    """

    model: object
    T_cam_B: Sim3
    states: np.ndarray
    template: str


def fitted_model(fit: FitResult, corr: Correspondences, templates, *, joints: str = "fitted") -> FittedModel | None:
    """The model of a successful articulated fit, or ``None`` when no template is available here.

    ``joints``: ``"fitted"`` (the default) gives every joint the fit's axis and pivot, so that the model at the
    fitted states has the fit's part poses; ``"template"`` keeps the reshaped template's own joint lines (what
    render-and-compare and the ``p_object`` calibrations measured: the template's hinge on the fitted parts).

    Raises
    ------
    ValueError
        A failed fit, or one without the boxes, joints or states an articulated fit has (naming it).
    """
    from .icp.category import fitted_layout, fitted_template

    layout = fitted_layout(fit, corr)
    nearest = templates.nearest(layout.centres, layout.sizes, count=1)
    if not nearest:
        return None
    if joints not in ("fitted", "template"):
        raise ValueError(f"joints: expected 'fitted' or 'template', got {joints!r}")
    ft = fitted_template(templates.model(nearest[0]), layout)
    model = _with_fitted_joints(ft.model, fit, corr, layout) if joints == "fitted" else ft.model
    return FittedModel(model, layout.T_cam_B, model.rest_states + np.asarray(fit.joint_states, dtype=np.float64), ft.source)


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
                    root: str = "camera", name: str | None = None, overwrite: bool = False):
    """Write a fit as a URDF folder (:func:`ancsh.model.urdf_export.write_urdf`): one link per part, the template's
    meshes reshaped to the fit, joints with the fitted axes and pivots, the category's limits, the fitted states
    in ``joint_states.json``, the base placed in the camera frame (``root="camera"``) or in a frame the user gives.

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
    twin = fitted_model(fit, corr, templates)
    if twin is None:
        raise ValueError(f"templates: no template of {templates.category!r} is available here to give the parts shapes")
    T = twin.T_cam_B if T_frame_cam is None else T_frame_cam @ twin.T_cam_B
    path = write_urdf(twin.model, folder, states=twin.states, T_root_base=Sim3(T.rotation, T.translation), root=root,
                      name=name or templates.category, overwrite=overwrite)
    return path, twin
