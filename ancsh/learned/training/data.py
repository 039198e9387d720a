"""Training arrays: ANCSH ground truth of many frames packed into fixed-size numpy arrays.

A frame (camera-frame points + :class:`~ancsh.model.canonical.AncshGroundTruth`) becomes
``num_points`` sampled points with their per-point targets. :class:`TrainingArrays` keeps
all frames of a split in memory (float32, about 90 bytes per point) and serves batches
as :class:`~ancsh.learned.training.losses.Targets` tensors.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from ...geometry._checks import check_generator
from ...model.articulated import JointType, joint_tree_root

__all__ = ["TrainingArrays", "naocs_rotations", "frame_arrays", "stack_frames", "camera_joint_targets", "arrays_from_dataset", "synthetic_arrays"]


@dataclass(frozen=True)
class TrainingArrays:
    """``F`` frames of ``N`` points each (float32 / int64 numpy arrays).

    Attributes
    ----------
    points : (F, N, 3) float32
        Camera frame, metres.
    labels : (F, N) int64
    npcs : (F, N, 3) float32
    scale : (F, N) float32
        NPCS -> NAOCS scale of the point's part.
    translation : (F, N, 3) float32
    association : (F, N) int64
        0 = none, ``k + 1`` = joint ``k``.
    joint : (F, N, 7) float32
        NAOCS joint vector.
    joint_mask : (F, N, 7) float32
    joint_cam : (F, N, 7) float32
        Camera-frame joint vector (distance in metres).
    instance : (F,) int64
        Object instance of each frame (for instance-level validation splits).
    revolute : (K,) bool
        Joint types (``True`` = revolute).
    joint_parents, joint_children : (K,) int64
        Part indices joined by each joint.
    num_parts : int
    """

    points: np.ndarray
    labels: np.ndarray
    npcs: np.ndarray
    scale: np.ndarray
    translation: np.ndarray
    association: np.ndarray
    joint: np.ndarray
    joint_mask: np.ndarray
    joint_cam: np.ndarray
    instance: np.ndarray
    revolute: np.ndarray
    joint_parents: np.ndarray
    joint_children: np.ndarray
    num_parts: int

    _PER_FRAME = ("points", "labels", "npcs", "scale", "translation", "association", "joint", "joint_mask", "joint_cam", "instance")

    def __post_init__(self):
        F = self.points.shape[0]
        for name in self._PER_FRAME:
            if getattr(self, name).shape[0] != F:
                raise ValueError(f"{name}: expected {F} frames, got {getattr(self, name).shape[0]}")
        if self.points.ndim != 3 or self.points.shape[2] != 3:
            raise ValueError(f"points: expected shape (F, N, 3), got {self.points.shape}")

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def num_points(self) -> int:
        return int(self.points.shape[1])

    @property
    def num_joints(self) -> int:
        return int(self.revolute.shape[0])

    def subset(self, index) -> "TrainingArrays":
        """Frames ``index`` (array of ints or bool mask)."""
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        for name in self._PER_FRAME:
            kw[name] = kw[name][index]
        return TrainingArrays(**kw)

    def batch(self, index):
        """``(points (B, N, 3), Targets)`` torch tensors for frames ``index``."""
        import torch

        from .losses import Targets

        t = {name: torch.from_numpy(np.ascontiguousarray(getattr(self, name)[index])) for name in self._PER_FRAME[:-1]}
        points = t.pop("points")
        return points, Targets(**t)

    @property
    def root_part(self) -> int:
        """The part no joint moves (the base: its NPCS orientation is the NAOCS orientation)."""
        return joint_tree_root(self.num_parts, self.joint_children)

    def naocs_rotations(self, index) -> np.ndarray:
        """``R_cam_naocs`` ``(B, 3, 3)`` of frames ``index``: :func:`naocs_rotations` of their points."""
        index = np.asarray(index)
        naocs = self.scale[index][..., None] * self.npcs[index] + self.translation[index]
        return naocs_rotations(self.points[index], naocs, self.labels[index] == self.root_part)

    def save(self, path) -> None:
        """Write an uncompressed ``.npz`` cache."""
        np.savez(Path(path), **{f.name: np.asarray(getattr(self, f.name)) for f in fields(self)})

    @classmethod
    def load(cls, path) -> "TrainingArrays":
        """Read a cache written by :meth:`save`; a file that is not one (an array of Python objects, a missing array)
        raises ``ValueError`` naming it."""
        z = read_npz(path, "training-array cache")
        missing = [f.name for f in fields(cls) if f.name not in z]
        if missing:
            raise ValueError(f"{path}: not a training-array cache of ancsh (no {missing}); delete it to rebuild it")
        kw = {f.name: z[f.name] for f in fields(cls)}
        kw["num_parts"] = int(kw["num_parts"])
        return cls(**kw)


def read_npz(path, what: str) -> dict:
    """Every array of the ``.npz`` file ``path`` (no pickled objects); ``ValueError`` naming the file and ``what`` it
    should be (an array of Python objects, a file that is no ``.npz``) -- delete it to rebuild it."""
    try:
        with np.load(Path(path)) as z:
            return {k: z[k] for k in z.files}
    except (ValueError, OSError) as exc:
        raise ValueError(f"{path}: not a {what} of ancsh ({exc}); delete it to rebuild it") from exc


def naocs_rotations(points_cam: np.ndarray, naocs: np.ndarray, on_base: np.ndarray) -> np.ndarray:
    """Each frame's NAOCS orientation in the camera, ``R_cam_naocs``, from its base part's points.

    The base part is posed in the camera as the whole NAOCS is (no joint moves it), so a
    similarity fit (Umeyama) of its points' NAOCS coordinates to their camera coordinates gives
    the rotation. A frame whose base shows on fewer than 3 points (or degenerately) is fitted on
    all its points instead (exact at the rest state only).

    Parameters
    ----------
    points_cam : (B, N, 3)
        Camera frame, metres.
    naocs : (B, N, 3)
        The points' NAOCS coordinates.
    on_base : (B, N) bool
        Which points lie on the base part.

    Returns
    -------
    (B, 3, 3) float64
        ``points_cam ~= s R_cam_naocs naocs + t`` on the base.
    """
    from ...geometry.umeyama import umeyama_batch

    src, dst = np.asarray(naocs, dtype=np.float64), np.asarray(points_cam, dtype=np.float64)
    R, _, _, valid = umeyama_batch(src, dst, np.asarray(on_base, dtype=np.float64))
    if not np.all(valid):
        R_all, _, _, _ = umeyama_batch(src[~valid], dst[~valid])
        R[~valid] = R_all
    return R


def camera_joint_targets(points_cam: np.ndarray, association: np.ndarray, revolute: np.ndarray, axes_cam: np.ndarray, pivots_cam: np.ndarray) -> np.ndarray:
    """7-D joint vectors in the camera frame (the direct-voting baseline's targets).

    Parameters
    ----------
    points_cam : (N, 3) float64
        Metres.
    association : (N,) int
        0 = none, ``k + 1`` = joint ``k``.
    revolute : (K,) bool
    axes_cam, pivots_cam : (K, 3) float64
        Unit axes and pivots in the camera frame (metres).

    Returns
    -------
    (N, 7) float64
        Axis, unit direction from the point to the axis, distance (metres); zeros where
        not associated; prismatic joints fill the axis only.
    """
    out = np.zeros((points_cam.shape[0], 7))
    for k in range(len(revolute)):
        sel = association == k + 1
        if not np.any(sel):
            continue
        a = axes_cam[k]
        out[sel, :3] = a
        if revolute[k]:
            rel = pivots_cam[k] - points_cam[sel]
            to_axis = rel - np.outer(rel @ a, a)
            dist = np.linalg.norm(to_axis, axis=1)
            out[sel, 3:6] = np.where(dist[:, None] > 1e-12, to_axis / np.maximum(dist, 1e-12)[:, None], 0.0)
            out[sel, 6] = dist
    return out


def frame_arrays(points_cam, gt, num_points: int, rng) -> dict[str, np.ndarray]:
    """Sample ``num_points`` points of one frame and build their targets.

    Points are drawn without replacement when the frame has enough, with replacement otherwise.

    Parameters
    ----------
    points_cam : (P, 3) float64
        Observed points, camera frame, metres.
    gt : AncshGroundTruth
        Ground truth of those ``P`` points.
    num_points : int
    rng : numpy.random.Generator or int

    Returns
    -------
    dict of per-frame arrays keyed like :class:`TrainingArrays` fields (without the frame axis).
    """
    rng = check_generator(rng)
    points_cam = np.asarray(points_cam, dtype=np.float64)
    P = points_cam.shape[0]
    if P == 0:
        raise ValueError("points_cam: frame has no points")
    if gt.part_labels.shape != (P,):
        raise ValueError(f"gt: labels of {gt.part_labels.shape[0]} points for {P} observed points")
    idx = rng.choice(P, size=num_points, replace=P < num_points)
    labels = gt.part_labels[idx]
    association = gt.joint_association[idx]
    revolute = np.array([JointType(t) == JointType.REVOLUTE for t in gt.joint_types], dtype=bool)
    mask = np.zeros((num_points, 7))
    assoc_k = association - 1
    associated = association > 0
    mask[associated, :3] = 1.0
    rev_pts = associated & revolute[np.clip(assoc_k, 0, None)] if revolute.size else associated & False
    mask[rev_pts, 3:] = 1.0
    pts = points_cam[idx]
    return {
        "points": pts.astype(np.float32),
        "labels": labels.astype(np.int64),
        "npcs": gt.npcs[idx].astype(np.float32),
        "scale": np.asarray(gt.npcs_scale)[labels].astype(np.float32),
        "translation": np.asarray(gt.npcs_translation)[labels].astype(np.float32),
        "association": association.astype(np.int64),
        "joint": gt.joint_targets[idx].astype(np.float32),
        "joint_mask": mask.astype(np.float32),
        "joint_cam": camera_joint_targets(pts, association, revolute, gt.joint_axes_cam, gt.joint_pivots_cam).astype(np.float32),
        "revolute": revolute,
        "joint_parents": np.asarray(gt.joint_parents, dtype=np.int64),
        "joint_children": np.asarray(gt.joint_children, dtype=np.int64),
        "num_parts": gt.num_parts,
    }


def stack_frames(frames, num_points: int, rng, instances=None) -> TrainingArrays:
    """Pack ``(points_cam, gt)`` pairs into :class:`TrainingArrays`.

    Parameters
    ----------
    frames : iterable of (points_cam (P, 3), AncshGroundTruth)
    num_points : int
    rng : numpy.random.Generator or int
    instances : sequence of int, optional
        Instance id of each frame (default: all 0).
    """
    rng = check_generator(rng)
    per = [frame_arrays(p, gt, num_points, rng) for p, gt in frames]
    if not per:
        raise ValueError("frames: empty")
    kinds = {(d["num_parts"], tuple(d["revolute"].tolist()), tuple(d["joint_parents"].tolist()), tuple(d["joint_children"].tolist())) for d in per}
    if len(kinds) != 1:
        raise ValueError(f"frames: mixed kinematic structures {sorted(kinds)}")
    inst = np.zeros(len(per), dtype=np.int64) if instances is None else np.asarray(instances, dtype=np.int64)
    stacked = {k: np.stack([d[k] for d in per]) for k in TrainingArrays._PER_FRAME if k != "instance"}
    first = per[0]
    return TrainingArrays(**stacked, instance=inst, revolute=first["revolute"], joint_parents=first["joint_parents"],
                          joint_children=first["joint_children"], num_parts=int(first["num_parts"]))


def arrays_from_dataset(source, num_points: int | None = None, seed: int = 0) -> TrainingArrays:
    """Read HDF5 shards (:mod:`ancsh.data.dataset`) into :class:`TrainingArrays`, vectorised.

    Parameters
    ----------
    source : path or list of paths
        Shards or directories of shards of one kinematic structure.
    num_points : int, optional
        Points per frame; default: the shards' own count. Fewer points are subsampled
        (without replacement, seeded by ``seed``), more are drawn with replacement.
    seed : int
        Seed of that subsampling.
    """
    from ...data.dataset import FrameDataset

    ds = FrameDataset(source)
    kinds = {(len(r.part_names), tuple(r.joint_types), tuple(r.joint_parents.tolist()), tuple(r.joint_children.tolist()))
             for r in ds.readers}
    if len(kinds) != 1:
        raise ValueError(f"source: shards of different kinematic structures {sorted(kinds)}")
    M, types, parents, children = kinds.pop()
    revolute = np.array([JointType(t) == JointType.REVOLUTE for t in types], dtype=bool)
    keys = ["points", "part_labels", "npcs", "joint_association", "joint_targets", "npcs_scale", "npcs_translation",
            "joint_axes_cam", "joint_pivots_cam", "instance_index"]
    d = ds.arrays(keys)
    F, P = d["points"].shape[:2]
    if F == 0:
        raise ValueError("source: no frames")
    n = P if num_points is None else int(num_points)
    rng = np.random.default_rng(seed)
    if n == P:
        idx = np.broadcast_to(np.arange(P), (F, P))
    elif n < P:
        idx = np.argsort(rng.random((F, P)), axis=1)[:, :n]
    else:
        idx = rng.integers(0, P, size=(F, n))
    take = lambda a: np.take_along_axis(a, idx.reshape(F, n, *([1] * (a.ndim - 2))), axis=1)  # noqa: E731
    points = take(d["points"]).astype(np.float64)
    labels = take(d["part_labels"]).astype(np.int64)
    assoc = take(d["joint_association"]).astype(np.int64)
    scale = np.take_along_axis(d["npcs_scale"], labels, axis=1)
    translation = np.take_along_axis(d["npcs_translation"], labels[..., None], axis=1)
    mask = np.zeros((F, n, 7), dtype=np.float32)
    joint_cam = np.zeros((F, n, 7))
    for k in range(len(revolute)):
        sel = assoc == k + 1
        mask[sel, :3] = 1.0
        a = d["joint_axes_cam"][:, k]  # (F, 3)
        joint_cam[..., :3] += sel[..., None] * a[:, None, :]
        if revolute[k]:
            mask[sel, 3:] = 1.0
            rel = d["joint_pivots_cam"][:, k][:, None, :] - points
            to_axis = rel - (rel * a[:, None, :]).sum(-1, keepdims=True) * a[:, None, :]
            dist = np.linalg.norm(to_axis, axis=-1)
            unit = to_axis / np.maximum(dist, 1e-12)[..., None]
            joint_cam[..., 3:6] += sel[..., None] * unit
            joint_cam[..., 6] += sel * dist
    return TrainingArrays(
        points=points.astype(np.float32),
        labels=labels,
        npcs=take(d["npcs"]).astype(np.float32),
        scale=scale.astype(np.float32),
        translation=translation.astype(np.float32),
        association=assoc,
        joint=take(d["joint_targets"]).astype(np.float32),
        joint_mask=mask,
        joint_cam=joint_cam.astype(np.float32),
        instance=d["instance_index"].astype(np.int64),
        revolute=revolute,
        joint_parents=np.array(parents, dtype=np.int64),
        joint_children=np.array(children, dtype=np.int64),
        num_parts=int(M),
    )


def synthetic_arrays(num_frames: int, num_points: int, seed: int, *, num_parts: int = 2, joint_types="revolute", instances: int = 1) -> TrainingArrays:
    """Frames of seeded random box-part objects (:mod:`ancsh.model.synthetic`), no rendering.

    Surface points of all parts (no occlusion) -- for tests and smoke runs, not for real training.

    Parameters
    ----------
    num_frames, num_points : int
    seed : int
    num_parts : int
    joint_types : str or sequence
        Passed to :func:`ancsh.model.synthetic.random_articulated_model`.
    instances : int
        Number of distinct random objects (frames cycle through them).
    """
    from ...model.canonical import ancsh_ground_truth
    from ...model.synthetic import random_articulated_model, sample_frame

    rng = np.random.default_rng(seed)
    models = [random_articulated_model(rng, num_parts=num_parts, joint_types=joint_types) for _ in range(instances)]
    pairs, inst = [], []
    for i in range(num_frames):
        model = models[i % instances]
        fr = sample_frame(model, rng, points_per_part=num_points)
        pairs.append((fr.points_cam, ancsh_ground_truth(model, fr.q, fr.T_cam_base, fr.points_cam, fr.part_labels)))
        inst.append(i % instances)
    return stack_frames(pairs, num_points, rng, inst)
