"""Depth rendering by ray casting (CPU, headless): open3d's ``RaycastingScene``, or numpy.

Camera convention (OpenCV)
--------------------------
The camera frame ``cam`` has ``+x`` right, ``+y`` down and ``+z`` forward (viewing direction).
Pixel ``(u, v)`` is column ``u``, row ``v``; integer coordinates are pixel *centres*, so the
pixel centre ``(u, v)`` back-projects along the ray ``((u - cx) / fx, (v - cy) / fy, 1)``.
Depth is the ``z`` coordinate of the hit point in the camera frame (metres), not the ray
length; ``0`` marks "no hit". ``T_cam_base`` maps the object's base frame into the camera.

Default intrinsics
------------------
640x480 with ``fx = fy = 525``, ``cx = 319.5``, ``cy = 239.5``: the Kinect v1 (PrimeSense)
calibration commonly used for RGB-D benchmarks (about 62 x 49 degrees field of view).

Rendering
---------
A :class:`ModelRenderer` caches, per articulated model, the part meshes as float32 arrays
and a fixed set of surface samples. Each render transforms the part vertices into the
camera frame (forward kinematics), builds one ``RaycastingScene`` with one geometry per
part (geometry id -> part index) and casts one ray per pixel centre -- only inside the
image rectangle covered by the projected vertices, which is exact and much cheaper than
casting the whole image. Rebuilding the BVH costs well under a millisecond for the
procedural objects; casting dominates.

Backends
--------
``ModelRenderer(..., backend=)``: ``"open3d"`` (a BVH, the default where open3d is installed),
``"numpy"`` (:class:`~ancsh.data.raycast.CameraRayCaster`: a grid over the image plane; the same
depths up to float rounding on triangle edges, slower on meshes of many thousand triangles) or
``"auto"`` (open3d when it can be imported, else numpy: e.g. on a GPU machine with only torch).

Visible-area ratio
------------------
For each part, ``visibility = visible surface area / total surface area`` is estimated by
ray casting a fixed, area-uniform sample of surface points (default 1024 per part): a
sample is visible when it lies inside the image and the ray from the camera centre
through it hits nothing before it. This avoids the grazing-angle blow-up of pixel
footprint estimates; its standard error is ``sqrt(r (1 - r) / samples)``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..geometry._checks import as_array, check_generator
from ..geometry.transforms import Sim3
from ..model.articulated import sample_surface
from .category_types import CategoryConvention, ViewpointRange

__all__ = [
    "DEFAULT_VIEWPOINT",
    "DepthFrame",
    "RENDER_BACKENDS",
    "Intrinsics",
    "ModelRenderer",
    "ViewpointRange",
    "backproject",
    "look_at",
    "object_extent",
    "pixels_to_points",
    "project",
    "render_depth",
    "sample_points",
    "sample_viewpoint",
    "viewpoint_pose",
    "viewpoint_range",
]

RENDER_BACKENDS = ("auto", "open3d", "numpy")
"""The ray-casting backends of :class:`ModelRenderer` (see the module docstring)."""


@functools.lru_cache(maxsize=None)
def _open3d_importable() -> bool:
    try:
        import open3d  # noqa: F401
    except ImportError:
        return False
    return True


def _resolve_backend(backend: str) -> str:
    """``"open3d"`` or ``"numpy"`` for a :data:`RENDER_BACKENDS` name (``"auto"``: open3d where importable)."""
    if backend == "auto":
        return "open3d" if _open3d_importable() else "numpy"
    return backend


# Depths below this are treated as behind the camera when cropping the ray grid (metres).
_NEAR = 1e-3
# Relative tolerance on the ray parameter when testing a surface sample for visibility.
_VISIBILITY_TOL = 1e-5


# --------------------------------------------------------------------------------------
# intrinsics
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics (pixels) and image size.

    Attributes
    ----------
    fx, fy : float
        Focal lengths in pixels, positive.
    cx, cy : float
        Principal point in pixels (pixel centres at integer coordinates).
    width, height : int
        Image size in pixels, positive.
    """

    fx: float = 525.0
    fy: float = 525.0
    cx: float = 319.5
    cy: float = 239.5
    width: int = 640
    height: int = 480

    def __post_init__(self):
        for name in ("fx", "fy", "cx", "cy"):
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"{name}: expected a number, got {value!r}") from None
            if not np.isfinite(value):
                raise ValueError(f"{name}: expected a finite number, got {value}")
            object.__setattr__(self, name, value)
        for name in ("fx", "fy"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name}: focal length must be positive, got {getattr(self, name)}")
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or int(value) <= 0:
                raise ValueError(f"{name}: expected a positive integer, got {value!r}")
            object.__setattr__(self, name, int(value))

    @classmethod
    def kinect(cls, width: int = 640, height: int = 480) -> "Intrinsics":
        """Kinect-v1-like intrinsics scaled to ``width x height`` (same field of view)."""
        sx, sy = width / 640.0, height / 480.0
        return cls(525.0 * sx, 525.0 * sy, (width - 1) / 2.0, (height - 1) / 2.0, width, height)

    def matrix(self) -> np.ndarray:
        """``(3, 3)`` calibration matrix ``K``."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def as_array(self) -> np.ndarray:
        """``(6,)`` float64 ``[fx, fy, cx, cy, width, height]``."""
        return np.array([self.fx, self.fy, self.cx, self.cy, self.width, self.height], dtype=np.float64)

    @classmethod
    def from_array(cls, values) -> "Intrinsics":
        v = as_array(values, "values", (6,))
        return cls(v[0], v[1], v[2], v[3], int(round(v[4])), int(round(v[5])))

    def to_json(self) -> dict:
        return {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy, "width": self.width, "height": self.height}

    @classmethod
    def from_json(cls, data: dict) -> "Intrinsics":
        keys = {"fx", "fy", "cx", "cy", "width", "height"}
        if not isinstance(data, dict) or set(data) != keys:
            got = sorted(data) if isinstance(data, dict) else type(data).__name__
            raise ValueError(f"data: expected the keys {sorted(keys)}, got {got}")
        for name in sorted(keys):  # JSON numbers only: "525" (a string) is a mistake, not a focal length
            if isinstance(data[name], bool) or not isinstance(data[name], (int, float)):
                raise ValueError(f"{name}: expected a JSON number, got {data[name]!r}")
        return cls(**data)


@functools.lru_cache(maxsize=8)
def _ray_grid(intr: Intrinsics) -> np.ndarray:
    """``(H, W, 3)`` float32 ray directions with ``z = 1`` through every pixel centre."""
    u = (np.arange(intr.width, dtype=np.float64) - intr.cx) / intr.fx
    v = (np.arange(intr.height, dtype=np.float64) - intr.cy) / intr.fy
    grid = np.empty((intr.height, intr.width, 3), dtype=np.float32)
    grid[..., 0] = u[None, :]
    grid[..., 1] = v[:, None]
    grid[..., 2] = 1.0
    grid.flags.writeable = False
    return grid


def project(points, intrinsics: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Project camera-frame points.

    Parameters
    ----------
    points : (N, 3) float64
        Points in the camera frame (metres), ``z > 0``.
    intrinsics : Intrinsics

    Returns
    -------
    uv : (N, 2) float64
        Pixel coordinates ``(u, v)`` (column, row).
    z : (N,) float64
        Depths (metres).
    """
    p = as_array(points, "points", (None, 3))
    z = p[:, 2]
    if np.any(z <= 0):
        raise ValueError("points: every point must be in front of the camera (z > 0)")
    uv = np.stack([intrinsics.fx * p[:, 0] / z + intrinsics.cx, intrinsics.fy * p[:, 1] / z + intrinsics.cy], axis=1)
    return uv, z.copy()


