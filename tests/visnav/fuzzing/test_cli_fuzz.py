"""visnav fuzz and visnav replay (visnav/app/cli_fuzz.py): outputs, files, exit codes."""

from __future__ import annotations

import json
import os
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
    (["fuzz", "--seed", "-1"], "argument --seed: -1 is negative; give a whole number >= 0"),
    (["fuzz", "--seed", "0.5"], "argument --seed: '0.5' is not an integer; give a whole number >= 0"),
    (["fuzz", "--seed", "9" * 5000], "has more than 300 digits; give a whole number >= 0 of at most 300 digits"),
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


def _scenario_data():
    from visnav.scenario import load_scenario

    cx = Counterexample(property="no_collision", variant="resolved", kind="scenario", message="m",
                        scenario=load_scenario("paper"))
    return json.loads(counterexample_to_json(cx))


def _edit(data, edit):
    edit(data)
    return json.dumps(data)


_VALID = json.dumps(_valid_text())
_ROW = "[1.0, 1.6, 1.0, 160.0, 320.0, 0.0, 0.0, 1.0]"

# (id, the file: bytes, text, or "dir"/"fifo"/"huge", key words of the message)
HOSTILE = [
    ("nested-5000", "[" * 5000 + "]" * 5000, ["malformed counterexample file", "line 1, column 65",
                                              "nested more than 64 levels deep"]),
    ("integer-5000-digits", _VALID.replace('"seed": null', '"seed": ' + "9" * 5000),
     ["malformed counterexample file: seed: an integer of 5000 digits (at most 300 are read)"]),
    ("property-a-list", json.dumps({"format": "visnav-fuzz-counterexample", "version": 1, "property": ["x"]}),
     ["property = ['x']: expected a string, one of: mu_range"]),
    ("scenario-d-minus-above-d-plus", lambda: _edit(_scenario_data(), lambda d: d["scenario"]["envelopes"].update(
        d_minus_m=0.9)), ["scenario: envelopes.d_minus_m = 0.9: expected d_minus_m < d_zero_m < d_plus_m"]),
    ("scenario-nan-duration", lambda: _edit(_scenario_data(), lambda d: d["scenario"].update(duration_s="nan")),
     ["scenario: duration_s = 'nan': expected a number [s]"]),
    ("scenario-NaN-token", lambda: _edit(_scenario_data(), lambda d: d["scenario"].update(duration_s=float("nan"))),
     ["scenario.duration_s: NaN is not a JSON number"]),
    ("scenario-period-5e-324", lambda: _edit(_scenario_data(), lambda d: d["scenario"].update(
        sampling_period_s=5e-324)), ["scenario: duration_s = 120.0: expected a run of at most"]),
    ("scenario-unknown-key", lambda: _edit(_scenario_data(), lambda d: d["scenario"]["gains"].update(lamda=1.0)),
     ["scenario: gains.lamda = 1.0: expected one of the keys"]),
    ("unknown-top-level-key", lambda: _edit(_valid_text(), lambda d: d.update(comment="x")),
     ["unknown key 'comment'; the known keys are channels, format, kind, measurements"]),
    ("directory", "dir", ["is a folder, not a file", "give a counterexample file written by visnav fuzz"]),
    ("fifo", "fifo", ["is not a regular file (a device, FIFO or socket)"]),
    ("empty", "", ["malformed counterexample file: the file is empty"]),
    ("invalid-utf8", b'{"format": "visnav-fuzz-counterexample", "property": "\xff"}',
     ["not UTF-8 text: byte 0xff at line 1, column 55"]),
    ("bom", "\ufeff" + _VALID, ["malformed counterexample file: it starts with a byte-order mark (U+FEFF)"]),
    ("over-50-MB", "huge", ["the file is 50,000,001 bytes, more than the 50,000,000 bytes"]),
    ("NaN-token", _VALID.replace(_ROW, _ROW.replace("1.6", "NaN")), ["measurements[0][1]: NaN is not a JSON number"]),
    ("Infinity-token", _VALID.replace(_ROW, _ROW.replace("160.0", "-Infinity")),
     ["measurements[0][3]: -Infinity is not a JSON number"]),
    ("overflowing-number", _VALID.replace(_ROW, _ROW.replace("320.0", "3e999")),
     ["measurements[0][4]: a number too large for a float"]),
    ("wrong-format", _VALID.replace('"visnav-fuzz-counterexample"', '"visnav-fuzz-counterexample-2"'),
     ["not a counterexample file (format = 'visnav-fuzz-counterexample-2', expected 'visnav-fuzz-counterexample')"]),
    ("version-2", _VALID.replace('"version": 1', '"version": 2'),
     ["format version 2 is not supported (this visnav reads version 1)"]),
    ("version-a-string", _VALID.replace('"version": 1', '"version": "1"'),
     ["version = '1': expected the integer 1, found a string"]),
    ("version-true", _VALID.replace('"version": 1', '"version": true'), ["version = True: expected the integer 1"]),
    ("duplicate-key", _VALID[:-1] + ', "variant": "paper"}',
     ["malformed counterexample file: the top-level object: duplicate key 'variant'"]),
    ("top-level-array", "[" + _VALID + "]", ["not a counterexample file: the top level is an array"]),
    ("unpaired-surrogate", _VALID.replace('"message": "m"', '"message": "\\ud83d"'),
     ["violation.message: string '\\ud83d' has an unpaired surrogate"]),
]


@pytest.mark.parametrize("content, words", [h[1:] for h in HOSTILE], ids=[h[0] for h in HOSTILE])
def test_cli_replay_of_a_hostile_file_exits_2_with_a_precise_message(content, words, tmp_path, capsys):
    path = tmp_path / "cx.json"
    if content == "dir":
        path.mkdir()
    elif content == "fifo":
        os.mkfifo(path)
    elif content == "huge":
        with open(path, "wb") as handle:
            handle.truncate(50_000_001)  # sparse: no disk used, nothing read
    else:
        content = content() if callable(content) else content
        path.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8", "surrogatepass"))
    assert main(["replay", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith("visnav: error: replay") and captured.err.count("\n") == 1
    assert str(path) in captured.err
    for word in words:
        assert word in captured.err
    assert "Traceback" not in captured.err and "internal error" not in captured.err
