"""Tests of analysis.polynomial: exact normal forms of CasADi expressions, arithmetic, errors."""

from __future__ import annotations

import math
from fractions import Fraction

import casadi as ca
import pytest
from hypothesis import given
from hypothesis import strategies as st

from analysis.polynomial import (
    Atom,
    InvalidVariables,
    Polynomial,
    PolynomialError,
    UnsupportedExpression,
    normal_form,
)

DELTA, ALPHA = Atom.var("delta"), Atom.var("alpha")
SIN_A, COS_A = Atom.sin("alpha"), Atom.cos("alpha")


def path_following_vdot(k: float, v: float):
    """V̇ = ∇V · f for δ̇ = v sin α, α̇ = -v (k δ + α + 2k sin α), V = k δ²/2 + 1 - cos α."""
    delta, alpha = ca.SX.sym("delta"), ca.SX.sym("alpha")
    state = ca.vertcat(delta, alpha)
    flow = ca.vertcat(v * ca.sin(alpha), -v * (k * delta + alpha + 2 * k * ca.sin(alpha)))
    lyapunov = k * delta**2 / 2 + (1 - ca.cos(alpha))
    return ca.dot(ca.gradient(lyapunov, state), flow), delta, alpha


@pytest.mark.parametrize("k, v", [(4.0, 0.1), (0.7, 0.3), (2.5, 0.05)])
def test_path_following_vdot_has_no_delta_term_and_is_exact(k, v):
    expr, delta, alpha = path_following_vdot(k, v)
    poly = normal_form(expr, [delta, alpha])
    assert not poly.depends_on("delta")
    assert not poly.depends_on(DELTA)
    assert poly.degree_in(DELTA) == 0
    a, s = Polynomial.atom(ALPHA), Polynomial.atom(SIN_A)
    expected = -Fraction(v) * a * s - 2 * Fraction(k) * Fraction(v) * s**2
    assert poly == expected
    assert poly.atoms == (ALPHA, SIN_A)
    assert poly.variables == ("alpha",)
    assert poly.degree_in(SIN_A) == 2
    assert poly.coefficient_of(SIN_A, 2) == Polynomial.constant(-2 * Fraction(k) * Fraction(v))
    assert poly.coefficient_of(SIN_A, 1) == -Fraction(v) * a


def test_path_following_vdot_str():
    expr, delta, alpha = path_following_vdot(4.0, 0.1)
    assert str(normal_form(expr, [delta, alpha])) == "-0.1*alpha*sin(alpha) - 0.8*sin(alpha)^2"


def test_float_constants_are_taken_at_their_exact_binary_value():
    x = ca.SX.sym("x")
    poly = normal_form(0.1 * x + 1.0 / 3.0, [x])
    assert poly.terms[((Atom.var("x"), 1),)] == Fraction(0.1)
    assert poly.constant_term == Fraction(1.0 / 3.0) != Fraction(1, 3)
    assert normal_form(x / 0.1, [x]).terms[((Atom.var("x"), 1),)] == 1 / Fraction(0.1)


def test_trig_of_negated_variable_and_constants():
    x = ca.SX.sym("x")
    assert normal_form(ca.sin(-x), [x]) == -Polynomial.atom(Atom.sin("x"))
    assert normal_form(ca.cos(-x), [x]) == Polynomial.atom(Atom.cos("x"))
    assert normal_form(ca.SX(2.5), [x]) == Polynomial.constant(2.5)
    assert normal_form(3.0, [x]) == Polynomial.constant(3)
    assert normal_form(ca.SX(1, 1), [x]).is_zero  # structural zero: no output instruction
    assert normal_form(x - x, [x]).is_zero


def test_powers_and_squares_expand_exactly():
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    poly = normal_form((x + 2 * y) ** 3 + ca.constpow(x, 2) + x**0, [x, y])
    px, py = Polynomial.atom("x"), Polynomial.atom("y")
    assert poly == (px + 2 * py) ** 3 + px**2 + 1
    assert poly.degree_in("y") == 3
    assert normal_form(x ** ca.SX(2), [x]) == px**2  # symbolic constant exponent


