"""The saved flowpipe as a schedule for the own-set re-check (:mod:`analysis.reach.recheck_own`).

:func:`schedule_recheck` first checks that the saved JSON is a well-formed, complete run of *this* model from
*this* initial box — the hints it gives are then used, its sets are not:

* one flowpipe per termination and one per jump plus the initial one; every box finite with ``lo <= hi``;
* the first flowpipe is in the initial mode and its entry box holds the initial box (the producer's claim is
  about this box);
* every termination is conclusive and not the jump bound (``"horizon"`` or ``"left_invariant"``);
* every saved jump is a transition of the model (name, source, target) whose ``after`` box holds the exact reset
  image of its ``before`` box (a flowpipe saved for another reset is refused); a saved zonotope jump set
  (:mod:`analysis.reach.jumpsets`) likewise: its ``after`` zonotope holds the exact reset image of its ``before``
  zonotope (:func:`_check_zonotope`, exact rationals);
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
        if "zonotope" in jump:
            _check_zonotope(jump["zonotope"], t, j)


def _exact(values: Any, what: str) -> list[Fraction]:
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
        raise OwnFailure(f"{what}: the saved numbers are malformed (finite numbers expected)")
    return [Fraction(v) for v in values]


def _check_zonotope(saved: Mapping[str, Any], t: Any, j: int) -> None:
    """A saved zonotope jump set must be well formed: its ``after`` holds the exact reset image of its ``before``.

    ``before = c + G ξ`` and ``after = c₂ + G₂ ξ ⊕ [−d, d]`` (the columns of ``G₂`` matched one for one with
    ``G``); with the exact image ``c₁ = R c + r``, ``G₁ = R G`` (rationals), ``|c₁ − c₂| + Σ_j |G₁_j − G₂_j| <= d``
    (componentwise) implies ``R·before + r ⊆ after``: each ``c₁ + G₁ ξ = c₂ + G₂ ξ + ((c₁ − c₂) + (G₁ − G₂) ξ)``
    and the bracket is within ``d`` for ``|ξ| <= 1``.  Decided in exact rationals (docs/reachability.md)."""
    what = f"jumps: jump {j} ({t.name}): the saved zonotope jump set"
    before, after = saved["before"], saved["after"]
    c = _exact(before["center"], what)
    gens = [_exact(row, what) for row in before["generators"]]
    c2 = _exact(after["center"], what)
    gens2 = [_exact(row, what) for row in after["generators"]]
    d = _exact(after["box"], what)
    n = len(t.r_matrix)
    m = len(gens[0]) if gens else 0
    if not (len(c) == len(gens) == len(c2) == len(gens2) == len(d) == n) or any(len(r) != m for r in gens + gens2) \
            or any(v < 0 for v in d):
        raise OwnFailure(f"{what} is malformed (shapes: n = {n} rows, the same columns before and after, box >= 0)")
    for i, (row, off) in enumerate(zip(t.r_matrix, t.r_offset)):
        terms = [(k, a) for k, a in enumerate(row) if a]
        total = abs(sum((a * c[k] for k, a in terms), Fraction(0)) + off - c2[i])
        for col in range(m):
            total += abs(sum((a * gens[k][col] for k, a in terms), Fraction(0)) - gens2[i][col])
            if total > d[i]:
                break
        if total > d[i]:
            raise OwnFailure(f"{what}: the reset image of its 'before' zonotope is not inside its 'after' zonotope "
                             f"(coordinate {i}: |c1 - c2| + sum |G1 - G2| = {float(total):.6g} > box {float(d[i]):.6g})")


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
