"""Throughput of the supervisor fuzzer: supervisor steps per second through hypothesis, and the CI budget.

Usage::

    python benchmarks/bench_fuzz.py [--rounds N] [--examples N] [--skip-budget]

1. **Steps per second.**  Every signal-sequence property of
   :mod:`visnav.fuzzing` runs ``--examples`` examples on the resolved automaton,
   ``--rounds`` times (interleaved); each round's rate is the supervisor
   steps checked divided by the wall time of the whole hypothesis run
   (generation, the supervisor, the checks, hypothesis' own bookkeeping).
   Printed: the median per property and the median of the overall rate.
2. **CI budget.**  The whole registry at its CI budget (what the ``ci``
   profile of the tests and ``visnav fuzz`` without options run), timed
   once per round; the median wall time is printed.

Exits 1 if the overall median is below 2,000 steps/s or the CI budget's
median above 180 s (the acceptance figures of issue 6).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

from visnav.fuzzing import PROPERTIES, budget, fuzz, fuzz_property, property_names

MIN_STEPS_PER_S = 2000.0
MAX_CI_BUDGET_S = 180.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--examples", type=int, default=100, help="examples per property for the rate")
    parser.add_argument("--skip-budget", action="store_true", help="measure the rate only")
    args = parser.parse_args()
    names = property_names("signals")
    fuzz_property("mu_range", examples=5)  # warm-up: imports, strategy caches
    rates: dict[str, list[float]] = {name: [] for name in names}
    overall: list[float] = []
    for _ in range(args.rounds):
        steps = wall = 0.0
        for name in names:
            start = time.perf_counter()
            result = fuzz_property(name, examples=args.examples)
            elapsed = time.perf_counter() - start
            assert result.passed, (name, result.counterexample.message)
            rates[name].append(result.steps / elapsed)
            steps += result.steps
            wall += elapsed
        overall.append(steps / wall)
    print(f"supervisor steps per second through hypothesis ({args.examples} examples per property, "
          f"median of {args.rounds} rounds, {os.cpu_count()} CPUs):")
    for name in names:
        print(f"  {name:<22} {statistics.median(rates[name]):>10,.0f} steps/s")
    rate = statistics.median(overall)
    print(f"  {'all signal properties':<22} {rate:>10,.0f} steps/s  (target >= {MIN_STEPS_PER_S:,.0f})")
    ok = rate >= MIN_STEPS_PER_S
    if not args.skip_budget:
        walls = []
        for _ in range(args.rounds):
            start = time.perf_counter()
            report = fuzz()
            walls.append(time.perf_counter() - start)
            assert report.passed, [r.counterexample.message for r in report.results if not r.passed]
        per = {r.name: r.wall_time_s for r in report.results}
        total_examples = sum(budget(name) for name in PROPERTIES)
        print(f"CI budget ({len(PROPERTIES)} properties, {total_examples} examples): median {statistics.median(walls):.1f} s "
              f"over {args.rounds} rounds (min {min(walls):.1f}, max {max(walls):.1f}; target < {MAX_CI_BUDGET_S:.0f} s)")
        print("  last round: " + ", ".join(f"{name} {t:.1f} s" for name, t in per.items()))
        ok = ok and statistics.median(walls) < MAX_CI_BUDGET_S
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
