"""Cost of one simulation of a verification problem: the numerical executor against the closed form, side by side.

Usage::

    python benchmarks/bench_simulation.py [--quick] [--points N] [--rounds R]

What one call of ``problem.simulate(point)`` costs (build the system, execute it, build the STL trace: what
``visnav verify`` pays per evaluation), on points drawn from the problem's box with a fixed seed:

* thermostat: ``examples/thermostat.py:problem`` (one state, two affine modes, hysteresis, 120 s, about
  120 switches, sampled every 0.25 s);
* bouncing ball: :func:`hybrid.examples.bouncing_ball` (two states ``h, v``, affine flight, a self-loop at
  impact, 8 impacts) as a problem over its initial height, sampled every 0.01 s.

Each point runs through two paths in the same process, interleaved round by round:

* ``numerical``: today's executor, ``closed_form=False`` (RK45, rtol 1e-10, atol 1e-12, every step watched);
* ``closed form``: the default of :func:`analysis.verify.problems.hybrid_problem` with a sample period (affine modes
  solved by the matrix exponential, :mod:`hybrid.closed_form`).

Prints, per model, the median CPU time per simulation of each path (``time.process_time``: the machine is
shared), the ratio, and how far the two agree: the largest difference of the jump times and of the sampled
signals, and the robustness of each requirement (the verdicts must be the same).  ``--quick``: fewer points
and rounds (the test suite runs it).

Then the throughput of the ARCH-COMP automatic transmission (``examples/arch/autotrans.py``, every AT problem,
its own simulator: a fixed-step integration between the shift logic's ticks): simulations per second of CPU
(one core), on the same seeded points; issue 29 asks for at least 20.  The same for the ARCH-COMP chasing cars
(``examples/arch/chasing_cars.py``, every CC problem: five cars, about 2,000 mode switches in 100 s, each located on
the closed form).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script from a checkout
    sys.path.insert(0, str(ROOT))

from analysis.verify.loading import load_problem  # noqa: E402
from analysis.verify.problems import hybrid_problem  # noqa: E402
from analysis.verify.requirements import Requirement  # noqa: E402
from analysis.verify.verification import Parameter, VerificationProblem  # noqa: E402
from hybrid.examples import bouncing_ball  # noqa: E402

SEED = 0


def ball_problem() -> VerificationProblem:
    """The bouncing ball from a height in [0.8, 1.2] m, over its reference horizon, sampled every 10 ms."""
    model = bouncing_ball()
    return hybrid_problem(
        name="bouncing-ball", system=model.system,
        initial={"h": Parameter(name="h0", low=0.8, high=1.2, nominal=1.0, unit="m"), "v": 0.0},
        horizon=model.duration, sample_period=0.01, reach=False,
        requirements=(Requirement(name="below_start", formula=f"always[0, {model.duration:.6g}] (h <= 1.25)"),),
    )


def cases() -> dict[str, VerificationProblem]:
    """The benchmarked problems by name."""
    return {"thermostat": load_problem(str(ROOT / "examples" / "thermostat.py") + ":problem"),
            "bouncing ball": ball_problem()}


AT_PROBLEMS = ("at1", "at2", "at51", "at52", "at53", "at54", "at6a", "at6b", "at6c")
"""The AT problems of ``examples/arch/autotrans.py`` (horizons 10 to 32.6 s)."""


CC_PROBLEMS = ("cc1", "cc2", "cc3", "cc4", "cc5", "ccx")
"""The CC problems of ``examples/arch/chasing_cars.py`` (one model, horizon 100 s; the requirement differs)."""


def at_throughput(count: int, rounds: int, example: str = "autotrans.py",
                  names: Sequence[str] = AT_PROBLEMS) -> dict[str, Any]:
    """Median CPU seconds per simulation of each problem ``names`` of ``examples/arch/<example>`` (AT by default)
    over ``count`` seeded points; the slowest's rate."""
    per: dict[str, float] = {}
    for name in names:
        problem = load_problem(str(ROOT / "examples" / "arch" / example) + ":" + name)
        pts = points(problem, count)
        problem.simulate(pts[0])  # warm
        samples = []
        for _ in range(rounds):
            start = time.process_time()
            for point in pts:
                problem.simulate(point)
            samples.append((time.process_time() - start) / len(pts))
        per[name] = statistics.median(samples)
    slowest = max(per, key=per.__getitem__)
    return {"seconds": per, "slowest": slowest,
            "sims_per_s": 1.0 / per[slowest] if per[slowest] > 0 else float("inf")}


def points(problem: VerificationProblem, count: int, seed: int = SEED) -> list[dict[str, float]]:
    """``count`` points of the problem's box, uniformly at random (seeded), the nominal one first."""
    rng = np.random.default_rng(seed)
    out = [dict(problem.nominal())]
    for _ in range(count - 1):
        out.append({p.name: float(p.low + (p.high - p.low) * rng.random()) for p in problem.parameters})
    return out


