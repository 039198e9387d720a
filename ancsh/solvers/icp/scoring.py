"""The symmetric score of an articulated fit (:class:`FitScorer`): observed points far from the posed model, plus
model surface the camera should see where nothing was observed; the multi-start search and the category
refinement (:mod:`ancsh.solvers.icp.category`) compare fits by it. The same score at the scale of the sensor noise
(:func:`sensor_noise`, :func:`noise_tolerance`, :func:`depth_support`) judges whether a fit explains the depth and
whether a rival fit explains it as well (:func:`paired_z`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...geometry._checks import check_generator, check_positive
from .template import ModelSurface

__all__ = ["DepthSupport", "FitScore", "FitScorer", "depth_support", "noise_tolerance", "paired_z", "sensor_noise"]


@dataclass(frozen=True)
class FitScore:
    """How well a posed model explains observed points (lower :attr:`score` is better).

    Attributes
    ----------
    score : float
        ``observed + unobserved``, each in ``[0, 1]`` (see :class:`FitScorer`).
    observed : float
        Truncated mean of ``(d / gate)^2`` over the observed points' distances ``d`` to the model.
    unobserved : float
        Fraction of the model surface the camera would see (inside the observed field of view)
        with no observed point within reach.
    inlier_ratio : float
        Fraction of observed points within the gate.
    rmse : float
        RMS distance of those inliers (metres; ``inf`` without inliers).
    part_observed : (M,) float64
        :attr:`observed` over the points whose closest model point lies on part ``j`` (NaN
        where no point does).
    part_unobserved : (M,) float64
        :attr:`unobserved` over part ``j``'s visible surface (NaN where none is visible).
    """

    score: float
    observed: float
    unobserved: float
    inlier_ratio: float
    rmse: float
    part_observed: np.ndarray
    part_unobserved: np.ndarray
    distances: np.ndarray | None = field(default=None, repr=False, compare=False)


class FitScorer:
    """The symmetric score of articulated ICP, for one set of observed points.

    A posed model is scored by the truncated mean of ``(d / gate)^2`` over the observed points'
    distances ``d`` to the model (visible surface), plus the fraction of the model surface the
    camera would see at the estimate (inside the observed field of view) that has no observed
    point within ``max(gate, 3 x point spacing)``. The second half penalises model surface where
    nothing was observed (e.g. a drawer pulled out whose observed front is explained equally well
    by its side walls). Both halves lie in ``[0, 1]``; lower is better. Estimates of different
    models (e.g. a template at several scales) are compared on the same terms when scored with
    the same scorer and gate.

    Parameters
    ----------
    points_cam : (N, 3) float64
        Observed points (metres, camera frame, ``z > 0``), ``N >= 1``.
    rng : numpy.random.Generator or int
        Seeds the model surface samples (300 per part, drawn once per surface).
    """

    def __init__(self, points_cam, rng=0):
        from ...geometry._checks import as_points

        self.points = as_points(points_cam, "points_cam", min_points=1)
        if np.any(self.points[:, 2] <= 0):
            raise ValueError("points_cam: every point must be in front of the camera (z > 0)")
        self.rng = check_generator(rng)
        uv = self.points[:, :2] / self.points[:, 2:3]
        margin = 0.02 * (uv.max(axis=0) - uv.min(axis=0))
        self.fov = (uv.min(axis=0) - margin, uv.max(axis=0) + margin)  # observed field of view (x/z, y/z)
        self._tree = None
        self._spacing = None
        self._samples: dict = {}

    def _tree_spacing(self):
        if self._tree is None:
            from scipy.spatial import cKDTree

            self._tree = cKDTree(self.points)
            n = len(self.points)
            self._spacing = float(np.median(self._tree.query(self.points, k=2)[0][:, 1])) if n > 1 else 0.0
        return self._tree, self._spacing

    def samples(self, surface: ModelSurface):
        """Surface samples of ``surface`` (drawn once per surface and kept)."""
        key = id(surface)
        hit = self._samples.get(key)
        if hit is None or hit[0] is not surface:
            hit = (surface, surface.sample(300, self.rng, normals=True))
            self._samples[key] = hit
        return hit[1]

    def score(self, surface: ModelSurface, T_cam_parts, gate: float) -> FitScore:
        """Score ``surface``'s model posed at ``T_cam_parts`` (``(M,)`` Sim3) with gate ``gate`` (metres)."""
        gate = check_positive(gate, "gate")
        M = surface.model.num_parts
        cp = surface.closest(self.points, T_cam_parts, visible=True)
        d = cp.distances
        inl = d <= gate
        rmse = float(np.sqrt(np.mean(d[inl] ** 2))) if inl.any() else float("inf")
        e = np.minimum(d / gate, 1.0) ** 2
        tree, spacing = self._tree_spacing()
        reach = max(gate, 3.0 * spacing)
        pts, labels, normals = self.samples(surface)
        seen, seen_labels = surface.visible_samples(T_cam_parts, pts, labels, normals, return_labels=True)
        if seen.shape[0]:
            uv = seen[:, :2] / seen[:, 2:3]
            keep = np.all((uv >= self.fov[0]) & (uv <= self.fov[1]), axis=1)
            seen, seen_labels = seen[keep], seen_labels[keep]
        missed = ~np.isfinite(tree.query(seen, distance_upper_bound=reach)[0]) if seen.shape[0] else np.zeros(0, bool)
        back = float(np.mean(missed)) if seen.shape[0] else 1.0
        part_obs = np.array([float(np.mean(e[cp.labels == j])) if np.any(cp.labels == j) else np.nan for j in range(M)])
        part_back = np.array([float(np.mean(missed[seen_labels == j])) if np.any(seen_labels == j) else np.nan
                              for j in range(M)])
        obs = float(np.mean(e))
        return FitScore(obs + back, obs, back, float(inl.mean()), rmse, part_obs, part_back, d)


