"""``visnav verify PROBLEM``: prove, falsify or search a verification problem's requirements.

``PROBLEM`` is ``paper`` (the built-in case study, requirements in the scenario
TOML), ``package.module:OBJECT`` or ``path/to/file.py:OBJECT`` (the user's own
system, :mod:`analysis.verify.loading`).  The search (:mod:`analysis.verify.falsification`)
writes every simulation to ``OUT/evaluations.jsonl`` as it finishes; running
the same command again resumes it.  At the end ``OUT/verification.json`` and,
per falsified requirement, ``OUT/counterexamples/NAME.json`` (re-run by
``visnav replay``) are written.

Exit codes: 0 every requirement proven or not falsified with every simulation complete, 1 one is
falsified, 2 bad input (problem, formula, options), 3 a simulation diverged numerically, 5 incomplete
(a simulation ended before its horizon and left a requirement undecided), 6 the model's code raised.
"""

from __future__ import annotations

import argparse
import contextlib
import re
from concurrent.futures import BrokenExecutor
import hashlib
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from analysis.verify.falsification import DEFAULT_TIMEOUT_S

from visnav.app.counterexample_files import (COUNTEREXAMPLE_FORMAT, PAPER, counterexample_text,
                                             is_verification_counterexample, replay_command)
from visnav.app.cli_types import VERIFY_BUDGET, VERDICT_EXIT_CODES, EXIT_BAD_INPUT, EXIT_DIVERGED, non_negative_int, positive_int, positive_seconds

__all__ = ["user_problem", "is_verification_counterexample", "cli_words", "add_parser", "load_verification_problem", "counterexample_text", "replay_command",
           "JOURNAL_FORMAT", "COUNTEREXAMPLE_FORMAT", "DEFAULT_BUDGET", "PAPER"]

JOURNAL_FORMAT = "visnav-verification-journal"
JOURNAL_VERSION = 3
"""3: the guided search of issue 29 (a space-filling start, surrogate and local steps: phases
``start``, ``surrogate``, ``local``, ``gradient``, ``descent``) and the ``whitebox`` method; a journal of
version 2 holds the points of the former hypothesis search, which a resumed search would not replay, so it
is refused (the message names both versions: delete the folder or give another ``--out``).
2: every evaluation says how its run ended (``end``, ``end_time``) and decides each requirement or not
(``satisfied`` may be ``null``); a journal of version 1 judged runs that ended early as complete, so it
is not read back."""
JOURNAL_FILE = "evaluations.jsonl"
"""The search's journal in the ``--out`` folder (appended as the simulations finish)."""
DEFAULT_BUDGET = VERIFY_BUDGET
"""Default simulations per run (:data:`visnav.app.cli_types.VERIFY_BUDGET`, the one definition)."""


def add_parser(sub: Any) -> None:
    """Register ``verify`` on the subcommand parsers ``sub``."""
    from analysis.verify.falsification import METHODS

    ver = sub.add_parser("verify", help="verify a problem's STL requirements: proven, falsified or not falsified")
    ver.add_argument("problem", help="paper, package.module:OBJECT, path/to/file.py:OBJECT, or a SpaceEx model "
                                     "FILE.xml[:COMPONENT] with --config FILE.cfg")
    ver.add_argument("--config", default=None, metavar="FILE.cfg",
                     help="SpaceEx models only: the configuration (initially, forbidden, time-horizon; docs/spaceex.md)")
    ver.add_argument("--budget", type=positive_int, default=DEFAULT_BUDGET,
                     help=f"simulations allowed (default: {DEFAULT_BUDGET})")
    ver.add_argument("--seed", type=non_negative_int, default=0, help="seed of the search (default: 0)")
    ver.add_argument("--method", choices=METHODS, default="guided",
                     help="guided: hypothesis targets + scipy polish + shrink (default); monte-carlo: the baseline; "
                          "dual-annealing: scipy's global optimiser")
    ver.add_argument("--requirement", action="append", default=None, metavar="NAME",
                     help="verify only this requirement (repeatable)")
    ver.add_argument("--scenario", default=None, help="paper only: built-in scenario name or TOML file")
    ver.add_argument("--variant", default=None,
                     help="paper only: supervisor variant (resolved, paper, a mutant), or saturated: the resolved "
                          "loop with its applied commands clipped to [limits] (NAME+saturated: another supervisor)")
    ver.add_argument("--out", default=None, help="folder of the journal, verification.json and counterexamples "
                                                 "(default: out/verify/<problem>/<method>-seed<S>-budget<N>)")
    ver.add_argument("--workers", type=positive_int, default=None,
                     help="monte-carlo only: local worker processes (default: in this process)")
    ver.add_argument("--sim-timeout", type=positive_seconds, default=DEFAULT_TIMEOUT_S, metavar="S",
                     help=f"wall-clock limit of one simulation in seconds (default: {DEFAULT_TIMEOUT_S:g}); a "
                          "simulation past it is recorded as timed out and the verdict is incomplete")
    ver.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    ver.set_defaults(func=_cmd_verify)


