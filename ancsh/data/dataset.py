"""HDF5 shards of depth frames with ANCSH ground truth: atomic writer and torch-free reader.

A shard holds ``F`` frames of one object source (a procedural category/split or one URDF
object) with ``N`` points, ``M`` parts and ``K`` joints each. Every per-frame field is a
dataset whose first axis is the frame; per-point fields are float32 (int16 labels) to keep
shards small, everything else float64. :class:`Frame` objects returned by the reader are
float64 throughout.

Per-frame datasets (``F`` leading axis omitted)
------------------------------------------------
=======================  ==========  ===========================================================
key                      shape       meaning
=======================  ==========  ===========================================================
points                   (N, 3) f4   sampled back-projected points, camera frame (metres)
part_labels              (N,) i2     part index ``0..M-1``
npcs                     (N, 3) f4   points in their part's NPCS
naocs                    (N, 3) f4   points in NAOCS
joint_association        (N,) i2     ``0`` none, ``k + 1`` joint ``k``
joint_targets            (N, 7) f4   NAOCS axis (3), unit direction to the axis (3), distance (1)
npcs_scale               (M,)        NPCS -> NAOCS scale ``s_j``
npcs_translation         (M, 3)      NPCS -> NAOCS translation ``t_j``
part_rotation            (M, 3, 3)   part pose ``T_cam_npcs``: rotation
part_translation         (M, 3)      ... translation (metres)
part_scale               (M,)        ... scale (metres per NPCS unit)
box_center               (M, 3)      amodal part box in the camera frame: centre (metres)
box_rotation             (M, 3, 3)   ... axes as columns
box_extents              (M, 3)      ... side lengths (metres)
naocs_rotation           (3, 3)      object pose ``T_cam_naocs`` (base part): rotation
naocs_translation        (3,)        ... translation
naocs_scale              ()          ... scale
joint_axes_naocs         (K, 3)      unit joint axes in NAOCS
joint_pivots_naocs       (K, 3)      joint pivots in NAOCS
joint_axes_cam           (K, 3)      unit joint axes in the camera frame
joint_pivots_cam         (K, 3)      joint pivots in the camera frame (metres)
joint_states             (K,)        ``q - rest`` (radians / metres)
joint_states_abs         (K,)        absolute ``q``
visibility               (M,)        visible-area ratio of each part (see :mod:`.render`)
part_pixels              (M,) i4     pixels showing each part in the noise-free render
intrinsics               (6,)        ``fx, fy, cx, cy, width, height``
cam_rotation             (3, 3)      camera pose ``T_cam_base``: rotation
cam_translation          (3,)        ... translation (metres)
instance_index           () i4       index of the instance in its split
instance_seed            () i8       the instance's generator seed (-1 for URDF objects)
instance_name            () str      the model's name
frame_index              () i8       index of the frame in the whole dataset
frame_seed               () i8       seed of the frame's random stream
sequence_index           () i8       sequence of the frame (-1: a single frame)
time_index               () i8       time index within its sequence (-1: a single frame)
=======================  ==========  ===========================================================

``sequence_index`` and ``time_index`` are optional on reading: shards written before them hold
single frames (both read as -1).

Shard attributes: ``format_version``, ``category``, ``split``, ``source``, ``part_names``,
``joint_names``, ``joint_types``, ``joint_parents``, ``joint_children`` (JSON lists),
``config`` (JSON of the generation settings), ``frame_start``, ``frame_count``,
``complete`` (set last). Datasets carry Fletcher-32 checksums, so a damaged chunk is
detected on reading.
"""

from __future__ import annotations

import io
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry.boxes import OrientedBox
from ..geometry.transforms import Sim3
from .render import Intrinsics

__all__ = [
    "FORMAT_VERSION",
    "CorruptShardError",
    "Frame",
    "FrameDataset",
    "ShardReader",
    "frame_record",
    "read_arrays",
    "read_frames",
    "shard_paths",
    "write_shard",
]

