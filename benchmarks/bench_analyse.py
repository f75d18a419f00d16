"""Wall time of the whole analysis of the paper's law (`visnav analyse`), median of rounds.

Usage::

    python benchmarks/bench_analyse.py [--rounds N] [--budget-s B]

Prints the median and the minimum; exits with status 1 when the median exceeds the
budget (10 s, the issue's requirement on one core).
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
    args = parser.parse_args()
    scenario = load_scenario("paper")
    samples = []
    for _ in range(args.rounds):
        start = time.perf_counter()
        analyse(scenario)
        samples.append(time.perf_counter() - start)
    median = statistics.median(samples)
    print(f"visnav analyse (paper): median {median:.2f} s, min {min(samples):.2f} s over {args.rounds} rounds "
          f"(budget {args.budget_s:g} s, ratio {median / args.budget_s:.2f})")
    return 0 if median <= args.budget_s else 1


if __name__ == "__main__":
    sys.exit(main())
