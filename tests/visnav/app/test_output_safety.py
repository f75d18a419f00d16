"""Nothing of the user's is lost by visnav's writers (issue 25): ``report --out`` replaces only a folder visnav
wrote (its manifest), names from data never leave their folder, a ``chdir`` in user code moves no output, a
look-alike partial folder is kept, and a counterexample's stored trace stays readable by ``replay``.

Every test plants user files (their bytes chosen here) around and inside the output folders and checks, after
each command, that every one of them still has exactly those bytes.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from analysis.counterexamples import MAX_FILE_BYTES
from visnav.app import report_files

ROOT = Path(__file__).resolve().parents[3]
THERMOSTAT = f"{ROOT / 'examples' / 'thermostat.py'}:zero_band"
PAPER_TOML = ROOT / "visnav" / "scenarios" / "paper.toml"

USER_FILES = {
    "report.md": b"# my own notes\n",
    "report.json": b'{"mine": true}\n',
    "report.html": b"<p>mine</p>\n",
    "figures/thesis.png": b"\x89PNG my thesis figure",
    "counterexamples/mine.json": b'{\n "format": "visnav-verification-counterexample",\n "mine": 1\n}\n',
    "notes.txt": b"notes\n",
}
"""Files a user keeps, named as a report's files are (and one that is not)."""

MODULE = '''
import os
import numpy as np
from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verification import Parameter, VerificationProblem
PRELUDE

def simulate(p):
    DURING
    t = np.linspace(0.0, 2.0, 41)
    return SignalTrace(times=t, signals={"x": p["x0"] * np.exp(-t)}, labels={"mode": ("run",) * 41})

problem = VerificationProblem(name=NAME, simulate=simulate,
    parameters=(Parameter(name="x0", low=0.5, high=2.0),), horizon=2.0, signals=("x",), labels={"mode": ("run",)},
    requirements=(Requirement(name=REQUIREMENT, formula="always[0, 2] (x > 0.2)"),))
'''
"""A user's problem (x0 exp(-t) > 0.2 on [0, 2] fails for x0 < 1.478, the nominal 1.25 among them: falsified); NAME, REQUIREMENT, PRELUDE
(module level, at import) and DURING (in every simulation) are filled in per test."""


def _module(folder: Path, stem: str, *, name: str = "decay", requirement: str = "above", prelude: str = "",
            during: str = "pass") -> str:
    path = folder / f"{stem}.py"
    path.write_text(MODULE.replace("NAME", repr(name)).replace("REQUIREMENT", repr(requirement))
                    .replace("PRELUDE", prelude).replace("DURING", during))
    return f"{path}:problem"


def _plant(folder: Path, names=tuple(USER_FILES)) -> dict[Path, bytes]:
    """The user's files ``names`` written under ``folder``; their paths and bytes."""
    planted = {}
    for name in names:
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(USER_FILES[name])
        planted[path] = USER_FILES[name]
    return planted


def _assert_unchanged(planted: dict[Path, bytes]) -> None:
    for path, data in planted.items():
        assert path.is_file(), f"{path} was deleted"
        assert path.read_bytes() == data, f"{path} was changed"


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", ""])
    child.wait()
    return child.pid


def _look_alike(parent: Path, name: str) -> dict[Path, bytes]:
    """A user's folder and file named as visnav's partial ones are, of a writer that has ended, an hour old."""
    dead = _dead_pid()
    folder = parent / f".{name}.partial-{dead}-abcd1234"
    folder.mkdir(parents=True)
    planted = {folder / "report.md": b"kept in a folder with a partial-looking name\n",
               parent / f".notes.txt.partial-{dead}-wxyz5678": b"a file with a partial-looking name\n"}
    for path, data in planted.items():
        path.write_bytes(data)
    past = time.time() - 3600
    for path in (*planted, folder):
        os.utime(path, (past, past))
    return planted


# ---------------------------------------------------------------------------------- 1. report --out


