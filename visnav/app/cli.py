"""The ``visnav`` command line: the parser and the entry point.

Each subcommand lives in its own module ``visnav/app/cli_<name>.py`` (``simulate``, ``mode_graph``, ``analyse``,
``report``, ``check`` for ``check-model``, ``sweep``, ``stiffness``, ``fuzz``, ``verify``, ``replay``...), which
registers itself with ``add_parser(sub)``.  Subcommands print a human summary, or with ``--json`` one JSON object
on standard output.  Exit codes (:mod:`visnav.app.cli_types`, ``docs/failure_modes.md``): 0 success, 1 the run
finished but the task failed or a requirement is falsified, 2 bad input, 3 a simulation diverged, 4 an internal
error, 5 incomplete (a check or run that did not decide), 6 an error of the user's model, 130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from importlib import import_module

from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_DIVERGED, EXIT_OK

__all__ = ["main", "build_parser", "REPORT_NUMERICS"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse exits with 2 too; keep its usage line
        self.print_usage(sys.stderr)
        self.exit(EXIT_BAD_INPUT, f"visnav: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``visnav``."""
    parser = _Parser(prog="visnav", description="Verify the Folio & Cadenat switching controller as a hybrid automaton.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name in ("simulate", "mode_graph", "analyse", "report", "check", "sweep", "stiffness", "fuzz", "replay", "verify", "reach"):
        import_module(f"visnav.app.cli_{name}").add_parser(sub)
    return parser


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
