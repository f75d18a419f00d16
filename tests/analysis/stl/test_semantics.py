"""analysis.stl semantics: every rule against values computed by hand, jumps, end of trace, explanations.

The closed forms below were worked out on paper from the rules of
``docs/stl.md``; values are exact in binary (small integers and halves, no
rounding), so they are compared exactly, except where a sum of decimals is
involved (then 1e-12, far below any difference a wrong rule would make).
"""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from analysis.stl import Explanation, Formula, SignalTrace, TraceError, parse_formula
from analysis.stl.semantics import window_bounds, window_reduce
from analysis.stl.syntax import (
    And,
    BinOp,
    Compare,
    Const,
    Edge,
    Func,
    Implies,
    LabelIs,
    Neg,
    Not,
    Num,
    Or,
    Temporal,
    Until,
    Var,
)

INF = math.inf
X = [1.0, -2.0, 3.0, 0.5, 4.0, -1.0]
Y = [0.0, 2.0, -1.0, 1.0, 0.0, 3.0]
UNIFORM = SignalTrace(times=np.arange(6.0), signals={"x": X, "y": Y})


def rho(text: str, trace: SignalTrace = UNIFORM) -> list[float]:
    return parse_formula(text).robustness_signal(trace).tolist()


@pytest.mark.parametrize(("text", "expected"), [
    ("x > 0.5", [0.5, -2.5, 2.5, 0.0, 3.5, -1.5]),
    ("x >= y", [1.0, -4.0, 4.0, -0.5, 4.0, -4.0]),
    ("x < y", [-1.0, 4.0, -4.0, 0.5, -4.0, 4.0]),
    ("x <= y", [-1.0, 4.0, -4.0, 0.5, -4.0, 4.0]),
    ("x == 1", [0.0, -3.0, -2.0, -0.5, -3.0, -2.0]),
    ("x != 1", [0.0, 3.0, 2.0, 0.5, 3.0, 2.0]),
    ("not x > 0", [-1.0, 2.0, -3.0, -0.5, -4.0, 1.0]),
    ("x > 0 and y > 0", [0.0, -2.0, -1.0, 0.5, 0.0, -1.0]),
    ("x > 0 or y > 0", [1.0, 2.0, 3.0, 1.0, 4.0, 3.0]),
    ("x > 0 -> y > 0", [0.0, 2.0, -1.0, 1.0, 0.0, 3.0]),
    ("true", [INF] * 6),
    ("false or not true", [-INF] * 6),
    ("0 <= x <= 2", [1.0, -2.0, -1.0, 0.5, -2.0, -1.0]),
])
def test_atoms_and_connectives(text, expected):
    assert rho(text) == expected


@pytest.mark.parametrize(("text", "expected"), [
    ("abs(x) > 1", [0.0, 1.0, 2.0, -0.5, 3.0, 0.0]),
    ("min(x, y) > 0", [0.0, -2.0, -1.0, 0.5, 0.0, -1.0]),
    ("max(x, y) > 0", [1.0, 2.0, 3.0, 1.0, 4.0, 3.0]),
    ("prev(x) > 0", [1.0, 1.0, -2.0, 3.0, 0.5, 4.0]),  # at sample 0: the first sample's value
    ("x - prev(x) > 0", [0.0, -3.0, 5.0, -2.5, 3.5, -5.0]),
    ("2 * x + y / 2 - -1 > 0", [3.0, -2.0, 6.5, 2.5, 9.0, 0.5]),
])
def test_arithmetic(text, expected):
    assert rho(text) == expected


