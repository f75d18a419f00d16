"""reach(): inputs against closed forms, bad input, blow-up and limits, the result object."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from analysis.reach import AffineError, ModeInput, ReachError, Zonotope, reach, unsafe_set
from hybrid import HybridAutomaton, Mode
from hybrid.examples import thermostat
from hybrid.symbolic import const, coordinates, flow_map
from hybrid.system import HybridSystem


def _one_mode(flow, names=("x",), invariant=None) -> HybridSystem:
    automaton = HybridAutomaton(name="s", modes=(Mode(name="m", invariant=invariant),), transitions=(),
                                variables=names)
    return HybridSystem(automaton=automaton, state_names=names, flows={"m": flow})


X = coordinates("x")


def test_pure_input_integrator_is_exact():
    """x' = u, |u| <= 1, x(0) = 0: the states of [kδ, (k+1)δ] are exactly [-(k+1)δ, (k+1)δ]."""
    system = _one_mode(flow_map(const(0.0) * X.x))
    result = reach(system, {"x": (0.0, 0.0)}, horizon=1.0, time_step=0.125,
                   inputs={"m": ModeInput(matrix=[[1.0]], bounds=([-1.0], [1.0]))})
    flows = [s for s in result.segments if not s.entry]
    for k, s in enumerate(flows[:8]):
        assert s.lo[0] <= -(k + 1) * 0.125 and s.hi[0] >= (k + 1) * 0.125
        assert s.hi[0] - (k + 1) * 0.125 < 1e-12 and -(k + 1) * 0.125 - s.lo[0] < 1e-12


def test_input_with_decay_against_closed_form():
    """x' = -x + u + 0.5, u ∈ [-1, 1], x(0) = 0: x(t) ∈ 0.5 (1 - e^{-t}) ± (1 - e^{-t})."""
    system = _one_mode(flow_map(-X.x))
    delta = 0.01
    result = reach(system, {"x": (0.0, 0.0)}, horizon=3.0, time_step=delta,
                   inputs={"m": ModeInput(matrix=[[1.0]], bounds=([-0.5], [1.5]))})
    for s in (s for s in result.segments if not s.entry):
        t = np.linspace(max(s.t_lo, 0.0), s.t_hi, 5)
        upper_true, lower_true = 1.5 * (1 - np.exp(-t)), -0.5 * (1 - np.exp(-t))
        assert np.all(s.hi[0] >= upper_true - 1e-12) and np.all(s.lo[0] <= lower_true + 1e-12)
    top = max(s.hi[0] for s in result.segments)
    assert top >= 1.5 * (1 - math.exp(-3.0)) and top < 1.5 * (1 - math.exp(-3.01)) + 0.02


def test_blow_up_is_an_inconclusive_termination_not_an_exception():
    system = _one_mode(flow_map(X.x))  # x' = x: e^t grows past the size limit at t ≈ ln(1e6)
    result = reach(system, {"x": (1.0, 2.0)}, horizon=30.0, time_step=0.01)
    assert result.status == "inconclusive" and not result.complete
    (stop,) = result.terminations
    assert stop.reason == "blow_up" and 12.0 < stop.time < 14.5
    assert stop.detail.startswith("inconclusive: the over-approximation blew up at t = ") and "in mode 'm'" in stop.detail
    far = unsafe_set("far", X.x >= 1e9, ("x",))
    assert result.distance_to(far) > 0  # separated as far as computed, but the run is inconclusive
    assert json.loads(result.to_json())["status"] == "inconclusive"


def test_segment_and_flowpipe_limits_end_inconclusively():
    room = thermostat()
    few = reach(room.system, {"T": (20.0, 20.0)}, horizon=30.0, time_step=0.01, max_segments=50)
    assert few.status == "inconclusive" and few.terminations[-1].reason == "segment_limit"
    assert len(few.segments) <= 50
    short = reach(room.system, {"T": (20.0, 20.0)}, horizon=30.0, time_step=0.01, max_flowpipes=2, max_jumps=10)
    assert short.status == "inconclusive" and short.terminations[-1].reason == "flowpipe_limit"


def test_jump_bound_is_conclusive_and_reported():
    room = thermostat()
    result = reach(room.system, {"T": (20.0, 20.0)}, horizon=30.0, time_step=0.01, max_jumps=2)
    assert result.complete and [j.transition for j in result.jumps] == ["heat_on", "heat_off"]
    assert result.terminations[-1].reason == "max_jumps"


