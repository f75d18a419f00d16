"""Speed of the paper scenario's closed loop: simulated seconds per wall second.

Run: ``python benchmarks/bench_paper_scenario.py [--repeat N]``.  Prints, side
by side in one run, the median real-time factor of the closed loop with the
exact plant flow (what ``visnav simulate`` uses) and with the plant integrated
by ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-10) between samples, and
the median cost per sample.  Exits 1 if the exact-flow loop is slower than
1000x real time (the acceptance figure of issue 2).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time

from hybrid import Plant, simulate_sampled
from visnav.closed_loop import ClosedLoop, robot_plant
from visnav.scenario import load_scenario

TARGET_FACTOR = 1000.0


def run_once(scenario, plant: Plant) -> tuple[float, float, int]:
    loop = ClosedLoop(scenario=scenario)
    start = time.perf_counter()
    trace = simulate_sampled(
        loop.supervisor.automaton, plant, loop, scenario.start.as_tuple(),
        period=scenario.sampling_period_s, duration=scenario.duration_s, stop=loop.stop,
    )
    wall = time.perf_counter() - start
    return float(trace.times[-1]), wall, len(trace.times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    scenario = load_scenario("paper")
    exact = robot_plant()
    numeric = dataclasses.replace(exact, exact_flow=None)
    run_once(scenario, exact)  # warm-up (imports, caches)
    factors, per_step = [], []
    for _ in range(args.repeat):
        sim, wall, steps = run_once(scenario, exact)
        factors.append(sim / wall)
        per_step.append(wall / steps * 1e6)
    sim_n, wall_n, steps_n = run_once(scenario, numeric)
    factor = statistics.median(factors)
    print(f"paper scenario: {sim:.2f} s simulated, {steps} samples of {scenario.sampling_period_s * 1e3:.0f} ms")
    print(f"  exact plant flow        : median {factor:8.0f}x real time, {statistics.median(per_step):6.1f} us/sample "
          f"(min {min(factors):.0f}x, max {max(factors):.0f}x over {args.repeat} runs)")
    print(f"  solve_ivp plant (DOP853): {sim_n / wall_n:8.0f}x real time, {wall_n / steps_n * 1e6:6.1f} us/sample")
    print(f"  ratio exact / solve_ivp : {factor / (sim_n / wall_n):.1f}")
    print(f"  target >= {TARGET_FACTOR:.0f}x real time: {'met' if factor >= TARGET_FACTOR else 'NOT met'}")
    return 0 if factor >= TARGET_FACTOR else 1


if __name__ == "__main__":
    sys.exit(main())
