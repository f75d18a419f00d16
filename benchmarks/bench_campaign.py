"""Throughput of a Monte-Carlo campaign: scenarios per second with 1 and 2 workers and on Dask.

Run: ``python benchmarks/bench_campaign.py [--samples 1000] [--scenario paper] [--repeat 1]``.

Runs the same campaign (``visnav sweep``'s default distributions around the
scenario) on a process pool of 1 worker, a process pool of 2 workers and a Dask
``LocalCluster`` of 2 single-threaded worker processes, and prints for each the
scenarios per second (median over ``--repeat`` runs), measured from the first
submission to the last result, the executor already started (its start-up time
is printed beside it), and the speed-up from 1 to 2 workers.  Beside each rate: the
CPU time the workers used per scenario and the number of cores they kept busy
(``/proc``), which tells a saturated machine from a scaling problem.  Both pools use
the executor settings of ``visnav sweep`` (forkserver, workers ignoring
SIGINT).  It also checks that the three executors return identical results,
and exits 1 if they do not.

The rates are only meaningful on an otherwise idle machine with at least two
cores: the speed-up can be no better than the number of cores left free.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import os
import statistics
import sys
import time
from collections import Counter

from analysis.campaigns import campaign_executor
from visnav.studies.campaign import CampaignSpec, process_pool, run_campaign
from visnav.scenario import load_scenario


def _pid_after(delay: float) -> int:
    time.sleep(delay)
    return os.getpid()


def _cpu_seconds(pids: set[int]) -> float:
    """User + system CPU time of the processes ``pids`` (Linux ``/proc``; 0 elsewhere)."""
    total = 0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as handle:
                fields = handle.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15 of stat)
    return total / os.sysconf("SC_CLK_TCK")


def timed(spec: CampaignSpec, make, workers: int) -> tuple[float, float, float, list]:
    """(scenarios/s, start-up s, worker CPU s per scenario, results sorted by index) on a fresh executor."""
    start = time.perf_counter()
    with make() as executor:
        # start every worker (imports done) before timing, and learn their process ids
        pids = {f.result() for f in [executor.submit(_pid_after, 0.3) for _ in range(workers)]}
        ready = time.perf_counter()
        cpu0 = _cpu_seconds(pids)
        results: list = []
        run_campaign(spec, executor, results.append, window=2 * workers)
        wall = time.perf_counter() - ready
        cpu = _cpu_seconds(pids) - cpu0
    return spec.samples / wall, ready - start, cpu / spec.samples, sorted(results, key=lambda r: r.index)


def pool(workers: int):
    return lambda: process_pool(workers)


class _Dask:
    def __init__(self, workers: int) -> None:
        self.workers = workers

    def __call__(self):
        return self

    def __enter__(self) -> cf.Executor:
        self._context = campaign_executor(dask_local=self.workers)
        return self._context.__enter__().executor

    def __exit__(self, *exc) -> None:
        self._context.__exit__(*exc)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1000, help="scenarios per campaign (default: 1000)")
    parser.add_argument("--scenario", default="paper")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeat", type=int, default=1, help="runs per executor; the median is printed")
    args = parser.parse_args()
    spec = CampaignSpec(scenario=load_scenario(args.scenario), samples=args.samples, seed=args.seed)
    configs = [
        ("process pool, 1 worker ", pool(1), 1),
        ("process pool, 2 workers", pool(2), 2),
        ("dask LocalCluster, 2 workers", _Dask(2), 2),
    ]
    print(f"campaign: scenario {spec.scenario.name}, {spec.samples} samples, seed {spec.seed}; "
          f"{os.cpu_count()} CPUs seen, load average {os.getloadavg()[0]:.2f} at start")
    rates: dict[str, float] = {}
    reference = None
    identical = True
    for name, make, workers in configs:
        runs = [timed(spec, make, workers) for _ in range(args.repeat)]
        rate = statistics.median(r[0] for r in runs)
        rates[name] = rate
        for *_, results in runs:
            if reference is None:
                reference = results
            identical &= results == reference
        spread = f" (min {min(r[0] for r in runs):.2f}, max {max(r[0] for r in runs):.2f})" if args.repeat > 1 else ""
        cpu = statistics.median(r[2] for r in runs)
        print(f"  {name:<29}: {rate:7.2f} scenarios/s{spread}, {spec.samples / rate:6.1f} s; "
              f"start-up {statistics.median(r[1] for r in runs):.2f} s (not counted); worker CPU "
              f"{cpu * 1e3:.0f} ms/scenario, {cpu * rate:.2f} cores busy", flush=True)
    outcomes = Counter(r.outcome for r in reference or [])
    speedup = rates["process pool, 2 workers"] / rates["process pool, 1 worker "]
    print(f"  speed-up 1 -> 2 workers (process pool): {speedup:.2f}x ({100 * speedup / 2:.0f} % parallel efficiency)")
    print(f"  dask / process pool at 2 workers: {rates['dask LocalCluster, 2 workers'] / rates['process pool, 2 workers']:.2f}")
    print(f"  outcomes: {', '.join(f'{k} {v}' for k, v in sorted(outcomes.items()))}; "
          f"identical results on the three executors: {'yes' if identical else 'NO'}")
    print(f"  load average at the end {os.getloadavg()[0]:.2f}")
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
