"""``visnav stiffness``: the BDF stiffness study of equation (13) from the command line.

Registered by :func:`visnav.app.cli.build_parser` through :func:`add_parser`.
Prints a human summary, or with ``--json`` one JSON object (deterministic for
a given scenario and seed; wall-clock times only with ``--timing``); with
``--out DIR`` writes ``stiffness.json`` (always with the wall-clock times) and
the four figures there.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_OK, non_negative_int

__all__ = ["add_parser", "cmd_stiffness", "human_summary"]




def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register the ``stiffness`` subcommand on ``sub`` (the parser's subparsers action)."""
    cmd = sub.add_parser(
        "stiffness",
        help="is (13) stiff, does the BDF matter: stability regions, eigenvalues along the run, accuracy and cost",
    )
    cmd.add_argument("--scenario", default="paper", help="built-in scenario name or path to a TOML file (default: paper)")
    cmd.add_argument("--json", action="store_true", help="print the study as one JSON object")
    cmd.add_argument("--out", default=None, help="folder for stiffness.json and the figures (PNG)")
    cmd.add_argument("--seed", type=int, default=0, help="seed of the random scenarios (default: 0)")
    cmd.add_argument("--random", type=non_negative_int, default=None,
                     help="number of random scenarios (default: 6, or 2 with --quick)")
    cmd.add_argument("--quick", action="store_true",
                     help="fewer steps, tolerances, timing repeats and random scenarios (a few seconds)")
    cmd.add_argument("--timing", action="store_true",
                     help="include the wall-clock times in the JSON (they differ from run to run)")
    cmd.set_defaults(func=cmd_stiffness)
    return cmd


def _fmt(value: Any, spec: str = ".3g") -> str:
    if value is None:
        return "none"
    if isinstance(value, float) and math.isinf(value):
        return "inf"
    return format(value, spec)


