"""The paper's claims as STL requirements: the signal catalogue and the trace of one closed-loop run.

A scenario's ``[[requirements]]`` (``docs/requirements.md``, ``docs/scenarios.md``)
are STL formulas over the signals of :func:`signal_catalogue`; they are parsed
when the scenario is loaded.  :func:`run_trace` turns one run of the sampled
closed loop -- with the resolved supervisor (:func:`visnav.simulation.simulate`)
or with any variant of it (``visnav.fuzzing.closed_loop.simulate_variant``) --
into an :class:`analysis.stl.SignalTrace` on the hybrid time domain, and
:func:`requirement_values` gives the robustness of every requirement on it.

The hybrid time domain
----------------------
A row of :class:`hybrid.SampledTrace` is a sample *after* the supervisor's jumps
of that instant.  At a sample where the supervisor jumped, the trace built here
has one row per mode the instant went through: first the pre-jump row (the
mode, flags and memory before the first jump), then one row after each jump, the
last being the sample's own row.  All these rows share the sample time and the
measurements; the jump counter ``j`` increases by one from row to row, and µ of
each row is the risk of its mode with its memory at these measurements (the
case model's :meth:`~visnav.supervisor.SupervisorModel.risk`).  So "µ_coll is
continuous at every jump" reads
``always[0, T] ((jumps - prev(jumps) > 0.5) implies abs(mu_coll - prev(mu_coll)) <= 1e-9)``.
The input of a pre-jump row is the one held until that instant (the previous
sample's, zero at the start); every other value is the sample's.

Examples
--------
>>> from visnav.scenario import load_scenario
>>> from visnav.simulation import simulate
>>> scenario = load_scenario("paper")
>>> result = simulate(scenario)                                          # doctest: +SKIP
>>> trace = run_trace(scenario, result.trace, result.loop.supervisor)    # doctest: +SKIP
>>> dict(requirement_values(scenario, trace))["no_collision"].robustness  # doctest: +SKIP
0.2608139573173538
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from analysis.verify.requirements import ParsedRequirement, Requirement, parse_requirements
from analysis.stl import SignalTrace

if TYPE_CHECKING:  # annotations only: loading a scenario does not load the executors
    from hybrid import SampledTrace

from visnav.geometry import wrap_angle
from visnav.parameters import Scenario
from visnav.supervisor import (
    COLLISION_PHASES,
    I_D_BORD,
    I_D_NEAREST,
    I_D_OCC,
    I_FIRST_OBSTACLE,
    I_NEAREST,
    I_SIDE,
    OCCLUSION_PHASES,
    SupervisorModel,
    mode_name,
    split_mode,
)

__all__ = [
    "UNBOUNDED",
    "MEMORY",
    "DEMAND_SIGNALS",
    "MemoryView",
    "SIGNAL_TABLE",
    "MODE_LABEL",
    "RequirementValue",
    "signal_descriptions",
    "signal_catalogue",
    "mode_values",
    "run_trace",
    "result_trace",
    "paper_requirements",
    "parsed_requirements",
    "demand_requirements",
    "requirement_values",
]

UNBOUNDED = 1e9
"""Finite stand-in for ``+inf`` (no occluder in view: ``d_occ_px``, ``d_bord_px``; no obstacle: distances).

STL traces hold finite numbers only (:class:`analysis.stl.SignalTrace`); every
guard of the supervisor treats ``inf`` and this value alike (all thresholds are
below 1e3)."""

MEMORY = ("obstacle", "side", "arm_sign", "dL", "d_end", "DL", "D_end")
"""The supervisor's latched memory, exposed as signals (``docs/supervisor.md``)."""

DEMAND_SIGNALS = ("v_demand_mps", "omega_demand_radps", "pan_rate_demand_radps")
"""The demand of the control (19) before clipping (the applied command is ``v_mps``, ``omega_radps``,
``pan_rate_radps``); they differ only in a saturated loop (:func:`demand_requirements`)."""

MODE_LABEL = "mode"
"""The one label of the trace: the supervisor's mode name, ``COLLISION|OCCLUSION``."""

