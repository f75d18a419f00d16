"""``visnav verify`` against a hostile or careless user's module (issue 25): no hang, the user's code never
sets visnav's exit code, a journal is bound to the model it was computed from, stdout keeps the JSON alone."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import time

import pytest


MODULE = '''
import numpy as np
from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verification import Parameter, VerificationProblem

def simulate(p):
    t = np.linspace(0.0, 2.0, 41)
    BODY
    return SignalTrace(times=t, signals={"x": p["x0"] * np.exp(-t)})

def factory():
    FACTORY
    return problem

problem = VerificationProblem(name="decay", simulate=simulate,
    parameters=(Parameter(name="x0", low=0.5, high=2.0),), horizon=2.0, signals=("x",),
    requirements=(Requirement(name="positive", formula="always[0, 2] (x > 0)"),))
'''


def _module(tmp_path, body="pass", factory="pass", name="user_mod.py"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(MODULE).replace("BODY", body).replace("FACTORY", factory))
    return path


@pytest.mark.parametrize("body", ["import sys; sys.exit(0)", "import sys; sys.exit('msg')", "import sys; sys.exit(3)",
                                  "raise GeneratorExit()"])
def test_sys_exit_in_the_simulator_is_a_model_error_never_our_exit_code(tmp_path, cli, body):
    path = _module(tmp_path, body=body)
    code, out, err = cli("verify", f"{path}:problem", "--budget", "2", "--out", str(tmp_path / "o"))
    assert code == 6, (out, err)
    assert "MODEL ERROR" in out and ("SystemExit" in err or "GeneratorExit" in err)


@pytest.mark.parametrize("factory", ["import sys; sys.exit(0)", "import sys; sys.exit(3)", "raise GeneratorExit()"])
def test_sys_exit_in_a_problem_factory_is_bad_input(tmp_path, cli, factory):
    path = _module(tmp_path, factory=factory)
    code, _, err = cli("verify", f"{path}:factory", "--budget", "2", "--out", str(tmp_path / "o"))
    assert code == 2 and "fix the error in your code" in err


def test_a_simulator_that_hangs_is_stopped_and_the_verdict_is_incomplete(tmp_path, cli):
    path = _module(tmp_path, body="import time; time.sleep(60)")
    start = time.monotonic()
    code, out, err = cli("verify", f"{path}:problem", "--budget", "2", "--sim-timeout", "0.3",
                          "--out", str(tmp_path / "o"), "--json")
    assert time.monotonic() - start < 20
    assert code == 5, err
    data = json.loads(out)
    assert data["verdict"] == "incomplete" and data["requirements"][0]["verdict"] == "incomplete"
    assert data["ended_early"][0]["status"] == "timeout"


def test_a_looping_simulator_is_stopped_in_the_process_pool_too(tmp_path):
    path = _module(tmp_path, body="while True: pass")
    start = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "visnav.app.cli", "verify", f"{path}:problem", "--budget", "2",
                           "--method", "monte-carlo", "--workers", "2", "--sim-timeout", "0.5",
                           "--out", str(tmp_path / "o"), "--json"], capture_output=True, text=True, timeout=120)
    assert time.monotonic() - start < 90
    assert done.returncode == 5, done.stderr
    assert {d["status"] for d in json.loads(done.stdout)["ended_early"]} == {"timeout"}


def test_a_journal_of_an_edited_model_is_refused_naming_the_file(tmp_path, cli):
    path = _module(tmp_path)
    out = str(tmp_path / "o")
    code, _, err = cli("verify", f"{path}:problem", "--budget", "4", "--out", out)
    assert code == 0, err
    path.write_text(path.read_text().replace("p[\"x0\"] * np.exp(-t)", "p[\"x0\"] * np.exp(-t) - 1.0"))
    code, _, err = cli("verify", f"{path}:problem", "--budget", "4", "--out", out)
    assert code == 2 and "another campaign" in err and "user_mod.py changed" in err
    # the same command on a fresh folder (a new process: this one keeps the module it imported) sees the edit
    done = subprocess.run([sys.executable, "-m", "visnav.app.cli", "verify", f"{path}:problem", "--budget", "4",
                           "--out", str(tmp_path / "fresh")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr


def test_json_stdout_holds_the_json_alone_when_the_model_prints(tmp_path, cli):
    path = _module(tmp_path, body="print('chatty model')")
    code, out, err = cli("verify", f"{path}:problem", "--budget", "2", "--out", str(tmp_path / "o"),
                          "--json")
    assert code == 0 and json.loads(out)["verdict"] == "not_falsified"
    assert "chatty model" in err


@pytest.mark.parametrize("forge", [
    lambda r: r.update(unit=[0.1, 0.2]),  # a point of the wrong length
    lambda r: r.update(unit=[7.0]),  # outside the unit box
    lambda r: r.update(status="bogus"),  # a status outside the vocabulary
    lambda r: r.update(robustness=["nan"]),  # NaN robustness
    lambda r: r.update(satisfied=[]),  # no truth value: IndexError before
    lambda r: r.update(satisfied=["yes"]),  # not a boolean
])
def test_forged_journal_lines_with_a_valid_checksum_are_dropped_with_a_warning(tmp_path, cli, forge):
    from visnav.app.campaign_store import canonical_json, line_checksum

    path = _module(tmp_path)
    out = tmp_path / "o"
    code, first, err = cli("verify", f"{path}:problem", "--budget", "4", "--out", str(out), "--json")
    assert code == 0, err
    journal = out / "evaluations.jsonl"
    lines = journal.read_text().splitlines()
    line = json.loads(lines[2])
    forge(line["result"])
    line["sha256"] = line_checksum(line["result"])
    lines[2] = canonical_json(line)
    journal.write_text("\n".join(lines) + "\n")
    code, again, err = cli("verify", f"{path}:problem", "--budget", "4", "--out", str(out), "--json")
    assert code == 0, err
    assert "dropped 1 bad line" in err
    assert json.loads(again)["requirements"] == json.loads(first)["requirements"]  # re-simulated: the same answer


def test_a_worker_that_dies_exits_3_with_the_resume_hint(tmp_path):
    path = _module(tmp_path, body="import os; os._exit(7)")
    done = subprocess.run([sys.executable, "-m", "visnav.app.cli", "verify", f"{path}:problem", "--budget", "3",
                           "--method", "monte-carlo", "--workers", "2", "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 3, done.stderr
    assert "worker process died" in done.stderr and "Traceback" not in done.stderr


def test_a_forking_simulator_does_not_multiply_the_search(tmp_path, capsys):
    path = _module(tmp_path, body="import os; os.fork()")
    out = tmp_path / "o"
    done = subprocess.run([sys.executable, "-m", "visnav.app.cli", "verify", f"{path}:problem", "--budget", "6",
                           "--out", str(out), "--json"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    time.sleep(0.5)
    lines = (out / "evaluations.jsonl").read_text().splitlines()
    assert len(lines) == 1 + 6  # the header and one line per simulation of the budget


def test_a_formula_that_divides_by_zero_is_bad_input_naming_the_formula_not_the_simulator(tmp_path, cli):
    path = _module(tmp_path)
    path.write_text(path.read_text().replace('formula="always[0, 2] (x > 0)"', 'formula="always[0, 2] (x / (x - x) > 0)"'))
    code, _, err = cli("verify", f"{path}:problem", "--budget", "2", "--out", str(tmp_path / "o"))
    assert code == 2 and "x / (x - x)" in err and "your simulator raised" not in err and "Traceback" not in err


BALL = '''
from analysis.verify import Parameter, Requirement, hybrid_problem
from hybrid.examples import bouncing_ball

problem = hybrid_problem(
    name="ball", system=bouncing_ball(h0=4.905, restitution=0.5).system,
    initial={"h": Parameter(name="h0", low=4.8, high=4.905, nominal=4.905), "v": 0.0}, horizon=10.0,
    requirements=(Requirement(name="r", formula="always[0, 10] (h >= -0.01)"),), stability=True)
'''


def test_report_of_a_zeno_model_is_incomplete_never_a_pass(tmp_path, cli):
    path = tmp_path / "ball.py"
    path.write_text(BALL)
    code, out, err = cli("report", "--problem", f"{path}:problem", "--quick", "--budget", "3",
                          "--out", str(tmp_path / "r"), "--json")
    assert code == 5, err
    summary = json.loads(out)
    assert summary["verdict"] == "incomplete"
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    assert report["verdict"] == "incomplete" and report["verification"]["requirements"][0]["verdict"] == "incomplete"
    assert "INCOMPLETE" in (tmp_path / "r" / "report.md").read_text()


def test_analyse_of_a_stability_it_cannot_decide_exits_5(tmp_path, cli):
    path = tmp_path / "ball.py"
    path.write_text(BALL)
    code, out, _ = cli("analyse", "--problem", f"{path}:problem")
    assert code == 5 and "NOT DECIDED" in out
