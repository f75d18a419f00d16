"""analysis.mode_region: a mode's region of attraction, proven by branch and bound, as a hybrid-system claim.

Van der Pol in reverse time (x' = -y, y' = x + (x^2 - 1) y): the origin is stable and its region of
attraction is bounded by the unstable limit cycle, which crosses the x-axis at |x| ~ 2.01.  Every
certified set must lie inside it: its boundary points converge under the true flow, and the hybrid
executor itself never leaves the mode from them.
"""

from __future__ import annotations

import copy
import json
import math
from fractions import Fraction

import casadi as ca
import cvxpy as cp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import analysis.mode_region as mode_region_module
from analysis.mode_region import (
    ModeRegion,
    mode_polynomials,
    mode_region_of_attraction,
    recheck_mode_region,
)
from analysis.polynomial import Polynomial
from analysis.sublevel import SublevelCertificate, lie_derivative, recheck_bound, recheck_sublevel
from hybrid import HybridAutomaton, HybridSystem, Mode, Transition, all_of, simulate_continuous
from hybrid.errors import ParameterError

LIMIT_CYCLE_X = 2.01
"""Where the unstable limit cycle of reversed Van der Pol crosses the x-axis (|x|, to 2 decimals: 2.0086)."""


def _vdp(t, x, m):
    return (-x[1], x[0] + (x[0] ** 2 - 1) * x[1])


def _vdp_rhs(_t, s):
    return [-s[1], s[0] + (s[0] ** 2 - 1) * s[1]]


def _system(*, invariant=None, invariant_text="", transitions=(), flow=_vdp, names=("x", "y"), other=None):
    """Mode 'q' with ``flow`` (and a mode 'r' for the transitions to go to)."""
    automaton = HybridAutomaton(name="roa", modes=(Mode(name="q", invariant=invariant, invariant_text=invariant_text),
                                                   Mode(name="r")),
                                transitions=transitions, variables=names, initial_mode="q")
    return HybridSystem(automaton=automaton, state_names=names, flows={"q": flow, "r": other or flow})


VDP = _system()


@pytest.fixture(scope="module")
def quadratic() -> ModeRegion:
    return mode_region_of_attraction(VDP, "q")


@pytest.fixture(scope="module")
def quartic() -> ModeRegion:
    return mode_region_of_attraction(VDP, "q", degree=4)


def _lyapunov(region: ModeRegion) -> Polynomial:
    """``V`` in the shifted coordinates ``Δx = x − x*`` (read back from its exact coefficients)."""
    return region.lyapunov_polynomial()


def _boundary(region: ModeRegion, count: int = 720) -> np.ndarray:
    """Points of ``{V = level}`` along rays from x* (bisection on each ray), shape (count, 2)."""
    v = _lyapunov(region)
    theta = np.linspace(0.0, 2.0 * math.pi, count, endpoint=False)
    rays = np.column_stack([np.cos(theta), np.sin(theta)])
    lo, hi = np.zeros(count), np.full(count, 10.0)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        inside = np.array([v.evaluate_at(dict(zip(region.variables, r * m))) <= region.level
                           for r, m in zip(rays, mid)])
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    return np.asarray(region.equilibrium) + rays * lo[:, None]


def _area(points: np.ndarray, center: np.ndarray) -> float:
    r2 = np.sum((points - center) ** 2, axis=1)
    return float(0.5 * np.sum(r2) * 2.0 * math.pi / len(points))


# --------------------------------------------------------------------------- Van der Pol: proven and inside the truth


def test_van_der_pol_quadratic_region_is_proven_with_its_precise_claim(quadratic):
    r = quadratic
    assert r.status == "proven" and r.rechecked and r.why == ""
    assert r.equilibrium == (0.0, 0.0) and r.lyapunov == "1.5*x^2 - x*y + y^2"
    # the SOS level of this V is about 2.30 (Drake's example); the proven level sits just below it
    assert 2.1 < r.level < 2.31 and 0.0 < r.inner_level < 0.1 * r.level
    assert 0 < r.time_bound_s < 200 and r.convergence_rate > 0.1 and r.equilibrium_radius == 0.0
    assert set(r.certificates) == {"sublevel", "time", "inner", "invariant", "guards"}
    assert r.certificates["sublevel"]["certified"] and r.certificates["sublevel"]["strict"]
    for text in ("stays in 'q'", "positively invariant", f"V(x) <= {r.level!r}", "x_e = x* (f(x*) = 0 exactly)",
                 "no transition leaves 'q'", "contracts"):
        assert text in r.claim
    assert recheck_mode_region(VDP, r) == ()


@pytest.mark.parametrize("which", ["quadratic", "quartic"])
def test_the_certified_set_lies_inside_the_true_region_of_attraction(which, request):
    r = request.getfixturevalue(which)
    assert r.status == "proven"
    edge = _boundary(r)
    assert np.abs(edge[:, 0]).max() < LIMIT_CYCLE_X
    v = _lyapunov(r)
    for point in edge[::60]:
        sol = solve_ivp(_vdp_rhs, (0.0, 40.0), point, rtol=1e-9, atol=1e-12, dense_output=True)
        assert np.hypot(*sol.y[:, -1]) < 1e-3
        ts = np.linspace(0.0, 40.0, 400)
        along = [v.evaluate_at(dict(zip(r.variables, sol.sol(t)))) for t in ts]
        assert max(along) <= r.level * (1 + 1e-6)  # S is invariant along the true flow
    # the time bound is an upper bound: by then the solution is in {V <= c_in}
    sol = solve_ivp(_vdp_rhs, (0.0, r.time_bound_s), edge[0], rtol=1e-9, atol=1e-12)
    assert v.evaluate_at(dict(zip(r.variables, sol.y[:, -1]))) <= r.inner_level


def test_degree_four_certifies_a_larger_set_than_degree_two(quadratic, quartic):
    # measured, not assumed: areas of {V <= c} from the boundary points
    small, large = _area(_boundary(quadratic), np.zeros(2)), _area(_boundary(quartic), np.zeros(2))
    assert quartic.status == "proven" and quartic.rechecked and quartic.degree == 4
    assert "x^4" in quartic.lyapunov
    assert math.isclose(small, math.pi * quadratic.level / math.sqrt(1.25), rel_tol=1e-3)  # the ellipse's area
    assert large > 1.3 * small  # about 9.35 against 6.28 (the true region is about 10)
    assert recheck_mode_region(VDP, quartic) == ()


# --------------------------------------------------------------------------- the mode's invariant and guards


def test_an_invariant_limits_the_level_and_the_set_stays_inside_it():
    system = _system(invariant=all_of(lambda v, m: 0.5 - v[0], lambda v, m: v[0] + 3.0),
                     invariant_text="-3 <= x <= 0.5")
    r = mode_region_of_attraction(system, "q")
    assert r.status == "proven" and r.rechecked
    # V = z'Pz with P = [[1.5, -0.5], [-0.5, 1]]: {V <= c} reaches x = 0.5 at c = 0.25/(P^-1)_xx = 0.3125
    assert 0.9 * 0.3125 < r.level < 0.3125
    assert _boundary(r)[:, 0].max() < 0.5
    assert [e["index"] for e in r.certificates["invariant"]] == [0, 1]
    assert all(float.fromhex(e["certificate"]["bound"]) < 0 for e in r.certificates["invariant"])
    assert "-3 <= x <= 0.5" in r.claim and "limited by invariant term 0" in r.search
    assert recheck_mode_region(system, r) == ()


def test_a_guard_limits_the_level_and_the_executor_never_jumps_from_the_set():
    jump = Transition(name="up", source="q", target="r", guard=lambda v, m: v[1] - 0.8, guard_text="y >= 0.8")
    system = _system(transitions=(jump,), other=lambda t, x, m: (1.0, 0.0))
    r = mode_region_of_attraction(system, "q")
    assert r.status == "proven" and r.rechecked
    assert 0.9 * 0.64 / 1.2 < r.level < 0.64 / 1.2  # {V <= c} reaches y = 0.8 at c = 0.64/(P^-1)_yy
    edge = _boundary(r)
    assert edge[:, 1].max() < 0.8
    assert [(e["transition"], e["index"]) for e in r.certificates["guards"]] == [("up", 0)]
    assert "'up': guard of transition 'up' (y >= 0.8)" in r.claim
    for point in edge[::90]:
        run = simulate_continuous(system, tuple(point), duration=30.0, initial_mode="q")
        assert run.events == () and run.final_mode == "q" and np.hypot(*run.final_state) < 1e-3
    # the guard of a conjunction is disabled as soon as one of its terms is negative on S
    both = Transition(name="up", source="q", target="r", guard=all_of(lambda v, m: v[1] - 0.8, lambda v, m: -1.0))
    r2 = mode_region_of_attraction(_system(transitions=(both,)), "q")
    assert r2.status == "proven" and r2.level > 2.0 and r2.certificates["guards"][0]["index"] == 1


def test_quartic_with_an_invariant_stays_inside_it():
    system = _system(invariant=lambda v, m: 0.5 - v[0], invariant_text="x <= 0.5")
    r = mode_region_of_attraction(system, "q", degree=4)
    assert r.status == "proven" and r.rechecked
    assert _boundary(r)[:, 0].max() < 0.5


def test_an_equilibrium_away_from_the_origin_not_exactly_representable():
    # competitive Lotka-Volterra: x* = (2/3, 2/3) is not a float, so f(x*) = 0 only up to rounding
    system = _system(invariant=all_of(lambda v, m: v[0], lambda v, m: v[1]), invariant_text="x >= 0 and y >= 0",
                     flow=lambda t, x, m: (x[0] * (1 - x[0] - 0.5 * x[1]), x[1] * (1 - x[1] - 0.5 * x[0])))
    r = mode_region_of_attraction(system, "q", guess=(0.5, 0.5))
    assert r.status == "proven" and r.rechecked
    assert np.allclose(r.equilibrium, (2 / 3, 2 / 3), atol=1e-12)
    assert 0.0 < r.equilibrium_radius < 1e-12 and "|x_e - x*| <=" in r.claim
    assert r.variables == ("Δx", "Δy") and "Δx = x - 0.6666666666666" in r.claim
    edge = _boundary(r)
    assert edge.min() > 0.0  # inside the invariant x, y >= 0
    for point in edge[::120]:
        sol = solve_ivp(lambda _t, s: [s[0] * (1 - s[0] - 0.5 * s[1]), s[1] * (1 - s[1] - 0.5 * s[0])],
                        (0.0, 60.0), point, rtol=1e-10, atol=1e-12)
        assert np.allclose(sol.y[:, -1], (2 / 3, 2 / 3), atol=1e-6)
    assert recheck_mode_region(system, r) == ()


# --------------------------------------------------------------------------- not applicable, not proven


@pytest.mark.parametrize("flow, needle", [
    (lambda t, x, m: (-x[1], math.sin(x[0]) + (x[0] ** 2 - 1) * x[1]), "converts the state to a float"),
    (lambda t, x, m: (-x[1], (ca.sin(x[0]) if isinstance(x[0], ca.SX) else math.sin(x[0])) - x[1]), "uses sin"),
    (lambda t, x, m: (-x[1], x[0] / (1 + x[1] ** 2) - x[1]), "division by a state-dependent expression"),
    (lambda t, x, m: (-x[1], x[0] - x[1] + 0.1 * t * x[0]), "depends on the time t"),
])
def test_a_non_polynomial_or_timed_flow_is_not_applicable_naming_mode_component_and_function(flow, needle):
    r = mode_region_of_attraction(_system(flow=flow), "q")
    assert r.status == "not applicable" and r.level is None and r.certificates == {}
    assert r.why.startswith("the flow (component dy/dt) of mode 'q' is not polynomial in the state")
    assert needle in r.why
    assert json.dumps(r.as_dict(), allow_nan=False)


def test_a_flow_whose_traced_expression_differs_from_its_values_is_refused():
    # traces to x - y but evaluates to x - 2y: the probe comparison catches the mismatch
    def two_faced(t, x, m):
        return (-x[1], x[0] - (2.0 if isinstance(x[0], float) else 1.0) * x[1])

    r = mode_region_of_attraction(_system(flow=two_faced), "q")
    assert r.status == "not applicable" and "traced" in r.why and "branches on the state" in r.why


def test_a_symbolic_model_is_traced_term_by_term():
    from hybrid.symbolic import coordinates, flow_map

    v = coordinates("x", "y")
    automaton = HybridAutomaton(
        name="sym", modes=(Mode(name="q", invariant=(v.x <= 0.5) & (v.y >= -3.0)), Mode(name="r")),
        transitions=(Transition(name="up", source="q", target="r", guard=v.y >= 0.8),), variables=("x", "y"),
        initial_mode="q")
    system = HybridSystem(automaton=automaton, state_names=("x", "y"),
                          flows={"q": flow_map(-v.y, v.x + (v.x ** 2 - 1) * v.y), "r": flow_map(-v.y, -v.x)})
    r = mode_region_of_attraction(system, "q")
    assert r.status == "proven" and r.rechecked
    assert [e["index"] for e in r.certificates["invariant"]] == [0, 1]  # the & is split into its two terms
    assert 0.9 * 0.3125 < r.level < 0.3125  # x <= 0.5 binds before y >= 0.8 (0.533) does
    assert "((0.5 - x) >= 0): -x + 0.5 > 0" in r.claim and "((y - 0.8) >= 0): y - 0.8 < 0" in r.claim


def test_non_polynomial_invariant_or_guard_is_not_applicable():
    r = mode_region_of_attraction(_system(invariant=lambda v, m: 1.0 - abs(v[0])), "q")
    assert r.status == "not applicable" and "invariant of mode 'q'" in r.why and "uses abs" in r.why
    r = mode_region_of_attraction(_system(invariant=lambda v, m: min(1.0 - v[0], 1.0 + v[0])), "q")
    assert r.status == "not applicable" and "hybrid.all_of" in r.why


def test_virtual_unstable_boundary_and_too_large_are_not_applicable():
    virtual = mode_region_of_attraction(_system(invariant=lambda v, m: v[0] - 0.5), "q")
    assert virtual.status == "not applicable" and virtual.why.startswith("virtual equilibrium")
    unstable = mode_region_of_attraction(_system(flow=lambda t, x, m: (x[1], x[0] + (1 - x[0] ** 2) * x[1])), "q")
    assert unstable.status == "not applicable" and "not Hurwitz" in unstable.why
    edge = mode_region_of_attraction(_system(invariant=lambda v, m: v[0]), "q")  # x* = 0 on x >= 0's boundary
    assert edge.status == "not applicable" and "no neighbourhood of x* stays in the mode" in edge.why
    names = ("a", "b", "c", "d", "e")
    five = mode_region_of_attraction(_system(flow=lambda t, x, m: tuple(-c for c in x), names=names), "q")
    assert five.status == "not applicable" and "5 states > max_dimension = 4" in five.why
    not_there = mode_region_of_attraction(VDP, "q", equilibrium=(0.5, 0.0))
    assert not_there.status == "not applicable" and "is not an equilibrium" in not_there.why


def test_solver_failure_and_exhausted_budgets_are_statuses(monkeypatch):
    def fail(self, *args, **kwargs):
        raise cp.error.SolverError("simulated failure")

    with monkeypatch.context() as patch:
        patch.setattr(cp.Problem, "solve", fail)
        r = mode_region_of_attraction(VDP, "q")
    assert r.status == "not proven" and "simulated failure" in r.why and r.level is None
    real = mode_region_module.certify_sublevel
    monkeypatch.setattr(mode_region_module, "certify_sublevel",
                        lambda *a, **k: real(*a, **{**k, "max_boxes": 1}))
    r = mode_region_of_attraction(VDP, "q")
    assert r.status == "not proven" and not r.rechecked and r.claim == ""
    assert len(r.attempts) == len(mode_region_module._LADDER)
    assert all("invariance not decided (max_boxes" in a["result"] for a in r.attempts)
    assert r.why.startswith("no level proven (at V <= ")


# --------------------------------------------------------------------------- re-check rejects mutants


def _tampered(region: ModeRegion) -> dict:
    return copy.deepcopy(region.as_dict())


def test_recheck_rejects_a_doctored_level(quadratic):
    data = _tampered(quadratic)
    data["level"] = 1.3 * quadratic.level
    problems = recheck_mode_region(VDP, data)
    assert any("levels differ" in p for p in problems)
    # doctored consistently everywhere, the boxes themselves refute it
    sub = data["certificates"]["sublevel"]
    sub["rho_out"] = float.hex(data["level"])
    assert any(p.startswith("sublevel: ") and "does not hold" in p for p in recheck_mode_region(VDP, data))


def test_recheck_rejects_a_doctored_lyapunov_function(quadratic):
    data = _tampered(quadratic)
    exps, coefficient = data["lyapunov_terms"][0]
    data["lyapunov_terms"][0] = [exps, str(Fraction(coefficient) * Fraction(3, 4))]
    assert any("does not hold on re-check" in p for p in recheck_mode_region(VDP, data))
    # the same with the library's re-check directly, as tests/analysis/test_sublevel.py does
    polys = mode_polynomials(VDP, "q", (0.0, 0.0))
    v = ModeRegion(mode="q", status="proven", variables=polys.variables,
                   lyapunov_terms=tuple((tuple(e), c) for e, c in data["lyapunov_terms"])).lyapunov_polynomial()
    cert = SublevelCertificate.from_dict(quadratic.certificates["sublevel"])
    assert recheck_sublevel(v, lie_derivative(v, polys.rates), cert) != ()
    true_v = _lyapunov(quadratic)
    assert recheck_sublevel(true_v, lie_derivative(true_v, polys.rates), cert) == ()


def test_recheck_rejects_doctored_inner_argument_time_and_missing_guard():
    jump = Transition(name="up", source="q", target="r", guard=lambda v, m: v[1] - 0.8)
    system = _system(transitions=(jump,))
    r = mode_region_of_attraction(system, "q")
    assert r.status == "proven" and recheck_mode_region(system, r) == ()
    data = _tampered(r)
    data["certificates"]["inner"]["c_w"] = str(10 * Fraction(data["certificates"]["inner"]["c_w"]))
    assert any("is not inside the cube" in p for p in recheck_mode_region(system, data))
    data = _tampered(r)
    data["certificates"]["inner"]["kappa"] = "100"
    assert any("kappa" in p for p in recheck_mode_region(system, data))
    data = _tampered(r)
    data["time_bound_s"] = 0.5 * r.time_bound_s
    assert any("time bound" in p for p in recheck_mode_region(system, data))
    data = _tampered(r)
    data["certificates"]["guards"] = []
    assert any("guard of transition 'up'" in p for p in recheck_mode_region(system, data))
    # the guard certificate re-checked alone, then claimed for a guard that is enabled in S
    entry = r.certificates["guards"][0]["certificate"]
    polys = mode_polynomials(system, "q", r.equilibrium)
    v = _lyapunov(r)
    (_, guard), = polys.guards[0][1]
    assert recheck_bound(guard, [(v, r.level)], entry) == ()
    moved = _system(transitions=(Transition(name="up", source="q", target="r", guard=lambda v, m: v[1] - 0.5),))
    assert any("'up'" in p for p in recheck_mode_region(moved, r))
    # another flow: the same certificate does not prove anything about it
    other = _system(transitions=(jump,), flow=lambda t, x, m: (-x[1], x[0] + (x[0] ** 2 - 2) * x[1]))
    assert recheck_mode_region(other, r) != ()


# --------------------------------------------------------------------------- JSON and inputs


def test_json_is_deterministic_and_finite(quadratic):
    again = mode_region_of_attraction(VDP, "q")
    one, two = json.dumps(quadratic.as_dict(), allow_nan=False), json.dumps(again.as_dict(), allow_nan=False)
    assert one == two
    data = json.loads(one)
    assert data["format"] == "analysis.mode_region/1" and data["status"] == "proven"
    assert recheck_mode_region(VDP, data) == ()
    refused = mode_region_of_attraction(_system(invariant=lambda v, m: v[0] - 0.5), "q")
    assert json.loads(json.dumps(refused.as_dict(), allow_nan=False))["level"] is None


@pytest.mark.parametrize("kwargs, pattern", [
    ({"mode": "nope"}, r"^mode = 'nope': expected one of the modes \['q', 'r'\]"),
    ({"equilibrium": (0.0,)}, r"^equilibrium = \(0\.0,\): expected 2 finite values \(x, y\)"),
    ({"guess": (math.nan, 0.0)}, r"^guess = \(nan, 0\.0\): expected 2 finite values"),
    ({"equilibrium": (0.0, 0.0), "guess": (0.0, 0.0)}, r"^guess = \(0\.0, 0\.0\): expected None when equilibrium"),
    ({"degree": 3}, r"^degree = 3: expected an even integer >= 2"),
    ({"degree": 0}, r"^degree = 0: expected an even integer >= 2"),
    ({"max_dimension": 0}, r"^max_dimension = 0: expected an integer >= 1"),
    ({"max_boxes": 10}, r"^max_boxes = 10: expected an integer >= 1000"),
    ({"max_extent": -1.0}, r"^max_extent = -1\.0: expected a finite number > 0"),
    ({"memory": {"k": 1.0}}, r"^memory = \{'k': 1\.0\}: expected names among the memory variables"),
    ({"arithmetic": "exact"}, r"^arithmetic = 'exact': expected one of \('scalar', 'batched'\)"),
])
def test_bad_inputs_name_the_parameter(kwargs, pattern):
    mode = kwargs.pop("mode", "q")
    with pytest.raises(ParameterError, match=pattern):
        mode_region_of_attraction(VDP, mode, **kwargs)


def test_not_a_system():
    with pytest.raises(ParameterError, match=r"^system = 'str': expected a hybrid\.HybridSystem"):
        mode_region_of_attraction("vdp", "q")
