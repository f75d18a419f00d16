"""The verification report of a scenario: what was verified, simulated, proven, measured and sampled.

:func:`build_report` runs every study on one scenario and returns a
:class:`Report`: a JSON-ready dictionary (byte-identical for the same
scenario, options and dependency versions: no wall-clock time, no absolute
path, no date), the figures as matplotlib figures and the counterexample
files.  The first section is the verification of the scenario's requirements
(:func:`visnav.verification.paper_problem`, the generic section of
:mod:`visnav.app.verification_report`): ``report.json``'s top-level
``verdict`` is its overall verdict.  The second, ``saturated``, verifies the
same requirements on the loop whose applied commands are clipped to the
actuator limits (``paper_problem(scenario, "saturated")``: the design answer
to actuator saturation), with its own verdict.  Then come
the case study's own sections (model, simulation, analysis, stiffness,
fuzzing, campaign).  Rendering to
Markdown and self-contained HTML is :mod:`visnav.app.report_render`; writing the
files is :mod:`visnav.app.report_files`.

Every claim of the report is a :class:`Claim` marked

* ``proven`` — a sound certificate or an exact symbolic identity,
  re-checkable from the report;
* ``measured`` — a number computed by deterministic numerics on the model
  (a simulation, eigenvalues, margins, errors against a reference, a
  counterexample to a requirement);
* ``sampled`` — a statement that generalises from samples and can miss
  cases (a requirement not falsified, structural checks by sampling,
  fuzzing, Monte-Carlo campaigns, entry angles from one run).

The structural checks make one claim per check
(:func:`visnav.app.structural.report_claims`): ``proven`` when the SMT
solver proved it over the measurement box (the supervisor is symbolic),
``measured`` when it found a defect whose witness re-checks on the model,
``sampled`` when it was searched by sampling; plus one for the graph checks
(exact).
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from visnav.app.verification_report import (
    CLAIM_STATUSES,
    DEPENDENCIES,
    VERIFY_BUDGET,
    VERIFY_BUDGET_QUICK,
    Claim,
    Report,
    Section,
    dependency_versions,
)
from visnav.app.precision import quantise_for_figure, round_section, round_value
from visnav.parameters import Scenario

__all__ = [
    "CLAIM_STATUSES",
    "DEPENDENCIES",
    "PAPER_PUBLISHED",
    "Claim",
    "ReportOptions",
    "Report",
    "build_report",
    "automaton_digest",
    "dependency_versions",
]

PAPER_PUBLISHED = {
    "task_achieved": True,
    "collision": False,
    "occlusion_duration_s": 15.0,
    "max_reconstruction_error_px": 0.17,
    "max_depth_error_mm": 1.164,
    "controls_saturated": False,
}
"""Folio & Cadenat's published results for their scenario (as ``docs/estimator.md`` and ``docs/requirements.md`` quote them)."""

Progress = Callable[[str], None]


@dataclass(frozen=True, kw_only=True, slots=True)
class ReportOptions:
    """What the report runs, and how much.

    Attributes
    ----------
    quick : bool
        Smaller budgets everywhere (the ``--quick`` report, about a minute).
    seed : int
        Seed of every random study (verification search, structural sampling, fuzzing, campaign).
    verify_budget : int
        Simulations of the verification of the scenario's requirements.
    check_samples : int
        Samples per mode of the structural checks.
    fuzz_examples : int
        Hypothesis examples per fuzzing property.
    campaign_samples : int
        Scenarios of the Monte-Carlo campaign.
    """

    quick: bool = False
    seed: int = 0
    verify_budget: int = VERIFY_BUDGET
    check_samples: int = 300
    fuzz_examples: int = 60
    campaign_samples: int = 40

    @classmethod
    def for_mode(cls, *, quick: bool, seed: int = 0, verify_budget: int | None = None) -> ReportOptions:
        """The full or the quick budgets (``verify_budget`` overrides the mode's)."""
        if quick:
            return cls(quick=True, seed=seed, verify_budget=verify_budget or VERIFY_BUDGET_QUICK, check_samples=40,
                       fuzz_examples=10, campaign_samples=6)
        return cls(quick=False, seed=seed, verify_budget=verify_budget or VERIFY_BUDGET)

    def __post_init__(self) -> None:
        for name in ("verify_budget", "check_samples", "fuzz_examples", "campaign_samples"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"ReportOptions.{name} = {value!r}; expected a whole number >= 1")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"ReportOptions.seed = {self.seed!r}; expected a whole number >= 0")


