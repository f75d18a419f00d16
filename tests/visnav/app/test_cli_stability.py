"""A user's state-dependent switched system asks for stability: the piecewise quadratic certificate reaches
`visnav analyse --problem` and the report's stability section as a PROVEN claim."""

from __future__ import annotations

import json

from visnav.app.cli import main

PROBLEM = '''
"""Liberzon's two unstable spirals switched on the quadrants (8 sectors): stable, but by no common P."""
import numpy as np

from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter
from hybrid.conewise import conewise_linear_system

SPIRALS = {"one": np.array([[0.1, -1.0], [2.0, 0.1]]), "two": np.array([[0.1, -2.0], [1.0, 0.1]])}
ORDER = ORDER_PLACEHOLDER


def build(params):
    return conewise_linear_system("spirals", [SPIRALS[ORDER[(i * 4) // 8]] for i in range(8)])


problem = hybrid_problem(
    name="spirals", system=build,
    initial={"x": Parameter(name="x0", low=0.5, high=1.0, nominal=1.0), "y": 0.3},
    horizon=20.0, sample_period=0.05,
    requirements=(Requirement(name="bounded", formula="always[0, 20] (abs(x) <= 10)"),),
    stability=True)
'''


def _write(tmp_path, order):
    path = tmp_path / f"spirals_{order[0]}.py"
    path.write_text(PROBLEM.replace("ORDER_PLACEHOLDER", repr(order)))
    return f"{path}:problem"


def test_the_stable_assignment_is_proven_by_a_piecewise_quadratic_function(tmp_path, capsys):
    spec = _write(tmp_path, ("two", "one", "two", "one"))
    assert main(["analyse", "--problem", spec, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["verdict"] == "stable"
    assert data["switched"]["status"] == "none" and data["piecewise"]["status"] == "exists"
    assert data["piecewise_note"] == "" and data["dwell"] is None  # both modes are unstable: no dwell time
    assert data["claims"][-1]["status"] == "proven" and "state-dependent switching" in data["claims"][-1]["text"]
    assert main(["analyse", "--problem", spec]) == 0
    human = capsys.readouterr().out
    assert human.startswith("analyse spirals: STABLE") and "PROVEN       every execution" in human

    from analysis.verify.loading import load_problem
    from visnav.app.verification_report import stability_section

    section = stability_section(load_problem(spec))
    proven = [c for c in section.claims if c.status == "proven"]
    assert any("piecewise" in section.data["claims"][-1]["method"] and "converges" in c.text for c in proven)


def test_the_swapped_assignment_is_not_called_stable(tmp_path, capsys):
    spec = _write(tmp_path, ("one", "two", "one", "two"))
    assert main(["analyse", "--problem", spec, "--json"]) == 5  # not decided: incomplete, never a pass
    data = json.loads(capsys.readouterr().out)
    assert data["verdict"] == "not decided" and data["piecewise"]["status"] == "undecided"
    assert data["claims"][-1]["status"] == "not decided"


def test_the_report_of_the_problem_tabulates_the_lmi_results(tmp_path):
    spec = _write(tmp_path, ("two", "one", "two", "one"))
    # the model's guards are plain callables: its structural checks are sampled and leave the Zeno question
    # undecided, so the report is incomplete (5) though no requirement is falsified
    assert main(["report", "--problem", spec, "--out", str(tmp_path / "r"), "--quick"]) == 5
    text = (tmp_path / "r" / "report.md").read_text()
    assert json.loads((tmp_path / "r" / "report.json").read_text())["structural_errors"]["undecided"]
    assert "| common quadratic | none | no common quadratic Lyapunov function exists" in text
    assert "| piecewise quadratic | exists | a piecewise quadratic Lyapunov function exists (proven exactly)" in text
    data = json.loads((tmp_path / "r" / "report.json").read_text())
    assert data["stability"]["verdict"] == "stable"
