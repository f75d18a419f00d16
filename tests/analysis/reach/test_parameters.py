"""Problem parameters as constant states, the common time scale, and the start modes of a box.

Yardsticks are closed forms computed here, not by the engine:

* ``ẋ = −x + p``, ``x(0) = 0``, ``p ∈ [1, 2]``: ``x(t) = p (1 − e^{−t})``, so over ``[0, 5]`` the largest
  value is ``2 (1 − e^{−5}) = 1.98652…`` (at ``p = 2``, ``t = 5``);
* ``ẋ = −k (x − 1)``, ``x(0) = 0``, ``k ∈ [0.5, 2]``: ``x(t) = 1 − e^{−kt}``, largest over ``[0, 2]``:
  ``1 − e^{−4} = 0.98168…``;
* the worked thermostat (``examples/thermostat.py``): from ``T0 ∈ [19.5, 20.5]`` the room stays in its
  hysteresis band ``[19.5, 20.5]`` for every rate (each mode flows monotonically to the threshold where
  it switches), so ``|T − 20| <= 1.5`` has the slack 1.0 and ``T <= 20.5 + m`` the slack ``m``.
"""

from __future__ import annotations

import math
from fractions import Fraction

import pytest

from analysis.verify.problems import hybrid_problem
from analysis.reach.parameters import ParameterRoute, initial_modes, reach_setup
from analysis.verify.requirements import Requirement
from analysis.verify.verdicts import verify
from analysis.verify.verification import Parameter
from hybrid import HybridAutomaton, Mode, Transition
from hybrid.symbolic import coordinates, flow_map, jump_map
from hybrid.system import HybridSystem

ADDITIVE_MAX = 2.0 * (1.0 - math.exp(-5.0))
SCALED_MAX = 1.0 - math.exp(-4.0)


def _one_mode(flow) -> HybridSystem:
    automaton = HybridAutomaton(name="one", modes=(Mode(name="m"),), transitions=(), variables=("x",),
                                initial_mode="m")
    return HybridSystem(automaton=automaton, state_names=("x",), flows={"m": flow_map(flow)})


def _additive(point):
    x = coordinates("x")
    return _one_mode(-x.x + point["p"])


def _scaled(point):
    x = coordinates("x")
    return _one_mode(-point["k"] * (x.x - 1.0))


def _problem(build, parameter: Parameter, formula: str, end: float):
    return hybrid_problem(name="p", system=build, initial={"x": 0.0}, parameters=(parameter,), horizon=end,
                          requirements=(Requirement(name="r", formula=formula),))


P = Parameter(name="p", low=1.0, high=2.0)
K = Parameter(name="k", low=0.5, high=2.0)


def test_an_additive_parameter_is_a_constant_state():
    setup = reach_setup(_additive, {"x": 0.0}, (P,), builder=True)
    assert setup.model.state_names == ("x", "p") and setup.parameters == ("p",) and setup.scale == 1
    assert setup.box == (("x", 0.0, 0.0), ("p", 1.0, 2.0))
    assert setup.model.modes["m"].a == ((-1, 1), (0, 0)) and setup.model.modes["m"].c == (0, 0)
    # the unsafe set x > 1.99 lies just outside the reachable values (max 1.98652): proven, slack <= true one
    proof = _problem(_additive, P, "always[0, 5] x <= 1.99", 5.0).proofs["r"]()
    assert proof.proven and 0.0 < proof.margin <= 1.99 - ADDITIVE_MAX + 1e-12
    # x > 1.98 is entered (at p = 2 near t = 5): never proven, and verify falsifies it
    inside = _problem(_additive, P, "always[0, 5] x <= 1.98", 5.0)
    assert not inside.proofs["r"]().holds
    assert verify(inside, budget=40, seed=0).requirements[0].verdict == "falsified"


def test_a_common_time_scale_reads_the_window_in_scaled_time():
    setup = reach_setup(_scaled, {"x": 0.0}, (K,), builder=True)
    assert setup.parameters == () and setup.scale == 2 and setup.scale_text == "k"
    assert setup.model.modes["m"].a == ((-1,),) and setup.model.modes["m"].c == (1,)
    proof = _problem(_scaled, K, "always[0, 2] x <= 0.985", 2.0).proofs["r"]()
    assert proof.proven and 0.0 < proof.margin <= 0.985 - SCALED_MAX + 1e-12
    assert any("tau = k·t" in a for a in proof.assumptions)
    inside = _problem(_scaled, K, "always[0, 2] x <= 0.98", 2.0)
    assert not inside.proofs["r"]().holds
    assert verify(inside, budget=40, seed=0).requirements[0].verdict == "falsified"


