"""The report of any verification problem: verdict table first, counterexample links, figures, collapsed lists.

Small budgets throughout (the whole file runs in well under a minute).
"""

from __future__ import annotations

import dataclasses
import json
import re
import textwrap
from pathlib import Path
from types import SimpleNamespace

import pytest

from analysis.verify.loading import load_problem
from hybrid.check import Finding

from visnav.app.cli import main
from visnav.app.report_files import report_json_text
from visnav.app.report_render import Block, render_html, render_markdown
from visnav.app.verification_report import (
    VERDICT_LABELS,
    WORST_FINDINGS,
    build_problem_report,
    findings_summary,
)

ROOT = Path(__file__).resolve().parents[3]
THERMOSTAT = "examples/thermostat.py"
BUDGET = 12

USER_PROBLEM = '''
"""A user's problem outside the repository: x' = -x from x0 in [0.5, 2]."""
from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter
from hybrid import HybridAutomaton, HybridSystem, Mode, check

automaton = HybridAutomaton(name="decay", modes=(Mode(name="flow"),), transitions=(), variables=("x",),
                            initial_mode="flow")
system = HybridSystem(automaton=automaton, state_names=("x",), flows={"flow": lambda t, x, m: (-x[0],)})
problem = hybrid_problem(
    name="decay", system=system, initial={"x": Parameter(name="x0", low=0.5, high=2.0, nominal=1.0)},
    horizon=3.0, sample_period=0.1, structural=lambda: check(system),
    requirements=(Requirement(name="positive", formula="always[0, 3] (x > 0)", description="x stays positive"),
                  Requirement(name="bounded", formula="always[0, 3] (x <= 1.5)", description="x stays below 1.5")))
'''


@pytest.fixture(autouse=True)
def _close_figures():
    """The reports built in-process keep their matplotlib figures open: close them after each test."""
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


def _report(spec: str, budget: int = BUDGET):
    problem = load_problem(str(ROOT / spec.split(":")[0]) + ":" + spec.split(":")[1])
    return problem, build_problem_report(problem, spec=spec, seed=0, budget=budget, quick=True)


def _documents(report) -> tuple[str, str]:
    png = {stem: b"png" for stem in report.figures}
    return (render_markdown(report.data, {stem: f"figures/{stem}.png" for stem in report.figures}),
            render_html(report.data, png))


@pytest.fixture(scope="module")
def zero_band():
    return _report(f"{THERMOSTAT}:zero_band")


