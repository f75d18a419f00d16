"""Falsification: search a verification problem's box for the point that makes a requirement's robustness negative.

The budget is counted in simulations: every distinct point simulated costs
one, whichever requirement it was simulated for (one simulation evaluates
every requirement), and a point met again is taken from the cache.

Methods (:data:`METHODS`)
    ``"guided"`` (the default)
        1. the nominal point;
        2. a space-filling start: scrambled Sobol points under the seed, each followed by a
           surrogate step (a least-squares model of the robustness minimised over the box);
        3. local search, alternating with the rest of the start, the budget allocated in chunks to
           the requirement still holding whose robustness is lowest relative to its spread (and
           falling): local surrogate steps, coordinate moves towards the faces of the box (a compass
           search) and a (1+1) evolution strategy with step-size adaptation, restarted from new
           Sobol points;
        4. a shrink of each counterexample (each coordinate set back to nominal where the
           violation persists).
        :mod:`analysis.verify.falsification_search` has the details.
    ``"whitebox"``
        Projected gradient descent on the robustness, Armijo backtracking, restarts; then the shrink.
        Gradients from the model's sensitivities when the problem gives them (one simulation each,
        from the nominal point on: :mod:`analysis.verify.falsification_gradient`), otherwise by
        central finite differences (a batch of ``2k`` simulations each) after the same start as
        ``"guided"``; the result says which.
    ``"monte-carlo"``
        Independent draws from the parameters' distributions (point ``i``
        depends only on ``(seed, i)``): the baseline, and the one method that
        the campaign executors (process pool, Dask) run in parallel.
    ``"dual-annealing"``
        :func:`scipy.optimize.dual_annealing` on the lowest robustness over the
        requirements not yet falsified (a comparison, ``benchmarks/bench_falsification.py``).

Nothing here prints or writes: :func:`falsify` calls ``on_evaluation`` with every
new :class:`Evaluation` (the application appends them to a journal) and takes
the evaluations of an interrupted run as ``cache`` (resuming replays the same
deterministic search, each point already simulated read from the cache).
"""

from __future__ import annotations

import math
import os
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from hybrid.errors import (DivergenceError, ExecutionError, NumericalFailure, ParameterError, UserFunctionError,
                           ZenoError)

from analysis.stl import FormulaValueError, SignalTrace, TraceError
from analysis.timelimit import TimeLimitExceeded, time_limit
from analysis.verify.falsification_book import BudgetExhausted, Evaluation, Outcome, Search, unit_key
from analysis.verify.verification import InvalidPoint, VerificationProblem

__all__ = [
    "METHODS",
    "PHASES",
    "Runner",
    "BudgetExhausted",
    "STATUSES",
    "FalsificationError",
    "SimulationFailed",
    "Outcome",
    "Evaluation",
    "evaluate",
    "run_end",
    "DEFAULT_TIMEOUT_S",
    "COMPLETE_ENDS",
    "monte_carlo_unit",
    "Search",
    "falsify",
]

METHODS = ("guided", "monte-carlo", "dual-annealing", "whitebox")
PHASES = ("nominal", "start", "surrogate", "local", "gradient", "descent", "shrink", "monte-carlo", "dual-annealing")
"""Where an evaluation comes from (:attr:`Evaluation.phase`)."""
STATUSES = ("ok", "incomplete", "invalid", "diverged", "zeno", "error", "timeout")
"""How a simulation ended.  ``ok``: it covered the horizon (or ended on a stop the problem declares
final) and every requirement was evaluated; ``incomplete``: it ended early without a fault (Zeno,
a deadlock, a jump limit, chatter, a stop condition not declared final, a trace shorter than the
horizon: ``end`` and ``end_time`` say how and when); ``invalid``: outside the problem's hypotheses
(skipped); ``diverged``: the numerics broke down (time, mode, cause in ``detail``); ``zeno``: the
executor raised on too many jumps at one instant; ``error``: the model's own code raised or returned
garbage (``detail`` and ``traceback``); ``timeout``: the simulation ran past its wall-clock limit
(:data:`DEFAULT_TIMEOUT_S`, :mod:`analysis.timelimit`).  On an ``incomplete`` run each requirement is judged on the
trace cut short (:meth:`analysis.stl.Formula.prefix_satisfied`): decided when every continuation
agrees, undecided (``None``) otherwise; never passed on a window that reaches past the end."""

