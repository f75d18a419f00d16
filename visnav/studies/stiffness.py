"""The BDF stiffness study of equation (13): is it stiff here, does the BDF matter, what limits it?

Applies the generic tools of :mod:`analysis.integrators` and
:mod:`analysis.integrator_regions` to the feature/depth reconstruction of a
scenario (``visnav stiffness`` prints it; ``docs/stiffness.md`` discusses it):

1. **Stability regions**: the A(α) angles of BDF1–6 measured on their boundary
   loci against the published values, the zero-instability of BDF7, the real
   stability intervals of the explicit schemes.
2. **Stiffness along real trajectories**: the eigenvalues of ``∂F/∂ψ`` of (13)
   (CasADi AD of :func:`visnav.model.feature_depth_rate`, the single source)
   at every sample where the scenario's estimator reconstructs, and along
   seeded random perturbations of the scenario; the stiffness ratio over time;
   ``h λ`` against every scheme's region (the first step at which it would
   leave it, and the spurious growth over the window); the worst case over the
   actuator limits as a function of depth.
3. **Accuracy and cost** on the *reconstruction problem* of the scenario's
   occlusion (:func:`occlusion_window`, :func:`reconstruction_problem`): (13)
   from the true features at the last unoccluded sample, driven by the
   **histopolant** camera screw (:class:`HistopolantScrew`: the C⁵ spline whose
   means over every sampling period equal the exact ZOH period means, so a
   smooth ODE that any integrator can solve); error against a reference
   (Radau, ``rtol = 1e-13``, cross-checked with DOP853 at ``3e-14``) as a
   function of the step and of the cost.  Observed orders are measured twice:
   on this problem, and on a verification problem with an exact solution
   (:func:`orbit_problem`).
4. **Reconstruction at the sampling period** ``h = T_e``: the paper's metrics
   (max ``f‖s − s̃‖`` [px] and ``1000‖z − z̃‖`` [mm] over the hidden samples)
   per scheme, split into the scheme's truncation error (against the
   reference of the same smooth problem) and the *sampling* error of the
   smooth input (reference against the true ZOH trajectory); the estimator
   itself (:class:`visnav.estimator.FeatureEstimator`) per order and screw
   model; and a one-step RK4 fed the exact in-period ZOH screw
   (:func:`visnav.estimator.zoh_period_rk4`).

Nothing here prints or writes files; wall-clock times are kept apart from the
deterministic results (:meth:`StiffnessStudy.as_dict`).
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np

from analysis.bdf import MAX_ORDER
from analysis.integrators import (
    FIXED_STEP_SCHEMES,
    REFERENCE_SCHEMES,
    SCHEME_ORDERS,
    IntegrationResult,
    OdeProblem,
    integrate,
    observed_order,
    pareto_front,
)
from analysis.integrator_regions import (
    a_alpha,
    boundary_locus,
    real_stability_interval,
    stability_grid,
    stability_polynomial,
    zero_stability,
)
from hybrid import DivergenceError

from hybrid.jsonable import to_jsonable
from visnav.parameters import EstimatorSettings, Scenario
from visnav.simulation import SimulationResult, simulate
from visnav.studies.stiffness_problem import (
    HISTOPOLANT_DEGREE,
    HISTORY_PERIODS,
    HistopolantScrew,
    NoOcclusionError,
    ORBIT_DURATION_S,
    ORBIT_RADIUS_M,
    ORBIT_RATE_RADPS,
    ReconstructionWindow,
    Spectrum,
    StiffnessStudyError,
    UNSTABLE_STEP_SEARCH_S,
    WORST_CASE_DEPTHS_M,
    histopolant_screw,
    jacobian_blocks,
    metrics_dict,
    occlusion_window,
    orbit_problem,
    paper_metrics,
    random_scenarios,
    reconstruction_problem,
    replay_estimator,
    replay_zoh_rk4,
    scheme_margins,
    spectrum,
    spectrum_of_run,
    spectrum_summary,
    state_error,
    worst_case_depths,
)

__all__ = [
    "StiffnessStudyError",
    "NoOcclusionError",
    "StudySettings",
    "QUICK_SETTINGS",
    "ReconstructionWindow",
    "HistopolantScrew",
    "Spectrum",
    "StiffnessStudy",
    "occlusion_window",
    "histopolant_screw",
    "reconstruction_problem",
    "orbit_problem",
    "jacobian_blocks",
    "spectrum",
    "spectrum_of_run",
    "random_scenarios",
    "replay_estimator",
    "replay_zoh_rk4",
    "paper_metrics",
    "state_error",
    "stiffness_study",
    "HISTORY_PERIODS",
    "HISTOPOLANT_DEGREE",
    "REFERENCE_SETTINGS",
    "CROSS_CHECK_SETTINGS",
    "ORBIT_RADIUS_M",
    "ORBIT_RATE_RADPS",
    "ORBIT_DURATION_S",
    "ORDER_FIT_FLOOR",
    "WORST_CASE_DEPTHS_M",
    "region_plot_data",
    "UNSTABLE_STEP_SEARCH_S",
    "REGION_VIEWS",
]

REFERENCE_SETTINGS = ("scipy_radau", 1e-13, 1e-15)
"""Reference of the smooth reconstruction problem: scheme, rtol, atol.

