"""Stability regions, boundary loci and A(α) angles of analysis.integrator_regions."""

import math

import numpy as np
import pytest

from analysis.bdf import BdfOrderError
from analysis.integrators import FIXED_STEP_SCHEMES, OdeProblem, UnknownSchemeError, integrate
from analysis.integrator_regions import (
    PUBLISHED_A_ALPHA_DEG,
    a_alpha,
    boundary_locus,
    first_unstable_step,
    is_stable,
    max_root_modulus,
    real_stability_interval,
    stability_polynomial,
    zero_stability,
)


@pytest.mark.parametrize("order", range(1, 7))
def test_a_alpha_matches_hairer_wanner_within_0_01_degree(order):
    a = a_alpha(order)
    # The published values have three decimals (rounding error <= 0.0005°); the measurement is
    # limited by the rounding of arg (~1e-13°).  Measured errors: 0, 0, 3.7e-4, 6.7e-4, 7.6e-4, 7.8e-4.
    assert abs(a.alpha_deg - PUBLISHED_A_ALPHA_DEG[order]) < 1e-3
    # the tangency route, independent of the minimisation, agrees to round-off
    assert a.alpha_tangency_deg == pytest.approx(a.alpha_deg, abs=1e-9)


@pytest.mark.parametrize("order", range(3, 7))
def test_the_a_alpha_sector_is_stable_and_a_wider_one_is_not(order):
    a = a_alpha(order)
    poly = stability_polynomial(f"bdf{order}")
    radii = np.geomspace(1e-3, 1e3, 400)
    inside = math.radians(a.alpha_deg - 0.01)
    # rays at α - 0.01° (both half planes) stay in the region
    for sign in (1, -1):
        z = -radii * np.exp(1j * sign * inside)
        assert np.all(is_stable(poly, z, tol=1e-12))
    # a ray at α + 0.01° crosses the locus near the tangency point: at |z*| it is outside
    outside = math.radians(a.alpha_deg + 0.01)
    z = -abs(a.z_star) * np.exp(-1j * outside)  # upper half plane, like z*
    assert max_root_modulus(poly, z) > 1.0


@pytest.mark.parametrize("order", [1, 2])
def test_bdf1_and_bdf2_are_a_stable(order):
    assert a_alpha(order).alpha_deg == 90.0
    locus = boundary_locus(stability_polynomial(f"bdf{order}"), 4096)[:, 0]
    assert locus.real.min() > -1e-12  # the locus stays in the closed right half plane
    assert bool(is_stable(stability_polynomial(f"bdf{order}"), -1.0 + 50.0j))


def test_bdf7_is_not_zero_stable_and_bdf1_to_6_are():
    z7 = zero_stability(7)
    assert not z7.zero_stable
    assert z7.max_parasitic_modulus == pytest.approx(1.0222, abs=1e-4)
    for order in range(1, 7):
        assert zero_stability(order).zero_stable
    with pytest.raises(BdfOrderError, match=r"order = 7: expected a BDF order in 1\.\.6"):
        a_alpha(7)


def test_loci_lie_on_the_region_boundary():
    for scheme in ("bdf3", "bdf6", "euler"):
        poly = stability_polynomial(scheme)
        locus = boundary_locus(poly, 257)[:, 0]
        assert np.allclose(max_root_modulus(poly, locus), 1.0, atol=1e-9)


def test_real_stability_intervals():
    assert real_stability_interval(stability_polynomial("euler")) == pytest.approx(-2.0, abs=1e-12)
    # RK4: the real root of 1 + x + x²/2 + x³/6 + x⁴/24 = 1, i.e. of x³ + 4x² + 12x + 24 = 0
    roots = np.roots([1.0, 4.0, 12.0, 24.0])
    closed = float(roots[np.abs(roots.imag) < 1e-12].real[0])
    assert real_stability_interval(stability_polynomial("rk4")) == pytest.approx(closed, abs=1e-11)
    assert real_stability_interval(stability_polynomial("bdf4")) == -math.inf


