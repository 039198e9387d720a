"""Types shared by every fitting method: observations, correspondences, providers, results.

Conventions (see ``docs/ARCHITECTURE.md``):

- A part pose ``T_cam_npcs[j]`` is a :class:`~ancsh.geometry.transforms.Sim3` mapping the
  part's NPCS coordinates to the camera frame (metres): ``p_cam = s R c + t``.
- NPCS -> NAOCS is ``g = npcs_scale[j] * c + npcs_translation[j]`` (paper Sec. 4.1, 4.2).
- Joint ``k`` connects ``joint_parents[k] -> joint_children[k]``; its axis and pivot are given in
  NAOCS at the rest state. Joint states are reported relative to rest (radians / metres).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Protocol, runtime_checkable

import numpy as np

from ..geometry._checks import as_array, as_points
from ..geometry.boxes import OrientedBox
from ..geometry.transforms import Sim3
from ..model.articulated import JointType, joint_tree_order, joint_tree_root

__all__ = [
    "Correspondences",
    "CorrespondenceProvider",
    "FitResult",
    "FitStatus",
    "JointType",
    "Observation",
]


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.flags.writeable = False
    return a


def _as_int_vector(value, name: str, n: int | None) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim != 1 or (n is not None and arr.shape[0] != n):
        raise ValueError(f"{name}: expected shape ({'N' if n is None else n},), got {arr.shape}")
    if arr.size and not (np.issubdtype(arr.dtype, np.integer) or np.all(np.equal(np.mod(arr, 1), 0))):
        raise ValueError(f"{name}: expected integer values")
    return arr.astype(np.int64)


@dataclass(frozen=True)
class Observation:
    """What the camera saw: points in the camera frame.

    Attributes
    ----------
    points_cam : (N, 3) float64
        Observed points in the camera frame, metres. ``N`` may be 0 (a fit then reports
        :attr:`FitStatus.TOO_FEW_POINTS`); NaN/inf are rejected.
    metadata : dict
        Optional per-point or per-frame extras (e.g. ``{"pixels": (N, 2)}``), not used by solvers.
    """

    points_cam: np.ndarray
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "points_cam", _frozen(as_points(self.points_cam, "points_cam")))
        if not isinstance(self.metadata, dict):
            raise ValueError(f"metadata: expected a dict, got {type(self.metadata).__name__}")

    @property
    def num_points(self) -> int:
        return int(self.points_cam.shape[0])


@dataclass(frozen=True)
class Correspondences:
    """Per-point canonical coordinates and per-part / per-joint canonical parameters.

    Attributes
    ----------
    part_labels : (N,) int64
        Part index ``0..M-1`` of each observed point.
    npcs : (N, 3) float64
        Each point's coordinates in its part's NPCS.
    npcs_scale : (M,) float64
        ``G_s``: NPCS -> NAOCS scale per part, positive.
    npcs_translation : (M, 3) float64
        ``G_t``: NPCS -> NAOCS translation per part.
    joint_types : tuple of JointType, length K
    joint_parents, joint_children : (K,) int64
        Part indices joined by each joint; the joints form one tree over the ``M`` parts.
    joint_axes_naocs : (K, 3) float64
        Unit joint axes in NAOCS (rest state).
    joint_pivots_naocs : (K, 3) float64
        A point on each revolute axis in NAOCS (for prismatic joints a reference point).
    weights : (N,) float64, optional
        Non-negative per-point weights (e.g. segmentation confidence); ``None`` = all 1.
    npcs_extents : (M, 3) float64, optional
        Tight-box extents of each part in NPCS (amodal boxes); ``None`` = the box of the
        observed NPCS points (NOCS style).
    joint_limits : (K, 2) float64, optional
        ``[lower, upper]`` joint limits relative to the rest state (radians / metres);
        ``-inf`` / ``inf`` for unlimited; ``None`` = no limits.
    """

    part_labels: np.ndarray
    npcs: np.ndarray
    npcs_scale: np.ndarray
    npcs_translation: np.ndarray
    joint_types: tuple = ()
    joint_parents: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    joint_children: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    joint_axes_naocs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    joint_pivots_naocs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    weights: np.ndarray | None = None
    npcs_extents: np.ndarray | None = None
    joint_limits: np.ndarray | None = None

    def __post_init__(self):
        npcs = as_points(self.npcs, "npcs")
        n = npcs.shape[0]
        labels = _as_int_vector(self.part_labels, "part_labels", n)
        scale = as_array(self.npcs_scale, "npcs_scale", (None,))
        m = scale.shape[0]
        if m < 1:
            raise ValueError("npcs_scale: need at least one part")
        if np.any(scale <= 0):
            raise ValueError(f"npcs_scale: must be positive, got {scale}")
        trans = as_array(self.npcs_translation, "npcs_translation", (m, 3))
        if labels.size and (labels.min() < 0 or labels.max() >= m):
            raise ValueError(f"part_labels: expected values in 0..{m - 1}, got range {labels.min()}..{labels.max()}")
        weights = None
        if self.weights is not None:
            weights = as_array(self.weights, "weights", (n,))
            if np.any(weights < 0):
                raise ValueError("weights: must be non-negative")
        extents = None
        if self.npcs_extents is not None:
            extents = as_array(self.npcs_extents, "npcs_extents", (m, 3))
            if np.any(extents < 0):
                raise ValueError("npcs_extents: must be non-negative")

        # --- joints ---------------------------------------------------------
        try:
            jtypes = tuple(JointType(t) for t in self.joint_types)
        except ValueError:
            raise ValueError(
                f"joint_types: expected 'revolute' or 'prismatic' entries, got {list(self.joint_types)!r}"
            ) from None
        k = len(jtypes)
        parents = _as_int_vector(self.joint_parents, "joint_parents", k)
        children = _as_int_vector(self.joint_children, "joint_children", k)
        axes = as_array(self.joint_axes_naocs, "joint_axes_naocs", (k, 3))
        pivots = as_array(self.joint_pivots_naocs, "joint_pivots_naocs", (k, 3))
        if k:
            norms = np.linalg.norm(axes, axis=1)
            if np.any(np.abs(norms - 1.0) > 1e-6):
                raise ValueError(f"joint_axes_naocs: expected unit vectors, got norms {np.round(norms, 6).tolist()}")
        for name, idx in (("joint_parents", parents), ("joint_children", children)):
            if idx.size and (idx.min() < 0 or idx.max() >= m):
                raise ValueError(f"{name}: expected part indices in 0..{m - 1}, got {idx.tolist()}")
        seen: dict = {}
        for j in range(k):
            if parents[j] == children[j]:
                raise ValueError(f"joint_children: joint {j} joins part {parents[j]} to itself")
            pair = frozenset((int(parents[j]), int(children[j])))
            if pair in seen:
                other = seen[pair]
                if jtypes[other] != jtypes[j]:
                    raise ValueError(
                        f"joint_types: contradictory types {jtypes[other].value!r} and {jtypes[j].value!r} "
                        f"for the joints {other} and {j} between parts {sorted(pair)}"
                    )
                raise ValueError(f"joint_children: joints {other} and {j} both join parts {sorted(pair)}")
            seen[pair] = j
        _check_tree(m, parents, children)
        limits = None
        if self.joint_limits is not None:
            limits = as_array(self.joint_limits, "joint_limits", (k, 2), finite=False)
            if np.any(np.isnan(limits)):
                raise ValueError("joint_limits: contains NaN")
            if np.any(limits[:, 0] > limits[:, 1]):
                raise ValueError(f"joint_limits: lower above upper in {limits.tolist()}")

        object.__setattr__(self, "part_labels", _frozen(labels))
        object.__setattr__(self, "npcs", _frozen(npcs))
        object.__setattr__(self, "npcs_scale", _frozen(scale))
        object.__setattr__(self, "npcs_translation", _frozen(trans))
        object.__setattr__(self, "joint_types", jtypes)
        object.__setattr__(self, "joint_parents", _frozen(parents))
        object.__setattr__(self, "joint_children", _frozen(children))
        object.__setattr__(self, "joint_axes_naocs", _frozen(axes / np.linalg.norm(axes, axis=1, keepdims=True) if k else axes))
        object.__setattr__(self, "joint_pivots_naocs", _frozen(pivots))
        object.__setattr__(self, "weights", None if weights is None else _frozen(weights))
        object.__setattr__(self, "npcs_extents", None if extents is None else _frozen(extents))
        object.__setattr__(self, "joint_limits", None if limits is None else _frozen(limits))

    # --- sizes ---------------------------------------------------------------
    @property
    def num_points(self) -> int:
        return int(self.npcs.shape[0])

    @property
    def num_parts(self) -> int:
        return int(self.npcs_scale.shape[0])

    @property
    def num_joints(self) -> int:
        return len(self.joint_types)

    @property
    def root_part(self) -> int:
        """The part that is no joint's child (the base)."""
        return joint_tree_root(self.num_parts, self.joint_children)

    @property
    def topological_joints(self) -> tuple[int, ...]:
        """Joint indices ordered so that every joint's parent part is placed before it."""
        return joint_tree_order(self.num_parts, self.joint_parents, self.joint_children)

    def structure_key(self) -> tuple:
        """Hashable kinematic structure: part count, joint types and topology."""
        return (
            self.num_parts,
            tuple(t.value for t in self.joint_types),
            tuple(self.joint_parents.tolist()),
            tuple(self.joint_children.tolist()),
        )

    def with_weights(self, weights) -> "Correspondences":
        """A copy with new per-point ``weights`` ``(N,)``."""
        return Correspondences(
            self.part_labels, self.npcs, self.npcs_scale, self.npcs_translation, self.joint_types,
            self.joint_parents, self.joint_children, self.joint_axes_naocs, self.joint_pivots_naocs,
            weights, self.npcs_extents, self.joint_limits,
        )

    @classmethod
    def from_ground_truth(cls, gt, *, joint_limits=None) -> "Correspondences":
        """Exact correspondences from an ``ancsh.model.canonical.AncshGroundTruth``.

        ``joint_limits`` ``(K, 2)`` (relative to rest) is optional; the ground truth has none.
        """
        extents = getattr(gt, "npcs_extents", None)
        if extents is None:
            # Amodal NPCS boxes: the camera boxes mapped back into NPCS (same extents / scale).
            boxes = getattr(gt, "boxes_cam", ())
            if len(boxes) == len(gt.T_cam_npcs) and len(boxes):
                extents = np.array([b.extents / T.scale for b, T in zip(boxes, gt.T_cam_npcs)])
        return cls(
            part_labels=gt.part_labels,
            npcs=gt.npcs,
            npcs_scale=gt.npcs_scale,
            npcs_translation=gt.npcs_translation,
            joint_types=tuple(gt.joint_types),
            joint_parents=gt.joint_parents,
            joint_children=gt.joint_children,
            joint_axes_naocs=gt.joint_axes_naocs,
            joint_pivots_naocs=gt.joint_pivots_naocs,
            npcs_extents=extents,
            joint_limits=joint_limits,
        )


