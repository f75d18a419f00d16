"""The ``visnav`` command line.

Subcommands print a human summary, or with ``--json`` one JSON object on
standard output.  Exit codes: 0 success, 1 the run finished but the task
failed (collision, timeout; for ``verify`` and ``report``: a requirement is
falsified), 2 bad input (scenario, problem, options, output folder), 3 the
simulation diverged (for ``verify`` and ``report``: a simulation of the
verification diverged and nothing was falsified).
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import sys
from pathlib import Path
from collections.abc import Sequence
from typing import Any

from visnav.app.cli_types import (
    EXIT_BAD_INPUT,
    EXIT_DIVERGED,
    EXIT_INCOMPLETE,
    EXIT_OK,
    EXIT_TASK_FAILED,
    non_negative_int,
    positive_int,
    positive_seconds,
)

__all__ = ["main", "build_parser", "REPORT_NUMERICS"]



class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse exits with 2 too; keep its usage line
        self.print_usage(sys.stderr)
        self.exit(EXIT_BAD_INPUT, f"visnav: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``visnav``."""
    parser = _Parser(prog="visnav", description="Verify the Folio & Cadenat switching controller as a hybrid automaton.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    sim = sub.add_parser("simulate", help="run a scenario's closed loop, write its data and figures")
    sim.add_argument("--scenario", default="paper", help="built-in scenario name or path to a TOML file (default: paper)")
    sim.add_argument("--out", default=None, help="folder for trajectory.csv, summary.json and the figures")
    sim.add_argument("--json", action="store_true", help="print one JSON object instead of the human summary")
    sim.add_argument("--no-figures", action="store_true", help="skip the figures (data and summary only)")
    sim.set_defaults(func=_cmd_simulate)
    graph = sub.add_parser("mode-graph", help="print the supervisor's mode graph (Graphviz DOT or JSON)")
    graph.add_argument("--scenario", default="paper")
    graph.add_argument("--problem", default=None, metavar="SPEC",
                       help="the automaton of a verification problem instead (PKG.MOD:OBJ or FILE.py:OBJ, or a "
                            "SpaceEx model FILE.xml[:COMPONENT] with --config FILE.cfg: the flattened automaton)")
    graph.add_argument("--config", default=None, metavar="FILE.cfg",
                       help="with --problem FILE.xml[:COMPONENT]: the SpaceEx configuration (docs/spaceex.md)")
    graph.add_argument("--format", choices=("dot", "json"), default="dot",
                       help="dot: Graphviz with guards and resets as labels; json: the automaton's description")
    graph.set_defaults(func=_cmd_mode_graph)
    ana = sub.add_parser("analyse", help="linearisation, Lyapunov certificate, admissible gains, stability margins")
    ana.add_argument("--scenario", default="paper", help="built-in scenario name or path to a TOML file")
    ana.add_argument("--problem", default=None, metavar="SPEC",
                     help="the stability analysis of a verification problem instead (PKG.MOD:OBJ or FILE.py:OBJ, "
                          "built with hybrid_problem(..., stability=True)): equilibria against their modes, LMI "
                          "certificates, periodic orbits")
    ana.add_argument("--clearance", type=float, default=None,
                     help="clearance [m] the admissible gains must guarantee (default: 0.1)")
    ana.add_argument("--sos", choices=("scan", "scenario", "off"), default="scan",
                     help="the sum-of-squares study of path following: with the scan of k (default, about 20 s), "
                          "at the scenario's k only (about 10 s), or off")
    ana.add_argument("--json", action="store_true", help="print the analysis as one JSON object")
    ana.add_argument("--out", default=None, help="folder for analysis.json and the figures (Bode, Nyquist, "
                                                 "margins and eigenvalues against the gains)")
    ana.set_defaults(func=_cmd_analyse)
    rep = sub.add_parser("report", help="the verification report of a scenario or of any verification problem: "
                                        "report.md, report.html, report.json, the figures and the counterexamples")
    rep.add_argument("--scenario", default=None, help="built-in scenario name or path to a TOML file (default: "
                                                      "paper); with --problem paper: the scenario verified")
    rep.add_argument("--problem", default=None, metavar="SPEC",
                     help="report a verification problem instead: paper, package.module:OBJECT or "
                          "path/to/file.py:OBJECT (the verification and the structural checks only)")
    rep.add_argument("--config", default=None, metavar="FILE.cfg",
                     help="with --problem FILE.xml[:COMPONENT]: the SpaceEx configuration (docs/spaceex.md)")
    rep.add_argument("--out", default=None, help="output folder (default: reports/<scenario or problem>)")
    rep.add_argument("--quick", action="store_true", help="smaller budgets (verification, structural samples, "
                                                          "fuzzing, campaign, stiffness grid): about a minute")
    rep.add_argument("--seed", type=non_negative_int, default=0, help="seed of every random study (default: 0)")
    rep.add_argument("--budget", type=positive_int, default=None,
                     help="simulations of the verification (default: 120, with --quick 16)")
    rep.add_argument("--json", action="store_true", help="print report.json's verdict and claims summary as JSON")
    rep.set_defaults(func=_cmd_report)
    chk = sub.add_parser("check-model", help="structural checks of the supervisor automaton (hybrid.check)")
    chk.add_argument("--scenario", default="paper", help="built-in scenario name or path to a TOML file")
    chk.add_argument("--samples", type=positive_int, default=300,
                     help="uniform samples per mode for the state-space checks (default: 300)")
    chk.add_argument("--starts", type=positive_int, default=8, help="optimiser starts per question (default: 8)")
    chk.add_argument("--seed", type=int, default=0, help="seed of the sampling (default: 0)")
    chk.add_argument("--json", action="store_true", help="print the report as one JSON object")
    chk.add_argument("--problem", default=None, metavar="SPEC",
                     help="check a verification problem's automaton instead (its own box; PKG.MOD:OBJ or FILE.py:OBJ, "
                          "or a SpaceEx model FILE.xml[:COMPONENT] with --config FILE.cfg)")
    chk.add_argument("--config", default=None, metavar="FILE.cfg",
                     help="with --problem FILE.xml[:COMPONENT]: the SpaceEx configuration (docs/spaceex.md)")
    chk.add_argument("--method", choices=("auto", "sampled", "smt"), default=None,
                     help="auto: decide the symbolic modes with the SMT solver (PROVEN), sample the others "
                          "(SAMPLED); sampled: sample every mode; smt: decide only (default: auto)")
    chk.add_argument("--timeout", type=positive_seconds, default=None, metavar="SECONDS",
                     help="timeout of one solver call [s]; a call that times out leaves its answer undecided "
                          "(default: 5)")
    chk.add_argument("--search-budget", type=positive_seconds, default=None, metavar="SECONDS",
                     help="wall-clock budget of the sampled searches [s]; modes left when it runs out are not "
                          "searched and the report is INCOMPLETE (default: 120)")
    chk.add_argument("--parametric", action="store_true",
                     help="also decide which pairs of transitions are exclusive for EVERY admissible envelope "
                          "(0 < d- < d0 < d+, 0 < D- < D0 < D+, hysteresis > 0, 0 < arm < pi/2), not only the "
                          "scenario's values")
    chk.set_defaults(func=_cmd_check_model)
    from visnav.app.cli_sweep import add_parser as _add_sweep; _add_sweep(sub)
    from visnav.app.cli_stiffness import add_parser as _add_stiffness; _add_stiffness(sub)
    from visnav.app.cli_fuzz import add_parser as _add_fuzz; _add_fuzz(sub)
    from visnav.app.cli_verify import add_parser as _add_verify; _add_verify(sub)
    from visnav.app.cli_reach import add_parser as _add_reach; _add_reach(sub)
    return parser






def _build_problem_report(args: argparse.Namespace, options: Any, progress: Any) -> Any:
    """``visnav report --problem SPEC``: load the problem and build its generic report.

    Returns the report, the folder as shown (``--out`` or ``reports/NAME``), the folder written
    (anchored at the starting folder) and the problem's name."""
    from visnav.app.cli_verify import load_verification_problem
    from visnav.app.files import prepare_output_dir
    from visnav.app.ownership import anchored, check_requirement_names, safe_name
    from visnav.app.report_files import check_report_folder
    from visnav.app.verification_report import build_problem_report

    loading = {} if args.scenario is None else {"scenario": args.scenario}
    if args.config is not None:
        loading["config"] = args.config
    problem = load_verification_problem(args.problem, loading, None)
    check_requirement_names(problem.requirement_names, f"problem {problem.name!r}")
    shown = Path(args.out if args.out is not None else "reports/" + safe_name(
        "the problem's name (VerificationProblem.name)", problem.name,
        "rename the problem, or give --out FOLDER"))
    folder = prepare_output_dir(anchored(args, shown))
    check_report_folder(folder, shown)  # the report replaces the folder whole: refused before the work
    report = build_problem_report(problem, spec=args.problem, options=loading, seed=options.seed,
                                  budget=options.verify_budget, quick=options.quick, progress=progress)
    return report, shown, folder, problem.name


def _scenario_report_folder(args: argparse.Namespace, scenario: Any) -> tuple[Path, Path]:
    """The folder of ``visnav report --scenario``, as shown and as written (anchored), checked before the work:
    the scenario's name (the default ``reports/NAME``) and its requirement names (file names) must be plain
    names, and the report may replace the folder (:func:`~visnav.app.report_files.check_report_folder`)."""
    from visnav.app.files import prepare_output_dir
    from visnav.app.ownership import anchored, check_requirement_names, safe_name
    from visnav.app.report_files import check_report_folder

    check_requirement_names((r.name for r in scenario.requirements), f"scenario {scenario.name!r}")
    shown = Path(args.out if args.out is not None else "reports/" + safe_name(
        f"the scenario's name (name in {args.scenario or 'paper'})", scenario.name,
        "rename the scenario (its name = ...), or give --out FOLDER"))
    folder = prepare_output_dir(anchored(args, shown))
    check_report_folder(folder, shown)  # the report replaces the folder whole: refused before the work
    return shown, folder


def _verdict_lines(rows: list[dict[str, Any]], folder: Any, spec: str, most: int = 10) -> list[str]:
    """One line per requirement; beyond ``most`` the ones not falsified are counted, not listed."""
    from visnav.app.cli_verify import replay_command

    shown = rows if len(rows) <= most else [r for r in rows if r["verdict"] != "not_falsified"]
    lines = [f"  {r['verdict']:<14} {r['name']}"
             + (f"  replay: {replay_command(folder / r['counterexample_file'], spec)}" if r["counterexample_file"]
                else "") for r in shown]
    if len(shown) < len(rows):
        lines.append(f"  not_falsified  {len(rows) - len(shown)} other requirement(s) (report.md has the table)")
    return lines


def _cmd_report(args: argparse.Namespace) -> int:
    import time

    from analysis.falsification import FalsificationError, SimulationFailed
    from analysis.loading import ProblemLoadError
    from hybrid.errors import ParameterError

    from visnav.app.ownership import anchored
    from visnav.app.report import ReportOptions, build_report
    from visnav.app.report_files import check_report_folder, write_report
    from visnav.app.verification_report import VERDICT_LABELS
    from visnav.scenario import load_scenario

    def show(name: str) -> None:
        print(f"visnav report: {name} ...", file=sys.stderr, flush=True)

    progress = show if sys.stderr.isatty() else None
    options = ReportOptions.for_mode(quick=args.quick, seed=args.seed, verify_budget=args.budget)
    start = time.perf_counter()
    try:
        if args.problem is not None:
            if args.out is not None:  # refused before the work (the default folder needs the problem's name)
                check_report_folder(anchored(args, args.out), args.out)
            report, shown, folder, subject = _build_problem_report(args, options, progress)
        else:
            scenario = load_scenario(args.scenario or "paper")
            shown, folder = _scenario_report_folder(args, scenario)
            report = build_report(scenario, options, progress=progress, source=args.scenario or "paper")
            subject = scenario.name
    except ProblemLoadError as error:
        if error.user_traceback:
            print(error.user_traceback.rstrip(), file=sys.stderr)
        print(f"visnav: error: {error.render()}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except SimulationFailed as error:
        print(f"{error.traceback.rstrip()}\nvisnav: error: {error}\nyour simulator raised (your code's traceback "
              "above)", file=sys.stderr)
        return EXIT_BAD_INPUT
    except ParameterError as error:  # FalsificationError, or a problem the user built wrongly
        if args.problem is None and not isinstance(error, FalsificationError):
            raise  # the scenario's own studies: not the user's input
        print(f"visnav: error: {error.render()}", file=sys.stderr)
        return EXIT_BAD_INPUT
    written = [shown / path.relative_to(folder) for path in write_report(report, folder, shown)]
    folder = shown
    elapsed = time.perf_counter() - start
    counts, verdict = report.data["claim_counts"], report.data["verdict"]
    code = report.data["exit_code"]  # the verification's, or 1 for a structural error (REPORT_EXIT_CODES)
    # the scenario's own task (its nominal simulation): a failed task is a failed report, as for `simulate`
    metrics = report.data.get("simulation", {}).get("metrics")
    task_achieved = None if metrics is None else bool(metrics["success"])
    if task_achieved is False:
        code = EXIT_TASK_FAILED
    if args.json:
        print(json.dumps({"problem" if args.problem is not None else "scenario": subject, "out": str(folder),
                          "verdict": verdict, "task_achieved": task_achieved, "exit_code": code,
                          "claim_counts": counts, "files": [str(p) for p in written]}, sort_keys=True))
    else:
        task = "" if task_achieved is not False else (
            f"; TASK FAILED in the nominal simulation ({metrics['termination']}"
            f"{', collision' if metrics.get('collided') else ''})")
        lines = [f"visnav report {subject}{' (quick)' if args.quick else ''}: {VERDICT_LABELS[verdict]}{task}; "
                 f"{counts['proven']} proven, {counts['measured']} measured, {counts['sampled']} sampled claims in "
                 f"{elapsed:.1f} s"]
        lines += _verdict_lines(report.data["verification"]["requirements"], folder,
                                report.data["verification"].get("source") or "paper")
        if "saturated" in report.data:  # the loop clipping its commands: its own verdict, not the report's
            saturated = report.data["saturated"]
            lines.append(f"  saturated loop ({saturated['problem']}): {VERDICT_LABELS[saturated['verdict']]}")
            lines += _verdict_lines(saturated["requirements"], folder, saturated.get("source") or "paper")
        errors = report.data["structural_errors"]
        if errors["count"]:
            lines.append(f"  structural     {errors['count']} error(s): {', '.join(errors['kinds'])} "
                         f"(report.md, section {' and '.join(errors['sections'])})")
        for line in errors.get("undecided", ())[:5]:
            lines.append(f"  not decided    {line}")
        lines += [f"  {name:<12} {seconds:6.1f} s" for name, seconds in report.timings_s.items()]
        lines += [f"  wrote {p}" for p in written]
        print("\n".join(lines))
    return code


def _summary(result: Any, digest: str) -> dict[str, Any]:
    out = {"scenario": result.scenario.name, "scenario_digest": digest}
    out.update(result.metrics.as_dict())
    out["wall_time_s"] = result.wall_time_s
    out["real_time_factor"] = result.metrics.sim_time_s / result.wall_time_s if result.wall_time_s > 0 else None
    return out


def _trajectory_csv(result: Any) -> str:
    trace = result.trace
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    header = ["t_s", "jump", "mode", *trace.state_names, *trace.input_names, *trace.variable_names, *trace.record_names]
    writer.writerow(header)
    for k in range(len(trace.times)):
        row: list[Any] = [repr(float(trace.times[k])), int(trace.jumps[k]), trace.mode_names[int(trace.modes[k])]]
        for block in (trace.states[k], trace.inputs[k], trace.signals[k], trace.records[k]):
            row.extend(repr(float(v)) for v in block)
        writer.writerow(row)
    return buffer.getvalue()


def _human(summary: dict[str, Any], written: list[str]) -> str:
    def fmt(value: Any) -> str:
        if isinstance(value, float):
            return f"{value:.6g}"
        if value is None:
            return "inf"
        return str(value)

    lines = [
        f"scenario {summary['scenario']} ({summary['scenario_digest'][:12]}): {summary['termination']}",
        f"  success                     {fmt(summary['success'])}",
        f"  collided                    {fmt(summary['collided'])}",
        f"  min clearance               {fmt(summary['min_clearance_m'])} m",
        f"  final feature error         {fmt(summary['final_feature_error_px'])} px",
        f"  occlusion (>=1 hidden)      {fmt(summary['occlusion_duration_s'])} s"
        f"  (all hidden {fmt(summary['all_hidden_duration_s'])} s)",
        f"  max |s - s~| while hidden   {fmt(summary['max_reconstruction_error_px'])} px",
        f"  max |z - z~| while hidden   {fmt(summary['max_depth_error_mm'])} mm",
        f"  max |v|, |w|, |pan rate|    {', '.join(fmt(v) for v in summary['max_abs_input'])}"
        f"  (within limits: {summary['within_actuator_limits']})",
        f"  transitions                 {len(summary['transitions'])}  (chatter: {summary['chatter_count']})",
        f"  modes visited               {' -> '.join(summary['modes_visited'])}",
        f"  simulated {fmt(summary['sim_time_s'])} s in {summary['steps']} steps, "
        f"wall {fmt(summary['wall_time_s'])} s ({fmt(summary['real_time_factor'])}x real time)",
    ]
    lines += [f"  wrote {path}" for path in written]
    return "\n".join(lines)


def _cmd_simulate(args: argparse.Namespace) -> int:
    from visnav.app.files import prepare_output_dir, write_figures, write_text_atomic
    from visnav.scenario import load_scenario, scenario_digest
    from visnav.simulation import simulate

    scenario = load_scenario(args.scenario)
    folder = prepare_output_dir(args.out) if args.out else None
    result = simulate(scenario)
    summary = _summary(result, scenario_digest(scenario))
    written: list[str] = []
    if folder is not None:
        write_text_atomic(folder / "trajectory.csv", _trajectory_csv(result))
        write_text_atomic(folder / "summary.json", json.dumps(summary, indent=2, sort_keys=True) + "\n")
        written += [str(folder / "trajectory.csv"), str(folder / "summary.json")]
        if not args.no_figures:
            from visnav.app.figures import paper_figures

            written += [str(path) for path in write_figures(folder, paper_figures(result)).values()]
    if args.json:
        print(json.dumps(summary, sort_keys=True))
    else:
        print(_human(summary, written))
    return EXIT_OK if summary["success"] else EXIT_TASK_FAILED


def _user_problem(spec: str, config: str | None = None) -> Any:
    """The verification problem ``spec`` names (a SpaceEx model with its ``config``), or the exit code of a bad
    one (the message printed)."""
    from hybrid.errors import ParameterError

    from visnav.app.cli_verify import load_verification_problem

    try:
        return load_verification_problem(spec, {} if config is None else {"config": config}, None)
    except ParameterError as error:
        trace = getattr(error, "user_traceback", "")
        if trace:
            print(trace.rstrip(), file=sys.stderr)
        print(f"visnav: error: {error.render()}", file=sys.stderr)
        return EXIT_BAD_INPUT


def _cmd_mode_graph(args: argparse.Namespace) -> int:
    from hybrid import to_dot, to_json

    from visnav.scenario import load_scenario
    from visnav.supervisor import build_supervisor

    if args.problem is not None:
        problem = _user_problem(args.problem, args.config)
        if isinstance(problem, int):
            return problem
        automaton = problem.automaton
        if automaton is None:
            print(f"visnav: error: problem {problem.name!r} declares no automaton (VerificationProblem.automaton); "
                  "build it with analysis.problems.hybrid_problem or sampled_problem, or set automaton=",
                  file=sys.stderr)
            return EXIT_BAD_INPUT
    else:
        scenario = load_scenario(args.scenario)
        automaton = build_supervisor(scenario.envelopes, scenario.supervisor, len(scenario.obstacles)).automaton
    if args.format == "json":
        print(json.dumps(to_json(automaton), sort_keys=True, indent=2))
    else:
        print(to_dot(automaton), end="")
    return EXIT_OK


CHECK_DEFAULT_METHOD, CHECK_DEFAULT_TIMEOUT_S = "auto", 5.0
"""``visnav check-model``'s ``--method`` and ``--timeout`` when not given."""
_CHECK_EXIT = {"clean": EXIT_OK, "finding": EXIT_TASK_FAILED, "incomplete": EXIT_INCOMPLETE}
"""``check-model``'s exit code per :func:`visnav.app.structural.verdict_line` verdict: 0 only when complete and clean."""
_MOST_FINDINGS = 20
"""Errors and warnings written out one per line in the human summary (``--json`` has them all)."""


def cli_words(text: str) -> str:
    """A library message in the command line's words (:func:`visnav.app.cli_verify.cli_words`)."""
    from visnav.app.cli_verify import cli_words as words

    return words(text)


def _check_human(report: Any, source: str, elapsed: float, *, method: str, timeout_s: float | None,
                 box: str = "declared box") -> str:
    """The check report in words; ``source`` says where the automaton comes from (``"scenario paper"``).

    One line per check with its claim (PROVEN, FOUND, SAMPLED, UNDECIDED, SKIPPED) and how it was
    answered, the pairs of transitions sharing a mode, the Zeno cycles grouped in one line, then the
    errors and warnings (the first :data:`_MOST_FINDINGS`) and the infos counted by kind.
    ``timeout_s`` is ``None`` when the problem's own structural callable chose it.
    """
    from visnav.app.structural import claim_label, claims_table, pairs_line, verdict_line, zeno_line

    modes = report.searched.modes
    sampled = [m for m in modes if m.samples > 0]
    decided = [m for m in modes if any(note.startswith("decided by the SMT solver") for note in m.notes)]
    solver = getattr(report, "solver", "")
    how = [f"method {method}"]
    if decided:
        how.append(f"{len(decided)} decided by {solver or 'the SMT solver'}"
                   + ("" if timeout_s is None else f" (timeout {timeout_s:g} s per solver call)"))
    neither = [m for m in modes if any(note.startswith("not decided") for note in m.notes)]
    if neither:
        how.append(f"{len(neither)} neither decided nor sampled (functions not symbolic)")
    if all(m.box is None for m in modes):
        box = "mode graph only (no box given)"
    if sampled:
        how.append(f"{len(sampled)} sampled (seed {report.searched.seed}, {report.searched.samples} samples + "
                   f"corners + face samples per mode, {report.searched.starts} optimiser starts per question)")
    lines = [
        f"check-model {report.automaton} ({source}): {verdict_line(report)[1]}",
        f"  checked {len(modes)} modes over the {box}: " + "; ".join(how) + f"; {elapsed:.1f} s",
    ]
    if modes and modes[0].box is not None:
        lines.append(f"  box: {modes[0].box}")
    claims = claims_table(report)
    claimed = {row["check"] for row in claims}
    graph_kinds = {"unreachable": ("unreachable_mode", "unreachable_transition"), "sink_mode": ("sink_mode",)}
    kinds = {f.kind for f in report.findings}
    for name, status in report.searched.checks.items():  # the graph checks, exact
        if name in graph_kinds:
            label = "FOUND" if any(k in kinds for k in graph_kinds[name]) else "PROVEN"
            lines.append(f"  {name:<24} {label:<9} exact, on the mode graph" + ("" if status == "ran" else
                                                                                 f" ({status})"))
        elif name not in claimed and name != "zeno_candidate":
            lines.append(f"  {name:<24} {status}")
    for row in claims:
        extra = f" ({row['detail']})" if row["detail"] and row["check"] != "zeno" else ""
        lines.append(f"  {row['check']:<24} {claim_label(row['status']):<9} {row['method']}{extra}")
    if not claims:  # a report without claims (a user's own structural callable)
        lines += [f"  {name:<24} {status}" for name, status in report.searched.checks.items()
                  if name == "zeno_candidate"]
    pairs = pairs_line(getattr(report, "pairs", ()), report.findings)
    if pairs:
        lines.append(f"  pairs: {pairs}")
    zeno = zeno_line(getattr(report, "zeno", None), report.findings)
    if zeno:
        lines.append(f"  Zeno: {zeno}")
        rates: dict[str, float] = {}
        for per_mode in report.zeno.rates.values():
            for name, rate in per_mode.items():
                rates[name] = max(rates.get(name, 0.0), rate)
        finite = {name: rate for name, rate in rates.items() if rate < float("inf")}
        if finite:
            lines.append("  rate bounds of the dwell times [unit/s]: "
                         + ", ".join(f"{name} {rate:.4g}" for name, rate in finite.items()))
    elif report.searched.cycles_found:
        capped = "+" if report.searched.cycles_capped else ""
        why = report.claims["zeno"].detail if "zeno" in report.claims else f"method {method}"
        lines.append(f"  Zeno: {report.searched.cycles_found}{capped} cycle(s) of the mode graph not decided "
                     f"({why}): one zeno_candidate info")
    assumptions = list(dict.fromkeys(a for name in claimed for a in report.claims[name].assumptions
                                     if report.claims[name].status == "proven"))
    if assumptions:
        lines.append("  PROVEN over: " + "; ".join(assumptions))
    if sampled:
        lines.append("  sampled modes: memory held at its initial value except what resets write along a chain "
                     "of jumps")
    serious = [f for f in report.findings if f.severity != "info"]
    for finding in serious[:_MOST_FINDINGS]:
        lines.append(f"  [{finding.severity}] {finding.kind}: {finding.message}")
    if len(serious) > _MOST_FINDINGS:
        lines.append(f"  ... and {len(serious) - _MOST_FINDINGS} more error(s)/warning(s) (--json lists them all)")
    by_kind: dict[str, int] = {}
    for finding in report.findings:
        if finding.severity == "info":
            by_kind[finding.kind] = by_kind.get(finding.kind, 0) + 1
    for kind, count in sorted(by_kind.items()):
        lines.append(f"  [info] {kind}: {count}")
    return "\n".join(lines)


def _sos_human(sos: dict[str, Any] | None) -> list[str]:
    """The SOS study's lines of ``visnav analyse`` (beside the hand-given V's)."""
    if sos is None:
        return ["  SOS study                   left out (--sos off)"]
    region = sos["region"]
    lines = [f"  SOS region (degree {region['degree']})       {region['status'].upper()}: {{V <= 1}} invariant, area "
             f"{region['area_ratio']:.4g} x the hand-given sublevel set ({region['boxes']} boxes; {region['why']})"]
    for b in sos["bypass"]:
        hand, best = b["hand_closed_form"]["nominal"], b["combined"]
        lines.append(f"  SOS bypass alpha0 = {b['alpha0_rad']:.4g}  {b['status'].upper()}: |delta| <= "
                     f"{best['delta_max_m']:.4g} m (clearance >= {best['min_distance_m']:.4g} m), |omega| <= "
                     f"{best['omega_max_radps']:.4g} rad/s (hand V: {hand['delta_max_m']:.4g} m, "
                     f"{hand['omega_max_radps']:.4g} rad/s)")
    lines.append(f"  SOS admissible k            {sos['admissible']['finding']}"
                 + ("" if sos["scan"] else " (--sos scenario: only the scenario's k judged)"))
    return lines


def _analyse_human(d: dict[str, Any]) -> str:
    pf = d["path_following"]
    lyap = pf["lyapunov"]
    par = pf["parameters"]
    eig = ", ".join(f"{re:.6g}" + (f"{im:+.6g}j" if im else "") for re, im in pf["eigenvalues"])
    region = ", ".join(f"{n} in [{lo:.4g}, {hi:.4g}]" for n, (lo, hi) in lyap["region"].items())
    lines = [
        f"analyse {d['scenario']}: path following k = {par['k']:g} 1/m, v_coll = {par['v_coll_mps']:g} m/s",
        f"  eigenvalues (AD)            {eig}   [{pf['finding']}]",
        f"  V = k d^2/2 + 1 - cos(a):   V' = {lyap['normal_form']}",
        f"  certificate                 {'PROVEN' if lyap['certified'] else 'NOT PROVEN'} V' <= 0 on {region} "
        f"({lyap['boxes']} boxes, interval branch and bound)",
        f"  LaSalle                     {lyap['lasalle']}",
    ]
    for entry, bound in zip(pf["entry_states"], pf["entry_bounds"]):
        lines.append(
            f"  entry {entry['obstacle']:<8} (sampled)  alpha0 = {entry['alpha_rad']:.4g} rad: |delta| <= "
            f"{bound['delta_max_m']:.4g} m (closest {bound['min_distance_m']:.4g} m), |omega| <= "
            f"{bound['omega_max_radps']:.4g} rad/s"
        )
    lines.append(f"  admissible k                {pf['admissible']['finding']}")
    lines += _sos_human(pf["sos"])
    sw = pf["switched"]
    lines.append(f"  switched family             {sw['finding']} [{sw['claim'].upper()}: {sw['recheck']['method']}] "
                 f"({sw['family']})")
    goal = d["goal"]
    task = ", ".join(f"{re:.6g}" for re, _ in goal["visual_servoing_task"]["eigenvalues"])
    full = ", ".join(f"{re:.3g}" for re, _ in goal["closed_loop"]["eigenvalues"])
    lines += [
        f"  goal: e_VS task (7)         eigenvalues {task} (closed form {goal['visual_servoing_task']['closed_form'][0]:g})",
        f"  goal: full loop (x,y,th,pan) eigenvalues {full}: {goal['closed_loop']['finding'].split(';')[0]}",
        f"                              zero mode {[round(c, 4) for c in goal['closed_loop']['zero_mode'] or []]} moves "
        f"the camera by {goal['closed_loop']['zero_mode_camera_motion'] or 0:.2g}: curve of equilibria (camera at "
        "its goal pose, base turned about it)",
        f"  goal: pan task (16)         eigenvalue {goal['pan_task']['eigenvalues'][0][0]:.6g}, "
        f"|e_gc' + lambda_gc e_gc| <= {goal['pan_task']['closure_residual']:.2g} along the way",
    ]
    for key, curve in d["margins_vs_gains"].items():
        gain_name = next(k for k in curve if k in ("k", "lambda_gc", "lambda_vs"))
        sampled = curve["sampled"]["stable_gain_range"]
        limit = curve["sampled"]["stability_limit"]
        grid = curve[gain_name]
        lines.append(
            f"  {key:<27} sampled loop stable for {gain_name} in "
            + (f"[{sampled[0]:.3g}, {sampled[1]:.3g}]" if sampled else "none")
            + f" of the grid [{grid[0]:.3g}, {grid[-1]:.3g}]"
            + (f"; unstable above {limit:.6g}" if limit is not None else "")
        )
    lines.append(f"  margins (continuous | sampled T = {d['sampling_period_s']:g} s, ZOH + 1 sample delay)")

    def fmt(value: Any, unit: str) -> str:
        return "inf" if value is None else f"{value:.4g}{unit}"

    for name, pair in d["margins"].items():
        c, s = pair["continuous"], pair["sampled"]
        lines.append(
            f"    {name:<12} GM {fmt(c['gain_margin_db'], ' dB'):>11} | {fmt(s['gain_margin_db'], ' dB'):>10}   "
            f"PM {fmt(c['phase_margin_deg'], '°'):>7} | {fmt(s['phase_margin_deg'], '°'):>7}   "
            f"DM {fmt(c['delay_margin_s'], ' s'):>9} | {fmt(s['delay_margin_s'], ' s'):>9}"
        )
    return "\n".join(lines)


def _stability_human(d: dict[str, Any]) -> str:
    lines = [f"analyse {d['system']}: {d['verdict'].upper()}"]
    lines += [f"  {c['status'].upper():<12} {c['text']}" + ("" if c["status"] != "not decided" else f" [{c['method']}]")
              for c in d["claims"]]
    orbit = d["orbit"]
    if orbit is not None:
        lines.append(f"  orbit: period {orbit['period']:.10g} s through {orbit['section']!r}, nontrivial multipliers "
                     f"{orbit['nontrivial_multipliers']}")
    return "\n".join(lines)


def _cmd_analyse_problem(args: argparse.Namespace) -> int:
    from visnav.app.figures_verification import orbit_figure
    from visnav.app.files import prepare_output_dir, write_figures, write_text_atomic
    from visnav.app.ownership import anchored

    problem = _user_problem(args.problem)
    if isinstance(problem, int):
        return problem
    if problem.stability is None:
        print(f"visnav: error: --problem {args.problem}: the problem {problem.name!r} has no stability analysis; "
              "expected a problem built with hybrid_problem(..., stability=True) (or a stability callable); "
              "fix: add stability=True where the problem is built", file=sys.stderr)
        return EXIT_BAD_INPUT
    # anchored where the command started: the user's module (imported above) may have changed the folder
    folder = prepare_output_dir(anchored(args, args.out)) if args.out else None
    analysis = problem.stability()
    out = analysis.as_dict()
    written = []
    if folder is not None:
        write_text_atomic(folder / "stability.json", json.dumps(out, indent=1, sort_keys=True) + "\n")
        written.append(str(Path(args.out) / "stability.json"))
        if analysis.orbit is not None:
            figures = write_figures(folder, {"stability_orbit": orbit_figure(analysis.orbit)})
            written += [str(Path(args.out) / p.name) for p in figures.values()]
    if args.json:
        print(json.dumps(out, sort_keys=True))
    else:
        print(_stability_human(out) + "".join(f"\n  wrote {path}" for path in written))
    # a stability that was not decided is never a pass: incomplete (5); an unstable system is a finding (1)
    return {"stable": EXIT_OK, "unstable": EXIT_TASK_FAILED}.get(analysis.verdict, EXIT_INCOMPLETE)


def _cmd_analyse(args: argparse.Namespace) -> int:
    from visnav.studies.loop_analysis import DEFAULT_CLEARANCE_M, analyse
    from visnav.scenario import load_scenario, scenario_digest

    from visnav.app.files import prepare_output_dir, write_figures, write_text_atomic

    if args.problem is not None:
        return _cmd_analyse_problem(args)
    scenario = load_scenario(args.scenario)
    folder = prepare_output_dir(args.out) if args.out else None
    clearance = DEFAULT_CLEARANCE_M if args.clearance is None else args.clearance
    try:
        result = analyse(scenario, clearance_m=clearance, sos=args.sos)
    except ValueError as err:
        print(f"visnav: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    out = result.as_dict()
    out["scenario_digest"] = scenario_digest(scenario)
    written = []
    if folder is not None:
        from visnav.app.figures_analysis import analysis_figures

        write_text_atomic(folder / "analysis.json", json.dumps(out, indent=1, sort_keys=True) + "\n")
        written.append(str(folder / "analysis.json"))
        written += [str(path) for path in write_figures(folder, analysis_figures(out)).values()]
    if args.json:
        print(json.dumps(out, sort_keys=True))
    else:
        print(_analyse_human(out) + "".join(f"\n  wrote {path}" for path in written))
    return EXIT_OK


def _check_problem(args: argparse.Namespace) -> int:
    import dataclasses
    import time

    from analysis.problems import StructuralChecks

    from visnav.app.structural import completeness_data, verdict_line

    problem = _user_problem(args.problem, args.config)
    if isinstance(problem, int):
        return problem
    structural = problem.structural
    if structural is None:
        print(f"visnav: error: problem {problem.name!r} has no structural checks (VerificationProblem.structural); "
              "give hybrid_problem(..., check_box=Box(...)) or structural=...", file=sys.stderr)
        return EXIT_BAD_INPUT
    method, timeout_s = args.method or CHECK_DEFAULT_METHOD, args.timeout or CHECK_DEFAULT_TIMEOUT_S
    if isinstance(structural, StructuralChecks):
        structural = dataclasses.replace(structural, method=method, timeout_s=timeout_s, budget_s=args.search_budget)
    else:
        if args.method is not None or args.timeout is not None:
            print(f"visnav: note: problem {problem.name!r} has its own structural checks (not "
                  "analysis.problems.StructuralChecks): --method and --timeout do not apply to them",
                  file=sys.stderr)
        method, timeout_s = "of the problem", None
    start = time.perf_counter()
    report = structural()
    elapsed = time.perf_counter() - start
    if args.json:
        out = {"problem": problem.name, **report.as_dict(), **completeness_data(report)}
        out["clean"] = verdict_line(report)[0] == "clean"
        if timeout_s is not None:
            out.update(method=method, timeout_s=timeout_s)
        print(cli_words(json.dumps(out, sort_keys=True)))
    else:
        print(cli_words(_check_human(report, f"problem {problem.name}", elapsed, method=method, timeout_s=timeout_s)))
    return _CHECK_EXIT[verdict_line(report)[0]]


def _cmd_check_model(args: argparse.Namespace) -> int:
    import time

    from visnav.app.structural import check_supervisor, completeness_data, supervisor_rates, verdict_line
    from visnav.scenario import load_scenario, scenario_digest

    if args.problem is not None:
        if args.parametric:
            print("visnav: error: --parametric asks about the supervisor's envelopes (a --scenario), not a --problem; "
                  "for your own model call hybrid.exclusive_for_all(system, box, ParameterSpace(...)) from Python",
                  file=sys.stderr)
            return EXIT_BAD_INPUT
        return _check_problem(args)
    scenario = load_scenario(args.scenario)
    method, timeout_s = args.method or CHECK_DEFAULT_METHOD, args.timeout or CHECK_DEFAULT_TIMEOUT_S
    start = time.perf_counter()
    report = check_supervisor(scenario, samples=args.samples, starts=args.starts, seed=args.seed, method=method,
                              timeout_s=timeout_s, budget_s=args.search_budget)
    elapsed = time.perf_counter() - start
    parametric = _parametric_pairs(scenario, timeout_s) if args.parametric else None
    if args.json:
        rates = {name: float(f"{rate:.12g}") for name, rate in supervisor_rates(scenario).items()}
        out = {"scenario": scenario.name, "scenario_digest": scenario_digest(scenario),
               "method": method, "timeout_s": timeout_s, "rates": rates}
        out.update(report.as_dict(), **completeness_data(report))
        if parametric is not None:
            out["parametric"] = parametric
        print(cli_words(json.dumps(out, sort_keys=True)))
    else:
        print(cli_words(_check_human(report, f"scenario {scenario.name}", elapsed, method=method,
                                     timeout_s=timeout_s, box="declared measurement box")))
        if parametric is not None:
            print(_parametric_human(parametric))
    return _CHECK_EXIT[verdict_line(report)[0]]


def _parametric_pairs(scenario: Any, timeout_s: float) -> dict[str, Any]:
    """The supervisor's pairs decided for every admissible envelope (``check-model --parametric``)."""
    from hybrid.decide import exclusive_for_all

    from visnav.supervisor import build_supervisor, measurement_box, measurement_system, parameter_space

    model = build_supervisor(scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    space = parameter_space(model)
    pairs = exclusive_for_all(measurement_system(model), measurement_box(model, scenario.camera.half_width_px),
                              space, timeout_s=timeout_s)
    return {"assumptions": space.description, "pairs": [p.as_dict() for p in pairs]}


def _parametric_human(parametric: dict[str, Any]) -> str:
    rows = parametric["pairs"]
    exclusive = [r for r in rows if r["verdict"] == "exclusive"]
    overlap = [r for r in rows if r["verdict"] == "overlap"]
    undecided = [r for r in rows if r["verdict"] not in ("exclusive", "overlap")]
    lines = [f"  parametric, for {parametric['assumptions']}:",
             f"    {len(exclusive)} of {len(rows)} pairs exclusive for every admissible envelope (PROVEN); "
             f"{len(overlap)} overlap for some envelope (re-checked witnesses with its values)"
             + (f"; {len(undecided)} undecided" if undecided else "")]
    lines += [f"    undecided: {r['mode']} {r['first']} / {r['second']}: {r['detail']}" for r in undecided[:5]]
    return "\n".join(lines)


def _single_threaded_blas() -> None:
    """One BLAS/LAPACK thread for every command, set before numpy loads.

    OpenBLAS splits some LAPACK work across threads, and the split changes the
    round-off: the stiffness study's 1e-13 reference then differs in its last
    digits between a 1-thread and a 2-thread process, and so would report.json.
    The report is computed single-threaded wherever it runs (the matrices are
    12×12: nothing is lost).  Without effect if numpy is already imported
    (in-process use); the console script imports it later.
    """
    import os

    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[name] = "1"


REPORT_NUMERICS = {"NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR", "OPENBLAS_CORETYPE": "Nehalem"}
"""What ``visnav report`` pins before numpy loads, so that its figures are drawn by the same code on every
x86-64 machine: numpy's baseline loops instead of the SIMD dispatch targets of the pinned numpy (2.4: AVX2
and AVX-512 variants of log10, exp, sin... whose last bits differ, which moves an antialiased edge of a
log-scale figure by a 1/255 grey level), and OpenBLAS's Nehalem kernels (SSE4.2: every x86-64-v2 CPU) instead
of the ones it picks for the CPU.  The numbers are rounded anyway (:mod:`visnav.app.precision`); this keeps
the remaining round-off below the figures too.  A name another numpy does not dispatch is ignored by it."""


def _pinned_report_numerics(argv: Sequence[str] | None) -> None:
    """Pin :data:`REPORT_NUMERICS` when the command is ``report`` (before numpy loads; without effect after)."""
    import os

    words = list(sys.argv[1:] if argv is None else argv)
    command = next((w for w in words if not w.startswith("-")), None)
    if command == "report":
        os.environ.update(REPORT_NUMERICS)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``visnav`` console script; returns the exit code (``docs/failure_modes.md``)."""
    from visnav.app.failures import run_guarded

    return run_guarded(lambda: _main(argv), None if argv is None else list(argv))


def _main(argv: Sequence[str] | None) -> int:
    _single_threaded_blas()  # before anything imports numpy (building the parser imports some of the toolkit)
    _pinned_report_numerics(argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    from visnav.app.ownership import start_folder

    args.start_dir = start_folder()  # every output folder is anchored here, before any user code can chdir

    from hybrid import DivergenceError

    from visnav.app.files import OutputError
    from visnav.scenario import ScenarioError
    try:
        return int(args.func(args))
    except (ScenarioError, OutputError) as err:
        print(f"visnav: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # e.g. `visnav report | head`: the reader left; not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except DivergenceError as err:
        if getattr(args, "json", False):
            print(json.dumps({"success": False, "diverged": True, "time_s": err.time, "mode": err.mode,
                              "cause": err.cause}, sort_keys=True))
        print(f"visnav: {err}", file=sys.stderr)
        return EXIT_DIVERGED


if __name__ == "__main__":  # pragma: no cover
    from visnav.app.cli_types import ignore_late_interrupts

    sys.exit(ignore_late_interrupts(main()))

