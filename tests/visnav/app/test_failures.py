"""What escapes a command becomes one message and one exit code (docs/failure_modes.md)."""

from __future__ import annotations

import os
import re

import pytest

import visnav.app.cli as cli
import visnav.app.cli_mode_graph as cli_mode_graph
from hybrid.errors import DivergenceError, ExecutionError, ModelDefinitionError, NumericalFailure, ZenoError
from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_CODES, EXIT_DIVERGED, EXIT_INTERNAL, EXIT_INTERRUPTED
from visnav.app.failures import TRACEBACK_PREFIX


def _planted(monkeypatch, err: BaseException) -> None:
    def command(args):
        raise err

    monkeypatch.setattr(cli_mode_graph, "_cmd_mode_graph", command)


@pytest.mark.parametrize("err, code, words", [
    (RuntimeError("planted defect\nsecond line"), EXIT_INTERNAL, "internal error"),
    (KeyError("x"), EXIT_INTERNAL, "internal error"),
    (RecursionError("maximum recursion depth exceeded"), EXIT_INTERNAL, "internal error"),
    (KeyboardInterrupt(), EXIT_INTERRUPTED, "interrupted"),
    (NumericalFailure("the step size underflowed"), EXIT_DIVERGED, "could not complete"),
    (ZenoError("1000 jumps at t = 1"), EXIT_DIVERGED, "could not complete"),
    (ExecutionError("non-determinism at t = 0"), EXIT_DIVERGED, "could not complete"),
    (ModelDefinitionError("guard of 'a' returns a bool"), EXIT_BAD_INPUT, "error"),
])
def test_each_kind_of_exception_has_its_code_and_one_message(monkeypatch, capsys, tmp_path, err, code, words):
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)
    _planted(monkeypatch, err)
    assert cli.main(["mode-graph"]) == code
    err_text = capsys.readouterr().err
    assert "Traceback" not in err_text
    assert words in err_text
    assert len(err_text.strip().splitlines()) == 1
    files = sorted(tmp_path.glob(f"{TRACEBACK_PREFIX}*.txt"))
    if code == EXIT_INTERNAL:
        assert len(files) == 1 and str(files[0]) in err_text
        text = files[0].read_text()
        assert "Traceback (most recent call last)" in text and type(err).__name__ in text
        assert "command: visnav mode-graph" in text
    else:
        assert files == []


def test_a_divergence_gives_3_with_time_mode_and_cause(monkeypatch, capsys):
    _planted(monkeypatch, DivergenceError(12.5, "AVOID|CLEAR", "the state is not finite"))
    assert cli.main(["mode-graph"]) == EXIT_DIVERGED
    text = capsys.readouterr().err
    assert "12.5" in text and "AVOID|CLEAR" in text and "Traceback" not in text


def test_usage_errors_stay_argparse_exits():
    with pytest.raises(SystemExit) as exit_:
        cli.main(["no-such-command"])
    assert exit_.value.code == EXIT_BAD_INPUT


def test_the_exit_codes_are_documented():
    here = os.path.dirname(__file__)
    doc = open(os.path.join(here, "..", "..", "..", "docs", "failure_modes.md"), encoding="utf-8").read()
    for code in EXIT_CODES:
        assert re.search(rf"^\| {code} \|", doc, re.M), code


def test_a_finished_command_ignores_a_late_ctrl_c_during_shutdown(monkeypatch):
    import signal

    from visnav.app import entry

    monkeypatch.setattr("sys.argv", ["visnav", "mode-graph", "--format", "json"])
    previous = signal.getsignal(signal.SIGINT)
    try:
        assert entry.main() == 0
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN  # no "Exception ignored in threading._shutdown"
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_late_ctrl_c_after_the_command_does_not_print_or_change_the_exit_code(tmp_path):
    import subprocess
    import sys
    import textwrap

    script = tmp_path / "late.py"  # the command finishes, then SIGINT arrives while a thread is still joined
    script.write_text(textwrap.dedent('''
        import os, signal, sys, threading, time
        from visnav.app import entry
        sys.argv = ["visnav", "mode-graph", "--format", "json"]
        code = entry.main()
        threading.Thread(target=time.sleep, args=(0.5,)).start()   # a non-daemon thread the shutdown joins
        threading.Timer(0.1, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        sys.exit(code)
    '''))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "Exception ignored" not in done.stderr and "KeyboardInterrupt" not in done.stderr
