"""Run a scenario's closed loop, measure it and classify how it ended.

:func:`simulate` returns a :class:`SimulationResult`: the sampled-data trace
and the figures of merit that the CLI prints and the tests check.
:data:`OUTCOMES` is the one vocabulary of how a run ends, used by every study
(campaigns, fuzzing); :func:`classify_run` is its classifier.  Nothing here
prints or writes files.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid import SampledTrace, simulate_sampled

from hybrid.jsonable import to_jsonable

from visnav.closed_loop import ClosedLoop, record_names, robot_plant
from visnav.parameters import Scenario
from visnav.supervisor import SIGNALS, split_mode

__all__ = [
    "SimulationResult",
    "Metrics",
    "simulate",
    "compute_metrics",
    "arc_clearance",
    "dense_clearance",
    "classify_run",
    "without_diagnosis",
    "OUTCOMES",
    "RUN_OUTCOMES",
    "TIMEOUT_OUTCOMES",
    "TARGET_LOST_WINDOW_S",
    "LOOP_TRANSITION_COUNT",
    "CHATTER_WINDOW_S",
    "CLEARANCE_SUBSTEPS",
    "MAX_RUN_SAMPLES",
    "MAX_TRACE_BYTES",
    "TRACE_BYTES_PER_VALUE",
    "RunSize",
    "run_size",
]

OUTCOMES = ("success", "collision", "timeout", "stuck_in_loop", "target_lost", "diverged", "invalid_scenario", "error")
"""How a run ends, in report order: the one outcome vocabulary of every study.

Runs that finished (:func:`classify_run`, :data:`RUN_OUTCOMES`):

``success``
    The task was achieved (feature error below the tolerance) without touching an obstacle.
``collision``
    The exact trajectory reached an obstacle surface (also between samples); wins over any other class.
``timeout``
    The scenario's duration ran out, for no cause diagnosed below.
``stuck_in_loop``
    A timeout in which the heading turned through a full circle, or one supervisor transition fired
    :data:`LOOP_TRANSITION_COUNT` times or more: the robot went round an obstacle or round the mode graph.
``target_lost``
    A timeout that ends with no target point visible during the last :data:`TARGET_LOST_WINDOW_S`.

Runs that did not finish (set by the caller that ran them):

``diverged``
    :class:`hybrid.DivergenceError` (the numerics broke down; the error gives time, mode and cause).
``invalid_scenario``
    The scenario broke a rule of :mod:`visnav.scenario` and was not run.
``error``
    Any other exception.
"""

RUN_OUTCOMES = OUTCOMES[:5]
"""What :func:`classify_run` returns."""

TIMEOUT_OUTCOMES = ("timeout", "stuck_in_loop", "target_lost")
"""The outcomes of runs that used their whole duration (a timeout and its two diagnosed causes)."""

TARGET_LOST_WINDOW_S = 5.0
"""A timeout that ends with no target point visible for this long is ``target_lost`` [s]."""

LOOP_TRANSITION_COUNT = 3
"""A timeout in which one transition fired this many times or more is ``stuck_in_loop``."""

CHATTER_WINDOW_S = 1.0
"""A transition undone by its reverse within this window counts as chatter [s]."""

CLEARANCE_SUBSTEPS = 20
"""Sub-samples per period at which the exact arc is checked for clearance."""

MAX_RUN_SAMPLES = 1_000_000
"""Most samples one run may have, ``floor(duration_s / sampling_period_s) + 1``.

About 30 minutes of simulation at the measured 1.7 ms per sample of the paper scenario
(the paper run: 2,401 samples, 4 s).  :mod:`visnav.scenario` refuses a scenario over it
when it is loaded (``docs/scenarios.md``, "Resource bounds"), and :func:`simulate` passes
it to :func:`hybrid.simulate_sampled` as ``max_samples``."""

MAX_TRACE_BYTES = 500_000_000
"""Most memory [bytes] the trace of one run may take (:func:`run_size`): 500 MB.

A run keeps every sample until it ends, and a run that never reaches its goal runs its
whole duration; the bound is checked before the run starts, so that a long duration
(or a short period) is refused instead of filling the memory."""

TRACE_BYTES_PER_VALUE = 48
"""Memory of one recorded value while a run goes on [bytes]: a Python float in the
executor's rows (24 B) and its reference (8 B), the row tuples and the final numpy
arrays; measured 2.4 kB per sample for the paper scenario's 51-value rows."""


