"""The saved flowpipe as a schedule for the own-set re-check (:mod:`analysis.reach.recheck_own`).

:func:`schedule_recheck` first checks that the saved JSON is a well-formed, complete run of *this* model from
*this* initial box — the hints it gives are then used, its sets are not:

* one flowpipe per termination and one per jump plus the initial one; every box finite with ``lo <= hi``;
* the first flowpipe is in the initial mode and its entry box holds the initial box (the producer's claim is
  about this box);
* every termination is conclusive and not the jump bound (``"horizon"`` or ``"left_invariant"``);
* every saved jump is a transition of the model (name, source, target) whose ``after`` box holds the exact reset
  image of its ``before`` box (a flowpipe saved for another reset is refused);
* the saved inputs (``B``, ``U``) cover the model's (:func:`analysis.reach.recheck_inputs.checked_inputs`, done
  by the caller).

It then runs :func:`~analysis.reach.recheck_own.own_recheck` with the schedule: the step per mode
(``time_step`` and ``schedule.mode_time_steps``), the jump clustering (``schedule.jump_cluster``) and the jump
bound (``max_jumps``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from fractions import Fraction
from typing import Any

from .recheck_own import OwnFailure, OwnOutcome, own_recheck

__all__ = ["schedule_recheck", "OWN_PARTS"]

OWN_PARTS = ("the saved flowpipe as a schedule only (well-formed, this model's transitions and resets, complete)",
             "own sets per step: e^(A step) enclosed in outward-rounded intervals, zonotopes without wrapping, "
             "tubes with the interpolation error", "own guard intersections, reset images and chaining",
             "no deadlock on the reached part of each invariant face or at entries",
             "requirement atoms on the own sets, compared in exact rationals")

Box = list[tuple[Fraction, Fraction]]


def _box(pair: Sequence[Sequence[float]], what: str) -> Box:
    lo, hi = pair
    if len(lo) != len(hi) or not all(math.isfinite(a) and math.isfinite(b) and a <= b for a, b in zip(lo, hi)):
        raise OwnFailure(f"{what}: the saved box is malformed or empty (lo <= hi, finite)")
    return [(Fraction(a), Fraction(b)) for a, b in zip(lo, hi)]


def _check_saved(data: Mapping[str, Any], model: Any, initial: Box, initial_mode: str) -> None:
    segments, jumps, ends = data["segments"], data["jumps"], data["terminations"]
    if not segments or not segments[0]["entry"]:
        raise OwnFailure("chaining: the first saved segment is not an entry segment")
    pipes = sum(1 for s in segments if s["entry"])
    if pipes != len(ends) or pipes != len(jumps) + 1:
        raise OwnFailure(f"chaining: {pipes} flowpipes, {len(ends)} terminations and {len(jumps)} jumps do not match "
                         "(one flowpipe per termination, one per jump plus the initial one)")
    for i, s in enumerate(segments):
        box = _box(s["box"], f"segments: saved segment {i}")
        if i == 0 and (s["mode"] != initial_mode or not all(a <= lo and hi <= b for (lo, hi), (a, b)
                                                             in zip(initial, box))):
            raise OwnFailure("chaining: the saved flowpipe's first entry does not hold the initial box in the initial "
                             "mode (it was computed from another start)")
    for i, end in enumerate(ends):
        if end["reason"] not in ("horizon", "left_invariant"):
            raise OwnFailure(f"ends: flowpipe {i} ended with {end['reason']!r}: the flowpipe does not cover every "
                             "behaviour (a jump bound or a limit); nothing is proven")
    for j, jump in enumerate(jumps):
        t = next((t for t in model.transitions if t.name == jump["transition"]), None)
        if t is None or t.source != jump["source"] or t.target != jump["target"]:
            raise OwnFailure(f"jumps: jump {j}: {jump['transition']!r} from {jump['source']!r} to {jump['target']!r} "
                             "is not a transition of the system")
        before, after = _box(jump["before"], f"jumps: jump {j}"), _box(jump["after"], f"jumps: jump {j}")
        for row, off, (lo, hi) in zip(t.r_matrix, t.r_offset, after):
            top = sum((max(a * l, a * h) for a, (l, h) in zip(row, before) if a), Fraction(0)) + off
            bottom = sum((min(a * l, a * h) for a, (l, h) in zip(row, before) if a), Fraction(0)) + off
            if bottom < lo or top > hi:
                raise OwnFailure(f"jumps: jump {j} ({t.name}): the reset image of the box before is not inside the "
                                 "box after (a flowpipe of another reset)")


def schedule_recheck(data: Mapping[str, Any], model: Any, initial: Box, initial_mode: str, fragment: Any,
                     inputs: Mapping[str, Any]) -> OwnOutcome:
    """Check the saved JSON as a schedule (module docstring) and re-check on own sets; raises :class:`OwnFailure`."""
    _check_saved(data, model, initial, initial_mode)
    schedule = data.get("schedule", {})
    step = float(data["time_step"])
    steps = {mode: float(schedule.get("mode_time_steps", {}).get(mode, step)) for mode in model.modes}
    if not all(math.isfinite(v) and v > 0 for v in steps.values()):
        raise OwnFailure(f"schedule: the saved steps {steps} are not all finite and > 0")
    cluster = schedule.get("jump_cluster")
    if cluster is not None and (not isinstance(cluster, int) or cluster < 1):
        raise OwnFailure(f"schedule: the saved jump_cluster {cluster!r} is not None or a whole number >= 1")
    max_jumps = data["max_jumps"]
    return own_recheck(model, initial, initial_mode, fragment, steps=steps, cluster=cluster, max_jumps=int(max_jumps),
                       inputs=inputs)
