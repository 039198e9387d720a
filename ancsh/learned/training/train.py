"""Training loop: seeded, resumable, with validation on held-out instances and saved curves.

A run directory holds

- ``config.json`` -- the :class:`~ancsh.learned.network.config.TrainConfig`;
- ``last.pt`` -- the latest checkpoint (model, optimiser, step, history), written atomically;
- ``best.pt`` -- the best checkpoint: the lowest pose score of the pose validation
  (:class:`PoseValidation`: validation frames through the learned provider and the
  ``exact_reduced`` fit, mean fitted rotation error plus mean joint-axis error, degrees) when
  ``config.pose_val_every > 0``, else the lowest validation loss;
- ``history.csv`` and ``curves.png`` -- training/validation losses and metrics;
- ``neighbourhoods.npz`` -- the per-frame sampling / grouping / interpolation indices of the
  training frames (:func:`neighbourhood_cache`), computed on first load and reused on resume.

The batch of step ``s`` is a pure function of ``(seed, s)`` (a per-epoch permutation), and the
learning rate is ``lr * lr_decay ** (s // lr_decay_steps)``, so a resumed run repeats exactly
the steps an uninterrupted run would have taken.
"""

from __future__ import annotations

import functools
import io
import math
import os
import time
from pathlib import Path

import numpy as np
import torch

from ...outputs import write_bytes_atomically
from ..network.config import TrainConfig
from .data import TrainingArrays, read_npz
from ..devices import model_device, move
from ..distributed import DistributedContext, global_batch
from .losses import ancsh_loss, direct_voting_loss
from ..network.models import build_network
from ..network.pointnet2 import Neighbourhoods
from .history import HistoryRow, plot_history, write_history_csv

__all__ = ["Trainer", "HistoryRow", "split_by_instance", "evaluate_arrays", "trivial_baselines", "loss_function",
           "neighbourhood_cache", "PoseValidation", "write_history_csv", "plot_history", "camera_rotations",
           "rotate_batch", "refine_rotations", "input_batch"]


def loss_function(config: TrainConfig):
    """``(outputs, targets) -> (total, parts)``: the loss of ``config`` (kind, loss weights, pose weight)."""
    fn = ancsh_loss if config.kind == "ancsh" else direct_voting_loss
    return functools.partial(fn, weights=config.loss_weights, pose_weight=config.pose_weight, pose_loss=config.pose_loss)


