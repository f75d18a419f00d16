"""Soundness of the nonlinear (NLN) flowpipes against the executor: issue 27's 10,000 runs for VDP and LOVO.

For each instance of :data:`reach_nln.INSTANCES`: the flowpipe of every piece of the benchmark's split (the
options of the verdict, adaptive steps included), then ``--runs`` seeded executor runs
(:func:`hybrid.continuous.simulate_continuous`, RK45 with ``rtol 1e-10``, ``atol 1e-12``) from the corners of the
initial box and uniform points in it (:func:`reach_soundness.starts`); each run is checked against the piece that
holds its start, every step point inside a segment whose time interval holds it
(:func:`reach_soundness.outside_points`: the segment's box and its zonotope in sampled directions, to ``1e-6``
relative).  No reachability code computes the runs.

Run: ``PYTHONPATH=$PWD .venv/bin/python benchmarks/reach_soundness_nln.py [--runs N] [--seed S] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

import reach_nln  # noqa: E402  (benchmarks/ is not a package)
from reach_soundness import outside_points, run_points, starts  # noqa: E402


def _piece_of(pieces: list[dict[str, tuple[float, float]]], names: tuple[str, ...], x0: np.ndarray) -> int:
    for k, piece in enumerate(pieces):
        if all(piece[s][0] <= v <= piece[s][1] for s, v in zip(names, x0)):
            return k
    raise AssertionError(f"start {x0} in no piece of the split")


def check(instance: dict[str, Any], runs: int, seed: int) -> dict[str, Any]:
    """``{"name", "runs", "points", "outside", "example", "simulate_s", "reach_s"}`` for one instance."""
    from analysis.reach import reach
    from analysis.reach.split import split_box

    system, box, kwargs, requirement = instance["build"]()
    pieces = list(split_box(box, kwargs.get("splits") or {}))
    start = time.process_time()
    results = [reach(system, p, horizon=requirement.end, time_step=kwargs["time_step"], **(kwargs.get("engine") or {}))
               for p in pieces]
    reach_s = time.process_time() - start
    names = system.state_names
    case = SimpleNamespace(system=system, box=box, initial_mode=None, simulation={"duration": requirement.end})
    initial = starts(case, runs, seed)
    owner = np.array([_piece_of(pieces, names, x0) for x0 in initial])
    points = outside = 0
    first = None
    start = time.process_time()
    for k, result in enumerate(results):
        assert result.status == "complete", result.terminations
        mine = initial[owner == k]
        if not mine.size:
            continue
        times, modes, states = run_points(case, mine)
        missing = outside_points(result, times, modes, states, np.random.default_rng(seed + 1 + k))
        points += int(times.size)
        outside += int(missing.size)
        if missing.size and first is None:
            i = int(missing[0])
            first = {"piece": k, "t": float(times[i]), "x": [float(v) for v in states[i]]}
    return {"name": instance["name"], "runs": int(len(initial)), "points": points, "outside": outside,
            "example": first, "simulate_s": round(time.process_time() - start, 1), "reach_s": round(reach_s, 2)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10_000, help="executor runs per instance (default 10,000)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", action="append", default=None, help="an instance name (repeatable)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    rows = [check(i, args.runs, args.seed) for i in reach_nln.INSTANCES if not args.only or i["name"] in args.only]
    if args.json:
        print(json.dumps(rows, sort_keys=True, indent=1))
    else:
        for r in rows:
            print(f"{r['name']:28} runs {r['runs']:6d}  step points {r['points']:10,d}  outside {r['outside']}  "
                  f"(simulation {r['simulate_s']} s CPU, flowpipes {r['reach_s']} s)")
    return 0 if all(r["outside"] == 0 for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