FORMAT_VERSION = 1

# key -> (stored dtype, per-frame shape template); "N", "M", "K" (points, parts, joints) are filled
# per shard, and every frame's record is checked against the template before it is written.
FIELDS = {
    "points": ("f4", ("N", 3)),
    "part_labels": ("i2", ("N",)),
    "npcs": ("f4", ("N", 3)),
    "naocs": ("f4", ("N", 3)),
    "joint_association": ("i2", ("N",)),
    "joint_targets": ("f4", ("N", 7)),
    "npcs_scale": ("f8", ("M",)),
    "npcs_translation": ("f8", ("M", 3)),
    "part_rotation": ("f8", ("M", 3, 3)),
    "part_translation": ("f8", ("M", 3)),
    "part_scale": ("f8", ("M",)),
    "box_center": ("f8", ("M", 3)),
    "box_rotation": ("f8", ("M", 3, 3)),
    "box_extents": ("f8", ("M", 3)),
    "naocs_rotation": ("f8", (3, 3)),
    "naocs_translation": ("f8", (3,)),
    "naocs_scale": ("f8", ()),
    "joint_axes_naocs": ("f8", ("K", 3)),
    "joint_pivots_naocs": ("f8", ("K", 3)),
    "joint_axes_cam": ("f8", ("K", 3)),
    "joint_pivots_cam": ("f8", ("K", 3)),
    "joint_states": ("f8", ("K",)),
    "joint_states_abs": ("f8", ("K",)),
    "visibility": ("f8", ("M",)),
    "part_pixels": ("i4", ("M",)),
    "intrinsics": ("f8", (6,)),
    "cam_rotation": ("f8", (3, 3)),
    "cam_translation": ("f8", (3,)),
    "instance_index": ("i4", ()),
    "instance_seed": ("i8", ()),
    "instance_name": ("str", ()),
    "frame_index": ("i8", ()),
    "frame_seed": ("i8", ()),
    "sequence_index": ("i8", ()),
    "time_index": ("i8", ()),
}

# Fields that shards written before them lack, with the value they read as.
OPTIONAL_FIELDS = {"sequence_index": -1, "time_index": -1}

_REQUIRED_ATTRS = (
    "format_version", "category", "split", "source", "part_names", "joint_names", "joint_types",
    "joint_parents", "joint_children", "config", "frame_start", "frame_count", "complete",
)


class CorruptShardError(ValueError):
    """A shard file cannot be read or fails its integrity checks (the message names it)."""


# --------------------------------------------------------------------------------------
# frames
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Frame:
    """One rendered frame with its ANCSH ground truth.

    Attributes
    ----------
    points : (N, 3) float64
        Sampled back-projected points in the camera frame (metres).
    gt : AncshGroundTruth
        Labels, NPCS, NAOCS, part poses, boxes, joints (``gt.part_labels`` labels ``points``).
    intrinsics : Intrinsics
    T_cam_base : Sim3
        Rigid camera pose (base frame -> camera).
    visibility : (M,) float64
        Visible-area ratio of each part.
    part_pixels : (M,) int64
        Pixels showing each part in the noise-free render.
    joint_states_abs : (K,) float64
        Absolute joint states (``gt.joint_states`` is relative to rest).
    category : str
        Category (``"urdf"`` for an uncategorised URDF object).
    instance : str
        The model's name.
    instance_index : int
        Index of the instance in its split.
    instance_seed : int
        Generator seed of the instance (-1 for URDF objects).
    frame_index : int
        Index of the frame in its dataset.
    seed : int
        Seed of the frame's random stream (reproduces the frame with the same settings).
    part_names, joint_names : tuple of str
    depth : (H, W) float64 or None
        The noisy depth image the points were sampled from (metres, 0 = no return), when the
        frame was generated with ``keep_depth=True``; shards do not store it.
    sequence_index : int
        Sequence the frame belongs to (:mod:`.sequences`); -1 for a single frame.
    time_index : int
        Its time index within the sequence; -1 for a single frame.
    """

    points: np.ndarray
    gt: object
    intrinsics: Intrinsics
    T_cam_base: Sim3
    visibility: np.ndarray
    part_pixels: np.ndarray
    joint_states_abs: np.ndarray
    category: str
    instance: str
    instance_index: int
    instance_seed: int
    frame_index: int
    seed: int
    part_names: tuple
    joint_names: tuple
    depth: np.ndarray | None = None
    sequence_index: int = -1
    time_index: int = -1

    @property
    def num_parts(self) -> int:
        return len(self.part_names)

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)


