"""A fit's result from its solved part poses (paper Sec. 4.4): camera-space joint axes, pivots and states, amodal
part boxes and the largest joint violation, gathered into a :class:`~ancsh.solvers.types.FitResult`; and the data
costs of the closed-form (``per_part``) fits."""

from __future__ import annotations

import numpy as np

from ..geometry.boxes import OrientedBox, unit_diagonal
from ..geometry.transforms import Sim3
from .terms import CanonicalParameters, DataTerm, ExactJointTerm, JointLimitTerm, KinematicStructure, ProgramInputs, ProgramStart
from .types import Correspondences, FitResult, FitStatus

__all__ = ["amodal_box", "closed_form_costs", "fit_result", "max_violation", "postprocess"]


def postprocess(structure: KinematicStructure, poses: list, canonical: CanonicalParameters) -> tuple:
    """Camera-space joint axes ``(K, 3)``, pivots ``(K, 3)`` (metres) and joint states ``(K,)`` relative to rest
    (radians or metres) of the part poses ``T_cam_npcs``."""
    from .program import postprocess_function

    return postprocess_function(structure)(poses, canonical)


def max_violation(structure: KinematicStructure, poses: list, canonical: CanonicalParameters, L: float,
                  limits: np.ndarray) -> float:
    """Largest exact-joint or joint-limit violation of the part poses (object-normalised units, radians)."""
    prog = _violation_program(structure)
    p = prog.pack(ProgramInputs(L, canonical, ProgramStart(T_cam_npcs=tuple(poses))))
    g = np.asarray(prog.constraints(prog.initial_x(), p)).ravel()
    lo, hi = prog.constraint_bounds(limits)
    return float(np.max(np.concatenate([[0.0], lo - g, g - hi]))) if g.size else 0.0


_VIOLATION_PROGRAMS: dict = {}


def _violation_program(structure: KinematicStructure):
    """The maximal program of the exact joints and the limits of ``structure`` (memoised: its key is built once)."""
    prog = _VIOLATION_PROGRAMS.get(structure)
    if prog is None:
        from .program import ProgramKey, get_program

        terms = (ExactJointTerm,) + ((JointLimitTerm,) if structure.num_joints else ())
        prog = _VIOLATION_PROGRAMS[structure] = get_program(ProgramKey(structure, "maximal", False, terms))
    return prog


def closed_form_costs(structure: KinematicStructure, canonical: CanonicalParameters, poses: list, L: float,
                      moments: tuple) -> dict:
    """``{"data": e}``: the data energy of the points with these moments at the given poses (closed-form fits)."""
    from .program import ProgramKey, get_program

    prog = get_program(ProgramKey(structure, "maximal", False, (DataTerm,)))
    p = prog.pack(ProgramInputs(L, canonical, ProgramStart(T_cam_npcs=tuple(poses)), moments))
    return dict(zip(prog.cost_names, np.asarray(prog.term_costs(prog.initial_x(), p)).ravel().tolist()))


def amodal_box(corr: Correspondences, j: int, T: Sim3, inliers: np.ndarray, box_extents: str) -> OrientedBox:
    """Part ``j``'s amodal box: its NPCS box (centred at the NPCS origin; the provider's extents, else twice the
    inliers' largest NPCS coordinates, optionally rescaled to a unit diagonal) mapped by the part pose ``T``."""
    if corr.npcs_extents is not None:
        extents = corr.npcs_extents[j]
    else:
        sel = inliers & (corr.part_labels == j)
        extents = 2.0 * np.max(np.abs(corr.npcs[sel]), axis=0)  # NOCS: symmetric about the NPCS origin
        if box_extents == "unit_diagonal":
            extents = unit_diagonal(extents)
    extents = T.scale * np.asarray(extents, dtype=np.float64)
    if np.any(extents < 0):  # the validating constructor names the problem
        return OrientedBox(T.translation, T.rotation, extents)
    return OrientedBox.unchecked(T.translation, T.rotation, extents)  # T: a fit's pose, a rotation by construction


def fit_result(structure: KinematicStructure, corr: Correspondences, poses: list, inliers: np.ndarray, L: float,
               canonical: CanonicalParameters, limits: np.ndarray, *, formulation: str, solver: str, status: FitStatus,
               message: str, iterations: int, costs: dict, uncertainty, box_extents: str, time_s: float) -> FitResult:
    """The :class:`~ancsh.solvers.types.FitResult` of the solved part poses ``T_cam_npcs`` (``inliers``: ``(N,)`` bool,
    ``L``: the object scale in metres, ``limits``: ``(K, 2)`` the joint limits the fit enforced)."""
    axes, pivots, states = postprocess(structure, poses, canonical)
    return FitResult(
        formulation=formulation, solver=solver, T_cam_npcs=tuple(poses), joint_axes_cam=axes, joint_pivots_cam=pivots,
        joint_states=states, boxes_cam=tuple(amodal_box(corr, j, T, inliers, box_extents) for j, T in enumerate(poses)),
        status=status, message=message, cost_per_term=costs, iterations=int(iterations),
        max_constraint_violation=max_violation(structure, poses, canonical, L, limits), inliers=inliers, time_s=time_s,
        uncertainty=uncertainty, canonical=canonical,
    )
