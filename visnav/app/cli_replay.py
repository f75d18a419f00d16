"""``visnav replay FILE [--problem SPEC]`` of a ``visnav verify`` counterexample: no code chosen by the file.

A counterexample file is data: it names the problem it was found on
(``"problem"``), but replay never imports what a file names.  The problem run
is the one the command line names:

* ``--problem SPEC`` given: the file must name the same problem (the same
  string, or the same ``.py`` file and object once both paths are resolved),
  and ``SPEC`` as typed is what is loaded;
* ``--problem`` not given: only the built-in ``paper`` problem is replayed (it
  names no user code: the case study, with the file's ``scenario`` and
  ``variant`` options, which are data); a file naming anything else is refused
  with ``this counterexample names problem X; re-run with --problem X to confirm``.

The rest of the file is checked before anything runs: ``options`` holds only
keys the problem accepts (``scenario`` and ``variant``, both strings, for
``paper``; none for a user's problem); every ``unit`` coordinate is finite and
in ``[-1, 1]`` (a coordinate outside is not clamped into the box: that would
replay another point); ``point`` names exactly the problem's parameters with
the values the unit coordinates give (within :data:`POINT_TOLERANCE` of each
parameter's range: otherwise the box changed or the file was edited).

Exit codes: 0 the requirement holds now, 1 still violated, 2 bad input (the
file, the options, the problem not confirmed, a formula not finite on the
replayed run), 3 the run could not complete (divergence, Zeno, an executor
failure), 6 the user's simulator raised (their traceback is shown).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import sys
import traceback
from collections.abc import Mapping
from typing import Any

from analysis.verify.falsification import run_end
from hybrid.jsonable import to_jsonable

from visnav.app.cli_types import (EXIT_BAD_INPUT, EXIT_DIVERGED, EXIT_INCOMPLETE, EXIT_MODEL_ERROR, EXIT_OK,
                                  EXIT_TASK_FAILED)
from visnav.app.cli_verify import COUNTEREXAMPLE_FORMAT, PAPER, load_verification_problem

__all__ = ["add_parser", "cmd_replay", "PAPER", "PAPER_OPTIONS", "POINT_TOLERANCE", "same_problem", "replay_verification"]

PAPER_OPTIONS = ("scenario", "variant")
"""The ``options`` keys the ``paper`` problem accepts (strings: a scenario name or TOML file, a variant)."""
POINT_TOLERANCE = 1e-9
"""Largest difference between a file's point and its unit coordinates' point, relative to the parameter's range."""


class _Refused(Exception):
    """A replay refused before anything ran: the message and the exit code."""

    def __init__(self, message: str, code: int = EXIT_BAD_INPUT, user_traceback: str = "") -> None:
        super().__init__(message)
        self.message, self.code, self.user_traceback = message, code, user_traceback


def _file_target(spec: str) -> tuple[str, str] | None:
    """``(resolved file, object)`` of a ``path/to/file.py:OBJECT`` spec, ``None`` for a module spec."""
    from analysis.verify.loading import ProblemLoadError, split_spec

    try:
        where, name = split_spec(spec)
    except ProblemLoadError:
        return None
    if not (where.endswith(".py") or os.sep in where or "/" in where):
        return None
    try:
        return os.path.realpath(os.path.expanduser(where)), name
    except (OSError, ValueError):
        return None


def same_problem(named: str, given: str) -> bool:
    """Whether a file's problem ``named`` is the problem ``given`` on the command line (nothing is imported).

    The same string, or two file specs naming the same object of the same file once their paths are resolved.
    """
    if named == given:
        return True
    a, b = _file_target(named), _file_target(given)
    return a is not None and a == b


def _confirmed_problem(named: str, given: str | None) -> str:
    """The spec to load: ``given`` when it confirms ``named``, ``paper`` when both say so; else refused."""
    from analysis.counterexamples import show_value

    shown = show_value(named, 200)
    if given is None:
        if named == PAPER:
            return PAPER
        raise _Refused(f"this counterexample names problem {shown}; re-run with --problem {shlex.quote(named)} to "
                       "confirm (replay runs only the code the command line names, never what a file names)")
    if not same_problem(named, given):
        raise _Refused(f"this counterexample names problem {shown}, not {show_value(given, 200)} (--problem); "
                       f"re-run with --problem {shlex.quote(named)} to confirm, or replay a counterexample of "
                       f"{show_value(given, 200)}")
    return given


