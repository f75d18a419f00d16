"""hybrid.system.state_vector: the one validation of a state-valued parameter."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybrid.errors import ParameterError
from hybrid.system import state_vector

NAMES = ("x", "y")


def test_a_state_is_a_float_array_one_value_per_state():
    x = state_vector("guess", [1, np.float32(2.5)], NAMES)
    assert x.dtype == float and x.tolist() == [1.0, 2.5]


@pytest.mark.parametrize("value, shown", [
    ("12", "'12'"), (b"12", "b'12'"), (None, "None"), (3.0, "3.0"), ((True, 0.0), r"\(True, 0\.0\)"),
    ((1j, 0.0), r"\(1j, 0\.0\)"), ((1.0,), r"\(1\.0,\)"), ((1.0, 2.0, 3.0), r"\(1\.0, 2\.0, 3\.0\)"),
    ((math.nan, 0.0), r"\(nan, 0\.0\)"), ((math.inf, 0.0), r"\(inf, 0\.0\)"), (("a", 0.0), r"\('a', 0\.0\)"),
    (([1.0, 2.0], 0.0), r"\(\[1\.0, 2\.0\], 0\.0\)"),
])
def test_anything_else_is_refused_naming_the_parameter_value_and_fix(value, shown):
    with pytest.raises(ParameterError, match=rf"^initial_state = {shown}: expected 2 finite values \(x, y\); fix: "):
        state_vector("initial_state", value, NAMES)


def test_the_error_type_is_the_callers():
    class MyError(ParameterError):
        pass

    with pytest.raises(MyError):
        state_vector("state", "x", NAMES, error=MyError)
