"""Exit codes and argument types of the ``visnav`` subcommands: one definition, one wording of every error.

The exit codes are shared by every subcommand (``docs/failure_modes.md``): 0 the task holds, 1 it
failed (collision, timeout, a falsified requirement, a finding), 2 bad input (nothing was run, or
what was given cannot be used; the message says what to change), 3 the run could not complete (a
simulation diverged or an executor failed), 4 internal error (a defect of visnav: the one-line
message names the file holding the traceback), 5 incomplete (a check or a simulation did not decide:
skipped, undecided, ended before its horizon), 6 a model error (the model's own code raised during a
run), 130 interrupted (SIGINT).

Each raises :class:`argparse.ArgumentTypeError` naming the value and what to give instead, which
argparse turns into a usage error (exit code 2).
"""

from __future__ import annotations

import argparse
import math
import signal

__all__ = ["EXIT_OK", "EXIT_TASK_FAILED", "EXIT_BAD_INPUT", "EXIT_DIVERGED", "EXIT_INTERNAL", "EXIT_INTERRUPTED",
           "EXIT_INCOMPLETE", "EXIT_MODEL_ERROR", "EXIT_CODES", "VERDICT_EXIT_CODES", "positive_int", "non_negative_int", "positive_seconds", "ignore_late_interrupts",
           "VERIFY_BUDGET", "VERIFY_BUDGET_QUICK"]

EXIT_OK, EXIT_TASK_FAILED, EXIT_BAD_INPUT, EXIT_DIVERGED, EXIT_INTERNAL = 0, 1, 2, 3, 4
"""The exit codes of every ``visnav`` subcommand."""
EXIT_INCOMPLETE, EXIT_MODEL_ERROR = 5, 6
"""5: a check or a run did not decide (skipped, undecided, a run that ended before its horizon: Zeno, a
deadlock, a jump limit), so nothing is claimed to pass; 6: the model's own code raised (or returned
garbage) during a run: a defect of the model, not a numerical divergence."""
EXIT_INTERRUPTED = 130
"""Interrupted by SIGINT (128 + 2, the shells' convention)."""
EXIT_CODES = {EXIT_OK: "the task holds", EXIT_TASK_FAILED: "the task failed",
              EXIT_BAD_INPUT: "bad input", EXIT_DIVERGED: "the run could not complete",
              EXIT_INTERNAL: "internal error", EXIT_INCOMPLETE: "a check or run did not decide",
              EXIT_MODEL_ERROR: "the model's code raised", EXIT_INTERRUPTED: "interrupted"}
"""What each exit code means (one line each, as ``docs/failure_modes.md`` explains them)."""
VERIFY_BUDGET, VERIFY_BUDGET_QUICK = 120, 16
"""Simulations of a verification: ``visnav verify``'s and the full report's default, and the quick report's
(the one definition of both; the paper's problem: about 40 s on one core for 120)."""
VERDICT_EXIT_CODES = {"proven": EXIT_OK, "not_falsified": EXIT_OK, "falsified": EXIT_TASK_FAILED,
                      "diverged": EXIT_DIVERGED, "incomplete": EXIT_INCOMPLETE, "error": EXIT_MODEL_ERROR}
"""The exit code of each overall verdict of a verification (:data:`analysis.verify.verdicts.OVERALL`)."""


def _whole(text: str, minimum: int, wanted: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer; give {wanted}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(
            f"{value} is {'not positive' if minimum == 1 else 'negative'}; give {wanted}")
    return value


def positive_int(text: str) -> int:
    """A whole number >= 1 (counts: samples, examples, workers)."""
    return _whole(text, 1, "a whole number >= 1")


def non_negative_int(text: str) -> int:
    """A whole number >= 0 (seeds, optional counts)."""
    return _whole(text, 0, "a whole number >= 0")


def positive_seconds(text: str) -> float:
    """A finite time > 0 [s]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number; give a time in seconds, e.g. 10") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text} is not a positive time; give seconds > 0, e.g. 10")
    return value


def ignore_late_interrupts(code: int) -> int:
    """Return ``code`` with SIGINT ignored from now on: the command has finished and written its results, so a
    Ctrl-C during the interpreter's shutdown (joining the executors' threads) must neither print "Exception
    ignored in threading._shutdown" nor change the exit code."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return code