def test_variables_may_be_given_as_one_sx_vector():
    x = ca.SX.sym("x", 2)
    poly = normal_form(x[0] * x[1], x)
    assert poly.variables == ("x_0", "x_1")


# --------------------------------------------------------------------------- random expressions


@st.composite
def expressions(draw, depth=3):
    x, y = SYMBOLS
    if depth == 0 or draw(st.integers(0, 3)) == 0:
        leaf = draw(st.integers(0, 6))
        if leaf == 0:
            return ca.SX(draw(st.floats(-3.0, 3.0, allow_nan=False)))
        return (x, y, ca.sin(x), ca.cos(y), ca.sin(-y), ca.cos(x))[leaf - 1]
    op = draw(st.sampled_from(["+", "-", "*", "pow", "div", "neg", "sq"]))
    a = draw(expressions(depth=depth - 1))
    if op == "neg":
        return -a
    if op == "sq":
        return a * a
    if op == "pow":
        return a ** draw(st.integers(0, 3))
    if op == "div":
        return a / draw(st.sampled_from([2.0, -3.0, 0.1, 7.5]))
    b = draw(expressions(depth=depth - 1))
    return {"+": a + b, "-": a - b, "*": a * b}[op]


SYMBOLS = (ca.SX.sym("x"), ca.SX.sym("y"))


@given(expressions(), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0))
def test_random_expressions_agree_with_casadi(expr, px, py):
    poly = normal_form(expr, list(SYMBOLS))
    reference = float(ca.Function("f", list(SYMBOLS), [expr])(px, py))
    value = poly.evaluate_at({"x": px, "y": py})
    magnitude = abs(Polynomial({m: abs(c) for m, c in poly.terms.items()}).evaluate(
        {a: abs(v) for a, v in _atom_values(px, py).items()}
    ))
    assert abs(value - reference) <= 1e-12 * (1.0 + magnitude)


def _atom_values(px, py):
    out = {}
    for name, p in (("x", px), ("y", py)):
        out.update({Atom.var(name): p, Atom.sin(name): math.sin(p), Atom.cos(name): math.cos(p)})
    return out


@given(expressions(), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0))
def test_pythagorean_reduction_preserves_values(expr, px, py):
    poly = normal_form(expr, list(SYMBOLS))
    reduced = poly.reduce_pythagorean()
    assert all(dict(m).get(Atom.cos(v), 0) <= 1 for m in reduced.terms for v in ("x", "y"))
    assert reduced.evaluate_at({"x": px, "y": py}) == pytest.approx(
        poly.evaluate_at({"x": px, "y": py}), rel=1e-9, abs=1e-9
    )


def test_pythagorean_reduction_is_canonical():
    x = ca.SX.sym("x")
    s, c = ca.sin(x), ca.cos(x)
    lhs = normal_form(c**4 - s**4, [x]).reduce_pythagorean()  # = cos² - sin² = 1 - 2 sin²
    assert lhs == 1 - 2 * Polynomial.atom(Atom.sin("x")) ** 2
    assert normal_form(c * c * x, [x]) != normal_form(x - x * s * s, [x])  # normal_form alone does not
    assert normal_form(c * c * x, [x]).reduce_pythagorean() == normal_form(x - x * s * s, [x])


# --------------------------------------------------------------------------- polynomial API


