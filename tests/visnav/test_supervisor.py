"""The supervisor automaton: the paper's flag logic with every open question settled.

Property tests drive the automaton with bounded-rate signal sequences and
check the invariants after every sample; example tests pin the answer to
each open question of docs/supervisor.md.
"""

import math

import networkx as nx
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hybrid import mode_graph, settle
from visnav.parameters import Envelopes, SupervisorSettings
from visnav.supervisor import build_supervisor, split_mode

ENV = Envelopes()
MODEL = build_supervisor(ENV, SupervisorSettings(), n_obstacles=1)
AUTOMATON = MODEL.automaton


def signals(d, d_occ=math.inf, d_bord=math.inf, pan=0.0, side=1.0):
    return (d, 0.0, side, d_occ, d_bord, pan, d)


def run(sequence, mode=None, memory=None):
    """Feed signals sample by sample; return the list of (mode, memory, events, v)."""
    mode = mode or AUTOMATON.initial_mode
    memory = memory or AUTOMATON.initial_memory()
    previous = None
    out = []
    for k, v in enumerate(sequence):
        mode, memory, events = settle(AUTOMATON, mode, memory, v, previous, time=float(k), sample=k)
        out.append((mode, memory, events, v))
        previous = v
    return out


def test_structure():
    assert len(AUTOMATON.modes) == 18
    graph = mode_graph(AUTOMATON)
    reachable = nx.descendants(graph, AUTOMATON.initial_mode) | {AUTOMATON.initial_mode}
    assert reachable == set(AUTOMATON.mode_names)
    # LEAVE only with AVOID, in every mode
    for mode in AUTOMATON.modes:
        assert mode.labels["LEAVE"] <= mode.labels["AVOID"]


# ---- bounded-rate signal sequences -------------------------------------------------------
MAX_DD, MAX_DOCC, MAX_DBORD, MAX_DPAN = 0.01, 4.0, 6.0, 0.04


@st.composite
def bounded_rate_runs(draw, length=400):
    d = draw(st.floats(0.2, 1.2))
    d_occ = draw(st.floats(0.0, 150.0))
    d_bord = draw(st.floats(0.0, 300.0))
    pan = draw(st.floats(-1.0, 1.0))
    # piecewise-constant rates with a few switches: long excursions, plausible motions
    seq = []
    n_pieces = draw(st.integers(1, 8))
    cuts = sorted(draw(st.lists(st.integers(1, length - 1), min_size=n_pieces - 1, max_size=n_pieces - 1)))
    bounds = [0, *cuts, length]
    for a, b in zip(bounds[:-1], bounds[1:]):
        rd = draw(st.floats(-MAX_DD, MAX_DD))
        ro = draw(st.floats(-MAX_DOCC, MAX_DOCC))
        rb = draw(st.floats(-MAX_DBORD, MAX_DBORD))
        rp = draw(st.floats(-MAX_DPAN, MAX_DPAN))
        for _ in range(a, b):
            d = min(max(d + rd, 0.05), 1.5)
            d_occ = min(max(d_occ + ro, 0.0), 200.0)
            d_bord = min(max(d_bord + rb, 0.0), 320.0)
            pan = min(max(pan + rp, -1.5), 1.5)
            seq.append(signals(d, d_occ, d_bord, pan))
    return seq


@given(bounded_rate_runs())
def test_risk_parameters_bounded_continuous_and_flags_consistent(seq):
    states = run(seq)
    prev_mu = None
    prev_v = None
    for mode, memory, events, v in states:
        mu_c, mu_o = MODEL.risk(mode, v, memory)
        assert 0.0 <= mu_c <= 1.0 and 0.0 <= mu_o <= 1.0
        flags = MODEL.flags(mode)
        assert flags["LEAVE"] <= flags["AVOID"]
        # no jump at any transition: both sides of every jump agree on the same signals
        for e in events:
            before = MODEL.risk(e.source, v, dict(_memory_before(states, e, memory)))
            after = MODEL.risk(e.target, v, dict(e.memory))
            assert after == pytest.approx(before, abs=1e-12), (e.transition, before, after)
        # continuity in time: Lipschitz in the measured distances
        if prev_mu is not None:
            dd = abs(v[6] - prev_v[6])
            docc = abs(v[3] - prev_v[3])
            assert abs(mu_c - prev_mu[0]) <= dd / (ENV.d_plus_m - ENV.d_zero_m) + 1e-12
            assert abs(mu_o - prev_mu[1]) <= docc / (ENV.D_plus_px - ENV.D_zero_px) + 1e-12
        prev_mu, prev_v = (mu_c, mu_o), v


def _memory_before(states, event, memory_after_sample):
    """Memory just before ``event`` (the previous event's memory, or the previous sample's)."""
    k = event.sample
    earlier = [e for e in states[k][2] if e.jump < event.jump]
    if earlier:
        return earlier[-1].memory
    return states[k - 1][1].items() if k > 0 else AUTOMATON.initial_memory().items()