def _options(data: Mapping[str, Any], spec: str, source: str) -> dict[str, str]:
    """The file's ``options``: only keys the problem accepts, each a string."""
    from analysis.counterexamples import CounterexampleError, json_type, show_value

    options = data.get("options", {})
    if not isinstance(options, Mapping):
        raise CounterexampleError(source, f"options = {show_value(options)}: expected an object, found "
                                          f"{json_type(options)}")
    from analysis.spaceex import is_spaceex_spec

    # paper's options name a scenario and a variant; a SpaceEx model's, its .cfg: data read, never code run
    accepted = PAPER_OPTIONS if spec == PAPER else (("config",) if is_spaceex_spec(spec) else ())
    for key, value in options.items():
        if key not in accepted:
            known = ", ".join(accepted) if accepted else "none (a user's problem takes no options from a file)"
            raise CounterexampleError(source, f"options: unknown key {show_value(key, 60)} for problem "
                                              f"{show_value(spec, 120)}; the accepted keys are: {known}")
        if not isinstance(value, str):
            raise CounterexampleError(source, f"options.{key} = {show_value(value)}: expected a string, found "
                                              f"{json_type(value)}")
    return dict(options)


def _units(data: Mapping[str, Any], source: str) -> tuple[float, ...]:
    """The ``unit`` coordinates: a list of finite numbers in [-1, 1] (never clamped)."""
    from analysis.counterexamples import CounterexampleError, decode_float, show_value

    units = data.get("unit")
    if not isinstance(units, list):
        raise CounterexampleError(source, f"unit = {show_value(units)}: expected a list of numbers in [-1, 1]")
    out = []
    for i, value in enumerate(units):
        u = decode_float(value, f"unit[{i}]", source)
        if not (math.isfinite(u) and -1.0 <= u <= 1.0):
            raise CounterexampleError(
                source, f"unit[{i}] = {show_value(value)}: expected a finite number in [-1, 1] (unit coordinates "
                        "of the box; a value outside is not clamped, that would replay another point)")
        out.append(u)
    return tuple(out)


def _check_point(data: Mapping[str, Any], problem: Any, unit: tuple[float, ...], source: str) -> dict[str, float]:
    """The point of ``unit``, after checking that the file's ``point`` agrees with it."""
    from analysis.counterexamples import CounterexampleError, decode_float, show_value

    point = problem.point(unit)
    written = data.get("point")
    if not isinstance(written, Mapping) or set(written) != set(point):
        raise CounterexampleError(source, f"point = {show_value(written)}: expected an object with the problem's "
                                          f"parameters {sorted(point)}")
    for i, p in enumerate(problem.parameters):
        value = decode_float(written[p.name], f"point.{p.name}", source)
        if not abs(value - point[p.name]) <= POINT_TOLERANCE * max(1.0, p.high - p.low):
            raise CounterexampleError(
                source, f"point.{p.name} = {show_value(written[p.name])} disagrees with unit coordinate "
                        f"{unit[i]!r}, which gives {point[p.name]!r} in the box "
                        f"[{p.low!r}, {p.high!r}]; the problem's box changed since the file was written, or the "
                        "file was edited: run visnav verify again")
    return point


def _simulate(problem: Any, point: Mapping[str, float]) -> Any:
    """The trace at ``point``; a failure of the run is refused with the exit code of its kind."""
    from analysis.stl import SignalTrace
    from analysis.verify.verification import InvalidPoint
    from hybrid.errors import ExecutionError, NumericalFailure, UserFunctionError

    try:
        trace = problem.trace(point)
    except InvalidPoint as error:
        raise _Refused(f"the point {dict(point)} is outside the problem's hypotheses now: {error}") from None
    except UserFunctionError as error:
        raise _Refused(f"your model raised during the replay: {error}", EXIT_MODEL_ERROR,
                       "".join(traceback.format_exception(error))) from None
    except (ExecutionError, NumericalFailure) as error:
        raise _Refused(f"the run could not complete: {type(error).__name__}: {error}", EXIT_DIVERGED) from None
    except Exception as error:  # the user's own simulator: their traceback
        raise _Refused(f"your simulator raised {type(error).__name__}: {error} at {dict(point)}", EXIT_MODEL_ERROR,
                       "".join(traceback.format_exception(error))) from None
    if not isinstance(trace, SignalTrace):
        raise _Refused(f"simulate(point) returned a {type(trace).__name__}: expected an analysis.stl.SignalTrace",
                       EXIT_MODEL_ERROR)
    return trace


