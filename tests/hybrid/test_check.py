"""Tests of hybrid.check: every finding kind with a witness that re-verifies, clean models stay clean.

Witnesses are re-verified here by evaluating the model's own guards, invariants,
flows and jump maps at the witness state, independently of the checker's code.
"""

import json
import math

import pytest

from hybrid import (
    Box,
    ExecutionError,
    HybridAutomaton,
    HybridSystem,
    MemoryVariable,
    Mode,
    ModelDefinitionError,
    Transition,
    all_of,
)
from hybrid.check import KIND_SEVERITY, CheckReport, Finding, Witness, check

TOL = 1e-9  # the checker's default tolerance, used by the re-verifications below
SAMPLES = 400  # enough for these one- and two-dimensional fixtures, keeps the suite fast


# ---------------------------------------------------------------------- fixtures
def thermostat(*, heat_guard=None, heat_jump=None, cool_guard=None):
    """Thermostat with hysteresis: off (T >= 18, cools to 10), on (T <= 22, heats to 30).

    heat: off -> on at T <= 19, cool: on -> off at T >= 21 (both level-triggered).
    Clean with the defaults.
    """
    automaton = HybridAutomaton(
        name="thermostat",
        modes=(
            Mode(name="off", invariant=lambda v, m: v[0] - 18.0),
            Mode(name="on", invariant=lambda v, m: 22.0 - v[0]),
        ),
        transitions=(
            Transition(name="heat", source="off", target="on", guard=heat_guard or (lambda v, m: 19.0 - v[0])),
            Transition(name="cool", source="on", target="off", guard=cool_guard or (lambda v, m: v[0] - 21.0)),
        ),
        variables=("T",),
    )
    return HybridSystem(
        automaton=automaton,
        state_names=("T",),
        flows={"off": lambda t, x, m: (-0.1 * (x[0] - 10.0),), "on": lambda t, x, m: (0.1 * (30.0 - x[0]),)},
        jumps={"heat": heat_jump} if heat_jump else {},
    )


THERMO_BOX = Box(bounds={"T": (10.0, 30.0)})

E = 0.8  # restitution of the ball


def ball(*, guard=None):
    """Bouncing ball: invariant h >= 0, crossing-triggered bounce on -h (direction +1), v -> -e v."""
    automaton = HybridAutomaton(
        name="ball",
        modes=(Mode(name="fall", invariant=lambda v, m: v[0]),),
        transitions=(
            Transition(name="bounce", source="fall", target="fall", guard=guard or (lambda v, m: -v[0]), direction=+1),
        ),
        variables=("h", "v"),
    )
    return HybridSystem(
        automaton=automaton,
        state_names=("h", "v"),
        flows={"fall": lambda t, x, m: (x[1], -9.81)},
        jumps={"bounce": lambda x, m: (x[0], -E * x[1])},
    )


BALL_BOX = Box(bounds={"h": (-1.0, 10.0), "v": (-20.0, 20.0)})


def one_state(name, modes, transitions, *, memory=()):
    """A bare automaton over one signal x."""
    return HybridAutomaton(name=name, modes=modes, transitions=transitions, variables=("x",), memory=memory)


def forked(priority_b=0, guard_a=None, guard_b=None):
    """Mode idle with two transitions: to_a at x >= 1, to_b at x <= 2 (overlap [1, 2])."""
    return one_state(
        "forked",
        (Mode(name="idle"), Mode(name="a"), Mode(name="b")),
        (
            Transition(name="to_a", source="idle", target="a", guard=guard_a or (lambda v, m: v[0] - 1.0)),
            Transition(name="to_b", source="idle", target="b", guard=guard_b or (lambda v, m: 2.0 - v[0]),
                       priority=priority_b),
            Transition(name="a_back", source="a", target="idle", guard=lambda v, m: -1.0),
            Transition(name="b_back", source="b", target="idle", guard=lambda v, m: -1.0),
        ),
    )


X_BOX = Box(bounds={"x": (-3.0, 3.0)})


