"""The ``visnav fuzz`` subcommand (``visnav replay`` of its counterexamples: :mod:`visnav.app.cli_replay`).

``visnav fuzz [--property NAME]... [--variant NAME] [--examples N] [--seed S] [--out DIR] [--json] [--progress]``
runs the properties of :mod:`visnav.fuzzing` (all by default, each with its CI
budget of examples), writes the shrunk counterexample of every failed
property to ``DIR/<variant>.<property>.json`` (atomically) and exits 1 if a
property failed, 0 if all held.  A progress bar goes to standard error when
it is a terminal (or with ``--progress``).  With ``--json`` it prints one
JSON object, byte-identical for the same arguments (no timings in it).

``visnav replay FILE [--problem SPEC] [--all] [--json]`` runs a counterexample again and shows
the trace and the violated property; exit 1 if the property still fails, 0
if it now holds, 2 if the file cannot be read (missing, a folder, not a
regular file, over :data:`analysis.counterexamples.MAX_FILE_BYTES`, not UTF-8)
or is malformed (not strict JSON, another format or version, a missing,
unknown or ill-typed key, a scenario the scenario validator refuses).  A file
never chooses code to run: a fuzz counterexample names a property and a variant
of visnav's registries (looked up, never imported); a ``visnav verify``
counterexample of a user's problem is replayed only with ``--problem SPEC``
naming the same problem (:mod:`visnav.app.cli_replay`), ``--problem`` is refused
for a fuzz counterexample.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_OK, EXIT_TASK_FAILED, non_negative_int, positive_int

__all__ = ["add_parser", "cmd_fuzz", "DEFAULT_OUT"]

DEFAULT_OUT = "out/fuzz"
"""Where counterexamples go without ``--out``."""

def _exit_codes() -> tuple[int, int, int]:
    return EXIT_OK, EXIT_TASK_FAILED, EXIT_BAD_INPUT


def _property_name(text: str) -> str:
    from visnav.fuzzing import PROPERTIES

    if text not in PROPERTIES:
        raise argparse.ArgumentTypeError(f"unknown property {text!r}; known properties: {', '.join(PROPERTIES)}")
    return text


def _variant_name(text: str) -> str:
    from visnav.fuzzing import VARIANTS

    if text not in VARIANTS:
        raise argparse.ArgumentTypeError(f"unknown variant {text!r}; known variants: {', '.join(VARIANTS)}")
    return text


def _seed(text: str) -> int:
    """A seed: a whole number >= 0 that a counterexample file can hold (at most ``MAX_INT_DIGITS`` digits)."""
    from analysis.counterexamples import MAX_INT_DIGITS, show_value

    if len(text.strip().lstrip("+-").lstrip("0")) > MAX_INT_DIGITS:
        raise argparse.ArgumentTypeError(
            f"{show_value(text, 40)} has more than {MAX_INT_DIGITS} digits; give a whole number >= 0 of at most "
            f"{MAX_INT_DIGITS} digits (the counterexample files hold no longer integers)")
    return non_negative_int(text)


def add_parser(sub: Any) -> None:
    """Register the ``fuzz`` subcommand on ``visnav``'s subparsers."""
    fz = sub.add_parser("fuzz", help="fuzz the supervisor's switching logic with hypothesis (exit 1 if a property fails)")
    fz.add_argument("--property", dest="properties", action="append", type=_property_name, metavar="NAME",
                    help="a property to run (repeatable; default: all, see docs/fuzzing.md)")
    fz.add_argument("--variant", type=_variant_name, default="resolved",
                    help="supervisor to fuzz: resolved (default), paper (as written) or a mutant")
    fz.add_argument("--examples", type=positive_int, default=None,
                    help="examples per property (default: each property's CI budget)")
    fz.add_argument("--seed", type=_seed, default=None,
                    help="hypothesis seed, a whole number >= 0 (default: derandomised, the CI examples)")
    fz.add_argument("--out", default=None, help=f"folder for counterexample files (default: {DEFAULT_OUT})")
    fz.add_argument("--json", action="store_true", help="print one JSON object")
    fz.add_argument("--progress", action="store_true", help="show the progress bar even when stderr is not a terminal")
    fz.add_argument("--no-shrink", action="store_true", help="keep the first failing example (faster, longer)")
    fz.set_defaults(func=cmd_fuzz)


