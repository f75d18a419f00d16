"""The supervisor on both executors: continuous time, and sampled data as T_e → 0.

:func:`simulate_continuous_time` runs the paper's closed loop with the
controller evaluated continuously and every supervisor event located exactly
(:func:`hybrid.simulate_continuous`).  :func:`sampled_convergence` runs the
sampled-data loop (zero-order hold, period ``T_e``) for a sequence of periods
and measures how its trajectory approaches the continuous-time one: the
largest position and angle deviation on a common time grid, the shift of
every supervisor event, and the observed order (least-squares slope of
``log error`` against ``log T_e``; zero-order hold predicts 1).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid import HybridTrajectory, simulate_continuous
from hybrid.jsonable import to_jsonable

from visnav.closed_loop import ClosedLoop
from visnav.parameters import Scenario
from visnav.simulation import simulate

__all__ = [
    "ContinuousRun",
    "ConvergenceStudy",
    "simulate_continuous_time",
    "sampled_convergence",
    "observed_order",
    "DEFAULT_PERIODS",
]

DEFAULT_PERIODS = (0.05, 0.025, 0.0125, 0.00625, 0.003125)
"""Sampling periods of the convergence study [s] (the paper's 50 ms halved four times)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ContinuousRun:
    """A continuous-time run of a scenario's loop."""

    scenario: Scenario
    loop: ClosedLoop
    trajectory: HybridTrajectory
    wall_time_s: float


def simulate_continuous_time(
    scenario: Scenario,
    *,
    method: str = "DOP853",
    rtol: float = 1e-11,
    atol: float = 1e-12,
    max_step: float = 0.5,
) -> ContinuousRun:
    """Run ``scenario`` with the controller evaluated continuously and exact events.

    Parameters
    ----------
    scenario : Scenario
    method, rtol, atol, max_step
        Passed to :func:`hybrid.simulate_continuous` (``max_step`` bounds the
        step so that a guard entered and left within one step is still seen).

    Returns
    -------
    ContinuousRun
        Ends at ``stop:success``, ``stop:collision`` or the scenario's duration.
    """
    loop = ClosedLoop(scenario=scenario)
    start = time.perf_counter()
    trajectory = simulate_continuous(
        loop.continuous_system(),
        scenario.start.as_tuple(),
        duration=scenario.duration_s,
        method=method,
        rtol=rtol,
        atol=atol,
        max_step=max_step,
        stops=loop.continuous_stops(),
    )
    return ContinuousRun(
        scenario=scenario, loop=loop, trajectory=trajectory, wall_time_s=time.perf_counter() - start
    )


@dataclass(frozen=True, kw_only=True, slots=True)
class ConvergenceStudy:
    """How the sampled-data loop approaches the continuous-time one.

    Attributes
    ----------
    periods : tuple of float
        Sampling periods ``T_e`` [s], decreasing.
    compare_until : float
        End of the common comparison grid [s].
    compare_step : float
        Spacing of the grid [s] (a multiple of every period).
    position_error_m : tuple of float
        Largest ‖(x, y) − (x, y)_ct‖ on the grid, per period [m].
    angle_error_rad : tuple of float
        Largest |θ − θ_ct| or |ϑ − ϑ_ct| on the grid, per period [rad].
    smooth_phase_error_m : tuple of float
        The same position error restricted to the flow before the first
        supervisor event (no switching: the pure zero-order-hold error).
    event_shift_s : tuple of float
        Largest |t_event − t_event,ct| over the supervisor's events, per period
        (``nan`` when the sequence of transitions differs).
    same_transitions : tuple of bool
        Whether each sampled run fires the continuous run's transitions in the same order.
    order : float
        Observed order of ``position_error_m`` (least-squares slope).
    smooth_phase_order : float
        Observed order of ``smooth_phase_error_m``.
    event_shift_order : float
        Observed order of ``event_shift_s``.
    continuous_events : tuple of (float, str)
        The continuous run's events.
    """

    periods: tuple[float, ...]
    compare_until: float
    compare_step: float
    position_error_m: tuple[float, ...]
    angle_error_rad: tuple[float, ...]
    smooth_phase_error_m: tuple[float, ...]
    event_shift_s: tuple[float, ...]
    same_transitions: tuple[bool, ...]
    order: float
    smooth_phase_order: float
    event_shift_order: float
    continuous_events: tuple[tuple[float, str], ...]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: every field, non-finite numbers (an ``event_shift_s`` of ``nan``) as ``None``."""
        return to_jsonable(self)


def observed_order(steps: Sequence[float], errors: Sequence[float]) -> float:
    """Least-squares slope of ``log(error)`` against ``log(step)``.

    Raises
    ------
    ValueError
        Fewer than two points, or a non-positive step or error.
    """
    h = np.asarray(steps, dtype=float)
    e = np.asarray(errors, dtype=float)
    if h.size < 2 or h.size != e.size:
        raise ValueError(f"observed_order: need at least two (step, error) pairs, got {h.size} and {e.size}")
    if np.any(h <= 0) or np.any(~(e > 0)):
        raise ValueError(f"observed_order: steps {h.tolist()} and errors {e.tolist()} must be positive")
    slope, _ = np.polyfit(np.log(h), np.log(e), 1)
    return float(slope)


def sampled_convergence(
    scenario: Scenario,
    periods: Sequence[float] = DEFAULT_PERIODS,
    *,
    compare_step: float | None = None,
    reference: ContinuousRun | None = None,
) -> ConvergenceStudy:
    """Run the sampled-data loop at each period and compare it with continuous time.

    Parameters
    ----------
    scenario : Scenario
        Its ``sampling_period_s`` is replaced by each period in turn.
    periods : sequence of float
        Decreasing periods [s]; each must divide ``compare_step``.
    compare_step : float or None
        Spacing of the comparison grid [s]; default the largest period.
    reference : ContinuousRun or None
        A continuous-time run of the same scenario (computed when absent).

    Returns
    -------
    ConvergenceStudy

    Raises
    ------
    ValueError
        Periods not positive and decreasing, or not dividing the grid step.
    """
    periods = tuple(float(p) for p in periods)
    if len(periods) < 2 or any(p <= 0 for p in periods) or any(a <= b for a, b in zip(periods, periods[1:])):
        raise ValueError(f"sampled_convergence: periods = {periods}; expected at least two positive, decreasing periods [s]")
    step = float(compare_step) if compare_step is not None else periods[0]
    for p in periods:
        ratio = step / p
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(
                f"sampled_convergence: period {p} s does not divide the comparison step {step} s; "
                "use periods that halve the largest one"
            )
    ref = reference if reference is not None else simulate_continuous_time(scenario)
    runs = [simulate(dataclasses.replace(scenario, sampling_period_s=p)) for p in periods]
    end = min([ref.trajectory.final_time] + [float(r.trace.times[-1]) for r in runs])
    grid = np.arange(0.0, end - 0.5 * step, step)
    reference_states, _ = ref.trajectory.sample(grid)
    events = ref.trajectory.events
    first_event = events[0].time if events else end
    smooth = grid < first_event
    position, angle, smooth_error, shift, same = [], [], [], [], []
    for p, run in zip(periods, runs):
        index = np.rint(grid / p).astype(int)
        states = run.trace.states[index]
        d = np.hypot(states[:, 0] - reference_states[:, 0], states[:, 1] - reference_states[:, 1])
        position.append(float(d.max()))
        angle.append(float(np.abs(states[:, 2:] - reference_states[:, 2:]).max()))
        smooth_error.append(float(d[smooth].max()) if smooth.any() else math.nan)
        names = [e.transition for e in run.trace.events]
        matches = names == [e.transition for e in events]
        same.append(matches)
        shift.append(max((abs(a.time - b.time) for a, b in zip(run.trace.events, events)), default=0.0)
                     if matches else math.nan)

    def order_of(values: list[float]) -> float:
        finite = [(p, v) for p, v in zip(periods, values) if v > 0 and math.isfinite(v)]
        return observed_order(*zip(*finite)) if len(finite) >= 2 else math.nan

    return ConvergenceStudy(
        periods=periods,
        compare_until=float(grid[-1]) if grid.size else 0.0,
        compare_step=step,
        position_error_m=tuple(position),
        angle_error_rad=tuple(angle),
        smooth_phase_error_m=tuple(smooth_error),
        event_shift_s=tuple(shift),
        same_transitions=tuple(same),
        order=order_of(position),
        smooth_phase_order=order_of(smooth_error),
        event_shift_order=order_of(shift),
        continuous_events=tuple((e.time, e.transition) for e in events),
    )
