"""Where the project's shared data lives.

``shared_data_dir()`` is ``<repo>/../shared/data`` (the folder next to the repository), or the
folder named by the environment variable ``ANCSH_SHARED_DATA`` when it is set.
"""

from __future__ import annotations

import os
from pathlib import Path

ENV_VAR = "ANCSH_SHARED_DATA"


def shared_data_dir() -> Path:
    """The shared data folder (real articulated objects); it need not exist."""
    override = os.environ.get(ENV_VAR)
    if override:
        return Path(override).expanduser().resolve()
    return (Path(__file__).resolve().parents[2] / ".." / "shared" / "data").resolve()


def shared_objects(root=None) -> list[Path]:
    """Every object URDF under the shared data folder (or ``root``), sorted.

    PartNet-Mobility objects contribute their ``mobility.urdf``, ReplicaCAD folders every
    ``*.urdf``. An absent folder gives an empty list.
    """
    root = shared_data_dir() if root is None else Path(root)
    if not root.is_dir():
        return []
    return sorted(p for p in root.rglob("*.urdf") if p.is_file())
