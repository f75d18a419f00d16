"""A supervisor variant in the paper's closed loop: one run, its outcome and its control at every switch.

:func:`simulate_variant` runs a scenario around a variant
(:class:`VariantLoop`, through :func:`hybrid.simulate_sampled`), measures the
largest control jump at a switch and classifies the end of the run
(:func:`classify_outcome`, one of :data:`OUTCOMES`).  The variant is a
supervisor of :data:`visnav.fuzzing.variants.VARIANTS` or a closed-loop mutant
of :data:`visnav.fuzzing.loop_mutants.LOOP_MUTANTS` (the resolved supervisor
with a mutated estimator or blend).  A :class:`BlendMonitor` passed to it
compares the applied control at every sample with eqs. (18)–(19) recomputed
from the recorded µ and pure controllers computed apart from the loop
(:func:`visnav.fuzzing.blend_reference.blend_reference`); an :class:`EstimatorLog`
keeps what the estimator saw and gave at every sample, even if the run raises.
The properties on these runs are in
:mod:`visnav.fuzzing.scenario_properties` and :mod:`visnav.fuzzing.loop_properties`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from hybrid import Plant, SampledTrace, simulate_sampled
from hybrid.errors import NumericalFailure

from visnav.closed_loop import ClosedLoop, LoopState, robot_plant
from visnav.fuzzing.blend_reference import blend_reference
from visnav.fuzzing.loop_mutants import LOOP_MUTANTS, LoopMutant, PureControls, loop_mutant
from visnav.fuzzing.mutants import RESOLVED, SupervisorVariant
from visnav.fuzzing.variants import make_variant
from visnav.geometry import ImageMeasurement
from visnav.parameters import Scenario
from visnav.simulation import RUN_OUTCOMES, TARGET_LOST_WINDOW_S, Metrics, classify_run, compute_metrics
from visnav.supervisor import I_PAN

__all__ = [
    "OUTCOMES",
    "TARGET_LOST_WINDOW_S",
    "VariantLoop",
    "ScenarioRun",
    "BlendMonitor",
    "EstimatorLog",
    "classify_outcome",
    "simulate_variant",
]

OUTCOMES = RUN_OUTCOMES
"""Classified ends of a closed-loop run: the case's one vocabulary (:data:`visnav.simulation.RUN_OUTCOMES`)."""

classify_outcome = classify_run
"""How a run ended (:func:`visnav.simulation.classify_run`, the case's one classifier)."""

