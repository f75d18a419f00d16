"""``visnav reach --problem``: verdicts and exit codes, the JSON, the files of --out, and every bad input.

The yardstick is the closed form of ``ẋ = −x + p``, ``x(0) = 0``, ``p ∈ [1, 2]`` (the parameter is a
constant state): ``x(t) = p (1 − e^{−t})``, largest over ``[0, 5]`` at ``p = 2``, ``t = 5``:
``2 (1 − e^{−5}) = 1.98652``.  So ``x <= 1.99`` holds with the slack ``0.00348`` and the flowpipe
meets ``x > 1.98``.
"""

from __future__ import annotations

import json
import math
import textwrap

import pytest

from visnav.app.cli import main

TRUE_MAX = 2.0 * (1.0 - math.exp(-5.0))

MODULE = '''
from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter
from hybrid import HybridAutomaton, HybridSystem, Mode
from hybrid.symbolic import coordinates, flow_map


def build(point):
    x = coordinates("x")
    automaton = HybridAutomaton(name="lag", modes=(Mode(name="m"),), transitions=(), variables=("x",),
                                initial_mode="m")
    return HybridSystem(automaton=automaton, state_names=("x",), flows={"m": flow_map(-x.x + point["p"])})


def plain(point):
    automaton = HybridAutomaton(name="lag", modes=(Mode(name="m"),), transitions=(), variables=("x",),
                                initial_mode="m")
    return HybridSystem(automaton=automaton, state_names=("x",), flows={"m": lambda t, x, m: (-x[0] + point["p"],)})


def make(system, formula):
    return hybrid_problem(name="lag", system=system, initial={"x": 0.0},
                          parameters=(Parameter(name="p", low=1.0, high=2.0),), horizon=5.0,
                          requirements=(Requirement(name="bound", formula=formula),))


safe = make(build, "always[0, 5] x <= 1.99")
unsafe = make(build, "always[0, 5] x <= 1.98")
mixed = hybrid_problem(name="lag", system=build, initial={"x": 0.0},
                       parameters=(Parameter(name="p", low=1.0, high=2.0),), horizon=5.0,
                       requirements=(Requirement(name="bound", formula="always[0, 5] x <= 1.99"),
                                     Requirement(name="later", formula="eventually[0, 5] x >= 0.5")))
not_symbolic = make(plain, "always[0, 5] x <= 1.99")
'''


@pytest.fixture()
def spec(tmp_path):
    path = tmp_path / "lag_problem.py"
    path.write_text(textwrap.dedent(MODULE))
    return lambda name: f"{path}:{name}"


def test_a_proven_requirement_exits_0_with_its_margin_and_json(spec, cli):
    code, out, err = cli("reach", "--problem", spec("safe"), "--json")
    assert code == 0, err
    data = json.loads(out)
    assert data["format"] == "visnav-reach" and data["complete"] is True
    assert data["state_names"] == ["x", "p"] and data["parameters_as_states"] == ["p"]
    (req,) = data["requirements"]
    assert req["status"] == "proven" and 0.0 < req["margin"] <= 1.99 - TRUE_MAX + 1e-12
    assert 0.0 < req["recheck_margin"] <= 1.99 - TRUE_MAX + 1e-12
    (start,) = data["starts"]
    assert start["mode"] == "m" and start["box"] == [["x", 0.0, 0.0], ["p", 1.0, 2.0]]
    # the saved flowpipe reaches the true maximum and stays below the bound
    tops = [seg["box"][1][0] for seg in start["flowpipe"]["segments"]]
    assert TRUE_MAX - 1e-9 <= max(tops) < 1.99
    again = cli("reach", "--problem", spec("safe"), "--json")[1]
    assert again == out  # deterministic: no timings in the JSON


def test_an_unsafe_set_the_flowpipe_meets_exits_1(spec, cli):
    code, out, err = cli("reach", "--problem", spec("unsafe"))
    assert code == 1, err
    assert "unsafe set met" in out and "not a counterexample" in out


def test_a_requirement_outside_the_fragment_leaves_the_run_incomplete(spec, cli):
    code, out, err = cli("reach", "--problem", spec("mixed"))
    assert code == 5, err
    assert "proven" in out and "not decided" in out and "later" in out