Checked against Richardson-extrapolated RK4 (h = 12.5 and 6.25 ms) on the
paper occlusion: agreement 6e-16 in X, Y (DOP853 at rtol 1e-13: 6e-14)."""
CROSS_CHECK_SETTINGS = ("scipy_dop853", 3e-14, 1e-16)
"""Independent second reference; :attr:`StiffnessStudy.data` reports the agreement."""
ORDER_FIT_FLOOR = 1e-11
"""On the reconstruction problem, errors below this are not used in the order fits.

About 30× the agreement of the two references (4e-13) and 100× the round-off
level the fixed-step schemes reach (BDF6: 1e-13 to 5e-13)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class StudySettings:
    """What the study computes.

    Attributes
    ----------
    seed : int
        Seed of the random scenarios.
    random_scenarios : int
        Number of random perturbations of the scenario (>= 0).
    order_steps : tuple of float
        Steps of the observed-order fits on the verification problem [s] (the
        coarsest must divide its duration, :data:`ORBIT_DURATION_S`).
    pareto_steps : tuple of float
        Steps of the error-vs-step and error-vs-time study on the
        reconstruction problem [s]; its observed orders are fitted on the three
        smallest whose errors exceed :data:`ORDER_FIT_FLOOR`.
    reference_tolerances : tuple of float
        ``rtol`` ladder of the references (``atol = rtol / 100``).
    timing_repeats : int
        Runs per timed point (the median is kept).
    reconstruction_rtol : float
        ``rtol`` of the references in the reconstruction table (``atol`` /100).
    """

    seed: int = 0
    random_scenarios: int = 6
    order_steps: tuple[float, ...] = (0.1, 0.05, 0.025)
    pareto_steps: tuple[float, ...] = (0.2, 0.1, 0.05, 0.025, 0.0125)
    reference_tolerances: tuple[float, ...] = (1e-4, 1e-6, 1e-8, 1e-10)
    timing_repeats: int = 3
    reconstruction_rtol: float = 1e-10

    def __post_init__(self) -> None:
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise StiffnessStudyError(f"StudySettings.seed = {self.seed!r}: expected an integer, e.g. 0")
        if isinstance(self.random_scenarios, bool) or not isinstance(self.random_scenarios, int) \
                or self.random_scenarios < 0:
            raise StiffnessStudyError(
                f"StudySettings.random_scenarios = {self.random_scenarios!r}: expected an integer >= 0"
            )
        for name in ("order_steps", "pareto_steps", "reference_tolerances"):
            values = getattr(self, name)
            if len(values) < 2 or not all(isinstance(v, (int, float)) and v > 0 and math.isfinite(v) for v in values):
                raise StiffnessStudyError(
                    f"StudySettings.{name} = {values!r}: expected at least two positive finite numbers"
                )
        for name, coarse in (("order_steps", ORBIT_DURATION_S), ("pareto_steps", max(self.pareto_steps))):
            for step in getattr(self, name):
                ratio = coarse / step
                if abs(ratio - round(ratio)) > 1e-9 * ratio or (name == "order_steps"
                                                                 and _not_divisor(max(self.order_steps), step)):
                    raise StiffnessStudyError(
                        f"StudySettings.{name} contains {step!r}, which does not divide {coarse!r}: the errors "
                        f"are compared on a common grid; use steps that halve each other, e.g. (0.1, 0.05, 0.025)"
                    )
        if isinstance(self.timing_repeats, bool) or not isinstance(self.timing_repeats, int) or self.timing_repeats < 1:
            raise StiffnessStudyError(f"StudySettings.timing_repeats = {self.timing_repeats!r}: expected an integer >= 1")


