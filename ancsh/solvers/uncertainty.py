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

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..geometry._checks import check_number

__all__ = ["FitUncertainty", "INFLATED_QUANTITIES", "Inflation", "INFLATION_PATH", "SigmaMap", "UNCERTAINTY_STATUSES",
           "block_sigma", "effective_points", "first_measured_inflation", "fit_covariance", "inflation_for",
           "load_inflation_table", "maps_from_json", "maps_to_json", "tracked_provider"]

UNCERTAINTY_STATUSES = ("ok", "singular", "unavailable")

#: Measured inflation factors per provider and category (written by ``ancsh bench uncertainty --install``).
INFLATION_PATH = Path(__file__).resolve().parents[1] / "weights" / "uncertainty_inflation.json"

_RELATIVE_NULL = 1e-10  # eigenvalues of the reduced H below this fraction of the largest: undetermined
_NULL_LEAK = 1e-6  # a quantity whose gradient has this share along an undetermined direction is unbounded


@dataclass(frozen=True)
class SigmaMap:
    """How one quantity's raw standard deviation becomes the reported one.

    ``sigma' = sqrt((k * sigma**p * s**(1 - p))**2 + b**2)``, where ``sigma`` is the block's raw
    RMS standard deviation per coordinate (:func:`block_sigma`, after the within-part correlation)
    and the block's covariance is multiplied by ``(sigma' / sigma)**2`` (its shape is kept).

    - ``p = 1, b = 0``: a single factor ``k`` on the standard deviations;
    - ``p < 1``: a power that compresses the spread of the raw ``sigma`` across fits around the
      reference ``s`` (``sigma' = k s`` at ``sigma = s``): fits whose raw ``sigma`` is small get a
      larger factor, when the raw spread over-states how much the fits' accuracy differs;
    - ``p > 1``: expands that spread -- the fits' errors differ more than their raw ``sigma`` say
      (measured for several learned quantities, up to ``p`` near 3). A map is measured over the
      calibration fits' range of raw ``sigma`` (for the learned provider about 3x between the 5th
      and 95th percentiles); far outside it, a power is an extrapolation;
    - ``b > 0``: a floor ``b`` (the quantity's unit) that ``sigma'`` does not go below -- an error
      that more or better points do not remove.

    Attributes
    ----------
    factor : float
        ``k >= 0``.
    power : float
        ``p`` in ``[0, 4]``.
    reference : float
        ``s > 0``, the quantity's unit (radians, metres, metres per NPCS unit; a joint state's unit);
        matters only when ``p != 1``.
    floor : float
        ``b >= 0``, the quantity's unit.
    """

    factor: float = 1.0
    power: float = 1.0
    reference: float = 1.0
    floor: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "factor", check_number(self.factor, "factor", minimum=0.0))
        object.__setattr__(self, "power", check_number(self.power, "power", minimum=0.0, maximum=4.0))
        object.__setattr__(self, "reference", check_number(self.reference, "reference", minimum=0.0, lower_open=True))
        object.__setattr__(self, "floor", check_number(self.floor, "floor", minimum=0.0))

    @property
    def is_factor(self) -> bool:
        """Only the factor (``p = 1``, ``b = 0``)."""
        return self.power == 1.0 and self.floor == 0.0

    @property
    def is_identity(self) -> bool:
        return self.is_factor and self.factor == 1.0

    def ratio(self, sigma) -> np.ndarray:
        """``sigma' / sigma`` for raw standard deviations ``sigma`` (array, the quantity's unit).

        Where ``sigma`` is ``0`` or not finite (an exactly determined or an unbounded quantity) the
        ratio is ``k``: a zero variance stays zero and an infinite one infinite."""
        sigma = np.asarray(sigma, dtype=np.float64)
        if self.is_factor:
            return np.full(sigma.shape, self.factor)
        usable = np.isfinite(sigma) & (sigma > 0.0)
        x = np.where(usable, sigma, self.reference) / self.reference
        r = self.factor * x ** (self.power - 1.0)
        if self.floor > 0.0:
            r = np.sqrt(r**2 + (self.floor / (x * self.reference)) ** 2)
        return np.where(usable, r, self.factor)

    def to_json(self):
        """The stored form: a plain number for a single factor, else ``{factor, power, reference, floor}``."""
        if self.is_factor:
            return self.factor
        return {"factor": self.factor, "power": self.power, "reference": self.reference, "floor": self.floor}

    @classmethod
    def from_json(cls, value, name: str = "value") -> "SigmaMap":
        """From :meth:`to_json`'s forms (a number: the old single-factor entries)."""
        if isinstance(value, SigmaMap):
            return value
        if isinstance(value, dict):
            unknown = set(value) - {"factor", "power", "reference", "floor"}
            if unknown:
                raise ValueError(f"{name}: unknown keys {sorted(unknown)} (known: factor, power, reference, floor)")
            return cls(**{k: float(v) for k, v in value.items()})
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
            raise ValueError(f"{name}: expected a factor or a mapping of factor, power, reference, floor; got {value!r}")
        return cls(factor=float(value))


