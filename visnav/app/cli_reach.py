"""``visnav reach --problem SPEC``: flowpipes of a verification problem and a verdict per requirement.

``SPEC`` is ``package.module:OBJECT``, ``path/to/file.py:OBJECT`` (a problem of
:func:`analysis.verify.problems.hybrid_problem` with a symbolic system, or a function of the parameters
building one: the parameters become constant states) or a SpaceEx model ``FILE.xml[:COMPONENT]``
with ``--config FILE.cfg`` (as ``visnav verify`` loads them; its bounded inputs taken as any signal within
their bounds, as ``verify``'s proofs take them, and named in the table and the JSON).  The computation is
:func:`analysis.reach.problem.problem_reach`; ``docs/reachability.md`` explains it.

Exit codes: 0 every flowpipe complete and every requirement proven (re-checked); 1 a flowpipe meets a
requirement's unsafe set (the over-approximation reaches it; ``visnav verify`` searches a
counterexample); 2 bad input (the problem, a model reachability cannot read, an option); 5
inconclusive (a flowpipe that blew up or hit a limit, a requirement outside the fragment or not
re-checked).
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path
from typing import Any

from visnav.app.cli_types import (EXIT_BAD_INPUT, EXIT_INCOMPLETE, EXIT_OK, EXIT_TASK_FAILED, non_negative_int,
                                  positive_seconds)

__all__ = ["add_parser", "exit_code", "RESULT_FILE"]

RESULT_FILE = "reach.json"
"""The flowpipes and verdicts in the ``--out`` folder."""


def add_parser(sub: Any) -> None:
    """Register ``reach`` on the subcommand parsers ``sub``."""
    cmd = sub.add_parser("reach", help="reachability of a problem: sound flowpipes and proven requirements")
    cmd.add_argument("--problem", required=True, metavar="SPEC",
                     help="package.module:OBJECT, path/to/file.py:OBJECT, or a SpaceEx model FILE.xml[:COMPONENT] "
                          "with --config FILE.cfg")
    cmd.add_argument("--config", default=None, metavar="FILE.cfg",
                     help="SpaceEx models only: the configuration (initially, forbidden, time-horizon)")
    cmd.add_argument("--horizon", type=positive_seconds, default=None, metavar="S",
                     help="time horizon in seconds (default: the problem's)")
    cmd.add_argument("--time-step", type=positive_seconds, default=None, metavar="S",
                     help="flowpipe step in seconds, 0 < step <= horizon, used alone (default: as `visnav verify`: "
                          "the problem's step, e.g. a SpaceEx sampling-time, else horizon / 1000, with the steps "
                          "of fast modes chosen from the dynamics; docs/reachability.md)")
    cmd.add_argument("--max-jumps", type=non_negative_int, default=None, metavar="N",
                     help="jump bound (default: max(50, 10 per second of horizon))")
    cmd.add_argument("--json", action="store_true", help="print one JSON object (flowpipes and verdicts)")
    cmd.add_argument("--out", default=None, metavar="DIR",
                     help=f"write {RESULT_FILE} and figures (each state over time, and --plot) into DIR")
    cmd.add_argument("--plot", default=None, metavar="X,Y",
                     help="with --out: also the phase plane of the states X and Y")
    cmd.add_argument("--progress", action="store_true",
                     help="show the progress bar on stderr even when it is not a terminal")
    cmd.set_defaults(func=_cmd_reach)


def exit_code(result: Any) -> int:
    """0 complete and every requirement proven; 1 an unsafe set met; 5 anything undecided."""
    statuses = [r.status for r in result.requirements]
    if "met" in statuses:
        return EXIT_TASK_FAILED
    if not result.complete or any(s != "proven" for s in statuses):
        return EXIT_INCOMPLETE
    return EXIT_OK


def _bad(message: str, user_traceback: str = "") -> int:
    if user_traceback:
        print(user_traceback.rstrip(), file=sys.stderr)
    print(f"visnav: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


_WORDS = (("time_step = ", "--time-step "), ("horizon = ", "--horizon "), ("max_jumps = ", "--max-jumps "))


def _words(message: str) -> str:
    for library, cli in _WORDS:
        message = message.replace(library, cli)
    return message


class _Bar:
    """``[#####.....] 50% of the horizon`` on stderr, redrawn in place (only when asked or on a terminal)."""

    def __init__(self, on: bool) -> None:
        self.on = on
        self.shown = -1

    def __call__(self, share: float) -> None:
        percent = int(100 * max(0.0, min(1.0, share)))
        if not self.on or percent == self.shown:
            return
        self.shown = percent
        filled = percent // 5
        sys.stderr.write(f"\rreach: [{'#' * filled}{'.' * (20 - filled)}] {percent:3d}% of the horizon")
        if percent == 100:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _plot_pair(text: str | None, names: tuple[str, ...]) -> tuple[str, str] | None | str:
    """``(x, y)``, None without --plot, or an error message."""
    if text is None:
        return None
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 2 or not all(parts):
        return f"--plot {text!r}: expected two state names X,Y, e.g. --plot {','.join((*names, *names)[:2])}"
    unknown = [p for p in parts if p not in names]
    if unknown:
        return f"--plot {text!r}: {unknown} not among the flowpipe's states {list(names)}; give two of them"
    return parts[0], parts[1]


def _load(args: argparse.Namespace) -> Any:
    from visnav.app.cli_verify import load_verification_problem

    options = {"config": args.config} if args.config is not None else {}
    quiet = contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext()
    with quiet:  # with --json, stdout carries the JSON alone: the model's own prints go to stderr
        return load_verification_problem(args.problem, options)


def _cmd_reach(args: argparse.Namespace) -> int:
    from analysis.verify.loading import ProblemLoadError
    from analysis.reach.affine import AffineError
    from analysis.reach.parameters import ParameterRoute
    from analysis.reach.problem import problem_reach
    from hybrid.errors import ModelDefinitionError, ParameterError

    try:
        problem = _load(args)
    except ProblemLoadError as error:
        return _bad(error.render(), error.user_traceback)
    except ParameterError as error:
        return _bad(_words(error.render()))
    unbounded = _unbounded(args)
    if unbounded and args.horizon is None:
        return _bad(f"--config {args.config}: time-horizon < 0 is unbounded (for all t >= 0): visnav reach computes a "
                    "flowpipe over a bounded horizon only; give --horizon H for the flowpipe over [0, H] (its verdicts "
                    "then hold over [0, H] only), or run visnav verify, which decides it for all time by cycle "
                    "induction")
    horizon = args.horizon if args.horizon is not None else problem.horizon
    if args.time_step is not None and args.time_step > horizon:
        return _bad(f"--time-step {args.time_step:g}: larger than the horizon {horizon:g} s; give a step "
                    f"0 < step <= {horizon:g} (e.g. {horizon / 1000:g})")
    bar = _Bar(args.progress or sys.stderr.isatty())
    try:
        with contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext():
            result = problem_reach(problem, horizon=args.horizon, time_step=args.time_step,
                                   max_jumps=args.max_jumps, progress=bar)
    except AffineError as error:
        return _bad(f"problem {problem.name!r}: reachability needs a symbolic, affine model: {error}. Write the "
                    "flows with hybrid.symbolic.flow_map(...), the resets with jump_map(...), guards and invariants "
                    "as symbolic conditions (v = coordinates('x'); v.x >= 1.0); `visnav verify` still falsifies "
                    "other models")
    except ParameterRoute as error:
        return _bad(f"problem {problem.name!r}: reachability cannot read its parameters: {error}")
    except (ParameterError, ModelDefinitionError) as error:
        return _bad(_words(error.render() if hasattr(error, "render") else str(error)))
    pair = _plot_pair(args.plot, result.setup.model.state_names)
    if isinstance(pair, str):
        return _bad(pair)
    written: list[str] = []
    if args.out is not None:
        try:
            written = _write(args, result, pair)
        except _Foreign as error:
            return _bad(str(error))
    if args.json:
        print(result.to_json())
    else:
        print(_human(result, written))
    return exit_code(result)


def _unbounded(args: argparse.Namespace) -> bool:
    """Whether ``--config`` names a SpaceEx configuration with an unbounded horizon (``time-horizon < 0``)."""
    from analysis.spaceex import config_unbounded

    return args.config is not None and config_unbounded(args.config)


class _Foreign(Exception):
    """Files in ``--out`` that visnav did not write and would overwrite."""


def _time_label(result: Any) -> str:
    s = result.setup
    return f"time tau = {s.scale_text}·t [s]" if s.scale_text else "time t [s]"


def _write(args: argparse.Namespace, result: Any, pair: tuple[str, str] | None) -> list[str]:
    from visnav.app.files import figures_png, prepare_output_dir, write_png, write_text_atomic
    from visnav.app.figures_reach import phase_plane, sets_over_time
    from visnav.app.ownership import anchored, describe_entries, read_manifest, unowned_targets, write_manifest

    shown = Path(args.out)
    folder = prepare_output_dir(anchored(args, shown))
    names = result.setup.model.state_names
    stems = {f"figures/sets_{n}": n for n in names}
    if pair is not None:
        stems[f"figures/phase_{pair[0]}_{pair[1]}"] = pair
    targets = [RESULT_FILE, *(f"{stem}.png" for stem in stems)]
    foreign = unowned_targets(folder, targets)
    if foreign:
        raise _Foreign(f"--out {str(shown)!r}: {len(foreign)} file(s) that reach would overwrite are there and were "
                       f"not written by visnav ({describe_entries(foreign)}); nothing was overwritten: move them "
                       "away, or choose another --out")
    earlier = read_manifest(folder) or {}
    title = result.problem
    figures = {}
    for stem, what in stems.items():
        if isinstance(what, tuple):
            figures[stem] = phase_plane(result.runs, what[0], what[1], f"{title}: {what[0]}, {what[1]}")
        else:
            figures[stem] = sets_over_time(result.runs, what, f"{title}: {what}", _time_label(result))
    (folder / "figures").mkdir(exist_ok=True)
    write_png(folder, figures_png(figures))
    write_text_atomic(folder / RESULT_FILE, result.to_json() + "\n")
    kept = [r for r in earlier if r not in targets and (folder / r).is_file() and not unowned_targets(folder, [r])]
    write_manifest(folder, [*targets, *kept], "reach")
    return [str(shown / t) for t in targets]


_SHOWN = {"proven": "proven", "not_rechecked": "not re-checked", "met": "unsafe set met", "inconclusive":
          "inconclusive", "not_in_fragment": "not decided"}


def _human(result: Any, written: list[str]) -> str:
    s = result.setup
    segments = sum(len(r.segments) for _, _, r in result.runs)
    jumps = sum(len(r.jumps) for _, _, r in result.runs)
    status = "COMPLETE" if result.complete else "INCONCLUSIVE"
    lines = [f"reach {result.problem}: {status} ({len(result.runs)} start mode(s) "
             f"{', '.join(m for m, _, _ in result.runs)}; {segments} segments, {jumps} jumps; horizon "
             f"{result.horizon:g} s, step {result.time_step:g} s, jump bound {result.max_jumps})"]
    if result.steps_chosen:
        lines.append(f"  {result.steps_chosen}")
    elif result.options.get("mode_time_steps"):
        lines.append("  the problem's steps: " + ", ".join(f"{k!r} {v:.4g} s" for k, v in
                                                          sorted(result.options["mode_time_steps"].items())))
    if result.inputs:
        bounds = [f"{n} in [{lo:g}, {hi:g}]" for n, lo, hi in result.inputs]
        lines.append(f"  inputs (any signal within the bounds): {', '.join(bounds)}")
    if s.parameters:
        lines.append(f"  parameters as constant states: {', '.join(s.parameters)}")
    if s.scale_text:
        lines.append(f"  time scale: every flow is {s.scale_text} times a flow free of it; the flowpipes run in "
                     f"tau = {s.scale_text}·t up to {result.horizon * float(s.scale):g} (max {s.scale_text} = "
                     f"{float(s.scale):g})")
    for mode, _, r in result.runs:
        for t in r.terminations:
            if not t.conclusive:
                lines.append(f"  from mode {mode!r}: {t.detail}")
                break
    width = max([len(q.name) for q in result.requirements] or [0])
    for q in result.requirements:
        margin = "" if q.margin is None else f"  margin {q.margin:.4g}"
        again = "" if q.recheck_margin is None else f" (re-check {q.recheck_margin:.6g})"
        lines.append(f"  {_SHOWN[q.status]:<15} {q.name:<{width}}{margin}{again}  {q.reason}")
    if any(q.status == "met" for q in result.requirements):
        lines.append("  an unsafe set met by the flowpipe (an over-approximation) is not a counterexample: "
                     "`visnav verify` searches one")
    for path in written:
        lines.append(f"  wrote {path}")
    return "\n".join(lines)
