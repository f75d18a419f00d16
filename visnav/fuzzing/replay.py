"""Replaying a saved counterexample: its example through its property again, with a trace.

:func:`replay` is the supervisor's re-run given to the generic
:func:`analysis.counterexamples.replay_counterexample`: a measurement sequence
through the variant (one trace row per sample) or a scenario through its
closed loop (one row per transition, then the outcome).
"""

from __future__ import annotations

import functools
from typing import Any

from analysis.counterexamples import Replay, TraceRecorder, replay_counterexample

from visnav.fuzzing.counterexamples import Counterexample
from visnav.fuzzing.properties import hypotheses_prefix
from visnav.fuzzing.registry import PROPERTIES, RESPECTING, Property
from visnav.fuzzing.runner import run_supervisor
from visnav.fuzzing.variants import variant_for

__all__ = ["Replay", "replay"]


def _ignore(label: str, value: float) -> None:
    """The observer of a replay (no guided search)."""


def _rerun_signals(prop: Property, cx: Counterexample, record: TraceRecorder) -> None:
    """The sequence through the variant; one row per sample (``k``, channels, ``mode``, µ, ``jumps``)."""
    space = cx.space
    model = variant_for(cx.variant, space)
    steps = run_supervisor(model, space, cx.measurements or ())  # a raise here is the failure found (e.g. a NaN guard)
    if prop.inputs in RESPECTING:
        steps = steps[:hypotheses_prefix(model, space, steps)]
    for s in steps:
        record({
            "k": s.index,
            **{name: value for name, value in zip(space.names, s.measurement)},
            "mode": s.mode,
            "mu_coll": s.mu_coll,
            "mu_occ": s.mu_occ,
            "jumps": tuple(j.transition for j in s.jumps),
        })
    prop.check(model, space, steps, _ignore)


def _rerun_scenario(prop: Property, cx: Counterexample, record: TraceRecorder) -> None:
    """The scenario's closed loop; one row per transition (``t_s``, ``transition``), then the outcome."""
    assert cx.scenario is not None
    run: Any = prop.check(cx.variant, cx.scenario, _ignore)
    for e in run.trace.events:
        record({"t_s": e.time, "transition": e.transition})
    record({
        "outcome": run.outcome, "min_clearance_m": run.metrics.min_clearance_m,
        "termination": run.metrics.termination, "sim_time_s": run.metrics.sim_time_s,
    })


def replay(cx: Counterexample) -> Replay:
    """Run a counterexample's example through its property again.

    Returns
    -------
    Replay
        ``violated``, the message and sample now, and the trace: signal kinds,
        one row per sample (``k``, the measurements by channel, ``mode``,
        ``mu_coll``, ``mu_occ``, ``jumps``; on hypothesis-respecting inputs the
        prefix the property checks); scenarios, one row per transition
        (``t_s``, ``transition``) then a row with the outcome and metrics
        (none when the property fails: the check raises before the run is returned).
    """
    prop = PROPERTIES[cx.property]
    rerun = _rerun_signals if prop.kind in ("signals", "stateful") else _rerun_scenario
    return replay_counterexample(cx, functools.partial(rerun, prop))
