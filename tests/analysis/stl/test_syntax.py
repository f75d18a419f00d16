"""analysis.stl.syntax: precedence, associativity, aliases, canonical round trip, and every error message."""

from __future__ import annotations

import math
import pickle

import pytest
from hypothesis import given
from hypothesis import strategies as st

from analysis.stl import Formula, FormulaError, parse_formula
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
    canonical,
    parse_tree,
)


def gt(name: str, value: float = 0.0) -> Compare:
    return Compare(">", Var(name), Num(value))


P, Q, R = gt("p"), gt("q"), gt("r")


# --------------------------------------------------------------------------- precedence and associativity


@pytest.mark.parametrize(("text", "tree"), [
    ("p > 0 or q > 0 and r > 0", Or(P, And(Q, R))),
    ("p > 0 and q > 0 or r > 0", Or(And(P, Q), R)),
    ("p > 0 -> q > 0 -> r > 0", Implies(P, Implies(Q, R))),  # right associative
    ("p > 0 or q > 0 -> r > 0", Implies(Or(P, Q), R)),
    ("p > 0 and q > 0 and r > 0", And(And(P, Q), R)),  # left associative
    ("p > 0 or q > 0 or r > 0", Or(Or(P, Q), R)),
    ("not p > 0 and q > 0", And(Not(P), Q)),
    ("not not p > 0", Not(Not(P))),
    ("always[0, 1] p > 0 and q > 0", And(Temporal("always", (0.0, 1.0), P), Q)),
    ("always[0, 1] not p > 0", Temporal("always", (0.0, 1.0), Not(P))),
    ("not p > 0 until[0, 1] q > 0", Not(Until("until", (0.0, 1.0), P, Q))),  # until binds tighter than not
    ("always[0, 1] p > 0 until[0, 2] q > 0", Temporal("always", (0.0, 1.0), Until("until", (0.0, 2.0), P, Q))),
    ("p > 0 and q > 0 until[0, 1] r > 0", And(P, Until("until", (0.0, 1.0), Q, R))),
    ("(p > 0 or q > 0) and r > 0", And(Or(P, Q), R)),
    ("eventually[1, 2] always[0, 3] p > 0",
     Temporal("eventually", (1.0, 2.0), Temporal("always", (0.0, 3.0), P))),
])
def test_precedence_and_associativity_of_the_connectives(text, tree):
    assert parse_tree(text) == tree


@pytest.mark.parametrize(("text", "expr"), [
    ("x + y * 2", BinOp("+", Var("x"), BinOp("*", Var("y"), Num(2.0)))),
    ("x * y + 2", BinOp("+", BinOp("*", Var("x"), Var("y")), Num(2.0))),
    ("x - y - z", BinOp("-", BinOp("-", Var("x"), Var("y")), Var("z"))),
    ("x / y / z", BinOp("/", BinOp("/", Var("x"), Var("y")), Var("z"))),
    ("-x * y", BinOp("*", Neg(Var("x")), Var("y"))),
    ("- -x", Neg(Neg(Var("x")))),
    ("(x + y) * 2", BinOp("*", BinOp("+", Var("x"), Var("y")), Num(2.0))),
    ("abs(x - 1)", Func("abs", (BinOp("-", Var("x"), Num(1.0)),))),
    ("min(x, max(y, 2))", Func("min", (Var("x"), Func("max", (Var("y"), Num(2.0)))))),
    ("prev(prev(x))", Func("prev", (Func("prev", (Var("x"),)),))),
])
def test_arithmetic_precedence(text, expr):
    assert parse_tree(f"{text} > 0") == Compare(">", expr, Num(0.0))