_MEASURED = {
    "d_nearest_m": ("m", "distance from M to the nearest obstacle surface, at the sample (inf -> UNBOUNDED)"),
    "nearest_obstacle": ("-", "index of that obstacle (0 without obstacle)"),
    "bypass_side": ("-", "side the nearest obstacle would be passed on: +1 on the left, -1 on the right"),
    "d_occ_px": ("px", "d_occ: image distance from the target's features to the occluder; 0 while a feature "
                       "is hidden by it, UNBOUNDED without occluder in view"),
    "d_bord_px": ("px", "d_bord: occluder border to the image side opposite the features; 0 once it left "
                        "the image, UNBOUNDED without occluder"),
    "pan_wrapped_rad": ("rad", "pan angle ϑ wrapped to (-π, π] (computed from the state, whatever a variant's "
                               "measurement stage feeds its guards)"),
}
_DERIVED = {
    "d_coll_m": ("m", "distance to the obstacle the collision component reads: the latched one while an "
                      "obstacle is latched (collision phase other than FAR), the nearest one otherwise"),
    "clearance_m": ("m", "smallest distance from M to any obstacle surface along the exact arc from this "
                         "sample to the next (visnav.simulation.dense_clearance, per sample)"),
}
_STATE = {
    "x_m": ("m", "robot reference point M, x"),
    "y_m": ("m", "robot reference point M, y"),
    "theta_rad": ("rad", "heading θ"),
    "pan_rad": ("rad", "pan angle ϑ, not wrapped"),
}
_INPUTS = {
    "v_mps": ("m/s", "linear velocity v applied to the robot: the control (19), clipped to [limits] in a "
                     "saturated loop (the input held from this sample on; before the jumps: the one held "
                     "until this instant)"),
    "omega_radps": ("rad/s", "angular velocity ω of the base, applied (same)"),
    "pan_rate_radps": ("rad/s", "pan rate ϖ, applied (same)"),
    "v_demand_mps": ("m/s", "linear velocity v demanded by the control (19), before any clipping: v_mps in a "
                            "loop that does not clip (held as v_mps)"),
    "omega_demand_radps": ("rad/s", "angular velocity ω demanded by (19) (same)"),
    "pan_rate_demand_radps": ("rad/s", "pan rate ϖ demanded by (19) (same)"),
}
_RISK = {
    "mu_coll": ("-", "collision risk µ_coll of the row's mode, eq. (2) as resolved"),
    "mu_occ": ("-", "occlusion risk µ_occ of the row's mode, eq. (3) as resolved"),
    "avoid": ("-", "flag AVOID of the row's mode (0/1)"),
    "leave": ("-", "flag LEAVE (0/1)"),
    "occlu": ("-", "flag OCCLU (0/1)"),
}
_IMAGE = {
    "feature_error_px": ("px", "‖s − s*‖·f: error of the true features to the goal image"),
    "n_hidden": ("-", "number of target points not visible (occluded or out of the image)"),
    "n_occluded": ("-", "number of target points hidden by an occluder"),
    "reconstructing": ("-", "1 while the features are reconstructed (µ_occ > 0), else 0"),
    "recon_error_px": ("px", "f·max_i ‖(X_i, Y_i) − (X̃_i, Ỹ_i)‖: largest feature reconstruction error over "
                             "the points, 0 while not reconstructing"),
    "depth_error_mm": ("mm", "1000·max_i |z_i − z̃_i|: largest depth reconstruction error, 0 while not "
                             "reconstructing"),
}
_MEMORY = {
    "obstacle": ("-", "memory: index of the latched obstacle (the nearest for a variant that latches none)"),
    "side": ("-", "memory: latched bypass side σ, ±1, 0 when none is latched (the current bypass side for "
                  "a variant that latches none)"),
    "arm_sign": ("-", "memory: sign of ϑ when the LEAVE test was armed, 0 when disarmed"),
    "dL": ("m", "memory: d_coll latched when LEAVE was set, 0 when not latched"),
    "d_end": ("m", "memory: end of the collision release band max(d+, dL + d+ − d0), 0 when not latched"),
    "DL": ("px", "memory: d_occ latched when OCCLU was reset, 0 when not latched"),
    "D_end": ("px", "memory: end of the occlusion release band max(D+, DL + D+ − D0), 0 when not latched"),
}
_CONSTANTS = {
    "d_minus": ("m", "envelope d− (envelopes.d_minus_m)"),
    "d_zero": ("m", "envelope d0 (envelopes.d_zero_m)"),
    "d_plus": ("m", "envelope d+ (envelopes.d_plus_m)"),
    "D_minus": ("px", "envelope D− (envelopes.D_minus_px)"),
    "D_zero": ("px", "envelope D0 (envelopes.D_zero_px)"),
    "D_plus": ("px", "envelope D+ (envelopes.D_plus_px)"),
    "hysteresis": ("m", "detection hysteresis beyond d+ (supervisor.detection_hysteresis_m)"),
    "arm_angle": ("rad", "arming angle of the LEAVE test (supervisor.arm_angle_rad)"),
    "success_tolerance_px": ("px", "feature error below which the task is achieved (success_tolerance_px)"),
    "v_max_mps": ("m/s", "actuator limit on |v| (limits.v_max_mps)"),
    "omega_max_radps": ("rad/s", "actuator limit on |ω| (limits.omega_max_radps)"),
    "pan_rate_max_radps": ("rad/s", "actuator limit on |ϖ| (limits.pan_rate_max_radps)"),
}

