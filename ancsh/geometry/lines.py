"""Lines in 3D: distance between infinite lines and angles between axes.

A line is a point ``p`` on it and a direction ``u`` (normalised here; only its zero
length is an error). Joint axes are lines whose direction sign carries no meaning, so
:func:`axis_angle_error` treats ``u`` and ``-u`` as the same axis.
"""

from __future__ import annotations

import numpy as np

from ._checks import as_array, as_unit_vector

# Below this |sin(angle)| two lines count as parallel: the skew-line formula would divide
# by a cross product whose direction is mostly rounding error. Switching formulas here
# changes the distance by at most |p2 - p1| * 1e-8.
_PARALLEL_SIN = 1e-8


def line_distance(p1, u1, p2, u2) -> float:
    """Minimum distance between the infinite lines ``p1 + s u1`` and ``p2 + t u2``.

    Parameters
    ----------
    p1, p2 : (3,) float64
        A point on each line (same frame, e.g. metres in the camera frame).
    u1, u2 : (3,) float64
        Line directions, any non-zero length, either sign.

    Returns
    -------
    float
        The distance, in the units of the points; for (anti-)parallel lines, the distance
        from ``p2`` to the first line.
    """
    p1 = as_array(p1, "p1", (3,))
    p2 = as_array(p2, "p2", (3,))
    u1 = as_unit_vector(u1, "u1", normalize=True)
    u2 = as_unit_vector(u2, "u2", normalize=True)
    w = p2 - p1
    n = np.cross(u1, u2)
    sin = float(np.linalg.norm(n))
    if sin < _PARALLEL_SIN:
        return float(np.linalg.norm(w - (w @ u1) * u1))
    return float(abs(w @ n) / sin)


def direction_angle(u1, u2) -> float:
    """Angle between two directions in ``[0, pi]`` radians (sign matters: ``u`` vs ``-u`` is pi)."""
    u1 = as_unit_vector(u1, "u1", normalize=True)
    u2 = as_unit_vector(u2, "u2", normalize=True)
    return float(np.arctan2(np.linalg.norm(np.cross(u1, u2)), u1 @ u2))


def axis_angle_error(u1, u2) -> float:
    """Angle between two axes in ``[0, pi/2]`` radians, treating ``u`` and ``-u`` as one axis."""
    u1 = as_unit_vector(u1, "u1", normalize=True)
    u2 = as_unit_vector(u2, "u2", normalize=True)
    return float(np.arctan2(np.linalg.norm(np.cross(u1, u2)), abs(u1 @ u2)))
