"""``visnav verify PROBLEM``: prove, falsify or search a verification problem's requirements.

``PROBLEM`` is ``paper`` (the built-in case study, requirements in the scenario
TOML), ``package.module:OBJECT`` or ``path/to/file.py:OBJECT`` (the user's own
system, :mod:`analysis.loading`).  The search (:mod:`analysis.falsification`)
writes every simulation to ``OUT/evaluations.jsonl`` as it finishes; running
the same command again resumes it.  At the end ``OUT/verification.json`` and,
per falsified requirement, ``OUT/counterexamples/NAME.json`` (re-run by
``visnav replay``) are written.

Exit codes: 0 every requirement proven or not falsified, 1 one is falsified,
2 bad input (problem, formula, options), 3 a simulation diverged.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from visnav.app.cli_types import EXIT_BAD_INPUT, non_negative_int, positive_int

__all__ = ["add_parser", "load_verification_problem", "counterexample_text", "JOURNAL_FORMAT",
           "COUNTEREXAMPLE_FORMAT", "DEFAULT_BUDGET"]

JOURNAL_FORMAT = "visnav-verification-journal"
COUNTEREXAMPLE_FORMAT = "visnav-verification-counterexample"
DEFAULT_BUDGET = 120
"""Default simulations per run (the paper's problem: about 40 s on one core)."""


def add_parser(sub: Any) -> None:
    """Register ``verify`` on the subcommand parsers ``sub``."""
    from analysis.falsification import METHODS

    ver = sub.add_parser("verify", help="verify a problem's STL requirements: proven, falsified or not falsified")
    ver.add_argument("problem", help="paper, package.module:OBJECT or path/to/file.py:OBJECT")
    ver.add_argument("--budget", type=positive_int, default=DEFAULT_BUDGET,
                     help=f"simulations allowed (default: {DEFAULT_BUDGET})")
    ver.add_argument("--seed", type=non_negative_int, default=0, help="seed of the search (default: 0)")
    ver.add_argument("--method", choices=METHODS, default="guided",
                     help="guided: hypothesis targets + scipy polish + shrink (default); monte-carlo: the baseline; "
                          "dual-annealing: scipy's global optimiser")
    ver.add_argument("--requirement", action="append", default=None, metavar="NAME",
                     help="verify only this requirement (repeatable)")
    ver.add_argument("--scenario", default=None, help="paper only: built-in scenario name or TOML file")
    ver.add_argument("--variant", default=None, help="paper only: supervisor variant (resolved, paper, a mutant)")
    ver.add_argument("--out", default=None, help="folder of the journal, verification.json and counterexamples "
                                                 "(default: out/verify/<problem>/<method>-seed<S>-budget<N>)")
    ver.add_argument("--workers", type=positive_int, default=None,
                     help="monte-carlo only: local worker processes (default: in this process)")
    ver.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    ver.set_defaults(func=_cmd_verify)


def _options(args: argparse.Namespace) -> dict[str, Any]:
    options = {}
    if args.scenario is not None:
        options["scenario"] = args.scenario
    if args.variant is not None:
        options["variant"] = args.variant
    return options


def load_verification_problem(spec: str, options: Mapping[str, Any], requirements: Sequence[str] | None = None):
    """The problem ``spec`` names (``paper`` is :func:`visnav.verification.paper_problem`), restricted to
    ``requirements`` when given."""
    from analysis.loading import ProblemLoadError, load_problem

    if spec == "paper":
        from visnav.verification import paper_problem

        problem = paper_problem(**options)
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
    identity = {"problem": spec, "options": dict(options), "method": args.method, "seed": args.seed,
                "budget": args.budget, "requirements": [[r.name, r.formula] for r in problem.requirements],
                "parameters": [[p.name, p.low, p.high, p.nominal] for p in problem.parameters]}
    digest = hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()
    return {"format": JOURNAL_FORMAT, "version": 1, "spec_hash": digest, "spec": identity}


def _default_out(name: str, args: argparse.Namespace) -> str:
    """``out/verify/<problem>/<method>-seed<S>-budget<N>[-<requirements>]``: a search of other options resumes
    its own journal instead of being refused by this one."""
    tail = f"{args.method}-seed{args.seed}-budget{args.budget}"
    if args.requirement:
        tail += "-" + hashlib.sha256(",".join(sorted(args.requirement)).encode()).hexdigest()[:8]
    return f"out/verify/{name}/{tail}"


def _journal(folder: Path, header: dict[str, Any], budget: int):
    from analysis.falsification import Evaluation

    from visnav.app.campaign_store import ResultCodec, StoreHints, open_store

    codec = ResultCodec(to_dict=lambda e: e.as_dict(), from_dict=Evaluation.from_dict, index=lambda e: e.index)
    hints = StoreHints(writer="visnav verify", same_campaign="the same problem, --method, --seed, --budget and "
                       "requirements")
    return open_store(folder / "evaluations.jsonl", header, codec, samples=budget, hints=hints)


def counterexample_text(result: Any, verdict: Any, problem: Any, spec: str, options: Mapping[str, Any], *,
                        rounded: bool = False) -> str:
    """The counterexample file of a falsified requirement: where, how much, and the trace it reads.

    ``rounded`` (the report's files): the trace, the robustness and the instant with the digits the report
    prints (:mod:`visnav.app.precision`: ``time``, ``simulation``); the unit coordinates that
    ``visnav replay`` re-runs are kept bit for bit either way.
    """
    from analysis.counterexamples import CounterexampleFormat

    from visnav.app.precision import round_value

    def keep(value: float, kind: str) -> float:
        return round_value(value, kind) if rounded else value

    cx = verdict.counterexample
    parsed = next(p for p in problem.parsed if p.name == verdict.name)
    trace = problem.simulate(problem.point(cx.unit))
    names = sorted(parsed.formula.signals - {"time", "jumps"})
    labels = sorted(parsed.formula.labels)
    rows = [[keep(float(trace.times[k]), "time"), int(trace.jumps[k]), *(trace.label(n)[k] for n in labels),
             *(keep(float(trace.signal(n)[k]), "simulation") for n in names)] for k in range(trace.n)]
    fmt = CounterexampleFormat(name=COUNTEREXAMPLE_FORMAT, version=1, reader="this visnav")
    fields = {
        "problem": spec, "options": dict(options), "requirement": verdict.name, "formula": verdict.formula,
        "unit": list(cx.unit), "point": dict(cx.point), "robustness": keep(cx.robustness, "simulation"),
        "time": keep(cx.time, "time"),
        "atom": cx.atom, "how": cx.how, "seed": result.seed, "method": result.method,
        "columns": ["time", "jumps", *labels, *names],
        "replay": f"visnav replay <this file>",
    }
    return fmt.dumps(fields, rows_key="trace", rows=rows)


def _cmd_verify(args: argparse.Namespace) -> int:
    from analysis.falsification import FalsificationError, SimulationFailed
    from analysis.loading import ProblemLoadError
    from analysis.verdicts import verify
    from hybrid.errors import ParameterError

    from visnav.app.campaign_store import CampaignStoreError
    from visnav.app.files import prepare_output_dir, write_text_atomic

    options = _options(args)
    try:
        problem = load_verification_problem(args.problem, options, args.requirement)
    except ProblemLoadError as error:
        return _bad_input(error.render(), error.user_traceback)
    except ParameterError as error:
        return _bad_input(error.render())
    folder = prepare_output_dir(args.out or _default_out(problem.name, args))
    header = _spec_hash(args.problem, options, problem, args)
    try:
        store, found = _journal(folder, header, args.budget)
    except CampaignStoreError as error:
        return _bad_input(str(error))
    cache = {e.unit: e.outcome for e in store.results()}
    done = set(store.done)

    def record(evaluation: Any) -> None:
        if evaluation.index not in done:
            store.append(evaluation)
            done.add(evaluation.index)

    runner = _runner(args, problem, options, record) if args.method == "monte-carlo" and args.workers else None
    try:
        with store:
            result = verify(problem, budget=args.budget, seed=args.seed, method=args.method, cache=cache,
                            on_evaluation=record, runner=runner)
            store.compact()
    except SimulationFailed as error:
        return _bad_input(f"{error}\nyour simulator raised (your code's traceback follows)", error.traceback)
    except FalsificationError as error:
        return _bad_input(error.render())
    written = _write_results(folder, result, problem, args.problem, options)
    out = _json_summary(result, written)
    if args.json:
        print(json.dumps(out, sort_keys=True))
    else:
        print(_human(result, written, resumed=len(cache)))
    return result.exit_code


def _write_results(folder: Path, result: Any, problem: Any, spec: str, options: Mapping[str, Any]) -> dict[str, str]:
    from visnav.app.files import write_text_atomic

    written: dict[str, str] = {}
    for verdict in result.requirements:
        if verdict.counterexample is None:
            continue
        path = folder / "counterexamples" / f"{verdict.name}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(path, counterexample_text(result, verdict, problem, spec, options))
        written[verdict.name] = str(path)
    data = result.as_dict(evaluations=True)
    data["counterexample_files"] = written
    write_text_atomic(folder / "verification.json", json.dumps(data, indent=1, sort_keys=True) + "\n")
    return written


def _json_summary(result: Any, written: Mapping[str, str]) -> dict[str, Any]:
    data = result.as_dict()
    for entry in data["requirements"]:
        cx = entry["counterexample"]
        if cx is not None:
            cx["file"] = written.get(entry["name"])
            cx["replay"] = f"visnav replay {written.get(entry['name'])}"
    return data


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.4g}"


