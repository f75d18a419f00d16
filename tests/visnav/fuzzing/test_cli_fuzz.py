"""visnav fuzz and visnav replay (visnav/app/cli_fuzz.py): outputs, files, exit codes."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from visnav.app.cli import main
from visnav.fuzzing.counterexamples import Counterexample, counterexample_to_json


def row(d0, d1=1.6, side=1.0, d_occ=160.0, d_bord=320.0, pan=0.0, alpha=0.0, visible=1.0):
    return (d0, d1, side, d_occ, d_bord, pan, alpha, visible)


def _valid_text():
    cx = Counterexample(property="mu_range", variant="resolved", kind="signals", message="m",
                        measurements=(row(1.0),))
    return json.loads(counterexample_to_json(cx))


def test_cli_fuzz_reports_a_failure_writes_and_replays_its_counterexample(tmp_path, capsys):
    args = ["fuzz", "--variant", "equal_priority", "--property", "determinism", "--examples", "60", "--json",
            "--out", str(tmp_path), "--no-shrink"]
    assert main(args) == 1
    first = capsys.readouterr().out
    out = json.loads(first)
    (prop,) = out["properties"]
    assert out["passed"] is False and prop["failures"] == 1 and prop["name"] == "determinism"
    path = tmp_path / "equal_priority.determinism.json"
    assert prop["counterexamples"] == [str(path)] and path.is_file()
    assert main(args) == 1
    assert capsys.readouterr().out == first  # byte-identical for the same arguments
    assert main(["replay", str(path)]) == 1
    shown = capsys.readouterr().out
    assert "property determinism on variant equal_priority" in shown and "VIOLATED at sample" in shown
    assert "<== violated here" in shown
    assert main(["replay", str(path), "--json"]) == 1
    replayed = json.loads(capsys.readouterr().out)
    assert replayed["violated"] is True and replayed["message"] == prop["message"]


def test_cli_fuzz_exits_0_when_the_properties_hold(tmp_path, capsys):
    assert main(["fuzz", "--property", "mu_range", "--property", "determinism", "--examples", "5", "--json",
                 "--out", str(tmp_path), "--progress"]) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["passed"] is True and [p["examples"] for p in out["properties"]] == [5, 5]
    assert all(p["counterexamples"] == [] for p in out["properties"])
    assert "[1/2] mu_range" in captured.err and "[2/2] determinism" in captured.err
    assert list(tmp_path.iterdir()) == []


def test_cli_fuzz_human_summary(capsys):
    assert main(["fuzz", "--property", "flag_consistency", "--examples", "5"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("visnav fuzz: variant resolved, derandomised")
    assert "flag_consistency" in text and "1 properties, 0 failed" in text and "supervisor steps/s" in text


@pytest.mark.parametrize("args, message", [
    (["fuzz", "--property", "bogus"], "unknown property 'bogus'; known properties: mu_range, mu_continuity"),
    (["fuzz", "--examples", "0"], "0 is not positive"),
    (["fuzz", "--examples", "-3"], "-3 is not positive"),
    (["fuzz", "--variant", "nope"], "unknown variant 'nope'; known variants: resolved, paper, drop_dl_latch"),
])
def test_cli_fuzz_bad_arguments_exit_2(args, message, capsys):
    with pytest.raises(SystemExit) as info:
        main(args)
    assert info.value.code == 2
    assert message in capsys.readouterr().err


def test_cli_replay_bad_files_exit_2(tmp_path, capsys):
    missing = tmp_path / "missing.json"
    assert main(["replay", str(missing)]) == 2
    assert f"replay '{missing}': no such file" in capsys.readouterr().err
    corrupt = tmp_path / "corrupt.json"
    corrupt.write_text("{ nope")
    assert main(["replay", str(corrupt)]) == 2
    assert f"counterexample '{corrupt}': not valid JSON" in capsys.readouterr().err
    old = tmp_path / "old.json"
    old.write_text(json.dumps({**_valid_text(), "version": 0}))
    assert main(["replay", str(old)]) == 2
    assert "format version 0 is not supported" in capsys.readouterr().err


def test_cli_replay_of_a_fixed_example_exits_0(tmp_path, capsys):
    cx = Counterexample(property="mu_range", variant="resolved", kind="signals", message="was broken",
                        sample=0, measurements=(row(1.0), row(0.9)))
    path = tmp_path / "fixed.json"
    path.write_text(counterexample_to_json(cx))
    assert main(["replay", str(path)]) == 0
    assert "the property now HOLDS" in capsys.readouterr().out


def test_cli_module_runs_the_replay_subcommand(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "visnav.app.cli", "replay", str(tmp_path / "none.json")],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and "no such file" in proc.stderr


def test_cli_replay_of_a_file_with_an_invalid_scenario_exits_2(tmp_path, capsys):
    from visnav.scenario import load_scenario

    cx = Counterexample(property="no_collision", variant="resolved", kind="scenario", message="m",
                        scenario=load_scenario("paper"))
    data = json.loads(counterexample_to_json(cx))
    data["scenario"]["envelopes"]["d_minus_m"] = 0.9  # d- > d+
    path = tmp_path / "bad-scenario.json"
    path.write_text(json.dumps(data))
    assert main(["replay", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert f"visnav: error: replay: counterexample '{path}': scenario: envelopes.d_minus_m = 0.9" in captured.err
