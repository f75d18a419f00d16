"""What the executors say when user code fails or diverges, and the guard windows they must not miss.

Messages: a failing flow, output, guard, invariant, jump map, reset or stop
function is named with the mode, the time and the state, the original chained
(one mechanism, :func:`hybrid.system.call_user`); :class:`DivergenceError`
gives the time to 12 significant digits, the mode, the cause and the state.

Windows: ``x' = 1`` is integrated exactly, so RK45's steps grow tenfold and
span many guard windows; the refinement of bending samples finds every window
of the tester's two measurements (31 of 14 ms, 8 of 4.2 s), where the uniform
samples alone (``refine_depth=0``, the executor before) found 0 and 4.

Run as a script for the detection counts and the cost of the refinement::

    .venv/bin/python tests/hybrid/test_executor_messages.py
"""

import math
import pickle
import warnings

import numpy as np
import pytest

from hybrid import (
    DivergenceError,
    ExecutionError,
    HybridAutomaton,
    HybridSystem,
    MemoryVariable,
    Mode,
    NumericalFailure,
    Transition,
    simulate_continuous,
)
from hybrid.errors import GuardResolutionWarning, UserFunctionError, format_named_state, format_time
from hybrid.system import call_user

# ---------------------------------------------------------------------------- models


def clock_system(*, guard=lambda v, m: v[0] - 0.5, invariant=None, output=None, jump=None, reset=None,
                 flow=lambda t, x, m: (1.0,), variables=("x",)):
    """x' = 1 in mode 'wait'; 'hit' to 'done' when the guard holds."""
    automaton = HybridAutomaton(
        name="clock",
        modes=(Mode(name="wait", invariant=invariant), Mode(name="done")),
        transitions=(Transition(name="hit", source="wait", target="done", guard=guard, reset=reset,
                                writes=("n",) if reset is not None else ()),),
        variables=variables, memory=(MemoryVariable(name="n"),),
    )
    return HybridSystem(automaton=automaton, state_names=("x",), flows={"wait": flow, "done": flow},
                        jumps={} if jump is None else {"hit": jump}, output=output)


def self_loop(guard):
    """x' = 1 and one crossing self-loop: every rising zero of the guard is one event."""
    automaton = HybridAutomaton(
        name="windows", modes=(Mode(name="run"),),
        transitions=(Transition(name="enter", source="run", target="run", guard=guard, direction=+1),),
        variables=("x",),
    )
    return HybridSystem(automaton=automaton, state_names=("x",), flows={"run": lambda t, x, m: (1.0,)})


NARROW_HALF = 0.007  # 14 ms windows
NARROW_CENTRES = tuple(0.5 + k for k in range(31))


def narrow_windows(v, m):
    """``0.007 - |x - c_k|`` around the nearest of 31 centres 1 s apart: on during 14 ms around each."""
    k = min(max(round(v[0] - 0.5), 0), len(NARROW_CENTRES) - 1)
    return NARROW_HALF - abs(v[0] - NARROW_CENTRES[k])


SLOW_PERIOD, SLOW_WIDTH = 12.5, 4.2


def slow_windows(v, m):
    """``sin(2 pi x / 12.5) - cos(pi 4.2 / 12.5)``: on during 4.2 s of every 12.5 s (8 windows in 100 s)."""
    return math.sin(2.0 * math.pi * v[0] / SLOW_PERIOD) - math.cos(math.pi * SLOW_WIDTH / SLOW_PERIOD)


SLOW_STARTS = tuple(SLOW_PERIOD / 4.0 - SLOW_WIDTH / 2.0 + SLOW_PERIOD * k for k in range(8))  # 1.025 + 12.5 k


