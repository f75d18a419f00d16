"""A guard or invariant that returns a bool is refused, never read as 0.0 (enabled) or 1.0.

``lambda v, m: v[0] > 5.0`` looks like a guard but is one only by accident: its
``False`` reads as ``0.0``, which is ``>= 0``, i.e. *enabled*.  The automaton
refuses it when it is built (a probe at zero signals and the initial memory),
and every executor refuses it where it evaluates it (a guard that returns a
bool only at some points gets past the probe).  A symbolic comparison
(``v.x >= 5.0``) is the way to write it: its level form ``x - 5`` is used, and
it fires where the hand-written level function ``v[0] - 5.0`` fires.
"""

import inspect
import math

import numpy as np
import pytest

from hybrid import (
    Box,
    ExecutionError,
    HybridAutomaton,
    HybridSystem,
    MemoryVariable,
    Mode,
    ModelDefinitionError,
    Plant,
    Transition,
    simulate_continuous,
    simulate_sampled,
)
from hybrid.check import check
from hybrid.model import guard_value, transition_fires
from hybrid.symbolic import Expr, SymbolicReset, coordinates, memory, reset

V = coordinates("x")
M = memory("n")
PERIOD = 0.125  # exactly representable: the sampled ramp x = t is exact
BOX = Box(bounds={"x": (0.0, 10.0)})
SAMPLES = 200


# ---------------------------------------------------------------------- fixtures
def automaton(guard, *, invariant=None, reset_=None, writes=(), direction=0):
    """wait --go--> done, over the signal x (= the state of the clock below)."""
    return HybridAutomaton(
        name="clock",
        modes=(Mode(name="wait", invariant=invariant), Mode(name="done")),
        transitions=(Transition(name="go", source="wait", target="done", guard=guard, reset=reset_, writes=writes,
                                direction=direction),),
        variables=("x",),
        memory=(MemoryVariable(name="n", initial=0.0),),
    )


def ramp_plant():
    return Plant(state_names=("x",), input_names=("u",), derivative=lambda x, u: (u[0],),
                 exact_flow=lambda x, u, dt: (x[0] + u[0] * dt,))


class Ramp:
    """u = 1: x = t at every sample; records the memory counter."""

    record_names = ("n",)

    def initial_state(self, t, x):
        return None

    def measure(self, t, x, c):
        return (x[0],), c

    def control(self, t, x, c, v, mode, memory):
        return (1.0,), c, (memory.get("n", 0.0),)


def clock(a):
    """dx/dt = 1 in both modes."""
    return HybridSystem(automaton=a, state_names=("x",), flows={"wait": lambda t, x, m: (1.0,),
                                                                 "done": lambda t, x, m: (1.0,)})


def run_sampled(a, duration=8.0):
    return simulate_sampled(a, ramp_plant(), Ramp(), (0.0,), period=PERIOD, duration=duration)


def run_continuous(a, duration=8.0):
    return simulate_continuous(clock(a), (0.0,), duration=duration)


def run_check(a, **kw):
    return check(a, BOX, samples=SAMPLES, **kw)


BOOL_HINT = r"v\[0\] - 5\.0"


# ---------------------------------------------------------------------- refused when the automaton is built
@pytest.mark.parametrize(
    "guard",
    [
        lambda v, m: v[0] > 5.0,  # False at zero
        lambda v, m: v[0] < 5.0,  # True at zero
        lambda v, m: m["n"] >= 1.0,  # reads the initial memory
        lambda v, m: bool(v[0] - 5.0),
    ],
    ids=["gt", "lt", "memory", "bool()"],
)
def test_a_guard_returning_a_bool_is_refused_at_construction(guard):
    with pytest.raises(ModelDefinitionError, match=r"guard of transition 'go' returns a bool") as info:
        automaton(guard)
    message = str(info.value)
    assert "automaton 'clock'" in message
    assert "v[0] - 5.0" in message  # how to write it instead
    assert "v.T >= 5.0" in message or "symbolic" in message


