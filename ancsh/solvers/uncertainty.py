"""Uncertainty of a fit: covariances of part poses, object pose and joints from the program's Jacobian.

At a solution ``x`` of a program (:mod:`ancsh.solvers.program`), the Gauss-Newton approximation
linearises the residuals ``r(x)``: with ``H = J^T J`` (every cost term, priors and penalties
included, as in the solve) the solution moves by ``dx = -H^-1 J^T dr`` when the data residuals
move by ``dr``. The data terms (:attr:`~ancsh.solvers.terms.EnergyTerm.rows_per_part`) are
per-part weighted means over the observed points, so a part with ``n_j`` (effective,
``(sum w)^2 / sum w^2``) points contributes ``Cov(J_j^T dr_j) = v_j / n_j * J_j^T J_j``, where
``v_j`` is the variance of one residual component estimated from the part's own residuals (its
weighted mean squared residual over the components per point, with a degrees-of-freedom
correction). Hence the sandwich

    ``Cov(x) = H^-1 (sum_j v_j / n_j J_j^T J_j) H^-1``,

which is ``sigma^2 (J^T J)^-1`` when every part has the same points and noise and nothing but data
terms. Robust (IRLS) weights enter as used in the last solve (in the moments and in ``n_j``).

**Reduced coordinates.** The covariance lives in the program's own coordinates: for
``exact_reduced`` the object pose, the object scale and one state per joint (joints hold by
construction); for maximal programs with exact joint equalities it is restricted to the null space
``Z`` of the equality Jacobian (``H`` -> ``Z^T H Z``), so it respects the constraints to first
order. Joint limits (bounds, inequalities) are ignored: a state at its limit gets the covariance
of the unconstrained problem. The object scale is always a variable of the covariance program
(it was estimated from the data even when the solve held it fixed), so its uncertainty reaches
the translations; the NPCS -> NAOCS offsets of free canonical parameters are nuisance variables.

**Reported quantities**, propagated through the Jacobian of the program's own expressions
(:meth:`~ancsh.solvers.program.Program.output_jacobian`): per part the rotation as a
camera-frame tangent ``phi`` (``R_true = exp([phi]) R_fit``, radians), the translation (metres)
and the scale; the object pose (root part's rotation, NAOCS origin, metres per NAOCS unit); per
joint the state (radians / metres), the camera axis (unit vector) and the pivot (metres).

**Other frames.** :meth:`FitUncertainty.composed` maps the pose covariances to frames a constant
map away (a known model's part frames: ``T_cam_part = T_cam_npcs @ T_npcs_part``), as articulated ICP
reports them (:func:`ancsh.solvers.icp.articulated.icp_uncertainty`).

A direction that the data do not determine (a degenerate part, collinear points) makes
``H`` singular: every quantity that moves along it gets an infinite variance and
:attr:`FitUncertainty.status` is ``"singular"`` -- never an exception.

**Inflation.** Jacobian covariances assume independent residuals; the errors of a network's
NPCS predictions are correlated, so they are over-confident. :class:`Inflation` holds a measured
within-part residual correlation (each raw result carries the covariance per unit of it,
:attr:`FitUncertainty.correlated`: ``v_j (1 - 1 / n_j)`` in place of ``v_j / n_j``) and per
quantity a measured :class:`SigmaMap` -- one for all parts (joints) or one per part (joint) -- of
each block's raw standard deviation ``sigma`` (:func:`block_sigma`) to the reported one,
``sigma' = sqrt((k sigma^p s^(1-p))^2 + b^2)``: a single factor ``k``, a power ``p`` about a
reference ``s``, or a floor ``b`` (``ancsh bench uncertainty``, stored in
``ancsh/weights/uncertainty_inflation.json``, :func:`inflation_for`; a number there is a single
factor). :meth:`FitUncertainty.inflated` applies them, the raw covariances stay available.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from .inflation import (  # measured inflation, importable from here as before
    INFLATED_QUANTITIES,
    INFLATION_PATH,
    Inflation,
    SigmaMap,
    first_measured_inflation,
    inflation_for,
    load_inflation_table,
    maps_from_json,
    maps_to_json,
    tracked_provider,
)

__all__ = ["FitUncertainty", "INFLATED_QUANTITIES", "Inflation", "INFLATION_PATH", "SigmaMap", "UNCERTAINTY_STATUSES",
           "block_sigma", "effective_points", "first_measured_inflation", "fit_covariance", "inflation_for",
           "load_inflation_table", "maps_from_json", "maps_to_json", "tracked_provider"]

UNCERTAINTY_STATUSES = ("ok", "singular", "unavailable")


_RELATIVE_NULL = 1e-10  # eigenvalues of the reduced H below this fraction of the largest: undetermined
_NULL_LEAK = 1e-6  # a quantity whose gradient has this share along an undetermined direction is unbounded


def block_sigma(cov: np.ndarray) -> np.ndarray:
    """The RMS standard deviation per coordinate, ``sqrt(tr(C) / n)``, of ``(..., n, n)`` covariance blocks
    (``(...)``, their unit): the raw ``sigma`` a :class:`SigmaMap` maps."""
    cov = np.asarray(cov, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.trace(cov, axis1=-2, axis2=-1) / cov.shape[-1])


def _pose_ratios(inf: Inflation, cov: np.ndarray, index: int, count: int) -> np.ndarray:
    """``(7,)`` ratios of the ``[phi, t, s]`` coordinates of a ``(7, 7)`` pose covariance of part ``index`` of ``count``."""
    r = [inf.map_for(q, index, count).ratio(block_sigma(cov[sl, sl]))
         for q, sl in (("rotation", slice(0, 3)), ("translation", slice(3, 6)), ("scale", slice(6, 7)))]
    return np.array([r[0]] * 3 + [r[1]] * 3 + [r[2]])


@dataclass(frozen=True)
class FitUncertainty:
    """Covariances of a fit's reported quantities (camera frame; radians, metres).

    Attributes
    ----------
    status : str
        ``"ok"``; ``"singular"`` (some quantity is undetermined by the data: its variance is
        ``inf``); ``"unavailable"`` (no estimate, or too few residuals: every variance ``inf``).
    message : str
    part_covariances : (M, 7, 7) float64
        Per part, over ``[phi (3), t (3), s]``: ``phi`` the camera-frame rotation tangent
        (``R_true = exp([phi]) R_fit``, radians), ``t`` the translation of ``T_cam_npcs`` (metres),
        ``s`` its scale.
    object_covariance : (7, 7) float64
        The object pose ``T_cam_naocs`` (root part's rotation, NAOCS origin in metres, metres per
        NAOCS unit), same layout.
    joint_state_covariance : (K, K) float64
        Joint states relative to rest (radians / metres).
    joint_axis_covariances : (K, 3, 3) float64
        Camera-frame unit axes (rank 2: perpendicular to the axis).
    joint_pivot_covariances : (K, 3, 3) float64
        Camera-frame pivots (metres).
    noise_std_m : (M,) float64
        Per part, the estimated standard deviation of one residual component (metres).
    points : (M,) float64
        Effective number of points per part (``(sum w)^2 / sum w^2`` of the final weights).
    inflation : Inflation
        The factors already applied (``source == "raw"``: none).
    time_s : float
        Wall time of the computation (seconds).
    correlated : FitUncertainty or None
        Raw results only: the covariances added per unit of within-part residual correlation
        (see :attr:`Inflation.correlation`), same layout.
    base : FitUncertainty or None
        Inflated results only: the raw result they were made from (:meth:`raw`).
    """

    status: str
    message: str
    part_covariances: np.ndarray
    object_covariance: np.ndarray
    joint_state_covariance: np.ndarray
    joint_axis_covariances: np.ndarray
    joint_pivot_covariances: np.ndarray
    noise_std_m: np.ndarray
    points: np.ndarray
    inflation: Inflation = field(default_factory=Inflation)
    time_s: float = 0.0
    correlated: "FitUncertainty | None" = field(default=None, repr=False)
    base: "FitUncertainty | None" = field(default=None, repr=False)

    def __post_init__(self):
        if self.status not in UNCERTAINTY_STATUSES:
            raise ValueError(f"status: expected one of {UNCERTAINTY_STATUSES}, got {self.status!r}")
        for name in ("part_covariances", "object_covariance", "joint_state_covariance", "joint_axis_covariances",
                     "joint_pivot_covariances", "noise_std_m", "points"):
            a = np.array(getattr(self, name), dtype=np.float64, copy=True)
            a.flags.writeable = False
            object.__setattr__(self, name, a)

    @classmethod
    def unavailable(cls, message: str, num_parts: int, num_joints: int) -> "FitUncertainty":
        """Every variance ``inf`` (no estimate or no residual degrees of freedom)."""
        M, K = num_parts, num_joints
        eye = lambda n: np.where(np.eye(n, dtype=bool), np.inf, 0.0)  # noqa: E731
        return cls("unavailable", message, np.stack([eye(7)] * M) if M else np.zeros((0, 7, 7)), eye(7), eye(K),
                   np.stack([eye(3)] * K) if K else np.zeros((0, 3, 3)), np.stack([eye(3)] * K) if K else np.zeros((0, 3, 3)),
                   np.full(M, np.nan), np.zeros(M))

    # -- standard deviations ---------------------------------------------------------------------
    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def rotation_rms_rad(self) -> np.ndarray:
        """``(M,)`` predicted RMS rotation angle error per part: ``sqrt(tr Cov(phi))`` (radians)."""
        return np.sqrt(np.trace(self.part_covariances[:, :3, :3], axis1=1, axis2=2))

    @property
    def translation_rms_m(self) -> np.ndarray:
        """``(M,)`` predicted RMS translation error per part: ``sqrt(tr Cov(t))`` (metres)."""
        return np.sqrt(np.trace(self.part_covariances[:, 3:6, 3:6], axis1=1, axis2=2))

    @property
    def scale_std(self) -> np.ndarray:
        """``(M,)`` standard deviation of each part's scale (metres per NPCS unit)."""
        return np.sqrt(self.part_covariances[:, 6, 6])

    @property
    def joint_state_std(self) -> np.ndarray:
        """``(K,)`` standard deviation of each joint state (radians / metres)."""
        return np.sqrt(np.diag(self.joint_state_covariance))

    @property
    def joint_axis_rms_rad(self) -> np.ndarray:
        """``(K,)`` predicted RMS axis angle error: ``sqrt(tr Cov(axis))`` (radians, small angles)."""
        return np.sqrt(np.trace(self.joint_axis_covariances, axis1=1, axis2=2)) if len(self.joint_axis_covariances) else np.zeros(0)

    @property
    def joint_pivot_rms_m(self) -> np.ndarray:
        """``(K,)`` predicted RMS pivot error: ``sqrt(tr Cov(pivot))`` (metres)."""
        return np.sqrt(np.trace(self.joint_pivot_covariances, axis1=1, axis2=2)) if len(self.joint_pivot_covariances) else np.zeros(0)

    # -- inflation -------------------------------------------------------------------------------
    def inflated(self, inflation: Inflation) -> "FitUncertainty":
        """These covariances with the within-part correlation added and the standard deviations
        multiplied by ``inflation``'s factors (always from the raw ones: inflating twice does not compound)."""
        if not isinstance(inflation, Inflation):
            raise ValueError(f"inflation: expected an Inflation, got {type(inflation).__name__}")
        raw = self.raw()
        if inflation.is_identity:
            return replace(raw, inflation=inflation)
        rho = inflation.correlation
        corr = raw.correlated

        def add(name):
            a = getattr(raw, name)
            return a + rho * getattr(corr, name) if rho > 0 and corr is not None else a

        parts, obj = add("part_covariances"), add("object_covariance")
        states, axes, pivots = add("joint_state_covariance"), add("joint_axis_covariances"), add("joint_pivot_covariances")
        M, K = parts.shape[0], states.shape[0]
        d_parts = np.array([_pose_ratios(inflation, parts[j], j, M) for j in range(M)]).reshape(M, 7)
        d_obj = _pose_ratios(inflation, obj, 0, M) if M else np.ones(7)  # the object pose takes the root part's maps
        with np.errstate(invalid="ignore"):
            d_state = np.array([inflation.map_for("joint_state", k, K).ratio(np.sqrt(states[k, k])) for k in range(K)])
            d_axis = np.array([inflation.map_for("joint_axis", k, K).ratio(block_sigma(axes[k])) for k in range(K)])
            d_pivot = np.array([inflation.map_for("joint_pivot", k, K).ratio(block_sigma(pivots[k])) for k in range(K)])
            return replace(
                raw, inflation=inflation, base=raw, correlated=None,
                part_covariances=parts * d_parts[:, :, None] * d_parts[:, None, :], object_covariance=obj * np.outer(d_obj, d_obj),
                joint_state_covariance=states * np.outer(d_state, d_state),
                joint_axis_covariances=axes * (d_axis**2).reshape(K, 1, 1),
                joint_pivot_covariances=pivots * (d_pivot**2).reshape(K, 1, 1),
            )

    def composed(self, T_cam_parts, T_parts_frames, T_cam_object, T_object_frame) -> "FitUncertainty":
        """The covariances of the poses composed on the right with constant maps, ``T_cam_a @ T_a_b``.

        A fit reports poses in the program's frames (NPCS, NAOCS); a known model's part frames are
        fixed maps away (``T_cam_part = T_cam_npcs @ T_npcs_part``). The rotation tangent ``phi``
        (camera frame) is unchanged; the translation moves by ``ds R t_ab + [phi] s R t_ab``
        (``t_ab`` the translation of ``T_a_b``); the scale is multiplied by ``T_a_b``'s. Joint
        quantities are camera-frame and stay as they are; so does an inflation already applied
        (the raw, correlated and inflated covariances are all mapped).

        Parameters
        ----------
        T_cam_parts : sequence of Sim3
            ``(M,)`` the poses these covariances describe (``T_cam_a``, e.g. ``T_cam_npcs``).
        T_parts_frames : sequence of Sim3
            ``(M,)`` the constant maps ``T_a_b`` (e.g. ``T_npcs_part``).
        T_cam_object, T_object_frame : Sim3
            The same for the object pose (e.g. ``T_cam_naocs`` and ``T_naocs_base``).
        """
        M = self.part_covariances.shape[0]
        if len(T_cam_parts) != M or len(T_parts_frames) != M:
            raise ValueError(f"T_cam_parts, T_parts_frames: expected {M} poses each, got "
                             f"{len(T_cam_parts)} and {len(T_parts_frames)}")
        A_parts = [_composition_jacobian(T, C) for T, C in zip(T_cam_parts, T_parts_frames)]
        A_obj = _composition_jacobian(T_cam_object, T_object_frame)

        def mapped(u):
            if u is None:
                return None
            return replace(u, part_covariances=np.stack([_propagate(c, A) for c, A in zip(u.part_covariances, A_parts)])
                           if M else u.part_covariances,
                           object_covariance=_propagate(u.object_covariance, A_obj),
                           correlated=mapped(u.correlated), base=mapped(u.base))

        return mapped(self)

    def raw(self) -> "FitUncertainty":
        """The raw Jacobian covariances (this object when no inflation was applied)."""
        return self if self.base is None else self.base

    # -- output ----------------------------------------------------------------------------------
    def summary(self) -> dict:
        """Standard deviations (lists; ``inf`` where undetermined) -- see :meth:`to_dict`."""
        obj = self.object_covariance
        return {
            "parts": [{"rotation_rms_rad": float(a), "translation_rms_m": float(b), "scale_std": float(c)}
                      for a, b, c in zip(self.rotation_rms_rad, self.translation_rms_m, self.scale_std)],
            "object": {"rotation_rms_rad": float(np.sqrt(np.trace(obj[:3, :3]))),
                       "translation_rms_m": float(np.sqrt(np.trace(obj[3:6, 3:6]))), "scale_std": float(np.sqrt(obj[6, 6]))},
            "joints": [{"state_std": float(a), "axis_rms_rad": float(b), "pivot_rms_m": float(c)}
                       for a, b, c in zip(self.joint_state_std, self.joint_axis_rms_rad, self.joint_pivot_rms_m)],
        }

    def to_dict(self, *, covariances: bool = False) -> dict:
        """JSON-ready: status, message, the inflation, the (inflated) standard deviations and the raw ones
        (``raw``), the noise estimate; with ``covariances`` also the full matrices. Infinite values
        stay ``inf`` here (JSON writers turn them into ``null``)."""
        out = {"status": self.status, "message": self.message,
               "inflation": self.inflation.to_json(),
               **self.summary(), "raw": self.raw().summary(),
               "noise_std_m": self.noise_std_m.tolist(), "points": self.points.tolist(), "time_ms": 1e3 * self.time_s}
        if covariances:
            out["covariances"] = {
                "parts": self.part_covariances.tolist(), "object": self.object_covariance.tolist(),
                "joint_states": self.joint_state_covariance.tolist(), "joint_axes": self.joint_axis_covariances.tolist(),
                "joint_pivots": self.joint_pivot_covariances.tolist(),
            }
        return out


