"""The robustness gradient from trace sensitivities (analysis.stl.gradient): closed forms on affine traces, the
signs through negations, and central differences of the robustness (the semantics, evaluated on perturbed
traces: an independent route) on nonlinear traces and nested formulas."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.stl import SignalTrace, TraceError, parse_formula
from analysis.stl.gradient import robustness_gradient

T = np.linspace(0.0, 2.0, 41)


def _affine(a, b):
    """x(t) = a + b t (affine in (a, b): sensitivities (1, t)) and y(t) = 2a - b^2 t (sensitivities (2, -2bt))."""
    trace = SignalTrace(times=T, signals={"x": a + b * T, "y": 2 * a - b * b * T})
    sens = {"x": np.stack([np.ones_like(T), T], axis=1), "y": np.stack([2 * np.ones_like(T), -2 * b * T], axis=1)}
    return trace, sens


@pytest.mark.parametrize("a, b", [(1.0, 2.0), (1.0, -2.0), (-0.5, 0.3)])
def test_the_gradient_of_always_is_the_closed_form_at_the_active_sample(a, b):
    trace, sens = _affine(a, b)
    rho, grad = robustness_gradient(parse_formula("always[0, 2] (x < 7)"), trace, sens)
    t_star = 2.0 if b > 0 else 0.0  # the largest x: at the end for b > 0, at the start otherwise
    assert rho == pytest.approx(7 - (a + b * t_star), rel=1e-12)
    assert grad.tolist() == pytest.approx([-1.0, -t_star], abs=1e-15)


def test_negations_flip_the_gradient_and_implications_follow_the_deciding_side():
    trace, sens = _affine(1.0, 2.0)
    rho, grad = robustness_gradient(parse_formula("not eventually[0, 2] (x > 7)"), trace, sens)
    assert rho == pytest.approx(7 - 5.0) and grad.tolist() == pytest.approx([-1.0, -2.0])
    # the antecedent decides: rho = max(-min_t (x - 100), y(0) - 50) = max(100 - x(0), -48) = 99, read at t = 0
    rho, grad = robustness_gradient(parse_formula("(always[0, 2] (x > 100)) -> (y > 50)"), trace, sens)
    assert rho == pytest.approx(99.0) and grad.tolist() == pytest.approx([-1.0, 0.0])
    # an atom with arithmetic and abs: y - x at t = 2 is 2 - 8 - 5 = -11 (the minimum), |.| = 11
    rho, grad = robustness_gradient(parse_formula("eventually[0, 2] (abs(y - x) > 3)"), trace, sens)
    # d(x - y) = (1 - 2, t + 2 b t) = (-1, 2 + 8) at t = 2; |y - x| = x - y there
    assert rho == pytest.approx(11.0 - 3.0) and grad.tolist() == pytest.approx([-1.0, 10.0])


def _nonlinear(p):
    a, b, c = p
    x = a * np.sin(1.3 * T + c) + b * T
    y = b * np.exp(-a * T) - c * T * T
    trace = SignalTrace(times=T, signals={"x": x, "y": y})
    sens = {"x": np.stack([np.sin(1.3 * T + c), T, a * np.cos(1.3 * T + c)], axis=1),
            "y": np.stack([-T * b * np.exp(-a * T), np.exp(-a * T), -T * T], axis=1)}
    return trace, sens


FORMULAS = ["always[0, 1.5] ((x - y < 3) or eventually[0, 0.5] (abs(y) > 0.2))",
            "eventually[0, 1] always[0, 0.5] (min(x, 2 * y) >= prev(x) - 1)",
            "(always[0, 2] (y < 1)) -> not (x * y > 0.5)",
            "always[0, 2] (x / (2 + y * y) <= 0.4)"]


@pytest.mark.parametrize("formula", FORMULAS)
@pytest.mark.parametrize("seed", range(4))
def test_the_gradient_matches_central_differences_of_the_robustness(formula, seed):
    f = parse_formula(formula)
    p = np.random.default_rng(seed).uniform([0.5, -1.0, -1.0], [2.0, 1.0, 1.0])
    trace, sens = _nonlinear(p)
    rho, grad = robustness_gradient(f, trace, sens)
    assert rho == f.robustness(trace)
    h = 1e-7  # the robustness is piecewise smooth: central differences within one piece err by ~h^2, round-off
    for j in range(3):  # ~1e-16 / h ~ 1e-9; a switch of the active sample within +-h would show as a jump
        up, down = p.copy(), p.copy()
        up[j] += h
        down[j] -= h
        fd = (f.robustness(_nonlinear(up)[0]) - f.robustness(_nonlinear(down)[0])) / (2 * h)
        assert grad[j] == pytest.approx(fd, rel=1e-5, abs=1e-6), (j, grad, fd)


def test_a_signal_without_sensitivities_is_refused_and_labels_give_a_zero_gradient():
    trace, sens = _affine(1.0, 2.0)
    with pytest.raises(TraceError, match="'y'"):
        robustness_gradient(parse_formula("always[0, 2] (y < 7)"), trace, {"x": sens["x"]})
    with pytest.raises(TraceError, match=r"shape \(41, 2\)"):
        robustness_gradient(parse_formula("always[0, 2] (x < 7)"), trace, {"x": sens["x"][:, :1]}, 2)
    labelled = SignalTrace(times=T, signals={"x": trace.signal("x")}, labels={"mode": ("a",) * T.size})
    rho, grad = robustness_gradient(parse_formula('always[0, 2] (mode == "a")'), labelled, sens)
    assert rho == np.inf and grad.tolist() == [0.0, 0.0]
    rho, grad = robustness_gradient(parse_formula("always[0, 2] (time < 9)"), trace, sens)
    assert rho == pytest.approx(7.0) and grad.tolist() == [0.0, 0.0]
