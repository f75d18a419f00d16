"""Which method decided each requirement (``RequirementVerdict.decided_by``), in verify's JSON and table.

The end-to-end problem is ``ẋ = −x + p``, ``x(0) = 0``, ``p ∈ [1, 2]`` over ``[0, 5]`` (closed form
``x(t) = p (1 − e^{−t})``, largest value ``2 (1 − e^{−5}) = 1.98652``): ``x <= 1.99`` is proven by
reachability; ``x <= 1.987`` holds too (slack 0.00048) but the flowpipe at the step 0.1 s is wider
than that (by about 0.0014), so reachability is inconclusive (its margin is negative) and the search decides it;
``eventually ... x >= 0.5`` is outside the fragment; ``x <= 1.9`` is falsified by the search.
"""

from __future__ import annotations

import json
import math

import pytest

from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.verify.verdicts import RequirementVerdict, decided_by, verify
from analysis.verify.verification import Parameter, Proof
from hybrid import HybridAutomaton, HybridSystem, Mode
from hybrid.symbolic import coordinates, flow_map

TRUE_MAX = 2.0 * (1.0 - math.exp(-5.0))


def _verdict(verdict: str, proof: Proof | None, simulations: int = 40, undecided: int = 0) -> RequirementVerdict:
    return RequirementVerdict(name="r", formula="always[0, 1] x <= 1", description="", verdict=verdict,
                              robustness=0.1, nominal_robustness=0.2, simulations=simulations, lowest_at=None,
                              counterexample=None, proof=proof, history=(), undecided=undecided)


REACH = "reachability (zonotope flowpipe, analysis.reach), re-checked by interval Picard and exact rationals"


@pytest.mark.parametrize("verdict, proof, expected", [
    ("proven", Proof(holds=True, method=REACH, evidence="", rechecked=True, margin=0.01), "reachability (re-checked)"),
    ("proven", Proof(holds=True, method="Lyapunov function, interval branch and bound", evidence="", rechecked=True),
     "Lyapunov function (re-checked)"),
    ("not_falsified", None, "falsification (40 simulations)"),
    ("falsified", None, "falsification (40 simulations)"),
    ("incomplete", None, "falsification (40 simulations; 3 ended early)"),
    ("not_falsified", Proof(holds=False, method=REACH, evidence="", rechecked=False, margin=-0.0125),
     "falsification (40 simulations); reachability: inconclusive, margin -0.0125"),
    ("not_falsified", Proof(holds=False, method=REACH, evidence="not decided by reachability: x", rechecked=False),
     "falsification (40 simulations); reachability: not decided"),
    ("not_falsified", Proof(holds=True, method=REACH, evidence="", rechecked=False, margin=0.5),
     "falsification (40 simulations); reachability: holds, not re-checked"),
    ("falsified", Proof(holds=True, method=REACH, evidence="", rechecked=True, margin=0.5),
     "falsification (40 simulations); reachability: proven (re-checked), contradicted by the search"),
])
def test_decided_by_names_the_method_that_decided(verdict, proof, expected):
    v = _verdict(verdict, proof, undecided=3 if verdict == "incomplete" else 0)
    assert decided_by(v) == v.decided_by == expected
    assert v.as_dict()["decided_by"] == expected


def _build(point):
    x = coordinates("x")
    automaton = HybridAutomaton(name="lag", modes=(Mode(name="m"),), transitions=(), variables=("x",),
                                initial_mode="m")
    return HybridSystem(automaton=automaton, state_names=("x",), flows={"m": flow_map(-x.x + point["p"])})


def test_verify_says_per_requirement_which_method_decided_it(capsys):
    problem = hybrid_problem(
        name="lag", system=_build, initial={"x": 0.0}, parameters=(Parameter(name="p", low=1.0, high=2.0),),
        horizon=5.0, requirements=(Requirement(name="wide", formula="always[0, 5] x <= 1.99"),
                                   Requirement(name="tight", formula="always[0, 5] x <= 1.987"),
                                   Requirement(name="later", formula="eventually[0, 5] x >= 0.5"),
                                   Requirement(name="low", formula="always[0, 5] x <= 1.9")),
        reach_options={"time_step": 0.1})
    result = verify(problem, budget=30, seed=0)
    by = {r.name: r for r in result.requirements}
    assert by["wide"].verdict == "proven" and by["wide"].decided_by == "reachability (re-checked)"
    assert 0.0 < by["wide"].proof.margin <= 1.99 - TRUE_MAX + 1e-12
    # tight: true slack 0.00048, not proven: the reachability margin is shown as inconclusive beside the search
    n = by["tight"].simulations
    assert by["tight"].verdict == "not_falsified" and by["tight"].proof.margin < 0.0
    assert by["tight"].decided_by.startswith(f"falsification ({n} simulations); reachability: inconclusive, margin -")
    assert by["later"].proof is None and by["later"].decided_by == f"falsification ({by['later'].simulations} simulations)"
    assert by["low"].verdict == "falsified" and by["low"].decided_by.startswith("falsification (")
    assert [r["decided_by"] for r in result.as_dict()["requirements"]] == [r.decided_by for r in result.requirements]
    json.dumps(result.as_dict())