def maps_from_json(value, name: str):
    """One quantity's map(s): a :class:`SigmaMap` from :meth:`SigmaMap.from_json`'s forms, or a tuple of them
    from a non-empty sequence (one per part or joint); errors name ``name`` (and the index)."""
    if isinstance(value, (list, tuple)):
        if not value:
            raise ValueError(f"{name}: expected a map or a non-empty sequence of maps (one per part or joint)")
        return tuple(SigmaMap.from_json(m, f"{name}[{i}]") for i, m in enumerate(value))
    return SigmaMap.from_json(value, name)


def maps_to_json(maps):
    """The stored form of :func:`maps_from_json`'s result: a number or mapping, or a list of them."""
    return [m.to_json() for m in maps] if isinstance(maps, tuple) else maps.to_json()


#: The quantities an :class:`Inflation` maps (the :class:`SigmaMap` fields).
INFLATED_QUANTITIES = ("rotation", "translation", "scale", "joint_state", "joint_axis", "joint_pivot")


@dataclass(frozen=True)
class Inflation:
    """How the raw standard deviations of each kind of quantity are inflated (identity = raw).

    Attributes
    ----------
    rotation, translation, scale : SigmaMap or tuple of SigmaMap
        Part pose blocks: one map for every part, or one per part (in the category's part order;
        the parts of one object can be calibrated very differently, e.g. a washing machine's body
        and door). Each block's covariance scales by its ratio squared, cross terms by the products
        of ratios. The object pose (the root part's rotation, the NAOCS origin and scale) takes the
        root part's maps. A number ``k`` stands for ``SigmaMap(factor=k)``.
    joint_state, joint_axis, joint_pivot : SigmaMap or tuple of SigmaMap
        Joint blocks: one map for every joint, or one per joint.
    correlation : float
        In ``[0, 1]``: the correlation ``rho`` of the residuals within a part, applied before the
        maps. A part's ``n`` points then count as ``n / (1 + (n - 1) rho)`` independent ones (the
        design effect of equicorrelated errors): with ``rho n >> 1`` its pose uncertainty no longer
        shrinks with more points, as for a network's spatially correlated NPCS errors.
    source : str
        Where the maps come from (``"raw"``, ``"learned/laptop"``, ...).
    """

    rotation: SigmaMap | tuple = SigmaMap()
    translation: SigmaMap | tuple = SigmaMap()
    scale: SigmaMap | tuple = SigmaMap()
    joint_state: SigmaMap | tuple = SigmaMap()
    joint_axis: SigmaMap | tuple = SigmaMap()
    joint_pivot: SigmaMap | tuple = SigmaMap()
    correlation: float = 0.0
    source: str = "raw"

    def __post_init__(self):
        for q in INFLATED_QUANTITIES:
            object.__setattr__(self, q, maps_from_json(getattr(self, q), q))
        object.__setattr__(self, "correlation", check_number(self.correlation, "correlation", minimum=0.0, maximum=1.0))

    @property
    def is_identity(self) -> bool:
        return self.correlation == 0.0 and all(m.is_identity for q in INFLATED_QUANTITIES for m in self._all(q))

    def _all(self, quantity: str) -> tuple:
        v = getattr(self, quantity)
        return v if isinstance(v, tuple) else (v,)

    def map_for(self, quantity: str, index: int, count: int) -> SigmaMap:
        """The map of ``quantity`` (from :data:`INFLATED_QUANTITIES`) for part or joint ``index`` of ``count``.

        Raises
        ------
        ValueError
            When per-part (per-joint) maps do not match ``count``.
        """
        v = getattr(self, quantity)
        if not isinstance(v, tuple):
            return v
        if len(v) != count:
            raise ValueError(f"inflation.{quantity}: {len(v)} per-part/joint maps ({self.source}) for {count} "
                             f"{'parts' if quantity in ('rotation', 'translation', 'scale') else 'joints'}")
        return v[index]

    def to_json(self) -> dict:
        """``{quantity: number | {factor, power, reference, floor} | [one of those per part or joint],
        "correlation": rho, "source": str}`` (the stored form of :meth:`from_json`, with the source)."""
        return {**{q: maps_to_json(getattr(self, q)) for q in INFLATED_QUANTITIES},
                "correlation": self.correlation, "source": self.source}

    @classmethod
    def from_json(cls, entry: dict, source: str = "raw", *, name: str = "inflation") -> "Inflation":
        """From a stored entry (``{quantity: number | mapping | list, "correlation": rho, ...}``; other keys
        ignored; a number is the single factor of the first stored tables)."""
        if not isinstance(entry, dict):
            raise ValueError(f"{name}: expected a mapping of quantities, got {type(entry).__name__}")
        kw = {q: maps_from_json(entry[q], f"{name}.{q}") for q in INFLATED_QUANTITIES if q in entry}
        if "correlation" in entry:
            kw["correlation"] = float(entry["correlation"])
        return cls(**kw, source=source)


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
    """Jacobian ``(3, n)`` of the camera-frame tangent ``phi`` from that of ``vec(R)`` ``(9, n)`` (column-major):
    ``dR = [phi] R`` -> ``[phi] = dR R^T``."""
    n = G_vecR.shape[1]
    dR = G_vecR.T.reshape(n, 3, 3).transpose(0, 2, 1)  # column-major vec -> (n, 3, 3)
    W = dR @ R.T
    return 0.5 * np.stack([W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0], W[:, 1, 0] - W[:, 0, 1]])


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
    rows = []
    for j in range(M + 1):  # parts, then the object pose
        b = 13 * j
        R = out[b : b + 9].reshape(3, 3, order="F")
        rows += [_rotation_rows(G[b : b + 9], R), G[b + 9 : b + 13]]
    rows.append(G[13 * (M + 1) :])  # axes (3K), pivots (3K), states (K)
    Gq = np.concatenate(rows)
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
    parts = np.stack([cov[7 * j : 7 * j + 7, 7 * j : 7 * j + 7] for j in range(M)])
    o = 7 * M
    obj = cov[o : o + 7, o : o + 7]
    a0, p0, s0 = o + 7, o + 7 + 3 * K, o + 7 + 6 * K
    axes = np.stack([cov[a0 + 3 * k : a0 + 3 * k + 3, a0 + 3 * k : a0 + 3 * k + 3] for k in range(K)]) if K else np.zeros((0, 3, 3))
    piv = np.stack([cov[p0 + 3 * k : p0 + 3 * k + 3, p0 + 3 * k : p0 + 3 * k + 3] for k in range(K)]) if K else np.zeros((0, 3, 3))
    return parts, obj, cov[s0 : s0 + K, s0 : s0 + K], axes, piv


