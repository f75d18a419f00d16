import json
import math

import casadi as ca
import numpy as np
import pytest

from analysis.linearise import (
    LinearisationError,
    NotAnEquilibriumError,
    common_quadratic_lyapunov,
    eigen_modes,
    linearise,
    quadratic_lyapunov,
)


def test_damped_oscillator_modes_in_closed_form():
    """ẍ + 2ζω ẋ + ω² x = 0: eigenvalues −ζω ± iω sqrt(1 − ζ²)."""
    zeta, omega = 0.3, 2.0
    modes = eigen_modes(np.array([[0.0, 1.0], [-omega**2, -2 * zeta * omega]]))
    for m in modes:
        assert m.damping_ratio == pytest.approx(zeta, rel=1e-12)
        assert m.natural_frequency_radps == pytest.approx(omega, rel=1e-12)
        assert m.time_constant_s == pytest.approx(1 / (zeta * omega), rel=1e-12)
    assert {round(m.imag, 12) for m in modes} == {round(omega * math.sqrt(1 - zeta**2), 12),
                                                  -round(omega * math.sqrt(1 - zeta**2), 12)}


def test_linearise_reports_non_hurwitz_without_raising():
    x = ca.SX.sym("x", 2)
    integrator = ca.Function("F", [x], [ca.vertcat(x[1], -x[1])])  # a continuum of equilibria x2 = 0
    lin = linearise(integrator, (0.7, 0.0), state_names=("p", "q"))
    assert not lin.hurwitz and "imaginary axis" in lin.finding
    unstable = ca.Function("G", [x], [ca.vertcat(x[0], -x[1])])
    assert "unstable" in linearise(unstable, (0.0, 0.0), state_names=("p", "q")).finding


def test_linearise_validates_shapes():
    x = ca.SX.sym("x", 2)
    f = ca.Function("F", [x], [x])
    with pytest.raises(LinearisationError, match="point has 3 components"):
        linearise(f, (0.0, 0.0, 0.0), state_names=("a", "b"))
    with pytest.raises(LinearisationError, match="not finite"):
        linearise(f, (math.nan, 0.0), state_names=("a", "b"))


def test_quadratic_lyapunov_solves_the_equation():
    a = np.array([[0.0, 1.0], [-2.0, -3.0]])
    lyap = quadratic_lyapunov(a)
    assert lyap.valid and lyap.residual < 1e-12
    np.testing.assert_allclose(a.T @ lyap.P + lyap.P @ a, -np.eye(2), atol=1e-12)
    assert lyap.decay_rate == pytest.approx(1 / np.linalg.eigvalsh(lyap.P).max(), rel=1e-12)
    assert not quadratic_lyapunov(np.array([[0.0, 1.0], [0.0, 0.0]])).valid


def test_common_lyapunov_found_for_commuting_stable_pair():
    a1 = np.array([[-1.0, 0.0], [0.0, -2.0]])
    a2 = np.array([[-3.0, 0.0], [0.0, -0.5]])  # diagonal: P = I works
    result = common_quadratic_lyapunov([a1, a2], ["fast", "slow"])
    assert result.found and result.dwell_time_s == 0.0
    for a in (a1, a2):
        assert np.linalg.eigvalsh(a.T @ result.P + result.P @ a).max() < 0


def test_no_common_lyapunov_for_the_classic_destabilising_pair_gives_a_dwell_time():
    """Two stable oscillators whose switching can diverge: no common quadratic V exists."""
    a1 = np.array([[-0.1, 1.0], [-10.0, -0.1]])
    a2 = np.array([[-0.1, 10.0], [-1.0, -0.1]])
    result = common_quadratic_lyapunov([a1, a2])
    assert not result.found and result.worst_margin > 0
    assert 0 < result.dwell_time_s < math.inf
    # switching every 0.25 s (a quarter turn of each) grows the state: the dwell time is not vacuous
    from scipy.linalg import expm

    grow = expm(a2 * (math.pi / 2 / math.sqrt(10))) @ expm(a1 * (math.pi / 2 / math.sqrt(10)))
    assert max(abs(np.linalg.eigvals(grow))) > 1


