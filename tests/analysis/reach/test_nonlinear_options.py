"""Where the benchmark options, parameters as constant states and smooth nonlinear flows meet.

Yardsticks are independent of the engine: fine ``solve_ivp`` simulations (DOP853, rtol 1e-10) for
the Van der Pol flowpipe with a per-mode step, and closed forms for the affine systems:

* the two-mode system of ``_split`` (invariants decide the start mode, ``x0 ∈ [−1, 1]``): ``neg`` flows
  up to 0 and jumps to 0.5, ``pos`` approaches 1 from below (``x(t) = 1 − (1 − x0) e^{−t}``), so
  ``x <= 1.01`` has the slack 0.01 and ``x <= 0.9`` is violated at ``x0 = 1``;
* ``ẋ = −k (x − 1)``, ``x0 ∈ [0, 0.2]``, ``k ∈ [0.5, 2]``: ``x(t) = 1 − (1 − x0) e^{−kt}``, the largest
  value over ``[0, 2]`` is ``1 − 0.8 e^{−4}``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy.integrate import solve_ivp

from analysis.verify.problems import hybrid_problem
from analysis.reach import reach
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter
from hybrid import HybridAutomaton, Mode, Transition
from hybrid.symbolic import coordinates, flow_map, jump_map, sin
from hybrid.system import HybridSystem


def _one_mode(flow, names=("x", "y"), name="s") -> HybridSystem:
    automaton = HybridAutomaton(name=name, modes=(Mode(name="m"),), transitions=(), variables=names,
                                initial_mode="m")
    return HybridSystem(automaton=automaton, state_names=names, flows={"m": flow})


def _vdp() -> HybridSystem:
    x = coordinates("x", "y")
    return _one_mode(flow_map(x.y, (1.0 - x.x ** 2) * x.y - x.x), name="vdp")


def test_a_per_mode_step_drives_a_smooth_mode_and_stays_sound():
    """``mode_time_steps`` replaces the step in a nonlinear mode: segments of that step, every simulated
    point inside its segment (within 1e-6, the integration tolerance)."""
    box = {"x": (1.25, 1.3), "y": (2.35, 2.4)}
    result = reach(_vdp(), box, horizon=1.0, time_step=0.5, mode_time_steps={"m": 0.01})
    assert result.status == "complete", result.terminations
    flowed = [s for s in result.segments if not s.entry]
    widths = np.array([s.t_hi - s.t_lo for s in flowed])
    assert np.allclose(widths, 0.01, atol=1e-12)
    assert 100 <= len(flowed) <= 101
    rng = np.random.default_rng(3)
    starts = np.vstack([np.array(list(itertools.product(*box.values()))),
                        rng.uniform((1.25, 2.35), (1.3, 2.4), size=(10, 2))])
    for x0 in starts:
        ts = np.arange(0.0, 1.0, 0.0137)
        sol = solve_ivp(lambda t, z: [z[1], (1 - z[0] ** 2) * z[1] - z[0]], (0.0, 1.0), x0, method="DOP853",
                        t_eval=ts, rtol=1e-10, atol=1e-12)
        for t, point in zip(sol.t, sol.y.T):
            holders = [s for s in flowed if s.t_lo - 1e-9 <= t <= s.t_hi + 1e-9]
            assert any(np.all(point >= s.lo - 1e-6) and np.all(point <= s.hi + 1e-6) for s in holders), (t, point)


def test_a_per_mode_step_too_long_for_the_linearisation_is_inconclusive():
    """A step whose Jacobian norm times step exceeds the series bound ends the run (blow_up), never a wrong set."""
    result = reach(_vdp(), {"x": (1.25, 1.3), "y": (2.35, 2.4)}, horizon=1.0, time_step=0.01,
                   mode_time_steps={"m": 1.0})
    assert result.status != "complete"
    assert any(t.reason == "blow_up" and "Jacobian" in t.detail for t in result.terminations)


def _split() -> HybridSystem:
    v = coordinates("x")
    automaton = HybridAutomaton(
        name="split", modes=(Mode(name="neg", invariant=v.x <= 0.0), Mode(name="pos", invariant=v.x >= 0.0)),
        transitions=(Transition(name="up", source="neg", target="pos", guard=v.x >= 0.0),
                     Transition(name="down", source="pos", target="neg", guard=v.x <= 0.0)),
        variables=("x",))
    return HybridSystem(automaton=automaton, state_names=("x",), jumps={"down": jump_map(v.x - 1.0),
                                                                        "up": jump_map(v.x + 0.5)},
                        flows={"neg": flow_map(1.0 + 0.0 * v.x), "pos": flow_map(1.0 - v.x)})


def test_splits_cut_the_box_of_every_start_mode():
    initial = {"x": Parameter(name="x0", low=-1.0, high=1.0)}
    ok = hybrid_problem(name="s", system=_split(), initial=initial, horizon=3.0, reach_options={"splits": {"x": 2}},
                        requirements=(Requirement(name="r", formula="always[0, 3] x <= 1.01"),))
    proof = ok.proofs["r"]()
    assert proof.proven, proof.evidence
    assert "each of 2 start modes split into 4 pieces" in proof.evidence
    assert 0.0 < proof.margin <= 0.01
    bad = hybrid_problem(name="s", system=_split(), initial=initial, horizon=3.0, reach_options={"splits": {"x": 2}},
                         requirements=(Requirement(name="r", formula="always[0, 3] x <= 0.9"),))
    assert not bad.proofs["r"]().holds


def _scaled(point):
    x = coordinates("x")
    automaton = HybridAutomaton(name="one", modes=(Mode(name="m"),), transitions=(), variables=("x",),
                                initial_mode="m")
    return HybridSystem(automaton=automaton, state_names=("x",), flows={"m": flow_map(-point["k"] * (x.x - 1.0))})


def test_splits_keep_the_time_scale_and_name_a_parameter_it_absorbed():
    """``ẋ = −k (x − 1)``, ``x0 ∈ [0, 0.2]``: ``x(t) = 1 − (1 − x0) e^{−kt}``, at most
    ``1 − 0.8 e^{−4}`` (``x0 = 0.2``, ``k = 2``, ``t = 2``).  ``k`` is the time scale, not a state, so a
    split over it is refused by name."""
    k = Parameter(name="k", low=0.5, high=2.0)
    top = 1.0 - 0.8 * math.exp(-4.0)

    def problem(bound, splits):
        return hybrid_problem(name="p", system=_scaled, initial={"x": Parameter(name="x0", low=0.0, high=0.2)},
                              parameters=(k,), horizon=2.0, reach_options={"splits": splits},
                              requirements=(Requirement(name="r", formula=f"always[0, 2] x <= {bound!r}"),))

    proof = problem(top + 0.01, {"x": 2}).proofs["r"]()
    assert proof.proven, proof.evidence
    assert "split into 2 pieces" in proof.evidence and any("tau" in a for a in proof.assumptions)
    assert 0.0 < proof.margin <= 0.01
    assert not problem(top - 0.01, {"x": 2}).proofs["r"]().holds
    absorbed = problem(top + 0.01, {"k": 2}).proofs["r"]()
    assert not absorbed.holds and "splits" in absorbed.evidence


def test_a_builder_with_smooth_flows_is_declined_with_its_reason():
    """Parameters as constant states read affine flows only: reach=True gives a proof that does not hold."""
    k = Parameter(name="k", low=0.5, high=2.0)

    def build(point):
        x = coordinates("x")
        automaton = HybridAutomaton(name="one", modes=(Mode(name="m"),), transitions=(), variables=("x",),
                                    initial_mode="m")
        return HybridSystem(automaton=automaton, state_names=("x",),
                            flows={"m": flow_map(-point["k"] * sin(x.x))})

    problem = hybrid_problem(name="p", system=build, initial={"x": 0.5}, parameters=(k,), horizon=1.0, reach=True,
                             requirements=(Requirement(name="r", formula="always[0, 1] x <= 2"),))
    proof = problem.proofs["r"]()
    assert not proof.holds and not proof.rechecked
    assert "nonlinear (smooth) flows are read only for a system not built from the parameters" in proof.evidence
