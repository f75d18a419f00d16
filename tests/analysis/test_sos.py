"""analysis.sos: Gram-matrix SOS programs on textbook systems, re-proven by analysis.sublevel."""

from __future__ import annotations

import math
from fractions import Fraction

import cvxpy as cp
import numpy as np
import pytest
import scipy.linalg as la
from scipy.integrate import solve_ivp

from analysis.polynomial import Atom, Polynomial
from analysis.sos import (
    SemialgebraicSet,
    SosError,
    SosPoly,
    SosProgram,
    bounding_region,
    invariant_region,
    monomial_basis,
    region_of_attraction,
    round_polynomial,
    sos_lyapunov,
    to_polynomial,
)
from analysis.sublevel import bound_on_sublevel, certify_sublevel, lie_derivative, recheck_sublevel
from hybrid.errors import ParameterError

XY = ("x", "y")
X, Y = SosPoly.variable("x", XY), SosPoly.variable("y", XY)
PX, PY = Polynomial.atom("x"), Polynomial.atom("y")

# The cascade x' = -x + y^2, y' = -y is globally asymptotically stable, but no quadratic V works: the
# cubic term x y^2 of dV/dt cannot be dominated (along x = y^2/2, dV/dt ~ a y^4/2 > 0 for V = a x^2 + b y^2
# + 2h x y).  The quartic V = x^2 + y^2 + y^4/4 gives dV/dt = -2y^2 - (x sqrt2 - y^2/sqrt2)^2 - y^4/2.
CASCADE = {"x": -X + Y * Y, "y": -Y}
CASCADE_EXACT = {"x": -PX + PY * PY, "y": -PY}


def test_degree_two_is_too_low_for_the_cascade_and_says_so():
    result = sos_lyapunov(CASCADE, degree=2)
    assert not result.found and result.status == "infeasible"
    assert result.lyapunov is None
    assert "degree too low to certify" in result.message and "try degree 4" in result.message


def test_degree_four_works_for_the_cascade_and_the_interval_recheck_proves_it():
    result = sos_lyapunov(CASCADE, degree=4)
    assert result.found and result.status in ("solved", "inaccurate")
    v = result.lyapunov
    assert all(isinstance(c, Fraction) and (c.denominator & (c.denominator - 1)) == 0 for c in v.terms.values())
    rate = lie_derivative(v, CASCADE_EXACT)
    box = {"x": (-2.0, 2.0), "y": (-2.0, 2.0)}
    # a sublevel set inside the box: its level below the smallest V on the box's faces
    level = 0.9 * min(v.evaluate_at({"x": a, "y": b}) for a in np.linspace(-2, 2, 81) for b in (-2.0, 2.0))
    level = min(level, 0.9 * min(v.evaluate_at({"x": a, "y": b}) for b in np.linspace(-2, 2, 81) for a in (-2.0, 2.0)))
    cert = certify_sublevel(v, rate, box, rho_out=level, rho_in=0.01 * level)
    assert cert.certified, cert.status
    assert recheck_sublevel(v, rate, cert) == ()


def test_parrilo_example_quadratic_lyapunov_function():
    # Parrilo's thesis: x' = -x - 2y^2, y' = -y - xy - 2y^3; V = x^2 + 2y^2 gives dV/dt = -2x^2 - 4y^2 - 8y^4.
    rates = {"x": -X - 2 * Y * Y, "y": -Y - X * Y - 2 * Y**3}
    result = sos_lyapunov(rates, degree=2)
    assert result.found
    v = result.lyapunov
    rate = lie_derivative(v, {"x": -PX - 2 * PY * PY, "y": -PY - PX * PY - 2 * PY**3})
    rng = np.random.default_rng(0)
    for x, y in rng.uniform(-3, 3, size=(200, 2)):
        point = {"x": float(x), "y": float(y)}
        assert v.evaluate_at(point) > 0.0 and rate.evaluate_at(point) < 0.0


def _van_der_pol_reversed():
    """x' = -y, y' = x + (x^2 - 1) y: stable origin, region of attraction bounded by the limit cycle."""
    rates = {"x": -Y, "y": X + (X * X - 1) * Y}
    a = np.array([[0.0, -1.0], [1.0, -1.0]])
    p = la.solve_continuous_lyapunov(a.T, -np.eye(2))
    v = SosPoly.from_terms(XY, {(2, 0): p[0, 0], (1, 1): 2 * p[0, 1], (0, 2): p[1, 1]})
    return rates, v


