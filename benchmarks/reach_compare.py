"""Two source trees of visnav side by side on the reachability benchmark: wall and CPU time, verdict, width, margin.

Run from a worktree: ``git archive BASE | tar -x -C /tmp/before`` (the tree to compare with), then
``PYTHONPATH=$PWD python benchmarks/reach_compare.py --before /tmp/before [--repeats 3] [--only NAME ...]``.

Per instance of ``reach_instances.py`` (and the two nonlinear ones of ``reach_nln.py``, named ``nln:VDP`` and
``nln:LOVO``) the two trees are run one after the other in fresh processes (before, then after: the same load for
both), each ``--repeats`` times; the medians of the wall clock and of the process's CPU time are printed (on a
shared machine the CPU time is the steadier figure; the load average is printed after each pair).  Hylaa runs
with the current tree when the peers are on ``PYTHONPATH`` (``bench_reach.py``'s module docstring).  Nonlinear rows:
the flowpipes of every piece of the split (``flowpipe_seconds``) and the verdict with its re-check
(``run_instance``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
NLN = ("nln:VDP", "nln:LOVO")


def measure(tree: str, name: str, repeats: int, peers: bool) -> dict[str, Any]:
    """One instance with the tree's code (run in a child process: ``--child``)."""
    sys.path[:0] = [str(Path(tree) / "benchmarks"), tree]
    if name in NLN:
        import reach_nln

        inst = next(i for i in reach_nln.INSTANCES if i["name"].startswith(name[4:]))
        flow, cpu, outs, vcpu = [], [], [], []
        for _ in range(repeats):
            c = time.process_time()
            flow.append(reach_nln.flowpipe_seconds(inst))
            cpu.append(time.process_time() - c)
            c = time.process_time()
            outs.append(reach_nln.run_instance(inst))
            vcpu.append(time.process_time() - c)
        safe = bool(outs[-1]["holds"] and outs[-1]["rechecked"])
        return {"verdict": "safe" if safe else "unknown", "wall": statistics.median(flow),
                "cpu": statistics.median(cpu), "with_recheck_wall": statistics.median(o["seconds"] for o in outs),
                "with_recheck_cpu": statistics.median(vcpu), "margin": outs[-1]["margin"]}
    import bench_reach
    import reach_instances
    from analysis.reach import reach

    inst = reach_instances.BUILDERS[name]()
    walls, cpus, result = [], [], None
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        result = reach(inst.system, inst.box, initial_mode=inst.initial_mode, **inst.options)
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
        if walls[-1] > bench_reach.LONG_RUN:
            break
    verdict, margin, _ = bench_reach._verdict(inst, result)
    out = {"verdict": verdict, "wall": statistics.median(walls), "cpu": statistics.median(cpus), "runs": len(walls),
           "width": bench_reach._width(result), "margin": margin, "segments": len(result.segments)}
    if peers:
        out["hylaa"] = bench_reach.run_hylaa(inst)
    return out


def _child(tree: str, name: str, repeats: int, peers: bool) -> dict[str, Any]:
    env = dict(os.environ)
    paths = [tree] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and ".peers" in p]
    env["PYTHONPATH"] = os.pathsep.join(paths)
    args = [sys.executable, str(Path(__file__).resolve()), "--child", tree, name, str(repeats)]
    args += ["--peers"] if peers else []
    done = subprocess.run(args, capture_output=True, text=True, env=env, timeout=3600)
    if done.returncode != 0:
        return {"verdict": "error", "error": done.stderr[-500:]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def _fmt(v: Any, spec: str = ".3g") -> str:
    return "-" if v is None else format(v, spec)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", help="the source tree to compare with (e.g. a git archive of the base commit)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", action="append", help="an instance name, or nln:VDP / nln:LOVO (repeatable)")
    parser.add_argument("--child", nargs=3, metavar=("TREE", "NAME", "REPEATS"), help=argparse.SUPPRESS)
    parser.add_argument("--peers", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        tree, name, repeats = args.child
        print(json.dumps(measure(tree, name, int(repeats), args.peers), default=float))
        return 0
    if not args.before:
        parser.error("--before is required")
    sys.path.insert(0, str(HERE))
    import reach_instances

    after = str(HERE.parent)
    names = args.only or [*reach_instances.BUILDERS, *NLN]
    print(f"{'instance':<15} {'verdict b/a':<13} {'wall s b/a':<15} {'cpu s b/a':<15} {'width b/a':<17} "
          f"{'margin b/a':<19} {'hylaa s':>8} {'ratio':>6}  load")
    for name in names:
        b = _child(args.before, name, args.repeats, False)
        a = _child(after, name, args.repeats, name not in NLN)
        h = a.get("hylaa") or {}
        ratio = a["wall"] / h["seconds"] if h.get("verdict") and h.get("seconds") else None
        load = os.getloadavg()[0]
        print(f"{name:<15} {b['verdict'] + '/' + a['verdict']:<13} "
              f"{_fmt(b.get('wall')) + ' / ' + _fmt(a.get('wall')):<15} "
              f"{_fmt(b.get('cpu')) + ' / ' + _fmt(a.get('cpu')):<15} "
              f"{_fmt(b.get('width')) + ' / ' + _fmt(a.get('width')):<17} "
              f"{_fmt(b.get('margin'), '.4g') + ' / ' + _fmt(a.get('margin'), '.4g'):<19} {_fmt(h.get('seconds')):>8} "
              f"{_fmt(ratio, '.2f'):>6}  {load:.1f}", flush=True)
        if name in NLN:
            print(f"{'':<15} with re-check: wall {_fmt(b.get('with_recheck_wall'))} / "
                  f"{_fmt(a.get('with_recheck_wall'))} s, "
                  f"cpu {_fmt(b.get('with_recheck_cpu'))} / {_fmt(a.get('with_recheck_cpu'))} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
