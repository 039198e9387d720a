"""The typed inputs of the fitting programs: the kinematic structure, canonical parameters, start, per-part
moments, term weights and the temporal prior's previous solution, gathered in :class:`ProgramInputs`.

Plain numpy dataclasses (no CasADi): callers build them, each energy term of :mod:`ancsh.solvers.terms` fills its
CasADi parameters from them (``fill``), and :mod:`ancsh.solvers.program` packs them. Importable from
:mod:`ancsh.solvers.terms` as before."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry._checks import as_array, check_number
from ..geometry.transforms import Sim3
from ..model.articulated import JointType, joint_tree_order, joint_tree_root


# --------------------------------------------------------------------------------------------
# Kinematic structure
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class KinematicStructure:
    """Part count and joint tree (hashable; a program is built once per structure).

    Attributes
    ----------
    num_parts : int
    joint_types : tuple of str
        ``"revolute"`` / ``"prismatic"`` per joint.
    joint_parents, joint_children : tuple of int
    """

    num_parts: int
    joint_types: tuple
    joint_parents: tuple
    joint_children: tuple

    @classmethod
    def from_correspondences(cls, corr) -> "KinematicStructure":
        return cls(*corr.structure_key())

    @property
    def num_joints(self) -> int:
        return len(self.joint_types)

    @property
    def root(self) -> int:
        """The part that is no joint's child (the base)."""
        return joint_tree_root(self.num_parts, self.joint_children)

    def topological_joints(self) -> tuple[int, ...]:
        """Joints ordered so that each joint's parent part is reached before it."""
        return joint_tree_order(self.num_parts, self.joint_parents, self.joint_children)

    def is_revolute(self, k: int) -> bool:
        return self.joint_types[k] == JointType.REVOLUTE.value


# --------------------------------------------------------------------------------------------
# Typed inputs of one frame (what the terms' parameters are filled from)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CanonicalParameters:
    """The canonical (NAOCS) quantities of one object, as the programs see them.

    Attributes
    ----------
    npcs_scale : (M,) float64
        ``Gs_j`` of the NPCS -> NAOCS map ``g = Gs_j c + Gt_j``.
    npcs_translation : (M, 3) float64
        ``Gt_j`` (NAOCS units).
    joint_axes_naocs : (K, 3) float64
        Unit joint axes ``u_k`` in NAOCS.
    joint_pivots_naocs : (K, 3) float64
        Joint pivots ``q_k`` in NAOCS (rest state).
    state_reference : (K,) float64
        Centre of the window in which revolute states are reported (radians; see
        :func:`joint_state_expr`); zeros: states in ``(-pi, pi]``.
    """

    npcs_scale: np.ndarray
    npcs_translation: np.ndarray
    joint_axes_naocs: np.ndarray
    joint_pivots_naocs: np.ndarray
    state_reference: np.ndarray

    @classmethod
    def of(cls, source, joint_limits=None) -> "CanonicalParameters":
        """From anything holding ``npcs_scale``, ``npcs_translation``, ``joint_axes_naocs`` and
        ``joint_pivots_naocs`` (:class:`~ancsh.solvers.types.Correspondences`,
        :class:`~ancsh.model.canonical.CanonicalSpace`).

        Parameters
        ----------
        joint_limits : (K, 2) float64, optional
            Joint limits relative to rest; the revolute state windows are centred on them
            (default: every window centred on 0).
        """
        axes = np.asarray(source.joint_axes_naocs, dtype=np.float64).reshape(-1, 3)
        if joint_limits is None:
            ref = np.zeros(len(axes))
        else:
            ref = np.array([state_reference(lo, hi) for lo, hi in np.asarray(joint_limits, dtype=np.float64)])
        return cls(
            np.asarray(source.npcs_scale, dtype=np.float64), np.asarray(source.npcs_translation, dtype=np.float64),
            axes, np.asarray(source.joint_pivots_naocs, dtype=np.float64).reshape(-1, 3), ref,
        )

    def with_offsets(self, offsets: "CanonicalOffsets") -> "CanonicalParameters":
        """These parameters moved by a solution's canonical offsets."""
        return CanonicalParameters(
            self.npcs_scale, self.npcs_translation + offsets.npcs_translation, self.joint_axes_naocs,
            self.joint_pivots_naocs + offsets.joint_pivots_naocs, self.state_reference,
        )


