"""``visnav verify`` on a user's own problem: exit codes and the messages of every bad input."""

from __future__ import annotations

import json
import textwrap

import pytest

from visnav.app.cli import main

MODULE = '''
import numpy as np
from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verification import Parameter, VerificationProblem

def simulate(p):
    t = np.linspace(0.0, 2.0, 41)
    if p["x0"] > 1e9:
        raise RuntimeError("user bug")
    return SignalTrace(times=t, signals={"x": p["x0"] * np.exp(-t)}, labels={"mode": ("run",) * 41})

problem = VerificationProblem(name="decay", simulate=simulate,
    parameters=(Parameter(name="x0", low=0.5, high=2.0),), horizon=2.0, signals=("x",), labels={"mode": ("run",)},
    requirements=(Requirement(name="positive", formula=FORMULA),))
'''


def _module(tmp_path, formula="always[0, 2] (x > 0)", extra=""):
    path = tmp_path / "user_sys.py"
    path.write_text(textwrap.dedent(MODULE.replace("FORMULA", repr(formula))) + extra)
    return path


def test_a_users_system_outside_the_repository_is_verified_end_to_end(tmp_path, cli):
    path = _module(tmp_path)
    code, out, err = cli("verify", f"{path}:problem", "--budget", "8", "--out", str(tmp_path / "o"), "--json")
    assert code == 0, err
    data = json.loads(out)
    assert data["verdict"] == "not_falsified" and data["simulations"] == 8
    r = data["requirements"][0]
    # min over t of x0 exp(-t) is x0 exp(-2): between the box's lowest value 0.5 and the nominal 1.25
    assert 0.5 * 2.718281828459045 ** -2 <= r["robustness"] < 1.25 * 2.718281828459045 ** -2
    assert r["nominal_robustness"] == pytest.approx(1.25 * 2.718281828459045 ** -2, rel=1e-12)


def test_a_falsified_requirement_exits_1_with_its_counterexample(tmp_path, cli):
    path = _module(tmp_path, "always[0, 2] (x > 0.1)")
    code, out, err = cli("verify", f"{path}:problem", "--budget", "20", "--out", str(tmp_path / "o"))
    assert code == 1, err
    assert "FALSIFIED" in out and "visnav replay" in out


@pytest.mark.parametrize("formula, needles", [
    ("always[0, 2] (x > )", ["column", "^"]),
    ("always[0, 2] (y > 0)", ["'y'", "x"]),
    ("always[2, 1] (x > 0)", ["^"]),
    ("always[-1, 1] (x > 0)", ["^"]),
    ("always[0, 3] (x > 0)", ["horizon"]),
    ('always[0, 2] (mode == "stop")', ["stop"]),
])
def test_bad_formulas_exit_2_with_a_position_and_no_traceback(tmp_path, cli, formula, needles):
    path = _module(tmp_path, formula)
    code, out, err = cli("verify", f"{path}:problem", "--budget", "3", "--out", str(tmp_path / "o"))
    assert code == 2
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err


def test_a_module_that_fails_to_import_shows_the_users_own_traceback(tmp_path, cli):
    path = _module(tmp_path, extra="\nraise ValueError('my own mistake')\n")
    code, out, err = cli("verify", f"{path}:problem", "--out", str(tmp_path / "o"))
    assert code == 2
    assert "my own mistake" in err and "user_sys.py" in err and "a module that imports" in err


def test_an_object_of_the_wrong_type_and_a_missing_object_exit_2(tmp_path, cli):
    path = _module(tmp_path, extra="\nsomething = 42\n")
    code, _, err = cli("verify", f"{path}:something", "--out", str(tmp_path / "o"))
    assert code == 2 and "found int" in err
    code, _, err = cli("verify", f"{path}:nothing", "--out", str(tmp_path / "o"))
    assert code == 2 and "problem" in err


def test_a_non_positive_budget_is_refused_by_the_option_parser(tmp_path, capsys):
    path = _module(tmp_path)
    with pytest.raises(SystemExit) as info:
        main(["verify", f"{path}:problem", "--budget", "0"])
    assert info.value.code == 2
    assert "budget" in capsys.readouterr().err


def test_a_crash_in_the_users_simulator_exits_6_model_error_with_their_traceback(tmp_path, cli):
    path = _module(tmp_path)
    text = path.read_text().replace('if p["x0"] > 1e9:', 'if p["x0"] > 0:')
    path.write_text(text)
    code, out, err = cli("verify", f"{path}:problem", "--budget", "2", "--out", str(tmp_path / "o"))
    assert code == 6  # a defect of the model: its own exit code, neither bad input (2) nor divergence (3)
    assert "user bug" in err and "user_sys.py" in err and "MODEL ERROR" in out


def test_check_model_and_mode_graph_take_a_users_problem(cli):
    from pathlib import Path

    example = Path(__file__).resolve().parents[3] / "examples" / "thermostat.py"
    code, out, _ = cli("check-model", "--problem", f"{example}:zero_band", "--json")
    data = json.loads(out)
    # a zero band: each switch re-enables the other at once (the Zeno cycle the verification finds)
    assert code == 1 and not data["clean"]
    assert sorted({f["kind"] for f in data["findings"] if f["severity"] == "error"}) == ["reset_retriggers"]
    code, out, _ = cli("check-model", "--problem", f"{example}:problem", "--json")
    data = json.loads(out)  # written symbolically: every check decided by z3, clean and complete
    assert code == 0 and data["clean"] and data["complete"] and data["incomplete"] == []
    assert not [f for f in data["findings"] if f["severity"] != "info"]
    code, out, _ = cli("mode-graph", "--problem", f"{example}:problem")
    assert code == 0 and '"off" -> "on"' in out