# ---------------------------------------------------------------------- re-verification helpers
def state_of(model, witness):
    """(x, v, m) re-derived from the witness with the model's own output map."""
    if isinstance(model, HybridSystem):
        x = tuple(witness.state[n] for n in model.state_names)
        v = model.signals(0.0, x)
        automaton = model.automaton
    else:
        x = tuple(witness.state[n] for n in model.variables)
        v = x
        automaton = model
    assert tuple(witness.signals[n] for n in automaton.variables) == pytest.approx(v, abs=0.0)
    return x, v, dict(witness.memory)


def automaton_of(model):
    return model.automaton if isinstance(model, HybridSystem) else model


def transition(model, name):
    return next(t for t in automaton_of(model).transitions if t.name == name)


def invariant(model, mode, v, m):
    inv = automaton_of(model).mode(mode).invariant
    return math.inf if inv is None else inv(v, m)


def only(report, kind):
    found = report.of_kind(kind)
    assert len(found) == 1, [f.message for f in report.findings]
    return found[0]


def assert_only_zeno_undecided(report):
    """Sampled plain callables: no error, every check answered but the Zeno cycles, so the report is not clean."""
    assert [reason.split()[:2] for reason in report.incomplete] == [["zeno", "undecided:"]], report.incomplete
    assert not report.complete and not report.clean


# ---------------------------------------------------------------------- clean models
def test_thermostat_with_hysteresis_is_clean():
    report = check(thermostat(), THERMO_BOX, samples=SAMPLES)
    assert report.no_findings, [f.message for f in report.findings if f.severity != "info"]
    assert_only_zeno_undecided(report)
    assert report.kinds() == {"zeno_candidate"}  # the off -> on -> off cycle, an info
    cycle = only(report, "zeno_candidate")
    assert cycle.modes == ("off", "on") and cycle.transitions == ("heat", "cool")
    off = report.searched.mode("off")
    assert (off.samples, off.corners, off.box) == (SAMPLES, 2, "T ∈ [10, 30]")
    assert off.boundary_points > 0 and off.starts > 0 and off.function_calls > SAMPLES
    assert set(report.searched.checks.values()) == {"ran"}


def test_bouncing_ball_with_crossing_guard_is_clean():
    # The boundary h = 0 is found by bisection from h < 0 samples: there the guard -h sits within tol
    # of zero (enabled within tol), so this is also the test that the deadlock check is not fooled by it.
    report = check(ball(), BALL_BOX, samples=SAMPLES)
    assert report.no_findings, [f.message for f in report.findings if f.severity != "info"]
    assert_only_zeno_undecided(report)
    assert report.kinds() == {"zeno_candidate"}
    assert "crossing guards do not re-fire" in report.searched.checks["reset_retriggers"]


def test_crossing_self_loop_that_sits_on_its_guard_is_not_a_retrigger():
    # The jump keeps x on the guard x >= 1: level-triggered it fires forever, crossing-triggered it does not.
    def automaton(direction):
        return one_state(
            "stay",
            (Mode(name="s"),),
            (Transition(name="loop", source="s", target="s", guard=lambda v, m: v[0] - 1.0, direction=direction),),
        )

    assert check(automaton(+1), X_BOX, samples=SAMPLES).kinds("error") == frozenset()
    assert check(automaton(0), X_BOX, samples=SAMPLES).kinds("error") == {"reset_retriggers"}


# ---------------------------------------------------------------------- nondeterminism
def test_nondeterminism_witness_enables_both_guards():
    model = forked()
    report = check(model, X_BOX, samples=SAMPLES)
    finding = only(report, "nondeterminism")
    assert finding.severity == "error" and finding.transitions == ("to_a", "to_b") and finding.modes == ("idle",)
    x, v, m = state_of(model, finding.witness)
    assert transition(model, "to_a").guard(v, m) >= 0.0 and transition(model, "to_b").guard(v, m) >= 0.0
    assert finding.witness.values["guard to_a"] == transition(model, "to_a").guard(v, m)
    assert "'to_a' and 'to_b'" in finding.message and "idle" in finding.message
    assert f"{finding.witness.values['guard to_a']:.10g}" in finding.message
    assert not report.clean and report.errors == (finding,)