def _human(result: Any, written: Mapping[str, str], resumed: int) -> str:
    lines = [f"verify {result.problem}: {result.verdict.upper()} ({result.simulations} simulations, method "
             f"{result.method}, seed {result.seed}{f', {resumed} read back from the journal' if resumed else ''})"]
    width = max(len(r.name) for r in result.requirements)
    for r in result.requirements:
        line = f"  {r.verdict:<14} {r.name:<{width}}  robustness {_fmt(r.robustness):>10}"
        if r.counterexample is not None:
            cx = r.counterexample
            line += f"  at t = {cx.time:.4g} s ({cx.atom}); replay: visnav replay {written.get(r.name)}"
        elif r.proof is not None and r.verdict == "proven":
            line += f"  {r.proof.method}"
        elif r.lowest_at:
            line += "  lowest at " + ", ".join(f"{k}={v:.4g}" for k, v in r.lowest_at.items())
        lines.append(line)
    if result.invalid:
        lines.append(f"  {result.invalid} points outside the problem's hypotheses skipped: {result.invalid_reasons[0]}")
    for d in result.diverged[:3]:
        lines.append(f"  {d['status']} at {d['point']}: {d['detail']}")
    cov = result.coverage
    if cov.parameters:
        share = min(cov.bins_hit)
        lines.append(f"  coverage: {cov.points} points; every parameter hit >= {share:.0%} of its {10} bins")
    return "\n".join(lines)