def _check_tree(m: int, parents: np.ndarray, children: np.ndarray) -> None:
    k = parents.shape[0]
    if k != m - 1:
        raise ValueError(f"joint_parents: {m} parts need {m - 1} joints to form a tree, got {k}")
    dup = sorted({int(c) for c in children if np.count_nonzero(children == c) > 1})
    if dup:
        raise ValueError(f"joint_children: part(s) {dup} have more than one parent joint (not a tree)")
    roots = [j for j in range(m) if j not in set(children.tolist())]
    if len(roots) != 1:
        raise ValueError(f"joint_children: expected exactly one root part, got {roots}")
    reached, frontier = {roots[0]}, [roots[0]]
    while frontier:
        p = frontier.pop()
        for c in children[parents == p].tolist():
            if c not in reached:
                reached.add(c)
                frontier.append(c)
    if len(reached) != m:
        raise ValueError(f"joint_parents: parts {sorted(set(range(m)) - reached)} are not connected to the root")


@runtime_checkable
class CorrespondenceProvider(Protocol):
    """Anything that turns an observation into correspondences (network, oracle, CAD + ICP)."""

    def correspond(self, observation: Observation) -> Correspondences: ...


class FitStatus(str, Enum):
    """Outcome of a fit; only ``SUCCESS`` means the result satisfied the solver's tests."""

    SUCCESS = "success"
    MAX_ITER = "max_iter"
    INFEASIBLE = "infeasible"
    NUMERICAL_FAILURE = "numerical_failure"
    TOO_FEW_POINTS = "too_few_points"
    DEGENERATE = "degenerate"
    INVALID_INPUT = "invalid_input"
    IMPLAUSIBLE_SIZE = "implausible_size"  # the fitted object's size is outside its category's range
    TOO_FEW_INLIERS = "too_few_inliers"  # too small a share of the points agrees with the fit
    LARGE_RESIDUAL = "large_residual"  # the points lie far from the fitted parts (far above validation frames)
    NO_OBJECT = "no_object"  # no candidate segment of the image passed the checks: the object is not found
    NOT_THIS_CATEGORY = "not_this_category"  # the fitted segment does not look like an object of the category
    OUT_OF_VIEW = "out_of_view"  # the segment found without a mask or hint runs out of the image: only part is seen
    JOINT_AT_LIMIT = "joint_at_limit"  # the data put a joint past the category's range (ancsh.solvers.limits)
    AMBIGUOUS = "ambiguous"  # another, distinct fit explains the points as well (e.g. a symmetric object turned)