# --------------------------------------------------------------------------- JSON views


def test_eigen_mode_as_dict_writes_nonfinite_as_null():
    zero, = (m for m in eigen_modes(np.array([[0.0, 0.0], [0.0, -1.0]])) if m.real == 0.0)
    assert zero.as_dict() == {"real": 0.0, "imag": 0.0, "damping_ratio": None, "natural_frequency_radps": 0.0,
                              "time_constant_s": None}


def test_linearisation_as_dict_derives_norm_eigenvalues_and_finding():
    x = ca.SX.sym("x", 2)
    F = ca.Function("F", [x], [ca.vertcat(x[1], -2.0 * x[0] - 3.0 * x[1])])
    lin = linearise(F, (0.0, 0.0), state_names=("p", "q"), name="pq")
    data = lin.as_dict()
    assert list(data) == ["name", "state_names", "point", "residual_norm", "jacobian", "eigenvalues", "modes",
                          "hurwitz", "spectral_abscissa", "finding"]
    assert data["name"] == "pq" and data["state_names"] == ["p", "q"] and data["point"] == [0.0, 0.0]
    assert data["residual_norm"] == 0.0 and data["jacobian"] == [[0.0, 1.0], [-2.0, -3.0]]
    assert data["eigenvalues"] == [[pytest.approx(-2.0), 0.0], [pytest.approx(-1.0), 0.0]]
    assert data["modes"] == [m.as_dict() for m in lin.modes]
    assert data["hurwitz"] is True and data["finding"] == lin.finding
    json.dumps(data, allow_nan=False)


def test_lyapunov_as_dicts_list_every_field_and_null_the_nonfinite():
    good = quadratic_lyapunov(np.diag([-1.0, -2.0])).as_dict()
    assert list(good) == ["P", "Q", "valid", "decay_rate", "residual"]
    assert good["P"] == [[0.5, 0.0], [0.0, 0.25]] and good["valid"] is True and good["decay_rate"] == 2.0
    bad = quadratic_lyapunov(np.diag([1.0, -1.0])).as_dict()
    assert bad == {"P": [[None, None], [None, None]], "Q": [[1.0, 0.0], [0.0, 1.0]], "valid": False,
                   "decay_rate": None, "residual": None}
    none = common_quadratic_lyapunov([np.diag([-1.0, -2.0]), np.eye(2)], ("a", "b")).as_dict()
    assert none == {"names": ["a", "b"], "found": False, "P": None, "worst_margin": None, "dwell_time_s": None}
    for data in (good, bad, none):
        json.dumps(data, allow_nan=False)


def test_a_hybrid_mode_is_linearised_against_its_invariant():
    """The thermostat's modes: 10 °C and 30 °C are equilibria of the flows but outside their modes."""
    from analysis.equilibria import ModeEquilibrium
    from hybrid.examples import thermostat

    system = thermostat().system
    off = linearise(system, (10.0,), mode="off")
    assert isinstance(off, ModeEquilibrium) and off.kind == "virtual" and "virtual equilibrium" in off.finding
    assert off.point == pytest.approx((10.0,), abs=1e-12) and off.jacobian[0][0] == pytest.approx(-0.1, rel=1e-12)
    with pytest.raises(NotAnEquilibriumError, match=r"mode 'off': the point \{'T': 20\.0\} is not an equilibrium"):
        linearise(system, (20.0,), mode="off")
    with pytest.raises(LinearisationError, match=r"mode = None; expected one of \['off', 'on'\]"):
        linearise(system, (10.0,))
    with pytest.raises(LinearisationError, match=r"point = \[10\.0, 1\.0\]; expected 1 finite values"):
        linearise(system, (10.0, 1.0), mode="off")
