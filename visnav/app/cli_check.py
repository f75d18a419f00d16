"""``visnav check-model``: the structural checks of the supervisor automaton or of a problem's automaton."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from visnav.app.cli_verify import user_problem
from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_INCOMPLETE, EXIT_OK, EXIT_TASK_FAILED, positive_int, positive_seconds

__all__ = ["add_parser", "CHECK_DEFAULT_METHOD", "CHECK_DEFAULT_TIMEOUT_S", "cli_words"]


def add_parser(sub: Any) -> None:
    """Register the subcommand on ``visnav``'s subparsers."""
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


def _check_problem(args: argparse.Namespace) -> int:
    import dataclasses
    import time

    from analysis.verify.problems import StructuralChecks

    from visnav.app.structural import completeness_data, verdict_line

    problem = user_problem(args.problem, args.config)
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
                  "analysis.verify.problems.StructuralChecks): --method and --timeout do not apply to them",
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
