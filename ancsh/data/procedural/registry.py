"""Category metadata, the per-category generator registry and the fixed train/test instance split.

Each category module defines ``INFO`` (a :class:`CategoryInfo`) and ``build(rng, name)``
returning an :class:`~ancsh.model.articulated.ArticulatedModel` built in the canonical
orientation (+y up, +z front, +x right; ``R_canon_base`` = identity), base = part 0.

Split: an instance is identified by its seed. Training seeds are ``0 .. NUM_TRAIN-1``, test
seeds ``TEST_SEED_OFFSET .. TEST_SEED_OFFSET+NUM_TEST-1``; the generator's random stream is
``default_rng([seed, crc32(category)])``, so test instances share no random draws with
training instances (they are unseen shapes from the same parameter distribution).
"""

from __future__ import annotations

import zlib

import numpy as np

from ...model.articulated import JointType
from ..conventions import CategoryConvention

NUM_TRAIN = 200
NUM_TEST = 20
TEST_SEED_OFFSET = 1_000_000
SPLITS = ("train", "test")


#: A procedural category's metadata is its convention (:mod:`ancsh.data.conventions`): part and
#: joint names and types, rest states, size range. Kept under this name for callers of the registry.
CategoryInfo = CategoryConvention


def category_rng(category: str, seed: int) -> np.random.Generator:
    """The random stream of instance ``seed`` of ``category``."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected a non-negative int, got {seed!r}")
    return np.random.default_rng([int(seed), zlib.crc32(category.encode())])


def split_seeds(split: str) -> tuple[int, ...]:
    """Instance seeds of ``split`` (``"train"`` or ``"test"``); the same for every category."""
    if split == "train":
        return tuple(range(NUM_TRAIN))
    if split == "test":
        return tuple(range(TEST_SEED_OFFSET, TEST_SEED_OFFSET + NUM_TEST))
    raise ValueError(f"split: expected one of {SPLITS}, got {split!r}")


REVOLUTE, PRISMATIC = JointType.REVOLUTE, JointType.PRISMATIC