@pytest.mark.parametrize(("kwargs", "parameter"), [
    (dict(horizon=1.0, time_step=0.0), "time_step"),
    (dict(horizon=1.0, time_step=-0.1), "time_step"),
    (dict(horizon=1.0, time_step=2.0), "time_step"),
    (dict(horizon=1.0, time_step=float("nan")), "time_step"),
    (dict(horizon=float("inf"), time_step=0.1), "horizon"),
    (dict(horizon=1.0, time_step=0.1, max_jumps=-1), "max_jumps"),
    (dict(horizon=1.0, time_step=0.1, size_limit=float("nan")), "size_limit"),
    (dict(horizon=1.0, time_step=0.1, initial_mode="nowhere"), "initial_mode"),
])
def test_bad_parameters_are_named(kwargs, parameter):
    with pytest.raises(ReachError) as err:
        reach(_one_mode(flow_map(-X.x)), {"x": (0.0, 1.0)}, **kwargs)
    assert err.value.parameter == parameter and "fix:" in str(err.value)


@pytest.mark.parametrize("initial", [
    {"x": (0.0, math.inf)}, {"x": (float("nan"), 1.0)}, {"x": (2.0, 1.0)}, {"y": (0.0, 1.0)},
    [[0.0], [math.inf]], "box", Zonotope(center=[0.0, 0.0], generators=[[1.0], [0.0]])])
def test_unbounded_or_malformed_initial_sets_are_refused(initial):
    with pytest.raises(ReachError) as err:
        reach(_one_mode(flow_map(-X.x)), initial, horizon=1.0, time_step=0.1)
    assert err.value.parameter == "initial" and "bounded" in str(err.value)


def test_too_large_a_step_for_the_dynamics_is_refused_with_a_bound():
    with pytest.raises(ReachError, match="use time_step <= "):
        reach(_one_mode(flow_map(-1000.0 * X.x)), {"x": (0.0, 1.0)}, horizon=10.0, time_step=1.0)


def test_non_symbolic_and_non_finite_models_are_refused():
    with pytest.raises(AffineError, match="reachability needs a symbolic model"):
        reach(_one_mode(lambda t, x, m: (-x[0],)), {"x": (0.0, 1.0)}, horizon=1.0, time_step=0.1)
    with pytest.raises(AffineError, match="not finite"):
        reach(_one_mode(flow_map(X.x + math.inf)), {"x": (0.0, 1.0)}, horizon=1.0, time_step=0.1)


def test_vertices_initial_set_and_contains():
    x = coordinates("x", "y")
    system = _one_mode(flow_map(-x.y, x.x), names=("x", "y"))
    result = reach(system, [[1.0, 0.0], [1.1, 0.05], [0.95, -0.05]], horizon=1.0, time_step=0.01)
    t = 0.731
    for x0 in ([1.0, 0.0], [1.1, 0.05], [0.95, -0.05]):
        exact = [x0[0] * math.cos(t) - x0[1] * math.sin(t), x0[0] * math.sin(t) + x0[1] * math.cos(t)]
        assert result.contains("m", t, exact)
    assert not result.contains("m", t, [0.0, 0.0]) and not result.contains("other", t, exact)


def test_json_is_deterministic_and_complete():
    room = thermostat()
    T = coordinates("T").T
    runs = [reach(room.system, {"T": (19.5, 20.5)}, horizon=5.0, time_step=0.05, max_jumps=3,
                  unsafe=[unsafe_set("hot", T >= 21.5, ("T",))]) for _ in range(2)]
    assert runs[0].to_json() == runs[1].to_json()
    data = json.loads(runs[0].to_json())
    assert data["status"] == "complete" and data["distances"][0]["unsafe"] == "hot"
    assert data["distances"][0]["distance"] > 0.4  # the band ends at 21: 0.5 away, minus the bloating
    assert {"segments", "jumps", "terminations"} <= set(data)


