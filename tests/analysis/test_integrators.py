"""The integrator family of analysis.integrators: orders, exactness on polynomials, references, errors."""

import math

import numpy as np
import pytest

from analysis.bdf import (
    BdfConvergenceError,
    BdfHistoryError,
    BdfOrderError,
    BdfStartupError,
    BdfStepSizeError,
    integrate_bdf,
)
from analysis.integrators import (
    FIXED_STEP_SCHEMES,
    REFERENCE_SCHEMES,
    SCHEME_ORDERS,
    OdeProblem,
    ProblemDefinitionError,
    ReferenceSolverError,
    UnknownSchemeError,
    integrate,
    observed_order,
    pareto_front,
    scheme_order,
    step_count,
)

# A damped rotation: y' = A y, y(0) = (1, 0), exact y(t) = e^{-0.1 t} (cos t, -sin t).
A = np.array([[-0.1, 1.0], [-1.0, -0.1]])


def _exact(t):
    return math.exp(-0.1 * t) * np.array([math.cos(t), -math.sin(t)])


def _rotation(t1=4.0):
    import casadi as ca

    t = ca.MX.sym("t")
    y = ca.MX.sym("y", 2)
    rhs = ca.Function("rhs", [t, y], [ca.mtimes(ca.DM(A), y)])
    return OdeProblem(f=lambda t, y: A @ y, jac=lambda t, y: A, t0=0.0, t1=t1, y0=[1.0, 0.0], casadi_rhs=rhs,
                      name="damped rotation")


def _startup_kwargs(scheme, h):
    needed = 3 if scheme == "abm4" else (SCHEME_ORDERS[scheme] - 1 if scheme.startswith("bdf") else 0)
    if needed == 0:
        return {}
    return {"startup": "exact", "start_values": np.array([_exact(h * j) for j in range(1, needed + 1)])}


# The rotation's eigenvalues -0.1 ± i are oscillatory, where the schemes reach their asymptotic
# order early.  With h = 0.05, 0.025, 0.0125 over 4 s the smallest error (BDF6, h = 0.0125) is
# 1.5e-12, far above round-off (~1e-15).  Measured slopes: euler 1.021, rk4 3.997, abm4 3.940,
# bdf1-6 0.978, 1.980, 2.974, 3.968, 4.963, 5.933: the remaining deviations (at most 0.067) are
# the next term of the error expansion, O(h |λ|), not noise; the tolerance 0.1 is the issue's.
ORDER_STEPS = (0.05, 0.025, 0.0125)


@pytest.mark.parametrize("scheme", FIXED_STEP_SCHEMES)
def test_observed_order_equals_the_classical_order(scheme):
    problem = _rotation()
    errors = []
    for h in ORDER_STEPS:
        result = integrate(problem, scheme, h=h, **_startup_kwargs(scheme, h))
        exact = np.array([_exact(t) for t in result.t])
        errors.append(float(np.abs(result.y - exact).max()))
    assert min(errors) > 1e-13
    assert abs(observed_order(ORDER_STEPS, errors) - SCHEME_ORDERS[scheme]) < 0.1, errors


@pytest.mark.parametrize("scheme, degree", [("euler", 1), ("rk4", 4), ("abm4", 4), *((f"bdf{q}", q) for q in range(1, 7))])
def test_schemes_are_exact_for_polynomial_solutions_of_their_order(scheme, degree):
    # y = t^p with y' = p t^(p-1): a scheme of order p reproduces it up to round-off
    # (the local error is proportional to y^(p+1) = 0).
    problem = OdeProblem(f=lambda t, y: np.array([degree * t ** (degree - 1)]), jac=lambda t, y: np.zeros((1, 1)),
                         t0=0.0, t1=1.0, y0=[0.0])
    h = 0.1
    needed = 3 if scheme == "abm4" else (degree - 1 if scheme.startswith("bdf") else 0)
    kwargs = {"startup": "exact", "start_values": [[(h * j) ** degree] for j in range(1, needed + 1)]} if needed else {}
    result = integrate(problem, scheme, h=h, **kwargs)
    assert np.allclose(result.y[:, 0], result.t ** degree, rtol=0.0, atol=1e-13)