def human_summary(d: dict[str, Any], written: list[str]) -> str:
    """The human-readable summary of :meth:`StiffnessStudy.as_dict` (``include_timing`` optional)."""
    ans = d["answer"]
    paper = d["stiffness"]["paper"]
    where = paper["where_fastest"]
    stab = d["stability"]
    lines = [
        f"stiffness {d['scenario']} ({d.get('scenario_digest', '')[:12]}): is (13) stiff here? "
        f"{'YES' if ans['stiff'] else 'NO'}: max |h lambda| = {_fmt(ans['max_abs_h_lambda'])} at h = "
        f"{d['period_s']:g} s",
        "  A(alpha) of BDF1-6 [deg]  " + ", ".join(
            f"{row['alpha_deg']:.4f} ({row['error_deg']:+.4f})" for row in stab["a_alpha"].values()
        ) + "  (vs published)",
        f"  BDF7                      parasitic root |zeta| = {stab['zero_stability']['7']['max_parasitic_modulus']:.4f}"
        f" > 1: not zero-stable",
        "  real stability intervals  " + ", ".join(
            f"{k} [{v:.4g}, 0]" for k, v in stab["real_stability_interval"].items()
        ),
        f"  along the run             {paper['samples']} samples: spectral radius <= "
        f"{_fmt(paper['max_spectral_radius_per_s'])} 1/s (t = {where['t_s']:.2f} s, point {where['point']}, depth "
        f"{where['depth_m']:.2f} m); stiffness ratio <= {_fmt(paper['max_stiffness_ratio'])} (raw Lambert "
        f"{_fmt(paper['max_lambert_ratio'])}); min depth {paper['min_depth_m']:.2f} m",
        f"  explicit RK4              stays stable up to h = "
        f"{_fmt(paper['schemes']['rk4']['first_unstable_step_s'])} s (searched to "
        f"{paper['schemes']['rk4']['searched_up_to_s']:g} s; none = never)",
    ]
    rnd = d["stiffness"]["random"]
    lines.append(
        f"  random scenarios          seed {rnd['seed']}: {rnd['with_reconstruction']} of {rnd['count']} reconstruct; "
        f"max |h lambda| = {_fmt(rnd['max_abs_h_lambda'])}, max stiffness ratio {_fmt(rnd['max_stiffness_ratio'])}"
    )
    worst = d["stiffness"]["worst_case_within_limits"]["stiff_below_depth_m"]
    lines.append("  worst case within limits  stiff (h*decay beyond the real interval) below depth: " + ", ".join(
        f"{k} {_fmt(v)} m" for k, v in worst.items() if k in ("euler", "rk4", "abm4")
    ))
    lines.append("  observed order (orbit)    " + ", ".join(
        f"{k} {v:.3f}" for k, v in d["observed_order"].items()
    ))
    lines.append("  observed order (occlusion) " + ", ".join(
        f"{k} {_fmt(v, '.3f')}" for k, v in d["observed_order_paper_problem"].items()
    ))
    comps = d["reconstruction_components"]
    floor = comps["sampling_floor"]
    lines.append(
        f"  reconstruction at h = {d['period_s']:g} s over the {comps['window']['duration_s']:.2f} s occlusion "
        f"[px / mm]; sampling floor of the smooth input {floor['max_error_px']:.3g} / {floor['max_depth_error_mm']:.3g}"
    )
    for scheme, row in d["reconstruction"].items():
        lines.append(
            f"    {scheme:<13} total {row['max_error_px']:.3g} / {row['max_depth_error_mm']:.3g}   truncation "
            f"{row['truncation_error_px']:.3g} / {row['truncation_error_mm']:.3g}   ({row['evaluations']} evaluations)"
        )
    est = comps["estimator"]
    lines.append("  estimator BDF4 by screw model [px / mm]  " + ", ".join(
        f"{m} {est[m]['bdf4']['max_error_px']:.3g} / {est[m]['bdf4']['max_depth_error_mm']:.3g}" for m in est
    ))
    zoh = comps["zoh_rk4"]["substeps_1"]
    lines.append(
        f"  RK4 on the exact ZOH screw, one step per period: {zoh['max_error_px']:.3g} px / "
        f"{zoh['max_depth_error_mm']:.3g} mm"
    )
    if "timing" in d:
        front = d["timing"].get("pareto_front", [])
        lines.append("  Pareto front (wall time)  " + ", ".join(
            f"{p['scheme']}[{p['index']}] {p['wall_s'] * 1e3:.1f} ms -> {p['error']:.2g}" for p in front
        ))
    lines += [f"  wrote {path}" for path in written]
    return "\n".join(lines)


def cmd_stiffness(args: argparse.Namespace) -> int:
    """Run the study for ``args`` and print or write it; returns the exit code."""
    import dataclasses

    from visnav.app.files import prepare_output_dir, write_figures, write_text_atomic
    from visnav.scenario import load_scenario, scenario_digest
    from visnav.studies.stiffness import QUICK_SETTINGS, StiffnessStudyError, StudySettings, stiffness_study

    scenario = load_scenario(args.scenario)
    folder = prepare_output_dir(args.out) if args.out else None
    settings = QUICK_SETTINGS if args.quick else StudySettings()
    changes: dict[str, Any] = {"seed": args.seed}
    if args.random is not None:
        changes["random_scenarios"] = args.random
    try:
        settings = dataclasses.replace(settings, **changes)
        study = stiffness_study(scenario, settings)
    except StiffnessStudyError as err:
        print(f"visnav: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    out = study.as_dict(include_timing=args.timing)
    out["scenario_digest"] = scenario_digest(scenario)
    written: list[str] = []
    if folder is not None:
        from visnav.app.figures_stiffness import stiffness_figures

        full = study.as_dict(include_timing=True)
        full["scenario_digest"] = out["scenario_digest"]
        write_text_atomic(folder / "stiffness.json", json.dumps(full, indent=2, sort_keys=True) + "\n")
        written.append(str(folder / "stiffness.json"))
        written += [str(path) for path in write_figures(folder, stiffness_figures(study)).values()]
    if args.json:
        print(json.dumps(out, sort_keys=True))
    else:
        if "timing" not in out:
            out["timing"] = study.as_dict(include_timing=True)["timing"]
        print(human_summary(out, written))
    return EXIT_OK
