"""The worked example of docs/verify.md: a thermostat with hysteresis, verified, falsified at zero band."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from analysis.verify.loading import load_problem
from analysis.verify.testing import VerificationFailed, assert_verified

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "thermostat.py"


def _visnav(*args, cwd):
    return subprocess.run([sys.executable, "-m", "visnav.app.cli", *args], capture_output=True, text=True, cwd=cwd)


def test_the_shortest_dwell_over_the_box_is_above_the_requirement_in_closed_form():
    # on: T from 19.5 to 20.5 under T' = -k (T - 30); off: from 20.5 to 19.5 under T' = -k (T - 10); k <= 0.2
    on = math.log((30 - 19.5) / (30 - 20.5)) / 0.2
    off = math.log((20.5 - 10) / (19.5 - 10)) / 0.2
    assert min(on, off) == pytest.approx(0.5004, abs=1e-4) and min(on, off) > 0.25


def test_with_a_band_the_requirements_are_not_falsified():
    result = assert_verified(load_problem(f"{EXAMPLE}:problem"), budget=40)
    assert result.verdict == "not_falsified"
    comfort = result.requirement("comfort")
    # the room stays in [19.5, 20.5] once inside: robustness 1.5 - 0.5 = 1.0 (to the solver's tolerance)
    assert comfort.robustness == pytest.approx(1.0, abs=1e-6)


def test_with_a_zero_band_the_dwell_requirement_is_falsified_with_the_replay_command():
    problem = load_problem(f"{EXAMPLE}:zero_band")
    with pytest.raises(VerificationFailed) as info:
        assert_verified(problem, budget=10)
    message = str(info.value)
    assert "min_dwell FALSIFIED" in message and "visnav verify" in message and "visnav replay" in message
    cx = info.value.result.requirement("min_dwell").counterexample
    assert cx.time == 0.0 and cx.robustness < 0


def test_cli_verify_and_replay_exit_codes(tmp_path):
    out = tmp_path / "v"
    ok = _visnav("verify", f"{EXAMPLE}:problem", "--budget", "12", "--out", str(out / "a"), "--json", cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr
    data = json.loads(ok.stdout)
    assert data["verdict"] == "not_falsified"
    assert [r["name"] for r in data["requirements"]] == ["comfort", "min_dwell"]
    assert {"name", "formula", "verdict", "robustness", "simulations", "counterexample"} <= set(data["requirements"][0])
    bad = _visnav("verify", f"{EXAMPLE}:zero_band", "--budget", "6", "--out", str(out / "b"), "--json", cwd=tmp_path)
    assert bad.returncode == 1, bad.stderr
    data = json.loads(bad.stdout)
    cx = data["requirements"][1]["counterexample"]
    assert data["verdict"] == "falsified" and Path(cx["file"]).is_file()
    refused = _visnav("replay", cx["file"], "--json", cwd=tmp_path)  # the file's problem is not run unconfirmed
    assert refused.returncode == 2 and "re-run with --problem" in refused.stderr and refused.stdout == ""
    replay = _visnav("replay", cx["file"], "--problem", f"{EXAMPLE}:zero_band", "--json", cwd=tmp_path)
    assert replay.returncode == 1, replay.stderr
    assert json.loads(replay.stdout)["violated"] is True


def test_cli_verify_resumes_from_its_journal_with_identical_results(tmp_path):
    args = ("verify", f"{EXAMPLE}:problem", "--budget", "10", "--out", str(tmp_path / "r"), "--json")
    first = _visnav(*args, cwd=tmp_path)
    journal = (tmp_path / "r" / "evaluations.jsonl").read_text()
    assert len(journal.splitlines()) == 1 + 10
    second = _visnav(*args, cwd=tmp_path)
    assert first.returncode == second.returncode == 0
    assert json.loads(first.stdout) == json.loads(second.stdout)
    assert (tmp_path / "r" / "evaluations.jsonl").read_text() == journal


def test_cli_analyse_problem_finds_the_limit_cycle(tmp_path, capsys):
    from visnav.app.cli import main

    assert main(["analyse", "--problem", f"{EXAMPLE}:problem", "--json", "--out", str(tmp_path / "a")]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["verdict"] == "stable" and [e["kind"] for e in data["equilibria"]] == ["virtual", "virtual"]
    assert abs(data["orbit"]["period"] - 2 * math.log(10.5 / 9.5) / 0.1) < 1e-9
    assert (tmp_path / "a" / "stability.json").is_file() and (tmp_path / "a" / "stability_orbit.png").is_file()
    problem = load_problem(f"{EXAMPLE}:problem")
    bare = tmp_path / "bare.py"  # the same problem without stability=True: told how to ask for it, exit 2
    bare.write_text(EXAMPLE.read_text().replace("stability=True,", ""))
    assert main(["analyse", "--problem", f"{bare}:problem"]) == 2
    assert "has no stability analysis" in capsys.readouterr().err and problem.stability is not None