DEFAULT_TIMEOUT_S = 300.0
"""Wall-clock limit of one simulation [s] unless the caller gives another (``None``: none)."""

COMPLETE_ENDS = ("end_time",)
"""Terminations that mean the run covered its horizon; ``final:<reason>`` (a stop the problem declares
final) counts too, and ``None`` (the simulator did not say) when the trace reaches the horizon."""

_FINITE = 1e300

Runner = Callable[[list[tuple[int, tuple[float, ...]]]], Mapping[int, "Outcome"]]
"""Evaluates Monte-Carlo draws ``(index, unit)`` (in parallel) and returns their outcomes by index."""


class FalsificationError(ParameterError):
    """Bad options of a search (budget, method, seed)."""


class SimulationFailed(RuntimeError):
    """The user's simulator raised an unexpected exception; ``traceback`` is its own traceback text."""

    def __init__(self, point: Mapping[str, float], error: BaseException) -> None:
        self.point = dict(point)
        self.traceback = "".join(traceback.format_exception(type(error), error, error.__traceback__))
        super().__init__(f"the simulator failed at {self.point}: {type(error).__name__}: {error}")

    def __reduce__(self):
        return (_failed, (self.point, str(self), self.traceback))


def _failed(point: Mapping[str, float], message: str, text: str) -> SimulationFailed:
    error = SimulationFailed.__new__(SimulationFailed)
    RuntimeError.__init__(error, message)
    error.point, error.traceback = dict(point), text
    return error


def evaluate(problem: VerificationProblem, unit: Sequence[float], timeout_s: float | None = None, *,
             sensitivities: bool = False) -> Outcome:
    """Simulate ``problem`` at unit coordinates ``unit`` and evaluate every requirement.

    The status says how the run ended (:data:`STATUSES`); a run that ended before its horizon is
    judged on its prefix, each requirement decided only when every continuation would agree.
    ``timeout_s`` bounds the simulation's wall-clock time (status ``timeout`` past it).  With
    ``sensitivities`` the run is the problem's simulation with sensitivities
    (:meth:`VerificationProblem.trace_sensitivities`) and the outcome carries each requirement's robustness
    gradient in unit coordinates (:func:`analysis.verify.falsification_gradient.unit_gradients`).

    Raises
    ------
    SimulationFailed
        The simulator returned something else than a :class:`~analysis.stl.SignalTrace`, or a formula
        could not be evaluated on it (a signal missing, a non-finite value).
    """
    point = problem.point(unit)
    pid = os.getpid()
    try:
        with time_limit(timeout_s):
            trace, sens = problem.trace_sensitivities(point) if sensitivities else (problem.trace(point), None)
            _forked(pid)
    except TimeLimitExceeded as error:
        return Outcome(status="timeout", end="timeout",
                       detail=f"the simulation was stopped: {error} (its wall-clock limit; a loop or a sleep in the "
                              "model, or give a longer limit)")
    except InvalidPoint as error:
        return Outcome(status="invalid", detail=str(error))
    except ZenoError as error:
        return Outcome(status="zeno", detail=str(error), end="zeno")
    except (DivergenceError, NumericalFailure) as error:
        return Outcome(status="diverged", detail=str(error), end="diverged")
    except UserFunctionError as error:
        return _model_error(error, error.__cause__ or error)
    except ExecutionError as error:  # a model function returned NaN, a bool, the wrong shape
        return _model_error(error, error)
    except (Exception, SystemExit, GeneratorExit) as error:  # the user's simulator itself raised (or called
        return _model_error(error, error)                    # sys.exit): their traceback is kept
    if not isinstance(trace, SignalTrace):
        error = TypeError(f"simulate(point) returned a {type(trace).__name__}: expected an analysis.stl.SignalTrace "
                          "(build it with SignalTrace(times=..., signals={...}, labels={...}))")
        raise SimulationFailed(point, error)
    try:
        outcome = _judge(problem, trace)
        if sens is None or not outcome.evaluated:
            return outcome
        from analysis.verify.falsification_gradient import unit_gradients

        gradient, how = unit_gradients(problem, unit, trace, sens)
        return replace(outcome, gradient=gradient, gradient_method=how)
    except FormulaValueError as error:  # the formula's own arithmetic (the trace's values are finite)
        raise FalsificationError(f"requirement formula {error.formula!r}", error.value,
                                 "a formula whose arithmetic is finite on every run",
                                 f"{error} at the point {dict(point)}; guard the division or the overflow in the "
                                 "formula") from None
    except TraceError as error:
        raise SimulationFailed(point, error) from error


