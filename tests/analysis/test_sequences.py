"""analysis.sequences: a generic automaton fed sample by sample (robot-free: a thermostat, a PWM clock)."""

import math
import subprocess
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.sequences import MAX_JUMPS_PER_INSTANT, SequenceRunner, run_sequence
from hybrid import ExecutionError, HybridAutomaton, MemoryVariable, Mode, Transition, settle


def thermostat(low=19.0, high=21.0, *, tie=False):
    """Heater with hysteresis [low, high]; memory counts the switches; ``tie`` adds an equal-priority twin."""
    count = lambda v, m: {"switches": m["switches"] + 1.0}  # noqa: E731
    transitions = [
        Transition(name="heat", source="off", target="on", guard=lambda v, m: low - v[0], reset=count,
                   writes=("switches",), priority=0),
        Transition(name="cool", source="on", target="off", guard=lambda v, m: v[0] - high, reset=count,
                   writes=("switches",), priority=0),
    ]
    if tie:
        transitions.append(Transition(name="boost", source="off", target="on", guard=lambda v, m: low - 1.0 - v[0],
                                      priority=0))
    return HybridAutomaton(name="thermostat", modes=(Mode(name="off"), Mode(name="on")),
                           transitions=tuple(transitions), variables=("T",), initial_mode="off",
                           memory=(MemoryVariable(name="switches", initial=0.0),))


def pwm():
    """A PWM output: a sawtooth carrier c against a duty d, high from the period start (c drops below d)
    until c rises through d; both edges are rising crossings of a guard."""
    rise = Transition(name="rise", source="low", target="high", guard=lambda v, m: v[1] - v[0], direction=+1)
    fall = Transition(name="fall", source="high", target="low", guard=lambda v, m: v[0] - v[1], direction=+1)
    return HybridAutomaton(name="pwm", modes=(Mode(name="low"), Mode(name="high")), transitions=(rise, fall),
                           variables=("carrier", "duty"), initial_mode="low")


def cascade():
    """a -> b -> c, both on the rising crossing of the same signal through 0."""
    up = lambda v, m: v[0]  # noqa: E731
    return HybridAutomaton(name="cascade", modes=(Mode(name="a"), Mode(name="b"), Mode(name="c")),
                           transitions=(Transition(name="a->b", source="a", target="b", guard=up, direction=+1),
                                        Transition(name="b->c", source="b", target="c", guard=up, direction=+1)),
                           variables=("x",), initial_mode="a")


def names(step):
    return [j.transition for j in step.jumps]


def test_the_thermostat_switches_with_hysteresis_and_records_the_memory():
    steps = run_sequence(thermostat(), [(20.0,), (19.0,), (20.5,), (21.0,), (20.0,)])
    assert [s.mode for s in steps] == ["off", "on", "on", "off", "off"]
    assert [names(s) for s in steps] == [[], ["heat"], [], ["cool"], []]
    heat = steps[1].jumps[0]
    assert (heat.source, heat.target, heat.enabled, heat.tied) == ("off", "on", ("heat",), ())
    assert (dict(heat.memory_before), dict(heat.memory_after), heat.guard_value) == ({"switches": 0.0},
                                                                                     {"switches": 1.0}, 0.0)
    assert dict(steps[-1].memory) == {"switches": 2.0} and steps[3].mode_before == "on"
    assert [s.index for s in steps] == [0, 1, 2, 3, 4] and steps[2].signals == (20.5,)
    assert all(s.zeno is None for s in steps)


def test_a_tie_is_recorded_and_the_first_declared_fires():
    (step,) = run_sequence(thermostat(tie=True), [(17.0,)])
    (jump,) = step.jumps
    assert (jump.transition, jump.enabled, jump.tied) == ("heat", ("heat", "boost"), ("boost",))


def test_instantaneous_zeno_is_recorded_and_the_run_goes_on():
    steps = run_sequence(thermostat(low=20.0, high=20.0), [(20.0,), (25.0,)])
    assert len(steps[0].jumps) == MAX_JUMPS_PER_INSTANT == 8
    assert steps[0].zeno is not None and "instantaneous Zeno" in steps[0].zeno and "heat -> cool" in steps[0].zeno
    assert steps[0].mode == "off" and dict(steps[0].memory) == {"switches": 8.0}
    assert names(steps[1]) == [] and steps[1].zeno is None  # the next sample starts from where settling stopped
    assert len(run_sequence(thermostat(low=20.0, high=20.0), [(20.0,)], max_jumps=3)[0].jumps) == 3


def test_crossing_guards_compare_with_the_previous_sample_on_the_first_jump_only():
    carrier = [0.0, 0.25, 0.5, 0.75, 0.0, 0.25, 0.5, 0.75]
    steps = run_sequence(pwm(), [(c, 0.5) for c in carrier])
    # no previous sample at k = 0; rise when the carrier drops below the duty (0.75 -> 0.0), fall when it
    # reaches the duty from below (0.25 -> 0.5: g0 = -0.25 <= 0 <= g1 = 0 and g0 < g1)
    assert [names(s) for s in steps] == [[], [], [], [], ["rise"], [], ["fall"], []]
    # one crossing is one jump: the crossing happened while flowing in the mode of the period that just ended,
    # so the successor's crossing guard (reading the same signal) does not fire at the same instant
    steps = run_sequence(cascade(), [(-1.0,), (1.0,), (2.0,), (-1.0,), (0.0,)])
    assert [names(s) for s in steps] == [[], ["a->b"], [], [], ["b->c"]]  # -1 -> 0 reaches zero from below


@given(st.lists(st.floats(10.0, 30.0), max_size=60))
@settings(max_examples=60, derandomize=True, database=None, deadline=None)
def test_the_runner_agrees_with_the_sampled_executor(temperatures):
    automaton = thermostat()
    mode, memory, previous = automaton.initial_mode, automaton.initial_memory(), None
    for step, t in zip(run_sequence(automaton, [(t,) for t in temperatures]), temperatures):
        mode, memory, events = settle(automaton, mode, memory, (t,), previous)
        assert (step.mode, dict(step.memory), names(step)) == (mode, memory, [e.transition for e in events])
        previous = (t,)


def test_the_runner_owns_its_state_and_checks_the_width():
    runner = SequenceRunner(thermostat(), initial_mode="on", initial_memory={"switches": 5.0})
    step = runner.step((22.0,))
    assert names(step) == ["cool"] and (runner.mode, runner.index, runner.previous) == ("off", 1, (22.0,))
    assert dict(runner.memory) == {"switches": 6.0}
    with pytest.raises(TypeError):
        runner.memory["switches"] = 0.0  # read-only
    with pytest.raises(ValueError, match=r"automaton 'thermostat': sample 1 has 2 values, expected 1 \(T\)"):
        runner.step((1.0, 2.0))
    with pytest.raises(ExecutionError, match="is NaN"):
        runner.step((math.nan,))


def test_analysis_sequences_does_not_import_visnav():
    code = ("import sys, analysis.sequences, analysis.counterexamples; "
            "sys.exit(1 if any(m.startswith('visnav') for m in sys.modules) else 0)")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0