@pytest.mark.parametrize(("text", "expected"), [
    ("always[1, 2] x > 0", [-2.0, 0.5, 0.5, -1.0, -1.0, INF]),
    ("eventually[0, 1] x > 0", [1.0, 3.0, 3.0, 4.0, 4.0, -1.0]),
    ("historically x > 0", [1.0, -2.0, -2.0, -2.0, -2.0, -2.0]),
    ("once x > 0", [1.0, 1.0, 3.0, 3.0, 4.0, 4.0]),
    ("historically[0, 1] x > 0", [1.0, -2.0, -2.0, 0.5, 0.5, -1.0]),
    ("once[1, 1] y > 0", [-INF, 0.0, 2.0, -1.0, 1.0, 0.0]),
    # until: psi at k, phi on [i, k) -- phi is not required at k itself (k = 2 decides at i = 0)
    ("y > 0 until[0, 2] x > 2", [0.0, 1.0, 1.0, 1.0, 2.0, -3.0]),
    # since: psi at k, phi on (k, i]
    ("y > 0 since x > 2", [-1.0, -1.0, 1.0, 1.0, 2.0, 2.0]),
    ("rise(x > 0)", [1.0, -2.0, 2.0, -3.0, -0.5, -4.0]),  # at 0: rho(0)
    ("fall(x > 0)", [-1.0, 1.0, -3.0, -0.5, -4.0, 1.0]),  # at 0: -rho(0)
])
def test_temporal_operators_on_a_uniform_trace(text, expected):
    assert rho(text) == expected


@pytest.mark.parametrize(("text", "expected"), [
    # the window is truncated to the samples present; an empty one is +inf (always) or -inf (eventually, until)
    ("always[2, 4] x > 0", [0.5, -1.0, -1.0, -1.0, INF, INF]),
    ("eventually[1, 10] x > 0", [4.0, 4.0, 4.0, 4.0, -1.0, -INF]),
    ("x > -3 until[1, 3] y > 2.5", [-0.5, -1.5, 0.5, 0.5, 0.5, -INF]),
    ("historically[1, 2] x > 0", [INF, 1.0, -2.0, -2.0, 0.5, 0.5]),
    ("x > -5 since[1, 2] y > 1.5", [-INF, -1.5, 0.5, 0.5, -0.5, -0.5]),
])
def test_end_of_trace_truncation(text, expected):
    assert rho(text) == expected


SPARSE = SignalTrace(times=[0.0, 0.3, 1.0, 1.1, 2.5, 2.6], signals={"x": X})


@pytest.mark.parametrize(("text", "expected"), [
    ("always[0, 1] x > 0", [-2.0, -2.0, 0.5, 0.5, -1.0, -1.0]),
    # 2.5 - 1.0 and 2.6 - 1.1 (= 1.5000000000000002 in binary) both sit on the bound 1.5: inside
    ("eventually[0.5, 1.5] x > 0", [3.0, 3.0, 4.0, 4.0, -INF, -INF]),
    # 1.1 - 0.8 = 0.30000000000000004 > 0.3 = t_1: inside within the time resolution
    ("once[0.2, 0.8] x > 0", [-INF, 1.0, -2.0, -2.0, -INF, -INF]),
])
def test_windows_are_measured_in_time_on_non_uniform_samples(text, expected):
    assert rho(text, SPARSE) == expected


JUMP = SignalTrace(times=[0.0, 1.0, 1.0, 2.0], signals={"x": [1.0, -3.0, 5.0, 2.0]},
                   labels={"mode": ("A", "A", "B", "B")})


def test_a_repeated_time_is_a_jump_with_both_sides_as_samples():
    assert JUMP.jumps.tolist() == [0, 0, 1, 1]
    assert rho("jumps >= 1", JUMP) == [-1.0, -1.0, 0.0, 0.0]
    assert rho("time > 0.5", JUMP) == [-0.5, 0.5, 0.5, 1.5]
    # the later side (x = 5) is in always[0, 0] of the earlier side (x = -3), not vice versa
    assert rho("always[0, 0] x > 0", JUMP) == [1.0, -3.0, 5.0, 2.0]
    assert rho("eventually[0, 0] x > 0", JUMP) == [1.0, 5.0, 5.0, 2.0]
    # past operators: the mirror image
    assert rho("historically[0, 0] x > 0", JUMP) == [1.0, -3.0, -3.0, 2.0]
    assert rho("always[0, 1] x > 0", JUMP) == [-3.0, -3.0, 2.0, 2.0]