def test_rk4_step_is_the_degree_4_taylor_polynomial_on_the_linear_test_equation():
    problem = OdeProblem(f=lambda t, y: -2.0 * y, t0=0.0, t1=0.3, y0=[1.0])
    z = -2.0 * 0.3
    result = integrate(problem, "rk4", h=0.3)
    assert result.y[-1, 0] == pytest.approx(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24, rel=1e-15)
    assert result.n_rhs == 4


def test_evaluation_counts():
    problem = _rotation(1.0)
    assert integrate(problem, "euler", h=0.1).n_rhs == 10
    assert integrate(problem, "rk4", h=0.1).n_rhs == 40
    # ABM4, exact start: 4 evaluations of the history, then 2 per PECE step for the 7 remaining steps
    assert integrate(problem, "abm4", h=0.1, **_startup_kwargs("abm4", 0.1)).n_rhs == 4 + 2 * 7
    # ABM4, RK4 start-up with 16 substeps: 3 * 16 * 4 more
    assert integrate(problem, "abm4", h=0.1).n_rhs == 3 * 64 + 4 + 2 * 7


def test_bdf_schemes_are_analysis_bdf_integrate_bdf():
    problem = _rotation(2.0)
    direct = integrate_bdf(problem.f, problem.jac, 0.0, [1.0, 0.0], 0.1, 20, 4)
    through = integrate(problem, "bdf4", h=0.1)
    assert np.array_equal(direct.y, through.y)
    assert through.newton_iterations == direct.newton_iterations and through.startup == "rk4"


def test_bdf_without_jacobian_uses_finite_differences():
    problem = _rotation(2.0)
    no_jac = OdeProblem(f=problem.f, t0=0.0, t1=2.0, y0=[1.0, 0.0])
    # The forward-difference Jacobian is exact to ~1e-8 on this linear f; Newton still converges to
    # the same BDF solution (its fixed point does not depend on the Jacobian).
    assert np.allclose(integrate(no_jac, "bdf3", h=0.1).y, integrate(problem, "bdf3", h=0.1).y, atol=1e-11)


@pytest.mark.parametrize("scheme", REFERENCE_SCHEMES)
def test_references_reach_their_tolerance(scheme):
    problem = _rotation()
    result = integrate(problem, scheme, rtol=1e-10, atol=1e-12, h=0.5)
    exact = np.array([_exact(t) for t in result.t])
    assert result.t.size == 9 and result.step is None
    # global error of an adaptive method is a small multiple of its local tolerance
    assert np.abs(result.y - exact).max() < 1e-8
    assert result.n_rhs > 0


def test_results_are_read_only():
    result = integrate(_rotation(1.0), "rk4", h=0.1)
    with pytest.raises(ValueError):
        result.y[0, 0] = 2.0


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("scheme", ["bdf7", "bdf0", "bdf-1"])
def test_bdf_order_outside_1_to_6(scheme):
    with pytest.raises(BdfOrderError, match=rf"scheme '{scheme}': BDF order = .*expected a BDF order in 1\.\.6"):
        integrate(_rotation(1.0), scheme, h=0.1)


def test_unknown_scheme():
    with pytest.raises(UnknownSchemeError, match=r"scheme = 'rk5': expected one of euler, rk4, abm4"):
        integrate(_rotation(1.0), "rk5", h=0.1)
    with pytest.raises(UnknownSchemeError, match="no fixed order"):
        scheme_order("cvodes")


@pytest.mark.parametrize("h, message", [
    (None, r"h = None: a fixed-step scheme needs a step size"),
    (0.0, r"h = 0.0: expected a positive finite step size; pass h > 0"),
    (-0.1, r"h = -0.1: expected a positive finite step size"),
    (math.inf, r"h = inf: expected a positive finite step size"),
    ("x", r"h = 'x': expected a positive finite step size \(a number\)"),
    (0.3, r"h = 0.3 does not divide t1 - t0 = 1.0 \(3.33333 steps\).*choose h = \(t1 - t0\)/n, e.g. h = 0.3333"),
])
def test_bad_step(h, message):
    with pytest.raises(BdfStepSizeError, match=message):
        integrate(_rotation(1.0), "rk4", h=h)


def test_step_count():
    assert step_count(0.0, 1.0, 0.1) == 10
    assert step_count(9.45, 26.8, 0.05) == 347