@dataclass(frozen=True)
class FitResult:
    """An articulated fit: part poses, camera-space joints, amodal boxes and solver diagnostics.

    Attributes
    ----------
    formulation, solver : str
        Names from :data:`ancsh.solvers.FORMULATIONS` and the backend (``"ipopt"``, ``"lsq"``, ...).
    T_cam_npcs : tuple of Sim3, length M
        Part poses, NPCS -> camera (rotation, translation in metres, scale). Empty on failure
        without an estimate.
    joint_axes_cam : (K, 3) float64
        Unit joint axes in the camera frame (NaN when unknown).
    joint_pivots_cam : (K, 3) float64
        Pivot points in the camera frame, metres (NaN when unknown).
    joint_states : (K,) float64
        Joint states relative to rest: signed radians (revolute), metres (prismatic).
    boxes_cam : tuple of OrientedBox, length M
        Amodal part boxes in the camera frame.
    status : FitStatus
    message : str
    cost_per_term : dict[str, float]
        Final energy of each term (sum of squared residuals).
    iterations : int
    max_constraint_violation : float
        Largest violation of the exact joint constraints and limits (0 for unconstrained fits).
    inliers : (N,) bool
        Points used by the final solve.
    time_s : float
        Wall time of the whole fit, seconds.
    uncertainty : FitUncertainty or None
        Covariances and standard deviations of the part poses, object pose and joints
        (:mod:`ancsh.solvers.uncertainty`; raw Jacobian values unless a caller inflated them);
        ``None`` for a fit without an estimate, with ``FitConfig(uncertainty=False)``, or refined
        afterwards by a category template's ``base`` candidate; an ``articulated`` refinement
        (:func:`ancsh.solvers.icp.category.refine_fit`) carries the template ICP's covariance.
    canonical : CanonicalParameters or None
        The canonical parameters the part poses and joints were solved with
        (:class:`~ancsh.solvers.terms.CanonicalParameters`: the correspondences', moved by the solved
        offsets where the formulation frees them, ``FitConfig.naocs_prior_weight > 0``), so that the
        object pose and joint states reproduce the part poses through forward kinematics (tracking's
        predictions); ``None`` for a fit without an estimate or from elsewhere (a category template).
    """

    formulation: str
    solver: str
    T_cam_npcs: tuple
    joint_axes_cam: np.ndarray
    joint_pivots_cam: np.ndarray
    joint_states: np.ndarray
    boxes_cam: tuple
    status: FitStatus
    message: str = ""
    cost_per_term: dict = field(default_factory=dict)
    iterations: int = 0
    max_constraint_violation: float = 0.0
    inliers: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    time_s: float = 0.0
    uncertainty: object = None
    canonical: object = None

    def __post_init__(self):
        if self.uncertainty is not None:
            from .uncertainty import FitUncertainty

            if not isinstance(self.uncertainty, FitUncertainty):
                raise ValueError(f"uncertainty: expected a FitUncertainty or None, got {type(self.uncertainty).__name__}")
        if self.canonical is not None:
            from .terms import CanonicalParameters

            if not isinstance(self.canonical, CanonicalParameters):
                raise ValueError(f"canonical: expected CanonicalParameters or None, got {type(self.canonical).__name__}")
        if not isinstance(self.status, FitStatus):
            object.__setattr__(self, "status", FitStatus(self.status))
        for p in self.T_cam_npcs:
            if not isinstance(p, Sim3):
                raise ValueError(f"T_cam_npcs: expected Sim3 entries, got {type(p).__name__}")
        for b in self.boxes_cam:
            if not isinstance(b, OrientedBox):
                raise ValueError(f"boxes_cam: expected OrientedBox entries, got {type(b).__name__}")
        object.__setattr__(self, "T_cam_npcs", tuple(self.T_cam_npcs))
        object.__setattr__(self, "boxes_cam", tuple(self.boxes_cam))
        object.__setattr__(self, "joint_axes_cam", _frozen(as_array(self.joint_axes_cam, "joint_axes_cam", (None, 3), finite=False)))
        object.__setattr__(self, "joint_pivots_cam", _frozen(as_array(self.joint_pivots_cam, "joint_pivots_cam", (None, 3), finite=False)))
        object.__setattr__(self, "joint_states", _frozen(as_array(self.joint_states, "joint_states", (None,), finite=False)))
        object.__setattr__(self, "inliers", _frozen(np.asarray(self.inliers, dtype=bool)))

    @property
    def ok(self) -> bool:
        """``True`` when :attr:`status` is :attr:`FitStatus.SUCCESS`."""
        return self.status == FitStatus.SUCCESS

    @property
    def num_parts(self) -> int:
        return len(self.T_cam_npcs)

    @classmethod
    def failure(
        cls, status: FitStatus, message: str, *, formulation: str, solver: str, num_joints: int = 0,
        num_points: int = 0, time_s: float = 0.0,
    ) -> "FitResult":
        """A result without an estimate (NaN joints, no poses, no boxes)."""
        nan3 = np.full((num_joints, 3), np.nan)
        return cls(
            formulation=formulation, solver=solver, T_cam_npcs=(), joint_axes_cam=nan3,
            joint_pivots_cam=nan3.copy(), joint_states=np.full(num_joints, np.nan), boxes_cam=(),
            status=status, message=message, inliers=np.zeros(num_points, dtype=bool), time_s=time_s,
        )
