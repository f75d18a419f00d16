"""Thin planted defects: how often the sampled search finds them, against the SMT-decided check.

Run: ``.venv/bin/python benchmarks/bench_slivers.py [--seeds N]``.

A non-determinism on a sliver of width 5e-4 (two equal-priority guards ``x >= 1`` and
``x <= 1.0005`` in the box ``[-5, 5]²``) and a deadlock on a sliver of the same width (the flow
``(1, 0)`` leaves ``x <= 1`` where neither ``y >= 5e-4`` nor ``y <= 0`` is enabled), written once
with plain Python callables (sampled) and once symbolically (decided); the table gives the seeds
(``check(seed=s)``, ``s = 0 .. N-1``) on which each finds the defect, and the median wall time.
The decided check does not depend on the seed; ``tests/hybrid/test_decide.py`` asserts it finds both
for every seed.
"""

from __future__ import annotations

import argparse
import statistics
import time

from hybrid import Box, HybridAutomaton, HybridSystem, Mode, Transition, all_of, check
from hybrid.symbolic import coordinates, flow_map

SLIVER = 5e-4
BOX = Box(bounds={"x": (-5.0, 5.0), "y": (-5.0, 5.0)})


def overlap(symbolic: bool) -> HybridAutomaton:
    v = coordinates("x", "y")
    g1 = (v.x - 1.0) if symbolic else (lambda s, m: s[0] - 1.0)
    g2 = ((1.0 + SLIVER) - v.x) if symbolic else (lambda s, m: (1.0 + SLIVER) - s[0])
    return HybridAutomaton(name="sliver_overlap", variables=("x", "y"),
                           modes=(Mode(name="a"), Mode(name="b"), Mode(name="c")),
                           transitions=(Transition(name="t1", source="a", target="b", guard=g1),
                                        Transition(name="t2", source="a", target="c", guard=g2)))


def deadlock(symbolic: bool) -> HybridSystem:
    v = coordinates("x", "y")
    if symbolic:
        inv, up, down = 1.0 - v.x, all_of(v.x - 1.0, v.y - SLIVER), all_of(v.x - 1.0, -v.y)
        run, stop = flow_map(1.0, 0.0), flow_map(0.0, 0.0)
    else:
        inv = lambda s, m: 1.0 - s[0]  # noqa: E731
        up = all_of(lambda s, m: s[0] - 1.0, lambda s, m: s[1] - SLIVER)
        down = all_of(lambda s, m: s[0] - 1.0, lambda s, m: -s[1])
        run, stop = (lambda t, x, m: (1.0, 0.0)), (lambda t, x, m: (0.0, 0.0))
    a = HybridAutomaton(name="sliver_deadlock", variables=("x", "y"),
                        modes=(Mode(name="run", invariant=inv), Mode(name="stop")),
                        transitions=(Transition(name="up", source="run", target="stop", guard=up, priority=0),
                                     Transition(name="down", source="run", target="stop", guard=down, priority=1)))
    return HybridSystem(automaton=a, state_names=("x", "y"), flows={"run": run, "stop": stop})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    print(f"{'defect':<16} {'method':<8} {'found':>8} {'median s':>9}")
    for name, build, kind in (("non-determinism", overlap, "nondeterminism"), ("deadlock", deadlock, "deadlock")):
        for method, symbolic in (("sampled", False), ("decided", True)):
            model, hits, walls = build(symbolic), 0, []
            for seed in range(args.seeds):
                start = time.perf_counter()
                report = check(model, BOX, seed=seed, method="sampled" if not symbolic else "auto")
                walls.append(time.perf_counter() - start)
                hits += bool(report.of_kind(kind))
            print(f"{name:<16} {method:<8} {hits:>4}/{args.seeds:<3} {statistics.median(walls):>9.3f}")


if __name__ == "__main__":
    main()
