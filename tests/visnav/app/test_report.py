"""`visnav report`: reproducible, self-contained, claims marked, verdict first, bad input refused; the HTML in a browser."""

from __future__ import annotations

import json
import os
import shutil

import pytest

from visnav.app.cli import main
from visnav.app.report import CLAIM_STATUSES, Claim, ReportOptions, dependency_versions


@pytest.fixture(scope="module")
def quick_dirs(tmp_path_factory, report_tools):
    """The quick report written twice, by two processes with different string hashing and BLAS threads."""
    dirs = []
    for seed, threads in (("1", "2"), ("2", None)):
        out = tmp_path_factory.mktemp(f"quick{seed}")
        done = report_tools.run(out, "--quick", hashseed=seed, blas_threads=threads)
        report_tools.exit_is_the_verdicts(done, out)
        dirs.append(out)
    return dirs


def test_quick_report_is_byte_identical_across_processes(quick_dirs, report_tools):
    """report.json and report.md are byte-identical; so is every figure but the wall-time Pareto front."""
    a, b = quick_dirs
    for name in ("report.json", "report.md"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert report_tools.counterexamples(a) == report_tools.counterexamples(b)
    for png in sorted((a / "figures").glob("*.png")):
        if png.name != "stiffness_error_vs_time.png":  # plots measured wall-clock times
            assert png.read_bytes() == (b / "figures" / png.name).read_bytes(), png.name


def test_report_contents_and_claims(quick_dirs):
    out = quick_dirs[0]
    data = json.loads((out / "report.json").read_text())
    assert data["sections"][:4] == ["verification", "model", "simulation", "analysis"]
    assert data["verdict"] == data["verification"]["verdict"]
    assert data["meta"]["budgets"]["verify_budget"] == ReportOptions.for_mode(quick=True).verify_budget
    for row in data["verification"]["requirements"]:  # every counterexample linked is next to the report
        assert row["counterexample_file"] is None or (out / row["counterexample_file"]).is_file()
    assert data["meta"]["versions"] == dependency_versions()
    assert len(data["meta"]["scenario_digest"]) == 64 and len(data["meta"]["automaton_digest"]) == 64
    statuses = {c["status"] for c in data["claims"]}
    assert statuses <= set(CLAIM_STATUSES) and "proven" in statuses and "sampled" in statuses
    assert sum(data["claim_counts"].values()) == len(data["claims"])
    comparison = {row["quantity"]: row for row in data["simulation"]["paper_comparison"]}
    assert comparison["max_reconstruction_error_px"]["ours"] < comparison["max_reconstruction_error_px"]["paper"]
    # every figure the documents refer to exists, and the Markdown links them relatively
    md = (out / "report.md").read_text()
    assert md.index("## Verification of") < md.index("## Claims") < md.index("## Model")
    for stem in (data["verification"]["figures"] + data["simulation"]["figures"] + data["analysis"]["figures"]
                 + ["mode_graph"]):
        assert (out / "figures" / f"{stem}.png").is_file()
        assert f"(figures/{stem}.png)" in md
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") == len(list((out / "figures").glob("*.png")))
    assert "<script" not in html and "http://" not in html and "https://" not in html
    # the structural checks: decided by the SMT solver, one PROVEN claim per check, the cycles grouped
    checks = data["model"]["structural_checks"]
    assert {c["status"] for c in checks["claims"].values()} == {"proven"} and checks["method"] == "auto"
    model_claims = [c for c in data["claims"] if c["section"] == "model"]
    assert [c["status"] for c in model_claims] == ["proven"] * 6  # graph checks, then one per check
    assert [c["text"].split(" of ")[0] for c in model_claims[1:]] == [
        "nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers", "zeno"]
    assert set(checks["claims"]) == {c["text"].split(" of ")[0] for c in model_claims[1:]}
    assert "43 pairs of transitions sharing a source mode: 29 can be enabled together" in model_claims[1]["text"]
    assert "| nondeterminism | PROVEN | z3" in md and "| zeno | PROVEN |" in md
    (zeno,) = [line for line in md.splitlines() if line.startswith("Zeno: ")]  # the cycles in one line
    assert "non-Zeno (proven), smallest dwell bound 0.05 s in LEAVE|CLEAR" in zeno
    assert sum(f["kind"] == "zeno_candidate" for f in checks["findings"]) <= 1  # never one row per cycle
    assert checks["zeno"]["cycles"] > 100 and "verdicts" not in checks["zeno"]
    # the model's structural findings: counts and the worst few visible, the full list collapsed
    findings = data["model"]["structural_checks"]["findings"]
    if len(findings) > len(data["model"]["structural_checks"]["summary"]["worst"]):
        assert f"<summary>All {len(findings)} findings</summary>" in html and "<details>" in md


def test_claims_need_a_known_status():
    with pytest.raises(ValueError, match="Claim.status = 'likely'"):
        Claim(text="x", status="likely", section="model")
    with pytest.raises(ValueError, match="check_samples = 0"):
        ReportOptions(check_samples=0)
    with pytest.raises(ValueError, match="verify_budget = 0"):
        ReportOptions(verify_budget=0)
    assert ReportOptions.for_mode(quick=True, verify_budget=5).verify_budget == 5


def test_markdown_escapes_table_pipes(quick_dirs):
    text = (quick_dirs[0] / "report.md").read_text()
    rows = [line for line in text.splitlines() if line.startswith("|") and 'mode == "*' in line]
    assert rows  # the formula table: mode patterns such as "*|RELEASE" hold a pipe
    for line in rows:
        assert '"*\\|' in line and '"*|' not in line


def test_unknown_scenario_and_unwritable_folder_are_clear_errors(tmp_path, capsys):
    assert main(["report", "--scenario", "no-such-scenario", "--out", str(tmp_path / "x")]) == 2
    assert "no-such-scenario" in capsys.readouterr().err
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert main(["report", "--quick", "--out", str(blocker / "sub")]) == 2
    assert str(blocker) in capsys.readouterr().err


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def test_html_report_renders_in_headless_chromium(quick_dirs):
    """Open report.html in headless Chromium: every figure decodes, no console error, no failed request."""
    if CHROMIUM is None:
        if os.environ.get("VISNAV_REQUIRE_BROWSER"):
            pytest.fail("VISNAV_REQUIRE_BROWSER is set but chromium is not installed (apt-get install chromium)")
        pytest.skip("chromium not installed (apt-get install chromium; .ci/run installs it and requires this test)")
    from playwright.sync_api import sync_playwright

    page_file = quick_dirs[0] / "report.html"
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=[
            "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
            "--disable-sync", "--no-first-run"])
        try:
            page = browser.new_page()
            problems: list[str] = []
            page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type in (
                "error", "warning") else None)
            page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
            page.on("requestfailed", lambda r: problems.append(f"request failed: {r.url[:80]}"))
            page.goto(page_file.as_uri(), wait_until="load")
            images = page.evaluate(
                "Array.from(document.images).map(i => [i.complete, i.naturalWidth, i.naturalHeight, i.alt])")
            heading = page.inner_text("h1")
        finally:
            browser.close()
    assert problems == []
    assert len(images) == len(list((quick_dirs[0] / "figures").glob("*.png"))) >= 9
    for complete, width, height, alt in images:
        assert complete and width > 100 and height > 100, alt
    assert "Verification report" in heading