def _not_divisor(coarse: float, step: float) -> bool:
    ratio = coarse / step
    return abs(ratio - round(ratio)) > 1e-9 * ratio


QUICK_SETTINGS = StudySettings(
    random_scenarios=2, pareto_steps=(0.1, 0.05), reference_tolerances=(1e-6, 1e-8), timing_repeats=1,
)
"""A fast variant (``visnav stiffness --quick``): fewer steps, tolerances and random scenarios."""


# --------------------------------------------------------------------------- the reconstruction window


@dataclass(frozen=True, kw_only=True, slots=True)
class StiffnessStudy:
    """Result of :func:`stiffness_study`.

    Attributes
    ----------
    scenario : str
    settings : StudySettings
    data : dict
        Deterministic results (JSON-ready through :meth:`as_dict`): the same
        scenario and seed give the same values on the same machine.
    timing : dict
        Wall-clock medians [s] of the timed runs (vary from run to run).
    plots : dict
        Arrays for :mod:`visnav.app.figures_stiffness` (not serialised).
    """

    scenario: str
    settings: StudySettings
    data: dict[str, Any]
    timing: dict[str, Any] = field(default_factory=dict)
    plots: dict[str, Any] = field(default_factory=dict, repr=False)

    def as_dict(self, *, include_timing: bool = False) -> dict[str, Any]:
        """Plain JSON types; wall-clock times only with ``include_timing=True``."""
        out = {"scenario": self.scenario, "settings": dataclasses.asdict(self.settings), **self.data}
        if include_timing:
            out["timing"] = self.timing
        return to_jsonable(out)


def _timed(run: Callable[[], IntegrationResult], repeats: int) -> tuple[IntegrationResult, float]:
    times = []
    result = None
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    assert result is not None
    return result, statistics.median(times)


def _stability_section() -> dict[str, Any]:
    rows = {}
    for order in range(1, MAX_ORDER + 1):
        a = a_alpha(order)
        rows[str(order)] = {
            "alpha_deg": a.alpha_deg, "alpha_tangency_deg": a.alpha_tangency_deg,
            "published_deg": a.published_deg, "error_deg": a.error_deg,
            "z_star": None if a.z_star is None else complex(a.z_star),
        }
    zs = {str(m): {"max_parasitic_modulus": z.max_parasitic_modulus, "zero_stable": z.zero_stable}
          for m in range(1, MAX_ORDER + 2) for z in [zero_stability(m)]}
    intervals = {s: real_stability_interval(stability_polynomial(s)) for s in ("euler", "rk4", "abm4")}
    return {
        "a_alpha_deg": {k: v["alpha_deg"] for k, v in rows.items()},
        "a_alpha": rows,
        "max_a_alpha_error_deg": max(abs(v["error_deg"]) for v in rows.values()),
        "zero_stability": zs,
        "real_stability_interval": intervals,
        "published_source": "Hairer & Wanner, Solving ODEs II, section V.2, Table 2.3",
    }


def _order_study_verification(scenario: Scenario, steps: Sequence[float]) -> tuple[dict[str, Any], dict[str, Any]]:
    problem, exact = orbit_problem(scenario)
    coarse = max(steps)
    grid = np.arange(0.0, problem.t1 + 0.5 * coarse, coarse)
    truth = np.array([exact(t) for t in grid])
    rows: dict[str, Any] = {}
    for scheme in FIXED_STEP_SCHEMES:
        errors = []
        for h in steps:
            needed = 3 if scheme == "abm4" else (SCHEME_ORDERS[scheme] - 1 if scheme.startswith("bdf") else 0)
            kwargs: dict[str, Any] = {}
            if needed > 0:
                kwargs = {"startup": "exact", "start_values": np.array([exact(h * j) for j in range(1, needed + 1)])}
            res = integrate(problem, scheme, h=h, **kwargs)
            stride = int(round(coarse / h))
            errors.append(state_error(res.y[::stride], truth))
        rows[scheme] = {"steps_s": tuple(steps), "errors": tuple(errors), "observed_order": observed_order(steps, errors),
                        "theoretical_order": SCHEME_ORDERS[scheme]}
    meta = {"problem": problem.name, "duration_s": problem.t1, "radius_m": ORBIT_RADIUS_M,
            "rate_radps": ORBIT_RATE_RADPS, "start_values": "exact (closed form)", "error": "max(|dX|,|dY|,|dz|/z)"}
    return rows, meta


