"""``ancsh predict``: one depth image in, per-part poses, amodal boxes, joints and states out.

Pipeline: read the depth image (16-bit PNG in millimetres by default, or ``.npy`` in metres),
back-project the valid pixels (``depth > 0``, finite, inside the optional mask and below the optional
``max_depth``), sample ``num_points`` of them with a seed, run the category's shipped ANCSH network
(:class:`~ancsh.learned.provider.LearnedProvider`) and fit a formulation
(:func:`ancsh.solvers.fit`). :meth:`DepthPrediction.to_json` gives the result as plain JSON;
:func:`draw_prediction` draws boxes and joint axes over the depth image and over the point cloud.

Frames: camera (OpenCV: x right, y down, z forward), metres. A part pose maps its NPCS coordinates
``c`` to the camera: ``p = scale * rotation @ c + translation``.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data.render import Intrinsics

__all__ = [
    "DepthPrediction",
    "depth_to_points",
    "draw_prediction",
    "predict_depth",
    "read_depth",
    "read_intrinsics",
    "read_mask",
]


# --------------------------------------------------------------------------------------------
# inputs
# --------------------------------------------------------------------------------------------
def read_depth(path, *, depth_scale: float = 0.001) -> np.ndarray:
    """Read a depth image as ``(H, W)`` float64 metres (0 = no measurement).

    Parameters
    ----------
    path : str or Path
        A 16-bit single-channel PNG (values times ``depth_scale`` = metres; millimetres by default)
        or a ``.npy`` array of depths in metres (non-finite entries count as no measurement).
    depth_scale : float
        Metres per PNG unit, positive.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"depth: no such file {path}")
    if not (np.isfinite(depth_scale) and depth_scale > 0):
        raise ValueError(f"depth_scale: expected a positive number, got {depth_scale}")
    if path.suffix.lower() == ".npy":
        d = np.load(path, allow_pickle=False)
        if d.ndim != 2 or not np.issubdtype(d.dtype, np.number):
            raise ValueError(f"depth: expected a 2-D numeric array of metres in {path}, got {d.dtype} {d.shape}")
        d = np.where(np.isfinite(d), d, 0.0).astype(np.float64)
    elif path.suffix.lower() == ".png":
        from PIL import Image

        with Image.open(path) as im:
            if im.mode not in ("I;16", "I;16B", "I;16L", "I"):
                raise ValueError(f"depth: expected a 16-bit single-channel PNG in {path}, got mode {im.mode!r}")
            d = np.asarray(im).astype(np.float64) * float(depth_scale)
        if d.ndim != 2:
            raise ValueError(f"depth: expected a single-channel image in {path}, got shape {d.shape}")
    else:
        raise ValueError(f"depth: expected a .png or .npy file, got {path.name}")
    if np.any(d < 0):
        raise ValueError(f"depth: negative depths in {path}")
    return d


def read_mask(path, shape) -> np.ndarray:
    """Read a mask image (PNG or ``.npy``) as ``(H, W)`` bool (nonzero = object) of the given shape."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"mask: no such file {path}")
    if path.suffix.lower() == ".npy":
        m = np.load(path, allow_pickle=False)
    else:
        from PIL import Image

        with Image.open(path) as im:
            m = np.asarray(im)
    if m.ndim == 3:  # RGB(A) mask: any nonzero channel
        m = m[..., :3].any(axis=-1)
    if m.shape != tuple(shape):
        raise ValueError(f"mask: expected shape {tuple(shape)} (the depth image), got {m.shape} in {path}")
    return m != 0


def read_intrinsics(path) -> Intrinsics:
    """Read ``{"fx", "fy", "cx", "cy", "width", "height"}`` JSON (:meth:`Intrinsics.to_json`)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"intrinsics: no such file {path}")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"intrinsics: {path} is not valid JSON ({exc})") from None
    try:
        return Intrinsics.from_json(data)
    except ValueError as exc:
        raise ValueError(f"intrinsics: {path}: {exc}") from None