@pytest.mark.parametrize(("alias", "word"), [
    ("G[0, 1] p > 0", "always[0, 1] p > 0"),
    ("F[0, 1] p > 0", "eventually[0, 1] p > 0"),
    ("H[0, 1] p > 0", "historically[0, 1] p > 0"),
    ("O[0, 1] p > 0", "once[0, 1] p > 0"),
    ("H (p > 0)", "historically p > 0"),
    ("p > 0 U[0, 1] q > 0", "p > 0 until[0, 1] q > 0"),
    ("p > 0 S[0, 1] q > 0", "p > 0 since[0, 1] q > 0"),
    ("p > 0 S q > 0", "p > 0 since q > 0"),
    ("p > 0 & q > 0 | !r > 0", "p > 0 and q > 0 or not r > 0"),
    ("p > 0 -> q > 0", "p > 0 implies q > 0"),
    ("always[0:1.5] p > 0", "always[0, 1.5] p > 0"),
    ("always[2e-3, 1E+1] p > 0", "always[0.002, 10] p > 0"),
    ("always[.5, 1.] p > 0", "always[0.5, 1] p > 0"),
    ("always[0, 1] # a comment\n  (p > 0)  # another\n", "always[0, 1] p > 0"),
])
def test_aliases_and_spellings(alias, word):
    assert parse_tree(alias) == parse_tree(word)


def test_aliases_and_function_names_stay_usable_as_signal_names():
    assert parse_tree("G > 1") == Compare(">", Var("G"), Num(1.0))
    assert parse_tree("U > 0 U[0, 1] S > 0") == Until("until", (0.0, 1.0), gt("U"), gt("S"))
    assert parse_tree("abs + prev > rise") == Compare(">", BinOp("+", Var("abs"), Var("prev")), Var("rise"))
    assert parse_tree("robot.x_1 > 0") == gt("robot.x_1")


def test_chained_comparisons_are_conjunctions():
    mu = Var("mu")
    assert parse_tree("0 <= mu <= 1") == And(Compare("<=", Num(0.0), mu), Compare("<=", mu, Num(1.0)))
    assert parse_tree("0 < mu < 1 < nu") == And(And(Compare("<", Num(0.0), mu), Compare("<", mu, Num(1.0))),
                                                Compare("<", Num(1.0), Var("nu")))


def test_label_atoms_constants_and_edges():
    assert parse_tree('mode == "AVOID|*"') == LabelIs("mode", "==", "AVOID|*")
    assert parse_tree("'A?' != mode") == LabelIs("mode", "!=", "A?")
    assert parse_tree("true and not false") == And(Const(True), Not(Const(False)))
    assert parse_tree("rise(mode == 'B') or fall(x > 1)") == Or(Edge("rise", LabelIs("mode", "==", "B")),
                                                                Edge("fall", gt("x", 1.0)))


# --------------------------------------------------------------------------- canonical round trip

NAMES = ("x", "y", "mu_coll", "robot.v", "G", "U", "S", "abs", "prev", "rise")
numbers = st.floats(min_value=0.0, max_value=1e300, allow_nan=False, allow_infinity=False) | st.sampled_from(
    (0.0, 1.0, 0.1, 2e-3, 1e16, 5e-324, 12345678901234567.0))
expressions = st.recursive(
    st.builds(Num, numbers) | st.builds(Var, st.sampled_from(NAMES)),
    lambda e: st.builds(Neg, e) | st.builds(BinOp, st.sampled_from("+-*/"), e, e)
    | st.builds(lambda a: Func("abs", (a,)), e) | st.builds(lambda a: Func("prev", (a,)), e)
    | st.builds(lambda a, b: Func("min", (a, b)), e, e) | st.builds(lambda a, b: Func("max", (a, b)), e, e),
    max_leaves=6)


@st.composite
def intervals(draw, optional=False):
    if optional and draw(st.booleans()):
        return None
    a = draw(st.floats(min_value=0.0, max_value=1e6, allow_nan=False))
    return (a, a + draw(st.floats(min_value=0.0, max_value=1e6, allow_nan=False)))


patterns = st.text(st.sampled_from("AVOID|*?_ -'[]"), max_size=8)
atoms = (st.builds(Compare, st.sampled_from(("<", "<=", ">", ">=", "==", "!=")), expressions, expressions)
         | st.builds(LabelIs, st.sampled_from(("mode", "phase")), st.sampled_from(("==", "!=")), patterns)
         | st.builds(Const, st.booleans()))
