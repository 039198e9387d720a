"""The networks: PointNet++ layers, the ANCSH and direct-voting networks, their configuration and weights files.

The network classes live in :mod:`ancsh.learned.network.models`; they are also reachable here (as before the
package was split) without importing torch until one is used.
"""

from __future__ import annotations

import importlib

_MODELS = ("AncshNet", "DirectVotingNet", "build_network", "normalize_cloud", "denormalize_joint_votes")


def __getattr__(name: str):
    if name in _MODELS:
        return getattr(importlib.import_module("ancsh.learned.network.models"), name)
    raise AttributeError(f"module 'ancsh.learned.network' has no attribute {name!r}")