def depth_to_points(depth, intrinsics: Intrinsics, *, mask=None, max_depth: float | None = None,
                    num_points: int | None = 1024, rng=0) -> tuple[np.ndarray, np.ndarray, int]:
    """Back-project the valid pixels and sample ``num_points`` of them.

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
        Must match the image size.
    mask : (H, W) bool, optional
    max_depth : float, optional
        Pixels deeper than this (metres) are dropped.
    num_points : int or None
        Points to sample without replacement (all of them when fewer are valid); ``None`` = all.
    rng : numpy.random.Generator or int

    Returns
    -------
    points : (n, 3) float64
        Camera frame, metres.
    pixels : (n, 2) int64
        ``(u, v)`` of each point.
    valid : int
        Number of valid pixels before sampling.

    Raises
    ------
    ValueError
        When no valid pixel remains.
    """
    from ..data.render import backproject, valid_depth_pixels
    from ..geometry._checks import check_generator

    d, sel = valid_depth_pixels(depth, intrinsics, mask)
    if max_depth is not None:
        if not (np.isfinite(max_depth) and max_depth > 0):
            raise ValueError(f"max_depth: expected a positive number, got {max_depth}")
        sel &= d <= max_depth
    valid = int(np.count_nonzero(sel))
    if valid == 0:
        raise ValueError("depth: no valid pixel after masking (depth > 0"
                         + (", inside the mask" if mask is not None else "")
                         + (f", depth <= {max_depth} m" if max_depth is not None else "") + ")")
    if num_points is not None:
        if isinstance(num_points, bool) or int(num_points) != num_points or num_points < 1:
            raise ValueError(f"num_points: expected a positive integer, got {num_points!r}")
        if valid > num_points:
            flat = np.flatnonzero(sel)
            pick = check_generator(rng).choice(flat, size=int(num_points), replace=False)
            sel = np.zeros_like(sel)
            sel.ravel()[pick] = True
    pts = backproject(d, intrinsics, mask=sel)  # row-major pixel order, as np.nonzero
    v, u = np.nonzero(sel & (d > 0))
    return pts, np.stack([u, v], axis=1).astype(np.int64), valid


# --------------------------------------------------------------------------------------------
# prediction
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DepthPrediction:
    """Result of :func:`predict_depth`.

    Attributes
    ----------
    category : str
    result : FitResult
        Part poses ``T_cam_npcs``, amodal boxes, camera-frame joints and states, status.
    points_cam : (n, 3) float64
        The sampled points (camera frame, metres).
    pixels : (n, 2) int64
        Their ``(u, v)``.
    part_labels : (n,) int64
        Predicted part of each point.
    part_names, joint_names : tuple of str
    weights : str
        The weights file used.
    valid_pixels : int
    timings_ms : dict
        ``backproject``, ``network``, ``fit``, ``total`` (milliseconds).
    joint_types : tuple of str
        ``"revolute"`` / ``"prismatic"`` per joint.
    joint_parents, joint_children : tuple of int
        Part indices joined by each joint.
    """

    category: str
    result: object
    points_cam: np.ndarray
    pixels: np.ndarray
    part_labels: np.ndarray
    part_names: tuple
    joint_names: tuple
    weights: str
    valid_pixels: int
    timings_ms: dict = field(default_factory=dict)
    joint_types: tuple = ()
    joint_parents: tuple = ()
    joint_children: tuple = ()

    def to_json(self) -> dict:
        """Plain-JSON description (lists, floats; NaN -> ``None``)."""
        r = self.result
        counts = np.bincount(self.part_labels, minlength=len(self.part_names))
        parts = []
        for j, name in enumerate(self.part_names):
            rec = {"name": name, "points": int(counts[j]), "pose": None, "box": None}
            if j < len(r.T_cam_npcs):
                T = r.T_cam_npcs[j]
                rec["pose"] = {"rotation": T.rotation.tolist(), "translation": T.translation.tolist(), "scale": float(T.scale)}
            if j < len(r.boxes_cam):
                b = r.boxes_cam[j]
                rec["box"] = {"center": b.center.tolist(), "rotation": b.rotation.tolist(), "extents": b.extents.tolist(),
                              "corners": b.corners().tolist()}
            parts.append(rec)
        joints = []
        for k, name in enumerate(self.joint_names):
            jt = self.joint_types[k] if k < len(self.joint_types) else None
            joints.append({
                "name": name, "type": jt,
                "parent": self.part_names[int(self.joint_parents[k])], "child": self.part_names[int(self.joint_children[k])],
                "axis_cam": r.joint_axes_cam[k].tolist(), "pivot_cam": r.joint_pivots_cam[k].tolist(),
                "state": float(r.joint_states[k]), "state_unit": "rad" if jt == "revolute" else "m",
            })
        data = {
            "category": self.category, "weights": self.weights,
            "formulation": r.formulation, "solver": r.solver, "status": r.status.value, "ok": bool(r.ok),
            "message": r.message, "iterations": int(r.iterations),
            "max_constraint_violation": float(r.max_constraint_violation),
            "points": int(self.points_cam.shape[0]), "valid_pixels": int(self.valid_pixels),
            "parts": parts, "joints": joints, "timings_ms": dict(self.timings_ms),
            "frames": "camera frame (x right, y down, z forward), metres; pose maps part NPCS c to the camera: "
                      "p = scale * rotation @ c + translation; joint states relative to the category's rest state",
        }
        from .evaluate import json_safe

        return json_safe(data)



