"""Reachability benchmark: visnav's sound zonotope flowpipes beside Hylaa and the ARCH-COMP published results.

Run: ``PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_reach.py [--quick] [--json] [--repeats N]
[--soundness N [--closed-form]] [--no-peers]``; with the peers (Hylaa 2.0.2 and a compatible swiglpk, see README
"Benchmarks"): ``PYTHONPATH=$PWD:$PWD/.peers-swig:$PWD/.peers``.

Per instance (``reach_instances.py``): our verdict (``safe`` when the flowpipe is complete and the requirement
holds on every segment, :func:`analysis.reach.verdict.decide`, under SpaceEx's may-semantics, as in ARCH-COMP;
``unknown`` otherwise, with the reason), the median wall time over ``--repeats`` runs of
:func:`analysis.reach.reach` (one core, model reading included), the largest box width of the last stored
segment, the margin (the requirement's smallest slack over the flowpipe), Hylaa's verdict and time and the ratio
(ours / Hylaa's), the verdicts published for CORA and JuliaReach (ARCH-COMP AFF reports, different machines),
and the soundness benchmark (``reach_soundness.py``): executor runs inside the flowpipe, planted sets never proven.
Rows of ``benchmarks/reach_nln.py`` (nonlinear instances, another module, decided by its ``run_instance``:
``reach_proof`` with its splits and the re-check; ``safe`` only when both hold) are added when that file exists.
``--json`` prints one JSON document (deterministic but for the times).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import reach_instances as ri  # noqa: E402  (benchmarks/ is not a package)

LONG_RUN = 20.0
"""A run longer than this [s] is not repeated (the median is then of fewer runs; ``runs`` says how many)."""


def _verdict(instance: ri.Instance, result: Any) -> tuple[str, float, str]:
    from analysis.reach import safety_fragment
    from analysis.reach.verdict import decide
    from analysis.stl.syntax import parse_tree

    fragment = safety_fragment(parse_tree(instance.requirement), instance.system.state_names)
    holds, margin, reason = decide(result, fragment)
    return ("safe" if holds else "unknown"), margin, reason


def _width(result: Any) -> float:
    last = max(result.segments, key=lambda s: (s.t_hi, not s.entry))
    return float(max(last.hi - last.lo)) if len(last.lo) else 0.0


def run_ours(instance: ri.Instance, repeats: int) -> tuple[dict[str, Any], Any]:
    """Our flowpipe ``repeats`` times: the row's fields and the last result."""
    from analysis.reach import reach

    times, result = [], None
    for _ in range(max(repeats, 1)):
        start = time.perf_counter()
        result = reach(instance.system, instance.box, initial_mode=instance.initial_mode, **instance.options)
        times.append(time.perf_counter() - start)
        if times[-1] > LONG_RUN:
            break
    verdict, margin, reason = _verdict(instance, result)
    distances = {u.name: result.distance_to(u) for u in instance.unsafe}
    return {"verdict": verdict, "seconds": statistics.median(times), "runs": len(times), "width": _width(result),
            "margin": margin, "reason": reason, "status": result.status, "segments": len(result.segments),
            "min_distance": min(distances.values()) if distances else math.nan}, result


def run_hylaa(instance: ri.Instance) -> dict[str, Any]:
    from reach_hylaa import hylaa_run

    o = instance.options
    step = instance.hylaa_step or min([o["time_step"], *o.get("mode_time_steps", {}).values()])
    return hylaa_run(instance.system, instance.box, instance.initial_mode, instance.unsafe, o["horizon"], step)


def _nln_rows(quick: bool, repeats: int) -> tuple[list[dict[str, Any]], str | None]:
    path = HERE / "reach_nln.py"
    if not path.exists():
        return [], "benchmarks/reach_nln.py is absent: no nonlinear rows"
    spec = importlib.util.spec_from_file_location("reach_nln", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)

    rows = []
    for item in getattr(module, "INSTANCES", []):
        # reach_nln's own runner: reach_proof (its splits) and the independent re-check; safe only when both hold
        outs = [module.run_instance(item) for _ in range(max(1 if quick else repeats, 1))]
        out = outs[-1]
        safe = bool(out["holds"] and out["rechecked"])
        ours = {"verdict": "safe" if safe else "unknown", "seconds": statistics.median(o["seconds"] for o in outs),
                "width": None, "margin": out["margin"]}
        if not safe:
            ours["reason"] = out["evidence"]
        rows.append({"name": item["name"], "ours": ours, "published": None, "published_nln": item.get("published"),
                     "kind": "nonlinear"})
    return rows, None


