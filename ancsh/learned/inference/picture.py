"""Pictures of an ``ancsh predict`` result: boxes and joint axes over the point cloud and the image."""

from __future__ import annotations

import numpy as np

from ...data.render import Intrinsics

__all__ = ["draw_prediction"]


def draw_prediction(depth, prediction, intrinsics: Intrinsics, *, title: str = "", rgb=None):
    """Boxes and joint axes over the point cloud (3D) and projected on the depth (or colour) image.

    Uses :func:`ancsh.data.show.draw_fit` and puts the depth image, or ``rgb`` when given
    (``(H, W, 3)`` uint8, registered to the depth), under its image-plane panel; a legend names the
    parts. Returns a matplotlib ``Figure`` (Agg).
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    from ...data.show import draw_fit

    r = prediction.result
    fig = Figure(figsize=(14, 6), dpi=100)
    if prediction.points_cam.shape[0] == 0:  # nothing fitted: the depth image and the isolation only
        ax = fig.add_subplot(1, 1, 1)
        d = np.asarray(depth, dtype=np.float64)
        ax.imshow(np.ma.masked_where(d <= 0, d), cmap="gray", interpolation="nearest")
        _draw_isolation(ax, prediction.isolation)
        ax.set_title(title or f"{prediction.category}: {r.status.value}: {r.message}", fontsize=9)
        return fig
    title = title or (f"{prediction.category}: {r.formulation} fit, status {r.status.value} "
                      f"({prediction.points_cam.shape[0]} points)")
    import dataclasses

    shown = r if r.ok else dataclasses.replace(  # a rejected fit's boxes are drawn dashed by _draw_objects, not here
        r, boxes_cam=(), joint_axes_cam=np.full_like(r.joint_axes_cam, np.nan))
    draw_fit(prediction.points_cam, shown, intrinsics, labels=prediction.part_labels, title=title, fig=fig)
    handles = [Line2D([], [], marker="o", linestyle="", color=colormaps["tab10"](j % 10), label=name)
               for j, name in enumerate(prediction.part_names)]
    fig.axes[0].legend(handles=handles, loc="upper left", fontsize=8, title="parts", title_fontsize=8)
    ax = fig.axes[-1]
    xlim, ylim = ax.get_xlim(), ax.get_ylim()
    d = np.asarray(depth, dtype=np.float64)
    extent = (-0.5, d.shape[1] - 0.5, d.shape[0] - 0.5, -0.5)
    if rgb is None:
        im = ax.imshow(np.ma.masked_where(d <= 0, d), cmap="gray", interpolation="nearest", zorder=0, extent=extent)
    else:
        ax.imshow(np.asarray(rgb), interpolation="nearest", zorder=0, extent=extent)
    for coll in ax.collections:
        coll.set_alpha(0.35)
    _draw_objects(ax, prediction, intrinsics)
    # the whole image, or more where the projected boxes reach beyond it
    ax.set_xlim(min(xlim[0], extent[0]), max(xlim[1], extent[1]))
    ax.set_ylim(max(ylim[0], extent[2]), min(ylim[1], extent[3]))
    if rgb is None:
        fig.colorbar(im, ax=ax, label="depth (m)", shrink=0.8, pad=0.02)
    _draw_isolation(ax, prediction.isolation)
    found = sum(o.result.ok for o in (prediction.objects or (prediction,)))
    ax.set_title(("colour" if rgb is not None else "depth") + f" image: {found} object(s) found, numbered with their "
                 "opening;\nboxes in part colours, joint axes black;\nrejected fits dashed grey with their status"
                 + ("; other segments blue" if prediction.isolation is not None else ""), fontsize=8)
    return fig


def _opening(pred) -> str:
    """The joints' absolute states in words (``lid_hinge 131 deg``; prismatic in metres)."""
    words = []
    for k, name in enumerate(pred.joint_names):
        q = float(pred.result.joint_states[k]) + (float(pred.joint_rest[k]) if k < len(pred.joint_rest) else 0.0)
        if not np.isfinite(q):
            continue
        revolute = k < len(pred.joint_types) and pred.joint_types[k] == "revolute"
        words.append(f"{name} {np.degrees(q):.0f} deg" if revolute else f"{name} {q:.3f} m")
    return ", ".join(words)


def _draw_objects(ax, prediction, intrinsics) -> None:
    """Every object of ``prediction`` (numbered, its mask outlined, its opening written) and its rejected fits
    (dashed grey boxes and their status) on the image axis."""
    from ...data.show import _draw_boxes_and_axes, _image_projector, draw_fit_on_image

    to_image = _image_projector(intrinsics)
    for pred in tuple(prediction.objects or (prediction,)) + tuple(prediction.rejected):
        r = pred.result
        ok = r.ok
        if r is not prediction.result and ok and r.boxes_cam:  # the first object's boxes are drawn by draw_fit
            length = 0.6 * max(float(np.linalg.norm(np.ptp(pred.points_cam, axis=0))), 1e-3)
            draw_fit_on_image(ax, r, intrinsics, length)
        elif not ok and r.boxes_cam:
            _draw_boxes_and_axes(ax, r.boxes_cam, (), (), 0.0, style="--", to_plot=to_image, color="0.55", lw=0.8)
        mask = pred.mask
        if mask is not None and mask.any():
            ax.contour(mask.astype(float), levels=[0.5], colors="red" if ok else "0.55", linewidths=1.2 if ok else 0.8,
                       linestyles="solid" if ok else "dashed")
            v, u = np.nonzero(mask)
            label = (f"{pred.object_id}: {_opening(pred)}" if ok else r.status.value)
            ax.text(float(u.min()), float(v.min()) - 4, label, fontsize=7, color="white" if ok else "0.9",
                    va="bottom", bbox={"facecolor": "red" if ok else "0.4", "alpha": 0.75, "pad": 1.5,
                                       "linewidth": 0})


def _draw_isolation(ax, isolation) -> None:
    """Outline the segments of an :class:`~ancsh.data.isolate.Isolation` that are not the chosen one (blue; the
    objects are outlined by :func:`_draw_objects`)."""
    if isolation is None:
        return
    others = (isolation.labels >= 0) & ~isolation.mask
    if others.any():
        ax.contour(others.astype(float), levels=[0.5], colors="tab:blue", linewidths=0.6)