def test_mode_graph_of_a_problem_without_automaton_is_a_clear_error(tmp_path, cli):
    path = _module(tmp_path)
    code, _, err = cli("mode-graph", "--problem", f"{path}:problem")
    assert code == 2 and "declares no automaton" in err


@pytest.mark.parametrize("returned, needle, exit_code", [
    ("{'x': 1.0}", "returned a dict", 2),  # a definition error: the simulator's contract
    # a NaN the model computed: SignalTrace refuses it inside the user's code, a defect of the model (6)
    ("SignalTrace(times=t, signals={'x': t * float('nan')})", "nan", 6)])
def test_a_simulator_returning_a_wrong_object_or_nan_is_refused_with_a_message(tmp_path, cli, returned, needle,
                                                                               exit_code):
    path = _module(tmp_path)
    text = path.read_text().replace('return SignalTrace(times=t, signals={"x": p["x0"] * np.exp(-t)}, '
                                    'labels={"mode": ("run",) * 41})', f"return {returned}")
    assert text != path.read_text()
    path.write_text(text)
    code, _, err = cli("verify", f"{path}:problem", "--budget", "2", "--out", str(tmp_path / "o"))
    assert code == exit_code and needle in err.lower()


def test_a_journal_of_the_former_search_is_refused_naming_both_versions(tmp_path, cli):
    # version 3 (issue 29): a version-2 journal holds the points of the former hypothesis search, which the new
    # guided search would not replay; it is refused before any simulation, never silently mixed in
    path = _module(tmp_path)
    out = tmp_path / "o"
    code, _, err = cli("verify", f"{path}:problem", "--budget", "6", "--out", str(out))
    assert code == 0, err
    journal = out / "evaluations.jsonl"
    lines = journal.read_text().splitlines()
    header = json.loads(lines[0])
    assert header["version"] == 3
    journal.write_text("\n".join([json.dumps({**header, "version": 2}, sort_keys=True), *lines[1:]]) + "\n")
    code, _, err = cli("verify", f"{path}:problem", "--budget", "6", "--out", str(out))
    assert code == 2
    assert "format version 2, this visnav writes 3" in err


@pytest.mark.parametrize("method", ["guided", "whitebox"])
def test_an_interrupted_search_resumes_from_its_journal_byte_identically(tmp_path, cli, method):
    path = _module(tmp_path, "always[0, 2] (x > 0.3)")
    args = ["verify", f"{path}:problem", "--budget", "12", "--method", method, "--json"]
    code, whole, err = cli(*args, "--out", str(tmp_path / "a"))
    assert code in (0, 1), err
    journal = (tmp_path / "a" / "evaluations.jsonl").read_text().splitlines()
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "evaluations.jsonl").write_text("\n".join(journal[: 1 + (len(journal) - 1) // 2]) + "\n")
    code2, resumed, err = cli(*args, "--out", str(tmp_path / "b"))
    assert code2 == code, err
    strip = lambda text: {k: v for k, v in json.loads(text).items() if k != "requirements"}  # noqa: E731
    a, b = json.loads(whole), json.loads(resumed)
    assert strip(whole) == strip(resumed)
    assert [{k: v for k, v in r.items() if k != "counterexample"} for r in a["requirements"]] == \
           [{k: v for k, v in r.items() if k != "counterexample"} for r in b["requirements"]]


def test_whitebox_says_which_gradient_it_used_and_resumes_sensitivity_runs_from_the_journal(tmp_path, cli):
    at1 = "examples/arch/autotrans.py:at1"
    code, text, err = cli("verify", at1, "--budget", "12", "--method", "whitebox", "--out",
                           str(tmp_path / "a"))
    assert code == 1, err
    assert "gradients: sensitivities (the model's, one simulation per gradient)" in text
    lines = [json.loads(x)["result"] for x in (tmp_path / "a" / "evaluations.jsonl").read_text().splitlines()[1:]]
    assert any(x.get("gradient_method") == "sensitivities" and x["phase"] == "gradient" for x in lines)
    code, text, err = cli("verify", at1, "--budget", "12", "--method", "whitebox", "--json", "--out",
                           str(tmp_path / "a"))  # read back from the journal, the gradients with it
    assert code == 1 and json.loads(text)["gradients"].startswith("sensitivities"), err
    assert json.loads(text)["simulations"] == len(lines)
    # interrupted after the gradient runs: the resumed search reads them back and ends as the whole one did
    journal = (tmp_path / "a" / "evaluations.jsonl").read_text().splitlines()
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "evaluations.jsonl").write_text("\n".join(journal[:4]) + "\n")
    code, resumed, err = cli("verify", at1, "--budget", "12", "--method", "whitebox", "--json", "--out",
                              str(tmp_path / "c"))
    assert code == 1, err
    assert [json.loads(x)["result"] for x in (tmp_path / "c" / "evaluations.jsonl").read_text().splitlines()[1:]] \
        == lines
    path = _module(tmp_path)
    code, text, err = cli("verify", f"{path}:problem", "--budget", "8", "--method", "whitebox", "--out",
                           str(tmp_path / "b"))
    assert "gradients: central finite differences (the problem gives no sensitivities" in text, err