@pytest.mark.parametrize(
    "guard",
    [lambda v, m: np.float64(v[0]) > 5.0, lambda v, m: np.array(v)[0] < 5.0, lambda v, m: np.bool_(False)],
    ids=["float64_gt", "array_lt", "bool_"],
)
def test_a_guard_returning_a_numpy_bool_is_refused_at_construction(guard):
    assert isinstance(guard((0.0,), {"n": 0.0}), np.bool_)
    with pytest.raises(ModelDefinitionError, match=r"guard of transition 'go' returns a bool") as info:
        automaton(guard)
    assert "v[0] - 5.0" in str(info.value)


@pytest.mark.parametrize(
    "invariant", [lambda v, m: v[0] <= 8.0, lambda v, m: np.float64(v[0]) <= 8.0], ids=["bool", "numpy_bool"]
)
def test_an_invariant_returning_a_bool_is_refused_at_construction(invariant):
    with pytest.raises(ModelDefinitionError, match=r"invariant of mode 'wait' returns a bool") as info:
        automaton(lambda v, m: v[0] - 5.0, invariant=invariant)
    assert "v[0] - 5.0" in str(info.value)


@pytest.mark.parametrize(
    "guard",
    [lambda v, m: v[0] - 5.0, lambda v, m: 1, lambda v, m: np.float64(v[0]) - 5.0, lambda v, m: math.log(v[0]) - 1.0],
    ids=["float", "int", "float64", "raises_at_zero"],
)
def test_real_valued_guards_pass_the_probe(guard):
    """A number of any real type is a level; a probe that raises proves nothing (undefined at zero)."""
    a = automaton(guard)
    assert a.transitions[0].guard is guard


def test_guard_value_and_transition_fires_refuse_a_bool():
    t = Transition(name="go", source="wait", target="done", guard=lambda v, m: v[0] > 5.0)  # no probe: no automaton
    for v in ((0.0,), (7.0,)):
        with pytest.raises(ExecutionError, match=r"guard of transition 'go' \(from mode 'wait'\) returned the bool"):
            guard_value(t, v, {})
        with pytest.raises(ExecutionError, match=r"returned the bool"):
            transition_fires(t, v, {}, None)
    numpy_t = Transition(name="np", source="wait", target="done", guard=lambda v, m: np.float64(v[0]) > 5.0)
    with pytest.raises(ExecutionError, match=r"guard of transition 'np'.*returned the bool"):
        guard_value(numpy_t, (0.0,), {})


# ---------------------------------------------------------------------- refused where the executors evaluate it
def partly_bool(v, m):
    """A level function below x = 1, a bool above: the construction probe at x = 0 sees a float."""
    return (v[0] > 5.0) if v[0] > 1.0 else v[0] - 5.0


def partly_numpy_bool(v, m):
    return (np.float64(v[0]) > 5.0) if v[0] > 1.0 else v[0] - 5.0


PARTLY = pytest.mark.parametrize("guard", [partly_bool, partly_numpy_bool], ids=["bool", "numpy_bool"])


@PARTLY
def test_sampled_executor_refuses_a_guard_that_returns_a_bool_at_run_time(guard):
    a = automaton(guard)  # the probe at x = 0 sees -5.0
    with pytest.raises(ExecutionError, match=r"guard of transition 'go'.*returned the bool") as info:
        run_sampled(a)
    assert "v[0] - 5.0" in str(info.value)
    assert "t = 1.125 s" in str(info.value)  # the first sample with x > 1, well before x = 5


@PARTLY
def test_continuous_executor_refuses_a_guard_that_returns_a_bool_at_run_time(guard):
    a = automaton(guard)
    with pytest.raises(ExecutionError, match=r"guard of transition 'go' \(mode 'wait', t = .*\) returned the bool"):
        run_continuous(a)