SIGNAL_TABLE: Mapping[str, tuple[str, str]] = MappingProxyType({
    **_MEASURED, **_DERIVED, **_STATE, **_INPUTS, **_RISK, **_IMAGE, **_MEMORY, **_CONSTANTS,
})
"""Every signal that does not depend on the number of obstacles: name -> (unit, meaning), in catalogue order.

:func:`signal_descriptions` adds ``d_coll_<i>_m`` per obstacle, and the trace's
built-in ``time`` [s] and ``jumps`` (the jump counter ``j``)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class RequirementValue:
    """A requirement's value on one trace.

    Attributes
    ----------
    name : str
    robustness : float
        Space robustness at the first sample (``> 0``: satisfied with that margin).
    satisfied : bool
        The boolean verdict of the formula.
    """

    name: str
    robustness: float
    satisfied: bool


# ---------------------------------------------------------------------------------------------
# The catalogue
# ---------------------------------------------------------------------------------------------


def _obstacle_signals(scenario: Scenario) -> dict[str, tuple[str, str]]:
    return {
        f"d_coll_{i}_m": ("m", f"distance from M to the surface of obstacle {i} ({o.name!r})")
        for i, o in enumerate(scenario.obstacles)
    }


def signal_descriptions(scenario: Scenario) -> dict[str, tuple[str, str]]:
    """Every signal of :func:`signal_catalogue` with its unit and meaning (for docs and reports).

    The built-in ``time`` and ``jumps`` of every STL trace are included, last.
    """
    out = dict(_MEASURED)
    out.update(_obstacle_signals(scenario))
    for table in (_DERIVED, _STATE, _INPUTS, _RISK, _IMAGE, _MEMORY, _CONSTANTS):
        out.update(table)
    out["time"] = ("s", "sample time t (repeated at a jump: hybrid time (t, j))")
    out["jumps"] = ("-", "jump counter j of the supervisor")
    return out


def mode_values() -> tuple[str, ...]:
    """The supervisor's mode names, the values of the label ``mode`` (a variant's traces may carry others)."""
    return tuple(mode_name(c, o) for c in COLLISION_PHASES for o in OCCLUSION_PHASES)


def signal_catalogue(scenario: Scenario) -> tuple[tuple[str, ...], dict[str, tuple[str, ...]]]:
    """The numeric signals and the labels (with their values) a requirement of ``scenario`` may read.

    Returns
    -------
    signals : tuple of str
        :data:`SIGNAL_TABLE` with one ``d_coll_<i>_m`` per obstacle (``time``
        and ``jumps`` are built into every trace and not listed).
    labels : dict
        ``{"mode": mode names of the supervisor}``.
    """
    names = [*_MEASURED, *_obstacle_signals(scenario)]
    for table in (_DERIVED, _STATE, _INPUTS, _RISK, _IMAGE, _MEMORY, _CONSTANTS):
        names.extend(table)
    return tuple(names), {MODE_LABEL: mode_values()}


def _constants(scenario: Scenario) -> dict[str, float]:
    env, sup, lim = scenario.envelopes, scenario.supervisor, scenario.limits
    return {
        "d_minus": env.d_minus_m, "d_zero": env.d_zero_m, "d_plus": env.d_plus_m,
        "D_minus": env.D_minus_px, "D_zero": env.D_zero_px, "D_plus": env.D_plus_px,
        "hysteresis": sup.detection_hysteresis_m, "arm_angle": sup.arm_angle_rad,
        "success_tolerance_px": scenario.success_tolerance_px,
        "v_max_mps": lim.v_max_mps, "omega_max_radps": lim.omega_max_radps,
        "pan_rate_max_radps": lim.pan_rate_max_radps,
    }


# ---------------------------------------------------------------------------------------------
# The trace on the hybrid time domain
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Rows:
    """Where the rows of the STL trace come from: sample index, and which rows are pre-jump rows."""

    sample: np.ndarray  # (R,) sample index of every row
    post: np.ndarray  # (N,) row of each sample's own (after-jumps) row
    pre: np.ndarray  # (E,) row before event e (in event order)
    state: np.ndarray  # (R,) index into the memory table: 0 initial, e + 1 after event e


def _rows(trace: SampledTrace) -> _Rows:
    n = len(trace.times)
    event_samples = np.fromiter((e.sample for e in trace.events), dtype=np.int64, count=len(trace.events))
    counts = np.bincount(event_samples, minlength=n)[:n]
    width = counts + 1
    start = np.cumsum(width) - width
    post = start + counts
    sample = np.repeat(np.arange(n), width)
    is_post = np.zeros(sample.size, dtype=bool)
    is_post[post] = True
    pre = np.flatnonzero(~is_post)
    state = np.empty(sample.size, dtype=np.int64)
    # after a sample's jumps: every event at or before that sample has fired
    state[post] = np.cumsum(counts)
    state[pre] = np.arange(len(trace.events))  # before event e: the memory after event e - 1
    return _Rows(sample=sample, post=post, pre=pre, state=state)


def _bounded(values: np.ndarray) -> np.ndarray:
    """``±inf`` replaced by ``±UNBOUNDED`` (NaN kept: the trace refuses it, naming the signal)."""
    return np.clip(np.asarray(values, dtype=float), -UNBOUNDED, UNBOUNDED)


MemoryView = Callable[[Sequence[float], Mapping[str, float]], Mapping[str, float]]
"""``view(v, memory) -> memory``: what the controllers read of the supervisor's memory at signals ``v``."""


