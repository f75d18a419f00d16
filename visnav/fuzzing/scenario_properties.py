"""The properties on whole scenarios: closed-loop runs of a variant (:mod:`visnav.fuzzing.closed_loop`).

A check is ``check(variant_name, scenario, observe) -> ScenarioRun``; it
raises :class:`analysis.fuzzing.PropertyViolation` on failure (an exception of
the executor is one too).
"""

from __future__ import annotations

from analysis.fuzzing import Observer, PropertyViolation
from hybrid import DivergenceError, HybridError

from visnav.fuzzing.closed_loop import OUTCOMES, ScenarioRun, simulate_variant
from visnav.fuzzing.properties import CONTROL_TOLERANCE
from visnav.parameters import Scenario

__all__ = ["check_no_collision", "check_classified_outcome", "check_closed_loop_continuity"]


def _scenario_run(prop: str, variant: str, scenario: Scenario) -> ScenarioRun:
    try:
        return simulate_variant(scenario, variant)
    except DivergenceError as err:
        raise PropertyViolation(prop, f"the run raised DivergenceError: {err}",
                                details={"time_s": err.time, "mode": err.mode, "cause": err.cause}) from err
    except HybridError as err:  # ZenoError (a jump loop at one instant), ExecutionError (e.g. a tie)
        raise PropertyViolation(prop, f"the run raised {type(err).__name__}: {err}") from err


def check_no_collision(variant: str, scenario: Scenario, observe: Observer) -> ScenarioRun:
    """No collision whenever the paper's hypotheses hold.

    The dense clearance (exact arcs between samples) stays > 0.  Inputs:
    random scenarios respecting the hypotheses.  Guided search minimises the clearance.
    """
    run = _scenario_run("no_collision", variant, scenario)
    observe("negative minimum clearance [m]", -run.metrics.min_clearance_m)
    if run.metrics.collided:
        raise PropertyViolation(
            "no_collision", f"collision: minimum clearance {run.metrics.min_clearance_m:.6g} m "
            f"(outcome {run.outcome}, termination {run.metrics.termination})",
            details={"min_clearance_m": run.metrics.min_clearance_m, "t_end_s": run.metrics.sim_time_s},
        )
    return run


def check_classified_outcome(variant: str, scenario: Scenario, observe: Observer) -> ScenarioRun:
    """Every run ends in a classified outcome, never an exception.

    The outcome is one of :data:`OUTCOMES` (:func:`~visnav.fuzzing.closed_loop.classify_outcome`); a
    success ends in the variant's initial mode within the feature tolerance.
    A :class:`hybrid.DivergenceError` or any other exception is a violation.
    Inputs: random scenarios, half of them breaking the hypotheses.
    """
    run = _scenario_run("classified_outcome", variant, scenario)
    if run.outcome not in OUTCOMES or run.metrics.termination not in ("end_time", "success", "collision"):
        raise PropertyViolation("classified_outcome", f"unclassified end: outcome {run.outcome!r}, termination "
                                f"{run.metrics.termination!r}")
    if run.outcome == "success" and not run.metrics.final_feature_error_px <= scenario.success_tolerance_px:
        raise PropertyViolation("classified_outcome", f"success with a feature error of "
                                f"{run.metrics.final_feature_error_px!r} px", details={"final_mode": run.trace.final_mode})
    return run


def check_closed_loop_continuity(variant: str, scenario: Scenario, observe: Observer) -> ScenarioRun:
    """In the closed loop, the control (19) does not jump at any switch.

    At every sample whose jumps changed the mode, the control of the mode
    before and the mode after, at the same state and image, agree to 1e-9
    (the real controllers, estimator and measurements).  Inputs: random
    scenarios respecting the hypotheses.  Guided search maximises the jump.
    """
    run = _scenario_run("closed_loop_continuity", variant, scenario)
    observe("largest control jump at a switch (closed loop)", run.switch_jump)
    if run.switch_jump > CONTROL_TOLERANCE:
        at = dict(run.switch_jump_at)
        raise PropertyViolation(
            "closed_loop_continuity",
            f"the control jumps by {run.switch_jump:.6g} at t = {at.get('t_s', 0.0):.6g} s "
            f"({at.get('from')} -> {at.get('to')}): {at.get('before')} -> {at.get('after')}",
            details=at,
        )
    return run
