"""The supervisor exported to SpaceEx and read back is the same automaton, decided symbolically.

``measurement_system(model, held=True)`` (symbolic zero flows) is written by
:func:`hybrid.spaceex_export.to_spaceex` and re-read by
:func:`hybrid.spaceex_import.import_spaceex`.  The comparison does not sample: z3 decides, for every
transition, that the union of its SpaceEx cases is enabled exactly where the original guard is, up to
:data:`EPS` on the guard's level (the constants' float folding; the signals replaced by the output map over
the measurements, the memory a state of the re-import), and that each case assigns the original reset
wherever it is enabled.  The yardstick is the solver on the original expressions; the exporter's own case
splitting is not reused.

The memory's ``obstacle`` is an index, 0 or 1 (the only values the resets give it).  SpaceEx reads
strict comparisons as closed (docs/spaceex.md): on the boundary of a strict split (a tie
``d_coll_0 = d_coll_1`` of the nearest obstacle, ``pan = 0`` of the arming sign) both cases are
enabled, each with its own value; the resets are compared off those boundaries and the test shows
that on them both readings are present.
"""

from __future__ import annotations

import re

import pytest

from hybrid.spaceex_export import spaceex_names, to_spaceex
from hybrid.spaceex_import import import_spaceex
from hybrid.symbolic import level_form, substitute
from visnav.parameters import Envelopes, SupervisorSettings
from visnav.supervisor import build_supervisor, measurement_system

import z3  # z3-solver is a required dependency: its absence is a failure, not a skip
from hybrid.smt import Translation, check_sat, fresh_context  # noqa: E402  (needs z3)

TIMEOUT_S = 20.0
EPS = 1e-9
"""Tolerance on guard levels and assigned values: the re-import folds constant arithmetic in floats
(``0.6 + 0.02`` is the double 0.62), the original's parameters are summed exactly by the solver; the two
differ by an ulp of the constants (~1e-16 here), far below this."""


@pytest.fixture(scope="module")
def exported():
    model = build_supervisor(Envelopes(), SupervisorSettings(), 2)
    system = measurement_system(model, held=True)
    xml = to_spaceex(system)
    back = import_spaceex(xml.encode(), source="supervisor").system
    return system, back, spaceex_names(system)


def _cases(back, label):
    return [u for u in back.automaton.transitions if re.fullmatch(rf"{re.escape(label)}(_\d+)?", u.name)]


def _on_measurements(system, node):
    """``node`` over the signals, with the output map put in for them (an expression over the measurements)."""
    out = dict(zip(system.automaton.variables, system.output.components))
    return substitute(node, coordinates=out)


def test_modes_transitions_and_flows_come_back(exported):
    system, back, names = exported
    memory = tuple(m.name for m in system.automaton.memory)
    assert back.state_names == (*system.state_names, *memory)
    assert back.automaton.mode_names == tuple(names[m] for m in system.automaton.mode_names)
    assert back.automaton.initial_mode == names[system.automaton.initial_mode]
    for t in system.automaton.transitions:
        cases = _cases(back, names[t.name])
        assert cases, t.name
        assert {(u.source, u.target) for u in cases} == {(names[t.source], names[t.target])}
    labels = {names[t.name] for t in system.automaton.transitions}
    assert all(any(re.fullmatch(rf"{re.escape(lb)}(_\d+)?", u.name) for lb in labels)
               for u in back.automaton.transitions)
    for mode in back.automaton.mode_names:  # held measurements, constant memory
        assert all(c.value == 0.0 for c in back.flows[mode].components)


def test_every_guard_is_the_union_of_its_cases_and_every_case_assigns_the_reset(exported):
    system, back, names = exported
    memory = tuple(m.name for m in system.automaton.memory)
    with fresh_context() as ctx:
        x = {n: z3.Real(n, ctx) for n in back.state_names}
        tr = Translation(coordinates=x, memory={n: x[n] for n in memory})
        domain = [z3.Or(x["obstacle"] == 0, x["obstacle"] == 1)]
        generic = [x["d_coll_0_m"] != x["d_coll_1_m"], x["pan_wrapped_rad"] != 0]
        decided = 0
        for t in system.automaton.transitions:
            tr.begin()
            original = tr.term(_on_measurements(system, t.guard)) >= 0
            cases = _cases(back, names[t.name])
            level = tr.term(_on_measurements(system, t.guard))
            enabled = [tr.term(level_form(u.guard)) >= 0 for u in cases]
            inside = check_sat([*domain, *tr.side, level >= EPS, z3.Not(z3.Or(*enabled))], TIMEOUT_S)
            outside = check_sat([*domain, *tr.side, level <= -EPS, z3.Or(*enabled)], TIMEOUT_S)
            assert (inside.status, outside.status) == ("unsat", "unsat"), (t.name, inside.model, outside.model)
            decided += 1
            if t.reset is None:
                continue
            for u, on in zip(cases, enabled):
                jump = back.jumps[u.name].components
                for name, e in t.reset.assignments.items():
                    tr.begin()
                    want = tr.term(_on_measurements(system, e))
                    got = tr.term(jump[back.state_names.index(name)])
                    differ = z3.Or(want - got > EPS, got - want > EPS)
                    answer = check_sat([*domain, *generic, *tr.side, original, on, differ], TIMEOUT_S)
                    assert answer.status == "unsat", (t.name, u.name, name, answer.status, answer.model)
                    decided += 1
        assert decided > 100


def test_on_a_strict_boundary_both_closed_cases_are_present(exported):
    """A tie of the two distances: the original latches obstacle 0 (the first one), SpaceEx also allows 1."""
    system, back, names = exported
    v_far = (0.3, 0.3, 1.0, 500.0, 100.0, 0.2)  # d_coll_0 = d_coll_1 = 0.3 m <= d+, both sides of the tie
    memory = {m.name: 0.0 for m in system.automaton.memory}
    t = next(t for t in system.automaton.transitions if t.name == "FAR->APPROACH@CLEAR")
    signals = system.signals(0.0, v_far)
    assert t.guard(signals, memory) >= 0 and t.reset(signals, memory)["obstacle"] == 0.0
    state = (*v_far, *memory.values())
    latched = {back.jump(u.name, 0.0, state, {})[back.state_names.index("obstacle")]
               for u in _cases(back, names[t.name]) if u.guard(state, {}) >= 0}
    assert latched == {0.0, 1.0}
