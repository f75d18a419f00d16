import math

import numpy as np
import pytest

from hybrid import (
    DivergenceError,
    ExecutionError,
    HybridAutomaton,
    MemoryVariable,
    Mode,
    NumericalFailure,
    Plant,
    Transition,
    ZenoError,
    simulate_sampled,
)

PERIOD = 0.125  # exactly representable: sample times and ramp values are exact


def integrator_plant(exact=True):
    return Plant(
        state_names=("x",),
        input_names=("u",),
        derivative=lambda x, u: (u[0],),
        exact_flow=(lambda x, u, dt: (x[0] + u[0] * dt,)) if exact else None,
    )


def sawtooth_automaton():
    count = lambda v, m: {"n": m["n"] + 1.0}  # noqa: E731
    return HybridAutomaton(
        name="sawtooth",
        modes=(Mode(name="up"), Mode(name="down")),
        transitions=(
            Transition(name="top", source="up", target="down", guard=lambda v, m: v[0] - 1.0, reset=count, writes=("n",)),
            Transition(name="bottom", source="down", target="up", guard=lambda v, m: -v[0], reset=count, writes=("n",)),
        ),
        variables=("x",),
        memory=(MemoryVariable(name="n", initial=0.0),),
    )


class Follow:
    """u = +1 in 'up', -1 in 'down'; records the memory counter."""

    record_names = ("n",)

    def initial_state(self, t, x):
        return None

    def measure(self, t, x, c):
        return (x[0],), c

    def control(self, t, x, c, v, mode, memory):
        return ((1.0 if mode == "up" else -1.0),), c, (memory.get("n", 0.0),)


def test_sawtooth_event_times_are_exact():
    trace = simulate_sampled(sawtooth_automaton(), integrator_plant(), Follow(), (0.0,), period=PERIOD, duration=4.0)
    assert [e.time for e in trace.events] == [1.0, 2.0, 3.0, 4.0]
    assert [e.transition for e in trace.events] == ["top", "bottom", "top", "bottom"]
    assert [e.jump for e in trace.events] == [1, 2, 3, 4]
    assert trace.jumps[-1] == 4 and trace.record("n")[-1] == 4.0
    assert trace.states.shape == (33, 1) and trace.times[-1] == 4.0
    assert not trace.states.flags.writeable
    np.testing.assert_array_equal(trace.state("x")[:9], np.arange(9) * PERIOD)
    assert trace.visited_modes == ("up", "down")


def test_fallback_integration_matches_exact_flow():
    decay = Plant(state_names=("x",), input_names=("u",), derivative=lambda x, u: (-x[0] + u[0],))
    x = decay.flow((2.0,), (0.5,), 0.3)
    exact = 0.5 + (2.0 - 0.5) * math.exp(-0.3)
    assert abs(x[0] - exact) <= 1e-10 * abs(exact)


def test_zeno_at_one_instant_is_reported():
    loop = HybridAutomaton(
        name="ping",
        modes=(Mode(name="a"), Mode(name="b")),
        transitions=(
            Transition(name="ab", source="a", target="b", guard=lambda v, m: 1.0),
            Transition(name="ba", source="b", target="a", guard=lambda v, m: 1.0),
        ),
        variables=("x",),
    )
    with pytest.raises(ZenoError, match=r"instantaneous Zeno at t = 0 s in mode .b.: 3 jumps at one instant \(ab -> ba -> ab\)"):
        simulate_sampled(loop, integrator_plant(), Follow(), (0.0,), period=PERIOD, duration=1.0, max_jumps_per_sample=3)


def test_equal_priorities_enabled_together_is_non_determinism():
    a = HybridAutomaton(
        name="fork",
        modes=(Mode(name="up"), Mode(name="down"), Mode(name="other")),
        transitions=(
            Transition(name="t1", source="up", target="down", guard=lambda v, m: v[0] - 0.5),
            Transition(name="t2", source="up", target="other", guard=lambda v, m: v[0] - 0.5),
        ),
        variables=("x",),
    )
    with pytest.raises(ExecutionError, match=r"non-determinism at t = 0.5 s in mode 'up'.*\['t1', 't2'\]"):
        simulate_sampled(a, integrator_plant(), Follow(), (0.0,), period=PERIOD, duration=2.0)


def test_priority_resolves_and_reports_outranked():
    a = HybridAutomaton(
        name="fork",
        modes=(Mode(name="up"), Mode(name="down"), Mode(name="other")),
        transitions=(
            Transition(name="t1", source="up", target="down", guard=lambda v, m: v[0] - 0.5, priority=1),
            Transition(name="t2", source="up", target="other", guard=lambda v, m: v[0] - 0.5, priority=0),
        ),
        variables=("x",),
    )
    trace = simulate_sampled(a, integrator_plant(), Follow(), (0.0,), period=PERIOD, duration=1.0)
    assert trace.events[0].transition == "t2" and trace.events[0].outranked == ("t1",)


