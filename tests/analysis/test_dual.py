"""Forward-mode dual numbers (analysis.dual): derivatives against closed forms and central differences, the
values bit-identical to the float code, a silent loss of the derivative refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.dual import Dual, exp, expm1, split, sqrt, value_of, variables


def _model(x, y):
    """One float code path, run on floats and on duals: every operation the duals implement."""
    a = x * y + 3.0 * x - y / 2.0 + 1.0 / (x + 4.0) - (2.0 - y)
    b = (x - 1.0) ** 3 + abs(y - 5.0) + exp(0.3 * x) * expm1(-y / 4.0) + sqrt(x * x + 1.0)
    return -a / b + (b if b > a else a)


def test_derivatives_match_the_closed_form_of_a_product_and_a_quotient():
    x, y = variables([2.0, 3.0])
    z = (x * y) / (x + y)
    # d/dx xy/(x+y) = y^2/(x+y)^2 = 9/25, d/dy = x^2/(x+y)^2 = 4/25
    assert z.value == pytest.approx(1.2, rel=1e-15)
    assert z.grad.tolist() == pytest.approx([9 / 25, 4 / 25], rel=1e-14)
    w = exp(x) * sqrt(y) - expm1(-x)
    assert w.grad.tolist() == pytest.approx([math.exp(2) * math.sqrt(3) + math.exp(-2),
                                             math.exp(2) / (2 * math.sqrt(3))], rel=1e-14)


@pytest.mark.parametrize("seed", range(5))
def test_derivatives_of_a_longer_code_path_match_central_differences_and_the_values_are_bit_identical(seed):
    rng = np.random.default_rng(seed)
    p = rng.uniform(0.5, 3.0, 2)
    dual = _model(*variables(p.tolist()))
    assert dual.value == _model(*p.tolist())  # the same IEEE operations on the values
    h = 1e-6  # central differences: truncation h^2 |f'''| / 6 ~ 1e-12, round-off eps |f| / h ~ 1e-10
    for j in range(2):
        up, down = p.copy(), p.copy()
        up[j] += h
        down[j] -= h
        fd = (_model(*up.tolist()) - _model(*down.tolist())) / (2 * h)
        assert dual.grad[j] == pytest.approx(fd, rel=1e-7, abs=1e-8)


def test_comparisons_read_the_values_and_float_refuses_to_drop_the_derivative():
    x, y = variables([1.0, 2.0])
    assert x < y and y > 1.5 and 1.5 < y and max(x, y) is y and min(0.5, x) == 0.5
    with pytest.raises(TypeError, match="value_of"):
        float(x)
    with pytest.raises(TypeError, match="analysis.dual.exp"):
        math.exp(x)
    assert value_of(x) == 1.0 and value_of(2.5) == 2.5


def test_split_gives_values_and_gradients_with_zero_rows_for_floats():
    x, y = variables([1.0, 2.0], k=3, offset=1)
    values, grads = split([x, 7.0, x * y], 3)
    assert values.tolist() == [1.0, 7.0, 2.0]
    assert grads.tolist() == [[0, 1, 0], [0, 0, 0], [0, 2, 1]]
    assert isinstance(x + 1, Dual) and (2 - x).grad.tolist() == [0, -1, 0]
