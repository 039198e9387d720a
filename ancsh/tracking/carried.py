"""Correspondences carried between network frames by the previous fit (category-level tracking).

After a frame whose correspondences came from the network, every inlier point of every part is
mapped into its part's NPCS *through the fitted pose* (``c = T_cam_npcs[j]^-1 p``): a point
template of the observed surface in the fit's own canonical coordinates. On the next frames,
without running the network, each observed point is matched to the nearest template point posed
at the current estimate (ICP's closest-point step, on a point template instead of a CAD surface,
:mod:`ancsh.solvers.icp`): it takes that template point's part label and NPCS coordinates; the
canonical parameters (NPCS -> NAOCS maps, joints, limits) are those of the network frame.
Matches farther than a gate get weight 0.

On a network frame the tracker can fit both sets of rows at once (:func:`stack_correspondences`,
``TrackerConfig.fusion_weight``): the carried rows then bring the previous estimate, moved by the
observed motion, into the new one -- tracking's fusion over time.
"""

from __future__ import annotations

import numpy as np

from ..geometry._checks import as_points, check_positive
from ..solvers.types import Correspondences, FitResult

__all__ = ["CarriedTemplate", "stack_correspondences"]


class CarriedTemplate:
    """The point template of one fitted frame (see the module docstring).

    Parameters
    ----------
    points_cam : (N, 3) float64
        The frame's observed points (camera frame, metres).
    correspondences : Correspondences
        Their correspondences (part labels; the canonical parameters are kept).
    result : FitResult
        A successful fit of that frame (its part poses and inliers).

    Raises
    ------
    ValueError
        When ``result`` is not a successful fit of these points, or a part keeps no inlier.
    """

    def __init__(self, points_cam, correspondences: Correspondences, result: FitResult):
        pts = as_points(points_cam, "points_cam")
        if not isinstance(result, FitResult) or not result.ok:
            raise ValueError("result: expected a successful FitResult")
        if result.inliers.shape != (pts.shape[0],) or correspondences.num_points != pts.shape[0]:
            raise ValueError(f"result: its inliers / correspondences do not cover the {pts.shape[0]} points")
        self.correspondences = correspondences
        labels = np.asarray(correspondences.part_labels)
        npcs, keep_labels = [], []
        for j, T in enumerate(result.T_cam_npcs):
            sel = result.inliers & (labels == j)
            if not np.any(sel):
                raise ValueError(f"result: part {j} keeps no inlier point for the template")
            npcs.append(T.inverse().apply(pts[sel]))
            keep_labels.append(np.full(int(sel.sum()), j, dtype=np.int64))
        self.npcs = np.concatenate(npcs)
        self.labels = np.concatenate(keep_labels)
        # the template is grouped by part: part j is rows bounds[j]:bounds[j + 1]
        self._bounds = np.concatenate([[0], np.cumsum([len(x) for x in keep_labels])])

    @property
    def num_points(self) -> int:
        return int(self.labels.shape[0])

    def correspond(self, points_cam, T_cam_npcs, gate: float) -> Correspondences:
        """Correspondences of new points by their nearest template point at the part poses ``T_cam_npcs``.

        Parameters
        ----------
        points_cam : (N, 3) float64
            Observed points (camera frame, metres).
        T_cam_npcs : sequence of Sim3
            ``(M,)`` part poses of the current estimate.
        gate : float
            Matches farther than this (metres) get weight 0.
        """
        from scipy.spatial import cKDTree

        pts = as_points(points_cam, "points_cam")
        gate = check_positive(gate, "gate")
        if len(T_cam_npcs) != self.correspondences.num_parts:
            raise ValueError(f"T_cam_npcs: expected {self.correspondences.num_parts} part poses, got {len(T_cam_npcs)}")
        b = self._bounds
        posed = np.concatenate([T.apply(self.npcs[b[j]:b[j + 1]]) for j, T in enumerate(T_cam_npcs)])
        # one query per tree: the unbalanced, uncompacted build is the cheaper one here
        d, idx = cKDTree(posed, balanced_tree=False, compact_nodes=False).query(pts, k=1)
        labels, npcs = self.labels[idx], self.npcs[idx]
        c = self.correspondences
        return Correspondences(
            part_labels=labels, npcs=npcs, npcs_scale=c.npcs_scale,
            npcs_translation=c.npcs_translation, joint_types=c.joint_types, joint_parents=c.joint_parents,
            joint_children=c.joint_children, joint_axes_naocs=c.joint_axes_naocs, joint_pivots_naocs=c.joint_pivots_naocs,
            weights=(d <= gate).astype(np.float64), npcs_extents=c.npcs_extents, joint_limits=c.joint_limits,
        )


def stack_correspondences(first: Correspondences, second: Correspondences, weight: float) -> Correspondences:
    """One set of correspondences for the points of two sets stacked (``first``'s rows, then ``second``'s).

    Tracking's fused network frames (``TrackerConfig.fusion_weight``): ``first`` the network's
    correspondences of a frame, ``second`` the carried ones of the same points, their weights
    multiplied by ``weight``. The canonical parameters, joints and extents are ``first``'s; the NPCS
    coordinates of both are of the same parts' NPCS frames.

    Parameters
    ----------
    first, second : Correspondences
        Of the same object (part and joint counts), ``N1`` and ``N2`` points.
    weight : float
        Factor of ``second``'s per-point weights, ``>= 0``.

    Returns
    -------
    Correspondences
        ``N1 + N2`` points.
    """
    from ..geometry._checks import check_number

    weight = check_number(weight, "weight", minimum=0.0)
    if second.num_parts != first.num_parts or len(second.joint_types) != len(first.joint_types):
        raise ValueError(f"second: {second.num_parts} parts and {len(second.joint_types)} joints, first has "
                         f"{first.num_parts} and {len(first.joint_types)}")
    w1 = np.ones(first.num_points) if first.weights is None else np.asarray(first.weights, dtype=np.float64)
    w2 = np.ones(second.num_points) if second.weights is None else np.asarray(second.weights, dtype=np.float64)
    return Correspondences(
        part_labels=np.concatenate([first.part_labels, second.part_labels]), npcs=np.concatenate([first.npcs, second.npcs]),
        npcs_scale=first.npcs_scale, npcs_translation=first.npcs_translation, joint_types=first.joint_types,
        joint_parents=first.joint_parents, joint_children=first.joint_children, joint_axes_naocs=first.joint_axes_naocs,
        joint_pivots_naocs=first.joint_pivots_naocs, weights=np.concatenate([w1, weight * w2]),
        npcs_extents=first.npcs_extents, joint_limits=first.joint_limits,
    )
