"""LMI certificates of switched linear families: success rates and times, the former Nelder–Mead search beside them.

Usage::

    python benchmarks/bench_lmi.py [--cases 200] [--seed 0] [--baseline-cases 27] [--budget-s 1.0]

Draws ``cases`` seeded families with a planted common quadratic Lyapunov function and ``cases``
planted infeasible ones (:func:`analysis.lmi.planted_common_lyapunov`,
:func:`analysis.lmi.planted_no_common_lyapunov`), n = 2…10 states in turn, 1…10 modes (2…10 for
the infeasible ones; n = 10 with 10 modes is always included), and prints: the share proven
``"exists"`` and ``"none"`` (exact re-checks), the median and largest time of one decision
(LMI solves + exact re-check) per size and overall, and the success rate of the former
Nelder–Mead search (:func:`analysis.linearise.common_quadratic_lyapunov`) on the first
``baseline-cases`` planted feasible families, measured side by side.  Exits with status 1 when a
target is missed (100 % found, 100 % certified, every decision within the budget).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import defaultdict

import numpy as np

from analysis.linearise import common_quadratic_lyapunov
from analysis.lmi import common_quadratic_lyapunov_lmi, planted_common_lyapunov, planted_no_common_lyapunov

SIZES = range(2, 11)


def _timed(family: tuple[np.ndarray, ...]) -> tuple[object, float]:
    start = time.perf_counter()
    result = common_quadratic_lyapunov_lmi(family)
    return result, time.perf_counter() - start


def _sizes(rng: np.random.Generator, case: int, m_min: int) -> tuple[int, int]:
    n = SIZES[case % len(SIZES)]
    m = 10 if case == len(SIZES) - 1 else int(rng.integers(m_min, 11))  # the first n = 10 has 10 modes
    return n, m


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--baseline-cases", type=int, default=27, help="feasible families also given to Nelder–Mead")
    parser.add_argument("--budget-s", type=float, default=1.0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    common_quadratic_lyapunov_lmi([-np.eye(2)])  # warm-up: imports cvxpy and the solvers outside the timings
    times: dict[str, dict[int, list[float]]] = {"feasible": defaultdict(list), "infeasible": defaultdict(list)}
    found = certified = by_dual = 0
    big = []
    baseline: dict[int, list[tuple[bool, float, bool, float]]] = defaultdict(list)  # old found, time; LMI
    for case in range(args.cases):
        n, m = _sizes(rng, case, 1)
        family, _ = planted_common_lyapunov(rng, n, m)
        result, elapsed = _timed(family)
        times["feasible"][n].append(elapsed)
        found += result.status == "exists" and result.recheck.passed
        if n == 10 and m == 10:
            big.append(elapsed)
        if case < args.baseline_cases:
            start = time.perf_counter()
            old = common_quadratic_lyapunov(family)
            baseline[n].append((old.found, time.perf_counter() - start, result.status == "exists", elapsed))
        n, m = _sizes(rng, case, 2)
        family, _ = planted_no_common_lyapunov(rng, n, m)
        result, elapsed = _timed(family)
        times["infeasible"][n].append(elapsed)
        certified += result.status == "none" and result.recheck.passed
        by_dual += result.status == "none" and result.dual is not None
        if n == 10 and m == 10:
            big.append(elapsed)
    cases = args.cases
    print(f"LMI common quadratic Lyapunov functions: {cases} + {cases} seeded families (seed {args.seed}), "
          f"n = {SIZES[0]}..{SIZES[-1]}")
    print(f"planted common P:   proven 'exists' (exact re-check) in {found}/{cases} ({100 * found / cases:.1f} %)")
    print(f"planted infeasible: proven 'none' in {certified}/{cases} ({100 * certified / cases:.1f} %), "
          f"by a re-checked dual certificate in {by_dual}/{cases} ({100 * by_dual / cases:.1f} %)")
    print("time of one decision [s] (LMI solves + exact re-check)")
    print("   n   feasible: median    max   infeasible: median    max")
    for n in SIZES:
        f, i = times["feasible"][n], times["infeasible"][n]
        print(f"  {n:2d}  {len(f):4d} cases {statistics.median(f):7.3f} {max(f):6.3f}   "
              f"{len(i):4d} cases {statistics.median(i):7.3f} {max(i):6.3f}")
    every = [t for kind in times.values() for values in kind.values() for t in values]
    worst = max(every)
    print(f"all {len(every)} decisions: median {statistics.median(every):.3f} s, max {worst:.3f} s "
          f"(budget {args.budget_s:g} s, ratio max/budget {worst / args.budget_s:.2f}); "
          f"n = 10 with 10 modes: max {max(big) if big else float('nan'):.3f} s over {len(big)}")
    if baseline:
        rows = [row for n in sorted(baseline) for row in baseline[n]]
        print(f"side by side on the first {len(rows)} planted feasible families: former Nelder–Mead search "
              f"(analysis.linearise.common_quadratic_lyapunov) found {sum(r[0] for r in rows)}/{len(rows)}, "
              f"the LMI proved {sum(r[2] for r in rows)}/{len(rows)}")
        for n in sorted(baseline):
            v = baseline[n]
            old_median, lmi_median = statistics.median(r[1] for r in v), statistics.median(r[3] for r in v)
            print(f"  n = {n:2d}: Nelder–Mead {sum(r[0] for r in v)}/{len(v)} (median {old_median:.2f} s), "
                  f"LMI {sum(r[2] for r in v)}/{len(v)} (median {lmi_median:.3f} s)")
    met = found == cases and certified == cases and worst <= args.budget_s
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