def _nearest_view(v: Sequence[float], memory: Mapping[str, float]) -> Mapping[str, float]:
    """The memory of a supervisor without latch as the controllers read it: the nearest obstacle, its side."""
    return {**memory, "obstacle": float(v[I_NEAREST]), "side": float(v[I_SIDE])}


def _viewed(
    view: MemoryView, sig: np.ndarray, k: np.ndarray, state: np.ndarray, states: Sequence[Mapping[str, float]]
) -> tuple[np.ndarray, np.ndarray]:
    """``obstacle`` and ``side`` of the view, row by row."""
    obstacle, side = np.empty(k.size), np.empty(k.size)
    for r, (s, m) in enumerate(zip(k, state)):
        seen = view(sig[s], states[m])
        obstacle[r], side[r] = seen.get("obstacle", 0.0), seen.get("side", 0.0)
    return obstacle, side


def _memory_table(
    trace: SampledTrace, model: SupervisorModel, scenario: Scenario
) -> tuple[list[Mapping[str, float]], np.ndarray]:
    """Memory before the first event and after each event, and as a table ``(E + 1, len(MEMORY))``.

    Keys a variant lacks take the resolved automaton's value for "nothing latched" (0), or
    are derived as the resolved automaton derives them (``d_end`` from ``dL``, ``D_end``
    from ``DL``); non-finite values (a variant's "not latched yet") become 0.
    """
    env = scenario.envelopes
    states: list[Mapping[str, float]] = [model.automaton.initial_memory()]
    states += [dict(e.memory) for e in trace.events]
    table = np.zeros((len(states), len(MEMORY)))
    for i, m in enumerate(states):
        row = {key: float(m.get(key, 0.0)) for key in MEMORY}
        row = {k: (x if math.isfinite(x) else 0.0) for k, x in row.items()}
        if "d_end" not in m and row["dL"] != 0.0:
            row["d_end"] = max(env.d_plus_m, row["dL"] + (env.d_plus_m - env.d_zero_m))
        if "D_end" not in m and row["DL"] != 0.0:
            row["D_end"] = max(env.D_plus_px, row["DL"] + (env.D_plus_px - env.D_zero_px))
        table[i] = [row[k] for k in MEMORY]
    return states, table