def test_different_priorities_are_a_priority_overlap_info():
    report = check(forked(priority_b=1), X_BOX, samples=SAMPLES)
    finding = only(report, "priority_overlap")
    assert finding.severity == "info" and "in favour of 'to_a'" in finding.message
    assert "nondeterminism" not in report.kinds() and report.no_findings
    assert_only_zeno_undecided(report)


def test_overlap_on_a_single_point_is_found_by_the_optimiser():
    # to_a: x >= 0.3, to_b: x <= 0.3; the overlap is the single point x = 0.3, which uniform sampling
    # (and the corners -3, 3) never hits: only the local search (with rounding of its answer) finds it.
    model = forked(guard_a=lambda v, m: v[0] - 0.3, guard_b=lambda v, m: 0.3 - v[0])
    report = check(model, X_BOX, samples=SAMPLES)
    finding = only(report, "nondeterminism")
    x, v, m = state_of(model, finding.witness)
    assert transition(model, "to_a").guard(v, m) >= 0.0 and transition(model, "to_b").guard(v, m) >= 0.0
    # Without optimiser starts the same search misses it: the test above can fail.
    assert "nondeterminism" not in check(model, X_BOX, samples=SAMPLES, starts=0).kinds()


def test_overlap_outside_the_invariant_is_not_nondeterminism():
    model = one_state(
        "guarded",
        (Mode(name="idle", invariant=lambda v, m: 0.5 - v[0]), Mode(name="a"), Mode(name="b")),
        (
            Transition(name="to_a", source="idle", target="a", guard=lambda v, m: v[0] - 1.0),
            Transition(name="to_b", source="idle", target="b", guard=lambda v, m: 2.0 - v[0]),
            Transition(name="a_back", source="a", target="idle", guard=lambda v, m: -v[0]),
            Transition(name="b_back", source="b", target="idle", guard=lambda v, m: -v[0]),
        ),
    )
    assert "nondeterminism" not in check(model, X_BOX, samples=SAMPLES).kinds()


def test_discrete_choices_are_enumerated_not_optimised():
    # Overlap only for side = +1; side is a discrete coordinate, so the witness carries exactly +1.
    automaton = HybridAutomaton(
        name="sided",
        modes=(Mode(name="idle"), Mode(name="a"), Mode(name="b")),
        transitions=(
            Transition(name="to_a", source="idle", target="a", guard=lambda v, m: v[0] - 1.0),
            Transition(name="to_b", source="idle", target="b",
                       guard=all_of(lambda v, m: v[1], lambda v, m: 2.0 - v[0])),
            Transition(name="a_back", source="a", target="idle", guard=lambda v, m: -1.0),
            Transition(name="b_back", source="b", target="idle", guard=lambda v, m: -1.0),
        ),
        variables=("x", "side"),
    )
    box = Box(bounds={"x": (1.5, 3.0)}, choices={"side": (-1.0, 1.0)})
    finding = only(check(automaton, box, samples=SAMPLES), "nondeterminism")
    assert finding.witness.state["side"] == 1.0
    x, v, m = state_of(automaton, finding.witness)
    assert automaton.transitions[0].guard(v, m) >= 0.0 and automaton.transitions[1].guard(v, m) >= 0.0


def test_search_over_state_through_an_output_map():
    # Guards read s = x + y; the box is over the state (x, y): an overlap s in [1, 2].
    automaton = HybridAutomaton(
        name="summed",
        modes=(Mode(name="idle"), Mode(name="a"), Mode(name="b")),
        transitions=(
            Transition(name="to_a", source="idle", target="a", guard=lambda v, m: v[0] - 1.0),
            Transition(name="to_b", source="idle", target="b", guard=lambda v, m: 2.0 - v[0]),
            Transition(name="a_back", source="a", target="idle", guard=lambda v, m: -1.0),
            Transition(name="b_back", source="b", target="idle", guard=lambda v, m: -1.0),
        ),
        variables=("s",),
    )
    zero = lambda t, x, m: (0.0, 0.0)  # noqa: E731
    system = HybridSystem(
        automaton=automaton, state_names=("x", "y"), flows={"idle": zero, "a": zero, "b": zero},
        output=lambda t, x: (x[0] + x[1],),
    )
    box = Box(bounds={"x": (0.0, 1.0), "y": (0.0, 1.0)})
    finding = only(check(system, box, samples=SAMPLES), "nondeterminism")
    x, v, m = state_of(system, finding.witness)
    assert 1.0 <= v[0] <= 2.0
    with pytest.raises(ModelDefinitionError, match=r"missing coordinate\(s\) \['x', 'y'\]"):
        check(system, Box(bounds={"s": (0.0, 2.0)}))  # the signals are not the search space of a system


