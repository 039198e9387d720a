"""Data terms: the observed points against the part poses, point-to-point (:class:`DataTerm`) and point-to-plane
(:class:`PointToPlaneTerm`), both on per-part moments so their cost does not grow with the points."""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..inputs import KinematicStructure, PartMoments, ProgramInputs
from .context import Context, EnergyTerm, register_term


@register_term
class DataTerm(EnergyTerm):
    """Point-to-point data term of every part, on per-part moments (paper's ``e_j``).

    ``e_j = sum_i w_i |p_i - (s_j R_j c_i + t_j)|^2 / (sum_i w_i L^2)``. With centred
    coordinates ``x_i = [c_i - cbar; 1]``, ``p'_i = p_i - pbar`` and ``A = [s R | s R cbar + t - pbar]``,
    ``e_j = |A Lm - B|_F^2 / L^2 + c0`` exactly, where ``Lm Lm^T = mean(w x x^T)``,
    ``Lm B^T = mean(w x p'^T)`` and ``c0 = (mean(w |p'|^2) - |B|^2) / L^2`` (see :func:`part_moments`).
    The residual is ``[vec(A Lm - B) / L; sqrt(c0)]`` (13 per part), so ``|r|^2 == sum_j e_j``.
    """

    name = "data"
    rows_per_part = 13

    def expression(self, ctx: Context) -> ca.SX:
        out = []
        for j in range(len(ctx.poses)):
            P = ctx.data_pose(j)
            Lm = ctx.params.get(f"Lm{j}", 4, 4)
            B = ctx.params.get(f"B{j}", 3, 4)
            sqrt_c0 = ctx.params.get(f"sqrt_c0_{j}")
            cbar = ctx.params.get(f"cbar{j}", 3)
            pbar = ctx.params.get(f"pbar{j}", 3)
            sR = P.s * P.R
            A = ca.horzcat(sR, sR @ cbar + P.t - pbar)
            k = ctx.data_weight(j)
            out.append(k * ca.vec(A @ Lm - B) / ctx.L)
            out.append(k * sqrt_c0)
        return ca.vertcat(*out)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        v = {}
        for j, m in enumerate(inputs.require("moments", self.name)):
            v[f"Lm{j}"], v[f"B{j}"], v[f"sqrt_c0_{j}"], v[f"cbar{j}"], v[f"pbar{j}"] = m.Lm, m.B, m.sqrt_c0, m.cbar, m.pbar
        return v


def part_moments(points_cam, npcs, weights, L: float) -> PartMoments:
    """Numeric moments of one part for :class:`DataTerm` (``Lp`` left ``None``).

    Parameters
    ----------
    points_cam : (n, 3) float64
        Camera-frame points (metres).
    npcs : (n, 3) float64
        Their NPCS coordinates.
    weights : (n,) float64
        Non-negative weights with a positive sum.
    L : float
        Object scale (metres) used to normalise the residual.
    """
    weights = np.asarray(weights, dtype=np.float64)
    return parts_moments(points_cam, npcs, np.zeros(len(weights), dtype=np.intp), weights, 1, L)[0]


def parts_moments(points_cam, npcs, labels, weights, num_parts: int, L: float) -> tuple:
    """:func:`part_moments` of every part at once: ``(num_parts,)`` :class:`PartMoments`.

    Parameters
    ----------
    points_cam, npcs : (n, 3) float64
        Camera-frame points (metres) and their NPCS coordinates.
    labels : (n,) int
        Part of each point, in ``0 .. num_parts - 1``.
    weights : (n,) float64
        Non-negative weights (0 leaves a point out); every part needs a positive sum.
    num_parts : int
    L : float
        Object scale (metres) used to normalise the residual.
    """
    n = len(labels)
    W = np.zeros((num_parts, n))
    W[labels, np.arange(n)] = weights
    W /= W.sum(axis=1, keepdims=True)  # (M, n): each part's normalised weights
    cbar, pbar = W @ npcs, W @ points_cam  # (M, 3)
    x = np.empty((n, 4))
    x[:, :3] = npcs - cbar[labels]
    x[:, 3] = 1.0
    pc = points_cam - pbar[labels]
    xw = W[:, :, None] * x  # (M, n, 4)
    Mx = xw.transpose(0, 2, 1) @ x  # (M, 4, 4)
    C = xw.transpose(0, 2, 1) @ pc  # (M, 4, 3)
    P = W @ np.einsum("ij,ij->i", pc, pc)  # (M,)
    lam, V = np.linalg.eigh(Mx)
    keep = lam > 1e-12 * np.maximum(lam.max(axis=1, keepdims=True), 1e-300)
    root = np.where(keep, np.sqrt(np.where(keep, lam, 1.0)), 0.0)
    inv_root = np.where(keep, 1.0 / np.where(keep, root, 1.0), 0.0)
    Lm = V * root[:, None, :]
    B = (C.transpose(0, 2, 1) @ V) * inv_root[:, None, :]
    sqrt_c0 = np.sqrt(np.maximum(P - np.sum(B * B, axis=(1, 2)), 0.0) / L**2)
    return tuple(PartMoments(Lm[j], B[j], float(sqrt_c0[j]), cbar[j], pbar[j]) for j in range(num_parts))


@register_term
class PointToPlaneTerm(EnergyTerm):
    """Point-to-plane data term on per-part moments (parameters ``Lp{j}`` (13, 13), ``pbar{j}``).

    The point-to-plane ICP error of every part, ``sum_i w_i (n_i . (p_i - (s_j R_j c_i + t_j)))^2 / L^2`` with ``n_i = R_j m_i`` the model
    normal ``m_i`` (NPCS) rotated into the camera. Like the point-to-point
    :class:`~ancsh.solvers.terms.DataTerm` it depends on the points only through moments, so
    its cost does not grow with the number of points: with
    ``phi_i = [vec((p_i - pbar) m_i^T); m_i; m_i . c_i]`` (13) and
    ``beta = [vec(R); -R^T (t - pbar); -s]`` the residual of point ``i`` is ``beta . phi_i``, hence
    ``sum_i w_i r_i^2 = |Lp^T beta|^2`` with ``Lp Lp^T = sum_i w_i phi_i phi_i^T``.
    """

    name = "point_to_plane"
    rows_per_part = 13
    residual_dims = 1

    def expression(self, ctx: Context) -> ca.SX:
        if ctx.npcs_stretch:
            raise ValueError(f"terms: the {self.name!r} term needs rotations (its normals turn with R_j); "
                             "NPCS stretch biases are for the point-to-point data term")
        out = []
        for j in range(len(ctx.poses)):
            P = ctx.data_pose(j)
            Lp = ctx.params.get(f"Lp{j}", 13, 13)
            pbar = ctx.params.get(f"pbar{j}", 3)
            beta = ca.vertcat(ca.vec(P.R), -(P.R.T @ (P.t - pbar)), -P.s)
            out.append((Lp.T @ beta) / ctx.L)
        return ca.vertcat(*out)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        v = {}
        for j, m in enumerate(inputs.require("moments", self.name)):
            if m.Lp is None:
                raise ValueError(f"inputs.moments[{j}].Lp: required by the {self.name!r} term, got None")
            v[f"Lp{j}"], v[f"pbar{j}"] = m.Lp, m.pbar
        return v


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
