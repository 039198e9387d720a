"""Depth noise measured in a segment and averaged away where it is larger than a network saw in training
(``ancsh.data.noise.measured_sigma`` / ``averaged_depth``; ``ancsh.learned.inference.candidate.noise_averaged``)."""

import numpy as np
import pytest

from ancsh.data.noise import DepthNoise, averaged_depth, measured_sigma


def _noisy_plane(sigma, seed=0, shape=(160, 200)):
    """A tilted plane 2-3 m away with Gaussian depth noise ``sigma`` (metres), and a mask inside it."""
    rng = np.random.default_rng(seed)
    vv, uu = np.mgrid[0:shape[0], 0:shape[1]]
    clean = 2.0 + 0.004 * uu + 0.002 * vv
    mask = np.zeros(shape, dtype=bool)
    mask[20:140, 30:170] = True
    return clean + rng.normal(0.0, sigma, shape), clean, mask


@pytest.mark.parametrize("sigma", [0.003, 0.02, 0.05])
def test_the_noise_of_a_segment_is_measured_in_it(sigma):
    noisy, _, mask = _noisy_plane(sigma)
    assert measured_sigma(noisy, mask) == pytest.approx(sigma, rel=0.1)


def test_averaging_brings_the_noise_down_by_the_window_and_keeps_depth_steps_and_the_outside():
    sigma = 0.02
    noisy, clean, mask = _noisy_plane(sigma, seed=1)
    step = np.zeros_like(mask)
    step[:, 100:] = True
    noisy[step] += 0.4  # a second surface 40 cm behind inside the mask (a door ajar in front of a wall)
    clean = clean + 0.4 * step
    out = averaged_depth(noisy, mask, 5, 5 * sigma)
    inner = mask.copy()
    inner[:, 96:104] = False  # away from the step, where fewer neighbours are on the pixel's surface
    inner[20:23], inner[137:140], inner[:, 30:33], inner[:, 167:170] = False, False, False, False
    assert np.std(out[inner] - clean[inner]) == pytest.approx(sigma / 5, rel=0.25)
    # the step stays sharp: every averaged pixel stays on its own surface
    assert np.max(np.abs(out[mask] - clean[mask])) < 6 * sigma
    assert np.array_equal(out[~mask], noisy[~mask])
    assert averaged_depth(noisy, mask, 1, 0.1) is noisy  # a window of one pixel: the depth itself
    holes = noisy.copy()
    holes[50:60, 50:60] = 0.0  # no measurement stays no measurement, and is no neighbour
    out = averaged_depth(holes, mask, 5, 5 * sigma)
    assert np.all(out[50:60, 50:60] == 0.0) and np.all(out[mask & (holes > 0)] > 1.9)


def test_bad_arguments_are_named():
    noisy, _, mask = _noisy_plane(0.01)
    for window in (0, 4, -3, 2.5, True):
        with pytest.raises(ValueError, match="window"):
            averaged_depth(noisy, mask, window, 0.05)
    with pytest.raises(ValueError, match="jump"):
        averaged_depth(noisy, mask, 3, 0.0)
    with pytest.raises(ValueError, match="depth, mask"):
        measured_sigma(noisy, mask[:10])
    tiny = np.zeros_like(mask)
    tiny[5:8, 5:8] = True
    assert np.isnan(measured_sigma(noisy, tiny)) and np.isnan(measured_sigma(noisy, np.zeros_like(mask)))


def test_a_segment_noisier_than_training_is_averaged_by_a_window_that_grows_with_the_ratio():
    from ancsh.learned.inference.candidate import MAX_AVERAGING_WINDOW, noise_averaged, training_noise
    from ancsh.learned.inference.category import load_category

    category = load_category("microwave")
    seen = training_noise(category)
    # the dataset's model at the farthest training view of a typical microwave
    from ancsh.data.render import viewpoint_range

    assert seen == pytest.approx(DepthNoise().sigma(viewpoint_range("microwave").distance[1] * category.typical_size),
                                 rel=1e-9)
    near, _, mask = _noisy_plane(0.7 * seen, seed=2)
    d, window, sigma = noise_averaged(near, mask, category)
    assert window == 1 and d is near and sigma == pytest.approx(0.7 * seen, rel=0.15)
    for ratio, expected in ((2.5, 3), (4.4, 5), (30.0, MAX_AVERAGING_WINDOW)):
        far, _, _ = _noisy_plane(ratio * seen, seed=3)
        d, window, sigma = noise_averaged(far, mask, category)
        assert window == expected
        assert measured_sigma(d, mask) < sigma / 2 and np.array_equal(d[~mask], far[~mask])
    d, window, _ = noise_averaged(far, None, category)  # no mask: every measured pixel
    assert window == MAX_AVERAGING_WINDOW and not np.array_equal(d, far)
