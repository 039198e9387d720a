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
    draw_fit(prediction.points_cam, r, intrinsics, labels=prediction.part_labels, title=title, fig=fig)
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
    # the whole image, or more where the projected boxes reach beyond it
    ax.set_xlim(min(xlim[0], extent[0]), max(xlim[1], extent[1]))
    ax.set_ylim(max(ylim[0], extent[2]), min(ylim[1], extent[3]))
    if rgb is None:
        fig.colorbar(im, ax=ax, label="depth (m)", shrink=0.8)
    _draw_isolation(ax, prediction.isolation)
    ax.set_title(("colour" if rgb is not None else "depth") + " image: boxes (part colours) and joint axes (black) projected"
                 + ("; isolated object outlined in red, other clusters in blue" if prediction.isolation is not None else ""),
                 fontsize=9)
    return fig


def _draw_isolation(ax, isolation) -> None:
    """Outline the chosen cluster (red) and the others (blue) of an :class:`~ancsh.data.isolate.Isolation`."""
    if isolation is None:
        return
    others = (isolation.labels >= 0) & ~isolation.mask
    if others.any():
        ax.contour(others.astype(float), levels=[0.5], colors="tab:blue", linewidths=0.8)
    if isolation.mask.any():
        ax.contour(isolation.mask.astype(float), levels=[0.5], colors="red", linewidths=1.2)
