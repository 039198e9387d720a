"""Interactive 3D views (plotly) of a prediction and of a track, for notebooks: turn them with the mouse.

``plotly`` is an optional dependency (``pip install 'ancsh[viz]'``); the static pictures of the commands stay
matplotlib. Everything is drawn in the camera frame (metres; +z away from the camera, +y down), with equal axes.

- :func:`prediction_figure`: the observed points coloured by predicted part, the amodal part boxes, the joint axes
  and, for a successful fit, the exported model's meshes (:func:`ancsh.solvers.twin.fitted_model`).
- :func:`track_figure`: a slider over the frames of a track: each frame's points and fitted boxes and axes.
"""

from __future__ import annotations

import numpy as np

__all__ = ["prediction_figure", "track_figure"]

COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f")
"""Part colours, in part order (cycled)."""

_EDGES = [(0, 1), (0, 2), (0, 4), (1, 3), (1, 5), (2, 3), (2, 6), (3, 7), (4, 5), (4, 6), (5, 7), (6, 7)]
"""Box edges between the corners of :meth:`ancsh.geometry.boxes.OrientedBox.corners` (signs x, y, z in binary)."""


def _plotly():
    try:
        import plotly.graph_objects as go
    except ImportError:
        raise ImportError("plotly is needed for the interactive views: pip install 'ancsh[viz]'") from None
    return go


def _box_lines(box):
    """``(x, y, z)`` lists of the box's 12 edges, separated by ``None`` (one line trace)."""
    c = box.corners()
    xs, ys, zs = [], [], []
    for a, b in _EDGES:
        for p in (c[a], c[b]):
            xs.append(p[0]), ys.append(p[1]), zs.append(p[2])
        xs.append(None), ys.append(None), zs.append(None)
    return xs, ys, zs


def _fit_traces(go, points, labels, result, part_names, joint_names, *, visible=True, max_points=4000) -> list:
    """Points by part, boxes and joint axes of one fit (traces)."""
    points = np.asarray(points, dtype=np.float64)
    labels = np.asarray(labels)
    traces = []
    stride = max(1, len(points) // max_points)
    for j, name in enumerate(part_names):
        sel = points[labels == j][::stride]
        colour = COLOURS[j % len(COLOURS)]
        traces.append(go.Scatter3d(x=sel[:, 0], y=sel[:, 1], z=sel[:, 2], mode="markers", name=f"{name} points",
                                   marker={"size": 2, "color": colour}, visible=visible))
        if result is not None and j < len(result.boxes_cam):
            xs, ys, zs = _box_lines(result.boxes_cam[j])
            traces.append(go.Scatter3d(x=xs, y=ys, z=zs, mode="lines", name=f"{name} box", line={"color": colour},
                                       visible=visible))
    if result is not None and len(points):
        half = 0.5 * float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
        for k, name in enumerate(joint_names):
            a, p = np.asarray(result.joint_axes_cam[k]), np.asarray(result.joint_pivots_cam[k])
            if not (np.all(np.isfinite(a)) and np.all(np.isfinite(p))):
                continue
            ends = np.stack([p - half * a, p + half * a])
            traces.append(go.Scatter3d(x=ends[:, 0], y=ends[:, 1], z=ends[:, 2], mode="lines", name=f"{name} axis",
                                       line={"color": "black", "width": 6}, visible=visible))
    return traces


def _layout(go, fig, title: str):
    fig.update_layout(title=title, scene={"aspectmode": "data", "xaxis_title": "x (m)", "yaxis_title": "y (m)",
                                          "zaxis_title": "z (m)", "camera": {"up": {"x": 0, "y": -1, "z": 0},
                                                                             "eye": {"x": 0, "y": 0, "z": -2}}},
                      margin={"l": 0, "r": 0, "t": 40, "b": 0}, legend={"itemsizing": "constant"})
    return fig


def prediction_figure(prediction, *, mesh: bool = True, max_points: int = 4000):
    """A plotly figure of a :class:`~ancsh.learned.inference.predict.DepthPrediction`.

    Parameters
    ----------
    prediction : DepthPrediction
    mesh : bool
        Add the exported model's part meshes (a successful fit only; semi-transparent).
    max_points : int
        Points drawn per part at most (evenly thinned).
    """
    go = _plotly()
    r = prediction.result
    fit = r if r.ok else None
    traces = _fit_traces(go, prediction.points_cam, prediction.part_labels, fit, prediction.part_names,
                         prediction.joint_names, max_points=max_points)
    if mesh and fit is not None and prediction.correspondences is not None:
        from .data.templates import load_template_library
        from .solvers.twin import fitted_model

        category = getattr(prediction, "category_info", None)
        library = category.template_library() if category is not None else load_template_library(prediction.category)
        twin = fitted_model(fit, prediction.correspondences, library)
        if twin is not None:
            q = np.clip(twin.states, twin.model.lower_limits, twin.model.upper_limits)
            for j, (part, T) in enumerate(zip(twin.model.parts, twin.model.forward_kinematics(q))):
                v = (twin.T_cam_B @ T).apply(np.asarray(part.mesh.vertices, dtype=np.float64))
                f = np.asarray(part.mesh.faces)
                traces.append(go.Mesh3d(x=v[:, 0], y=v[:, 1], z=v[:, 2], i=f[:, 0], j=f[:, 1], k=f[:, 2], opacity=0.3,
                                        color=COLOURS[j % len(COLOURS)], name=f"{part.name} model"))
    status = r.status.value
    return _layout(go, go.Figure(traces), f"{prediction.category}: {status}")


def track_figure(frames, part_names, joint_names, *, max_points: int = 2000):
    """A plotly figure with a slider over a track's frames.

    Parameters
    ----------
    frames : sequence of (points (N, 3), labels (N,) or None, TrackedFrame)
        Each frame's observed points (camera frame, metres), their part labels (``None``: one colour) and the
        tracker's answer (its ``result`` a fit with boxes and camera joints, or ``None`` when lost).
    part_names, joint_names : sequence of str
    max_points : int
        Points drawn per part and frame at most.
    """
    go = _plotly()
    frames = list(frames)
    if not frames:
        raise ValueError("frames: expected at least one frame")
    per_frame, counts = [], []
    for points, labels, tracked in frames:
        labels = np.zeros(len(points), dtype=int) if labels is None else labels
        result = getattr(tracked, "result", None)
        result = result if result is not None and hasattr(result, "boxes_cam") else None
        traces = _fit_traces(go, points, labels, result, part_names, joint_names, visible=False, max_points=max_points)
        per_frame.append(traces)
        counts.append(len(traces))
    all_traces = [t for ts in per_frame for t in ts]
    for t in per_frame[0]:
        t.visible = True
    steps, start = [], 0
    for i, ((_, _, tracked), n) in enumerate(zip(frames, counts)):
        vis = [False] * len(all_traces)
        vis[start:start + n] = [True] * n
        start += n
        status = getattr(tracked, "status", "")
        label = f"{i}: {getattr(status, 'value', status)}"
        steps.append({"method": "update", "args": [{"visible": vis}], "label": label})
    fig = go.Figure(all_traces)
    fig.update_layout(sliders=[{"active": 0, "steps": steps, "currentvalue": {"prefix": "frame "}}])
    return _layout(go, fig, "track")