@pytest.mark.parametrize("name", ["report.md", "report.json", "report.html", "figures/thesis.png",
                                  "counterexamples/mine.json"])
def test_report_out_holding_a_users_file_named_as_a_reports_is_refused_untouched(tmp_path, cli, name):
    out = tmp_path / "d"
    planted = _plant(out, [name])
    code, _, err = cli("report", "--problem", THERMOSTAT, "--quick", "--out", str(out))
    assert code == 2, err
    _assert_unchanged(planted)
    assert sorted(_tree(out)) == [name]
    assert name in err and "choose another --out" in err and "move them" in err


def test_report_replaces_only_the_folder_it_wrote_as_its_manifest_lists_it(tmp_path, cli):
    out = tmp_path / "d"
    beside = _plant(tmp_path, ["notes.txt"]) | _look_alike(tmp_path, "d")
    code, _, err = cli("report", "--problem", THERMOSTAT, "--quick", "--out", str(out))
    assert code == 1, err  # the example's min_dwell requirement is falsified
    first = _tree(out)
    manifest = json.loads(first[".visnav-manifest.json"])
    assert manifest["tool"] == "visnav" and manifest["command"] == "report"
    assert sorted(manifest["files"]) == sorted(k for k in first if k != ".visnav-manifest.json")
    code, _, err = cli("report", "--problem", THERMOSTAT, "--quick", "--out", str(out))
    assert code == 1, err
    assert _tree(out) == first  # its own folder replaced (same seed: the same bytes)
    _assert_unchanged(beside)  # the look-alike partial folder and file beside it are kept
    for change in ("modified", "extra", "manifest"):
        if change == "modified":
            (out / "report.md").write_bytes(b"edited by the user\n")
        elif change == "extra":
            (out / "figures" / "thesis.png").write_bytes(USER_FILES["figures/thesis.png"])
        else:
            (out / ".visnav-manifest.json").write_text("{}")
        kept = _tree(out)
        code, _, err = cli("report", "--problem", THERMOSTAT, "--quick", "--out", str(out))
        assert code == 2 and "not part of a visnav report" in err, (change, err)
        assert _tree(out) == kept, change
    _assert_unchanged(beside)


def test_a_look_alike_partial_folder_and_file_beside_out_are_kept(tmp_path, cli):
    planted = _look_alike(tmp_path, "d")  # named as an interrupted report's would be, writer ended, an hour old
    code, _, err = cli("report", "--problem", THERMOSTAT, "--quick", "--out", str(tmp_path / "d"))
    assert code == 1, err
    _assert_unchanged(planted)