def test_crossing_guards_and_affine_jumps_cover_the_executor():
    """A two-mode saw-tooth with a rising crossing guard and an offset jump map: executor runs inside."""
    from hybrid import Transition
    from hybrid.continuous import simulate_continuous
    from hybrid.symbolic import jump_map

    v = coordinates("x")
    automaton = HybridAutomaton(
        name="saw", variables=("x",), initial_mode="a",
        modes=(Mode(name="a", invariant=v.x <= 2.0), Mode(name="b", invariant=v.x >= -1.0)),
        transitions=(Transition(name="up", source="a", target="b", guard=v.x >= 1.0, direction=+1),
                     Transition(name="down", source="b", target="a", guard=v.x <= -0.5)))
    system = HybridSystem(automaton=automaton, state_names=("x",),
                          flows={"a": flow_map(const(1.0) + 0.0 * X.x), "b": flow_map(-0.5 * X.x - 1.0)},
                          jumps={"up": jump_map(X.x - 1.0), "down": jump_map(0.5 * X.x + 0.25)})
    result = reach(system, {"x": (0.0, 0.5)}, horizon=5.0, time_step=0.01, max_jumps=8)
    assert result.complete
    rng = np.random.default_rng(4)
    for x0 in rng.uniform(0.0, 0.5, size=60):
        tr = simulate_continuous(system, (x0,), duration=5.0, rtol=1e-10, atol=1e-12, max_jumps=8)
        for t, mode, x in zip(tr.times, tr.modes, tr.states):
            assert result.contains(mode, float(t), x, tol=1e-6), (x0, t, mode, x)


def test_polytope_initial_sets_by_halfspaces():
    from fractions import Fraction

    from analysis.reach import initial_zonotope
    from analysis.reach.zonotope import interval_hull

    x = coordinates("p", "q")
    lo, hi = interval_hull(initial_zonotope((x.p + x.q <= 1.0) & (x.p >= 0.0) & (x.q >= 0.0), ("p", "q")))
    assert np.all(lo <= 0.0) and np.all(hi >= 1.0) and np.all(hi - 1.0 < 1e-14) and np.all(lo > -1e-14)
    # 3 p + q <= 0.3, p >= -0.1, q >= -0.2: vertices (-0.1, -0.2), (-0.1, 0.6), (1/6 + 1/60, -0.2) exactly
    lo, hi = interval_hull(initial_zonotope((3.0 * x.p + x.q <= 0.3) & (x.p >= -0.1) & (x.q >= -0.2), ("p", "q")))
    p_max = (Fraction(0.3) - Fraction(-0.2)) / 3
    q_max = Fraction(0.3) + 3 * Fraction(0.1)
    assert Fraction(float(hi[0])) >= p_max and Fraction(float(hi[1])) >= q_max
    assert float(hi[0]) - float(p_max) < 1e-12 and float(hi[1]) - float(q_max) < 1e-12
    for condition, words in (((x.p >= 0.0) & (x.q >= 0.0), "unbounded"),
                             ((x.p >= 1.0) & (x.p <= 0.0) & (x.q >= 0.0) & (x.q <= 1.0), "empty")):
        with pytest.raises(ReachError, match=words):
            initial_zonotope(condition, ("p", "q"))
    with pytest.raises(ReachError, match="one polytope"):
        initial_zonotope((x.p <= 0.0) | (x.p >= 1.0), ("p", "q"))


def test_three_dimensional_affine_flow_covers_the_executor():
    """A damped oscillator with a driven third state (n = 3: membership by linear programs)."""
    from hybrid.continuous import simulate_continuous

    x = coordinates("a", "b", "c")
    system = _one_mode(flow_map(-0.1 * x.a + x.b, -x.a - 0.1 * x.b, -0.5 * x.c + 1.0 + 0.2 * x.a),
                       names=("a", "b", "c"))
    box = {"a": (0.9, 1.1), "b": (-0.1, 0.1), "c": (0.0, 0.2)}
    result = reach(system, box, horizon=4.0, time_step=0.02)
    assert result.complete
    rng = np.random.default_rng(9)
    for x0 in rng.uniform([0.9, -0.1, 0.0], [1.1, 0.1, 0.2], size=(30, 3)):
        tr = simulate_continuous(system, tuple(x0), duration=4.0, rtol=1e-10, atol=1e-12)
        for t, mode, state in list(zip(tr.times, tr.modes, tr.states))[::3]:
            assert result.contains(mode, float(t), state, tol=1e-6), (x0, t, state)
    # far outside: the third state stays below its driven equilibrium bound 2 + 0.4·max|a| + margin
    assert result.distance_to(unsafe_set("c high", x.c >= 3.0, ("a", "b", "c"))) > 0
