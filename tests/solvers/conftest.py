"""Seeded articulated test cases for the solver tests."""

from dataclasses import dataclass, replace

import numpy as np
import pytest

from ancsh.model.canonical import ancsh_ground_truth
from ancsh.model.synthetic import random_articulated_model, sample_frame
from ancsh.solvers.types import Correspondences, Observation


@dataclass(frozen=True)
class FitCase:
    model: object
    gt: object
    observation: Observation
    correspondences: Correspondences


def build_fit_case(seed, num_parts=3, joint_types=None, tree=False, points_per_part=150, npcs_noise=0.0, limits=True):
    """Surface points of a random model, with exact (or NPCS-noisy) ground-truth correspondences."""
    rng = np.random.default_rng(seed)
    model = random_articulated_model(rng, num_parts, joint_types=joint_types, tree=tree)
    frame = sample_frame(model, rng, points_per_part=points_per_part)
    gt = ancsh_ground_truth(model, frame.q, frame.T_cam_base, frame.points_cam, frame.part_labels)
    lim = np.stack([model.lower_limits - model.rest_states, model.upper_limits - model.rest_states], axis=1)
    corr = Correspondences.from_ground_truth(gt, joint_limits=lim if limits else None)
    if npcs_noise:
        corr = replace(corr, npcs=corr.npcs + rng.normal(0.0, npcs_noise, corr.npcs.shape))
    return FitCase(model, gt, Observation(frame.points_cam), corr)


@pytest.fixture
def fit_case():
    return build_fit_case