@pytest.mark.parametrize("scheme, rows, message", [
    ("bdf4", 2, r"start_values has 2 rows but order = 4 needs 3"),
    ("abm4", 2, r"scheme 'abm4' \(4-step history\) needs at least \(3, n\) = \(3, 2\)"),
])
def test_history_shorter_than_the_order(scheme, rows, message):
    with pytest.raises(BdfHistoryError, match=message):
        integrate(_rotation(1.0), scheme, h=0.1, startup="exact", start_values=[[1.0, 0.0]] * rows)


def test_missing_start_values_and_unknown_startup():
    with pytest.raises(BdfHistoryError, match="needs start_values"):
        integrate(_rotation(1.0), "abm4", h=0.1, startup="exact")
    with pytest.raises(BdfStartupError, match=r"startup = 'ramp': expected one of 'rk4', 'exact'"):
        integrate(_rotation(1.0), "bdf2", h=0.1, startup="ramp")


def test_newton_that_does_not_converge_says_after_how_many_iterations_and_with_what_residual():
    problem = OdeProblem(f=lambda t, y: -(y**3), jac=lambda t, y: np.diag(-3 * y**2), t0=0.0, t1=1.0, y0=[2.0])
    with pytest.raises(BdfConvergenceError, match=r"did not converge after 1 iterations \(last update max-norm "
                                                  r"[0-9.e+-]+, residual max-norm [0-9.e+-]+") as info:
        integrate(problem, "bdf1", h=0.5, newton_maxiter=1)
    assert info.value.iterations == 1 and info.value.residual_norm > 0


def test_problem_validation():
    with pytest.raises(ProblemDefinitionError, match=r"expected finite t0 < t1"):
        OdeProblem(f=lambda t, y: y, t0=1.0, t1=1.0, y0=[1.0])
    with pytest.raises(ProblemDefinitionError, match=r"expected a non-empty finite 1-D array"):
        OdeProblem(f=lambda t, y: y, t0=0.0, t1=1.0, y0=[math.nan])
    bad = OdeProblem(f=lambda t, y: np.zeros(3), t0=0.0, t1=1.0, y0=[1.0, 2.0])
    with pytest.raises(ProblemDefinitionError, match=r"OdeProblem.f returned 3 values at t = 0.0: expected 2"):
        integrate(bad, "euler", h=0.5)
    with pytest.raises(ProblemDefinitionError, match=r"scheme 'cvodes' needs OdeProblem.casadi_rhs"):
        integrate(OdeProblem(f=lambda t, y: -y, t0=0.0, t1=1.0, y0=[1.0]), "cvodes")


def test_a_failing_reference_says_which_and_why():
    import casadi as ca

    # y' = y², y(0) = 1 blows up at t = 1: scipy's BDF cannot reach t = 2
    blow_up = OdeProblem(f=lambda t, y: y**2, jac=lambda t, y: np.diag(2 * y), t0=0.0, t1=2.0, y0=[1.0],
                         name="blow-up")
    with pytest.raises(ReferenceSolverError, match=r"scipy_bdf \(solve_ivp method 'BDF'.*failed on blow-up at t = "):
        integrate(blow_up, "scipy_bdf", rtol=1e-8, atol=1e-10)
    # CVODES on a right-hand side that is NaN from the start (log of a negative number)
    t, y = ca.MX.sym("t"), ca.MX.sym("y")
    nan = OdeProblem(f=lambda t, y: np.log(y - 2), t0=0.0, t1=1.0, y0=[1.0],
                     casadi_rhs=ca.Function("rhs", [t, y], [ca.log(y - 2)]), name="nan rhs")
    with pytest.raises(ReferenceSolverError, match=r"cvodes \(rtol=1e-08, atol=1e-10\) failed on nan rhs"):
        integrate(nan, "cvodes", rtol=1e-8, atol=1e-10)


def test_observed_order_and_pareto_front():
    assert observed_order([0.2, 0.1], [4e-4, 1e-4]) == pytest.approx(2.0, abs=1e-12)
    with pytest.raises(ValueError, match="at least two"):
        observed_order([0.1], [1e-3])
    with pytest.raises(ValueError, match="must all be positive"):
        observed_order([0.1, 0.05], [1e-3, 0.0])
    assert pareto_front([3.0, 1.0, 2.0, 2.0], [1e-6, 1e-3, 1e-4, 1e-5]) == (1, 3, 0)
