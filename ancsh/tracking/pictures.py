"""Pictures of a multi-object track (``ancsh track --png-dir``): each frame's depth with every track's boxes, joint
axes, id and opening (:func:`draw_tracks`), and each track's joint states over time (:func:`draw_states`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["draw_states", "draw_tracks"]


def _opening(states, types) -> str:
    return ", ".join(f"{np.rad2deg(v):.0f} deg" if t == "revolute" else f"{100 * v:.1f} cm"
                     for v, t in zip(states, types))


def draw_tracks(depth, intrinsics, frame, path, joint_types) -> Path:
    """One frame: the depth image (metres, grey), every live track of ``frame`` (a
    :class:`~ancsh.tracking.multi.MultiFrame`) drawn as its model's part boxes and joint axes at the filtered state,
    labelled ``#id`` with its status and joint states (relative to rest); coasting and outlier tracks dashed."""
    from matplotlib.figure import Figure

    from ..data.show import _BOX_EDGES, _image_projector, save_figure

    fig = Figure(figsize=(8, 8 * depth.shape[0] / depth.shape[1] + 0.6), dpi=90)
    ax = fig.add_subplot(1, 1, 1)
    shown = np.where(depth > 0, depth, np.nan)
    ax.imshow(shown, cmap="gray")
    to_image = _image_projector(intrinsics)
    colours = ["tab:red", "tab:blue", "tab:green", "tab:orange", "tab:purple", "tab:cyan"]
    for t in frame.tracks:
        colour = colours[t.id % len(colours)]
        style = "-" if t.status in ("born", "tracked", "reinitialised") else "--"
        corners = []
        for box in t.model.boxes_cam:
            c = box.corners()
            corners.append(c)
            for a, b in _BOX_EDGES:
                ax.plot(*to_image(c[[a, b]]), color=colour, lw=1.2, ls=style)
        for p, u in zip(t.model.joint_pivots_cam, t.model.joint_axes_cam):
            seg = np.stack([p - 0.1 * u, p + 0.1 * u])
            ax.plot(*to_image(seg), color="k", lw=2.0, ls=style)
        top = np.concatenate(corners) if corners else np.zeros((0, 3))
        if len(top) and np.all(top[:, 2] > 0):
            u, v = to_image(top)
            ax.text(float(np.nanmean(u)), float(np.nanmin(v)) - 6, f"#{t.id} {t.status}: "
                    f"{_opening(t.joint_states, joint_types)}", color=colour, fontsize=8, ha="center",
                    bbox={"facecolor": "white", "alpha": 0.7, "pad": 1, "lw": 0})
    ax.set_xlim(0, depth.shape[1])
    ax.set_ylim(depth.shape[0], 0)
    ax.set_title(f"frame {frame.index}: {len(frame.tracks)} track(s)" + (", detection" if frame.detected else ""),
                 fontsize=9)
    ax.axis("off")
    return save_figure(fig, path)


def draw_states(records, path, joint_types) -> Path:
    """Each track's filtered joint states (degrees / centimetres, relative to rest) over the frames of ``records``
    (``ancsh.track/2`` lines), with one standard deviation shaded."""
    from matplotlib.figure import Figure

    from ..data.show import save_figure

    series = {}
    for r in records:
        for t in r.get("tracks", []):
            series.setdefault(t["id"], []).append((r["frame"], t["joint_states"], t["joint_states_std"]))
    k = max(len(joint_types), 1)
    fig = Figure(figsize=(9, 2.6 * k), dpi=90)
    for j in range(k):
        ax = fig.add_subplot(k, 1, j + 1)
        scale, unit = (180 / np.pi, "deg") if j >= len(joint_types) or joint_types[j] == "revolute" else (100.0, "cm")
        for tid, rows in sorted(series.items()):
            f = np.array([x[0] for x in rows])
            q = np.array([np.nan if x[1][j] is None else x[1][j] for x in rows], dtype=float) * scale
            s = np.array([np.nan if x[2][j] is None else x[2][j] for x in rows], dtype=float) * scale
            line = ax.plot(f, q, ".-", ms=3, lw=1, label=f"#{tid}")[0]
            ax.fill_between(f, q - s, q + s, color=line.get_color(), alpha=0.2, lw=0)
        ax.set_ylabel(f"joint {j} ({unit})")
        ax.grid(alpha=0.3)
        if series:
            ax.legend(fontsize=7, loc="upper right")
    fig.axes[-1].set_xlabel("frame")
    fig.tight_layout()
    return save_figure(fig, path)
