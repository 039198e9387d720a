"""Correspondence providers: anything that turns an observation into correspondences.

:class:`~ancsh.solvers.types.CorrespondenceProvider` is the protocol. Here:

- :class:`OracleProvider` -- ground-truth correspondences of a frame with controlled
  corruption (:class:`Corruption`, named presets in :data:`CORRUPTION_PRESETS`), to compare
  solvers before any network exists.

The network (``ancsh.learned``) and CAD/ICP templates provide the same protocol elsewhere.
"""

from .oracle import CORRUPTION_PRESETS, Corruption, OracleProvider, OracleSample, corrupt_ground_truth

__all__ = ["CORRUPTION_PRESETS", "Corruption", "OracleProvider", "OracleSample", "corrupt_ground_truth"]