def test_the_default_report_folder_holding_a_users_report_is_refused(tmp_path, cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    planted = _plant(tmp_path / "reports" / "thermostat-band-0", ["report.md"])
    code, _, err = cli("report", "--problem", THERMOSTAT, "--quick")
    assert code == 2 and "report.md" in err, err
    _assert_unchanged(planted)


# ---------------------------------------------------------------------------------- 2. names from data


@pytest.fixture()
def evil_scenario(tmp_path: Path) -> Path:
    """paper.toml with its scenario name changed to ``../victim`` (the first ``name =`` line is the scenario's)."""
    lines = PAPER_TOML.read_text().splitlines(keepends=True)
    first = next(i for i, line in enumerate(lines) if line.startswith("name = "))
    lines[first] = 'name = "../victim"\n'
    path = tmp_path / "evil.toml"
    path.write_text("".join(lines))
    return path


def test_a_scenario_name_with_dot_dot_cannot_write_outside_the_reports_folder(tmp_path, cli, monkeypatch,
                                                                             evil_scenario):
    monkeypatch.chdir(tmp_path)
    planted = _plant(tmp_path / "victim", ["report.md", "notes.txt"])
    code, _, err = cli("report", "--scenario", str(evil_scenario), "--quick")
    assert code == 2, err
    assert "'../victim'" in err and "name" in err and "path separator" in err
    _assert_unchanged(planted)
    assert sorted(_tree(tmp_path / "victim")) == ["notes.txt", "report.md"]
    code, _, err = cli("verify", "paper", "--scenario", str(evil_scenario), "--budget", "1")
    assert code == 2 and "'../victim'" in err, err
    assert not (tmp_path / "out").exists() and not (tmp_path / "victim" / "verification.json").exists()
    _assert_unchanged(planted)


@pytest.mark.parametrize("name, problem", [("../escape", "path separator"), ("a/b", "path separator"),
                                           (".hidden", "starts with a dot"), ("x" * 101, "101 bytes"),
                                           ("a\nb", "control character")])
def test_a_problem_name_that_is_no_plain_file_name_is_refused_before_any_work(tmp_path, cli, monkeypatch,
                                                                              name, problem):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    spec = _module(tmp_path, "named", name=name)
    code, _, err = cli("verify", spec, "--budget", "2")
    assert code == 2 and problem in err and "VerificationProblem.name" in err, err
    code, _, err = cli("report", "--problem", spec, "--quick")
    assert code == 2 and problem in err, err
    written = sorted(p.name for p in tmp_path.rglob("*") if "__pycache__" not in p.parts)
    assert written == ["named.py", "work"]  # nothing written anywhere


def test_a_requirement_name_too_long_for_a_file_is_refused_before_the_search(tmp_path, cli):
    spec = _module(tmp_path, "long_requirement", requirement="r" * 300)
    out = tmp_path / "o"
    code, _, err = cli("verify", spec, "--budget", "4", "--out", str(out))
    assert code == 2 and "requirement name" in err and "300 bytes" in err, err
    assert not (out / "evaluations.jsonl").exists()  # no simulation was run


# ---------------------------------------------------------------------------------- 3. during the run


def test_a_file_saved_into_the_report_folder_during_the_run_refuses_the_swap(tmp_path, cli, monkeypatch):
    out = tmp_path / "d"
    code, _, err = cli("report", "--problem", THERMOSTAT, "--quick", "--out", str(out))
    assert code == 1, err
    before = _tree(out)
    real_figures_png = report_files.figures_png

    def saving_meanwhile(figures):  # the report is being built: the user saves a file into its folder
        (out / "notes.txt").write_bytes(USER_FILES["notes.txt"])
        return real_figures_png(figures)

    monkeypatch.setattr(report_files, "figures_png", saving_meanwhile)
    code, _, err = cli("report", "--problem", THERMOSTAT, "--quick", "--out", str(out))
    assert code == 2 and "notes.txt" in err, err
    assert _tree(out) == {**before, "notes.txt": USER_FILES["notes.txt"]}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]  # no partial folder left beside it


def test_a_file_saved_between_the_last_check_and_the_swap_is_put_back(tmp_path, cli, monkeypatch):
    out = tmp_path / "d"
    code, _, err = cli("report", "--problem", THERMOSTAT, "--quick", "--out", str(out))
    assert code == 1, err
    before = _tree(out)
    real_swap_in = report_files._swap_in

    def late(staging, real):
        (out / "notes.txt").write_bytes(USER_FILES["notes.txt"])
        return real_swap_in(staging, real)

    monkeypatch.setattr(report_files, "_swap_in", late)
    code, _, err = cli("report", "--problem", THERMOSTAT, "--quick", "--out", str(out))
    assert code == 2 and "notes.txt" in err and "nothing was deleted" in err, err
    assert _tree(out) == {**before, "notes.txt": USER_FILES["notes.txt"]}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]