# ---------------------------------------------------------------------- deadlock
def test_deadlock_of_a_system_witness_is_on_the_boundary_and_leaving():
    # heat now needs T <= 17.5, below the invariant T >= 18 of off: at T = 18 the room cools out of 'off'.
    model = thermostat(heat_guard=lambda v, m: 17.5 - v[0])
    finding = only(check(model, THERMO_BOX, samples=SAMPLES), "deadlock")
    assert finding.severity == "error" and finding.modes == ("off",)
    x, v, m = state_of(model, finding.witness)
    inv = invariant(model, "off", v, m)
    assert 0.0 <= inv <= TOL
    assert transition(model, "heat").guard(v, m) < -TOL
    # d/dt inv = dT/dt = -0.1 (T - 10) = -0.8 at T = 18.  The checker's centred difference of an affine
    # invariant is exact up to rounding: h |f| = 1e-7 * 20 gives a relative error ~ 1e-16 * 18 / 2e-6 ≈ 1e-9.
    rate = finding.witness.values["d/dt invariant off"]
    assert rate == pytest.approx(-0.1 * (x[0] - 10.0), rel=1e-6)
    assert rate == pytest.approx(-0.8, rel=1e-6)
    assert "'off'" in finding.message and "guard heat = -0.5" in finding.message


def test_deadlock_of_a_ball_whose_bounce_fires_too_late():
    # The bounce needs h <= -0.5 but the invariant ends at h = 0: a falling ball (v < 0) is stuck there.
    model = ball(guard=lambda v, m: -v[0] - 0.5)
    finding = only(check(model, BALL_BOX, samples=SAMPLES), "deadlock")
    x, v, m = state_of(model, finding.witness)
    assert 0.0 <= invariant(model, "fall", v, m) <= TOL
    assert x[1] < 0.0  # dh/dt = v < 0: leaving h >= 0
    assert finding.witness.values["d/dt invariant fall"] == pytest.approx(x[1], rel=1e-6)
    assert transition(model, "bounce").guard(v, m) < -TOL
    assert "crossing-triggered ['bounce']" in finding.message


def test_deadlock_of_a_bare_automaton_is_any_boundary_point_without_enabled_guard():
    model = one_state(
        "stuck",
        (Mode(name="a", invariant=lambda v, m: 5.0 - v[0]), Mode(name="b")),
        (
            Transition(name="go", source="a", target="b", guard=lambda v, m: v[0] - 6.0),
            Transition(name="back", source="b", target="a", guard=lambda v, m: -v[0]),
        ),
    )
    finding = only(check(model, Box(bounds={"x": (0.0, 10.0)}), samples=SAMPLES), "deadlock")
    x, v, m = state_of(model, finding.witness)
    assert 0.0 <= 5.0 - x[0] <= TOL and transition(model, "go").guard(v, m) < -TOL
    assert "d/dt invariant a" not in finding.witness.values  # no flow: every boundary point counts
    assert "no flow" in finding.message


def test_no_deadlock_where_the_flow_points_inwards():
    # Same stuck boundary T = 18, but the room now warms in 'off' (flow towards 30): it never leaves.
    model = thermostat(heat_guard=lambda v, m: 17.5 - v[0])
    warming = HybridSystem(
        automaton=model.automaton, state_names=("T",),
        flows={"off": lambda t, x, m: (0.1 * (30.0 - x[0]),), "on": lambda t, x, m: (-0.1 * (x[0] - 10.0),)},
    )
    report = check(warming, THERMO_BOX, samples=SAMPLES)
    assert "deadlock" not in report.kinds()


