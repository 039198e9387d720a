"""The requests of ``ancsh serve``, checked before any work: :func:`parse_predict` turns a JSON object (or a raw depth
image with query parameters) into a :class:`PredictRequest`; every problem is a :class:`RequestError` with the HTTP
status and a message naming the field. Paths are read only inside the folder given at start (:class:`PathPolicy`).
"""

from __future__ import annotations

import base64
import binascii
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["MAX_PIXELS", "PathPolicy", "PredictRequest", "RequestError", "TrackRequest", "parse_predict", "parse_track"]

#: The largest depth image a request may hold (a 4K frame); larger images are refused before decoding.
MAX_PIXELS = 3840 * 2160
REFINE_CHOICES = ("auto", "template", "network", "none")
#: Where an image of a request comes from: a path, base64 text in a JSON body, or (``*_bytes``) a raw request body's
#: bytes as they came (``ancsh.service.http``: no base64 round trip).
_IMAGE_KINDS = ("path", "png_base64", "npy_base64", "png_bytes", "npy_bytes")


class RequestError(ValueError):
    """A request the service refuses: ``status`` (an HTTP 4xx code) and a message naming what is wrong."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = int(status)


@dataclass(frozen=True)
class PathPolicy:
    """Where requests may read files: inside ``root`` only (``None``: no paths at all, images travel as bytes)."""

    root: Path | None = None

    def resolve(self, value, field: str) -> Path:
        """The file ``value`` names, relative to the root (or absolute inside it), with links resolved.

        Raises :class:`RequestError` 403 for a path outside the root (or any path without one), 404 for a missing
        file, 400 for a value that is not a string."""
        if not isinstance(value, str) or not value:
            raise RequestError(400, f"{field}: expected a file path (a non-empty string), got {type(value).__name__}")
        if self.root is None:
            raise RequestError(403, f"{field}: this service reads no paths (started without --root); send the image "
                                    "as bytes (png_base64 / npy_base64)")
        root = self.root.resolve()
        path = Path(value)
        path = (path if path.is_absolute() else root / path).resolve()
        if not path.is_relative_to(root):
            raise RequestError(403, f"{field}: {value!r} lies outside the service's folder")
        if not path.is_file():
            raise RequestError(404, f"{field}: no such file {value!r} in the service's folder")
        return path


@dataclass(frozen=True)
class PredictRequest:
    """One ``/predict`` request, checked: the depth (metres, ``(H, W)``), the intrinsics, an optional mask and the
    options of :func:`~ancsh.learned.inference.predict.predict_depth` (as ``ancsh predict`` names them)."""

    category: str
    depth: np.ndarray
    intrinsics: object  # Intrinsics
    mask: np.ndarray | None = None
    pixel: tuple | None = None
    box: tuple | None = None
    seed: int = 0
    max_objects: int | None = None
    hypotheses: int | None = None
    max_depth: float | None = None
    isolate: bool = True
    points: int = 1024
    formulation: str = "exact_reduced"
    refine: str = "auto"
    source: dict | None = None  # where the depth and mask came from, for the result's "input" block


@dataclass(frozen=True)
class TrackRequest:
    """One ``/track`` request: a frame of the tracking session ``session`` (``reset`` starts the session anew)."""

    session: str
    frame: PredictRequest
    reset: bool = False


def _get(body: dict, key: str, kind, default=None, *, check=None, what: str = ""):
    """``body[key]`` of type ``kind`` (a tuple of types), checked by ``check``; ``default`` when absent or null."""
    if key not in body or body[key] is None:
        return default
    value = body[key]
    if isinstance(value, bool) and bool not in (kind if isinstance(kind, tuple) else (kind,)):
        raise RequestError(400, f"{key}: expected {what or kind}, got a boolean")
    if not isinstance(value, kind):
        raise RequestError(400, f"{key}: expected {what or kind}, got {type(value).__name__}")
    if check is not None and not check(value):
        raise RequestError(400, f"{key}: expected {what}, got {value!r}")
    return value


def _numbers(body: dict, key: str, count: int) -> tuple | None:
    value = body.get(key)
    if value is None:
        return None
    if (not isinstance(value, (list, tuple)) or len(value) != count
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in value)):
        raise RequestError(400, f"{key}: expected a list of {count} finite numbers, got {value!r}")
    return tuple(float(v) for v in value)


def _image_source(body: dict, name: str, required: bool) -> tuple[str, object] | None:
    """Which of ``{name}_path``, ``{name}_png_base64``, ``{name}_npy_base64`` the request gives (exactly one)."""
    given = [k for k in _IMAGE_KINDS if body.get(f"{name}_{k}") is not None]
    if len(given) > 1:
        raise RequestError(400, f"{name}: give one of {', '.join(f'{name}_{k}' for k in given)}, not several")
    if not given:
        if required:
            raise RequestError(400, f"{name}: missing; give {name}_path, {name}_png_base64 or {name}_npy_base64")
        return None
    return given[0], body[f"{name}_{given[0]}"]


def _decoded(kind: str, value, field: str) -> bytes:
    if kind.endswith("_bytes"):
        if not isinstance(value, (bytes, bytearray)):
            raise RequestError(400, f"{field}: the image of a raw request body only; a JSON body sends it as "
                                    f"{field.replace('_bytes', '_base64')}")
        return bytes(value)
    if not isinstance(value, str):
        raise RequestError(400, f"{field}: expected base64 text, got {type(value).__name__}")
    try:
        return base64.b64decode(value, validate=True)
    except (binascii.Error, ValueError):
        raise RequestError(400, f"{field}: not valid base64") from None


def read_image(kind: str, value, name: str, policy: PathPolicy, reader, **kwargs):
    """An image of a request through ``reader`` (``read_depth`` / ``read_mask``): from a path inside the policy's
    root, or from PNG / NPY bytes (written to a private temporary file and read with the same checks)."""
    field = f"{name}_{kind}"
    if kind == "path":
        path = policy.resolve(value, field)
        try:
            return reader(path, argument=field, **kwargs)
        except (ValueError, OSError) as exc:
            raise RequestError(400, str(exc)) from None
    data = _decoded(kind, value, field)
    suffix = ".png" if kind.startswith("png") else ".npy"
    with tempfile.TemporaryDirectory(prefix="ancsh-serve-") as tmp:
        path = Path(tmp) / f"{name}{suffix}"
        path.write_bytes(data)
        try:
            return reader(path, argument=field, **kwargs)
        except (ValueError, OSError) as exc:
            raise RequestError(400, str(exc).replace(str(path), f"the {name} bytes")) from None


def parse_predict(body, policy: PathPolicy) -> PredictRequest:
    """A :class:`PredictRequest` of a JSON object (see ``docs/serve.md`` for the fields)."""
    from ..data.images import read_depth, read_intrinsics, read_mask
    from ..data.render import Intrinsics

    if not isinstance(body, dict):
        raise RequestError(400, f"request: expected a JSON object, got {type(body).__name__}")
    known = {"category", "intrinsics", "intrinsics_path", "pixel", "box", "seed", "max_objects", "hypotheses",
             "max_depth", "depth_scale", "isolate", "points", "formulation", "refine", "session", "reset"}
    known |= {f"{n}_{k}" for n in ("depth", "mask") for k in _IMAGE_KINDS}
    unknown = sorted(set(body) - known)
    if unknown:
        raise RequestError(400, f"request: unknown field(s) {unknown}; known: {sorted(known)}")
    category = _get(body, "category", str, what="a category name")
    if not category:
        raise RequestError(400, "category: missing (e.g. \"laptop\")")
    if body.get("intrinsics") is not None and body.get("intrinsics_path") is not None:
        raise RequestError(400, "intrinsics: give intrinsics or intrinsics_path, not both")
    if body.get("intrinsics") is not None:
        try:
            intr = Intrinsics.from_json(body["intrinsics"])
        except (ValueError, TypeError) as exc:
            raise RequestError(400, f"intrinsics: {exc}") from None
    elif body.get("intrinsics_path") is not None:
        try:
            intr = read_intrinsics(policy.resolve(body["intrinsics_path"], "intrinsics_path"), argument="intrinsics_path")
        except (ValueError, OSError) as exc:
            raise RequestError(400, str(exc)) from None
    else:
        raise RequestError(400, "intrinsics: missing; give intrinsics {fx, fy, cx, cy, width, height} or intrinsics_path")
    if intr.width * intr.height > MAX_PIXELS:
        raise RequestError(413, f"intrinsics: a {intr.width}x{intr.height} image is larger than this service takes "
                                f"({MAX_PIXELS} pixels)")
    depth_scale = _get(body, "depth_scale", (int, float), 0.001, check=lambda v: np.isfinite(v) and v > 0,
                       what="a positive number of metres per PNG unit")
    kind, value = _image_source(body, "depth", required=True)
    depth = read_image(kind, value, "depth", policy, read_depth, depth_scale=float(depth_scale),
                       shape=(intr.height, intr.width))
    if depth.shape != (intr.height, intr.width):
        raise RequestError(400, f"depth: a {depth.shape[1]}x{depth.shape[0]} image, the intrinsics say "
                                f"{intr.width}x{intr.height}")
    mask_source = _image_source(body, "mask", required=False)
    mask = None if mask_source is None else read_image(*mask_source, "mask", policy, read_mask, shape=depth.shape)
    pixel, box = _numbers(body, "pixel", 2), _numbers(body, "box", 4)
    if (mask is not None) + (pixel is not None) + (box is not None) > 1:
        raise RequestError(400, "mask, pixel, box: give at most one of them")
    integer = lambda lo: dict(check=lambda v: v >= lo, what=f"an integer >= {lo}")  # noqa: E731
    refine = _get(body, "refine", str, "auto", check=lambda v: v in REFINE_CHOICES, what=f"one of {REFINE_CHOICES}")
    max_objects = _get(body, "max_objects", int, None, **integer(1))
    if max_objects is not None and (mask is not None or pixel is not None or box is not None):
        raise RequestError(400, "max_objects: a mask, pixel or box selects one object; leave max_objects out")
    source = {"depth": value if kind == "path" else f"<{kind.split('_')[0]} bytes>",
              "mask": None if mask_source is None else (mask_source[1] if mask_source[0] == "path"
                                                         else f"<{mask_source[0].split('_')[0]} bytes>"),
              "depth_scale": float(depth_scale)}
    from ..solvers.fit import FORMULATIONS

    return PredictRequest(
        category=category, depth=depth, intrinsics=intr, mask=mask, pixel=pixel, box=box,
        seed=_get(body, "seed", int, 0, **integer(0)), max_objects=max_objects,
        hypotheses=_get(body, "hypotheses", int, None, **integer(1)),
        max_depth=_get(body, "max_depth", (int, float), None, check=lambda v: np.isfinite(v) and v > 0,
                       what="a positive number of metres"),
        isolate=_get(body, "isolate", bool, True, what="true or false"),
        points=_get(body, "points", int, 1024, **integer(1)),
        formulation=_get(body, "formulation", str, "exact_reduced", check=lambda v: v in FORMULATIONS,
                         what=f"one of {sorted(FORMULATIONS)}"),
        refine=refine, source=source)


def parse_track(body, policy: PathPolicy) -> TrackRequest:
    """A :class:`TrackRequest` of a JSON object: the fields of :func:`parse_predict` plus ``session`` (a name of up
    to 64 letters, digits, ``-``, ``_``) and ``reset``."""
    if not isinstance(body, dict):
        raise RequestError(400, f"request: expected a JSON object, got {type(body).__name__}")
    session = body.get("session")
    if not isinstance(session, str) or not 0 < len(session) <= 64 or not all(c.isalnum() or c in "-_" for c in session):
        raise RequestError(400, f"session: expected a name of 1-64 letters, digits, '-' or '_', got {session!r}")
    frame = parse_predict(body, policy)
    for key in ("pixel", "box", "max_objects", "hypotheses", "formulation", "refine"):
        if body.get(key) is not None:
            raise RequestError(400, f"{key}: not a tracking option (a session tracks with its category's settings)")
    return TrackRequest(session, frame, _get(body, "reset", bool, False, what="true or false"))
