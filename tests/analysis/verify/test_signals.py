"""Input signals as problem parameters (analysis/verify/signals.py): control points, values, errors, the budget."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.verify.signals import PiecewiseConstantInput, input_parameters, signal_problem
from analysis.stl import SignalTrace
from analysis.verify.verdicts import verify
from analysis.verify.verification import ProblemError
from analysis.verify.falsification import FalsificationError
from analysis.verify.requirements import Requirement


def _ramp_problem(points: int = 4, formula: str = "always[0, 4] (y < 100)"):
    u = PiecewiseConstantInput(name="u", low=-1.0, high=2.0, control_points=points, span=4.0)

    def simulate(inputs, point):
        t = np.linspace(0.0, 4.0, 81)
        return SignalTrace(times=t, signals={"y": np.cumsum(inputs["u"].at(t)) * 0.05, "u": inputs["u"].at(t)})

    return signal_problem(name="ramp", simulate=simulate, inputs=(u,), outputs=("y", "u"), horizon=4.0,
                          requirements=(Requirement(name="r", formula=formula),))


def test_control_points_are_parameters_and_the_signal_is_right_continuous_piecewise_constant():
    s = PiecewiseConstantInput(name="throttle", low=0.0, high=100.0, control_points=4, span=30.0, nominal=0.0)
    params = s.parameters()
    assert [p.name for p in params] == ["throttle_0", "throttle_1", "throttle_2", "throttle_3"]
    assert all((p.low, p.high, p.nominal) == (0.0, 100.0, 0.0) for p in params)
    point = {"throttle_0": 1.0, "throttle_1": 2.0, "throttle_2": 3.0, "throttle_3": 4.0}
    sig = s.signal(point)
    # segment k covers [7.5 k, 7.5 (k + 1)); the last value holds after the span
    times = [0.0, 7.4999, 7.5, 14.9, 15.0, 22.5, 29.99, 30.0, 40.0]
    assert sig.at(times).tolist() == [1.0, 1.0, 2.0, 2.0, 3.0, 4.0, 4.0, 4.0, 4.0]
    assert sig.starts.tolist() == [0.0, 7.5, 15.0, 22.5]


@pytest.mark.parametrize("kwargs, words", [
    ({"control_points": 0}, "control_points"),
    ({"control_points": -3}, "control_points"),
    ({"control_points": 2.5}, "control_points"),
    ({"control_points": True}, "control_points"),
    ({"low": 5.0, "high": 1.0}, "[low, high]"),
    ({"low": float("nan")}, "low"),
    ({"high": float("inf")}, "high"),
    ({"span": 0.0}, "span"),
    ({"nominal": 200.0}, "nominal"),
    ({"name": "bad name"}, "name"),
])
def test_bad_signal_definitions_are_refused_naming_the_parameter(kwargs, words):
    args = {"name": "u", "low": 0.0, "high": 1.0, "control_points": 3, "span": 10.0, **kwargs}
    with pytest.raises(ProblemError) as info:
        PiecewiseConstantInput(**args)
    assert words in info.value.parameter and "fix:" in str(info.value)


def test_values_outside_the_range_or_missing_are_refused():
    s = PiecewiseConstantInput(name="u", low=0.0, high=1.0, control_points=2, span=1.0)
    with pytest.raises(ProblemError, match="u_1"):
        s.values({"u_0": 0.5})
    with pytest.raises(ProblemError, match=r"\[0.0, 1.0\]"):
        s.values({"u_0": 0.5, "u_1": 1.5})


def test_two_signals_of_one_name_are_refused():
    s = PiecewiseConstantInput(name="u", low=0.0, high=1.0, control_points=2, span=1.0)
    with pytest.raises(ProblemError, match="distinct"):
        input_parameters((s, s))


def test_a_requirement_on_a_signal_the_model_does_not_output_is_refused():
    with pytest.raises(ValueError, match="speed"):
        _ramp_problem(formula="always[0, 4] (speed < 100)")


def test_the_problem_simulates_the_signal_of_its_point_and_needs_one_simulation_per_control_point():
    problem = _ramp_problem(points=4)
    assert problem.min_budget == 4 and problem.dimension == 4
    point = {"u_0": 2.0, "u_1": 2.0, "u_2": -1.0, "u_3": 0.0}
    trace = problem.trace(point)
    u = trace.signal("u")
    # closed form of the cumulative sum: 20 samples at 2 in each of the first two seconds, then -1, then 0
    assert u[0] == 2.0 and u[40] == -1.0 and u[80] == 0.0
    assert trace.signal("y")[-1] == pytest.approx(0.05 * (2.0 * 40 - 1.0 * 20 + 0.0 * 21))
    with pytest.raises(FalsificationError) as info:
        verify(problem, budget=3, seed=0)
    assert info.value.parameter == "budget" and "at least 4" in str(info.value)
    assert verify(problem, budget=4, seed=0).simulations <= 4