def frame_record(frame: Frame) -> dict:
    """The per-frame datasets of :data:`FIELDS` for ``frame`` (float64 / int64 / str values)."""
    gt = frame.gt
    M, K = frame.num_parts, frame.num_joints
    rec = {
        "points": frame.points,
        "part_labels": gt.part_labels,
        "npcs": gt.npcs,
        "naocs": gt.naocs,
        "joint_association": gt.joint_association,
        "joint_targets": gt.joint_targets,
        "npcs_scale": gt.npcs_scale,
        "npcs_translation": gt.npcs_translation,
        "part_rotation": np.stack([T.rotation for T in gt.T_cam_npcs]),
        "part_translation": np.stack([T.translation for T in gt.T_cam_npcs]),
        "part_scale": np.array([T.scale for T in gt.T_cam_npcs]),
        "box_center": np.stack([b.center for b in gt.boxes_cam]),
        "box_rotation": np.stack([b.rotation for b in gt.boxes_cam]),
        "box_extents": np.stack([b.extents for b in gt.boxes_cam]),
        "naocs_rotation": gt.T_cam_naocs.rotation,
        "naocs_translation": gt.T_cam_naocs.translation,
        "naocs_scale": np.float64(gt.T_cam_naocs.scale),
        "joint_axes_naocs": np.reshape(gt.joint_axes_naocs, (K, 3)),
        "joint_pivots_naocs": np.reshape(gt.joint_pivots_naocs, (K, 3)),
        "joint_axes_cam": np.reshape(gt.joint_axes_cam, (K, 3)),
        "joint_pivots_cam": np.reshape(gt.joint_pivots_cam, (K, 3)),
        "joint_states": np.reshape(gt.joint_states, (K,)),
        "joint_states_abs": np.reshape(frame.joint_states_abs, (K,)),
        "visibility": np.reshape(frame.visibility, (M,)),
        "part_pixels": np.reshape(frame.part_pixels, (M,)),
        "intrinsics": frame.intrinsics.as_array(),
        "cam_rotation": frame.T_cam_base.rotation,
        "cam_translation": frame.T_cam_base.translation,
        "instance_index": np.int64(frame.instance_index),
        "instance_seed": np.int64(frame.instance_seed),
        "instance_name": str(frame.instance),
        "frame_index": np.int64(frame.frame_index),
        "frame_seed": np.int64(frame.seed),
        "sequence_index": np.int64(frame.sequence_index),
        "time_index": np.int64(frame.time_index),
    }
    return rec


def _check_record_shapes(record: dict, dims: dict, name: str) -> None:
    """Raise ``ValueError`` when a field of ``record`` does not have its :data:`FIELDS` shape."""
    for key, (dtype, template) in FIELDS.items():
        if dtype == "str":
            continue
        expected = tuple(dims[d] if isinstance(d, str) else d for d in template)
        actual = np.shape(record[key])
        if actual != expected:
            raise ValueError(f"{name}.{key}: expected shape {expected}, got {actual}")


