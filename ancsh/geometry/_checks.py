"""Input checks shared by the whole package: arrays, rotations, generators and configuration scalars.

Every check raises ``ValueError`` naming the argument and what was expected (``check_generator``
raises ``TypeError``, as for any wrong-typed argument; see ``docs/ARCHITECTURE.md``).
"""

from __future__ import annotations

import numpy as np


def as_array(value, name: str, shape: tuple, *, finite: bool = True) -> np.ndarray:
    """Convert ``value`` to a float64 array and check its shape.

    Parameters
    ----------
    value : array_like
        The input.
    name : str
        Argument name used in the error message.
    shape : tuple
        Expected shape; ``None`` entries match any size.
    finite : bool
        Reject NaN and infinite entries.

    Raises
    ------
    ValueError
        Naming ``name``, the expected and the actual shape.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a numeric array of shape {_fmt(shape)}, got {type(value).__name__}") from exc
    if arr.ndim != len(shape) or any(e is not None and e != a for e, a in zip(shape, arr.shape)):
        raise ValueError(f"{name}: expected shape {_fmt(shape)}, got {arr.shape}")
    if finite and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    return arr


def as_points(value, name: str, *, min_points: int = 0, finite: bool = True) -> np.ndarray:
    """Check ``value`` is an ``(N, 3)`` float64 point array with ``N >= min_points``."""
    pts = as_array(value, name, (None, 3), finite=finite)
    if pts.shape[0] < min_points:
        raise ValueError(f"{name}: need at least {min_points} points, got {pts.shape[0]}")
    return pts


def as_unit_vector(value, name: str, *, tol: float = 1e-6, normalize: bool = False) -> np.ndarray:
    """Check ``value`` is a unit 3-vector (or normalise it when ``normalize``)."""
    v = as_array(value, name, (3,))
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        raise ValueError(f"{name}: zero vector cannot be a direction")
    if normalize:
        return v / n
    if abs(n - 1.0) > tol:
        raise ValueError(f"{name}: expected a unit vector, got norm {n:.6g}")
    return v


def as_rotation(value, name: str, *, tol: float = 1e-6) -> np.ndarray:
    """Check ``value`` is a ``(3, 3)`` rotation matrix (orthonormal, det +1)."""
    R = as_array(value, name, (3, 3))
    err = np.abs(R.T @ R - np.eye(3)).max()
    if err > tol or np.linalg.det(R) < 0:
        raise ValueError(f"{name}: not a rotation matrix (|R^T R - I| = {err:.3g}, det = {np.linalg.det(R):.3g})")
    return R


def check_generator(rng, name: str = "rng") -> np.random.Generator:
    """Accept a ``numpy.random.Generator`` or an int seed; reject anything else."""
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        return np.random.default_rng(int(rng))
    raise TypeError(f"{name}: expected numpy.random.Generator or int seed, got {type(rng).__name__}")


def check_bool(value, name: str) -> bool:
    """Check ``value`` is a bool (``numpy.bool_`` too; not ``0``/``1``)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name}: expected a bool, got {value!r}")
    return bool(value)


def check_int(value, name: str, *, minimum: int | None = None) -> int:
    """Check ``value`` is an integer (not a bool, not a float such as ``2.7`` or ``3.0``) ``>= minimum``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name}: expected an integer{'' if minimum is None else f' >= {minimum}'}, got {value!r}")
    if minimum is not None and value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def check_number(value, name: str, *, minimum: float | None = None, maximum: float | None = None,
                 lower_open: bool = False) -> float:
    """Check ``value`` is a finite real number (not a bool) in ``[minimum, maximum]``.

    Parameters
    ----------
    lower_open : bool
        Exclude ``minimum`` itself (``(minimum, maximum]``).
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value):
        raise ValueError(f"{name}: expected a finite number, got {value!r}")
    if minimum is not None and (value < minimum or (lower_open and value == minimum)):
        if maximum is not None:
            interval = f"{'(' if lower_open else '['}{minimum}, {maximum}]"
            raise ValueError(f"{name}: expected a number in {interval}, got {value!r}")
        if minimum == 0:
            raise ValueError(f"{name}: expected a {'positive' if lower_open else 'non-negative'} number, got {value!r}")
        raise ValueError(f"{name}: expected a number {'>' if lower_open else '>='} {minimum}, got {value!r}")
    if maximum is not None and value > maximum:
        lo = "" if minimum is None else f"{'(' if lower_open else '['}{minimum}, "
        raise ValueError(f"{name}: expected a number {'in ' + lo if lo else '<= '}{maximum}{']' if lo else ''}, got {value!r}")
    return float(value)


def check_positive(value, name: str) -> float:
    """Check ``value`` is a positive finite number."""
    return check_number(value, name, minimum=0.0, lower_open=True)


def check_choice(value, name: str, choices: tuple):
    """Check ``value`` is one of ``choices``."""
    if value not in choices:
        raise ValueError(f"{name}: expected one of {tuple(choices)}, got {value!r}")
    return value


def _fmt(shape: tuple) -> str:
    return "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
