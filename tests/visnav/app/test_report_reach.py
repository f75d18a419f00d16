"""The sampled loop's reachability proof in the report: data (rounded outward), claims and the row beside
the SOS bounds.

The proof itself (minutes of flowpipe) runs in the committed full report (``test_report_committed.py``)
and in ``tests/visnav/studies/test_path_following_reach.py``; here its result is read from the committed
``reports/paper/report.json`` or given (a study result with chosen numbers) and the report's own code is
checked: the rounding direction, the claims' statuses and words, the rendered lines.
"""

from __future__ import annotations

import copy
import json
import math
from collections import defaultdict
from decimal import Decimal
from pathlib import Path

import pytest

import visnav.studies.path_following_reach as study
from visnav.app.report_reach import bypass_reach_data
from visnav.app.report_render import render_markdown
from visnav.scenario import load_scenario

COMMITTED = Path(__file__).resolve().parents[3] / "reports" / "paper"


def _result(status: str, bound: float, margin: float) -> study.BypassReach:
    return study.BypassReach(
        k=4.0, v_mps=0.2, d_zero_m=0.5, period_s=0.05, radius_m=(1.3519847302919699, 1.4496007589520032),
        entry_box={"delta_m": (-0.21130000000000002, -0.1951), "alpha_rad": (-0.7922, -0.21179999999999999)},
        coverage={"claim": "measured", "entries": 37, "inside": 37, "samples": 40, "seed": 0,
                  "longest_bypass_s": 31.600000000000005, "unfinished_bypasses": 0},
        horizon_s=31.600000000000005, status=status, margin_m=margin, delta_bound_m=bound,
        evidence="reachability: raw text 0.180413", time_step_s=0.0249999995, segments=2530, jumps=632, seconds=12.5)


def test_the_proven_bound_is_rounded_up_and_the_margin_down(monkeypatch):
    monkeypatch.setattr(study, "bypass_reach", lambda scenario, samples, seed: _result("proven", 0.31958691214810464,
                                                                                       0.1804130878518954))
    data, claims = bypass_reach_data(load_scenario("paper"), samples=40, seed=0, run=True)
    assert data["delta_bound_m"] == 0.3196 and Decimal(repr(data["delta_bound_m"])) >= Decimal(0.31958691214810464)
    assert data["margin_m"] == 0.1804 and Decimal(repr(data["margin_m"])) <= Decimal(0.1804130878518954)
    assert data["horizon_s"] == 31.6 and data["entry_box"]["alpha_rad"] == [-0.7922, -0.2118]
    assert "evidence" not in data and "seconds" not in data  # raw floats and the wall clock stay out of the report
    assert [c.status for c in claims] == ["proven", "sampled"]
    assert "|delta| <= 0.3196 m over [0, 31.6] s after entry" in claims[0].text
    assert "re-checked independently" in claims[0].text
    assert "R in [1.352, 1.449] m" in claims[0].text  # the radii inward: never more than proven
    assert "37/37 entries measured in 40 campaign draws" in claims[1].text
    assert "not a proof of coverage" in claims[1].text


def test_a_proof_that_did_not_hold_is_never_claimed_proven(monkeypatch):
    monkeypatch.setattr(study, "bypass_reach", lambda scenario, samples, seed: _result("not proven", math.nan,
                                                                                       math.nan))
    data, claims = bypass_reach_data(load_scenario("paper"), samples=40, seed=0, run=True)
    assert data["status"] == "not proven"
    assert [c.status for c in claims] == ["measured", "sampled"]
    assert claims[0].text.startswith("NOT PROVEN")


def test_the_quick_report_leaves_the_proof_out_and_says_so(monkeypatch):
    def boom(*_, **__):
        raise AssertionError("the quick report must not run the flowpipe")

    monkeypatch.setattr(study, "bypass_reach", boom)
    data, claims = bypass_reach_data(load_scenario("paper"), samples=6, seed=0, run=False)
    assert data["status"] == "not run" and claims == []


@pytest.fixture(scope="module")
def committed():
    return json.loads((COMMITTED / "report.json").read_text())


def _lines(data):
    return render_markdown(data, defaultdict(lambda: "figure.png")).splitlines()  # figures are not checked here


def test_the_committed_report_shows_the_proven_set_beside_the_sos_bound(committed):
    reach = committed["analysis"]["path_following"]["bypass_reach"]
    assert reach["status"] == "proven" and reach["delta_bound_m"] < reach["d_zero_m"]
    assert reach["coverage"]["inside"] == reach["coverage"]["entries"] == 37
    lines = _lines(committed)
    table = [i for i, line in enumerate(lines) if "| all sets (claimed) |" in line]
    assert table, "the SOS bounds' table is missing"
    row = lines[table[0] + 1]  # the sampled loop's row right under the SOS sets' bound
    assert row.startswith(f"| [{reach['entry_box']['alpha_rad'][0]:.6g}, {reach['entry_box']['alpha_rad'][1]:.6g}] "
                          f"| sampled loop, flowpipe over 31.6 s (re-checked) | {reach['delta_bound_m']:.6g} |")
    text = "\n".join(lines)
    assert "**proven, re-checked**" in text
    assert "37/37 measured entries (a sample of the campaign, not a proof of coverage)" in text
    assert ("The SOS rows bound the continuous loop for all time from one entry angle; the flowpipe bounds the "
            "sampled loop over a finite window from a range of entry angles.") in text
    claims = [c for c in committed["claims"] if c["text"].startswith("the sampled path-following loop")]
    assert [c["status"] for c in claims] == ["proven"]


@pytest.mark.parametrize("status", ["not proven", "not run"])
def test_without_a_proof_there_is_no_row_and_the_paragraph_says_why(committed, status):
    data = copy.deepcopy(committed)
    reach = data["analysis"]["path_following"]["bypass_reach"]
    if status == "not run":
        data["analysis"]["path_following"]["bypass_reach"] = {"status": "not run", "why": "quick report"}
    else:
        reach.update(status="not proven", delta_bound_m=None, margin_m=None)
    text = "\n".join(_lines(data))
    assert "sampled loop, flowpipe over" not in text
    assert ("**NOT PROVEN**" in text) if status == "not proven" else ("not run (quick report)" in text)
    assert "proven, re-checked" not in text