def _evaluate(formula: Any, trace: Any, name: str) -> tuple[float, bool, Any]:
    """Robustness, violation and explanation of ``formula``; a non-finite formula or a missing signal refused."""
    from analysis.stl import FormulaValueError, TraceError

    try:
        return float(formula.robustness(trace)), not formula.satisfied(trace), formula.explain(trace)
    except FormulaValueError as error:
        raise _Refused(f"requirement {name}: {error}") from None
    except TraceError as error:
        raise _Refused(f"requirement {name}: the simulator's trace does not fit the formula: {error}",
                       EXIT_MODEL_ERROR) from None


def _run(text: str, path: str, given: str | None) -> dict[str, Any]:
    from analysis.counterexamples import CounterexampleError, CounterexampleFormat, decode_float, decode_str
    from analysis.verify.loading import ProblemLoadError
    from hybrid.errors import ParameterError

    fmt = CounterexampleFormat(name=COUNTEREXAMPLE_FORMAT, version=1, reader="this visnav")
    try:
        data = fmt.loads(text, path)
        named = decode_str(data.get("problem"), "problem", path)
        name = decode_str(data.get("requirement"), "requirement", path)
        spec = _confirmed_problem(named, given)
        options = _options(data, spec, path)
        unit = _units(data, path)
        recorded = decode_float(data.get("robustness"), "robustness", path)
    except CounterexampleError as error:
        raise _Refused(f"replay: {error}") from None
    try:
        problem = load_verification_problem(spec, options, [name])
        point = _check_point(data, problem, unit, path)
    except ProblemLoadError as error:
        raise _Refused(f"replay {path}: {error.render()}", user_traceback=error.user_traceback) from None
    except CounterexampleError as error:
        raise _Refused(f"replay: {error}") from None
    except ParameterError as error:
        raise _Refused(f"replay {path}: {error.render()}") from None
    formula = problem.parsed[0].formula
    trace = _simulate(problem, point)
    rho, violated, why = _evaluate(formula, trace, name)
    out = {"file": path, "problem": spec, "requirement": name, "formula": formula.text, "point": point,
           "robustness": rho, "recorded_robustness": recorded, "violated": violated, "time": float(why.time),
           "atom": str(why.atom), "atom_value": float(why.value), "ended_early": None}
    complete, end, detail = run_end(problem, trace)
    if not complete:  # judged on the prefix, for every continuation (as the search judged it)
        truth = formula.prefix_satisfied(trace)
        out.update(violated=truth is False, undecided=truth is None, ended_early={"end": end, "detail": detail})
    return out


def replay_verification(text: str, path: str, as_json: bool, problem: str | None = None) -> int:
    """``visnav replay`` of a ``visnav verify`` counterexample (module docstring); returns the exit code."""
    try:
        out = _run(text, path, problem)
    except _Refused as refused:
        if refused.user_traceback:
            print(refused.user_traceback.rstrip(), file=sys.stderr)
        print(f"visnav: error: {refused.message}", file=sys.stderr)
        return refused.code
    if as_json:
        from hybrid.jsonable import to_jsonable

        print(json.dumps(to_jsonable(out, nonfinite="string"), sort_keys=True))
    else:
        state = "VIOLATED" if out["violated"] else ("UNDECIDED (the run ended early: "
                                                   f"{out['ended_early']['detail']})" if out.get("undecided")
                                                   else "holds now")
        print(f"replay {path}: requirement {out['requirement']} of {out['problem']}: {state}, robustness "
              f"{out['robustness']:.6g} (recorded {out['recorded_robustness']:.6g})\n"
              f"  formula: {out['formula'].strip()}\n  decided at t = {out['time']:.6g} s by {out['atom']} = "
              f"{out['atom_value']:.6g}\n  point: " + ", ".join(f"{k}={v:.6g}" for k, v in out["point"].items()))
    if out.get("undecided"):
        return EXIT_INCOMPLETE
    return EXIT_TASK_FAILED if out["violated"] else EXIT_OK


def add_parser(sub: Any) -> None:
    """Register the ``replay`` subcommand on ``visnav``'s subparsers."""
    rp = sub.add_parser("replay", help="replay a saved counterexample: its trace and the violated property")
    rp.add_argument("file", help="a counterexample written by visnav fuzz or visnav verify")
    rp.add_argument("--problem", default=None, metavar="SPEC",
                    help="the problem a visnav verify counterexample was found on, to confirm it (the file's own "
                         "is never imported): package.module:OBJECT or path/to/file.py:OBJECT; not needed for "
                         "paper")
    rp.add_argument("--all", action="store_true", help="show every sample of the trace")
    rp.add_argument("--json", action="store_true", help="print one JSON object")
    rp.set_defaults(func=cmd_replay)


