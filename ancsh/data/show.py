"""Draw one frame with its ANCSH ground truth (matplotlib Agg, headless).

Four panels: the points in the camera frame coloured by part with the amodal part boxes
and the joint axes; the same points coloured by their NPCS coordinates (RGB); the points
in NAOCS with the canonical joint axes; the image-plane projection coloured by depth with
the joint association.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["draw_fit", "draw_fit_on_image", "draw_frame", "save_figure", "save_frame_figure"]

# Box edges as pairs of corner indices (corner order of OrientedBox.corners: sx, sy, sz signs).
_BOX_EDGES = [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)]


def _plot_coords(p: np.ndarray) -> tuple:
    """Camera (x right, y down, z forward) -> plot axes (x, depth, up)."""
    p = np.atleast_2d(p)
    return p[:, 0], p[:, 2], -p[:, 1]


def _equal_aspect(ax, pts: np.ndarray) -> None:
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c, r = 0.5 * (lo + hi), 0.5 * float(np.max(hi - lo)) + 1e-6
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))


def draw_frame(frame, fig=None):
    """Draw ``frame`` (a :class:`~ancsh.data.dataset.Frame`) into a matplotlib figure.

    Returns the figure (created with the Agg-compatible ``matplotlib.figure.Figure`` when
    ``fig`` is None, so no display is needed).
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    gt = frame.gt
    fig = fig or Figure(figsize=(14, 11), dpi=100)
    part_cmap = colormaps["tab10"]
    labels = gt.part_labels
    colors = part_cmap(labels % 10)
    pts = frame.points

    # 1: camera frame, parts, boxes, joint axes
    ax = fig.add_subplot(2, 2, 1, projection="3d")
    ax.scatter(*_plot_coords(pts), c=colors, s=2, depthshade=False)
    extent_pts = [pts]
    for j, box in enumerate(gt.boxes_cam):
        c = box.corners()
        extent_pts.append(c)
        for a, b in _BOX_EDGES:
            ax.plot(*_plot_coords(c[[a, b]]), color=part_cmap(j % 10), lw=1)
    diag = max(float(np.linalg.norm(pts.max(0) - pts.min(0))), 1e-3)
    for k in range(gt.num_joints):
        p, u = gt.joint_pivots_cam[k], gt.joint_axes_cam[k]
        seg = np.stack([p - 0.4 * diag * u, p + 0.4 * diag * u])
        ax.plot(*_plot_coords(seg), color="k", lw=2.5)
        ax.scatter(*_plot_coords(p), color="k", s=25, marker="o")
    _equal_aspect(ax, np.stack(_plot_coords(np.concatenate(extent_pts)), axis=1))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    ax.set_zlabel("-y (m)")
    ax.view_init(elev=20, azim=-75)
    names = ", ".join(f"{j}:{n}" for j, n in enumerate(frame.part_names))
    ax.set_title(f"camera frame: parts ({names}),\namodal boxes, joint axes (black)", fontsize=9)

    # 2: NPCS as RGB
    ax = fig.add_subplot(2, 2, 2, projection="3d")
    rgb = np.clip(gt.npcs + 0.5, 0.0, 1.0)
    ax.scatter(*_plot_coords(pts), c=rgb, s=2, depthshade=False)
    _equal_aspect(ax, np.stack(_plot_coords(pts), axis=1))
    ax.view_init(elev=20, azim=-75)
    ax.set_title("NPCS coordinates as RGB (camera frame)", fontsize=9)

    # 3: NAOCS with canonical joints
    ax = fig.add_subplot(2, 2, 3, projection="3d")
    n = gt.naocs
    ax.scatter(n[:, 0], n[:, 2], n[:, 1], c=colors, s=2, depthshade=False)
    for k in range(gt.num_joints):
        p, u = gt.joint_pivots_naocs[k], gt.joint_axes_naocs[k]
        seg = np.stack([p - 0.4 * u, p + 0.4 * u])
        ax.plot(seg[:, 0], seg[:, 2], seg[:, 1], color="k", lw=2.5)
    _equal_aspect(ax, np.concatenate([n[:, [0, 2, 1]], np.array([[-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]])]))
    ax.set_xlabel("x")
    ax.set_ylabel("z (front)")
    ax.set_zlabel("y (up)")
    ax.view_init(elev=20, azim=-60)
    ax.set_title("NAOCS with canonical joint axes", fontsize=9)

    # 4: image plane
    ax = fig.add_subplot(2, 2, 4)
    intr = frame.intrinsics
    u = intr.fx * pts[:, 0] / pts[:, 2] + intr.cx
    v = intr.fy * pts[:, 1] / pts[:, 2] + intr.cy
    sc = ax.scatter(u, v, c=pts[:, 2], s=4, cmap="viridis")
    assoc = gt.joint_association > 0
    ax.scatter(u[assoc], v[assoc], s=14, facecolors="none", edgecolors="r", lw=0.5, label="joint-associated")
    margin = 0.1 * max(np.ptp(u), np.ptp(v), 10.0)
    ax.set_xlim(max(u.min() - margin, 0), min(u.max() + margin, intr.width))
    ax.set_ylim(min(v.max() + margin, intr.height), max(v.min() - margin, 0))
    ax.set_aspect("equal")
    fig.colorbar(sc, ax=ax, label="depth (m)", shrink=0.8)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_xlabel("u (pixels)")
    ax.set_ylabel("v (pixels)")
    ax.set_title(f"sampled pixels of the {intr.width}x{intr.height} image (fx={intr.fx:g}), zoomed", fontsize=9)

    vis = ", ".join(f"{x:.2f}" for x in frame.visibility)
    states = ", ".join(f"{x:.3f}" for x in gt.joint_states)
    fig.suptitle(
        f"{frame.category} / {frame.instance}  frame {frame.frame_index}   "
        f"joint states (rel. rest): [{states}]   visible-area ratio: [{vis}]",
        fontsize=11,
    )
    fig.tight_layout()
    return fig


