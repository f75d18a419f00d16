"""Tests of analysis.bdf: exact coefficients, zero-stability, observed orders, errors."""

from __future__ import annotations

import math
from fractions import Fraction as Fr

import numpy as np
import pytest

from analysis.bdf import (
    BdfCoefficients,
    BdfConvergenceError,
    BdfHistoryError,
    BdfOrderError,
    BdfStartupError,
    BdfStepSizeError,
    bdf_characteristic_roots,
    bdf_coefficients,
    bdf_coefficients_exact,
    extrapolation_weights,
    histopolation_weights,
    integrate_bdf,
    validate_order,
)
from hybrid.errors import NumericalFailure

# The standard BDF table (Hairer, Nørsett & Wanner, Solving ODEs I, §III.1),
# written as y_{k+1} = sum_j c_j y_{k+1-j} + beta h f_{k+1}.
KNOWN_TABLE = {
    1: ((Fr(1),), Fr(1)),
    2: ((Fr(4, 3), Fr(-1, 3)), Fr(2, 3)),
    3: ((Fr(18, 11), Fr(-9, 11), Fr(2, 11)), Fr(6, 11)),
    4: ((Fr(48, 25), Fr(-36, 25), Fr(16, 25), Fr(-3, 25)), Fr(12, 25)),
    5: ((Fr(300, 137), Fr(-300, 137), Fr(200, 137), Fr(-75, 137), Fr(12, 137)), Fr(60, 137)),
    6: ((Fr(360, 147), Fr(-450, 147), Fr(400, 147), Fr(-225, 147), Fr(72, 147), Fr(-10, 147)), Fr(60, 147)),
}


@pytest.mark.parametrize("order", range(1, 7))
def test_coefficients_match_known_table_exactly(order):
    hist, beta = bdf_coefficients_exact(order)
    assert (hist, beta) == KNOWN_TABLE[order]
    floats = bdf_coefficients(order)
    assert floats == BdfCoefficients(
        order=order, history=tuple(float(c) for c in KNOWN_TABLE[order][0]), beta=float(KNOWN_TABLE[order][1])
    )


def test_bdf4_is_the_papers_formula():
    c = bdf_coefficients(4)
    assert [x * 25 for x in c.history] == pytest.approx([48, -36, 16, -3], abs=1e-13)
    assert c.beta * 25 == pytest.approx(12, abs=1e-13)


@pytest.mark.parametrize("order", range(1, 8))
def test_consistency_and_exactness_on_polynomials(order):
    """sum c_j = 1, and the formula is exact for y = t^d, d <= order (order conditions), in exact arithmetic."""
    hist, beta = bdf_coefficients_exact(order)
    assert sum(hist) == 1
    # grid t_{k+1-j} = 1 - j (h = 1); y = t^d, f = d t^(d-1) evaluated at t_{k+1} = 1
    for degree in range(order + 1):
        lhs = Fr(1)
        rhs = sum(c * Fr(1 - j) ** degree for j, c in enumerate(hist, start=1)) + beta * degree
        assert lhs == rhs, degree


@pytest.mark.parametrize("order", range(1, 7))
def test_orders_1_to_6_are_zero_stable(order):
    roots = bdf_characteristic_roots(order)
    assert np.min(np.abs(roots - 1.0)) < 1e-9  # consistency root
    assert np.max(np.abs(roots)) <= 1.0 + 1e-9
    others = roots[np.abs(roots - 1.0) > 1e-6]
    assert np.all(np.abs(others) < 1.0)  # the other roots strictly inside: no repeated root on the circle


def test_bdf7_has_a_root_outside_the_unit_circle():
    roots = bdf_characteristic_roots(7)
    assert np.max(np.abs(roots)) == pytest.approx(1.0222, abs=1e-4)  # Hairer–Wanner: BDF7 not zero-stable
    assert np.max(np.abs(roots)) > 1.02


def test_extrapolation_weights_are_exact_for_polynomials():
    for count in range(1, 7):
        w = extrapolation_weights(count)
        for degree in range(count):
            # values at t = 0, -1, ..., -(count-1) extrapolated to t = 1
            assert sum(wj * (-j) ** degree for j, wj in enumerate(w)) == pytest.approx(1.0, abs=1e-12)


