"""Property-based fuzzing of switching logic: signal-sequence strategies and a property runner.

Robot-free: a *channel* is a named real signal with a range, a bound on its
change per sample and a few *landmarks* (thresholds worth visiting, such as a
guard's switching value).  The strategies build sequences of samples (one
tuple of floats per sample, one float per channel):

:func:`follow_waypoints`
    The samples of a run given its start and its legs (:class:`Segment`:
    a waypoint and a speed per channel, a duration); the strategies below
    and the domain-specific ones of a case study build on it.
:func:`bounded_rate_sequences`
    Physically plausible runs: every channel moves piecewise linearly towards
    a drawn waypoint (often a landmark, or just beside one) at a drawn
    fraction of its rate bound, so ``|x[k+1] - x[k]| <= max_step`` always
    holds.  Shrinking simplifies the waypoints (towards the first landmark)
    and the speeds (towards holding still), so a shrunk failure reads as a
    short story: "go to 0.3, wait, swing to 0.25 rad, come back".
:func:`unbounded_sequences`
    Adversarial runs: each segment either *jumps* to its waypoint or ramps at
    any rate, and may visit the channel's special values (``inf``, values
    outside the range).
:func:`adversarial_sequences`
    Either of the two.

:func:`run_property` runs a check under hypothesis with an explicit,
deterministic configuration (:func:`fuzz_settings`: fixed ``max_examples``,
``database=None``, derandomised or seeded) and returns a
:class:`PropertyRun` holding the *shrunk* counterexample when the check
fails; :func:`run_machine` does the same for a
:class:`hypothesis.stateful.RuleBasedStateMachine`.  A check signals a
violation by raising :class:`PropertyViolation` (any other exception is a
failure too: "never an exception" is part of every property).

Examples
--------
>>> from hypothesis import strategies as st
>>> ch = (Channel(name="x", low=0.0, high=1.0, max_step=0.1, landmarks=(0.5,)),)
>>> def check(seq, observe):
...     if any(s[0] > 0.7 for s in seq):
...         raise PropertyViolation("below", "x went above 0.7")
...     return len(seq)
>>> run = run_property("below", check, bounded_rate_sequences(ch, max_length=20), max_examples=50)
>>> run.passed, run.failure.message, run.failure.example
(False, 'x went above 0.7', ((1.0,), (1.0,)))
"""

from __future__ import annotations

import contextlib
import functools
import math
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from hypothesis import HealthCheck, Phase, Verbosity, given, seed as hypothesis_seed, settings, target
from hypothesis import strategies as st
from hypothesis.errors import HypothesisException, HypothesisWarning
from hypothesis.stateful import RuleBasedStateMachine, run_state_machine_as_test

__all__ = [
    "project_constants_ignored",
    "Channel",
    "Sample",
    "Segment",
    "follow_waypoints",
    "waypoint_strategy",
    "bounded_rate_sequences",
    "unbounded_sequences",
    "adversarial_sequences",
    "max_rate_ratio",
    "PropertyViolation",
    "Failure",
    "PropertyRun",
    "Observer",
    "fuzz_settings",
    "run_property",
    "run_machine",
    "NEAR_FRACTION",
]

Sample = tuple[float, ...]
"""One sample: one float per channel."""

Observer = Callable[[str, float], None]
"""``observe(label, value)``: a margin to maximise (hypothesis ``target``), or a no-op outside hypothesis."""

