"""Continuous-time execution of a :class:`~hybrid.system.HybridSystem` with exact events.

The executor integrates the flow of the current mode with one of scipy's
ODE solvers (explicit or stiff, chosen by ``method``), one step at a time.
After every accepted step it watches, on the step's dense output,

* the guard of every outgoing transition (level-triggered: ``g >= 0``;
  ``direction = +1``: ``g`` crosses zero upwards; ``-1``: downwards; one
  event per crossing, see :mod:`hybrid.instant`),
* the mode's invariant (the flow leaving ``inv >= 0``),
* the user's stop functions (``s >= 0`` ends the run),

at the step's end *and* at ``sign_checks`` evenly spaced interior points of
the step's dense output, so a window (an interval where a watched function is
on) longer than ``step / (sign_checks + 1)`` is always seen
(:attr:`HybridTrajectory.resolution` is that spacing, the largest of the
run).  Shorter windows are searched where the samples leave room for one: two
samples of a function that is off, on one side of zero, closer to it than the
function can move between them (1.5 × the largest rate seen in the segment)
or than the samples bend, are refined on the dense output, 4 sub-intervals
per level, down to ``refine_depth`` levels, with a search of the extremum at
the finest (:class:`hybrid.events.Refiner`); what is still
undecided there is listed in :attr:`HybridTrajectory.unresolved` and reported
by a :class:`~hybrid.errors.GuardResolutionWarning`, never dropped silently.
The first change (in time order, hidden windows first) is located by a
bracketing root finder (Anderson–Björck regula falsi with bisection
safeguards) to ``event_tol`` in time; the located time is the right end
of the final bracket, where the guard *is* satisfied.  What happens at that
instant (and at the initial time) is decided by
:func:`hybrid.instant.settle_instant`, the rule shared by every executor and
check: priorities, ties (an error here), jump maps and resets, further
level-triggered jumps of the new mode at the same instant, crossing guards
against the state at the bracket's left end (those disarmed by their own
crossing excepted), and the jump limit.

The driver :func:`simulate_continuous` only keeps the books; the work is done
by small functions in the manner of scipy's ``_ivp``: :func:`_flow_segment`
(one mode's integration) and :func:`_resolve` (the instant); the event search,
:func:`hybrid.events.find_switch` (watches along a step) and
:func:`hybrid.events.locate_event` (the bracket search), is in :mod:`hybrid.events`.

Termination causes (``HybridTrajectory.termination``): ``"end_time"``,
``"jump_limit"``, ``"zeno"``, ``"chatter"``, ``"invariant_violated"`` (the flow
leaves the invariant with no transition enabled: a deadlock),
``"solver_failure"`` and ``"stop:<name>"`` for a user stop function.

Errors in user code are never swallowed: a flow, output, guard, invariant,
jump map, reset or stop function that raises becomes a
:class:`~hybrid.errors.UserFunctionError` (an
:class:`~hybrid.errors.ExecutionError`) naming the function, the mode (the
source mode for a transition's), the time and the state, chained to the
original exception, by the one mechanism of :func:`hybrid.system.call_user`
(the :class:`~hybrid.system.HybridSystem` methods); one that returns NaN, a
bool or the wrong shape raises an ``ExecutionError`` with the same naming;
:class:`~hybrid.errors.NumericalFailure` becomes a
:class:`~hybrid.errors.DivergenceError` with the time, the mode, the cause and
the state at the last finite point.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, OdeSolution, Radau

from .closed_form import ClosedFormSolver, closed_form_switch, point_evaluator
from .diagnostics import ChatterEpisode, ZenoReport, estimate_zeno, find_chatter
from .errors import ExecutionError, GuardResolutionWarning, ZenoError
from .events import (
    LocatedEvent,
    Refiner,
    UnresolvedWindow,
    Watch,
    arm_watches,
    find_switch,
    is_on,
    locate_crossing,
    locate_event,
    still_disarmed,
    unresolved_message,
)
from .instant import MAX_JUMPS_PER_INSTANT, Instant, settle_instant
from .model import Transition
from .model_calls import ModelCalls
from .system import HybridSystem
from .system import format_state as _fmt

__all__ = [
    "METHODS",
    "StopFunction",
    "HybridEvent",
    "FlowSegment",
    "ExecutionStats",
    "HybridTrajectory",
    "UnresolvedWindow",
    "simulate_continuous",
    "locate_crossing",
]

METHODS = {"RK45": RK45, "RK23": RK23, "DOP853": DOP853, "Radau": Radau, "BDF": BDF, "LSODA": LSODA}
"""scipy solvers available by name (``Radau``, ``BDF`` and ``LSODA`` handle stiff flows)."""

StopFunction = Callable[[float, Sequence[float], str, Mapping[str, float]], float]
"""``s(t, x, mode, memory)``: the run stops when it becomes ``>= 0``."""

_ZENO_WINDOW = 10
"""Intervals fitted by the accumulation test."""

_NONE: frozenset[str] = frozenset()


@dataclass(frozen=True, kw_only=True, slots=True)
class HybridEvent:
    """One jump of a continuous-time execution.

    Attributes
    ----------
    time : float
        Located event time [s].
    jump : int
        Jump counter after the jump (hybrid time ``(time, jump)``).
    transition, source, target : str
        What fired.
    state_before, state_after : tuple of float
        Continuous state before and after the jump map.
    memory : tuple of (str, float)
        Memory after the reset.
    outranked : tuple of str
        Transitions enabled at the same instant that lost on priority.
    instantaneous : bool
        ``True`` for a jump fired at the same instant as the previous one
        (the new mode was entered with a level-triggered guard already true).
    """

    time: float
    jump: int
    transition: str
    source: str
    target: str
    state_before: tuple[float, ...]
    state_after: tuple[float, ...]
    memory: tuple[tuple[str, float], ...] = ()
    outranked: tuple[str, ...] = ()
    instantaneous: bool = False


@dataclass(frozen=True, kw_only=True, slots=True)
class FlowSegment:
    """The flow between two jumps: interval ``[t_start, t_end]`` at jump count ``jump``.

    Attributes
    ----------
    mode : str
    jump : int
    t_start, t_end : float
    times : ndarray, shape (k,)
        Accepted step points (read-only), ``times[0] = t_start``, ``times[-1] = t_end``.
    states : ndarray, shape (k, n)
        States at ``times`` (read-only).
    memory : tuple of (str, float)
        Memory during the segment.
    dense : callable or None
        The dense output ``x(t)`` over the segment (scipy's ``OdeSolution``,
        built on first use); ``None`` when run with ``dense=False``.
    """

    mode: str
    jump: int
    t_start: float
    t_end: float
    times: np.ndarray
    states: np.ndarray
    memory: tuple[tuple[str, float], ...]
    dense: Callable[[float | np.ndarray], np.ndarray] | None = field(default=None, repr=False, compare=False)

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        """Dense output: state at ``t`` in ``[t_start, t_end]``, shape ``(n,)`` or ``(n, len(t))``."""
        if self.dense is None:
            if self.t_start == self.t_end:
                out = self.states[0]
                return out if np.ndim(t) == 0 else np.repeat(out[:, None], np.size(t), axis=1)
            raise ExecutionError(
                f"segment in mode {self.mode!r} on [{self.t_start}, {self.t_end}] s was run with dense=False; "
                "re-run simulate_continuous(..., dense=True) to evaluate it between steps"
            )
        return self.dense(t)


@dataclass(frozen=True, kw_only=True, slots=True)
class ExecutionStats:
    """Work done by one execution (deterministic for a given input).

    Attributes
    ----------
    steps, rhs_evaluations, root_iterations, events : int
    guard_evaluations : int
        Evaluations of the watched functions (all of a mode's watches count one each).
    refinement_evaluations : int
        Evaluations of all the watches at once made by the refinement (:class:`hybrid.events.Refiner`);
        each is also counted in ``guard_evaluations``, once per watch.
    """

    steps: int
    rhs_evaluations: int
    guard_evaluations: int
    root_iterations: int
    events: int
    refinement_evaluations: int = 0

    def as_dict(self) -> dict[str, int]:
        """JSON-ready view."""
        return {
            "steps": self.steps,
            "rhs_evaluations": self.rhs_evaluations,
            "guard_evaluations": self.guard_evaluations,
            "root_iterations": self.root_iterations,
            "events": self.events,
            "refinement_evaluations": self.refinement_evaluations,
        }


@dataclass(frozen=True, kw_only=True, slots=True)
class HybridTrajectory:
    """Result of :func:`simulate_continuous` on the hybrid time domain.

    Attributes
    ----------
    system : str
    mode_names, state_names : tuple of str
    segments : tuple of FlowSegment
        One per flow interval, in order; ``segments[i].jump == i`` unless
        instantaneous jumps skipped a (zero-length) flow.
    events : tuple of HybridEvent
    termination : str
        Why the run ended (see the module docstring).
    detail : str
        The reason in words (time, mode, state, values).
    zeno : ZenoReport or None
    chatter : tuple of ChatterEpisode
    final_time : float
    final_state : tuple of float
    final_mode : str
    final_memory : Mapping[str, float]
    stats : ExecutionStats
    resolution : float
        The guaranteed resolution of the run [s]: the largest spacing of the
        uniform samples of the watched functions in any step (step length over
        ``sign_checks + 1``).  Every window longer than this in which a guard,
        the invariant or a stop function is on was seen.  ``0.0`` when nothing
        was watched, or every flow's event was found on a closed form (``closed_form``).
    unresolved : tuple of UnresolvedWindow
        Where a shorter window could not be ruled out at the finest refinement
        (the samples were still closer to zero than the function can move
        between them or than they bend); empty when everything was decided.
        Also reported by a :class:`~hybrid.errors.GuardResolutionWarning`.  At
        most :data:`UNRESOLVED_KEPT` (the first ones).
    """

    system: str
    mode_names: tuple[str, ...]
    state_names: tuple[str, ...]
    segments: tuple[FlowSegment, ...]
    events: tuple[HybridEvent, ...]
    termination: str
    detail: str
    zeno: ZenoReport | None
    chatter: tuple[ChatterEpisode, ...]
    final_time: float
    final_state: tuple[float, ...]
    final_mode: str
    final_memory: Mapping[str, float]
    stats: ExecutionStats
    resolution: float = 0.0
    unresolved: tuple[UnresolvedWindow, ...] = ()

    @property
    def event_times(self) -> np.ndarray:
        """Times of the jumps, shape ``(len(events),)``."""
        return np.array([e.time for e in self.events], dtype=float)

    @property
    def times(self) -> np.ndarray:
        """All step points, jump instants repeated (before and after), shape ``(N,)``."""
        return _readonly(np.concatenate([s.times for s in self.segments]) if self.segments else np.empty(0))

    @property
    def states(self) -> np.ndarray:
        """States at :attr:`times`, shape ``(N, n)``."""
        if not self.segments:
            return _readonly(np.empty((0, len(self.state_names))))
        return _readonly(np.concatenate([s.states for s in self.segments]))

    @property
    def jumps(self) -> np.ndarray:
        """Jump counter of every row of :attr:`times`."""
        if not self.segments:
            return _readonly(np.empty(0, dtype=int))
        return _readonly(np.concatenate([np.full(s.times.size, s.jump, dtype=int) for s in self.segments]))

    @property
    def modes(self) -> tuple[str, ...]:
        """Mode of every row of :attr:`times`."""
        return tuple(s.mode for s in self.segments for _ in range(s.times.size))

    def sample(self, times: Sequence[float]) -> tuple[np.ndarray, tuple[str, ...]]:
        """States and modes at ``times`` (after the jumps of an instant).

        Parameters
        ----------
        times : sequence of float
            Non-decreasing times within ``[t0, final_time]`` [s].

        Returns
        -------
        states : ndarray, shape (len(times), n)
        modes : tuple of str
        """
        t = np.asarray(times, dtype=float)
        if t.size and (t[0] < self.segments[0].t_start - 1e-12 or t[-1] > self.final_time + 1e-12):
            raise ExecutionError(
                f"sample: times span [{t[0]}, {t[-1]}] s, trajectory spans "
                f"[{self.segments[0].t_start}, {self.final_time}] s"
            )
        out = np.empty((t.size, len(self.state_names)))
        modes: list[str] = [""] * t.size
        starts = np.array([s.t_start for s in self.segments])
        index = np.searchsorted(starts, t, side="right") - 1
        index = np.clip(index, 0, len(self.segments) - 1)
        for k in np.unique(index):
            seg = self.segments[int(k)]
            rows = np.nonzero(index == k)[0]
            tt = np.clip(t[rows], seg.t_start, seg.t_end)
            out[rows] = np.asarray(seg(tt)).T.reshape(rows.size, -1)
            for r in rows:
                modes[int(r)] = seg.mode
        return out, tuple(modes)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary (events, termination, diagnostics, work)."""
        return {
            "system": self.system,
            "termination": self.termination,
            "detail": self.detail,
            "final_time": self.final_time,
            "final_mode": self.final_mode,
            "final_state": list(self.final_state),
            "events": [
                {
                    "time": e.time,
                    "jump": e.jump,
                    "transition": e.transition,
                    "source": e.source,
                    "target": e.target,
                    "outranked": list(e.outranked),
                }
                for e in self.events
            ],
            "zeno": None if self.zeno is None else self.zeno.as_dict(),
            "chatter": [c.as_dict() for c in self.chatter],
            "stats": self.stats.as_dict(),
            "resolution": self.resolution,
            "unresolved": [u.as_dict() for u in self.unresolved],
        }


class _LazySolution:
    """A segment's dense output: scipy's :class:`~scipy.integrate.OdeSolution`, built on first use.

    Most segments of a long run are never evaluated between their steps; building
    the ``OdeSolution`` of each costs more than integrating a short segment.
    """

    __slots__ = ("_times", "_interpolants", "_solution")

    def __init__(self, times: list[float], interpolants: list[Any]) -> None:
        self._times, self._interpolants = times, interpolants
        self._solution: OdeSolution | None = None

    @property
    def solution(self) -> OdeSolution:
        """The :class:`~scipy.integrate.OdeSolution` over the segment's steps."""
        if self._solution is None:
            self._solution = OdeSolution(np.array(self._times), self._interpolants)
        return self._solution

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        return self.solution(t)


@dataclass(frozen=True, slots=True)
class _Options:
    """The solver and event settings of one execution (validated by :func:`_validated`)."""

    method: str
    rtol: float
    atol: float
    max_step: float
    event_tol: float
    sign_checks: int
    refine_depth: int
    max_steps: int
    dense: bool
    t_end: float
    closed_form: bool = False


@dataclass(slots=True)
class _SegmentResult:
    segment: FlowSegment
    event: LocatedEvent | None
    on: tuple[int, ...]  # invariant and stop watches on at the event
    watches: tuple[Watch, ...]
    steps: int
    rhs: int
    roots: int
    failure: str | None
    resolution: float = 0.0  # largest spacing of the uniform samples of the watches in a step [s]
    disarmed: frozenset[str] = frozenset()  # crossing guards disarmed at the segment's start
    end: tuple[float, ...] = ()  # the last state, as floats


def _flow_segment(run: ModelCalls, opts: _Options, mode: str, jump: int, t: float, x: tuple[float, ...],
                  memory: Mapping[str, float], steps_before: int, disarmed: frozenset[str]) -> _SegmentResult:
    """Integrate ``mode`` from ``(t, x)`` until a watch switches on, the horizon, or a solver failure.

    ``disarmed``: crossing guards that cannot fire from zero (:func:`hybrid.events.arm_watches`).
    """
    seg_memory = dict(memory)
    watches = run.watches(mode, seg_memory, t, x)
    values = run.evaluator(watches, mode, seg_memory)  # watches: armed below, the same roles and order
    if t < opts.t_end:
        phi_old = values(t, x)
        watches = arm_watches(watches, phi_old, disarmed) if run.crossing_names else watches
    run.last_point = (t, x)
    times, states, interpolants = [t], [x], []
    steps = rhs = roots = 0
    event: LocatedEvent | None = None
    on: tuple[int, ...] = ()
    failure: str | None = None
    refiner = None
    resolution = 0.0
    if t < opts.t_end:
        affine = run.affine(mode, seg_memory) if opts.closed_form else None
        solver = (ClosedFormSolver(affine, t, x, opts.t_end, opts.max_step, bool(watches)) if affine is not None else
                  METHODS[opts.method](run.flow_function(mode, seg_memory), t, np.array(x), opts.t_end,
                                       rtol=opts.rtol, atol=opts.atol, max_step=opts.max_step))
        found = (closed_form_switch(solver, values, watches, phi_old, outgoing=run.outgoing[mode], memory=seg_memory,
                                    invariant=run.invariants[mode], system=run.system, stops=bool(run.stops),
                                    max_step=opts.max_step, event_tol=opts.event_tol,
                                    forms=run.watch_forms(mode, seg_memory) if affine.route[0] == "scalar" else None)
                 if affine is not None and steps_before < opts.max_steps else None)
        if found is not None:  # one piece of the exact solution, its event found on the closed form
            event, on = found.event(watches)
            segment = FlowSegment(
                mode=mode, jump=jump, t_start=t, t_end=found.time, times=_readonly(np.array([t, found.time])),
                states=_readonly(_rows([x, found.state])), memory=tuple(sorted(seg_memory.items())) if seg_memory else (),
                dense=solver.propagator if opts.dense else None)  # the exact solution over the whole segment
            return _SegmentResult(segment=segment, event=event, on=on, watches=watches, steps=1, rhs=0,
                                  roots=found.evaluations, failure=None, disarmed=disarmed, end=found.state)
        want_dense = opts.dense or (opts.sign_checks > 0 and bool(watches))
        if watches and opts.sign_checks and opts.refine_depth:
            rates = [0.0] * len(watches)  # learned afresh in each segment (a mode's time scale is its own)
            refiner = Refiner(values, watches, lambda tt: x, opts.refine_depth, mode, run.unresolved, rates,
                              opts.event_tol, t)
        while solver.status == "running":
            if steps_before + steps >= opts.max_steps:
                failure = (f"more than max_steps = {opts.max_steps} solver steps (at t = {solver.t:.17g} s in "
                           f"mode {mode!r})")
                break
            message = solver.step()
            steps += 1
            if solver.status == "failed":
                failure = f"{opts.method} failed at t = {solver.t:.17g} s in mode {mode!r}, x = {_fmt(solver.y)}: {message}"
                break
            t_old, t_new, y_new = float(solver.t_old), float(solver.t), tuple(solver.y.tolist())
            interp = solver.dense_output() if want_dense else None
            point = point_evaluator(interp) if interp is not None and opts.sign_checks and watches else None
            if watches:
                spacing = (t_new - t_old) / (opts.sign_checks + 1 if point is not None else 1)
                resolution = spacing if spacing > resolution else resolution
                if refiner is not None and point is not None:
                    refiner.point = point
                bracket, phi_old = find_switch(values, watches, t_old, t_new, y_new, phi_old, point,
                                                opts.sign_checks, refiner if point is not None else None)
            else:
                bracket = None
            if bracket is None:
                run.last_point = (t_new, y_new)
                times.append(t_new)
                states.append(y_new)
                if interp is not None:
                    interpolants.append(interp)
                continue
            if interp is None:
                interp = solver.dense_output()
            point = point or point_evaluator(interp)
            event, iterations = locate_event(values, watches, bracket, point, opts.event_tol)
            roots += iterations
            times.append(event.time)
            states.append(event.state)
            interpolants.append(interp)
            on = tuple(k for k in bracket.candidates if watches[k].role != "guard"
                       and is_on(watches[k].kind, event.values[k]))
            break
        rhs = int(getattr(solver, "nfev", 0))
    dense_out = _LazySolution(times, interpolants) if interpolants and opts.dense else None
    if dense_out is not None and isinstance(solver, ClosedFormSolver):
        dense_out = solver.propagator  # the exact solution over the whole segment
    segment = FlowSegment(
        mode=mode, jump=jump, t_start=times[0], t_end=times[-1], times=_readonly(np.array(times)),
        states=_readonly(_rows(states)), memory=tuple(sorted(seg_memory.items())) if seg_memory else (),
        dense=dense_out,
    )
    if refiner is not None:
        run.refinement_evaluations += refiner.evaluations
    return _SegmentResult(segment=segment, event=event, on=on, watches=watches, steps=steps, rhs=rhs, roots=roots,
                          failure=failure, resolution=resolution, disarmed=disarmed, end=tuple([float(c) for c in states[-1]]))


def _resolve(run: ModelCalls, mode: str, t: float, x: tuple[float, ...], memory: Mapping[str, float],
             max_jumps: int, located: _SegmentResult | None = None) -> Instant:
    """The instant at ``t``: :func:`hybrid.instant.settle_instant` on the system's output, guards and jump maps.

    At a located event (``located``) the kernel's first round reuses the guard
    values the search computed at the event and at the bracket's left end
    (the "previous" evaluation of crossing guards) instead of calling the
    guards again; later rounds evaluate them at the post-jump states.  The
    crossing guards still disarmed at the bracket's left end
    (:func:`hybrid.events.still_disarmed`) cannot fire.
    """
    known: dict[int, float] = {}
    v_now: tuple[float, ...] | None = None
    v_left: tuple[float, ...] | None = None
    previous = None
    disarmed: frozenset[str] = frozenset()
    if located is not None and located.event is not None:
        event = located.event
        disarmed = still_disarmed(located.watches, event.left_values, located.disarmed) if located.disarmed else _NONE
        v_now = run.signals(mode, t, x)
        guards, crossing = run.guard_watches(located.watches)
        if crossing:
            v_left = previous = run.signals(mode, event.left_time, event.left_state)
        values, left_values = event.values, event.left_values
        for k, key, sign in guards:
            known[key] = sign * values[k]
            known[-key - 1] = sign * left_values[k]

    first_round = [True]

    def signals(q: str, state: tuple[float, ...]) -> tuple[float, ...]:
        return v_now if (first_round[0] and v_now is not None) else run.signals(q, t, state)

    def guard(tr: Transition, v: Sequence[float], m: Mapping[str, float]) -> float:
        if known and first_round[0]:
            key = id(tr)
            if v is v_now and key in known:
                return known[key]
            if v is v_left and v_left is not None and -key - 1 in known:
                return known[-key - 1]
        return run.guard(tr, v, m, t, x)

    def fire(tr: Transition, state: tuple[float, ...], v: Sequence[float], m: Mapping[str, float]
             ) -> tuple[tuple[float, ...], dict[str, float]]:
        first_round[0] = False
        return run.jump(tr, state, v, m, t)

    return settle_instant(run.outgoing, mode, x, memory, signals=signals, previous=previous, guard=guard,
                          fire=fire, ties="raise", max_jumps=max_jumps, time=t, disarmed=disarmed, where=_where)


def _where(state: tuple[float, ...]) -> str:
    """The state in the kernel's messages."""
    return f"x = {_fmt(state)}"


def _disarmed_after(run: ModelCalls, instant: Instant, located: _SegmentResult) -> frozenset[str]:
    """Crossing guards disarmed for the next flow: those crossed at ``instant`` and those still disarmed before it.

    A crossing guard enabled at the instant's first jump (the winner and the
    outranked) has had its crossing; if the next flow starts on its zero it
    must first go strictly below zero (:func:`hybrid.events.arm_watches`).
    One disarmed before and not yet strictly below stays disarmed.
    """
    if not run.crossing_names:
        return _NONE
    crossed_now = (n for n in instant.jumps[0].enabled if n in run.crossing_names) if instant.jumps else ()
    assert located.event is not None
    return still_disarmed(located.watches, located.event.left_values, located.disarmed).union(crossed_now)


def _landing_error(run: ModelCalls, mode: str, t: float, x: tuple[float, ...], memory: Mapping[str, float],
                   last: str | None) -> ExecutionError | None:
    """An error when the instant ends outside the invariant of its mode (beyond ``invariant_tol``)."""
    inv = run.invariant(mode, run.signals(mode, t, x), memory, t, x)
    if inv >= -run.invariant_tol:
        return None
    how = f"after transition {last!r}" if last else "initially"
    return ExecutionError(
        f"{how}, the state x = {_fmt(x)} at t = {t:.17g} s lies outside the invariant of mode "
        f"{mode!r} ({run.automaton.mode(mode).invariant_text or 'inv'} = {inv:.6g} < 0) and no transition "
        "is enabled there; fix the reset (jump map) or the invariant"
    )


# ---------------------------------------------------------------------- bookkeeping
class _Book:
    """What the driver accumulates: segments, events, the jump counter, work, termination (private)."""

    def __init__(self, zeno_dt: float) -> None:
        self.segments: list[FlowSegment] = []
        self.events: list[HybridEvent] = []
        self.jump_times: list[float] = []
        self.j = 0
        self.steps = self.rhs = self.roots = 0
        self.resolution = 0.0
        self.termination, self.detail = "end_time", ""
        self.zeno_report: ZenoReport | None = None
        self.zeno_dt = zeno_dt

    def add_segment(self, result: _SegmentResult) -> None:
        self.segments.append(result.segment)
        self.steps += result.steps
        self.rhs += result.rhs
        self.roots += result.roots
        self.resolution = max(self.resolution, result.resolution)

    def record(self, t: float, instant: Instant) -> None:
        for n, step in enumerate(instant.jumps):
            self.j += 1
            self.events.append(HybridEvent(
                time=t, jump=self.j, transition=step.transition.name, source=step.source, target=step.target,
                state_before=step.state_before, state_after=step.state_after,
                memory=tuple(sorted(step.memory_after.items())) if step.memory_after else (),
                outranked=step.outranked, instantaneous=n > 0,
            ))
            self.jump_times.append(t)

    def end(self, termination: str, detail: str) -> None:
        self.termination, self.detail = termination, detail

    def point_segment(self, mode: str, t: float, x: tuple[float, ...], memory: Mapping[str, float]) -> None:
        """A zero-length segment carrying the state at ``t`` (jumps after the last flow)."""
        self.segments.append(FlowSegment(
            mode=mode, jump=self.j, t_start=t, t_end=t, times=_readonly(np.array([t])),
            states=_readonly(np.array([x])), memory=tuple(sorted(memory.items())),
        ))

    def accumulation(self) -> ZenoReport | None:
        """A Zeno report when the last jump intervals shrink geometrically below ``zeno_dt``."""
        times = self.jump_times
        if len(times) < _ZENO_WINDOW + 1:
            return None
        d1, d2 = times[-1] - times[-2], times[-2] - times[-3]
        if not (0.0 < d1 < d2) or d1 > self.zeno_dt:
            return None
        est = estimate_zeno(times, window=_ZENO_WINDOW)
        if est is None or not est.accumulating:
            return None
        tail = self.events[-(_ZENO_WINDOW + 1):]
        modes = tuple(dict.fromkeys(m for e in tail for m in (e.source, e.target)))
        names = tuple(dict.fromkeys(e.transition for e in tail))
        return ZenoReport(
            kind="accumulation", zeno_time=est.zeno_time, ratio=est.ratio, jumps=len(self.events), modes=modes,
            transitions=names, last_times=tuple(times[-12:]),
            message=(
                f"jumps accumulate: intervals shrink by r = {est.ratio:.6g} (fit scatter {est.scatter:.2g}), "
                f"last interval {est.last_interval:.3g} s after {len(self.events)} jumps; estimated Zeno time "
                f"t_Z = {est.zeno_time:.15g} s in mode(s) {list(modes)} via {list(names)}"
            ),
        )

    def instantaneous(self, t: float, instant: Instant, max_jumps: int) -> ZenoReport:
        tail = self.events[-max_jumps:]
        return ZenoReport(
            kind="instantaneous", zeno_time=t, ratio=math.nan, jumps=len(self.events),
            modes=tuple(dict.fromkeys(m for e in tail for m in (e.source, e.target))),
            transitions=tuple(dict.fromkeys(e.transition for e in tail)),
            last_times=tuple(self.jump_times[-12:]), message=instant.zeno or "",
        )


def _after_jumps(book: _Book, t: float, max_jumps: int, zeno: str, chatter_window: float | None,
                 chatter_switches: int, stop_on_chatter: bool) -> bool:
    """The run-level checks after an event's jumps; ``True`` when the run ends here."""
    if len(book.events) >= max_jumps:
        book.end("jump_limit", f"{len(book.events)} jumps (max_jumps = {max_jumps}) by t = {t:.17g} s")
        return True
    report = book.accumulation()
    if report is not None and book.zeno_report is None:
        book.zeno_report = report
        if zeno == "raise":
            raise ZenoError(report.message)
        if zeno == "stop":
            book.end("zeno", report.message)
            return True
    if chatter_window is not None and stop_on_chatter:
        recent = find_chatter(book.events[-chatter_switches:], window=chatter_window, min_switches=chatter_switches)
        if recent:
            c = recent[0]
            book.end("chatter", f"chatter between modes {list(c.modes)} via {list(c.transitions)}: {c.switches} "
                     f"switches from t = {c.start:.9g} s to {c.end:.9g} s (shortest dwell {c.shortest_dwell:.3g} s)")
            return True
    return False


def _event_outcome(run: ModelCalls, result: _SegmentResult, mode: str) -> tuple[str, str] | None:
    """A termination decided by the event itself (a stop function reached zero), or ``None``."""
    event = result.event
    assert event is not None
    stops = [result.watches[k].name for k in result.on if result.watches[k].role == "stop"]
    if stops:
        return f"stop:{stops[0]}", f"stop function {stops[0]!r} reached zero at t = {event.time:.17g} s in mode {mode!r}"
    return None


def _deadlock_detail(run: ModelCalls, result: _SegmentResult, mode: str) -> str:
    event = result.event
    assert event is not None
    names = [result.watches[k].name for k in result.on if result.watches[k].role == "invariant"]
    text = run.automaton.mode(mode).invariant_text or (names[0] if names else mode)
    return (f"the flow leaves the invariant of mode {mode!r} ({text}) at t = {event.time:.17g} s, "
            f"x = {_fmt(event.state)}, and no transition is enabled there (deadlock)")


def simulate_continuous(
    system: HybridSystem,
    x0: Sequence[float],
    *,
    duration: float,
    t0: float = 0.0,
    initial_mode: str | None = None,
    initial_memory: Mapping[str, float] | None = None,
    method: str = "RK45",
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_step: float = math.inf,
    event_tol: float = 1e-12,
    sign_checks: int = 3,
    refine_depth: int = 10,
    max_jumps: int = 100_000,
    max_jumps_per_instant: int = MAX_JUMPS_PER_INSTANT,
    max_steps: int = 10_000_000,
    zeno: str = "stop",
    zeno_interval: float | None = None,
    chatter_window: float | None = None,
    chatter_switches: int = 6,
    stop_on_chatter: bool = False,
    stops: Mapping[str, StopFunction] | None = None,
    invariant_tol: float = 1e-9,
    dense: bool = True,
    closed_form: bool = False,
) -> HybridTrajectory:
    """Execute ``system`` from ``(x0, initial_mode)`` for ``duration`` seconds.

    Parameters
    ----------
    system : HybridSystem
    x0 : sequence of float, shape (n,)
        Initial continuous state.
    duration : float
        Length of the time horizon ``> 0`` [s].
    t0 : float
        Initial time [s].
    initial_mode, initial_memory
        Default: the automaton's initial mode and memory.
    method : str
        A key of :data:`METHODS`.
    rtol, atol, max_step : float
        Passed to the scipy solver.
    event_tol : float
        Width of the final event bracket [s] (at least 4 ulp of the time).
    sign_checks : int
        Interior points of every step where the watched functions are also
        evaluated, evenly spaced: a window (an interval where a guard, the
        invariant or a stop function is on) longer than
        ``step / (sign_checks + 1)`` always contains a sample and is found
        (:attr:`HybridTrajectory.resolution` is the largest such spacing of
        the run).  ``0``: the step's end only, as ``solve_ivp`` does (no
        refinement either).
    refine_depth : int
        Shorter windows: where the samples of a function bend towards zero by
        at least their distance from it (second difference >= distance), the
        interval between them is split into 4 at points of the dense output,
        recursively, down to ``refine_depth`` levels (spacing
        ``step / (sign_checks + 1) / 4**refine_depth``; at most
        :data:`~hybrid.events.REFINE_BUDGET` evaluations per step), where the
        extremum is searched (a touch of zero is found).  Bends still
        unresolved there are listed in :attr:`HybridTrajectory.unresolved` and
        reported by one :class:`~hybrid.errors.GuardResolutionWarning`.  ``0``
        disables it.
    max_jumps : int
        Total jumps before termination ``"jump_limit"``.
    max_jumps_per_instant : int
        Jumps allowed at one instant (:data:`hybrid.instant.MAX_JUMPS_PER_INSTANT`
        by default); one more enabled is instantaneous Zeno.
    max_steps : int
        Solver steps before termination ``"solver_failure"`` (never hang).
    zeno : {"stop", "continue", "raise"}
        What to do when jumps accumulate: end the run with termination
        ``"zeno"``, keep going (the report is still filled), or raise
        :class:`~hybrid.errors.ZenoError`.
    zeno_interval : float or None
        Accumulation is declared when the geometric fit of the last
        inter-jump intervals converges and the last interval is shorter than
        this [s]; default ``1e-6 * duration``.
    chatter_window : float or None
        Dwell [s] under which back-and-forth switching counts as chatter;
        ``None`` disables the chatter report.
    chatter_switches : int
        Back-and-forth jumps that make a chatter episode.
    stop_on_chatter : bool
        End the run (termination ``"chatter"``) at the first episode.
    stops : Mapping[str, StopFunction] or None
        Named stop functions; the run ends with termination ``"stop:<name>"``
        at the located time where one becomes ``>= 0``.
    invariant_tol : float
        How far below zero an invariant may be at a jump's landing point
        (rounding of the located event) before the reset is an error.
    dense : bool
        Keep the dense output of every step (for :meth:`HybridTrajectory.sample`).
    closed_form : bool
        ``True``: a mode whose symbolic flow is exactly affine, ``ẋ = A x + b``, is solved in closed form
        (:mod:`hybrid.closed_form`: same event rules and ``event_tol``, no integration error, few steps:
        sample the dense output, the exact solution, for a plot).  ``False`` (default): ``method`` everywhere.

    Returns
    -------
    HybridTrajectory

    Raises
    ------
    ExecutionError
        Bad arguments; user functions that return NaN or the wrong shape;
        non-determinism (equal priorities enabled together); a jump landing
        outside the target mode's invariant with nothing enabled there.
    UserFunctionError
        A user function raised (an :class:`ExecutionError` naming the
        function, the mode, the time and the state, the original chained).
    ZenoError
        With ``zeno="raise"``.
    DivergenceError
        A :class:`~hybrid.errors.NumericalFailure` raised by user code (time,
        mode, cause and the state at the last finite point).

    Warns
    -----
    GuardResolutionWarning
        Once per run, when :attr:`HybridTrajectory.unresolved` is not empty.
    """
    _check_arguments(system, duration=duration, method=method, rtol=rtol, atol=atol, max_step=max_step,
                     event_tol=event_tol, invariant_tol=invariant_tol, zeno=zeno, sign_checks=sign_checks,
                     refine_depth=refine_depth, max_jumps=max_jumps, max_jumps_per_instant=max_jumps_per_instant, max_steps=max_steps,
                     chatter_switches=chatter_switches, chatter_window=chatter_window,
                     closed_form=closed_form)
    mode, x, memory = _initial_state(system, x0, initial_mode, initial_memory)
    opts = _Options(method=method, rtol=rtol, atol=atol, max_step=max_step, event_tol=event_tol,
                    sign_checks=sign_checks, refine_depth=refine_depth, max_steps=max_steps, dense=dense, t_end=float(t0) + float(duration),
                    closed_form=closed_form)
    run = ModelCalls(system, dict(stops or {}), invariant_tol)
    book = _Book(zeno_interval if zeno_interval is not None else 1e-6 * float(duration))
    t = float(t0)
    instant = _resolve(run, mode, t, x, memory, max_jumps_per_instant)
    after_event, disarmed = False, frozenset()
    while True:
        book.record(t, instant)
        mode, x, memory = instant.mode, instant.state, instant.memory
        if instant.zeno is not None:
            book.zeno_report = book.instantaneous(t, instant, max_jumps_per_instant)
            if zeno == "raise":
                raise ZenoError(instant.zeno)
            book.end("zeno", instant.zeno)
            if not book.segments or book.segments[-1].t_end != t or book.segments[-1].mode != mode:
                book.point_segment(mode, t, x, memory)
            break
        error = _landing_error(run, mode, t, x, memory, book.events[-1].transition if book.events else None)
        if error is not None:
            raise error
        if after_event and _after_jumps(book, t, max_jumps, zeno, chatter_window, chatter_switches,
                                                   stop_on_chatter):
            break
        result = _flow_segment(run, opts, mode, book.j, t, x, memory, book.steps, disarmed)
        book.add_segment(result)
        t, x = result.segment.t_end, result.end
        if result.failure is not None:
            book.end("solver_failure", result.failure)
            break
        if result.event is None:
            book.end("end_time", f"reached t = {t:.17g} s")
            if book.segments[-1].jump != book.j:
                book.point_segment(mode, t, x, memory)
            break
        outcome = _event_outcome(run, result, mode) if result.on else None
        if outcome is not None:
            book.end(*outcome)
            break
        x = result.event.state
        instant = _resolve(run, mode, t, x, memory, max_jumps_per_instant, located=result)
        after_event, disarmed = True, _disarmed_after(run, instant, result)
        if not instant.jumps:
            book.end("invariant_violated", _deadlock_detail(run, result, mode))
            break
    chatter = (find_chatter(book.events, window=chatter_window, min_switches=chatter_switches)
               if chatter_window is not None else ())
    if run.unresolved.total:
        warnings.warn(unresolved_message(system.name, run.unresolved), GuardResolutionWarning, stacklevel=2)
    return HybridTrajectory(
        system=system.name, mode_names=system.automaton.mode_names, state_names=system.state_names,
        segments=tuple(book.segments), events=tuple(book.events), termination=book.termination,
        detail=book.detail, zeno=book.zeno_report, chatter=chatter, final_time=t, final_state=x, final_mode=mode,
        final_memory=dict(memory),
        stats=ExecutionStats(steps=book.steps, rhs_evaluations=book.rhs, guard_evaluations=run.guard_evaluations,
                             root_iterations=book.roots, events=len(book.events),
                             refinement_evaluations=run.refinement_evaluations),
        resolution=book.resolution, unresolved=tuple(run.unresolved.items),
    )


def _check_arguments(system: Any, *, duration: float, method: str, rtol: float, atol: float, max_step: float,
                     event_tol: float, invariant_tol: float, zeno: str, sign_checks: int, refine_depth: int,
                     max_jumps: int,
                     max_jumps_per_instant: int, max_steps: int, chatter_switches: int,
                     chatter_window: float | None, closed_form: bool = False) -> None:
    """Raise :class:`ExecutionError` naming the first bad argument of :func:`simulate_continuous`."""
    if not isinstance(system, HybridSystem):
        raise ExecutionError(f"simulate_continuous: system = {system!r}; expected a HybridSystem")
    if method not in METHODS:
        raise ExecutionError(f"simulate_continuous: method = {method!r}; expected one of {sorted(METHODS)}")
    for name, value, positive in (
        ("duration", duration, True), ("rtol", rtol, True), ("atol", atol, True),
        ("event_tol", event_tol, True), ("max_step", max_step, True), ("invariant_tol", invariant_tol, False),
    ):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and value == value
        ok = ok and (value > 0 if positive else value >= 0) and (name == "max_step" or math.isfinite(value))
        if not ok:
            raise ExecutionError(f"simulate_continuous: {name} = {value!r}; expected a {'positive' if positive else 'non-negative'} finite number")
    if not isinstance(closed_form, bool):
        raise ExecutionError(f"simulate_continuous: closed_form = {closed_form!r}; expected True or False")
    if zeno not in ("stop", "continue", "raise"):
        raise ExecutionError(f"simulate_continuous: zeno = {zeno!r}; expected 'stop', 'continue' or 'raise'")
    for name, value, least in (("sign_checks", sign_checks, 0), ("refine_depth", refine_depth, 0),
                               ("max_jumps", max_jumps, 1),
                               ("max_jumps_per_instant", max_jumps_per_instant, 1), ("max_steps", max_steps, 1),
                               ("chatter_switches", chatter_switches, 2)):
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise ExecutionError(f"simulate_continuous: {name} = {value!r}; expected an int >= {least}")
    if chatter_window is not None and not (chatter_window > 0):
        raise ExecutionError(f"simulate_continuous: chatter_window = {chatter_window!r}; expected a positive time [s] or None")


def _initial_state(system: HybridSystem, x0: Sequence[float], initial_mode: str | None,
                   initial_memory: Mapping[str, float] | None) -> tuple[str, tuple[float, ...], dict[str, float]]:
    automaton = system.automaton
    mode = initial_mode or automaton.initial_mode
    automaton.mode(mode)
    memory = automaton.initial_memory()
    if initial_memory:
        unknown = sorted(set(initial_memory) - set(memory))
        if unknown:
            raise ExecutionError(f"simulate_continuous: initial_memory names unknown variable(s) {unknown}")
        memory.update({k: float(v) for k, v in initial_memory.items()})
    try:
        x = tuple(float(c) for c in x0)
    except (TypeError, ValueError):
        raise ExecutionError(f"simulate_continuous: x0 = {x0!r}; expected {system.dimension} real numbers") from None
    if len(x) != system.dimension or any(c != c for c in x):
        raise ExecutionError(
            f"simulate_continuous: x0 = {x0!r}; expected {system.dimension} finite values "
            f"({', '.join(system.state_names)})"
        )
    return mode, x, memory


def _rows(states: list[tuple[float, ...]]) -> np.ndarray:
    """The states as an array of shape ``(k, n)``."""
    out = np.array(states, dtype=float)
    return out if out.ndim == 2 else out.reshape(len(states), -1)


def _readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array
