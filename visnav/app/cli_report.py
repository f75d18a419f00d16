"""``visnav report``: the verification report of a scenario or of a verification problem."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_TASK_FAILED, non_negative_int, positive_int

__all__ = ["add_parser"]


def add_parser(sub: Any) -> None:
    """Register the subcommand on ``visnav``'s subparsers."""
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

    from analysis.verify.falsification import FalsificationError, SimulationFailed
    from analysis.verify.loading import ProblemLoadError
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