trees = st.recursive(
    atoms,
    lambda f: st.builds(Not, f) | st.builds(And, f, f) | st.builds(Or, f, f) | st.builds(Implies, f, f)
    | st.builds(Temporal, st.sampled_from(("always", "eventually")), intervals(), f)
    | st.builds(Temporal, st.sampled_from(("historically", "once")), intervals(optional=True), f)
    | st.builds(Until, st.just("until"), intervals(), f, f)
    | st.builds(Until, st.just("since"), intervals(optional=True), f, f)
    | st.builds(Edge, st.sampled_from(("rise", "fall")), f),
    max_leaves=8)


@given(trees)
def test_canonical_text_parses_back_to_an_equal_tree(tree):
    text = canonical(tree)
    assert parse_tree(text) == tree
    formula = parse_formula(text)
    assert formula == Formula(tree) and formula.canonical == text
    assert pickle.loads(pickle.dumps(formula)) == formula


@pytest.mark.parametrize("text", [
    "G[0, 2] x > 1 -> F[0:1] (y <= -x or mode == 'A*')",
    "0 <= mu <= 1 and not rise(z == 2) U[0.5, 1] abs(prev(x)) >= min(y, 3)",
    "H[0, 2] x > 0 S y > 1e-3",
])
def test_canonical_of_written_formulas_round_trips(text):
    f = parse_formula(text)
    g = parse_formula(f.canonical)
    assert g == f and hash(g) == hash(f) and g.text != f.text and g.canonical == f.canonical


def test_formulas_are_immutable_hashable_and_picklable():
    f = parse_formula("always[0, 2] (x > 1 and mode == 'A')")
    with pytest.raises(AttributeError):
        f.text = "other"
    assert {f: 1}[parse_formula("G[0,2] (x > 1 & mode == \"A\")")] == 1
    g = pickle.loads(pickle.dumps(f))
    assert g == f and g.text == f.text and g.signals == {"x"} and g.labels == {"mode"}


@pytest.mark.parametrize(("text", "signals", "labels", "future", "past"), [
    ("x > 0", {"x"}, set(), 0.0, 0.0),
    ("always[0, 2] eventually[1, 3] x > y", {"x", "y"}, set(), 5.0, 0.0),
    ("always[0, 2] x > 0 and eventually[0, 7] y > 0", {"x", "y"}, set(), 7.0, 0.0),
    ("(always[0, 4] x > 0) until[1, 2] (eventually[0, 1] z > 0)", {"x", "z"}, set(), 6.0, 0.0),
    ("always[0, 2] once[0, 3] x > 0", {"x"}, set(), 2.0, 3.0),
    ("historically[1, 2] (x > 0 since[0, 4] mode == 'A')", {"x"}, {"mode"}, 0.0, 6.0),
    ("historically x > 0", {"x"}, set(), 0.0, math.inf),
    ("rise(prev(x) > time) and jumps < 3", {"x", "time", "jumps"}, set(), 0.0, 0.0),
])
def test_static_properties(text, signals, labels, future, past):
    f = parse_formula(text)
    assert (f.signals, f.labels, f.horizon, f.past_horizon) == (signals, labels, future, past)


# --------------------------------------------------------------------------- errors

KNOWN = ["x", "y", "mu_coll", "mu_occ", "clearance_m"]
MODES = {"mode": ["FAR|CLEAR", "AVOID|CLEAR", "AVOID|OCCLUDED"]}


def error(text: str, **kwargs) -> FormulaError:
    with pytest.raises(FormulaError) as info:
        parse_formula(text, **kwargs)
    return info.value


def test_the_message_shows_line_column_reason_and_a_caret():
    e = error("x > 1 and\n  (y <)")
    assert (e.line, e.column) == (2, 7) and e.text == "x > 1 and\n  (y <)"
    assert str(e) == (f"formula error at line 2, column 7: {e.reason}\n"
                      "    (y <)\n"
                      "        ^")
    assert "expected an operand" in e.reason and isinstance(e, ValueError)
    again = pickle.loads(pickle.dumps(e))
    assert (type(again), str(again), again.line, again.column) == (FormulaError, str(e), 2, 7)


