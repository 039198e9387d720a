"""Depth-image sequences in, one JSON line per frame out (``ancsh track``).

- :func:`depth_files`: the frames of a folder (``.png`` 16-bit millimetres / ``.npy`` metres), in
  natural order (``frame_2`` before ``frame_10``).
- :func:`track_files`: reads each frame, checks it against the intrinsics, isolates the object
  (a mask file, or :func:`ancsh.data.isolate.isolate_object`), samples points and steps a tracker.
  A frame that cannot be read, or whose size differs from the intrinsics, is a ``lost`` record
  naming the problem and the file -- the track goes on with the next frame; an empty frame (or
  one without the object) is ``lost`` through the tracker (``too_few_points``), which
  re-initialises when the object returns.
- :class:`JsonLinesWriter`: appends each record as one line and flushes it to disk at once
  (``fsync``), so an interrupted run keeps every frame written before it; an existing output
  file is never overwritten. The closing summary is written atomically next to it.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

__all__ = ["JsonLinesWriter", "depth_files", "track_depth", "track_files", "track_files_multi"]

#: The schema of a multi-object track line (:func:`track_files_multi`, ``docs/json_schema.md``).
MULTI_SCHEMA = "ancsh.track/2"

_SUFFIXES = (".png", ".npy")


def depth_files(folder) -> list[Path]:
    """The depth frames of ``folder`` (``.png`` / ``.npy``), in natural order.

    Raises
    ------
    FileNotFoundError
        ``folder`` does not exist.
    ValueError
        It is not a folder, or holds no depth frame.
    """
    folder = Path(folder)
    if not folder.exists():
        raise FileNotFoundError(f"depth: no such folder {folder}")
    if not folder.is_dir():
        raise ValueError(f"depth: expected a folder of depth frames (.png / .npy), got the file {folder}")
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in _SUFFIXES]
    if not files:
        raise ValueError(f"depth: {folder} holds no depth frame (.png 16-bit millimetres or .npy metres)")
    key = lambda p: [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", p.name)]  # noqa: E731
    return sorted(files, key=key)


class JsonLinesWriter:
    """Append-only JSON-lines output, each line on disk before the next frame is processed.

    Parameters
    ----------
    path : str or Path
        A new file (its folder is created); an existing one is refused.
    """

    def __init__(self, path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._f = open(self.path, "x", encoding="utf-8")
        except FileExistsError:
            raise ValueError(f"out: {self.path} exists; choose a new file (nothing is overwritten)") from None
        self.count = 0

    def write(self, record: dict) -> None:
        self._f.write(json.dumps(record, allow_nan=False) + "\n")
        self._f.flush()
        os.fsync(self._f.fileno())
        self.count += 1

    def close(self) -> None:
        self._f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def _lost_record(index: int, path: Path, message: str, num_joints: int) -> dict:
    return {"frame": index, "file": path.name, "status": "lost", "message": message, "source": "none", "fit_status": None,
            "joint_states": [None] * num_joints, "joint_states_std": None, "part_poses": [], "iterations": 0, "time_ms": 0.0}


def _emit(rec: dict, records: list, writer, progress) -> None:
    """Keep a frame's record, write it (``writer``) and show it (``progress``)."""
    records.append(rec)
    if writer is not None:
        writer.write(rec)
    if progress is not None:
        progress(rec)


def track_files(files, intrinsics, tracker, writer: JsonLinesWriter | None = None, *, category=None,
                mask_dir=None, isolate: bool = True, max_depth: float | None = None, num_points: int = 1024, seed: int = 0,
                num_joints: int = 0, progress=None) -> list[dict]:
    """Track the object through depth frames; one record per frame (written at once when ``writer`` is given).

    Parameters
    ----------
    files : sequence of Path
        The frames, in order (:func:`depth_files`).
    intrinsics : Intrinsics
        Of every frame; a frame of another size is a ``lost`` record.
    tracker : CategoryTracker or InstanceTracker
    writer : JsonLinesWriter, optional
    category : str, Path or Category, optional
        Its size range sizes :func:`~ancsh.data.isolate.isolate_object` (needed when isolating without masks); a
        name, spec file or folder is loaded once.
    mask_dir : str or Path, optional
        Object masks with the frames' names (``.png`` / ``.npy``); they replace isolation.
    isolate : bool
        Isolate the object in each frame without a mask (plane removal + clustering); ``False``
        uses every valid pixel.
    max_depth : float, optional
        Metres.
    num_points : int
        Points sampled per frame.
    seed : int
    num_joints : int
        Joint count (for the records of unreadable frames).
    progress : callable, optional
        Called with each record.

    Returns
    -------
    list of dict
        The records (see ``docs/json_schema.md``, ``ancsh.track/1``).
    """
    from ..data.images import read_depth, read_mask

    if isolate and mask_dir is None and category is None:
        raise ValueError("category: isolating the object needs its category (or give masks, or isolate=False)")
    category = _loaded(category, tracker)
    records = []
    for i, path in enumerate(files):
        path = Path(path)
        try:
            depth = read_depth(path, argument=f"frame {i}", shape=(intrinsics.height, intrinsics.width))
            mask = None
            if mask_dir is not None:
                mpath = next((Path(mask_dir) / (path.stem + s) for s in _SUFFIXES if (Path(mask_dir) / (path.stem + s)).is_file()),
                             None)
                if mpath is None:
                    raise ValueError(f"frame {i}: no mask {path.stem}.png/.npy in {mask_dir}")
                mask = read_mask(mpath, depth.shape, argument=f"mask of frame {i}")
        except (ValueError, FileNotFoundError, OSError) as exc:
            rec = _lost_record(i, path, f"unreadable frame: {exc}", num_joints)
        else:
            rec = track_depth(depth, intrinsics, tracker, i, mask=mask, category=category, isolate=isolate,
                              max_depth=max_depth, num_points=num_points, seed=seed)
            rec["file"] = path.name
        _emit(rec, records, writer, progress)
    return records