def _options(args: argparse.Namespace) -> dict[str, Any]:
    options = {}
    if args.scenario is not None:
        options["scenario"] = args.scenario
    if args.variant is not None:
        options["variant"] = args.variant
    if getattr(args, "config", None) is not None:
        options["config"] = args.config
    return options


def load_verification_problem(spec: str, options: Mapping[str, Any], requirements: Sequence[str] | None = None):
    """The problem ``spec`` names (``paper`` is :func:`visnav.verification.paper_problem`), restricted to
    ``requirements`` when given."""
    from analysis.verify.loading import ProblemLoadError, load_problem

    from analysis.spaceex import is_spaceex_spec

    if "config" in options and not is_spaceex_spec(spec):
        raise ProblemLoadError("--config", options["config"], "a SpaceEx model FILE.xml[:COMPONENT] as the problem",
                               "drop --config (it gives a SpaceEx model its .cfg)")
    if spec == "paper":
        from visnav.verification import paper_problem

        problem = paper_problem(**options)
    elif is_spaceex_spec(spec):
        problem = load_problem(spec, options)  # a SpaceEx model and its --config (or the error saying so)
    else:
        if options:
            raise ProblemLoadError("--scenario/--variant", dict(options), "options of the built-in 'paper' problem",
                                   "drop them, or choose the variant in your own module")
        problem = load_problem(spec)
    if requirements:
        names = problem.requirement_names
        unknown = [n for n in requirements if n not in names]
        if unknown:
            raise ProblemLoadError("--requirement", unknown, f"requirements of {problem.name}: {list(names)}",
                                   "check the spelling")
        problem = problem.with_requirements([r for r in problem.requirements if r.name in requirements])
    return problem


def _spec_hash(spec: str, options: Mapping[str, Any], problem: Any, args: argparse.Namespace) -> dict[str, Any]:
    """The journal's header: the search's options, the requirements, the box and the model's code
    (:func:`analysis.verify.loading.source_digests`): a journal of an edited model is another campaign."""
    from analysis.verify.loading import source_digests

    identity = {"problem": spec, "options": dict(options), "method": args.method, "seed": args.seed,
                "budget": args.budget, "requirements": [[r.name, r.formula] for r in problem.requirements],
                "parameters": [[p.name, p.low, p.high, p.nominal] for p in problem.parameters],
                "timeout_s": getattr(args, "sim_timeout", None), "model": source_digests(spec, getattr(args, "start_dir", None),
                                            [options["config"]] if "config" in options else [])}
    digest = hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()
    return {"format": JOURNAL_FORMAT, "version": JOURNAL_VERSION, "spec_hash": digest, "spec": identity}


def _default_out(name: str, args: argparse.Namespace) -> str:
    """``out/verify/<problem>/<method>-seed<S>-budget<N>[-<requirements>]``: a search of other options resumes
    its own journal instead of being refused by this one."""
    tail = f"{args.method}-seed{args.seed}-budget{args.budget}"
    if args.requirement:
        tail += "-" + hashlib.sha256(",".join(sorted(args.requirement)).encode()).hexdigest()[:8]
    return f"out/verify/{name}/{tail}"


def _checked_evaluation(problem: Any, data: Any) -> Any:
    """A journal line's evaluation, refused (``ValueError``) unless it could have been written for ``problem``:
    a unit point of its dimension in [-1, 1], a status of the vocabulary, one robustness (not NaN) and one
    truth value (true, false or null) per requirement when evaluated, none otherwise."""
    import math

    from analysis.verify.falsification import PHASES as _PHASES
    from analysis.verify.falsification import STATUSES, Evaluation

    e = Evaluation.from_dict(data)
    o = e.outcome
    n = len(problem.requirements)
    if len(e.unit) != problem.dimension or not all(math.isfinite(u) and -1.0 <= u <= 1.0 for u in e.unit):
        raise ValueError(f"unit point {list(e.unit)[:8]}: expected {problem.dimension} coordinates in [-1, 1]")
    if o.status not in STATUSES or e.phase not in _PHASES:
        raise ValueError(f"status {o.status!r} / phase {e.phase!r}: expected one of {STATUSES} / {_PHASES}")
    if len(o.robustness) not in ((n,) if o.status == "ok" else (0, n)) or len(o.satisfied) != len(o.robustness):
        raise ValueError(f"{len(o.robustness)} robustness values and {len(o.satisfied)} truth values for {n} "
                         f"requirement(s) with status {o.status!r}")
    if any(math.isnan(r) for r in o.robustness) or not all(isinstance(v, bool) or v is None
                                                           for v in data.get("satisfied", ())):
        raise ValueError("a robustness that is NaN, or a truth value that is not true, false or null")
    if o.status == "ok" and None in o.satisfied:
        raise ValueError("an undecided requirement on a complete run")
    return e