def test_rise_and_fall_at_a_jump_sit_on_its_later_side():
    assert rho('rise(mode == "B")', JUMP) == [-INF, -INF, INF, -INF]
    assert rho('fall(mode == "A")', JUMP) == [-INF, -INF, INF, -INF]
    f = parse_formula('eventually[0, 2] rise(mode == "B")')
    assert f.satisfied_signal(JUMP).tolist() == [True, True, True, False]
    assert f.explain(JUMP) == Explanation(index=2, time=1.0, atom='(mode == "B")', value=INF,
                                          signals=frozenset({"mode"}), window=(0.0, 2.0))


RAMP = SignalTrace(times=np.arange(11.0), signals={"x": 5.0 - np.abs(np.arange(11.0) - 3.0)})  # peak 5 at t = 3


@pytest.mark.parametrize("text, time, window", [
    ("eventually[0, 9] x >= 6", 3.0, (0.0, 9.0)),          # never reached: the best instant, where x peaks
    ("eventually[2, 20] x >= 6", 3.0, (2.0, 10.0)),        # the window clipped to the trace
    ("not always[0, 9] x <= 5", 3.0, (0.0, 9.0)),          # = eventually x > 5 (the atom negated: its lowest)
    ("(always[0, 9] x < 6) -> false", 3.0, (0.0, 9.0)),    # an implication's antecedent is negated (its lowest)
    ("always[0, 9] x >= 0", 9.0, None),                    # the worst instant: a violation
    ("not eventually[0, 9] x >= 4", 3.0, None),            # = always x < 4: violated most at the peak
    ("always[0, 2] eventually[0, 3] x >= 6", 3.0, (0.0, 3.0)),  # the eventually at the always's worst instant 0
])
def test_explain_says_when_its_instant_is_an_eventuallys_best_one(text, time, window):
    """``x = 5 - |t - 3|``: an ``eventually`` that fails is explained at its best instant, with its window (the
    operand is reached nowhere in it); an ``always`` at its worst instant, without one."""
    why = parse_formula(text).explain(RAMP)
    assert (why.time, why.window) == (time, window)
    rho = parse_formula(text).robustness(RAMP)
    assert abs(why.value) == abs(rho)  # the atom decides the robustness (negated or not on the way)
    if window is not None:  # the closest instant of the window: the atom's best there, or its worst when negated
        a, b = window
        atom = parse_formula(why.atom).robustness_signal(RAMP)[(RAMP.times >= a) & (RAMP.times <= b)]
        assert why.value == (min(atom) if text.startswith(("not", "(")) else max(atom))


def test_label_atoms_use_star_and_question_mark_wildcards_only():
    modes = ("AVOID|CLEAR", "FAR|CLEAR", "AVOID|OCCLUDED", "A[1]", "AB")
    trace = SignalTrace(times=np.arange(5.0), labels={"mode": modes})
    T, F = INF, -INF
    assert rho('mode == "AVOID|*"', trace) == [T, F, T, F, F]
    assert rho('mode == "*|CLEAR"', trace) == [T, T, F, F, F]
    assert rho('mode == "A?"', trace) == [F, F, F, F, T]
    assert rho('mode == "A[1]"', trace) == [F, F, F, T, F]  # brackets are literal
    assert rho('mode != "AVOID|*"', trace) == [F, T, F, T, T]
    assert parse_formula('mode == "AVOID|*"').satisfied_signal(trace).tolist() == [True, False, True, False, False]