def test_a_time_scale_that_is_not_positive_and_bilinear_terms_are_refused():
    with pytest.raises(ParameterRoute, match="not positive over the parameter box"):
        reach_setup(_scaled, {"x": 0.0}, (Parameter(name="k", low=-1.0, high=1.0),), builder=True)

    def bilinear(point):
        x = coordinates("x")
        return _one_mode(-point["k"] * x.x + 1.0)  # k multiplies x, but not the constant: not a time scale

    proof = _problem(bilinear, K, "always[0, 2] x <= 3", 2.0).proofs["r"]()
    assert not proof.holds and "a parameter multiplies a state" in proof.evidence

    def branching(point):
        x = coordinates("x")
        return _one_mode(-x.x if point["k"] > 1.0 else -2.0 * x.x)  # a different system per value

    problem = _problem(branching, K, "always[0, 2] x <= 3", 2.0)
    proof = problem.proofs["r"]()  # "auto" says why no proof: the builder needs numbers
    assert not proof.holds and "does not take symbolic values" in proof.evidence


def _split() -> HybridSystem:
    v = coordinates("x")
    automaton = HybridAutomaton(
        name="split", modes=(Mode(name="neg", invariant=v.x <= 0.0), Mode(name="pos", invariant=v.x >= 0.0)),
        transitions=(Transition(name="up", source="neg", target="pos", guard=v.x >= 0.0),
                     Transition(name="down", source="pos", target="neg", guard=v.x <= 0.0)),
        variables=("x",))
    x = coordinates("x")
    return HybridSystem(automaton=automaton, state_names=("x",), jumps={"down": jump_map(x.x - 1.0), "up": jump_map(x.x + 0.5)},
                        flows={"neg": flow_map(1.0 + 0.0 * x.x), "pos": flow_map(1.0 - x.x)})


def test_start_modes_over_the_box():
    system = _split()
    assert not system.automaton.initial_mode_given
    across = reach_setup(system, {"x": Parameter(name="x0", low=-1.0, high=1.0)}, (), builder=False)
    # each start mode gets the part of the box its invariant may hold on
    assert initial_modes(across, None, False) == (("neg", (("x", -1.0, 0.0),)), ("pos", (("x", 0.0, 1.0),)))
    right = reach_setup(system, {"x": Parameter(name="x0", low=0.5, high=1.0)}, (), builder=False)
    assert initial_modes(right, None, False) == (("pos", (("x", 0.5, 1.0),)),)
    whole = (("x", 0.5, 1.0),)
    assert initial_modes(right, lambda point: "pos", False) == (("neg", whole), ("pos", whole))  # any mode
    assert initial_modes(right, "neg", False) == (("neg", whole),)
    # from x0 in [-1, 1] (invariants decide): neg flows up to 0 and jumps to 0.5, pos rises towards 1 (x(t) = 1 − (1 −
    # x0) e^{−t} <= 1) or, at 0, drops to −1: x <= 1.01 holds with the slack 0.01, x <= 0.9 does not (x0 = 1)
    initial = {"x": Parameter(name="x0", low=-1.0, high=1.0)}
    ok = hybrid_problem(name="s", system=system, initial=initial, horizon=3.0,
                        requirements=(Requirement(name="r", formula="always[0, 3] x <= 1.01"),))
    proof = ok.proofs["r"]()
    assert proof.proven and "from mode 'neg'" in proof.evidence and "from mode 'pos'" in proof.evidence
    assert 0.0 < proof.margin <= 0.01
    bad = hybrid_problem(name="s", system=system, initial=initial, horizon=3.0,
                         requirements=(Requirement(name="r", formula="always[0, 3] x <= 0.9"),))
    assert not bad.proofs["r"]().holds


def test_the_worked_thermostat_is_proven_over_its_rates():
    from examples.thermostat import problem, thermostat_problem

    setup = reach_setup(problem.simulate.build, problem.simulate.initial, problem.parameters, builder=True)
    assert setup.scale == Fraction(0.2) and setup.scale_text == "rate" and setup.parameters == ()
    proof = problem.proofs["comfort"]()
    assert proof.proven and 0.9 < proof.margin <= 1.0
    assert "from mode 'off'" in proof.evidence and "from mode 'on'" in proof.evidence  # a callable initial mode
    planted = thermostat_problem(1.0)
    reqs = (Requirement(name="out", formula="always[0, 120] T <= 20.52"),
            Requirement(name="in", formula="always[0, 120] T <= 20.45"))
    again = hybrid_problem(name="t", system=planted.simulate.build, initial=planted.simulate.initial,
                 parameters=planted.parameters[1:], initial_mode=planted.simulate.initial_mode, horizon=120.0,
                 requirements=reqs)
    out, inside = again.proofs["out"](), again.proofs["in"]()
    assert out.proven and 0.0 < out.margin <= 0.02
    assert not inside.holds
