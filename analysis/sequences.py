"""Driving a hybrid automaton with a sequence of signal samples, recording every instant.

Robot-free: any :class:`hybrid.HybridAutomaton` whose ``variables`` are the
signals it reads (a supervisor, a thermostat, a clock automaton).  A
:class:`SequenceRunner` feeds it one sample (one tuple of floats, one per
variable) at a time.  What fires at a sample is decided by the toolkit's
single instant rule, :func:`hybrid.instant.settle_instant` (the signal row is
the state; crossing-triggered guards compare with the previous sample, on the
first jump of the instant only), called with ``ties="record"``: instead of
raising on non-determinism or on instantaneous Zeno behaviour the runner
*records* them (:attr:`SequenceJump.tied`, :attr:`SequenceStep.zeno`), so that
a property can report them with the run that caused them and the run goes on.

:func:`run_sequence` runs a whole sequence through a fresh runner.  Nothing
here prints or writes files.

Examples
--------
>>> from hybrid.model import HybridAutomaton, Mode, Transition
>>> heat = Transition(name="heat", source="off", target="on", guard=lambda v, m: 19.0 - v[0])
>>> cool = Transition(name="cool", source="on", target="off", guard=lambda v, m: v[0] - 21.0)
>>> thermostat = HybridAutomaton(name="thermostat", modes=(Mode(name="off"), Mode(name="on")),
...                              transitions=(heat, cool), variables=("T",), initial_mode="off")
>>> [(s.mode, [j.transition for j in s.jumps]) for s in run_sequence(thermostat, [(20.0,), (18.5,), (20.0,)])]
[('off', []), ('on', ['heat']), ('on', [])]
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

from hybrid import HybridAutomaton, Transition
from hybrid.instant import MAX_JUMPS_PER_INSTANT, Instant, InstantJump, apply_reset, settle_instant

__all__ = [
    "MAX_JUMPS_PER_INSTANT",
    "SequenceJump",
    "SequenceStep",
    "SequenceRunner",
    "run_sequence",
    "sequence_jumps",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class SequenceJump:
    """One discrete jump at a sample.

    Attributes
    ----------
    transition, source, target : str
        Names of the transition that fired and of the modes before and after.
    memory_before, memory_after : Mapping[str, float]
        Read-only memory before and after the reset.
    enabled : tuple of str
        Transitions enabled at the jump, priority order, winner first.
    tied : tuple of str
        Enabled transitions with the winner's priority (non-determinism; the
        first declared fired).
    guard_value : float
        The winner's guard value.
    """

    transition: str
    source: str
    target: str
    memory_before: Mapping[str, float]
    memory_after: Mapping[str, float]
    enabled: tuple[str, ...]
    tied: tuple[str, ...]
    guard_value: float


@dataclass(frozen=True, kw_only=True, slots=True)
class SequenceStep:
    """The automaton at one sample.

    Attributes
    ----------
    index : int
        Position of the sample in the sequence (from 0).
    signals : tuple of float
        The sample.
    mode_before, memory_before :
        Discrete state before the sample's jumps.
    mode, memory :
        Discrete state after them.
    jumps : tuple of SequenceJump
    zeno : str or None
        The kernel's message when ``max_jumps`` jumps happened and a
        transition was still enabled (settling stopped there), else ``None``.
    """

    index: int
    signals: tuple[float, ...]
    mode_before: str
    memory_before: Mapping[str, float]
    mode: str
    memory: Mapping[str, float]
    jumps: tuple[SequenceJump, ...]
    zeno: str | None


def _jump(j: InstantJump) -> SequenceJump:
    return SequenceJump(
        transition=j.transition.name, source=j.source, target=j.target, memory_before=j.memory_before,
        memory_after=j.memory_after, enabled=j.enabled, tied=j.tied, guard_value=j.guard_value,
    )


def sequence_jumps(instant: Instant) -> tuple[SequenceJump, ...]:
    """The jumps of a kernel :class:`~hybrid.instant.Instant` as :class:`SequenceJump` records."""
    if not instant.jumps:
        return ()
    return tuple(_jump(j) for j in instant.jumps)


def _jump_function(maps: dict[str, Callable[[Sequence[float], Mapping[str, float]], Sequence[float]]]):
    """The kernel's ``fire`` for signal rows reset by ``maps`` (and the memory by the transition's reset)."""

    def fire(t: Transition, v: tuple[float, ...], signals: Sequence[float], memory: Mapping[str, float]):
        row, new_memory = apply_reset(t, v, signals, memory)
        jump = maps.get(t.name)
        return (tuple(float(c) for c in jump(v, memory)) if jump is not None else row), new_memory

    return fire


class SequenceRunner:
    """Feeds signal samples to an automaton one at a time (the state belongs to one run).

    Parameters
    ----------
    automaton : HybridAutomaton
        Its ``variables`` name the columns of a sample.
    max_jumps : int
        Jumps allowed at one sample before :attr:`SequenceStep.zeno` is set
        (:data:`MAX_JUMPS_PER_INSTANT`, the executors' limit, by default).
    initial_mode, initial_memory :
        Discrete state before the first sample (the automaton's own by default).
    jump_maps : Mapping[str, callable] or None
        ``r(v, m) -> v⁺`` per transition name, for an automaton whose samples
        are the state of a system with jump maps (a clock reset ``τ := 0``):
        the jump's successors are evaluated on ``v⁺``, as the executors do.
        Without it, samples are only read, never reset.

    Attributes
    ----------
    mode, memory : str, Mapping[str, float]
        Discrete state after the samples fed so far.
    previous : tuple of float or None
        The last sample (what crossing-triggered guards compare with).
    index : int
        Index of the next sample.
    """

    def __init__(
        self,
        automaton: HybridAutomaton,
        *,
        max_jumps: int = MAX_JUMPS_PER_INSTANT,
        initial_mode: str | None = None,
        initial_memory: Mapping[str, float] | None = None,
        jump_maps: Mapping[str, Callable[[Sequence[float], Mapping[str, float]], Sequence[float]]] | None = None,
    ) -> None:
        self.automaton = automaton
        self._fire = _jump_function(dict(jump_maps)) if jump_maps else apply_reset
        self.max_jumps = max_jumps
        self._outgoing = {name: automaton.outgoing(name) for name in automaton.mode_names}
        self._width = len(automaton.variables)
        self.mode = automaton.initial_mode if initial_mode is None else initial_mode
        automaton.mode(self.mode)
        memory = automaton.initial_memory() if initial_memory is None else dict(initial_memory)
        self.memory: Mapping[str, float] = MappingProxyType(memory)
        self.previous: tuple[float, ...] | None = None
        self.index = 0

    def advance(self, v: Sequence[float]) -> Instant:
        """Settle the instant of sample ``v``, update the runner's state and return the kernel's result.

        Raises
        ------
        ValueError
            ``v`` does not have one value per variable of the automaton.
        hybrid.ExecutionError
            A NaN guard, or a reset that does not write exactly its declared memory.
        """
        if len(v) != self._width:
            raise ValueError(
                f"automaton {self.automaton.name!r}: sample {self.index} has {len(v)} values, expected "
                f"{self._width} ({', '.join(self.automaton.variables)})"
            )
        signals = v if type(v) is tuple else tuple(v)
        instant = settle_instant(self._outgoing, self.mode, signals, self.memory, previous=self.previous,
                                 fire=self._fire, ties="record", max_jumps=self.max_jumps)
        self.mode, self.memory, self.previous = instant.mode, instant.memory, signals
        self.index += 1
        return instant

    def step(self, v: Sequence[float]) -> SequenceStep:
        """Evaluate one sample; return what happened (see :meth:`advance` for the errors)."""
        index, mode_before, memory_before = self.index, self.mode, self.memory
        instant = self.advance(v)
        return SequenceStep(
            index=index, signals=self.previous, mode_before=mode_before, memory_before=memory_before,
            mode=instant.mode, memory=instant.memory, jumps=sequence_jumps(instant), zeno=instant.zeno,
        )


def run_sequence(
    automaton: HybridAutomaton, samples: Iterable[Sequence[float]], *, max_jumps: int = MAX_JUMPS_PER_INSTANT
) -> tuple[SequenceStep, ...]:
    """Every sample of a sequence through a fresh :class:`SequenceRunner`."""
    runner = SequenceRunner(automaton, max_jumps=max_jumps)
    return tuple(runner.step(v) for v in samples)