def _composition_jacobian(T, C) -> np.ndarray:
    """``(7, 7)``: ``[phi, t, s]`` of ``T @ C`` per unit of ``T``'s (``C`` constant; see :meth:`FitUncertainty.composed`)."""
    v = T.rotation @ np.asarray(C.translation, dtype=np.float64)  # d(t') / ds
    w = T.scale * v
    A = np.eye(7)
    A[3:6, 0:3] = -np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])  # [phi] w = -[w] phi
    A[3:6, 6] = v
    A[6, 6] = float(C.scale)
    return A


def _propagate(cov: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``A cov A^T`` where an infinite variance (unbounded quantity) makes every output it reaches unbounded."""
    inf = ~np.isfinite(np.diag(cov))
    if not np.any(inf):
        return A @ cov @ A.T
    c = np.where(np.isfinite(cov), cov, 0.0)
    c[inf, :] = 0.0
    c[:, inf] = 0.0
    out = A @ c @ A.T
    reach = np.any(A[:, inf] != 0.0, axis=1)
    out[reach, :] = 0.0
    out[:, reach] = 0.0
    out[reach, reach] = np.inf
    return out


# ------------------------------------------------------------------------------------------------
# computation
# ------------------------------------------------------------------------------------------------
def _null_space(A: np.ndarray, n: int) -> np.ndarray:
    """Orthonormal basis ``(n, d)`` of the null space of ``A`` ``(m, n)``."""
    if A.shape[0] == 0:
        return np.eye(n)
    _, s, Vt = np.linalg.svd(A)
    rank = int(np.sum(s > max(A.shape) * np.finfo(float).eps * max(s.max(initial=0.0), 1.0) * 1e3))
    return Vt[rank:].T


def _rotation_rows(G_vecR: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Jacobians ``(B, 3, n)`` of the camera-frame tangents ``phi`` of ``B`` rotations ``R`` ``(B, 3, 3)`` from those
    of their ``vec(R)`` ``(B, 9, n)`` (column-major): ``dR = [phi] R`` -> ``[phi] = dR R^T``."""
    B, _, n = G_vecR.shape
    dR = G_vecR.transpose(0, 2, 1).reshape(B, n, 3, 3).transpose(0, 1, 3, 2)  # column-major vec -> (B, n, 3, 3)
    W = dR @ R[:, None].transpose(0, 1, 3, 2)
    return 0.5 * np.stack([W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0], W[..., 1, 0] - W[..., 0, 1]], axis=1)


