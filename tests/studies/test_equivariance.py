"""The camera-roll gain: 1 for correspondences read from the shape, 0 for ones tied to the camera frame."""


import numpy as np
import pytest

from ancsh.studies.equivariance import measure_roll_gain, roll_gain, roll_points
from ancsh.solvers.providers.oracle import OracleProvider


def test_roll_points_turns_about_the_ray_through_the_centroid():
    rng = np.random.default_rng(4)
    p = rng.normal(size=(200, 3)) * 0.2 + [0.3, -0.1, 2.0]
    rolled, axis = roll_points(p, np.radians(25.0))
    np.testing.assert_allclose(axis, p.mean(0) / np.linalg.norm(p.mean(0)))
    np.testing.assert_allclose(rolled.mean(0), p.mean(0), atol=1e-12)  # the centroid stays on its ray
    np.testing.assert_allclose(np.linalg.norm(rolled, axis=1), np.linalg.norm(p, axis=1))  # about the camera centre
    d = p - p.mean(0)
    d2 = rolled - rolled.mean(0)
    cos = np.einsum("ni,ni->n", np.cross(axis, d), np.cross(axis, d2)) / (
        np.linalg.norm(np.cross(axis, d), axis=1) * np.linalg.norm(np.cross(axis, d2), axis=1))
    np.testing.assert_allclose(cos, np.cos(np.radians(25.0)))
    for bad in (p[:, :2], np.zeros((0, 3)), np.zeros((4, 3))):
        with pytest.raises(ValueError, match="points_cam"):
            roll_points(bad, 0.1)


def test_gain_is_one_for_the_ground_truth_and_zero_for_camera_frame_correspondences():
    from ancsh.data.generate import FrameGenerator, GenerationConfig

    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=2))
    frames = [gen.frame(i) for i in range(4)]
    truth = measure_roll_gain(frames, lambda f: OracleProvider(f, "none"), angle_rad=np.radians(8.0))
    assert truth["frames"] == 4 and truth["gain_mean"] == pytest.approx(1.0, abs=1e-6)

    class CameraFrame:
        """Correspondences whose NPCS are the points' own camera coordinates (ignoring the shape)."""

        def __init__(self, frame):
            self.truth = OracleProvider(frame, "none")

        def correspond(self, observation):
            import dataclasses

            corr = self.truth.correspond(observation)
            p = observation.points_cam
            npcs = np.empty_like(p)
            for j in np.unique(corr.part_labels):
                sel = corr.part_labels == j
                npcs[sel] = (p[sel] - p[sel].mean(0)) / (2 * np.linalg.norm(p[sel] - p[sel].mean(0), axis=1).max())
            return dataclasses.replace(corr, npcs=npcs)

    lazy = measure_roll_gain(frames, CameraFrame, angle_rad=np.radians(8.0))
    assert lazy["frames"] + lazy["skipped"] == 4 and abs(lazy["gain_mean"]) < 0.2


def test_roll_gain_names_bad_arguments():
    with pytest.raises(ValueError, match="angle_deg"):
        roll_gain("laptop", angle_deg=0.0)
    with pytest.raises(ValueError, match="frames"):
        roll_gain("laptop", frames=0)
