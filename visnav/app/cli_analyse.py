"""``visnav analyse``: linearisation, Lyapunov and SOS certificates, admissible gains, margins; or a
problem's stability analysis."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from visnav.app.cli_verify import user_problem
from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_INCOMPLETE, EXIT_OK, EXIT_TASK_FAILED

__all__ = ["add_parser"]


def add_parser(sub: Any) -> None:
    """Register the subcommand on ``visnav``'s subparsers."""
    ana = sub.add_parser("analyse", help="linearisation, Lyapunov certificate, admissible gains, stability margins")
    ana.add_argument("--scenario", default="paper", help="built-in scenario name or path to a TOML file")
    ana.add_argument("--problem", default=None, metavar="SPEC",
                     help="the stability analysis of a verification problem instead (PKG.MOD:OBJ or FILE.py:OBJ, "
                          "built with hybrid_problem(..., stability=True)): equilibria against their modes, LMI "
                          "certificates, periodic orbits")
    ana.add_argument("--clearance", type=float, default=None,
                     help="clearance [m] the admissible gains must guarantee (default: 0.1)")
    ana.add_argument("--sos", choices=("scan", "scenario", "off"), default="scan",
                     help="the sum-of-squares study of path following: with the scan of k (default, about 20 s), "
                          "at the scenario's k only (about 10 s), or off")
    ana.add_argument("--json", action="store_true", help="print the analysis as one JSON object")
    ana.add_argument("--out", default=None, help="folder for analysis.json and the figures (Bode, Nyquist, "
                                                 "margins and eigenvalues against the gains)")
    ana.set_defaults(func=_cmd_analyse)


def _sos_human(sos: dict[str, Any] | None) -> list[str]:
    """The SOS study's lines of ``visnav analyse`` (beside the hand-given V's)."""
    if sos is None:
        return ["  SOS study                   left out (--sos off)"]
    region = sos["region"]
    lines = [f"  SOS region (degree {region['degree']})       {region['status'].upper()}: {{V <= 1}} invariant, area "
             f"{region['area_ratio']:.4g} x the hand-given sublevel set ({region['boxes']} boxes; {region['why']})"]
    for b in sos["bypass"]:
        hand, best = b["hand_closed_form"]["nominal"], b["combined"]
        lines.append(f"  SOS bypass alpha0 = {b['alpha0_rad']:.4g}  {b['status'].upper()}: |delta| <= "
                     f"{best['delta_max_m']:.4g} m (clearance >= {best['min_distance_m']:.4g} m), |omega| <= "
                     f"{best['omega_max_radps']:.4g} rad/s (hand V: {hand['delta_max_m']:.4g} m, "
                     f"{hand['omega_max_radps']:.4g} rad/s)")
    lines.append(f"  SOS admissible k            {sos['admissible']['finding']}"
                 + ("" if sos["scan"] else " (--sos scenario: only the scenario's k judged)"))
    return lines


def _analyse_human(d: dict[str, Any]) -> str:
    pf = d["path_following"]
    lyap = pf["lyapunov"]
    par = pf["parameters"]
    eig = ", ".join(f"{re:.6g}" + (f"{im:+.6g}j" if im else "") for re, im in pf["eigenvalues"])
    region = ", ".join(f"{n} in [{lo:.4g}, {hi:.4g}]" for n, (lo, hi) in lyap["region"].items())
    lines = [
        f"analyse {d['scenario']}: path following k = {par['k']:g} 1/m, v_coll = {par['v_coll_mps']:g} m/s",
        f"  eigenvalues (AD)            {eig}   [{pf['finding']}]",
        f"  V = k d^2/2 + 1 - cos(a):   V' = {lyap['normal_form']}",
        f"  certificate                 {'PROVEN' if lyap['certified'] else 'NOT PROVEN'} V' <= 0 on {region} "
        f"({lyap['boxes']} boxes, interval branch and bound)",
        f"  LaSalle                     {lyap['lasalle']}",
    ]
    for entry, bound in zip(pf["entry_states"], pf["entry_bounds"]):
        lines.append(
            f"  entry {entry['obstacle']:<8} (sampled)  alpha0 = {entry['alpha_rad']:.4g} rad: |delta| <= "
            f"{bound['delta_max_m']:.4g} m (closest {bound['min_distance_m']:.4g} m), |omega| <= "
            f"{bound['omega_max_radps']:.4g} rad/s"
        )
    lines.append(f"  admissible k                {pf['admissible']['finding']}")
    lines += _sos_human(pf["sos"])
    sw = pf["switched"]
    lines.append(f"  switched family             {sw['finding']} [{sw['claim'].upper()}: {sw['recheck']['method']}] "
                 f"({sw['family']})")
    goal = d["goal"]
    task = ", ".join(f"{re:.6g}" for re, _ in goal["visual_servoing_task"]["eigenvalues"])
    full = ", ".join(f"{re:.3g}" for re, _ in goal["closed_loop"]["eigenvalues"])
    lines += [
        f"  goal: e_VS task (7)         eigenvalues {task} (closed form {goal['visual_servoing_task']['closed_form'][0]:g})",
        f"  goal: full loop (x,y,th,pan) eigenvalues {full}: {goal['closed_loop']['finding'].split(';')[0]}",
        f"                              zero mode {[round(c, 4) for c in goal['closed_loop']['zero_mode'] or []]} moves "
        f"the camera by {goal['closed_loop']['zero_mode_camera_motion'] or 0:.2g}: curve of equilibria (camera at "
        "its goal pose, base turned about it)",
        f"  goal: pan task (16)         eigenvalue {goal['pan_task']['eigenvalues'][0][0]:.6g}, "
        f"|e_gc' + lambda_gc e_gc| <= {goal['pan_task']['closure_residual']:.2g} along the way",
    ]
    for key, curve in d["margins_vs_gains"].items():
        gain_name = next(k for k in curve if k in ("k", "lambda_gc", "lambda_vs"))
        sampled = curve["sampled"]["stable_gain_range"]
        limit = curve["sampled"]["stability_limit"]
        grid = curve[gain_name]
        lines.append(
            f"  {key:<27} sampled loop stable for {gain_name} in "
            + (f"[{sampled[0]:.3g}, {sampled[1]:.3g}]" if sampled else "none")
            + f" of the grid [{grid[0]:.3g}, {grid[-1]:.3g}]"
            + (f"; unstable above {limit:.6g}" if limit is not None else "")
        )
    lines.append(f"  margins (continuous | sampled T = {d['sampling_period_s']:g} s, ZOH + 1 sample delay)")

    def fmt(value: Any, unit: str) -> str:
        return "inf" if value is None else f"{value:.4g}{unit}"

    for name, pair in d["margins"].items():
        c, s = pair["continuous"], pair["sampled"]
        lines.append(
            f"    {name:<12} GM {fmt(c['gain_margin_db'], ' dB'):>11} | {fmt(s['gain_margin_db'], ' dB'):>10}   "
            f"PM {fmt(c['phase_margin_deg'], '°'):>7} | {fmt(s['phase_margin_deg'], '°'):>7}   "
            f"DM {fmt(c['delay_margin_s'], ' s'):>9} | {fmt(s['delay_margin_s'], ' s'):>9}"
        )
    return "\n".join(lines)


