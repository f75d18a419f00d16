"""Long soundness runs of ``reach_soundness.py`` (issue 27: 10,000 executor runs per benchmark), resumable.

Run: ``PYTHONPATH=$PWD nice -n 10 .venv/bin/python benchmarks/reach_soundness_long.py --only SRNA01 --runs 10000
--results soundness.jsonl [--closed-form] [--chunk 100] [--workers 2]``.

Per instance: the flowpipe (:func:`analysis.reach.reach` with the instance's options, as ``bench_reach.py``), then
the ``--runs`` seeded executor runs of :func:`reach_soundness.starts` (the seed of ``bench_reach.py``:
the sum of the name's character codes, so run ``i`` is the same run whatever the chunking), in chunks of ``--chunk``
runs, the instances interleaved (chunk 0 of each, then chunk 1, ...: an interrupted run has figures for all).  Each chunk's step points are checked against the flowpipe by :func:`reach_soundness.outside_points` (the
membership tests of ``reach_soundness.py``, unchanged; the random directions seeded by the instance's seed and the
chunk's index) and give one JSON line appended to ``--results`` (one ``os.write`` of the whole line, then
``fsync``): instance, chunk, first run, runs, step points, points outside, the first point outside, the seconds.
A restart with the same arguments reads the file and skips the chunks already recorded (a torn last line is
ignored and redone), so an interrupted run resumes where it stopped.  ``--workers 2`` simulates the chunks in
two forked processes (the checks stay in the parent, in chunk order).  The totals per instance are printed.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import multiprocessing
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import numpy as np  # noqa: E402

import reach_instances as ri  # noqa: E402  (benchmarks/ is not a package)
from reach_soundness import example, outside_points, run_points, starts  # noqa: E402

_WORKER: dict[str, Any] = {}


def _simulate(args: tuple[str, bool, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    name, closed_form, initial = args
    if _WORKER.get("name") != name:
        _WORKER.update(name=name, instance=ri.BUILDERS[name]())
    start = time.perf_counter()
    times, modes, points = run_points(_WORKER["instance"], initial, closed_form)
    return times, modes, points, time.perf_counter() - start


def recorded(path: Path, key: dict[str, Any]) -> dict[int, dict[str, Any]]:
    """The chunks of ``path`` whose settings equal ``key``, by chunk index (torn or foreign lines are skipped)."""
    done: dict[int, dict[str, Any]] = {}
    if not path.exists():
        return done
    for line in path.read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(rec, dict) and all(rec.get(k) == v for k, v in key.items()):
            done[int(rec["chunk"])] = rec
    return done


def append(path: Path, record: dict[str, Any]) -> None:
    """One JSON line, written by one ``os.write`` and synced (a line is either whole or torn at the end)."""
    data = (json.dumps(record, sort_keys=True) + "\n").encode()
    fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        size = os.fstat(fd).st_size
        if size and os.pread(fd, 1, size - 1) != b"\n":  # a torn last line stays on its own line
            data = b"\n" + data
        os.write(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)


@dataclass(kw_only=True, slots=True)
class _Plan:
    name: str
    seed: int
    key: dict[str, Any]
    chunks: list[np.ndarray]
    done: dict[int, dict[str, Any]]
    result: Any = None
    reach_seconds: float = 0.0


def _plan(name: str, runs: int, chunk: int, path: Path, closed_form: bool) -> _Plan:
    instance = ri.BUILDERS[name]()
    seed = sum(map(ord, name))
    key = {"instance": name, "seed": seed, "chunk_runs": chunk, "closed_form": closed_form}
    initial = starts(instance, runs, seed)
    chunks = [initial[k * chunk:(k + 1) * chunk] for k in range((len(initial) + chunk - 1) // chunk)]
    return _Plan(name=name, seed=seed, key=key, chunks=chunks, done=recorded(path, key))


def _flowpipe(plan: _Plan) -> None:
    from analysis.reach import reach

    instance = ri.BUILDERS[plan.name]()
    start = time.perf_counter()
    plan.result = reach(instance.system, instance.box, initial_mode=instance.initial_mode, **instance.options)
    plan.reach_seconds = time.perf_counter() - start
    if plan.result.status != "complete":
        raise SystemExit(f"{plan.name}: the flowpipe is {plan.result.status}: no soundness check")


def run_all(names: list[str], *, runs: int, chunk: int, path: Path, closed_form: bool, workers: int
            ) -> list[dict[str, Any]]:
    """The chunks of every instance, interleaved (chunk 0 of each, then chunk 1, ...), resumed from ``path``;
    the totals per instance over its recorded chunks."""
    plans = [_plan(name, runs, chunk, path, closed_form) for name in names]
    todo = [(p, k) for k in range(max(len(p.chunks) for p in plans)) for p in plans
            if k < len(p.chunks) and k not in p.done]
    for plan in {id(p): p for p, _ in todo}.values():
        _flowpipe(plan)
    jobs = [(p.name, closed_form, p.chunks[k]) for p, k in todo]
    if workers > 1:
        pool = concurrent.futures.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"))
        outputs = pool.map(_simulate, jobs)
    else:
        pool, outputs = None, map(_simulate, jobs)
    try:
        for (p, k), (times, modes, points, sim_seconds) in zip(todo, outputs):
            t0 = time.perf_counter()
            missing = outside_points(p.result, times, modes, points, np.random.default_rng([p.seed + 1, k]))
            rec = dict(p.key, chunk=k, first_run=k * chunk, runs=len(p.chunks[k]), points=int(times.size),
                       outside=int(missing.size), example=example(times, modes, points, missing),
                       simulate_seconds=round(sim_seconds, 3), check_seconds=round(time.perf_counter() - t0, 3),
                       reach_seconds=round(p.reach_seconds, 3), unix_time=round(time.time(), 1))
            append(path, rec)
            p.done[k] = rec
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    return [_totals(p, closed_form) for p in plans]


def _totals(p: _Plan, closed_form: bool) -> dict[str, Any]:
    recs = [p.done[k] for k in sorted(p.done) if k < len(p.chunks)]
    return {"instance": p.name, "closed_form": closed_form, "runs": sum(r["runs"] for r in recs),
            "points": sum(r["points"] for r in recs), "outside": sum(r["outside"] for r in recs),
            "first_outside": next((r["example"] for r in recs if r["example"]), None),
            "simulate_seconds": round(sum(r["simulate_seconds"] for r in recs), 1),
            "check_seconds": round(sum(r["check_seconds"] for r in recs), 1)}


def agreement(name: str, count: int) -> dict[str, Any]:
    """The closed form against RK45 on the first ``count`` runs: the largest difference of the closed form's states
    (its exact solution, :meth:`hybrid.continuous.HybridTrajectory.sample`) at RK45's step points away from the jumps,
    relative to ``max(1, |x|)``; the largest jump-time difference [s]; whether the jump sequences have the same
    modes; the modes the closed form reads as affine (:func:`hybrid.closed_form.affine_flow`, with the route) and
    the seconds per run of each."""
    from hybrid.closed_form import affine_flow
    from hybrid.continuous import simulate_continuous

    instance = ri.BUILDERS[name]()
    system = instance.system
    routes = {m: (lambda a: None if a is None else a.route[0])(affine_flow(f, system.dimension, {}))
              for m, f in system.flows.items()}
    kwargs = dict(instance.simulation)
    duration = kwargs.pop("duration")
    worst, worst_event, same_modes, seconds = 0.0, 0.0, True, {"rk45": 0.0, "closed_form": 0.0}
    for x0 in starts(instance, count, sum(map(ord, name))):
        runs = {}
        for label, closed in (("rk45", False), ("closed_form", True)):
            start = time.perf_counter()
            runs[label] = simulate_continuous(system, tuple(x0), duration=duration, rtol=1e-10, atol=1e-12,
                                              initial_mode=instance.initial_mode, closed_form=closed, **kwargs)
            seconds[label] += time.perf_counter() - start
        rk, cf = runs["rk45"], runs["closed_form"]
        same_modes &= [e.target for e in rk.events] == [e.target for e in cf.events]
        if rk.event_times.size == cf.event_times.size and rk.event_times.size:
            worst_event = max(worst_event, float(np.max(np.abs(rk.event_times - cf.event_times))))
        jumps = np.concatenate([rk.event_times, cf.event_times])
        t = rk.times
        keep = np.all(np.abs(t[:, None] - jumps[None, :]) > 1e-6, axis=1) if jumps.size else np.ones(t.size, bool)
        exact, _ = cf.sample(t[keep])
        worst = max(worst, float(np.max(np.abs(exact - rk.states[keep]) / np.maximum(1.0, np.abs(exact)))))
    return {"instance": name, "runs": count, "routes": routes, "max_relative_difference": worst,
            "max_event_time_difference": worst_event, "same_jump_modes": bool(same_modes),
            "seconds_per_run": {k: round(v / count, 3) for k, v in seconds.items()}}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", action="append", required=True, choices=list(ri.BUILDERS),
                        help="run this instance (repeatable)")
    parser.add_argument("--runs", type=int, default=10_000, help="executor runs per instance")
    parser.add_argument("--chunk", type=int, default=100, help="runs per recorded chunk")
    parser.add_argument("--results", type=Path, help="JSON-lines file (appended, resumed)")
    parser.add_argument("--closed-form", action="store_true", help="the executor's closed form of affine modes")
    parser.add_argument("--workers", type=int, default=1, choices=(1, 2), help="simulating processes")
    parser.add_argument("--agreement", type=int, default=0, metavar="N",
                        help="only compare the closed form with RK45 on the first N runs (no flowpipe)")
    args = parser.parse_args(argv)
    if args.agreement > 0:
        for name in args.only:
            print(json.dumps(agreement(name, args.agreement), sort_keys=True), flush=True)
        return 0
    if args.runs < 1 or args.chunk < 1:
        parser.error(f"--runs and --chunk must be positive integers, got {args.runs} and {args.chunk}")
    if args.results is None:
        parser.error("--results PATH is required (the JSON-lines file of the chunks)")
    total = 0
    for summary in run_all(args.only, runs=args.runs, chunk=args.chunk, path=args.results,
                           closed_form=args.closed_form, workers=args.workers):
        print(json.dumps(summary, sort_keys=True), flush=True)
        total += summary["outside"]
    return 1 if total else 0


if __name__ == "__main__":
    raise SystemExit(main())
