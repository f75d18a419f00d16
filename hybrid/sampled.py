"""Sampled-data execution of a hybrid automaton wrapped around a plant.

Every sampling period ``T`` the executor

1. lets the controller *measure* the plant (it may update its own discrete
   state, e.g. an estimator, from the input held over the period just ended);
2. evaluates the automaton on the measured signals and fires enabled
   transitions by the rule of :mod:`hybrid.instant` (priority order, each a
   jump of the hybrid time domain ``(t, j)``, crossing guards against the
   previous sample), until none is enabled (a limit on jumps per sample
   turns Zeno behaviour into a :class:`~hybrid.errors.ZenoError`);
3. asks the controller for the input ``u`` of the new mode and holds it
   (zero-order hold) while the plant is integrated over ``[t, t + T]`` by its
   exact flow map when it has one, otherwise by ``scipy.integrate.solve_ivp``
   (DOP853, ``rtol = 1e-10``, ``atol = 1e-12``).

A :class:`~hybrid.errors.NumericalFailure` raised by user code, or a NaN in a
state, a signal or an input, stops the run with a
:class:`~hybrid.errors.DivergenceError` naming the time, the mode and the cause.

Resource bound: the run has ``floor(duration / period) + 1`` samples and keeps
one row per sample in memory.  :func:`simulate_sampled` refuses, before it
allocates anything or calls user code, a sample count above ``max_samples``
(default :data:`DEFAULT_MAX_SAMPLES`), one that is not representable (an
overflowing ``duration / period``) and a period too small to advance the time
stamps, with a :class:`SampledArgumentError` naming the argument, the value,
what was expected and the fix.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from scipy.integrate import solve_ivp

from .errors import DivergenceError, ExecutionError, NumericalFailure, ParameterError, ZenoError
from .instant import MAX_JUMPS_PER_INSTANT, Instant, guard_value, settle_instant
from .model import HybridAutomaton, Transition
from .system import call_user

__all__ = [
    "Plant",
    "SampledController",
    "SampledEvent",
    "SampledTrace",
    "simulate_sampled",
    "settle",
    "sample_count",
    "SampledArgumentError",
    "DEFAULT_MAX_SAMPLES",
    "FLOW_RTOL",
    "FLOW_ATOL",
]

FLOW_RTOL = 1e-10
"""Relative tolerance of the fallback plant integration."""
FLOW_ATOL = 1e-12
"""Absolute tolerance of the fallback plant integration."""
DEFAULT_MAX_SAMPLES = 10_000_000
"""Default ``max_samples`` of :func:`simulate_sampled`: samples of one run at most.