def test_polynomial_construction_and_queries():
    p = Polynomial({((ALPHA, 1), (SIN_A, 1)): Fraction(-1, 10), ((SIN_A, 2),): -0.5, (): 0})
    assert p.constant_term == 0
    assert len(p.terms) == 2
    assert p.evaluate({ALPHA: 1.0, SIN_A: 2.0}) == pytest.approx(-0.1 * 2 - 0.5 * 4)
    assert p.evaluate({("var", "alpha"): Fraction(1), ("sin", "alpha"): Fraction(2)}) == Fraction(-11, 5)
    assert p.depends_on("alpha") and p.depends_on(("sin", "alpha")) and not p.depends_on(COS_A)
    assert hash(p) == hash(Polynomial(dict(p.terms)))
    assert str(Polynomial({})) == "0"
    assert str(Polynomial.constant(Fraction(1, 3))) == "(1/3)"
    assert str(2 - Polynomial.atom("x")) == "-x + 2"
    with pytest.raises(TypeError):
        p.terms[()] = 1  # read-only


def test_polynomial_errors():
    p = Polynomial.atom(ALPHA) * Polynomial.atom(SIN_A)
    with pytest.raises(KeyError, match=r"no value for atom sin\(alpha\)"):
        p.evaluate({ALPHA: 1.0})
    with pytest.raises(KeyError, match=r"no value for variable 'alpha'"):
        p.evaluate_at({"delta": 1.0})
    with pytest.raises(PolynomialError, match=r"power of x = 0; expected an integer >= 1"):
        Polynomial({((Atom.var("x"), 0),): 1})
    with pytest.raises(TypeError, match=r"expected a Fraction, int or float"):
        Polynomial({(): "1"})
    with pytest.raises(PolynomialError, match=r"expected a finite number"):
        Polynomial({(): math.inf})
    with pytest.raises(TypeError, match=r"expected an Atom such as"):
        p.degree_in(("tan", "alpha"))
    with pytest.raises(PolynomialError, match=r"exponent n = -1: expected an integer >= 0"):
        p ** -1
    with pytest.raises(PolynomialError, match=r"power = -1: expected an integer >= 0"):
        p.coefficient_of(ALPHA, -1)


# --------------------------------------------------------------------------- unsupported input


@pytest.mark.parametrize("build, operation", [
    (lambda x, y: ca.sqrt(x), "sqrt"),
    (lambda x, y: ca.exp(x), "exp"),
    (lambda x, y: ca.fabs(x), "fabs"),
    (lambda x, y: ca.fmin(x, y), "fmin"),
    (lambda x, y: ca.sin(2 * x), "sin"),
    (lambda x, y: ca.cos(x + y), "cos"),
    (lambda x, y: ca.sin(ca.sin(x)), "sin"),
    (lambda x, y: ca.sin((x + 1) * (x - 1) - x * x), "sin"),  # sin(-1): not a rational value
    (lambda x, y: x / y, "div"),
    (lambda x, y: 1 / x, "inv"),
    (lambda x, y: x**2.5, "constpow"),
    (lambda x, y: x**y, "pow"),
])
def test_unsupported_operations_raise(build, operation):
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    with pytest.raises(UnsupportedExpression, match=rf"operation '{operation}' .* is not supported") as info:
        normal_form(build(x, y), [x, y])
    assert info.value.operation == operation


def test_bad_variables_and_expressions_raise():
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    with pytest.raises(InvalidVariables, match=r"symbols \['y'\] that are not in variables \['x'\]"):
        normal_form(x * y, [x])
    with pytest.raises(InvalidVariables, match=r"expected a scalar casadi.SX symbol"):
        normal_form(x, [2 * x])
    with pytest.raises(InvalidVariables, match=r"distinct name"):
        normal_form(x, [x, ca.SX.sym("x")])
    with pytest.raises(PolynomialError, match=r"expected a scalar \(1, 1\) expression"):
        normal_form(ca.vertcat(x, x), [x])
    with pytest.raises(PolynomialError, match=r"expr is a MX: expected a casadi.SX"):
        normal_form(ca.MX.sym("m"), [x])
    with pytest.raises(PolynomialError, match=r"constant inf .* is not finite"):
        normal_form(x + ca.inf, [x])
