"""The input route's arbitrary-switching case: a relaxed flowpipe and its independent re-check.

When the locations reached from the initial one switch arbitrarily (identity resets, guards that always hold,
the same invariants, the same inputs, no transition out: :func:`analysis.reach.relaxed.switching_group`),
the hybrid loop of :func:`analysis.reach.reach` starts one flowpipe per jump set and never ends (PLAA01: the guards
always hold).  :func:`relaxed_outcome` reaches the relaxation ``ẋ ∈ conv{A_i x + c_i} + B U`` instead
(:func:`analysis.reach.relaxed.relaxed_reach`: every run of the group, whatever its switches, is a solution),
decides the requirement on it (:func:`analysis.reach.verdict.decide`) and re-checks a decision that holds on the
re-check's own sets (:func:`analysis.reach.recheck_relaxed.recheck_relaxed`); only a passed re-check gives
``rechecked=True``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from analysis.verify.verification import Proof

__all__ = ["relaxed_outcome", "relaxed_flowpipe", "NOT_USED"]

NOT_USED = "arbitrary-switching relaxation not used"
"""The evidence's note when a model has always-enabled switches that do not form a group (the reason follows)."""


def _has_free_guard(model: Any) -> bool:
    """Whether some transition's guard always holds (a candidate for the relaxation)."""
    return any(any(all(not any(h.normal) and h.offset >= 0 for h in p.halfspaces) for p in t.guard)
               for t in model.transitions)


def relaxed_flowpipe(system: Any, matrices: Mapping[str, Any], initial: Mapping[str, tuple[float, float]],
                     initial_mode: str, *, horizon: float, time_step: float) -> Any:
    """The relaxed flowpipe from ``initial_mode`` when it belongs to an arbitrary-switching group, else ``None``.

    Parameters
    ----------
    system : HybridSystem or AffineHybridModel
        The input-free model (every input at 0).
    matrices : mapping {mode: ModeInput}
    initial : mapping {state: (lo, hi)}
    initial_mode : str
    horizon, time_step : float
        [s], ``0 < time_step <= horizon``.

    Returns
    -------
    analysis.reach.result.ReachResult or None
        Its schedule names the group (``relaxed_group``): :func:`analysis.reach.recheck_relaxed.recheck_relaxed`
        re-checks it, not the hybrid loop's re-check.
    """
    from analysis.reach.model import affine_model
    from analysis.reach.relaxed import NoGroup, relaxed_reach, switching_group
    from analysis.reach.verdict import MAX_SEGMENTS

    model = affine_model(system)
    try:
        group = switching_group(model, matrices, initial_mode)
    except NoGroup:
        return None
    return relaxed_reach(model, group, initial, horizon=horizon, time_step=time_step, max_segments=MAX_SEGMENTS)


def relaxed_outcome(system: Any, matrices: Mapping[str, Any], initial: Mapping[str, tuple[float, float]],
                    fragment: Any, initial_mode: str, time_step: float, *, method: str, bounds: str,
                    assumptions: tuple[str, ...]) -> Proof | str:
    """The relaxed route's proof, or the note for the evidence of the ordinary route (``""``: nothing to say).

    Parameters
    ----------
    system : HybridSystem
        The input-free model (every input at 0).
    matrices : mapping {mode: ModeInput}
    initial : mapping {state: (lo, hi)}
    fragment : SafetyFragment
    initial_mode : str
    time_step : float
        ``δ`` [s] of the relaxed flowpipe and of its re-check.
    method, bounds : str
        The proof's method and the inputs in words (for the evidence).
    assumptions : tuple of str

    Returns
    -------
    Proof or str
        A :class:`Proof` when the initial mode belongs to an arbitrary-switching group (held or not); otherwise the
        reason the relaxation was not used when some guard always holds, else ``""``.
    """
    from analysis.reach.model import affine_model
    from analysis.reach.recheck_relaxed import recheck_relaxed
    from analysis.reach.relaxed import NoGroup, switching_group
    from analysis.reach.verdict import decide

    model = affine_model(system)
    end = max(fragment.end, 1e-9)
    result = relaxed_flowpipe(model, matrices, initial, initial_mode, horizon=end, time_step=time_step)
    if result is None:
        try:
            switching_group(model, matrices, initial_mode)
        except NoGroup as exc:  # always raised here: relaxed_flowpipe found no group
            return f"; {NOT_USED}: {exc}" if _has_free_guard(model) else ""
        return ""
    holds, margin, reason = decide(result, fragment, model, initial)
    check = None
    if holds:
        schedule = {"time_step": result.time_step, "schedule": dict(result.schedule)}
        check = recheck_relaxed(schedule, system, initial, fragment, initial_mode=initial_mode, inputs=matrices)
    if check is None:
        again = "not re-checked (the producer did not decide it: nothing to re-check)"
    elif check.passed:
        again = (f"re-checked on its own sets of the relaxation ({check.steps} steps), exact margin "
                 f"{check.margin}")
    else:
        again = f"re-check FAILED ({check.failure})"
    modes = " and ".join(repr(m) for m in dict(result.schedule)["relaxed_group"])
    evidence = (f"reachability with inputs {bounds} under arbitrary switching of {modes} (the relaxation "
                f"ẋ ∈ conv{{A_i x + c_i}} + B U, any number of switches): {reason}"
                + (f", margin {margin:.6g}" if math.isfinite(margin) else "")
                + f"; {len(result.segments)} segments, step {time_step:g} s; {again}")
    return Proof(holds=holds, method=method, evidence=evidence, rechecked=check is not None and check.passed,
                 assumptions=assumptions + (f"arbitrary switching among {modes} (identity resets)",),
                 margin=margin if math.isfinite(margin) else None)