def test_van_der_pol_region_of_attraction_is_certified_and_inside_the_true_one():
    rates, v = _van_der_pol_reversed()
    roa = region_of_attraction(rates, v, multiplier_degree=2)
    assert roa.found and 2.0 < roa.rho < 2.6  # Drake's example finds about 2.3 for this V
    exact = to_polynomial(v)
    rate = lie_derivative(exact, {"x": -PY, "y": PX + (PX * PX - 1) * PY})
    level = 0.99 * roa.rho
    cert = certify_sublevel(exact, rate, {"x": (-3.0, 3.0), "y": (-3.0, 3.0)}, rho_out=level, rho_in=0.01)
    assert cert.certified and cert.entry_time_bound is not None
    # boundary points of {V = level} converge to the origin along the true (reversed-time) flow
    w, q = np.linalg.eigh(np.array([[float(exact.terms.get(((Atom.var("x"), 2),), 0)),
                                     float(exact.terms.get(((Atom.var("x"), 1), (Atom.var("y"), 1)), 0)) / 2],
                                    [float(exact.terms.get(((Atom.var("x"), 1), (Atom.var("y"), 1)), 0)) / 2,
                                     float(exact.terms.get(((Atom.var("y"), 2),), 0))]]))
    for theta in np.linspace(0, 2 * math.pi, 12, endpoint=False):
        z = q @ (np.array([math.cos(theta), math.sin(theta)]) * np.sqrt(level / w))
        sol = solve_ivp(lambda _t, s: [-s[1], s[0] + (s[0] ** 2 - 1) * s[1]], (0, 40), z, rtol=1e-9, atol=1e-12)
        assert np.hypot(*sol.y[:, -1]) < 1e-3
    # and just beyond the limit cycle the level set is refuted: a point of the annulus with dV/dt > 0
    refuted = certify_sublevel(exact, rate, {"x": (-4.0, 4.0), "y": (-4.0, 4.0)}, rho_out=1.3 * roa.rho, rho_in=0.01)
    assert refuted.status == "counterexample" and not refuted.certified


def test_invariant_region_in_a_box_is_inside_and_certified():
    # x' = -x + x^3 (stable for |x| < 1) with a stable y' = -y: largest region inside the box |x|, |y| <= 0.9
    rates = {"x": -X + X**3, "y": -Y}
    box = {"x": (-0.9, 0.9), "y": (-0.9, 0.9)}
    result = invariant_region(rates, degree=4, box=box, epsilon=1e-3)
    assert result.lyapunov.found, result.lyapunov.message
    v = result.lyapunov.lyapunov
    rate = lie_derivative(v, {"x": -PX + PX**3, "y": -PY})
    cert = certify_sublevel(v, rate, box, rho_out=1.0, rho_in=0.01)
    assert cert.certified, cert.status
    assert recheck_sublevel(v, rate, cert) == ()
    assert v.evaluate_at({"x": 0.5, "y": 0.5}) <= 1.0  # a good part of the box


def test_bounding_region_through_a_point_bounds_the_solution():
    rates = {"x": -X + Y, "y": -X - Y}
    point = {"x": 0.5, "y": 0.0}
    result = bounding_region(rates, points=[point], targets=[X * X * 4.0], degree=2, epsilon=1e-3,
                             regularisation=1e-4)
    assert result.lyapunov.found and result.gamma is not None and result.gamma > 0
    v = result.lyapunov.lyapunov
    rate = lie_derivative(v, {"x": -PX + PY, "y": -PX - PY})
    level = bound_on_sublevel(v, {"x": (0.5, 0.5), "y": (0.0, 0.0)}).bound
    cert = certify_sublevel(v, rate, {"x": (-2.0, 2.0), "y": (-2.0, 2.0)}, rho_out=level, rho_in=0.5 * level)
    assert cert.certified
    bound = bound_on_sublevel(PX, {"x": (-2.0, 2.0), "y": (-2.0, 2.0)}, sets=[(v, level)], absolute=True)
    sol = solve_ivp(lambda _t, s: [-s[0] + s[1], -s[0] - s[1]], (0, 20), [0.5, 0.0], max_step=0.01)
    assert 0.5 <= np.abs(sol.y[0]).max() <= bound.bound <= 0.5 * (1 + 1e-2)  # the x-extent is tight here


