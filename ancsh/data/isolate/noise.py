"""Sensor noise on isolation's grid: the points averaged over their neighbours on the same surface, and how far a
plane's inliers may lie from it at each depth (:func:`smooth_grid`, :func:`noise_sigma`, :func:`plane_points`).

A depth sensor's noise grows with distance (about quadratically for structured light and stereo: a few millimetres at
1 m, centimetres at 4-5 m). Normals from neighbours a few grid spacings apart, and a plane's inliers within a fixed
distance, work near the camera and fail far from it: on rendered scenes with the dataset's noise model at 4-5 m, the
floor's normals scattered so widely that no support plane was removed and three objects came back as one 7 m segment.
Where the noise measured in the image itself (no sensor model is assumed) is larger than a plane's fixed
tolerance, plane search therefore runs on the smoothed points, with a tolerance that follows that noise
(:func:`plane_points`); elsewhere on the points as measured."""

from __future__ import annotations

import numpy as np

from ..noise import surface_mean

__all__ = ["NOISE_BINS", "SMOOTH_RADIUS", "TOLERANCE_SIGMAS", "noise_sigma", "plane_points", "smooth_grid"]

#: The smoothing window is ``2 r + 1`` grid pixels wide (its neighbours within a depth jump of the centre count).
SMOOTH_RADIUS = 2

#: A point lies on a plane when it is within this many of its own noise's standard deviations of it.
TOLERANCE_SIGMAS = 3.0

#: The noise is measured in up to this many depth bins (quantiles of the grid's depths), each of at least
#: :data:`MIN_BIN_PIXELS` grid pixels.
NOISE_BINS = 8

MIN_BIN_PIXELS = 200


def smooth_grid(P: np.ndarray, gv: np.ndarray, jump: np.ndarray, radius: int = SMOOTH_RADIUS) -> tuple[np.ndarray, np.ndarray]:
    """The grid points averaged over their ``(2 radius + 1)^2`` window, counting only neighbours whose depth is within
    ``jump`` of the centre's (the same surface: depth edges stay sharp).

    Parameters
    ----------
    P : (h, w, 3) float64
        Grid points (camera frame, metres; zeros where ``gv`` is False).
    gv : (h, w) bool
        Grid pixels with depth.
    jump : (h, w) float64
        Per pixel, the depth difference (metres) beyond which a neighbour is another surface.
    radius : int

    Returns
    -------
    smoothed : (h, w, 3) float64
        ``P`` where ``gv`` is False.
    counts : (h, w) int64
        Neighbours averaged per pixel (itself included; 0 off ``gv``).
    """
    return surface_mean(P, P[..., 2], gv, jump, radius)


def noise_sigma(P: np.ndarray, smoothed: np.ndarray, counts: np.ndarray, gv: np.ndarray) -> np.ndarray:
    """Per grid pixel, the standard deviation (metres) of the sensor's depth noise at its depth, measured in the image:
    the depth residual of each point from its smoothed one (:func:`smooth_grid`; a robust standard deviation per depth
    bin, corrected for the point's own share of the mean), interpolated over depth. Curved surfaces and edges inflate
    the residual a little, so it errs high where the image has few flat surfaces.

    Returns ``(h, w)`` float64 (0 off ``gv``, and everywhere when fewer than :data:`MIN_BIN_PIXELS` pixels have a full
    enough window)."""
    out = np.zeros(gv.shape)
    use = gv & (counts >= 9)
    if np.count_nonzero(use) < MIN_BIN_PIXELS:
        return out
    z = P[..., 2][use]
    n = counts[use].astype(np.float64)
    residual = np.abs(z - smoothed[..., 2][use]) / np.sqrt(1.0 - 1.0 / n)
    bins = int(min(NOISE_BINS, max(1, z.size // MIN_BIN_PIXELS)))
    centres, sigmas = [], []
    for part in np.array_split(np.argsort(z), bins):
        centres.append(float(np.median(z[part])))
        sigmas.append(1.4826 * float(np.median(residual[part])))
    out[gv] = np.interp(P[..., 2][gv], centres, sigmas)
    return out


def plane_points(P: np.ndarray, gv: np.ndarray, jump: np.ndarray, minimum: float) -> tuple[np.ndarray, np.ndarray]:
    """The grid points plane search runs on, and each one's tolerance from a plane it is on (module docstring).

    Where the noise measured at a pixel's depth (:func:`noise_sigma`) keeps :data:`TOLERANCE_SIGMAS` of it within
    ``minimum`` metres (a sensor near its objects, or depth a sensor already smoothed), the point stays as measured:
    averaging it would blur edges the depth does not jump across (a lid against the riser behind it). Where it does
    not, the point is its smoothed one (:func:`smooth_grid`), and its tolerance that many of the mean's standard
    deviations (``1 / sqrt(n)`` of the noise for a mean of ``n``).

    Returns ``(points, tolerance)``: ``(h, w, 3)`` camera frame, metres, and ``(h, w)`` metres (``minimum`` where the
    points stay as measured)."""
    smoothed, counts = smooth_grid(P, gv, jump)
    sigma = noise_sigma(P, smoothed, counts, gv)
    noisy = gv & (TOLERANCE_SIGMAS * sigma > minimum)
    points = np.where(noisy[..., None], smoothed, P)
    tolerance = np.full(gv.shape, float(minimum))
    tolerance[noisy] = np.maximum(minimum, TOLERANCE_SIGMAS * sigma[noisy] / np.sqrt(np.maximum(counts[noisy], 1)))
    return points, tolerance