def quiet(**kwargs):
    """``simulate_continuous`` with a GuardResolutionWarning turned into an error (none is expected)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", GuardResolutionWarning)
        return simulate_continuous(**kwargs)


# ---------------------------------------------------------------------------- user functions that raise
def raising(when, result):
    """A function of (v, m) or (t, x[, m]) raising ValueError once the first state/signal exceeds ``when``."""

    def f(*args):
        first = args[1] if isinstance(args[0], float) else args[0]
        if first[0] > when:
            raise ValueError(f"sensor saturated at {first[0]:.3f}")
        return result(*args)

    return f


@pytest.mark.parametrize(
    "build, function, mode",
    [
        (lambda: clock_system(output=raising(0.25, lambda t, x: (x[0],))), "output", "wait"),
        (lambda: clock_system(guard=raising(0.25, lambda v, m: v[0] - 0.5)), "guard of transition 'hit'", "wait"),
        (lambda: clock_system(invariant=raising(0.25, lambda v, m: 1.0)), "invariant of mode 'wait'", "wait"),
        (lambda: clock_system(flow=raising(0.25, lambda t, x, m: (1.0,))), "flow of mode 'wait'", "wait"),
    ],
    ids=["output", "guard", "invariant", "flow"],
)
def test_a_raising_function_is_named_with_mode_time_and_state(build, function, mode):
    with pytest.raises(UserFunctionError) as info:
        simulate_continuous(build(), (0.0,), duration=1.0)
    err = info.value
    assert isinstance(err, ExecutionError)  # callers catching ExecutionError still do
    assert isinstance(err.__cause__, ValueError) and "sensor saturated" in str(err.__cause__)
    assert (err.function, err.mode, err.system, err.error_type) == (function, mode, "clock", "ValueError")
    # x' = 1 from 0: the state is the time, and the first evaluation past 0.25 is where it failed
    assert 0.25 < err.time < 0.5 and err.state == (pytest.approx(err.time, abs=1e-12),)
    message = str(err)
    assert message.startswith(f"system 'clock': {function} raised ValueError: sensor saturated at ")
    assert f"in mode '{mode}' at t = {format_time(err.time)} s, x = (x={err.state[0]:.12g})" in message
    assert "; fix: " in message


def test_jump_map_and_reset_that_raise_name_the_transition_and_its_source_mode():
    jump = clock_system(jump=lambda x, m: 1.0 / 0.0)
    with pytest.raises(UserFunctionError, match=r"jump map of transition 'hit' raised ZeroDivisionError") as info:
        simulate_continuous(jump, (0.0,), duration=1.0)
    assert info.value.mode == "wait" and info.value.time == pytest.approx(0.5, abs=2e-12)
    assert isinstance(info.value.__cause__, ZeroDivisionError)
    reset = clock_system(reset=lambda v, m: {"n": [][0]})
    with pytest.raises(UserFunctionError, match=r"reset of transition 'hit' raised IndexError.*in mode 'wait'"):
        simulate_continuous(reset, (0.0,), duration=1.0)


def test_stop_function_that_raises_goes_through_the_same_mechanism():
    def stop(t, x, mode, m):
        raise KeyError("goal")

    with pytest.raises(UserFunctionError, match=r"stop function 'goal' raised KeyError: 'goal' in mode 'wait' at t = 0 s"):
        simulate_continuous(clock_system(), (0.0,), duration=1.0, stops={"goal": stop})


def test_output_returning_nan_or_the_wrong_length_names_the_mode():
    nan = clock_system(output=lambda t, x: (math.nan if x[0] > 0.25 else x[0],))
    with pytest.raises(ExecutionError, match=r"output 'x' is NaN in mode 'wait' at t = 0\.\d+ s, x = \(0\.\d+\)"):
        simulate_continuous(nan, (0.0,), duration=1.0)
    short = clock_system(output=lambda t, x: (x[0], 1.0) if x[0] > 0.25 else (x[0],))
    with pytest.raises(ExecutionError, match=r"output returned 2 values in mode 'wait' at t = .*expected 1 \(x\)"):
        simulate_continuous(short, (0.0,), duration=1.0)


def test_system_methods_wrap_directly_and_let_numerical_failure_through():
    system = clock_system(output=lambda t, x: (1.0 / x[0],))
    with pytest.raises(UserFunctionError, match=r"^system 'clock': output raised ZeroDivisionError: .* in mode 'wait' "
                                                r"at t = 2\.5 s, x = \(x=0\)"):
        system.signals(2.5, (0.0,), mode="wait")
    with pytest.raises(UserFunctionError, match=r"output raised ZeroDivisionError: .* at t = 2\.5 s, x = \(x=0\)"):
        system.signals(2.5, (0.0,))  # no mode given: none named

    def fails(t, x, m):
        raise NumericalFailure("depth of point 2 is -0.01 m")

    with pytest.raises(NumericalFailure):  # the executors turn it into a DivergenceError
        clock_system(flow=fails).flow("wait", 0.0, (0.0,), {})
    inner = UserFunctionError("guard of transition 'x'", ValueError("v"), mode="q")
    with pytest.raises(UserFunctionError) as info:  # an error that already carries its context is not re-wrapped
        call_user(lambda: (_ for _ in ()).throw(inner), (), function="output", mode="wait")
    assert info.value is inner


def test_user_function_error_pickles_with_its_fields():
    err = UserFunctionError("flow of mode 'on'", ValueError("bad"), mode="on", time=0.125, state=(1.0, 2.0),
                            state_names=("h", "v"), system="ball")
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is UserFunctionError and str(back) == str(err)
    assert (back.function, back.mode, back.time, back.state, back.state_names, back.error_type) == (
        "flow of mode 'on'", "on", 0.125, (1.0, 2.0), ("h", "v"), "ValueError")


# ---------------------------------------------------------------------------- DivergenceError
def test_divergence_names_time_mode_cause_and_the_state():
    def fails(t, x, m):
        if x[0] > 0.3:
            raise NumericalFailure("depth of point 2 is -0.01 m")
        return (1.0,)

    with pytest.raises(DivergenceError) as info:
        simulate_continuous(clock_system(flow=fails), (0.0,), duration=1.0)
    err = info.value
    assert err.mode == "wait" and err.cause == "depth of point 2 is -0.01 m"
    assert 0.3 < err.time < 1.0 and err.state == (pytest.approx(err.time, abs=1e-12),) and err.state_time == err.time
    assert str(err) == (f"simulation diverged at t = {err.time:.12g} s in mode 'wait': depth of point 2 is -0.01 m; "
                        f"last finite state (x={err.state[0]:.12g})")
    assert isinstance(err.__cause__, NumericalFailure)


def test_divergence_time_is_told_from_the_step_before_it():
    old_style = f"{10.0000001:.6g}"
    assert old_style == f"{10.0:.6g}"  # what the message printed before: both "10"
    err = DivergenceError(10.0000001, "run", "NaN in the state")
    assert str(err) == "simulation diverged at t = 10.0000001 s in mode 'run': NaN in the state"
    close = DivergenceError(100.00000000000001, "run", "overflow", state=(1.0,), state_time=100.0)
    assert "t = 100.00000000000001 s" in str(close) and "last finite state at t = 100 s (x[0]=1)" in str(close)
    assert format_time(0.35000000000000003) == "0.35" and format_time(3.25) == "3.25" and format_time(0.0) == "0"


def test_divergence_state_is_abbreviated_when_long_and_pickles():
    names = tuple(f"s{i}" for i in range(20))
    err = DivergenceError(1.5, "m", "singular matrix", state=tuple(float(i) for i in range(20)), state_names=names)
    assert str(err).endswith("(s0=0, s1=1, s2=2, s3=3, s4=4, s5=5, s6=6, ..., s19=19; 20 components)")
    assert format_named_state((1.25, -math.inf), ("h", "v")) == "(h=1.25, v=-inf)"
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is DivergenceError and str(back) == str(err) and back.state == err.state


# ---------------------------------------------------------------------------- guard windows
def test_narrow_windows_31_of_31_found_where_the_uniform_samples_found_0():
    before = simulate_continuous(self_loop(narrow_windows), (0.0,), duration=31.0, refine_depth=0)
    assert before.events == ()  # the tester's measurement: 0 of 31
    assert before.resolution > 1.0  # and the run says its samples were more than 1 s apart
    run = quiet(system=self_loop(narrow_windows), x0=(0.0,), duration=31.0)
    exact = np.array(NARROW_CENTRES) - NARROW_HALF  # x = t: each window is entered at c_k - 7 ms
    assert run.event_times == pytest.approx(exact, abs=1e-9)
    assert run.unresolved == () and run.stats.refinement_evaluations > 0


def test_slow_windows_8_of_8_found_where_the_uniform_samples_found_4():
    before = simulate_continuous(self_loop(slow_windows), (0.0,), duration=100.0, refine_depth=0)
    assert len(before.events) == 4  # the tester's measurement: 4 of 8 windows of 4.2 s
    run = quiet(system=self_loop(slow_windows), x0=(0.0,), duration=100.0)
    assert run.event_times == pytest.approx(np.array(SLOW_STARTS), abs=1e-9)


def test_a_window_longer_than_the_reported_resolution_is_always_found():
    run = quiet(system=self_loop(narrow_windows), x0=(0.0,), duration=31.0, max_step=0.04)
    assert 0.0 < run.resolution <= 0.04 / 4 * (1 + 1e-12)  # max_step / (sign_checks + 1) < 14 ms
    assert len(run.events) == 31


def test_a_near_miss_narrower_than_the_finest_spacing_is_reported_not_silenced():
    def near_miss(v, m):  # peaks at -1e-7 at x = 5.3: never on, but nearly
        return -1e-7 - abs(v[0] - 5.3)

    with pytest.warns(GuardResolutionWarning, match=r"the guard 'enter' in mode 'run' on \[") as record:
        run = simulate_continuous(self_loop(near_miss), (0.0,), duration=10.0)
    assert len(record) == 1 and run.events == ()
    assert any(u.name == "enter" and u.t_start <= 5.3 <= u.t_end for u in run.unresolved)
    place = next(u for u in run.unresolved if u.t_start <= 5.3 <= u.t_end)
    assert place.distance < place.reach and place.reason == "depth" and place.t_end - place.t_start < 1e-5
    assert run.as_dict()["unresolved"][0]["name"] == "enter"
    # the fix the warning names: a bounded step resolves it (and there is indeed no window)
    bounded = quiet(system=self_loop(near_miss), x0=(0.0,), duration=10.0, max_step=0.01)
    assert bounded.events == () and bounded.unresolved == ()


def test_a_crossing_guard_starting_on_zero_keeps_its_meaning():
    """docs/hybrid.md: it fires as soon as it moves in its direction, never at the initial instant."""
    rising = quiet(system=self_loop(lambda v, m: v[0]), x0=(0.0,), duration=1.0)
    assert len(rising.events) == 1 and 0.0 < rising.events[0].time <= 2e-12
    away = quiet(system=self_loop(lambda v, m: -v[0]), x0=(0.0,), duration=5.0)
    assert away.events == () and away.stats.refinement_evaluations == 0


def test_refine_depth_is_validated():
    with pytest.raises(ExecutionError, match=r"refine_depth = -1; expected an int >= 0"):
        simulate_continuous(clock_system(), (0.0,), duration=1.0, refine_depth=-1)


# ---------------------------------------------------------------------------- measurement (not collected)
def _measure(rounds=7):  # pragma: no cover - run as a script
    import time

    from hybrid.examples import bouncing_ball, thermostat, water_tanks

    warnings.simplefilter("ignore", GuardResolutionWarning)
    for name, guard, duration, total in (("14 ms", narrow_windows, 31.0, 31), ("4.2 s", slow_windows, 100.0, 8)):
        found = {depth: len(simulate_continuous(self_loop(guard), (0.0,), duration=duration,
                                                refine_depth=depth).events) for depth in (0, 10)}
        print(f"windows of {name}: {found[0]}/{total} without refinement, {found[10]}/{total} with (default)")
    ball, thermo, tanks = bouncing_ball(), thermostat(), water_tanks()
    cases = (("bouncing ball 10 s", ball.system, ball.x0, 10.0), ("thermostat 2000 s", thermo.system, thermo.x0, 2000.0),
             ("water tanks 10 s", tanks.system, tanks.x0, 10.0))
    for name, system, x0, duration in cases:
        times = {0: [], 10: []}
        for _ in range(rounds):
            for depth in (0, 10):
                start = time.perf_counter()
                simulate_continuous(system, x0, duration=duration, refine_depth=depth)
                times[depth].append(time.perf_counter() - start)
        t0, t1 = min(times[0]), min(times[10])
        print(f"{name:20s} refine_depth=0 {t0 * 1e3:8.1f} ms  default {t1 * 1e3:8.1f} ms  ratio {t1 / t0:.2f}")


if __name__ == "__main__":  # pragma: no cover
    _measure()
