"""A formula whose arithmetic is not finite on a trace: a FormulaValueError naming the formula and the instant.

The values are worked by hand: ``y`` is 0 at sample 2 (t = 2 s), so ``x / y`` is ``inf`` there and only there;
``x * 1e308 * 10`` overflows wherever ``x >= 0.18``.
"""

from __future__ import annotations

import math
import pickle

import pytest

from analysis.stl import FormulaValueError, SignalTrace, TraceError, parse_formula

TRACE = SignalTrace(times=[0.0, 1.0, 2.0, 3.0], signals={"x": [1.0, 1.0, 1.0, 0.5], "y": [1.0, 2.0, 0.0, 4.0]})


@pytest.mark.parametrize("method", ["robustness", "satisfied", "explain", "robustness_signal"])
def test_a_division_by_zero_names_the_formula_the_expression_and_the_instant(method):
    text = "always[0, 3] (x / y > 0)"
    with pytest.raises(FormulaValueError) as info:
        getattr(parse_formula(text), method)(TRACE)
    err = info.value
    assert (err.formula, err.expression, err.index, err.time, err.value, err.count) == (
        text, "(x / y)", 2, 2.0, math.inf, 1)
    assert isinstance(err, TraceError)  # callers catching trace errors still catch it
    message = str(err)
    assert f"formula {text!r}: expression (x / y) at sample 2 (t = 2 s) = inf" in message
    assert "1 of 4 samples are not finite" in message


def test_an_overflow_is_refused_with_the_first_sample():
    text = "eventually[0, 3]\n    x * 1e308 * 10 > 0"
    with pytest.raises(FormulaValueError) as info:
        parse_formula(text).robustness(TRACE)
    err = info.value
    # every sample: x = 0.5 at sample 3 gives 5e308, beyond the largest double (1.8e308) too
    assert (err.index, err.value, err.count) == (0, math.inf, 4)
    assert "formula 'eventually[0, 3] x * 1e308 * 10 > 0'" in str(err)  # whitespace folded for one line


def test_formula_value_errors_pickle():
    with pytest.raises(FormulaValueError) as info:
        parse_formula("x / y > 0").robustness(SignalTrace(times=[0.0], signals={"x": [1.0], "y": [0.0]}))
    back = pickle.loads(pickle.dumps(info.value))
    assert type(back) is FormulaValueError and str(back) == str(info.value) and back.index == 0
