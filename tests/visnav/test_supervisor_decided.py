"""The paper's supervisor decided by hybrid.decide (through hybrid.check): pairs, memory, Zeno, witnesses.

Decided once (about 4 s) over the measurement system of ``visnav.supervisor``
with the paper scenario's envelopes and the measurement rate bounds; every
witness is re-evaluated with the automaton's own guards on the signals that the
model's output map derives from the witness state.
"""

from __future__ import annotations

import math
from collections import Counter

import networkx as nx
import pytest

from hybrid import check
from visnav.scenario import load_scenario
from visnav.supervisor import (
    COLLISION_PHASES,
    OCCLUSION_PHASES,
    build_supervisor,
    measurement_box,
    measurement_rates,
    measurement_system,
    mode_name,
)

MAX_STEP = {"d": 0.01, "d_occ": 4.0, "d_bord": 6.0, "pan": 0.04}
PERIOD_S = 0.05


@pytest.fixture(scope="module")
def decided():
    scenario = load_scenario("paper")
    n = len(scenario.obstacles)
    model = build_supervisor(scenario.envelopes, scenario.supervisor, n)
    system = measurement_system(model)
    box = measurement_box(model, scenario.camera.half_width_px)
    rates = measurement_rates(MAX_STEP, PERIOD_S, n)
    report = check(system, box, rates=rates)
    return {"model": model, "system": system, "box": box, "rates": rates, "report": report,
            "transitions": {t.name: t for t in system.automaton.transitions}}


def _signals(system, witness):
    return tuple(system.signals(0.0, tuple(witness.state[n] for n in system.state_names)))


def _guard(decided, name, witness):
    t = decided["transitions"][name]
    return float(t.guard(_signals(decided["system"], witness), dict(witness.memory)))


def test_pairs_sharing_a_source_mode_are_29_overlaps_and_14_exclusive(decided):
    a = decided["system"].automaton
    pairs = decided["report"].pairs
    expected = sum(math.comb(len(a.outgoing(q)), 2) for q in a.mode_names)
    assert len(pairs) == expected == 43
    assert Counter(p.verdict for p in pairs) == {"overlap": 29, "exclusive": 14}
    for p in pairs:
        ts = decided["transitions"]
        assert ts[p.first].source == ts[p.second].source == p.mode


def test_every_overlap_witness_enables_both_guards(decided):
    overlaps = [p for p in decided["report"].pairs if p.verdict == "overlap"]
    assert overlaps
    for p in overlaps:
        g1, g2 = _guard(decided, p.first, p.witness), _guard(decided, p.second, p.witness)
        assert g1 >= 0.0 and g2 >= 0.0, (p.mode, p.first, p.second, g1, g2)
        assert p.witness.values[f"guard {p.first}"] == pytest.approx(g1, abs=1e-12)
        assert p.witness.values[f"guard {p.second}"] == pytest.approx(g2, abs=1e-12)


def test_leave_to_avoid_overlaps_the_occlusion_transitions_with_dl_one_centimetre_above_d(decided):
    pairs = [p for p in decided["report"].pairs
             if p.mode.startswith("LEAVE|") and any(n.startswith("LEAVE->AVOID@") for n in (p.first, p.second))
             and any(n.startswith("LEAVE@") for n in (p.first, p.second))]
    assert len(pairs) == 4
    assert {p.mode for p in pairs} == {mode_name("LEAVE", o) for o in OCCLUSION_PHASES}
    d_minus = decided["model"].envelopes.d_minus_m
    for p in pairs:
        assert p.verdict == "overlap", (p.mode, p.first, p.second, p.detail)
        w = p.witness
        d = w.state[f"d_coll_{int(round(w.memory['obstacle']))}_m"]
        assert w.memory["dL"] >= d + 0.01 - 1e-12
        assert d <= d_minus + 1e-12


def test_release_transitions_never_overlap_because_d_end_is_latched_above_d_minus(decided):
    pairs = {(p.mode, p.first, p.second): p for p in decided["report"].pairs}
    a = decided["system"].automaton
    d_minus = decided["model"].envelopes.D_minus_px
    for c in COLLISION_PHASES:
        q = mode_name(c, "RELEASE")
        key = (q, f"{c}@RELEASE->CLEAR", f"{c}@RELEASE->OCCLUDED")
        assert key in pairs and pairs[key].verdict == "exclusive", key
        # at the automaton's initial memory (D_end = 0) the two guards would overlap (d_occ in [0, D-]):
        # the answer rests on the latched D_end of the entering OCCLUDED -> RELEASE reset
        to_clear, to_occluded = (decided["transitions"][n] for n in key[1:])
        v = [0.0] * len(a.variables)
        v[a.variables.index("d_occ_px")] = 0.5 * d_minus
        assert to_clear.guard(v, a.initial_memory()) >= 0 and to_occluded.guard(v, a.initial_memory()) >= 0
        assert "decided by the SMT solver (not sampled)" in decided["report"].searched.mode(q).notes
    assert sum(1 for p in decided["report"].pairs
               if "@RELEASE->" in p.first and "@RELEASE->" in p.second) == 6