def numerical(problem: VerificationProblem) -> Any:
    """The problem's simulator forced onto today's numerical path."""
    return dataclasses.replace(problem.simulate, options={**dict(problem.simulate.options), "closed_form": False})


def _jump_times(trace: Any) -> np.ndarray:
    return np.asarray(trace.times)[np.flatnonzero(np.diff(np.asarray(trace.jumps)) > 0) + 1]


def agreement(problem: VerificationProblem, old: Any, new: Any, pts: Sequence[dict[str, float]]) -> dict[str, Any]:
    """How far the two paths' traces differ over ``pts``: jump times [s], signals, robustness, verdicts."""
    d_jump = d_signal = d_rob = 0.0
    same_verdicts, same_jumps = True, True
    for point in pts:
        a, b = old(point), new(point)
        ja, jb = _jump_times(a), _jump_times(b)
        same_jumps &= ja.size == jb.size
        if ja.size == jb.size and ja.size:
            d_jump = max(d_jump, float(np.max(np.abs(ja - jb))))
        if a.times.size == b.times.size:
            for name in a.signals:
                d_signal = max(d_signal, float(np.max(np.abs(a.signals[name] - b.signals[name]))))
        else:
            same_jumps = False
        for req in problem.parsed:
            ra, rb = float(req.formula.robustness(a)), float(req.formula.robustness(b))
            d_rob = max(d_rob, abs(ra - rb))
            same_verdicts &= (ra >= 0) == (rb >= 0)
    return {"jump_times": d_jump, "signals": d_signal, "robustness": d_rob, "same_verdicts": same_verdicts,
            "same_jump_counts": same_jumps}


def measure(problem: VerificationProblem, count: int, rounds: int) -> dict[str, Any]:
    """Median CPU seconds per simulation of both paths over ``count`` points, ``rounds`` interleaved rounds."""
    pts = points(problem, count)
    old, new = numerical(problem), problem.simulate
    for sim in (old, new):  # warm: imports, compiled guards
        sim(pts[0])
    per: dict[str, list[float]] = {"numerical": [], "closed form": []}
    for _ in range(rounds):
        for label, sim in (("numerical", old), ("closed form", new)):
            start = time.process_time()
            for point in pts:
                sim(point)
            per[label].append((time.process_time() - start) / len(pts))
    old_s, new_s = statistics.median(per["numerical"]), statistics.median(per["closed form"])
    return {"numerical_s": old_s, "closed_form_s": new_s, "ratio": old_s / new_s if new_s > 0 else float("inf"),
            "points": len(pts), "rounds": rounds, **agreement(problem, old, new, pts)}


def main(argv: Sequence[str] | None = None) -> dict[str, dict[str, Any]]:
    """Run the benchmark, print the table, return the figures by model (and ``"AT"``, ``"CC"``:
    :func:`at_throughput`)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 points, 3 rounds (the test suite's run)")
    parser.add_argument("--points", type=int, default=None, help="points per round (default 10; quick 3)")
    parser.add_argument("--rounds", type=int, default=None, help="interleaved rounds (default 5; quick 3)")
    args = parser.parse_args(argv)
    count = args.points or (3 if args.quick else 10)
    rounds = args.rounds or (3 if args.quick else 5)
    results = {}
    print(f"per simulation (CPU ms, median of {rounds} rounds of {count} points): problem.simulate(point)")
    print(f"{'model':<14} {'numerical':>10} {'closed form':>12} {'ratio':>7}  {'d jump [s]':>10} {'d signal':>9} "
          f"{'d robust':>9}  verdicts")
    for name, problem in cases().items():
        r = measure(problem, count, rounds)
        results[name] = r
        print(f"{name:<14} {1e3 * r['numerical_s']:>10.3f} {1e3 * r['closed_form_s']:>12.3f} {r['ratio']:>6.1f}x  "
              f"{r['jump_times']:>10.2e} {r['signals']:>9.2e} {r['robustness']:>9.2e}  "
              f"{'same' if r['same_verdicts'] and r['same_jump_counts'] else 'DIFFER'}")
    at = at_throughput(count, rounds)
    results["AT"] = at
    print(f"AT (examples/arch/autotrans.py, {len(AT_PROBLEMS)} problems, CPU ms per simulation): "
          + ", ".join(f"{name} {1e3 * sec:.2f}" for name, sec in at["seconds"].items()))
    print(f"AT throughput: {at['sims_per_s']:.1f} simulations/s/core (the slowest, {at['slowest']}; "
          f"issue 29 asks >= 20)")
    cc = at_throughput(count, rounds, "chasing_cars.py", CC_PROBLEMS)
    results["CC"] = cc
    print(f"CC (examples/arch/chasing_cars.py, {len(CC_PROBLEMS)} problems, CPU ms per simulation): "
          + ", ".join(f"{name} {1e3 * sec:.2f}" for name, sec in cc["seconds"].items()))
    print(f"CC throughput: {cc['sims_per_s']:.1f} simulations/s/core (the slowest, {cc['slowest']})")
    return results


if __name__ == "__main__":
    main()
