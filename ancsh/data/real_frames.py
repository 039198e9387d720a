"""Real sensor frames with measured truth: one folder per frame (``../shared/data/real_frames/<name>/``).

A folder holds ``depth.png`` (uint16, millimetres, registered to the colour image), ``K.json``
(``fx, fy, cx, cy, width, height``), an optional ``color.png``, masks (``mask_*.png``, nonzero =
object) and ``truth.json`` (schema ``real-frame-truth/1``)::

    {"schema": "real-frame-truth/1",
     "objects": [{"category": "box", "mask": "mask_box.png", "part_masks": {"lid": "mask_lid.png"},
                  "joint_state_deg": 127.5, "uncertainty_deg": 3.0}],
     "files": {"depth": "depth.png", "color": "color.png", "intrinsics": "K.json"}}

``objects`` lists every articulated object of a known category in view; an empty list says that
nothing of any category is there (a negative frame). ``joint_state_deg`` is the opening in the
category's convention (0 = closed); ``files`` is needed only when the files have other names.

:func:`load_real_frame` reads and checks a folder; every problem is a ``ValueError`` naming the
folder and the file or field.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .images import read_depth, read_intrinsics, read_mask, read_rgb
from .render import Intrinsics

__all__ = ["SCHEMA", "RealFrame", "RealObject", "default_real_frame_folders", "load_real_frame"]

SCHEMA = "real-frame-truth/1"
_DEFAULT_FILES = {"depth": "depth.png", "color": "color.png", "intrinsics": "K.json"}


@dataclass(frozen=True)
class RealObject:
    """One object in a real frame, as measured.

    Attributes
    ----------
    category : str
    mask : (H, W) bool
        Its pixels.
    mask_file : str
    part_masks : dict
        Part name -> (H, W) bool, where the frame gives them.
    joint_state_deg : float or None
        The opening (degrees, the category's convention: 0 = closed), when measured.
    uncertainty_deg : float or None
        The measurement's uncertainty (degrees).
    """

    category: str
    mask: np.ndarray
    mask_file: str
    part_masks: dict = field(default_factory=dict)
    joint_state_deg: float | None = None
    uncertainty_deg: float | None = None


@dataclass(frozen=True)
class RealFrame:
    """A real depth frame and what is known about it.

    Attributes
    ----------
    name : str
        The folder's name.
    folder : Path
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
    rgb : (H, W, 3) uint8 or None
    objects : tuple of RealObject
        Empty: no object of any category is in view.
    """

    name: str
    folder: Path
    depth: np.ndarray
    intrinsics: Intrinsics
    rgb: np.ndarray | None
    objects: tuple = ()

    @property
    def negative(self) -> bool:
        """No object of any category is in view."""
        return not self.objects


def _number_or_none(value, where: str):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ValueError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _file(folder: Path, name, where: str) -> Path:
    """``folder / name`` for a plain file name inside the folder (no paths that leave it)."""
    if not isinstance(name, str) or not name or Path(name).name != name or name in (".", ".."):
        raise ValueError(f"{where}: expected a file name inside {folder}, got {name!r}")
    return folder / name


def load_real_frame(folder, *, depth_scale: float = 0.001) -> RealFrame:
    """Read one real-frame folder (module docstring).

    Parameters
    ----------
    folder : str or Path
    depth_scale : float
        Metres per depth-PNG unit (default millimetres).

    Raises
    ------
    ValueError
        A missing or malformed file or field, naming the folder and what is wrong.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"real frame: {folder} is not a folder")
    truth_path = folder / "truth.json"
    if not truth_path.is_file():
        raise ValueError(f"real frame {folder.name}: no truth.json in {folder}")
    try:
        truth = json.loads(truth_path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"real frame {folder.name}: truth.json is not JSON: {exc}") from None
    if not isinstance(truth, dict) or truth.get("schema") != SCHEMA:
        got = truth.get("schema") if isinstance(truth, dict) else type(truth).__name__
        raise ValueError(f"real frame {folder.name}: truth.json schema: expected {SCHEMA!r}, got {got!r}")
    files = dict(_DEFAULT_FILES)
    given = truth.get("files", {})
    if not isinstance(given, dict) or set(given) - set(_DEFAULT_FILES):
        raise ValueError(f"real frame {folder.name}: truth.json files: expected keys among {sorted(_DEFAULT_FILES)}, "
                         f"got {given!r}")
    files.update(given)
    where = f"real frame {folder.name}"
    intr = read_intrinsics(_file(folder, files["intrinsics"], f"{where}: files.intrinsics"), argument=f"{where}: intrinsics")
    depth = read_depth(_file(folder, files["depth"], f"{where}: files.depth"), depth_scale=depth_scale,
                       argument=f"{where}: depth", shape=(intr.height, intr.width))
    color = _file(folder, files["color"], f"{where}: files.color")
    rgb = read_rgb(color, depth.shape, argument=f"{where}: color") if color.is_file() else None
    objects = truth.get("objects")
    if not isinstance(objects, list):
        raise ValueError(f"{where}: truth.json objects: expected a list (empty = nothing in view), got {objects!r}")
    out = []
    for i, o in enumerate(objects):
        ow = f"{where}: objects[{i}]"
        if not isinstance(o, dict) or not isinstance(o.get("category"), str) or not o["category"]:
            raise ValueError(f"{ow}: expected an object with a 'category' and a 'mask', got {o!r}")
        mask = read_mask(_file(folder, o.get("mask"), f"{ow}.mask"), depth.shape, argument=f"{ow}.mask")
        if not mask.any():
            raise ValueError(f"{ow}.mask: {o['mask']} marks no pixel")
        parts = o.get("part_masks", {})
        if not isinstance(parts, dict):
            raise ValueError(f"{ow}.part_masks: expected {{part name: mask file}}, got {parts!r}")
        part_masks = {str(k): read_mask(_file(folder, v, f"{ow}.part_masks.{k}"), depth.shape, argument=f"{ow}.part_masks.{k}")
                      for k, v in parts.items()}
        out.append(RealObject(o["category"], mask, o["mask"], part_masks,
                              _number_or_none(o.get("joint_state_deg"), f"{ow}.joint_state_deg"),
                              _number_or_none(o.get("uncertainty_deg"), f"{ow}.uncertainty_deg")))
    return RealFrame(folder.name, folder, depth, intr, rgb, tuple(out))


def default_real_frame_folders() -> list[Path]:
    """Every folder of ``<shared data>/real_frames`` holding a ``truth.json`` (sorted; empty without the data)."""
    from .paths import shared_data_dir

    root = shared_data_dir() / "real_frames"
    if not root.is_dir():
        return []
    return sorted(p for p in root.iterdir() if p.is_dir() and (p / "truth.json").is_file())