def test_not_falsified_problem_has_its_verdict_table_first():
    problem, report = _report(f"{THERMOSTAT}:problem")
    data = report.data
    assert data["verdict"] == "not_falsified" and data["sections"] == ["verification", "structure", "stability"]
    rows = data["verification"]["requirements"]
    assert [r["name"] for r in rows] == list(problem.requirement_names)
    # comfort is proven by reachability over the whole box (the rate is a time scale: docs/reachability.md),
    # min_dwell (jumps, prev: outside the fragment) is searched
    by = {r["name"]: r for r in rows}
    assert by["comfort"]["verdict"] == "proven" and by["comfort"]["decided_by"] == "reachability (re-checked)"
    assert by["min_dwell"]["verdict"] == "not_falsified"
    assert by["min_dwell"]["decided_by"] == f"falsification ({BUDGET} simulations)"
    assert all(r["counterexample_file"] is None for r in rows)
    assert f"{BUDGET} simulations, lowest at" in by["min_dwell"]["evidence"] and "coverage" in by["min_dwell"]["evidence"]
    assert "re-checked from the saved flowpipe" in by["comfort"]["evidence"]
    assert report.files == {}
    assert {"verification_nominal", "verification_robustness", "stability_orbit"} == set(report.figures)
    md, _ = _documents(report)
    body = md.split("\n## ", 2)
    assert body[1].startswith("Verification of `thermostat-band-1`")  # the first section, before the claims
    assert "Overall verdict: NOT FALSIFIED (exit code 0)" in md
    assert "| comfort | PROVEN | reachability (re-checked) |" in md
    assert f"| min_dwell | NOT FALSIFIED | falsification ({BUDGET} simulations) |" in md
    # the example is written symbolically: the state-space checks are decided by z3, the graph checks exact
    from visnav.app.structural import REPORT_STATUS

    structure = [c for c in data["claims"] if c["section"] == "structure"]
    checks = data["structure"]["claims"]
    assert checks["nondeterminism"]["status"] == checks["deadlock"]["status"] == "proven"
    # the graph checks (exact), then one claim per check that makes one (an undecided check makes none)
    assert [c["status"] for c in structure] == ["proven"] + [REPORT_STATUS[c["status"]] for c in checks.values()
                                                             if c["status"] in REPORT_STATUS]
    # stability=True: both equilibria are virtual (outside their modes), the steady state is the limit cycle
    stability = data["stability"]
    assert [e["kind"] for e in stability["equilibria"]] == ["virtual", "virtual"]
    assert stability["verdict"] == "stable" and stability["orbit"]["verdict"] == "orbitally stable"
    period = 2 * __import__("math").log(10.5 / 9.5) / 0.1  # nominal rate 0.1, thresholds 19.5 and 20.5
    assert abs(stability["orbit"]["period"] - period) < 1e-9
    assert "## Stability of `thermostat`" in md and "virtual equilibrium, outside the mode" in md
    assert [c["status"] for c in data["claims"] if c["section"] == "stability"] == ["measured"] * 3
    assert structure[0]["text"].startswith("graph checks of thermostat (exact, on the mode graph)")
    assert structure[1]["text"].startswith("nondeterminism of thermostat: no two transitions of equal priority")
    assert [c["status"] for c in data["claims"] if c["section"] == "verification"] == ["proven", "sampled"]
    assert data["structure"]["automaton"] == "thermostat" and data["structure"]["checks"]  # hybrid.check ran
    assert data["structure"]["claims"]["zeno"]["status"] == "proven"  # symbolic: the dwell bound is proven by z3
    assert "| zeno | PROVEN |" in md


def test_falsified_problem_links_its_counterexample(zero_band):
    problem, report = zero_band
    data = report.data
    assert data["verdict"] == "falsified" and data["verification"]["exit_code"] == 1
    row = {r["name"]: r for r in data["verification"]["requirements"]}["min_dwell"]
    assert row["verdict"] == "falsified" and row["counterexample_file"] == "counterexamples/min_dwell.json"
    cx = row["counterexample"]
    assert f"violated at t = {cx['time']:.4g} s by `{cx['atom'].strip()}`" in row["evidence"]
    text = report.files["counterexamples/min_dwell.json"]
    assert json.loads(text)["requirement"] == "min_dwell"
    md, html = _documents(report)
    assert "| min_dwell | FALSIFIED |" in md
    assert "[counterexamples/min_dwell.json](counterexamples/min_dwell.json)" in md
    assert '<a href="counterexamples/min_dwell.json">counterexamples/min_dwell.json</a>' in html
    assert any(c["status"] == "measured" and "min_dwell FALSIFIED" in c["text"] for c in data["claims"])


def test_counterexample_figure_marks_the_violation_instant(zero_band):
    _, report = zero_band
    cx = {r["name"]: r for r in report.data["verification"]["requirements"]}["min_dwell"]["counterexample"]
    figure = report.figures["verification_counterexample_min_dwell"]
    ax = figure.axes[0]
    marks = [line for line in ax.get_lines() if str(line.get_label()).startswith("violated at t = ")]
    assert len(marks) == 1 and marks[0].get_color() == "tab:red"
    assert f"t = {cx['time']:.4g} s" in marks[0].get_label() and cx["atom"].strip() in marks[0].get_label()
    # the nominal run marks where each requirement is decided, one panel per requirement
    assert len(report.figures["verification_nominal"].axes) >= 2


