"""The supervisor's rules are written once, as data (issue 26): the automaton and its texts derive from them."""

from __future__ import annotations

import math

import pytest

from hybrid.spaceex_export import to_spaceex
from hybrid.spaceex_syntax import SpaceExError
from hybrid.symbolic import is_symbolic
from visnav.parameters import Envelopes, SupervisorSettings
from visnav.supervisor import (
    COLLISION_PHASES,
    COLLISION_RULES,
    OCCLUSION_PHASES,
    OCCLUSION_RULES,
    build_supervisor,
    measurement_system,
    split_mode,
)

ENV, SETTINGS = Envelopes(), SupervisorSettings()


def test_every_transition_is_one_rule_in_one_phase_with_the_rules_text_and_priority():
    a = build_supervisor(ENV, SETTINGS, 2).automaton
    rules = {("c", r.source, r.target): r for r in COLLISION_RULES} | {("o", r.source, r.target): r
                                                                         for r in OCCLUSION_RULES}
    assert len(rules) == len(COLLISION_RULES) + len(OCCLUSION_RULES)  # no rule written twice
    expected = sum(len(r.phases or OCCLUSION_PHASES) for r in COLLISION_RULES)
    expected += len(OCCLUSION_RULES) * len(COLLISION_PHASES)
    assert len(a.transitions) == expected == 47
    for t in a.transitions:
        (c0, o0), (c1, o1) = split_mode(t.source), split_mode(t.target)
        rule = rules[("c", c0, c1)] if o0 == o1 else rules[("o", o0, o1)]
        assert (c0 == c1) == (o0 != o1)
        assert t.guard_text == rule.guard_text and t.reset_text == rule.reset_text and t.priority == rule.priority
        assert t.writes == (rule.reset.writes if rule.reset else ())
        assert is_symbolic(t.guard) and (t.reset is None or is_symbolic(t.reset))
    assert {t.name for t in a.transitions if t.name.startswith("ARMED->LEAVE")} == {"ARMED->LEAVE@CLEAR"}


def test_the_instantiated_guards_are_the_papers_conditions_at_the_scenarios_values():
    """Values computed by hand from Envelopes() (d- 0.3, d0 0.5, d+ 0.6, D- 40, D0 60, D+ 80) and the settings
    (arm 0.2 rad, hysteresis 0.02 m), with obstacle 1 latched at d_coll_1 = 0.25 m."""
    a = build_supervisor(ENV, SETTINGS, 2).automaton
    guard = {t.name: t.guard for t in a.transitions}
    reset = {t.name: t.reset for t in a.transitions}
    v = (0.25, 1.0, 1.0, 50.0, 0.0, -0.1, 0.9, 0.25)  # d_nearest, nearest, side, d_occ, d_bord, pan, d_coll_0, d_coll_1
    m = {"obstacle": 1.0, "side": 1.0, "arm_sign": 1.0, "dL": 0.27, "d_end": 0.7, "DL": 0.0, "D_end": 0.0}
    assert guard["LEAVE->AVOID@CLEAR"](v, m) == pytest.approx(min(0.3 - 0.25, 0.27 - 0.01 - 0.25), abs=1e-15)
    assert guard["APPROACH->FAR@CLEAR"](v, m) == pytest.approx(0.25 - 0.62, abs=1e-15)
    assert guard["ARMED->PASSED@CLEAR"](v, m) == pytest.approx(min(0.1, math.pi / 2 - 0.1), abs=1e-15)
    assert guard["ARMED->LEAVE@CLEAR"](v, m) == pytest.approx(min(0.1, 50.0 - 60.0), abs=1e-12)
    # d_bord = 0 and d_occ = 50 >= (40 + 60)/2: the release fires although d_occ < D0
    assert guard["FAR@OCCLUDED->RELEASE"](v, m) == pytest.approx(max(50.0 - 60.0, min(0.0, 50.0 - 50.0)), abs=1e-12)
    assert reset["PASSED->LEAVE@CLEAR"](v, m) == pytest.approx({"dL": 0.25, "d_end": max(0.6, 0.25 + 0.1)})
    assert reset["FAR@OCCLUDED->RELEASE"](v, m) == pytest.approx({"DL": 50.0, "D_end": 80.0})
    hidden = (0.25, 1.0, 1.0, math.inf, 0.0, -0.1, 0.9, 0.25)  # no occluder in view: DL latches D0
    assert reset["FAR@OCCLUDED->RELEASE"](hidden, m) == pytest.approx({"DL": 60.0, "D_end": 80.0})


def test_measurement_flows_are_symbolic_only_when_held():
    model = build_supervisor(ENV, SETTINGS, 1)
    plain, held = measurement_system(model), measurement_system(model, held=True)
    assert not any(is_symbolic(f) for f in plain.flows.values())
    assert all(is_symbolic(f) and all(c.value == 0.0 for c in f.components) for f in held.flows.values())
    assert plain.flow("FAR|CLEAR", 0.0, (0.1,) * plain.dimension, {}) == held.flow("FAR|CLEAR", 0.0,
                                                                                   (0.1,) * held.dimension, {})
    with pytest.raises(SpaceExError, match=r"mode 'FAR\|CLEAR'.*flow.*Python function"):
        to_spaceex(plain)
    assert "<location" in to_spaceex(held)