def _reconstruction_errors(scenario: Scenario, trace: SampledTrace) -> tuple[np.ndarray, np.ndarray]:
    n_points = len(scenario.target.points_m)
    f = scenario.camera.focal_px
    dx = np.stack([trace.record(f"X{i}") - trace.record(f"X{i}_est") for i in range(n_points)], axis=1)
    dy = np.stack([trace.record(f"Y{i}") - trace.record(f"Y{i}_est") for i in range(n_points)], axis=1)
    dz = np.stack([trace.record(f"z{i}") - trace.record(f"z{i}_est") for i in range(n_points)], axis=1)
    on = trace.record("reconstructing") > 0.5
    px = np.where(on, f * np.hypot(dx, dy).max(axis=1), 0.0)
    mm = np.where(on, 1000.0 * np.abs(dz).max(axis=1), 0.0)
    return px, mm


def _latched_phase(mode: str) -> bool:
    """Whether the collision component holds an obstacle in ``mode`` (every phase but FAR)."""
    return split_mode(mode)[0] != "FAR"


def run_trace(
    scenario: Scenario,
    trace: SampledTrace,
    model: SupervisorModel | object,
    *,
    latches_obstacle: bool | None = None,
    memory_view: MemoryView | None = None,
    substeps: int | None = None,
) -> SignalTrace:
    """The signals of :func:`signal_catalogue` along one closed-loop run, on the hybrid time domain.

    Parameters
    ----------
    scenario : Scenario
        The scenario run.
    trace : hybrid.SampledTrace
        The run (:attr:`visnav.simulation.SimulationResult.trace`, or the trace of
        ``visnav.fuzzing.closed_loop.simulate_variant``).
    model : SupervisorModel or supervisor variant
        The supervisor that drove it (``result.loop.supervisor``), or a
        ``visnav.fuzzing.mutants.SupervisorVariant`` (anything with a ``model``): its
        flags and risk give the rows of every mode an instant went through, and a
        variant's ``latches_obstacle`` and ``controller_view`` are the defaults of the two
        arguments below.
    latches_obstacle : bool, optional
        Whether the supervisor latches the avoided obstacle and its side in its memory
        (default: whether its memory has ``obstacle``); otherwise the nearest obstacle
        and the current bypass side are read, as ``VariantLoop`` does.
    memory_view : callable, optional
        ``view(v, memory) -> memory`` the controllers read instead of the memory (a
        variant's ``controller_view``); its ``obstacle`` and ``side`` are the signals of
        those names, and the pre-jump rows' µ reads it.  Default: the memory itself, or the
        view of a supervisor that latches no obstacle.
    substeps : int, optional
        Sub-steps per period of ``clearance_m`` (default
        :data:`visnav.simulation.CLEARANCE_SUBSTEPS`).

    Returns
    -------
    analysis.stl.SignalTrace
        One row per sample, plus one pre-jump row per supervisor jump (module docstring).
    """
    if not isinstance(model, SupervisorModel):  # a variant: its model, latch and controller view
        if latches_obstacle is None:
            latches_obstacle = getattr(model, "latches_obstacle", None)
        if memory_view is None:
            memory_view = getattr(model, "controller_view", None)
        model = model.model  # type: ignore[attr-defined]
    latches = ("obstacle" in model.automaton.initial_memory()) if latches_obstacle is None else latches_obstacle
    view = memory_view if memory_view is not None else (None if latches else _nearest_view)
    rows = _rows(trace)
    modes, signals = _discrete_rows(scenario, trace, model, rows, view)
    signals.update(_measured_rows(scenario, trace, rows, modes, signals["obstacle"], latches, substeps))
    signals.update(_controller_rows(trace, rows))
    signals.update({name: np.full(rows.sample.size, value) for name, value in _constants(scenario).items()})
    jumps = trace.jumps[rows.sample].astype(np.int64)
    jumps[rows.pre] = [e.jump - 1 for e in trace.events]
    signals = {name: _bounded(values) for name, values in signals.items()}
    return SignalTrace(times=trace.times[rows.sample], signals=signals, labels={MODE_LABEL: tuple(modes)},
                       jumps=jumps, termination=run_termination(trace.termination),
                       termination_detail=f"the run stopped on {trace.termination!r} at t = {trace.times[-1]:.6g} s")


