"""Regions of attraction of a user's polynomial mode (analysis.mode_region): level, area, time, boxes per case.

Run: ``.venv/bin/python benchmarks/bench_mode_region.py [--repeats N] [--skip-4d]``.

For each system (one mode, no invariant unless stated), the median wall time of ``--repeats`` calls of
:func:`analysis.mode_region.mode_region_of_attraction` and what the last one proved: the level ``c`` and
inner level, the entry-time bound, the boxes examined by the branch and bound, and in the plane the area
of ``{V <= c}`` (grid estimate) beside that of the quadratic (degree-2) set, as a ratio measured in the
same run.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from analysis.mode_region import mode_region_of_attraction
from hybrid import HybridAutomaton, HybridSystem, Mode, Transition


def _one_mode(name, names, flow, *, invariant=None, guard=None):
    transitions = (Transition(name="leave", source="q", target="out", guard=guard),) if guard else ()
    automaton = HybridAutomaton(name=name, variables=names, initial_mode="q",
                                modes=(Mode(name="q", invariant=invariant), Mode(name="out")), transitions=transitions)
    return HybridSystem(automaton=automaton, state_names=names,
                        flows={"q": flow, "out": lambda t, x, m: tuple(0.0 for _ in names)})


def _vdp(t, x, m):
    return (-x[1], x[0] + (x[0] ** 2 - 1) * x[1])


def _cases(skip_4d: bool):
    xy = ("x", "y")
    yield "Van der Pol (reverse), degree 2", _one_mode("vdp", xy, _vdp), {}, 2
    yield "Van der Pol (reverse), degree 4", _one_mode("vdp", xy, _vdp), {}, 4
    yield "Van der Pol, invariant x <= 0.5", _one_mode("vdp", xy, _vdp, invariant=lambda v, m: 0.5 - v[0]), {}, 2
    yield "Van der Pol, guard y >= 0.8", _one_mode("vdp", xy, _vdp, guard=lambda v, m: v[1] - 0.8), {}, 2
    yield ("Lotka-Volterra (competitive)",
           _one_mode("lv", xy, lambda t, x, m: (x[0] * (1 - x[0] - 0.5 * x[1]), x[1] * (1 - x[1] - 0.5 * x[0]))),
           {"guess": (0.6, 0.6)}, 2)
    yield ("cubic-damped oscillator",
           _one_mode("cubic", xy, lambda t, x, m: (x[1], -x[0] - x[1] - x[1] ** 3)), {}, 2)
    yield ("3 states: Van der Pol + z' = -z + x^2",
           _one_mode("vdp3", ("x", "y", "z"), lambda t, x, m: (-x[1], x[0] + (x[0] ** 2 - 1) * x[1], -x[2] + x[0] ** 2)),
           {}, 2)
    if not skip_4d:
        def coupled(t, x, m):
            return (-x[1], x[0] + (x[0] ** 2 - 1) * x[1] + 0.1 * x[2], -x[3], x[2] + (x[2] ** 2 - 1) * x[3] + 0.1 * x[0])
        yield "4 states: two coupled Van der Pol", _one_mode("vdp4", ("x1", "y1", "x2", "y2"), coupled), {}, 2


def _area(region) -> float | None:
    """Grid estimate of the area of {x in B : V(x) <= c} in the plane (None above 2 states)."""
    if len(region.state_names) != 2 or region.level is None:
        return None
    v = region.lyapunov_polynomial()
    (lo0, hi0), (lo1, hi1) = (region.box[n] for n in region.state_names)
    x0, x1 = region.equilibrium
    g0, g1 = np.meshgrid(np.linspace(lo0 - x0, hi0 - x0, 401), np.linspace(lo1 - x1, hi1 - x1, 401))
    a, b = region.variables
    values = np.vectorize(lambda p, q: v.evaluate_at({a: p, b: q}))(g0, g1)
    cell = (hi0 - lo0) / 400 * (hi1 - lo1) / 400
    return float(np.count_nonzero(values <= region.level) * cell)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--skip-4d", action="store_true", help="leave out the 4-state case (about 30 s)")
    args = parser.parse_args()
    quadratic_area = None
    print(f"{'case':40s} {'status':8s} {'c':>9s} {'c_in':>8s} {'T [s]':>8s} {'boxes':>7s} {'area':>7s} "
          f"{'ratio':>6s} {'median [s]':>10s}")
    for name, system, kwargs, degree in _cases(args.skip_4d):
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            region = mode_region_of_attraction(system, "q", degree=degree, **kwargs)
            times.append(time.perf_counter() - start)
        area = _area(region)
        if name.endswith("degree 2"):
            quadratic_area = area
        ratio = (f"{area / quadratic_area:6.3f}" if area and quadratic_area and "Van der Pol (reverse)" in name
                 else "")
        print(f"{name:40s} {region.status:8s} {region.level or float('nan'):9.5g} "
              f"{region.inner_level or float('nan'):8.3g} {region.time_bound_s or float('nan'):8.4g} "
              f"{region.boxes_examined:7d} {'' if area is None else f'{area:7.4g}'} {ratio:>6s} "
              f"{statistics.median(times):10.2f}")
        if region.status != "proven":
            print(f"    why: {region.why}")


if __name__ == "__main__":
    main()
