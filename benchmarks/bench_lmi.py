"""LMI certificates of switched linear families: success rates and solve times, the old search beside them.

Run: ``.venv/bin/python benchmarks/bench_lmi.py [--cases 200] [--seed 0]``.

Prints, over ``cases`` random families with n = 2…10 states and 2…10 modes: the share with a planted
common P for which a common quadratic Lyapunov function was *proven* (exact re-check), the share of
planted infeasible families with a re-checked dual certificate, the median and largest solve time per
decision, and, on the first 40 planted feasible families, the success rate of the former Nelder–Mead
search measured side by side.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from analysis.linearise import common_quadratic_lyapunov
from analysis.lmi import common_quadratic_lyapunov_lmi
from analysis.random_families import planted_common_lyapunov, planted_no_common_lyapunov


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--nelder-mead", type=int, default=40, help="feasible cases also given to the old search")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    times: dict[str, list[float]] = {"exists": [], "none": []}
    found = certified = 0
    old_found = old_tried = 0
    for case in range(args.cases):
        n, m = int(rng.integers(2, 11)), int(rng.integers(2, 11))
        family, _ = planted_common_lyapunov(rng, n, m)
        start = time.perf_counter()
        result = common_quadratic_lyapunov_lmi(family)
        times["exists"].append(time.perf_counter() - start)
        found += result.status == "exists"
        if case < args.nelder_mead:
            old_tried += 1
            old_found += common_quadratic_lyapunov(family).found
        bad, _ = planted_no_common_lyapunov(rng, n, m)
        start = time.perf_counter()
        result = common_quadratic_lyapunov_lmi(bad)
        times["none"].append(time.perf_counter() - start)
        certified += result.status == "none"
    print(f"planted common P:   proven to exist in {found}/{args.cases} ({100 * found / args.cases:.1f} %)")
    print(f"planted infeasible: absence proven in {certified}/{args.cases} ({100 * certified / args.cases:.1f} %)")
    for kind, values in times.items():
        print(f"solve time ({kind:>6}): median {statistics.median(values):.3f} s, max {max(values):.3f} s")
    if old_tried:
        print(f"former Nelder-Mead search: found {old_found}/{old_tried} of the same feasible families "
              f"(LMI: all of them)")


if __name__ == "__main__":
    main()
