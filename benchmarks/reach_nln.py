"""ARCH-COMP-style nonlinear (NLN) reachability instances for :mod:`analysis.reach`, and their runner.

``INSTANCES`` is module-level data a benchmark can use: each entry is a dict

* ``"name"``: the instance;
* ``"build"``: a callable returning ``(system, initial_box, reach_kwargs, requirement)``: the symbolic
  :class:`hybrid.system.HybridSystem`, the box ``{state: (lo, hi)}``, the keyword arguments of
  :func:`analysis.reach.verdict.reach_proof` (``time_step``, ``splits``, ``engine``), and the requirement as an
  :class:`analysis.reach.SafetyFragment`.  Run it as
  ``reach_proof(system, requirement, initial_box, **reach_kwargs)`` (what :func:`run_instance` does);
* ``"published"``: a figure to set beside ours: ``{"tool", "report", "verdict", "runtime_s", "note"}``.

Published figures.  The ARCH-COMP NLN reports (e.g. *ARCH-COMP21 Category Report: Continuous and
Hybrid Systems with Nonlinear Dynamics*, Geretti et al., EPiC Series in Computing 80, 2021, pp. 32–54)
list the VDP instance (μ = 1, ``x ∈ [1.25, 1.55]``, ``y ∈ [2.35, 2.45]``, T = 7, ``y < 2.75``) as
verified safe by CORA and JuliaReach, among others.  Their runtimes were not available to this work in
a form that could be checked (the report's tables were not readable here), so ``runtime_s`` is
``None`` rather than a number from memory.  LOVO in ARCH has a circular guard (a nonlinear guard,
which :mod:`analysis.reach` does not read) and a specification on the time spent inside it; the
instance here keeps LOVO's dynamics, parameters, initial set and horizon with a box safety property,
so it is not the ARCH problem and its figure is not comparable (said in its note).

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/reach_nln.py [--repeats N]``: per instance the
verdict, whether it was re-checked, the margin, and the wall-clock seconds (flowpipe and re-check).
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any


def _one_mode(name: str, flow: Any, names: tuple[str, ...]) -> Any:
    from hybrid import HybridAutomaton, Mode
    from hybrid.system import HybridSystem

    automaton = HybridAutomaton(name=name, modes=(Mode(name="m"),), transitions=(), variables=names)
    return HybridSystem(automaton=automaton, state_names=names, flows={"m": flow})


def _fragment(text: str, names: tuple[str, ...]) -> Any:
    from analysis.reach import safety_fragment
    from analysis.stl.syntax import parse_tree

    return safety_fragment(parse_tree(text), names)


def build_vdp() -> tuple[Any, dict[str, tuple[float, float]], dict[str, Any], Any]:
    """Van der Pol, μ = 1: ``x' = y``, ``y' = μ (1 − x²) y − x``; ARCH's VDP initial box, T = 7 s, ``y < 2.75``.

    Adaptive steps from 0.01 s (ratio 2.2, :func:`analysis.reach.nonlinear.adaptive_segments`), zonotope order 160,
    the box split in 4 along ``x`` (docs/reachability.md, "Adaptive step")."""
    from hybrid.symbolic import coordinates, flow_map

    names = ("x", "y")
    x = coordinates(*names)
    system = _one_mode("vdp", flow_map(x.y, 1.0 * (1.0 - x.x ** 2) * x.y - x.x), names)
    box = {"x": (1.25, 1.55), "y": (2.35, 2.45)}
    options = {"time_step": 0.01, "splits": {"x": 4}, "engine": {"adaptive_step": 2.2, "order": 160}}
    return system, box, options, _fragment("always[0, 7] (y < 2.75)", names)


def build_lovo() -> tuple[Any, dict[str, tuple[float, float]], dict[str, Any], Any]:
    """Lotka–Volterra with LOVO's parameters ``x' = 1.5 x − x y``, ``y' = x y − 3 y``, ``x ∈ [1.3, 1.32]``,
    ``y = 1``, T = 3.64 s; safety: ``x < 6.2`` and ``y < 4`` (fine simulations reach 5.993 and 3.819)."""
    from hybrid.symbolic import coordinates, flow_map

    names = ("x", "y")
    x = coordinates(*names)
    system = _one_mode("lovo", flow_map(1.5 * x.x - x.x * x.y, x.x * x.y - 3.0 * x.y), names)
    box = {"x": (1.3, 1.32), "y": (1.0, 1.0)}
    return system, box, {"time_step": 0.005}, _fragment("always[0, 3.64] (x < 6.2 and y < 4)", names)


INSTANCES = [
    {"name": "VDP (mu = 1)", "build": build_vdp,
     "published": {"tool": "CORA", "report": "ARCH-COMP21 NLN", "verdict": "safe", "runtime_s": None,
                   "note": "different machine; verified safe in the ARCH-COMP NLN reports (CORA, JuliaReach); "
                           "runtime not given: the report's table could not be checked here"}},
    {"name": "LOVO dynamics (box safety)", "build": build_lovo,
     "published": {"tool": "JuliaReach", "report": "ARCH-COMP21 NLN", "verdict": "safe", "runtime_s": None,
                   "note": "different machine and a different property: ARCH's LOVO has a circular guard and a "
                           "time-inside specification, not modelled here; not comparable"}},
]
"""The instances (see the module docstring)."""


def run_instance(instance: dict[str, Any]) -> dict[str, Any]:
    """Build and decide one instance: ``{"name", "holds", "rechecked", "margin", "seconds", "evidence"}``."""
    from analysis.reach.verdict import reach_proof

    system, box, kwargs, requirement = instance["build"]()
    start = time.perf_counter()
    proof, decision = reach_proof(system, requirement, box, **kwargs)
    return {"name": instance["name"], "holds": proof.holds, "rechecked": proof.rechecked,
            "margin": decision.margin, "seconds": time.perf_counter() - start, "evidence": proof.evidence}


def flowpipe_seconds(instance: dict[str, Any]) -> float:
    """Seconds of the flowpipes alone (every piece of the split), without the re-check."""
    from analysis.reach import reach
    from analysis.reach.split import split_box

    system, box, kwargs, requirement = instance["build"]()
    pieces = split_box(box, kwargs.get("splits") or {})
    start = time.perf_counter()
    for piece in pieces:
        reach(system, piece, horizon=requirement.end, time_step=kwargs["time_step"], **(kwargs.get("engine") or {}))
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    for instance in INSTANCES:
        flow = statistics.median(flowpipe_seconds(instance) for _ in range(args.repeats))
        out = run_instance(instance)
        published = instance["published"]
        print(f"{out['name']}: holds {out['holds']}, re-checked {out['rechecked']}, margin {out['margin']:.4g}; "
              f"flowpipes {flow:.2f} s, verdict with re-check {out['seconds']:.2f} s; published "
              f"{published['tool']} ({published['report']}): {published['verdict']}, {published['runtime_s']} s "
              f"({published['note']})")


if __name__ == "__main__":
    main()