def stiffness_study(
    scenario: Scenario, settings: StudySettings | None = None, *, result: SimulationResult | None = None
) -> StiffnessStudy:
    """Run the whole study on ``scenario`` (see the module docstring).

    Parameters
    ----------
    scenario : Scenario
        Must hide the target at some point (``paper`` does).
    settings : StudySettings, optional
        Default :class:`StudySettings` (``QUICK_SETTINGS`` for a fast variant).
    result : SimulationResult, optional
        A run of ``scenario`` to reuse (otherwise simulated here).

    Raises
    ------
    StiffnessStudyError
        No occlusion, or settings incompatible with the window.
    hybrid.DivergenceError
        The scenario's own run diverged.
    """
    settings = settings or StudySettings()
    h = float(scenario.sampling_period_s)
    if _not_divisor(max(settings.pareto_steps), h):
        raise StiffnessStudyError(
            f"StudySettings.pareto_steps: the coarsest step {max(settings.pareto_steps)!r} is not a multiple of the "
            f"sampling period {h!r} s: the errors are compared at samples; use multiples of {h!r} s"
        )
    run = result if result is not None else simulate(scenario)
    window = occlusion_window(run)
    screw = histopolant_screw(run)
    data: dict[str, Any] = {"period_s": h}
    timing: dict[str, Any] = {}
    plots: dict[str, Any] = {}

    # 1. stability regions -------------------------------------------------------------
    stability = _stability_section()
    data.update({k: stability[k] for k in ("a_alpha_deg", "max_a_alpha_error_deg")})
    data["stability"] = {k: v for k, v in stability.items() if k not in ("a_alpha_deg", "max_a_alpha_error_deg")}

    # 2. stiffness along the run and random runs -----------------------------------------
    stiffness, paper_spec, all_random = _stiffness_section(scenario, settings, run, window, h)
    data["stiffness"] = stiffness
    data["max_stiffness_ratio"] = stiffness["paper"]["max_stiffness_ratio"]
    plots["paper_spectrum"] = paper_spec
    plots["random_cloud"] = all_random
    plots["occlusion"] = (float(window.times[0]), float(window.times[-1]))
    cloud_max = float(np.abs(np.concatenate([paper_spec.eigenvalues.reshape(-1), all_random])).max())
    plots["region_zoom"] = 1.5 * h * cloud_max  # the figure asks region_plot_data() for this view
    plots["a_alpha"] = {int(k): v for k, v in stability["a_alpha"].items()}

    # 3. accuracy and cost ------------------------------------------------------------------
    reference_full, problem_full = _accuracy_section(scenario, settings, window, screw, h, data, timing, plots)

    # 4. reconstruction at h = T_e ------------------------------------------------------------
    _reconstruction_section(settings, run, window, h, problem_full, reference_full, data, timing)
    data["answer"] = _answer(data)
    return StiffnessStudy(scenario=scenario.name, settings=settings, data=data, timing=timing, plots=plots)