def track_files_multi(files, intrinsics, tracker, writer: JsonLinesWriter | None = None, *, progress=None,
                      on_frame=None) -> list[dict]:
    """Track every object of the category through depth frames (a
    :class:`~ancsh.tracking.multi.MultiObjectTracker`); one record per frame (``ancsh.track/2``: every live track's id,
    status, filtered pose and joint states), written at once when ``writer`` is given. A frame that cannot be read, or
    whose size differs from the intrinsics, is a record with an ``error`` and no tracks (the tracker is not stepped).
    ``on_frame(index, depth, MultiFrame)`` is called after each stepped frame (pictures).
    """
    from ..data.images import read_depth

    records = []
    for i, path in enumerate(files):
        path = Path(path)
        try:
            depth = read_depth(path, argument=f"frame {i}", shape=(intrinsics.height, intrinsics.width))
        except (ValueError, FileNotFoundError, OSError) as exc:
            rec = {"schema": MULTI_SCHEMA, "frame": i, "file": path.name, "tracks": [], "ended": [], "detected": False,
                   "detections": 0, "stages_ms": {}, "time_ms": 0.0, "error": f"unreadable frame: {exc}"}
        else:
            stepped = tracker.step(depth)
            rec = {"schema": MULTI_SCHEMA, **stepped.to_dict()}
            rec["frame"], rec["file"] = i, path.name
            if on_frame is not None:
                on_frame(i, depth, stepped)
        _emit(rec, records, writer, progress)
    return records


def _loaded(category, tracker):
    """``category`` loaded once (:func:`~ancsh.tracking.cold_fit.tracked_category`; ``None`` stays ``None``)."""
    from .cold_fit import tracked_category

    return tracked_category(category, getattr(tracker, "provider", None))


def track_depth(depth, intrinsics, tracker, index: int, *, mask=None, category=None, isolate: bool = True,
                max_depth: float | None = None, num_points: int = 1024, seed: int = 0) -> dict:
    """One frame of a track: the object's pixels (``mask``, or isolation seeded like ``predict``'s, or every valid
    pixel), ``num_points`` of them sampled (seed ``seed + index``) and the tracker stepped; the frame's record
    (``ancsh.track/1`` without its ``file``).

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
    tracker : CategoryTracker or InstanceTracker
    index : int
        The frame's number in the sequence.
    category : str, Path or Category, optional
        Its size range sizes the isolation (a loaded Category: nothing is looked up).
    """
    from ..learned.inference.predict import depth_to_points
    from ..solvers.types import Observation

    if mask is None and isolate and np.any(depth > 0):
        from ..data.isolate import isolate_object
        from ..learned.inference.predict import ISOLATION_SEED

        # seeded like predict's isolation: the segments are a function of the image, not of the seed
        category = _loaded(category, tracker)
        if category is None:
            raise ValueError("category: isolating the object needs its category (or give a mask, or isolate=False)")
        mask = isolate_object(depth, intrinsics, category.size_range, max_depth=max_depth, rng=ISOLATION_SEED).mask
    try:
        points = depth_to_points(depth, intrinsics, mask=mask, max_depth=max_depth, num_points=num_points,
                                 rng=seed + index)[0]
    except ValueError:  # no valid pixel: an empty frame
        points = np.zeros((0, 3))
    rec = tracker.step(Observation(points)).to_dict()
    rec["frame"] = index
    return rec
