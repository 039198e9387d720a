"""Render-and-compare: does a fitted model explain the depth the sensor saw?

:func:`ancsh.solvers.twin.render_fit` reshapes the category template nearest to a fit
(:mod:`ancsh.solvers.icp.category`) to the fitted part boxes, poses it at the fitted object pose and joint states and
renders its depth from the input camera with the project's renderer (:class:`ancsh.data.render.ModelRenderer`).
:func:`compare_depth` compares a model depth image with the observed one:

- **explained**: the share of the object's observed pixels where the model's surface lies within
  the tolerance of the observed depth;
- **see-through**: the share of the model's pixels (where the sensor measured something) where the sensor
  saw *beyond* the model's surface by more than the tolerance (free space where the model claims a solid:
  the model cannot be there); pixels where the sensor saw something nearer are occlusions and count as
  neither, pixels without a measurement (holes, or nothing behind a rendered object) are left out;
- **hidden**: the share of the model's pixels (where the sensor measured something) where the sensor saw a surface
  *nearer* than the model by more than the tolerance: the model lies behind something else (an occluder, or the
  surface it was fitted to: a model fitted behind its points). Little of a model that is mostly hidden is seen at all;
- **median residual**: the median of ``|observed - model|`` over the object's pixels where both have depth;
- the per-pixel residual map ``observed - model`` (metres, NaN where either has no depth).

:func:`aligned_comparison` measures the same after moving the model along the camera's depth axis onto the object's
pixels (by the median residual there): a category fit places the part boxes' unseen sides by the category's
proportions, so a right fit of an instance deeper or shallower than those can stand a few centimetres before or
behind the surface it was fitted to, and the comparison above then calls the whole front see-through.

The tolerance grows with depth (:data:`ABS_TOLERANCE_M` plus :data:`REL_TOLERANCE` of the depth):
sensor noise and a template that is not the instance.

A near object fills hundreds of thousands of pixels; the model is rendered with at most :data:`COMPARE_RAYS` rays
(every ``stride``-th pixel, :func:`compare_stride`, :func:`coarse_intrinsics`) and its depth spread back over the
window (:func:`upsample_depth`): the shares above are shares of pixels, which a pixel in every ``stride x stride``
block estimates to within the block at the silhouette's edge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ABS_TOLERANCE_M", "COMPARE_RAYS", "REL_TOLERANCE", "DepthComparison", "aligned_comparison",
           "coarse_intrinsics", "compare_depth", "compare_stride", "crop_intrinsics", "mask_window", "occluding_pixels",
           "upsample_depth"]

#: Depth agreement tolerance: this many metres plus :data:`REL_TOLERANCE` times the depth.
ABS_TOLERANCE_M = 0.015
REL_TOLERANCE = 0.02

#: Rays a model is rendered with at most for a comparison (module docstring): a 1280 x 720 frame's near object (a
#: 700 x 550 pixel window) is rendered at every second pixel, one ray per 2 x 2 block, a quarter of the time.
COMPARE_RAYS = 100_000


@dataclass(frozen=True)
class DepthComparison:
    """What :func:`compare_depth` measured (see the module docstring).

    Attributes
    ----------
    explained : float
        Share of the object's observed pixels the model explains (0..1; NaN without object pixels).
    see_through : float
        Share of the model's pixels where the sensor saw beyond the model (0..1; NaN without model pixels).
    hidden : float
        Share of the model's pixels where the sensor saw something nearer than the model (0..1; NaN without model
        pixels).
    median_abs_residual_m : float
        Metres, over the object's pixels where the model has depth (NaN when there are none).
    object_pixels : int
        The object's pixels with a measurement.
    model_pixels : int
        The model's pixels with a measurement.
    residual : (H, W) float64
        ``observed - model`` in metres; NaN where either has no depth.
    shift_m : float
        Metres the model was moved along the camera's depth axis before comparing (:func:`aligned_comparison`;
        positive: away from the camera); 0 for :func:`compare_depth`.
    """

    explained: float
    see_through: float
    median_abs_residual_m: float
    object_pixels: int
    model_pixels: int
    residual: np.ndarray
    hidden: float = float("nan")
    shift_m: float = 0.0

    def to_dict(self) -> dict:
        return {"explained": self.explained, "see_through": self.see_through, "hidden": self.hidden,
                "median_abs_residual_m": self.median_abs_residual_m, "object_pixels": self.object_pixels,
                "model_pixels": self.model_pixels, "shift_m": self.shift_m}


def compare_depth(model_depth, observed_depth, object_mask) -> DepthComparison:
    """Compare a rendered model depth with the observed depth (module docstring).

    Parameters
    ----------
    model_depth, observed_depth : (H, W) float64
        Metres, 0 = nothing rendered / no measurement.
    object_mask : (H, W) bool
        The object's observed pixels.
    """
    m = np.asarray(model_depth, dtype=np.float64)
    o = np.asarray(observed_depth, dtype=np.float64)
    mask = np.asarray(object_mask, dtype=bool)
    if m.shape != o.shape or mask.shape != o.shape:
        raise ValueError(f"model_depth, observed_depth, object_mask: expected one shape, got {m.shape}, {o.shape}, {mask.shape}")
    has_m, has_o = m > 0, o > 0
    both = has_m & has_o
    residual = np.full(o.shape, np.nan)
    residual[both] = o[both] - m[both]
    return _measured(residual, o, mask, 0.0)


def _measured(residual, o, mask, shift_m: float) -> DepthComparison:
    """:class:`DepthComparison` of a residual map ``observed - model`` (NaN where either has no depth), the observed
    depth ``o`` and the object's pixels ``mask`` (one shape)."""
    both = np.isfinite(residual)
    obj = mask & (o > 0)
    n_obj = int(np.count_nonzero(obj))
    r = residual[both]  # the model's pixels with a measurement (the window's other pixels count for n_obj only)
    tol = ABS_TOLERANCE_M + REL_TOLERANCE * o[both]
    on_obj = obj[both]
    n_model = int(r.size)
    explained = float(np.count_nonzero(on_obj & (np.abs(r) <= tol)) / n_obj) if n_obj else float("nan")
    see_through = float(np.count_nonzero(r > tol) / n_model) if n_model else float("nan")
    hidden = float(np.count_nonzero(-r > tol) / n_model) if n_model else float("nan")
    med = float(np.median(np.abs(r[on_obj]))) if on_obj.any() else float("nan")
    return DepthComparison(explained, see_through, med, n_obj, n_model, residual, hidden, float(shift_m))