A run keeps every sample's row (time, jump counter, mode, state, signals, input and
recorded values) as Python objects until it returns, about 50 bytes per value: ten
million samples of a 10-value row are about 5 GB.  Pass a larger ``max_samples`` for
longer runs on a machine that has the memory."""


class SampledArgumentError(ParameterError, ExecutionError):
    """An argument of :func:`simulate_sampled` that cannot describe a run (found before anything runs).

    A :class:`~hybrid.errors.ParameterError` (``parameter``, ``value``, ``expected``,
    ``fix``), and an :class:`~hybrid.errors.ExecutionError` as the executor's argument
    errors always were.  The message is
    ``"simulate_sampled: <parameter> = <value>; expected <expected>; fix: <fix>"``.
    """

    def render(self) -> str:
        """The message."""
        return f"simulate_sampled: {self.parameter} = {self.value!r}; expected {self.expected}; fix: {self.fix}"


@dataclass(frozen=True, kw_only=True, slots=True)
class Plant:
    """A continuous plant ``ẋ = f(x, u)`` under zero-order hold.

    Attributes
    ----------
    state_names : tuple of str
        Names of the state components (dimension ``n``).
    input_names : tuple of str
        Names of the input components (dimension ``p``).
    derivative : callable
        ``f(x, u) -> ẋ`` (sequences of floats).
    exact_flow : callable or None
        ``phi(x, u, dt) -> x(t + dt)`` when the flow under a constant input is
        known in closed form; preferred over numerical integration.
    """

    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    derivative: Callable[[Sequence[float], Sequence[float]], Sequence[float]]
    exact_flow: Callable[[Sequence[float], Sequence[float], float], Sequence[float]] | None = None

    def flow(self, x: Sequence[float], u: Sequence[float], dt: float) -> tuple[float, ...]:
        """State after ``dt`` under the constant input ``u``."""
        if self.exact_flow is not None:
            return tuple(self.exact_flow(x, u, dt))
        sol = solve_ivp(
            lambda _t, y: np.asarray(self.derivative(y, u), dtype=float),
            (0.0, dt),
            np.asarray(x, dtype=float),
            method="DOP853",
            rtol=FLOW_RTOL,
            atol=FLOW_ATOL,
        )
        if not sol.success:
            raise NumericalFailure(f"plant integration failed: {sol.message}")
        return tuple(float(c) for c in sol.y[:, -1])


class SampledController(Protocol):
    """What :func:`simulate_sampled` needs from the controller side.

    ``c`` is the controller's own discrete state (opaque to the executor).
    """

    record_names: tuple[str, ...]

    def initial_state(self, t: float, x: Sequence[float]) -> Any:
        """Controller state at the start of the run."""

    def measure(self, t: float, x: Sequence[float], c: Any) -> tuple[Sequence[float], Any]:
        """Signals ``v`` for the automaton at a sample, and the updated controller state."""

    def control(
        self, t: float, x: Sequence[float], c: Any, v: Sequence[float], mode: str, memory: Mapping[str, float]
    ) -> tuple[Sequence[float], Any, Sequence[float]]:
        """Input held over the next period, the updated state, and a row of recorded values."""


@dataclass(frozen=True, kw_only=True, slots=True)
class SampledEvent:
    """One discrete jump.

    Attributes
    ----------
    time : float
        Sample time of the jump [s].
    jump : int
        Jump counter ``j`` after the jump (hybrid time ``(time, jump)``).
    sample : int
        Sample index ``k``.
    transition, source, target : str
        What fired.
    outranked : tuple of str
        Other transitions enabled at the same instant that a smaller priority
        number beat (reported, not silent).
    memory : tuple of (str, float)
        Memory after the reset.
    """

    time: float
    jump: int
    sample: int
    transition: str
    source: str
    target: str
    outranked: tuple[str, ...] = ()
    memory: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True, kw_only=True, slots=True)
class SampledTrace:
    """Result of :func:`simulate_sampled` on the hybrid time domain.

    Arrays are read-only; row ``k`` holds the sample at ``times[k]`` *after*
    the jumps of that instant, with the input chosen there.

    Attributes
    ----------
    times : ndarray, shape (N,)
    jumps : ndarray of int, shape (N,)
        Jump counter ``j`` after each sample's jumps.
    modes : ndarray of int, shape (N,)
        Index into ``mode_names``.
    states : ndarray, shape (N, n)
    signals : ndarray, shape (N, len(variables))
    inputs : ndarray, shape (N, p)
    records : ndarray, shape (N, len(record_names))
    events : tuple of SampledEvent
    termination : str
        ``"end_time"`` or the reason returned by the stop condition.
    """

    automaton: str
    mode_names: tuple[str, ...]
    state_names: tuple[str, ...]
    variable_names: tuple[str, ...]
    input_names: tuple[str, ...]
    record_names: tuple[str, ...]
    period: float
    times: np.ndarray
    jumps: np.ndarray
    modes: np.ndarray
    states: np.ndarray
    signals: np.ndarray
    inputs: np.ndarray
    records: np.ndarray
    events: tuple[SampledEvent, ...]
    termination: str
    final_state: tuple[float, ...]
    final_mode: str
    final_memory: Mapping[str, float] = field(default_factory=dict)

    def record(self, name: str) -> np.ndarray:
        """Column of the recorded values called ``name``."""
        return self.records[:, self._index(self.record_names, name, "record")]

    def signal(self, name: str) -> np.ndarray:
        """Column of the signal called ``name``."""
        return self.signals[:, self._index(self.variable_names, name, "signal")]

    def state(self, name: str) -> np.ndarray:
        """Column of the state called ``name``."""
        return self.states[:, self._index(self.state_names, name, "state")]

    def input(self, name: str) -> np.ndarray:
        """Column of the input called ``name``."""
        return self.inputs[:, self._index(self.input_names, name, "input")]

    @staticmethod
    def _index(names: tuple[str, ...], name: str, kind: str) -> int:
        try:
            return names.index(name)
        except ValueError:
            raise KeyError(f"no {kind} called {name!r}; available: {list(names)}") from None

    @property
    def visited_modes(self) -> tuple[str, ...]:
        """Modes in order of first visit."""
        seen: dict[str, None] = {}
        for i in self.modes:
            seen.setdefault(self.mode_names[int(i)], None)
        return tuple(seen)


def _readonly(rows: list[Sequence[float]], width: int, dtype: type = float) -> np.ndarray:
    array = np.asarray(rows, dtype=dtype).reshape(len(rows), width)
    array.setflags(write=False)
    return array


def _first_nan(values: Sequence[float], names: Sequence[str]) -> str | None:
    for name, value in zip(names, values):
        if value != value:  # NaN test without a function call
            return name
    return None


_NONE: frozenset[str] = frozenset()


def settle(
    automaton: HybridAutomaton,
    mode: str,
    memory: Mapping[str, float],
    v: Sequence[float],
    previous: Sequence[float] | None = None,
    *,
    time: float = 0.0,
    sample: int = 0,
    jump: int = 0,
    max_jumps: int = MAX_JUMPS_PER_INSTANT,
    outgoing: Mapping[str, tuple[Any, ...]] | None = None,
) -> tuple[str, dict[str, float], list[SampledEvent]]:
    """Fire enabled transitions at one sample until none is enabled (:func:`hybrid.instant.settle_instant`).

    The signals ``v`` are the state of the instant (a sampled-data automaton
    has no jump map: the plant is not reset, only the memory); ties raise.

    Parameters
    ----------
    mode, memory : str, mapping
        Discrete state before the instant.
    v, previous : sequences of float
        Signals now and at the previous sample (for crossing guards).
    time, sample, jump : float, int, int
        Hybrid time before the instant (recorded in the events).
    max_jumps : int
        Jumps allowed at one instant; one more enabled raises :class:`ZenoError`.

    Returns
    -------
    mode, memory, events
        The discrete state after the instant and the jumps taken.

    Raises
    ------
    ExecutionError
        Two enabled transitions with the same priority (non-determinism), a NaN
        guard, or a reset that does not return exactly its declared ``writes``.
    ZenoError
        A transition still enabled after ``max_jumps`` jumps.
    """
    table = outgoing if outgoing is not None else {name: automaton.outgoing(name) for name in automaton.mode_names}
    instant = _sample_instant(table, mode, memory, v, previous, time, max_jumps)
    return instant.mode, dict(instant.memory), _events(instant, time, sample, jump)


def _sample_instant(
    outgoing: Mapping[str, tuple[Any, ...]], mode: str, memory: Mapping[str, float], v: Sequence[float],
    previous: Sequence[float] | None, time: float, max_jumps: int, disarmed: frozenset[str] = frozenset(),
) -> Instant:
    """The kernel at one sample: errors carry the time and mode, Zeno raises."""
    try:
        instant = settle_instant(outgoing, mode, v, memory, previous=previous, max_jumps=max_jumps, time=time,
                                 disarmed=disarmed)
    except ExecutionError as err:
        if str(err).startswith("non-determinism at t ="):  # the kernel's message already names both
            raise
        raise ExecutionError(f"at t = {time:.6g} s in mode {mode!r}: {err}") from err
    if instant.zeno is not None:
        raise ZenoError(f"{instant.zeno} (simulate_sampled: max_jumps_per_sample)")
    return instant


def _disarmed_after(crossing: Mapping[str, Transition], instant: Instant, v: Sequence[float],
                    memory: Mapping[str, float], disarmed: Collection[str]) -> frozenset[str]:
    """The crossing guards disarmed for the next sample (:mod:`hybrid.instant`: one event per crossing).

    Parameters
    ----------
    crossing : Mapping[str, Transition]
        The crossing-triggered outgoing transitions, by name, of the mode the period ran in (the instant's first
        jump is from it).
    instant : Instant
        The instant settled at this sample.
    v, memory
        The signals at this sample and the memory the period ran with.
    disarmed : collection of str
        The crossing guards disarmed at this sample.

    Returns
    -------
    frozenset of str
        Those crossed at this instant (enabled at its first jump: the winner and the outranked), and those
        disarmed before that are not yet strictly on their pre-crossing side (``direction · g(v) >= 0``): a
        sample exactly on the zero, then one beyond it, is one crossing, not two.
    """
    if not crossing:
        return _NONE
    still = {name for name in disarmed if name in crossing
             and crossing[name].direction * guard_value(crossing[name], v, memory) >= 0.0}
    crossed_now = {name for name in instant.jumps[0].enabled if name in crossing} if instant.jumps else set()
    return frozenset(still | crossed_now)


def _events(instant: Instant, time: float, sample: int, jump: int) -> list[SampledEvent]:
    return [
        SampledEvent(
            time=time, jump=jump + n, sample=sample, transition=step.transition.name, source=step.source,
            target=step.target, outranked=step.outranked, memory=tuple(sorted(step.memory_after.items())),
        )
        for n, step in enumerate(instant.jumps, start=1)
    ]


def _finite_time(name: str, value: object, wanted: str, example: str, positive: bool = True) -> float:
    """``value`` as a float [s], or a :class:`SampledArgumentError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise SampledArgumentError(name, value, f"{wanted}, found {type(value).__name__}",
                                   f"pass a number such as {example}")
    number = float(value)
    if not math.isfinite(number) or (positive and not number > 0):
        raise SampledArgumentError(name, value, wanted, f"pass a {wanted.removeprefix('a ')} such as {example}")
    return number


def sample_count(period: float, duration: float, *, t0: float = 0.0, max_samples: int = DEFAULT_MAX_SAMPLES) -> int:
    """The number of samples :func:`simulate_sampled` takes, ``floor(duration / period) + 1``, checked.

    Nothing is allocated: the arguments are checked against :func:`simulate_sampled`'s
    rules and its resource bound, so a caller can refuse a run up front.

    Parameters
    ----------
    period, duration : float
        Sampling period and simulated time, finite and ``> 0`` [s].
    t0 : float
        Time of the first sample, finite [s].
    max_samples : int
        Most samples allowed, ``>= 1`` (default :data:`DEFAULT_MAX_SAMPLES`).

    Returns
    -------
    int
        Between 1 and ``max_samples``.

    Raises
    ------
    SampledArgumentError
        Naming the argument, its value, what was expected and the fix.

    Examples
    --------
    >>> sample_count(0.05, 120.0)
    2401
    >>> sample_count(1e-12, 1e3)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hybrid.sampled.SampledArgumentError: simulate_sampled: duration = 1000.0; expected at most max_samples = ...
    """
    period = _finite_time("period", period, "a positive finite time step [s]", "0.01")
    duration = _finite_time("duration", duration, "a positive finite time [s]", "10.0")
    t0 = _finite_time("t0", t0, "a finite time [s]", "0.0", positive=False)
    if isinstance(max_samples, bool) or not isinstance(max_samples, numbers.Integral) or max_samples < 1:
        raise SampledArgumentError("max_samples", max_samples, "an integer >= 1",
                                   f"pass a whole number of samples, e.g. the default {DEFAULT_MAX_SAMPLES:_}")
    ratio = duration / period  # inf when it overflows: compared before any int()
    fix = "lengthen period, shorten duration, or pass a larger max_samples"
    if not (math.isfinite(ratio) and ratio < 2.0 * max_samples):
        count = f"{ratio:.3g} samples" if math.isfinite(ratio) else "overflows a float"
        raise SampledArgumentError(
            "duration", duration,
            f"at most max_samples = {int(max_samples):,} samples of period = {period!r} s "
            f"(duration / period = {count})", fix)
    n_samples = int(math.floor(ratio + 1e-9)) + 1
    if n_samples > max_samples:
        raise SampledArgumentError(
            "duration", duration,
            f"at most max_samples = {int(max_samples):,} samples of period = {period!r} s "
            f"(floor(duration / period) + 1 = {n_samples:,} samples)", fix)
    t_last = t0 + (n_samples - 1) * period
    if not (math.isfinite(t_last) and t0 + period > t0 and t_last + period > t_last):
        raise SampledArgumentError(
            "period", period,
            f"a period that advances the time from t0 = {t0!r} s to the last sample ({t_last!r} s): at that "
            "magnitude t + period == t",
            "start at a smaller t0 or lengthen period",
        )
    return n_samples


def simulate_sampled(
    automaton: HybridAutomaton,
    plant: Plant,
    controller: SampledController,
    x0: Sequence[float],
    *,
    period: float,
    duration: float,
    t0: float = 0.0,
    initial_mode: str | None = None,
    initial_memory: Mapping[str, float] | None = None,
    stop: Callable[[float, Sequence[float], Any, Sequence[float], str, Mapping[str, float]], str | None]
    | None = None,
    max_jumps_per_sample: int = MAX_JUMPS_PER_INSTANT,
    max_samples: int = DEFAULT_MAX_SAMPLES,
) -> SampledTrace:
    """Run the sampled-data closed loop for ``duration`` seconds.

    Parameters
    ----------
    automaton : HybridAutomaton
        The supervisor; its signals are what ``controller.measure`` returns.
    plant : Plant
        Continuous plant integrated exactly between samples.
    controller : SampledController
        Measurement, control law and recorded values.
    x0 : sequence of float, shape (n,)
        Initial plant state.
    period : float
        Sampling period ``T > 0`` [s], finite.
    duration : float
        Simulated time ``> 0`` [s], finite; the last sample is at ``t0 + K T <= t0 + duration``
        (:func:`sample_count` samples).
    t0 : float
        Time of the first sample [s], finite.
    stop : callable or None
        ``stop(t, x, c, v, mode, memory)`` returning a termination reason to
        end the run after the current sample, or ``None`` to go on.
    max_jumps_per_sample : int
        Jumps allowed at one instant before a :class:`ZenoError`.
    max_samples : int
        Most samples the run may have (default :data:`DEFAULT_MAX_SAMPLES`): a longer
        ``duration / period`` is refused before anything is allocated, since the
        trace holds every sample (a ``stop`` condition that ends the run early does
        not lift the bound: it may never hold).

    Returns
    -------
    SampledTrace

    Raises
    ------
    SampledArgumentError
        (a :class:`~hybrid.errors.ParameterError` and an :class:`ExecutionError`) on
        invalid arguments: a period, duration or ``t0`` that is not a finite number
        (``period``, ``duration > 0``), more samples than ``max_samples`` or than a
        float can count, a period too small to advance the time, a wrong ``x0``.
    ExecutionError
        On wrong signal dimensions or unknown initial memory.
    ZenoError
        When more than ``max_jumps_per_sample`` jumps happen at one instant.
    DivergenceError
        When user code raises :class:`NumericalFailure` or a value becomes NaN.
    """
    n_samples = sample_count(period, duration, t0=t0, max_samples=max_samples)
    mode, memory = _start(automaton, plant, x0, initial_mode, initial_memory, max_jumps_per_sample)

    x = tuple(float(c) for c in x0)
    mode_index = {name: i for i, name in enumerate(automaton.mode_names)}
    outgoing = {name: automaton.outgoing(name) for name in automaton.mode_names}
    crossing = {name: {t.name: t for t in ts if t.direction != 0} for name, ts in outgoing.items()}
    n_vars = len(automaton.variables)
    times: list[float] = []
    jumps: list[int] = []
    modes: list[int] = []
    states: list[tuple[float, ...]] = []
    signals: list[Sequence[float]] = []
    inputs: list[Sequence[float]] = []
    records: list[Sequence[float]] = []
    events: list[SampledEvent] = []
    j = 0
    previous: Sequence[float] | None = None
    disarmed: frozenset[str] = frozenset()  # crossing guards that had their crossing (_disarmed_after)
    termination = "end_time"
    t = t0

    def user(what: str, at: float, state: Sequence[float], fn: Callable[..., Any], *args: Any) -> Any:
        """A user's plant, controller or stop function, its exceptions named with the mode, time and state."""
        return call_user(fn, args, function=what, mode=mode, time=at, state=state,
                         state_names=plant.state_names, system=automaton.name)

    try:
        c = user("initial_state of the controller", t0, x, controller.initial_state, t0, x)
    except NumericalFailure as err:
        raise DivergenceError(t0, mode, err.cause) from err

    for k in range(n_samples):
        t = t0 + k * period
        bad = _first_nan(x, plant.state_names)
        if bad is not None:
            raise DivergenceError(t, mode, f"plant state {bad!r} is NaN")
        try:
            v, c = user("measure of the controller", t, x, controller.measure, t, x, c)
            if len(v) != n_vars:
                automaton.check_signals(v)
            bad = _first_nan(v, automaton.variables)
            if bad is not None:
                raise NumericalFailure(f"signal {bad!r} is NaN")
            # --- discrete jumps at this instant -------------------------------------
            instant = _sample_instant(outgoing, mode, memory, v, previous, t, max_jumps_per_sample, disarmed)
            disarmed = _disarmed_after(crossing[mode], instant, v, memory, disarmed)
            if instant.jumps:
                fired = _events(instant, t, k, j)
                events.extend(fired)
                j = fired[-1].jump
            mode, memory = instant.mode, instant.memory
            # --- control --------------------------------------------------------------
            u, c, row = user("control of the controller", t, x, controller.control, t, x, c, v, mode, memory)
            bad = _first_nan(u, plant.input_names)
            if bad is not None:
                raise NumericalFailure(f"input {bad!r} is NaN")
        except NumericalFailure as err:
            raise DivergenceError(t, mode, err.cause) from err
        times.append(t)
        jumps.append(j)
        modes.append(mode_index[mode])
        states.append(x)
        signals.append(v)
        inputs.append(u)
        records.append(row)
        previous = v
        if stop is not None:
            reason = user("stop condition", t, x, stop, t, x, c, v, mode, memory)
            if reason:
                termination = reason
                break
        if k + 1 < n_samples:
            try:
                x = user("flow of the plant", t, x, plant.flow, x, u, period)
            except NumericalFailure as err:
                raise DivergenceError(t, mode, err.cause) from err

    return _trace(automaton, plant, controller, period, (times, jumps, modes, states, signals, inputs, records),
                  events, termination, x, mode, memory)


def _start(automaton: HybridAutomaton, plant: Plant, x0: Sequence[float], initial_mode: str | None,
           initial_memory: Mapping[str, float] | None, max_jumps_per_sample: int) -> tuple[str, dict[str, float]]:
    """The checked initial mode and memory of :func:`simulate_sampled` (its ``x0`` and ``max_jumps_per_sample``
    checked too)."""
    if len(x0) != len(plant.state_names):
        raise SampledArgumentError(
            "x0", tuple(x0),
            f"one value per plant state: x0 has {len(x0)} components, plant state has {len(plant.state_names)} "
            f"({', '.join(plant.state_names)})",
            "give x0 in the order of plant.state_names",
        )
    if isinstance(max_jumps_per_sample, bool) or not isinstance(max_jumps_per_sample, numbers.Integral) or (
            max_jumps_per_sample < 1):
        raise SampledArgumentError("max_jumps_per_sample", max_jumps_per_sample, "an integer >= 1",
                                   f"use the default {MAX_JUMPS_PER_INSTANT}")
    mode = initial_mode or automaton.initial_mode
    automaton.mode(mode)
    memory = automaton.initial_memory()
    if initial_memory:
        unknown = set(initial_memory) - set(memory)
        if unknown:
            raise ExecutionError(f"simulate_sampled: initial_memory names unknown variable(s) {sorted(unknown)}")
        memory.update({k: float(val) for k, val in initial_memory.items()})
    return mode, memory


def _trace(automaton: HybridAutomaton, plant: Plant, controller: SampledController, period: float,
           columns: tuple[list, ...], events: list[SampledEvent], termination: str, x: tuple[float, ...], mode: str,
           memory: dict[str, float]) -> SampledTrace:
    """The :class:`SampledTrace` of a run of :func:`simulate_sampled` from its per-sample ``columns`` (times, jump
    counts, mode indices, states, signals, inputs, records)."""
    times, jumps, modes, states, signals, inputs, records = columns
    n_vars = len(automaton.variables)
    return SampledTrace(
        automaton=automaton.name,
        mode_names=automaton.mode_names,
        state_names=tuple(plant.state_names),
        variable_names=automaton.variables,
        input_names=tuple(plant.input_names),
        record_names=tuple(controller.record_names),
        period=float(period),
        times=_readonly(times, 1).reshape(-1),
        jumps=_readonly(jumps, 1, int).reshape(-1),
        modes=_readonly(modes, 1, int).reshape(-1),
        states=_readonly(states, len(plant.state_names)),
        signals=_readonly(signals, n_vars),
        inputs=_readonly(inputs, len(plant.input_names)),
        records=_readonly(records, len(controller.record_names)),
        events=tuple(events),
        termination=termination,
        final_state=x,
        final_mode=mode,
        final_memory=dict(memory),
    )