def test_a_jump_bound_reached_is_inconclusive(tmp_path, cli):
    from pathlib import Path

    example = Path(__file__).resolve().parents[3] / "examples" / "thermostat.py"
    code, out, err = cli("reach", "--problem", f"{example}:problem", "--horizon", "10", "--max-jumps", "3")
    assert code == 5, err
    assert "jump bound" in out and "inconclusive" in out


def test_out_writes_the_json_and_figures_and_owns_them(spec, tmp_path, cli):
    folder = tmp_path / "o"
    code, out, err = cli("reach", "--problem", spec("safe"), "--out", folder, "--plot", "x,p")
    assert code == 0, err
    for name in ("reach.json", "figures/sets_x.png", "figures/sets_p.png", "figures/phase_x_p.png"):
        assert (folder / name).is_file() and str(folder / name) in out
    assert (folder / "figures" / "phase_x_p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((folder / "reach.json").read_text())["requirements"][0]["status"] == "proven"
    assert cli("reach", "--problem", spec("safe"), "--out", folder)[0] == 0  # its own files: rewritten
    (folder / "reach.json").write_text("mine")
    code, _, err = cli("reach", "--problem", spec("safe"), "--out", folder)
    assert code == 2 and "not written by visnav" in err and (folder / "reach.json").read_text() == "mine"


@pytest.mark.parametrize("extra, words", [
    (("--time-step", "10"), "larger than the horizon"),
    (("--time-step", "0"), "not a positive time"),
    (("--time-step", "nan"), "not a positive time"),
    (("--horizon", "-1"), "not a positive time"),
    (("--max-jumps", "-2"), "negative"),
    (("--plot", "x"), "two state names"),
    (("--plot", "x,y"), "not among the flowpipe's states"),
])
def test_bad_options_exit_2_with_a_message(spec, capsys, extra, words):
    try:
        code = main(["reach", "--problem", spec("safe"), *extra])
    except SystemExit as stop:  # argparse's usage error
        code = stop.code
    err = capsys.readouterr().err
    assert code == 2 and words in err and "Traceback" not in err


def test_a_model_that_is_not_symbolic_is_bad_input_with_what_to_write(spec, cli):
    code, out, err = cli("reach", "--problem", spec("not_symbolic"))
    assert code == 2 and "Traceback" not in err
    assert "reachability needs a symbolic" in err and "flow_map" in err


def test_a_missing_problem_is_bad_input(tmp_path, cli):
    code, _, err = cli("reach", "--problem", f"{tmp_path / 'nope.py'}:problem")
    assert code == 2 and "nope.py" in err and "Traceback" not in err


THERMOSTAT = str(__import__("pathlib").Path(__file__).resolve().parents[3] / "examples" / "thermostat.py") + ":problem"


@pytest.mark.parametrize("extra, horizon", [((), "120"), (("--horizon", "60"), "60")])
def test_a_step_lost_on_the_time_scale_is_refused_as_typed(cli, extra, horizon):
    """The thermostat runs on τ = rate·t (rate <= 0.2): 5e-324 s × 0.2 rounds to 0.  The message names the
    step the user typed and the horizon the user gave (or the problem's), never the scaled ones."""
    code, _, err = cli("reach", "--time-step", "5e-324", *extra, "--problem", THERMOSTAT)
    assert code == 2 and "Traceback" not in err
    assert "--time-step 5e-324:" in err and f"--horizon {horizon} [s]" in err
    assert "--time-step 0.0:" not in err and "24.000000000000004" not in err and "time_step =" not in err


def test_the_library_refuses_the_step_in_the_users_values():
    from analysis.reach.initial import ReachError
    from analysis.reach.problem import problem_reach
    from analysis.verify.loading import load_problem

    with pytest.raises(ReachError) as caught:
        problem_reach(load_problem(THERMOSTAT), time_step=5e-324)
    assert caught.value.parameter == "time_step" and caught.value.value == 5e-324
    assert "horizon = 120 [s]" in caught.value.expected and "0.2·t" in caught.value.expected