NEAR_FRACTION = 0.5
"""Waypoints "beside" a landmark sit at ``landmark ± NEAR_FRACTION * max_step`` (and ``± 1e-9``)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class Channel:
    """A real signal of a sequence.

    Attributes
    ----------
    name : str
        Name (for traces and counterexample files).
    low, high : float
        Range of the plausible values (``low <= high``).
    max_step : float
        Bound on ``|x[k+1] - x[k]|`` in bounded-rate sequences (> 0).
    landmarks : tuple of float
        Values worth visiting exactly and just beside (guard thresholds).
    specials : tuple of float
        Values outside ``[low, high]`` (e.g. ``inf``) visited only by
        adversarial sequences.
    choices : tuple of float
        If not empty, the channel is discrete: it takes only these values and
        may change at any sample (e.g. a side ``±1``); ``low``, ``high`` and
        ``max_step`` are then ignored.

    Raises
    ------
    ValueError
        On an empty or inverted range, a non-positive rate bound or a
        landmark outside the range.
    """

    name: str
    low: float = 0.0
    high: float = 1.0
    max_step: float = 1.0
    landmarks: tuple[float, ...] = ()
    specials: tuple[float, ...] = ()
    choices: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "landmarks", tuple(float(x) for x in self.landmarks))
        object.__setattr__(self, "specials", tuple(float(x) for x in self.specials))
        object.__setattr__(self, "choices", tuple(float(x) for x in self.choices))
        if self.choices:
            return
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low <= self.high):
            raise ValueError(
                f"Channel {self.name!r}: range [{self.low!r}, {self.high!r}]; expected finite low <= high"
            )
        if not (self.max_step > 0 and math.isfinite(self.max_step)):
            raise ValueError(f"Channel {self.name!r}: max_step = {self.max_step!r}; expected a finite value > 0")
        bad = [x for x in self.landmarks if not self.low <= x <= self.high]
        if bad:
            raise ValueError(
                f"Channel {self.name!r}: landmarks {bad} outside [{self.low!r}, {self.high!r}]; "
                "move them inside the range or widen it"
            )

    def waypoints(self) -> tuple[float, ...]:
        """Landmarks and the values just beside them, clipped to the range, without duplicates."""
        out: dict[float, None] = {}
        near = NEAR_FRACTION * self.max_step
        for x in self.landmarks:
            for value in (x, x - near, x + near, x - 1e-9, x + 1e-9):
                out.setdefault(min(max(value, self.low), self.high), None)
        return tuple(out)


@functools.lru_cache(maxsize=1024)
def _value_strategy(channel: Channel, adversarial: bool) -> st.SearchStrategy[float]:
    """A waypoint: a landmark (or beside one), any value of the range, or (adversarial) a special.

    Built once per channel (the sequence strategies ask for it at every segment of every example).
    """
    if channel.choices:
        return st.sampled_from(channel.choices)
    options = []
    points = channel.waypoints()
    if points:
        options.append(st.sampled_from(points))
    options.append(st.floats(channel.low, channel.high, allow_nan=False))
    if adversarial and channel.specials:
        options.append(st.sampled_from(channel.specials))
    return st.one_of(*options)


@dataclass(frozen=True, kw_only=True, slots=True)
class Segment:
    """One leg of a waypoint sequence.

    Attributes
    ----------
    duration : int
        Samples in the leg (>= 1).
    targets : tuple of (float or None)
        Waypoint per channel; ``None`` holds the channel.
    speeds : tuple of float
        Largest change per sample per channel; ``inf`` jumps to the waypoint
        at the leg's first sample, ``0`` holds.
    """

    duration: int
    targets: tuple[float | None, ...]
    speeds: tuple[float, ...]


def follow_waypoints(start: Sample, segments: Sequence[Segment]) -> tuple[Sample, ...]:
    """The samples of a run that starts at ``start`` and follows ``segments``.

    Every channel moves towards its leg's waypoint by at most its speed per
    sample and holds there; non-finite values (``inf``) are reached or left
    by a jump.  The result has ``1 + sum(duration)`` samples.

    Examples
    --------
    >>> follow_waypoints((0.0,), [Segment(duration=4, targets=(1.0,), speeds=(0.3,))])
    ((0.0,), (0.3,), (0.6,), (0.8999999999999999,), (1.0,))
    """
    values = list(start)
    samples: list[Sample] = [tuple(values)]
    for seg in segments:
        # the channels that move in this leg; one that reached its waypoint holds it for the rest of the leg
        moving = [(i, goal, speed) for i, (goal, speed) in enumerate(zip(seg.targets, seg.speeds))
                  if goal is not None and not speed <= 0.0]
        remaining = seg.duration
        while remaining > 0 and moving:
            still = []
            for i, goal, speed in moving:
                now = values[i]
                if now == goal:
                    continue
                if speed == math.inf or not (math.isfinite(now) and math.isfinite(goal)):
                    values[i] = goal
                elif goal > now:
                    values[i] = min(goal, now + speed)
                else:
                    values[i] = max(goal, now - speed)
                still.append((i, goal, speed))
            samples.append(tuple(values))
            moving = still
            remaining -= 1
        if remaining > 0:  # every channel holds: the same sample to the end of the leg
            samples.extend([tuple(values)] * remaining)
    return tuple(samples)


def waypoint_strategy(channel: Channel, *, adversarial: bool = False) -> st.SearchStrategy[float]:
    """A waypoint of ``channel``: a landmark or a value beside one (first: they shrink there), any value
    of the range, or (adversarial) a special value."""
    return _value_strategy(channel, adversarial)


@st.composite
def _sequences(
    draw: Callable[[st.SearchStrategy[Any]], Any],
    channels: tuple[Channel, ...],
    min_length: int,
    max_length: int,
    max_segments: int,
    adversarial: bool,
) -> tuple[Sample, ...]:
    start = tuple(draw(_value_strategy(ch, adversarial)) for ch in channels)
    n_segments = draw(st.integers(1, max_segments))
    longest = max(1, (max_length - 1) // max(1, n_segments) * 2)
    segments: list[Segment] = []
    used = 1
    for _ in range(n_segments):
        remaining = max_length - used
        if remaining <= 0:
            break
        duration = draw(st.integers(1, min(remaining, longest)))
        used += duration
        targets = []
        speeds = []
        for ch in channels:
            targets.append(draw(_value_strategy(ch, adversarial)))
            if ch.choices:
                speeds.append(math.inf)
            elif adversarial:
                # inf: jump at once; otherwise ramp at up to 4x the plausible rate, or hold
                speeds.append(draw(st.sampled_from((math.inf, 4.0 * ch.max_step, 0.0, ch.max_step))))
            else:
                speeds.append(draw(st.floats(0.0, 1.0)) * ch.max_step)
        segments.append(Segment(duration=duration, targets=tuple(targets), speeds=tuple(speeds)))
    samples = follow_waypoints(start, segments)
    if len(samples) < min_length:
        samples = samples + (samples[-1],) * (min_length - len(samples))
    return samples


def _check_lengths(min_length: int, max_length: int, max_segments: int) -> None:
    if not (isinstance(min_length, int) and isinstance(max_length, int) and 1 <= min_length <= max_length):
        raise ValueError(f"sequence lengths [{min_length!r}, {max_length!r}]: expected integers 1 <= min <= max")
    if not (isinstance(max_segments, int) and max_segments >= 1):
        raise ValueError(f"max_segments = {max_segments!r}: expected an integer >= 1")


def bounded_rate_sequences(
    channels: Sequence[Channel], *, min_length: int = 1, max_length: int = 400, max_segments: int = 8
) -> st.SearchStrategy[tuple[Sample, ...]]:
    """Physically plausible sequences: ``|x[k+1] - x[k]| <= max_step`` on every continuous channel.

    Parameters
    ----------
    channels : sequence of Channel
    min_length, max_length : int
        Number of samples (a short run is held at its last value up to ``min_length``).
    max_segments : int
        Waypoints per run; each segment ramps every channel towards its
        waypoint at a drawn fraction of its bound, then holds.

    Returns
    -------
    strategy of tuple of samples
    """
    _check_lengths(min_length, max_length, max_segments)
    return _sequences(tuple(channels), min_length, max_length, max_segments, False)


def unbounded_sequences(
    channels: Sequence[Channel], *, min_length: int = 1, max_length: int = 200, max_segments: int = 12
) -> st.SearchStrategy[tuple[Sample, ...]]:
    """Adversarial sequences: jumps, fast ramps and special values (``inf``) on any channel."""
    _check_lengths(min_length, max_length, max_segments)
    return _sequences(tuple(channels), min_length, max_length, max_segments, True)


def adversarial_sequences(
    channels: Sequence[Channel], *, min_length: int = 1, max_length: int = 300, max_segments: int = 10
) -> st.SearchStrategy[tuple[Sample, ...]]:
    """Either a bounded-rate or an unbounded sequence (the bounded ones first: they shrink further)."""
    return st.one_of(
        bounded_rate_sequences(channels, min_length=min_length, max_length=max_length, max_segments=max_segments),
        unbounded_sequences(channels, min_length=min_length, max_length=max_length, max_segments=max_segments),
    )


def max_rate_ratio(sequence: Sequence[Sample], channels: Sequence[Channel]) -> float:
    """Largest ``|x[k+1] - x[k]| / max_step`` over the continuous channels (``<= 1`` when bounded-rate).

    A change from or to a non-finite value counts as ``inf``; discrete
    channels are ignored.
    """
    worst = 0.0
    for a, b in zip(sequence, sequence[1:]):
        for ch, x, y in zip(channels, a, b):
            if ch.choices or x == y:
                continue
            if not (math.isfinite(x) and math.isfinite(y)):
                return math.inf
            worst = max(worst, abs(y - x) / ch.max_step)
    return worst


class PropertyViolation(AssertionError):
    """A property failed on one example.

    Attributes
    ----------
    property : str
        Name of the property.
    message : str
        What failed, with the values.
    sample : int or None
        Index of the sample where it failed (``None`` for whole-run properties).
    details : Mapping[str, Any]
        JSON-ready values that explain the failure.
    """

    def __init__(
        self, prop: str, message: str, *, sample: int | None = None, details: Mapping[str, Any] | None = None
    ) -> None:
        super().__init__(f"{prop}: {message}" + ("" if sample is None else f" (sample {sample})"))
        self.property = prop
        self.message = message
        self.sample = sample
        self.details = MappingProxyType(dict(details or {}))


@dataclass(frozen=True, kw_only=True, slots=True)
class Failure:
    """The shrunk counterexample of a failed property.

    Attributes
    ----------
    example : Any
        The minimal failing example (what the strategy drew).
    message : str
        The violation's message, or ``"ExceptionType: text"`` for any other exception.
    sample : int or None
        Sample index of the violation, when known.
    details : Mapping[str, Any]
        The violation's details.
    exception : str
        Name of the exception class (``"PropertyViolation"`` for a violated property).
    """

    example: Any
    message: str
    sample: int | None = None
    details: Mapping[str, Any] = field(default_factory=dict)
    exception: str = "PropertyViolation"

    def __post_init__(self) -> None:
        object.__setattr__(self, "details", MappingProxyType(dict(self.details)))


@dataclass(frozen=True, kw_only=True, slots=True)
class PropertyRun:
    """Outcome of :func:`run_property` or :func:`run_machine`.

    Attributes
    ----------
    name : str
    examples : int
        Examples the check ran on (generation, targeting and shrinking).
    steps : int
        Work units the check reported (e.g. supervisor steps), summed.
    failure : Failure or None
        The shrunk counterexample, ``None`` when the property held.
    """

    name: str
    examples: int
    steps: int
    failure: Failure | None = None

    @property
    def passed(self) -> bool:
        """Whether no example failed."""
        return self.failure is None


def fuzz_settings(
    max_examples: int, *, derandomize: bool = True, shrink: bool = True, stateful_step_count: int = 50
) -> settings:
    """An explicit, reproducible hypothesis configuration (independent of the loaded profile).

    Fixed ``max_examples``, no example database, no deadline, no health
    checks (sequences are long on purpose), no ``explain`` phase, one bug
    reported (the first, shrunk).
    """
    if not (isinstance(max_examples, int) and max_examples >= 1):
        raise ValueError(f"max_examples = {max_examples!r}: expected an integer >= 1")
    phases = [Phase.explicit, Phase.generate, Phase.target]
    if shrink:
        phases.append(Phase.shrink)
    return settings(
        max_examples=max_examples,
        derandomize=derandomize,
        database=None,
        deadline=None,
        suppress_health_check=list(HealthCheck),
        phases=phases,
        report_multiple_bugs=False,
        print_blob=False,
        verbosity=Verbosity.quiet,
        stateful_step_count=stateful_step_count,
    )


def _failure(example: Any, err: BaseException) -> Failure:
    if isinstance(err, PropertyViolation):
        return Failure(example=example, message=err.message, sample=err.sample, details=dict(err.details))
    return Failure(example=example, message=f"{type(err).__name__}: {err}", exception=type(err).__name__)


def _observe(label: str, value: float) -> None:
    if math.isfinite(value):
        target(float(value), label=label)


@contextlib.contextmanager
def project_constants_ignored() -> Iterator[None]:
    """Keep hypothesis from mixing the project's own source constants into the draws (every hypothesis search of
    the toolkit runs inside this: fuzzing here, falsification in :mod:`analysis.verify.falsification`).

    Since 6.131 hypothesis draws, with a small probability, numbers found in
    the source of every *local* module in ``sys.modules``; the examples of a
    seed then depend on which project modules (and test files) happen to be
    imported, and on every constant anyone adds anywhere.  A fuzzing run must
    give the same examples for the same seed from the CLI, a library call or
    the test suite, so its draws use hypothesis' global constants only.  The
    hook is internal to hypothesis: when it is absent (another version) this
    does nothing.
    """
    try:
        from hypothesis.internal.conjecture import providers
    except ImportError:  # pragma: no cover - hypothesis layout changed
        yield
        return
    original = getattr(providers, "_get_local_constants", None)
    empty_type = getattr(providers, "Constants", None)
    cache = getattr(providers, "CONSTANTS_CACHE", None)
    if original is None or empty_type is None or cache is None:  # pragma: no cover - other version
        yield
        return
    from sortedcontainers import SortedSet  # a dependency of hypothesis

    empty = empty_type(integers=SortedSet(), floats=SortedSet(key=providers.float_to_int), bytes=SortedSet(),
                       strings=SortedSet())
    cache.cache.clear()
    providers._get_local_constants = lambda: empty
    try:
        yield
    finally:
        providers._get_local_constants = original
        cache.cache.clear()


def run_property(
    name: str,
    check: Callable[[Any, Observer], int | None],
    strategy: st.SearchStrategy[Any],
    *,
    max_examples: int = 100,
    seed: int | None = None,
    shrink: bool = True,
    on_example: Callable[[int], None] | None = None,
) -> PropertyRun:
    """Run ``check`` on examples of ``strategy``; keep the shrunk counterexample.

    Parameters
    ----------
    name : str
        Property name (recorded in the result).
    check : callable
        ``check(example, observe) -> steps``; raises :class:`PropertyViolation`
        (or anything else) on failure; ``observe(label, value)`` forwards a
        margin to ``hypothesis.target`` (maximised).
    strategy : SearchStrategy
    max_examples : int
        Examples generated (shrinking runs more).
    seed : int or None
        ``None``: derandomised (the same examples every run); an integer: that
        random seed (the same examples for the same seed).
    shrink : bool
        Shrink a failure (``False`` stops at the first failing example).
    on_example : callable or None
        Called with the number of examples run so far after each example (progress).

    Returns
    -------
    PropertyRun
    """
    config = fuzz_settings(max_examples, derandomize=seed is None, shrink=shrink)
    state: dict[str, Any] = {"examples": 0, "steps": 0, "last": None}

    def test(example: Any) -> None:
        state["examples"] += 1
        try:
            steps = check(example, _observe)
        except HypothesisException:
            raise
        except Exception as err:
            state["last"] = (example, err)
            raise
        finally:
            if on_example is not None:
                on_example(state["examples"])
        state["steps"] += int(steps or 0)

    wrapped = config(given(strategy)(test))
    if seed is not None:
        wrapped = hypothesis_seed(seed)(wrapped)
    try:
        with warnings.catch_warnings(), project_constants_ignored():
            warnings.simplefilter("ignore", HypothesisWarning)  # large reprs of long failing sequences
            wrapped()
    except HypothesisException:
        raise
    except Exception:
        if state["last"] is None:  # pragma: no cover - hypothesis failed outside the check
            raise
        example, err = state["last"]
        return PropertyRun(name=name, examples=state["examples"], steps=state["steps"], failure=_failure(example, err))
    return PropertyRun(name=name, examples=state["examples"], steps=state["steps"])


def run_machine(
    name: str,
    machine: type[RuleBasedStateMachine],
    *,
    max_examples: int = 50,
    steps_per_example: int = 50,
    seed: int | None = None,
    shrink: bool = True,
    record: Callable[[RuleBasedStateMachine], Any] = lambda m: None,
    on_example: Callable[[int], None] | None = None,
) -> PropertyRun:
    """Run a rule-based state machine as a property; keep the shrunk run.

    Parameters
    ----------
    machine : RuleBasedStateMachine subclass
        Its invariants raise :class:`PropertyViolation` (or anything else) on
        failure; an attribute ``steps`` (work units of one run) is summed.
    steps_per_example : int
        Rules per run (hypothesis ``stateful_step_count``).
    record : callable
        ``record(machine_instance)`` returns the replayable example of a run
        (e.g. the signals the machine fed); it is read on the final, shrunk run.
    Other parameters as :func:`run_property`.
    """
    config = fuzz_settings(max_examples, derandomize=seed is None, shrink=shrink, stateful_step_count=steps_per_example)
    state: dict[str, Any] = {"examples": 0, "steps": 0, "instance": None}

    class Recorded(machine):  # type: ignore[misc, valid-type]
        def __init__(self) -> None:
            super().__init__()
            state["examples"] += 1
            state["instance"] = self
            if on_example is not None:
                on_example(state["examples"])

        def teardown(self) -> None:
            state["steps"] += int(getattr(self, "steps", 0) or 0)
            super().teardown()

    Recorded.__name__ = machine.__name__
    Recorded.__qualname__ = machine.__qualname__
    if seed is not None:
        Recorded = hypothesis_seed(seed)(Recorded)  # noqa: N806
    try:
        with warnings.catch_warnings(), project_constants_ignored():
            warnings.simplefilter("ignore", HypothesisWarning)
            run_state_machine_as_test(Recorded, settings=config)
    except HypothesisException:
        raise
    except Exception as err:
        instance = state["instance"]
        example = record(instance) if instance is not None else None
        return PropertyRun(name=name, examples=state["examples"], steps=state["steps"], failure=_failure(example, err))
    return PropertyRun(name=name, examples=state["examples"], steps=state["steps"])
