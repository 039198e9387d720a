"""Extra energy terms for template fitting, registered with the solver core's term registry.

:class:`PointToPlaneTerm` (``"point_to_plane"``) is the point-to-plane ICP error of every
part, ``sum_i w_i (n_i . (p_i - (s_j R_j c_i + t_j)))^2 / L^2`` with ``n_i = R_j m_i`` the model
normal ``m_i`` (NPCS) rotated into the camera. Like the point-to-point
:class:`~ancsh.solvers.terms.DataTerm` it depends on the points only through moments, so
its cost does not grow with the number of points: with
``phi_i = [vec((p_i - pbar) m_i^T); m_i; m_i . c_i]`` (13) and
``beta = [vec(R); -R^T (t - pbar); -s]`` the residual of point ``i`` is ``beta . phi_i``, hence
``sum_i w_i r_i^2 = |Lp^T beta|^2`` with ``Lp Lp^T = sum_i w_i phi_i phi_i^T``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..terms import TERMS, Context, EnergyTerm, register_term

__all__ = ["PointToPlaneTerm", "plane_moments"]


class PointToPlaneTerm(EnergyTerm):
    """Point-to-plane data term on per-part moments (parameters ``Lp{j}`` (13, 13), ``pbar{j}``)."""

    name = "point_to_plane"

    def expression(self, ctx: Context) -> ca.SX:
        out = []
        for j, P in enumerate(ctx.poses):
            Lp = ctx.params.get(f"Lp{j}", 13, 13)
            pbar = ctx.params.get(f"pbar{j}", 3)
            beta = ca.vertcat(ca.vec(P.R), -(P.R.T @ (P.t - pbar)), -P.s)
            out.append((Lp.T @ beta) / ctx.L)
        return ca.vertcat(*out)


if PointToPlaneTerm.name not in TERMS:  # re-imports (e.g. importlib.reload) keep the first registration
    register_term(PointToPlaneTerm)


def plane_moments(points_cam, npcs, normals_npcs, weights, pbar) -> np.ndarray:
    """``Lp`` ``(13, 13)`` of one part for :class:`PointToPlaneTerm`.

    Parameters
    ----------
    points_cam : (n, 3) float64
        Observed points (metres, camera frame).
    npcs : (n, 3) float64
        Their matches in the part's NPCS.
    normals_npcs : (n, 3) float64
        Unit model normals at the matches, in NPCS.
    weights : (n,) float64
        Non-negative weights; the moments use ``weights / sum(weights)`` like the
        point-to-point term (a per-part weighted mean).
    pbar : (3,) float64
        The centring point (the same ``pbar`` as the point-to-point term of this part).
    """
    w = np.asarray(weights, dtype=np.float64)
    total = w.sum()
    if total <= 0:
        return np.zeros((13, 13))
    w = w / total
    pc = np.asarray(points_cam) - pbar
    m = np.asarray(normals_npcs)
    # vec() is column-major in CasADi: vec(A)[3 * col + row] = A[row, col]; (p m^T)[r, c] = p_r m_c.
    phi = np.empty((len(w), 13))
    phi[:, :9] = (m[:, :, None] * pc[:, None, :]).reshape(-1, 9)
    phi[:, 9:12] = m
    phi[:, 12] = np.einsum("ij,ij->i", m, np.asarray(npcs))
    M = (phi * w[:, None]).T @ phi
    lam, V = np.linalg.eigh(M)
    return V * np.sqrt(np.clip(lam, 0.0, None))