def _shard_meta(frame: Frame) -> dict:
    gt = frame.gt
    return {
        "category": frame.category,
        "part_names": json.dumps(list(frame.part_names)),
        "joint_names": json.dumps(list(frame.joint_names)),
        "joint_types": json.dumps([str(getattr(t, "value", t)) for t in gt.joint_types]),
        "joint_parents": json.dumps([int(x) for x in gt.joint_parents]),
        "joint_children": json.dumps([int(x) for x in gt.joint_children]),
    }


# --------------------------------------------------------------------------------------
# writer
# --------------------------------------------------------------------------------------
def write_shard(path, frames, *, split: str, source: str, config: str, frame_start: int) -> Path:
    """Write ``frames`` to the HDF5 shard ``path`` atomically.

    The data go to ``<path>.tmp<pid>``, which is flushed, fsync'ed and renamed onto
    ``path``; a crash leaves either the old state or a stray temporary file, never a
    half-written ``path``.

    Parameters
    ----------
    path : str or Path
    frames : sequence of Frame
        At least one; all with the same point count, part and joint structure.
    split : str
        Split name stored as an attribute (``"-"`` for URDF objects).
    source : str
        ``"procedural"`` or ``"urdf:<path>"``.
    config : str
        JSON of the generation settings (used to verify shards on resume).
    frame_start : int
        Dataset index of the first frame.
    """
    import h5py

    path = Path(path)
    frames = list(frames)
    if not frames:
        raise ValueError("frames: a shard needs at least one frame")
    meta = _shard_meta(frames[0])
    records = []
    for i, fr in enumerate(frames):
        if not isinstance(fr, Frame):
            raise ValueError(f"frames[{i}]: expected a Frame, got {type(fr).__name__}")
        if _shard_meta(fr) != meta or len(fr.points) != len(frames[0].points):
            raise ValueError(f"frames[{i}]: category, part/joint structure or point count differs from frames[0]")
        record = frame_record(fr)
        _check_record_shapes(record, {"N": len(fr.points), "M": fr.num_parts, "K": fr.num_joints}, f"frames[{i}]")
        records.append(record)
    buffer = io.BytesIO()  # built in memory: a full disk then fails one plain write, not inside HDF5 (a segfault)
    with h5py.File(buffer, "w") as f:
        for key, (dtype, _) in FIELDS.items():
            values = [r[key] for r in records]
            if dtype == "str":
                data = np.array(values, dtype=h5py.string_dtype())
                f.create_dataset(key, data=data).attrs["sha256"] = _digest(values)
                continue
            data = np.stack([np.asarray(v) for v in values]).astype(dtype)
            kwargs = {}
            if data.size:
                kwargs = {"chunks": (min(len(data), 64),) + data.shape[1:], "fletcher32": True}
            f.create_dataset(key, data=data, **kwargs).attrs["sha256"] = _digest(data)
        f.attrs.update(meta)
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["split"] = split
        f.attrs["source"] = source
        f.attrs["config"] = config
        f.attrs["frame_start"] = int(frame_start)
        f.attrs["frame_count"] = len(frames)
        f.attrs["complete"] = True
    tmp = path.with_name(f"{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as out:
            out.write(buffer.getbuffer())
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, path)
        _fsync_dir(path.parent)
    except OSError as exc:  # full disk, read-only folder: the complete shards written before stay
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def _digest(data) -> str:
    """SHA-256 of a dataset's values: array bytes (C order), or strings joined by NUL."""
    import hashlib

    if isinstance(data, np.ndarray) and data.dtype != object:
        return hashlib.sha256(np.ascontiguousarray(data).tobytes()).hexdigest()
    items = [x if isinstance(x, bytes) else str(x).encode() for x in data]
    return hashlib.sha256(b"\0".join(items)).hexdigest()


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:  # pragma: no cover - platforms without directory fds
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)