def _stiffness_section(
    scenario: Scenario, settings: StudySettings, run: SimulationResult, window: ReconstructionWindow, h: float
) -> tuple[dict[str, Any], Any, np.ndarray]:
    """Section 2 of :func:`stiffness_study`: the stiffness of (13) along the scenario's run and along seeded random
    runs; returns the section's data, the run's spectrum and the random runs' eigenvalue cloud."""
    paper_spec = spectrum_of_run(run, window_s=window.duration)
    if paper_spec is None:  # pragma: no cover - an occlusion implies reconstruction
        raise StiffnessStudyError(f"scenario {scenario.name!r}: the estimator never reconstructs")
    window_steps = window.pans.size
    stiffness: dict[str, Any] = {"paper": spectrum_summary(paper_spec, h)}
    stiffness["paper"]["schemes"] = scheme_margins(paper_spec.eigenvalues, h, window_steps)
    random_rows = []
    clouds = []
    for rs in random_scenarios(scenario, settings.random_scenarios, settings.seed):
        row: dict[str, Any] = {"name": rs.name}
        try:
            rrun = simulate(rs)
        except DivergenceError as err:
            row.update({"status": "diverged", "cause": str(err)})
            random_rows.append(row)
            continue
        spec = spectrum_of_run(rrun)
        row["status"] = rrun.metrics.termination
        if spec is None:
            row["reconstructs"] = False
        else:
            row["reconstructs"] = True
            row.update(spectrum_summary(spec, h))
            clouds.append(spec.eigenvalues.reshape(-1))
        random_rows.append(row)
    all_random = np.concatenate(clouds) if clouds else np.zeros(0, dtype=complex)
    stiffness["random"] = {
        "seed": settings.seed, "count": settings.random_scenarios, "runs": random_rows,
        "with_reconstruction": len(clouds),
        "max_abs_h_lambda": float(h * np.abs(all_random).max()) if all_random.size else None,
        "max_stiffness_ratio": max((r["max_stiffness_ratio"] for r in random_rows if r.get("reconstructs")),
                                   default=None),
        "schemes": scheme_margins(all_random, h, window_steps) if all_random.size else {},
    }
    stiffness["worst_case_within_limits"] = worst_case_depths(scenario, h)
    return stiffness, paper_spec, all_random


