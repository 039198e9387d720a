"""Template correspondences: closest points on a known articulated model.

Given an :class:`~ancsh.model.ArticulatedModel` instance (procedural or loaded from a
URDF) and an estimate of its pose (object pose ``T_cam_base`` and joint states ``q``),
every observed point is matched to the closest point on the model's surface posed at
that estimate. The match gives the point's part label and its coordinates in that
part's NPCS, which is exactly what the ANCSH network predicts; so the solver
formulations fit a template unchanged (paper Sec. 4.3 with a CAD model instead of a
network).

Closest points are exact points on the part meshes (open3d ``RaycastingScene``), not on
a point sampling of them, so a noise-free view is matched without discretisation error.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...geometry._checks import as_array, as_points
from ...geometry.transforms import Sim3
from ...model.articulated import ArticulatedModel

__all__ = [
    "ArticulatedPose",
    "ClosestPoints",
    "ModelSurface",
    "TemplateProvider",
    "robust_weights",
]

ROBUST_LOSSES = ("none", "huber", "cauchy", "tukey")


@dataclass(frozen=True)
class ArticulatedPose:
    """Pose of an articulated model instance in the camera.

    Attributes
    ----------
    T_cam_base : Sim3
        Base part frame -> camera (rigid, metres).
    q : (K,) float64
        Absolute joint states (radians / metres), ordered like ``model.joints``.
    """

    T_cam_base: Sim3
    q: np.ndarray

    def __post_init__(self):
        if not isinstance(self.T_cam_base, Sim3):
            raise ValueError(f"T_cam_base: expected a Sim3, got {type(self.T_cam_base).__name__}")
        q = as_array(self.q, "q", (None,)).copy()
        q.flags.writeable = False
        object.__setattr__(self, "q", q)

    def part_poses(self, model: ArticulatedModel) -> list[Sim3]:
        """``T_cam_part`` for every part, in part order."""
        return [self.T_cam_base @ T for T in model.forward_kinematics(self.q)]


@dataclass(frozen=True)
class ClosestPoints:
    """Closest model points of ``N`` observed points.

    Attributes
    ----------
    labels : (N,) int64
        Part of the closest model point.
    points_part : (N, 3) float64
        Closest point in that part's frame (metres).
    normals_part : (N, 3) float64
        Unit surface normal of the closest triangle, in the part frame.
    distances : (N,) float64
        Distance observed point -> closest model point (metres).
    """

    labels: np.ndarray
    points_part: np.ndarray
    normals_part: np.ndarray
    distances: np.ndarray


class ModelSurface:
    """The part meshes of a model, ready for closest-point queries.

    Parameters
    ----------
    model : ArticulatedModel
        Every part needs a mesh with triangles.
    """

    def __init__(self, model: ArticulatedModel):
        import open3d as o3d

        if not isinstance(model, ArticulatedModel):
            raise ValueError(f"model: expected an ArticulatedModel, got {type(model).__name__}")
        self.model = model
        self._scenes = []
        for part in model.parts:
            if part.mesh is None or len(np.asarray(part.mesh.faces)) == 0:
                raise ValueError(f"model: part {part.name!r} has no mesh triangles")
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(
                np.ascontiguousarray(part.mesh.vertices, dtype=np.float32),
                np.ascontiguousarray(part.mesh.faces, dtype=np.uint32),
            )
            self._scenes.append(scene)

    def closest(self, points_cam, T_cam_parts) -> ClosestPoints:
        """Closest points on the posed model surface.

        Parameters
        ----------
        points_cam : (N, 3) array_like
            Observed points in the camera frame (metres).
        T_cam_parts : sequence of Sim3
            ``(M,)`` part poses in the camera.
        """
        import open3d as o3d

        pts = as_points(points_cam, "points_cam")
        M = self.model.num_parts
        if len(T_cam_parts) != M:
            raise ValueError(f"T_cam_parts: expected {M} part poses, got {len(T_cam_parts)}")
        N = pts.shape[0]
        best = np.full(N, np.inf)
        labels = np.zeros(N, dtype=np.int64)
        local = np.zeros((N, 3))
        normals = np.zeros((N, 3))
        for j, (scene, T) in enumerate(zip(self._scenes, T_cam_parts)):
            q_part = T.inverse().apply(pts)
            r = scene.compute_closest_points(o3d.core.Tensor(q_part.astype(np.float32)))
            c = r["points"].numpy().astype(np.float64)
            d = np.linalg.norm(c - q_part, axis=1) * T.scale
            sel = d < best
            best[sel], labels[sel], local[sel] = d[sel], j, c[sel]
            normals[sel] = r["primitive_normals"].numpy().astype(np.float64)[sel]
        nn = np.linalg.norm(normals, axis=1, keepdims=True)
        normals = np.divide(normals, nn, out=np.zeros_like(normals), where=nn > 0)
        return ClosestPoints(labels, local, normals, best)

    def sample(self, count: int, rng) -> tuple[np.ndarray, np.ndarray]:
        """``count`` surface points per part in the part frames: ``(points (M*count, 3), labels)``."""
        from ...model.articulated import sample_surface

        pts, labels = [], []
        for j, part in enumerate(self.model.parts):
            pts.append(sample_surface(part.mesh, count, rng))
            labels.append(np.full(count, j, dtype=np.int64))
        return np.concatenate(pts), np.concatenate(labels)


def robust_weights(residuals, loss: str, scale: float) -> np.ndarray:
    """IRLS weights ``w(r)`` of a robust loss for non-negative residuals ``(N,)`` (metres).

    ``none``: 1; ``huber``: ``min(1, c / r)``; ``cauchy``: ``1 / (1 + (r / c)^2)``;
    ``tukey``: ``(1 - (r / c)^2)^2`` inside ``c``, 0 outside.
    """
    r = np.abs(as_array(residuals, "residuals", (None,)))
    if loss not in ROBUST_LOSSES:
        raise ValueError(f"loss: expected one of {ROBUST_LOSSES}, got {loss!r}")
    scale = float(scale)
    if not np.isfinite(scale) or scale <= 0:
        raise ValueError(f"scale: expected a positive finite number, got {scale}")
    if loss == "none":
        return np.ones_like(r)
    if loss == "huber":
        return np.minimum(1.0, scale / np.maximum(r, 1e-300))
    u = r / scale
    if loss == "cauchy":
        return 1.0 / (1.0 + u * u)
    return np.where(u < 1.0, (1.0 - u * u) ** 2, 0.0)