def effective_points(weights) -> float:
    """Kish's effective sample size ``(sum w)^2 / sum w^2`` of non-negative weights (0 when empty)."""
    w = np.asarray(weights, dtype=np.float64)
    s2 = float(w @ w)
    return float(w.sum() ** 2 / s2) if s2 > 0 else 0.0


# ------------------------------------------------------------------------------------------------
# measured inflation factors
# ------------------------------------------------------------------------------------------------
def load_inflation_table(path=None) -> dict:
    """The stored table ``{"providers": {provider: {category: {quantity: factor}}}, ...}`` (empty without a file).

    Raises
    ------
    ValueError
        When the file exists but is not such a table (naming the file).
    """
    path = INFLATION_PATH if path is None else Path(path)
    if not path.is_file():
        return {"providers": {}}
    try:
        table = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a readable inflation table ({exc})") from exc
    if not isinstance(table, dict) or not isinstance(table.get("providers"), dict):
        raise ValueError(f"{path}: expected an object with a 'providers' mapping")
    return table


_TABLE_CACHE: dict = {}  # path -> ((mtime_ns, size), table): inflation_for runs on every tracked frame


def _read_table(path: Path) -> dict:
    """:func:`load_inflation_table`, parsed once per version of the file (by modification time and size);
    for reading only (callers that change the table load their own copy)."""
    try:
        st = path.stat()
    except OSError:
        return {"providers": {}}
    stamp = (st.st_mtime_ns, st.st_size)
    cached = _TABLE_CACHE.get(path)
    if cached is None or cached[0] != stamp:
        cached = (stamp, load_inflation_table(path))
        _TABLE_CACHE[path] = cached
    return cached[1]


def inflation_for(provider: str, category: str, *, weights_sha256: str | None = None, path=None) -> Inflation:
    """The measured :class:`Inflation` of ``provider`` (``"learned"``, ``"oracle-realistic"``, ...)
    on ``category``; identity (``source="raw"``) when none was measured, or when the factors were
    measured with network weights (their recorded ``weights_sha256``) other than ``weights_sha256``."""
    entry = _read_table(INFLATION_PATH if path is None else Path(path))["providers"].get(provider, {}).get(category)
    if entry is None or ("weights_sha256" in entry and entry["weights_sha256"] != weights_sha256):
        return Inflation()
    return Inflation.from_json(entry, source=f"{provider}/{category}", name=f"{path or INFLATION_PATH}: {provider}.{category}")


def tracked_provider(provider: str, source: str) -> str:
    """The inflation-table provider of warm tracked frames of one source: ``"learned-tracked-carried"``, ...
    (``provider`` the single-frame one, ``source`` a :class:`~ancsh.tracking.tracker.TrackedFrame` source)."""
    return f"{provider}-tracked-{source}"


def first_measured_inflation(providers, category: str, *, weights_sha256: str | None = None, path=None) -> Inflation:
    """The :func:`inflation_for` of the first of ``providers`` (``None`` entries skipped) measured for
    ``category`` (and these weights); identity when none was."""
    for provider in providers:
        if provider is None:
            continue
        inflation = inflation_for(provider, category, weights_sha256=weights_sha256, path=path)
        if not inflation.is_identity:
            return inflation
    return Inflation()
