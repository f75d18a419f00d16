"""The one place where an exception escaping a ``visnav`` command becomes a message and an exit code.

Every subcommand returns its own exit code for the outcomes it knows (the task
holds, fails, bad input).  What escapes it is classified here
(``docs/failure_modes.md``):

* a :class:`KeyboardInterrupt` (SIGINT, also during start-up): "interrupted",
  exit 130, no traceback;
* an error of the input the command was given (:class:`ParameterError`,
  :class:`ScenarioError`, :class:`OutputError`, a model the user wrote that
  :mod:`hybrid` refuses): its message, exit 2;
* a run that could not complete (divergence, a numerical failure, a Zeno
  execution, an executor refusing a state): its message, exit 3;
* anything else is a defect of visnav: one line naming the exception and the
  file that holds the full traceback (written atomically to the temporary
  directory), exit 4.  Never a raw traceback on the terminal.
"""

from __future__ import annotations

import datetime
import os
import sys
import tempfile
import traceback
from collections.abc import Callable
from typing import Any, TextIO

from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_DIVERGED, EXIT_INTERNAL, EXIT_INTERRUPTED

__all__ = ["run_guarded", "classify", "write_traceback", "TRACEBACK_PREFIX"]

TRACEBACK_PREFIX = "visnav-internal-error-"
"""File name prefix of the tracebacks written for internal errors (in :func:`tempfile.gettempdir`)."""


def classify(err: BaseException) -> int:
    """The exit code of an exception escaping a command (module docstring)."""
    from hybrid.errors import (DivergenceError, ExecutionError, ModelDefinitionError, NumericalFailure, ParameterError,
                               ZenoError)

    if isinstance(err, KeyboardInterrupt):
        return EXIT_INTERRUPTED
    if isinstance(err, (ParameterError, ModelDefinitionError)):  # first: a bad argument may also be an ExecutionError
        return EXIT_BAD_INPUT
    if isinstance(err, (DivergenceError, NumericalFailure, ZenoError, ExecutionError)):
        return EXIT_DIVERGED
    for module, name in (("visnav.scenario", "ScenarioError"), ("visnav.app.files", "OutputError")):
        kind = getattr(sys.modules.get(module), name, None)
        if kind is not None and isinstance(err, kind):
            return EXIT_BAD_INPUT
    return EXIT_INTERNAL


def write_traceback(err: BaseException, argv: list[str] | None) -> str:
    """Write ``err``'s full traceback (and the command line) to a new file; return its path ("" if impossible)."""
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    text = (f"visnav internal error at {stamp} (pid {os.getpid()})\ncommand: visnav {' '.join(argv or sys.argv[1:])}\n"
            f"python {sys.version.split()[0]}\n\n"
            + "".join(traceback.format_exception(type(err), err, err.__traceback__)))
    try:
        fd, path = tempfile.mkstemp(prefix=f"{TRACEBACK_PREFIX}{stamp}-", suffix=".txt")
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
        return path
    except OSError:
        return ""


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    if len(text) > 300:
        text = text[:300] + "…"
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def run_guarded(command: Callable[[], int], argv: list[str] | None = None, stderr: TextIO | None = None) -> int:
    """Run ``command()`` and turn whatever escapes it into a message on ``stderr`` and an exit code."""
    out = stderr if stderr is not None else sys.stderr
    try:
        return int(command())
    except SystemExit:
        raise  # argparse's own exits (usage errors: 2, --help: 0)
    except BaseException as err:  # noqa: BLE001 - this is the one place that decides
        code = classify(err)
        _report(err, code, argv, out)
        return code


def _report(err: BaseException, code: int, argv: list[str] | None, out: Any) -> None:
    try:
        if code == EXIT_INTERRUPTED:
            print("visnav: interrupted (SIGINT); nothing half-written is left as a result "
                  "(see docs/failure_modes.md for what each command keeps)", file=out)
        elif code == EXIT_INTERNAL:
            path = write_traceback(err, argv)
            where = f"full traceback in {path}" if path else "the traceback could not be written to a file"
            print(f"visnav: internal error (a defect of visnav, please report it): {_one_line(err)}; {where}",
                  file=out)
        elif code == EXIT_DIVERGED:
            print(f"visnav: the run could not complete: {err}", file=out)
        else:
            print(f"visnav: error: {err}", file=out)
    except (OSError, ValueError):  # stderr closed or broken: the exit code still says it
        pass