# ---------------------------------------------------------------------------------------------
# support at the scale of the sensor noise
# ---------------------------------------------------------------------------------------------
NOISE_NEIGHBOURS = 10
"""Neighbours of each point in the plane fit of :func:`sensor_noise` (the smallest count whose plane is well posed
with a few points to spare)."""

GAUSS_MAD = 1.4826
"""Standard deviation over median absolute deviation of a normal distribution."""

NOISE_SIGMAS = 3.0
"""A point lies on the model when within this many standard deviations of the sensor noise (99.7% of normal noise)."""


def sensor_noise(points_cam, neighbours: int = NOISE_NEIGHBOURS) -> float:
    """Robust standard deviation of the depth noise, estimated from the points themselves.

    Each point's distance to the least-squares plane of its ``neighbours`` nearest neighbours measures the noise
    (on a smooth surface); ``1.4826 x`` the median of these distances (robust to edges and corners, a minority of the
    points), over ``sqrt(1 + 1 / neighbours)`` (the plane's own error at the point), is returned.

    Parameters
    ----------
    points_cam : (N, 3) array_like
        Observed points (metres), ``N > neighbours``.
    neighbours : int
        ``>= 3``.
    """
    from scipy.spatial import cKDTree

    from ...geometry._checks import as_points, check_int

    check_int(neighbours, "neighbours", minimum=3)
    pts = as_points(points_cam, "points_cam", min_points=neighbours + 1)
    _, idx = cKDTree(pts).query(pts, k=neighbours + 1)
    nb = pts[idx[:, 1:]]
    centre = nb.mean(axis=1)
    X = nb - centre[:, None, :]
    _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", X, X))
    normal = vecs[:, :, 0]
    dist = np.abs(np.einsum("ni,ni->n", pts - centre, normal))
    return GAUSS_MAD * float(np.median(dist)) / np.sqrt(1.0 + 1.0 / neighbours)


def noise_tolerance(points_cam, floor: float) -> tuple[float, float]:
    """``(tolerance, sigma)``: :data:`NOISE_SIGMAS` x :func:`sensor_noise` of ``points_cam``, at least ``floor``
    (metres; the solver's own resolution, e.g. its convergence tolerance, and the float32 resolution of the
    closest-point queries at the points' range, whichever is larger)."""
    floor = check_positive(floor, "floor")
    pts = np.asarray(points_cam, dtype=np.float64)
    sigma = sensor_noise(pts)
    single = float(np.finfo(np.float32).eps) * float(np.max(np.abs(pts)))
    return max(NOISE_SIGMAS * sigma, floor, NOISE_SIGMAS * single), sigma


@dataclass(frozen=True)
class DepthSupport:
    """How well a posed model explains observed points at the scale of the sensor noise.

    Attributes
    ----------
    tolerance : float
        Distance (metres) within which a point lies on the model (:func:`noise_tolerance`).
    share : float
        Fraction of the observed points within ``tolerance`` of the model's visible surface.
    unobserved : float
        Fraction of the model surface the camera would see (inside the observed field of view) with no observed
        point within reach (:class:`FitScorer`).
    score : float
        ``mean(min(d / tolerance, 1)^2) + unobserved`` (lower is better).
    errors : (N,) float64
        ``min(d / tolerance, 1)^2`` per observed point (below 1: on the model; :func:`paired_z`).
    """

    tolerance: float
    share: float
    unobserved: float
    score: float
    errors: np.ndarray = field(repr=False, compare=False)

    def explains(self, share: float) -> bool:
        """At least ``share`` of the points on the model and at most ``1 - share`` of its visible surface unobserved."""
        return self.share >= share and self.unobserved <= 1.0 - share


def depth_support(scorer: FitScorer, surface: ModelSurface, T_cam_parts, tolerance: float) -> DepthSupport:
    """:class:`DepthSupport` of ``surface``'s model posed at ``T_cam_parts`` against ``scorer``'s points."""
    sc = scorer.score(surface, T_cam_parts, tolerance)
    e = np.minimum(sc.distances / tolerance, 1.0) ** 2
    return DepthSupport(float(tolerance), sc.inlier_ratio, sc.unobserved, float(np.mean(e)) + sc.unobserved, e)


def paired_z(better: DepthSupport, worse: DepthSupport) -> float:
    """How many standard errors ``worse`` puts fewer of the same points on the model than ``better`` (McNemar's
    test): ``(b - c) / sqrt(b + c)`` with ``b`` the points within the tolerance of ``better`` only and ``c`` those
    within that of ``worse`` only (0 when there are none). Only the share within the tolerance counts, so
    differences far below the sensor noise (one fit converged a little further) do not."""
    if worse.errors.shape != better.errors.shape or better.errors.size < 2:
        raise ValueError(f"worse: expected the support of the same (at least 2) points as better, got "
                         f"{worse.errors.shape} errors against {better.errors.shape}")
    on_better, on_worse = better.errors < 1.0, worse.errors < 1.0
    b, c = int(np.sum(on_better & ~on_worse)), int(np.sum(on_worse & ~on_better))
    return 0.0 if b + c == 0 else (b - c) / np.sqrt(b + c)