def test_histopolation_weights_known_values_and_exactness():
    assert histopolation_weights(1) == (1.0,)
    assert histopolation_weights(2) == (1.5, -0.5)
    assert histopolation_weights(3) == pytest.approx((11 / 6, -7 / 6, 2 / 6), abs=1e-15)
    for count in range(1, 7):
        w = histopolation_weights(count)
        assert sum(w) == pytest.approx(1.0, abs=1e-13)
        for degree in range(count):
            # cell i = [-i, 1 - i]; mean of t^d over it = ((1-i)^(d+1) - (-i)^(d+1)) / (d+1); value at t = 1 is 1
            means = [((1 - i) ** (degree + 1) - (-i) ** (degree + 1)) / (degree + 1) for i in range(count)]
            assert sum(wi * m for wi, m in zip(w, means)) == pytest.approx(1.0, abs=1e-12), (count, degree)


# --------------------------------------------------------------------------- observed order

Y0 = 0.07  # logistic y' = y (1 - y), y(0) = Y0; exact y = 1 / (1 + (1/Y0 - 1) e^{-t})
T_END = 4.0


def _logistic(t):
    return 1.0 / (1.0 + (1.0 / Y0 - 1.0) * np.exp(-t))


def _f(t, y):
    return y * (1.0 - y)


def _jac(t, y):
    return [[1.0 - 2.0 * y[0]]]


def _max_error(order, n):
    h = T_END / n
    start = _logistic(h * np.arange(1, order)).reshape(-1, 1) if order > 1 else None
    sol = integrate_bdf(_f, _jac, 0.0, [Y0], h, n, order, "exact", start_values=start)
    return float(np.max(np.abs(sol.y[:, 0] - _logistic(sol.t))))


# Step counts per order: in the asymptotic range of this problem, with the smallest error >= 2e-11
# (100x the round-off floor of about 1e-13 seen with 1000 steps), found by a scan of n = 8..1024.
# BDF5/6 reach their asymptotic slope only where the error is 1e-6..1e-10.
ORDER_STEPS = {1: (32, 64, 128), 2: (128, 256, 512), 3: (128, 256, 512), 4: (128, 256, 512), 5: (8, 16, 32), 6: (32, 64, 128)}


@pytest.mark.parametrize("order", range(1, 7))
def test_observed_order_on_the_logistic_equation(order):
    steps = ORDER_STEPS[order]
    errors = [_max_error(order, n) for n in steps]
    assert min(errors) > 2e-11  # round-off does not dominate
    slope = np.polyfit(np.log(T_END / np.array(steps)), np.log(errors), 1)[0]
    assert abs(slope - order) < 0.1, (order, slope, errors)


def test_rk4_startup_is_as_accurate_as_exact_start_values():
    n = 256
    exact = _max_error(4, n)
    sol = integrate_bdf(_f, _jac, 0.0, [Y0], T_END / n, n, 4, "rk4")
    rk4 = float(np.max(np.abs(sol.y[:, 0] - _logistic(sol.t))))
    assert rk4 == pytest.approx(exact, rel=1e-3)
    assert sol.newton_iterations <= 3 * (n - 3)


def test_ramp_startup_runs_and_is_documented_as_less_accurate():
    n = 256
    sol = integrate_bdf(_f, _jac, 0.0, [Y0], T_END / n, n, 4, "ramp")
    ramp = float(np.max(np.abs(sol.y[:, 0] - _logistic(sol.t))))
    # The first (BDF1) step has a local error h²|y''|/2 ≈ 7e-6 (h = 1/64, y''(0) ≈ 0.056), which the
    # growing logistic amplifies ~5x: 3.6e-5 measured, against 2e-9 from exact start values.
    assert 1000 * _max_error(4, n) < ramp < 1e-4


def test_solution_is_read_only_and_shaped():
    sol = integrate_bdf(lambda t, y: -y, lambda t, y: -np.eye(2), 0.0, [1.0, 2.0], 0.1, 5, 2)
    assert sol.t.shape == (6,) and sol.y.shape == (6, 2)
    with pytest.raises(ValueError, match="read-only"):
        sol.y[0, 0] = 3.0
    assert sol.order == 2 and sol.startup == "rk4"


def test_zero_steps_returns_initial_value():
    sol = integrate_bdf(lambda t, y: -y, lambda t, y: [[-1.0]], 1.0, [3.0], 0.1, 0, 4)
    assert sol.y.tolist() == [[3.0]] and sol.t.tolist() == [1.0]


# --------------------------------------------------------------------------- errors


