"""ancsh: category-level articulated object pose estimation from a single depth image.

Implements ANCSH (Li et al., CVPR 2020) as a classical geometric pipeline with
a learned correspondence provider:

- :mod:`ancsh.geometry` -- numpy float64 math: rotations, Sim(3), Umeyama, RANSAC,
  oriented boxes, metrics;
- :mod:`ancsh.model` -- articulated models, forward kinematics, ANCSH ground truth;
- :mod:`ancsh.data` -- procedural objects, URDF loading, rendering, HDF5 datasets;
- :mod:`ancsh.solvers` -- energy terms, CasADi/IPOPT and scipy back ends, fitting;
- :mod:`ancsh.evaluation` -- the paper's metrics of one fit against ground truth;
- :mod:`ancsh.learned` -- the PointNet++ ANCSH network (the only package importing torch);
- :mod:`ancsh.tracking` -- trackers over depth sequences.

The studies that write ``docs/results/`` are :mod:`ancsh.studies`, the commands :mod:`ancsh.cli`
(``docs/ARCHITECTURE.md``). Sub-packages are imported lazily so that ``import ancsh`` stays fast.

Prediction on a depth image is one call, :func:`predict` (``ancsh predict`` on the command line).
"""

from __future__ import annotations

import importlib

from ._version import __version__  # noqa: F401  (ancsh.__version__)

_SUBPACKAGES = ("geometry", "model", "data", "solvers", "evaluation", "learned", "tracking", "studies", "cli")


def predict(depth, intrinsics, category, **options):
    """Poses, boxes and joints of a ``category`` object in one depth image (the learned ANCSH pipeline).

    Parameters
    ----------
    depth : str, Path or (H, W) float64 array
        A 16-bit PNG of millimetres or a ``.npy`` of metres, or the depth itself in metres (0 = none).
    intrinsics : str, Path or Intrinsics
        ``{"fx", "fy", "cx", "cy", "width", "height"}`` JSON, or the object.
    category : str, Path or Category
        A built-in category's name (its shipped network is used), a spec file or built category folder, or a
        :class:`ancsh.learned.inference.category.Category` loaded once for many calls
        (:func:`~ancsh.learned.inference.category.load_category`).
    **options
        Of :func:`ancsh.learned.inference.predict.predict_depth`: ``mask`` (array, or a PNG/``.npy`` path),
        ``hint`` (:class:`ancsh.data.isolate.ObjectHint`), ``isolate``, ``max_depth``, ``weights``,
        ``formulation``, ``num_points``, ``seed``, ``max_objects``, ``hypotheses``.

    Returns
    -------
    DepthPrediction
        The best-supported object: ``.result`` (a :class:`ancsh.solvers.FitResult`: ``status``, ``message``,
        ``T_cam_npcs``, ``boxes_cam``, ``joint_*``), ``.notes``, ``.mask``, ``.consensus``; ``.objects``, every object
        of the category found (itself first); and ``.to_json()`` (``docs/json_schema.md``).
    """
    from pathlib import Path

    from .data.images import read_depth, read_intrinsics, read_mask
    from .learned.inference.predict import predict_depth

    if isinstance(depth, (str, Path)):
        depth = read_depth(depth)
    if isinstance(intrinsics, (str, Path)):
        intrinsics = read_intrinsics(intrinsics)
    if isinstance(options.get("mask"), (str, Path)):
        options["mask"] = read_mask(options["mask"], (intrinsics.height, intrinsics.width))
    return predict_depth(depth, intrinsics, category, **options)


def __getattr__(name: str):
    if name in _SUBPACKAGES:
        return importlib.import_module(f"ancsh.{name}")
    raise AttributeError(f"module 'ancsh' has no attribute {name!r}")