@dataclass(frozen=True, kw_only=True, slots=True)
class VariantLoop(ClosedLoop):
    """The paper's closed loop around a supervisor variant instead of the resolved automaton.

    The measurement stage passes ϑ unwrapped when the variant says so; the
    controllers read the memory through the variant's
    :meth:`~visnav.fuzzing.mutants.SupervisorVariant.controller_memory` (a
    variant that does not latch the avoided obstacle is given the nearest one
    and the current bypass side, as the paper reads them at every sample);
    success needs the variant's initial mode (no risk flag) instead of
    ``FAR|CLEAR``.  With a :class:`~visnav.fuzzing.loop_mutants.LoopMutant`
    the loop builds its estimator, or combines its pure controls by its
    blending law, instead of the resolved ones.
    """

    variant: SupervisorVariant
    mutant: LoopMutant | None = None

    def __post_init__(self) -> None:
        ClosedLoop.__post_init__(self)
        object.__setattr__(self, "supervisor", self.variant.model)

    def initial_state(self, t: float, x: Sequence[float]) -> LoopState:
        """As :meth:`ClosedLoop.initial_state`, with the mutant's estimator if it has one."""
        c = ClosedLoop.initial_state(self, t, x)
        if self.mutant is not None and self.mutant.estimator is not None:
            c.estimator = self.mutant.estimator(self.scenario.robot, self.scenario.estimator)
        return c

    def pure_controls(self, x: Sequence[float], v: Sequence[float], image: ImageMeasurement,
                      features: tuple[tuple[float, float, float], ...],
                      estimated: tuple[tuple[float, float, float], ...], mode: str,
                      memory: Mapping[str, float]) -> PureControls:
        """The resolved loop's pure controls at one sample (:class:`~visnav.fuzzing.loop_mutants.PureControls`)."""
        return PureControls(lambda mu_coll, mu_occ: ClosedLoop.command(
            self, x, v, image, features, estimated, mode, memory, risk=(mu_coll, mu_occ)))

    def command(self, x: Sequence[float], v: Sequence[float], image: ImageMeasurement,
                features: tuple[tuple[float, float, float], ...], estimated: tuple[tuple[float, float, float], ...],
                mode: str, memory: Mapping[str, float], *,
                risk: tuple[float, float] | None = None) -> tuple[float, float, float]:
        """As :meth:`ClosedLoop.command`, or the mutant's blending law of the same pure controls."""
        if self.mutant is None or self.mutant.blend_law is None:
            return ClosedLoop.command(self, x, v, image, features, estimated, mode, memory, risk=risk)
        mu_coll, mu_occ = self.supervisor.risk(mode, v, memory) if risk is None else risk
        return self.mutant.blend_law(mu_coll, mu_occ,
                                     self.pure_controls(x, v, image, features, estimated, mode, memory))

    def measure(self, t: float, x: Sequence[float], c: LoopState) -> tuple[tuple[float, ...], LoopState]:
        """As :meth:`ClosedLoop.measure`, with the raw pan angle for a variant that does not wrap it."""
        v, c = ClosedLoop.measure(self, t, x, c)
        if not self.variant.wrap_pan:
            v = (*v[:I_PAN], float(x[3]), *v[I_PAN + 1:])
        return v, c

    def _view(self, v: Sequence[float], memory: Mapping[str, float]) -> Mapping[str, float]:
        return self.variant.controller_memory(v, memory)

    def control(self, t: float, x: Sequence[float], c: LoopState, v: Sequence[float], mode: str,
                memory: Mapping[str, float]) -> tuple[tuple[float, float, float], LoopState, tuple[float, ...]]:
        """As :meth:`ClosedLoop.control` with the variant's µ."""
        return ClosedLoop.control(self, t, x, c, v, mode, self._view(v, memory))

    def stop(self, t: float, x: Sequence[float], c: LoopState, v: Sequence[float], mode: str,
             memory: Mapping[str, float]) -> str | None:
        """``"collision"``, ``"success"`` (in the variant's initial mode) or ``None``."""
        if c.clearance <= 0.0:
            return "collision"
        if c.feature_error_px <= self.scenario.success_tolerance_px and mode == self.supervisor.automaton.initial_mode:
            return "success"
        return None


@dataclass(kw_only=True, slots=True)
class BlendMonitor:
    """What :func:`simulate_variant` finds when it checks the blend of the controllers at every sample.

    At every sample the control ``(v, ω, ϖ)`` (in a saturated loop the demand, before clipping) is compared with
    eqs. (18)–(19) written out (:func:`~visnav.fuzzing.blend_reference.blend_reference`)
    from the µ the loop recorded and the pure controllers computed apart from
    the loop at the same state, image, features and memory: neither
    :func:`visnav.controllers.blend`, :func:`visnav.controllers.avoidance_control`
    nor the loop's :meth:`~visnav.closed_loop.ClosedLoop.command` takes part.
    Filled in during the run, so it keeps what was seen even if the run later raises.

    Attributes
    ----------
    tolerance : float
        Largest accepted gap (max norm) [m/s, rad/s].
    worst : float
        Largest gap seen.
    worst_at : dict
        Time, mode, µ, applied and recomputed control of the largest gap.
    first_at : dict or None
        The same at the first sample whose gap exceeded ``tolerance``.
    samples : int
        Samples compared.
    skipped : int
        Samples where a pure control could not be computed (it raised).
    """

    tolerance: float = 1e-9
    worst: float = 0.0
    worst_at: dict[str, Any] = field(default_factory=dict)
    first_at: dict[str, Any] | None = None
    samples: int = 0
    skipped: int = 0

    def compare(self, t: float, mode: str, mu: tuple[float, float], applied: Sequence[float],
                reference: Callable[[], Sequence[float]]) -> None:
        """Compare one sample's applied control with ``reference()``, (18)–(19) at the recorded ``mu``."""
        try:
            expected = tuple(reference())
        except NumericalFailure:
            self.skipped += 1
            return
        self.samples += 1
        gap = max(abs(a - b) for a, b in zip(applied, expected))
        if gap > self.worst or (gap > self.tolerance and self.first_at is None):
            at = {"t_s": t, "mode": mode, "mu_coll": mu[0], "mu_occ": mu[1], "applied": [float(a) for a in applied],
                  "eq_18_19": list(expected), "gap": gap}
            if gap > self.worst:
                self.worst, self.worst_at = gap, at
            if gap > self.tolerance and self.first_at is None:
                self.first_at = at


