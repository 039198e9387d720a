"""Helpers shared by every test folder."""

import numpy as np
import pytest


def central_differences(f, x, h: float = 1e-6) -> np.ndarray:
    """Central-difference derivative of ``f`` at ``x`` (float64).

    ``f`` maps an ``(n,)`` vector to an array of shape ``S`` (a scalar: ``S = ()``); the result
    has shape ``S + (n,)`` (the Jacobian ``(m, n)`` of a vector function, the gradient ``(n,)``
    of a scalar one).
    """
    x = np.asarray(x, dtype=np.float64)
    cols = []
    for e in np.eye(x.size):
        cols.append((np.asarray(f(x + h * e), dtype=np.float64) - np.asarray(f(x - h * e), dtype=np.float64)) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.fixture
def numeric_derivative():
    """:func:`central_differences` (the one finite-difference helper of the tests)."""
    return central_differences