def test_discontinuous_invariant_boundary_is_not_claimed_as_a_deadlock():
    # inv jumps from +1 to -1 at x = 5: bisection ends next to the jump with inv = 1 > tol, which is no
    # "inv = 0 within tol" boundary point; the summary says so instead of reporting a witness that is not one.
    model = one_state(
        "step",
        (Mode(name="a", invariant=lambda v, m: 1.0 if v[0] <= 5.0 else -1.0), Mode(name="b")),
        (
            Transition(name="go", source="a", target="b", guard=lambda v, m: v[0] - 6.0),
            Transition(name="back", source="b", target="a", guard=lambda v, m: -v[0]),
        ),
    )
    report = check(model, Box(bounds={"x": (0.0, 10.0)}), samples=SAMPLES)
    assert "deadlock" not in report.kinds()
    assert any("where the invariant jumps" in note for note in report.searched.mode("a").notes)


# ---------------------------------------------------------------------- resets
def test_reset_outside_invariant_witness_lands_outside():
    # heat boosts T by 5: from T in [18, 19] it lands in [23, 24], outside on's T <= 22.
    model = thermostat(heat_jump=lambda x, m: (x[0] + 5.0,))
    finding = only(check(model, THERMO_BOX, samples=SAMPLES), "reset_outside_invariant")
    assert finding.severity == "error" and finding.modes == ("off", "on") and finding.transitions == ("heat",)
    x, v, m = state_of(model, finding.witness)
    assert transition(model, "heat").guard(v, m) >= 0.0 and invariant(model, "off", v, m) >= 0.0
    post = model.jump("heat", 0.0, x, m)
    assert post == (finding.witness.values["post T"],)
    after = invariant(model, "on", model.signals(0.0, post), m)
    assert after < -TOL and after == finding.witness.values["invariant on after heat"]


def test_memory_reset_outside_invariant_with_memory_in_the_box():
    # 'arm' latches limit := x + 1, but mode 'armed' requires x <= limit - 2: always violated after the jump.
    # The box searches the memory 'gain' (read by the guard) over [0, 1]; 'limit' keeps its initial value.
    model = one_state(
        "latched",
        (Mode(name="idle"), Mode(name="armed", invariant=lambda v, m: m["limit"] - 2.0 - v[0])),
        (
            Transition(name="arm", source="idle", target="armed", guard=lambda v, m: m["gain"] * v[0] - 0.5,
                       reset=lambda v, m: {"limit": v[0] + 1.0}, writes=("limit",)),
            Transition(name="disarm", source="armed", target="idle", guard=lambda v, m: -v[0]),
        ),
        memory=(MemoryVariable(name="limit", initial=100.0), MemoryVariable(name="gain", initial=0.0)),
    )
    box = Box(bounds={"x": (0.0, 3.0)}, memory={"gain": (0.0, 1.0)})
    finding = only(check(model, box, samples=SAMPLES), "reset_outside_invariant")
    x, v, m = state_of(model, finding.witness)
    assert m["limit"] == 100.0 and 0.0 <= m["gain"] <= 1.0
    arm = transition(model, "arm")
    assert arm.guard(v, m) >= 0.0
    after = {**m, **arm.reset(v, m)}
    assert invariant(model, "armed", v, after) < -TOL
    assert finding.witness.values["post memory limit"] == after["limit"]
    assert "memory {limit=100" in finding.message


