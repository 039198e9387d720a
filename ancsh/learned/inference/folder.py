"""A folder of depth images predicted one by one (``ancsh predict --depth DIR``), on the cores it is given.

:func:`predict_folder` hands the images to an :class:`~ancsh.executors.Executor`: each worker process loads the
network once (:class:`FolderWorker`) and predicts the images it receives, writing each image's JSON (and picture)
itself. Every prediction is a function of its image and the options alone, so the files do not depend on the number
of workers; the statuses come back in the images' order.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["FolderOptions", "FolderWorker", "predict_folder"]


@dataclass(frozen=True)
class FolderOptions:
    """What every image of the folder is predicted with (the options of ``ancsh predict``).

    ``predict`` holds the keyword arguments of :func:`~ancsh.learned.inference.predict.predict_depth` other than the
    image and the provider; ``provider`` those of the :class:`~ancsh.learned.inference.provider.LearnedProvider`;
    ``input`` the fields of each result's ``input`` block besides its ``depth``."""

    category: str
    intrinsics: object  # Intrinsics
    depth_scale: float = 0.001
    weights: str | None = None
    provider: dict = field(default_factory=dict)
    predict: dict = field(default_factory=dict)
    input: dict = field(default_factory=dict)


class FolderWorker:
    """One worker's network (loaded once) and the prediction of one image to its JSON file (and picture)."""

    def __init__(self, options: FolderOptions, out: str, png: str | None):
        from .category import load_category
        from .predict import check_weights_category
        from .provider import LearnedProvider

        self.options, self.out, self.png = options, Path(out), None if png is None else Path(png)
        if options.weights is None:  # the category loaded once per worker, its network with it
            self.category = load_category(options.category)
            self.provider = LearnedProvider(self.category.weights_path(), category=self.category, **options.provider)
        else:
            self.provider = LearnedProvider(options.weights, **options.provider)
            self.category = load_category(options.category, network_category=self.provider.category)
            check_weights_category(self.provider, self.category, options.weights)

    def __call__(self, path: str) -> tuple[str, str]:
        """``(file name, status)``: the prediction's status, or ``"error: ..."`` for an image that cannot be read
        (the others go on)."""
        from ...data.show import save_figure
        from ...outputs import write_bytes_atomically
        from .predict import draw_prediction, predict_depth, read_depth

        path, o = Path(path), self.options
        intr = o.intrinsics
        try:
            depth = read_depth(path, depth_scale=o.depth_scale, shape=(intr.height, intr.width))
            pred = predict_depth(depth, intr, self.category, provider=self.provider, **o.predict)
        except (ValueError, OSError) as exc:  # one bad image (or a dangling link) does not stop the others
            return path.name, f"error: {exc}"
        data = pred.to_json()
        data["input"] = {"depth": str(path), "intrinsics": intr.to_json(), "depth_scale": o.depth_scale, **o.input}
        write_bytes_atomically(self.out / f"{path.stem}.json", (json.dumps(data, indent=1) + "\n").encode())
        if self.png is not None:
            save_figure(draw_prediction(depth, pred, intr), self.png / f"{path.stem}.png")
        return path.name, pred.result.status.value


def _make_worker(options: FolderOptions, out: str, png: str | None) -> FolderWorker:
    return FolderWorker(options, out, png)


def predict_folder(files, options: FolderOptions, out, png=None, *, executor=None, progress=None) -> dict:
    """Predict every image of ``files`` (paths) into ``out/<stem>.json`` (and ``png/<stem>.png``).

    Parameters
    ----------
    files : sequence of Path
    options : FolderOptions
    out, png : Path
        Existing folders (``png`` optional).
    executor : Executor, optional
        Where the images are predicted (default: this process); each worker loads the network once.
    progress : callable, optional
        Called after each image.

    Returns
    -------
    dict
        ``{file name: status}`` in the order of ``files``.
    """
    from ...executors import LocalExecutor

    executor = LocalExecutor() if executor is None else executor
    statuses = {}
    tasks = [str(p) for p in files]
    for name, status in executor.imap(_make_worker, (options, str(out), None if png is None else str(png)), tasks):
        statuses[name] = status
        if progress is not None:
            progress()
    return statuses