def backproject(depth, intrinsics: Intrinsics, mask=None) -> np.ndarray:
    """Back-project a depth image to camera-frame points.

    Parameters
    ----------
    depth : (H, W) float
        Depth (``z``, metres); ``0`` = no measurement.
    intrinsics : Intrinsics
        Must match the image size.
    mask : (H, W) bool, optional
        Extra pixel selection, combined with ``depth > 0``.

    Returns
    -------
    (N, 3) float64
        Points of the selected pixels in row-major pixel order.
    """
    d, valid = valid_depth_pixels(depth, intrinsics, mask)
    v, u = np.nonzero(valid)
    return pixels_to_points(u, v, d[v, u], intrinsics)


def valid_depth_pixels(depth, intrinsics: Intrinsics, mask=None) -> tuple[np.ndarray, np.ndarray]:
    """Checked depth image ``(H, W)`` float64 (metres) and its valid pixels: depth > 0, inside ``mask``.

    Raises
    ------
    ValueError
        When ``depth`` does not match the intrinsics' image size or ``mask`` is not a bool
        array of the same shape.
    """
    d = _check_image(depth, intrinsics, "depth")
    valid = d > 0
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != d.shape or m.dtype != bool:
            raise ValueError(f"mask: expected a bool array of shape {d.shape}, got {m.dtype} {m.shape}")
        valid &= m
    return d, valid