@dataclass(kw_only=True, slots=True)
class EstimatorLog:
    """What the loop's estimator saw and gave at every sample, filled in during the run (kept if it raises).

    The same values as the trace's records (``pan_rad`` state, inputs, ``X0..z{n-1}``,
    their ``_est``, ``reconstructing``, ``n_hidden``), for the samples run so far.

    Attributes
    ----------
    times : list of float
        Sample times [s].
    pan : list of float
        Pan angle at the sample [rad].
    inputs : list of (v, ω, ϖ)
        Joint rates held from the sample on [m/s, rad/s, rad/s].
    true, estimated : list of tuple of (X, Y, z)
        True and estimated features after the sample's control [-, -, m].
    reconstructing : list of bool
        Whether the loop reconstructs after the sample's control.
    hidden : list of int
        Target points not visible at the sample.
    """

    times: list[float] = field(default_factory=list)
    pan: list[float] = field(default_factory=list)
    inputs: list[tuple[float, float, float]] = field(default_factory=list)
    true: list[tuple[tuple[float, float, float], ...]] = field(default_factory=list)
    estimated: list[tuple[tuple[float, float, float], ...]] = field(default_factory=list)
    reconstructing: list[bool] = field(default_factory=list)
    hidden: list[int] = field(default_factory=list)

    def add(self, t: float, pan: float, u: Sequence[float], c: LoopState) -> None:
        """Record one sample (after the loop's control)."""
        self.times.append(float(t))
        self.pan.append(float(pan))
        self.inputs.append((float(u[0]), float(u[1]), float(u[2])))
        self.true.append(tuple(c.true_features))
        self.estimated.append(tuple(c.estimated))
        self.reconstructing.append(bool(c.reconstructing))
        self.hidden.append(0 if c.image is None else sum(1 for vis in c.image.visible if not vis))