# --------------------------------------------------------------------------------------
# reader
# --------------------------------------------------------------------------------------
class ShardReader:
    """Random access to the frames of one shard (no torch).

    The whole shard is read (and checksum-verified) on first data access and kept in
    memory; opening only reads the attributes.

    Parameters
    ----------
    path : str or Path

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    CorruptShardError
        Naming ``path``, if the file is not a complete shard of this format or a chunk
        fails its checksum.
    """

    def __init__(self, path):
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"shard {self.path}: no such file")
        self._data = None
        self.attrs = _read_attrs(self.path)
        self.category = str(self.attrs["category"])
        self.split = str(self.attrs["split"])
        self.source = str(self.attrs["source"])
        self.part_names = tuple(json.loads(self.attrs["part_names"]))
        self.joint_names = tuple(json.loads(self.attrs["joint_names"]))
        self.joint_types = tuple(json.loads(self.attrs["joint_types"]))
        self.joint_parents = np.array(json.loads(self.attrs["joint_parents"]), dtype=np.int64)
        self.joint_children = np.array(json.loads(self.attrs["joint_children"]), dtype=np.int64)
        self.config = json.loads(self.attrs["config"])
        self.frame_start = int(self.attrs["frame_start"])
        self._len = int(self.attrs["frame_count"])

    def __len__(self) -> int:
        return self._len

    def __repr__(self) -> str:
        return f"ShardReader({str(self.path)!r}, category={self.category!r}, frames={self._len})"

    def arrays(self, keys=None) -> dict:
        """``{key: array}`` with the frame axis first, in the stored dtypes (all keys by default)."""
        keys = list(FIELDS) if keys is None else list(keys)
        for k in keys:
            if k not in FIELDS:
                raise KeyError(f"keys: unknown field {k!r}; fields: {list(FIELDS)}")
        if self._data is None:  # read just these fields, do not cache
            return _read_datasets(self.path, keys, expected_len=self._len)
        return {k: self._data[k] for k in keys}

    def release(self) -> None:
        """Drop the in-memory copy of the shard's data (it is re-read on the next access)."""
        self._data = None

    def _load(self) -> dict:
        if self._data is None:
            self._data = _read_datasets(self.path, list(FIELDS), expected_len=self._len)
        return self._data

    def __getitem__(self, index) -> Frame:
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
            raise TypeError(f"index: expected an int, got {type(index).__name__}")
        i = int(index)
        if i < 0:
            i += self._len
        if not 0 <= i < self._len:
            raise IndexError(f"index: {index} out of range for {self._len} frames in {self.path.name}")
        d = self._load()
        return self._frame(d, i)

    def __iter__(self):
        for i in range(self._len):
            yield self[i]

    def _frame(self, d: dict, i: int) -> Frame:
        from ..model.articulated import JointType
        from ..model.canonical import AncshGroundTruth

        f64 = lambda k: np.array(d[k][i], dtype=np.float64)  # noqa: E731
        M = len(self.part_names)
        K = len(self.joint_names)
        poses = tuple(
            Sim3(d["part_rotation"][i, j], d["part_translation"][i, j], float(d["part_scale"][i, j])) for j in range(M)
        )
        boxes = tuple(
            OrientedBox(d["box_center"][i, j], d["box_rotation"][i, j], d["box_extents"][i, j]) for j in range(M)
        )
        gt = AncshGroundTruth(
            part_labels=np.array(d["part_labels"][i], dtype=np.int64),
            npcs=f64("npcs"),
            naocs=f64("naocs"),
            npcs_scale=f64("npcs_scale"),
            npcs_translation=f64("npcs_translation"),
            T_cam_npcs=poses,
            boxes_cam=boxes,
            joint_types=tuple(JointType(t) for t in self.joint_types),
            joint_parents=self.joint_parents.copy(),
            joint_children=self.joint_children.copy(),
            joint_axes_naocs=f64("joint_axes_naocs").reshape(K, 3),
            joint_pivots_naocs=f64("joint_pivots_naocs").reshape(K, 3),
            joint_axes_cam=f64("joint_axes_cam").reshape(K, 3),
            joint_pivots_cam=f64("joint_pivots_cam").reshape(K, 3),
            joint_states=f64("joint_states").reshape(K),
            joint_association=np.array(d["joint_association"][i], dtype=np.int64),
            joint_targets=f64("joint_targets"),
            T_cam_naocs=Sim3(d["naocs_rotation"][i], d["naocs_translation"][i], float(d["naocs_scale"][i])),
        )
        name = d["instance_name"][i]
        return Frame(
            points=f64("points"),
            gt=gt,
            intrinsics=Intrinsics.from_array(d["intrinsics"][i]),
            T_cam_base=Sim3(d["cam_rotation"][i], d["cam_translation"][i]),
            visibility=f64("visibility"),
            part_pixels=np.array(d["part_pixels"][i], dtype=np.int64),
            joint_states_abs=f64("joint_states_abs").reshape(K),
            category=self.category,
            instance=name.decode() if isinstance(name, bytes) else str(name),
            instance_index=int(d["instance_index"][i]),
            instance_seed=int(d["instance_seed"][i]),
            frame_index=int(d["frame_index"][i]),
            seed=int(d["frame_seed"][i]),
            part_names=self.part_names,
            joint_names=self.joint_names,
            sequence_index=int(d["sequence_index"][i]),
            time_index=int(d["time_index"][i]),
        )