class _Progress:
    """A one-line progress bar on a stream (redrawn in place)."""

    WIDTH = 24
    INTERVAL_S = 0.2

    def __init__(self, stream: TextIO, budgets: dict[str, int]) -> None:
        self.stream = stream
        self.drawn_at = 0.0
        self.budgets = budgets
        self.index = 0
        self.total = len(budgets)
        self.name = ""

    def start(self, name: str, index: int, total: int) -> None:
        if self.name:
            self.stream.write("\n")
        self.name, self.index, self.total = name, index, total
        self.draw(0)

    def draw(self, done: int) -> None:
        budget = max(1, self.budgets.get(self.name, 1))
        filled = min(self.WIDTH, self.WIDTH * done // budget)
        bar = "#" * filled + "." * (self.WIDTH - filled)
        extra = " (shrinking)" if done > budget else ""
        self.stream.write(f"\r[{self.index + 1}/{self.total}] {self.name:<24} [{bar}] {min(done, budget)}/{budget}{extra}")
        self.stream.flush()

    def example(self, name: str, done: int) -> None:
        now = time.monotonic()
        if now - self.drawn_at >= self.INTERVAL_S:
            self.drawn_at = now
            self.draw(done)

    def close(self) -> None:
        if self.name:
            self.stream.write("\n")
            self.stream.flush()


def cmd_fuzz(args: argparse.Namespace) -> int:
    """``visnav fuzz``: run the properties, write the counterexamples, report."""
    from visnav.fuzzing import PROPERTIES, budget, counterexample_to_json, fuzz
    from visnav.app.files import prepare_output_dir, write_text_atomic

    exit_ok, exit_failed, _ = _exit_codes()
    names = tuple(dict.fromkeys(args.properties)) if args.properties else tuple(PROPERTIES)
    folder = prepare_output_dir(args.out) if args.out is not None else None
    budgets = {name: args.examples or budget(name) for name in names}
    progress = _Progress(sys.stderr, budgets) if (args.progress or sys.stderr.isatty()) else None
    start = time.perf_counter()
    try:
        report = fuzz(
            names, variant=args.variant, examples=args.examples, seed=args.seed, shrink=not args.no_shrink,
            on_property=None if progress is None else progress.start,
            on_example=None if progress is None else progress.example,
        )
    finally:
        if progress is not None:
            progress.close()
    wall = time.perf_counter() - start
    written: dict[str, list[str]] = {}
    for result in report.results:
        written[result.name] = []
        if result.counterexample is None:
            continue
        if folder is None:
            folder = prepare_output_dir(DEFAULT_OUT)
        path = Path(folder) / f"{report.variant}.{result.name}.json"
        write_text_atomic(path, counterexample_to_json(result.counterexample))
        written[result.name].append(str(path))
    if args.json:
        out = {
            "variant": report.variant,
            "seed": report.seed,
            "passed": report.passed,
            "properties": [{**r.as_dict(), "counterexamples": written[r.name]} for r in report.results],
        }
        print(json.dumps(out, sort_keys=True))
    else:
        print(_fuzz_human(report, written, wall))
    return exit_ok if report.passed else exit_failed


def _fuzz_human(report: Any, written: dict[str, list[str]], wall: float) -> str:
    seed = "derandomised" if report.seed is None else f"seed {report.seed}"
    lines = [f"visnav fuzz: variant {report.variant}, {seed}"]
    steps = 0
    for r in report.results:
        steps += r.steps
        unit = "steps" if r.kind != "scenario" else "samples"
        lines.append(f"  {r.name:<24} {'ok  ' if r.passed else 'FAIL'} {r.examples:>6} examples {r.steps:>9} {unit:<7} "
                     f"{r.wall_time_s:6.1f} s")
        if r.counterexample is not None:
            lines.append(f"      {r.counterexample.message}")
            for path in written[r.name]:
                lines.append(f"      counterexample: {path}  (visnav replay {path})")
    failed = sum(1 for r in report.results if not r.passed)
    signal_steps = sum(r.steps for r in report.results if r.kind != "scenario")
    signal_time = sum(r.wall_time_s for r in report.results if r.kind != "scenario")
    rate = f", {signal_steps / signal_time:,.0f} supervisor steps/s" if signal_time > 0 and signal_steps else ""
    lines.append(f"{len(report.results)} properties, {failed} failed; {wall:.1f} s{rate}")
    return "\n".join(lines)

