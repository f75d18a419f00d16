"""The two closed-loop properties written against slips, each with a yardstick that shares no judged code.

``check(variant_name, scenario, observe) -> ScenarioRun``, as in
:mod:`visnav.fuzzing.scenario_properties`; each raises
:class:`analysis.fuzzing.PropertyViolation` on failure.

* ``reconstruction_bounded`` judges the feature/depth estimator
  (:mod:`visnav.estimator`, the BDF of :mod:`analysis.bdf`, equation (13) of
  :mod:`visnav.model`).  Its yardstick, :mod:`visnav.fuzzing.reconstruction_reference`,
  integrates the rigid motion of the hidden points under the run's
  zero-order-hold inputs from the last measured image and propagates the
  specified BDF's local defects along it; none of the judged modules is imported.
* ``blend_weights`` judges the blend of the controllers ((18)–(19):
  :func:`visnav.controllers.blend`, :func:`visnav.controllers.avoidance_control`,
  the loop's command, the loop mutants' laws).  Its yardstick,
  :mod:`visnav.fuzzing.blend_reference`, writes (18)–(19) out on pure
  controllers it computes itself.

The runs themselves of course go through the judged code (that is what is run);
``tests/visnav/fuzzing/test_loop_properties.py`` checks that neither this module
nor the two yardsticks import it, and that planted slips in it are caught.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from analysis.fuzzing import Observer, PropertyViolation
from hybrid import DivergenceError, HybridError

from visnav.fuzzing.closed_loop import BlendMonitor, EstimatorLog, ScenarioRun, simulate_variant
from visnav.fuzzing.reconstruction_reference import ReconstructionReference, zoh_reconstruction_reference
from visnav.parameters import Scenario

__all__ = [
    "BLEND_TOLERANCE",
    "RECONSTRUCTION_FACTOR",
    "RECONSTRUCTION_FLOOR",
    "TRUTH_TOLERANCE",
    "reconstruction_yardstick",
    "check_reconstruction_bounded",
    "check_blend_weights",
]

BLEND_TOLERANCE = 1e-9
"""Largest accepted gap between the applied control and (18)–(19) [m/s, rad/s] (round-off of the sums)."""
RECONSTRUCTION_FACTOR = 1.1
"""How much the loop's reconstruction error may exceed the specified BDF's predicted one at a sample.

The prediction is first order; the second-order remainder is relative ``≲ |e|/z`` (below 1e-2 for
errors up to 5 px at 1 m).  Measured: the resolved loop matches the prediction to 1.4e-9 px on
random layouts and to 4e-8 (relative) on the paper scenario.
"""
RECONSTRUCTION_FLOOR = (1e-6, 1e-6)
"""Absolute slack of ``reconstruction_bounded`` at a sample [px, mm], plus the Newton tolerance times the
BDF steps (scaled to px and mm): round-off and the exact start-up steps (< 1e-10 in normalised units)."""
TRUTH_TOLERANCE = 1e-7
"""Largest accepted gap between the integrated ZOH motion and the recorded true features [-, m]."""


def _run(prop: str, variant: str, scenario: Scenario, **options: Any) -> ScenarioRun:
    """:func:`simulate_variant`, an exception of the executor reported as a violation of ``prop``."""
    try:
        return simulate_variant(scenario, variant, **options)
    except DivergenceError as err:
        raise PropertyViolation(prop, f"the run raised DivergenceError: {err}",
                                details={"time_s": err.time, "mode": err.mode, "cause": err.cause}) from err
    except HybridError as err:
        raise PropertyViolation(prop, f"the run raised {type(err).__name__}: {err}") from err


def reconstruction_yardstick(log: EstimatorLog, scenario: Scenario) -> ReconstructionReference:
    """:func:`~visnav.fuzzing.reconstruction_reference.zoh_reconstruction_reference` of a run's estimator log."""
    return zoh_reconstruction_reference(
        np.array(log.true, dtype=float), np.array(log.pan, dtype=float), np.array(log.inputs, dtype=float),
        np.array(log.reconstructing, dtype=bool), scenario.sampling_period_s, scenario.robot,
        scenario.estimator.order, scenario.estimator.screw_model,
    )


