"""Falsification at equal simulation budget: guided search vs Monte-Carlo vs scipy's dual annealing.

Run: ``.venv/bin/python benchmarks/bench_falsification.py [--budget N] [--seeds K] [--problem SPEC]
[--requirement NAME]``.  Default: the paper's problem (``visnav verify paper``'s box) and its
clearance requirement; each method gets the same budget and the same seeds; the table gives, per
method, the median over seeds of the lowest robustness found (lower is better: a violation is
negative) and the median wall time, and the ratios to the guided search side by side.
"""

from __future__ import annotations

import argparse
import statistics
import time

from analysis.verify.verdicts import verify

from visnav.app.cli_verify import load_verification_problem


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default="paper")
    parser.add_argument("--requirement", default="no_collision")
    parser.add_argument("--budget", type=int, default=60)
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    problem = load_verification_problem(args.problem, {}, [args.requirement])
    print(f"problem {problem.name}, requirement {args.requirement}: {problem.requirements[0].formula.strip()}")
    print(f"box: {problem.dimension} parameters; budget {args.budget} simulations per method; seeds 0..{args.seeds - 1}")
    rows = {}
    for method in ("guided", "monte-carlo", "dual-annealing"):
        lows, walls = [], []
        for seed in range(args.seeds):
            start = time.perf_counter()
            result = verify(problem, budget=args.budget, seed=seed, method=method)
            walls.append(time.perf_counter() - start)
            lows.append(result.requirements[0].robustness)
        rows[method] = (statistics.median(lows), min(lows), statistics.median(walls), lows)
    ref = rows["guided"][0]
    print(f"{'method':<16} {'median lowest':>14} {'best':>10} {'median wall s':>14}  per seed")
    for method, (median, best, wall, lows) in rows.items():
        print(f"{method:<16} {median:>14.6g} {best:>10.6g} {wall:>14.2f}  {', '.join(f'{v:.5g}' for v in lows)}")
    for method in ("monte-carlo", "dual-annealing"):
        gap = rows[method][0] - ref
        print(f"guided minus {method}: {-gap:+.4g} (negative: guided found lower robustness)")


if __name__ == "__main__":
    main()
