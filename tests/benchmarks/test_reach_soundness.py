"""``benchmarks/reach_soundness.py`` on a spacecraft instance: the closed-form route runs and finds no point outside;
a deliberately shrunken flowpipe is caught; the long runner's JSON lines resume.

The flowpipe is SRNA01's (``benchmarks/reach_instances.py``, 0.5 s).  The executor's closed form of the spacecraft's
affine modes (``hybrid.closed_form``, the ``expm`` route: the clock ``t`` makes the augmented matrix defective) costs
about 10 s per 30 min of simulated time, so the closed-form runs here stop at 30 min (still in ``P2``; every step
point is checked against the 300 min flowpipe at its time).  The shrunken flowpipe keeps every segment's times and
mode and halves its zonotope and box about their centres: the runs from the corners of the initial box (±25 m,
±0.1 m/min around the start) lie outside the halved initial sets, so the check must report points outside.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import types
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import reach_instances as ri  # noqa: E402
import reach_soundness as rs  # noqa: E402
import reach_soundness_long as rl  # noqa: E402

SEED = sum(map(ord, "SRNA01"))


@pytest.fixture(scope="module")
def srna01():
    from analysis.reach import reach

    instance = ri.srna01()
    result = reach(instance.system, instance.box, initial_mode=instance.initial_mode, **instance.options)
    assert result.status == "complete"
    return instance, result


def _shrunk(result, factor):
    from analysis.reach.zonotope import Zonotope

    segments = []
    for s in result.segments:
        mid = (s.lo + s.hi) / 2
        z = Zonotope(center=s.zonotope.center, generators=factor * s.zonotope.generators)
        segments.append(dataclasses.replace(s, zonotope=z, lo=mid - factor * (mid - s.lo),
                                            hi=mid + factor * (s.hi - mid)))
    return types.SimpleNamespace(segments=tuple(segments))


def test_closed_form_route_finds_no_point_outside(srna01):
    instance, result = srna01
    short = dataclasses.replace(instance, simulation=dict(instance.simulation, duration=30.0))
    out = rs.simulations_inside(short, result, 2, seed=SEED, closed_form=True)
    assert out["outside"] == 0, out["example"]
    assert out["runs"] == 2 and out["points"] > 100


def test_closed_form_runs_are_the_rk45_runs(srna01):
    """The same start, the two solvers: RK45's step points lie on the closed form's exact solution (its dense output,
    ``sample``) within 1e-7 relative (RK45 at rtol 1e-10 over 30 min; measured 2e-9 over 300 min), so the closed-form
    check is a check of the same runs."""
    from hybrid.continuous import simulate_continuous

    instance, _ = srna01
    x0 = tuple(rs.starts(instance, 1, SEED)[0])
    runs = [simulate_continuous(instance.system, x0, duration=30.0, rtol=1e-10, atol=1e-12,
                                initial_mode=instance.initial_mode, closed_form=c) for c in (False, True)]
    rk, cf = runs
    exact, modes = cf.sample(rk.times)
    assert list(modes) == list(rk.modes)
    assert np.max(np.abs(exact - rk.states) / np.maximum(1.0, np.abs(exact))) < 1e-7


def test_a_shrunken_flowpipe_is_caught(srna01):
    instance, result = srna01
    short = dataclasses.replace(instance, simulation=dict(instance.simulation, duration=30.0))
    initial = rs.starts(short, 2, SEED)
    times, modes, points = rs.run_points(short, initial, closed_form=True)
    assert rs.outside_points(result, times, modes, points, np.random.default_rng(1)).size == 0
    missing = rs.outside_points(_shrunk(result, 0.5), times, modes, points, np.random.default_rng(1))
    assert missing.size > 0
    first = rs.example(times, modes, points, missing)
    assert first["t"] == pytest.approx(0.0, abs=1e-9)  # the corner start itself is outside the halved initial set


def test_long_runner_records_and_resumes(tmp_path, srna01):
    """Two chunks of two runs (RK45); the second line then torn, as a kill in mid-write would leave it: a restart
    with the same arguments runs chunk 1 again (same seeds: the same runs, the same counts), writes it on a line
    of its own, and chunk 0 is not run again."""
    path = tmp_path / "s.jsonl"
    first = rl.run_all(["SRNA01"], runs=4, chunk=2, path=path, closed_form=False, workers=1)[0]
    lines = path.read_text().splitlines()
    assert len(lines) == 2 and [json.loads(x)["chunk"] for x in lines] == [0, 1]
    assert first["runs"] == 4 and first["outside"] == 0 and first["points"] > 100
    path.write_text(lines[0] + "\n" + lines[1][:40])
    again = rl.run_all(["SRNA01"], runs=4, chunk=2, path=path, closed_form=False, workers=1)[0]
    now = path.read_text().splitlines()
    assert len(now) == 3 and now[:2] == [lines[0], lines[1][:40]]
    redo, old = json.loads(now[2]), json.loads(lines[1])
    assert {k: redo[k] for k in ("chunk", "first_run", "runs", "points", "outside")} == \
        {k: old[k] for k in ("chunk", "first_run", "runs", "points", "outside")}
    assert {k: again[k] for k in ("runs", "points", "outside")} == {k: first[k] for k in ("runs", "points", "outside")}
    assert rl.run_all(["SRNA01"], runs=4, chunk=2, path=path, closed_form=False, workers=1)[0]["runs"] == 4
    assert len(path.read_text().splitlines()) == 3  # complete: nothing run or appended