def test_no_equal_priority_overlap_nondeterminism_proven(decided):
    report = decided["report"]
    assert not [p for p in report.pairs if p.same_priority and p.verdict == "overlap"]
    assert report.claim("nondeterminism") == "proven"
    assert not report.of_kind("nondeterminism")
    assert not report.errors
    assert {k: c.status for k, c in report.claims.items()} == dict.fromkeys(
        ("nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers", "zeno"), "proven")


def _cycle_count(automaton) -> int:
    """Simple cycles of the mode graph, each counted once per choice of parallel transitions."""
    parallel = Counter((t.source, t.target) for t in automaton.transitions)
    graph = nx.DiGraph(list(parallel))
    total = 0
    for cycle in nx.simple_cycles(graph):
        total += math.prod(parallel[(u, v)] for u, v in zip(cycle, cycle[1:] + cycle[:1]))
    return total


def test_every_cycle_is_non_zeno_with_a_positive_dwell_bound(decided):
    z = decided["report"].zeno
    assert not z.capped
    expected = _cycle_count(decided["system"].automaton)
    assert z.cycles == len(z.verdicts) == expected
    assert z.counts == {"non_zeno": expected, "infeasible": 0, "instantaneous": 0, "zeno_point": 0, "undecided": 0}
    assert all(v.verdict == "non_zeno" and v.dwell_s > 0.0 for v in z.verdicts)
    assert len({v.transitions for v in z.verdicts}) == expected  # no cycle counted twice


def test_the_smallest_dwell_bound_is_one_centimetre_at_the_distance_rate(decided):
    """LEAVE latches dL := d and LEAVE -> AVOID needs d <= dL - 0.01: d must move 0.01 m at <= 0.2 m/s.

    0.05 s is attained (a distance falling at the full rate right after the latch), so a sound lower bound
    cannot exceed it (up to float rounding of 0.01 / 0.2); the decider takes a relative margin of 1e-9
    off the optimiser's value before verifying it, so the bound lies within 1e-6 below it.
    """
    z = decided["report"].zeno
    rate = decided["rates"]["d_coll_0_m"]
    assert rate == pytest.approx(MAX_STEP["d"] / PERIOD_S) == pytest.approx(0.2)
    exact = 0.01 / rate
    assert exact * (1.0 - 1e-6) <= z.min_dwell_s <= exact * (1.0 + 1e-12)
    assert "LEAVE" in z.binding and "LEAVE->AVOID" in z.binding
    assert any(n.startswith("LEAVE->AVOID@") for n in z.binding_cycle)


def test_dropping_the_detection_hysteresis_is_caught_by_the_zeno_check():
    """A realistic slip (hysteresis 0, finding R2 of docs/fuzzing.md): FAR <-> APPROACH can cycle at one
    instant on d = d+, and the decided Zeno check says so with a re-checked witness."""
    from hybrid import check

    from visnav.parameters import Envelopes, SupervisorSettings
    from visnav.supervisor import build_supervisor, measurement_box, measurement_rates, measurement_system

    model = build_supervisor(Envelopes(), SupervisorSettings(detection_hysteresis_m=0.0), 2)
    rates = measurement_rates({"d": 0.01, "d_occ": 4.0, "d_bord": 6.0, "pan": 0.04}, 0.05, 2)
    report = check(measurement_system(model), measurement_box(model, 320.0), rates=rates)
    assert report.claims["zeno"].status == "found"
    cycles = [v for v in report.zeno.verdicts if v.verdict in ("zeno_point", "instantaneous")]
    assert cycles and all(set(v.transitions) <= {f"FAR->APPROACH@{o}" for o in ("CLEAR", "OCCLUDED", "RELEASE")}
                          | {f"APPROACH->FAR@{o}" for o in ("CLEAR", "OCCLUDED", "RELEASE")} for v in cycles)
    w = cycles[0].witness
    d_plus = Envelopes().d_plus_m
    assert min(w.state["d_coll_0_m"], w.state["d_coll_1_m"]) == pytest.approx(d_plus, abs=1e-12)