def save_frame_figure(frame, out) -> Path:
    """Draw ``frame`` and save it as an image (format from the suffix, e.g. ``.png``)."""
    return save_figure(draw_frame(frame), out)


def save_figure(fig, out, **savefig) -> Path:
    """Save a figure atomically (a temporary file and a rename), creating the folder; the format comes from
    the suffix (e.g. ``.png``; a name without one gets ``.png``, as matplotlib does); ``savefig`` are
    matplotlib's ``savefig`` options (``dpi``, ...). Returns the path written."""
    import io

    from ..outputs import write_bytes_atomically

    out = Path(out)
    if not out.suffix:
        out = out.with_name(out.name + ".png")
    buffer = io.BytesIO()
    fig.savefig(buffer, format=out.suffix.lstrip(".") or "png", **savefig)
    write_bytes_atomically(out, buffer.getvalue())
    return out


def _draw_boxes_and_axes(ax, boxes, pivots, axes, length: float, *, style: str, to_plot, color=None,
                         lw: float = 1.2) -> list:
    """Box edges per part (tab10 colours, or ``color`` for all) and joint axes through their pivots; returns drawn
    points."""
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    drawn = []
    for j, box in enumerate(boxes):
        c = box.corners()
        drawn.append(c)
        for a, b in _BOX_EDGES:
            ax.plot(*to_plot(c[[a, b]]), color=cmap(j % 10) if color is None else color, lw=lw, ls=style)
    for p, u in zip(pivots, axes):
        if np.all(np.isfinite(p)) and np.all(np.isfinite(u)):
            seg = np.stack([p - 0.5 * length * u, p + 0.5 * length * u])
            drawn.append(seg)
            ax.plot(*to_plot(seg), color="k", lw=2.0, ls=style)
    return drawn


