"""Generated hostile inputs against ``verify``, ``replay`` and ``report --problem`` (issue 25), with the contract:

* the exit code is one the command documents (never 4, "internal error", for a user's fault);
* no traceback of visnav's own: a traceback appears only when it is the user's (exit 2 for a module that
  does not load, 6 for a model that raised), and then it names the user's file;
* every case ends within :data:`CASE_BOUND_S` (a hang is a failure);
* an accepted input gives the same answer twice;
* no file outside visnav's own output is deleted or changed: every user file's bytes are compared after
  each case;
* no code runs that the command line did not name (a module a data file names writes a sentinel if run).

Five generators: user modules (simulators, factories and module bodies that raise, exit, print, sleep,
change the folder, return garbage), verify counterexample files (every field mutated, the problem
pointing at code), journals (cut, corrupted, forged with a valid checksum, stale), ``--out`` folders
holding user files, and label patterns.  ``CI`` runs :data:`CI_CASES` cases in all; locally a quarter.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import signal
import textwrap
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import visnav.app.cli as cli
from visnav.app.cli_types import (EXIT_BAD_INPUT, EXIT_DIVERGED, EXIT_INCOMPLETE, EXIT_INTERNAL, EXIT_MODEL_ERROR,
                                  EXIT_OK, EXIT_TASK_FAILED)

CI_CASES = 240
SHARE = {"module": 0.35, "counterexample": 0.25, "journal": 0.2, "out": 0.1, "pattern": 0.1}
CASE_BOUND_S = 60.0
VERDICT_CODES = {EXIT_OK, EXIT_TASK_FAILED, EXIT_BAD_INPUT, EXIT_DIVERGED, EXIT_INCOMPLETE, EXIT_MODEL_ERROR}


def _examples(kind: str) -> int:
    total = CI_CASES if os.environ.get("CI") else CI_CASES // 4
    return max(6, int(total * SHARE[kind]))


def _settings(kind: str) -> settings:
    return settings(max_examples=_examples(kind), deadline=None, database=None, derandomize=True,
                    suppress_health_check=list(HealthCheck))


class _Hang(Exception):
    pass


def run(argv: list[str]) -> tuple[int, str, str]:
    """``visnav ARGV`` in-process: (exit code, stdout, stderr) within :data:`CASE_BOUND_S`; the folder restored."""
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()

    def alarm(signum, frame):
        raise _Hang(f"visnav {' '.join(argv)} ran over {CASE_BOUND_S} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, CASE_BOUND_S)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = cli.main(argv)
            except SystemExit as exit_:
                code = exit_.code if isinstance(exit_.code, int) else EXIT_BAD_INPUT
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        os.chdir(here)
    return code, out.getvalue(), err.getvalue()


def snapshot(folder: Path) -> dict[str, str]:
    """sha256 of every file under ``folder`` (the user's files)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def assert_contract(code: int, out: str, err: str, allowed: set[int], user_file: Path | None = None) -> None:
    text = out + err
    assert code != EXIT_INTERNAL, f"internal error: {text[-1500:]}"
    assert code in allowed, f"exit {code} (allowed {sorted(allowed)}): {text[-1500:]}"
    if "Traceback (most recent call last)" in text:
        assert code in (EXIT_BAD_INPUT, EXIT_MODEL_ERROR), f"a traceback with exit {code}: {text[-1500:]}"
        assert user_file is not None and user_file.name in text, f"a traceback not of the user's code: {text[-1500:]}"


# --------------------------------------------------------------------------- user modules
MODULE = '''
import numpy as np
from analysis.verify import Parameter, Requirement, SignalTrace, VerificationProblem
IMPORT_BODY

def simulate(p):
    t = np.linspace(0.0, 2.0, 41)
    SIM_BODY
    return SignalTrace(times=t, signals={"x": p["x0"] * np.exp(-t)}, labels={"mode": ("run",) * 41})

def factory():
    FACTORY_BODY
    return problem

problem = VerificationProblem(name="decay", simulate=simulate,
    parameters=(Parameter(name="x0", low=0.5, high=2.0),), horizon=2.0, signals=("x",), labels={"mode": ("run",)},
    requirements=(Requirement(name="positive", formula=FORMULA),))
'''

SIM_BODIES = [
    "pass", "raise ValueError('mu = 1.3 is outside [0, 1]')", "import sys; sys.exit(0)", "import sys; sys.exit('m')",
    "import sys; sys.exit(3)", "raise GeneratorExit()", "raise KeyError('y')",
    "class E(Exception):\n        def __str__(self): raise RuntimeError()\n    raise E()",
    "print('noise from the model')", "import time; time.sleep(5)", "import os; os.chdir('/')",
    "return {'x': 1.0}", "return SignalTrace(times=t, signals={'x': t * float('nan')})",
    "return SignalTrace(times=t[:10], signals={'x': np.ones(10)}, labels={'mode': ('run',) * 10})",
    "if p['x0'] > 1.5: raise RuntimeError('only part of the box')", "x = 1 / 0",
]
IMPORT_BODIES = ["", "print('import noise')", "import os; os.chdir('/')", "raise ImportError('broken dependency')",
                 "import sys; sys.exit(0)", "raise SystemExit(3)"]
FACTORY_BODIES = ["pass", "raise ValueError('bad factory')", "import sys; sys.exit(0)", "return 42"]
FORMULAS = ["always[0, 2] (x > 0)", "always[0, 2] (x > 0.3)", "eventually[0, 2] (x < 0.2)",
            "always[0, 2] (x / (x - x) > 0)", 'always[0, 2] (mode == "r*n")']


def _write_module(folder: Path, sim: str, body: str, factory: str, formula: str) -> Path:
    text = textwrap.dedent(MODULE).replace("IMPORT_BODY", body).replace("SIM_BODY", sim) \
        .replace("FACTORY_BODY", factory).replace("FORMULA", repr(formula))
    path = folder / "user_model.py"
    path.write_text(text)
    return path


@_settings("module")
@given(sim=st.sampled_from(SIM_BODIES), body=st.sampled_from(IMPORT_BODIES), factory=st.sampled_from(FACTORY_BODIES),
       formula=st.sampled_from(FORMULAS), obj=st.sampled_from(["problem", "factory"]), as_json=st.booleans())
def test_generated_user_modules(tmp_path_factory, sim, body, factory, formula, obj, as_json):
    user = tmp_path_factory.mktemp("user")
    (user / "notes.txt").write_text("mine")
    path = _write_module(user, sim, body, factory, formula)
    before = snapshot(user)
    answers = []
    for k in range(2):
        argv = ["verify", f"{path}:{obj}", "--budget", "3", "--sim-timeout", "0.5",
                "--out", str(tmp_path_factory.mktemp("out") / f"o{k}")] + (["--json"] if as_json else [])
        code, out, err = run(argv)
        assert_contract(code, out, err, VERDICT_CODES, path)
        if as_json and code not in (EXIT_BAD_INPUT,):
            data = json.loads(out)  # stdout holds the JSON alone, whatever the model prints
            answers.append((code, data["verdict"], [r["verdict"] for r in data["requirements"]]))
        else:
            answers.append((code,))
    assert answers[0] == answers[1], answers
    assert snapshot(user) == before
    assert not Path("/out").exists() or not any(Path("/out").rglob("verification.json"))


# --------------------------------------------------------------------------- counterexample files
@st.composite
def counterexample_edit(draw):
    key = draw(st.sampled_from(["problem", "options", "unit", "point", "requirement", "robustness", "format", "trace",
                                "cut", "none"]))
    value = draw(st.sampled_from([
        None, "os:abort", "tempfile:mkdtemp", "SENTINEL", "paper", float("nan"), "inf", [float("nan")], [7.0],
        [-1.0], [0.0, 0.0], {"scenario": "paper"}, {"evil": 1}, {"x0": 99.0}, "", [], {}, 3, True,
    ]))
    return key, value, draw(st.booleans())


@_settings("counterexample")
@given(edit=counterexample_edit())
def test_generated_counterexample_files(tmp_path_factory, edit):
    key, value, confirm = edit
    user = tmp_path_factory.mktemp("user")
    path = _write_module(user, "pass", "", "pass", "always[0, 2] (x > 0.3)")
    sentinel = user / "SENTINEL_RAN"
    evil = user / "evil.py"
    evil.write_text(f"open({str(sentinel)!r}, 'w').write('ran')\nproblem = None\n")
    out = tmp_path_factory.mktemp("out") / "o"
    code, _, err = run(["verify", f"{path}:problem", "--budget", "8", "--out", str(out)])
    assert code == EXIT_TASK_FAILED, err
    cx = out / "counterexamples" / "positive.json"
    data = json.loads(cx.read_text())
    if key == "cut":
        text = cx.read_text()[: len(cx.read_text()) // 2]
    else:
        if key != "none":
            data[key] = f"{evil}:problem" if value == "SENTINEL" else value
        text = json.dumps(data)
    cx.write_text(text)
    before = snapshot(user)
    argv = ["replay", str(cx)] + (["--problem", f"{path}:problem"] if confirm else [])
    codes = []
    for _ in range(2):
        code, out_text, err = run(argv)
        assert_contract(code, out_text, err, {EXIT_OK, EXIT_TASK_FAILED, EXIT_BAD_INPUT, EXIT_INCOMPLETE,
                                              EXIT_MODEL_ERROR, EXIT_DIVERGED}, path)
        codes.append(code)
    assert codes[0] == codes[1]
    assert not sentinel.exists(), "a data file chose the code that ran"
    assert snapshot(user) == before


# --------------------------------------------------------------------------- journals
@_settings("journal")
@given(kind=st.sampled_from(["cut", "byte", "forge_unit", "forge_status", "forge_nan", "forge_sat", "stale",
                             "duplicate", "empty", "header"]),
       where=st.integers(0, 10_000), budget=st.sampled_from([4, 6]))
def test_generated_journals(tmp_path_factory, kind, where, budget):
    from visnav.app.campaign_store import canonical_json, line_checksum

    user = tmp_path_factory.mktemp("user")
    path = _write_module(user, "pass", "", "pass", "always[0, 2] (x > 0.3)")
    fresh = tmp_path_factory.mktemp("fresh") / "o"
    code0, first, _ = run(["verify", f"{path}:problem", "--budget", str(budget), "--out", str(fresh), "--json"])
    out = tmp_path_factory.mktemp("out") / "o"
    run(["verify", f"{path}:problem", "--budget", str(budget), "--out", str(out)])
    journal = out / "evaluations.jsonl"
    raw = journal.read_bytes()
    lines = raw.decode().splitlines()
    if kind == "cut":
        journal.write_bytes(raw[: where % max(1, len(raw))])
    elif kind == "byte":
        k = where % len(raw)
        journal.write_bytes(raw[:k] + bytes([raw[k] ^ 0x5A]) + raw[k + 1:])
    elif kind.startswith("forge") and len(lines) > 2:
        line = json.loads(lines[2])
        change = {"forge_unit": {"unit": [0.1, 0.2]}, "forge_status": {"status": "bogus"},
                  "forge_nan": {"robustness": ["nan"]}, "forge_sat": {"satisfied": []}}[kind]
        line["result"].update(change)
        line["sha256"] = line_checksum(line["result"])
        lines[2] = canonical_json(line)
        journal.write_text("\n".join(lines) + "\n")
    elif kind == "stale":
        path.write_text(path.read_text().replace("0.3", "0.31"))
    elif kind == "duplicate" and len(lines) > 2:
        journal.write_text("\n".join(lines + [lines[2]]) + "\n")
    elif kind == "empty":
        journal.write_text("")
    elif kind == "header":
        journal.write_text("\n".join(['{"format": "other"}'] + lines[1:]) + "\n")
    code, again, err = run(["verify", f"{path}:problem", "--budget", str(budget), "--out", str(out), "--json"])
    assert_contract(code, again, err, {EXIT_OK, EXIT_TASK_FAILED, EXIT_BAD_INPUT}, path)
    if code != EXIT_BAD_INPUT and kind != "stale":  # a resumed search ends as an uninterrupted one
        assert code == code0
        assert _verdicts(again) == _verdicts(first)
    if kind == "stale":
        assert code == EXIT_BAD_INPUT and "changed" in err


def _verdicts(text: str) -> list[dict]:
    """The requirements' verdicts of a ``--json`` output, without where its files were written."""
    rows = json.loads(text)["requirements"]
    for row in rows:
        if row.get("counterexample"):
            row["counterexample"] = {k: v for k, v in row["counterexample"].items() if k not in ("file", "replay")}
    return rows


# --------------------------------------------------------------------------- --out folders holding user files
USER_FILES = ["report.md", "report.json", "report.html", "figures/thesis.png", "verification.json",
              "counterexamples/positive.json", "notes.txt", ".visnav-manifest.json", "evaluations.jsonl"]


@_settings("out")
@given(files=st.lists(st.sampled_from(USER_FILES), min_size=1, max_size=4, unique=True),
       command=st.sampled_from(["verify", "report"]), beside=st.booleans())
def test_generated_out_folders_keep_the_users_files(tmp_path_factory, files, command, beside):
    user = tmp_path_factory.mktemp("user")
    path = _write_module(user, "pass", "", "pass", "always[0, 2] (x > 0.3)")
    target = user / "results"
    for name in files:
        (target / name).parent.mkdir(parents=True, exist_ok=True)
        (target / name).write_text(f"the user's own {name}")
    if beside:
        (user / ".results.partial-1-abcdefgh").mkdir()
        (user / ".results.partial-1-abcdefgh" / "draft.txt").write_text("mine too")
    before = snapshot(user)
    if command == "verify":
        argv = ["verify", f"{path}:problem", "--budget", "3", "--out", str(target)]
    else:
        argv = ["report", "--problem", f"{path}:problem", "--quick", "--budget", "3", "--out", str(target)]
    code, out, err = run(argv)
    assert_contract(code, out, err, {EXIT_OK, EXIT_TASK_FAILED, EXIT_BAD_INPUT, EXIT_INCOMPLETE}, path)
    after = snapshot(user)
    changed = {k for k in before if after.get(k) != before[k]}
    assert not changed, f"user files changed or deleted: {sorted(changed)} ({command} exit {code}: {err[-500:]})"


# --------------------------------------------------------------------------- label patterns
@_settings("pattern")
@given(pattern=st.lists(st.sampled_from(["*", "?", "r", "u", "n", "Z", "|"]), min_size=1, max_size=60).map("".join),
       op=st.sampled_from(["==", "!="]))
def test_generated_label_patterns_end_fast(tmp_path_factory, pattern, op):
    user = tmp_path_factory.mktemp("user")
    path = _write_module(user, "pass", "", "pass", f'always[0, 2] (mode {op} "{pattern}" or x > 0)')
    code, out, err = run(["verify", f"{path}:problem", "--budget", "2", "--out", str(user / "o"), "--json"])
    assert_contract(code, out, err, {EXIT_OK, EXIT_TASK_FAILED, EXIT_BAD_INPUT}, path)