@given(bounded_rate_runs())
def test_no_chatter_under_bounded_rates(seq):
    """A component never switches back faster than its narrowest hysteresis band allows.

    The bands: detection hysteresis (2 cm) at 1 cm/sample, and the occlusion
    release margin (D0 - D-)/2 = 10 px at 4 px/sample: at least 2 samples.
    """
    settings = SupervisorSettings()
    min_gap = math.floor(
        min(settings.detection_hysteresis_m / MAX_DD, 0.5 * (ENV.D_zero_px - ENV.D_minus_px) / MAX_DOCC)
    )
    assert min_gap == 2
    states = run(seq)
    last = {}
    for mode, memory, events, v in states:
        assert len(events) <= 4
        for e in events:
            for comp in (0, 1):
                a, b = split_mode(e.source)[comp], split_mode(e.target)[comp]
                if a != b:
                    back = last.get((comp, b, a))
                    assert back is None or e.sample - back >= min_gap, (e.transition, e.sample, back)
                    last[(comp, a, b)] = e.sample


# ---- the open questions, one by one -------------------------------------------------------
def approach_and_avoid():
    """FAR -> APPROACH -> AVOID -> ARMED along a straight approach then a turning pan."""
    seq = [signals(0.8 - 0.01 * k) for k in range(60)]  # down to 0.21 m: enters d- = 0.3
    seq += [signals(0.25 + 0.005 * k, pan=0.01 * k) for k in range(50)]  # pan grows to 0.49 rad
    return seq


def test_q1_avoid_is_not_reset_when_leave_is_set():
    seq = approach_and_avoid() + [signals(0.5, pan=0.49 - 0.02 * k) for k in range(30)]
    states = run(seq)
    leave = [s for s in states if split_mode(s[0])[0] == "LEAVE"]
    assert leave, "LEAVE must be set once pan has come back through zero"
    mode, memory, events, v = leave[0]
    assert MODEL.flags(mode) == {"AVOID": 1, "LEAVE": 1, "OCCLU": 0}
    assert MODEL.risk(mode, v, memory)[0] == 1.0  # no jump: AVOID kept, mu_coll = 1 at dL


def test_q2_leave_is_reset_beyond_the_release_band():
    seq = approach_and_avoid() + [signals(0.5, pan=0.49 - 0.02 * k) for k in range(30)]
    seq += [signals(0.5 + 0.005 * k, pan=-0.1) for k in range(40)]  # moves away to 0.7 m
    states = run(seq)
    modes = [split_mode(s[0])[0] for s in states]
    assert modes[-1] == "FAR"
    i = modes.index("FAR", modes.index("LEAVE"))
    mode, memory, events, v = states[i]
    assert events[-1].transition.startswith("LEAVE->FAR")
    assert v[6] >= max(ENV.d_plus_m, 0.5 + ENV.d_plus_m - ENV.d_zero_m) - 1e-12
    assert MODEL.risk(mode, v, memory)[0] == 0.0


def test_q3_leave_band_takes_precedence_over_the_approach_band():
    """With LEAVE set and d in [d-, d0], mu follows case 3 of (2), not case 2."""
    seq = approach_and_avoid() + [signals(0.5, pan=0.49 - 0.02 * k) for k in range(30)]
    states = run(seq)
    mode, memory, _, _ = states[-1]
    assert split_mode(mode)[0] == "LEAVE"
    v = signals(0.45, pan=-0.1)
    assert MODEL.risk(mode, v, memory)[0] == 1.0  # below dL: still 1 (case 3 is for d >= dL)
    v = signals(0.55, pan=-0.1)
    d_end = memory["d_end"]
    assert MODEL.risk(mode, v, memory)[0] == pytest.approx((0.55 - d_end) / (memory["dL"] - d_end))


def test_q4_blending_band_without_entering_d_minus_never_sets_avoid():
    seq = [signals(0.8 - 0.01 * k) for k in range(35)] + [signals(0.45)] * 200  # stays in (d-, d0)
    states = run(seq)
    assert {split_mode(s[0])[0] for s in states} == {"FAR", "APPROACH"}
    mu = MODEL.risk(states[-1][0], states[-1][3], states[-1][1])[0]
    assert mu == pytest.approx((0.5 - 0.45) / 0.2)


def test_q5_dL_is_latched_at_the_switch():
    seq = approach_and_avoid() + [signals(0.5, pan=0.49 - 0.02 * k) for k in range(30)]
    seq += [signals(0.5 + 0.001 * k, pan=-0.1) for k in range(20)]
    states = run(seq)
    dls = {s[1]["dL"] for s in states if split_mode(s[0])[0] == "LEAVE"}
    assert dls == {0.5}