FINAL_STOPS = ("success",)
"""Stops of the closed loop that end the run for good: on ``success`` the visual task is achieved and the
robot is stopped at the goal (section V), so the requirements are judged on the run up to there.  Any other
stop (``collision``) ends the run early: a requirement its prefix does not decide is not passed on it."""


def run_termination(termination: str) -> str:
    """The run's end as :class:`analysis.stl.SignalTrace` states it: ``final:success``, ``end_time`` or the stop."""
    return f"final:{termination}" if termination in FINAL_STOPS else termination


def _discrete_rows(
    scenario: Scenario, trace: SampledTrace, model: SupervisorModel, rows: _Rows, view: MemoryView | None
) -> tuple[list[str], dict[str, np.ndarray]]:
    """Mode of every row, and its memory, flags and µ (the risk of that mode at the sample's signals)."""
    k, events, sig = rows.sample, trace.events, trace.signals
    names = [trace.mode_names[int(i)] for i in trace.modes]
    modes = [names[int(s)] for s in k]
    for e, r in zip(events, rows.pre):
        modes[int(r)] = e.source
    states, table = _memory_table(trace, model, scenario)
    out = {key: table[rows.state, i] for i, key in enumerate(MEMORY)}
    if view is not None:
        out["obstacle"], out["side"] = _viewed(view, sig, k, rows.state, states)
    flags = {name: model.flags(name) for name in set(modes)}
    for flag, name in (("AVOID", "avoid"), ("LEAVE", "leave"), ("OCCLU", "occlu")):
        out[name] = np.array([float(flags[m][flag]) for m in modes])
    mu_coll = trace.record("mu_coll")[k].copy()
    mu_occ = trace.record("mu_occ")[k].copy()
    for i, (e, r) in enumerate(zip(events, rows.pre)):  # the last row of an instant: as the controller recorded
        v = sig[e.sample]
        mu_coll[r], mu_occ[r] = model.risk(e.source, v, states[i] if view is None else view(v, states[i]))
    out["mu_coll"], out["mu_occ"] = mu_coll, mu_occ
    return modes, out


def _measured_rows(
    scenario: Scenario, trace: SampledTrace, rows: _Rows, modes: Sequence[str], obstacle: np.ndarray, latches: bool,
    substeps: int | None,
) -> dict[str, np.ndarray]:
    """The sample's measurements on each of its rows, and ``d_coll_m`` (which depends on the row's memory)."""
    from visnav.simulation import CLEARANCE_SUBSTEPS, arc_clearance

    k, sig = rows.sample, trace.signals
    n_obstacles = len(scenario.obstacles)
    distances = sig[:, I_FIRST_OBSTACLE:I_FIRST_OBSTACLE + n_obstacles]
    latched = np.array([latches and _latched_phase(m) for m in modes], dtype=bool)
    if n_obstacles:
        d_latched = distances[k, np.clip(obstacle.astype(np.int64), 0, n_obstacles - 1)]
    else:
        d_latched = sig[k, I_D_NEAREST]
    pan = trace.state("pan_rad")
    wrapped = np.fromiter((wrap_angle(float(p)) for p in pan), dtype=float, count=pan.size)
    recon_px, recon_mm = _reconstruction_errors(scenario, trace)
    clearance = arc_clearance(scenario, trace, CLEARANCE_SUBSTEPS if substeps is None else substeps)
    out = {
        "d_nearest_m": sig[k, I_D_NEAREST],
        "nearest_obstacle": sig[k, I_NEAREST],
        "bypass_side": sig[k, I_SIDE],
        "d_occ_px": sig[k, I_D_OCC],
        "d_bord_px": sig[k, I_D_BORD],
        "pan_wrapped_rad": wrapped[k],
        **{f"d_coll_{i}_m": distances[k, i] for i in range(n_obstacles)},
        "d_coll_m": np.where(latched, d_latched, sig[k, I_D_NEAREST]),
        "clearance_m": clearance[k],
        "x_m": trace.states[k, 0], "y_m": trace.states[k, 1], "theta_rad": trace.states[k, 2], "pan_rad": pan[k],
        "recon_error_px": recon_px[k],
        "depth_error_mm": recon_mm[k],
    }
    for name in ("feature_error_px", "n_hidden", "n_occluded", "reconstructing"):
        out[name] = trace.record(name)[k]
    return out