def aligned_comparison(comparison: DepthComparison, depth, object_mask, max_shift_m: float) -> DepthComparison:
    """``comparison`` measured again with the model moved along the camera's depth axis by the median of ``observed -
    model`` on the object's pixels, clipped to ``max_shift_m`` either way (module docstring); its
    :attr:`~DepthComparison.shift_m` is the move. Unchanged when no object pixel has model depth.

    Parameters
    ----------
    comparison : DepthComparison
        Made by :func:`ancsh.solvers.twin.compare_fit` with this ``object_mask`` (its residual map covers
        :func:`mask_window` of the mask).
    depth : (H, W) float64
        The observed depth (metres, 0 = no measurement).
    object_mask : (H, W) bool
    max_shift_m : float
        The largest move (metres, >= 0).
    """
    if not np.isfinite(max_shift_m) or max_shift_m < 0:
        raise ValueError(f"max_shift_m: expected a non-negative number of metres, got {max_shift_m!r}")
    o, mask, residual, _ = _window(comparison, depth, object_mask)
    on = mask & (o > 0) & np.isfinite(residual)  # empty for an empty mask
    if not on.any():
        return comparison
    shift = float(np.clip(np.median(residual[on]), -max_shift_m, max_shift_m))
    return _measured(residual - shift, o, mask, shift)


def _window(comparison: DepthComparison, depth, object_mask) -> tuple:
    """``(observed depth, object mask, comparison's residual map, (v0, v1, u0, u1) slices)`` in the window
    :func:`mask_window` of ``object_mask`` that the map covers (empty arrays and slices for an empty mask); a clear
    error when the shapes disagree."""
    mask = np.asarray(object_mask, dtype=bool)
    d = np.asarray(depth, dtype=np.float64)
    if mask.shape != d.shape:
        raise ValueError(f"depth, object_mask: expected one shape, got {d.shape}, {mask.shape}")
    if not mask.any():
        return np.zeros((0, 0)), np.zeros((0, 0), dtype=bool), np.zeros((0, 0)), (slice(0, 0), slice(0, 0))
    u0, v0, u1, v1 = mask_window(mask)
    residual = comparison.residual
    if residual.shape != (v1 - v0, u1 - u0):
        raise ValueError(f"comparison: its residual map {residual.shape} does not cover the mask's window "
                         f"{(v1 - v0, u1 - u0)}; compare with this object_mask")
    window = (slice(v0, v1), slice(u0, u1))
    return d[window], mask[window], residual, window


