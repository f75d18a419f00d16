"""Tests of analysis.margins: closed forms, loop breaking, sampled loops, two routes, errors."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys

import control
import numpy as np
import pytest

from analysis.margins import (
    FrequencyGridError,
    LoopBreakError,
    LoopDefinitionError,
    LoopFrequencyResponse,
    LoopModel,
    LoopShapeError,
    LoopTypeError,
    Margins,
    NonFiniteLoopError,
    SamplingError,
    frequency_response_data,
    loop_model,
    loop_transfer,
    margins,
    margins_by_sweep,
    sampled_loop,
    sampled_loop_transfer,
)

CLOSED_FORM = dict(rel=1e-9, abs=1e-12)
TWO_ROUTES = dict(rel=1e-6, abs=1e-9)
SWEEP = dict(w_min=1e-4, w_max=1e4)


def both(L, **sweep):
    """The polynomial route and the sweep route on the same loop."""
    kwargs = {**SWEEP, **sweep}
    if L.dt:
        kwargs["w_max"] = min(kwargs["w_max"], math.pi / L.dt)
    return margins(L), margins_by_sweep(L, **kwargs)


def response(L, w):
    """L at s = jw or z = e^{jwT}, by python-control (a third evaluation)."""
    points = 1j * np.asarray(w) if not L.dt else np.exp(1j * np.asarray(w) * L.dt)
    return np.array([complex(np.squeeze(L(p))) for p in points])


def assert_routes_agree(poly: Margins, sweep: Margins) -> None:
    assert poly.method == "polynomial" and sweep.method == "sweep"
    assert_margins_agree(poly, sweep)


def assert_margins_agree(poly: Margins, sweep: Margins) -> None:
    for field in ("phase_crossovers", "gain_margins", "gain_crossovers", "phase_margins_deg", "delay_margins_s"):
        a, b = getattr(poly, field), getattr(sweep, field)
        assert len(a) == len(b), (field, a, b)
        assert a == pytest.approx(b, **TWO_ROUTES), field
    for field in ("gain_margin", "phase_margin_deg", "delay_margin_s", "gain_margin_db"):
        a, b = getattr(poly, field), getattr(sweep, field)
        assert (math.isinf(a) and a == b) or a == pytest.approx(b, **TWO_ROUTES), field
    for field in ("phase_crossover_frequency", "gain_crossover_frequency"):
        a, b = getattr(poly, field), getattr(sweep, field)
        assert (math.isnan(a) and math.isnan(b)) or a == pytest.approx(b, **TWO_ROUTES), field
    assert poly.closed_loop_stable == sweep.closed_loop_stable
    assert poly.open_loop_unstable_poles == sweep.open_loop_unstable_poles


# --------------------------------------------------------------------------- closed forms


@pytest.mark.parametrize("k", [0.3, 1.0, 2.0, 17.0])
def test_integrator_k_over_s(k):
    for m in both(control.tf([k], [1.0, 0.0])):
        assert m.phase_margin_deg == pytest.approx(90.0, **CLOSED_FORM)
        assert m.gain_margin == math.inf and m.gain_margin_db == math.inf
        assert m.phase_crossovers == () and math.isnan(m.phase_crossover_frequency)
        assert m.gain_crossover_frequency == pytest.approx(k, **CLOSED_FORM)
        assert m.gain_crossovers == pytest.approx((k,), **CLOSED_FORM)
        assert m.delay_margin_s == pytest.approx(math.pi / (2.0 * k), **CLOSED_FORM)
        assert m.delay_margin_samples is None and m.period is None
        assert m.closed_loop_stable and m.open_loop_unstable_poles == 0 and m.open_loop_boundary_poles == 1
        assert m.closed_loop_poles == pytest.approx((-k,), **CLOSED_FORM)
        assert m.notes == ()


@pytest.mark.parametrize("k", [0.5, 1.0, 2.0, 10.0])
def test_integrator_with_lag_k_over_s_s_plus_1(k):
    # |L(jω)| = k / (ω sqrt(ω² + 1)) = 1  <=>  ω² (ω² + 1) = k²
    w_c = math.sqrt((-1.0 + math.sqrt(1.0 + 4.0 * k * k)) / 2.0)
    assert w_c * math.sqrt(w_c**2 + 1.0) == pytest.approx(k, rel=1e-14)
    pm_deg = 180.0 - 90.0 - math.degrees(math.atan(w_c))
    for m in both(control.tf([k], [1.0, 1.0, 0.0])):
        assert m.gain_crossover_frequency == pytest.approx(w_c, **CLOSED_FORM)
        assert m.phase_margin_deg == pytest.approx(pm_deg, **CLOSED_FORM)
        assert m.delay_margin_s == pytest.approx(math.radians(pm_deg) / w_c, **CLOSED_FORM)
        assert m.gain_margin == math.inf
        assert m.closed_loop_stable


@pytest.mark.parametrize("k, period", [(2.0, 0.1), (1.0, 0.05), (5.0, 0.02), (0.4, 1.0)])
def test_sampled_integrator_with_one_sample_delay(k, period):
    """ZOH of k/s with one sample of delay: L(z) = kT / (z (z − 1))."""
    Lz = sampled_loop(control.tf([k], [1.0, 0.0]), period, delay_samples=1)
    assert Lz.dt == period
    w = np.geomspace(1e-2, 0.99 * math.pi / period, 7)
    z = np.exp(1j * w * period)
    assert response(Lz, w) == pytest.approx(k * period / (z * (z - 1.0)), rel=1e-12)

    w_c = 2.0 / period * math.asin(k * period / 2.0)  # |kT / (e^{jωT} − 1)| = 1
    pm_rad = math.pi - math.pi / 2.0 - 1.5 * w_c * period  # phase −π/2 − ωT/2, delay −ωT
    w_pi = math.pi / (3.0 * period)  # −π/2 − 3 ω T / 2 = −π
    gm = 2.0 * math.sin(math.pi / 6.0) / (k * period)  # = 1 / (kT)
    for m in both(Lz):
        assert m.period == period
        assert m.gain_crossover_frequency == pytest.approx(w_c, **CLOSED_FORM)
        assert m.phase_margin_deg == pytest.approx(math.degrees(pm_rad), **CLOSED_FORM)
        assert m.phase_crossover_frequency == pytest.approx(w_pi, **CLOSED_FORM)
        assert m.phase_crossovers == pytest.approx((w_pi,), **CLOSED_FORM)
        assert m.gain_margin == pytest.approx(gm, **CLOSED_FORM)
        assert m.gain_margin == pytest.approx(1.0 / (k * period), **CLOSED_FORM)
        assert m.gain_margin_db == pytest.approx(20.0 * math.log10(gm), **CLOSED_FORM)
        assert m.delay_margin_s == pytest.approx(pm_rad / w_c, **CLOSED_FORM)
        assert m.delay_margin_samples == pytest.approx(pm_rad / (w_c * period), **CLOSED_FORM)
        assert m.closed_loop_stable == (gm > 1.0)


def test_sampled_integrator_delay_margin_in_samples_predicts_instability():
    """Adding n whole samples of delay is stable iff n < delay_margin_samples."""
    k, period = 2.0, 0.1
    base = margins(sampled_loop(control.tf([k], [1.0, 0.0]), period, delay_samples=1))
    for extra in range(0, 10):
        m = margins(sampled_loop(control.tf([k], [1.0, 0.0]), period, delay_samples=1 + extra))
        assert m.closed_loop_stable == (extra < base.delay_margin_samples), extra


def test_sampled_loop_without_delay_is_plain_zoh():
    k, period = 3.0, 0.2
    Lz = sampled_loop(control.tf([k], [1.0, 0.0]), period, delay_samples=0)
    w = np.geomspace(0.1, 10.0, 5)
    z = np.exp(1j * w * period)
    assert response(Lz, w) == pytest.approx(k * period / (z - 1.0), rel=1e-12)
    for m in both(Lz):
        assert m.phase_margin_deg == pytest.approx(90.0 - math.degrees(math.asin(k * period / 2.0)), **CLOSED_FORM)
        # L(−1) = −kT/2: the Nyquist curve ends on the negative real axis; closed-loop pole 1 − kT
        assert m.phase_crossovers == pytest.approx((math.pi / period,), **CLOSED_FORM)
        assert m.gain_margin == pytest.approx(2.0 / (k * period), **CLOSED_FORM)
        assert m.closed_loop_poles == pytest.approx((1.0 - k * period,), **CLOSED_FORM)


# --------------------------------------------------------------------------- unstable open loops


def test_unstable_open_loop_is_reported_with_stable_closed_loop():
    """L = 2 / (s − 1): one RHP pole, closed-loop pole −1, lower gain margin 1/2 at ω = 0, no upper one."""
    for m in both(control.tf([2.0], [1.0, -1.0])):
        assert m.open_loop_unstable_poles == 1 and not m.open_loop_stable
        assert m.closed_loop_stable
        assert m.closed_loop_poles == pytest.approx((-1.0,), **CLOSED_FORM)
        assert m.phase_crossovers == (0.0,)
        # stable for every gain multiplier g > 1/2: no upper bound, lower margin 1/2
        assert m.gain_margin == math.inf
        assert m.lower_gain_margin == pytest.approx(0.5, **CLOSED_FORM)
        assert m.lower_gain_margin_db == pytest.approx(20 * math.log10(0.5), **CLOSED_FORM)
        assert m.gain_crossover_frequency == pytest.approx(math.sqrt(3.0), **CLOSED_FORM)
        assert m.phase_margin_deg == pytest.approx(60.0, **CLOSED_FORM)
        assert len(m.notes) == 1 and "1 pole(s) in the right half plane" in m.notes[0]
        assert "encircles −1 counter-clockwise 1 time" in m.notes[0]


def test_unstable_closed_loop_is_reported():
    for m in both(control.tf([0.5], [1.0, -1.0])):
        assert m.open_loop_unstable_poles == 1 and not m.closed_loop_stable
        assert m.closed_loop_poles == pytest.approx((0.5,), **CLOSED_FORM)
        assert m.delay_margin_s == 0.0 and m.phase_margin_deg == math.inf
        assert any("closed loop 1/(1 + L) is unstable" in note for note in m.notes)


def test_unstable_discrete_open_loop_counts_poles_outside_unit_circle():
    Lz = control.tf([0.8], [1.0, -1.5], 0.1)  # pole 1.5; closed loop z = 0.7
    for m in both(Lz):
        assert m.open_loop_unstable_poles == 1 and m.closed_loop_stable
        assert m.closed_loop_poles == pytest.approx((0.7,), **CLOSED_FORM)
        assert "outside the unit circle" in m.notes[0]


# --------------------------------------------------------------------------- two routes


def random_stable_loop(rng: np.random.Generator, integrator: bool) -> control.TransferFunction:
    poles = list(-rng.uniform(0.2, 10.0, rng.integers(1, 3)))
    for _ in range(rng.integers(0, 2)):
        wn, zeta = rng.uniform(0.5, 10.0), rng.uniform(0.15, 0.9)
        poles += [complex(-zeta * wn, wn * math.sqrt(1 - zeta**2)), complex(-zeta * wn, -wn * math.sqrt(1 - zeta**2))]
    zeros = list(-rng.uniform(0.2, 20.0, rng.integers(0, len(poles))))
    if integrator:
        poles.append(0.0)
    num, den = np.atleast_1d(np.real(np.poly(zeros))), np.real(np.poly(poles))
    w_ref = 0.05
    scale = rng.uniform(2.0, 50.0) / abs(np.polyval(num, 1j * w_ref) / np.polyval(den, 1j * w_ref))
    return control.tf(scale * num, den)


@pytest.mark.parametrize("seed", range(12))
def test_routes_agree_on_random_continuous_loops(seed):
    rng = np.random.default_rng(seed)
    L = random_stable_loop(rng, integrator=bool(seed % 2))
    poly, sweep = both(L)
    assert poly.gain_crossovers, "the generator should produce at least one gain crossover"
    assert_routes_agree(poly, sweep)


@pytest.mark.parametrize("seed", range(8))
def test_routes_agree_on_random_sampled_loops(seed):
    rng = np.random.default_rng(100 + seed)
    L = random_stable_loop(rng, integrator=bool(seed % 2))
    Lz = sampled_loop(L, float(rng.uniform(0.01, 0.1)), delay_samples=int(rng.integers(0, 3)))
    poly, sweep = both(Lz)
    assert_routes_agree(poly, sweep)


def test_routes_agree_under_fast_sampling():
    """Poles clustered near z = 1 (T = 0.035 s, slow poles): python-control 0.10.2's z-plane roots put ω_c at
    0.2634 rad/s here instead of 0.2687 (−2 %); the w-plane route and the sweep agree."""
    L = control.tf([1.448, 18.36], [1.0, 5.977, 84.12, 181.7, 54.0, 0.0])
    Lz = sampled_loop(L, 0.03468, delay_samples=0)
    poly, sweep = both(Lz)
    assert_routes_agree(poly, sweep)
    assert np.abs(response(Lz, poly.gain_crossovers)) == pytest.approx(1.0, abs=1e-12)
    assert poly.gain_crossover_frequency == pytest.approx(0.2687, abs=1e-4)


def test_sampled_loop_with_pole_at_minus_one_uses_z_plane_solver():
    for Lz in (control.tf([0.3], [1.0, 1.0], 0.1), control.tf([0.3, 0.1], [1.0, 0.2, -0.8], 0.1)):
        poly, sweep = both(Lz, w_max=math.pi / 0.1 * (1 - 1e-6))
        assert_routes_agree(poly, sweep)
        assert poly.open_loop_boundary_poles == 1 and poly.gain_crossovers


def test_routes_agree_on_several_crossovers():
    """k ωn² / (s (s² + 2ζωn s + ωn²)), lightly damped: three gain crossovers, one phase crossover."""
    L = control.tf([0.3], [1.0, 0.1, 1.0, 0.0])
    poly, sweep = both(L, points=40_000)
    assert_routes_agree(poly, sweep)
    assert len(poly.gain_crossovers) == 3 and len(poly.phase_crossovers) == 1
    assert poly.phase_crossovers == pytest.approx((1.0,), **CLOSED_FORM)
    assert poly.gain_margin == pytest.approx(1.0 / 3.0, **CLOSED_FORM)  # |L(j1)| = k / (2ζ) = 3
    j = int(np.argmin(np.abs(poly.phase_margins_deg)))
    assert poly.phase_margin_deg == poly.phase_margins_deg[j]
    assert poly.gain_crossover_frequency == poly.gain_crossovers[j]
    assert poly.delay_margin_s == 0.0 and not poly.closed_loop_stable


def test_sweep_crossovers_are_roots_to_machine_precision():
    L = random_stable_loop(np.random.default_rng(7), integrator=True)
    sweep = margins_by_sweep(L, **SWEEP)
    assert np.abs(response(L, sweep.gain_crossovers)) == pytest.approx(1.0, abs=1e-13)
    for value in response(L, sweep.phase_crossovers):
        assert abs(value.imag) <= 1e-12 * abs(value) and value.real < 0


# --------------------------------------------------------------------------- breaking loops


@pytest.mark.parametrize("k1, k2", [(1.0, 2.0), (3.0, 0.5), (0.7, -0.3)])
def test_two_input_plant_broken_at_each_input_and_at_the_output(k1, k2):
    """y = u0/(s+1) + u1/(s+2), u = −[k1; k2] y.

    Cut at u0 with u1 = −k2 y: y (1 + k2/(s+2)) = v/(s+1), so
    L0 = k1 (s+2) / ((s+1)(s+2+k2)); symmetrically L1 = k2 (s+1) / ((s+2)(s+1+k1));
    cut at y: L = k1/(s+1) + k2/(s+2).
    """
    model = loop_model(np.diag([-1.0, -2.0]), np.eye(2), [[1.0, 1.0]], None, [[k1], [k2]],
                       input_names=("pan_rate", "omega"), output_names=("visual_servo",))
    s = 1j * np.geomspace(0.01, 100.0, 9)
    expected = {
        ("input", "pan_rate"): k1 * (s + 2) / ((s + 1) * (s + 2 + k2)),
        ("input", "omega"): k2 * (s + 1) / ((s + 2) * (s + 1 + k1)),
        ("output", "visual_servo"): k1 / (s + 1) + k2 / (s + 2),
    }
    full_closed_loop = np.diag([-1.0, -2.0]) - np.array([[k1], [k2]]) @ np.array([[1.0, 1.0]])
    expected_poles = sorted(np.linalg.eigvals(full_closed_loop), key=lambda p: (p.real, p.imag))
    for (kind, name), value in expected.items():
        L = loop_transfer(model, **{f"at_{kind}": name})
        assert (L.ninputs, L.noutputs, L.dt) == (1, 1, 0)
        assert response(L, s.imag) == pytest.approx(value, rel=1e-12)
        index = (model.input_names if kind == "input" else model.output_names).index(name)
        assert response(loop_transfer(model, **{f"at_{kind}": index}), s.imag) == pytest.approx(value, rel=1e-12)
        # 1 + L vanishes at the closed-loop poles of the whole system, whatever the cut
        assert margins(L).closed_loop_poles == pytest.approx(expected_poles, rel=1e-9)


def test_siso_loop_is_K_times_P_at_input_and_output():
    model = loop_model([[0.0, 1.0], [-2.0, -3.0]], [[0.0], [1.0]], [[4.0, 1.0]], [[0.5]], 1.7)
    P = control.ss([[0.0, 1.0], [-2.0, -3.0]], [[0.0], [1.0]], [[4.0, 1.0]], [[0.5]])
    w = np.geomspace(0.01, 100.0, 9)
    for L in (loop_transfer(model, at_input=0), loop_transfer(model, at_output=0)):
        assert response(L, w) == pytest.approx(1.7 * response(P, w), rel=1e-12)


def test_mimo_static_gain_matches_matrix_formula():
    """L_i = e_iᵀ K P (I + E K P)^{-1} e_i with E = I − e_i e_iᵀ, D ≠ 0."""
    rng = np.random.default_rng(3)
    n, m, p = 4, 2, 3
    A = rng.normal(size=(n, n)) - 3.0 * np.eye(n)
    B, C, D = rng.normal(size=(n, m)), rng.normal(size=(p, n)), 0.3 * rng.normal(size=(p, m))
    K = rng.normal(size=(m, p))
    model = loop_model(A, B, C, D, K)
    P = lambda s: C @ np.linalg.solve(s * np.eye(n) - A, B) + D  # noqa: E731
    w = np.geomspace(0.05, 50.0, 6)
    for i in range(m):
        L = loop_transfer(model, at_input=i)
        E = np.eye(m)
        E[i, i] = 0.0
        hand = [(K @ P(1j * x) @ np.linalg.solve(np.eye(m) + E @ K @ P(1j * x), np.eye(m)[:, i]))[i] for x in w]
        assert response(L, w) == pytest.approx(hand, rel=1e-10)
    for j in range(p):
        L = loop_transfer(model, at_output=j)
        E = np.eye(p)
        E[j, j] = 0.0
        hand = [-(P(1j * x) @ -K @ np.linalg.solve(np.eye(p) + E @ P(1j * x) @ K, np.eye(p)[:, j]))[j] for x in w]
        assert response(L, w) == pytest.approx(hand, rel=1e-10)


def test_dynamic_controller_every_cut_gives_the_closed_loop_poles():
    rng = np.random.default_rng(11)
    n, m, p, q = 3, 2, 2, 2
    A, B, C = rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.normal(size=(p, n))
    D = np.zeros((p, m))
    Kss = control.ss(-np.eye(q) + 0.3 * rng.normal(size=(q, q)), rng.normal(size=(q, p)),
                     rng.normal(size=(m, q)), rng.normal(size=(m, p)))
    model = loop_model(A, B, C, D, Kss)
    assert model.controller_dt == 0.0 and model.controller_a.shape == (q, q)
    # u = −(C_K ξ + D_K y), y = C x: [x; ξ]' = [[A − B D_K C, −B C_K], [B_K C, A_K]]
    full = np.block([[A - B @ Kss.D @ C, -B @ Kss.C], [Kss.B @ C, Kss.A]])
    expected = sorted(np.linalg.eigvals(full), key=lambda z: (round(z.real, 9), round(z.imag, 9)))
    for cut in [dict(at_input=0), dict(at_input=1), dict(at_output=0), dict(at_output=1)]:
        poles = margins(loop_transfer(model, **cut)).closed_loop_poles
        assert np.sort_complex(np.array(poles)) == pytest.approx(np.sort_complex(np.array(expected)), rel=1e-8)


# --------------------------------------------------------------------------- sampled loops


def test_sampled_loop_transfer_of_siso_static_loop_equals_sampled_loop():
    model = loop_model([[0.0, 1.0], [0.0, -2.0]], [[0.0], [1.0]], [[3.0, 0.0]], None, 0.8)
    for delay in (0, 1, 2):
        La = sampled_loop_transfer(model, 0.05, at_input=0, delay_samples=delay)
        Lb = sampled_loop(loop_transfer(model, at_input=0), 0.05, delay_samples=delay)
        w = np.geomspace(0.1, 60.0, 8)
        assert response(La, w) == pytest.approx(response(Lb, w), rel=1e-10)
        assert_margins_agree(margins(La), margins(Lb))


def test_sampled_multiloop_closed_loop_poles_by_hand():
    """Plant under ZOH, u_k = −K y_{k−1}: [x; s]_{k+1} = [[Ad, Bd], [−K Cd, −K D]] [x; s]_k."""
    rng = np.random.default_rng(5)
    n, m, p, period = 3, 2, 2, 0.1
    A, B, C = rng.normal(size=(n, n)) - np.eye(n), rng.normal(size=(n, m)), rng.normal(size=(p, n))
    D = 0.2 * rng.normal(size=(p, m))
    K = 0.5 * rng.normal(size=(m, p))
    model = loop_model(A, B, C, D, K, input_names=("pan_rate", "omega"))
    Pd = control.c2d(control.ss(A, B, C, D), period, method="zoh")
    full = np.block([[Pd.A, Pd.B], [-K @ Pd.C, -K @ D]])
    expected = np.sort_complex(np.linalg.eigvals(full))
    for cut in [dict(at_input="pan_rate"), dict(at_input="omega"), dict(at_output=1)]:
        Lz = sampled_loop_transfer(model, period, delay_samples=1, **cut)
        assert Lz.dt == period
        m_ = margins(Lz)
        assert np.sort_complex(np.array(m_.closed_loop_poles)) == pytest.approx(expected, rel=1e-8, abs=1e-12)
        assert m_.closed_loop_stable == bool(np.all(np.abs(expected) < 1.0))


def test_sampled_loop_transfer_with_discrete_controller():
    period = 0.1
    model = loop_model([[-1.0]], [[1.0]], [[1.0]], None, control.ss([[0.5]], [[1.0]], [[0.4]], [[1.0]], period))
    assert model.controller_dt == period
    Lz = sampled_loop_transfer(model, period, at_input=0, delay_samples=0)
    Pd = control.c2d(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), period, method="zoh")
    Kz = control.ss([[0.5]], [[1.0]], [[0.4]], [[1.0]], period)
    w = np.geomspace(0.1, 30.0, 6)
    assert response(Lz, w) == pytest.approx(response(Kz, w) * response(Pd, w), rel=1e-12)


# --------------------------------------------------------------------------- frequency response and results


def test_frequency_response_data_of_an_integrator():
    k = 2.0
    w = np.geomspace(0.1, 100.0, 50)
    fr = frequency_response_data(control.tf([k], [1.0, 0.0]), w, name="integrator")
    assert isinstance(fr, LoopFrequencyResponse) and fr.period is None and fr.name == "integrator"
    assert fr.magnitude_db == pytest.approx(20.0 * np.log10(k / w), rel=1e-12)
    assert fr.phase_deg == pytest.approx(np.full(w.size, -90.0), abs=1e-12)
    assert fr.nyquist_real == pytest.approx(np.zeros(w.size), abs=1e-12)
    assert fr.nyquist_imag == pytest.approx(-k / w, rel=1e-12)
    for array in (fr.omega, fr.magnitude_db, fr.phase_deg, fr.nyquist_real, fr.nyquist_imag):
        assert not array.flags.writeable
    json.dumps(fr.as_dict(), allow_nan=False)


def test_frequency_response_phase_is_unwrapped_past_minus_180():
    w = np.geomspace(0.01, 100.0, 400)
    fr = frequency_response_data(control.tf([1.0], [1.0, 3.0, 3.0, 1.0, 0.0]), w)  # 1 / (s (s+1)^3)
    expected = -90.0 - 3.0 * np.degrees(np.arctan(w))
    assert fr.phase_deg == pytest.approx(expected, abs=1e-9)
    assert fr.phase_deg[-1] < -300.0


def test_frequency_response_of_sampled_loop_uses_unit_circle():
    Lz = sampled_loop(control.tf([2.0], [1.0, 0.0]), 0.1)
    w = np.geomspace(0.1, 30.0, 20)
    fr = frequency_response_data(Lz, w)
    z = np.exp(1j * w * 0.1)
    value = 0.2 / (z * (z - 1.0))
    assert fr.period == 0.1
    assert fr.nyquist_real + 1j * fr.nyquist_imag == pytest.approx(value, rel=1e-12)
    assert fr.phase_deg == pytest.approx(-90.0 - np.degrees(1.5 * w * 0.1), abs=1e-9)


def test_margins_result_is_frozen_and_json_ready():
    m = margins(control.tf([2.0], [1.0, 0.0]), name="pan")
    assert isinstance(m, Margins) and m.name == "pan"
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.gain_margin = 1.0  # type: ignore[misc]
    data = m.as_dict()
    text = json.dumps(data, allow_nan=False)
    assert data["gain_margin"] is None and data["gain_margin_db"] is None
    assert data["phase_crossover_frequency"] is None
    assert data["phase_margin_deg"] == pytest.approx(90.0)
    assert data["closed_loop_poles"] == [[pytest.approx(-2.0), pytest.approx(0.0)]]
    assert data["open_loop_stable"] is True and "delay_margin_s" in text


def test_loop_model_is_frozen_with_read_only_arrays():
    model = loop_model([[-1.0]], [[1.0]], [[1.0]], None, 2.0)
    assert isinstance(model, LoopModel)
    assert model.input_names == ("u0",) and model.output_names == ("y0",)
    assert model.controller_dt is None and model.controller_d.shape == (1, 1)
    with pytest.raises(ValueError):
        model.plant_a[0, 0] = 3.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        model.plant_a = np.eye(1)  # type: ignore[misc]
    json.dumps(model.as_dict(), allow_nan=False)


def test_margins_as_dict_lists_every_field_then_open_loop_stable():
    m = margins(control.tf([3.0], [1.0, -1.0]), name="unstable")
    data = m.as_dict()
    assert list(data) == [f.name for f in dataclasses.fields(Margins)] + ["open_loop_stable"]
    assert data["open_loop_stable"] is False and data["open_loop_unstable_poles"] == 1
    assert data["lower_gain_margin"] == pytest.approx(1.0 / 3.0) and data["period"] is None
    assert data["closed_loop_poles"] == [[pytest.approx(-2.0), pytest.approx(0.0)]]
    assert all(isinstance(note, str) for note in data["notes"])
    assert json.loads(json.dumps(data, allow_nan=False)) == data


def test_frequency_response_as_dict_writes_nonfinite_as_null():
    fr = frequency_response_data(control.tf([1.0], [1.0, 0.0, 1.0]), np.array([0.5, 2.0]), name="osc")
    data = fr.as_dict()
    assert list(data) == ["name", "period", "omega", "magnitude_db", "phase_deg", "nyquist_real", "nyquist_imag"]
    assert data["omega"] == [0.5, 2.0] and data["name"] == "osc" and data["period"] is None
    assert data["nyquist_real"] == pytest.approx([1.0 / 0.75, -1.0 / 3.0])
    silent = dataclasses.replace(fr, magnitude_db=np.array([-math.inf, 1.0]))
    assert silent.as_dict()["magnitude_db"] == [None, 1.0]


def test_loop_model_as_dict_groups_plant_and_controller():
    model = loop_model([[0.0, 1.0], [-2.0, -3.0]], [[0.0], [1.0]], np.eye(2), None, [[1.0, 0.5]],
                       input_names=("u",), output_names=("p", "q"))
    data = model.as_dict()
    assert list(data) == ["plant", "controller", "input_names", "output_names"]
    assert data["plant"] == {"A": [[0.0, 1.0], [-2.0, -3.0]], "B": [[0.0], [1.0]], "C": [[1.0, 0.0], [0.0, 1.0]],
                             "D": [[0.0], [0.0]]}
    assert data["controller"] == {"A": [], "B": [], "C": [[]], "D": [[1.0, 0.5]], "dt": None}
    assert data["input_names"] == ["u"] and data["output_names"] == ["p", "q"]


def test_importing_margins_does_not_import_matplotlib():
    code = "import sys, analysis.margins; sys.exit(1 if 'matplotlib' in sys.modules else 0)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


# --------------------------------------------------------------------------- errors


def test_error_classes_are_value_errors():
    for cls in (LoopShapeError, NonFiniteLoopError, LoopTypeError, LoopBreakError, SamplingError, FrequencyGridError):
        assert issubclass(cls, LoopDefinitionError) and issubclass(cls, ValueError)
    assert issubclass(LoopTypeError, TypeError)


def test_bad_shapes_raise():
    with pytest.raises(LoopShapeError, match=r"A has shape \(2, 3\): expected a square"):
        loop_model(np.zeros((2, 3)), np.zeros((2, 1)), np.zeros((1, 2)), None, 1.0)
    with pytest.raises(LoopShapeError, match=r"B has shape \(3, 1\): expected 2 x \? \(rows: n = A.shape\[0\]"):
        loop_model(np.zeros((2, 2)), np.zeros((3, 1)), np.zeros((1, 2)), None, 1.0)
    with pytest.raises(LoopShapeError, match=r"C has shape \(1, 3\)"):
        loop_model(np.zeros((2, 2)), np.zeros((2, 1)), np.zeros((1, 3)), None, 1.0)
    with pytest.raises(LoopShapeError, match=r"D has shape \(2, 2\): expected 1 x 1"):
        loop_model(np.zeros((2, 2)), np.zeros((2, 1)), np.zeros((1, 2)), np.zeros((2, 2)), 1.0)
    with pytest.raises(LoopShapeError, match=r"K \(D_K\) has shape \(3, 2\): expected 2 x 3.*transpose"):
        loop_model(np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((3, 2)), None, np.zeros((3, 2)))
    with pytest.raises(LoopShapeError, match=r"B has shape \(2,\): expected a 2-D matrix; reshape"):
        loop_model(np.zeros((2, 2)), np.zeros(2), np.zeros((1, 2)), None, 1.0)
    with pytest.raises(LoopShapeError, match=r"K has 1 inputs and 1 outputs: expected p = 1 inputs .* m = 2"):
        loop_model(np.zeros((2, 2)), np.eye(2), np.zeros((1, 2)), None, control.tf([1.0], [1.0, 1.0]))
    with pytest.raises(LoopShapeError, match=r"input_names = \('a',\): expected 2 distinct"):
        loop_model(np.zeros((2, 2)), np.eye(2), np.zeros((1, 2)), None, np.ones((2, 1)), input_names=("a",))


def test_nan_matrices_raise():
    with pytest.raises(NonFiniteLoopError, match=r"A\[0, 1\] = nan: every entry must be finite"):
        loop_model([[0.0, math.nan], [0.0, 0.0]], np.zeros((2, 1)), np.zeros((1, 2)), None, 1.0)
    with pytest.raises(NonFiniteLoopError, match=r"K \(D_K\)\[0, 0\] = inf"):
        loop_model(np.zeros((2, 2)), np.zeros((2, 1)), np.zeros((1, 2)), None, math.inf)
    with pytest.raises(NonFiniteLoopError, match=r"L.D\[0, 0\] = nan"):
        margins(control.ss([[-1.0]], [[1.0]], [[1.0]], [[math.nan]]))


def test_bad_sampling_raises():
    L = control.tf([1.0], [1.0, 0.0])
    for period in (0.0, -0.1, math.nan, math.inf, "0.1", True):
        with pytest.raises(SamplingError, match=r"period = .*: expected a positive finite sampling period"):
            sampled_loop(L, period)
    for delay in (-1, 1.5, True):
        with pytest.raises(SamplingError, match=r"delay_samples = .*: expected a non-negative integer"):
            sampled_loop(L, 0.1, delay_samples=delay)
    with pytest.raises(SamplingError, match=r"L is already discrete \(dt = 0.1 s\)"):
        sampled_loop(sampled_loop(L, 0.1), 0.1)
    model = loop_model([[-1.0]], [[1.0]], [[1.0]], None, control.tf([1.0], [1.0, 1.0]))
    with pytest.raises(SamplingError, match=r"controller is continuous with 1 states.*c2d"):
        sampled_loop_transfer(model, 0.1, at_input=0)
    model = loop_model([[-1.0]], [[1.0]], [[1.0]], None, control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.2))
    with pytest.raises(SamplingError, match=r"dt = 0.2 s but period = 0.1 s"):
        sampled_loop_transfer(model, 0.1, at_input=0)
    with pytest.raises(SamplingError, match=r"controller is discrete \(dt = 0.2 s\).*sampled_loop_transfer"):
        loop_transfer(model, at_input=0)
    with pytest.raises(SamplingError, match=r"period = -1: expected a positive"):
        sampled_loop_transfer(model, -1, at_input=0)


def test_bad_break_points_raise():
    model = loop_model(np.diag([-1.0, -2.0]), np.eye(2), [[1.0, 1.0]], None, [[1.0], [2.0]],
                       input_names=("pan_rate", "omega"), output_names=("visual_servo",))
    with pytest.raises(LoopBreakError, match=r"give exactly one break point, e.g. at_input='pan_rate'"):
        loop_transfer(model)
    with pytest.raises(LoopBreakError, match=r"give exactly one break point"):
        loop_transfer(model, at_input=0, at_output=0)
    with pytest.raises(LoopBreakError, match=r"at_input = 'v': not a plant input name; known: pan_rate, omega"):
        loop_transfer(model, at_input="v")
    with pytest.raises(LoopBreakError, match=r"at_output = 1: expected a name \(visual_servo\) or an index in 0..0"):
        loop_transfer(model, at_output=1)
    with pytest.raises(LoopTypeError, match=r"expected a LoopModel"):
        loop_transfer("plant", at_input=0)  # type: ignore[arg-type]


def test_ill_posed_loops_raise():
    # two inputs, one output, D = [1, 1], K = [[-0.5], [-1]]: cutting u0 leaves 1 + K_1 D_1 = 0
    model = loop_model([[-1.0]], [[1.0, 1.0]], [[1.0]], [[1.0, 1.0]], [[-0.5], [-1.0]])
    with pytest.raises(LoopBreakError, match=r"cut at input 'u0': I \+ D_K D .* is singular .* not well-posed"):
        loop_transfer(model, at_input=0)
    with pytest.raises(LoopBreakError, match=r"1 \+ D = 0, so the closed loop 1/\(1 \+ L\) is not well-posed"):
        margins(control.ss([[-1.0]], [[1.0]], [[1.0]], [[-1.0]]))


def test_bad_loops_for_margins_raise():
    with pytest.raises(LoopTypeError, match=r"expected a python-control StateSpace or TransferFunction"):
        margins([1.0, 2.0])
    with pytest.raises(LoopTypeError, match=r"L has 2 inputs and 1 outputs: expected a SISO loop transfer"):
        margins(control.ss([[-1.0]], [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]]))
    with pytest.raises(LoopTypeError, match=r"dt = True"):
        margins(control.tf([1.0], [1.0, -0.5], True))
    with pytest.raises(LoopTypeError, match=r"L is not proper"):
        margins(control.tf([1.0, 0.0, 0.0], [1.0, 1.0]))


def test_bad_frequency_grids_raise():
    L = control.tf([1.0], [1.0, 0.0])
    with pytest.raises(FrequencyGridError, match=r"w_min = 0.0, w_max = 10.0: expected 0 < w_min < w_max"):
        margins_by_sweep(L, w_min=0.0, w_max=10.0)
    with pytest.raises(FrequencyGridError, match=r"expected 0 < w_min < w_max"):
        margins_by_sweep(L, w_min=10.0, w_max=1.0)
    with pytest.raises(FrequencyGridError, match=r"points = 1: expected an integer >= 2"):
        margins_by_sweep(L, w_min=1.0, w_max=10.0, points=1)
    with pytest.raises(FrequencyGridError, match=r"exceeds the Nyquist frequency π/T = 31.4159 rad/s"):
        margins_by_sweep(sampled_loop(L, 0.1), w_min=1.0, w_max=40.0)
    with pytest.raises(FrequencyGridError, match=r"expected positive, finite, strictly increasing"):
        frequency_response_data(L, [1.0, 0.5])
    with pytest.raises(FrequencyGridError, match=r"expected positive"):
        frequency_response_data(L, [0.0, 1.0])
    with pytest.raises(FrequencyGridError, match=r"expected a non-empty 1-D array"):
        frequency_response_data(L, np.ones((2, 2)))
    with pytest.raises(FrequencyGridError, match=r"ω = 2 rad/s is a pole of L"):
        frequency_response_data(control.ss([[0.0, 2.0], [-2.0, 0.0]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]]), [1.0, 2.0])


def test_bad_controllers_raise():
    with pytest.raises(SamplingError, match=r"controller_dt = 'x' with a 1-state controller: expected 0.0"):
        LoopModel(plant_a=[[-1.0]], plant_b=[[1.0]], plant_c=[[1.0]], plant_d=[[0.0]], controller_a=[[-1.0]],
                  controller_b=[[1.0]], controller_c=[[1.0]], controller_d=[[0.0]], controller_dt="x")
    with pytest.raises(SamplingError, match=r"K has dt = True"):
        loop_model([[-1.0]], [[1.0]], [[1.0]], None, control.tf([1.0], [1.0, -0.5], True))
    with pytest.raises(LoopTypeError, match=r"K = 'gain': expected an \(m, p\) = \(1, 1\) gain matrix"):
        loop_model([[-1.0]], [[1.0]], [[1.0]], None, "gain")
    with pytest.raises(LoopTypeError, match=r"cannot be written in state-space form"):
        loop_model([[-1.0]], [[1.0]], [[1.0]], None, control.tf([1.0, 0.0, 0.0], [1.0, 1.0]))


def test_bad_sweep_options_raise():
    L = control.tf([1.0], [1.0, 0.0])
    with pytest.raises(FrequencyGridError, match=r"min_frequency = -1.0: expected a finite frequency >= 0"):
        margins(L, min_frequency=-1.0)
    with pytest.raises(FrequencyGridError, match=r"w_min = 'a', w_max = 10.0: expected numbers"):
        margins_by_sweep(L, w_min="a", w_max=10.0)


# --------------------------------------------------------------------------- open-loop poles on the boundary


def test_open_loop_poles_on_the_imaginary_axis_are_not_phase_crossovers():
    """L = (2s + 1)/(s² + 4): poles ±2j; closed loop s² + 2g s + 4 + g is stable for every g > 0.

    python-control's polynomial solver returns ω = 2 as a phase crossover (Im(num·conj den)
    vanishes with den) with |L| = ∞, i.e. a "gain margin" of about 1e-17 (−340 dB).  It is not
    a crossing of the negative real axis: dropped, the boundary poles named in a note.
    """
    import control as ct

    _, _, _, w_pc, _, _ = ct.stability_margins(ct.tf([2.0, 1.0], [1.0, 0.0, 4.0]), returnall=True, method="poly")
    assert any(abs(w - 2.0) < 1e-9 for w in np.real(w_pc))  # the artefact this guards against
    for m in both(control.tf([2.0, 1.0], [1.0, 0.0, 4.0])):
        assert m.open_loop_boundary_poles == 2 and m.closed_loop_stable
        assert m.phase_crossovers == ()
        assert m.gain_margin == math.inf and m.lower_gain_margin is None
        assert any("poles on the imaginary axis at ω = 2 rad/s" in note for note in m.notes)


def test_upper_gain_margin_is_reported_beside_boundary_poles():
    """L = (2s − 1)/(s² + 4): closed loop s² + 2g s + 4 − g, stable iff 0 < g < 4: upper margin 4 at ω = 0."""
    for m in both(control.tf([2.0, -1.0], [1.0, 0.0, 4.0])):
        assert m.closed_loop_stable
        assert m.gain_margin == pytest.approx(4.0, **CLOSED_FORM)
        assert m.phase_crossover_frequency == 0.0
        assert m.lower_gain_margin is None
