"""Verification problems for the two kinds of system the toolkit executes, and their traces as STL signals.

:func:`trace_from_trajectory`
    A continuous-time execution (:class:`hybrid.HybridTrajectory`) as a
    :class:`analysis.stl.SignalTrace`: every accepted step point (or a uniform
    grid), both sides of every jump as samples (same time, successive jump
    counts), the states, the automaton's variables, the memory and the mode.
:func:`trace_from_sampled`
    A sampled-data run (:class:`hybrid.SampledTrace`): one sample per period,
    and before a sample whose instant had jumps one pre-jump sample per jump.
    Zero-order-hold semantics: at the pre-jump samples the plant's states and
    the measured signals are those of the instant (they are continuous), the
    inputs and the controller's recorded values are the ones held over the
    period that ends there, and the mode is the mode before that jump.
:func:`hybrid_problem`, :func:`sampled_problem`
    A :class:`~analysis.verify.verification.VerificationProblem` from a system (or a
    function building it from the parameters), the box of initial states and
    parameters, a horizon and requirements.  Their simulators are picklable
    module-level objects when the user's functions are.

Examples
--------
>>> from hybrid.examples import thermostat
>>> from analysis.verify.requirements import Requirement
>>> room = thermostat().system
>>> problem = hybrid_problem(
...     name="room", system=room, initial={"T": Parameter(name="T0", low=19.5, high=20.5)},
...     horizon=60.0, requirements=(Requirement(name="comfort", formula="always[0, 60] (abs(T - 20) <= 1.5)"),))
>>> trace = problem.simulate(problem.nominal())
>>> float(problem.parsed[0].formula.robustness(trace)) > 0
True
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from hybrid import HybridSystem
from hybrid.model import initial_mode_of
from hybrid.closed_form import sample_segments
from hybrid.continuous import FlowSegment, HybridTrajectory, simulate_continuous
from hybrid.sampled import Plant, SampledTrace, simulate_sampled

from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verification import Parameter, Proof, ProblemError, VerificationProblem

__all__ = [
    "trace_from_trajectory",
    "trace_from_sampled",
    "HybridSimulation",
    "SampledSimulation",
    "StructuralChecks",
    "hybrid_problem",
    "sampled_problem",
]


def _grid(t_start: float, t_end: float, step_times: np.ndarray, period: float | None) -> np.ndarray | list[float]:
    """The sample times of a segment: its step points, or (``period``) a uniform grid and both ends, as a list."""
    if period is None or t_end <= t_start:
        return step_times
    grid = [t_start]  # t_start + period * i in plain floats: the same IEEE products and sums as numpy's
    for i in range(1, int(math.floor((t_end - t_start) / period)) + 1):
        t = t_start + period * i
        if t < t_end:
            grid.append(t)
    grid.append(t_end)
    return grid


def trace_from_trajectory(
    trajectory: HybridTrajectory,
    *,
    system: HybridSystem | None = None,
    sample_period: float | None = None,
    final_stops: Sequence[str] | None = None,
) -> SignalTrace:
    """The STL trace of a continuous-time execution.

    Parameters
    ----------
    trajectory : HybridTrajectory
        The result of :func:`hybrid.simulate_continuous` (dense output needed for ``sample_period``).
    system : HybridSystem or None
        Adds the automaton's variables (its output map ``v = h(t, x)``) as signals.
    sample_period : float or None
        A uniform grid inside every flow segment [s] instead of the solver's step points
        (each segment's two ends are always samples: the two sides of its jumps).
    final_stops : sequence of str or None
        Given (the stop functions a problem declares final): the trace says how the run ended, as a
        problem's simulator reports it (``termination``, ``termination_detail``); ``None``: not said.

    Returns
    -------
    SignalTrace
        Signals: the state names, the memory names (constant on a segment), the
        system's variables (when given and not states); label ``mode``.
    """
    times: list[np.ndarray | list[float]] = []
    states: list[np.ndarray | None] = []
    modes: list[str] = []
    jumps: list[int] = []
    pieces: list[tuple[int, FlowSegment]] = []  # (chunk, segment): sampled on its grid at the end, together
    memory_chunks: list[Mapping[str, float] | None] = []

    def add(t: np.ndarray | list[float], x: np.ndarray | None, mode: str, jump: int,
            mem: Sequence[tuple[str, float]] | None) -> None:
        times.append(t)
        states.append(x)
        modes.extend([mode] * len(t))
        jumps.append(jump)
        memory_chunks.append(None if mem is None else dict(mem))

    covered = {seg.jump for seg in trajectory.segments}
    events = sorted(trajectory.events, key=lambda e: e.jump)
    if events and events[0].jump - 1 not in covered:  # jumps at the start: the initial state is a sample too
        first = events[0]
        add(np.array([first.time]), np.array([first.state_before], dtype=float), first.source, first.jump - 1, None)
    pending = 0
    for seg in trajectory.segments:
        while pending < len(events) and events[pending].jump < seg.jump:  # jumps with no flow in between
            e = events[pending]
            if e.jump not in covered:
                add(np.array([e.time]), np.array([e.state_after], dtype=float), e.target, e.jump, e.memory)
            pending += 1
        t = _grid(seg.t_start, seg.t_end, seg.times, sample_period)
        if t is not seg.times:
            pieces.append((len(states), seg))
        add(t, seg.states if t is seg.times else None, seg.mode, seg.jump, seg.memory)
    for e in events[pending:]:
        if e.jump not in covered:
            add(np.array([e.time]), np.array([e.state_after], dtype=float), e.target, e.jump, e.memory)
    sizes = [len(t) for t in times]
    flat: list[float] = []
    for t in times:  # one array of all the times (the grids are lists: one conversion, not one per segment)
        flat.extend(t if t.__class__ is list else t.tolist())
    t_all = np.array(flat, dtype=float)
    starts = list(itertools.accumulate(sizes, initial=0))
    grids = [t_all[starts[k]:starts[k + 1]] for k, _ in pieces]
    for (k, _), x in zip(pieces, sample_segments([(seg, t) for (_, seg), t in zip(pieces, grids)])):
        states[k] = x
    x_all = np.concatenate(states)  # type: ignore[arg-type]
    signals = {name: x_all[:, i] for i, name in enumerate(trajectory.state_names)}
    signals.update(_memory_signals(memory_chunks, sizes, exclude=signals))
    if system is not None and system.output is not None:
        values = np.array([system.output(float(ti), tuple(xi)) for ti, xi in zip(t_all, x_all)], dtype=float)
        for i, name in enumerate(system.automaton.variables):
            if name not in signals:
                signals[name] = values[:, i]
    counter = np.repeat(np.array(jumps, dtype=int), sizes)
    said, why = (None, "") if final_stops is None else _end_words(
        float(t_all[-1]), trajectory.termination, getattr(trajectory, "detail", ""), final_stops)
    return SignalTrace(times=t_all, signals=signals, labels={"mode": tuple(modes)}, jumps=counter, termination=said,
                       termination_detail=why)


def _memory_signals(chunks: Sequence[Mapping[str, float] | None], sizes: Sequence[int],
                    exclude: Collection[str]) -> dict[str, np.ndarray]:
    """Memory values per sample; a chunk without its own (the state before jumps at the start) takes the next one's."""
    known = [c for c in chunks if c is not None]
    names = [n for n in (known[0] if known else {}) if n not in exclude]
    filled: list[Mapping[str, float]] = []
    following: Mapping[str, float] = known[0] if known else {}
    for chunk in reversed(chunks):
        following = chunk if chunk is not None else following
        filled.append(following)
    filled.reverse()
    return {n: np.concatenate([np.full(size, float(c.get(n, math.nan))) for c, size in zip(filled, sizes)])
            for n in names}


def _sampled_columns(trace: SampledTrace) -> dict[str, tuple[np.ndarray, bool]]:
    """Name -> (column, held): held columns are chosen by the controller and kept over a period."""
    columns: dict[str, tuple[np.ndarray, bool]] = {}
    groups = (
        (trace.state_names, trace.states, False),
        (trace.variable_names, trace.signals, False),
        (trace.input_names, trace.inputs, True),
        (trace.record_names, trace.records, True),
    )
    for names, values, held in groups:
        for i, name in enumerate(names):
            if name in columns:
                raise ProblemError(
                    "sampled trace signal", name, "names distinct across states, signals, inputs and records",
                    f"rename one of the two {name!r} (the STL trace needs one signal per name)",
                )
            columns[name] = (np.asarray(values[:, i], dtype=float), held)
    return columns


def trace_from_sampled(trace: SampledTrace) -> SignalTrace:
    """The STL trace of a sampled-data run on the hybrid time domain (see the module docstring)."""
    n = trace.times.size
    before: dict[int, list[Any]] = {}
    for e in trace.events:
        before.setdefault(e.sample, []).append(e)
    rows: list[int] = []
    held_rows: list[int] = []
    modes: list[str] = []
    jumps: list[int] = []
    for k in range(n):
        events = before.get(k, ())
        for i, e in enumerate(events):
            rows.append(k)
            held_rows.append(max(k - 1, 0))
            modes.append(e.source)
            jumps.append(int(trace.jumps[k]) - (len(events) - i))
        rows.append(k)
        held_rows.append(k)
        modes.append(trace.mode_names[int(trace.modes[k])])
        jumps.append(int(trace.jumps[k]))
    index = np.asarray(rows, dtype=int)
    held_index = np.asarray(held_rows, dtype=int)
    signals = {
        name: (column[held_index] if held else column[index])
        for name, (column, held) in _sampled_columns(trace).items()
    }
    return SignalTrace(times=trace.times[index], signals=signals, labels={"mode": tuple(modes)},
                       jumps=np.asarray(jumps, dtype=int))


def _ended(trace: SignalTrace, termination: str, detail: str, final_stops: Sequence[str]) -> SignalTrace:
    """``trace`` saying how its run ended: ``end_time``, ``final:<stop>`` for a declared final stop, or the cause."""
    said, why = _end_words(float(trace.times[-1]), termination, detail, final_stops)
    return replace(trace, termination=said, termination_detail=why)


def _end_words(end: float, termination: str, detail: str, final_stops: Sequence[str]) -> tuple[str, str]:
    """``(termination, termination_detail)`` of a trace ending at ``end`` [s] (see :func:`_ended`)."""
    stop = termination[len("stop:"):] if termination.startswith("stop:") else termination
    said = f"final:{stop}" if stop in final_stops else termination
    why = detail or f"the run ended on {termination!r} at t = {end:.6g} s"
    if termination == "zeno":
        why = f"Zeno: the jumps accumulate at t = {end:.9g} s ({detail or 'the jump limit at one instant'})"
    elif termination == "invariant_violated":
        why = f"deadlock at t = {end:.6g} s: the flow leaves the invariant with no transition enabled ({detail})"
    return said, why


def _point_values(point: Mapping[str, float], spec: Mapping[str, Parameter | float]) -> dict[str, float]:
    return {name: (point[v.name] if isinstance(v, Parameter) else float(v)) for name, v in spec.items()}


@dataclass(frozen=True, kw_only=True, slots=True)
class HybridSimulation:
    """The simulator of :func:`hybrid_problem` (picklable when ``build`` is); ``reach_options`` are the problem's
    reachability options (:func:`hybrid_problem`), read again by :func:`analysis.reach.problem.problem_reach`."""

    build: Callable[[Mapping[str, float]], HybridSystem]
    initial: Mapping[str, Parameter | float]
    state_names: tuple[str, ...]
    horizon: float
    initial_mode: str | Callable[[Mapping[str, float]], str] | None = None
    sample_period: float | None = None
    options: Mapping[str, Any] = field(default_factory=dict)
    final_stops: tuple[str, ...] = ()
    reach_options: Mapping[str, Any] = field(default_factory=dict)

    @property
    def fixed_system(self) -> HybridSystem | None:
        """The system when the problem was given it (not a function of the parameters), else None."""
        return self.build.system if isinstance(self.build, _Fixed) else None

    def __call__(self, point: Mapping[str, float]) -> SignalTrace:
        system = self.build(point)
        x0 = _point_values(point, self.initial)
        mode = self.initial_mode(point) if callable(self.initial_mode) else self.initial_mode
        if mode is None and not system.automaton.initial_mode_given:  # the invariants decide it
            x = tuple(float(x0[s]) for s in self.state_names)
            mode = initial_mode_of(system.automaton, system.signals(0.0, x), system.automaton.initial_memory())
        options = dict(self.options)
        if self.sample_period is not None:  # the trace is on its own grid: affine modes in closed form
            options.setdefault("closed_form", True)
        trajectory = simulate_continuous(
            system, tuple(x0[s] for s in self.state_names), duration=self.horizon, initial_mode=mode, **options,
        )
        return trace_from_trajectory(trajectory, system=system, sample_period=self.sample_period,
                                     final_stops=self.final_stops)  # the trace built once, saying how it ended


@dataclass(frozen=True, slots=True)
class StructuralChecks:
    """``() -> hybrid.check.CheckReport`` of a system over a box (graph checks only without one); picklable.

    The modes whose guards, invariants, resets and jump maps are symbolic (:mod:`hybrid.symbolic`)
    are decided by the SMT solver with ``method="auto"`` (their claims PROVEN), the others sampled;
    ``method``, ``rates`` (declared ``|dx_j/dt|`` bounds per second, for the Zeno dwell bounds) and
    ``timeout_s`` (per solver call) and ``budget_s`` (of the sampled searches, ``None`` the default) are
    :func:`hybrid.check`'s.
    """

    model: Any
    box: Any = None
    samples: int = 300
    seed: int = 0
    method: str = "auto"
    rates: Mapping[str, float] | None = None
    timeout_s: float = 5.0
    budget_s: float | None = None

    def __call__(self) -> Any:
        from hybrid.check import SEARCH_BUDGET_S, check

        return check(self.model, self.box, samples=self.samples, seed=self.seed, method=self.method,
                     rates=None if self.rates is None else dict(self.rates), timeout_s=self.timeout_s,
                     budget_s=SEARCH_BUDGET_S if self.budget_s is None else self.budget_s)


@dataclass(frozen=True, slots=True)
class _Fixed:
    system: Any

    def __call__(self, point: Mapping[str, float]) -> Any:
        return self.system


def _box(initial: Mapping[str, Parameter | float], parameters: Sequence[Parameter], states: Sequence[str],
         where: str) -> tuple[Parameter, ...]:
    unknown = sorted(set(initial) - set(states))
    missing = [s for s in states if s not in initial]
    if unknown or missing:
        raise ProblemError(
            f"{where}: initial", dict(initial), f"one entry per state {list(states)}",
            f"give initial={{state: Parameter(...) or a number}}; unknown: {unknown}, missing: {missing}",
        )
    for name, v in initial.items():
        if not isinstance(v, Parameter) and not (isinstance(v, (int, float)) and math.isfinite(v)):
            raise ProblemError(f"{where}: initial[{name!r}]", v, "a Parameter or a finite number",
                               "write Parameter(name=..., low=..., high=...) for a range")
    return (*(v for v in initial.values() if isinstance(v, Parameter)), *parameters)


def _names(values: Sequence[str], what: str, name: str) -> tuple[str, ...]:
    if isinstance(values, str) or not all(isinstance(v, str) and v for v in values):
        raise ProblemError(f"problem {name!r}: {what}", values, "a sequence of non-empty names",
                           f"write {what}=(\"success\",)")
    return tuple(values)


def _builder(system: Any, kind: type, where: str) -> Callable[[Mapping[str, float]], Any]:
    if isinstance(system, kind):
        return _Fixed(system)
    if callable(system):
        return system
    raise ProblemError(f"{where}: system", system, f"a {kind.__name__} or a function point -> {kind.__name__}",
                       "pass the system, or a function building it from the parameters")


def hybrid_problem(
    *,
    name: str,
    system: HybridSystem | Callable[[Mapping[str, float]], HybridSystem],
    initial: Mapping[str, Parameter | float],
    horizon: float,
    requirements: Sequence[Requirement],
    parameters: Sequence[Parameter] = (),
    initial_mode: str | Callable[[Mapping[str, float]], str] | None = None,
    sample_period: float | None = None,
    options: Mapping[str, Any] | None = None,
    description: str = "",
    proofs: Mapping[str, Callable[[], Proof]] | None = None,
    structural: Callable[[], Any] | None = None,
    check_box: Any = None,
    stability: bool | Callable[[], Any] = False,
    stability_section: str | None = None,
    source: str = "",
    final_stops: Sequence[str] = (),
    reach: bool | str = "auto",
    reach_options: Mapping[str, Any] | None = None,
) -> VerificationProblem:
    """A verification problem for a continuous-time hybrid system.

    Parameters
    ----------
    system : HybridSystem or callable
        The system, or ``build(point) -> HybridSystem`` when parameters change it.
    initial : Mapping[str, Parameter or float]
        Every state name -> a :class:`Parameter` (a range searched) or a fixed value.
    parameters : sequence of Parameter
        The model parameters passed to ``build`` (in the point, by name).
    initial_mode : str, callable or None
        The initial mode, or ``mode(point)``; ``None``: the automaton's when it declares one, otherwise the one
        mode whose invariant holds at the point's initial state (an error naming the candidates when none or
        several hold: a definition error of the model, reported as such).
    sample_period : float or None
        Uniform sampling of the flows for the STL trace (:func:`trace_from_trajectory`).  With a sample
        period the trace does not depend on the solver's steps, so the modes whose symbolic flow is exactly
        affine are solved in closed form (``closed_form=True`` of :func:`hybrid.simulate_continuous`, unless
        ``options`` says otherwise); without one the trace is the solver's step points.
    options : Mapping or None
        Keyword arguments of :func:`hybrid.simulate_continuous` (``rtol``, ``max_step``, ``closed_form``, ...).
    structural, check_box :
        The structural checks: a callable, or by default :func:`hybrid.check` of the
        nominal system over ``check_box`` (a :class:`hybrid.Box` of the states, or one per
        mode; ``None``: the graph checks only).
    stability, stability_section :
        ``True`` adds the stability analysis of the nominal system from the nominal initial
        state and mode (:class:`analysis.stability.StabilityChecks`: equilibria against their
        modes, LMI certificates for a common linear equilibrium, or the limit cycle through the
        guard of ``stability_section``, by default the last transition of a run over the
        horizon); a callable is used as it is; ``False``: none.
    final_stops : sequence of str
        Names of stop functions (``options={"stops": ...}``) that end a run for good: the system
        does nothing more after them, so the requirements are judged on the run up to there.
        Any other early end (a stop not named here, Zeno, a deadlock, the jump limit) leaves
        the requirements it does not decide *incomplete* (:data:`analysis.verify.falsification.STATUSES`).
    reach : "auto", True or False
        Verdicts from reachability (:mod:`analysis.reach.verdict`).  ``"auto"``: each requirement of
        the STL safety fragment (``always[0, b]`` over affine state predicates and the mode) gets a
        proof from a zonotope flowpipe over the whole initial box, re-checked independently, when
        the system is a symbolic affine :class:`HybridSystem`; the search still runs as a
        cross-check.  ``True``: the same, and a system reachability cannot read is a
        :class:`ProblemError` (what to write instead).  ``False``: falsification only.  A proof the
        caller passes in ``proofs`` wins over the reachability one.
    reach_options : mapping or None
        ``time_step`` [s] (default: the window's end / 1000) and ``max_jumps`` (default
        ``max(50, 10·⌈end⌉)``) of the flowpipe, ``splits``, and the options of long or hybrid runs
        ``mode_time_steps``, ``jump_cluster``, ``merge_segments`` (:func:`analysis.reach.reach`).
    """
    build = _builder(system, HybridSystem, f"problem {name!r}")
    probe = build({p.name: p.at(0.0) for p in _box(initial, parameters, list(initial), name)})
    if not isinstance(probe, HybridSystem):
        raise ProblemError(f"problem {name!r}: system(point)", probe, "a HybridSystem",
                           "make the builder return hybrid.HybridSystem(...)")
    box = _box(initial, parameters, probe.state_names, f"problem {name!r}")
    a = probe.automaton
    memory = tuple(m.name for m in a.memory)
    variables = tuple(v for v in a.variables if v not in probe.state_names) if probe.output is not None else ()
    simulate = HybridSimulation(build=build, initial=dict(initial), state_names=probe.state_names,
                                horizon=float(horizon), initial_mode=initial_mode, sample_period=sample_period,
                                options=dict(options or {}), final_stops=_names(final_stops, "final_stops", name),
                                reach_options=dict(reach_options or {}))
    problem = VerificationProblem(
        name=name, simulate=simulate, parameters=box, horizon=horizon, requirements=tuple(requirements),
        signals=(*probe.state_names, *memory, *variables), labels={"mode": a.mode_names},
        description=description, proofs=dict(proofs or {}),
        structural=structural or StructuralChecks(model=probe, box=check_box),
        stability=_stability(stability, stability_section, probe, initial, box, initial_mode, float(horizon), name),
        source=source, automaton=a,
    )
    from analysis.reach.verdict import reach_proofs

    fixed = isinstance(system, HybridSystem)
    found = reach_proofs(probe if fixed else build, problem.parsed, initial, reach_mode=reach,
                         initial_mode=initial_mode, builder=not fixed, options=reach_options,
                         where=f"problem {name!r}", box=box)
    if not found:
        return problem
    return replace(problem, proofs={**found, **dict(proofs or {})})


def _stability(stability: bool | Callable[[], Any], section: str | None, probe: HybridSystem,
               initial: Mapping[str, Parameter | float], box: Sequence[Parameter],
               initial_mode: str | Callable[[Mapping[str, float]], str] | None, horizon: float,
               name: str) -> Callable[[], Any] | None:
    """The stability analysis of :func:`hybrid_problem`: ``None``, the user's callable, or the nominal one."""
    from analysis.stability import StabilityChecks

    if stability is False or stability is None:
        return None
    if stability is True:
        nominal = {p.name: p.at(0.0) for p in box}
        x0 = _point_values(nominal, initial)
        mode = initial_mode(nominal) if callable(initial_mode) else initial_mode
        return StabilityChecks(model=probe, initial_state=tuple(float(x0[s]) for s in probe.state_names),
                               initial_mode=mode, horizon=horizon, section=section)
    if callable(stability):
        return stability
    raise ProblemError(f"problem {name!r}: stability", stability, "True, False or a callable () -> StabilityAnalysis",
                       "write stability=True to analyse the nominal system")


@dataclass(frozen=True, kw_only=True, slots=True)
class SampledSimulation:
    """The simulator of :func:`sampled_problem` (picklable when ``build`` is)."""

    build: Callable[[Mapping[str, float]], tuple[Any, Plant, Any]]
    initial: Mapping[str, Parameter | float]
    state_names: tuple[str, ...]
    period: float
    horizon: float
    initial_mode: str | None = None
    final_stops: tuple[str, ...] = ()

    def __call__(self, point: Mapping[str, float]) -> SignalTrace:
        automaton, plant, controller = self.build(point)
        x0 = _point_values(point, self.initial)
        trace = simulate_sampled(automaton, plant, controller, tuple(x0[s] for s in self.state_names),
                                 period=self.period, duration=self.horizon, initial_mode=self.initial_mode)
        return _ended(trace_from_sampled(trace), trace.termination, "", self.final_stops)


def sampled_problem(
    *,
    name: str,
    build: Callable[[Mapping[str, float]], tuple[Any, Plant, Any]],
    initial: Mapping[str, Parameter | float],
    period: float,
    horizon: float,
    requirements: Sequence[Requirement],
    parameters: Sequence[Parameter] = (),
    initial_mode: str | None = None,
    description: str = "",
    proofs: Mapping[str, Callable[[], Proof]] | None = None,
    structural: Callable[[], Any] | None = None,
    source: str = "",
    final_stops: Sequence[str] = (),
) -> VerificationProblem:
    """A verification problem for a sampled-data closed loop (automaton + plant + controller).

    Parameters
    ----------
    build : callable
        ``build(point) -> (automaton, plant, controller)`` (:func:`hybrid.simulate_sampled`'s arguments).
    initial : Mapping[str, Parameter or float]
        Every plant state name -> a range or a fixed value.
    period : float
        Sampling period [s].
    final_stops : sequence of str
        Reasons returned by the controller's stop condition that end a run for good (as
        :func:`hybrid_problem`'s).
    """
    box0 = _box(initial, parameters, list(initial), f"problem {name!r}")
    automaton, plant, controller = build({p.name: p.at(0.0) for p in box0})
    box = _box(initial, parameters, plant.state_names, f"problem {name!r}")
    names = (*plant.state_names, *automaton.variables, *plant.input_names, *controller.record_names)
    simulate = SampledSimulation(build=build, initial=dict(initial), state_names=tuple(plant.state_names),
                                 period=float(period), horizon=float(horizon), initial_mode=initial_mode,
                                 final_stops=_names(final_stops, "final_stops", name))
    return VerificationProblem(
        name=name, simulate=simulate, parameters=box, horizon=horizon, requirements=tuple(requirements),
        signals=tuple(dict.fromkeys(names)), labels={"mode": automaton.mode_names}, description=description,
        proofs=dict(proofs or {}), structural=structural or StructuralChecks(model=automaton), source=source,
        automaton=automaton,
    )