def pixels_to_points(u, v, z, intr: Intrinsics) -> np.ndarray:
    """Camera-frame points ``(N, 3)`` (metres) of pixels ``(u, v)`` (columns, rows; ``(N,)`` each) at depths ``z``."""
    z = np.asarray(z, dtype=np.float64)
    return np.stack([(u - intr.cx) / intr.fx * z, (v - intr.cy) / intr.fy * z, z], axis=1)


def _check_image(image, intrinsics: Intrinsics, name: str) -> np.ndarray:
    if not isinstance(intrinsics, Intrinsics):
        raise ValueError(f"intrinsics: expected Intrinsics, got {type(intrinsics).__name__}")
    img = np.asarray(image, dtype=np.float64)
    if img.shape != (intrinsics.height, intrinsics.width):
        raise ValueError(
            f"{name}: image shape {img.shape} does not match the intrinsics' (height, width) "
            f"{(intrinsics.height, intrinsics.width)}"
        )
    return img


def sample_points(depth, part_ids, intrinsics: Intrinsics, count: int, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample ``count`` back-projected pixels uniformly.

    Draws without replacement when at least ``count`` pixels are valid (depth > 0 and a
    part id), otherwise uniformly with replacement. Points come in row-major pixel order.

    Parameters
    ----------
    depth : (H, W) float
        Depth image (metres), ``0`` = invalid.
    part_ids : (H, W) int
        Part index per pixel, ``-1`` = background.
    intrinsics : Intrinsics
    count : int
        Number of points, positive.
    rng : numpy.random.Generator or int

    Returns
    -------
    points : (count, 3) float64
        Camera frame, metres.
    labels : (count,) int64
        Part index of each point.
    pixels : (count,) int64
        Flat (row-major) pixel index of each point.
    """
    rng = check_generator(rng)
    if isinstance(count, bool) or int(count) != count or count <= 0:
        raise ValueError(f"count: expected a positive integer, got {count!r}")
    d = _check_image(depth, intrinsics, "depth")
    ids = np.asarray(part_ids)
    if ids.shape != d.shape:
        raise ValueError(f"part_ids: expected shape {d.shape}, got {ids.shape}")
    flat = np.flatnonzero((d > 0).ravel() & (ids.ravel() >= 0))
    if flat.size == 0:
        raise ValueError("depth: no valid object pixel to sample from")
    pick = rng.choice(flat.size, size=int(count), replace=flat.size < count)
    pixels = np.sort(flat[pick])
    v, u = np.divmod(pixels, intrinsics.width)
    points = pixels_to_points(u, v, d.ravel()[pixels], intrinsics)
    return points, ids.ravel()[pixels].astype(np.int64), pixels.astype(np.int64)


# --------------------------------------------------------------------------------------
# rendering
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DepthFrame:
    """A rendered depth image with per-pixel part ids.

    Attributes
    ----------
    depth : (H, W) float64
        ``z`` in the camera frame (metres), ``0`` = no hit.
    part_ids : (H, W) int32
        Part index of the surface hit, ``-1`` = background.
    intrinsics : Intrinsics
    visibility : (M,) float64 or None
        Visible-area ratio of each part (see module docstring), when requested.
    """

    depth: np.ndarray
    part_ids: np.ndarray
    intrinsics: Intrinsics
    visibility: np.ndarray | None = None

    def part_pixels(self, num_parts: int) -> np.ndarray:
        """``(num_parts,)`` int64 number of pixels showing each part."""
        ids = self.part_ids[self.part_ids >= 0]
        return np.bincount(ids, minlength=num_parts)[:num_parts].astype(np.int64)


class ModelRenderer:
    """Renders one articulated model from any joint state and camera pose.

    Parameters
    ----------
    model : ArticulatedModel
        Parts without a mesh are never seen (no pixels, visibility 0); at least one
        part needs a mesh.
    visibility_samples : int
        Surface samples per part for the visible-area ratio (fixed, seeded by
        ``sample_seed``).
    sample_seed : int
    backend : {"auto", "open3d", "numpy"}
        Ray-casting backend (module docstring); ``"auto"`` is open3d where it can be imported.
    """

    def __init__(self, model, *, visibility_samples: int = 1024, sample_seed: int = 0, backend: str = "auto"):
        if backend not in RENDER_BACKENDS:
            raise ValueError(f"backend: expected one of {', '.join(RENDER_BACKENDS)}, got {backend!r}")
        self.backend = _resolve_backend(backend)
        if isinstance(visibility_samples, bool) or int(visibility_samples) != visibility_samples or visibility_samples <= 0:
            raise ValueError(f"visibility_samples: expected a positive integer, got {visibility_samples!r}")
        self.model = model
        self._vertices, self._faces, self._samples = [], [], []
        rng = np.random.default_rng(sample_seed)
        for part in model.parts:
            if part.mesh is None:  # e.g. a URDF link without geometry: never seen
                v, f = np.empty((0, 3)), np.empty((0, 3), dtype=np.int64)
            else:
                v = np.asarray(part.mesh.vertices, dtype=np.float64)
                f = np.asarray(part.mesh.faces, dtype=np.int64).reshape(-1, 3)
            self._vertices.append(v)
            self._faces.append(np.ascontiguousarray(f, dtype=np.uint32))
            self._samples.append(sample_surface(part.mesh, int(visibility_samples), rng) if len(f) else np.empty((0, 3)))
        if not any(len(f) for f in self._faces):
            raise ValueError(f"model: no part of {model.name!r} has a mesh to render")

    @property
    def num_parts(self) -> int:
        return self.model.num_parts

    def part_poses(self, q, T_cam_base: Sim3) -> list[Sim3]:
        """``T_cam_part`` of every part at joint states ``q``."""
        if not isinstance(T_cam_base, Sim3):
            raise ValueError(f"T_cam_base: expected a Sim3, got {type(T_cam_base).__name__}")
        return [T_cam_base @ T for T in self.model.forward_kinematics(q)]

    def vertices_cam(self, q, T_cam_base: Sim3) -> list[np.ndarray]:
        """Part vertices ``(V_j, 3)`` in the camera frame at ``q`` (metres)."""
        return [T.apply(v) for T, v in zip(self.part_poses(q, T_cam_base), self._vertices)]

    def _scene(self, verts_cam, nthreads: int = 1):
        """A function ``cast(directions (..., 3)) -> (t, part)`` for rays from the camera centre.

        ``t`` is the hit's ray parameter (``inf``: no hit), ``part`` the hit part's index (``-1``).
        """
        meshes = [(v, f) for v, f in zip(verts_cam, self._faces)]
        if self.backend == "numpy":
            from .raycast import CameraRayCaster

            return CameraRayCaster(meshes).cast
        import open3d as o3d

        scene = o3d.t.geometry.RaycastingScene()
        lookup = {}
        for j, (v, f) in enumerate(meshes):
            if not len(f):
                continue
            gid = scene.add_triangles(
                o3d.core.Tensor(np.ascontiguousarray(v, dtype=np.float32)), o3d.core.Tensor(f)
            )
            lookup[int(gid)] = j
        table = np.full(max(lookup) + 2, -1, dtype=np.int32)
        for gid, j in lookup.items():
            table[gid] = j

        def cast(directions):
            d = np.asarray(directions, dtype=np.float32)
            rays = np.zeros(d.shape[:-1] + (6,), dtype=np.float32)
            rays[..., 3:] = d
            hit = scene.cast_rays(o3d.core.Tensor(rays), nthreads=nthreads)
            t = hit["t_hit"].numpy().astype(np.float64)
            ok = np.isfinite(t)
            part = np.full(t.shape, -1, dtype=np.int64)
            part[ok] = table[np.minimum(hit["geometry_ids"].numpy()[ok], len(table) - 1)]
            return np.where(ok, t, np.inf), part

        return cast

    def render(self, q, T_cam_base: Sim3, intrinsics: Intrinsics | None = None, *, visibility: bool = False, nthreads: int = 1) -> DepthFrame:
        """Render depth and part ids.

        Parameters
        ----------
        q : (K,) float64
            Absolute joint states within the limits.
        T_cam_base : Sim3
            Rigid base -> camera transform.
        intrinsics : Intrinsics, optional
            Default :class:`Intrinsics` (640x480 Kinect-like).
        visibility : bool
            Also estimate each part's visible-area ratio.
        nthreads : int
            open3d ray-casting threads (0 = all cores).
        """
        intr = Intrinsics() if intrinsics is None else intrinsics
        if not isinstance(intr, Intrinsics):
            raise ValueError(f"intrinsics: expected Intrinsics, got {type(intr).__name__}")
        if not isinstance(T_cam_base, Sim3) or not T_cam_base.is_rigid:
            raise ValueError("T_cam_base: expected a rigid Sim3 (scale 1)")
        poses = self.part_poses(q, T_cam_base)
        verts = [T.apply(v) for T, v in zip(poses, self._vertices)]
        cast = self._scene(verts, nthreads)
        H, W = intr.height, intr.width
        depth = np.zeros((H, W), dtype=np.float64)
        ids = np.full((H, W), -1, dtype=np.int32)

        window = _pixel_window(np.concatenate([v for v, f in zip(verts, self._faces) if len(f)]), intr)
        if window is not None:
            v0, v1, u0, u1 = window
            t, part = cast(_ray_grid(intr)[v0:v1, u0:u1])
            ok = np.isfinite(t)
            depth[v0:v1, u0:u1] = np.where(ok, t, 0.0)  # direction z = 1, so t is the depth
            ids[v0:v1, u0:u1] = part

        vis = None
        if visibility:
            vis = self._visibility(cast, poses, intr)
        return DepthFrame(depth, ids, intr, vis)

    def _visibility(self, cast, poses, intr: Intrinsics) -> np.ndarray:
        pts = [T.apply(s) for T, s in zip(poses, self._samples)]
        counts = [len(p) for p in pts]
        P = np.concatenate(pts)
        z = P[:, 2]
        front = z > _NEAR
        zs = np.where(front, z, 1.0)
        u = intr.fx * P[:, 0] / zs + intr.cx
        v = intr.fy * P[:, 1] / zs + intr.cy
        inside = front & (u >= -0.5) & (u < intr.width - 0.5) & (v >= -0.5) & (v < intr.height - 0.5)
        t, _ = cast(P)
        seen = inside & (t >= 1.0 - _VISIBILITY_TOL)
        out = np.zeros(len(counts))
        start = 0
        for j, c in enumerate(counts):
            out[j] = seen[start : start + c].mean() if c else 0.0
            start += c
        return out


def _pixel_window(points_cam: np.ndarray, intr: Intrinsics):
    """Pixel rectangle ``(v0, v1, u0, u1)`` (half-open) covering the projected points.

    Returns the whole image when a point is at or behind the camera plane, ``None``
    when the projection misses the image.
    """
    z = points_cam[:, 2]
    if np.all(z <= _NEAR):
        return None
    if np.any(z <= _NEAR):
        return 0, intr.height, 0, intr.width
    u = intr.fx * points_cam[:, 0] / z + intr.cx
    v = intr.fy * points_cam[:, 1] / z + intr.cy
    u0 = max(int(np.floor(u.min())), 0)
    u1 = min(int(np.ceil(u.max())) + 1, intr.width)
    v0 = max(int(np.floor(v.min())), 0)
    v1 = min(int(np.ceil(v.max())) + 1, intr.height)
    if u0 >= u1 or v0 >= v1:
        return None
    return v0, v1, u0, u1


def render_depth(model, q, T_cam_base: Sim3, intrinsics: Intrinsics | None = None, *, visibility: bool = False,
                 backend: str = "auto") -> DepthFrame:
    """One-shot :meth:`ModelRenderer.render` (use a :class:`ModelRenderer` for many frames)."""
    return ModelRenderer(model, backend=backend).render(q, T_cam_base, intrinsics, visibility=visibility)


# --------------------------------------------------------------------------------------
# viewpoints
# --------------------------------------------------------------------------------------
#: The range of a category without its own (``[viewpoint]`` of its spec).
DEFAULT_VIEWPOINT = ViewpointRange()


def viewpoint_range(category) -> ViewpointRange:
    """The :class:`ViewpointRange` of ``category`` (a name, a
    :class:`~ancsh.data.category_types.CategoryConvention` or a range): its spec's ``[viewpoint]`` (the default range
    where it gives none; ``None`` -> the default range).

    The paper renders "random camera viewpoints" with PyBullet without giving ranges; the built-in specs keep the
    user-facing side of each category in view (front doors, drawer fronts, the laptop's open side, the eyeglasses'
    front frame) as a depth camera in a room would see them.
    """
    if category is None:
        return DEFAULT_VIEWPOINT
    if isinstance(category, ViewpointRange):
        return category
    from .conventions import CONVENTIONS

    if isinstance(category, CategoryConvention):
        view = category.viewpoint
        return ViewpointRange(**dict(view)) if view else DEFAULT_VIEWPOINT
    if not isinstance(category, str) or category not in CONVENTIONS:
        raise ValueError(f"category: unknown category {category!r}; known: {sorted(CONVENTIONS)} (or None)")
    return viewpoint_range(CONVENTIONS[category])


def look_at(eye, target, up) -> Sim3:
    """Rigid ``T_cam_world`` of an OpenCV camera at ``eye`` looking at ``target``.

    ``up`` (a world direction, not parallel to the view) appears as image "up" (-y).
    """
    eye = as_array(eye, "eye", (3,))
    target = as_array(target, "target", (3,))
    up = as_array(up, "up", (3,))
    z = target - eye
    n = np.linalg.norm(z)
    if n < 1e-12:
        raise ValueError("target: coincides with eye")
    z /= n
    x = np.cross(z, up)
    nx = np.linalg.norm(x)
    if nx < 1e-9:
        raise ValueError("up: parallel to the viewing direction")
    x /= nx
    y = np.cross(z, x)
    R_world_cam = np.stack([x, y, z], axis=1)
    return Sim3(R_world_cam, eye).inverse()


def object_extent(model, q) -> tuple[np.ndarray, float]:
    """Centre ``(3,)`` (base frame, metres) and diagonal (metres) of the box of all part
    vertices at ``q`` (parts without a mesh are ignored)."""
    poses = model.forward_kinematics(q)
    pts = [T.apply(p.vertices) for T, p in zip(poses, model.parts) if p.mesh is not None]
    if not pts:
        raise ValueError(f"model: no part of {model.name!r} has a mesh")
    pts = np.concatenate(pts)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return 0.5 * (lo + hi), float(np.linalg.norm(hi - lo))


def sample_viewpoint(category, rng, model=None, q=None, *, center=None, diagonal=None) -> Sim3:
    """Random rigid ``T_cam_base`` for ``category`` (see :class:`ViewpointRange`).

    Parameters
    ----------
    category : str, ViewpointRange or None
        A category (its spec's ``[viewpoint]``), an explicit range, or ``None`` for the default.
    rng : numpy.random.Generator or int
    model : ArticulatedModel, optional
        When given (with ``q``, default its rest state), the camera aims at the centre of
        the object's box and scales distance by its diagonal; its ``R_canon_base``
        orients the azimuth/elevation frame.
    q : (K,) float64, optional
    center : (3,) float64, optional
        Look-at point in the base frame (metres); overrides the model's box centre.
    diagonal : float, optional
        Object size (metres); overrides the model's box diagonal. Default 1.
    """
    rng = check_generator(rng)
    vr = viewpoint_range(category)
    R_canon_base = np.eye(3)
    c, diag = np.zeros(3), 1.0
    if model is not None:
        q = model.rest_states if q is None else q
        c, diag = object_extent(model, q)
        R_canon_base = model.R_canon_base
    if center is not None:
        c = as_array(center, "center", (3,))
    if diagonal is not None:
        diag = float(diagonal)
        if not np.isfinite(diag) or diag <= 0:
            raise ValueError(f"diagonal: expected a positive number, got {diagonal}")
    d = rng.uniform(*vr.distance) * diag
    az = rng.uniform(*vr.azimuth)
    el = rng.uniform(*vr.elevation)
    roll = rng.uniform(-vr.roll, vr.roll)
    jitter = rng.normal(0.0, vr.target_jitter * diag, size=3)
    return viewpoint_pose(c + jitter, R_canon_base, distance=d, azimuth=az, elevation=el, roll=roll)


def viewpoint_pose(target, R_canon_base, *, distance: float, azimuth: float, elevation: float, roll: float = 0.0) -> Sim3:
    """Rigid ``T_cam_base`` of a camera placed as :class:`ViewpointRange` describes, from explicit values.

    Parameters
    ----------
    target : (3,) float64
        Look-at point in the base frame (metres).
    R_canon_base : (3, 3) float64
        Base frame -> canonical axes (``+y`` up, ``+z`` front) of the object.
    distance : float
        Camera distance from the target (metres).
    azimuth, elevation, roll : float
        Radians (see :class:`ViewpointRange`).
    """
    target = as_array(target, "target", (3,))
    direction_canon = np.array([np.cos(elevation) * np.sin(azimuth), np.sin(elevation),
                                np.cos(elevation) * np.cos(azimuth)])
    eye = target + float(distance) * (R_canon_base.T @ direction_canon)
    T_cam_base = look_at(eye, target, R_canon_base.T @ np.array([0.0, 1.0, 0.0]))
    c_r, s_r = np.cos(roll), np.sin(roll)
    R_roll = np.array([[c_r, -s_r, 0.0], [s_r, c_r, 0.0], [0.0, 0.0, 1.0]])
    return Sim3(R_roll, np.zeros(3)) @ T_cam_base
