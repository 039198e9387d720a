"""Scalar configuration checks: exact types, ranges, and errors naming the argument."""

import numpy as np
import pytest

from ancsh.geometry._checks import check_bool, check_choice, check_int, check_number, check_positive


@pytest.mark.parametrize("value", [True, 2.7, 3.0, "3", None, 0])
def test_check_int_rejects_bools_floats_and_small_values(value):
    with pytest.raises(ValueError, match="max_iterations: expected an integer >= 1"):
        check_int(value, "max_iterations", minimum=1)


def test_check_int_accepts_numpy_integers():
    assert check_int(np.int64(4), "n", minimum=1) == 4


@pytest.mark.parametrize("value, kwargs, match", [
    (True, {}, "expected a finite number"),
    (float("nan"), {}, "expected a finite number"),
    ("1", {}, "expected a finite number"),
    (-1.0, dict(minimum=0.0), "expected a non-negative number"),
    (0.0, dict(minimum=0.0, lower_open=True), "expected a positive number"),
    (1.5, dict(minimum=0.0, maximum=1.0, lower_open=True), r"expected a number in \(0.0, 1.0\]"),
])
def test_check_number(value, kwargs, match):
    with pytest.raises(ValueError, match=f"w: {match}"):
        check_number(value, "w", **kwargs)


def test_valid_scalars_pass():
    assert check_number(np.float64(0.5), "w", minimum=0.0, maximum=1.0) == 0.5
    assert check_positive(2, "w") == 2.0
    assert check_bool(np.bool_(True), "flag") is True
    assert check_choice("a", "mode", ("a", "b")) == "a"
    with pytest.raises(ValueError, match="flag: expected a bool"):
        check_bool(1, "flag")
    with pytest.raises(ValueError, match="mode: expected one of"):
        check_choice("c", "mode", ("a", "b"))