@pytest.mark.parametrize(("text", "value", "satisfied"), [
    ("x > 1", 0.0, False), ("x >= 1", 0.0, True), ("x < 1", 0.0, False), ("x <= 1", 0.0, True),
    ("x == 1", 0.0, True), ("x != 1", 0.0, False), ("not x > 1", 0.0, True),
])
def test_the_boolean_semantics_is_strict_at_equality(text, value, satisfied):
    f = parse_formula(text)
    assert f.robustness(UNIFORM) == value and f.satisfied(UNIFORM) is satisfied


# --------------------------------------------------------------------------- satisfied agrees with the sign

atoms = (st.builds(Compare, st.sampled_from(("<", "<=", ">", ">=", "==", "!=")),
                   st.builds(Var, st.sampled_from(("x", "y"))) | st.builds(Func, st.just("prev"),
                                                                             st.tuples(st.builds(Var, st.just("x")))),
                   st.builds(Num, st.sampled_from((0.0, 1.0))) | st.builds(Var, st.just("y"))
                   | st.builds(lambda a: BinOp("-", Var("y"), Neg(a)), st.builds(Num, st.just(0.5))))
         | st.builds(LabelIs, st.just("mode"), st.sampled_from(("==", "!=")), st.sampled_from(("A", "B*", "?")))
         | st.builds(Const, st.booleans()))
bounds = st.tuples(st.sampled_from((0.0, 0.5, 1.0)), st.sampled_from((0.0, 0.5, 1.0, 2.0))).map(
    lambda ab: (ab[0], ab[0] + ab[1]))
trees = st.recursive(
    atoms,
    lambda f: st.builds(Not, f) | st.builds(And, f, f) | st.builds(Or, f, f) | st.builds(Implies, f, f)
    | st.builds(Temporal, st.sampled_from(("always", "eventually")), bounds, f)
    | st.builds(Temporal, st.sampled_from(("historically", "once")), bounds | st.none(), f)
    | st.builds(Until, st.just("until"), bounds, f, f) | st.builds(Until, st.just("since"), bounds | st.none(), f, f)
    | st.builds(Edge, st.sampled_from(("rise", "fall")), f),
    max_leaves=7)


@st.composite
def traces(draw):
    """Small-integer signals (zero robustness is frequent), steps of 0, 0.5 or 1 s (0: a jump)."""
    n = draw(st.integers(1, 12))
    steps = draw(st.lists(st.sampled_from((0.0, 0.5, 1.0)), min_size=n - 1, max_size=n - 1))
    values = st.lists(st.integers(-2, 2).map(float), min_size=n, max_size=n)
    modes = st.lists(st.sampled_from(("A", "B", "BC")), min_size=n, max_size=n)
    return SignalTrace(times=np.concatenate(([0.0], np.cumsum(steps))), signals={"x": draw(values), "y": draw(values)},
                       labels={"mode": tuple(draw(modes))})


@given(trees, traces())
def test_satisfied_agrees_with_the_sign_of_a_nonzero_robustness(tree, trace):
    f = Formula(tree)
    r, s = f.robustness_signal(trace), f.satisfied_signal(trace)
    decided = r != 0
    assert (s[decided] == (r[decided] > 0)).all(), (f.canonical, r, s)
    if r[0] != 0:
        assert f.satisfied(trace) is bool(r[0] > 0)


@given(trees, traces())
def test_the_explained_atom_carries_the_robustness_up_to_sign(tree, trace):
    f = Formula(tree)
    e = f.explain(trace)
    r0 = f.robustness(trace)
    assert abs(e.value) == abs(r0), (f.canonical, e, r0)
    assert 0 <= e.index < trace.n and e.time == trace.times[e.index]


# --------------------------------------------------------------------------- explanations


