"""``visnav replay FILE [--problem SPEC]`` (visnav/app/cli_replay.py): a counterexample file never chooses code to run.

Issue 25's reproductions: a file naming ``/x/evil.py:problem``, ``os:abort`` or
``tempfile:mkdtemp`` ran it; NaN, infinite or out-of-box unit coordinates were
clamped and another point replayed; an ``options`` key the problem does not
take was a TypeError (exit 4); a hostile label pattern in a scenario the file
points at hung.  The counterexamples are written here from the problem's own
``point(unit)`` (the values a ``visnav verify`` file holds), then edited.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pytest

from analysis.counterexamples import CounterexampleFormat
from analysis.verify.loading import load_problem

from visnav.app.cli_replay import same_problem
from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_MODEL_ERROR, EXIT_OK, EXIT_TASK_FAILED
from visnav.app.cli_verify import COUNTEREXAMPLE_FORMAT, replay_command

ROOT = Path(__file__).resolve().parents[3]

MODULE = '''
import numpy as np
from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verification import Parameter, VerificationProblem

def simulate(p):
    t = np.linspace(0.0, 2.0, 41)
    if p["x0"] > 1.9:
        raise RuntimeError("user bug at the top of the box")
    return SignalTrace(times=t, signals={"x": p["x0"] * np.exp(-t)}, labels={"mode": ("run",) * 41})

problem = VerificationProblem(name="decay", simulate=simulate,
    parameters=(Parameter(name="x0", low=0.5, high=2.0),), horizon=2.0, signals=("x",), labels={"mode": ("run",)},
    requirements=(Requirement(name="big", formula="always[0, 2] (x > 0.2)"),
                  Requirement(name="ratio", formula="always[0, 2] (1 / (x - x) > 0)")))
'''


def _module(tmp_path: Path) -> str:
    path = tmp_path / "decay_problem.py"
    path.write_text(textwrap.dedent(MODULE))
    return f"{path}:problem"


def _counterexample(tmp_path: Path, spec: str, requirement: str, unit: tuple[float, ...], *, named: str | None = None,
                    options: dict | None = None, edit=None, problem=None, name: str = "cx.json") -> Path:
    """A counterexample file as ``visnav verify`` writes it (``named``: the problem the file names)."""
    if problem is None:
        problem = load_problem(spec)
    fields = {"problem": spec if named is None else named, "options": options or {}, "requirement": requirement,
              "formula": "", "unit": list(unit), "point": problem.point(unit), "robustness": -1.0, "time": 0.0,
              "atom": "", "how": "search", "seed": 0, "method": "guided", "columns": ["time", "jumps"],
              "replay": "visnav replay <this file>"}
    if edit is not None:
        edit(fields)
    text = CounterexampleFormat(name=COUNTEREXAMPLE_FORMAT, version=1, reader="this visnav").dumps(
        fields, rows_key="trace", rows=[[0.0, 0]])
    path = tmp_path / name
    path.write_text(text)
    return path


# --------------------------------------------------------------------------- the problem run is the command line's


def test_a_file_naming_a_python_file_does_not_run_it(tmp_path, cli):
    marker = tmp_path / "ran"
    evil = tmp_path / "evil.py"
    evil.write_text(f"open({str(marker)!r}, 'w').write('x')\nproblem = None\n")
    spec = _module(tmp_path)
    path = _counterexample(tmp_path, spec, "big", (1.0,), named=f"{evil}:problem")
    code, out, err = cli("replay", str(path))
    assert code == EXIT_BAD_INPUT and out == ""
    assert f"this counterexample names problem '{evil}:problem'; re-run with --problem {evil}:problem to confirm" in err
    code, _, err = cli("replay", str(path), "--problem", spec)  # another problem given: refused too
    assert code == EXIT_BAD_INPUT and f"not '{spec}' (--problem)" in err
    assert not marker.exists()


def test_a_file_naming_a_module_function_does_not_call_it(tmp_path, cli, monkeypatch):
    spec = _module(tmp_path)
    made = tmp_path / "temp"
    made.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(made))
    path = _counterexample(tmp_path, spec, "big", (1.0,), named="tempfile:mkdtemp")
    code, _, err = cli("replay", str(path))
    assert code == EXIT_BAD_INPUT and "re-run with --problem tempfile:mkdtemp to confirm" in err
    assert list(made.iterdir()) == []


def test_a_file_naming_os_abort_does_not_kill_the_process(tmp_path):
    spec = _module(tmp_path)
    path = _counterexample(tmp_path, spec, "big", (1.0,), named="os:abort")
    done = subprocess.run([sys.executable, "-m", "visnav.app.cli", "replay", str(path)], capture_output=True,
                          text=True, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    assert done.returncode == EXIT_BAD_INPUT, (done.returncode, done.stderr)
    assert "names problem 'os:abort'; re-run with --problem os:abort to confirm" in done.stderr
    assert "Traceback" not in done.stderr


def test_the_problem_confirmed_on_the_command_line_is_replayed_twice_alike(tmp_path, cli, monkeypatch):
    spec = _module(tmp_path)
    path = _counterexample(tmp_path, spec, "big", (-1.0,))  # x0 = 0.5: min 0.5 e^-2 = 0.068 < 0.2, violated
    first = cli("replay", str(path), "--problem", spec, "--json")
    assert first[0] == EXIT_TASK_FAILED, first[2]
    data = json.loads(first[1])
    assert data["violated"] is True and data["point"] == {"x0": 0.5}
    assert data["robustness"] == pytest.approx(0.5 * 2.718281828459045 ** -2 - 0.2, rel=1e-12)
    assert cli("replay", str(path), "--problem", spec, "--json") == first
    # the same file given by another path is the same problem (paths resolved, nothing imported to compare)
    monkeypatch.chdir(tmp_path)
    assert same_problem(spec, "./decay_problem.py:problem")
    assert cli("replay", str(path), "--problem", "decay_problem.py:problem")[0] == EXIT_TASK_FAILED
    assert not same_problem(spec, "decay_problem.py:other") and not same_problem("a.b:problem", "a.c:problem")


def test_replay_commands_name_the_problem_to_confirm():
    assert replay_command("out/cx.json", "paper") == "visnav replay out/cx.json"
    assert replay_command("out/c x.json", "my pkg.py:p") == "visnav replay 'out/c x.json' --problem 'my pkg.py:p'"


def test_verify_prints_and_writes_the_replay_command_with_the_problem(tmp_path, cli):
    spec = _module(tmp_path)
    out = tmp_path / "o"
    code, printed, err = cli("verify", spec, "--budget", "12", "--requirement", "big", "--out", str(out),
                              "--json")
    assert code == EXIT_TASK_FAILED, err
    cx = json.loads(printed)["requirements"][0]["counterexample"]
    assert cx["replay"] == replay_command(cx["file"], spec)
    assert json.loads(Path(cx["file"]).read_text())["replay"] == f"visnav replay <this file> --problem {spec}"
    assert cli("replay", cx["file"], "--problem", spec)[0] == EXIT_TASK_FAILED


# --------------------------------------------------------------------------- the rest of the file checked first


@pytest.mark.parametrize(("unit", "shown"), [
    ("nan", "unit[0] = 'nan'"), ("inf", "unit[0] = 'inf'"), ("-inf", "unit[0] = '-inf'"), (1.5, "unit[0] = 1.5"),
    (-1.0000001, "unit[0] = -1.0000001"),
])
def test_unit_coordinates_outside_the_box_are_refused_not_clamped(tmp_path, cli, unit, shown):
    spec = _module(tmp_path)

    def edit(fields):
        fields["unit"] = [unit]
        fields["point"] = {"x0": 2.0 if unit in ("inf", 1.5) else 0.5}  # what clamping would replay

    path = _counterexample(tmp_path, spec, "big", (0.0,), edit=edit)
    code, out, err = cli("replay", str(path), "--problem", spec)
    assert code == EXIT_BAD_INPUT and out == ""
    assert shown in err and "expected a finite number in [-1, 1]" in err and "not clamped" in err


def test_a_point_that_disagrees_with_its_unit_coordinates_is_refused(tmp_path, cli):
    spec = _module(tmp_path)
    path = _counterexample(tmp_path, spec, "big", (0.0,), edit=lambda f: f.update(point={"x0": 0.5}))
    code, _, err = cli("replay", str(path), "--problem", spec)
    assert code == EXIT_BAD_INPUT
    assert "point.x0 = 0.5 disagrees with unit coordinate 0.0, which gives 1.25 in the box [0.5, 2.0]" in err
    path = _counterexample(tmp_path, spec, "big", (0.0,), edit=lambda f: f.update(point={"y": 1.25}))
    assert cli("replay", str(path), "--problem", spec)[0] == EXIT_BAD_INPUT


def test_options_a_users_problem_does_not_take_are_refused(tmp_path, cli):
    spec = _module(tmp_path)
    path = _counterexample(tmp_path, spec, "big", (0.0,), options={"variant": "paper"})
    code, _, err = cli("replay", str(path), "--problem", spec)
    assert code == EXIT_BAD_INPUT and "options: unknown key 'variant'" in err and "the accepted keys are: none" in err


def _paper_problem():
    from visnav.verification import paper_problem

    return paper_problem()


@pytest.mark.parametrize(("options", "shown"), [
    ({"evil": 1}, "options: unknown key 'evil' for problem 'paper'; the accepted keys are: scenario, variant"),
    ({"variant": 5}, "options.variant = 5: expected a string, found an integer"),
])
def test_options_the_paper_problem_does_not_take_are_refused_not_exit_4(tmp_path, cli, options, shown):
    problem = _paper_problem()
    path = _counterexample(tmp_path, "paper", "no_collision", (0.0,) * len(problem.parameters), options=options,
                           problem=problem)
    code, _, err = cli("replay", str(path))
    assert code == EXIT_BAD_INPUT and shown in err


def test_the_paper_problem_replays_without_problem(tmp_path, cli):
    problem = _paper_problem()
    path = _counterexample(tmp_path, "paper", "no_collision", (0.0,) * len(problem.parameters), problem=problem,
                           options={"variant": "resolved"})
    code, out, err = cli("replay", str(path), "--json")
    assert code == EXIT_OK, err  # the nominal run does not collide (clearance > 0)
    assert json.loads(out)["violated"] is False and json.loads(out)["robustness"] > 0
    assert cli("replay", str(path), "--problem", "paper", "--json")[:2] == (code, out)


def test_a_hostile_label_pattern_in_the_scenario_a_file_points_at_does_not_hang(tmp_path, cli):
    # matches the *OCCLUDED modes; the old regex backtracked ~C(L + 30, 30) steps on a mode of L characters
    # that does not end in D (1.4 s for 13 stars on APPROACH|RELEASE, x2.2 per star)
    hostile = '"' + "*" * 30 + 'D"'
    scenario = tmp_path / "hostile.toml"
    scenario.write_text((ROOT / "visnav/scenarios/paper.toml").read_text() + textwrap.dedent(f"""
        [[requirements]]
        name = "hostile"
        description = "a pattern with 30 stars"
        formula = '''always[0, 90] (mode != {hostile} or clearance_m > 0)'''
        """))
    problem = _paper_problem()  # the same box: the requirements do not change the parameters
    path = _counterexample(tmp_path, "paper", "hostile", (0.0,) * len(problem.parameters), problem=problem,
                           options={"scenario": str(scenario)})
    start = time.perf_counter()
    code, out, err = cli("replay", str(path), "--json")
    assert time.perf_counter() - start < 30.0  # a paper run takes about 0.2 s; the old regex took hours
    assert code == EXIT_OK, err
    assert json.loads(out)["violated"] is False


# --------------------------------------------------------------------------- failures of the replayed run


def test_a_formula_dividing_by_zero_names_the_requirement_and_the_instant(tmp_path, cli):
    spec = _module(tmp_path)
    path = _counterexample(tmp_path, spec, "ratio", (0.0,))
    code, out, err = cli("replay", str(path), "--problem", spec)
    assert code == EXIT_BAD_INPUT and out == ""
    assert ("requirement ratio: formula 'always[0, 2] (1 / (x - x) > 0)': expression (1 / (x - x)) at sample 0 "
            "(t = 0 s) = inf") in err
    assert "Traceback" not in err and "simulator" not in err


def test_a_simulator_raising_is_a_model_error_with_its_traceback(tmp_path, cli):
    spec = _module(tmp_path)
    path = _counterexample(tmp_path, spec, "big", (1.0,))  # x0 = 2.0 > 1.9: the user's bug
    code, out, err = cli("replay", str(path), "--problem", spec)
    assert code == EXIT_MODEL_ERROR and out == ""
    assert "your simulator raised RuntimeError: user bug at the top of the box at {'x0': 2.0}" in err
    assert "decay_problem.py" in err  # the user's own frame, to fix their code


# --------------------------------------------------------------------------- fuzz counterexamples name no code


def test_a_fuzz_counterexample_names_only_registered_properties(tmp_path, cli):
    from visnav.fuzzing.counterexamples import COUNTEREXAMPLE_FORMAT as FUZZ_FORMAT

    text = FUZZ_FORMAT.dumps({"property": "os:abort", "variant": "tempfile:mkdtemp", "kind": "signals",
                              "violation": {"message": "m"}, "space": {}, "channels": []},
                             rows_key="measurements", rows=[[0.0]])
    path = tmp_path / "fuzz.json"
    path.write_text(text)
    code, _, err = cli("replay", str(path))
    assert code == EXIT_BAD_INPUT and "unknown property 'os:abort'; known:" in err
    text = text.replace('"os:abort"', '"mu_range"')
    path.write_text(text)
    code, _, err = cli("replay", str(path))
    assert code == EXIT_BAD_INPUT and "unknown variant 'tempfile:mkdtemp'; known:" in err


def test_problem_is_refused_for_a_fuzz_counterexample(tmp_path, cli):
    from visnav.fuzzing import counterexample_to_json
    from visnav.fuzzing.counterexamples import Counterexample
    from visnav.fuzzing.space import MeasurementSpace

    space = MeasurementSpace()
    cx = Counterexample(property="mu_range", variant="resolved", kind="signals", message="recorded", sample=0,
                        details={}, space=space, measurements=(tuple(0.5 for _ in space.names),))
    path = tmp_path / "fuzz.json"
    path.write_text(counterexample_to_json(cx))
    code, _, err = cli("replay", str(path), "--problem", "os:abort")
    assert code == EXIT_BAD_INPUT and "names property 'mu_range' of visnav fuzz, not a problem; drop --problem" in err
    assert cli("replay", str(path))[0] in (EXIT_OK, EXIT_TASK_FAILED)