@PARTLY
def test_checker_refuses_a_guard_that_returns_a_bool(guard):
    a = automaton(guard)
    with pytest.raises(ExecutionError, match=r"check of automaton 'clock': guard of transition 'go' returned the bool"):
        run_check(a)


def partly_bool_invariant(v, m):
    return (v[0] <= 8.0) if v[0] > 1.0 else 8.0 - v[0]


def partly_numpy_bool_invariant(v, m):
    return (np.float64(v[0]) <= 8.0) if v[0] > 1.0 else 8.0 - v[0]


PARTLY_INV = pytest.mark.parametrize("invariant", [partly_bool_invariant, partly_numpy_bool_invariant],
                                     ids=["bool", "numpy_bool"])


@PARTLY_INV
def test_continuous_executor_refuses_an_invariant_that_returns_a_bool_at_run_time(invariant):
    a = automaton(lambda v, m: v[0] - 5.0, invariant=invariant)
    with pytest.raises(ExecutionError, match=r"invariant of mode 'wait'.*returned the bool"):
        run_continuous(a)


@PARTLY_INV
def test_checker_refuses_an_invariant_that_returns_a_bool(invariant):
    a = automaton(lambda v, m: v[0] - 5.0, invariant=invariant)
    with pytest.raises(ExecutionError, match=r"invariant of mode 'wait' returned the bool"):
        run_check(a)


# ---------------------------------------------------------------------- a symbolic comparison is the way to write it
def test_a_condition_guard_and_invariant_become_their_level_forms():
    t = Transition(name="go", source="wait", target="done", guard=V.x >= 5.0)
    assert isinstance(t.guard, Expr)
    assert t.guard((7.0,), {}) == 2.0 and t.guard((3.0,), {}) == -2.0
    assert guard_value(t, (5.0,), {}) == 0.0
    q = Mode(name="wait", invariant=(V.x <= 8.0) & (V.x >= -1.0))
    assert isinstance(q.invariant, Expr)
    assert q.invariant((7.0,), {}) == 1.0 and q.invariant((-3.0,), {}) == -2.0
    assert automaton(V.x > 5.0).transitions[0].guard((6.5,), {}) == 1.5  # a strict guard: the same closed level


SYMBOLIC_GUARDS = pytest.mark.parametrize("symbolic", [V.x >= 5.0, V.x > 5.0, ~(V.x < 5.0), 5.0 <= V.x],
                                          ids=[">=", ">", "not <", "reflected"])


@SYMBOLIC_GUARDS
def test_sampled_symbolic_guard_fires_where_the_level_function_fires(symbolic):
    hand = run_sampled(automaton(lambda v, m: v[0] - 5.0))
    sym = run_sampled(automaton(symbolic))
    assert [e.time for e in hand.events] == [5.0]
    assert [(e.time, e.transition) for e in sym.events] == [(e.time, e.transition) for e in hand.events]
    np.testing.assert_array_equal(sym.states, hand.states)


@SYMBOLIC_GUARDS
def test_continuous_symbolic_guard_fires_where_the_level_function_fires(symbolic):
    hand = run_continuous(automaton(lambda v, m: v[0] - 5.0))
    sym = run_continuous(automaton(symbolic))
    assert len(hand.events) == 1 and abs(hand.events[0].time - 5.0) <= 1e-9
    # the level form x - 5 compiles to the same float operations as the lambda: the runs are identical
    assert [(e.time, e.transition) for e in sym.events] == [(e.time, e.transition) for e in hand.events]
    assert sym.events[0].state_after == hand.events[0].state_after


@pytest.mark.parametrize("direction", [1, -1])
def test_continuous_symbolic_crossing_guard_matches_the_level_function(direction):
    level = (lambda v, m: v[0] - 5.0) if direction > 0 else (lambda v, m: 5.0 - v[0])
    symbolic = (V.x >= 5.0) if direction > 0 else (V.x <= 5.0)
    hand = run_continuous(automaton(level, direction=direction))
    sym = run_continuous(automaton(symbolic, direction=direction))
    assert [e.time for e in sym.events] == [e.time for e in hand.events]