def crop_intrinsics(intrinsics, box):
    """The intrinsics of the image window ``box = (u0, v0, u1, v1)`` (pixels, end exclusive)."""
    from ..data.render import Intrinsics

    u0, v0, u1, v1 = (int(x) for x in box)
    return Intrinsics(fx=intrinsics.fx, fy=intrinsics.fy, cx=intrinsics.cx - u0, cy=intrinsics.cy - v0,
                      width=u1 - u0, height=v1 - v0)


def compare_stride(pixels: int, rays: int = COMPARE_RAYS) -> int:
    """The pixel stride at which a window of ``pixels`` is rendered with at most ``rays`` rays (1 when it fits)."""
    if isinstance(rays, bool) or int(rays) != rays or rays < 1:
        raise ValueError(f"rays: expected a positive integer, got {rays!r}")
    return max(1, int(np.ceil(np.sqrt(max(int(pixels), 0) / rays))))


def coarse_intrinsics(intrinsics, stride: int):
    """The intrinsics of every ``stride``-th pixel of ``intrinsics``' image, one ray through the centre of each
    ``stride x stride`` block (pixel ``(i, j)`` of the coarse image sees the centre of block ``(i, j)``); the image is
    ``ceil(width / stride) x ceil(height / stride)``. ``stride`` 1: ``intrinsics`` itself."""
    from ..data.render import Intrinsics

    s = int(stride)
    if s < 1:
        raise ValueError(f"stride: expected a positive integer, got {stride!r}")
    if s == 1:
        return intrinsics
    half = 0.5 * (s - 1)
    return Intrinsics(fx=intrinsics.fx / s, fy=intrinsics.fy / s, cx=(intrinsics.cx - half) / s,
                      cy=(intrinsics.cy - half) / s, width=-(-intrinsics.width // s), height=-(-intrinsics.height // s))


def upsample_depth(coarse, stride: int, shape: tuple) -> np.ndarray:
    """A depth image rendered at :func:`coarse_intrinsics` spread back to the full image ``shape = (H, W)``: each
    coarse pixel's depth over its ``stride x stride`` block."""
    s = int(stride)
    full = np.asarray(coarse)
    if s > 1:
        full = np.repeat(np.repeat(full, s, axis=0), s, axis=1)
    H, W = (int(x) for x in shape)
    if full.shape[0] < H or full.shape[1] < W:
        raise ValueError(f"coarse: {np.shape(coarse)} at stride {s} does not cover {(H, W)}")
    return full[:H, :W]


def mask_window(mask, margin: float = 0.5) -> tuple:
    """``(u0, v0, u1, v1)``: the mask's bounding box grown by ``margin`` of its size on each side, inside the image."""
    from ..data.images import mask_bounds

    v0, v1, u0, u1 = mask_bounds(mask)  # end exclusive
    H, W = np.shape(mask)
    du, dv = margin * (u1 - u0), margin * (v1 - v0)
    return (max(0, int(u0 - du)), max(0, int(v0 - dv)), min(W, int(u1 - 1 + du) + 1), min(H, int(v1 - 1 + dv) + 1))


def occluding_pixels(comparison: DepthComparison, depth, object_mask) -> np.ndarray:
    """Pixels ``(H, W)`` bool of ``object_mask`` where the sensor saw a surface nearer than the compared model by more
    than the tolerance: something in front of the object (an occluder taken into its segment), not the object. A model
    that lies behind the mask's pixels throughout (a negative median of ``observed - model``) is measured from that
    offset: only what stands out in front of the rest counts.

    Parameters
    ----------
    comparison : DepthComparison
        Made by :func:`ancsh.solvers.twin.compare_fit` with this ``object_mask`` (its residual map covers
        :func:`mask_window` of the mask).
    depth : (H, W) float64
        The observed depth (metres, 0 = no measurement).
    object_mask : (H, W) bool
    """
    mask = np.asarray(object_mask, dtype=bool)
    out = np.zeros(mask.shape, dtype=bool)
    o, inside, residual, window = _window(comparison, depth, mask)
    inside = inside & np.isfinite(residual)  # empty for an empty mask
    if not inside.any():
        return out
    offset = float(np.median(residual[inside]))  # a model fitted a little behind (or before) its points throughout
    with np.errstate(invalid="ignore"):
        nearer = residual - min(offset, 0.0) < -(ABS_TOLERANCE_M + REL_TOLERANCE * o)
    out[window] = nearer & inside
    return out