def _journal(folder: Path, header: dict[str, Any], budget: int, problem: Any):
    from visnav.app.campaign_store import ResultCodec, StoreHints, open_store

    codec = ResultCodec(to_dict=lambda e: e.as_dict(), from_dict=lambda d: _checked_evaluation(problem, d),
                        index=lambda e: e.index)
    hints = StoreHints(writer="visnav verify", same_campaign="the same problem, --method, --seed, --budget and "
                       "requirements")
    return open_store(folder / JOURNAL_FILE, header, codec, samples=budget, hints=hints)


def _cmd_verify(args: argparse.Namespace) -> int:
    from analysis.verify.falsification import FalsificationError, SimulationFailed
    from analysis.verify.loading import ProblemLoadError
    from analysis.verify.verdicts import verify
    from hybrid.errors import ParameterError

    from visnav.app.campaign_store import CampaignStoreError
    from visnav.app.files import prepare_output_dir
    from visnav.app.ownership import anchored, check_requirement_names, safe_name, unowned_targets

    options = _options(args)
    quiet = contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext()
    try:  # with --json, stdout carries the JSON alone: the model's own prints go to stderr
        with quiet:
            problem = load_verification_problem(args.problem, options, args.requirement)
    except ProblemLoadError as error:
        return _bad_input(error.render(), error.user_traceback)
    except ParameterError as error:
        return _bad_input(cli_words(error.render()))
    check_requirement_names(problem.requirement_names, f"problem {problem.name!r}")  # before the search
    shown = Path(args.out if args.out is not None else _default_out(safe_name(
        "the problem's name (VerificationProblem.name; for paper: the scenario's name)", problem.name,
        "rename it (a scenario: its name = ... in the TOML), or give --out FOLDER"), args))
    folder = prepare_output_dir(anchored(args, shown))  # anchored: the user's code may have changed the folder
    targets = _result_files(problem)
    foreign = unowned_targets(folder, targets)
    if foreign:
        return _bad_input(_foreign_message(shown, foreign, "already"))
    header = _spec_hash(args.problem, options, problem, args)
    try:
        store, found = _journal(folder, header, args.budget, problem)
    except CampaignStoreError as error:
        return _bad_input(str(error))
    for bad in found.bad_lines:
        print(f"visnav: warning: {found.path}: {bad}", file=sys.stderr)
    if found.bad_lines:
        print(f"visnav: warning: {found.path}: kept {found.results} valid evaluation(s) and dropped "
              f"{len(found.bad_lines)} bad line(s); their points will be simulated again", file=sys.stderr)
    cache = {e.unit: e.outcome for e in store.results()}
    done = set(store.done)

    def record(evaluation: Any) -> None:
        if evaluation.index not in done:
            store.append(evaluation)
            done.add(evaluation.index)

    runner = _runner(args, problem, options, record) if args.method == "monte-carlo" and args.workers else None
    try:
        with store, (contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext()):
            result = verify(problem, budget=args.budget, seed=args.seed, method=args.method, cache=cache,
                            on_evaluation=record, runner=runner, timeout_s=args.sim_timeout)
            store.compact()
    except SimulationFailed as error:
        return _bad_input(f"{error}\nyour simulator raised (your code's traceback follows)", error.traceback)
    except FalsificationError as error:
        return _bad_input(error.render())
    except BrokenExecutor as error:  # a worker process died (os._exit, a crash, the OOM killer)
        reason = " ".join(str(error).split())
        print(f"visnav: error: the search stopped: a worker process died ({type(error).__name__}"
              f"{': ' + reason if reason else ''}); {len(done)} evaluation(s) are kept in {shown / JOURNAL_FILE}"
              "; rerun the same command to resume (a model that kills its process: run without --workers to see "
              "its error)", file=sys.stderr)
        return EXIT_DIVERGED
    foreign = unowned_targets(folder, targets)
    if foreign:  # saved while the search ran: the journal keeps the search, the next run resumes it
        return _bad_input(_foreign_message(shown, foreign, "meanwhile"))
    written = _write_results(folder, shown, result, problem, args.problem, options)
    if result.errors and result.errors[0].get("traceback"):
        print(str(result.errors[0]["traceback"]).rstrip() + "\nvisnav: the model's code raised during a simulation "
              f"({result.errors[0]['detail']}); its traceback is above", file=sys.stderr)
    out = _json_summary(result, written, args.problem)
    if args.json:
        print(json.dumps(out, sort_keys=True))
    else:
        print(_human(result, written, resumed=len(cache), spec=args.problem))
    return VERDICT_EXIT_CODES[result.verdict]


