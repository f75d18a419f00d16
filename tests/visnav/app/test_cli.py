import json
import subprocess
import sys
from pathlib import Path

import pytest

from visnav.app.cli import main

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
    text = Path(__file__).parents[3].joinpath("visnav", "scenarios", "paper.toml").read_text()
    bad.write_text(text.replace("d_zero_m = 0.5", "d_zero_m = 0.7"))
    proc = subprocess.run([sys.executable, "-m", "visnav.app.cli", "simulate", "--scenario", str(bad)],
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


STATE_CHECKS = ("nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers")


def _check_json(capsys, *args: str) -> tuple[int, dict]:
    code = main(["check-model", *args, "--json"])
    return code, json.loads(capsys.readouterr().out)


def test_check_model_proves_the_paper_supervisor(capsys):
    """The supervisor is symbolic: every check decided by the SMT solver, 43 pairs, 578 cycles, no finding."""
    code, report = _check_json(capsys, "--samples", "60", "--starts", "2")
    assert code == 0 and report["clean"] is True and report["scenario"] == "paper"
    assert report["complete"] is True and report["incomplete"] == []
    assert {s["status"] for s in report["statuses"].values()} == {"decided"}
    assert report["method"] == "auto" and report["timeout_s"] == 5.0 and report["solver"].startswith("z3")
    assert {name: c["status"] for name, c in report["claims"].items()} == dict.fromkeys((*STATE_CHECKS, "zeno"),
                                                                                         "proven")
    assert all(c["assumptions"] for c in report["claims"].values())
    pairs = report["pairs"]
    assert len(pairs) == 43
    assert sum(p["verdict"] == "overlap" for p in pairs) == 29 and sum(p["verdict"] == "exclusive" for p in pairs) == 14
    assert not any(p["same_priority"] and p["verdict"] == "overlap" for p in pairs)
    zeno = report["zeno"]
    assert zeno["counts"]["non_zeno"] == zeno["cycles"] > 0 and zeno["counts"]["undecided"] == 0
    assert zeno["min_dwell_s"] > 0 and "verdicts" not in zeno  # the cycles grouped, never one row each
    # the rate bounds are the fuzz measurement space's
    from visnav.fuzzing.space import scenario_space
    from visnav.scenario import load_scenario

    space = scenario_space(load_scenario("paper"))
    assert report["rates"] == pytest.approx(space.rates_per_s())
    assert report["rates"]["d_coll_0_m"] == pytest.approx(space.max_step_d_m / space.period_s)
    assert {f["kind"] for f in report["findings"]} <= {"priority_overlap"}
    assert sum(f["kind"] == "zeno_candidate" for f in report["findings"]) <= 1
    assert report["searched"]["samples"] == 60 and len(report["searched"]["modes"]) == 18


def test_check_model_json_is_identical_across_processes():
    """Two processes (different string hashing) print the same bytes: the report's determinism."""
    import os

    script = Path(sys.executable).with_name("visnav")
    runs = [subprocess.run([str(script), "check-model", "--samples", "20", "--starts", "1", "--json"],
                           capture_output=True, text=True, env={**os.environ, "PYTHONHASHSEED": seed}, timeout=300)
            for seed in ("1", "2")]
    assert [r.returncode for r in runs] == [0, 0], runs[0].stderr
    assert runs[0].stdout == runs[1].stdout


def test_check_model_sampled_method_gives_sampled_claims(capsys):
    """Sampling leaves the 578 Zeno cycles undecided: INCOMPLETE (exit 5), never CLEAN."""
    code, report = _check_json(capsys, "--method", "sampled", "--samples", "30", "--starts", "1")
    assert code == 5 and report["method"] == "sampled" and report["pairs"] == [] and report["zeno"] is None
    assert report["clean"] is False and report["complete"] is False
    assert [line.split(":")[0] for line in report["incomplete"]] == ["zeno undecided"]
    assert {name: report["claims"][name]["status"] for name in STATE_CHECKS} == dict.fromkeys(STATE_CHECKS,
                                                                                               "sampled")
    assert report["claims"]["zeno"]["status"] == "undecided"
    assert sum(f["kind"] == "zeno_candidate" for f in report["findings"]) == 1  # the cycles grouped in one row
    assert main(["check-model", "--method", "sampled", "--samples", "30", "--starts", "1"]) == 5
    out = capsys.readouterr().out
    assert "INCOMPLETE, 1 check(s) did not decide: zeno undecided: cycles not decided (method sampled)" in (
        out.splitlines()[0]) and "CLEAN" not in out.splitlines()[0]
    claimed = {ln.split()[0]: ln.split()[1] for ln in out.splitlines() if ln.split()[:1] in ([n] for n in
                                                                                            (*STATE_CHECKS, "zeno"))}
    assert claimed == {**dict.fromkeys(STATE_CHECKS, "SAMPLED"), "zeno": "UNDECIDED"}
    assert "PROVEN over" not in out and "  unreachable              PROVEN    exact, on the mode graph" in out


def test_check_model_human_summary_and_bad_options(capsys):
    assert main(["check-model", "--samples", "30", "--starts", "1"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert "CLEAN" in lines[0] and "box: d_coll_0_m" in out
    for name in (*STATE_CHECKS, "zeno"):  # one line per check: its claim in capitals and the method
        (line,) = [ln for ln in lines if ln.split()[:1] == [name]]
        assert line.split()[1] == "PROVEN" and "z3" in line
    assert ("  pairs: 43 pairs of transitions sharing a source mode: 29 can be enabled together (re-checked "
            "witnesses), 14 exclusive (proven); equal-priority overlaps: 0") in lines
    (zeno,) = [ln for ln in lines if ln.startswith("  Zeno: ")]
    assert "non-Zeno (proven), smallest dwell bound 0.05 s in LEAVE|CLEAR between" in zeno
    assert zeno.endswith("; 0 instantaneous; 0 undecided")
    assert "[info] priority_overlap: 29" in out and "zeno_candidate" not in out
    with pytest.raises(SystemExit) as info:
        main(["check-model", "--samples", "0"])
    assert info.value.code == 2
    assert "0 is not positive" in capsys.readouterr().err


@pytest.mark.parametrize("value", ["-1", "0", "nan", "soon"])
def test_check_model_bad_timeout_exits_2(value, capsys):
    with pytest.raises(SystemExit) as info:
        main(["check-model", "--timeout", value])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--timeout" in err and "Traceback" not in err


def test_check_model_bad_method_exits_2(capsys):
    with pytest.raises(SystemExit) as info:
        main(["check-model", "--method", "guess"])
    assert info.value.code == 2 and "--method" in capsys.readouterr().err


def test_check_model_proves_a_users_symbolic_problem(symbolic_problem, capsys):
    """hybrid_problem(check_box=...) of a symbolic model: every check PROVEN by `check-model --problem`."""
    code, report = _check_json(capsys, "--problem", symbolic_problem)
    assert code == 0 and report["clean"] and report["problem"] == "symbolic-thermostat"
    assert {name: c["status"] for name, c in report["claims"].items()} == dict.fromkeys((*STATE_CHECKS, "zeno"),
                                                                                         "proven")
    assert report["zeno"]["counts"]["non_zeno"] == report["zeno"]["cycles"] == 1
    assert report["method"] == "auto" and report["timeout_s"] == 5.0
    assert main(["check-model", "--problem", symbolic_problem, "--timeout", "2"]) == 0
    out = capsys.readouterr().out
    assert "(problem symbolic-thermostat): CLEAN" in out and "timeout 2 s per solver call" in out
    for name in (*STATE_CHECKS, "zeno"):
        assert any(ln.split()[:2] == [name, "PROVEN"] for ln in out.splitlines()), name
    assert "  Zeno: 1 cycle: 1 non-Zeno (proven), smallest dwell bound" in out
    # --method sampled reaches the problem's checks too
    code, report = _check_json(capsys, "--problem", symbolic_problem, "--method", "sampled")
    assert {report["claims"][n]["status"] for n in STATE_CHECKS} == {"sampled"}
    assert code == 5 and not report["clean"] and report["incomplete"][0].startswith("zeno undecided")


def test_mode_graph_as_json(capsys):
    assert main(["mode-graph", "--format", "json"]) == 0
    graph = json.loads(capsys.readouterr().out)
    assert len(graph["modes"]) == 18 and len(graph["transitions"]) == 47


def test_docs_supervisor_dot_is_the_current_mode_graph(capsys):
    """docs/supervisor.dot is generated by `visnav mode-graph`; regenerate it when the automaton changes."""
    assert main(["mode-graph"]) == 0
    dot = capsys.readouterr().out
    assert (Path(__file__).parents[3] / "docs" / "supervisor.dot").read_text() == dot


def test_check_model_parametric_proves_the_exclusive_pairs_for_every_admissible_envelope(capsys):
    assert main(["check-model", "--parametric", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    rows = out["parametric"]["pairs"]
    verdicts = {(r["first"], r["second"]): r["verdict"] for r in rows}
    assert len(rows) == 43 and sum(v == "exclusive" for v in verdicts.values()) == 14
    # the release band is exclusive whatever the envelopes: D_end >= D+ > D-
    assert verdicts[("FAR@RELEASE->CLEAR", "FAR@RELEASE->OCCLUDED")] == "exclusive"
    assert "0 < d- < d0 < d+" in out["parametric"]["assumptions"]
    for r in rows:
        if r["verdict"] == "overlap":  # every overlap witness carries the envelope it holds for
            assert any(k.startswith("param ") for k in r["witness"]["values"])


def test_check_model_parametric_with_a_problem_is_refused(capsys):
    assert main(["check-model", "--problem", "examples/thermostat.py:problem", "--parametric"]) == 2
    err = capsys.readouterr().err
    assert "--parametric" in err and "exclusive_for_all" in err and "Traceback" not in err


def test_each_subcommand_lives_in_its_own_module():
    """Issue 26: ``visnav X`` is run by ``visnav/app/cli_X.py`` (``check-model`` by ``cli_check.py``); ``cli.py``
    only builds the parser and guards the entry point."""
    from visnav.app.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    owners = {name: p.get_default("func").__module__ for name, p in sub.choices.items()}
    expected = {name: "visnav.app.cli_" + {"check-model": "check"}.get(name, name).replace("-", "_")
                for name in owners}
    assert owners == expected
    assert {"simulate", "mode-graph", "analyse", "report", "check-model", "sweep", "stiffness", "fuzz", "replay",
            "verify"} <= set(owners)
