"""The initial mode decided by the invariants (issue 26): a problem need not name it when exactly one holds."""

from __future__ import annotations

import pytest

from analysis.verify.falsification import evaluate
from analysis.verify import Parameter, Requirement, hybrid_problem
from hybrid import HybridAutomaton, HybridSystem, Mode, Transition, coordinates, flow_map
from hybrid.errors import ModelDefinitionError
from hybrid.model import initial_mode_of


def _tank(declared: str = ""):
    v = coordinates("h")
    automaton = HybridAutomaton(
        name="tank", variables=("h",), initial_mode=declared,
        modes=(Mode(name="fill", invariant=v.h <= 1.0), Mode(name="drain", invariant=v.h >= 0.5)),
        transitions=(Transition(name="full", source="fill", target="drain", guard=v.h >= 1.0),
                     Transition(name="empty", source="drain", target="fill", guard=v.h <= 0.5)))
    return HybridSystem(automaton=automaton, state_names=("h",),
                        flows={"fill": flow_map(0.5 + 0.0 * v.h), "drain": flow_map(-0.5 + 0.0 * v.h)})


def test_the_invariants_decide_the_initial_mode_of_each_point():
    system = _tank()
    assert initial_mode_of(system.automaton, (0.2,), {}) == "fill"
    assert initial_mode_of(system.automaton, (1.5,), {}) == "drain"
    with pytest.raises(ModelDefinitionError, match="fill, drain all hold"):
        initial_mode_of(system.automaton, (0.8,), {})
    problem = hybrid_problem(name="tank", system=system, initial={"h": Parameter(name="h0", low=0.2, high=1.5)},
                             horizon=2.0, requirements=(Requirement(name="r", formula="always[0, 2] (h <= 2)"),))
    # from h0 = 1.5 the tank drains at 0.5/s to 0.5 at t = 2 (it would rise to 2.5 had it started in 'fill')
    trace = problem.trace({"h0": 1.5})
    assert trace.label("mode")[0] == "drain" and trace.signal("h")[-1] == pytest.approx(0.5, abs=1e-9)
    assert problem.trace({"h0": 0.2}).label("mode")[0] == "fill"


def test_an_undecided_initial_mode_is_a_definition_error_naming_the_candidates():
    system = _tank()
    problem = hybrid_problem(name="tank", system=system, initial={"h": Parameter(name="h0", low=0.2, high=1.5)},
                             horizon=2.0, requirements=(Requirement(name="r", formula="always[0, 2] (h <= 2)"),))
    outcome = evaluate(problem, (problem.parameters[0].unit_of(0.8),))
    assert outcome.status == "error" and "initial mode is not decided" in outcome.detail


def test_a_declared_initial_mode_is_kept():
    system = _tank(declared="fill")
    problem = hybrid_problem(name="tank", system=system, initial={"h": Parameter(name="h0", low=0.2, high=1.5)},
                             horizon=1.0, requirements=(Requirement(name="r", formula="always[0, 1] (h <= 3)"),))
    assert problem.trace({"h0": 1.5}).label("mode")[0] == "fill"