def _result_files(problem: Any) -> list[str]:
    """The files ``verify`` (over)writes in its folder, relative to it (the journal has its own header check)."""
    return ["verification.json", *(f"counterexamples/{name}.json" for name in problem.requirement_names)]


def _foreign_message(shown: Path, foreign: list[str], when: str) -> str:
    from visnav.app.ownership import MANIFEST_NAME, describe_entries

    saved = "were saved there while the search ran" if when == "meanwhile" else "are there"
    return (f"--out {str(shown)!r}: {len(foreign)} file(s) that verify would overwrite {saved} and were not written "
            f"by visnav ({describe_entries(foreign)}; not listed with their bytes in its {MANIFEST_NAME}); nothing "
            "was overwritten: move them away, or choose another --out"
            + (" (the search is kept in evaluations.jsonl: the same command then resumes it)"
               if when == "meanwhile" else ""))


def _write_results(folder: Path, shown: Path, result: Any, problem: Any, spec: str,
                   options: Mapping[str, Any]) -> dict[str, str]:
    """Write the counterexamples, verification.json and (last) the folder's manifest; the files by requirement
    (as shown: under ``shown``, the folder as the user gave it)."""
    from visnav.app.files import write_text_atomic
    from visnav.app.ownership import read_manifest, unowned_targets, write_manifest

    earlier = read_manifest(folder) or {}
    written: dict[str, str] = {}
    relatives = []
    for verdict in result.requirements:
        if verdict.counterexample is None:
            continue
        relative = f"counterexamples/{verdict.name}.json"
        (folder / relative).parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(folder / relative, counterexample_text(result, verdict, problem, spec, options))
        written[verdict.name] = str(shown / relative)
        relatives.append(relative)
    data = result.as_dict(evaluations=True)
    data["counterexample_files"] = written
    write_text_atomic(folder / "verification.json", json.dumps(data, indent=1, sort_keys=True) + "\n")
    relatives.append("verification.json")
    kept = [r for r in earlier if r not in relatives and r != JOURNAL_FILE and (folder / r).is_file()
            and not unowned_targets(folder, [r])]  # earlier files of visnav's still as written
    journal = [JOURNAL_FILE] if (folder / JOURNAL_FILE).is_file() else []
    write_manifest(folder, [*relatives, *kept, *journal], "verify")
    return written


def _json_summary(result: Any, written: Mapping[str, str], spec: str) -> dict[str, Any]:
    data = result.as_dict()
    for entry in data["requirements"]:
        cx = entry["counterexample"]
        if cx is not None:
            cx["file"] = written.get(entry["name"])
            cx["replay"] = replay_command(written.get(entry["name"]), spec)
    return data


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.4g}"