def test_q6_leave_needs_arming_and_uses_wrapped_pan():
    # pan stays ~0 during avoidance: never armed, so no LEAVE
    seq = [signals(0.8 - 0.01 * k) for k in range(60)] + [signals(0.5, pan=0.0)] * 100
    assert all(split_mode(s[0])[0] != "LEAVE" for s in run(seq))
    # a raw pan of 2*pi + 0.3 is wrapped by the measurement: the signal is 0.3
    from visnav.geometry import wrap_angle

    assert wrap_angle(2 * math.pi + 0.3) == pytest.approx(0.3)
    # crossing +pi/-pi (going the long way round) is not "pan = 0"
    seq = approach_and_avoid() + [signals(0.5, pan=p) for p in (1.0, 2.0, 3.0, -3.1, -2.0)]
    assert all(split_mode(s[0])[0] != "LEAVE" for s in run(seq))


def test_q6_leave_is_held_back_while_mu_occ_positive():
    seq = approach_and_avoid()
    seq += [signals(0.5, d_occ=50.0, d_bord=200.0, pan=0.49 - 0.02 * k) for k in range(30)]  # mu_occ = 0.5
    states = run(seq)
    assert split_mode(states[-1][0])[0] == "PASSED"
    seq += [signals(0.5, d_occ=50.0 + 2 * k, d_bord=200.0, pan=-0.2) for k in range(10)]
    states = run(seq)
    i = next(i for i, s in enumerate(states) if split_mode(s[0])[0] == "LEAVE")
    mode, memory, events, v = states[i]
    assert v[3] >= ENV.D_zero_px  # LEAVE only once mu_occ = 0
    assert MODEL.risk(mode, v, memory) == (1.0, 0.0)


def test_q7_q8_occlu_reset_and_release_phase():
    seq = [signals(2.0, d_occ=100.0 - 2 * k, d_bord=200.0) for k in range(40)]  # down to 22 px: OCCLU
    seq += [signals(2.0, d_occ=22.0 + 2 * k, d_bord=200.0) for k in range(40)]  # back out to 100 px
    states = run(seq)
    occ = [split_mode(s[0])[1] for s in states]
    assert "OCCLUDED" in occ and occ[-1] == "CLEAR"
    i = occ.index("RELEASE")
    mode, memory, events, v = states[i]
    assert v[3] >= ENV.D_zero_px and memory["DL"] == v[3]
    assert MODEL.risk(mode, v, memory)[1] == 1.0  # release starts at 1: no jump (question 8)
    mus = [MODEL.risk(s[0], s[3], s[1])[1] for s in states]
    assert all(abs(a - b) <= 2.0 / 20.0 + 1e-12 for a, b in zip(mus, mus[1:]))


def test_q7_occluder_leaving_the_image_releases():
    seq = [signals(2.0, d_occ=100.0 - 2 * k, d_bord=100.0) for k in range(40)]
    seq += [signals(2.0, d_occ=55.0, d_bord=100.0 - 10 * k) for k in range(12)]  # d_bord reaches 0
    states = run(seq)
    occ = [split_mode(s[0])[1] for s in states]
    i = occ.index("RELEASE")
    assert states[i][3][4] == 0.0 and states[i][1]["DL"] == 55.0


def test_structural_check_finds_a_planted_equal_priority_in_the_supervisor():
    """hybrid.check over the consistent measurement model: clean as built, and not vacuous."""
    import dataclasses

    from hybrid import HybridAutomaton, check
    from visnav.supervisor import measurement_box, measurement_rates, measurement_system

    model = build_supervisor(Envelopes(), SupervisorSettings(), 2)
    box = measurement_box(model, 320.0)
    # the rate bounds let the Zeno question be settled by dwell bounds (without them every cycle needs a lap query)
    rates = measurement_rates({"d": 0.01, "d_occ": 4.0, "d_bord": 6.0, "pan": 0.04}, 0.05, 2)
    assert check(measurement_system(model), box, samples=40, starts=2, rates=rates).clean
    a = model.automaton
    mutated = tuple(
        dataclasses.replace(t, priority=10) if t.name.startswith("ARMED->PASSED") else t for t in a.transitions
    )
    mutant = dataclasses.replace(
        model,
        automaton=HybridAutomaton(name=a.name, modes=a.modes, transitions=mutated, variables=a.variables,
                                  memory=a.memory, initial_mode=a.initial_mode),
    )
    report = check(measurement_system(mutant), box, samples=40, starts=2, rates=rates)
    found = [f for f in report.findings if f.kind == "nondeterminism"]
    assert found and all(f.severity == "error" for f in found)
    assert {f.modes[0] for f in found} == {"ARMED|CLEAR"}  # elsewhere ARMED->LEAVE does not exist
    witness = found[0].witness
    transitions = {t.name: t for t in mutated}
    v = tuple(witness.signals[name] for name in a.variables)
    assert all(transitions[name].guard(v, dict(witness.memory)) >= 0.0 for name in found[0].transitions)
