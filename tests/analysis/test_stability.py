"""The stability analysis picks the certificate that fits: LMIs at a common equilibrium, a limit cycle otherwise."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.stability import analyse_stability
from hybrid import HybridAutomaton, HybridSystem, Mode, Transition
from hybrid.errors import ParameterError
from hybrid.examples import thermostat


def switched_linear(a1: np.ndarray, a2: np.ndarray) -> HybridSystem:
    """Two linear modes switched on the sign of x·y (regions meeting at the common equilibrium, the origin)."""
    automaton = HybridAutomaton(
        name="switched", variables=("x", "y"), initial_mode="a",
        modes=(Mode(name="a", invariant=lambda v, m: v[0] * v[1]), Mode(name="b", invariant=lambda v, m: -v[0] * v[1])),
        transitions=(Transition(name="ab", source="a", target="b", guard=lambda v, m: -v[0] * v[1]),
                     Transition(name="ba", source="b", target="a", guard=lambda v, m: v[0] * v[1])))

    def flow(a: np.ndarray):
        return lambda t, x, m: (a[0, 0] * x[0] + a[0, 1] * x[1], a[1, 0] * x[0] + a[1, 1] * x[1])

    return HybridSystem(automaton=automaton, state_names=("x", "y"), flows={"a": flow(a1), "b": flow(a2)})


def test_a_common_quadratic_lyapunov_function_proves_stability_under_arbitrary_switching():
    result = analyse_stability(switched_linear(np.array([[-1.0, 2.0], [0.0, -1.0]]), np.array([[-1.0, 0.0], [1.0, -2.0]])),
                               initial_state=(1.0, 0.5))
    assert result.verdict == "stable" and result.switched.status == "exists" and result.orbit is None
    assert [c.status for c in result.claims][-1] == "proven" and "arbitrary switching" in result.finding


def test_without_one_the_absence_and_a_dwell_time_are_proven_and_nothing_is_concluded():
    result = analyse_stability(switched_linear(np.array([[-0.1, 1.0], [-10.0, -0.1]]),
                                               np.array([[-0.1, 10.0], [-1.0, -0.1]])), initial_state=(1.0, 0.5))
    assert result.switched.status == "none" and result.dwell.proven and result.verdict == "not decided"
    # CQLF absent (proven), dwell time (proven), then the piecewise quadratic search, not applicable (x·y >= 0)
    assert [c.status for c in result.claims][-3:] == ["proven", "proven", "not decided"]


def test_virtual_equilibria_lead_to_the_limit_cycle():
    result = analyse_stability(thermostat().system, initial_state=(20.0,), horizon=60.0)
    assert [e.kind for e in result.equilibria] == ["virtual", "virtual"]
    assert result.orbit is not None and result.verdict == "stable"
    assert result.as_dict()["orbit"]["period"] == pytest.approx(2 * np.log(11 / 9) / 0.1, abs=1e-9)


def test_bad_input():
    with pytest.raises(ParameterError, match=r"^section = 'nope': expected one of the transitions"):
        analyse_stability(thermostat().system, initial_state=(20.0,), section="nope")
    with pytest.raises(ParameterError, match=r"^horizon = 0"):
        analyse_stability(thermostat().system, initial_state=(20.0,), horizon=0)
    with pytest.raises(ParameterError, match=r"^initial_state = \(1\.0, 2\.0\): expected 1 finite values \(T\)"):
        analyse_stability(thermostat().system, initial_state=(1.0, 2.0))


def reverse_van_der_pol(*, with_guard: bool) -> HybridSystem:
    """Van der Pol in reverse time (ROA of the origin bounded by the unstable cycle), optionally left at y >= 0.8."""
    transitions = (Transition(name="leave", source="q", target="out", guard=lambda v, m: v[1] - 0.8),) if with_guard else ()
    automaton = HybridAutomaton(name="vdp", variables=("x", "y"), initial_mode="q",
                                modes=(Mode(name="q"), Mode(name="out")), transitions=transitions)
    vdp = lambda t, x, m: (-x[1], x[0] + (x[0] ** 2 - 1.0) * x[1])  # noqa: E731
    return HybridSystem(automaton=automaton, state_names=("x", "y"),
                        flows={"q": vdp, "out": lambda t, x, m: (1.0, 0.0)})


def test_a_polynomial_mode_gets_a_proven_region_of_attraction_limited_by_its_guard():
    free = analyse_stability(reverse_van_der_pol(with_guard=False), initial_state=(0.1, 0.0))
    left = analyse_stability(reverse_van_der_pol(with_guard=True), initial_state=(0.1, 0.0))
    for result in (free, left):
        assert result.verdict == "stable" and [r.mode for r in result.regions] == ["q"]
        region = result.regions[0]
        assert region.status == "proven" and region.rechecked
        assert result.claims[-1].status == "proven" and "region of attraction is proven for mode(s) 'q'" in result.finding
    # the guard y >= 0.8 must not be enabled in the set: a smaller level than without it
    assert left.regions[0].level < free.regions[0].level
    assert left.regions[0].box["y"][1] <= free.regions[0].box["y"][1]
    skipped = analyse_stability(reverse_van_der_pol(with_guard=False), initial_state=(0.1, 0.0), regions=False)
    assert skipped.regions == () and skipped.verdict == "stable" and skipped.claims[-1].status == "measured"
    with pytest.raises(ParameterError, match=r"^regions = 'yes': expected True or False"):
        analyse_stability(reverse_van_der_pol(with_guard=False), initial_state=(0.1, 0.0), regions="yes")