@pytest.mark.parametrize(("text", "index", "atom", "value"), [
    ("always[0, 5] x > 0", 1, "(x > 0)", -2.0),
    ("x > 0 and y > 1", 0, "(y > 1)", -1.0),
    ("eventually[0, 5] x > 3", 4, "(x > 3)", 1.0),
    ("not always[0, 5] x > 0", 1, "(x > 0)", -2.0),
    ("x > 0 -> y > 5", 0, "(x > 0)", 1.0),  # the premise decides: max(-1, -5)
    ("y > 0 until[0, 2] x > 2", 0, "(y > 0)", 0.0),  # k = 2 would do, but y must hold on [0, 2): y(0) = 0
    # past inside future: sample 5, then its past; g = max(|x| - 1, y - 2) is least at k = 3, by abs(x) > 1
    ("eventually[5, 5] historically[0, 5] (abs(x) > 1 or y > 2)", 3, "(abs(x) > 1)", -0.5),
    ("always[0, 5] rise(x > 0)", 4, "(x > 0)", 4.0),  # rise(5) = min(rho(5), -rho(4)) = min(-1, -4): rho(4)
])
def test_explain_follows_the_arg_min_and_arg_max(text, index, atom, value):
    e = parse_formula(text).explain(UNIFORM)
    assert (e.index, e.atom, e.value, e.time) == (index, atom, value, float(index))


def test_explain_names_the_signals_of_the_atom_and_stops_at_an_empty_window():
    e = parse_formula("always[0, 5] (x - y > -3 and abs(y) < 4)").explain(UNIFORM)
    assert (e.index, e.atom, e.signals) == (1, "((x - y) > (-3))", frozenset({"x", "y"}))
    short = SignalTrace(times=[0.0, 1.0], signals={"x": [1.0, 2.0]})
    e = parse_formula("x > 5 or always[2, 4] x > 0").explain(short)
    assert (e.atom, e.value, e.index, e.signals) == ("(always[2, 4] (x > 0))", INF, 0, frozenset({"x"}))
    assert parse_formula("x > 0").explain(UNIFORM, index=4).index == 4
    with pytest.raises(TraceError, match="index = 6"):
        parse_formula("x > 0").explain(UNIFORM, index=6)


# --------------------------------------------------------------------------- traces and errors


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"times": [0.0, 1.0, 2.0], "signals": {"x": [0.0, math.nan, 1.0]}},
     ["signals['x'] at sample 1 (t = 1 s) = nan", "expected a finite number"]),
    ({"times": [0.0, 0.5, 1.0], "signals": {"x": [0.0, 1.0, -math.inf]}},
     ["signals['x'] at sample 2 (t = 1 s) = -inf"]),
    ({"times": [0.0, math.nan]}, ["times[1] = nan"]),
    ({"times": [0.0, 2.0, 1.0]}, ["times[2] = 1.0", "non-decreasing"]),
    ({"times": []}, ["times.shape = (0,)"]),
    ({"times": [0.0, 1.0], "signals": {"x": [1.0]}}, ["signals['x'].shape = (1,)"]),
    ({"times": [0.0, 1.0], "signals": {"time": [1.0, 2.0]}}, ["signals['time']", "rename the signal"]),
    ({"times": [0.0, 1.0], "signals": {"mode": ["A", "B"]}}, ["signals['mode']", "labels="]),
    ({"times": [0.0, 1.0], "labels": {"mode": ("A", 3)}}, ["labels['mode'] at sample 1 (t = 1 s) = 3"]),
    ({"times": [0.0, 1.0], "labels": {"mode": ("A",)}}, ["len(labels['mode']) = 1"]),
    ({"times": [0.0, 1.0], "labels": {"mode": "AB"}}, ["labels['mode'] = 'str'"]),
    ({"times": [0.0, 1.0], "signals": {"m": [1, 2]}, "labels": {"m": ("A", "B")}}, ["labels = ['m']"]),
    ({"times": [0.0, 1.0, 1.0], "jumps": [0, 1, 1]}, ["jumps[2] at sample 2 (t = 1 s) = 1", "(t, j)"]),
    ({"times": [0.0, 1.0], "jumps": [0.0, 1.0]}, ["jumps = 'float64 array of shape (2,)'"]),
])
def test_ill_formed_traces_are_refused_with_the_place(kwargs, words):
    with pytest.raises(TraceError) as info:
        SignalTrace(**kwargs)
    assert isinstance(info.value, ValueError)
    for word in words:
        assert word in str(info.value), (word, str(info.value))


