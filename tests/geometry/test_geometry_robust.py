"""Robust kernels: the weight is d rho / d(r^2), outliers are down-weighted, bad input is refused."""

import numpy as np
import pytest

from ancsh.geometry.robust import ROBUST_LOSSES, robust_loss, robust_weights


@pytest.mark.parametrize("kernel", [k for k in ROBUST_LOSSES if k != "none"])
def test_weight_is_the_derivative_of_the_loss_in_r2_and_downweights_outliers(kernel, numeric_derivative):
    r2 = np.array([1e-6, 0.01, 0.5, 4.0, 100.0])
    c = 0.1
    r = np.sqrt(r2)
    rho, w = robust_loss(r, kernel, c), robust_weights(r, kernel, c)
    numeric = np.diag(numeric_derivative(lambda v: robust_loss(np.sqrt(v), kernel, c), r2, h=1e-7))
    np.testing.assert_allclose(w, numeric, rtol=1e-5, atol=1e-9)  # (Tukey is only C1 at r = c)
    assert np.all(np.diff(w) <= 0) and w[-1] <= 0.011 * w[0]
    assert np.all(rho[1:] < r2[1:] + 1e-15)  # grows slower than least squares


def test_none_is_least_squares():
    r = np.array([0.0, 0.3, 7.0])
    np.testing.assert_array_equal(robust_weights(r, "none", 1.0), 1.0)
    np.testing.assert_allclose(robust_loss(r, "none", 1.0), r**2)


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), True])
def test_bad_scale_or_loss_is_refused(scale):
    with pytest.raises(ValueError, match="scale"):
        robust_loss(np.ones(2), "huber", scale)
    with pytest.raises(ValueError, match="loss: expected one of"):
        robust_weights(np.ones(2), "l7", 1.0)
