"""A depth-sensor noise model (structured-light, Kinect-like).

Applied to a rendered depth image (metres, ``0`` = no measurement) in this order:

1. **Edge dropout**: pixels at a depth discontinuity -- a 4-neighbour that differs by more
   than ``edge_threshold`` metres or has no measurement (object silhouette) -- are
   dropped with probability ``edge_dropout`` (structured-light sensors lose these).
2. **Random dropout**: any remaining pixel is dropped with probability ``random_dropout``.
   **Blob holes**: a share ``blob_holes`` of the remaining pixels is dropped in blobs (where a random field
   smoothed over ``blob_size_px`` pixels is highest): what real sensors leave on dark, shiny or translucent patches
   (off by default).
3. **Mixed ("flying") pixels**: a remaining edge pixel whose neighbour across the jump has a
   measurement takes, with probability ``edge_mixing``, a depth between its own and that
   neighbour's (a uniform share of 20-80 % of the way): what real sensors report where a pixel
   sees both surfaces (off by default).
4. **Axial noise**: every remaining pixel gets Gaussian noise with standard deviation
   ``sigma(z) = sigma_a + sigma_b * (z - sigma_z0)**2`` (Nguyen, Izadi and Lovell, 3DIMPVT
   2012, fitted on a Kinect v1: ``0.0012 + 0.0019 (z - 0.4)^2`` metres).
5. **Quantisation**: depths rounded to multiples of ``quantisation`` metres (0, the default: off;
   sensors that write millimetres: 0.001).

Edges are found on the noise-free image. With ``DepthNoise.off()`` (or ``noise=None``)
:func:`apply_noise` returns an exact copy. :meth:`DepthNoise.real_frames` adds the quantisation and the blob holes
the project's real sensor frames show (``docs/results/sensor_realism.md``).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

import numpy as np

from ..geometry._checks import check_bool, check_generator, check_number, check_positive

__all__ = ["DepthNoise", "apply_noise", "averaged_depth", "depth_edges", "measured_sigma", "surface_mean"]


@dataclass(frozen=True)
class DepthNoise:
    """Parameters of the sensor noise model (see module docstring).

    Attributes
    ----------
    sigma_a : float
        Constant part of the axial standard deviation (metres), ``>= 0``.
    sigma_b : float
        Quadratic coefficient (1/metre), ``>= 0``.
    sigma_z0 : float
        Depth of the minimum of the quadratic (metres).
    edge_threshold : float
        Depth jump between 4-neighbours that marks an edge (metres), ``> 0``.
    edge_dropout : float
        Probability of dropping an edge pixel, in ``[0, 1]``.
    random_dropout : float
        Probability of dropping any pixel, in ``[0, 1]``.
    edge_mixing : float
        Probability that a kept edge pixel with a measured neighbour across the jump takes a depth between
        both, in ``[0, 1]`` (0: off).
    quantisation : float
        Depth step (metres), ``>= 0`` (0: off).
    blob_holes : float
        Share of the measured pixels dropped in blob holes, in ``[0, 1)`` (0: off).
    blob_size_px : float
        Length scale of the blob holes (pixels), ``> 0``.
    enabled : bool
        ``False`` turns the whole model off.
    """

    sigma_a: float = 0.0012
    sigma_b: float = 0.0019
    sigma_z0: float = 0.4
    edge_threshold: float = 0.02
    edge_dropout: float = 0.5
    random_dropout: float = 0.0
    enabled: bool = True
    edge_mixing: float = 0.0
    quantisation: float = 0.0
    blob_holes: float = 0.0
    blob_size_px: float = 10.0

    def __post_init__(self):
        for name in ("sigma_a", "sigma_b", "sigma_z0", "edge_threshold", "edge_dropout", "random_dropout",
                     "edge_mixing", "quantisation", "blob_holes", "blob_size_px"):
            object.__setattr__(self, name, check_number(getattr(self, name), name))
        for name in ("sigma_a", "sigma_b", "quantisation"):
            check_number(getattr(self, name), name, minimum=0.0)
        check_number(self.blob_holes, "blob_holes", minimum=0.0, maximum=0.99)
        check_positive(self.blob_size_px, "blob_size_px")
        check_positive(self.edge_threshold, "edge_threshold")
        for name in ("edge_dropout", "random_dropout", "edge_mixing"):
            check_number(getattr(self, name), name, minimum=0.0, maximum=1.0)
        check_bool(self.enabled, "enabled")

    @classmethod
    def off(cls) -> "DepthNoise":
        return cls(enabled=False)

    @classmethod
    def real_frames(cls) -> "DepthNoise":
        """The default model with the depth steps of the project's real sensor frames (whole millimetres;
        ``docs/results/sensor_realism.md``). Their edges are within what the default model gives already (at depth
        jumps between two flat surfaces 17-21 % of the pixels between are missing on the frames with more than a few
        jumps, 21-30 % on renders; 6-52 % lie between both surfaces, 27-41 % on renders, where steep faces between
        count too), so the edges stay; ``edge_mixing`` models a sensor that mixes more. Their missing pixels inside
        the image (0.2-2 %) lie mostly in blobs of over 100 pixels (33-93 % of them, against 3-4 % on renders): 1 % of
        the pixels go in blob holes."""
        return cls(quantisation=0.001, blob_holes=0.01)

    def sigma(self, z) -> np.ndarray:
        """Axial standard deviation (metres) at depth ``z`` (metres); zero when disabled."""
        z = np.asarray(z, dtype=np.float64)
        if not self.enabled:
            return np.zeros_like(z)
        return self.sigma_a + self.sigma_b * (z - self.sigma_z0) ** 2

    def to_json(self) -> str:
        """The parameters as JSON; the mixing, quantisation and blob holes only where on (so that the settings of
        datasets made before they existed read the same)."""
        d = asdict(self)
        for name in ("edge_mixing", "quantisation", "blob_holes"):
            if d[name] == 0.0:
                del d[name]
        if "blob_holes" not in d:
            del d["blob_size_px"]
        return json.dumps(d, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "DepthNoise":
        return cls(**json.loads(text))


def depth_edges(depth: np.ndarray, threshold: float) -> np.ndarray:
    """``(H, W)`` bool: valid pixels with a 4-neighbour jumping by more than ``threshold``
    metres or without a measurement. Image borders do not count as edges."""
    d = np.asarray(depth, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"depth: expected a 2-D image, got shape {d.shape}")
    valid = d > 0
    edge = np.zeros(d.shape, dtype=bool)
    # horizontal and vertical neighbour pairs
    for a, b in (((slice(None), slice(1, None)), (slice(None), slice(None, -1))), ((slice(1, None), slice(None)), (slice(None, -1), slice(None)))):
        jump = (np.abs(d[a] - d[b]) > threshold) | (valid[a] != valid[b])
        edge[a] |= jump
        edge[b] |= jump
    return edge & valid


def apply_noise(depth, noise: DepthNoise | None, rng) -> np.ndarray:
    """Noisy copy of a depth image.

    Parameters
    ----------
    depth : (H, W) float
        Noise-free depth (metres), ``0`` = no measurement.
    noise : DepthNoise or None
        ``None`` or a disabled model returns an exact copy.
    rng : numpy.random.Generator or int

    Returns
    -------
    (H, W) float64
        Noisy depth; dropped pixels are ``0``.
    """
    rng = check_generator(rng)
    d = np.array(depth, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"depth: expected a 2-D image, got shape {d.shape}")
    if noise is None or not noise.enabled:
        return d
    if not isinstance(noise, DepthNoise):
        raise ValueError(f"noise: expected DepthNoise or None, got {type(noise).__name__}")
    valid = d > 0
    if not valid.any():
        return d
    # Work on the bounding window of the valid pixels (plus a 1-pixel border) only.
    rows, cols = np.flatnonzero(valid.any(axis=1)), np.flatnonzero(valid.any(axis=0))
    r0, r1 = max(rows[0] - 1, 0), min(rows[-1] + 2, d.shape[0])
    c0, c1 = max(cols[0] - 1, 0), min(cols[-1] + 2, d.shape[1])
    win = d[r0:r1, c0:c1]
    keep = win > 0
    if noise.edge_dropout > 0:
        edges = depth_edges(win, noise.edge_threshold)
        keep &= ~(edges & (rng.random(win.shape) < noise.edge_dropout))
    if noise.random_dropout > 0:
        keep &= rng.random(win.shape) >= noise.random_dropout
    if noise.blob_holes > 0:
        keep &= ~_blob_holes(keep, noise, rng)
    if noise.edge_mixing > 0:
        win = _mix_edges(win, keep, noise, rng)
    z = win[keep]
    noisy = z + rng.standard_normal(z.shape) * noise.sigma(z)
    if noise.quantisation > 0:
        noisy = np.round(noisy / noise.quantisation) * noise.quantisation
    # A measurement behind the camera is no measurement (never happens at sensor depths).
    out = np.zeros_like(win)
    out[keep] = np.where(noisy > 0, noisy, 0.0)
    d[r0:r1, c0:c1] = out
    return d


def _mix_edges(win: np.ndarray, keep: np.ndarray, noise: DepthNoise, rng) -> np.ndarray:
    """``win`` with kept edge pixels moved towards their neighbour across the largest jump (noise-free
    depths; see :class:`DepthNoise`, ``edge_mixing``)."""
    H, W = win.shape
    target = np.zeros_like(win)
    best = np.zeros_like(win)  # the largest jump to a measured 4-neighbour
    padded = np.pad(win, 1)
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        nb = padded[1 + dr:1 + dr + H, 1 + dc:1 + dc + W]
        jump = np.where((nb > 0) & (win > 0), np.abs(nb - win), 0.0)
        better = jump > best
        best = np.where(better, jump, best)
        target = np.where(better, nb, target)
    mix = keep & (best > noise.edge_threshold) & (rng.random(win.shape) < noise.edge_mixing)
    share = rng.uniform(0.2, 0.8, size=win.shape)
    return np.where(mix, win + share * (target - win), win)


def _blob_holes(keep: np.ndarray, noise: DepthNoise, rng) -> np.ndarray:
    """Pixels of ``keep`` to drop in blobs: the share ``noise.blob_holes`` of them where white noise smoothed over
    ``noise.blob_size_px`` pixels is highest."""
    from scipy.ndimage import gaussian_filter

    if not keep.any():
        return np.zeros_like(keep)
    field = gaussian_filter(rng.standard_normal(keep.shape), noise.blob_size_px, mode="wrap")
    cut = np.quantile(field[keep], 1.0 - noise.blob_holes)
    return keep & (field > cut)


def measured_sigma(depth, mask) -> float:
    """The depth noise's standard deviation (metres) measured inside ``mask``: each pixel's residual from the mean of
    its 3 x 3 neighbourhood, at the pixels whose whole neighbourhood is measured and inside the mask (a robust
    standard deviation, corrected for the pixel's own share of the mean). Curved surfaces and edges inside the mask
    inflate it a little. NaN when fewer than 50 such pixels.

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    mask : (H, W) bool
    """
    from scipy.ndimage import uniform_filter

    d, m, _ = _masked_window(depth, mask)
    if d is None:
        return float("nan")
    on = m & (d > 0)
    full = uniform_filter(on.astype(np.float64), 3, mode="constant") > 1.0 - 1e-9
    if np.count_nonzero(full) < 50:
        return float("nan")
    mean = uniform_filter(np.where(on, d, 0.0), 3, mode="constant")
    residual = np.abs(d - mean)[full] / np.sqrt(1.0 - 1.0 / 9.0)
    return float(1.4826 * np.median(residual))


def averaged_depth(depth, mask, window: int, jump: float) -> np.ndarray:
    """``depth`` with each measured pixel of ``mask`` replaced by the mean of the measured mask pixels in its
    ``window x window`` neighbourhood whose depth is within ``jump`` metres of its own (the same surface: depth steps
    inside the mask stay sharp). Pixels outside the mask are unchanged. A copy; ``depth`` itself where ``window`` is 1.

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    mask : (H, W) bool
    window : int
        Odd, at least 1 (pixels).
    jump : float
        Metres, > 0.
    """
    if isinstance(window, bool) or int(window) != window or window < 1 or window % 2 == 0:
        raise ValueError(f"window: expected an odd positive integer, got {window!r}")
    if not (np.isfinite(jump) and jump > 0):
        raise ValueError(f"jump: expected a positive number of metres, got {jump!r}")
    d, m, bounds = _masked_window(depth, mask)
    if window == 1:
        return np.asarray(depth, dtype=np.float64)
    out = np.array(depth, dtype=np.float64)
    if d is None:
        return out
    v0, v1, u0, u1 = bounds
    on = m & (d > 0)
    mean, _ = surface_mean(d, d, on, jump, int(window) // 2)
    out[v0:v1, u0:u1][on] = mean[on]
    return out


def surface_mean(values, depth, valid, jump, radius: int) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's mean of ``values`` over the ``valid`` pixels of its ``(2 radius + 1)^2`` window whose ``depth`` is
    within ``jump`` of its own (the same surface: depth edges stay sharp); a pixel that is not valid counts for none.

    Parameters
    ----------
    values : (h, w) or (h, w, k) float64
        What is averaged (depths, or points).
    depth : (h, w) float64
        Metres: what decides which neighbours are on the pixel's surface.
    valid : (h, w) bool
    jump : float or (h, w) float64
        Metres.
    radius : int

    Returns
    -------
    mean : like ``values``
        ``values`` where no neighbour counts (``valid`` False).
    counts : (h, w) int64
        Neighbours averaged per pixel (itself included; 0 off ``valid``).
    """
    values = np.asarray(values, dtype=np.float64)
    h, w = valid.shape
    r = int(radius)
    channels = values.ndim == 3
    pad = ((r, r), (r, r), (0, 0)) if channels else r
    padded, padded_z, padded_valid = np.pad(values, pad), np.pad(depth, r), np.pad(valid, r)
    total = np.zeros(values.shape)
    counts = np.zeros(valid.shape, dtype=np.int64)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            window = (slice(r + dy, r + dy + h), slice(r + dx, r + dx + w))
            same = padded_valid[window] & valid & (np.abs(padded_z[window] - depth) < jump)
            total += np.where(same[..., None] if channels else same, padded[window], 0.0)
            counts += same
    mean = values.copy()
    some = counts > 0
    mean[some] = total[some] / (counts[some][:, None] if channels else counts[some])
    return mean, counts


def _masked_window(depth, mask):
    """``(depth, mask, bounds)`` cut to the mask's bounding box (:func:`~ancsh.data.images.mask_bounds`), or
    ``(None, None, None)`` for an empty mask; a ``ValueError`` when their shapes differ."""
    from .images import mask_bounds

    depth = np.asarray(depth, dtype=np.float64)
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != depth.shape:
        raise ValueError(f"depth, mask: expected one shape, got {depth.shape}, {mask.shape}")
    bounds = mask_bounds(mask)
    if bounds is None:
        return None, None, None
    v0, v1, u0, u1 = bounds
    return depth[v0:v1, u0:u1], mask[v0:v1, u0:u1], bounds