@pytest.mark.parametrize("scheme", FIXED_STEP_SCHEMES)
def test_stability_polynomial_predicts_the_integrators_growth(scheme):
    # Apply the actual integrator to y' = λ y (as the real 2x2 system of a complex λ) with exact
    # start values: the solution follows the principal root ζ(hλ) ≈ e^{hλ} of π(·, hλ) (the
    # parasitic roots are excited only by the O(h^(p+1)) start-up defect), so |y_n|^(1/n) must equal
    # |ζ|: a check of the polynomial against the integrator it describes.
    lam = complex(-0.6, 0.9)
    h = 0.1  # z = -0.06 + 0.09i: the principal root dominates every parasitic one (BDF6: 0.94 vs <= 0.87)
    z = h * lam
    poly = stability_polynomial(scheme)
    a = np.array([[lam.real, -lam.imag], [lam.imag, lam.real]])
    problem = OdeProblem(f=lambda t, y: a @ y, jac=lambda t, y: a, t0=0.0, t1=h * 120, y0=[1.0, 0.0])
    needed = 3 if scheme == "abm4" else (int(scheme[3:]) - 1 if scheme.startswith("bdf") else 0)
    kwargs = {}
    if needed:
        kwargs = {"startup": "exact", "start_values": [[math.exp(h * j * lam.real) * math.cos(h * j * lam.imag),
                                                         math.exp(h * j * lam.real) * math.sin(h * j * lam.imag)]
                                                        for j in range(1, needed + 1)]}
    y = integrate(problem, scheme, h=h, **kwargs).y
    n0, n1 = 60, 120
    rate = (np.linalg.norm(y[n1]) / np.linalg.norm(y[n0])) ** (1.0 / (n1 - n0))
    roots = np.roots(poly.in_zeta(z))
    principal = roots[np.argmin(np.abs(roots - np.exp(z)))]
    # tolerance: the parasitic components, relative size below (0.87/0.94)^60 ~ 1e-2 of a start-up
    # defect that is itself below 1e-6
    assert rate == pytest.approx(abs(principal), rel=1e-6)
    assert abs(principal) == pytest.approx(float(max_root_modulus(poly, z)), rel=1e-12)


def test_first_unstable_step_on_real_eigenvalues():
    lam = np.array([-1.0, -10.0, -0.5 + 0.0j])
    assert first_unstable_step(stability_polynomial("euler"), lam, 1e-3, 1e3) == pytest.approx(0.2, rel=1e-5)
    rk4 = -real_stability_interval(stability_polynomial("rk4"))
    assert first_unstable_step(stability_polynomial("rk4"), lam, 1e-3, 1e3) == pytest.approx(rk4 / 10, rel=1e-5)
    assert first_unstable_step(stability_polynomial("bdf2"), lam, 1e-3, 1e3) == math.inf
    assert math.isnan(first_unstable_step(stability_polynomial("rk4"), np.array([0.5]), 1e-3, 1.0))


def test_first_unstable_step_in_the_unstable_lobe_of_bdf6():
    # eigenvalues on the ray through the tangency point of BDF6's A(α) sector, slightly outside the
    # sector: h λ enters the lobe at a finite step and that step is found (checked by bisection
    # on the whole set).
    a = a_alpha(6)
    direction = a.z_star / abs(a.z_star) * np.exp(-1j * math.radians(0.5))
    lam = np.array([direction * 1.0, direction * 0.3, -1.0 + 0j])
    h = first_unstable_step(stability_polynomial("bdf6"), lam, 1e-3, 1e3)
    assert math.isfinite(h)
    assert bool(np.all(is_stable(stability_polynomial("bdf6"), 0.999 * h * lam)))
    assert not bool(np.all(is_stable(stability_polynomial("bdf6"), 1.001 * h * lam)))


def test_unknown_scheme_has_no_polynomial():
    with pytest.raises(UnknownSchemeError, match=r"scheme = 'scipy_bdf': a stability polynomial exists for"):
        stability_polynomial("scipy_bdf")