def camera_rotations(centroids_cam: np.ndarray, roll_rad: float, tilt_rad: float, seeds) -> np.ndarray:
    """Random camera rotations about the camera centre, one per frame (``TrainConfig.augment_*_deg``).

    Parameters
    ----------
    centroids_cam : (B, 3) float64
        Each frame's point centroid (camera frame, metres); its direction from the camera is the roll axis.
    roll_rad, tilt_rad : float
        Maximal angles (radians): a uniform roll about the ray to the centroid, then a uniform tilt about
        a uniformly drawn axis perpendicular to that ray.
    seeds : sequence of B seeds
        One ``np.random.default_rng`` seed per frame (the rotation of a frame depends on its seed only).

    Returns
    -------
    (B, 3, 3) float64
        Rotation matrices ``R`` acting on camera-frame vectors (``x -> R @ x``).
    """
    from scipy.spatial.transform import Rotation

    c = np.asarray(centroids_cam, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3 or not np.all(np.isfinite(c)):
        raise ValueError(f"centroids_cam: expected finite (B, 3) values, got shape {c.shape}")
    seeds = list(seeds)
    if len(seeds) != len(c):
        raise ValueError(f"seeds: expected {len(c)} seeds, got {len(seeds)}")
    out = np.empty((len(c), 3, 3))
    for b, (centroid, seed) in enumerate(zip(c, seeds)):
        rng = np.random.default_rng(seed)
        norm = np.linalg.norm(centroid)
        ray = centroid / norm if norm > 1e-9 else np.array([0.0, 0.0, 1.0])
        roll = Rotation.from_rotvec(rng.uniform(-roll_rad, roll_rad) * ray)
        perp = np.cross(ray, rng.normal(size=3))
        while np.linalg.norm(perp) < 1e-9:  # (a draw parallel to the ray: vanishingly rare)
            perp = np.cross(ray, rng.normal(size=3))
        tilt = Rotation.from_rotvec(rng.uniform(-tilt_rad, tilt_rad) * perp / np.linalg.norm(perp))
        out[b] = (tilt * roll).as_matrix()
    return out


def refine_rotations(R_cam_naocs: np.ndarray, max_rad: float, seeds) -> np.ndarray:
    """The input rotations of a refinement network's frames (``TrainConfig.refine_perturb_deg``).

    Parameters
    ----------
    R_cam_naocs : (B, 3, 3)
        Each frame's true NAOCS orientation in the camera.
    max_rad : float
        Largest perturbation (radians): a uniform angle in ``[0, max_rad]`` about a uniform axis.
    seeds : sequence of length B
        One ``np.random.default_rng`` seed per frame.

    Returns
    -------
    (B, 3, 3) float64
        ``dR_b @ R_cam_naocs[b].T``: rotating a frame's points by it leaves them in the NAOCS
        orientation perturbed by ``dR_b``, as a first fit that erred by ``dR_b.T`` would.
    """
    from scipy.spatial.transform import Rotation

    R_cam_naocs = np.asarray(R_cam_naocs, dtype=np.float64)
    out = np.empty_like(R_cam_naocs)
    for b, seed in enumerate(seeds):
        rng = np.random.default_rng(seed)
        axis = rng.normal(size=3)
        dR = Rotation.from_rotvec(rng.uniform(0.0, max_rad) * axis / np.linalg.norm(axis)).as_matrix()
        out[b] = dR @ R_cam_naocs[b].T
    return out


def input_batch(arrays: TrainingArrays, idx, config: TrainConfig, seeds, *, augment: bool = True):
    """Frames ``idx`` of ``arrays`` as the network of ``config`` takes them: ``(points, Targets)`` tensors,
    rotated into a refinement network's perturbed NAOCS orientation or, with ``augment``, by the
    camera-rotation augmentation (one seed per frame)."""
    points, targets = arrays.batch(idx)
    if config.is_refiner:
        rotations = refine_rotations(arrays.naocs_rotations(idx), math.radians(config.refine_perturb_deg), seeds)
        return rotate_batch(points, targets, rotations)
    if augment and (config.augment_roll_deg or config.augment_tilt_deg):
        rotations = camera_rotations(points.double().mean(dim=1).numpy(), math.radians(config.augment_roll_deg),
                                     math.radians(config.augment_tilt_deg), seeds)
        return rotate_batch(points, targets, rotations)
    return points, targets


VAL_STREAM = 2**32 - 1
"""Second seed entry of validation frames' input rotations (training steps use their step number)."""


def rotate_batch(points, targets, rotations):
    """Rotate a training batch's points about the camera centre (the origin) by ``rotations`` ``(B, 3, 3)``.

    As the provider turns a refinement network's input (``LearnedProvider.predict``): the viewpoint
    stays at the origin, so input normals signed to face it (``estimate_normals``) turn with the
    points (without normals the centre does not matter: the network centres its input). NPCS / NAOCS
    targets stay (canonical frames); the camera-frame joint vectors (``targets.joint_cam``: axis and
    unit direction to the axis, the distance unchanged) rotate with the points. Returns ``(points,
    targets)`` as new tensors.
    """
    import dataclasses

    R = torch.as_tensor(rotations, dtype=points.dtype, device=points.device)
    rotated = torch.einsum("bij,bnj->bni", R, points)
    jc = targets.joint_cam
    Rj = R.to(jc.dtype)
    joint_cam = torch.cat([torch.einsum("bij,bnj->bni", Rj, jc[..., 0:3]), torch.einsum("bij,bnj->bni", Rj, jc[..., 3:6]),
                           jc[..., 6:]], dim=-1)
    return rotated, dataclasses.replace(targets, joint_cam=joint_cam)


def neighbourhood_cache(model, points: np.ndarray, *, batch_size: int = 64, path=None) -> dict[str, np.ndarray]:
    """Per-frame :class:`~ancsh.learned.network.pointnet2.Neighbourhoods` of ``model`` for ``(F, N, 3)`` frames.

    Everything of a forward pass that depends only on a frame's points (farthest-point centres,
    ball-query neighbourhoods, interpolation indices and weights; with input normals each point's
    nearest points, which a step's rotation of the frame leaves unchanged), computed once, ``batch_size``
    frames at a time on the device of ``model``'s parameters, as compact numpy arrays with a leading
    frame axis (indices int32, weights float32); :meth:`Neighbourhoods.from_numpy` turns rows of it
    into a batch.

    Parameters
    ----------
    model : AncshNet or DirectVotingNet
    points : (F, N, 3) float32
        Camera-frame points (metres), as fed to the network.
    batch_size : int
    path : path, optional
        A ``.npz`` file: loaded when it holds the cache of these points and sampling settings,
        else computed and written there.
    """
    import hashlib

    import torch

    bb = model.backbone
    key = hashlib.sha256(np.ascontiguousarray(points, dtype=np.float32).tobytes())
    key.update(repr((bb.sa1.npoint, bb.sa1.radius, bb.sa1.nsample, bb.sa2.npoint, bb.sa2.radius, bb.sa2.nsample)).encode())
    if getattr(model, "normals", False):  # the cache holds the normals' nearest points too (normal_idx)
        from ..network.normals import NORMAL_NEIGHBOURS

        key.update(f"normal_idx {NORMAL_NEIGHBOURS}".encode())
    key = key.hexdigest()
    if path is not None and Path(path).is_file():
        z = read_npz(path, "neighbourhood cache")
        if str(z.get("key")) == key:
            return {k: v for k, v in z.items() if k != "key"}
    from ..devices import model_device

    device = model_device(model)  # on a GPU the sampling and grouping run there too
    chunks = []
    with torch.no_grad():
        for start in range(0, len(points), batch_size):
            x = torch.from_numpy(np.ascontiguousarray(points[start:start + batch_size], dtype=np.float32))
            chunks.append(model.neighbourhoods(x.to(device)).numpy())
    cache = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
    if path is not None:
        tmp = Path(path).with_suffix(".tmp.npz")
        np.savez(tmp, key=np.array(key), **cache)
        os.replace(tmp, path)
    return cache


class PoseValidation:
    """Validation on what users get: frames through the learned provider and ``fit`` (``exact_reduced``).

    Parameters
    ----------
    frames : sequence of (Observation, AncshGroundTruth)
        Held-out frames (validation instances of the training split -- never test instances).
    formulation : str
        Fitting formulation of :func:`ancsh.solvers.fit`.
    seed : int
        Seeds the provider's chunking and the fit's RANSAC.
    """

    def __init__(self, frames, *, formulation: str = "exact_reduced", seed: int = 0):
        self.frames = list(frames)
        if not self.frames:
            raise ValueError("frames: expected at least one validation frame")
        self.formulation = formulation
        self.seed = int(seed)

    @classmethod
    def from_dataset(cls, source, frame_indices, **kw) -> "PoseValidation":
        """Frames ``frame_indices`` of HDF5 shards ``source`` (:class:`~ancsh.data.dataset.FrameDataset`)."""
        from ...data.dataset import FrameDataset
        from ...solvers.types import Observation

        ds = FrameDataset(source)
        frames = []
        for i in frame_indices:
            fr = ds[int(i)]
            frames.append((Observation(fr.points), fr.gt))
        return cls(frames, **kw)

    def evaluate(self, network) -> dict[str, float]:
        """Means over frames: ``pose_rot_deg`` (over parts), ``pose_axis_deg``, ``pose_state_err`` (over joints),
        ``pose_failures`` (failed fits, left out) and ``pose_score = pose_rot_deg + pose_axis_deg``.

        A refinement network (``TrainConfig.refine_perturb_deg``) sees each frame in its true NAOCS
        orientation perturbed as in training (seeded per frame), i.e. after a simulated first fit.

        ``network`` is a :class:`~ancsh.learned.network.weights.LoadedNetwork`.
        """
        from ...evaluation import evaluate_fit
        from ...solvers import fit
        from ..inference.provider import LearnedProvider

        provider = LearnedProvider(network, seed=self.seed)
        c, fit_config = network.config, provider.fit_config()
        rot, axis, state, failures = [], [], [], 0
        for i, (obs, gt) in enumerate(self.frames):
            R_in = None
            if c.is_refiner:  # a first fit that erred by up to refine_perturb_deg
                R_in = refine_rotations(gt.T_cam_naocs.rotation[None], math.radians(c.refine_perturb_deg), [[self.seed, VAL_STREAM, i]])[0]
            r = fit(obs, provider.correspond(obs, input_rotation=R_in), self.formulation, config=fit_config, rng=self.seed + i)
            ev = evaluate_fit(r, gt)
            if not ev.ok:
                failures += 1
                continue
            rot.append(np.mean([p.rot_deg for p in ev.parts]))
            axis.append(np.mean([j.axis_deg for j in ev.joints]))
            state.append(np.mean([j.state_err for j in ev.joints]))
        out = {"pose_failures": float(failures)}
        for name, v in (("pose_rot_deg", rot), ("pose_axis_deg", axis), ("pose_state_err", state)):
            out[name] = float(np.mean(v)) if v else float("nan")
        out["pose_score"] = out["pose_rot_deg"] + out["pose_axis_deg"] if rot else float("inf")
        return out


def split_by_instance(arrays: TrainingArrays, fraction: float, seed: int) -> tuple[TrainingArrays, TrainingArrays | None]:
    """Hold out ``fraction`` of the instances (at least one when ``fraction > 0`` and several exist).

    With a single instance, a ``fraction`` of the frames is held out instead.
    """
    if fraction <= 0:
        return arrays, None
    rng = np.random.default_rng([seed, 7])
    inst = np.unique(arrays.instance)
    if inst.size >= 2:
        n_val = min(inst.size - 1, max(1, int(round(fraction * inst.size))))
        val_inst = rng.choice(inst, size=n_val, replace=False)
        is_val = np.isin(arrays.instance, val_inst)
    else:
        is_val = np.zeros(len(arrays), dtype=bool)
        n_val = max(1, int(round(fraction * len(arrays))))
        if n_val >= len(arrays):
            return arrays, None
        is_val[rng.choice(len(arrays), size=n_val, replace=False)] = True
    return arrays.subset(~is_val), arrays.subset(is_val)


@torch.no_grad()
def evaluate_arrays(model, arrays: TrainingArrays, config: TrainConfig, batch_size: int = 16) -> dict[str, float]:
    """Validation losses and per-point metrics of ``model`` on all frames of ``arrays``.

    Metrics: ``seg_acc`` (predicted part = true part), ``assoc_acc``; for ANCSH
    ``npcs_err`` (mean distance between the NPCS of the *predicted* part and the truth, NPCS
    units); ``axis_err_deg`` (mean angle between per-point axis votes and the truth over
    associated points).
    """
    was_training = model.training
    model.eval()
    loss_fn = loss_function(config)
    sums: dict[str, float] = {}
    count = 0
    try:
        for start in range(0, len(arrays), batch_size):
            idx = np.arange(start, min(start + batch_size, len(arrays)))
            seeds = [[config.seed, VAL_STREAM, int(i)] for i in idx]
            points, targets = move(input_batch(arrays, idx, config, seeds, augment=False), model_device(model))
            out = model(points)
            total, parts = loss_fn(out, targets)
            pred = out["seg_logits"].argmax(-1)
            m = {"total": float(total), **{k: float(v) for k, v in parts.items()}}
            m["seg_acc"] = float((pred == targets.labels).float().mean())
            m["assoc_acc"] = float((out["assoc_logits"].argmax(-1) == targets.association).float().mean())
            if config.kind == "ancsh":
                npcs = out["npcs"].gather(2, pred[..., None, None].expand(-1, -1, 1, 3)).squeeze(2)
                m["npcs_err"] = float((npcs - targets.npcs).norm(dim=-1).mean())
                true_axis = targets.joint[..., :3]
            else:
                true_axis = targets.joint_cam[..., :3]
            assoc = targets.joint_mask[..., 0] > 0
            votes = torch.nn.functional.normalize(out["joint"][..., :3], dim=-1)
            cos = (votes * true_axis).sum(-1).clamp(-1, 1)
            m["axis_err_deg"] = float(torch.rad2deg(torch.arccos(cos[assoc])).mean()) if assoc.any() else float("nan")
            n = len(idx)
            for k, v in m.items():
                sums[k] = sums.get(k, 0.0) + v * n
            count += n
    finally:
        model.train(was_training)
    return {k: v / max(count, 1) for k, v in sums.items()}


def trivial_baselines(arrays: TrainingArrays) -> dict[str, float]:
    """Scores of trivial predictors on ``arrays``: majority part label, NPCS = 0, no joint association,
    one constant camera-frame joint axis (the mean of the true axes: the direct-voting baseline)."""
    counts = np.bincount(arrays.labels.ravel(), minlength=arrays.num_parts)
    out = {
        "seg_acc_majority": float(counts.max() / counts.sum()),
        "npcs_err_zero": float(np.linalg.norm(arrays.npcs, axis=-1).mean()),
        "assoc_acc_none": float(np.mean(arrays.association == 0)),
    }
    axes = arrays.joint_cam[..., :3][arrays.association > 0].astype(np.float64)
    if len(axes):
        mean = axes.mean(axis=0)
        if np.linalg.norm(mean) > 0:
            cos = np.clip(axes @ (mean / np.linalg.norm(mean)), -1.0, 1.0)
            out["axis_err_deg_mean_axis"] = float(np.degrees(np.arccos(cos)).mean())
    return out


class Trainer:
    """Seeded, resumable training of one network on in-memory :class:`TrainingArrays`.

    Parameters
    ----------
    config : TrainConfig
    train : TrainingArrays
    val : TrainingArrays or None
        Held-out frames (first ``config.val_frames`` are used).
    out_dir : path or None
        Run directory (checkpoints, CSV, PNG); ``None`` keeps everything in memory.
    progress : bool
        Show a tqdm progress bar.
    pose_val : PoseValidation, optional
        Run every ``config.pose_val_every`` steps (and at the end); selects ``best.pt``.
    device : str or torch.device
        Where the network trains (``"cpu"``, ``"cuda"``, ``"auto"``); ignored with ``distributed``.
    distributed : DistributedContext, optional
        This process's rank in a ``torchrun`` launch (:mod:`ancsh.learned.distributed`): each rank runs
        its share of every global batch, rank 0 writes the run directory and validates.

    The sampling / grouping indices of the training frames are computed once
    (:func:`neighbourhood_cache`) and fed to every step.
    """

    def __init__(self, config: TrainConfig, train: TrainingArrays, val: TrainingArrays | None = None, out_dir=None, *,
                 progress: bool = True, pose_val: PoseValidation | None = None, device="cpu",
                 distributed: DistributedContext | None = None):
        if not isinstance(config, TrainConfig):
            raise ValueError(f"config: expected a TrainConfig, got {type(config).__name__}")
        if len(train) == 0:
            raise ValueError("train: no frames")
        if train.num_points != config.num_points:
            raise ValueError(f"train: frames have {train.num_points} points, config.num_points is {config.num_points}")
        self.config = config
        self.train_arrays = train
        self.val_arrays = None if val is None or len(val) == 0 else val.subset(np.arange(min(len(val), config.val_frames)))
        self.out_dir = None if out_dir is None else Path(out_dir)
        self.progress = progress
        torch.set_num_threads(config.num_threads)
        torch.manual_seed(config.seed)
        self.dist = _distributed_context(distributed, device)
        self.device = self.dist.device
        self.model = build_network(config.kind, train.num_parts, train.num_joints, **config.network_kwargs())
        self.init_sha256: str | None = None  # of config.init_weights, when given
        self.init_record: dict | None = None  # weights.parent_record of config.init_weights, kept in checkpoints
        if config.init_weights:
            self._initialise_from(config.init_weights, train)
        self.model = self.model.to(self.device)
        self.step_model = self.dist.wrap(self.model)  # the model itself, or its DDP wrapper
        if config.compile:
            if self.dist.active:
                raise ValueError(f"compile: not supported in a distributed run ({self.dist.world_size} processes); "
                                 "set compile = false")
            from .compiled import compile_network

            self.step_model = compile_network(self.model)  # shares the model's parameters; evaluation stays uncompiled
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=config.lr)
        self.loss_fn = loss_function(config)
        if pose_val is not None and not isinstance(pose_val, PoseValidation):
            raise ValueError(f"pose_val: expected a PoseValidation, got {type(pose_val).__name__}")
        self.pose_val = pose_val
        self.step, self.elapsed_s = 0, 0.0
        self.history: list[dict] = []
        self.best_val, self._saved_step = math.inf, -1
        self._acc, self._acc_n = {}, 0  # the loss sums since the last log line, and over how many steps
        if self.out_dir is not None and self.dist.is_main:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            config.to_json(self.out_dir / "config.json")
        cache_path = None if self.out_dir is None else self.out_dir / "neighbourhoods.npz"
        if self.dist.is_main:
            self.neighbourhoods = neighbourhood_cache(self.model, train.points, path=cache_path)
        self.dist.barrier()  # the other ranks read rank 0's cache
        if not self.dist.is_main:
            self.neighbourhoods = neighbourhood_cache(self.model, train.points, path=cache_path)

    def _initialise_from(self, source: str, train: TrainingArrays) -> None:
        """Copy ``source``'s parameters (``config.init_weights``) into the new model (another structure: ``init_match``)."""
        from ..network.models import load_adding_normals, load_matching
        from ..network.weights import load_network, parent_record

        c = self.config
        loaded = load_network(c.category if source == "builtin" else source, kind=c.kind)
        # a network without input normals may start one with them (the normals' weights at zero)
        adding_normals = c.input_normals and not loaded.config.input_normals
        wanted = {**c.network_kwargs(), "normals": False} if adding_normals else c.network_kwargs()
        if loaded.kind != c.kind or loaded.config.network_kwargs() != wanted:
            raise ValueError(f"init_weights: {loaded.source} is a {loaded.kind} network with {loaded.config.network_kwargs()}, "
                             f"not the configured {c.kind} network with {c.network_kwargs()}")
        self.init_sha256, self.init_record = loaded.sha256, parent_record(loaded)
        if c.init_match == "matching" and not adding_normals:  # another structure: the backbone, the heads afresh
            copied = load_matching(self.model, loaded.model.state_dict())
            self.init_record.update(copied_parameters=copied, parameters=len(self.model.state_dict()))
            return
        if loaded.num_parts != train.num_parts or not np.array_equal(loaded.revolute, train.revolute):
            raise ValueError(f"init_weights: {loaded.source} has {loaded.num_parts} parts and joints "
                             f"{['revolute' if r else 'prismatic' for r in loaded.revolute]}; the training frames have "
                             f"{train.num_parts} parts and {['revolute' if r else 'prismatic' for r in train.revolute]}")
        if adding_normals:
            load_adding_normals(self.model, loaded.model.state_dict())
        else:
            self.model.load_state_dict(loaded.model.state_dict())

    # --- schedule ------------------------------------------------------------------
    def batch_indices(self, step: int) -> np.ndarray:
        """Frame indices of the batch of ``step`` (deterministic in ``(seed, step)``)."""
        F, B = len(self.train_arrays), self.config.batch_size
        if F < B:
            return np.random.default_rng([self.config.seed, step]).choice(F, size=B, replace=True)
        per_epoch = F // B
        epoch, i = divmod(step, per_epoch)
        perm = np.random.default_rng([self.config.seed, epoch]).permutation(F)
        return perm[i * B:(i + 1) * B]

    def pose_weight(self, step: int) -> float:
        """Weight of the pose term in the training loss of ``step`` (0 before ``config.pose_start_step``)."""
        c = self.config
        return c.pose_weight if step >= c.pose_start_step else 0.0

    def learning_rate(self, step: int) -> float:
        c = self.config
        return c.lr * c.lr_decay ** (step // c.lr_decay_steps)

    # --- one step ----------------------------------------------------------------------
    def train_step(self) -> dict[str, float]:
        """One optimisation step; returns the loss components of this batch (the global batch, in a distributed run)."""
        self.model.train()
        for g in self.optimizer.param_groups:
            g["lr"] = self.learning_rate(self.step)
        idx = self.dist.local_batch(self.batch_indices(self.step))  # all of it in a single process
        c = self.config
        points, targets = input_batch(self.train_arrays, idx, c, [[c.seed, self.step, int(i)] for i in idx])
        points, targets = move((points, targets), self.device)
        with global_batch(self.dist):
            out = self.step_model(points, move(Neighbourhoods.from_numpy(self.neighbourhoods, idx), self.device))
            total, parts = self.loss_fn(out, targets, pose_weight=self.pose_weight(self.step))
        values = self.dist.average(torch.stack([total.detach(), *(v.detach() for v in parts.values())])).tolist()
        losses = dict(zip(("total", *parts), values))  # of the global batch
        if not math.isfinite(losses["total"]):
            raise FloatingPointError(f"non-finite loss at step {self.step}: { {k: v for k, v in losses.items()} }")
        self.optimizer.zero_grad(set_to_none=True)
        total.backward()  # DDP averages the gradients over the ranks
        self.optimizer.step()
        self.step += 1
        for k, v in losses.items():
            self._acc[k] = self._acc.get(k, 0.0) + v
        self._acc_n += 1
        return losses

    def fit(self, max_steps: int | None = None, *, time_limit_s: float | None = None) -> list[dict[str, float]]:
        """Train until ``max_steps`` (default ``config.max_steps``) or the time limit.

        Validates every ``val_every`` steps, checkpoints every ``checkpoint_every`` steps and
        at the end. Returns the per-step losses of this call.
        """
        c = self.config
        max_steps = c.max_steps if max_steps is None else int(max_steps)
        losses = []
        bar = None
        if self.progress:
            from tqdm import tqdm

            bar = tqdm(total=max_steps, initial=self.step, desc=f"train {c.category}/{c.kind}", dynamic_ncols=True)
        t_start = time.monotonic()
        t_last = t_start
        try:
            while self.step < max_steps:
                step_losses = self.train_step()
                losses.append(step_losses)
                now = time.monotonic()
                self.elapsed_s += now - t_last
                t_last = now
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix({k: f"{v:.3g}" for k, v in step_losses.items()})
                if self.step % c.val_every == 0 or self.step == max_steps:
                    self.record(pose=self.step == max_steps)
                if self.out_dir is not None and (self.step % c.checkpoint_every == 0 or self.step == max_steps):
                    self.save_checkpoint(self.out_dir / "last.pt")
                if time_limit_s is not None and self.dist.any(now - t_start >= time_limit_s):  # every rank stops
                    break
        except KeyboardInterrupt:  # Ctrl-C: keep the finished steps, then let the caller report it
            if self.out_dir is not None and self._saved_step != self.step:
                self.save_checkpoint(self.out_dir / "last.pt")
            raise
        finally:
            if bar is not None:
                bar.close()
        if self._acc_n:
            self.record(pose=True)
        if self.out_dir is not None and self._saved_step != self.step:
            self.save_checkpoint(self.out_dir / "last.pt")
        return losses

    # --- validation and logs -------------------------------------------------------------
    def pose_network(self):
        """The model being trained as a :class:`~ancsh.learned.network.weights.LoadedNetwork` (shares its parameters)."""
        from ..network.weights import LoadedNetwork

        a = self.train_arrays
        return LoadedNetwork(model=self.model, config=self.config, revolute=a.revolute, joint_parents=a.joint_parents,
                             joint_children=a.joint_children, num_parts=a.num_parts, metrics={}, source="training",
                             step=self.step)

    def measure(self, *, pose: bool = False) -> HistoryRow:
        """Measure one history row: the mean training losses since the last row (and reset them), the
        validation metrics, and the pose validation when ``pose`` or at multiples of ``config.pose_val_every``.

        Writes nothing; :meth:`record` appends the row and writes the run directory.
        """
        n = max(self._acc_n, 1)
        train = {k: v / n for k, v in self._acc.items()}
        self._acc, self._acc_n = {}, 0
        val = {} if self.val_arrays is None else evaluate_arrays(self.model, self.val_arrays, self.config)
        scores = {}
        if self._pose_selects and (pose or self.step % self.config.pose_val_every == 0):
            try:
                scores = self.pose_val.evaluate(self.pose_network())
            finally:
                self.model.train()
        return HistoryRow(step=self.step, elapsed_s=round(self.elapsed_s, 1), lr=self.learning_rate(max(self.step - 1, 0)),
                          train=train, val=val, pose=scores)

    @property
    def _pose_selects(self) -> bool:
        """Whether the pose validation runs (and so selects ``best.pt``) in this run."""
        return self.pose_val is not None and bool(self.config.pose_val_every)

    def record(self, *, pose: bool = False) -> dict:
        """Measure a row (:meth:`measure`), append it to the history and, with a run directory, write
        ``history.csv``/``curves.png`` and save ``best.pt`` when the row improves on the best.

        ``best.pt`` follows the row's ``pose_score`` when there is a pose validation, else the
        validation loss. Returns the row as written (:meth:`HistoryRow.to_dict`).
        """
        if not self.dist.is_main:  # rank 0 measures and writes; the others only drop their partial means
            self._acc, self._acc_n = {}, 0
            return {}
        row = self.measure(pose=pose)
        self.history.append(row.to_dict())
        if self.out_dir is not None:
            self.write_history()
            score = row.selection_score(pose=self._pose_selects)
            if score is not None and score < self.best_val:
                self.best_val = score
                self.save_checkpoint(self.out_dir / "best.pt")
        return self.history[-1]

    def write_history(self) -> None:
        """Write ``history.csv`` and ``curves.png`` of the run directory from the whole history."""
        write_history_csv(self.history, self.out_dir / "history.csv")
        plot_history(self.history, self.out_dir / "curves.png", title=f"{self.config.category} ({self.config.kind})")

    # --- checkpoints --------------------------------------------------------------------
    def state(self) -> dict:
        return {
            "config": self.config.to_dict(),
            "step": self.step,
            "elapsed_s": self.elapsed_s,
            "model": self.model.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "history": self.history,
            "best_val": self.best_val,
            "acc": (self._acc, self._acc_n),
            "num_parts": self.train_arrays.num_parts,
            "revolute": self.train_arrays.revolute.tolist(),
            "joint_parents": self.train_arrays.joint_parents.tolist(),
            "joint_children": self.train_arrays.joint_children.tolist(),
            "init": self.init_record,
        }

    def save_checkpoint(self, path) -> Path:
        """Write the full training state atomically (temporary file + rename); rank 0 only in a distributed run."""
        path = Path(path)
        if not self.dist.is_main:
            if path.name == "last.pt":
                self._saved_step = self.step
            return path
        buffer = io.BytesIO()  # serialised in memory: a full disk fails a plain write with its errno, not inside torch
        torch.save(self.state(), buffer)
        try:
            write_bytes_atomically(path, buffer.getbuffer())
        except OSError as exc:  # full disk, read-only folder: the previous checkpoint stays intact
            raise OSError(exc.errno, f"could not write the checkpoint {path}: {exc.strerror or exc}") from None
        if path.name == "last.pt":
            self._saved_step = self.step
        return path

    def load_checkpoint(self, path) -> None:
        """Restore model, optimiser, step and history from :meth:`save_checkpoint` output."""
        from ..network.weights import read_torch_file

        keys = ("config", "step", "elapsed_s", "model", "optimizer", "history", "best_val", "acc", "num_parts", "revolute")
        ck = read_torch_file(path, argument="--resume", required=keys)
        try:
            saved = TrainConfig.from_dict(ck["config"])
        except (ValueError, TypeError) as exc:
            raise ValueError(f"--resume: {path} holds an invalid config: {exc}") from None
        if saved.category != self.config.category:
            raise ValueError(f"--resume: {path} is a run of category {saved.category!r}, not {self.config.category!r}; "
                             "choose another --out")
        mismatch = [k for k in ("kind", "width", "npoints", "radii", "nsamples", "backbones", "num_points")
                    if getattr(saved, k) != getattr(self.config, k)]
        if mismatch:
            raise ValueError(f"checkpoint {path}: network settings {mismatch} differ from the config")
        if ck["num_parts"] != self.train_arrays.num_parts or ck["revolute"] != self.train_arrays.revolute.tolist():
            raise ValueError(f"checkpoint {path}: trained for another kinematic structure")
        try:
            self.model.load_state_dict(ck["model"])
            self.optimizer.load_state_dict(ck["optimizer"])
            self.step = int(ck["step"])
            self.elapsed_s = float(ck["elapsed_s"])
            self.history = list(ck["history"])
            self.best_val = float(ck["best_val"])
            self._acc, self._acc_n = dict(ck["acc"][0]), int(ck["acc"][1])
            if ck.get("init") is not None:  # the parent as it was when the run started, not today's file
                self.init_record = dict(ck["init"])
                self.init_sha256 = self.init_record.get("sha256")
        except (ValueError, TypeError, KeyError, IndexError, RuntimeError) as exc:
            raise ValueError(f"--resume: {path} is not a usable checkpoint: {str(exc).splitlines()[0][:200]}") from None
        self._saved_step = self.step


def _distributed_context(distributed, device) -> DistributedContext:
    """``distributed`` (checked), or a single-process context on ``device``."""
    if distributed is None:
        from ..devices import resolve_device

        return DistributedContext(device=resolve_device(device))
    if not isinstance(distributed, DistributedContext):
        raise ValueError(f"distributed: expected a DistributedContext, got {type(distributed).__name__}")
    return distributed