def _read_attrs(path: Path) -> dict:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            attrs = {k: f.attrs[k] for k in f.attrs}
    except Exception as exc:  # noqa: BLE001 - OSError, KeyError, RuntimeError, ... from a damaged file
        raise CorruptShardError(f"shard {path}: cannot be opened as HDF5 (truncated or damaged): {exc}") from None
    missing = [k for k in _REQUIRED_ATTRS if k not in attrs]
    if missing:
        raise CorruptShardError(f"shard {path}: incomplete (missing attributes {missing})")
    if not bool(attrs["complete"]):
        raise CorruptShardError(f"shard {path}: marked incomplete")
    if int(attrs["format_version"]) != FORMAT_VERSION:
        raise CorruptShardError(
            f"shard {path}: format version {int(attrs['format_version'])}, this reader reads {FORMAT_VERSION}"
        )
    return {k: (v.decode() if isinstance(v, bytes) else v) for k, v in attrs.items()}


def _read_datasets(path: Path, keys: list, expected_len: int) -> dict:
    import h5py

    out = {}
    try:
        with h5py.File(path, "r") as f:
            for k in keys:
                if k not in f and k in OPTIONAL_FIELDS:
                    out[k] = np.full(expected_len, OPTIONAL_FIELDS[k], dtype=FIELDS[k][0])
                    continue
                if k not in f:
                    raise CorruptShardError(f"shard {path}: dataset {k!r} is missing")
                data = f[k][()]
                if len(data) != expected_len:
                    raise CorruptShardError(
                        f"shard {path}: dataset {k!r} has {len(data)} frames, attributes say {expected_len}"
                    )
                stored = f[k].attrs.get("sha256")
                if stored is not None:  # shards written before the digests have Fletcher-32 only
                    stored = stored.decode() if isinstance(stored, bytes) else str(stored)
                    if _digest(data) != stored:
                        raise CorruptShardError(f"shard {path}: dataset {k!r} fails its SHA-256 check (damaged bytes)")
                if FIELDS[k][0] == "str":
                    data = np.array([x.decode() if isinstance(x, bytes) else str(x) for x in data], dtype=object)
                out[k] = data
    except CorruptShardError:
        raise
    except Exception as exc:  # noqa: BLE001 - h5py raises OSError, KeyError, RuntimeError, ... on damaged files
        raise CorruptShardError(f"shard {path}: damaged data ({type(exc).__name__}: {exc})") from None
    return out


