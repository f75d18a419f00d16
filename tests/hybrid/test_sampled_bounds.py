"""The argument checks and the resource bound of hybrid.simulate_sampled: refused before anything runs."""

from __future__ import annotations

import pickle
import time

import pytest

from hybrid import ExecutionError, HybridAutomaton, Mode, Plant, simulate_sampled
from hybrid.errors import ParameterError
from hybrid.sampled import DEFAULT_MAX_SAMPLES, SampledArgumentError, sample_count


def one_mode() -> HybridAutomaton:
    return HybridAutomaton(name="still", modes=(Mode(name="m"),), transitions=(), variables=("x",))


def plant() -> Plant:
    return Plant(state_names=("x",), input_names=("u",), derivative=lambda x, u: (u[0],),
                 exact_flow=lambda x, u, dt: (x[0] + u[0] * dt,))


class Counting:
    """A controller that counts its calls: a refused run must never reach it."""

    record_names = ("x",)

    def __init__(self) -> None:
        self.calls = 0

    def initial_state(self, t, x):
        self.calls += 1
        return None

    def measure(self, t, x, c):
        self.calls += 1
        return (x[0],), c

    def control(self, t, x, c, v, mode, memory):
        self.calls += 1
        return (0.0,), c, (x[0],)


def refused(parameter: str, **kwargs) -> SampledArgumentError:
    """Run with ``kwargs``; assert a quick refusal naming ``parameter``, before the controller is called."""
    controller = Counting()
    arguments = {"period": 0.1, "duration": 1.0, **kwargs}
    start = time.perf_counter()
    with pytest.raises(SampledArgumentError) as info:
        simulate_sampled(one_mode(), plant(), controller, (0.0,), **arguments)
    assert time.perf_counter() - start < 0.5  # nothing allocated per sample
    assert controller.calls == 0
    err = info.value
    assert isinstance(err, ParameterError) and isinstance(err, ExecutionError)
    assert err.parameter == parameter
    assert str(err).startswith(f"simulate_sampled: {parameter} = ")
    assert "; expected " in str(err) and "; fix: " in str(err)
    return err


@pytest.mark.parametrize("period", [5e-324, 1e-300, 1e-15])
def test_a_tiny_period_is_refused_by_the_sample_count(period):
    err = refused("duration", period=period, duration=1e3)
    assert f"period = {period!r} s" in err.expected
    assert "max_samples = 10,000,000 samples" in err.expected
    assert err.fix == "lengthen period, shorten duration, or pass a larger max_samples"


def test_an_overflowing_sample_count_is_named():
    err = refused("duration", period=5e-324, duration=1.7976931348623157e308)
    assert err.value == 1.7976931348623157e308
    assert "duration / period = overflows a float" in err.expected


def test_a_huge_duration_is_refused_before_allocating():
    err = refused("duration", period=1e-3, duration=1e12)  # 1e15 samples
    assert "(duration / period = 1e+15 samples)" in err.expected


def test_the_bound_is_the_max_samples_argument():
    err = refused("duration", period=0.1, duration=10.0, max_samples=100)  # 101 samples
    assert "at most max_samples = 100 samples" in err.expected
    assert "floor(duration / period) + 1 = 101 samples" in err.expected
    trace = simulate_sampled(one_mode(), plant(), Counting(), (0.0,), period=0.1, duration=9.9, max_samples=100)
    assert len(trace.times) == 100  # exactly at the bound: accepted


@pytest.mark.parametrize(("name", "value", "expected"), [
    ("period", 0.0, "a positive finite time step [s]"),
    ("period", -0.1, "a positive finite time step [s]"),
    ("period", float("nan"), "a positive finite time step [s]"),
    ("period", float("inf"), "a positive finite time step [s]"),
    ("period", True, "a positive finite time step [s], found bool"),
    ("period", "0.1", "a positive finite time step [s], found str"),
    ("duration", 0.0, "a positive finite time [s]"),
    ("duration", float("inf"), "a positive finite time [s]"),
    ("duration", None, "a positive finite time [s], found NoneType"),
    ("t0", float("nan"), "a finite time [s]"),
    ("max_samples", 0, "an integer >= 1"),
    ("max_samples", 1.5, "an integer >= 1"),
    ("max_samples", True, "an integer >= 1"),
    ("max_jumps_per_sample", 0, "an integer >= 1"),
])
def test_each_argument_is_checked(name, value, expected):
    err = refused(name, **{name: value})
    assert err.expected == expected
    assert err.value is value or (value != value and err.value != err.value)


def test_a_period_that_does_not_advance_the_time_is_refused():
    err = refused("period", period=1.0, duration=10.0, t0=1e300)
    assert "t + period == t" in err.expected


def test_a_wrong_initial_state_is_an_argument_error():
    with pytest.raises(SampledArgumentError, match=r"x0 has 2 components, plant state has 1 \(x\)") as info:
        simulate_sampled(one_mode(), plant(), Counting(), (0.0, 1.0), period=0.1, duration=1.0)
    assert info.value.parameter == "x0"


def test_sample_count_is_the_executors_count():
    assert sample_count(0.05, 120.0) == 2401
    assert sample_count(0.125, 1.0) == 9
    assert sample_count(0.1, 0.3) == 4  # 0.3 / 0.1 = 2.9999999999999996: the 1e-9 tolerance keeps the last sample
    trace = simulate_sampled(one_mode(), plant(), Counting(), (0.0,), period=0.1, duration=0.3)
    assert len(trace.times) == sample_count(0.1, 0.3)
    assert DEFAULT_MAX_SAMPLES == 10_000_000


def test_the_error_pickles_with_its_fields():
    err = refused("duration", period=1e-12, duration=1e3)
    copy = pickle.loads(pickle.dumps(err))
    assert type(copy) is SampledArgumentError and str(copy) == str(err) and copy.parameter == "duration"
