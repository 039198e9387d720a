"""Training configuration: a frozen dataclass validated at construction, read from / written to JSON.

Defaults are sized for a 2-core CPU (see ``docs/results/learned_width.md``): a quarter-width
PointNet++ with one shared backbone, 256/64 set-abstraction centres and 32 neighbours.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path

from ...geometry._checks import check_int, check_positive

__all__ = ["TrainConfig"]

_KINDS = ("ancsh", "direct_voting")


POSE_LOSSES = ("chordal", "displacement")  # the kinds of ancsh.learned.training.losses.npcs_pose_loss


def _positive_int(value, name: str) -> int:
    return check_int(value, name, minimum=1)


def _positive(value, name: str) -> float:
    return check_positive(value, name)


@dataclass(frozen=True)
class TrainConfig:
    """Everything that defines a training run (the data location is given separately).

    Attributes
    ----------
    category : str or None
        Object category (names the run and the shipped weights; ``ancsh train`` and ``ancsh category build`` set
        it). ``None`` (the default): a network of no named category (an experiment's, a test's); it cannot start
        from ``init_weights="builtin"``.
    kind : str
        ``"ancsh"`` (the ANCSH network) or ``"direct_voting"`` (camera-space joint-voting baseline).
    num_points : int
        Points per input cloud.
    width : float
        PointNet++ channel multiplier (1.0 = the reference part-segmentation widths).
    npoints, radii, nsamples : tuple of 2
        Set-abstraction centres, ball radii (normalised-cloud units) and neighbours.
    backbones : int
        1 = one backbone shared by all heads; 2 = the paper's two backbones.
    batch_size : int
    lr : float
        Adam learning rate.
    lr_decay : float
        Multiplicative decay in ``(0, 1]`` applied every ``lr_decay_steps`` steps.
    lr_decay_steps : int
    max_steps : int
        Total optimisation steps.
    loss_weights : tuple of 5 floats
        Weights of (seg, NPCS, NAOCS, association, joint); the paper's ``[1, 10, 1, 1, 1]``.
    pose_weight : float
        Weight of the pose-aware term :func:`~ancsh.learned.training.losses.npcs_pose_loss` (0 = the paper's
        loss only, the default; ANCSH networks only).
    pose_start_step : int
        First step whose training loss includes the pose term (0 = from the start). Switching it
        on late lets the paper's losses shape the NPCS first (a large pose term slows early training).
    pose_loss : str
        Which pose term (``kind`` of :func:`~ancsh.learned.training.losses.npcs_pose_loss`): ``"chordal"`` (the
        default; squared chordal distance of each part's NPCS orientation error) or ``"displacement"``
        (the mean squared distance the error moves the part's true NPCS: thin parts' rotations about
        their long axes weigh what they move).
    val_fraction : float
        Share of training *instances* held out for validation, in ``[0, 0.5]``.
    val_frames : int
        Validation frames evaluated at each validation (a fixed subset).
    val_every, checkpoint_every : int
        Steps between validations / checkpoints.
    init_weights : str
        Start from these weights instead of a random initialisation: ``""`` (none, the default),
        ``"builtin"`` (the shipped weights of ``category`` and ``kind``) or a weights file / checkpoint
        path. The network's structure must match this configuration's (or be the same without input
        normals, see ``input_normals``); the optimiser and the step start afresh.
    init_match : str
        With ``init_weights``: ``"all"`` (the default: the same parts and joint types, every parameter
        copied) or ``"matching"`` (a network of another part count or joint types: the parameters of
        the same name and shape are copied -- the backbone -- and the part-sized heads start afresh).
    pose_val_every : int
        Steps between pose validations (0 = none): validation frames through the full pipeline
        (learned provider, then ``fit`` ``exact_reduced``); with them, ``best.pt`` is the checkpoint
        with the lowest mean fitted rotation error (see :mod:`ancsh.learned.training.train`).
    pose_val_frames : int
        Validation frames of each pose validation (evenly spread over the validation frames). Default 256:
        with 64, the selected checkpoint was a noise winner -- measured on all 640 validation frames of two
        fine-tunes, eyeglasses' best.pt (64-frame score 6.68) scored 8.70 against 8.12 for its last checkpoint
        (64-frame 7.59); the washing machine's best and last tied (6.51 each, 64-frame 7.25 / 7.62). A
        pose validation costs about 35 ms per frame on one core (network pass and fit).
    seed : int
        Seeds initialisation, point sampling and batch order.
    num_threads : int
        torch intra-op threads.
    compile : bool
        Train with the network compiled by ``torch.compile`` (:mod:`ancsh.learned.training.compiled`): the
        same function, fewer CPU-seconds per step after a one-off compilation at the start of each
        process (``docs/results/learned_cost.md``); needs a C++ compiler on a CPU. Default
        ``False``. It changes no weights, so a run can be resumed with it switched on or off.
    augment_roll_deg, augment_tilt_deg : float
        Rotation augmentation (degrees; 0 = none, the default): each training frame of each step is
        rotated about its centroid, by a uniform angle up to ``augment_roll_deg`` about the ray from
        the camera through the centroid (a camera roll), then up to ``augment_tilt_deg`` about a
        random axis perpendicular to that ray (the object elsewhere in the field of view). Both are
        rotations of the camera about its own centre (the translation is immaterial to the network,
        which centres its input): the visible surface is unchanged, so the NPCS / NAOCS targets are
        too and the direct-voting camera-frame joint vectors rotate with the points. Distances are
        preserved, so the cached neighbourhoods stay valid. The shipped networks trained without it
        lean on the camera frame: their fitted rotation follows a 10° camera roll by only 0.4–0.7
        (oven, washing machine, drawer) against about 1 for the laptop (``ancsh bench
        roll-equivariance``).
    input_normals : bool
        Feed the network each input point's surface normal beside its coordinates (``False``, the
        default: coordinates only; issue 32's "normals as extra input channels"). The normals are
        estimated inside the network from the cloud it is given (the ``k`` nearest points' principal
        components, :func:`~ancsh.learned.network.normals.estimate_normals`, signed to face the
        camera), so training frames, augmented or refinement inputs and predictions get them alike.
        Changes the network's structure (the first layer's inputs). ``init_weights`` may name a network
        without them: it is loaded with the normals' weights at zero
        (:func:`~ancsh.learned.network.models.load_adding_normals`), so fine-tuning starts from exactly
        its predictions.
    refine_perturb_deg : float
        ``0`` (the default): a first-stage network, on camera-frame input. ``> 0``: a **refinement
        network** (the second stage of CAPTRA / DeepIM): every training and validation frame is rotated
        into its NAOCS orientation (its truth's ``R_cam_naocs``,
        :meth:`~ancsh.learned.training.data.TrainingArrays.naocs_rotations`) and then by a random
        rotation of up to this many degrees (uniform angle, uniform axis) -- what a second pass sees
        after a first fit whose rotation erred by that much. Translation and scale need no perturbation:
        the network centres and scales its input. At test time ``LearnedProvider(refine="network")``
        rotates the observed points by the first fit's ``R_cam_naocs`` transposed. ANCSH networks only;
        not combined with the camera-rotation augmentation (which it replaces).
    """

    category: str | None = None
    kind: str = "ancsh"
    num_points: int = 1024
    width: float = 0.25
    npoints: tuple = (256, 64)
    radii: tuple = (0.2, 0.4)
    nsamples: tuple = (32, 32)
    backbones: int = 1
    batch_size: int = 16
    lr: float = 1e-3
    lr_decay: float = 0.7
    lr_decay_steps: int = 1500
    max_steps: int = 6000
    loss_weights: tuple = (1.0, 10.0, 1.0, 1.0, 1.0)
    pose_weight: float = 0.0
    pose_start_step: int = 0
    pose_loss: str = "chordal"
    init_weights: str = ""
    init_match: str = "all"
    val_fraction: float = 0.1
    val_frames: int = 256
    val_every: int = 250
    checkpoint_every: int = 250
    pose_val_every: int = 0
    pose_val_frames: int = 256
    seed: int = 0
    num_threads: int = 1
    compile: bool = False
    augment_roll_deg: float = 0.0
    augment_tilt_deg: float = 0.0
    refine_perturb_deg: float = 0.0
    input_normals: bool = False

    def __post_init__(self):
        if self.category is not None and (not isinstance(self.category, str) or not self.category):
            raise ValueError(f"category: expected a non-empty string or None, got {self.category!r}")
        if self.kind not in _KINDS:
            raise ValueError(f"kind: expected one of {_KINDS}, got {self.kind!r}")
        for name in ("num_points", "batch_size", "lr_decay_steps", "max_steps", "val_frames", "val_every", "checkpoint_every", "num_threads"):
            _positive_int(getattr(self, name), name)
        _positive(self.width, "width")
        _positive(self.lr, "lr")
        if not 0 < _positive(self.lr_decay, "lr_decay") <= 1:
            raise ValueError(f"lr_decay: expected a number in (0, 1], got {self.lr_decay!r}")
        if self.backbones not in (1, 2):
            raise ValueError(f"backbones: expected 1 or 2, got {self.backbones!r}")
        if self.kind == "direct_voting" and self.backbones != 1:
            raise ValueError("backbones: the direct_voting network has one backbone")
        for name, conv in (("npoints", _positive_int), ("radii", _positive), ("nsamples", _positive_int)):
            value = getattr(self, name)
            if not isinstance(value, (tuple, list)) or len(value) != 2:
                raise ValueError(f"{name}: expected 2 values, got {value!r}")
            object.__setattr__(self, name, tuple(conv(v, name) for v in value))
        if not self.npoints[0] <= self.num_points or not self.npoints[1] <= self.npoints[0]:
            raise ValueError(f"npoints: expected num_points >= npoints[0] >= npoints[1], got {self.npoints} for {self.num_points} points")
        if not self.nsamples[0] <= self.num_points or not self.nsamples[1] <= self.npoints[0]:
            raise ValueError(f"nsamples: expected nsamples[0] <= num_points and nsamples[1] <= npoints[0], got {self.nsamples}")
        w = self.loss_weights
        if not isinstance(w, (tuple, list)) or len(w) != 5:
            raise ValueError(f"loss_weights: expected 5 values, got {w!r}")
        w = tuple(float(x) for x in w)
        if any(not math.isfinite(x) or x < 0 for x in w):
            raise ValueError(f"loss_weights: expected non-negative numbers, got {w}")
        object.__setattr__(self, "loss_weights", w)
        pw = self.pose_weight
        if isinstance(pw, bool) or not isinstance(pw, (int, float)) or not math.isfinite(pw) or pw < 0:
            raise ValueError(f"pose_weight: expected a non-negative number, got {pw!r}")
        if self.kind == "direct_voting" and pw:
            raise ValueError("pose_weight: the direct_voting network predicts no NPCS; expected 0")
        object.__setattr__(self, "pose_weight", float(pw))
        if self.pose_loss not in POSE_LOSSES:
            raise ValueError(f"pose_loss: expected one of {POSE_LOSSES}, got {self.pose_loss!r}")
        if not isinstance(self.init_weights, str):
            raise ValueError(f"init_weights: expected a string ('' = none, 'builtin' or a path), got {self.init_weights!r}")
        if self.init_weights == "builtin" and self.category is None:
            raise ValueError("init_weights: 'builtin' names the shipped weights of the category, and category is None")
        if self.init_match not in ("all", "matching"):
            raise ValueError(f"init_match: expected 'all' or 'matching', got {self.init_match!r}")
        if isinstance(self.pose_start_step, bool) or not isinstance(self.pose_start_step, int) or self.pose_start_step < 0:
            raise ValueError(f"pose_start_step: expected a non-negative integer, got {self.pose_start_step!r}")
        if isinstance(self.pose_val_every, bool) or not isinstance(self.pose_val_every, int) or self.pose_val_every < 0:
            raise ValueError(f"pose_val_every: expected a non-negative integer, got {self.pose_val_every!r}")
        _positive_int(self.pose_val_frames, "pose_val_frames")
        if isinstance(self.val_fraction, bool) or not isinstance(self.val_fraction, (int, float)) or not 0 <= self.val_fraction <= 0.5:
            raise ValueError(f"val_fraction: expected a number in [0, 0.5], got {self.val_fraction!r}")
        for name in ("compile", "input_normals"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: expected true or false, got {getattr(self, name)!r}")
        for name, top in (("augment_roll_deg", 180.0), ("augment_tilt_deg", 90.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= top:
                raise ValueError(f"{name}: expected a number of degrees in [0, {top:g}], got {v!r}")
            object.__setattr__(self, name, float(v))
        v = self.refine_perturb_deg
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= 90:
            raise ValueError(f"refine_perturb_deg: expected a number of degrees in [0, 90], got {v!r}")
        object.__setattr__(self, "refine_perturb_deg", float(v))
        if v and self.kind != "ancsh":
            raise ValueError(f"refine_perturb_deg: a refinement network is an ANCSH network, not {self.kind!r}")
        if v and (self.augment_roll_deg or self.augment_tilt_deg):
            raise ValueError("refine_perturb_deg: a refinement network's input is in its NAOCS orientation; "
                             "set augment_roll_deg and augment_tilt_deg to 0")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed: expected a non-negative integer, got {self.seed!r}")

    # --- (de)serialisation -------------------------------------------------------------
    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict, **overrides) -> "TrainConfig":
        """Build from a dict; unknown keys raise ``ValueError`` naming them."""
        if not isinstance(data, dict):
            raise ValueError(f"config: expected a JSON object, got {type(data).__name__}")
        merged = {**data, **{k: v for k, v in overrides.items() if v is not None}}
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(merged) - known)
        if unknown:
            raise ValueError(f"config: unknown key(s) {unknown}; known keys are {sorted(known)}")
        return cls(**merged)

    @classmethod
    def from_json(cls, path, **overrides) -> "TrainConfig":
        try:
            data = json.loads(Path(path).read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"config: {path} is not valid JSON ({exc})") from None
        if not isinstance(data, dict):
            raise ValueError(f"config: {path} must hold a JSON object of settings, got {type(data).__name__}")
        return cls.from_dict(data, **overrides)

    def to_json(self, path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n")

    @property
    def is_refiner(self) -> bool:
        """Whether this is a refinement network (input in a perturbed NAOCS orientation)."""
        return self.refine_perturb_deg > 0

    def network_kwargs(self) -> dict:
        """Keyword arguments of :func:`ancsh.learned.network.models.build_network` (besides kind, parts, joints)."""
        return dict(width=self.width, npoints=self.npoints, radii=self.radii, nsamples=self.nsamples, backbones=self.backbones,
                    normals=self.input_normals)
