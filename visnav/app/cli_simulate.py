"""``visnav simulate``: run a scenario's closed loop, write its data and figures."""

from __future__ import annotations

import argparse
import csv
import io
import json
from typing import Any

from visnav.app.cli_types import EXIT_OK, EXIT_TASK_FAILED

__all__ = ["add_parser"]


def add_parser(sub: Any) -> None:
    """Register the subcommand on ``visnav``'s subparsers."""
    sim = sub.add_parser("simulate", help="run a scenario's closed loop, write its data and figures")
    sim.add_argument("--scenario", default="paper", help="built-in scenario name or path to a TOML file (default: paper)")
    sim.add_argument("--out", default=None, help="folder for trajectory.csv, summary.json and the figures")
    sim.add_argument("--json", action="store_true", help="print one JSON object instead of the human summary")
    sim.add_argument("--no-figures", action="store_true", help="skip the figures (data and summary only)")
    sim.set_defaults(func=_cmd_simulate)


def _summary(result: Any, digest: str) -> dict[str, Any]:
    out = {"scenario": result.scenario.name, "scenario_digest": digest}
    out.update(result.metrics.as_dict())
    out["wall_time_s"] = result.wall_time_s
    out["real_time_factor"] = result.metrics.sim_time_s / result.wall_time_s if result.wall_time_s > 0 else None
    return out


def _trajectory_csv(result: Any) -> str:
    trace = result.trace
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    header = ["t_s", "jump", "mode", *trace.state_names, *trace.input_names, *trace.variable_names, *trace.record_names]
    writer.writerow(header)
    for k in range(len(trace.times)):
        row: list[Any] = [repr(float(trace.times[k])), int(trace.jumps[k]), trace.mode_names[int(trace.modes[k])]]
        for block in (trace.states[k], trace.inputs[k], trace.signals[k], trace.records[k]):
            row.extend(repr(float(v)) for v in block)
        writer.writerow(row)
    return buffer.getvalue()


def _human(summary: dict[str, Any], written: list[str]) -> str:
    def fmt(value: Any) -> str:
        if isinstance(value, float):
            return f"{value:.6g}"
        if value is None:
            return "inf"
        return str(value)

    lines = [
        f"scenario {summary['scenario']} ({summary['scenario_digest'][:12]}): {summary['termination']}",
        f"  success                     {fmt(summary['success'])}",
        f"  collided                    {fmt(summary['collided'])}",
        f"  min clearance               {fmt(summary['min_clearance_m'])} m",
        f"  final feature error         {fmt(summary['final_feature_error_px'])} px",
        f"  occlusion (>=1 hidden)      {fmt(summary['occlusion_duration_s'])} s"
        f"  (all hidden {fmt(summary['all_hidden_duration_s'])} s)",
        f"  max |s - s~| while hidden   {fmt(summary['max_reconstruction_error_px'])} px",
        f"  max |z - z~| while hidden   {fmt(summary['max_depth_error_mm'])} mm",
        f"  max |v|, |w|, |pan rate|    {', '.join(fmt(v) for v in summary['max_abs_input'])}"
        f"  (within limits: {summary['within_actuator_limits']})",
        f"  transitions                 {len(summary['transitions'])}  (chatter: {summary['chatter_count']})",
        f"  modes visited               {' -> '.join(summary['modes_visited'])}",
        f"  simulated {fmt(summary['sim_time_s'])} s in {summary['steps']} steps, "
        f"wall {fmt(summary['wall_time_s'])} s ({fmt(summary['real_time_factor'])}x real time)",
    ]
    lines += [f"  wrote {path}" for path in written]
    return "\n".join(lines)


def _cmd_simulate(args: argparse.Namespace) -> int:
    from visnav.app.files import prepare_output_dir, write_figures, write_text_atomic
    from visnav.scenario import load_scenario, scenario_digest
    from visnav.simulation import simulate

    scenario = load_scenario(args.scenario)
    folder = prepare_output_dir(args.out) if args.out else None
    result = simulate(scenario)
    summary = _summary(result, scenario_digest(scenario))
    written: list[str] = []
    if folder is not None:
        write_text_atomic(folder / "trajectory.csv", _trajectory_csv(result))
        write_text_atomic(folder / "summary.json", json.dumps(summary, indent=2, sort_keys=True) + "\n")
        written += [str(folder / "trajectory.csv"), str(folder / "summary.json")]
        if not args.no_figures:
            from visnav.app.figures import paper_figures

            written += [str(path) for path in write_figures(folder, paper_figures(result)).values()]
    if args.json:
        print(json.dumps(summary, sort_keys=True))
    else:
        print(_human(summary, written))
    return EXIT_OK if summary["success"] else EXIT_TASK_FAILED
