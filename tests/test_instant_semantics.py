"""Every user of the instant kernel agrees on one table of cases.

What happens at one instant (which transitions are enabled, priorities, ties,
jump maps and resets, crossing guards, the jump limit) is decided by
:func:`hybrid.instant.settle_instant` alone.  Its users are the sampled-data
executor (:func:`hybrid.settle`, :func:`hybrid.simulate_sampled`), the
continuous executor (:func:`hybrid.simulate_continuous`, at the initial
instant and at located events), the structural checks (:func:`hybrid.check`,
the chain of jumps a reset triggers) and the fuzzing sequence runner
(:class:`analysis.sequences.SequenceRunner`).  Each case below is driven
through every user that can express it, and the answers are compared.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest

from hybrid import (
    Box,
    ExecutionError,
    HybridAutomaton,
    HybridSystem,
    Mode,
    Plant,
    Transition,
    ZenoError,
    check,
    settle,
    simulate_continuous,
    simulate_sampled,
)
from hybrid.instant import MAX_JUMPS_PER_INSTANT, settle_instant


@dataclass(frozen=True)
class Case:
    """An automaton on one state ``x`` (its own signal), a flow ``ẋ = rate`` and jump maps."""

    name: str
    modes: tuple[str, ...]
    transitions: tuple[Transition, ...]
    x0: float
    rate: float = 1.0
    jumps: dict = field(default_factory=dict)
    previous: float | None = None
    # expected outcome of the instant at x0 (given `previous`)
    fired: tuple[str, ...] = ()
    mode: str = ""
    x_after: float | None = None
    zeno: bool = False
    tie: bool = False

    def automaton(self) -> HybridAutomaton:
        return HybridAutomaton(name=self.name, modes=tuple(Mode(name=m) for m in self.modes),
                               transitions=self.transitions, variables=("x",))

    def system(self) -> HybridSystem:
        return HybridSystem(automaton=self.automaton(), state_names=("x",),
                            flows={m: (lambda t, x, mem: (self.rate,)) for m in self.modes}, jumps=self.jumps)

    def fire(self):
        """The kernel's ``fire`` with this case's jump maps (what the continuous executor applies)."""
        def fire(t, x, v, memory):
            jump = self.jumps.get(t.name)
            return (tuple(jump(x, memory)) if jump else x), dict(memory)
        return fire


def level(name, source, target, guard, priority=0):
    return Transition(name=name, source=source, target=target, guard=guard, priority=priority)


CASES = (
    Case(name="clock_reset", modes=("off", "on"), x0=1.0,
         transitions=(level("start", "off", "on", lambda v, m: v[0] - 1.0),
                      level("stop", "on", "off", lambda v, m: v[0] - 0.4)),
         jumps={"start": lambda x, m: (0.0,)}, fired=("start",), mode="on", x_after=0.0),
    Case(name="crossing_starts_on_zero", modes=("a", "b"), x0=0.0, previous=0.0,
         transitions=(Transition(name="up", source="a", target="b", guard=lambda v, m: v[0], direction=+1),),
         fired=(), mode="a", x_after=0.0),
    Case(name="tie", modes=("a", "b", "c"), x0=0.0,
         transitions=(level("left", "a", "b", lambda v, m: 1.0), level("right", "a", "c", lambda v, m: 1.0)),
         tie=True, fired=("left",), mode="b", x_after=0.0),
    Case(name="instantaneous_cycle", modes=("a", "b"), x0=0.0,
         transitions=(level("ab", "a", "b", lambda v, m: 1.0), level("ba", "b", "a", lambda v, m: 1.0)),
         zeno=True, fired=("ab", "ba") * (MAX_JUMPS_PER_INSTANT // 2), mode="a", x_after=0.0),
    Case(name="priority_and_chain", modes=("a", "b", "c"), x0=2.0,
         transitions=(level("low", "a", "c", lambda v, m: v[0], priority=2),
                      level("high", "a", "b", lambda v, m: v[0] - 1.0, priority=1),
                      level("next", "b", "c", lambda v, m: v[0] - 1.5)),
         fired=("high", "next"), mode="c", x_after=2.0),
    Case(name="crossing_only_on_first_jump", modes=("a", "b", "c"), x0=1.0, previous=-1.0,
         transitions=(level("enter", "a", "b", lambda v, m: v[0]),
                      Transition(name="cross", source="b", target="c", guard=lambda v, m: v[0], direction=+1)),
         fired=("enter",), mode="b", x_after=1.0),
)
IDS = [c.name for c in CASES]


def kernel(case: Case, ties: str):
    a = case.automaton()
    outgoing = {m: a.outgoing(m) for m in a.mode_names}
    previous = None if case.previous is None else (case.previous,)
    return settle_instant(outgoing, a.initial_mode, (case.x0,), a.initial_memory(), previous=previous,
                          fire=case.fire(), ties=ties)


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_the_kernel_gives_the_expected_instant(case):
    if case.tie:
        with pytest.raises(ExecutionError, match="non-determinism"):
            kernel(case, "raise")
    instant = kernel(case, "record")
    assert tuple(j.transition.name for j in instant.jumps) == case.fired
    assert instant.mode == case.mode and instant.state == (case.x_after,)
    assert (instant.zeno is not None) == case.zeno
    assert bool(instant.jumps and instant.jumps[0].tied) == case.tie


@pytest.mark.parametrize("case", [c for c in CASES if not c.jumps], ids=[c.name for c in CASES if not c.jumps])
def test_sampled_settle_agrees(case):
    """``hybrid.settle`` (one sample of the sampled executor; no jump maps there): ties raise, Zeno raises."""
    a = case.automaton()
    previous = None if case.previous is None else (case.previous,)
    if case.tie:
        with pytest.raises(ExecutionError, match="non-determinism"):
            settle(a, a.initial_mode, {}, (case.x0,), previous)
        return
    if case.zeno:
        with pytest.raises(ZenoError, match="instantaneous Zeno"):
            settle(a, a.initial_mode, {}, (case.x0,), previous)
        return
    mode, _, events = settle(a, a.initial_mode, {}, (case.x0,), previous)
    assert tuple(e.transition for e in events) == case.fired and mode == case.mode


class _Hold:
    """A sampled controller that measures the plant state and holds the rate."""

    record_names = ()

    def __init__(self, rate):
        self.rate = rate

    def initial_state(self, t, x):
        return None

    def measure(self, t, x, c):
        return tuple(x), c

    def control(self, t, x, c, v, mode, memory):
        return (self.rate,), c, ()


@pytest.mark.parametrize("case", [c for c in CASES if not c.jumps and c.previous is None],
                         ids=[c.name for c in CASES if not c.jumps and c.previous is None])
def test_sampled_executor_agrees_at_its_first_sample(case):
    plant = Plant(state_names=("x",), input_names=("u",), derivative=lambda x, u: (u[0],),
                  exact_flow=lambda x, u, dt: (x[0] + u[0] * dt,))
    run = lambda: simulate_sampled(case.automaton(), plant, _Hold(case.rate), (case.x0,), period=0.1, duration=0.1)
    if case.tie:
        with pytest.raises(ExecutionError, match="non-determinism"):
            run()
        return
    if case.zeno:
        with pytest.raises(ZenoError):
            run()
        return
    trace = run()
    first = tuple(e.transition for e in trace.events if e.sample == 0)
    assert first == case.fired and trace.mode_names[int(trace.modes[0])] == case.mode


@pytest.mark.parametrize("case", [c for c in CASES if c.previous is None], ids=[c.name for c in CASES if c.previous is None])
def test_continuous_executor_agrees_at_the_initial_instant(case):
    system = case.system()
    if case.tie:
        with pytest.raises(ExecutionError, match="non-determinism"):
            simulate_continuous(system, (case.x0,), duration=1e-3)
        return
    run = simulate_continuous(system, (case.x0,), duration=1e-3)
    at_start = [e for e in run.events if e.time == 0.0]
    assert tuple(e.transition for e in at_start) == case.fired
    if case.zeno:
        assert run.termination == "zeno" and run.zeno is not None and run.zeno.kind == "instantaneous"
    else:
        assert run.segments[0].mode == case.mode
        assert at_start[-1].state_after == (case.x_after,) if at_start else True


def test_continuous_executor_fires_a_crossing_guard_that_starts_on_zero():
    """The crossing leaves zero in its direction at once: it fires right after t0 (no deadlock)."""
    case = next(c for c in CASES if c.name == "crossing_starts_on_zero")
    a = HybridAutomaton(name="start_on_zero", modes=(Mode(name="a", invariant=lambda v, m: -v[0]), Mode(name="b")),
                        transitions=case.transitions, variables=("x",))
    system = HybridSystem(automaton=a, state_names=("x",), flows={"a": lambda t, x, m: (1.0,), "b": lambda t, x, m: (1.0,)})
    run = simulate_continuous(system, (0.0,), duration=1.0)
    assert run.termination == "end_time", run.detail
    assert [e.transition for e in run.events] == ["up"] and 0.0 < run.events[0].time <= 1e-11
    # the structural checks agree that this mode does not deadlock
    report = check(system, Box(bounds={"x": (-1.0, 1.0)}), samples=200)
    assert "deadlock" not in report.kinds()


def test_continuous_executor_locates_a_clock_reset_and_does_not_call_it_zeno():
    case = next(c for c in CASES if c.name == "clock_reset")
    run = simulate_continuous(case.system(), (0.5,), duration=3.0, initial_mode="off")
    names = [e.transition for e in run.events]
    assert run.termination == "end_time" and names[:3] == ["start", "stop", "start"]
    start = [e for e in run.events if e.transition == "start"]
    assert all(e.state_after == (0.0,) for e in start)


@pytest.mark.parametrize("case", [c for c in CASES if c.name in ("instantaneous_cycle", "clock_reset")],
                         ids=[c.name for c in CASES if c.name in ("instantaneous_cycle", "clock_reset")])
def test_structural_checks_follow_the_same_instant(case):
    """``check`` runs the kernel after a reset: a cycle re-triggers, a clock reset does not."""
    report = check(case.system(), Box(bounds={"x": (0.0, 2.0)}), samples=100)
    retriggers = report.of_kind("reset_retriggers")
    if case.zeno:
        assert retriggers and retriggers[0].transitions[0] == retriggers[0].transitions[-1]
    else:
        assert not retriggers


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_the_fuzzing_sequence_runner_agrees(case):
    """``analysis.sequences`` (what the fuzz runs use): ties and Zeno are recorded, jump maps applied."""
    from analysis.sequences import SequenceRunner

    runner = SequenceRunner(case.automaton(), jump_maps=case.jumps)
    if case.previous is not None:
        runner.previous = (case.previous,)
    step = runner.step((case.x0,))
    assert tuple(j.transition for j in step.jumps) == case.fired and step.mode == case.mode
    assert (step.zeno is not None) == case.zeno
    assert bool(step.jumps and step.jumps[0].tied) == case.tie


def test_without_the_jump_map_a_clock_reset_looks_like_zeno():
    """Why the runner takes the jump maps: the clock reset ``τ := 0`` is what ends the instant."""
    from analysis.sequences import SequenceRunner

    case = next(c for c in CASES if c.name == "clock_reset")
    step = SequenceRunner(case.automaton()).step((case.x0,))
    assert step.zeno is not None