def _forked(pid: int) -> None:
    """A simulator that forked: its child must not carry on with the search (and write to the journal)."""
    if os.getpid() != pid:
        os._exit(0)


_TRACEBACK_LIMIT = 8000
"""Characters of a model's traceback kept in an outcome (its last lines: where it raised)."""


def _model_error(error: BaseException, original: BaseException) -> Outcome:
    text = "".join(traceback.format_exception(type(original), original, original.__traceback__))
    try:
        message = f"{type(error).__name__}: {error}"
    except Exception:  # an exception whose __str__ raises
        message = f"{type(error).__name__} (its message could not be rendered)"
    return Outcome(status="error", detail=message, end="error", traceback=text[-_TRACEBACK_LIMIT:])


def run_end(problem: VerificationProblem, trace: SignalTrace) -> tuple[bool, str, str]:
    """``(complete, end, why)``: whether ``trace`` covers the problem's horizon, how it ended, and why not.

    Complete: the simulator says ``end_time`` or a final stop (``final:<reason>``) and the trace is not
    shorter than the horizon, or it says nothing and the trace reaches the horizon.
    """
    end_time = float(trace.times[-1])
    start = float(trace.times[0])
    reached = end_time - start >= problem.horizon * (1.0 - 1e-9) - 1e-12
    said = trace.termination
    if said is not None and said.startswith("final:"):
        return True, said, ""
    if reached and (said is None or said in COMPLETE_ENDS):
        return True, said or "end_time", ""
    if said is None or said in COMPLETE_ENDS:
        return False, "short", (f"the trace ends at t = {end_time:.6g} s, before the horizon "
                                f"{start + problem.horizon:.6g} s")
    why = trace.termination_detail or f"the run ended ({said or 'short trace'}) at t = {end_time:.6g} s"
    return False, said or "short", why


def _judge(problem: VerificationProblem, trace: SignalTrace) -> Outcome:
    complete, end, why = run_end(problem, trace)
    rho = tuple(float(r.formula.robustness(trace)) for r in problem.parsed)
    end_time = float(trace.times[-1])
    if complete:
        sat = tuple(bool(r.formula.satisfied(trace)) for r in problem.parsed)
        return Outcome(status="ok", robustness=rho, satisfied=sat, end=end, end_time=end_time)
    sat = tuple(r.formula.prefix_satisfied(trace) for r in problem.parsed)
    status = {"diverged": "diverged", "error": "error"}.get(end, "incomplete")
    return Outcome(status=status, robustness=rho, satisfied=sat, detail=why, end=end, end_time=end_time)


def monte_carlo_unit(problem: VerificationProblem, seed: int, index: int) -> tuple[float, ...]:
    """Unit coordinates of Monte-Carlo draw ``index`` (depends only on ``(seed, index)``)."""
    rng = np.random.default_rng([int(seed), int(index)])
    return tuple(float(p.draw(rng)) for p in problem.parameters)


def _finite(value: float) -> float:
    return max(-_FINITE, min(_FINITE, value)) if not math.isnan(value) else _FINITE


def _record_violations(search: Search, falsified: dict[int, tuple[tuple[float, ...], str]], how: str) -> None:
    for r in range(len(search.problem.requirements)):
        if r not in falsified:
            hits = search.violated(r)
            if hits:
                worst = min(hits, key=lambda e: e.outcome.robustness[r])
                falsified[r] = (worst.unit, how)


def _shrink(search: Search, falsified: dict[int, tuple[tuple[float, ...], str]]) -> None:
    """Set each coordinate of an unshrunk counterexample back to nominal where the violation persists."""
    for r, (unit, how) in sorted(falsified.items()):
        if not any(unit):
            continue
        current = list(unit)
        try:
            for i in range(len(current)):
                if current[i] == 0.0:
                    continue
                trial = current.copy()
                trial[i] = 0.0
                if search.run(trial, "shrink").violates(r):
                    current = trial
        except BudgetExhausted:
            pass
        falsified[r] = (tuple(current), f"{how}, then coordinates reset to nominal")