def _held(values: np.ndarray, rows: _Rows) -> np.ndarray:
    """``values`` (one row per sample) on every row; on a pre-jump row the previous sample's (zero before the first)."""
    k = rows.sample
    out = values[k].copy()
    before = k[rows.pre] - 1
    out[rows.pre] = np.where(before[:, None] >= 0, values[np.maximum(before, 0)], 0.0)
    return out


def _controller_rows(trace: SampledTrace, rows: _Rows) -> dict[str, np.ndarray]:
    """The applied input and the demand; on a pre-jump row the ones held until the instant (zero before the first
    sample).  The demand is the trace's records :data:`visnav.closed_loop.DEMAND_RECORDS` (a saturated loop), or
    else the input itself: a loop without these records applies its demand unclipped."""
    from visnav.closed_loop import DEMAND_RECORDS

    inputs = _held(trace.inputs, rows)
    if all(name in trace.record_names for name in DEMAND_RECORDS):
        demand = _held(np.stack([trace.record(name) for name in DEMAND_RECORDS], axis=1), rows)
    else:
        demand = inputs
    out = {"v_mps": inputs[:, 0], "omega_radps": inputs[:, 1], "pan_rate_radps": inputs[:, 2]}
    out.update({name: demand[:, i].copy() for i, name in enumerate(DEMAND_SIGNALS)})
    return out


def result_trace(result: object) -> SignalTrace:
    """:func:`run_trace` of a :class:`visnav.simulation.SimulationResult` (its scenario, trace and supervisor)."""
    return run_trace(result.scenario, result.trace, result.loop.supervisor)  # type: ignore[attr-defined]


# ---------------------------------------------------------------------------------------------
# The requirements of a scenario
# ---------------------------------------------------------------------------------------------


def paper_requirements(scenario: Scenario) -> tuple[Requirement, ...]:
    """The scenario's requirements (its ``[[requirements]]`` tables; ``paper.toml`` holds the paper's claims)."""
    return tuple(scenario.requirements)


def parsed_requirements(scenario: Scenario) -> tuple[ParsedRequirement, ...]:
    """The scenario's requirements parsed against :func:`signal_catalogue` and ``duration_s`` as horizon.

    Raises
    ------
    analysis.verify.requirements.RequirementError
        As :func:`analysis.verify.requirements.parse_requirements` (a scenario loaded from TOML
        has passed this check already).
    """
    signals, labels = signal_catalogue(scenario)
    return parse_requirements(scenario.requirements, signals=signals, labels=labels, horizon=scenario.duration_s)


def demand_requirements(scenario: Scenario) -> tuple[str, ...]:
    """The names of the scenario's requirements that read the demand (a signal of :data:`DEMAND_SIGNALS`).

    In a loop that does not clip, the demand is the applied command: such a requirement repeats one on
    ``v_mps``, ``omega_radps``, ``pan_rate_radps`` (``demand_within_limits`` is ``controls_within_limits``
    there); it tells something of its own only in a saturated loop.
    """
    return tuple(p.name for p in parsed_requirements(scenario) if p.formula.signals & set(DEMAND_SIGNALS))


def requirement_values(scenario: Scenario, trace: SignalTrace) -> tuple[tuple[str, RequirementValue], ...]:
    """Robustness and verdict of every requirement of ``scenario`` on ``trace``, in file order."""
    out = []
    for parsed in parsed_requirements(scenario):
        rho = float(parsed.formula.robustness(trace))
        out.append((parsed.name, RequirementValue(name=parsed.name, robustness=rho,
                                                  satisfied=bool(parsed.formula.satisfied(trace)))))
    return tuple(out)