@pytest.mark.parametrize(("text", "column", "words"), [
    ("mu_col > 0", 1, ["unknown signal 'mu_col'", "did you mean 'mu_coll'", "known signals: clearance_m, jumps, "
                                                                              "mu_coll, mu_occ, time, x, y"]),
    ("x > 0 and abs(clearence_m) < 1", 15, ["unknown signal 'clearence_m'", "did you mean 'clearance_m'"]),
    ("qqq > 0", 1, ["unknown signal 'qqq'; known signals:"]),
    ('mdoe == "FAR|CLEAR"', 1, ["unknown label 'mdoe'", "did you mean 'mode'", "known labels: mode"]),
    ('mode == "AVODI|CLEAR"', 9, ['label pattern "AVODI|CLEAR" matches no value of label \'mode\'',
                                  'did you mean "AVOID|CLEAR"',
                                  "known values: AVOID|CLEAR, AVOID|OCCLUDED, FAR|CLEAR"]),
    ('mode == "LEAVE|*"', 9, ['label pattern "LEAVE|*" matches no value']),
    ("mode > 1", 1, ["'mode' is a label (string-valued)", 'mode == "NAME"']),
    ("x == 'A'", 1, ["'x' is a numeric signal, not a label"]),
])
def test_unknown_signals_labels_and_label_values(text, column, words):
    e = error(text, signals=KNOWN, labels=MODES)
    assert (e.line, e.column) == (1, column), str(e)
    for word in words:
        assert word in e.reason, (word, e.reason)


def test_known_names_and_wildcards_are_accepted():
    f = parse_formula('mode == "AVOID|*" -> mu_coll >= 0 and time < 10 and jumps <= 2', signals=KNOWN, labels=MODES)
    assert f.signals == {"mu_coll", "time", "jumps"}
    parse_formula('mode != "?AR|CLEAR"', labels=MODES)  # a label check without a signal list


@pytest.mark.parametrize(("text", "column", "words"), [
    ("always[3, 1] x > 0", 7, ["reversed interval [3, 1] of always", "write [1, 3]"]),
    ("eventually[-1, 2] x > 0", 12, ["interval [-1, 2] of eventually starts before 0"]),
    ("always (x > 0)", 8, ["always needs a bounded interval, e.g. always[0, 1.5]"]),
    ("x > 0 and\n  F(x > 1)", 4, ["F needs a bounded interval"]),
    ("x > 0 until y > 0", 13, ["until needs a bounded interval"]),
    ("always[0, inf] x > 0", 11, ["expected a number as a bound", "finite numbers of seconds"]),
    ("always[0 1] x > 0", 10, ["expected ',' or ':' between the interval bounds"]),
    ("always[0; 1] x > 0", 9, ["unexpected character ';'"]),
    ("always[0, 1 x > 0", 13, ["expected ']' closing the interval"]),
])
def test_interval_errors_point_at_the_interval(text, column, words):
    e = error(text)
    assert e.column == column, str(e)
    for word in words:
        assert word in e.reason, (word, e.reason)


def test_the_horizon_refuses_a_longer_window_and_accepts_a_sum_with_rounding():
    e = error("x > 0 and always[0, 5] eventually[0, 3] x > 0", horizon=6.0)
    assert e.column == 17 and "look 8 s ahead, more than the horizon 6 s" in e.reason
    e = error("(x > 0) until[0, 7] y > 0", horizon=6.0)
    assert e.column == 14 and "7 s ahead" in e.reason
    assert parse_formula("always[0, 0.1] eventually[0, 0.2] x > 0", horizon=0.3).horizon == pytest.approx(0.3)
    assert parse_formula("historically[0, 100] x > 0", horizon=0.0).past_horizon == 100.0  # the past is not bounded


