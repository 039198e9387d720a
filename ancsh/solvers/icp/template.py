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

from dataclasses import dataclass

import numpy as np

from ...geometry._checks import as_array, as_points, check_generator
from ...geometry.robust import robust_weights  # noqa: F401  (re-exported)
from ...geometry.transforms import Sim3
from ...model.articulated import ArticulatedModel, sample_surface_with_normals
from ..types import Correspondences, Observation

__all__ = [
    "ArticulatedPose",
    "ClosestPoints",
    "ModelSurface",
    "ModelTemplate",
    "TemplateCorrespondences",
    "TemplateProvider",
    "robust_weights",
]


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

    def closest(self, points_cam, T_cam_parts, *, visible: bool = False) -> ClosestPoints:
        """Closest points on the posed model surface.

        Parameters
        ----------
        points_cam : (N, 3) array_like
            Observed points in the camera frame (metres); the camera centre is the origin.
        T_cam_parts : sequence of Sim3
            ``(M,)`` part poses in the camera.
        visible : bool
            Match only surface the camera can see: a closest point hidden behind other
            model surface (e.g. the back face of a thin part, matched by a front-face
            point when the estimate is off by more than half the thickness) is replaced by
            the first model surface hit along the observed point's viewing ray (projective
            association); hidden points whose ray misses the model keep their closest
            point. This needs no consistent mesh normals.
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
        if visible and N:
            self._visible(pts, T_cam_parts, labels, local, normals, best)
        nn = np.linalg.norm(normals, axis=1, keepdims=True)
        normals = np.divide(normals, nn, out=np.zeros_like(normals), where=nn > 0)
        return ClosestPoints(labels, local, normals, best)

    def _visible(self, pts, T_cam_parts, labels, local, normals, best) -> None:
        """Replace hidden closest points by the ray hits of their observed points (in place)."""
        import open3d as o3d

        scene, table = self.posed_scene(T_cam_parts)
        match_cam = np.empty_like(pts)
        for j, T in enumerate(T_cam_parts):
            sel = labels == j
            match_cam[sel] = T.apply(local[sel])
        hidden = ~_seen(scene, match_cam)
        if not np.any(hidden):
            return
        idx = np.flatnonzero(hidden)
        rays = np.zeros((len(idx), 6), dtype=np.float32)
        rays[:, 3:] = pts[idx]
        hit = scene.cast_rays(o3d.core.Tensor(rays))
        th = hit["t_hit"].numpy().astype(np.float64)
        ok = np.isfinite(th)
        if not np.any(ok):
            return
        idx, th = idx[ok], th[ok]
        gids = hit["geometry_ids"].numpy()[ok]
        n_cam = hit["primitive_normals"].numpy().astype(np.float64)[ok]
        h_cam = th[:, None] * pts[idx]
        for gid, j in table.items():
            sel = gids == gid
            if not np.any(sel):
                continue
            T = T_cam_parts[j]
            ii = idx[sel]
            labels[ii] = j
            local[ii] = T.inverse().apply(h_cam[sel])
            normals[ii] = n_cam[sel] @ T.rotation  # camera -> part frame
            best[ii] = np.linalg.norm(pts[ii] - h_cam[sel], axis=1)

    def posed_scene(self, T_cam_parts):
        """``(RaycastingScene, {geometry id: part})`` of the model posed in the camera frame."""
        import open3d as o3d

        scene = o3d.t.geometry.RaycastingScene()
        table = {}
        for j, (part, T) in enumerate(zip(self.model.parts, T_cam_parts)):
            gid = scene.add_triangles(
                np.ascontiguousarray(T.apply(np.asarray(part.mesh.vertices, dtype=np.float64)), dtype=np.float32),
                np.ascontiguousarray(part.mesh.faces, dtype=np.uint32),
            )
            table[int(gid)] = j
        return scene, table

    def visible_samples(self, T_cam_parts, samples_part, labels, normals_part=None, *, min_cos: float = 0.3,
                        return_labels: bool = False):
        """The camera-frame positions ``(V, 3)`` of surface samples the camera sees (and their part
        labels ``(V,)`` when ``return_labels``).

        Parameters
        ----------
        T_cam_parts : sequence of Sim3
            ``(M,)`` part poses.
        samples_part : (S, 3) float64
            Surface samples in their part frames (e.g. from :meth:`sample`).
        labels : (S,) int
            Part of each sample.
        normals_part : (S, 3) float64, optional
            Their unit normals (any sign): samples seen at a grazing angle (``|cos|`` between
            normal and viewing ray below ``min_cos``) are dropped, since a depth camera
            samples such surface too sparsely to expect an observed point near each of them.
        """
        pts = np.empty_like(samples_part)
        keep = np.ones(len(pts), dtype=bool)
        for j, T in enumerate(T_cam_parts):
            sel = labels == j
            pts[sel] = T.apply(samples_part[sel])
            if normals_part is not None:
                n = T.apply_direction(normals_part[sel])
                ray = pts[sel] / np.maximum(np.linalg.norm(pts[sel], axis=1, keepdims=True), 1e-12)
                keep[sel] = np.abs(np.einsum("ij,ij->i", n, ray)) >= min_cos
        front = keep & (pts[:, 2] > 1e-6)
        scene, _ = self.posed_scene(T_cam_parts)
        ok = np.zeros(len(pts), dtype=bool)
        ok[front] = _seen(scene, pts[front])
        return (pts[ok], np.asarray(labels)[ok]) if return_labels else pts[ok]

    def sample(self, count: int, rng, *, normals: bool = False):
        """``count`` surface samples per part in the part frames: ``(points (M*count, 3), labels)``,
        plus their unit face normals ``(M*count, 3)`` when ``normals``."""
        rng = check_generator(rng)
        pts, nrm, labels = [], [], []
        for j, part in enumerate(self.model.parts):
            p, n = sample_surface_with_normals(part.mesh, count, rng)
            pts.append(p)
            nrm.append(n)
            labels.append(np.full(count, j, dtype=np.int64))
        out = (np.concatenate(pts), np.concatenate(labels))
        return out + (np.concatenate(nrm),) if normals else out


def _seen(scene, points_cam) -> np.ndarray:
    """``(N,)`` bool: is each surface point the first hit of the ray from the camera centre?"""
    import open3d as o3d

    rays = np.zeros((len(points_cam), 6), dtype=np.float32)
    rays[:, 3:] = points_cam  # camera centre -> point; t_hit = 1 at the point itself
    t = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    depth = np.linalg.norm(points_cam, axis=1)
    return t * depth >= depth - np.maximum(1e-4, 1e-4 * depth)


@dataclass(frozen=True)
class TemplateCorrespondences(Correspondences):
    """:class:`~ancsh.solvers.types.Correspondences` plus what a template knows beyond a network.

    Attributes
    ----------
    normals_npcs : (N, 3) float64 or None
        Unit surface normal at each point's model match, in its part's NPCS (for a
        point-to-plane data term).
    distances : (N,) float64 or None
        Distance of each observed point to its model match at the estimate (metres).
    """

    normals_npcs: np.ndarray | None = None
    distances: np.ndarray | None = None


class ModelTemplate:
    """What a known model offers every frame, built once per model: the closest-point surface,
    the canonical space, each part's frame -> NPCS map, the joint tree and limits.

    Parameters
    ----------
    model : ArticulatedModel
        The instance (at least one movable joint; every part needs a mesh).
    surface : ModelSurface, optional
        A closest-point structure of ``model`` to reuse (built when omitted).

    Raises
    ------
    ValueError
        If the model has no movable joint or a part has no mesh.
    """

    def __init__(self, model: ArticulatedModel, surface: ModelSurface | None = None):
        from ...model.canonical import canonical_space

        if not isinstance(model, ArticulatedModel):
            raise ValueError(f"model: expected an ArticulatedModel, got {type(model).__name__}")
        if model.num_joints == 0:
            raise ValueError(f"model: {model.name!r} has no movable joint; use rigid ICP (whole_object_icp) instead")
        if surface is not None and (not isinstance(surface, ModelSurface) or surface.model is not model):
            raise ValueError("surface: expected the ModelSurface of this model")
        self.model = model
        self.surface = surface if surface is not None else ModelSurface(model)
        self.canonical = cs = canonical_space(model)
        rest_poses = model.forward_kinematics(model.rest_states)
        # Part frame -> its NPCS (a similarity: the NAOCS normalisation scale over s_j).
        self.T_npcs_part = tuple(cs.T_naocs_npcs(j).inverse() @ cs.T_naocs_base @ rest_poses[j]
                                 for j in range(model.num_parts))
        self.joint_parts = np.array([model.joint_parts(k) for k in range(model.num_joints)], dtype=np.int64).reshape(-1, 2)
        self.joint_limits = np.stack([model.lower_limits, model.upper_limits], axis=1) - model.rest_states[:, None]

    @property
    def T_cam_naocs_scale(self) -> float:
        """Metres per NAOCS unit: the object scale of every part pose of this model."""
        return 1.0 / self.canonical.T_naocs_base.scale


class TemplateProvider:
    """Correspondences from a known model: closest points at the current estimate.

    Implements :class:`~ancsh.solvers.types.CorrespondenceProvider`. Each observed point gets
    the part label and NPCS coordinates of its closest point on the model surface posed at
    :attr:`estimate`; its weight is ``robust_weights(distance)``, and ``0`` beyond
    ``max_distance`` (gated). Per-part NPCS -> NAOCS maps, joints, box extents and joint
    limits are the model's own (exact).

    A provider is cheap (per frame and estimate); the expensive per-model part is its
    :class:`ModelTemplate`, shared by every provider built from it (and by :meth:`at`).

    Parameters
    ----------
    model : ArticulatedModel or ModelTemplate
        The instance (every part needs a mesh), e.g. from :func:`ancsh.data.urdf.load_urdf`, or
        its template.
    estimate : ArticulatedPose, optional
        Current pose; set or replace it with :meth:`at`. Required before :meth:`correspond`.
    max_distance : float
        Gating distance (metres): farther points get weight 0.
    loss : str
        Robust loss of the weights, one of ``none``, ``huber``, ``cauchy``, ``tukey``.
    loss_scale : float
        Scale of the robust loss (metres).
    visible : bool
        Match only model surface visible from the camera (see :meth:`ModelSurface.closest`).

    Raises
    ------
    ValueError
        If the model has no movable joint, a part has no mesh, or a setting is out of range.
    """

    def __init__(self, model, estimate: ArticulatedPose | None = None, *,
                 max_distance: float = 0.05, loss: str = "huber", loss_scale: float = 0.01, visible: bool = True):
        template = model if isinstance(model, ModelTemplate) else ModelTemplate(model)
        max_distance = float(max_distance)
        if not (np.isfinite(max_distance) and max_distance > 0):
            raise ValueError(f"max_distance: expected a positive number, got {max_distance}")
        robust_weights(np.zeros(1), loss, loss_scale)  # validates loss and loss_scale
        self.template = template
        self.model = template.model
        self.max_distance = max_distance
        self.loss = loss
        self.loss_scale = float(loss_scale)
        self.visible = bool(visible)
        self.estimate = None
        if estimate is not None:
            self.estimate = self._check_estimate(estimate)

    def _check_estimate(self, estimate) -> ArticulatedPose:
        if not isinstance(estimate, ArticulatedPose):
            raise ValueError(f"estimate: expected an ArticulatedPose, got {type(estimate).__name__}")
        self.model.check_states(estimate.q, "estimate.q")
        return estimate

    def at(self, estimate: ArticulatedPose, *, max_distance: float | None = None) -> "TemplateProvider":
        """The same provider at another estimate (and gating distance); shares the surface data."""
        return TemplateProvider(
            self.template, estimate, max_distance=self.max_distance if max_distance is None else max_distance,
            loss=self.loss, loss_scale=self.loss_scale, visible=self.visible,
        )

    # The template's per-model data, read through the provider.
    @property
    def surface(self) -> ModelSurface:
        return self.template.surface

    @property
    def canonical(self):
        """The model's :class:`~ancsh.model.canonical.CanonicalSpace`."""
        return self.template.canonical

    @property
    def T_npcs_part(self) -> tuple:
        return self.template.T_npcs_part

    @property
    def T_cam_naocs_scale(self) -> float:
        """Metres per NAOCS unit: the object scale of every part pose of this model."""
        return self.template.T_cam_naocs_scale

    def empty_correspondences(self, num_points: int = 0) -> "TemplateCorrespondences":
        """The model's canonical parameters with ``num_points`` zero-weight points (labels 0)."""
        return self._build(np.zeros(num_points, dtype=np.int64), np.zeros((num_points, 3)),
                           np.zeros(num_points), np.zeros((num_points, 3)), np.full(num_points, np.inf))

    def correspond(self, observation) -> "TemplateCorrespondences":
        """Correspondences of ``observation`` (an :class:`Observation` or ``(N, 3)`` camera points)."""
        if self.estimate is None:
            raise ValueError("estimate: the template provider needs an estimate; call .at(estimate) first")
        points = observation.points_cam if isinstance(observation, Observation) else as_points(observation, "observation")
        if points.shape[0] == 0:
            return self.empty_correspondences(0)
        cp = self.surface.closest(points, self.estimate.part_poses(self.model), visible=self.visible)
        M = self.model.num_parts
        npcs = np.empty((points.shape[0], 3))
        normals = np.empty((points.shape[0], 3))
        for j in range(M):
            sel = cp.labels == j
            if np.any(sel):
                npcs[sel] = self.T_npcs_part[j].apply(cp.points_part[sel])
                normals[sel] = self.T_npcs_part[j].apply_direction(cp.normals_part[sel])
        w = robust_weights(cp.distances, self.loss, self.loss_scale)
        w[cp.distances > self.max_distance] = 0.0
        return self._build(cp.labels, npcs, w, normals, cp.distances)

    def _build(self, labels, npcs, weights, normals, distances) -> "TemplateCorrespondences":
        t = self.template
        cs = t.canonical
        return TemplateCorrespondences(
            part_labels=labels, npcs=npcs, npcs_scale=cs.npcs_scale, npcs_translation=cs.npcs_translation,
            joint_types=tuple(cs.joint_types), joint_parents=t.joint_parts[:, 0],
            joint_children=t.joint_parts[:, 1], joint_axes_naocs=cs.joint_axes_naocs,
            joint_pivots_naocs=cs.joint_pivots_naocs, weights=weights, npcs_extents=cs.npcs_extents,
            joint_limits=t.joint_limits, normals_npcs=normals, distances=distances,
        )