def fit_covariance(program, x, p, points, *, equality_constraints: bool = True) -> FitUncertainty:
    """The covariance of the reported quantities of ``program`` at its solution ``x``.

    Parameters
    ----------
    program : Program
        Its data terms (:attr:`~ancsh.solvers.program.Program.data_blocks`) are the noise sources.
    x : (n,) float64
        The solution (a stationary point of ``|r|^2`` within the constraints).
    p : (P,) float64
        The program's parameters (:meth:`~ancsh.solvers.program.Program.pack`) of the last solve.
    points : (M,) float64
        Effective number of points per part in the data terms (``(sum w)^2 / sum w^2``).
    equality_constraints : bool
        Restrict to the null space of the program's equalities (exact joints).

    Returns
    -------
    FitUncertainty
        ``"unavailable"`` when the residuals are not finite or there are no more residual
        components than free variables; ``"singular"`` with infinite variances where ``H`` is singular.
    """
    t0 = time.perf_counter()
    st = program.key.structure
    M, K = st.num_parts, st.num_joints
    points = np.asarray(points, dtype=np.float64).reshape(M)
    x = np.asarray(x, dtype=np.float64).ravel()
    r, J, Jg, out, G = program.linearisation(x, p)
    n = x.size

    def unavailable(msg):
        u = FitUncertainty.unavailable(msg, M, K)
        return replace(u, points=points, time_s=time.perf_counter() - t0)

    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
        return unavailable("non-finite residuals or Jacobian at the solution")
    Z = np.eye(n)
    if equality_constraints and program.num_equalities:
        Z = _null_space(Jg, n)
    Hr = Z.T @ (J.T @ J) @ Z
    lam, V = np.linalg.eigh(0.5 * (Hr + Hr.T))
    good = lam > _RELATIVE_NULL * max(lam.max(initial=0.0), np.finfo(float).tiny)
    free = int(good.sum())
    blocks = program.data_blocks
    observed = float(sum(b.residual_dims * points[b.part] for b in blocks))
    if not blocks or observed <= free:
        return unavailable(f"{observed:.0f} residual components for {free} free variables")
    dof = observed / (observed - free)
    L = float(program.params.value(np.asarray(p, dtype=np.float64).ravel(), "L"))
    meat = np.zeros((n, n))  # independent residuals: variance v / n of a part's mean
    meat_corr = np.zeros((n, n))  # per unit within-part correlation rho: v (1 - 1 / n) more
    noise = np.full(M, np.nan)
    for b in blocks:
        if points[b.part] <= 0:
            continue
        Jb = J[b.rows]
        v = dof * float(r[b.rows] @ r[b.rows]) / b.residual_dims  # variance of one normalised residual component
        JtJ = Jb.T @ Jb
        meat += (v / points[b.part]) * JtJ
        meat_corr += (v * max(1.0 - 1.0 / points[b.part], 0.0)) * JtJ
        if np.isnan(noise[b.part]):
            noise[b.part] = L * np.sqrt(v)
    Vg = V[:, good]
    Hinv = (Vg / lam[good]) @ Vg.T
    null = Z @ V[:, ~good]

    # -- propagate to the reported quantities ----------------------------------------------------
    poses = G[: 13 * (M + 1)].reshape(M + 1, 13, n)  # parts, then the object pose: vec(R), t, s rows
    R = out[: 13 * (M + 1)].reshape(M + 1, 13)[:, :9].reshape(M + 1, 3, 3).transpose(0, 2, 1)  # column-major vec
    Gq = np.concatenate([np.concatenate([_rotation_rows(poses[:, :9], R), poses[:, 9:]], axis=1).reshape(-1, n),
                         G[13 * (M + 1) :]])  # axes (3K), pivots (3K), states (K)
    A = Gq @ Z @ Hinv  # reported quantities per unit of the reduced gradient
    B = Z.T
    status, message = "ok", f"Gauss-Newton covariance over {free} free variables, {observed:.0f} residual components"
    leak = np.zeros(Gq.shape[0], dtype=bool)
    if null.shape[1]:
        leak = np.linalg.norm(Gq @ null, axis=1) > _NULL_LEAK * (np.linalg.norm(Gq, axis=1) + 1e-300)
        if np.any(leak):
            status = "singular"
            message = f"{null.shape[1]} direction(s) undetermined by the data; {int(leak.sum())} quantities unbounded"
    blocks_white = _blocks(A @ (B @ meat @ B.T) @ A.T, leak, M, K)
    blocks_corr = _blocks(A @ (B @ meat_corr @ B.T) @ A.T, leak, M, K)
    correlated = FitUncertainty(status, "covariance per unit within-part correlation", *blocks_corr, noise, points)
    return FitUncertainty(status, message, *blocks_white, noise, points, time_s=time.perf_counter() - t0,
                          correlated=correlated)