def test_self_loop_retrigger_witness_fires_again():
    # wrap: x >= 1, x := x - 1: from x >= 2 it is enabled again right after its jump.
    model = one_state(
        "wrap", (Mode(name="run"),),
        (Transition(name="wrap", source="run", target="run", guard=lambda v, m: v[0] - 1.0),),
    )
    system = HybridSystem(
        automaton=model, state_names=("x",), flows={"run": lambda t, x, m: (1.0,)},
        jumps={"wrap": lambda x, m: (x[0] - 1.0,)},
    )
    finding = only(check(system, Box(bounds={"x": (0.0, 3.0)}), samples=SAMPLES), "reset_retriggers")
    assert finding.transitions == ("wrap", "wrap") and finding.severity == "error"
    x, v, m = state_of(system, finding.witness)
    guard = transition(system, "wrap").guard
    assert guard(v, m) >= 0.0 and guard(system.jump("wrap", 0.0, x, m), m) >= 0.0
    # x := 0 instead leaves the guard set: clean.
    fixed = HybridSystem(automaton=model, state_names=("x",), flows=system.flows,
                         jumps={"wrap": lambda x, m: (0.0,)})
    assert "reset_retriggers" not in check(fixed, Box(bounds={"x": (0.0, 3.0)}), samples=SAMPLES).kinds()


def test_ping_pong_retrigger_names_the_chain():
    # A -> B at x >= 0, B -> A at x >= 0.5: for x >= 0.5 the pair fires back and forth at one instant.
    model = one_state(
        "pingpong", (Mode(name="A"), Mode(name="B")),
        (
            Transition(name="ab", source="A", target="B", guard=lambda v, m: v[0]),
            Transition(name="ba", source="B", target="A", guard=lambda v, m: v[0] - 0.5),
        ),
    )
    report = check(model, Box(bounds={"x": (-1.0, 1.0)}), samples=SAMPLES)
    findings = report.of_kind("reset_retriggers")
    assert {f.transitions for f in findings} == {("ab", "ba", "ab"), ("ba", "ab", "ba")}
    for f in findings:
        x, v, m = state_of(model, f.witness)
        assert all(transition(model, name).guard(v, m) >= 0.0 for name in f.transitions)
        assert f.modes in (("A", "B", "A"), ("B", "A", "B"))


def test_retrigger_on_a_measure_zero_part_of_the_guard_set_is_a_zeno_point():
    # Level-triggered ball: bounce at h <= 0 and v <= 0, v := -e v.  It lands back on its guard only at
    # the rest state (0, 0): reported as an info, not as an error.
    automaton = HybridAutomaton(
        name="level_ball",
        modes=(Mode(name="fall", invariant=lambda v, m: v[0]),),
        transitions=(Transition(name="bounce", source="fall", target="fall",
                                guard=all_of(lambda v, m: -v[0], lambda v, m: -v[1])),),
        variables=("h", "v"),
    )
    system = HybridSystem(automaton=automaton, state_names=("h", "v"), flows=ball().flows,
                          jumps={"bounce": lambda x, m: (x[0], -E * x[1])})
    report = check(system, Box(bounds={"h": (0.0, 10.0), "v": (-20.0, 20.0)}), samples=SAMPLES)
    assert report.no_findings
    assert_only_zeno_undecided(report)
    finding = only(report, "zeno_point")
    assert finding.severity == "info"
    assert finding.witness.state["h"] == 0.0 and finding.witness.state["v"] == 0.0


# ---------------------------------------------------------------------- graph checks
def test_graph_checks_unreachable_and_sink():
    model = one_state(
        "graph",
        (Mode(name="start"), Mode(name="goal"), Mode(name="orphan")),
        (
            Transition(name="finish", source="start", target="goal", guard=lambda v, m: v[0]),
            Transition(name="lost", source="orphan", target="start", guard=lambda v, m: v[0]),
        ),
    )
    report = check(model)
    assert report.kinds() == {"unreachable_mode", "unreachable_transition", "sink_mode"}
    assert only(report, "unreachable_mode").modes == ("orphan",)
    assert only(report, "unreachable_transition").transitions == ("lost",)
    assert only(report, "sink_mode").modes == ("goal",)
    assert all(f.severity == "warning" and f.witness is None for f in report.findings)
    assert not report.clean and report.warnings == report.findings and report.errors == ()
    for name in ("nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers"):
        assert report.searched.checks[name].startswith("skipped: no box given")
    assert all(m.box is None and m.samples == 0 for m in report.searched.modes)