def shard_paths(source) -> list[Path]:
    """Shard files of ``source``: a shard path, a directory (every ``*.h5``, sorted) or a list."""
    if isinstance(source, (list, tuple)):
        out = []
        for s in source:
            out.extend(shard_paths(s))
        return out
    p = Path(source)
    if p.is_dir():
        paths = sorted(p.glob("*.h5"))
        if not paths:
            raise FileNotFoundError(f"{p}: directory holds no *.h5 shards")
        return paths
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such shard or directory")
    return [p]


class FrameDataset:
    """Frames of several shards as one sequence (no torch; wrap it for a DataLoader).

    Parameters
    ----------
    source : str, Path or list
        A shard, a directory of shards or a list of either.
    max_loaded : int
        Shards kept in memory at once for :meth:`__getitem__` (least recently used are
        released), so iterating over a large dataset needs little memory.
    skip_corrupt : bool
        Leave out shards that cannot be opened or fail their checks (listed in :attr:`skipped`
        as ``(path, reason)``) instead of raising :class:`CorruptShardError`, so one bad shard
        does not block the intact ones. Data damage is found when a shard's data are read
        (:meth:`arrays` checks every shard; :meth:`verify` does it up front).
    """

    def __init__(self, source, *, max_loaded: int = 2, skip_corrupt: bool = False):
        if isinstance(max_loaded, bool) or not isinstance(max_loaded, int) or max_loaded < 1:
            raise ValueError(f"max_loaded: expected an int >= 1, got {max_loaded!r}")
        self.skip_corrupt = bool(skip_corrupt)
        self.skipped: list = []
        self._max_loaded = max_loaded
        readers = []
        for p in shard_paths(source):
            try:
                readers.append(ShardReader(p))
            except CorruptShardError as exc:
                if not self.skip_corrupt:
                    raise
                self.skipped.append((p, str(exc)))
        self._set_readers(readers)

    def _set_readers(self, readers) -> None:
        self.readers = readers
        self._offsets = np.cumsum([0] + [len(r) for r in self.readers])
        self._loaded: list[int] = []

    def __len__(self) -> int:
        return int(self._offsets[-1])

    def __getitem__(self, index) -> Frame:
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
            raise TypeError(f"index: expected an int, got {type(index).__name__}")
        i = int(index)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"index: {index} out of range for {len(self)} frames")
        s = int(np.searchsorted(self._offsets, i, side="right") - 1)
        if s in self._loaded:
            self._loaded.remove(s)
        self._loaded.append(s)
        while len(self._loaded) > self._max_loaded:
            self.readers[self._loaded.pop(0)].release()
        return self.readers[s][i - int(self._offsets[s])]

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]

    def arrays(self, keys=None) -> dict:
        """``{key: array}`` over all shards, concatenated along the frame axis (checksums verified)."""
        return _concat(self._read_each(lambda r: r.arrays(keys)))

    def verify(self) -> list:
        """Read every shard's data once (checksums); with ``skip_corrupt`` drop the damaged ones.

        Returns :attr:`skipped`.
        """
        self._read_each(lambda r: r.arrays() and None)
        return self.skipped

    def _read_each(self, read) -> list:
        out, good = [], []
        for r in self.readers:
            try:
                out.append(read(r))
                good.append(r)
            except CorruptShardError as exc:
                if not self.skip_corrupt:
                    raise
                self.skipped.append((r.path, str(exc)))
        if len(good) != len(self.readers):
            self._set_readers(good)
        return out


def _concat(parts: list) -> dict:
    if not parts:
        return {}
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def read_arrays(source, keys=None) -> dict:
    """Bulk access for training: ``{key: (F_total, ...) array}`` in stored dtypes.

    Parameters
    ----------
    source : str, Path or list
        Shards or directories (see :func:`shard_paths`).
    keys : iterable of str, optional
        Fields of :data:`FIELDS`; all by default.
    """
    return FrameDataset(source).arrays(keys)


def read_frames(source) -> list[Frame]:
    """Every frame of ``source`` as :class:`Frame` objects (small datasets / evaluation)."""
    return list(FrameDataset(source))