def test_continuous_symbolic_invariant_matches_the_level_function():
    hand = run_continuous(automaton(lambda v, m: v[0] - 5.0, invariant=lambda v, m: 8.0 - v[0]))
    sym = run_continuous(automaton(V.x >= 5.0, invariant=V.x <= 8.0))
    assert [e.time for e in sym.events] == [e.time for e in hand.events]
    assert sym.termination == hand.termination


def check_methods():
    """The checker's evaluation methods available (symbolic models may also be decided by SMT)."""
    if "method" in inspect.signature(check).parameters:
        return [{}, {"method": "sampled"}]
    return [{}]


def forked(guard_a, guard_b):
    """idle -> a at x >= 5, idle -> b at x <= 6, same priority: nondeterministic on [5, 6]."""
    return HybridAutomaton(
        name="forked",
        modes=(Mode(name="idle"), Mode(name="a"), Mode(name="b")),
        transitions=(
            Transition(name="to_a", source="idle", target="a", guard=guard_a),
            Transition(name="to_b", source="idle", target="b", guard=guard_b),
            Transition(name="a_back", source="a", target="idle", guard=lambda v, m: -1.0),
            Transition(name="b_back", source="b", target="idle", guard=lambda v, m: -1.0),
        ),
        variables=("x",),
    )


@pytest.mark.parametrize("kw", check_methods(), ids=lambda kw: kw.get("method", "default"))
def test_checker_symbolic_guards_find_what_the_level_functions_find(kw):
    hand = run_check(forked(lambda v, m: v[0] - 5.0, lambda v, m: 6.0 - v[0]), **kw)
    sym = run_check(forked(V.x >= 5.0, V.x <= 6.0), **kw)
    assert "nondeterminism" in hand.kinds()
    assert sym.kinds() == hand.kinds()
    for report in (hand, sym):
        found = [f for f in report.findings if f.kind == "nondeterminism"]
        assert found and set(found[0].transitions) == {"to_a", "to_b"}
        w = found[0].witness
        if w is not None:  # the witness lies where both guards hold
            x = w.signals.get("x", w.state.get("x"))
            assert 5.0 - 1e-9 <= x <= 6.0 + 1e-9
    clean_hand = run_check(automaton(lambda v, m: v[0] - 5.0), **kw)
    clean_sym = run_check(automaton(V.x >= 5.0), **kw)
    assert clean_sym.kinds() == clean_hand.kinds()
    assert "nondeterminism" not in clean_sym.kinds()


# ---------------------------------------------------------------------- symbolic resets provide their writes
def test_a_symbolic_reset_provides_writes_and_runs():
    r = reset(n=M.n + V.x)
    assert isinstance(r, SymbolicReset)
    a = automaton(V.x >= 5.0, reset_=r)
    assert a.transitions[0].writes == ("n",)
    trace = run_sampled(a)
    assert trace.record("n")[-1] == 5.0  # n = 0 + x at the jump, x = 5
    assert automaton(V.x >= 5.0, reset_=r, writes=("n",)).transitions[0].writes == ("n",)
    with pytest.raises(ModelDefinitionError, match=r"writes = \('m',\) but the symbolic reset assigns \('n',\)"):
        Transition(name="go", source="wait", target="done", guard=V.x >= 5.0, reset=r, writes=("m",))


def test_a_symbolic_guard_over_other_coordinates_than_the_automaton_variables_is_refused():
    """coordinates('a', 'b') evaluated on variables ('x', 'y') would silently read the wrong component."""
    from hybrid.symbolic import coordinates

    v = coordinates("a", "b")
    with pytest.raises(ModelDefinitionError, match=r"'b' \(index 1, where the vector has 'y'\).*coordinates\('x', 'y'\)"):
        HybridAutomaton(name="x", modes=(Mode(name="q"),), variables=("x", "y"),
                        transitions=(Transition(name="t", source="q", target="q", guard=v.b - 1.0),))