def automaton_digest(scenario: Scenario) -> str:
    """SHA-256 (hex) of the supervisor automaton's canonical JSON (``hybrid.export.to_json``)."""
    from hybrid.export import to_json

    from visnav.supervisor import build_supervisor

    model = build_supervisor(scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    text = json.dumps(to_json(model.automaton), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _bounded_parameters(parameters: dict[str, Any]) -> dict[str, Any]:
    """The scenario's tables with its free texts (its and its requirements' descriptions) bounded
    (:func:`visnav.app.report_render.bounded_text`): a long description is not copied whole into
    every report file; ``meta.scenario_digest`` still covers the full text."""
    from visnav.app.report_render import bounded_text

    out = dict(parameters)
    if isinstance(out.get("description"), str):
        out["description"] = bounded_text(out["description"])
    if isinstance(out.get("requirements"), list):
        out["requirements"] = [{**r, "description": bounded_text(r["description"])}
                               if isinstance(r, dict) and isinstance(r.get("description"), str) else r
                               for r in out["requirements"]]
    return out


# --------------------------------------------------------------------------- sections


def _model_section(scenario: Scenario, options: ReportOptions) -> tuple[dict[str, Any], list[Claim], dict]:
    from visnav.app.figures import mode_graph_figure
    from visnav.app.structural import (
        DEFAULT_TIMEOUT_S,
        check_supervisor,
        report_claims,
        supervisor_rates,
    )
    from visnav.app.verification_report import findings_summary
    from visnav.scenario import scenario_to_toml
    from visnav.supervisor import build_supervisor

    model = build_supervisor(scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    automaton = model.automaton
    report = check_supervisor(scenario, samples=options.check_samples, starts=8 if not options.quick else 2,
                              seed=options.seed, method="auto", timeout_s=DEFAULT_TIMEOUT_S)
    checks = report.as_dict()
    checks["summary"] = findings_summary(checks["findings"])
    data = {
        "parameters": _bounded_parameters(tomllib.loads(scenario_to_toml(scenario))),
        "automaton": {
            "modes": len(automaton.modes),
            "transitions": len(automaton.transitions),
            "memory": sorted(m.name for m in automaton.memory),
            "digest": automaton_digest(scenario),
        },
        "structural_checks": {"clean": report.clean, "samples_per_mode": options.check_samples,
                              "seed": options.seed, "method": "auto", "timeout_s": DEFAULT_TIMEOUT_S,
                              "rates": {k: float(f"{r:.12g}") for k, r in supervisor_rates(scenario).items()},
                              **checks},
        "figures": ["mode_graph"],
    }
    claims = report_claims(report, section="model", subject=f"the {len(automaton.modes)}-mode supervisor",
                           claim=Claim)
    return data, claims, {"mode_graph": mode_graph_figure(automaton)}


def _simulation_section(scenario: Scenario, options: ReportOptions) -> tuple[dict[str, Any], list[Claim], dict]:
    from visnav.app.figures import paper_figures
    from visnav.simulation import simulate

    result = simulate(scenario)
    metrics = round_section("simulation", {"metrics": result.metrics.as_dict()})["metrics"]
    m = metrics  # the claims say what report.json says (visnav.app.precision)
    ours = {
        "task_achieved": m["success"],
        "collision": m["collided"],
        "occlusion_duration_s": m["occlusion_duration_s"],
        "max_reconstruction_error_px": m["max_reconstruction_error_px"],
        "max_depth_error_mm": m["max_depth_error_mm"],
        "controls_saturated": not m["within_actuator_limits"],
    }
    comparison = [{"quantity": k, "paper": PAPER_PUBLISHED[k], "ours": ours[k]} for k in PAPER_PUBLISHED]
    data = {"metrics": metrics, "paper_comparison": comparison,
            "figures": ["fig4_trajectory", "fig5_risk", "fig6_reconstruction", "fig7_controls"]}
    claims = [
        Claim(section="simulation", status="measured",
              text=(f"the paper scenario {'succeeds' if m['success'] else 'fails'} ({m['termination']}) "
                    f"{'without' if not m['collided'] else 'WITH'} collision; minimum clearance "
                    f"{m['min_clearance_m']:.3g} m (exact arcs, 20 sub-samples per period)")),
        Claim(section="simulation", status="measured",
              text=(f"reconstruction while hidden: max |s - s~| = {m['max_reconstruction_error_px']:.3g} px, "
                    f"max |z - z~| = {m['max_depth_error_mm']:.3g} mm over a {m['occlusion_duration_s']:.4g} s "
                    f"occlusion (paper: < {PAPER_PUBLISHED['max_reconstruction_error_px']} px, "
                    f"< {PAPER_PUBLISHED['max_depth_error_mm']} mm over about 15 s)")),
        Claim(section="simulation", status="measured",
              text=(f"{len(m['transitions'])} transitions, {m['chatter_count']} chatter episode(s); peak |v|, |w|, "
                    f"|pan rate| = {', '.join(f'{x:.3g}' for x in m['max_abs_input'])} "
                    f"({'within' if m['within_actuator_limits'] else 'BEYOND'} the actuator limits)")),
    ]
    return data, claims, paper_figures(quantise_for_figure(result))


def _sos_claims(sos: dict[str, Any] | None) -> list[Claim]:
    """The SOS study's claims as report claims: ``proven`` and ``sampled`` kept, ``computed`` is ``measured``
    (deterministic numerics), and anything else (``not proven``) ``measured`` with its status in words."""
    if sos is None:
        return []
    out = []
    for c in sos["claims"]:
        status = c["status"] if c["status"] in ("proven", "sampled") else "measured"
        prefix = "" if c["status"] in ("proven", "sampled", "computed") else f"{c['status'].upper()}: "
        out.append(Claim(section="analysis", status=status, text=f"SOS: {prefix}{c['claim']} ({c['why']})"))
    return out


def _analysis_section(scenario: Scenario, options: ReportOptions) -> tuple[dict[str, Any], list[Claim], dict]:
    from visnav.studies.loop_analysis import analyse
    from visnav.app.figures_analysis import analysis_figures
    from visnav.app.report_reach import bypass_reach_data

    # the quick report judges the scenario's k only; the full one scans the gains as `visnav analyse` does
    # rounded first (visnav.app.precision): the claims, the documents and the figures all use the same digits
    full = round_section("analysis", analyse(scenario, sos="scenario" if options.quick else "scan").as_dict())
    figures = analysis_figures(full)
    data = {k: v for k, v in full.items() if k not in ("frequency_responses", "scenario")}
    data["figures"] = sorted(figures)
    pf = full["path_following"]
    # the sampled loop's flowpipe from the campaign's measured entries, beside the SOS bounds (full report only)
    pf["bypass_reach"], reach_claims = bypass_reach_data(scenario, samples=options.campaign_samples,
                                                         seed=options.seed, run=not options.quick)
    eig = ", ".join(f"{re:.6g}" for re, _ in pf["eigenvalues"])
    region = ", ".join(f"{n} in [{lo:.4g}, {hi:.4g}]" for n, (lo, hi) in pf["lyapunov"]["region"].items())
    goal = full["goal"]
    claims = [
        Claim(section="analysis", status="proven" if pf["lyapunov"]["certified"] else "measured",
              text=(f"V' <= 0 for V = k delta^2/2 + 1 - cos(alpha) "
                    f"{'PROVEN' if pf['lyapunov']['certified'] else 'NOT proven'} on {region} (interval branch and "
                    f"bound on the exact normal form, {pf['lyapunov']['boxes']} boxes, re-checkable from the JSON); "
                    "LaSalle: every solution with V < 2 converges to the envelope")),
        Claim(section="analysis", status="measured",
              text=f"path-following eigenvalues {eig} 1/s (AD; equal to the closed form to 1e-12)"),
        Claim(section="analysis", status="sampled",
              text=f"admissible k for the simulated entry angles: {pf['admissible']['finding']}"),
        *_sos_claims(pf["sos"]),
        *reach_claims,
        Claim(section="analysis", status="measured",
              text=("goal: visual-servoing task eigenvalues "
                    + ", ".join(f"{re:.4g}" for re, _ in goal["visual_servoing_task"]["eigenvalues"])
                    + "; the full 4-state loop has one zero eigenvalue (a curve of equilibria: camera at its goal "
                    "pose, base turned about it); pan task eigenvalue "
                    f"{goal['pan_task']['eigenvalues'][0][0]:.4g}")),
    ]
    for name, pair in full["margins"].items():
        s = pair["sampled"]
        gm = "inf" if s["gain_margin_db"] is None else f"{s['gain_margin_db']:.3g} dB"
        claims.append(Claim(
            section="analysis", status="measured",
            text=(f"margins of {name} sampled at {full['sampling_period_s']:g} s (ZOH + 1 delay): GM {gm}, "
                  f"PM {s['phase_margin_deg']:.3g} deg, delay margin {s['delay_margin_s']:.3g} s"),
        ))
    for key, curve in full["margins_vs_gains"].items():
        limit = curve["sampled"]["stability_limit"]
        if limit is not None:
            gain = next(k for k in curve if k in ("k", "lambda_gc", "lambda_vs"))
            claims.append(Claim(section="analysis", status="measured",
                                text=f"{key}: the sampled loop is unstable for {gain} above {limit:.4g}"))
    return data, claims, figures


def _stiffness_section(scenario: Scenario, options: ReportOptions) -> tuple[dict[str, Any], list[Claim], dict]:
    import dataclasses

    from visnav.app.figures_stiffness import stiffness_figures
    from visnav.studies.stiffness import QUICK_SETTINGS, NoOcclusionError, StudySettings, stiffness_study

    # one timing run per integration: the report plots the cost against evaluations, never the clock
    settings = dataclasses.replace(QUICK_SETTINGS if options.quick else StudySettings(), seed=options.seed,
                                   timing_repeats=1)
    try:
        study = stiffness_study(scenario, settings)
    except NoOcclusionError as err:  # a scenario without an occlusion: nothing to reconstruct, nothing to study
        return ({"not_applicable": str(err), "figures": []},
                [Claim(section="stiffness", status="measured", text=f"stiffness study not applicable: {err}")], {})
    data = round_section("stiffness", study.as_dict(include_timing=False))
    figures = stiffness_figures(_figure_study(study), reproducible=True)
    data["figures"] = sorted(figures)
    ans = data["answer"]
    a_alpha = data["stability"]["a_alpha"]
    worst = max(abs(row["error_deg"]) for row in a_alpha.values())
    recon = data["reconstruction"]
    rnd = data["stiffness"]["random"]
    claims = [
        Claim(section="stiffness", status="measured",
              text=("A(alpha) of BDF1-6 measured from the boundary locus: "
                    + ", ".join(f"{row['alpha_deg']:.4f}" for row in a_alpha.values())
                    + f" deg, within {worst:.2g} deg of Hairer & Wanner; BDF7 is not zero-stable")),
        Claim(section="stiffness", status="measured",
              text=(f"is (13) stiff along the paper run? {'YES' if ans['stiff'] else 'NO'}: max |h lambda| = "
                    f"{ans['max_abs_h_lambda']:.3g} at h = {data['period_s']:g} s; explicit RK4 stays stable up to h = "
                    + ("any step searched" if ans["rk4_first_unstable_step_s"] is None
                       else f"{ans['rk4_first_unstable_step_s']:.3g} s"))),
        Claim(section="stiffness", status="sampled",
              text=(f"{rnd['count']} random scenarios (seed {rnd['seed']}): max |h lambda| = "
                    f"{rnd['max_abs_h_lambda']:.3g}, max stiffness ratio {rnd['max_stiffness_ratio']:.3g}")),
        Claim(section="stiffness", status="measured",
              text=(f"reconstruction at h = {data['period_s']:g} s: BDF4 {recon['bdf4']['max_error_px']:.3g} px, RK4 "
                    f"{recon['rk4']['max_error_px']:.3g} px, Euler {recon['euler']['max_error_px']:.3g} px; what limits "
                    f"it is the screw under zero-order hold (sampling floor {ans['sampling_floor_px']:.3g} px), not the "
                    "BDF order (from order 3 on)")),
    ]
    return data, claims, figures


def _figure_study(study: Any) -> Any:
    """What the stiffness figures plot: the study with every plotted float to
    :data:`~visnav.app.precision.FIGURE_DIGITS` digits, the integration errors of the reconstruction problem
    at least :data:`~visnav.app.precision.ACCURACY_FLOOR` (below, round-off of the references: drawn on the
    fit floor) and the observed orders as the report prints them."""
    import dataclasses

    plots = quantise_for_figure(dict(study.plots))
    for key in ("paper_accuracy", "reference_accuracy", "verification"):
        rows = plots.get(key, {})
        for row in rows.values():
            if key != "verification" and "errors" in row:
                row["errors"] = [round_value(e, "accuracy_error") for e in row["errors"]]
            if row.get("observed_order") is not None:
                row["observed_order"] = round_value(row["observed_order"], "order")
    return dataclasses.replace(study, plots=plots, data=round_section("stiffness", study.data))


def _fuzzing_section(scenario: Scenario, options: ReportOptions) -> tuple[dict[str, Any], list[Claim], dict]:
    from visnav.fuzzing import PAPER, PROPERTIES, RESOLVED, counterexample_to_json, fuzz_property

    # the quick report leaves out the closed-loop (scenario) properties: one example is a whole simulation
    names = [n for n, p in PROPERTIES.items() if not (options.quick and p.kind == "scenario")]
    data: dict[str, Any] = {"examples_per_property": options.fuzz_examples, "seed": options.seed,
                            "shrunk": not options.quick, "properties": names, "variants": {}}
    claims = []
    for variant in (RESOLVED, PAPER):
        results = [fuzz_property(n, variant=variant, examples=min(options.fuzz_examples, PROPERTIES[n].ci_examples),
                                 seed=options.seed, shrink=not options.quick) for n in names]
        rows = [r.as_dict() for r in results]
        counterexamples = {r.name: json.loads(counterexample_to_json(r.counterexample))
                           for r in results if r.counterexample is not None}
        failed = [r.name for r in results if not r.passed]
        data["variants"][variant] = {"passed": not failed, "properties": rows, "counterexamples": counterexamples}
        total = sum(r.examples for r in results)
        if variant == RESOLVED:
            text = (f"fuzzing the resolved supervisor: {len(rows) - len(failed)} of {len(rows)} properties held on "
                    f"{total} hypothesis examples (seed {options.seed})"
                    + (f"; FAILED: {', '.join(failed)}" if failed else ""))
        else:
            text = (f"fuzzing the paper's flag logic as written: {len(failed)} of {len(rows)} properties fail "
                    f"({', '.join(failed) or 'none'}), each with a "
                    + ("replayable counterexample (not shrunk in the quick report)" if options.quick
                       else "shrunk, replayable counterexample"))
        claims.append(Claim(section="fuzzing", status="sampled", text=text))
    return data, claims, {}


def _campaign_section(scenario: Scenario, options: ReportOptions) -> tuple[dict[str, Any], list[Claim], dict]:
    from visnav.studies.campaign import CampaignSpec, InlineExecutor, process_pool, run_campaign, summarise

    spec = CampaignSpec(scenario=scenario, samples=options.campaign_samples, seed=options.seed)
    results: list[Any] = []
    # the results depend on (seed, index) only, not on the executor: two processes for the full report
    executor = InlineExecutor() if options.quick else process_pool(2)
    with executor:
        run_campaign(spec, executor, results.append)
    data = round_section("campaign", {"spec": {k: v for k, v in spec.as_dict().items() if k != "scenario_toml"},
                                      "summary": summarise(spec, results).as_dict()})
    summary = data["summary"]
    rate, interval = summary["success_rate"], summary["success_interval_95"]
    counts = ", ".join(f"{k} {v}" for k, v in summary["counts"].items() if v)
    claims = [Claim(
        section="campaign", status="sampled",
        text=(f"Monte-Carlo campaign of {summary['samples_done']} perturbed scenarios (seed {options.seed}): "
              f"success rate {rate:.3g} (95 % Wilson interval [{interval[0]:.3g}, {interval[1]:.3g}]); "
              f"outcomes: {counts}; median clearance {summary['clearance_quantiles_m'].get('0.5', float('nan')):.3g} m"),
    )]
    return data, claims, {}


def _verification_section(scenario: Scenario, options: ReportOptions, source: str) -> Section:
    """The generic verification section of the scenario's problem (:func:`visnav.verification.paper_problem`)."""
    from analysis.verify.verdicts import verify

    from visnav.app.verification_report import verification_section
    from visnav.verification import paper_problem

    problem = paper_problem(scenario)
    result = verify(problem, budget=options.verify_budget, seed=options.seed)
    return verification_section(problem, result, spec="paper", options={"scenario": source})


def _saturated_section(scenario: Scenario, options: ReportOptions, source: str) -> Section:
    """The same verification for the saturated loop (``paper_problem(scenario, "saturated")``: the applied
    commands clipped to ``[limits]``), with the same budget and seed: its own verdict table, figures and
    counterexample files (``counterexamples/saturated~NAME.json``); the report's verdict stays the first section's.
    """
    from analysis.verify.verdicts import verify

    from visnav.app.verification_report import verification_section
    from visnav.verification import SATURATED, paper_problem

    problem = paper_problem(scenario, SATURATED)
    result = verify(problem, budget=options.verify_budget, seed=options.seed)
    return verification_section(problem, result, spec="paper", options={"scenario": source, "variant": SATURATED},
                                name="saturated")


_SECTIONS: tuple[tuple[str, Callable[..., tuple[dict[str, Any], list[Claim], dict]]], ...] = (
    ("model", _model_section),
    ("simulation", _simulation_section),
    ("analysis", _analysis_section),
    ("stiffness", _stiffness_section),
    ("fuzzing", _fuzzing_section),
    ("campaign", _campaign_section),
)
"""The case study's own sections, after the verification."""


def build_report(scenario: Scenario, options: ReportOptions | None = None, *,
                 progress: Progress | None = None, source: str | None = None) -> Report:
    """Verify ``scenario``'s requirements, run every study on it and assemble the report.

    Parameters
    ----------
    scenario : Scenario
    options : ReportOptions, optional
        Default: the full report with seed 0.
    progress : callable, optional
        Called with the name of each section as it starts (for a progress display).
    source : str, optional
        How the scenario was named (built-in name or TOML path; default its name): written into the
        counterexample files (``visnav replay`` loads it) and the regeneration command.

    Returns
    -------
    Report
    """
    import functools
    import time

    from visnav.app.verification_report import assemble_report, report_command
    from visnav.scenario import scenario_digest

    options = options or ReportOptions()
    source = source or scenario.name
    sections: list[tuple[str, Section]] = []
    timings: dict[str, float] = {}
    verification = functools.partial(_verification_section, source=source)
    saturated = functools.partial(_saturated_section, source=source)
    for name, build in (("verification", verification), ("saturated", saturated), *_SECTIONS):
        if progress is not None:
            progress(name)
        start = time.perf_counter()
        built = build(scenario, options)
        if not isinstance(built, Section):
            data, claims, figures = built
            built = Section(data=data, claims=tuple(claims), figures=figures)
        sections.append((name, built))
        timings[name] = time.perf_counter() - start
    meta = {
        "tool": "visnav report",
        "scenario": scenario.name,
        "scenario_digest": scenario_digest(scenario),
        "automaton_digest": dict(sections)["model"].data["automaton"]["digest"],  # computed once, by the model section
        "quick": options.quick,
        "seeds": {"report": options.seed},
        "budgets": {"verify_budget": options.verify_budget, "check_samples": options.check_samples,
                    "fuzz_examples": options.fuzz_examples, "campaign_samples": options.campaign_samples},
        "command": report_command(f"--scenario {source}", quick=options.quick, seed=options.seed,
                                  budget=options.verify_budget),
        "versions": dependency_versions(),
    }
    return assemble_report(meta, sections, timings)