def test_equality_multipliers_certify_trigonometric_nonnegativity():
    # 1 - c >= s^2/2 on the circle s^2 + c^2 = 1 (i.e. 1 - cos >= sin^2/2); false off the circle
    names = ("s", "c")
    s, c = SosPoly.variable("s", names), SosPoly.variable("c", names)
    program = SosProgram(names)
    program.add_nonnegative(1 - c - 0.5 * s * s, on=SemialgebraicSet(equalities=(s * s + c * c - 1,)), degree=2)
    assert program.solve().ok
    program = SosProgram(names)
    program.add_nonnegative(1 - c - 0.5 * s * s, degree=2)
    assert program.solve().status == "infeasible"


def test_polynomial_arithmetic_and_rounding():
    p = (X + 2 * Y) ** 2 - 3
    assert p.terms() == {(2, 0): 1.0, (1, 1): 4.0, (0, 2): 4.0, (0, 0): -3.0}
    assert p.derivative("x").terms() == {(1, 0): 2.0, (0, 1): 4.0}
    assert p.evaluate({"x": 1.0, "y": 1.0}) == 6.0
    assert monomial_basis(XY, 2, min_degree=1) == ((1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
    assert monomial_basis(("s", "c"), 2, max_exponents={"c": 1}) == ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1))
    rounded = round_polynomial(SosPoly.from_terms(XY, {(1, 0): 1 / 3, (0, 1): 1e-12}), bits=20)
    assert rounded == {(1, 0): Fraction(round((1 / 3) * 2**21), 2**21)}  # 2**-1 > 1/3: quantum 2**(-1-20)
    q = to_polynomial({(1, 0): Fraction(1, 2), (0, 1): Fraction(1)}, ("s", "c"),
                      atoms={"s": Atom.sin("a"), "c": Atom.cos("a")})
    assert str(q) == "0.5*sin(a) + cos(a)"
    unknown = SosProgram(XY).free_polynomial(monomial_basis(XY, 1))
    with pytest.raises(SosError, match="product of unknowns is not affine"):
        _ = unknown * unknown


@pytest.mark.parametrize(("call", "parameter"), [
    (lambda: sos_lyapunov(CASCADE, degree=1), "degree"),
    (lambda: sos_lyapunov(CASCADE, degree=3), "degree"),
    (lambda: sos_lyapunov(CASCADE, degree=4, lyapunov_variables=("z",)), "lyapunov_variables"),
    (lambda: SosPoly.from_terms(XY, {(1, 0): math.nan}), "coefficients"),
    (lambda: sos_lyapunov({"x": -X + 1.0, "y": -Y}, degree=2), "rates"),
    (lambda: invariant_region(CASCADE, degree=4, box={"x": (1.0, 1.0), "y": (-1.0, 1.0)}), "box['x']"),
    (lambda: invariant_region(CASCADE, degree=4, box={"x": (1.0, -1.0), "y": (-1.0, 1.0)}), "box['x']"),
    (lambda: invariant_region(CASCADE, degree=4, box={"z": (-1.0, 1.0)}), "box"),
    (lambda: sos_lyapunov(CASCADE, degree=2, epsilon=-1.0), "epsilon"),
])
def test_bad_inputs_name_parameter_value_expectation_and_fix(call, parameter):
    with pytest.raises(SosError) as info:
        call()
    err = info.value
    assert isinstance(err, ParameterError)
    assert err.parameter == parameter and err.expected and err.fix
    assert "expected" in str(err) and "fix:" in str(err)


def test_solver_failure_is_a_status_not_a_traceback(monkeypatch):
    def broken(self, *args, **kwargs):
        raise cp.error.SolverError("simulated failure")

    monkeypatch.setattr(cp.Problem, "solve", broken)
    result = sos_lyapunov(CASCADE, degree=4)
    assert not result.found and result.status == "solver_error"
    assert "solver failed" in result.message and "try degree 6" in result.message