def test_verify_never_overwrites_a_users_file_before_or_during_the_search(tmp_path, cli):
    out = tmp_path / "o"
    planted = _plant(out, ["notes.txt"])
    (out / "verification.json").write_bytes(b'{"mine": 1}\n')
    planted[out / "verification.json"] = b'{"mine": 1}\n'
    spec = _module(tmp_path, "verify_user")
    code, _, err = cli("verify", spec, "--budget", "4", "--out", str(out))
    assert code == 2 and "verification.json" in err and "choose another --out" in err, err
    _assert_unchanged(planted)
    assert not (out / "evaluations.jsonl").exists()
    (out / "verification.json").unlink()
    del planted[out / "verification.json"]
    saved = out / "counterexamples" / "above.json"  # the user saves a file there while the search runs
    armed = tmp_path / "armed"
    armed.touch()
    prelude = textwrap.dedent(f"""
        def _user_saves():
            if os.path.exists({str(armed)!r}):
                os.remove({str(armed)!r})
                os.makedirs({str(saved.parent)!r}, exist_ok=True)
                open({str(saved)!r}, "x").write("mine")
        """)
    spec = _module(tmp_path, "verify_during", prelude=prelude, during="_user_saves()")
    code, _, err = cli("verify", spec, "--budget", "4", "--out", str(out))
    assert code == 2 and "counterexamples/above.json" in err and "resumes" in err, err
    assert saved.read_text() == "mine" and not (out / "verification.json").exists()
    assert (out / "evaluations.jsonl").is_file()  # the search is kept: the next run resumes it
    _assert_unchanged(planted)
    saved.unlink()
    code, out_text, err = cli("verify", spec, "--budget", "4", "--out", str(out), "--json")
    assert code == 1, err
    manifest = json.loads((out / ".visnav-manifest.json").read_text())
    assert sorted(manifest["files"]) == ["counterexamples/above.json", "evaluations.jsonl", "verification.json"]
    code, _, err = cli("verify", spec, "--budget", "4", "--out", str(out))  # its own files: rewritten
    assert code == 1, err
    _assert_unchanged(planted)


# ---------------------------------------------------------------------------------- 4. chdir in user code


def test_a_simulator_that_changes_the_folder_moves_no_output(tmp_path, cli, monkeypatch):
    work, elsewhere = tmp_path / "work", tmp_path / "elsewhere"
    work.mkdir()
    elsewhere.mkdir()
    monkeypatch.chdir(work)
    spec = _module(tmp_path, "wanders", prelude=f"os.chdir({str(elsewhere)!r})",
                   during=f"os.chdir({str(elsewhere)!r})")
    code, out, err = cli("verify", spec, "--budget", "4", "--json")
    assert code == 1, err
    found = work / "out" / "verify" / "decay" / "guided-seed0-budget4"
    assert sorted(_tree(found)) == [".visnav-manifest.json", "counterexamples/above.json", "evaluations.jsonl",
                                    "verification.json"]
    assert json.loads(out)["requirements"][0]["counterexample"]["file"] == (
        "out/verify/decay/guided-seed0-budget4/counterexamples/above.json")  # shown as before: relative
    os.chdir(work)
    code, _, err = cli("verify", spec, "--budget", "4", "--out", "rel")
    assert code == 1, err
    assert (work / "rel" / "verification.json").is_file()
    assert list(elsewhere.iterdir()) == []


# ---------------------------------------------------------------------------------- 14. long traces


LONG = '''
import numpy as np
from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verification import Parameter, VerificationProblem

N = 300_001

def simulate(p):
    t = np.linspace(0.0, 10.0, N)
    jumps = (t >= 2.5).astype(int) + (t >= 7.5).astype(int)
    dip = 0.5 * np.exp(-((t - 6.1234) / 0.01) ** 2)
    return SignalTrace(times=t, signals={"x": p["x0"] - dip}, jumps=jumps, labels={"mode": ("run",) * N})

problem = VerificationProblem(name="long", simulate=simulate,
    parameters=(Parameter(name="x0", low=0.3, high=2.0),), horizon=10.0, signals=("x",), labels={"mode": ("run",)},
    requirements=(Requirement(name="above", formula="always[0, 10] (x > 0.8)"),))
'''
"""x0 - 0.5 exp(-((t - 6.1234)/0.01)^2) > 0.8 fails for x0 < 1.3 (the nominal 1.15 among them), at t = 6.1234 s (a sample: 6.1234 = 183702 dt)."""


