"""Measured inflation of the fits' raw covariances: :class:`SigmaMap` per quantity (a factor, a power or a floor,
fitted by ``ancsh bench uncertainty``), :class:`Inflation` of one provider and category, and the shipped table
(``ancsh/weights/uncertainty_inflation.json``) they are read from. Importable from
:mod:`ancsh.solvers.uncertainty` as before."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry._checks import check_number

#: Measured inflation factors per provider and category (written by ``ancsh bench uncertainty --install``).
INFLATION_PATH = Path(__file__).resolve().parents[1] / "weights" / "uncertainty_inflation.json"
_TABLE_CACHE: dict = {}  # path -> ((mtime_ns, size), table): inflation_for runs on every tracked frame


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