def test_a_trace_copies_its_arrays_read_only_and_pickles():
    x = np.array([1.0, 2.0])
    trace = SignalTrace(times=[0.0, 1.0], signals={"x": x}, labels={"mode": ["A", "B"]}, jumps=[0, 2])
    x[0] = 99.0
    assert trace.signal("x").tolist() == [1.0, 2.0] and trace.jumps.tolist() == [0, 2]
    with pytest.raises(ValueError):
        trace.signal("x")[0] = 5.0
    with pytest.raises(TypeError):
        trace.signals["y"] = x
    assert (trace.n, trace.names, trace.label_names, trace.label("mode")) == (2, ("x", "time", "jumps"), ("mode",),
                                                                              ("A", "B"))
    again = pickle.loads(pickle.dumps(trace))
    assert again.signal("x").tolist() == [1.0, 2.0] and again.label("mode") == ("A", "B")
    assert again.jumps.tolist() == [0, 2] and again.times.tolist() == [0.0, 1.0]


def test_check_trace_names_the_missing_signals_and_labels_with_the_available_ones():
    with pytest.raises(TraceError) as info:
        parse_formula("always[0, 1] (x > 0 and speed < 1)").robustness(UNIFORM)
    assert "['speed']" in str(info.value) and "signals of the trace: x, y, time, jumps" in str(info.value)
    with pytest.raises(TraceError, match=r"labels of the trace: \(none\)"):
        parse_formula('mode == "A"').satisfied(UNIFORM)
    with pytest.raises(TraceError, match="a SignalTrace"):
        parse_formula("x > 0").check_trace({"x": [1.0]})


def test_a_non_finite_expression_is_refused_not_propagated():
    trace = SignalTrace(times=[0.0, 1.0, 2.0], signals={"x": [1.0, 1.0, 1.0], "y": [1.0, 2.0, 0.0]})
    with pytest.raises(TraceError) as info:
        parse_formula("always[0, 2] x / y > 0").robustness(trace)
    assert "expression (x / y) at sample 2 (t = 2 s) = inf" in str(info.value)


def test_formulas_and_errors_pickle():
    f = parse_formula("always[0, 2] (x > 1 -> eventually[0, 1] y > 0)")
    g = pickle.loads(pickle.dumps(f))
    assert g == f and g.robustness_signal(UNIFORM).tolist() == f.robustness_signal(UNIFORM).tolist()
    e = TraceError("signals['x'] at sample 1", math.nan, "a finite number", "repair it")
    again = pickle.loads(pickle.dumps(e))
    assert type(again) is TraceError and str(again) == str(e)


# --------------------------------------------------------------------------- the window algorithms


@given(st.lists(st.integers(-5, 5).map(float), min_size=1, max_size=40),
       st.lists(st.sampled_from((0.0, 0.1, 0.25, 1.0)), min_size=39, max_size=39),
       st.sampled_from((0.0, 0.1, 0.3)), st.sampled_from((0.0, 0.2, 1.0, 3.0)), st.booleans())
def test_window_reduce_equals_a_brute_force_minimum(values, steps, a, width, past):
    x = np.array(values)
    times = np.concatenate(([0.0], np.cumsum(steps[: x.size - 1])))
    lo, hi = window_bounds(times, (a, a + width), past=past)
    got = window_reduce(x, lo, hi, np.minimum, INF)
    for i in range(x.size):
        gaps = (times[i] - times) if past else (times - times[i])
        side = np.arange(x.size) <= i if past else np.arange(x.size) >= i
        inside = side & (gaps >= a - 1e-9) & (gaps <= a + width + 1e-9)
        assert got[i] == (x[inside].min() if inside.any() else INF)
