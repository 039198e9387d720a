"""Reading user images: depth (16-bit PNG or ``.npy``), masks, pinhole intrinsics JSON; and the pixel bounds of a
mask (:func:`mask_bounds`).

One reader for every command (``ancsh predict`` and ``ancsh fit-cad`` accept the same files). Each
error is a ``ValueError`` (``FileNotFoundError`` for a missing file) naming the option and the file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .render import Intrinsics

__all__ = ["MAX_PLAUSIBLE_DEPTH", "mask_bounds", "read_depth", "read_mask", "read_rgb", "read_intrinsics", "read_json"]

#: Median valid depth (metres) above which a ``.npy`` depth image is taken to be in millimetres.
MAX_PLAUSIBLE_DEPTH = 20.0

_DEPTH_PNG_MODES = ("I;16", "I;16B", "I;16L", "I")
#: Largest image (pixels) read: far beyond any depth sensor (8192 x 8192); a file claiming more is refused before
#: its pixels are decoded or allocated (a crafted header can claim 20000 x 20000 or 100000 x 100000).
MAX_IMAGE_PIXELS = 8192 * 8192


def _check_shape(path: Path, argument: str, claimed: tuple, shape: tuple | None) -> None:
    """Refuse a file whose header claims another ``(H, W)`` than ``shape`` (the intrinsics'), before decoding it."""
    if shape is not None and tuple(int(x) for x in claimed) != tuple(int(x) for x in shape):
        size = f"{claimed[1]}x{claimed[0]}" if len(claimed) == 2 else f"of shape {tuple(claimed)}"
        raise ValueError(f"{argument}: {path} is {size} pixels, the intrinsics say {shape[1]}x{shape[0]} "
                         "(mismatched intrinsics file?); not read")


def _open_image(path: Path, argument: str, convert: str | None = None, shape: tuple | None = None) -> tuple[np.ndarray, str]:
    from PIL import Image, UnidentifiedImageError

    try:
        im = Image.open(path)  # reads the header only
    except Image.DecompressionBombError:  # PIL's own limit, met in the header before ours
        raise ValueError(f"{argument}: {path} claims more pixels than any depth image ({MAX_IMAGE_PIXELS} at "
                         "most); not read") from None
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as exc:
        raise ValueError(f"{argument}: {path} is not a readable image ({type(exc).__name__})") from None
    with im:
        width, height = im.size
        if width * height > MAX_IMAGE_PIXELS:
            raise ValueError(f"{argument}: {path} claims {width} x {height} pixels, more than any depth image "
                             f"({MAX_IMAGE_PIXELS} pixels at most); not read")
        _check_shape(path, argument, (height, width), shape)
        try:
            mode = im.mode
            data = np.asarray(im if convert is None else im.convert(convert))
        except (OSError, SyntaxError, ValueError) as exc:
            raise ValueError(f"{argument}: {path} is not a readable image ({type(exc).__name__})") from None
    return data, mode


def _load_npy(path: Path, argument: str, what: str = "depth array", expected: tuple | None = None) -> np.ndarray:
    """A numeric (or bool) ``.npy`` array; its header is checked before anything is allocated (type, size)."""
    fmt = np.lib.format
    try:
        with open(path, "rb") as f:
            version = fmt.read_magic(f)
            read_header = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
            shape, _, dtype = read_header(f)
    except (ValueError, OSError, EOFError, SyntaxError, TypeError):
        raise ValueError(f"{argument}: {path} is not a {what} (no readable .npy header)") from None
    if dtype.hasobject or not (np.issubdtype(dtype, np.number) or dtype == np.bool_):
        raise ValueError(f"{argument}: {path} is not a {what} (it holds {dtype} values, not numbers)")
    if float(np.prod(shape, dtype=np.float64)) > MAX_IMAGE_PIXELS:
        raise ValueError(f"{argument}: {path} claims an array of shape {tuple(shape)}, more than any image "
                         f"({MAX_IMAGE_PIXELS} values at most); not read")
    _check_shape(path, argument, tuple(shape), expected)
    try:
        return np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise ValueError(f"{argument}: {path} is not a {what} ({exc})") from None


def read_json(path, *, argument: str):
    """The JSON value in a file; ``FileNotFoundError`` / ``ValueError`` naming ``argument`` and the file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{argument}: no such file {path}")
    try:
        return json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{argument}: {path} is not valid JSON ({exc})") from None


def read_depth(path, *, depth_scale: float = 0.001, argument: str = "depth", shape: tuple | None = None) -> np.ndarray:
    """Read a depth image as ``(H, W)`` float64 metres (0 = no measurement).

    Parameters
    ----------
    path : str or Path
        A 16-bit single-channel PNG (values times ``depth_scale`` = metres; millimetres by default)
        or a ``.npy`` array of depths in metres (non-finite entries count as no measurement).
    depth_scale : float
        Metres per PNG unit, positive.
    argument : str
        Name of the option in error messages.
    shape : (H, W), optional
        The size the intrinsics give: a file whose header claims another is refused before its
        pixels are decoded.

    Raises
    ------
    ValueError
        Another size than ``shape``; not a 16-bit PNG (an 8-bit PNG holds no usable depth) or a 2-D numeric ``.npy``, negative
        depths, or ``.npy`` depths whose median exceeds :data:`MAX_PLAUSIBLE_DEPTH` metres (they
        look like millimetres: the message says to divide by 1000).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{argument}: no such file {path}")
    if not (np.isfinite(depth_scale) and depth_scale > 0):
        raise ValueError(f"depth_scale: expected a positive number, got {depth_scale}")
    if path.suffix.lower() == ".npy":
        d = _load_npy(path, argument, expected=shape)
        if d.ndim != 2 or not np.issubdtype(d.dtype, np.number):
            raise ValueError(f"{argument}: expected a 2-D numeric array of metres in {path}, got {d.dtype} {d.shape}")
        d = np.where(np.isfinite(d), d, 0.0).astype(np.float64)
        valid = d[d > 0]
        if valid.size and float(np.median(valid)) > MAX_PLAUSIBLE_DEPTH:
            raise ValueError(
                f"{argument}: {path} has a median depth of {float(np.median(valid)):.4g}, which looks like millimetres; "
                "a .npy depth image is in metres: divide it by 1000 (or save a 16-bit PNG of millimetres)"
            )
    elif path.suffix.lower() == ".png":
        d, mode = _open_image(path, argument, shape=shape)
        if mode not in _DEPTH_PNG_MODES:
            raise ValueError(f"{argument}: expected a 16-bit single-channel PNG in {path}, got mode {mode!r} "
                             "(an 8-bit image cannot hold depth in millimetres)")
        if d.ndim != 2:
            raise ValueError(f"{argument}: expected a single-channel image in {path}, got shape {d.shape}")
        d = d.astype(np.float64) * float(depth_scale)
    else:
        raise ValueError(f"{argument}: expected a .png or .npy file, got {path.name}")
    if np.any(d < 0):
        raise ValueError(f"{argument}: negative depths in {path}")
    return d


def read_mask(path, shape, *, argument: str = "mask") -> np.ndarray:
    """Read a mask image (PNG or ``.npy``) as ``(H, W)`` bool (nonzero = object) of the given shape."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{argument}: no such file {path}")
    if path.suffix.lower() == ".npy":
        m = _load_npy(path, argument, what="mask array")
    else:
        m, _ = _open_image(path, argument)
    if m.ndim == 3:  # RGB(A) mask: any nonzero channel
        m = m[..., :3].any(axis=-1)
    if m.shape != tuple(shape):
        raise ValueError(f"{argument}: expected shape {tuple(shape)} (the depth image), got {m.shape} in {path}")
    return m != 0


def read_rgb(path, shape, *, argument: str = "rgb") -> np.ndarray:
    """Read a colour image registered to the depth as ``(H, W, 3)`` uint8 of the depth's ``shape``."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{argument}: no such file {path}")
    rgb, _ = _open_image(path, argument, convert="RGB")
    if rgb.shape[:2] != tuple(shape):
        raise ValueError(f"{argument}: expected an image of {tuple(shape)} pixels (the depth image), got {rgb.shape[:2]} "
                         f"in {path}")
    return rgb


def read_intrinsics(path, *, argument: str = "intrinsics") -> Intrinsics:
    """Read ``{"fx", "fy", "cx", "cy", "width", "height"}`` JSON (:meth:`Intrinsics.to_json`); values must be JSON numbers."""
    data = read_json(path, argument=argument)
    try:
        return Intrinsics.from_json(data)
    except ValueError as exc:
        raise ValueError(f"{argument}: {path}: {exc}") from None


def mask_bounds(mask) -> tuple[int, int, int, int] | None:
    """``(v0, v1, u0, u1)``: the rows and columns a mask covers (pixels, end exclusive), or ``None`` for an empty one.

    Read from the mask's row and column projections rather than its pixel list (``np.nonzero``): about 30 times
    faster on a 1280 x 720 image, where the verification of a frame's candidates asks for it dozens of times.

    Parameters
    ----------
    mask : (H, W) bool
    """
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask: expected an (H, W) image, got shape {m.shape}")
    rows = np.flatnonzero(m.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(m[rows[0]:rows[-1] + 1].any(axis=0))
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
