"""Wall time of the whole analysis of the paper's law (`visnav analyse`), median of rounds.

Usage::

    python benchmarks/bench_analyse.py [--rounds N] [--budget-s B] [--sos-budget-s S]

Times, side by side in each round, the analysis without the SOS study (``sos="off"``) and with it
(``sos="scan"``, the default of ``visnav analyse``).  Prints the medians and minima; exits with status
1 when the median without SOS exceeds ``--budget-s`` (10 s, the requirement on one core) or the
median extra time of the SOS study exceeds ``--sos-budget-s`` (30 s).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

from visnav.studies.loop_analysis import analyse
from visnav.scenario import load_scenario


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--budget-s", type=float, default=10.0)
    parser.add_argument("--sos-budget-s", type=float, default=30.0)
    args = parser.parse_args()
    scenario = load_scenario("paper")
    samples: dict[str, list[float]] = {"off": [], "scan": []}
    for _ in range(args.rounds):
        for sos in samples:
            start = time.perf_counter()
            analyse(scenario, sos=sos)
            samples[sos].append(time.perf_counter() - start)
    off, scan = (statistics.median(samples[k]) for k in ("off", "scan"))
    extra = statistics.median(b - a for a, b in zip(samples["off"], samples["scan"]))
    print(f"visnav analyse (paper), {args.rounds} rounds:")
    print(f"  without SOS   median {off:6.2f} s, min {min(samples['off']):6.2f} s "
          f"(budget {args.budget_s:g} s, ratio {off / args.budget_s:.2f})")
    print(f"  with SOS scan median {scan:6.2f} s, min {min(samples['scan']):6.2f} s (ratio to without {scan / off:.2f})")
    print(f"  SOS study     median {extra:6.2f} s extra (budget {args.sos_budget_s:g} s, "
          f"ratio {extra / args.sos_budget_s:.2f})")
    return 0 if off <= args.budget_s and extra <= args.sos_budget_s else 1


if __name__ == "__main__":
    sys.exit(main())
