"""Articulated fitting: correspondences -> part poses, joints and boxes.

- :mod:`.types` -- :class:`Observation`, :class:`Correspondences`, the
  :class:`CorrespondenceProvider` protocol, :class:`FitResult` and :class:`FitStatus`.
- :mod:`.terms` -- energy terms and constraints, each defined once in CasADi.
- :mod:`.program` -- CasADi programs built once per kinematic structure (cached).
- :mod:`.backends` -- IPOPT and scipy least-squares backends.
- :mod:`.fit` -- :func:`fit`, :class:`FitConfig`, :data:`FORMULATIONS` (RANSAC loop,
  formulations, post-processing).

Importing this package does not import CasADi; the first solve does.
"""

from .fit import FORMULATIONS, FitConfig, Formulation, fit
from .types import Correspondences, CorrespondenceProvider, FitResult, FitStatus, Observation

__all__ = [
    "FORMULATIONS",
    "Correspondences",
    "CorrespondenceProvider",
    "FitConfig",
    "FitResult",
    "FitStatus",
    "Formulation",
    "Observation",
    "fit",
]