def _stability_human(d: dict[str, Any]) -> str:
    lines = [f"analyse {d['system']}: {d['verdict'].upper()}"]
    lines += [f"  {c['status'].upper():<12} {c['text']}" + ("" if c["status"] != "not decided" else f" [{c['method']}]")
              for c in d["claims"]]
    orbit = d["orbit"]
    if orbit is not None:
        lines.append(f"  orbit: period {orbit['period']:.10g} s through {orbit['section']!r}, nontrivial multipliers "
                     f"{orbit['nontrivial_multipliers']}")
    return "\n".join(lines)


def _cmd_analyse_problem(args: argparse.Namespace) -> int:
    from visnav.app.figures_verification import orbit_figure
    from visnav.app.files import prepare_output_dir, write_figures, write_text_atomic
    from visnav.app.ownership import anchored

    problem = user_problem(args.problem)
    if isinstance(problem, int):
        return problem
    if problem.stability is None:
        print(f"visnav: error: --problem {args.problem}: the problem {problem.name!r} has no stability analysis; "
              "expected a problem built with hybrid_problem(..., stability=True) (or a stability callable); "
              "fix: add stability=True where the problem is built", file=sys.stderr)
        return EXIT_BAD_INPUT
    # anchored where the command started: the user's module (imported above) may have changed the folder
    folder = prepare_output_dir(anchored(args, args.out)) if args.out else None
    analysis = problem.stability()
    out = analysis.as_dict()
    written = []
    if folder is not None:
        write_text_atomic(folder / "stability.json", json.dumps(out, indent=1, sort_keys=True) + "\n")
        written.append(str(Path(args.out) / "stability.json"))
        if analysis.orbit is not None:
            figures = write_figures(folder, {"stability_orbit": orbit_figure(analysis.orbit)})
            written += [str(Path(args.out) / p.name) for p in figures.values()]
    if args.json:
        print(json.dumps(out, sort_keys=True))
    else:
        print(_stability_human(out) + "".join(f"\n  wrote {path}" for path in written))
    # a stability that was not decided is never a pass: incomplete (5); an unstable system is a finding (1)
    return {"stable": EXIT_OK, "unstable": EXIT_TASK_FAILED}.get(analysis.verdict, EXIT_INCOMPLETE)


def _cmd_analyse(args: argparse.Namespace) -> int:
    from visnav.studies.loop_analysis import DEFAULT_CLEARANCE_M, analyse
    from visnav.scenario import load_scenario, scenario_digest

    from visnav.app.files import prepare_output_dir, write_figures, write_text_atomic

    if args.problem is not None:
        return _cmd_analyse_problem(args)
    scenario = load_scenario(args.scenario)
    folder = prepare_output_dir(args.out) if args.out else None
    clearance = DEFAULT_CLEARANCE_M if args.clearance is None else args.clearance
    try:
        result = analyse(scenario, clearance_m=clearance, sos=args.sos)
    except ValueError as err:
        print(f"visnav: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    out = result.as_dict()
    out["scenario_digest"] = scenario_digest(scenario)
    written = []
    if folder is not None:
        from visnav.app.figures_analysis import analysis_figures

        write_text_atomic(folder / "analysis.json", json.dumps(out, indent=1, sort_keys=True) + "\n")
        written.append(str(folder / "analysis.json"))
        written += [str(path) for path in write_figures(folder, analysis_figures(out)).values()]
    if args.json:
        print(json.dumps(out, sort_keys=True))
    else:
        print(_analyse_human(out) + "".join(f"\n  wrote {path}" for path in written))
    return EXIT_OK
