"""The ARCH-COMP AFF instances shipped as SpaceEx files: visnav's verdict next to the published one, with times.

Run: ``.venv/bin/python benchmarks/bench_spaceex_arch.py [--budget N] [--only NAME] [--quick] [--json]``.
``--quick`` runs the instances that take seconds (:data:`QUICK`, budget 8 unless given): CI runs it
(``tests/benchmarks/test_bench_spaceex_arch.py``); ``--json`` prints the rows as JSON instead of the table.

Each instance is verified as ``visnav verify FILE.xml --config FILE.cfg`` does (the guided search with the
budget, seed 0, and the reachability proofs the problem carries).  The instances that take minutes (the
building's searches, PLAN01's cycle induction) are here rather than in the tests.  The table says, per
instance, the published verdict, visnav's, whether a flowpipe decided it and whether that was re-checked, and
the seconds.  A row whose verdict differs from the published one is marked ``DIFFERS`` with its reason (see
docs/spaceex.md, "Published verdicts").
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "tests" / "data" / "spaceex" / "arch2017"
B, P, S = ROOT / "Building" / "SpaceEx", ROOT / "Platoon" / "SpaceEx", ROOT / "specs"

# name, model, cfg, published verdict, the verdict visnav can give and why it may differ
INSTANCES = (
    ("BLDC01-BDS01", B / "BLDC01.xml", B / "BLDC01-BDS01.cfg", "safe", "proven",
     "merged boxes, the own re-check in a modal basis (minutes)"),
    ("BLDF01-BDS01", B / "BLDF01.xml", B / "BLDF01-BDS01.cfg", "safe", "proven",
     "the sub-stepped input set, the input's rounding errors in the eigenbasis (minutes)"),
    ("BLDF01-BDU01", B / "BLDF01.xml", B / "BLDF01-BDU01.cfg", "unsafe", "falsified", ""),
    ("BLDC01-BDU01", B / "BLDC01.xml", S / "BLDC01-BDU01.cfg", "unsafe", "falsified", ""),
    ("BLDC01-BDU02", B / "BLDC01.xml", S / "BLDC01-BDU02.cfg", "unsafe", "falsified", ""),
    ("BLDF01-BDU02", B / "BLDF01.xml", S / "BLDF01-BDU02.cfg", "unsafe", "falsified", ""),
    ("PLAD01-BND42", P / "PLAD01-BND.xml", S / "PLAD01-BND42.cfg", "safe", "proven", "zonotope jump sets"),
    ("PLAD01-BND30", P / "PLAD01-BND.xml", S / "PLAD01-BND30.cfg", "safe", "proven",
     "zonotope jump sets whose union pairs the input sums' columns (docs/spaceex.md)"),
    ("PLAA01-BND42", P / "PLAA01-BND.xml", S / "PLAA01-BND42.cfg", "safe", "proven",
     "arbitrary switching: the relaxation's flowpipe, re-checked on its own sets (the runs end Zeno at t = 0)"),
    ("PLAN01-UNB50", P / "PLAN01-UNB.xml", S / "PLAN01-UNB50.cfg", "safe", "proven",
     "unbounded (time-horizon = -1): the relaxation's induction, the clock projected out (about 16 min CPU)"),
    ("GRBX01-MES01", ROOT / "Gear" / "SpaceEx" / "GRBX01-MES01.xml", ROOT / "Gear" / "SpaceEx" / "GRBX01-MES01.cfg",
     "safe", "proven", "every location initial, each flowpipe re-checked"),
)

QUICK = ("BLDC01-BDU02", "BLDF01-BDU02", "PLAD01-BND42", "PLAA01-BND42", "GRBX01-MES01")
"""The instances decided in seconds (a falsification at the first simulations, or a proof of a few seconds)."""


def main() -> None:
    from analysis.spaceex import spaceex_problem
    from analysis.verify.verdicts import verify

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", type=int, default=None, help="simulations per instance (default: verify's 120, "
                                                                     "8 with --quick)")
    parser.add_argument("--only", default=None, help="run one instance (its name)")
    parser.add_argument("--quick", action="store_true", help=f"only {', '.join(QUICK)}")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = parser.parse_args()
    budget = args.budget if args.budget is not None else (8 if args.quick else 120)
    rows = []
    if not args.json:
        print(f"{'instance':14} {'published':9} {'visnav':14} {'flowpipe':34} {'seconds':>8}")
    for name, xml, cfg, published, expected, why in INSTANCES:
        if (args.only and name != args.only) or (args.quick and name not in QUICK):
            continue
        start = time.perf_counter()
        result = verify(spaceex_problem(xml, cfg), budget=budget, seed=0)
        seconds = time.perf_counter() - start
        proof = result.requirement("safe").proof
        pipe = "none" if proof is None else f"{'holds' if proof.holds else 'undecided'}, " \
                                            f"{'re-checked' if proof.rechecked else 'not re-checked'}"
        verdict = result.requirement("safe").verdict
        note = "" if verdict == expected else f"  UNEXPECTED (expected {expected})"
        differs = "" if (published == "safe") == (verdict in ("proven", "not_falsified")) else f"  DIFFERS: {why}"
        rows.append({"instance": name, "published": published, "verdict": verdict, "expected": expected,
                     "flowpipe": pipe, "margin": None if proof is None else proof.margin, "seconds": seconds})
        if not args.json:
            print(f"{name:14} {published:9} {verdict:14} {pipe:34} {seconds:8.1f}{note}{differs}", flush=True)
    if args.json:
        print(json.dumps({"budget": budget, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
