"""Structural checks of the paper's supervisor: SMT-decided (PROVEN) vs sampled, side by side on one core.

Run: ``.venv/bin/python benchmarks/bench_check.py [--repeats N] [--samples S] [--cli-repeats K]``.

The process is pinned to one CPU and to one BLAS thread before anything is
measured.  Both methods run on the same automaton (the 18-mode product of
``visnav/scenarios/paper.toml``, over the measurement box, with the fuzz
measurement space's rate bounds), alternating, ``--repeats`` times; the table
gives the median wall time of each, their ratio, and what each answered (the
pair verdicts and Zeno cycles of the decided run; the sampled run's findings).
A cold run (first call: z3 import, compilation of the symbolic guards) is
reported separately from the warm medians, and so is the whole command
(``visnav check-model`` in a fresh process on the same CPU: interpreter
start, imports, scenario, cold check and output).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time


def _pin() -> str:
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[name] = "1"
    try:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
        return f"pinned to CPU {sorted(os.sched_getaffinity(0))}"
    except (AttributeError, OSError):
        return "not pinned (no sched_setaffinity)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--samples", type=int, default=300, help="samples per mode of the sampled check (the CLI default)")
    parser.add_argument("--cli-repeats", type=int, default=3, help="runs of the whole `visnav check-model` process")
    args = parser.parse_args()
    pinned = _pin()

    from hybrid import check

    from visnav.fuzzing.space import MeasurementSpace
    from visnav.scenario import load_scenario
    from visnav.supervisor import build_supervisor, measurement_box, measurement_system

    scenario = load_scenario("paper")
    model = build_supervisor(scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    system = measurement_system(model)
    box = measurement_box(model, scenario.camera.half_width_px)
    space = MeasurementSpace(envelopes=scenario.envelopes, settings=scenario.supervisor,
                             n_obstacles=len(scenario.obstacles),
                             camera_half_width_px=scenario.camera.half_width_px)
    rates = space.rates_per_s() if hasattr(space, "rates_per_s") else None
    print(f"supervisor: {len(model.automaton.modes)} modes, {len(model.automaton.transitions)} transitions; {pinned}")

    start = time.perf_counter()
    decided = check(system, box, method="auto", rates=rates)
    cold = time.perf_counter() - start
    walls: dict[str, list[float]] = {"smt": [], "sampled": []}
    sampled = None
    for _ in range(args.repeats):
        for method in ("smt", "sampled"):
            start = time.perf_counter()
            if method == "smt":
                decided = check(system, box, method="auto", rates=rates)
            else:
                sampled = check(system, box, method="sampled", samples=args.samples, starts=8)
            walls[method].append(time.perf_counter() - start)
    smt, smp = statistics.median(walls["smt"]), statistics.median(walls["sampled"])
    print(f"{'method':<10} {'median s':>9} {'min s':>7}  answers")
    pairs = decided.pairs
    overlap = sum(p.verdict == "overlap" for p in pairs)
    exclusive = sum(p.verdict == "exclusive" for p in pairs)
    z = decided.zeno
    claims = ", ".join(f"{k} {c.status}" for k, c in decided.claims.items())
    print(f"{'smt':<10} {smt:>9.3f} {min(walls['smt']):>7.3f}  {claims}")
    print(f"{'':<10} {'':>9} {'':>7}  pairs: {overlap} overlap, {exclusive} exclusive of {len(pairs)}; "
          f"zeno: {z.cycles} cycles {dict(z.counts)}, smallest dwell {z.min_dwell_s:.4g} s ({z.binding})")
    assert sampled is not None
    kinds = sorted(sampled.kinds())
    print(f"{'sampled':<10} {smp:>9.3f} {min(walls['sampled']):>7.3f}  {len(sampled.findings)} findings {kinds}, "
          f"{args.samples} samples per mode")
    print(f"cold first smt call (z3 import, guard compilation): {cold:.3f} s")
    print(f"ratio smt / sampled (medians, same run): {smt / smp:.3f}")
    cli = _cli_walls(args.cli_repeats)
    if cli:
        print(f"visnav check-model, whole process on the same CPU (interpreter, imports, cold check): median "
              f"{statistics.median(cli):.3f} s, min {min(cli):.3f} s over {len(cli)} runs")


def _cli_walls(repeats: int) -> list[float]:
    """Wall times of the command itself, each a fresh process (it inherits this process's CPU pinning)."""
    import subprocess
    import sys

    out = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", "import sys; from visnav.app.cli import main; sys.exit(main(['check-model']))"],
                       check=True, stdout=subprocess.DEVNULL)
        out.append(time.perf_counter() - start)
    return out


if __name__ == "__main__":
    main()
