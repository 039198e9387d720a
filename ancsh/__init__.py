"""ancsh: category-level articulated object pose estimation from a single depth image.

Implements ANCSH (Li et al., CVPR 2020) as a classical geometric pipeline with
a learned correspondence provider:

- :mod:`ancsh.geometry` -- numpy float64 math: rotations, Sim(3), Umeyama, RANSAC,
  oriented boxes, metrics;
- :mod:`ancsh.model` -- articulated models, forward kinematics, ANCSH ground truth;
- :mod:`ancsh.data` -- procedural objects, URDF loading, rendering, HDF5 datasets;
- :mod:`ancsh.solvers` -- energy terms, CasADi/IPOPT and scipy back ends, fitting;
- :mod:`ancsh.learned` -- the PointNet++ ANCSH network (the only package importing torch).

Sub-packages are imported lazily so that ``import ancsh`` stays fast.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

_SUBPACKAGES = ("geometry", "model", "data", "solvers", "learned")


def __getattr__(name: str):
    if name in _SUBPACKAGES:
        return importlib.import_module(f"ancsh.{name}")
    raise AttributeError(f"module 'ancsh' has no attribute {name!r}")
