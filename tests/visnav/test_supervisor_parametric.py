"""Parametric questions on the supervisor: exclusive for every admissible envelope, or a witness that says where."""

from __future__ import annotations

import dataclasses

import pytest

from hybrid.decide import ParameterSpace, exclusive_for_all
from hybrid.symbolic import evaluate, param, substitute, Const

from visnav.scenario import load_scenario
from visnav.supervisor import build_supervisor, measurement_box, measurement_system, parameter_space


@pytest.fixture(scope="module")
def supervisor():
    scenario = load_scenario("paper")
    model = build_supervisor(scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    return model, measurement_system(model), measurement_box(model, scenario.camera.half_width_px)


def verdicts(pairs):
    return {(p.first, p.second): p.verdict for p in pairs}


def test_release_and_leave_pairs_are_exclusive_for_every_admissible_envelope(supervisor):
    model, system, box = supervisor
    modes = ("APPROACH|CLEAR", "LEAVE|RELEASE", "FAR|RELEASE")
    pairs = verdicts(exclusive_for_all(system, box, parameter_space(model), modes=modes))
    # d <= d- and d >= d+ + h exclude each other whenever d- < d+ and h > 0
    assert pairs[("APPROACH->AVOID@CLEAR", "APPROACH->FAR@CLEAR")] == "exclusive"
    # d_occ >= D_end and d_occ <= D-: D_end = max(D+, DL + D+ - D0) >= D+ > D- whatever the envelopes
    assert pairs[("LEAVE@RELEASE->CLEAR", "LEAVE@RELEASE->OCCLUDED")] == "exclusive"
    assert pairs[("FAR@RELEASE->CLEAR", "FAR@RELEASE->OCCLUDED")] == "exclusive"
    assert pairs[("LEAVE->FAR@RELEASE", "LEAVE->AVOID@RELEASE")] == "exclusive"
    # the latched dL >= d + 1 cm lets LEAVE->AVOID meet the occlusion transitions, for some envelope at least
    assert pairs[("LEAVE@RELEASE->CLEAR", "LEAVE->AVOID@RELEASE")] == "overlap"


def test_without_the_ordering_rule_the_approach_pair_overlaps_and_the_witness_says_where(supervisor):
    model, system, box = supervisor
    space = parameter_space(model)
    d_minus, d_plus = param("d_minus", 0.0), param("d_plus", 0.0)
    loose = dataclasses.replace(space, assumptions=(d_minus > 0.0, d_plus > 0.0, param("hysteresis", 0.0) > 0.0))
    (pair,) = [p for p in exclusive_for_all(system, box, loose, modes=("APPROACH|CLEAR",))
               if (p.first, p.second) == ("APPROACH->AVOID@CLEAR", "APPROACH->FAR@CLEAR")]
    assert pair.verdict == "overlap"
    values = pair.witness.values
    # both guards hold only if d+ + h <= d <= d-: the witness needs d- >= d+ + h
    assert values["param d_minus"] >= values["param d_plus"] + values["param hysteresis"] - 1e-12
    # re-evaluate the symbolic guards independently with the witness's parameters
    fixed = {n[len("param "):]: Const(c) for n, c in values.items() if n.startswith("param ")}
    automaton = model.automaton
    x = tuple(pair.witness.state[n] for n in system.state_names)
    v = system.signals(0.0, x)
    for name in (pair.first, pair.second):
        t = next(t for t in automaton.transitions if t.name == name)
        assert evaluate(substitute(t.guard, params=fixed), v, dict(pair.witness.memory)) >= 0.0


def test_a_parameter_space_without_free_parameters_is_refused():
    with pytest.raises(Exception, match="no free parameter"):
        ParameterSpace(bounds={})
    with pytest.raises(Exception, match="lower <= upper"):
        ParameterSpace(bounds={"h": (1.0, 0.0)})
