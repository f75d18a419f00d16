"""``visnav reach`` without a step schedules its flowpipes as ``visnav verify`` does; a SpaceEx ``sampling-time``
is the user's step (an explicit ``--time-step`` still wins); a bad one is bad input naming it.

Yardsticks: the fast lag ``ẋ = −2000 x + 2000``, ``x(0) ∈ [0, 0.1]``: ``x(t) = 1 − (1 − x₀) e^{−2000 t} < 1``
(``1 − 0.9 e^{−4100}`` at 2.05 s), so ``x <= 1.5`` holds with the slack 0.5; its matrix with the constant column has
the row sum ``2000 + 1`` (the constant scaled to 1), so a step chosen for ``‖A‖·step <= κ`` is ``κ / 2001`` s; the
default step 2.05 s / 1000 gives ``2001 · 0.00205 > 4`` (refused).  At ``κ = 3.9`` the first step's tube reaches
``x ≈ 31`` (the interpolation error of a step with ``‖A‖δ = 3.9`` from the box's corner ``x = 0`` to 1), so the
proof comes from the second choice, ``κ = 0.4``, in both commands.  The bouncing ball from ``x ∈ [10, 10.2]`` never climbs above
its start (slack 0.3 to ``x >= 10.5``).
"""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[3]
BALL = ROOT / "tests" / "data" / "spaceex" / "spaceexparser" / "bball" / "bball.xml"
CFG = ('system = "system"\ninitially = "10<=x<=10.2 & v==0"\nforbidden = "x >= 10.5"\ntime-horizon = 8\n'
       'output-variables = "x,v"\n')

MODULE = '''
from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter
from hybrid import HybridAutomaton, HybridSystem, Mode
from hybrid.symbolic import coordinates, flow_map

x = coordinates("x")
automaton = HybridAutomaton(name="fast", modes=(Mode(name="m"),), transitions=(), variables=("x",), initial_mode="m")
system = HybridSystem(automaton=automaton, state_names=("x",), flows={"m": flow_map(-2000.0 * x.x + 2000.0)})
problem = hybrid_problem(name="fast", system=system, initial={"x": Parameter(name="x0", low=0.0, high=0.1)},
                         horizon=2.05, requirements=(Requirement(name="bound", formula="always[0, 2.05] x <= 1.5"),))
'''


@pytest.fixture()
def fast(tmp_path):
    path = tmp_path / "fast_problem.py"
    path.write_text(textwrap.dedent(MODULE))
    return f"{path}:problem"


def test_reach_without_a_step_chooses_the_steps_verify_chooses(fast, cli):
    from analysis.verify.loading import load_problem

    code, out, err = cli("reach", "--problem", fast, "--json")
    assert code == 0, err
    data = json.loads(out)
    (step,) = data["options"]["mode_time_steps"].values()
    assert step == pytest.approx(0.4 / 2001.0, rel=1e-12)  # by hand: the row sum 2000 + the constant column
    assert data["steps_chosen"] == "steps chosen from the dynamics, ‖A‖·step <= 0.4: 'm' 0.0001999 s"
    (req,) = data["requirements"]
    assert req["status"] == "proven" and 0.49 < req["margin"] <= 0.5 + 1e-9  # the true slack is 0.5
    proof = load_problem(fast).proofs["bound"]()  # verify's proof of the same requirement
    assert proof.holds and proof.rechecked and data["steps_chosen"] in proof.evidence


def test_an_explicit_step_is_used_alone_as_before(fast, cli):
    code, _, err = cli("reach", "--problem", fast, "--time-step", "0.00205")
    assert code == 2 and "--time-step 0.00205" in err and "‖A‖" in err and "Traceback" not in err


def _cfg(tmp_path, extra):
    path = tmp_path / "ball.cfg"
    path.write_text(CFG + extra)
    return path


def test_the_sampling_time_is_the_step_the_engine_reports(tmp_path, cli):
    from analysis.spaceex import spaceex_problem

    cfg = _cfg(tmp_path, "sampling-time = 0.05\n")
    code, out, err = cli("reach", "--problem", BALL, "--config", cfg, "--json")
    assert code == 0, err
    data = json.loads(out)
    assert data["time_step"] == 0.05 and data["steps_chosen"] == "" and data["options"] == {}
    assert all(s["flowpipe"]["time_step"] == 0.05 for s in data["starts"])
    proof = spaceex_problem(BALL, cfg).proofs["safe"]()  # verify's proof: the same step
    assert proof.holds and proof.rechecked and "step 0.05 s" in proof.evidence
    assert 0.0 < proof.margin <= 0.3 + 1e-9  # the ball's slack
    code, out, _ = cli("reach", "--problem", BALL, "--config", cfg, "--json", "--time-step", "0.02")
    assert code == 0 and json.loads(out)["time_step"] == 0.02  # an explicit step wins
    code, out, _ = cli("reach", "--problem", BALL, "--config", _cfg(tmp_path, ""), "--json")
    assert code == 0 and json.loads(out)["time_step"] == 8.0 / 1000.0  # none: the default base step


@pytest.mark.parametrize("value", ["0", "-1", "nan", "8.5"])
@pytest.mark.parametrize("command", ["reach", "verify"])
def test_a_bad_sampling_time_exits_2_naming_it(tmp_path, cli, value, command):
    cfg = _cfg(tmp_path, f"sampling-time = {value}\n")
    argv = ["reach", "--problem", BALL] if command == "reach" else ["verify", BALL, "--out", tmp_path / "v"]
    code, _, err = cli(*argv, "--config", cfg)
    assert code == 2 and "sampling-time" in err and value in err and "Traceback" not in err
