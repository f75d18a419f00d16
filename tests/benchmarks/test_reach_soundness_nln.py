"""``benchmarks/reach_soundness_nln.py``: executor runs of the NLN instances against their flowpipes (a quick subset;
the 10,000-run figures are in docs/reachability.md).  The runs are hybrid's executor (RK45), not reachability code;
a flowpipe that misses what the runs reach is caught (a shrunk segment)."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import reach_nln  # noqa: E402
import reach_soundness_nln as rsn  # noqa: E402

LOVO = next(i for i in reach_nln.INSTANCES if i["name"].startswith("LOVO"))


def test_every_step_point_of_seeded_runs_is_inside_the_flowpipe():
    row = rsn.check(LOVO, 24, seed=3)
    assert row["runs"] == 24 and row["points"] > 24 * 100 and row["outside"] == 0, row


def test_a_shrunk_flowpipe_is_caught(monkeypatch):
    from analysis.reach import reach as real_reach

    def shrunk(*args, **kwargs):  # every segment's box pulled in by 1e-3 around its centre: the runs leave it
        result = real_reach(*args, **kwargs)
        segments = [replace(s, lo=s.lo + 1e-3 * (s.hi > s.lo + 2e-3), hi=s.hi - 1e-3 * (s.hi > s.lo + 2e-3))
                    for s in result.segments]
        return replace(result, segments=tuple(segments))

    monkeypatch.setattr("analysis.reach.reach", shrunk)
    row = rsn.check(LOVO, 8, seed=3)
    assert row["outside"] > 0 and row["example"] is not None and np.isfinite(row["example"]["t"]), row