@pytest.mark.parametrize(("text", "line", "column", "words"), [
    ("", 1, 1, ["empty formula"]),
    ("   # only a comment\n", 1, 1, ["empty formula"]),
    ("mode == \"AVOID", 1, 9, ["unterminated string"]),
    ("x > 1 1", 1, 7, ["unexpected '1' after a complete formula"]),
    ("x > 0 )", 1, 7, ["unexpected ')' after a complete formula"]),
    ("(x > 1", 1, 7, ["expected ')' closing the '(' at column 1, found the end of the formula"]),
    ("x >", 1, 4, ["unexpected end of the formula: expected an operand"]),
    ("x + 1", 1, 6, ["expected a comparison (<, <=, >, >=, ==, !=) after the expression (x + 1)"]),
    ("x = 1", 1, 3, ["write == for equality"]),
    ("x > 1 @ 2", 1, 7, ["unexpected character '@'"]),
    ("not x", 1, 5, ["expected a formula as the operand of not, found the expression x"]),
    ("(x > 1) + 2 > 0", 1, 1, ["expected an arithmetic expression as an operand of +, found the formula (x > 1)"]),
    ("(x > 1) > 0", 1, 1, ["cannot compare the formula (x > 1)"]),
    ("x > 0 until[0, 1] not y > 0", 1, 19, ["unexpected 'not'", "parentheses"]),
    ("x > 0 U[0, 1] y > 0 U[0, 1] z > 0", 1, 21, ["until and since do not chain; parenthesise"]),
    ("mode < 'A'", 1, 6, ["labels are compared with == or != only"]),
    ("'A' == 'B'", 1, 8, ["two strings compared"]),
    ("mode == 'A' == 'B'", 1, 13, ["a label atom does not chain"]),
    ("x + 1 == 'A'", 1, 1, ["a string is compared with a label name only"]),
    ("mode == 'A' and mode > 0", 1, 17, ["'mode' is used both as a numeric signal and as a label"]),
    ("abs(x, y) > 0", 1, 1, ["abs() takes 1 argument, 2 given"]),
    ("min(x) > 0", 1, 1, ["min() takes 2 arguments, 1 given"]),
    ("abs(x > 0) > 1", 1, 5, ["expected an arithmetic expression as an argument of abs(), found the formula"]),
    ("x > 1e999", 1, 5, ["number 1e999 is not finite"]),
    ("x > 0 and", 1, 10, ["unexpected end of the formula"]),
    ("'A'", 1, 1, ["a string stands only in a label atom"]),
    ("x > and", 1, 5, ["unexpected 'and': an operand is expected here"]),
])
def test_syntax_errors(text, line, column, words):
    e = error(text)
    assert (e.line, e.column) == (line, column), str(e)
    for word in words:
        assert word in e.reason, (word, e.reason)
    shown = str(e).split("\n")
    assert shown[0].startswith(f"formula error at line {line}, column {column}: ")
    assert shown[2] == "  " + " " * (column - 1) + "^"


def test_a_non_string_formula_and_a_bad_horizon_are_refused():
    assert "a formula is a str" in error(42).reason
    assert "horizon = -1.0" in error("x > 0", horizon=-1.0).reason


@pytest.mark.parametrize("text", ["(" * 5000 + "x > 0" + ")" * 5000, "x" + " + x" * 20000 + " > 0",
                                  "always[0, 1] (" * 300 + "x > 0" + ")" * 300])
def test_a_formula_nested_too_deeply_is_a_formula_error_not_a_recursion_error(text):
    with pytest.raises(FormulaError, match="nests too deeply"):
        parse_formula(text, signals=["x"])


def test_a_formula_at_the_depth_limit_still_parses_and_evaluates():
    import numpy as np

    from analysis.stl import SignalTrace

    f = parse_formula("x" + " + x" * 190 + " > 0", signals=["x"])
    trace = SignalTrace(times=np.arange(3.0), signals={"x": np.ones(3)})
    assert f.robustness(trace) == 191.0
