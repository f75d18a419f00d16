"""Path-following stability: the composed CasADi model, its linearisation and the Lyapunov bounds."""

import math

import casadi as ca
import numpy as np
import pytest

from analysis.linearise import NotAnEquilibriumError, linearise
from visnav import controllers, model
from visnav.geometry import proximity
from visnav.parameters import Obstacle
from visnav.studies.path_following import (
    admissible_gains,
    entry_bounds,
    path_following_closed_form_eigenvalues,
    path_following_model,
)

K, V, D0, R = 4.0, 0.2, 0.5, 1.4


@pytest.fixture(scope="module")
def pf():
    return path_following_model(k=K, v=V, d_zero=D0, radius=R)


def test_symbolic_model_agrees_with_the_simulation_code(pf):
    """The CasADi closed loop equals the float code: proximity + path_following + the path-frame rates."""
    obstacle = Obstacle(name="o", center_m=(0.0, 0.0), radius_m=R, height_m=0.3)
    rng = np.random.default_rng(3)
    for _ in range(50):
        delta, alpha = rng.uniform(-0.4, 0.4), rng.uniform(-2.5, 2.5)
        rho = R + D0 + delta
        bearing = rng.uniform(-math.pi, math.pi)
        x, y = rho * math.cos(bearing), rho * math.sin(bearing)
        tangent = bearing + math.pi / 2  # side +1: counter-clockwise travel
        theta = tangent - alpha  # alpha = -(theta - tangent)
        prox = proximity(x, y, theta, obstacle, 1)
        assert prox.d_coll - D0 == pytest.approx(delta, abs=1e-12) and prox.alpha == pytest.approx(alpha, abs=1e-12)
        v, omega = controllers.path_following(prox, D0, V, K)
        numeric = model.path_error_rates(v, omega, prox.alpha, 1.0 / prox.rho, 1)
        symbolic = np.array(pf.function([delta, alpha]).full()).ravel()
        np.testing.assert_allclose(symbolic, numeric, rtol=1e-12, atol=1e-14)
        # the closed form the docstring states
        np.testing.assert_allclose(symbolic, [V * math.sin(alpha), -V * (K * delta + alpha + 2 * K * math.sin(alpha))],
                                   rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("k, v", [(K, V), (0.5, 0.1), (20.0, 0.4)])
def test_eigenvalues_agree_with_the_closed_form(k, v):
    lin = path_following_model(k=k, v=v, d_zero=D0, radius=R).linearisation()
    assert lin.hurwitz
    expected = sorted(path_following_closed_form_eigenvalues(k, v), key=lambda z: z.real)
    for got, want in zip(lin.eigenvalues, expected):
        assert abs(got - want) <= 1e-12 * abs(want)
    assert [m.damping_ratio for m in lin.modes] == [1.0, 1.0]


def test_lyapunov_rate_is_the_stated_expression(pf):
    f = ca.Function("vdot", [pf.delta, pf.alpha, pf.kappa], [pf.lyapunov_rate])
    for delta, alpha in ((0.3, 0.7), (-0.2, -2.9), (0.1, 0.0)):
        expected = -V * (alpha * math.sin(alpha) + 2 * K * math.sin(alpha) ** 2)
        for kappa in (0.0, 1 / (R + D0 + delta), 7.0):
            assert float(f(delta, alpha, kappa)) == pytest.approx(expected, abs=1e-15)


def test_loop_broken_at_omega_closes_to_the_linearisation(pf):
    a_p, b_p, gain = pf.plant_and_gain()
    np.testing.assert_allclose(a_p + b_p @ gain, pf.linearisation().jacobian, atol=1e-15)
    rho0 = R + D0
    np.testing.assert_allclose(a_p, [[0.0, V], [-V / rho0**2, 0.0]], atol=1e-15)
    np.testing.assert_allclose(gain, [[V * (K - 1 / rho0**2), V * (1 + 2 * K)]], rtol=1e-14)


def test_not_an_equilibrium_is_reported_with_the_residual(pf):
    with pytest.raises(NotAnEquilibriumError, match=r"delta_m.: 0.1.*is not an equilibrium.*dalpha_rad/dt. = 0.08") as info:
        linearise(pf.function, (0.1, 0.0), state_names=("delta_m", "alpha_rad"))
    assert info.value.residual[1] == pytest.approx(-V * K * 0.1, rel=1e-12)


def test_entry_bounds_hold_along_simulated_bypasses():
    """Integrate the closed loop from entry states: |δ|, |α|, |ω| never exceed the V-bounds."""
    from scipy.integrate import solve_ivp

    for alpha0 in (-0.2, -0.5, -0.9):
        b = entry_bounds(k=K, v=V, d_zero=D0, radius=R, delta0=-0.2, alpha0=alpha0)
        assert b.valid
        sol = solve_ivp(lambda t, y: [V * math.sin(y[1]), -V * (K * y[0] + y[1] + 2 * K * math.sin(y[1]))],
                        (0, 60), [-0.2, alpha0], rtol=1e-10, atol=1e-12, max_step=0.05)
        delta, alpha = sol.y
        rho = R + D0 + delta
        omega = V * (K * delta + alpha + 2 * K * np.sin(alpha) + np.cos(alpha) / rho)
        assert np.abs(delta).max() <= b.delta_max_m + 1e-9
        assert np.abs(alpha).max() <= b.alpha_max_rad + 1e-9
        assert np.abs(omega).max() <= b.omega_max_radps + 1e-9
        lyap = K * delta**2 / 2 + 1 - np.cos(alpha)
        assert np.all(np.diff(lyap) <= 1e-12)  # V never increases along the solution


def test_admissible_gains_interval_and_empty_set():
    ok = admissible_gains(v=V, d_zero=D0, radius=R, delta0=-0.2, entry_angles=[-0.2], clearance=0.1, omega_max=1.2)
    lo, hi = ok.interval
    assert 0 < lo < hi
    # just inside the interval both requirements hold, just outside one fails
    inside = entry_bounds(k=lo * (1 + 1e-6), v=V, d_zero=D0, radius=R, delta0=-0.2, alpha0=-0.2)
    assert inside.min_distance_m >= 0.1 and inside.omega_max_radps <= 1.2
    outside = entry_bounds(k=lo * (1 - 1e-6), v=V, d_zero=D0, radius=R, delta0=-0.2, alpha0=-0.2)
    assert outside.min_distance_m < 0.1
    # closed form of the clearance boundary: k_min = 2 (1 - cos α0) / ((d0 - c)² - δ0²)
    assert lo == pytest.approx(2 * (1 - math.cos(-0.2)) / ((D0 - 0.1) ** 2 - 0.04), rel=1e-8)
    steep = admissible_gains(v=V, d_zero=D0, radius=R, delta0=-0.2, entry_angles=[-0.2, -0.8], clearance=0.1,
                             omega_max=1.2)
    assert steep.interval is None and "no k" in steep.finding
    assert steep.per_angle[1][1] is None
    # the empty set is explained: for α0 = −0.8 the clearance needs k >= k_c (closed form above), and
    # there the guaranteed ω bound already exceeds 1.2 rad/s
    limit = steep.limits[1]
    k_c = 2 * (1 - math.cos(-0.8)) / ((D0 - 0.1) ** 2 - 0.04)
    # first grid point at or above k_c: one step of the 2000-point log grid over 6 decades is 0.69 %
    assert k_c <= limit["clearance_k"][0] <= k_c * 10 ** (6 / 1999)
    assert "clearance alone needs k in" in steep.finding and "smallest guaranteed |omega| bound" in steep.finding
    at_kc = entry_bounds(k=limit["clearance_k"][0], v=V, d_zero=D0, radius=R, delta0=-0.2, alpha0=-0.8)
    assert at_kc.omega_max_radps > 1.2
    assert limit["best_omega_bound_radps"] <= at_kc.omega_max_radps


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match=r"v = -0.1; expected a finite number > 0"):
        path_following_model(k=K, v=-0.1, d_zero=D0, radius=R)
    with pytest.raises(ValueError, match=r"side = 0"):
        path_following_model(k=K, v=V, d_zero=D0, radius=R, side=0)