def test_same_seed_gives_identical_bytes(zero_band):
    problem, first = zero_band
    second = build_problem_report(problem, spec=f"{THERMOSTAT}:zero_band", seed=0, budget=BUDGET, quick=True)
    assert report_json_text(first) == report_json_text(second)
    assert _documents(first)[0] == _documents(second)[0]
    assert first.files == second.files


def test_cli_report_problem_exits_1_when_falsified(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    out = tmp_path / "tmp"
    code = main(["report", "--problem", f"{THERMOSTAT}:zero_band", "--out", str(out), "--quick",
                 "--budget", str(BUDGET), "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 1 and summary["verdict"] == "falsified" and summary["exit_code"] == 1
    data = json.loads((out / "report.json").read_text())
    assert data["verdict"] == "falsified"
    assert (out / "counterexamples" / "min_dwell.json").is_file()
    assert (out / "figures" / "verification_counterexample_min_dwell.png").is_file()
    assert "visnav report --problem examples/thermostat.py:zero_band --quick --seed 0 --budget 12" in (
        out / "report.md").read_text()
    assert main(["replay", str(out / "counterexamples" / "min_dwell.json"), "--problem",
                 f"{THERMOSTAT}:zero_band"]) == 1


def test_user_problem_outside_the_repository_end_to_end(tmp_path, capsys):
    (tmp_path / "decay_problem.py").write_text(USER_PROBLEM)
    out = tmp_path / "report"
    spec = f"{tmp_path / 'decay_problem.py'}:problem"
    code = main(["report", "--problem", spec, "--out", str(out), "--budget", "30"])
    printed = capsys.readouterr().out
    assert code == 1, printed
    data = json.loads((out / "report.json").read_text())
    assert data["sections"] == ["verification", "structure"] and data["verdict"] == "falsified"
    rows = {r["name"]: r for r in data["verification"]["requirements"]}
    assert rows["positive"]["verdict"] == "not_falsified" and rows["bounded"]["verdict"] == "falsified"
    assert data["structure"]["summary"]["by_kind"] == [{"severity": "warning", "kind": "sink_mode", "count": 1}]
    # no box: the state-space checks skipped, the sink mode found by the exact graph check
    assert {c["status"] for c in data["structure"]["claims"].values()} == {"skipped"}
    assert [c["status"] for c in data["claims"] if c["section"] == "structure"] == ["measured"]
    md = (out / "report.md").read_text()
    assert "## Structural checks of `decay`" in md and "| bounded | FALSIFIED |" in md
    assert main(["replay", str(out / rows["bounded"]["counterexample_file"]), "--problem", spec]) == 1
    # a second report into the same folder without the counterexample removes the stale file
    (tmp_path / "fixed_problem.py").write_text(USER_PROBLEM.replace("x <= 1.5", "x <= 2.5"))
    assert main(["report", "--problem", f"{tmp_path / 'fixed_problem.py'}:problem", "--out", str(out),
                 "--budget", "8"]) in (0, 5)  # 5 when its sampled structural checks leave a question undecided
    assert not (out / "counterexamples" / "bounded.json").exists()


def test_symbolic_problem_report_shows_proven_claims(symbolic_problem):
    """A user's symbolic model: one PROVEN claim per structural check, the claims table and the Zeno line."""
    problem = load_problem(symbolic_problem)
    report = build_problem_report(problem, spec="symbolic", seed=0, budget=4, quick=True)
    st = report.data["structure"]
    assert {name: c["status"] for name, c in st["claims"].items()} == dict.fromkeys(
        ("nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers", "zeno"), "proven")
    assert st["zeno"]["cycles"] == 1 and st["solver"].startswith("z3")
    claims = [c for c in report.data["claims"] if c["section"] == "structure"]
    assert [c["status"] for c in claims] == ["proven"] * 6  # the graph checks, then one per check
    assert claims[5]["text"].startswith("zeno of symbolic-thermostat: no Zeno cycle")
    assert "over every state of the declared box" in claims[1]["text"]
    md, html = _documents(report)
    assert "| check | claim | how | detail |" in md and "| nondeterminism | PROVEN | z3" in md
    assert "Zeno: 1 cycle: 1 non-Zeno (proven), smallest dwell bound" in md
    assert "<td>PROVEN</td>" in html and '<span class="badge proven">PROVEN</span>zeno of' in html


def _many_findings_problem():
    problem = load_problem(f"{ROOT / THERMOSTAT}:problem")
    findings = [Finding(kind="zeno_candidate", severity="info", message=f"cycle {i} of the mode graph",
                        modes=("off", "on"), transitions=("heat_on", "heat_off")) for i in range(40)]
    findings.insert(17, Finding(kind="sink_mode", severity="warning", message="mode 'on' is a sink", modes=("on",)))
    report = SimpleNamespace(automaton="thermostat", findings=tuple(findings))
    return dataclasses.replace(problem, structural=lambda: report)


def test_long_finding_lists_are_collapsed():
    problem = _many_findings_problem()
    report = build_problem_report(problem, spec="many", seed=0, budget=4, quick=True)
    summary = report.data["structure"]["summary"]
    assert summary["total"] == 41 and summary["by_severity"] == {"error": 0, "warning": 1, "info": 40}
    assert summary["worst"][0]["kind"] == "sink_mode" and len(summary["worst"]) == WORST_FINDINGS
    md, html = _documents(report)
    assert "<details>" in html and "<summary>All 41 findings</summary>" in html
    assert "<details>\n<summary>All 41 findings</summary>\n" in md
    start = html.index("<h2>Structural checks of")
    section = html[start:html.index("<h2>", start + 4)]
    visible = re.sub(r"<details>.*?</details>", "", section, flags=re.S)
    assert visible.count("<table>") == 2  # the counts and the worst few
    for table in re.findall(r"<table>.*?</table>", visible, flags=re.S):
        assert table.count("<tr>") <= 11  # header + at most 10 rows outside the collapsed list
    assert html.count("cycle 39 of the mode graph") == 1  # in the full list only


def test_findings_summary_orders_by_severity():
    findings = [{"kind": "zeno_point", "severity": "info", "message": "a"},
                {"kind": "deadlock", "severity": "error", "message": "b"},
                {"kind": "sink_mode", "severity": "warning", "message": "c"}]
    summary = findings_summary(findings, worst=2)
    assert [f["message"] for f in summary["worst"]] == ["b", "c"]
    assert [r["kind"] for r in summary["by_kind"]] == ["deadlock", "sink_mode", "zeno_point"]


def test_details_block_renders_in_both_documents():
    from visnav.app import report_render

    blocks = [Block("details", ("Three rows", [Block("table", (["a"], [["1"], ["2"], ["3"]]))]))]
    md = "\n".join(report_render._markdown_lines(blocks, {}))
    html = "\n".join(report_render._html_parts(blocks, {}))
    assert md.startswith("<details>\n<summary>Three rows</summary>\n\n| a |") and md.rstrip().endswith("</details>")
    assert html.startswith("<details><summary>Three rows</summary>") and html.endswith("</details>")
    assert VERDICT_LABELS["not_falsified"] == "NOT FALSIFIED"


def test_bad_problem_spec_is_a_clear_error(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    assert main(["report", "--problem", "examples/no_such_file.py:problem", "--out", str(tmp_path / "x")]) == 2
    assert "no_such_file.py" in capsys.readouterr().err


def test_a_second_verification_section_has_its_own_figures_files_and_claims(zero_band):
    """``verification_section(..., name="saturated")`` (the case study's saturated loop): nothing it writes
    collides with the first section's, and the document shows both tables, the first before the claims."""
    from analysis.verify.verdicts import verify

    from visnav.app.verification_report import assemble_report, verification_section

    problem, report = zero_band
    result = verify(problem, budget=BUDGET, seed=0)
    first = verification_section(problem, result, spec=f"{THERMOSTAT}:zero_band")
    second = verification_section(problem, result, spec=f"{THERMOSTAT}:zero_band", name="saturated")
    assert set(first.figures) == set(report.figures) and set(first.files) == set(report.files)
    assert set(second.figures) == {stem.replace("verification_", "saturated_", 1) for stem in first.figures}
    assert set(second.files) == {"counterexamples/saturated~min_dwell.json"}
    assert second.files["counterexamples/saturated~min_dwell.json"] == first.files["counterexamples/min_dwell.json"]
    assert {c.section for c in second.claims} == {"saturated"} and {c.section for c in first.claims} == {
        "verification"}
    assert [c.text.replace("saturated~", "").replace("'", "") for c in second.claims] == [c.text.replace("'", "") for c in first.claims]
    row = {r["name"]: r for r in second.data["requirements"]}["min_dwell"]
    assert row["counterexample_file"] == "counterexamples/saturated~min_dwell.json"
    assert row["figure"] == "saturated_counterexample_min_dwell" and second.data["robustness_figure"] == (
        "saturated_robustness")
    meta = {"tool": "test", "problem": problem.name, "quick": True, "seeds": {"report": 0},
            "budgets": {"verify_budget": BUDGET}, "command": "-", "versions": {}}
    both = assemble_report(meta, [("verification", first), ("saturated", second)])
    assert both.verdict == "falsified" and len(both.claims) == 2 * len(first.claims)
    md = render_markdown(both.data, {stem: f"figures/{stem}.png" for stem in (*first.figures, *second.figures)})
    headings = [line for line in md.splitlines() if line.startswith("## ")]
    assert headings[:3] == [f"## Verification of `{problem.name}`"] * 2 + ["## Claims"]
    assert "clips the applied commands (v, ω, ϖ)" in md
    assert "[counterexamples/saturated~min_dwell.json](counterexamples/saturated~min_dwell.json)" in md
    assert "figures/saturated_counterexample_min_dwell.png" in md and "figures/verification_robustness.png" in md


ZERO_BAND_COMFORT = '''
"""The zero-band thermostat with its comfort requirement only: the runs stay comfortable, but both guards
hold at the setpoint, so a reset re-triggers its own guard (an instantaneous cycle the checks find)."""
import importlib.util

spec = importlib.util.spec_from_file_location("thermostat_example", {path!r})
example = importlib.util.module_from_spec(spec)
spec.loader.exec_module(example)

from analysis.verify.problems import hybrid_problem
from analysis.verify.verification import Parameter
from hybrid import Box

problem = hybrid_problem(
    name="zero-band-comfort", system=example._builder(0.0),
    initial={{"T": Parameter(name="T0", low=19.9, high=20.1, nominal=20.0, unit="°C")}},
    parameters=(Parameter(name="rate", low=0.05, high=0.2, nominal=0.1, unit="1/s"),),
    initial_mode=example._initial_mode, horizon=example.HORIZON_S, sample_period=0.25,
    requirements=example.REQUIREMENTS[:1], check_box=Box(bounds={{"T": (15.0, 25.0)}}))
'''


def test_structural_errors_fail_the_report_even_when_every_requirement_holds(tmp_path, capsys):
    """A problem whose checks find re-checked errors is not "not falsified, exit 0": the verdict is
    ``structural_error``, the exit code 1, and the summary line at the top of report.md names the errors."""
    source = tmp_path / "zero_band_comfort.py"
    source.write_text(ZERO_BAND_COMFORT.format(path=str(ROOT / THERMOSTAT)))
    out = tmp_path / "report"
    code = main(["report", "--problem", f"{source}:problem", "--out", str(out), "--quick", "--budget", str(BUDGET),
                 "--json"])
    summary = json.loads(capsys.readouterr().out)
    data = json.loads((out / "report.json").read_text())
    # no run violates comfort (the runs that end in the Zeno cycle leave it undecided: incomplete, never a pass)
    assert data["verification"]["verdict"] in ("not_falsified", "incomplete")
    errors = [f for f in data["structure"]["findings"] if f["severity"] == "error"]
    assert errors and {f["kind"] for f in errors} == {"reset_retriggers"}
    assert data["structural_errors"] == {"count": len(errors), "kinds": ["reset_retriggers"],
                                         "sections": ["structure"]}
    assert data["verdict"] == "structural_error" and data["exit_code"] == 1
    assert code == 1 and summary["verdict"] == "structural_error" and summary["exit_code"] == 1
    md = (out / "report.md").read_text()
    first = next(line for line in md.splitlines() if line.startswith("Overall verdict:"))
    assert md.index(first) < md.index("## Claims")  # the summary line at the top
    assert first.startswith(f"Overall verdict: STRUCTURAL ERROR (exit code 1); the structural checks found "
                            f"{len(errors)} error(s) (reset_retriggers; section \"Structural checks\")")
    # the human summary of the command says it too
    assert main(["report", "--problem", f"{source}:problem", "--out", str(out), "--quick",
                 "--budget", str(BUDGET)]) == 1
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("visnav report zero-band-comfort (quick): STRUCTURAL ERROR; ")
    assert any(line.strip().startswith(f"structural     {len(errors)} error(s): reset_retriggers")
               for line in printed)


def test_a_falsified_problem_keeps_its_verdict_and_names_its_structural_errors(zero_band):
    _, report = zero_band
    data = report.data
    assert data["verdict"] == "falsified" and data["exit_code"] == 1
    assert data["structural_errors"]["count"] >= 1 and data["structural_errors"]["kinds"] == ["reset_retriggers"]
    md, _ = _documents(report)
    assert "Overall verdict: FALSIFIED (exit code 1); the structural checks found" in md


NEVER_REACHED = USER_PROBLEM.replace(
    'requirements=(Requirement(name="positive", formula="always[0, 3] (x > 0)", description="x stays positive"),\n'
    '                  Requirement(name="bounded", formula="always[0, 3] (x <= 1.5)", description="x stays below 1.5")))',
    'requirements=(Requirement(name="settles", formula="eventually[0, 3] (x <= 0.01)", description="x settles"),))')


def test_an_eventually_never_reached_says_so_and_where_it_came_closest(tmp_path):
    """``eventually[0, 3] x <= 0.01`` on x' = -x, x0 in [0.5, 2]: x(t) = x0 e^-t >= 0.5 e^-3 = 0.0249 > 0.01, never
    reached; it comes closest at the window's end, t = 3, where ``0.01 - x`` = 0.01 - x0 e^-3 (closed form)."""
    assert "settles" in NEVER_REACHED
    path = tmp_path / "settle.py"
    path.write_text(textwrap.dedent(NEVER_REACHED))
    problem = load_problem(f"{path}:problem")
    report = build_problem_report(problem, spec=f"{path}:problem", seed=0, budget=BUDGET, quick=True)
    row = {r["name"]: r for r in report.data["verification"]["requirements"]}["settles"]
    cx = row["counterexample"]
    assert row["verdict"] == "falsified" and cx["window"] == [0.0, 3.0] and cx["time"] == 3.0
    x0 = cx["point"]["x0"]
    # the report rounds to 6 significant digits (half a unit: 5e-8 at 0.0398), RK45 at rtol 1e-10 adds < 1e-9
    assert abs(cx["atom_value"] - (0.01 - x0 * __import__("math").exp(-3.0))) < 6e-8
    assert row["evidence"].startswith("never reached within [0, 3] s; closest at t = 3 s by `(x <= 0.01)` = ")
    assert "violated at t" not in row["evidence"]
    claim = next(c for c in report.data["claims"] if c["status"] == "measured" and "settles" in c["text"])
    assert "never reached within [0, 3] s; closest at t = 3 s" in claim["text"]
    ax = report.figures["verification_counterexample_settles"].axes[0]
    (mark,) = [line for line in ax.get_lines() if line.get_color() == "tab:red"]
    assert str(mark.get_label()).startswith("never reached within [0, 3] s; closest at t = 3 s")

