"""A supervisor variant in the paper's closed loop: one run, its outcome and its control at every switch.

:func:`simulate_variant` runs a scenario around a variant
(:class:`VariantLoop`, through :func:`hybrid.simulate_sampled`), measures the
largest control jump at a switch and classifies the end of the run
(:func:`classify_outcome`, one of :data:`OUTCOMES`).  The properties on these
runs are in :mod:`visnav.fuzzing.scenario_properties`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from hybrid import Plant, SampledTrace, simulate_sampled

from visnav.closed_loop import ClosedLoop, LoopState, robot_plant
from visnav.fuzzing.mutants import RESOLVED, SupervisorVariant
from visnav.fuzzing.variants import make_variant
from visnav.parameters import Scenario
from visnav.simulation import RUN_OUTCOMES, TARGET_LOST_WINDOW_S, Metrics, classify_run, compute_metrics
from visnav.supervisor import I_NEAREST, I_PAN, I_SIDE

__all__ = [
    "OUTCOMES",
    "TARGET_LOST_WINDOW_S",
    "VariantLoop",
    "ScenarioRun",
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

    The measurement stage passes ϑ unwrapped when the variant says so; a
    variant that does not latch the avoided obstacle is given the nearest one
    and the current bypass side (as the paper reads them at every sample);
    success needs the variant's initial mode (no risk flag) instead of
    ``FAR|CLEAR``.
    """

    variant: SupervisorVariant

    def __post_init__(self) -> None:
        ClosedLoop.__post_init__(self)
        object.__setattr__(self, "supervisor", self.variant.model)

    def measure(self, t: float, x: Sequence[float], c: LoopState) -> tuple[tuple[float, ...], LoopState]:
        """As :meth:`ClosedLoop.measure`, with the raw pan angle for a variant that does not wrap it."""
        v, c = ClosedLoop.measure(self, t, x, c)
        if not self.variant.wrap_pan:
            v = (*v[:I_PAN], float(x[3]), *v[I_PAN + 1:])
        return v, c

    def _view(self, v: Sequence[float], memory: Mapping[str, float]) -> Mapping[str, float]:
        if self.variant.latches_obstacle:
            return memory
        return {**memory, "obstacle": float(v[I_NEAREST]), "side": float(v[I_SIDE])}

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


class _SwitchProbe:
    """Wraps a loop; at every sample whose jumps changed the mode, compares the controls of both modes."""

    def __init__(self, loop: VariantLoop) -> None:
        self.loop = loop
        self.record_names = loop.record_names
        self.previous: tuple[str, Mapping[str, float]] | None = None
        self.worst = 0.0
        self.worst_at: dict[str, Any] = {}

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


def simulate_variant(scenario: Scenario, variant: str = RESOLVED) -> ScenarioRun:
    """Run ``scenario``'s closed loop around a variant and classify the outcome.

    Raises
    ------
    hybrid.DivergenceError
        When the numerics break down (the properties report it).
    """
    model_variant = make_variant(variant, scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    loop = VariantLoop(scenario=scenario, variant=model_variant)
    probe = _SwitchProbe(loop)
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
