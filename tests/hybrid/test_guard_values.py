"""One rule for the values of guards and invariants (hybrid.model.not_a_number), applied alike by every evaluator.

Issue 25: a guard returning the text ``"1"`` was refused by one route and
accepted by another (``float("1")`` is 1.0, so the continuous executor fired
the transition).  A guard must return one real number; text, complex numbers
and bools are refused where the automaton is built (a probe at zero signals)
and wherever a run or a check evaluates one.  The fixtures mirror those of
``test_model_bool_guards.py`` (a clock ``x = t`` from 0, transition ``go`` out
of mode ``wait``).
"""

from __future__ import annotations

import numpy as np
import pytest

from hybrid import (
    Box,
    ExecutionError,
    HybridAutomaton,
    HybridSystem,
    Mode,
    ModelDefinitionError,
    Plant,
    Transition,
    simulate_continuous,
    simulate_sampled,
)
from hybrid.check import check
from hybrid.model import guard_value, not_a_number, real_number

PERIOD = 0.125  # exactly representable: the sampled ramp x = t is exact


def automaton(guard, *, invariant=None):
    """wait --go--> done, over the signal x (the clock's state)."""
    return HybridAutomaton(
        name="clock", modes=(Mode(name="wait", invariant=invariant), Mode(name="done")),
        transitions=(Transition(name="go", source="wait", target="done", guard=guard),), variables=("x",))


class Ramp:
    """u = 1: x = t at every sample."""

    record_names = ()

    def initial_state(self, t, x):
        return None

    def measure(self, t, x, c):
        return (x[0],), c

    def control(self, t, x, c, v, mode, memory):
        return (1.0,), c, ()


def run_sampled(a):
    plant = Plant(state_names=("x",), input_names=("u",), derivative=lambda x, u: (u[0],),
                  exact_flow=lambda x, u, dt: (x[0] + u[0] * dt,))
    return simulate_sampled(a, plant, Ramp(), (0.0,), period=PERIOD, duration=8.0)


def run_continuous(a):
    system = HybridSystem(automaton=a, state_names=("x",), flows={"wait": lambda t, x, m: (1.0,),
                                                                  "done": lambda t, x, m: (1.0,)})
    return simulate_continuous(system, (0.0,), duration=8.0)


def run_check(a):
    return check(a, Box(bounds={"x": (0.0, 10.0)}), samples=200)


@pytest.mark.parametrize(("value", "reason"), [
    (1.0, None), (1, None), (np.float64(2.5), None), (np.int32(3), None), (float("nan"), None),
    (True, "a bool"), (np.bool_(False), "a bool"),
    ("1", "text (str), not a number: return the number itself, e.g. 1.0 rather than '1'"),
    (b"1", "text (bytes), not a number: return the number itself, e.g. 1.0 rather than '1'"),
    (1 + 0j, "a complex number"), (np.complex128(1.0), "a complex number"),
    (None, "not a number"), ([1.0, 2.0], "not a number"),
])
def test_what_is_one_real_number(value, reason):
    assert not_a_number(value) == reason


def test_real_number_converts_or_names_the_function_and_the_place():
    assert real_number(np.float64(2.5), "guard g", "here") == 2.5 and type(real_number(3, "g", "")) is float
    with pytest.raises(ExecutionError, match=r"^guard g returned '1' at x = 3; expected one real number \(text"):
        real_number("1", "guard g", "at x = 3")


def test_a_text_guard_is_refused_when_the_automaton_is_built():
    with pytest.raises(ModelDefinitionError, match=r"guard of transition 'go' returns '1'; expected one real number"):
        automaton(lambda v, m: "1")


def partly_text(v, m):
    """A level function below x = 1, the text "1" above: the construction probe at x = 0 sees -5.0."""
    return "1" if v[0] > 1.0 else v[0] - 5.0


TEXT = r"returned '1' .*expected one real number \(text \(str\)"


def test_the_continuous_executor_refuses_a_text_guard():
    with pytest.raises(ExecutionError, match=r"guard of transition 'go' " + TEXT) as info:
        run_continuous(automaton(partly_text))
    assert "in mode 'wait'" in str(info.value)


def test_the_sampled_executor_refuses_a_text_guard():
    with pytest.raises(ExecutionError, match=r"guard of transition 'go' \(from mode 'wait'\) " + TEXT) as info:
        run_sampled(automaton(partly_text))
    assert "(1.125,)" in str(info.value)  # the first sample with x > 1


def test_the_structural_checks_refuse_a_text_guard():
    with pytest.raises(ExecutionError, match=r"check of automaton 'clock': guard of transition 'go' " + TEXT):
        run_check(automaton(partly_text))


def test_guard_value_refuses_text_and_complex():
    a = automaton(partly_text)
    with pytest.raises(ExecutionError, match=TEXT):
        guard_value(a.transitions[0], (2.0,), {})
    complex_guard = automaton(lambda v, m: (v[0] - 5.0) * (1 + 1j) if v[0] > 1.0 else v[0] - 5.0)
    with pytest.raises(ExecutionError, match=r"expected one real number \(a complex number\)"):
        run_continuous(complex_guard)


def test_a_text_invariant_is_refused_by_the_executor_and_the_checks():
    def invariant(v, m):
        return "8" if v[0] > 1.0 else 8.0 - v[0]

    a = automaton(lambda v, m: v[0] - 5.0, invariant=invariant)
    with pytest.raises(ExecutionError, match=r"invariant of mode 'wait' returned '8' .*\(text \(str\)"):
        run_continuous(a)
    with pytest.raises(ExecutionError, match=r"check of automaton 'clock': invariant of mode 'wait' returned '8'"):
        run_check(a)
