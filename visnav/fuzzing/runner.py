"""Driving a supervisor variant sample by sample: the measurement stage in front of the generic runner.

:class:`SupervisorRunner` turns each measurement row of a
:class:`~visnav.fuzzing.space.MeasurementSpace` into the supervisor's signals
(nearest obstacle, ϑ wrapped unless the variant reads it raw), feeds them to
:class:`analysis.sequences.SequenceRunner` — which settles every sample with
:func:`hybrid.instant.settle_instant`, recording ties and instantaneous Zeno
instead of raising — and evaluates the risk outputs µ_coll, µ_occ after the
sample's jumps.  What fires at a sample is decided there, not here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from analysis.sequences import SequenceJump, SequenceRunner, sequence_jumps
from hybrid.instant import MAX_JUMPS_PER_INSTANT

from visnav.fuzzing.mutants import SupervisorVariant
from visnav.fuzzing.space import MeasurementSpace
from visnav.geometry import wrap_angle

__all__ = ["MAX_JUMPS_PER_SAMPLE", "Jump", "Step", "SupervisorRunner", "run_supervisor"]

MAX_JUMPS_PER_SAMPLE = MAX_JUMPS_PER_INSTANT
"""Jumps allowed at one sample before the run counts as instantaneous Zeno (the executors' limit, 8)."""

Jump = SequenceJump
"""One discrete jump at a sample (:class:`analysis.sequences.SequenceJump`: transition, source and
target names, memory before and after the reset, the enabled transitions winner first, ties)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class Step:
    """The supervisor at one sample.

    Attributes
    ----------
    index : int
    measurement : tuple of float
        The row of :class:`MeasurementSpace`.
    signals : tuple of float
        What the guards read (the variant's measurement stage).
    mode_before, memory_before :
        Discrete state before the sample's jumps.
    mode, memory :
        Discrete state after them.
    jumps : tuple of Jump
    mu_coll, mu_occ : float
        Risk outputs after the jumps.
    zeno : bool
        :data:`MAX_JUMPS_PER_SAMPLE` jumps happened and a transition was still
        enabled (settling stopped).
    """

    index: int
    measurement: tuple[float, ...]
    signals: tuple[float, ...]
    mode_before: str
    memory_before: Mapping[str, float]
    mode: str
    memory: Mapping[str, float]
    jumps: tuple[Jump, ...]
    mu_coll: float
    mu_occ: float
    zeno: bool


class SupervisorRunner:
    """Feeds measurement rows to a variant one sample at a time (state owned by one run).

    The instant semantics are those of every executor of the toolkit
    (:func:`hybrid.instant.settle_instant`, through
    :class:`analysis.sequences.SequenceRunner`): the enabled transition with
    the smallest priority fires, level-triggered successors fire at the same
    instant, crossing-triggered guards compare with the previous sample's
    signals on the first jump of the sample.  Non-determinism and Zeno
    behaviour are recorded (:attr:`Jump.tied`, :attr:`Step.zeno`), so that the
    properties can report them with the run that caused them.
    """

    def __init__(self, variant: SupervisorVariant, space: MeasurementSpace) -> None:
        automaton = variant.model.automaton
        if len(automaton.variables) != 6 + space.n_obstacles:
            raise ValueError(
                f"variant {variant.name!r} reads {len(automaton.variables) - 6} obstacle distance(s), the "
                f"measurement space has {space.n_obstacles}; build both for the same number of obstacles"
            )
        self.variant = variant
        self.space = space
        self.sequence = SequenceRunner(automaton, max_jumps=MAX_JUMPS_PER_SAMPLE)
        self._risk = variant.model.risk
        self._wrap = variant.wrap_pan
        self._n = space.n_obstacles

    @property
    def mode(self) -> str:
        """Mode after the samples fed so far."""
        return self.sequence.mode

    @property
    def memory(self) -> Mapping[str, float]:
        """Memory after the samples fed so far (read-only)."""
        return self.sequence.memory

    @property
    def previous(self) -> tuple[float, ...] | None:
        """Signals of the last sample (what crossing-triggered guards compare with)."""
        return self.sequence.previous

    @property
    def index(self) -> int:
        """Index of the next sample."""
        return self.sequence.index

    def signals(self, row: Sequence[float]) -> tuple[float, ...]:
        """The variant's measurement stage: the supervisor's signals of one measurement row."""
        n = self._n
        ds = tuple(map(float, row[:n]))
        nearest = ds.index(min(ds))  # the first of the nearest
        pan = row[n + 3]
        return (ds[nearest], float(nearest), float(row[n]), float(row[n + 1]), float(row[n + 2]),
                wrap_angle(pan) if self._wrap else float(pan), *ds)

    def step(self, row: Sequence[float]) -> Step:
        """Evaluate one sample; return what happened."""
        v = self.signals(row)
        sequence = self.sequence
        index, mode_before, memory_before = sequence.index, sequence.mode, sequence.memory
        instant = sequence.advance(v)
        mode, memory = instant.mode, instant.memory
        mu_coll, mu_occ = self._risk(mode, v, memory)
        return Step(
            index=index, measurement=tuple(row), signals=v, mode_before=mode_before, memory_before=memory_before,
            mode=mode, memory=memory, jumps=sequence_jumps(instant), mu_coll=mu_coll, mu_occ=mu_occ,
            zeno=instant.zeno is not None,
        )


def run_supervisor(
    variant: SupervisorVariant, space: MeasurementSpace, rows: Iterable[Sequence[float]]
) -> tuple[Step, ...]:
    """Every sample of a measurement sequence through a fresh :class:`SupervisorRunner`."""
    runner = SupervisorRunner(variant, space)
    return tuple(runner.step(row) for row in rows)