@dataclass(frozen=True)
class CanonicalOffsets:
    """Solved offsets of the free canonical parameters (NAOCS units).

    Attributes
    ----------
    npcs_translation : (M, 3) float64
        ``dGt_j``.
    joint_pivots_naocs : (K, 3) float64
        ``dq_k``; zero rows for prismatic joints (their pivot is not free).
    """

    npcs_translation: np.ndarray
    joint_pivots_naocs: np.ndarray


@dataclass(frozen=True)
class ProgramStart:
    """Where a program's decision variables are zero (the linearisation point of one solve).

    Attributes
    ----------
    T_cam_npcs : tuple of Sim3, optional
        Per-part start poses (``maximal`` parameterisation).
    T_cam_naocs : Sim3, optional
        Start object pose, NAOCS -> camera of the root part, its scale the object's size in
        metres (``reduced`` parameterisation).
    """

    T_cam_npcs: tuple | None = None
    T_cam_naocs: Sim3 | None = None


@dataclass(frozen=True)
class PartMoments:
    """Moments of one part's weighted correspondences (see :func:`part_moments`, :func:`plane_moments`).

    Attributes
    ----------
    Lm : (4, 4) float64
    B : (3, 4) float64
    sqrt_c0 : float
    cbar : (3,) float64
        Weighted mean NPCS coordinate.
    pbar : (3,) float64
        Weighted mean camera point (metres).
    Lp : (13, 13) float64, optional
        Point-to-plane moments (:class:`PointToPlaneTerm`).
    """

    Lm: np.ndarray
    B: np.ndarray
    sqrt_c0: float
    cbar: np.ndarray
    pbar: np.ndarray
    Lp: np.ndarray | None = None

    @classmethod
    def zeros(cls) -> "PartMoments":
        """Moments of a part without correspondences (its terms vanish)."""
        return cls(np.zeros((4, 4)), np.zeros((3, 4)), 0.0, np.zeros(3), np.zeros(3), np.zeros((13, 13)))


@dataclass(frozen=True)
class TermWeights:
    """Weights of the weighted terms (see :class:`~ancsh.solvers.fit.FitConfig`)."""

    soft_weight: float
    soft_mu: float
    common_scale_weight: float
    naocs_prior_weight: float
    npcs_bias_weight: float = 0.0


@dataclass(frozen=True)
class PreviousSolution:
    """A prediction from previous frames, which :class:`TemporalPriorTerm` pulls a solve toward (tracking).

    Built directly (a zero-velocity prior: the last frame's solution) or by :meth:`constant_velocity`
    from the last two solutions (a constant-velocity prior: the energy penalises the change of the
    pose and joint-state velocities).

    Attributes
    ----------
    T_cam_naocs : Sim3
        Object pose, NAOCS -> camera of the root part, scale in metres per NAOCS unit
        (:attr:`~ancsh.solvers.program.Solution.T_cam_naocs` of the previous solve).
    joint_states : (K,) float64
        Joint states relative to rest (radians / metres; revolute ones within the window of
        :func:`joint_state_expr`).
    weight : float
        Non-negative weight of the pose part of the prior.
    state_weight : float, optional
        Non-negative weight of the joint-state part (default: ``weight``).
    """

    T_cam_naocs: Sim3
    joint_states: np.ndarray
    weight: float
    state_weight: float | None = None

    def __post_init__(self):
        if not isinstance(self.T_cam_naocs, Sim3):
            raise ValueError(f"T_cam_naocs: expected a Sim3, got {type(self.T_cam_naocs).__name__}")
        object.__setattr__(self, "joint_states", as_array(self.joint_states, "joint_states", (None,)))
        object.__setattr__(self, "weight", check_number(self.weight, "weight", minimum=0.0))
        sw = self.weight if self.state_weight is None else self.state_weight
        object.__setattr__(self, "state_weight", check_number(sw, "state_weight", minimum=0.0))

    @classmethod
    def constant_velocity(cls, last: "PreviousSolution", before: "PreviousSolution | None", *,
                          damping: float = 1.0, ahead: float = 1.0) -> "PreviousSolution":
        """The prediction of a constant-velocity model from the last two solutions (weights of ``last``).

        ``T_pred = dT^damping T_last`` with ``dT = T_last T_before^-1`` (camera-frame motion of the
        object between the two frames; the rotation scaled along its geodesic, the scale kept), and
        ``q_pred = q_last + damping (q_last - q_before)``. Without ``before`` it is ``last``
        (zero velocity). ``ahead`` predicts that many intervals ``before -> last`` past ``last``
        (the exponent becomes ``damping * ahead``): e.g. ``2 / 3`` for the second frame after
        ``last`` when ``before`` is 3 frames before ``last`` (tracking between network frames).

        Parameters
        ----------
        last, before : PreviousSolution
            The solutions of the last and the second-to-last frame.
        damping : float
            In ``[0, 1]``: 0 = zero-velocity prior, 1 = full constant velocity.
        ahead : float
            Intervals ``before -> last`` to predict past ``last``, ``>= 0`` (default 1: the next
            frame of an evenly spaced sequence).
        """
        from ..geometry.rotations import exp_so3, log_so3

        damping = check_number(damping, "damping", minimum=0.0, maximum=1.0) * check_number(ahead, "ahead", minimum=0.0)
        if before is None or damping == 0.0:
            return last
        if len(before.joint_states) != len(last.joint_states):
            raise ValueError(f"before.joint_states: expected {len(last.joint_states)} states, got {len(before.joint_states)}")
        A, B = last.T_cam_naocs, before.T_cam_naocs
        dR = exp_so3(damping * log_so3(A.rotation @ B.rotation.T))
        # the object's NAOCS origin moves on by the same (damped) step, the rotation about it
        t = A.translation + damping * (A.translation - B.translation)
        T = Sim3.unchecked(dR @ A.rotation, t, A.scale)
        q = last.joint_states + damping * (last.joint_states - before.joint_states)
        return cls(T, q, last.weight, last.state_weight)


