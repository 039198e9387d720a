"""Shared fixtures of the learned-model tests: a handful of synthetic frames and a tiny network config."""

import pytest

from ancsh.learned.network.config import TrainConfig
from ancsh.learned.training.data import synthetic_arrays


@pytest.fixture(scope="session")
def tiny_arrays():
    """Four frames of 64 points of two random two-part revolute objects (seeded)."""
    return synthetic_arrays(4, 64, seed=3, num_parts=2, joint_types="revolute", instances=2)


@pytest.fixture(scope="session")
def prismatic_arrays():
    """Three frames of 64 points of a random three-part object with prismatic joints."""
    return synthetic_arrays(3, 64, seed=5, num_parts=3, joint_types="prismatic")


@pytest.fixture
def tiny_config():
    """A network small enough to train for a hundred steps in a few seconds on one core."""
    return TrainConfig(
        num_points=64, width=0.125, npoints=(32, 8), nsamples=(8, 8), batch_size=4, max_steps=100,
        lr=1e-2, lr_decay=0.5, lr_decay_steps=100, val_every=1000, checkpoint_every=1000, val_frames=4,
    )