class _SwitchProbe:
    """Wraps a loop; at every sample whose jumps changed the mode, compares the controls of both modes.

    With a :class:`BlendMonitor` it also compares, at every sample, the applied control with (18)–(19).
    """

    def __init__(self, loop: VariantLoop, blend_monitor: BlendMonitor | None = None,
                 estimator_log: EstimatorLog | None = None) -> None:
        self.loop = loop
        self.record_names = loop.record_names
        self.previous: tuple[str, Mapping[str, float]] | None = None
        self.worst = 0.0
        self.worst_at: dict[str, Any] = {}
        self.blend_monitor = blend_monitor
        self.estimator_log = estimator_log

    def initial_state(self, t: float, x: Sequence[float]) -> LoopState:
        return self.loop.initial_state(t, x)

    def measure(self, t: float, x: Sequence[float], c: LoopState) -> tuple[tuple[float, ...], LoopState]:
        return self.loop.measure(t, x, c)

    def control(self, t: float, x: Sequence[float], c: LoopState, v: Sequence[float], mode: str,
                memory: Mapping[str, float]) -> tuple[tuple[float, float, float], LoopState, tuple[float, ...]]:
        loop = self.loop
        if self.previous is not None and self.previous[0] != mode and c.image is not None:
            features = tuple(tr if vis else es for tr, es, vis in zip(c.true_features, c.estimated, c.image.visible))
            before_mode, before_memory = self.previous
            u_before = loop.command(x, v, c.image, features, c.estimated, before_mode, loop._view(v, before_memory))
            u_after = loop.command(x, v, c.image, features, c.estimated, mode, loop._view(v, memory))
            gap = max(abs(a - b) for a, b in zip(u_before, u_after))
            if gap > self.worst:
                self.worst = gap
                self.worst_at = {"t_s": t, "from": before_mode, "to": mode, "before": list(u_before),
                                 "after": list(u_after)}
        u, c, row = loop.control(t, x, c, v, mode, memory)
        self.previous = (mode, dict(memory))
        if self.estimator_log is not None:
            self.estimator_log.add(t, x[3], u, c)
        monitor = self.blend_monitor
        if monitor is not None and c.image is not None:
            features = tuple(tr if vis else es for tr, es, vis in zip(c.true_features, c.estimated, c.image.visible))
            image, estimated, view, mu = c.image, c.estimated, loop._view(v, memory), (row[0], row[1])
            pose = (float(x[0]), float(x[1]), float(x[2]), float(x[3]))
            demand = row[-3:] if loop.saturate else u  # (19) before clipping: the demand records, last
            monitor.compare(t, mode, mu, demand,
                            lambda: blend_reference(loop, pose, image, features, estimated, view, mu))
        return u, c, row


@dataclass(frozen=True, kw_only=True, slots=True)
class ScenarioRun:
    """A closed-loop run of a variant: trace, metrics, outcome and the largest control jump at a switch."""

    scenario: Scenario
    variant: str
    trace: SampledTrace
    metrics: Metrics
    outcome: str
    switch_jump: float
    switch_jump_at: Mapping[str, Any]


def simulate_variant(scenario: Scenario, variant: str = RESOLVED, *,
                     blend_monitor: BlendMonitor | None = None,
                     estimator_log: EstimatorLog | None = None, saturate: bool = False) -> ScenarioRun:
    """Run ``scenario``'s closed loop around a variant and classify the outcome.

    Parameters
    ----------
    variant : str
        A supervisor of :data:`~visnav.fuzzing.variants.VARIANTS`; for a
        closed-loop mutant of :data:`~visnav.fuzzing.loop_mutants.LOOP_MUTANTS`
        the resolved supervisor with that mutant's estimator or blend.
    blend_monitor : BlendMonitor or None
        Filled in with the comparison of the applied control with (18)–(19) at every sample.
    estimator_log : EstimatorLog or None
        Filled in with what the estimator saw and gave at every sample.
    saturate : bool
        Clip the applied command to the scenario's ``[limits]``
        (:attr:`visnav.closed_loop.ClosedLoop.saturate`; the demand is recorded too).

    Raises
    ------
    hybrid.DivergenceError
        When the numerics break down (the properties report it).
    """
    model_variant = make_variant(variant, scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    mutant = loop_mutant(variant) if variant in LOOP_MUTANTS else None
    loop = VariantLoop(scenario=scenario, variant=model_variant, mutant=mutant, saturate=saturate)
    probe = _SwitchProbe(loop, blend_monitor, estimator_log)
    plant: Plant = robot_plant()
    trace = simulate_sampled(
        loop.supervisor.automaton, plant, probe, scenario.start.as_tuple(),
        period=scenario.sampling_period_s, duration=scenario.duration_s, stop=loop.stop,
    )
    metrics = compute_metrics(scenario, trace)
    return ScenarioRun(
        scenario=scenario, variant=variant, trace=trace, metrics=metrics,
        outcome=classify_outcome(scenario, trace, metrics), switch_jump=probe.worst,
        switch_jump_at=MappingProxyType(dict(probe.worst_at)),
    )