def predict_depth(depth, intrinsics: Intrinsics, category: str, *, mask=None, max_depth: float | None = None,
                  weights=None, provider=None, formulation: str = "exact_reduced", num_points: int = 1024,
                  seed: int = 0) -> DepthPrediction:
    """Run the learned pipeline on one depth image.

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
    category : str
        Object category; its shipped weights are used unless ``weights`` or ``provider`` is given.
    mask : (H, W) bool, optional
    max_depth : float, optional
        Metres.
    weights : str or Path, optional
        A weights file instead of the shipped ones.
    provider : LearnedProvider, optional
        A ready provider (reused across calls).
    formulation : str
        A key of :data:`ancsh.solvers.FORMULATIONS`.
    num_points : int
        Points sampled from the valid pixels.
    seed : int
        Sampling, network chunking and RANSAC seed.

    Raises
    ------
    FileNotFoundError
        No shipped weights for ``category`` (the message names the available ones).
    ValueError
        Bad inputs (shapes, empty depth after masking, unknown formulation).
    """
    from ..solvers import FORMULATIONS, Observation, fit
    from .provider import LearnedProvider
    from .weights import weights_path

    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation: expected one of {sorted(FORMULATIONS)}, got {formulation!r}")
    t_start = time.perf_counter()
    if provider is None:
        if weights is None and not weights_path(str(category)).is_file():
            from .evaluate import missing_weights_error

            raise missing_weights_error(category)
        provider = LearnedProvider(category if weights is None else weights, seed=seed)
    t0 = time.perf_counter()
    pts, pixels, valid = depth_to_points(depth, intrinsics, mask=mask, max_depth=max_depth, num_points=num_points, rng=seed)
    t_bp = time.perf_counter() - t0
    obs = Observation(pts)
    t0 = time.perf_counter()
    corr = provider.correspond(obs)
    t_net = time.perf_counter() - t0
    result = fit(obs, corr, formulation, rng=seed)
    part_names, joint_names = _names(category, corr.num_parts, corr.num_joints)
    return DepthPrediction(
        category=str(category), result=result, points_cam=pts, pixels=pixels, part_labels=np.asarray(corr.part_labels),
        part_names=part_names, joint_names=joint_names, weights=str(provider.network.source), valid_pixels=valid,
        timings_ms={"backproject": 1e3 * t_bp, "network": 1e3 * t_net, "fit": 1e3 * result.time_s,
                    "total": 1e3 * (time.perf_counter() - t_start)},
        joint_types=tuple(t.value for t in corr.joint_types),
        joint_parents=tuple(int(p) for p in corr.joint_parents),
        joint_children=tuple(int(c) for c in corr.joint_children),
    )


def _names(category: str, M: int, K: int) -> tuple[tuple, tuple]:
    from ..data.procedural import CATEGORY_INFO

    info = CATEGORY_INFO.get(category)
    if info is not None and len(info.part_names) == M and len(info.joint_names) == K:
        return tuple(info.part_names), tuple(info.joint_names)
    return tuple(f"part{j}" for j in range(M)), tuple(f"joint{k}" for k in range(K))


# --------------------------------------------------------------------------------------------
# picture
# --------------------------------------------------------------------------------------------
def draw_prediction(depth, prediction: DepthPrediction, intrinsics: Intrinsics, *, title: str = ""):
    """Boxes and joint axes over the point cloud (3D) and projected on the depth image.

    Uses :func:`ancsh.data.show.draw_fit` and puts the depth image under its image-plane panel.
    Returns a matplotlib ``Figure`` (Agg).
    """
    from matplotlib.figure import Figure

    from ..data.show import draw_fit

    r = prediction.result
    fig = Figure(figsize=(14, 6), dpi=100)
    title = title or (f"{prediction.category}: {r.formulation} fit, status {r.status.value} "
                      f"({prediction.points_cam.shape[0]} points)")
    draw_fit(prediction.points_cam, r, intrinsics, labels=prediction.part_labels, title=title, fig=fig)
    ax = fig.axes[-1]
    xlim, ylim = ax.get_xlim(), ax.get_ylim()
    d = np.asarray(depth, dtype=np.float64)
    im = ax.imshow(np.ma.masked_where(d <= 0, d), cmap="gray", interpolation="nearest", zorder=0,
                   extent=(-0.5, d.shape[1] - 0.5, d.shape[0] - 0.5, -0.5))
    for coll in ax.collections:
        coll.set_alpha(0.35)
    ax.set_xlim(xlim)
    ax.set_ylim(ylim)
    fig.colorbar(im, ax=ax, label="depth (m)", shrink=0.8)
    ax.set_title("depth image: boxes (part colours) and joint axes (black) projected", fontsize=9)
    return fig