def _pixels_and_mm(diff: np.ndarray, focal_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Per sample ``f ‖ΔX, ΔY‖`` over the points [px] and ``1000 ‖Δz‖`` [mm]; ``diff`` of shape (K, n, 3)."""
    return (focal_px * np.linalg.norm(diff[:, :, :2].reshape(len(diff), -1), axis=1),
            1000.0 * np.linalg.norm(diff[:, :, 2], axis=1))


def check_reconstruction_bounded(variant: str, scenario: Scenario, observe: Observer) -> ScenarioRun:
    """While target points are hidden the loop reconstructs them within the specified BDF's own error.

    Yardstick (:mod:`visnav.fuzzing.reconstruction_reference`, no code shared
    with the estimator, the BDF tools or (13) of ``visnav.model``): the exact
    motion of the points under the run's zero-order-hold inputs, integrated
    from the last measured image (rigid motion of fixed points in the camera
    frame, RK4 with 16 substeps per period, < 1e-12), and ``ê``, the error the
    BDF of the scenario's order ``q`` and ``screw_model`` (``docs/estimator.md``)
    must make on that motion: its local defects (``O(h^{q+1})`` truncation,
    ``O(h³)`` from the ZOH input with the histopolated screw, ``O(h²)`` with the
    held ones) propagated by the linearised BDF recurrence over the hiding time
    (global ``O(h^{min(q,2)})`` times the horizon; derivation in
    :func:`~visnav.fuzzing.reconstruction_reference.zoh_reconstruction_reference`).
    At every sample where at least one point is hidden (and the loop
    reconstructs), the loop's ``f ‖s − s̃‖`` [px] and ``‖z − z̃‖`` [mm] against
    that motion must be at most 1.1 × ``f ‖ê_s‖`` and ``‖ê_z‖`` there, plus
    1e-6 px / 1e-6 mm and the Newton tolerance times the BDF steps.  The
    factor covers the second-order terms the linearisation leaves out
    (relative ``≲ |e|/z``, below 1e-2 up to 5 px; measured: the resolved loop
    matches ``ê`` to 1.4e-9 px), the floor round-off and the exact start-up
    steps (1e-10).  A held screw (error
    ``O(h)``) is 3–3000× worse than ``ê`` on the same motion, a BDF coefficient
    on the wrong history sample breaks consistency.  Also: the integrated
    motion must match the true features the run records (1e-7), or (13) and
    the simulated world disagree.  Inputs: random scenarios respecting the
    hypotheses.  If the run raises (a step of a slipped estimator fails, say),
    the samples before are judged all the same and a violation there is what
    is reported.  Guided search maximises the ratio.
    """
    log = EstimatorLog()
    try:
        run: ScenarioRun | None = _run("reconstruction_bounded", variant, scenario, estimator_log=log)
        raised = None
    except PropertyViolation as err:
        run, raised = None, err
    _judge_reconstruction(log, scenario, observe, raised)
    if raised is not None:
        raise raised
    assert run is not None
    return run


def _judge_reconstruction(log: EstimatorLog, scenario: Scenario, observe: Observer,
                          raised: PropertyViolation | None) -> None:
    """The checks of :func:`check_reconstruction_bounded` on the samples logged (all, or those before a raise)."""
    hidden = (np.array(log.hidden) > 0) & np.array(log.reconstructing, dtype=bool)
    if not hidden.any():
        observe("reconstruction error / predicted BDF error", 0.0)
        return
    yard = reconstruction_yardstick(log, scenario)
    f, settings = scenario.camera.focal_px, scenario.estimator
    px, mm = (a[hidden] for a in _pixels_and_mm(np.array(log.estimated, dtype=float) - yard.reference, f))
    ref_px, ref_mm = (a[hidden] for a in _pixels_and_mm(yard.predicted, f))
    newton = settings.newton_tol * max(yard.bdf_steps, 1) * (1.0 + float(np.abs(yard.reference).max()))
    floor_px, floor_mm = RECONSTRUCTION_FLOOR[0] + f * newton, RECONSTRUCTION_FLOOR[1] + 1000.0 * newton
    factor = RECONSTRUCTION_FACTOR
    ratio = np.maximum(px / (ref_px + floor_px), mm / (ref_mm + floor_mm))
    worst = int(np.argmax(ratio))
    observe("reconstruction error / predicted BDF error", float(ratio[worst]))
    t = log.times[int(np.flatnonzero(hidden)[worst])]
    details = {"max_reconstruction_error_px": float(px.max()), "max_depth_error_mm": float(mm.max()),
               "predicted_px": float(ref_px.max()), "predicted_mm": float(ref_mm.max()),
               "t_s": t, "error_px": float(px[worst]), "error_mm": float(mm[worst]),
               "predicted_px_there": float(ref_px[worst]), "predicted_mm_there": float(ref_mm[worst]),
               "truth_gap": yard.truth_gap, "bdf_steps": yard.bdf_steps,
               "hidden_s": float(np.count_nonzero(log.hidden) * scenario.sampling_period_s)}
    after = "" if raised is None else f"; the run raised afterwards ({raised.message})"
    if yard.truth_gap > TRUTH_TOLERANCE:
        raise PropertyViolation(
            "reconstruction_bounded",
            f"the exact ZOH motion of the hidden points, integrated from the last measured image, differs from the "
            f"recorded true features by {yard.truth_gap:.3g} (> {TRUTH_TOLERANCE:g}): equation (13) and the "
            f"simulated world disagree{after}", details=details)
    if px[worst] > factor * ref_px[worst] + floor_px or mm[worst] > factor * ref_mm[worst] + floor_mm:
        raise PropertyViolation(
            "reconstruction_bounded",
            f"reconstruction error while hidden {px[worst]:.6g} px / {mm[worst]:.6g} mm at t = {t:.6g} s "
            f"against the exact ZOH motion, where the specified BDF{settings.order} ({settings.screw_model} screw) "
            f"makes {ref_px[worst]:.6g} px / {ref_mm[worst]:.6g} mm (first order): more than {factor:g}x "
            f"(+{floor_px:.2g} px / {floor_mm:.2g} mm); largest {px.max():.6g} px / {mm.max():.6g} mm against "
            f"{ref_px.max():.6g} px / {ref_mm.max():.6g} mm{after}", details=details,
        )


def check_blend_weights(variant: str, scenario: Scenario, observe: Observer) -> ScenarioRun:
    """The applied control is (18)–(19) of the pure controllers with the recorded µ, at every sample.

    At every sample of the closed-loop run the input ``(v, ω, ϖ)`` equals
    ``(1 − µ_occ)(1 − µ_coll) q̇_VS + (1 − µ_coll) µ_occ q̇_occ + µ_coll q̇_coll``,
    ``q̇_coll = (v_coll, ω_coll, (1 − µ_occ) ϖ + µ_occ ϖ~)`` (1e-9), with the
    µ the loop recorded.  Yardstick (:mod:`visnav.fuzzing.blend_reference`,
    through :class:`~visnav.fuzzing.closed_loop.BlendMonitor`): that closed
    form written out, on the pure controllers (7), (8)–(9), (11), (16)–(17)
    called directly at the same state, image, features and latched memory —
    not :func:`visnav.controllers.blend`, not
    :func:`visnav.controllers.avoidance_control`, not the loop's command.  A
    weight reading the wrong µ, 1 − µ for µ, two weights swapped, a component
    summed into the wrong one: all show wherever the controls they mix differ.
    If the run later raises, the first wrong blend is still what is reported.
    A sample where a pure controller cannot be computed is not judged, and a
    run with such a sample is reported (never passed as clean; the resolved
    loop computes the same controllers, so it never has one).  Inputs: random scenarios respecting the hypotheses.  Guided search
    maximises the gap.
    """
    monitor = BlendMonitor(tolerance=BLEND_TOLERANCE)
    try:
        run = _run("blend_weights", variant, scenario, blend_monitor=monitor)
    except PropertyViolation:
        if monitor.first_at is None:
            raise
        run = None
    observe("largest gap to (18)-(19) [m/s, rad/s]", monitor.worst)
    if monitor.first_at is not None:
        at = monitor.first_at
        raise PropertyViolation(
            "blend_weights",
            f"the applied control {at['applied']} differs from (18)-(19) with the recorded mu_coll = "
            f"{at['mu_coll']:.6g}, mu_occ = {at['mu_occ']:.6g}, {at['eq_18_19']}, by {at['gap']:.6g} at "
            f"t = {at['t_s']:.6g} s in {at['mode']} (largest gap {monitor.worst:.6g})"
            + ("" if run is not None else "; the run raised afterwards"),
            details={**at, "worst_gap": monitor.worst, "samples": monitor.samples},
        )
    if monitor.skipped:  # never clean: samples the yardstick could not evaluate are not judged
        raise PropertyViolation(
            "blend_weights",
            f"(18)-(19) could not be evaluated at {monitor.skipped} of {monitor.samples + monitor.skipped} samples "
            "(a pure controller raised there while the loop applied a control): those samples are not judged",
            details={"skipped": monitor.skipped, "samples": monitor.samples, "worst_gap": monitor.worst},
        )
    assert run is not None
    return run