def _accuracy_section(
    scenario: Scenario, settings: StudySettings, window: ReconstructionWindow, screw: HistopolantScrew, h: float,
    data: dict[str, Any], timing: dict[str, Any], plots: dict[str, Any],
) -> tuple[IntegrationResult, OdeProblem]:
    """Section 3 of :func:`stiffness_study`: accuracy and cost of the schemes (fills ``data``, ``timing`` and
    ``plots`` in place); returns the reference solution on the whole window and the whole-window problem."""
    verification, verification_meta = _order_study_verification(scenario, settings.order_steps)
    coarse = max(settings.pareto_steps)
    prefix = math.floor(window.duration / coarse + 1e-9) * coarse
    problem_full = reconstruction_problem(window, screw)
    problem = reconstruction_problem(window, screw, duration=prefix)
    ref_scheme, ref_rtol, ref_atol = REFERENCE_SETTINGS
    chk_scheme, chk_rtol, chk_atol = CROSS_CHECK_SETTINGS
    reference_full = integrate(problem_full, ref_scheme, rtol=ref_rtol, atol=ref_atol, t_eval=window.times)
    cross_full = integrate(problem_full, chk_scheme, rtol=chk_rtol, atol=chk_atol, t_eval=window.times)
    stride_ref = int(round(coarse / h))
    n_prefix = int(round(prefix / h))
    ref_grid = reference_full.y[: n_prefix + 1 : stride_ref]
    # the prefix problem is the same ODE on a shorter interval: its reference is the first rows
    paper_rows: dict[str, Any] = {}
    for scheme in FIXED_STEP_SCHEMES:
        errors, costs, walls = [], [], []
        for step in settings.pareto_steps:
            res, wall = _timed(partial(integrate, problem, scheme, h=step), settings.timing_repeats)
            stride = int(round(coarse / step))
            errors.append(state_error(res.y[::stride], ref_grid))
            costs.append(res.n_rhs + res.n_jac)
            walls.append(wall)
        usable = sorted((s, e) for s, e in zip(settings.pareto_steps, errors) if e > ORDER_FIT_FLOOR)[:3]
        paper_rows[scheme] = {
            "steps_s": settings.pareto_steps, "errors": tuple(errors), "evaluations": tuple(costs),
            "fit_steps_s": tuple(s for s, _ in usable),
            "observed_order": observed_order(*zip(*usable)) if len(usable) >= 2 else None,
            "theoretical_order": SCHEME_ORDERS[scheme],
        }
        timing[scheme] = {"steps_s": settings.pareto_steps, "wall_s": tuple(walls)}
    grid_times = problem.t0 + coarse * np.arange(ref_grid.shape[0])
    ref_rows: dict[str, Any] = {}
    for scheme in REFERENCE_SCHEMES:
        errors, costs, walls = [], [], []
        for tol in settings.reference_tolerances:
            res, wall = _timed(partial(integrate, problem, scheme, rtol=tol, atol=tol / 100.0, t_eval=grid_times),
                               settings.timing_repeats)
            errors.append(state_error(res.y, ref_grid))
            costs.append(res.n_rhs + res.n_jac)
            walls.append(wall)
        ref_rows[scheme] = {"rtol": settings.reference_tolerances, "errors": tuple(errors), "evaluations": tuple(costs)}
        timing[scheme] = {"rtol": settings.reference_tolerances, "wall_s": tuple(walls)}
    points = [(name, i, timing[name]["wall_s"][i], row["errors"][i])
              for name, row in {**paper_rows, **ref_rows}.items() for i in range(len(row["errors"]))]
    front = pareto_front([p[2] for p in points], [p[3] for p in points])
    timing["pareto_front"] = [{"scheme": points[i][0], "index": points[i][1], "wall_s": points[i][2],
                               "error": points[i][3]} for i in front]
    eval_front = pareto_front(
        [(paper_rows.get(p[0]) or ref_rows[p[0]])["evaluations"][p[1]] for p in points], [p[3] for p in points]
    )
    data["observed_order"] = {s: r["observed_order"] for s, r in verification.items()}
    data["observed_order_paper_problem"] = {s: r["observed_order"] for s, r in paper_rows.items()}
    data["accuracy"] = {
        "verification": {"problem": verification_meta, "schemes": verification},
        "paper": {
            "problem": {"name": problem.name, "t0_s": problem.t0, "duration_s": prefix,
                        "input": "histopolant screw (C5 spline, exact ZOH period means)",
                        "reference": {"scheme": ref_scheme, "rtol": ref_rtol, "atol": ref_atol},
                        "cross_check": {"scheme": chk_scheme, "rtol": chk_rtol, "atol": chk_atol,
                                        "agreement": state_error(cross_full.y, reference_full.y)},
                        "error": "max(|dX|,|dY|,|dz|/z) every %g s" % coarse,
                        "startup": "rk4, 16 substeps"},
            "fixed_step": paper_rows,
            "references": ref_rows,
            "pareto_front_by_evaluations": [{"scheme": points[i][0], "index": points[i][1]} for i in eval_front],
        },
    }
    plots["verification"] = verification
    plots["paper_accuracy"] = paper_rows
    plots["reference_accuracy"] = ref_rows

    return reference_full, problem_full