def _bad_input(message: str, user_traceback: str = "") -> int:
    if user_traceback:
        print(user_traceback.rstrip(), file=sys.stderr)
    print(f"visnav: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


_WORKER_PROBLEMS: dict[str, Any] = {}


def _evaluate_task(spec: tuple[str, tuple[tuple[str, Any], ...], tuple[str, ...] | None, Mapping[int, tuple]],
                   index: int):
    """Campaign task: evaluate Monte-Carlo draw ``index`` of the problem the spec names (loaded once per process)."""
    from analysis.falsification import evaluate

    source, options, requirements, units = spec
    key = repr((source, options, requirements))
    if key not in _WORKER_PROBLEMS:
        _WORKER_PROBLEMS[key] = load_verification_problem(source, dict(options), requirements)
    return evaluate(_WORKER_PROBLEMS[key], units[index])


def _runner(args: argparse.Namespace, problem: Any, options: Mapping[str, Any], record: Any):
    from analysis.campaigns import campaign_executor, run_tasks
    from analysis.falsification import Evaluation

    def run(pending: list[tuple[int, tuple[float, ...]]]) -> dict[int, Any]:
        units = dict(pending)  # one chunk of draws (analysis.falsification), by index
        spec = (args.problem, tuple(sorted(options.items())), tuple(args.requirement) if args.requirement else None,
                units)
        outcomes: dict[int, Any] = {}

        def sink(i: int, outcome: Any) -> None:
            outcomes[i] = outcome
            record(Evaluation(index=i, phase="monte-carlo", unit=units[i], outcome=outcome))

        with campaign_executor(workers=args.workers) as backend:
            run_tasks(_evaluate_task, spec, list(units), backend.executor, sink, order="index")
        return outcomes

    return run


def is_verification_counterexample(text: str) -> bool:
    """Whether ``text`` looks like a counterexample file of ``visnav verify`` (its format key)."""
    return f'"format": "{COUNTEREXAMPLE_FORMAT}"' in text[:4096]


def replay_verification(text: str, path: str, as_json: bool) -> int:
    """``visnav replay`` of a ``visnav verify`` counterexample: re-simulate the point, evaluate the formula.

    Exit 1 when the requirement is still violated, 0 when it now holds, 2 for a malformed file.
    """
    from analysis.counterexamples import CounterexampleError, CounterexampleFormat, decode_float, decode_str
    from analysis.loading import ProblemLoadError
    from hybrid.errors import ParameterError

    fmt = CounterexampleFormat(name=COUNTEREXAMPLE_FORMAT, version=1, reader="this visnav")
    try:
        data = fmt.loads(text, path)
        spec = decode_str(data.get("problem"), "problem", path)
        name = decode_str(data.get("requirement"), "requirement", path)
        options = data.get("options", {})
        if not isinstance(options, Mapping):
            raise CounterexampleError(path, "options: expected an object")
        units = data.get("unit")
        if not isinstance(units, list):
            raise CounterexampleError(path, "unit: expected a list of numbers")
        unit = tuple(decode_float(u, f"unit[{i}]", path) for i, u in enumerate(units))
        recorded = decode_float(data.get("robustness"), "robustness", path)
    except CounterexampleError as error:
        return _bad_input(f"replay: {error}")
    try:
        problem = load_verification_problem(spec, dict(options), [name])
        point = problem.point(unit)
    except ProblemLoadError as error:
        return _bad_input(f"replay {path}: {error.render()}", error.user_traceback)
    except ParameterError as error:
        return _bad_input(f"replay {path}: {error.render()}")
    formula = problem.parsed[0].formula
    trace = problem.simulate(point)
    rho = float(formula.robustness(trace))
    violated = not formula.satisfied(trace)
    why = formula.explain(trace)
    out = {"file": path, "problem": spec, "requirement": name, "formula": formula.text, "point": point,
           "robustness": rho, "recorded_robustness": recorded, "violated": violated, "time": float(why.time),
           "atom": str(why.atom), "atom_value": float(why.value)}
    if as_json:
        from hybrid.jsonable import to_jsonable

        print(json.dumps(to_jsonable(out, nonfinite="string"), sort_keys=True))
    else:
        state = "VIOLATED" if violated else "holds now"
        print(f"replay {path}: requirement {name} of {spec}: {state}, robustness {rho:.6g} "
              f"(recorded {recorded:.6g})\n  formula: {formula.text.strip()}\n  decided at t = {why.time:.6g} s "
              f"by {why.atom} = {why.value:.6g}\n  point: " + ", ".join(f"{k}={v:.6g}" for k, v in point.items()))
    return 1 if violated else 0