@pytest.mark.parametrize("order", [0, 7, -1])
def test_order_out_of_range(order):
    with pytest.raises(BdfOrderError, match=rf"order = {order}: expected a BDF order in 1\.\.6 .*not zero-stable.*choose order between 1 and 6"):
        bdf_coefficients(order)
    with pytest.raises(BdfOrderError, match=rf"order = {order}"):
        integrate_bdf(_f, _jac, 0.0, [Y0], 0.1, 3, order)


@pytest.mark.parametrize("order", [2.5, "4", True, None])
def test_order_not_an_integer(order):
    with pytest.raises(BdfOrderError, match=r"order = .*expected an integer BDF order in 1\.\.6; pass e\.g\. order=4"):
        validate_order(order)


def test_order_error_is_a_value_error_and_names_the_field():
    with pytest.raises(ValueError, match=r"EstimatorSettings\.order = 9"):
        validate_order(9, name="EstimatorSettings.order")


def test_exact_coefficients_reject_order_zero():
    with pytest.raises(BdfOrderError, match=r"order = 0: expected an integer >= 1"):
        bdf_coefficients_exact(0)


@pytest.mark.parametrize("h", [0.0, -0.1, math.nan, math.inf])
def test_non_positive_step(h):
    with pytest.raises(BdfStepSizeError, match=r"h = .*: expected a positive finite step size"):
        integrate_bdf(_f, _jac, 0.0, [Y0], h, 3, 2)


def test_negative_step_count():
    with pytest.raises(BdfStepSizeError, match=r"n_steps = -1: expected a non-negative integer"):
        integrate_bdf(_f, _jac, 0.0, [Y0], 0.1, -1, 2)


def test_unknown_startup():
    with pytest.raises(BdfStartupError, match=r"startup = 'euler': expected one of 'rk4', 'exact', 'ramp'"):
        integrate_bdf(_f, _jac, 0.0, [Y0], 0.1, 3, 2, "euler")


def test_exact_startup_without_values():
    with pytest.raises(BdfHistoryError, match=r"startup='exact' with order = 3 needs start_values.*use startup='rk4'"):
        integrate_bdf(_f, _jac, 0.0, [Y0], 0.1, 5, 3, "exact")


def test_history_shorter_than_the_order():
    with pytest.raises(BdfHistoryError, match=r"start_values has 2 rows but order = 4 needs 3 .*lower the order"):
        integrate_bdf(_f, _jac, 0.0, [Y0], 0.1, 5, 4, "exact", start_values=[[0.1], [0.2]])


def test_history_of_wrong_width():
    with pytest.raises(BdfHistoryError, match=r"start_values has shape \(3, 2\): expected \(order - 1, n\) = \(3, 1\)"):
        integrate_bdf(_f, _jac, 0.0, [Y0], 0.1, 5, 4, "exact", start_values=np.zeros((3, 2)))


def test_newton_not_converging_names_iterations_and_residual():
    with pytest.raises(BdfConvergenceError, match=r"BDF step 1 to t = 0\.5: Newton did not converge after 1 iterations \(last update max-norm .*, residual max-norm .*\); reduce h or raise newton_maxiter") as info:
        integrate_bdf(_f, _jac, 0.0, [Y0], 0.5, 3, 1, newton_maxiter=1, newton_tol=1e-15)
    err = info.value
    assert isinstance(err, ArithmeticError) and isinstance(err, NumericalFailure)
    assert err.iterations == 1 and err.residual_norm > 0.0


def test_singular_newton_matrix():
    # y' = y with h = 1, BDF1: I - h J = 0
    with pytest.raises(BdfConvergenceError, match=r"Newton matrix I - beta\*h\*J is singular at iteration 1; reduce h"):
        integrate_bdf(lambda t, y: y, lambda t, y: [[1.0]], 0.0, [1.0], 1.0, 1, 1)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"newton_tol": 0.0}, r"newton_tol = 0\.0: expected a positive finite tolerance"),
    ({"newton_maxiter": 0}, r"newton_maxiter = 0: expected an integer >= 1"),
    ({"rk4_substeps": 0}, r"rk4_substeps = 0: expected an integer >= 1"),
])
def test_bad_solver_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        integrate_bdf(_f, _jac, 0.0, [Y0], 0.1, 3, 2, **kwargs)


@pytest.mark.parametrize("func", [extrapolation_weights, histopolation_weights])
def test_weight_counts_must_be_positive(func):
    with pytest.raises(ValueError, match=r"count = 0: expected an integer >= 1"):
        func(0)