def _reconstruction_section(
    settings: StudySettings, run: SimulationResult, window: ReconstructionWindow, h: float, problem_full: OdeProblem,
    reference_full: IntegrationResult, data: dict[str, Any], timing: dict[str, Any],
) -> None:
    """Section 4 of :func:`stiffness_study`: the reconstruction at ``h = T_e`` by each scheme, by the estimator's
    own replays and by ZOH RK4 (fills ``data`` and ``timing`` in place)."""
    truth = window.psi
    hidden = window.hidden
    f = window.focal_px
    floor = paper_metrics(reference_full.y, truth, hidden, f)
    recon: dict[str, Any] = {}
    for scheme in FIXED_STEP_SCHEMES:
        res, wall = _timed(partial(integrate, problem_full, scheme, h=h), settings.timing_repeats)
        total = paper_metrics(res.y, truth, hidden, f)
        trunc = paper_metrics(res.y, reference_full.y, hidden, f)
        recon[scheme] = {**metrics_dict(total), "truncation_error_px": trunc[0], "truncation_error_mm": trunc[1],
                         "evaluations": res.n_rhs + res.n_jac}
        timing.setdefault("reconstruction", {})[scheme] = wall
    rtol = settings.reconstruction_rtol
    for scheme in REFERENCE_SCHEMES:
        res, wall = _timed(partial(integrate, problem_full, scheme, rtol=rtol, atol=rtol / 100.0,
                                   t_eval=window.times), settings.timing_repeats)
        total = paper_metrics(res.y, truth, hidden, f)
        trunc = paper_metrics(res.y, reference_full.y, hidden, f)
        recon[scheme] = {**metrics_dict(total), "truncation_error_px": trunc[0], "truncation_error_mm": trunc[1],
                         "evaluations": res.n_rhs + res.n_jac, "rtol": rtol}
        timing.setdefault("reconstruction", {})[scheme] = wall
    estimator: dict[str, Any] = {}
    for screw_model in ("end", "start", "mean", "histopolated"):
        estimator[screw_model] = {}
        for order in range(1, MAX_ORDER + 1):
            y = replay_estimator(window, EstimatorSettings(order=order, screw_model=screw_model))
            estimator[screw_model][f"bdf{order}"] = metrics_dict(paper_metrics(y, truth, hidden, f))
    zoh = {f"substeps_{s}": metrics_dict(paper_metrics(replay_zoh_rk4(window, s), truth, hidden, f))
           for s in (1, 16)}
    data["reconstruction"] = recon
    data["reconstruction_components"] = {
        "window": {"t0_s": float(window.times[0]), "t1_s": float(window.times[-1]), "steps": window.pans.size,
                   "hidden_samples": int(hidden.sum()), "duration_s": window.duration},
        "input_model": "histopolant screw; truncation = scheme vs reference of the same ODE; "
                       "sampling floor = reference vs the true ZOH trajectory",
        "sampling_floor": metrics_dict(floor),
        "estimator": estimator,
        "zoh_rk4": zoh,
        "closed_loop_run": {"max_error_px": run.metrics.max_reconstruction_error_px,
                            "max_depth_error_mm": run.metrics.max_depth_error_mm,
                            "note": "the scenario's own run: its reconstruction starts when mu_occ > 0, "
                                    "before the occlusion"},
    }


def _answer(data: dict[str, Any]) -> dict[str, Any]:
    """The short, measured answer: is (13) stiff here, and does the BDF choice matter?"""
    paper = data["stiffness"]["paper"]
    rk4_limit = paper["schemes"]["rk4"]["first_unstable_step_s"]
    recon = data["reconstruction"]
    comps = data["reconstruction_components"]
    return {
        "stiff": bool(paper["max_abs_h_lambda"] > abs(data["stability"]["real_stability_interval"]["euler"])),
        "max_abs_h_lambda": paper["max_abs_h_lambda"],
        "rk4_first_unstable_step_s": rk4_limit,
        "bdf4_px": recon["bdf4"]["max_error_px"],
        "rk4_px": recon["rk4"]["max_error_px"],
        "sampling_floor_px": comps["sampling_floor"]["max_error_px"],
        "estimator_bdf4_histopolated_px": comps["estimator"]["histopolated"]["bdf4"]["max_error_px"],
        "zoh_rk4_px": comps["zoh_rk4"]["substeps_1"]["max_error_px"],
    }


REGION_VIEWS = {"global": ((-8.0, 3.0), (-6.0, 6.0))}
"""Windows ``((re_min, re_max), (im_min, im_max))`` of the stability-region plots; a ``"zoom"`` view
of ±1.5 max ``|h λ|`` is added around the origin."""


def region_plot_data(zoom: float, points: int = 181) -> dict[str, Any]:
    """What the region figure draws: root-modulus grids of the explicit schemes on :data:`REGION_VIEWS`
    and on the zoom ``±zoom`` (contoured at 1), and the boundary loci of BDF1–7 (for BDF the locus is
    the region's boundary)."""
    out: dict[str, Any] = {"views": {}, "loci": {}}
    views = {**REGION_VIEWS, "zoom": ((-zoom, zoom), (-zoom, zoom))}
    for view, ((r0, r1), (i0, i1)) in views.items():
        n = points if view != "zoom" else (points + 1) // 2  # the zoom shows only curves through 0
        re = np.linspace(r0, r1, n)
        im = np.linspace(i0, i1, n)
        out["views"][view] = {
            "re": re, "im": im,
            "modulus": {s: stability_grid(stability_polynomial(s), re, im) for s in ("euler", "rk4", "abm4")},
        }
    for order in range(1, MAX_ORDER + 2):
        out["loci"][f"bdf{order}"] = boundary_locus(stability_polynomial(f"bdf{order}"), 2048)[:, 0]
    return out