@dataclass(frozen=True, kw_only=True, slots=True)
class RunSize:
    """What one run of a scenario takes before it starts (:func:`run_size`).

    Attributes
    ----------
    samples : int or float
        ``floor(duration_s / sampling_period_s) + 1``; a float above ``2 MAX_RUN_SAMPLES``
        (``inf`` when the ratio overflows).
    row_values : int
        Values recorded per sample: time, jump counter, mode, the 4 states, the
        ``6 + n_obstacles`` supervisor signals, the 3 inputs and the
        ``9 + 6 n_points`` records of :func:`visnav.closed_loop.record_names`.
    trace_bytes : float
        ``samples * row_values * TRACE_BYTES_PER_VALUE``.
    """

    samples: int | float
    row_values: int
    trace_bytes: float

    @property
    def within_limits(self) -> bool:
        """At most :data:`MAX_RUN_SAMPLES` samples and :data:`MAX_TRACE_BYTES` bytes."""
        return self.samples <= MAX_RUN_SAMPLES and self.trace_bytes <= MAX_TRACE_BYTES

    @property
    def max_samples(self) -> int:
        """The most samples a run with rows of this size may have under both limits."""
        return max(1, min(MAX_RUN_SAMPLES, MAX_TRACE_BYTES // (self.row_values * TRACE_BYTES_PER_VALUE)))


def run_size(sampling_period_s: float, duration_s: float, n_points: int, n_obstacles: int) -> RunSize:
    """Samples and trace memory of a run, from the scenario's values alone (nothing is run or allocated).

    Parameters
    ----------
    sampling_period_s, duration_s : float
        Positive and finite [s].
    n_points, n_obstacles : int
        Target points and obstacles of the scenario.

    Examples
    --------
    >>> size = run_size(0.05, 120.0, 4, 2)
    >>> size.samples, size.row_values, size.trace_bytes
    (2401, 51, 5877648)
    """
    ratio = duration_s / sampling_period_s
    samples: int | float = math.floor(ratio + 1e-9) + 1 if ratio < 2.0 * MAX_RUN_SAMPLES else (
        ratio + 1.0 if math.isfinite(ratio) else math.inf)
    row = (3 + len(robot_plant().state_names) + len(SIGNALS) + n_obstacles + len(robot_plant().input_names)
           + len(record_names(n_points)))
    return RunSize(samples=samples, row_values=row, trace_bytes=samples * row * TRACE_BYTES_PER_VALUE)


@dataclass(frozen=True, kw_only=True, slots=True)
class Metrics:
    """Figures of merit of one run (all SI units unless the name says otherwise)."""

    success: bool
    termination: str
    collided: bool
    min_clearance_m: float
    final_feature_error_px: float
    occlusion_duration_s: float
    all_hidden_duration_s: float
    reconstructed_tracking_s: float
    max_reconstruction_error_px: float
    max_depth_error_mm: float
    modes_visited: tuple[str, ...]
    transitions: tuple[dict[str, Any], ...]
    chatter_count: int
    max_abs_input: tuple[float, float, float]
    within_actuator_limits: bool
    max_input_step: tuple[float, float, float]
    max_mu_step: tuple[float, float]
    sim_time_s: float
    steps: int

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (lists instead of tuples, ``None`` for non-finite numbers)."""
        out: dict[str, Any] = {}
        for name in self.__slots__:  # type: ignore[attr-defined]
            value = getattr(self, name)
            out[name] = to_jsonable(value)
        return out


@dataclass(frozen=True, kw_only=True, slots=True)
class SimulationResult:
    """A run: the scenario, the trace, the metrics and the wall-clock time of the loop."""

    scenario: Scenario
    loop: ClosedLoop
    trace: SampledTrace
    metrics: Metrics
    wall_time_s: float


def simulate(scenario: Scenario) -> SimulationResult:
    """Simulate ``scenario``'s closed loop until success, collision or its duration.

    A loaded scenario is within the resource bounds (:func:`run_size`); one built in
    Python and not validated is refused by :func:`hybrid.simulate_sampled` before the run
    starts when it needs more than ``run_size(...).max_samples`` samples.

    Raises
    ------
    hybrid.DivergenceError
        With the time, the mode and the cause, if the numerics break down.
    hybrid.sampled.SampledArgumentError
        A run over the resource bounds (nothing was run).
    """
    loop = ClosedLoop(scenario=scenario)
    size = run_size(scenario.sampling_period_s, scenario.duration_s, len(scenario.target.points_m),
                    len(scenario.obstacles))
    start = time.perf_counter()
    trace = simulate_sampled(
        loop.supervisor.automaton,
        robot_plant(),
        loop,
        scenario.start.as_tuple(),
        period=scenario.sampling_period_s,
        duration=scenario.duration_s,
        stop=loop.stop,
        max_samples=size.max_samples,
    )
    wall = time.perf_counter() - start
    return SimulationResult(
        scenario=scenario, loop=loop, trace=trace, metrics=compute_metrics(scenario, trace), wall_time_s=wall
    )


def arc_clearance(scenario: Scenario, trace: SampledTrace, substeps: int = CLEARANCE_SUBSTEPS) -> np.ndarray:
    """Per sample, the smallest distance to any obstacle surface at the sample and along the exact arc to the next one.

    The exact flow (the arc of ``propagate_pose``) is evaluated ``substeps`` times per
    sampling period, so a minimum is missed by at most ``(v T / substeps)² / (2 R)``.

    Returns
    -------
    ndarray, shape (N,)
        [m]; ``inf`` without obstacles.
    """
    n = len(trace.times)
    if not scenario.obstacles:
        return np.full(n, math.inf)
    centres = np.array([o.center_m for o in scenario.obstacles])
    radii = np.array([o.radius_m for o in scenario.obstacles])
    states, inputs = trace.states[:-1], trace.inputs[:-1]
    # vectorised over samples (rows) and sub-steps (columns)
    tau = trace.period / substeps * np.arange(1, substeps)[None, :]
    v, omega, theta = inputs[:, 0:1], inputs[:, 1:2], states[:, 2:3]
    half = 0.5 * omega * tau
    chord = v * tau * np.sinc(half / np.pi)  # np.sinc(u/π) = sin(u)/u, exact at u = 0
    mid = theta + half
    xs = states[:, 0:1] + chord * np.cos(mid)
    ys = states[:, 1:2] + chord * np.sin(mid)

    def nearest(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return (np.hypot(x[..., None] - centres[:, 0], y[..., None] - centres[:, 1]) - radii).min(axis=-1)

    out = nearest(trace.states[:, 0], trace.states[:, 1])
    if n > 1:
        out[:-1] = np.minimum(out[:-1], nearest(xs, ys).min(axis=1))
    return out


def dense_clearance(scenario: Scenario, trace: SampledTrace, substeps: int = CLEARANCE_SUBSTEPS) -> float:
    """Smallest distance from M to any obstacle surface along the exact trajectory [m] (:func:`arc_clearance`)."""
    return float(arc_clearance(scenario, trace, substeps).min())


def _transitions(trace: SampledTrace) -> tuple[dict[str, Any], ...]:
    return tuple(
        {"t": e.time, "j": e.jump, "transition": e.transition, "from": e.source, "to": e.target}
        for e in trace.events
    )


def _chatter(trace: SampledTrace) -> int:
    """Number of transitions undone by their reverse within :data:`CHATTER_WINDOW_S`."""
    count = 0
    last: dict[tuple[str, str], float] = {}
    for e in trace.events:
        for component in (0, 1):
            a, b = split_mode(e.source)[component], split_mode(e.target)[component]
            if a == b:
                continue
            back = last.get((b, a))
            if back is not None and e.time - back < CHATTER_WINDOW_S:
                count += 1
            last[(a, b)] = e.time
    return count


def compute_metrics(scenario: Scenario, trace: SampledTrace) -> Metrics:
    """The figures of merit of a trace (see :class:`Metrics`)."""
    n_points = len(scenario.target.points_m)
    f = scenario.camera.focal_px
    period = trace.period
    s_true = np.stack([trace.record(f"{c}{i}") for i in range(n_points) for c in ("X", "Y")], axis=1)
    s_est = np.stack([trace.record(f"{c}{i}_est") for i in range(n_points) for c in ("X", "Y")], axis=1)
    z_true = np.stack([trace.record(f"z{i}") for i in range(n_points)], axis=1)
    z_est = np.stack([trace.record(f"z{i}_est") for i in range(n_points)], axis=1)
    hidden = trace.record("n_hidden") > 0
    all_hidden = trace.record("n_hidden") >= n_points
    mu_coll, mu_occ = trace.record("mu_coll"), trace.record("mu_occ")
    feat_err = f * np.linalg.norm(s_true - s_est, axis=1)
    depth_err = 1000.0 * np.linalg.norm(z_true - z_est, axis=1)
    inputs = trace.inputs
    limits = scenario.limits
    max_abs = tuple(float(v) for v in np.abs(inputs).max(axis=0))
    within = (
        max_abs[0] <= limits.v_max_mps and max_abs[1] <= limits.omega_max_radps and max_abs[2] <= limits.pan_rate_max_radps
    )
    steps_u = np.abs(np.diff(inputs, axis=0)).max(axis=0) if len(inputs) > 1 else np.zeros(3)
    steps_mu = (
        (float(np.abs(np.diff(mu_coll)).max()), float(np.abs(np.diff(mu_occ)).max())) if len(mu_coll) > 1 else (0.0, 0.0)
    )
    clearance = dense_clearance(scenario, trace)
    return Metrics(
        success=trace.termination == "success",
        termination=trace.termination,
        collided=clearance <= 0.0,
        min_clearance_m=clearance,
        final_feature_error_px=float(trace.record("feature_error_px")[-1]),
        occlusion_duration_s=float(hidden.sum() * period),
        all_hidden_duration_s=float(all_hidden.sum() * period),
        reconstructed_tracking_s=float(((mu_occ >= 1.0) & (mu_coll >= 1.0)).sum() * period),
        max_reconstruction_error_px=float(feat_err[hidden].max()) if hidden.any() else 0.0,
        max_depth_error_mm=float(depth_err[hidden].max()) if hidden.any() else 0.0,
        modes_visited=trace.visited_modes,
        transitions=_transitions(trace),
        chatter_count=_chatter(trace),
        max_abs_input=max_abs,  # type: ignore[arg-type]
        within_actuator_limits=bool(within),
        max_input_step=tuple(float(v) for v in steps_u),  # type: ignore[arg-type]
        max_mu_step=steps_mu,
        sim_time_s=float(trace.times[-1] - trace.times[0]),
        steps=len(trace.times),
    )


def classify_run(scenario: Scenario, trace: SampledTrace, metrics: Metrics) -> str:
    """How a finished run ended: one of :data:`RUN_OUTCOMES` (meanings in :data:`OUTCOMES`).

    In this order: ``collision`` (the dense clearance reached 0, or the run stopped on a
    collision), ``success``, then a timeout diagnosed as ``target_lost`` (no target point
    visible during the last :data:`TARGET_LOST_WINDOW_S`) or ``stuck_in_loop`` (heading
    range of at least 2π, or one transition fired :data:`LOOP_TRANSITION_COUNT` times),
    else ``timeout``.

    Parameters
    ----------
    scenario : Scenario
        The scenario run (its number of target points).
    trace : hybrid.SampledTrace
        The run's trace (records ``n_hidden``, state ``theta_rad``, events).
    metrics : Metrics
        :func:`compute_metrics` of the trace.

    Examples
    --------
    >>> result = simulate(scenario)                       # doctest: +SKIP
    >>> classify_run(result.scenario, result.trace, result.metrics)  # doctest: +SKIP
    'success'
    """
    if metrics.collided or metrics.termination == "collision":
        return "collision"
    if metrics.termination == "success":
        return "success"
    n_points = len(scenario.target.points_m)
    window = max(1, int(round(TARGET_LOST_WINDOW_S / trace.period)))
    hidden = trace.record("n_hidden")
    if len(hidden) >= window and bool((hidden[-window:] >= n_points).all()):
        return "target_lost"
    theta = trace.state("theta_rad")
    counts: dict[str, int] = {}
    for event in trace.events:
        counts[event.transition] = counts.get(event.transition, 0) + 1
    if float(theta.max() - theta.min()) >= 2.0 * math.pi or (counts and max(counts.values()) >= LOOP_TRANSITION_COUNT):
        return "stuck_in_loop"
    return "timeout"


def without_diagnosis(outcome: str) -> str:
    """``outcome`` with the diagnosed cause of a timeout dropped (``stuck_in_loop``, ``target_lost`` -> ``timeout``).

    For result files whose format predates the diagnosis (campaign format version 1).

    Raises
    ------
    ValueError
        For a name outside :data:`OUTCOMES`.
    """
    if outcome not in OUTCOMES:
        raise ValueError(f"outcome = {outcome!r}: expected one of {', '.join(OUTCOMES)}; fix: classify the run "
                         "with visnav.simulation.classify_run")
    return "timeout" if outcome in TIMEOUT_OUTCOMES else outcome