def test_a_long_trace_is_decimated_to_what_replay_reads_keeping_the_point(tmp_path, cli):
    path = tmp_path / "long_trace.py"
    path.write_text(textwrap.dedent(LONG))
    out = tmp_path / "o"
    code, _, err = cli("verify", f"{path}:problem", "--budget", "3", "--out", str(out))
    assert code == 1, err
    file = out / "counterexamples" / "above.json"
    assert file.stat().st_size <= MAX_FILE_BYTES // 5  # a fifth of replay's limit (the full trace: ~13 MB)
    data = json.loads(file.read_text())
    assert data["trace_decimated"]["samples"] == 300_001 and data["trace_decimated"]["every_change_kept"] is True
    rows = data["trace"]
    assert len(rows) == data["trace_decimated"]["stored"] <= 100_000
    times = [r[0] for r in rows]
    assert times[0] == 0.0 and times[-1] == 10.0
    dt = 10.0 / 300_000
    assert data["time"] == pytest.approx(6.1234, abs=dt)  # the violation: the dip's bottom
    assert any(abs(t - data["time"]) <= dt * 1.01 for t in times)  # stored beside it
    for jump_time in (2.5, 7.5):  # both samples of each jump
        k = int(np.ceil(jump_time / dt - 1e-9))
        assert k * dt in times and (k - 1) * dt in times
    assert [r[1] for r in rows] == sorted(r[1] for r in rows) and {r[1] for r in rows} == {0, 1, 2}
    assert data["point"] == {"x0": pytest.approx(data["point"]["x0"])} and data["requirement"] == "above"
    code, text, err = cli("replay", str(file), "--problem", f"{path}:problem")
    assert code == 1 and "VIOLATED" in text, err


# ---------------------------------------------------------------------------------- the harness contract


def test_no_user_file_around_or_inside_the_outputs_changes_in_any_case(tmp_path, cli, monkeypatch, evil_scenario):
    """The harness: user files everywhere a writer goes; after each case, every one of them has its bytes."""
    work = tmp_path / "work"
    monkeypatch.chdir(tmp_path)
    planted: dict[Path, bytes] = {}
    planted |= _plant(work / "mine")  # a folder of the user's own, every report-like name in it
    planted |= _plant(work, ["notes.txt", "report.md"])  # beside the outputs
    planted |= _plant(tmp_path / "victim", ["report.md"])
    planted |= _look_alike(work, "fresh")
    spec = _module(tmp_path, "harness")
    cases = [
        ("report", "--problem", THERMOSTAT, "--quick", "--out", str(work / "fresh")),  # new: written
        ("report", "--problem", THERMOSTAT, "--quick", "--out", str(work / "fresh")),  # its own: replaced
        ("report", "--problem", THERMOSTAT, "--quick", "--out", str(work / "mine")),  # the user's: refused
        ("report", "--scenario", str(evil_scenario), "--quick"),  # ../victim: refused
        ("verify", spec, "--budget", "4", "--out", str(work / "mine")),  # the user's report.json etc.: kept
        ("verify", spec, "--budget", "4", "--out", str(work / "verify")),
        ("verify", spec, "--budget", "4", "--out", str(work / "verify")),
    ]
    expected = [1, 1, 2, 2, 1, 1, 1]
    for argv, code_wanted in zip(cases, expected):
        code, _, err = cli(*argv)
        assert code == code_wanted, (argv, err)
        _assert_unchanged(planted)
    assert sorted(_tree(work / "mine")) == sorted([*USER_FILES, ".visnav-manifest.json", "counterexamples/above.json",
                                                   "evaluations.jsonl", "verification.json"])

