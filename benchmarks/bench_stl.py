"""STL robustness on the paper scenario's trace: ``analysis.stl`` against rtamt's discrete-time offline monitor.

Usage::

    python benchmarks/bench_stl.py [--rounds N] [--rtamt-rounds M]

The trace is the ``paper`` scenario's simulation (1447 samples, period 0.05 s):
every finite record and input becomes a numeric signal, the mode a label.
Each requirement below is written twice: for us with time bounds in seconds
on the simulated times, for rtamt (``StlDiscreteTimeSpecification``, default
unit and sampling period 1 s) with the same bounds in samples on times
0, 1, 2, ...  Both give the robustness at every sample; the two are asserted
equal (1e-12) before anything is timed.  The smoothness requirement starts
its window one sample ahead (``always[0.05, 60]``) so that no ``prev`` is ever
read at the first sample, where the two tools differ (``docs/stl.md``).

Printed per requirement: the median evaluation time of each side (parsing
excluded; it is printed once at the end), and the ratio rtamt / ours.
"""

from __future__ import annotations

import argparse
import gc
import statistics
import sys
import time
import warnings

import numpy as np

from analysis.stl import SignalTrace, parse_formula
from visnav.scenario import load_scenario
from visnav.simulation import simulate

TARGET_RATIO = 10.0

REQUIREMENTS = (
    # name, ours (seconds), rtamt (samples of 0.05 s)
    ("clearance",
     "always[0, 60] clearance_m > 0.25",
     "always[0,1200](clearance_m > 0.25)"),
    ("blend bounds",
     "always[0, 60] (0 <= mu_coll <= 1 and 0 <= mu_occ <= 1)",
     "always[0,1200](((0 <= mu_coll) and (mu_coll <= 1)) and ((0 <= mu_occ) and (mu_occ <= 1)))"),
    ("blend completes",
     "always[0, 50] (rise(mu_coll > 0.5) -> eventually[0, 2] mu_coll >= 0.99)",
     "always[0,1000]((rise(mu_coll > 0.5)) -> (eventually[0,40](mu_coll >= 0.99)))"),
    ("blend stays engaged",
     "always[0, 50] (rise(mu_coll > 0.05) -> (mu_coll > 0.01 until[0, 2] mu_coll >= 0.99))",
     "always[0,1000]((rise(mu_coll > 0.05)) -> ((mu_coll > 0.01) until[0,40] (mu_coll >= 0.99)))"),
    ("smooth turning",
     "always[0.05, 60] abs(omega_radps - prev(omega_radps)) <= 0.2",
     "always[1,1200](abs(omega_radps - prev(omega_radps)) <= 0.2)"),
    ("goal reached",
     "eventually[0, 72] (feature_error_px < 5 and v_mps < 0.05)",
     "eventually[0,1440]((feature_error_px < 5) and (v_mps < 0.05))"),
    ("reconstruction justified",
     "always[0, 60] (reconstructing > 0.5 -> once[0, 5] n_occluded > 0.5)",
     "always[0,1200]((reconstructing > 0.5) -> (once[0,100](n_occluded > 0.5)))"),
)


def paper_trace() -> tuple[SignalTrace, dict[str, list[float]]]:
    """The paper scenario's trace for us, and the same finite columns as rtamt's dataset."""
    trace = simulate(load_scenario("paper")).trace
    columns = {name: trace.record(name) for name in trace.record_names}
    columns |= {name: trace.input(name) for name in trace.input_names}
    finite = {name: np.asarray(v, dtype=float) for name, v in columns.items() if np.isfinite(v).all()}
    modes = tuple(trace.mode_names[int(i)] for i in trace.modes)
    ours = SignalTrace(times=trace.times, signals=finite, labels={"mode": modes}, jumps=trace.jumps)
    return ours, {name: v.tolist() for name, v in finite.items()}


def median_time(run, rounds: int) -> float:
    """Median wall time [s] of ``rounds`` calls of ``run`` (garbage collector off while timing)."""
    times = []
    for _ in range(rounds):
        gc.disable()
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
        gc.enable()
    return statistics.median(times)


def rtamt_spec(rtamt, text: str, names) -> object:
    spec = rtamt.StlDiscreteTimeSpecification()
    for name in names:
        spec.declare_var(name, "float")
    spec.spec = text
    spec.parse()
    return spec


def rtamt_evaluate(spec, dataset: dict[str, list[float]], n: int) -> np.ndarray:
    data = {"time": list(range(n)), **{k: list(v) for k, v in dataset.items()}}
    return np.array([v for _, v in spec.evaluate(data)], dtype=float)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=50, help="timed evaluations per requirement, ours")
    parser.add_argument("--rtamt-rounds", type=int, default=5, help="timed evaluations per requirement, rtamt")
    args = parser.parse_args()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            import rtamt
        except ImportError:
            print("rtamt is not installed: nothing to compare with (pip install rtamt); benchmark skipped")
            return 0
    trace, dataset = paper_trace()
    n = trace.n
    print(f"paper scenario: {n} samples, period {np.median(np.diff(trace.times)):.3g} s, "
          f"{len(dataset)} numeric signals; ours {args.rounds} rounds, rtamt {args.rtamt_rounds} rounds (medians)")
    print(f"{'requirement':<26} {'ours [ms]':>10} {'rtamt [ms]':>11} {'ratio':>8}  robustness")
    ours_total = theirs_total = parse_ours = parse_theirs = 0.0
    for name, ours_text, theirs_text in REQUIREMENTS:
        start = time.perf_counter()
        formula = parse_formula(ours_text, signals=trace.names)
        parse_ours += time.perf_counter() - start
        start = time.perf_counter()
        spec = rtamt_spec(rtamt, theirs_text, dataset)
        parse_theirs += time.perf_counter() - start
        ours, theirs = formula.robustness_signal(trace), rtamt_evaluate(spec, dataset, n)
        np.testing.assert_allclose(ours, theirs, rtol=0.0, atol=1e-12, err_msg=name)
        t_ours = median_time(lambda: formula.robustness_signal(trace), args.rounds)
        t_theirs = median_time(lambda: rtamt_evaluate(spec, dataset, n), args.rtamt_rounds)
        ours_total += t_ours
        theirs_total += t_theirs
        print(f"{name:<26} {t_ours * 1e3:>10.3f} {t_theirs * 1e3:>11.2f} {t_theirs / t_ours:>7.0f}x  {ours[0]:+.6g}")
    ratio = theirs_total / ours_total
    print(f"{'all (sum of medians)':<26} {ours_total * 1e3:>10.3f} {theirs_total * 1e3:>11.2f} {ratio:>7.0f}x")
    print(f"parsing all requirements once: ours {parse_ours * 1e3:.2f} ms, rtamt {parse_theirs * 1e3:.1f} ms")
    verdict = "met" if ratio >= TARGET_RATIO else "NOT met"
    print(f"values equal to 1e-12 at every sample; target >= {TARGET_RATIO:.0f}x faster: {verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