def test_numerical_failure_becomes_divergence_with_time_and_mode():
    class Breaks(Follow):
        def control(self, t, x, c, v, mode, memory):
            if t >= 0.5:
                raise NumericalFailure("depth of point 2 is -0.01 m")
            return super().control(t, x, c, v, mode, memory)

    with pytest.raises(DivergenceError, match=r"diverged at t = 0.5 s in mode 'up': depth of point 2 is -0.01 m") as info:
        simulate_sampled(sawtooth_automaton(), integrator_plant(), Breaks(), (0.0,), period=PERIOD, duration=2.0)
    assert info.value.time == 0.5 and info.value.mode == "up"


def test_nan_input_is_divergence():
    class NanInput(Follow):
        def control(self, t, x, c, v, mode, memory):
            return (float("nan"),), c, (0.0,)

    with pytest.raises(DivergenceError, match=r"t = 0 s in mode 'up': input 'u' is NaN"):
        simulate_sampled(sawtooth_automaton(), integrator_plant(), NanInput(), (0.0,), period=PERIOD, duration=1.0)


def test_bad_arguments():
    args = (sawtooth_automaton(), integrator_plant(), Follow(), (0.0,))
    with pytest.raises(ExecutionError, match=r"period = 0; expected a positive"):
        simulate_sampled(*args, period=0, duration=1.0)
    with pytest.raises(ExecutionError, match=r"x0 has 2 components, plant state has 1"):
        simulate_sampled(args[0], args[1], args[2], (0.0, 1.0), period=PERIOD, duration=1.0)

    class WrongSignals(Follow):
        def measure(self, t, x, c):
            return (x[0], 1.0), c

    with pytest.raises(ExecutionError, match=r"got 2 signal values, expected 1"):
        simulate_sampled(args[0], args[1], WrongSignals(), (0.0,), period=PERIOD, duration=1.0)


def test_stop_condition_ends_the_run():
    trace = simulate_sampled(
        sawtooth_automaton(), integrator_plant(), Follow(), (0.0,), period=PERIOD, duration=10.0,
        stop=lambda t, x, c, v, mode, m: "halfway" if x[0] >= 0.5 else None,
    )
    assert trace.termination == "halfway" and trace.times[-1] == 0.5


def test_nan_guard_is_an_error_not_a_disabled_transition():
    broken = HybridAutomaton(
        name="broken", modes=(Mode(name="up"), Mode(name="down")),
        transitions=(Transition(name="top", source="up", target="down", guard=lambda v, m: math.nan),),
        variables=("x",),
    )
    with pytest.raises(ExecutionError, match=r"at t = 0 s in mode 'up': guard of transition 'top'.*is NaN at signals \(0.0,\)"):
        simulate_sampled(broken, integrator_plant(), Follow(), (0.0,), period=PERIOD, duration=1.0)


@pytest.mark.parametrize("where, what", [("measure", "measure of the controller"),
                                         ("control", "control of the controller"),
                                         ("flow", "flow of the plant"), ("stop", "stop condition")])
def test_an_exception_in_the_users_loop_names_the_function_mode_time_and_state(where, what):
    from hybrid.errors import UserFunctionError

    def boom(*args):
        raise ZeroDivisionError("float division by zero")

    class Broken(Follow):
        def measure(self, t, x, c):
            return boom() if where == "measure" and t >= 0.5 else super().measure(t, x, c)

        def control(self, t, x, c, v, mode, memory):
            return boom() if where == "control" and t >= 0.5 else super().control(t, x, c, v, mode, memory)

    plant = integrator_plant()
    if where == "flow":
        plant = Plant(state_names=("x",), input_names=("u",), derivative=lambda x, u: (u[0],),
                      exact_flow=lambda x, u, dt: boom() if x[0] >= 0.5 else (x[0] + u[0] * dt,))
    stop = (lambda t, x, c, v, mode, m: boom() if t >= 0.5 else None) if where == "stop" else None
    with pytest.raises(UserFunctionError, match=rf"^system 'sawtooth': {what} raised ZeroDivisionError: float "
                                                r"division by zero in mode 'up' at t = 0\.5 s, x = \(x=0\.5\)") as info:
        simulate_sampled(sawtooth_automaton(), plant, Broken(), (0.0,), period=PERIOD, duration=2.0, stop=stop)
    assert isinstance(info.value.__cause__, ZeroDivisionError)