def _blocks(cov: np.ndarray, leak: np.ndarray, M: int, K: int) -> tuple:
    """``(parts (M, 7, 7), object (7, 7), states (K, K), axes (K, 3, 3), pivots (K, 3, 3))`` of the
    covariance of the stacked reported quantities; rows in ``leak`` unbounded (``inf`` variance)."""
    if np.any(leak):
        cov = cov.copy()
        cov[leak, :] = 0.0
        cov[:, leak] = 0.0
        cov[leak, leak] = np.inf
    o = 7 * M
    a0, p0, s0 = o + 7, o + 7 + 3 * K, o + 7 + 6 * K
    return _diagonal_blocks(cov, 0, M, 7), cov[o : o + 7, o : o + 7], cov[s0 : s0 + K, s0 : s0 + K], \
        _diagonal_blocks(cov, a0, K, 3), _diagonal_blocks(cov, p0, K, 3)


def _diagonal_blocks(cov: np.ndarray, start: int, count: int, size: int) -> np.ndarray:
    """``(count, size, size)``: the diagonal blocks of ``cov`` from row/column ``start`` on."""
    idx = start + size * np.arange(count)[:, None] + np.arange(size)
    return cov[idx[:, :, None], idx[:, None, :]]


def effective_points(weights) -> float:
    """Kish's effective sample size ``(sum w)^2 / sum w^2`` of non-negative weights (0 when empty)."""
    w = np.asarray(weights, dtype=np.float64)
    s2 = float(w @ w)
    return float(w.sum() ** 2 / s2) if s2 > 0 else 0.0