TRACE_CONTEXT = 3
"""Rows shown before and after the violated sample (and around every jump) without ``--all``."""


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, tuple):
        return " -> ".join(value) if value else "-"
    return str(value)


def _shown_rows(trace: tuple[Any, ...], sample: int | None) -> list[int]:
    keep: set[int] = {0, len(trace) - 1}
    for i, row in enumerate(trace):
        if row.get("jumps"):
            keep.update(range(max(0, i - 1), min(len(trace), i + 2)))
    if sample is not None:
        keep.update(range(max(0, sample - TRACE_CONTEXT), min(len(trace), sample + TRACE_CONTEXT + 1)))
    return sorted(i for i in keep if 0 <= i < len(trace))


def _replay_human(path: str, result: Any, show_all: bool) -> str:
    from visnav.fuzzing import PROPERTIES

    cx = result.counterexample
    prop = PROPERTIES[cx.property]
    size = f"{len(cx.measurements)} samples" if cx.measurements is not None else f"scenario {cx.scenario.name!r}"
    lines = [
        f"replay {path}: property {cx.property} on variant {cx.variant} ({cx.kind}, {size})",
        f"  {prop.summary}",
    ]
    trace = result.trace
    if trace and "k" in trace[0]:
        columns = list(trace[0].keys())
        lines.append("  " + "  ".join(f"{c:>10}" if c not in ("mode", "jumps") else f"{c:<16}" for c in columns))
        shown = range(len(trace)) if show_all else _shown_rows(trace, result.sample)
        last = -1
        for i in shown:
            if i > last + 1:
                lines.append(f"  {'...':>10}")
            row = trace[i]
            cells = [f"{_fmt(row[c]):>10}" if c not in ("mode", "jumps") else f"{_fmt(row[c]):<16}" for c in columns]
            marker = "  <== violated here" if result.violated and i == result.sample else ""
            lines.append("  " + "  ".join(cells) + marker)
            last = i
    else:
        for row in trace:
            lines.append("  " + ", ".join(f"{k} = {_fmt(v)}" for k, v in row.items()))
    if result.violated:
        where = "" if result.sample is None else f" at sample {result.sample}"
        lines.append(f"VIOLATED{where}: {result.message}")
    else:
        lines.append("the property now HOLDS on this example")
    lines.append(f"  (recorded when found: {cx.message})")
    return "\n".join(lines)


def cmd_replay(args: argparse.Namespace) -> int:
    """``visnav replay FILE``: run a counterexample again, show its trace and the violated property."""
    from analysis.counterexamples import read_counterexample_text
    from visnav.fuzzing import CounterexampleError, counterexample_from_json, replay

    exit_ok, exit_failed, exit_bad = (EXIT_OK, EXIT_TASK_FAILED, EXIT_BAD_INPUT)
    try:
        text = read_counterexample_text(args.file)
    except CounterexampleError as err:
        print(f"visnav: error: replay {args.file!r}: {err.problem}; give a counterexample file written by "
              "visnav fuzz or visnav verify", file=sys.stderr)
        return exit_bad
    from visnav.app.cli_verify import is_verification_counterexample

    if is_verification_counterexample(text):
        return replay_verification(text, args.file, args.json, args.problem)
    try:
        cx = counterexample_from_json(text, args.file)
    except CounterexampleError as err:
        print(f"visnav: error: replay: {err}", file=sys.stderr)
        return exit_bad
    if args.problem is not None:
        print(f"visnav: error: replay {args.file!r}: --problem {args.problem!r} given for a visnav fuzz "
              f"counterexample, which names property {cx.property!r} of visnav fuzz, not a problem; drop --problem",
              file=sys.stderr)
        return exit_bad
    result = replay(cx)
    if args.json:
        out = {
            "file": args.file,
            "property": cx.property,
            "variant": cx.variant,
            "kind": cx.kind,
            "violated": result.violated,
            "message": result.message,
            "sample": result.sample,
            "recorded_message": cx.message,
            "trace": [to_jsonable(dict(row), nonfinite="string") for row in result.trace],
        }
        print(json.dumps(out, sort_keys=True))
    else:
        print(_replay_human(args.file, result, args.all))
    return exit_failed if result.violated else exit_ok