def test_cycle_enumeration_is_capped_and_says_so():
    names = [f"q{i}" for i in range(5)]
    transitions = tuple(
        Transition(name=f"{a}_{b}", source=a, target=b, guard=lambda v, m: -1.0)
        for a in names for b in names if a != b
    )
    model = one_state("complete", tuple(Mode(name=n) for n in names), transitions)
    capped = check(model, max_cycles=3)
    (group,) = capped.of_kind("zeno_candidate")  # grouped: never one row per cycle
    assert group.message.startswith("3+ cycles of the mode graph not decided")
    assert capped.searched.cycles_capped and "capped at max_cycles = 3" in capped.searched.checks["zeno_candidate"]
    full = check(model)
    # Simple cycles of the complete digraph on 5 nodes: sum over k of C(5, k) (k - 1)! = 10 + 20 + 30 + 24 = 84.
    (group,) = full.of_kind("zeno_candidate")
    assert group.message.startswith("84 cycles of the mode graph") and "and 81 more" in group.message
    assert full.searched.cycles_found == 84 and not full.searched.cycles_capped


def test_box_mapping_searches_only_the_given_modes():
    model = thermostat(heat_guard=lambda v, m: 17.5 - v[0])  # deadlock in 'off'
    report = check(model, {"on": THERMO_BOX}, samples=SAMPLES)
    assert "deadlock" not in report.kinds()
    assert report.searched.mode("off").box is None
    assert "no entry for this mode" in report.searched.mode("off").notes[0]
    assert "['off'] not searched" in report.searched.checks["deadlock"]
    assert "deadlock" in check(model, {"off": THERMO_BOX}, samples=SAMPLES).kinds()


# ---------------------------------------------------------------------- report
def test_as_dict_is_deterministic_and_json_ready():
    model = thermostat(heat_jump=lambda x, m: (x[0] + 5.0,))
    first = check(model, THERMO_BOX, samples=SAMPLES, seed=7).as_dict()
    again = check(model, THERMO_BOX, samples=SAMPLES, seed=7).as_dict()
    assert first == again
    assert json.loads(json.dumps(first, allow_nan=False)) == first
    other = check(model, THERMO_BOX, samples=SAMPLES, seed=8).as_dict()
    # The witness is a random sample: another seed picks another one, so the equality above is not vacuous.
    assert first["findings"] != other["findings"]
    assert first["searched"]["seed"] == 7 and first["counts"] == {"error": 1, "warning": 0, "info": 1}
    assert first["searched"]["modes"][0]["box"] == "T ∈ [10, 30]"


def test_report_accessors():
    report = check(forked(priority_b=1), X_BOX, samples=SAMPLES)
    assert isinstance(report, CheckReport) and report.automaton == "forked" and report.model == "automaton"
    assert report.kinds("info") == {"priority_overlap", "zeno_candidate"}
    assert report.kinds("error", "warning") == frozenset()
    assert report.infos == report.findings
    with pytest.raises(ValueError, match="unknown severity"):
        report.kinds("fatal")
    assert set(KIND_SEVERITY.values()) == {"error", "warning", "info"}
    with pytest.raises(ValueError, match="Finding.kind = 'bogus'"):
        Finding(kind="bogus", severity="error", message="")
    w = Witness(state={"x": 1}, memory={}, signals={"x": 1}, values={"g": -0.0})
    with pytest.raises(TypeError):
        w.state["x"] = 2.0  # read-only


# ---------------------------------------------------------------------- errors
def test_box_missing_a_coordinate_is_refused():
    with pytest.raises(ModelDefinitionError, match=r"mode 'fall' of system 'ball'.*missing coordinate\(s\) \['v'\]"):
        check(ball(), Box(bounds={"h": (0.0, 1.0)}))
    with pytest.raises(ModelDefinitionError, match=r"box given for unknown mode\(s\) \['flying'\]"):
        check(ball(), {"flying": BALL_BOX})
    with pytest.raises(ModelDefinitionError, match=r"memory \['dL'\] is not declared by the automaton"):
        check(ball(), Box(bounds={"h": (0.0, 1.0), "v": (0.0, 1.0)}, memory={"dL": (0.0, 1.0)}))
    with pytest.raises(ModelDefinitionError, match="expected a HybridSystem or a HybridAutomaton"):
        check("ball")
    with pytest.raises(ExecutionError, match=r"samples = 0; expected an int >= 1"):
        check(ball(), BALL_BOX, samples=0)