def _human(result: Any, written: Mapping[str, str], resumed: int, spec: str) -> str:
    lines = [f"verify {result.problem}: {result.verdict.upper()} ({result.simulations} simulations, method "
             f"{result.method}, seed {result.seed}{f', {resumed} read back from the journal' if resumed else ''})"]
    if getattr(result, "gradients", ""):
        lines.append(f"  gradients: {result.gradients}")
    width = max(len(r.name) for r in result.requirements)
    decided = max(len(r.decided_by) for r in result.requirements)
    for r in result.requirements:
        rho = r.robustness if r.robustness is not None or r.counterexample is None else r.counterexample.robustness
        line = f"  {r.verdict:<14} {r.name:<{width}}  robustness {_fmt(rho):>10}  decided by {r.decided_by:<{decided}}"
        if r.counterexample is not None:
            cx = r.counterexample
            first = "" if cx.first_time is None else f"first violated at t = {cx.first_time:.4g} s, "
            where = (f"lowest at t = {cx.time:.4g} s" if cx.window is None else
                     f"never reached within [{cx.window[0]:.4g}, {cx.window[1]:.4g}] s, closest at t = {cx.time:.4g} s")
            line += (f"  {first}{where} ({cx.atom}); replay: "
                     f"{replay_command(written.get(r.name), spec)}")
        elif r.lowest_at and r.verdict != "proven":
            line += "  lowest at " + ", ".join(f"{k}={v:.4g}" for k, v in r.lowest_at.items())
        lines.append(line.rstrip())
    if result.invalid:
        lines.append(f"  {result.invalid} points outside the problem's hypotheses skipped: {result.invalid_reasons[0]}")
    for d in result.diverged[:3]:
        lines.append(f"  {d['status']} at {d['point']}: {d['detail']}")
    if result.ended_early:  # the first, and how many (their causes are often the same sentence)
        d = result.ended_early[0]
        more = len(result.ended_early) - 1
        lines.append(f"  ended early ({d['end']}) at {d['point']}: {d['detail']}"
                     + (f" (+{more} more run(s) ended early: verification.json has them)" if more else ""))
    for d in result.errors[:1]:
        lines.append(f"  MODEL ERROR at {d['point']}: {d['detail']} (the model's traceback is on stderr)")
    for r in result.requirements:
        if r.verdict == "incomplete":
            lines.append(f"  {r.name}: {r.undecided} run(s) ended before deciding it; first: {r.undecided_reasons[0]}")
    cov = result.coverage
    if cov.parameters:
        share = min(cov.bins_hit)
        lines.append(f"  coverage: {cov.points} points; every parameter hit >= {share:.0%} of its {10} bins")
    return "\n".join(lines)


_CLI_WORDS = ((re.compile(r"^variant = "), "--variant = "), (re.compile(r"use the variant '([^']+)'"), r"use --variant \1"),
              (re.compile(r", or '(saturated)' for"), r", or --variant \1 for"),
              (re.compile(r"method '(auto)' or '(sampled)'"), r"--method \1 or \2"))
"""The library's words for an option, in the command line's (``variant`` is ``--variant`` there)."""


def cli_words(message: str) -> str:
    """``message`` (a library error) with its option names as the command line spells them."""
    for pattern, replacement in _CLI_WORDS:
        message = pattern.sub(replacement, message)
    return message


def _bad_input(message: str, user_traceback: str = "") -> int:
    if user_traceback:
        print(user_traceback.rstrip(), file=sys.stderr)
    print(f"visnav: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


_WORKER_PROBLEMS: dict[str, Any] = {}


def _evaluate_task(spec: tuple[str, tuple[tuple[str, Any], ...], tuple[str, ...] | None, Mapping[int, tuple],
                               float | None], index: int):
    """Campaign task: evaluate Monte-Carlo draw ``index`` of the problem the spec names (loaded once per process)."""
    from analysis.verify.falsification import evaluate

    source, options, requirements, units, timeout_s = spec
    key = repr((source, options, requirements))
    if key not in _WORKER_PROBLEMS:
        _WORKER_PROBLEMS[key] = load_verification_problem(source, dict(options), requirements)
    return evaluate(_WORKER_PROBLEMS[key], units[index], timeout_s)


def _runner(args: argparse.Namespace, problem: Any, options: Mapping[str, Any], record: Any):
    from analysis.campaigns import campaign_executor, run_tasks
    from analysis.verify.falsification import Evaluation

    def run(pending: list[tuple[int, tuple[float, ...]]]) -> dict[int, Any]:
        units = dict(pending)  # one chunk of draws (analysis.verify.falsification), by index
        spec = (args.problem, tuple(sorted(options.items())), tuple(args.requirement) if args.requirement else None,
                units, args.sim_timeout)
        outcomes: dict[int, Any] = {}

        def sink(i: int, outcome: Any) -> None:
            outcomes[i] = outcome
            record(Evaluation(index=i, phase="monte-carlo", unit=units[i], outcome=outcome))

        with campaign_executor(workers=args.workers) as backend:
            run_tasks(_evaluate_task, spec, list(units), backend.executor, sink, order="index")
        return outcomes

    return run


def user_problem(spec: str, config: str | None = None) -> Any:
    """The verification problem ``spec`` names (a SpaceEx model with its ``config``), or the exit code of a bad
    one (the message printed)."""
    from hybrid.errors import ParameterError

    try:
        return load_verification_problem(spec, {} if config is None else {"config": config}, None)
    except ParameterError as error:
        trace = getattr(error, "user_traceback", "")
        if trace:
            print(trace.rstrip(), file=sys.stderr)
        print(f"visnav: error: {error.render()}", file=sys.stderr)
        return EXIT_BAD_INPUT
