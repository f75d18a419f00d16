"""Exact affine extraction from the expression tree: values as rationals, refusals naming the term."""

from __future__ import annotations

from fractions import Fraction

import pytest

from analysis.reach import AffineError, affine_form, affine_model, condition_polyhedra
from hybrid import HybridAutomaton, MemoryVariable, Mode, Transition
from hybrid.examples import bouncing_ball, thermostat
from hybrid.symbolic import Compare, as_expr, coordinates, cos, flow_map, ite, jump_map, memory, output_map, reset, time
from hybrid.system import HybridSystem

NAMES = ("p", "q")
X = coordinates(*NAMES)


def test_coefficients_are_exact_rationals():
    form = affine_form(0.1 * (X.p + X.q) * 3.0 - X.q / 4.0 + 0.2, NAMES)
    # the float 0.1 times the float 3.0: exact rational products, not the rounded float 0.30000000000000004
    assert form.coefficients == (Fraction(0.1) * 3, Fraction(0.1) * 3 - Fraction(1, 4))
    assert form.constant == Fraction(0.2)


def test_constant_subtrees_fold_exactly():
    form = affine_form((X.p - 2.0) * (3.0 - 1.0) + abs(-2.0 + 0.0 * X.q) * X.q, NAMES)
    assert form.coefficients == (Fraction(2), Fraction(2)) and form.constant == Fraction(-4)


@pytest.mark.parametrize(("expr", "words"), [
    (X.p * X.q, "product of two state-dependent factors"),
    (X.p ** 2, "power 2"),
    (cos(X.p), "cos()"),
    (ite(X.p >= 0.0, X.p, -X.p), "piecewise"),
    (X.p + time(), "reads the time t"),
    (abs(X.p), "abs()"),
])
def test_non_affine_terms_are_refused_by_name(expr, words):
    with pytest.raises(AffineError) as err:
        affine_form(expr, NAMES, role="flow of mode 'm'")
    assert words in str(err.value) and "fix:" in str(err.value)


def test_memory_constant_or_refused():
    m = memory("k")
    assert affine_form(m.k * X.p, NAMES, memory={"k": 2.5}).coefficients == (Fraction(5, 2), Fraction(0))
    with pytest.raises(AffineError, match="which a reset writes"):
        affine_form(m.k * X.p, NAMES, memory={"k": 2.5}, written=frozenset({"k"}))


def test_conditions_become_polyhedra():
    conj = condition_polyhedra((X.p <= 1.0) & (X.q >= -2.0), NAMES)
    assert len(conj) == 1
    rows = {(h.normal, h.offset) for h in conj[0].halfspaces}
    assert rows == {((Fraction(1), Fraction(0)), Fraction(1)), ((Fraction(0), Fraction(-1)), Fraction(2))}
    disj = condition_polyhedra((X.p <= 1.0) | (X.q >= 3.0), NAMES)
    assert len(disj) == 2
    eq = condition_polyhedra(Compare("==", X.p + X.q, as_expr(1.0)), NAMES)  # the level form -|p + q - 1|
    assert {(h.normal, h.offset) for h in eq[0].halfspaces} == {
        ((Fraction(1), Fraction(1)), Fraction(1)), ((Fraction(-1), Fraction(-1)), Fraction(-1))}


def test_reference_models_read_exactly():
    room = affine_model(thermostat().system)
    assert room.modes["off"].a == ((Fraction(-0.1),),) and room.modes["off"].c == (Fraction(0.1) * 10,)
    assert room.modes["on"].c == (Fraction(0.1) * 30,)
    (inv,) = room.modes["off"].invariant
    assert [(h.normal, h.offset) for h in inv.halfspaces] == [((Fraction(-1),), Fraction(-19))]  # T >= 19
    ball = affine_model(bouncing_ball(restitution=0.75).system)
    assert ball.modes["fly"].a == ((0, 1), (0, 0)) and ball.modes["fly"].c == (0, Fraction(-9.81))
    (bounce,) = ball.transitions
    assert bounce.r_matrix == ((1, 0), (0, Fraction(-3, 4))) and bounce.r_offset == (0, 0)
    assert {(h.normal, h.offset) for h in bounce.guard[0].halfspaces} == {((1, 0), 0), ((0, 1), 0)}


def _system(flow, guard=None, jump=None, output=None, variables=NAMES):
    transitions = () if guard is None else (Transition(name="t", source="m", target="m", guard=guard),)
    automaton = HybridAutomaton(name="s", modes=(Mode(name="m"),), transitions=transitions, variables=variables)
    return HybridSystem(automaton=automaton, state_names=NAMES, flows={"m": flow},
                        jumps={} if jump is None else {"t": jump}, output=output)


def test_plain_python_model_refused_with_what_to_write():
    with pytest.raises(AffineError) as err:
        affine_model(_system(lambda t, x, m: (x[1], -9.81)))
    text = str(err.value)
    assert "plain Python function" in text and "flow_map(" in text and "symbolic" in text
    with pytest.raises(AffineError, match="plain Python function"):
        affine_model(_system(flow_map(X.q, -1.0), guard=lambda v, m: -v[0]))
    with pytest.raises(AffineError, match="reachability needs a symbolic model"):
        affine_model("not a system")


def test_output_map_rewrites_guards_over_the_state():
    v = coordinates("s")
    system = _system(flow_map(X.q, -1.0), guard=v.s >= 4.0, jump=jump_map(X.p, -X.q),
                     output=output_map(2.0 * X.p + X.q - 1.0), variables=("s",))
    (t,) = affine_model(system).transitions
    (h,) = t.guard[0].halfspaces  # 2p + q - 1 >= 4  <=>  -2p - q <= -5
    assert h.normal == (Fraction(-2), Fraction(-1)) and h.offset == Fraction(-5)


def test_memory_written_by_a_reset_is_refused():
    m = memory("k")
    automaton = HybridAutomaton(
        name="s", modes=(Mode(name="m"),), variables=NAMES, memory=(MemoryVariable(name="k", initial=1.0),),
        transitions=(Transition(name="t", source="m", target="m", guard=X.p >= 1.0, reset=reset(k=X.q)),))
    system = HybridSystem(automaton=automaton, state_names=NAMES, flows={"m": flow_map(m.k * X.q, 0.0)})
    with pytest.raises(AffineError, match="does not track memory"):
        affine_model(system)
