import json
import subprocess
import sys
from pathlib import Path

import pytest

from visnav.cli import main

KEYS = {
    "success", "collided", "min_clearance_m", "final_feature_error_px", "occlusion_duration_s",
    "max_reconstruction_error_px", "max_depth_error_mm", "modes_visited", "transitions", "sim_time_s",
    "steps", "wall_time_s",
}


def test_simulate_json_and_files(tmp_path, capsys):
    code = main(["simulate", "--scenario", "paper", "--out", str(tmp_path / "run"), "--json"])
    out = capsys.readouterr().out
    summary = json.loads(out)
    assert code == 0 and summary["success"] is True
    assert KEYS <= set(summary)
    names = {p.name for p in (tmp_path / "run").iterdir()}
    assert {"trajectory.csv", "summary.json", "fig4_trajectory.png", "fig5_risk.png", "fig6_reconstruction.png",
            "fig7_controls.png"} <= names
    header = (tmp_path / "run" / "trajectory.csv").read_text().splitlines()[0].split(",")
    assert header[:3] == ["t_s", "jump", "mode"] and "mu_coll" in header


def test_bad_scenario_exits_2_without_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    text = Path(__file__).parents[2].joinpath("visnav", "scenarios", "paper.toml").read_text()
    bad.write_text(text.replace("d_zero_m = 0.5", "d_zero_m = 0.7"))
    proc = subprocess.run([sys.executable, "-m", "visnav.cli", "simulate", "--scenario", str(bad)],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "envelopes.d_zero_m = 0.7" in proc.stderr and "fix:" in proc.stderr


@pytest.mark.parametrize("args, message", [
    (["simulate", "--scenario", "nowhere"], "nowhere"),
    (["simulate", "--bogus"], "unrecognized arguments"),
])
def test_bad_arguments_exit_2(args, message, capsys):
    with pytest.raises(SystemExit) as info:
        code = main(args)
        raise SystemExit(code)
    assert info.value.code == 2
    assert message in capsys.readouterr().err


def test_uncreatable_output_folder_exits_2(tmp_path, capsys):
    parent = tmp_path / "plain-file"
    parent.write_text("")
    assert main(["simulate", "--out", str(parent / "sub"), "--no-figures"]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "cannot create the folder" in err and "Traceback" not in err


def test_output_path_that_is_a_file_exits_2(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("")
    assert main(["simulate", "--out", str(f), "--no-figures"]) == 2
    assert "is not a folder" in capsys.readouterr().err


def test_mode_graph_dot(capsys):
    assert main(["mode-graph"]) == 0
    dot = capsys.readouterr().out
    assert dot.startswith("digraph") and '"FAR|CLEAR" -> "APPROACH|CLEAR"' in dot


def test_check_model_on_the_paper_supervisor_is_clean_and_deterministic(capsys):
    assert main(["check-model", "--samples", "60", "--starts", "2", "--json"]) == 0
    first = capsys.readouterr().out
    report = json.loads(first)
    assert report["clean"] is True and report["scenario"] == "paper"
    assert {f["kind"] for f in report["findings"]} <= {"priority_overlap", "zeno_candidate"}
    assert report["searched"]["samples"] == 60 and len(report["searched"]["modes"]) == 18
    assert main(["check-model", "--samples", "60", "--starts", "2", "--json"]) == 0
    assert capsys.readouterr().out == first


def test_check_model_human_summary_and_bad_options(capsys):
    assert main(["check-model", "--samples", "30", "--starts", "1"]) == 0
    out = capsys.readouterr().out
    assert "CLEAN" in out and "nondeterminism" in out and "box: d_coll_0_m" in out
    with pytest.raises(SystemExit) as info:
        main(["check-model", "--samples", "0"])
    assert info.value.code == 2
    assert "0 is not positive" in capsys.readouterr().err


def test_mode_graph_as_json(capsys):
    assert main(["mode-graph", "--format", "json"]) == 0
    graph = json.loads(capsys.readouterr().out)
    assert len(graph["modes"]) == 18 and len(graph["transitions"]) == 47
