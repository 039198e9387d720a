"""The oracle provider: ground-truth correspondences of a frame with controlled corruption.

Solvers can be compared before any network exists by feeding them the exact ANCSH ground
truth of a frame (:class:`~ancsh.model.canonical.AncshGroundTruth`) corrupted in known,
independent ways. Each knob of :class:`Corruption` changes one thing only:

``npcs_sigma``
    i.i.d. Gaussian noise on every NPCS coordinate, standard deviation in NPCS units (a
    part's tight box has unit diagonal in its NPCS).
``npcs_warp``
    A systematic per-part error: the NPCS of part ``j`` are mapped ``c -> (I + E_j) c``
    with the entries of ``E_j`` i.i.d. ``N(0, npcs_warp^2)`` (dimensionless). Networks
    make spatially correlated errors that do not average out over points; this models them.
``outlier_fraction``
    That fraction of all points (chosen uniformly, without replacement) gets NPCS drawn
    uniformly in the cube ``[-0.5, 0.5]^3`` (which contains every NPCS box); labels stay.
``flip_radius``, ``flip_fraction``
    Label flips near part boundaries: a point whose nearest point of another part (in the
    observed cloud) is closer than ``flip_radius`` (NAOCS units, i.e. relative to the
    object's size) is, with probability ``flip_fraction``, relabelled to that part. Its
    NPCS are *re-expressed* in the new part's NPCS through the new part's ground-truth
    pose (``c = T_cam_npcs[new]^-1 p``): the coordinate the network would predict if it
    believed the point rigidly attached to the wrong part. Near a joint this is a small
    error, far from it a large one -- as for a real segmentation mistake.
``axis_sigma_deg``
    Each NAOCS joint axis is rotated about a uniformly random direction perpendicular to
    it by an angle ``N(0, axis_sigma_deg^2)`` degrees (so the axis angle error is the
    absolute value of that Gaussian).
``pivot_sigma``
    Each NAOCS joint pivot moves by an isotropic Gaussian offset (standard deviation
    ``pivot_sigma`` NAOCS units per direction) in the plane perpendicular to the true axis,
    so the line-to-line distance (without axis noise) is Rayleigh distributed.
``naocs_sigma``
    NPCS -> NAOCS parameters: every ``npcs_scale[j]`` is multiplied by
    ``exp(N(0, naocs_sigma^2))`` and every ``npcs_translation[j]`` gets i.i.d.
    ``N(0, naocs_sigma^2)`` NAOCS units per coordinate.

Order: label flips, then outliers, then NPCS noise and warp on the non-outlier points.
Each knob draws from its own random stream (spawned from the caller's generator), so
switching one knob on or off never changes the draws of another.

Presets (:data:`CORRUPTION_PRESETS`): ``"none"``, ``"low"``, ``"realistic"``, ``"high"``.
The paper reports no per-point NPCS errors, so ``"realistic"`` is calibrated on what it does
report: per-part fitting (its NPCS baseline) of ``"realistic"`` correspondences of rendered
procedural test frames gives mean rotation errors of 2.4-3.1 deg on the large parts and
3.4-10.6 deg on the thin ones (``docs/results/fit_benchmark.md``: eyeglasses 3.1 / 8.4 / 10.6,
laptop 2.8 / 3.4, oven 2.5 / 3.1, drawer 2.4-2.8 deg), the range of Table 1's NPCS row
(1.1-11.6 deg; eyeglasses 4.0 / 7.7 / 7.2, laptop 11.6 / 4.4, oven 1.3 / 3.5, drawer 1.8-3.5).
Joint axes get 1.5 deg and pivots 0.01 object units of noise, the size of ANCSH's
camera-space joint errors in Table 2 (0.5-2.3 deg, 0.008-0.024). Translation errors come out
lower than Table 1's.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from types import MappingProxyType

import numpy as np

from ...geometry._checks import check_generator, check_number
from ..types import Correspondences, Observation

__all__ = ["CORRUPTION_PRESETS", "Corruption", "OracleProvider", "OracleSample", "corrupt_ground_truth"]


@dataclass(frozen=True)
class Corruption:
    """How to corrupt ground-truth correspondences (see the module docstring for each knob).

    Attributes
    ----------
    npcs_sigma : float
        NPCS Gaussian noise, NPCS units, ``>= 0``.
    npcs_warp : float
        Per-part linear NPCS distortion, dimensionless, ``>= 0``.
    outlier_fraction : float
        Fraction of points with random NPCS, in ``[0, 1]``.
    flip_radius : float
        Boundary distance below which labels may flip, NAOCS units, ``>= 0``.
    flip_fraction : float
        Probability that an eligible point flips, in ``[0, 1]``.
    axis_sigma_deg : float
        Joint axis angle noise, degrees, ``>= 0``.
    pivot_sigma : float
        Joint pivot offset noise, NAOCS units, ``>= 0``.
    naocs_sigma : float
        NPCS -> NAOCS scale (relative) and translation (NAOCS units) noise, ``>= 0``.
    """

    npcs_sigma: float = 0.0
    npcs_warp: float = 0.0
    outlier_fraction: float = 0.0
    flip_radius: float = 0.0
    flip_fraction: float = 1.0
    axis_sigma_deg: float = 0.0
    pivot_sigma: float = 0.0
    naocs_sigma: float = 0.0

    def __post_init__(self):
        for f in fields(self):
            fraction = f.name in ("outlier_fraction", "flip_fraction")
            v = check_number(getattr(self, f.name), f.name, minimum=0.0, maximum=1.0 if fraction else None)
            object.__setattr__(self, f.name, v)

    @classmethod
    def preset(cls, name: str) -> "Corruption":
        """The named preset: one of :data:`CORRUPTION_PRESETS` (``"none"``, ``"low"``, ...)."""
        try:
            return CORRUPTION_PRESETS[name]
        except (KeyError, TypeError):
            raise ValueError(f"corruption: unknown preset {name!r}; choose from {sorted(CORRUPTION_PRESETS)}") from None

    @property
    def is_clean(self) -> bool:
        """``True`` when no knob corrupts anything."""
        return (
            self.npcs_sigma == 0 and self.npcs_warp == 0 and self.outlier_fraction == 0
            and (self.flip_radius == 0 or self.flip_fraction == 0) and self.axis_sigma_deg == 0
            and self.pivot_sigma == 0 and self.naocs_sigma == 0
        )


CORRUPTION_PRESETS = MappingProxyType({
    "none": Corruption(),
    "low": Corruption(npcs_sigma=0.01, npcs_warp=0.01, outlier_fraction=0.02, flip_radius=0.01, flip_fraction=0.5,
                      axis_sigma_deg=0.5, pivot_sigma=0.005, naocs_sigma=0.005),
    "realistic": Corruption(npcs_sigma=0.03, npcs_warp=0.03, outlier_fraction=0.05, flip_radius=0.02,
                            flip_fraction=0.5, axis_sigma_deg=1.5, pivot_sigma=0.01, naocs_sigma=0.01),
    "high": Corruption(npcs_sigma=0.06, npcs_warp=0.06, outlier_fraction=0.15, flip_radius=0.04, flip_fraction=0.5,
                       axis_sigma_deg=4.0, pivot_sigma=0.03, naocs_sigma=0.02),
})


@dataclass(frozen=True)
class OracleSample:
    """Corrupted correspondences plus a record of what was corrupted.

    Attributes
    ----------
    correspondences : Correspondences
    true_labels : (N,) int64
        Ground-truth part labels.
    flipped : (N,) bool
        Points whose label was flipped.
    outliers : (N,) bool
        Points whose NPCS were replaced by random coordinates.
    """

    correspondences: Correspondences
    true_labels: np.ndarray
    flipped: np.ndarray
    outliers: np.ndarray

    @property
    def clean(self) -> np.ndarray:
        """``(N,)`` bool: points neither flipped nor outliers (noise aside)."""
        return ~(self.flipped | self.outliers)


def _as_corruption(corruption) -> Corruption:
    if isinstance(corruption, Corruption):
        return corruption
    if isinstance(corruption, str):
        return Corruption.preset(corruption)
    raise ValueError(f"corruption: expected a Corruption or a preset name, got {type(corruption).__name__}")


def _ground_truth_of(source):
    """The AncshGroundTruth of a frame-like object, or ``source`` itself."""
    if hasattr(source, "T_cam_npcs") and hasattr(source, "npcs"):
        return source
    for name in ("gt", "ground_truth", "ancsh"):
        gt = getattr(source, name, None)
        if gt is not None and hasattr(gt, "T_cam_npcs"):
            return gt
    raise ValueError(
        f"frame_or_ground_truth: expected an AncshGroundTruth or a frame carrying one (.gt), got {type(source).__name__}"
    )


def corrupt_ground_truth(gt, points_cam, corruption, rng, *, joint_limits=None) -> OracleSample:
    """Corrupt the correspondences of one frame.

    Parameters
    ----------
    gt : AncshGroundTruth
        Ground truth of the frame (``N`` points, ``M`` parts, ``K`` joints).
    points_cam : (N, 3) float64
        The frame's points in the camera frame (metres), in the order of ``gt``.
    corruption : Corruption or str
        The corruption or a preset name.
    rng : numpy.random.Generator or int
    joint_limits : (K, 2) float64, optional
        Joint limits relative to rest, passed through to the correspondences.

    Returns
    -------
    OracleSample
    """
    corruption = _as_corruption(corruption)
    rng = check_generator(rng)
    exact = Correspondences.from_ground_truth(gt, joint_limits=joint_limits)
    points = np.asarray(points_cam, dtype=np.float64)
    N, M, K = exact.num_points, exact.num_parts, exact.num_joints
    if points.shape != (N, 3):
        raise ValueError(f"points_cam: expected shape ({N}, 3) to match the ground truth, got {points.shape}")
    s_flip, s_out, s_noise, s_warp, s_axis, s_pivot, s_naocs = rng.spawn(7)

    labels = exact.part_labels.copy()
    npcs = exact.npcs.copy()
    flipped = np.zeros(N, dtype=bool)
    outliers = np.zeros(N, dtype=bool)
    object_scale = float(gt.T_cam_naocs.scale)  # metres per NAOCS unit

    # 1. label flips near part boundaries
    if corruption.flip_radius > 0 and corruption.flip_fraction > 0 and M > 1 and N > 0:
        from scipy.spatial import cKDTree

        true = exact.part_labels
        best_d = np.full(N, np.inf)
        best_part = np.full(N, -1)
        for b in range(M):
            on_b = true == b
            if not on_b.any():
                continue
            tree = cKDTree(points[on_b])
            others = ~on_b
            d, _ = tree.query(points[others])
            idx = np.nonzero(others)[0]
            closer = d < best_d[idx]
            best_d[idx[closer]] = d[closer]
            best_part[idx[closer]] = b
        eligible = best_d / object_scale < corruption.flip_radius
        flipped = eligible & (s_flip.random(N) < corruption.flip_fraction)
        for b in np.unique(best_part[flipped]):
            sel = flipped & (best_part == b)
            labels[sel] = b
            npcs[sel] = gt.T_cam_npcs[int(b)].inverse().apply(points[sel])

    # 2. outliers
    n_out = int(round(corruption.outlier_fraction * N))
    if n_out:
        idx = s_out.choice(N, size=n_out, replace=False)
        outliers[idx] = True
        npcs[idx] = s_out.uniform(-0.5, 0.5, size=(n_out, 3))

    # 3. NPCS noise and per-part warp on the remaining points
    keep = ~outliers
    if corruption.npcs_warp > 0:
        E = s_warp.normal(0.0, corruption.npcs_warp, size=(M, 3, 3))
        for j in range(M):
            sel = keep & (labels == j)
            npcs[sel] = npcs[sel] + npcs[sel] @ E[j].T
    if corruption.npcs_sigma > 0:
        npcs[keep] = npcs[keep] + s_noise.normal(0.0, corruption.npcs_sigma, size=(int(keep.sum()), 3))

    # 4. joint parameters in NAOCS
    axes = exact.joint_axes_naocs.copy()
    pivots = exact.joint_pivots_naocs.copy()
    if K and corruption.axis_sigma_deg > 0:
        for k in range(K):
            axes[k] = _tilt(axes[k], np.radians(s_axis.normal(0.0, corruption.axis_sigma_deg)), s_axis)
    if K and corruption.pivot_sigma > 0:
        for k in range(K):
            u = exact.joint_axes_naocs[k]
            e1, e2 = _perpendicular_basis(u)
            a, b = s_pivot.normal(0.0, corruption.pivot_sigma, size=2)
            pivots[k] = pivots[k] + a * e1 + b * e2

    # 5. NPCS -> NAOCS
    scale = exact.npcs_scale.copy()
    trans = exact.npcs_translation.copy()
    if corruption.naocs_sigma > 0:
        scale = scale * np.exp(s_naocs.normal(0.0, corruption.naocs_sigma, size=M))
        trans = trans + s_naocs.normal(0.0, corruption.naocs_sigma, size=(M, 3))

    corr = Correspondences(
        part_labels=labels, npcs=npcs, npcs_scale=scale, npcs_translation=trans,
        joint_types=exact.joint_types, joint_parents=exact.joint_parents, joint_children=exact.joint_children,
        joint_axes_naocs=axes, joint_pivots_naocs=pivots, weights=None, npcs_extents=exact.npcs_extents,
        joint_limits=exact.joint_limits,
    )
    return OracleSample(corr, exact.part_labels.copy(), flipped, outliers)


def _perpendicular_basis(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane perpendicular to the unit vector ``u``."""
    helper = np.eye(3)[int(np.argmin(np.abs(u)))]
    e1 = np.cross(u, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


def _tilt(u: np.ndarray, angle: float, rng: np.random.Generator) -> np.ndarray:
    """``u`` rotated by ``angle`` (radians) towards a uniformly random perpendicular direction."""
    e1, e2 = _perpendicular_basis(u)
    phi = rng.uniform(0.0, 2.0 * np.pi)
    w = np.cos(phi) * e1 + np.sin(phi) * e2
    v = np.cos(angle) * u + np.sin(angle) * w
    return v / np.linalg.norm(v)


class OracleProvider:
    """Ground-truth correspondences of one frame, corrupted by :class:`Corruption`.

    Implements :class:`~ancsh.solvers.types.CorrespondenceProvider`.

    Parameters
    ----------
    frame_or_ground_truth : AncshGroundTruth or frame
        The ground truth, or a frame carrying it as ``.gt`` (and its points as ``.points``).
    corruption : Corruption or str
        A corruption or a preset name (default ``"none"``: the exact ground truth).
    rng : numpy.random.Generator or int
        Randomness of the corruption; every call to :meth:`correspond` draws anew.
    joint_limits : (K, 2) float64, optional
        Joint limits relative to rest, passed through to the correspondences.

    Examples
    --------
    >>> provider = OracleProvider(frame, "realistic", rng=0)        # doctest: +SKIP
    >>> corr = provider.correspond(Observation(frame.points))       # doctest: +SKIP
    """

    def __init__(self, frame_or_ground_truth, corruption="none", rng=0, *, joint_limits=None):
        self.ground_truth = _ground_truth_of(frame_or_ground_truth)
        self.corruption = _as_corruption(corruption)
        self._rng = check_generator(rng)
        self.joint_limits = joint_limits

    def sample(self, observation: Observation) -> OracleSample:
        """Corrupted correspondences of ``observation`` with the record of what was corrupted."""
        if not isinstance(observation, Observation):
            raise ValueError(f"observation: expected an Observation, got {type(observation).__name__}")
        n = len(self.ground_truth.part_labels)
        if observation.num_points != n:
            raise ValueError(
                f"observation: has {observation.num_points} points but the ground truth has {n}; "
                "the oracle needs the frame's own points"
            )
        return corrupt_ground_truth(self.ground_truth, observation.points_cam, self.corruption, self._rng,
                                    joint_limits=self.joint_limits)

    def correspond(self, observation: Observation) -> Correspondences:
        """Corrupted ground-truth correspondences of ``observation`` (the frame's points)."""
        return self.sample(observation).correspondences

    def __repr__(self) -> str:
        return f"OracleProvider(corruption={self.corruption})"