def _monte_carlo(search: Search, seed: int, runner: Runner | None, chunk: int = 1024) -> None:
    """Draws ``0..budget-1`` in order, generated chunk by chunk (a huge budget allocates nothing ahead)."""
    for first in range(0, search.budget, chunk):
        units = {i: monte_carlo_unit(search.problem, seed, i) for i in range(first, min(first + chunk, search.budget))}
        if runner is not None:
            pending = [(i, u) for i, u in units.items() if unit_key(u) not in search.cache]
            for i, outcome in runner(pending).items():
                search.cache[unit_key(units[i])] = outcome
        for u in units.values():
            try:
                search.run(u, "monte-carlo")
            except BudgetExhausted:
                return


def _dual_annealing(search: Search, seed: int, falsified: Mapping[int, Any]) -> None:
    from scipy.optimize import dual_annealing

    problem = search.problem
    open_ = [r for r in range(len(problem.requirements)) if r not in falsified]

    def objective(u: np.ndarray) -> float:
        e = search.run(np.clip(u, -1.0, 1.0), "dual-annealing")
        if not e.outcome.evaluated:
            return _FINITE
        return min(_finite(e.outcome.robustness[r]) for r in open_)

    try:
        dual_annealing(objective, [(-1.0, 1.0)] * problem.dimension, maxfun=search.budget, seed=seed,
                       no_local_search=False)
    except BudgetExhausted:
        pass


def _check_options(budget: object, method: object, seed: object) -> None:
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < 1:
        raise FalsificationError("budget", budget, "a positive number of simulations", "give budget=200")
    if method not in METHODS:
        raise FalsificationError("method", method, f"one of {', '.join(METHODS)}", "use method='guided'")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise FalsificationError("seed", seed, "a non-negative integer", "give seed=0")


def falsify(
    problem: VerificationProblem,
    *,
    budget: int,
    seed: int = 0,
    method: str = "guided",
    cache: Mapping[tuple[float, ...], Outcome] | None = None,
    on_evaluation: Callable[[Evaluation], None] | None = None,
    runner: Runner | None = None,
    timeout_s: float | None = DEFAULT_TIMEOUT_S,
) -> tuple[Search, dict[int, tuple[tuple[float, ...], str]]]:
    """Search ``problem``'s box with ``budget`` simulations.

    Parameters
    ----------
    budget : int
        Simulations allowed (``>= 1``); the nominal point is the first.
    seed : int
        Seeds the space-filling start, the local search, Monte-Carlo and dual annealing: the same seed,
        the same evaluations.
    method : str
        One of :data:`METHODS`.
    cache : Mapping or None
        Outcomes of points already simulated (a resumed run), keyed by unit coordinates.
    on_evaluation : callable or None
        Receives every new :class:`Evaluation`, in order.
    runner : callable or None
        Evaluates Monte-Carlo draws in parallel (:data:`Runner`), e.g. on a campaign executor;
        draw ``i`` becomes evaluation ``i``.
    timeout_s : float or None
        Wall-clock limit of each simulation [s] (status ``timeout`` past it); ``None``: none.

    Returns
    -------
    search : Search
        Every evaluation, in order.
    falsified : dict
        Requirement index -> (unit point of its counterexample, how it was found and shrunk).
    """
    _check_options(budget, method, seed)
    if timeout_s is not None and (isinstance(timeout_s, bool) or not isinstance(timeout_s, (int, float))
                                  or not math.isfinite(timeout_s) or timeout_s <= 0):
        raise FalsificationError("timeout_s", timeout_s, "a time > 0 [s] or None", "give e.g. timeout_s=60")
    search = Search(problem=problem, budget=budget, evaluator=evaluate, cache=dict(cache or {}),
                    on_evaluation=on_evaluation, timeout_s=timeout_s)
    falsified: dict[int, tuple[tuple[float, ...], str]] = {}
    if method == "monte-carlo":
        _monte_carlo(search, seed, runner)
        _record_violations(search, falsified, "monte-carlo")
        return search, falsified
    search.run((0.0,) * problem.dimension, "nominal")
    _record_violations(search, falsified, "nominal")
    if method == "dual-annealing":
        _dual_annealing(search, seed, falsified)
        _record_violations(search, falsified, "dual-annealing")
        return search, falsified
    from analysis.verify.falsification_search import guided_search, whitebox_search

    (whitebox_search if method == "whitebox" else guided_search)(search, seed, falsified)
    _record_violations(search, falsified, method)
    _shrink(search, falsified)
    return search, falsified