@dataclass(frozen=True)
class ProgramInputs:
    """Everything a program's parameters are filled from, for one solve.

    Attributes
    ----------
    scale : float
        ``L``: the object's size in metres per NAOCS unit.
    canonical : CanonicalParameters
    start : ProgramStart
    moments : tuple of PartMoments, optional
        One per part (data terms).
    weights : TermWeights, optional
        (weighted terms).
    previous : PreviousSolution, optional
        (:class:`TemporalPriorTerm`).
    """

    scale: float
    canonical: CanonicalParameters
    start: ProgramStart = field(default_factory=ProgramStart)
    moments: tuple | None = None
    weights: TermWeights | None = None
    previous: PreviousSolution | None = None

    def require(self, what: str, term: str):
        """``getattr(self, what)``, or a ``ValueError`` naming the term that needs it."""
        value = getattr(self, what)
        if value is None:
            raise ValueError(f"inputs.{what}: required by the {term!r} term, got None")
        return value


def state_reference(lower: float, upper: float) -> float:
    """Centre of the window in which revolute states are reported: the middle of the limits."""
    if np.isfinite(lower) and np.isfinite(upper):
        return 0.5 * (lower + upper)
    if np.isfinite(lower):
        return max(lower + np.pi, 0.0)
    if np.isfinite(upper):
        return min(upper - np.pi, 0.0)
    return 0.0


def perpendiculars(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit ``u`` to a right-handed orthonormal basis."""
    x, y, z = u
    if abs(x) <= abs(y) and abs(x) <= abs(z):
        a = np.array([0.0, z, -y])  # u x e_x
    elif abs(y) <= abs(z):
        a = np.array([-z, 0.0, x])  # u x e_y
    else:
        a = np.array([y, -x, 0.0])  # u x e_z
    a /= np.sqrt(a @ a)
    b = np.array([y * a[2] - z * a[1], z * a[0] - x * a[2], x * a[1] - y * a[0]])  # u x a
    return a, b


def canonical_parameter_values(canonical: CanonicalParameters) -> dict:
    """Named values of the canonical parameters used by :class:`Context` (``Gs``, ``Gt``, ``u``, ``q``,
    ``a``, ``b``, ``state_ref``): a new dict each call, its values computed once per ``canonical`` (a fit packs
    them five times; the parameters are not to be changed in place)."""
    cached = canonical.__dict__.get("_values")
    if cached is not None:
        return dict(cached)
    v = {}
    for j in range(len(canonical.npcs_scale)):
        v[f"Gs{j}"] = canonical.npcs_scale[j]
        v[f"Gt{j}"] = canonical.npcs_translation[j]
    for k in range(len(canonical.joint_axes_naocs)):
        u = canonical.joint_axes_naocs[k]
        a, b = perpendiculars(u)
        v[f"u{k}"], v[f"q{k}"], v[f"a{k}"], v[f"b{k}"] = u, canonical.joint_pivots_naocs[k], a, b
        v[f"state_ref{k}"] = canonical.state_reference[k]
    object.__setattr__(canonical, "_values", v)  # frozen dataclass: a private memo beside the fields
    return dict(v)
