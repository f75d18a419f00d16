"""visnav verify / report --problem / check-model --problem on a SpaceEx model with --config, end to end."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
DATA = ROOT / "tests" / "data" / "spaceex"
BALL = DATA / "spaceexparser" / "bball" / "bball.xml"
SAFE = DATA / "visnav" / "bball_forbidden.cfg"
UNSAFE = DATA / "visnav" / "bball_unsafe.cfg"


def visnav(*args, cwd):
    return subprocess.run([sys.executable, "-m", "visnav.app.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT if cwd is None else cwd, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})


def test_verify_a_safe_ball_is_not_falsified(tmp_path):
    proc = visnav("verify", BALL, "--config", SAFE, "--budget", 3, "--out", tmp_path / "v", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    (verdict,) = data["requirements"] if "requirements" in data else data["verdicts"]
    # x <= 10.2 on every run (the ball never climbs above its start): robustness 10.5 - x0 >= 0.3; the flowpipe
    # proves it and the own re-check confirms it (margin 0.29999, the closed-form slack 0.3)
    assert verdict["verdict"] == "proven" and 0.3 - 1e-9 <= verdict["robustness"] <= 0.5 + 1e-9


def test_verify_an_unsafe_ball_is_falsified_and_replays(tmp_path):
    proc = visnav("verify", f"{BALL}:system", "--config", UNSAFE, "--budget", 3, "--out", tmp_path / "v",
                  cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr
    assert "falsified" in proc.stdout
    counterexample = tmp_path / "v" / "counterexamples" / "safe.json"
    refused = visnav("replay", counterexample, cwd=tmp_path)  # the file names the model: confirm it
    assert refused.returncode == 2 and "--problem" in refused.stderr
    replay = visnav("replay", counterexample, "--problem", f"{BALL}:system", cwd=tmp_path)
    assert replay.returncode == 1 and "VIOLATED" in replay.stdout, replay.stderr


@pytest.mark.parametrize("args, expected", [
    (("verify", BALL), "--config"),
    (("verify", DATA / "nope.xml", "--config", SAFE), "nope.xml"),
    (("verify", BALL, "--config", DATA / "nope.cfg"), "nope.cfg"),
    (("verify", f"{BALL}:ghost", "--config", SAFE), "ghost"),
    (("report", "--problem", BALL, "--config", DATA / "nope.cfg"), "nope.cfg"),
    (("check-model", "--problem", DATA / "nope.xml", "--config", SAFE), "nope.xml"),
])
def test_bad_paths_exit_2_with_a_message(tmp_path, args, expected):
    proc = visnav(*args, cwd=tmp_path)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert expected in proc.stderr and "Traceback" not in proc.stderr


def test_report_problem_on_the_ball(tmp_path):
    out = tmp_path / "r"
    proc = visnav("report", "--problem", BALL, "--config", SAFE, "--quick", "--budget", 2, "--out", out, "--json",
                  cwd=tmp_path)
    # no state box in the .cfg: the state-space checks are skipped, so the report is incomplete (5), not a pass
    assert proc.returncode == 5, proc.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["verdict"] == "incomplete" and report["verification"]["verdict"] == "proven"
    assert "SpaceEx" in (out / "report.md").read_text()


def test_check_model_problem_on_the_ball_is_incomplete_without_a_box(tmp_path):
    proc = visnav("check-model", "--problem", BALL, "--config", SAFE, "--json", cwd=tmp_path)
    # the SpaceEx problem has no state box for the state-space searches: the graph checks run, the rest is
    # reported as not run, and the exit code says INCOMPLETE (5), never clean
    assert proc.returncode == 5, proc.stderr
    data = json.loads(proc.stdout)
    assert "unreachable" in json.dumps(data)


BUILDING = DATA / "arch2017" / "Building" / "SpaceEx"


def test_check_model_problem_on_the_building_is_a_finding_and_says_what_did_not_run(tmp_path):
    """The building's one location ``Model`` has no outgoing transition: the graph checks find a sink mode (a
    warning, a finding: exit 1 by the contract, which a decided finding takes over the checks that could not
    run), and the summary still lists the state-space checks that did not run (no box): never clean."""
    proc = visnav("check-model", "--problem", BUILDING / "BLDC01.xml", "--config", BUILDING / "BLDC01-BDS01.cfg",
                  "--json", cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr
    data = json.loads(proc.stdout)
    assert [(f["kind"], f["severity"]) for f in data["findings"]] == [("sink_mode", "warning")]
    assert not data["complete"] and not data["clean"]
    assert {line.split()[0] for line in data["incomplete"]} == {
        "nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers", "zeno"}
    text = visnav("check-model", "--problem", BUILDING / "BLDC01.xml", "--config", BUILDING / "BLDC01-BDS01.cfg",
                  cwd=tmp_path)
    assert text.returncode == 1 and "1 warning(s); INCOMPLETE" in text.stdout and "sink_mode" in text.stdout


def test_config_without_a_spaceex_model_is_refused(tmp_path):
    proc = visnav("verify", "paper", "--config", SAFE, "--budget", 1, cwd=tmp_path)
    assert proc.returncode == 2 and "drop --config" in proc.stderr and "Traceback" not in proc.stderr


def test_mode_graph_of_a_spaceex_network_is_the_flattened_automaton(tmp_path):
    timed = DATA / "spaceexparser" / "bball_timed" / "bball_timed.xml"
    proc = visnav("mode-graph", "--problem", timed, "--config", DATA / "spaceexparser" / "bball_timed" /
                  "bball_timed.cfg", "--format", "json", cwd=tmp_path)
    # bball_timed.cfg has no forbidden set: nothing to verify, refused with the reason
    assert proc.returncode == 2 and "forbidden" in proc.stderr
    proc = visnav("mode-graph", "--problem", BALL, "--config", SAFE, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "\"always\" -> \"always\"" in proc.stdout and "(x <= 0 and v < 0)" in proc.stdout  # eps = 0 substituted