def test_guard_that_raises_names_the_transition_and_the_state():
    def fragile(v, m):
        if v[0] > 2.0:
            raise ValueError("sensor saturated")
        return v[0] - 1.0

    with pytest.raises(ExecutionError, match=r"guard of transition 'to_a' raised ValueError: sensor saturated "
                                             r"at v = \(x=2\.\d+") as info:
        check(forked(guard_a=fragile), X_BOX, samples=SAMPLES)
    assert isinstance(info.value.__cause__, ValueError)


def test_nan_invariant_and_flow_are_execution_errors():
    model = thermostat()
    nan_flow = HybridSystem(automaton=model.automaton, state_names=("T",),
                            flows={"off": lambda t, x, m: (math.nan,), "on": model.flows["on"]})
    with pytest.raises(ExecutionError, match=r"flow of mode 'off' raised ExecutionError.*NaN.* at x = \(T=") as info:
        check(nan_flow, THERMO_BOX, samples=SAMPLES)
    assert isinstance(info.value.__cause__, ExecutionError)
    bad = one_state("nan", (Mode(name="a", invariant=lambda v, m: math.nan),), ())
    with pytest.raises(ExecutionError, match=r"invariant of mode 'a' returned NaN at v = \(x="):
        check(bad, X_BOX, samples=SAMPLES)


# ---------------------------------------------------------------------- reference models
def test_reference_models_report_exactly_their_planted_defects():
    from hybrid.examples import reference_models

    for name, model in reference_models().items():
        report = check(model.system, model.box)
        assert report.kinds("error", "warning") == set(model.planted), (name, [f.message for f in report.findings])
        for finding in report.findings:
            if finding.witness is None:
                continue
            x, v, m = state_of(model.system, finding.witness)
            for key, value in finding.witness.values.items():
                if key.startswith("guard ") and " after " not in key:
                    assert transition(model.system, key[len("guard "):]).guard(v, m) == value, (name, key)
                elif key.startswith("invariant ") and " after " not in key:
                    assert invariant(model.system, key[len("invariant "):], v, m) == value, (name, key)


def test_capped_cycle_enumeration_is_the_same_in_every_process():
    """A complete graph on 6 modes has hundreds of cycles; with max_cycles = 15 the ones reported must not
    depend on PYTHONHASHSEED (networkx walks sets of nodes: string hashing once made them vary)."""
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent("""
        import json
        from hybrid import check
        from hybrid.model import HybridAutomaton, Mode, Transition
        names = [f"m{i}" for i in range(6)]
        transitions = tuple(Transition(name=f"{a}->{b}", source=a, target=b, guard=lambda v, m: v[0])
                            for a in names for b in names if a != b)
        automaton = HybridAutomaton(name="complete", modes=tuple(Mode(name=n) for n in names),
                                    transitions=transitions, variables=("x",))
        report = check(automaton, None, max_cycles=15)
        print(json.dumps([f.message for f in report.findings if f.kind == "zeno_candidate"]))
    """)
    outputs = set()
    for seed in ("1", "2", "3"):
        env = {**__import__("os").environ, "PYTHONHASHSEED": seed}
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
        outputs.add(out.stdout)
    assert len(outputs) == 1
    (message,) = json.loads(outputs.pop())
    assert message.startswith("15+ cycles of the mode graph")


def test_a_flow_that_raises_is_named_once_with_the_original_exception():
    model = thermostat()
    broken = HybridSystem(automaton=model.automaton, state_names=("T",),
                          flows={"off": lambda t, x, m: (1.0 / 0.0,), "on": model.flows["on"]})
    with pytest.raises(ExecutionError, match=r"flow of mode 'off' raised ZeroDivisionError: float division by zero "
                                             r"at x = \(T=") as info:
        check(broken, THERMO_BOX, samples=SAMPLES)
    assert "UserFunctionError" not in str(info.value) and str(info.value).count(" raised ") == 1