def run(names: list[str], *, repeats: int, soundness: int, peers: bool, closed_form: bool = False) -> dict[str, Any]:
    """Every instance's row (see the module docstring)."""
    from reach_soundness import planted, simulations_inside

    rows = []
    for name in names:
        instance = ri.BUILDERS[name]()
        ours, result = run_ours(instance, repeats)
        row: dict[str, Any] = {"name": name, "expected": ri.EXPECTED[name], "ours": ours,
                               "published": [vars_of(p) for p in ri.PUBLISHED.get(name, ())], "note": instance.note}
        if peers:
            row["hylaa"] = run_hylaa(instance)
            h = row["hylaa"]
            row["ratio"] = ours["seconds"] / h["seconds"] if h.get("verdict") and h["seconds"] else None
        if soundness > 0:
            row["planted"] = planted(instance, result)
            if result.status == "complete":
                row["simulations"] = simulations_inside(instance, result, soundness, seed=sum(map(ord, name)),
                                                         closed_form=closed_form)
        rows.append(row)
    return {"rows": rows}


def vars_of(p: ri.Published) -> dict[str, Any]:
    return {"tool": p.tool, "verdict": p.verdict, "report": p.report, "seconds": p.seconds}


def _fmt(v: Any, spec: str = ".3g") -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def table(doc: dict[str, Any]) -> str:
    """The printed table."""
    head = (f"{'instance':<15} {'ours':<8} {'time s':>8} {'width':>9} {'margin':>9} {'hylaa':<7} {'time s':>8} "
            f"{'ratio':>6}  "
            f"{'published (CORA / JuliaReach; ARCH-COMP19 AFF, different machine)':<40} {'soundness'}")
    lines = [head, "-" * len(head)]
    for row in doc["rows"]:
        o, h = row["ours"], row.get("hylaa") or {}
        pub = " / ".join(f"{p['tool']} {p['verdict']} {_fmt(p['seconds'])}s" for p in row.get("published") or [])
        if row.get("published_nln"):  # reach_nln's figure: one tool, its report, a runtime or None
            p = row["published_nln"]
            pub = f"{p['tool']} {p['verdict']} {_fmt(p.get('runtime_s'))}s ({p['report']})"
        sims = row.get("simulations")
        sound = ""
        if "planted" in row:
            p = row["planted"]
            sound = (f"planted inside proven {len(p['inside_proven'])}/{p['inside']}, "
                     f"outside proven {p['outside_proven']}/{p['outside']}")
        if sims:
            sound += f"; {sims['runs']} runs, {sims['outside']}/{sims['points']} points outside"
        lines.append(f"{row['name']:<15} {o['verdict']:<8} {_fmt(o['seconds']):>8} {_fmt(o.get('width')):>9} "
                     f"{_fmt(o.get('margin'), '.4g'):>9} "
                     f"{str(h.get('verdict') or '-'):<7} {_fmt(h.get('seconds')):>8} "
                     f"{_fmt(row.get('ratio'), '.2f'):>6}  "
                     f"{pub or '(not an ARCH-COMP instance: closed form)':<40} {sound}")
    notes = [f"  {r['name']}: {r['ours']['reason']}" for r in doc["rows"] if r["ours"]["verdict"] != "safe"
             and "reason" in r["ours"]]
    notes += [f"  {r['name']}: hylaa: {r['hylaa']['note']}" for r in doc["rows"] if r.get("hylaa")
              and not r["hylaa"].get("verdict")]
    if doc.get("nln_note"):
        notes.append(f"  {doc['nln_note']}")
    return "\n".join(lines + (["notes:"] + notes if notes else []))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the small instances only (CI)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    parser.add_argument("--repeats", type=int, default=3, help="runs per instance (median time)")
    parser.add_argument("--soundness", type=int, default=0, metavar="N",
                        help="N executor runs per instance against the flowpipe, and the planted sets")
    parser.add_argument("--closed-form", action="store_true",
                        help="--soundness runs with the executor's closed form of affine modes instead of RK45")
    parser.add_argument("--no-peers", action="store_true", help="do not run Hylaa")
    parser.add_argument("--only", action="append", choices=list(ri.BUILDERS), help="run this instance (repeatable)")
    args = parser.parse_args(argv)
    names = args.only or (list(ri.QUICK) if args.quick else list(ri.BUILDERS))
    doc = run(names, repeats=args.repeats, soundness=args.soundness, peers=not args.no_peers,
              closed_form=args.closed_form)
    nln, note = _nln_rows(args.quick, args.repeats)
    doc["rows"].extend(nln)
    doc["nln_note"] = note
    print(json.dumps(doc, indent=1, sort_keys=True, default=float) if args.json else table(doc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