def draw_fit_on_image(ax, result, intrinsics, length: float) -> None:
    """A fit's amodal boxes (part colours) and joint axes (black, ``length`` metres) projected onto an
    image axis (pixels; parts behind the camera are left out)."""
    _draw_boxes_and_axes(ax, result.boxes_cam, result.joint_pivots_cam, result.joint_axes_cam, length, style="-",
                         to_plot=_image_projector(intrinsics))


def _image_projector(intrinsics):
    """``p (N, 3) camera frame -> (u, v)`` pixel arrays; points behind the camera (a failed fit) become
    NaN, which matplotlib leaves out."""
    from .render import project

    def to_image(p):
        p = np.atleast_2d(p)
        uv = np.full((len(p), 2), np.nan)
        front = p[:, 2] > 1e-6
        if np.any(front):
            uv[front] = project(p[front], intrinsics)[0]
        return uv[:, 0], uv[:, 1]

    return to_image


def draw_fit(points_cam, result, intrinsics, *, labels=None, gt=None, title: str = "", fig=None):
    """Draw a fit: estimated amodal boxes and joint axes over the points (and ground truth if given).

    Two panels: the camera frame in 3D and the image plane (boxes and axes projected with
    ``intrinsics``). Estimates are solid lines, ground truth dashed.

    Parameters
    ----------
    points_cam : (N, 3) float64
        Observed points, camera frame (metres).
    result : FitResult
        The fit (``boxes_cam``, ``joint_pivots_cam``, ``joint_axes_cam``).
    intrinsics : Intrinsics
        Pinhole intrinsics of the image.
    labels : (N,) int, optional
        Part label per point (colours); grey when absent.
    gt : AncshGroundTruth, optional
        Drawn dashed for comparison.
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    pts = np.asarray(points_cam, dtype=np.float64)
    fig = fig or Figure(figsize=(13, 5.5), dpi=100)
    colors = "0.6" if labels is None else colormaps["tab10"](np.asarray(labels) % 10)
    length = 0.6 * max(float(np.linalg.norm(np.ptp(pts, axis=0))), 1e-3)
    layers = [(result.boxes_cam, result.joint_pivots_cam, result.joint_axes_cam, "-")]
    if gt is not None:
        layers.append((gt.boxes_cam, gt.joint_pivots_cam, gt.joint_axes_cam, "--"))

    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.scatter(*_plot_coords(pts), c=colors, s=2, depthshade=False)
    drawn = [pts]
    for boxes, pivots, axes, style in layers:
        drawn += _draw_boxes_and_axes(ax, boxes, pivots, axes, length, style=style, to_plot=_plot_coords)
    _equal_aspect(ax, np.stack(_plot_coords(np.concatenate(drawn)), axis=1))
    ax.view_init(elev=20, azim=-75)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    ax.set_zlabel("-y (m)")
    ax.set_title("camera frame: estimate solid" + (", ground truth dashed" if gt is not None else ""), fontsize=9)

    ax = fig.add_subplot(1, 2, 2)
    to_image = _image_projector(intrinsics)

    u, v = to_image(pts)
    ax.scatter(u, v, c=colors, s=3)
    drawn_uv = [np.stack([u, v], axis=1)]
    for boxes, pivots, axes, style in layers:
        for seg in _draw_boxes_and_axes(ax, boxes, pivots, axes, length, style=style, to_plot=to_image):
            drawn_uv.append(np.stack(to_image(seg), axis=1))
    uv = np.concatenate(drawn_uv)
    uv = uv[np.all(np.isfinite(uv), axis=1)]
    margin = 0.05 * max(float(np.ptp(uv[:, 0])), float(np.ptp(uv[:, 1])), 10.0)
    ax.set_xlim(uv[:, 0].min() - margin, uv[:, 0].max() + margin)
    ax.set_ylim(uv[:, 1].max() + margin, uv[:, 1].min() - margin)
    ax.set_aspect("equal")
    ax.set_xlabel("u (pixels)")
    ax.set_ylabel("v (pixels)")
    ax.set_title("image plane", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig
