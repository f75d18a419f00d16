"""Piecewise quadratic Lyapunov functions in the stability analysis: proven for state-dependent switching where no
common quadratic function exists, refused (with the reason) where the automaton is not conewise linear."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from analysis.stability import analyse_stability, conewise_cells
from hybrid import HybridAutomaton, HybridSystem, MemoryVariable, Mode, Transition
from hybrid.conewise import conewise_linear_system, sector_normals
from hybrid.continuous import simulate_continuous

#: Liberzon's unstable spirals: each mode diverges, quadrant switching (SPIRAL_2 on Q1, Q3) is stable
SPIRAL_1, SPIRAL_2 = np.array([[0.1, -1.0], [2.0, 0.1]]), np.array([[0.1, -2.0], [1.0, 0.1]])
#: lightly damped pair: no common quadratic Lyapunov function, V = |x|² on the quadrants
DAMPED = (np.array([[-0.1, 1.0], [-10.0, -0.1]]), np.array([[-0.1, 10.0], [-1.0, -0.1]]))
STARTS = ([1.0, 0.3], [-0.2, 1.0], [0.5, -1.0], [-0.7, -0.4])


def by_quadrant(count: int, quadrants: tuple[np.ndarray, ...]) -> list[np.ndarray]:
    """``quadrants[q]`` on every one of ``count`` sectors lying in quadrant ``q``."""
    return [quadrants[int((i + 0.5) / count * 4) % 4] for i in range(count)]


def sector_mode(x: np.ndarray, count: int) -> str:
    return f"S{min(int((math.atan2(x[1], x[0]) % (2 * math.pi)) / (2 * math.pi) * count), count - 1)}"


def spirals(stable: bool = True, count: int = 8) -> HybridSystem:
    quadrants = (SPIRAL_2, SPIRAL_1, SPIRAL_2, SPIRAL_1) if stable else (SPIRAL_1, SPIRAL_2, SPIRAL_1, SPIRAL_2)
    return conewise_linear_system("spirals" if stable else "swapped", by_quadrant(count, quadrants))


def run_from(system: HybridSystem, x0, duration: float = 15.0):
    run = simulate_continuous(system, tuple(x0), duration=duration, initial_mode=sector_mode(np.array(x0), 8))
    assert run.termination == "end_time"
    return run


@pytest.fixture(scope="module")
def stable_result():
    return analyse_stability(spirals(), initial_state=(0.3, 0.2))


def test_the_spirals_are_proven_stable_by_a_piecewise_quadratic_function(stable_result):
    r = stable_result
    assert all(not e.hurwitz for e in r.equilibria)  # every mode alone diverges ...
    assert (r.switched.status, r.switched.proven) == ("none", True)  # ... and no common quadratic V exists
    assert r.dwell is None  # (no dwell time for unstable modes)
    pwq = r.piecewise
    assert (pwq.status, pwq.proven, pwq.recheck.passed, r.piecewise_note) == ("exists", True, True, "")
    assert r.verdict == "stable" and r.claims[-1].status == "proven"
    assert "state-dependent switching" in r.claims[-1].text and "not under arbitrary switching" in r.claims[-1].text
    assert r.finding.startswith("spirals: stable: every execution of the automaton converges")
    # the jump hyperplanes: the 8 rays, each between neighbours, given explicitly
    assert len(pwq.boundaries) == 8
    assert {frozenset(b.cells) for b in pwq.boundaries} == {frozenset((f"S{i}", f"S{(i + 1) % 8}")) for i in range(8)}
    assert not any(b.derived for b in pwq.boundaries)
    assert pwq.margin > 0 and not np.allclose(pwq.P[0], pwq.P[2])  # a rate, and genuinely piecewise


def test_the_certificate_checks_independently_on_the_cones(stable_result):
    pwq, system = stable_result.piecewise, spirals()
    rng = np.random.default_rng(1)
    normals = np.array(sector_normals(8))
    for i, p in enumerate(pwq.P):
        a = system.flows[f"S{i}"]
        for _ in range(200):  # points of sector i: V > 0, V̇ = 2 xᵀP A x <= −α V
            angle = 2 * math.pi * (i + rng.uniform()) / 8
            x = rng.uniform(0.1, 2.0) * np.array([math.cos(angle), math.sin(angle)])
            ax = np.array(a(0.0, tuple(x), {}))
            v = x @ p @ x
            assert v > 0 and 2 * x @ p @ ax <= -pwq.margin * v * (1 - 1e-9)
        ray = np.array([normals[(i + 1) % 8][1], -normals[(i + 1) % 8][0]])  # the ray θ_{i+1}, shared with S<i+1>
        assert ray @ p @ ray == pytest.approx(ray @ pwq.P[(i + 1) % 8] @ ray, rel=1e-12)


@pytest.mark.parametrize("x0", STARTS)
def test_every_run_of_the_automaton_decays_and_v_never_increases(stable_result, x0):
    pwq = stable_result.piecewise
    x_star = np.array(stable_result.equilibria[0].point)
    index = {name: k for k, name in enumerate(pwq.names)}
    run = run_from(spirals(), x0)
    xs = np.asarray(run.states)
    assert np.linalg.norm(xs[-1]) < np.linalg.norm(xs[0]) / 20  # (the automaton's run: about 25x over 15 s)
    vs = np.array([(x - x_star) @ pwq.P[index[q]] @ (x - x_star) for x, q in zip(xs, run.modes)])
    assert len(run.events) > 20 and np.all(vs > 0)
    # V is continuous at the jumps and decreases along the flow: never up by more than the integration's rounding
    assert np.all(np.diff(vs) <= 1e-9 * vs[:-1])


def test_the_swapped_assignment_diverges_and_nothing_is_claimed():
    system = spirals(stable=False)
    run = run_from(system, [1.0, 0.3])
    assert np.linalg.norm(run.final_state) > 10 * math.hypot(1.0, 0.3)  # this switching diverges
    r = analyse_stability(system, initial_state=(0.3, 0.2))
    assert r.switched.status == "none" and r.piecewise_note == ""
    assert (r.piecewise.status, r.piecewise.proven, r.piecewise.P) == ("undecided", False, None)
    assert r.verdict == "not decided" and r.claims[-1].status == "not decided"
    assert "proves nothing" in r.claims[-1].text


def test_the_damped_pair_on_the_quadrants_is_proven_stable():
    system = conewise_linear_system("damped", [DAMPED[0], DAMPED[1], DAMPED[0], DAMPED[1]])
    r = analyse_stability(system, initial_state=(0.3, 0.2))
    assert r.switched.status == "none" and r.dwell is not None and r.dwell.proven  # a dwell time, as before ...
    assert r.piecewise.proven and r.verdict == "stable"  # ... and now the automaton's own switching is proven stable
    assert [c.status for c in r.claims[-3:]] == ["proven", "proven", "proven"]
    assert len(r.piecewise.boundaries) == 4
    cells = conewise_cells(system, r.equilibria[0].point, [np.asarray(e.jacobian) for e in r.equilibria])
    normals = sector_normals(4)
    for i, cell in enumerate(cells.cells):  # E rows: n_i and −n_{i+1}, read off the symbolic invariants
        np.testing.assert_allclose(cell.E, [normals[i], [-c for c in normals[(i + 1) % 4]]], rtol=0, atol=1e-15)
        np.testing.assert_array_equal(cell.A, DAMPED[i % 2])
    # a located jump leaves the state ~3e-13 past the ray, where the fast flow (|A| = 10) could in principle
    # re-cross unseen: 20 levels of refinement (rather than 10) rule that out (no GuardResolutionWarning)
    run = simulate_continuous(system, (1.0, 0.3), duration=20.0, initial_mode="S0", refine_depth=20)
    assert run.termination == "end_time" and not run.unresolved
    assert np.linalg.norm(run.final_state) < 0.2 * math.hypot(1.0, 0.3)


def test_a_common_quadratic_function_makes_the_piecewise_search_unnecessary():
    system = conewise_linear_system("calm", [-np.eye(2), np.array([[-1.0, 0.5], [0.0, -1.0]]), -np.eye(2)])
    r = analyse_stability(system, initial_state=(0.3, 0.2))
    assert r.switched.status == "exists" and r.piecewise is None and r.verdict == "stable"
    assert r.piecewise_note.startswith("not needed")


# ------------------------------------------------------------------------------------ not applicable


def rebuilt(system: HybridSystem, *, transitions=None, memory=(), jumps=None) -> HybridSystem:
    a = system.automaton
    automaton = HybridAutomaton(name=a.name, modes=a.modes, transitions=transitions or a.transitions,
                                variables=a.variables, memory=memory, initial_mode=a.initial_mode)
    return HybridSystem(automaton=automaton, state_names=system.state_names, flows=dict(system.flows),
                        jumps=jumps or {})


def two_modes(inv_a, inv_b, guard_ab, guard_ba) -> HybridSystem:
    """The damped pair (no common quadratic V) switched by the given level functions."""
    automaton = HybridAutomaton(
        name="two", variables=("x", "y"), initial_mode="a",
        modes=(Mode(name="a", invariant=inv_a), Mode(name="b", invariant=inv_b)),
        transitions=(Transition(name="ab", source="a", target="b", guard=guard_ab),
                     Transition(name="ba", source="b", target="a", guard=guard_ba)))

    def flow(a: np.ndarray):
        return lambda t, x, m: (a[0, 0] * x[0] + a[0, 1] * x[1], a[1, 0] * x[0] + a[1, 1] * x[1])

    return HybridSystem(automaton=automaton, state_names=("x", "y"), flows={"a": flow(DAMPED[0]), "b": flow(DAMPED[1])})


def not_applicable(system: HybridSystem) -> str:
    r = analyse_stability(system, initial_state=(0.3, 0.2))
    assert r.switched.status == "none" and r.piecewise is None and r.verdict != "stable"
    assert r.claims[-1].status == "not decided" and r.piecewise_note in r.claims[-1].text
    assert r.as_dict()["piecewise"] is None and r.as_dict()["piecewise_note"] == r.piecewise_note
    return r.piecewise_note


def test_a_jump_that_changes_the_state_rules_it_out():
    note = not_applicable(rebuilt(spirals(), jumps={"S2->S3": lambda x, m: (2.0 * x[0], 2.0 * x[1])}))
    assert note.startswith("the jump map of transition 'S2->S3' ('S2' -> 'S3') is x⁺ = M x + c with M = [[2.0, 0.0], "
                           "[0.0, 2.0]], c = [0.0, 0.0], not the identity")


def test_a_memory_write_rules_it_out():
    system = spirals()
    counted = tuple(dataclasses.replace(t, reset=lambda v, m: {"laps": m["laps"] + 1.0}, writes=("laps",))
                    if t.name == "S7->S0" else t for t in system.automaton.transitions)
    note = not_applicable(rebuilt(system, transitions=counted, memory=(MemoryVariable(name="laps"),)))
    assert note == "transition 'S7->S0' writes memory ['laps']: the flows are analysed with the memory fixed"


def test_an_invariant_off_the_equilibrium_rules_it_out():
    note = not_applicable(two_modes(lambda v, m: v[1] - 0.1, lambda v, m: 0.1 - v[1],
                                    lambda v, m: 0.1 - v[1], lambda v, m: v[1] - 0.1))
    assert note.startswith("invariant term 0 of mode 'a' is -0.1 at x* = [")
    assert note.endswith("not 0: the mode's region is not a cone through the equilibrium")


def test_overlapping_cones_hysteresis_rule_it_out():
    # a = {y >= -0.3x}, b = {y <= 0.3x}: both cones through the origin, overlapping on a wedge around the x axis
    note = not_applicable(two_modes(lambda v, m: v[1] + 0.3 * v[0], lambda v, m: 0.3 * v[0] - v[1],
                                    lambda v, m: -(v[1] + 0.3 * v[0]), lambda v, m: v[1] - 0.3 * v[0]))
    assert note.startswith("transition 'ab' from mode 'a' to mode 'b': no row h of the cone of 'a' has a row −c·h")


def test_a_nonlinear_invariant_rules_it_out():
    note = not_applicable(two_modes(lambda v, m: v[0] * v[1], lambda v, m: -v[0] * v[1],
                                    lambda v, m: -v[0] * v[1], lambda v, m: v[0] * v[1]))
    assert note.startswith("invariant term 0 of mode 'a' is not affine in the state about x*: second difference")


def test_a_mode_without_invariant_is_the_whole_plane_and_a_jump_into_it_has_no_surface():
    note = not_applicable(two_modes(lambda v, m: v[1], None, lambda v, m: -v[1], lambda v, m: v[1]))
    assert note.startswith("transition 'ab' from mode 'a' to mode 'b': no row h")


# ------------------------------------------------------------------------------------ the JSON view


def test_as_dict_is_json_and_deterministic(stable_result):
    first = json.dumps(stable_result.as_dict(), allow_nan=False)
    again = json.dumps(analyse_stability(spirals(), initial_state=(0.3, 0.2)).as_dict(), allow_nan=False)
    assert first == again
    data = json.loads(first)
    assert data["piecewise"]["status"] == "exists" and data["piecewise_note"] == "" and data["verdict"] == "stable"
    assert len(data["piecewise"]["P"]) == 8 and "exact_P" not in data["piecewise"]
    swapped = analyse_stability(spirals(stable=False), initial_state=(0.3, 0.2)).as_dict()
    assert json.loads(json.dumps(swapped, allow_nan=False))["piecewise"]["margin"] is None  # nan: undecided
