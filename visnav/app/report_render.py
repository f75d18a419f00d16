"""Render a report's data as Markdown and as self-contained HTML.

Both renderers consume the same list of blocks built by :func:`report_blocks`
from ``report.json``'s content, so the two documents say the same things.
The HTML embeds every figure as a base64 PNG ``data:`` URI and carries no
script: it renders offline, in any browser, with nothing to fetch.  Long
lists (every structural finding) go into a ``details`` block: collapsed in
both documents (``<details>`` is an HTML block GitHub renders in Markdown too).
Text may hold `code` spans and relative ``[text](path)`` links (the
counterexample files).
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from visnav.app.precision import KINDS
from visnav.app.report_reach import radius_inward
from visnav.app.verification_report import VERDICT_LABELS

__all__ = ["Block", "report_blocks", "findings_blocks", "structural_blocks", "render_markdown", "render_html",
           "SECTION_RENDERERS", "TEXT_LIMIT", "bounded_text"]

_BADGE = {"proven": "PROVEN", "measured": "MEASURED", "sampled": "SAMPLED"}

TEXT_LIMIT = 2000
"""Characters of a free text of the input (a description) copied into the documents."""


_TRUNCATED = re.compile(r"… \(truncated, \d+ characters\)")


def bounded_text(text: str, limit: int = TEXT_LIMIT) -> str:
    """``text``, or its first ``limit`` characters and ``… (truncated, N characters)`` (N: the whole text's).

    A text bounded already (``report.json`` holds the scenario's description bounded) is kept as it is.
    """
    if len(text) <= limit or _TRUNCATED.fullmatch(text, limit):
        return text
    return f"{text[:limit]}… (truncated, {len(text)} characters)"


@dataclass(frozen=True, slots=True)
class Block:
    """One element of the document.

    ``kind`` is ``"h1"``, ``"h2"``, ``"h3"``, ``"p"``, ``"table"`` (``content`` =
    ``(header, rows)``), ``"figure"`` (``content`` = ``(stem, caption)``),
    ``"claims"`` (``content`` = list of claim dicts) or ``"details"``
    (``content`` = ``(summary, blocks)``: the blocks collapsed under a one-line summary).
    """

    kind: str
    content: Any


def _fmt(value: Any) -> str:
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        return ", ".join(_fmt(v) for v in value)
    return str(value)


def _claims_of(data: dict[str, Any], section: str) -> list[dict[str, Any]]:
    return [c for c in data["claims"] if c["section"] == section]


def _model_blocks(data: dict[str, Any]) -> list[Block]:
    model = data["model"]
    blocks = [Block("h2", "Model")]
    auto = model["automaton"]
    blocks.append(Block("p", (f"Supervisor automaton: {auto['modes']} modes, {auto['transitions']} transitions, "
                              f"latched memory {', '.join(auto['memory'])}; digest `{auto['digest'][:16]}…` "
                              f"(SHA-256 of its canonical JSON). Scenario digest "
                              f"`{data['meta']['scenario_digest'][:16]}…`.")))
    rows = []
    for table, values in model["parameters"].items():
        if isinstance(values, dict):
            for key, value in values.items():
                rows.append([table, key, bounded_text(_fmt(value))])
        elif isinstance(values, list):
            rows.append([table, f"{len(values)} entries", _fmt([v.get("name", "") if isinstance(v, dict) else v
                                                                 for v in values])])
        else:
            rows.append(["", table, bounded_text(_fmt(values))])
    blocks.append(Block("table", (["table", "parameter", "value"], rows)))
    blocks.append(Block("figure", ("mode_graph", "Mode graph of the supervisor automaton")))
    checks = model["structural_checks"]
    blocks.append(Block("h3", "Structural checks (hybrid.check)"))
    if checks.get("rates"):
        blocks.append(Block("p", (f"Over the measurement box, method {checks.get('method', 'auto')} (SMT solver "
                                  f"{checks.get('solver') or '—'}, timeout {_fmt(checks.get('timeout_s'))} s per "
                                  "call; modes it cannot take sampled, "
                                  f"{checks['samples_per_mode']} samples per mode, seed {checks['seed']}). Rate "
                                  "bounds of the dwell times, from the fuzzer's measurement space [unit/s]: "
                                  + ", ".join(f"{k} {_fmt(v)}" for k, v in checks["rates"].items()) + ".")))
    blocks += structural_blocks(checks, checks["searched"]["checks"])
    if checks["clean"] and not checks.get("findings"):
        blocks.append(Block("p", "Clean: no unreachable or sink mode, no non-determinism, no deadlock, no reset "
                                 "outside an invariant or re-triggering its guard."))
    else:
        blocks += findings_blocks(checks["findings"], checks["summary"], clean=checks["clean"])
    blocks.append(Block("claims", _claims_of(data, "model")))
    return blocks


_CHECK_ORDER = ("nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers", "zeno")
_GRAPH_FINDINGS = {"unreachable": ("unreachable_mode", "unreachable_transition"), "sink_mode": ("sink_mode",)}


def structural_blocks(checks: dict[str, Any], ran: dict[str, str]) -> list[Block]:
    """The claims table of the structural checks (one row per check: its claim in capitals, how, what),
    the pairs of transitions sharing a mode and the Zeno cycles grouped in one line.

    ``checks`` holds :meth:`hybrid.check.CheckReport.as_dict`'s ``claims``, ``zeno``, ``pairs`` and
    ``findings``; ``ran`` is its ``searched.checks`` (the graph checks' rows).  Never one row per cycle.
    """
    from visnav.app.structural import pairs_line, zeno_line

    claims = checks.get("claims") or {}
    kinds = {f["kind"] for f in checks.get("findings") or ()}
    rows = []
    for name, graph_kinds in _GRAPH_FINDINGS.items():
        if name in ran:
            found = any(k in kinds for k in graph_kinds)
            rows.append([name, "FOUND" if found else "PROVEN", "exact, on the mode graph",
                         "" if ran[name] == "ran" else ran[name]])
    zeno = zeno_line(checks.get("zeno"), (checks.get("findings") or ()))
    for name in [c for c in _CHECK_ORDER if c in claims] + [c for c in claims if c not in _CHECK_ORDER]:
        claim = claims[name]
        detail = zeno if name == "zeno" and zeno else claim.get("detail") or ""
        rows.append([name, claim["status"].upper(), claim["method"], detail])
    if not claims:  # a report without claims: the rows of searched.checks as they are
        return [Block("table", (["check", "status"], [[k, v] for k, v in ran.items()]))] if ran else []
    blocks = [Block("table", (["check", "claim", "how", "detail"], rows))]
    assumptions = list(dict.fromkeys(a for c in claims.values() if c["status"] == "proven"
                                     for a in c.get("assumptions") or ()))
    if assumptions:
        blocks.append(Block("p", "PROVEN over: " + "; ".join(assumptions) + "."))
    pairs = pairs_line(checks.get("pairs"), (checks.get("findings") or ()))
    if pairs:
        blocks.append(Block("p", f"Pairs: {pairs}."))
    if zeno:
        blocks.append(Block("p", f"Zeno: {zeno}."))
    return blocks


def _finding_row(f: dict[str, Any]) -> list[str]:
    return [f["severity"], f["kind"], _fmt(list(f.get("modes") or []) + list(f.get("transitions") or [])),
            f["message"]]


def findings_blocks(findings: list[dict[str, Any]], summary: dict[str, Any], *, clean: bool) -> list[Block]:
    """Structural findings: the counts, the worst few, and the full list collapsed in a ``details`` block.

    ``summary`` is :func:`visnav.app.verification_report.findings_summary` of ``findings``.
    """
    sev = summary["by_severity"]
    blocks = [Block("p", (("Clean (no error, no warning). " if clean else "NOT clean. ")
                          + f"{summary['total']} finding(s): {sev['error']} error(s), {sev['warning']} warning(s), "
                          f"{sev['info']} info(s)."))]
    if not findings:
        return blocks
    blocks.append(Block("table", (["severity", "kind", "findings"],
                                  [[r["severity"], r["kind"], _fmt(r["count"])] for r in summary["by_kind"]])))
    header = ["severity", "kind", "modes / transitions", "message"]
    worst = summary["worst"]
    if len(worst) < len(findings):
        blocks.append(Block("p", f"The first {len(worst)}, most severe first:"))
    blocks.append(Block("table", (header, [_finding_row(f) for f in worst])))
    if len(worst) < len(findings):
        blocks.append(Block("details", (f"All {len(findings)} findings",
                                        [Block("table", (header, [_finding_row(f) for f in findings]))])))
    return blocks


def _rho(value: Any) -> str:
    """A robustness: ``+∞``/``−∞`` for the JSON strings ``"inf"``/``"-inf"``, ``0`` for ``-0.0``."""
    if isinstance(value, str):
        return {"inf": "+∞", "-inf": "−∞"}.get(value, value)
    return _fmt(value + 0.0 if isinstance(value, float) else value)


_STRUCTURE_HEADINGS = {"structure": "Structural checks", "model": "Model"}
"""Where the report shows each section's structural findings (the heading of its part of the document)."""


def _structural_text(errors: dict[str, Any] | None) -> str:
    """`` — structural checks: N error(s) (kinds; section ...)`` when the checks found errors, else ``""``."""
    if not errors or not errors["count"]:
        return ""
    where = " and ".join(f"\"{_STRUCTURE_HEADINGS.get(s, s)}\"" for s in errors["sections"])
    return (f"; the structural checks found {errors['count']} error(s) ({', '.join(errors['kinds'])}; "
            f"section {where})")


def _verdict_sentence(data: dict[str, Any]) -> str:
    """The summary line: the report's overall verdict and exit code (structural errors included), the counts."""
    ver = data["verification"]
    verdict, code = data.get("verdict", ver["verdict"]), data.get("exit_code", ver["exit_code"])
    counts = {v: sum(r["verdict"] == v for r in ver["requirements"]) for v in ("proven", "falsified",
                                                                               "not_falsified")}
    parts = [f"{n} {VERDICT_LABELS[v].lower()}" for v, n in counts.items() if n]
    text = (f"Overall verdict: {VERDICT_LABELS[verdict]} (exit code {code}){_structural_text(data.get('structural_errors'))}"
            f" — {len(ver['requirements'])} requirement(s): {', '.join(parts)}; {ver['simulations']} simulation(s) "
            f"of a budget of {ver['budget']} (method {ver['method']}, seed {ver['seed']}).")
    if ver["invalid"]:
        text += (f" {ver['invalid']} point(s) outside the problem's hypotheses skipped ("
                 + "; ".join(ver["invalid_reasons"][:2]) + ").")
    if ver["diverged"]:
        first = ver["diverged"][0]
        text += f" {len(ver['diverged'])} simulation(s) diverged; first: {first['status']}: {first['detail']}."
    for key, what in (("errors", "raised in the model's code"), ("ended_early", "ended before the horizon")):
        if ver.get(key):
            first = ver[key][0]
            text += f" {len(ver[key])} simulation(s) {what}; first: {first['status']}: {first['detail']}."
    return text


def _verification_table(ver: dict[str, Any]) -> Block:
    rows = []
    for r in ver["requirements"]:
        file = r["counterexample_file"]
        rows.append([r["name"], VERDICT_LABELS[r["verdict"]], r.get("decided_by", "—"), _rho(r["robustness"]),
                     _rho(r["nominal_robustness"]), r["evidence"], f"[{file}]({file})" if file else "—"])
    return Block("table", (["requirement", "verdict", "decided by", "robustness (lowest)", "nominal", "evidence",
                            "counterexample"], rows))


def _verification_figures(ver: dict[str, Any]) -> list[Block]:
    blocks = []
    pages = ver["nominal"]["figures"]
    figures = [Block("figure", (page["stem"], "Nominal run" + (f" (requirements {page['first']}–{page['last']})"
                                                               if len(pages) > 1 else "")
                                + ": what each requirement compares, dashed thresholds, modes shaded, the deciding "
                                  "instant dotted")) for page in pages]
    blocks += figures[:1]
    if len(figures) > 1:  # the first page visible, the others collapsed
        blocks.append(Block("details", (f"Nominal run: requirements {pages[1]['first']}–{pages[-1]['last']}",
                                        figures[1:])))
    for r in ver["requirements"]:
        if r["figure"]:
            cx = r["counterexample"]
            where = (f"violated at t = {_fmt(cx['time'])} s (red)" if cx.get("window") is None else
                     f"never reached within [{_fmt(cx['window'][0])}, {_fmt(cx['window'][1])}] s; closest at t = "
                     f"{_fmt(cx['time'])} s (red)")
            blocks.append(Block("figure", (r["figure"], f"Counterexample to {r['name']}: {where} by "
                                           f"{cx['atom'].strip()}")))
    if ver["robustness_figure"]:
        blocks.append(Block("figure", (ver["robustness_figure"], "Lowest robustness against the simulations "
                                       "(below 0: violated)")))
    return blocks


def _verification_blocks(data: dict[str, Any]) -> list[Block]:
    ver = data["verification"]
    blocks = [Block("h2", f"Verification of `{ver['problem']}`"),
              Block("p", _verdict_sentence(data)),
              _verification_table(ver)]
    replay = [r["counterexample_file"] for r in ver["requirements"] if r["counterexample_file"]]
    if replay:
        source = ver.get("source") or "paper"
        confirm = "" if source == "paper" else f" --problem {source}"
        blocks.append(Block("p", f"Re-run a counterexample with `visnav replay FILE{confirm}` (files next to this "
                                 "report: " + ", ".join(f"[{f}]({f})" for f in replay) + ")."))
    blocks.append(Block("table", (["requirement", "formula", "meaning"],
                                  [[r["name"], f"`{' '.join(r['formula'].split())}`", bounded_text(r["description"])]
                                   for r in ver["requirements"]])))
    box = ver["parameters"]
    desc = (bounded_text(ver["description"]) + ". ") if ver["description"] else ""
    blocks.append(Block("p", f"{desc}Horizon {_fmt(ver['horizon_s'])} s; box of {len(box)} parameter(s) "
                             f"(source `{ver['source']}`). Coverage: per parameter, the share of ten equal bins a "
                             "simulated point fell in; a row's coverage is the smallest share."))
    if box:
        table = Block("table", (["parameter", "low", "nominal", "high", "unit", "distribution", "seen",
                                 "bins hit"],
                                [[p["name"], _fmt(p["low"]), _fmt(p["nominal"]), _fmt(p["high"]), p["unit"] or "",
                                  p["distribution"], f"{_fmt(p['low_seen'])} … {_fmt(p['high_seen'])}",
                                  f"{p['bins_hit']:.0%}"] for p in box]))
        blocks.append(table if len(box) <= 10 else Block("details", (f"The {len(box)} parameters", [table])))
    blocks += _verification_figures(ver)
    blocks.append(Block("claims", _claims_of(data, "verification")))
    return blocks


def _saturated_blocks(data: dict[str, Any]) -> list[Block]:
    """The saturated loop's verification (``visnav verify paper --variant saturated``), drawn as the first one."""
    view = {**data, "verification": data["saturated"],
            "claims": [{**c, "section": "verification"} for c in _claims_of(data, "saturated")]}
    blocks = _verification_blocks(view)
    blocks.insert(1, Block("p", "The same requirements on the loop that clips the applied commands (v, ω, ϖ) to "
                                "the actuator limits of `[limits]`: `v_mps`, `omega_radps`, `pan_rate_radps` are "
                                "the applied command (`controls_within_limits` in paper.toml), `v_demand_mps`, "
                                "`omega_demand_radps`, `pan_rate_demand_radps` the demand of (19) before clipping "
                                "(`demand_within_limits`). The report's verdict is the paper's loop's, above; this "
                                "is the verdict of the design answer to saturation."))
    return blocks


def _structure_blocks(data: dict[str, Any]) -> list[Block]:
    st = data["structure"]
    blocks = [Block("h2", f"Structural checks of `{st['automaton']}`")]
    blocks += structural_blocks(st, st["checks"])
    blocks += findings_blocks(st["findings"], st["summary"], clean=st["clean"])
    blocks.append(Block("claims", _claims_of(data, "structure")))
    return blocks


def _complex(re: float, im: float) -> str:
    return f"{re:.4g}" if im == 0 else f"{re:.4g}{im:+.4g}i"


def _certificate_blocks(st: dict[str, Any]) -> list[Block]:
    """The LMI results and the modes' regions of attraction of a stability analysis, one table each."""
    blocks = []
    rows = [[name, r["status"], r["finding"]] for name, r in
            (("common quadratic", st["switched"]), ("dwell time", st["dwell"]),
             ("piecewise quadratic", st.get("piecewise"))) if r is not None]
    if rows:
        blocks.append(Block("table", (["Lyapunov LMI", "status", "finding"], rows)))
    regions = st.get("regions") or []
    if regions:
        blocks.append(Block("table", (["mode", "region of attraction", "V", "level c", "entry time bound [s]",
                                       "why not"], [
            [r["mode"], r["status"], f"`{r['lyapunov']}`" if r["lyapunov"] else "—", _fmt(r["level"]),
             _fmt(r["time_bound_s"]), r["why"] or "—"] for r in regions])))
    return blocks


def _stability_blocks(data: dict[str, Any]) -> list[Block]:
    st = data["stability"]
    blocks = [Block("h2", f"Stability of `{st['system']}`"), Block("p", f"Verdict: **{st['verdict']}**. {st['finding']}")]
    blocks.append(Block("table", (["mode", "equilibrium", "x*", "eigenvalues", "finding"], [
        [e["mode"], e["kind"], _fmt(e["point"]) if e["point"] is not None else "none",
         ", ".join(_complex(re, im) for re, im in e["eigenvalues"]), e["finding"]]
        for e in st["equilibria"]])))
    if st["orbit"] is not None:
        o = st["orbit"]
        blocks.append(Block("table", (["periodic orbit", "value"], [
            ["section", f"`{o['section']}`"], ["period [s]", _fmt(o["period"])],
            ["fixed point", _fmt(o["fixed_point"])],
            ["nontrivial Floquet multipliers", _fmt(o["nontrivial_multipliers"])],
            ["verdict", o["verdict"]], ["shooting", f"{o['iterations']} iterations, residual {_fmt(o['residual'])}"]])))
        for stem in st["figures"]:
            blocks.append(Block("figure", (stem, "One revolution of the periodic orbit and its Floquet multipliers")))
    blocks += _certificate_blocks(st)
    undecided = [c for c in st["claims"] if c["status"] == "not decided"]
    if undecided:
        blocks.append(Block("p", "Not decided: " + "; ".join(f"{c['text']} ({c['method']})" for c in undecided)))
    blocks.append(Block("claims", _claims_of(data, "stability")))
    return blocks


def _simulation_blocks(data: dict[str, Any]) -> list[Block]:
    sim = data["simulation"]
    m = sim["metrics"]
    blocks = [Block("h2", "Simulation of the scenario")]
    blocks.append(Block("table", (["quantity", "paper (published)", "ours"],
                                  [[r["quantity"], _fmt(r["paper"]), _fmt(r["ours"])]
                                   for r in sim["paper_comparison"]])))
    keys = ("termination", "min_clearance_m", "final_feature_error_px", "occlusion_duration_s",
            "all_hidden_duration_s", "max_reconstruction_error_px", "max_depth_error_mm", "max_abs_input",
            "max_input_step", "max_mu_step", "chatter_count", "sim_time_s", "steps")
    blocks.append(Block("table", (["metric", "value"], [[k, _fmt(m[k])] for k in keys if k in m])))
    blocks.append(Block("p", "Modes visited: " + " → ".join(m["modes_visited"])))
    captions = {"fig4_trajectory": "Figure 4: trajectory, obstacles and envelopes",
                "fig5_risk": "Figure 5: risk parameters µ_coll, µ_occ",
                "fig6_reconstruction": "Figure 6: reconstruction errors while the target is hidden",
                "fig7_controls": "Figure 7: controls (v, ω, ϖ)"}
    for stem in sim["figures"]:
        blocks.append(Block("figure", (stem, captions.get(stem, stem))))
    blocks.append(Block("claims", _claims_of(data, "simulation")))
    return blocks


def _reach_row(reach: dict[str, Any] | None) -> list[list[str]]:
    """The sampled loop's proven bound as a row of the SOS bounds' table (none unless proven)."""
    if reach is None or reach["status"] != "proven":
        return []
    return [[f"[{_fmt(reach['entry_box']['alpha_rad'])}]",
             f"sampled loop, flowpipe over {_fmt(reach['horizon_s'])} s (re-checked)",
             _fmt(reach["delta_bound_m"]), _fmt(reach["margin_m"]), "—"]]


def _reach_blocks(reach: dict[str, Any] | None) -> list[Block]:
    """The sampled loop's reachability proof in words: bound, window, entry box, coverage, and how it differs
    from the SOS bounds."""
    if reach is None:
        return []
    if reach["status"] == "not run":
        return [Block("p", f"Sampled loop (flowpipe from the campaign's entries): not run ({reach['why']}).")]
    box, cov = reach["entry_box"], reach["coverage"]
    where = (f"δ ∈ [{_fmt(box['delta_m'])}] m, α ∈ [{_fmt(box['alpha_rad'])}] rad, "
             f"R ∈ [{_fmt(radius_inward(reach['radius_m']))}] m "
             f"at k = {_fmt(reach['k'])}, v_coll = {_fmt(reach['v_mps'])} m/s")
    if reach["status"] == "proven":
        verdict = (f"**proven, re-checked**: |δ| <= {_fmt(reach['delta_bound_m'])} m (margin >= "
                   f"{_fmt(reach['margin_m'])} m to d0 = {_fmt(reach['d_zero_m'])} m)")
    else:
        verdict = f"**NOT PROVEN**: |δ| < d0 = {_fmt(reach['d_zero_m'])} m was not decided"
    return [Block("p", (
        f"Sampled loop (`visnav.studies.path_following_reach`): {verdict} over the first {_fmt(reach['horizon_s'])} s "
        f"after entry, for the loop the robot runs (ω sampled every {_fmt(reach['period_s'] * 1000)} ms and held), "
        f"from every entry in {where}: a flowpipe by conservative linearisation ({reach['segments']} segments, "
        f"{reach['jumps']} samples, step {_fmt(reach['time_step_s'])} s) and its independent re-check. Coverage: "
        f"{cov['inside']}/{cov['entries']} measured entries (a sample of the campaign, not a proof of coverage) of "
        f"{cov['samples']} campaign draws (seed {cov['seed']}); the window is the longest measured bypass "
        f"({_fmt(cov['longest_bypass_s'])} s); the campaign's gain factors are not covered. The SOS rows bound the "
        "continuous loop for all time from one entry angle; the flowpipe bounds the sampled loop over a finite "
        "window from a range of entry angles."))]


def _sos_blocks(sos: dict[str, Any] | None, reach: dict[str, Any] | None = None) -> list[Block]:
    """The SOS study beside the hand-given V: region, bypass bounds by each set (and the sampled loop's proven
    bound, ``reach``), admissible gains."""
    if sos is None:
        return _reach_blocks(reach)
    region = sos["region"]
    blocks = [Block("h3", "Sum-of-squares certificates of path following"),
              Block("p", (f"Region: {{V <= 1}} of a degree-{region['degree']} SOS function, {region['status']} by "
                          f"interval branch and bound ({region['boxes']} boxes): area {_fmt(region['area_m_rad'])} "
                          f"m·rad against {_fmt(region['hand_area_m_rad'])} for the largest certified sublevel set "
                          f"of the hand-given V, ratio {_fmt(region['area_ratio'])}."))]
    rows = []
    for b in sos["bypass"]:
        hand = b["hand_closed_form"]["nominal"]
        rows.append([_fmt(b["alpha0_rad"]), "hand V, closed form", _fmt(hand["delta_max_m"]),
                     _fmt(hand["min_distance_m"]), _fmt(hand["omega_max_radps"])])
        for label, key in (("hand V, branch and bound", "hand"), ("SOS sets", "sos"), ("all sets (claimed)", "combined")):
            pair = b[key]
            rows.append([_fmt(b["alpha0_rad"]), label, _fmt(pair["delta_max_m"]), _fmt(pair["min_distance_m"]),
                         _fmt(pair["omega_max_radps"])])
    blocks.append(Block("table", (["entry alpha0 [rad]", "bound from", "max |delta| [m]", "clearance [m]",
                                   "max |omega| [rad/s]"], rows + _reach_row(reach))))
    blocks += _reach_blocks(reach)
    scope = "" if sos["scan"] else " (quick report: only the scenario's k judged)"
    blocks.append(Block("p", f"Admissible gains from the SOS certificates{scope}: {sos['admissible']['finding']}. "
                             f"Entry angles {sos['entry_angles_source']}."))
    return blocks


def _analysis_blocks(data: dict[str, Any]) -> list[Block]:
    ana = data["analysis"]
    pf = ana["path_following"]
    blocks = [Block("h2", "Linearisation, Lyapunov certificate, margins")]
    blocks.append(Block("p", f"V̇ normal form: `{pf['lyapunov']['normal_form']}`. {pf['lyapunov']['lasalle']}"))
    blocks.append(Block("p", f"Region of attraction: {pf['lyapunov']['region_of_attraction']}"))
    blocks.append(Block("p", f"Admissible gains: {pf['admissible']['finding']}"))
    blocks += _sos_blocks(pf["sos"], pf.get("bypass_reach"))
    blocks.append(Block("h3", "Stability margins of the loops"))
    rows = []
    for name, pair in ana["margins"].items():
        c, s = pair["continuous"], pair["sampled"]
        rows.append([name, _fmt(c["gain_margin_db"]), _fmt(s["gain_margin_db"]), _fmt(c["phase_margin_deg"]),
                     _fmt(s["phase_margin_deg"]), _fmt(c["delay_margin_s"]), _fmt(s["delay_margin_s"])])
    blocks.append(Block("table", (["loop", "GM cont. [dB]", "GM sampled [dB]", "PM cont. [deg]",
                                   "PM sampled [deg]", "DM cont. [s]", "DM sampled [s]"], rows)))
    blocks.append(Block("p", "— in a gain-margin column: infinite (no phase crossover). Sampled: T_e with "
                             "zero-order hold and one sample of computation delay."))
    captions = {"analysis_bode": "Bode diagrams of the loops", "analysis_nyquist": "Nyquist curves",
                "analysis_margins_vs_gains": "Margins against the gains (sampled stability limits dotted)",
                "analysis_eigenvalues_vs_gains": "Closed-loop eigenvalues against the gains"}
    for stem in ana["figures"]:
        blocks.append(Block("figure", (stem, captions.get(stem, stem))))
    blocks.append(Block("claims", _claims_of(data, "analysis")))
    return blocks


def _stiffness_blocks(data: dict[str, Any]) -> list[Block]:
    st = data["stiffness"]
    blocks = [Block("h2", "Stiffness of the reconstruction ODE (13) and the integrator choice")]
    if "not_applicable" in st:
        return blocks + [Block("p", f"Not applicable to this scenario: {st['not_applicable']}"),
                         Block("claims", _claims_of(data, "stiffness"))]
    rows = [[order, _fmt(row["alpha_deg"]), _fmt(row.get("published_deg")), _fmt(row["error_deg"])]
            for order, row in st["stability"]["a_alpha"].items()]
    blocks.append(Block("table", (["BDF order", "A(α) measured [deg]", "published [deg]", "difference [deg]"], rows)))
    rows = [[scheme, _fmt(row["max_error_px"]), _fmt(row["max_depth_error_mm"]), _fmt(row.get("truncation_error_px"))]
            for scheme, row in st["reconstruction"].items()]
    blocks.append(Block("table", ([f"scheme (h = {st['period_s']:g} s)", "max |s - s~| [px]", "max |z - z~| [mm]",
                                   "truncation error [px]"], rows)))
    px, mm, trunc = KINDS["error_px"], KINDS["error_mm"], KINDS["truncation_px"]
    blocks.append(Block("p", (f"Errors to {px.resolution:g} px and {mm.resolution:g} mm, truncation errors to "
                              f"{trunc.digits} significant digits; a truncation error of at most {trunc.floor:g} px "
                              f"is written {trunc.floor:g} (below it: round-off of the reference). Every number of "
                              "this report carries the digits its computation supports (docs/report.md).")))
    orders = st["observed_order"]
    blocks.append(Block("p", "Observed orders (exact-solution orbit problem): "
                        + ", ".join(f"{k} {_fmt(v)}" for k, v in orders.items()) + "."))
    captions = {"stiffness_regions": "Stability regions with the trajectory's h·λ cloud",
                "stiffness_error_vs_step": "Error against the step (observed order)",
                "stiffness_error_vs_time": "Error against wall time (measured on the machine that wrote this "
                                           "report: the one figure that is not reproducible byte for byte)",
                "stiffness_error_vs_evaluations": "Error against the evaluations of F and its Jacobian (the cost "
                                                  "without the machine's clock; wall times: visnav stiffness --timing)",
                "stiffness_ratio": "Stiffness ratio along the run"}
    for stem in st["figures"]:
        blocks.append(Block("figure", (stem, captions.get(stem, stem))))
    blocks.append(Block("claims", _claims_of(data, "stiffness")))
    return blocks


def _fuzzing_blocks(data: dict[str, Any]) -> list[Block]:
    fz = data["fuzzing"]
    blocks = [Block("h2", "Fuzzing the switching logic (hypothesis)")]
    blocks.append(Block("p", (f"{fz['examples_per_property']} examples per property, seed {fz['seed']}; failures "
                              "are shrunk to minimal counterexamples, replayable with `visnav replay FILE` "
                              "(their JSON is in report.json). Properties: docs/fuzzing.md.")))
    for variant, result in fz["variants"].items():
        blocks.append(Block("h3", f"Variant `{variant}`"))
        rows = [[r["name"], r["kind"], _fmt(r["examples"]), _fmt(r["steps"]),
                 "held" if not r["failures"] else "FAILED", r["message"] or ""] for r in result["properties"]]
        blocks.append(Block("table", (["property", "kind", "examples", "steps", "result", "counterexample"], rows)))
    blocks.append(Block("claims", _claims_of(data, "fuzzing")))
    return blocks


_SPEC_META = ("format", "version", "scenario", "scenario_digest", "scenario_toml", "samples", "seed")


def _campaign_blocks(data: dict[str, Any]) -> list[Block]:
    summary = data["campaign"]["summary"]
    spec = data["campaign"]["spec"]
    blocks = [Block("h2", "Monte-Carlo campaign")]
    blocks.append(Block("p", (f"{summary['samples_done']} scenarios drawn around `{data['meta']['scenario']}` "
                              f"(seed {spec.get('seed')}; sample i depends on (seed, i) only; spec hash "
                              f"`{summary['spec_hash'][:16]}…`). Perturbations: "
                              + ", ".join(f"{k} {_fmt(v)}" for k, v in spec.items()
                                          if k not in _SPEC_META) + ".")))
    blocks.append(Block("table", (["outcome", "count"], [[k, _fmt(v)] for k, v in summary["counts"].items()])))
    rows = []
    for key, label in (("clearance_quantiles_m", "min clearance [m]"),
                       ("reconstruction_error_quantiles_px", "max reconstruction error [px]"),
                       ("final_error_quantiles_px", "final feature error [px]")):
        q = summary[key]
        rows.append([label] + [_fmt(q.get(level)) for level in ("0", "0.05", "0.5", "0.95", "1")])
    blocks.append(Block("table", (["quantity", "min", "5 %", "median", "95 %", "max"], rows)))
    if summary["failures"]:
        blocks.append(Block("p", "Failures: " + "; ".join(f"{k}: samples {_fmt(v)}"
                                                          for k, v in summary["failures"].items())))
    blocks.append(Block("claims", _claims_of(data, "campaign")))
    return blocks


SECTION_RENDERERS: dict[str, Callable[[dict[str, Any]], list[Block]]] = {
    "verification": _verification_blocks,
    "saturated": _saturated_blocks,
    "structure": _structure_blocks,
    "stability": _stability_blocks,
    "model": _model_blocks,
    "simulation": _simulation_blocks,
    "analysis": _analysis_blocks,
    "stiffness": _stiffness_blocks,
    "fuzzing": _fuzzing_blocks,
    "campaign": _campaign_blocks,
}
"""Block builders per section name (sections without one are listed by their claims only)."""


def _subject(meta: dict[str, Any]) -> str:
    """What the report is about: ``scenario `paper``` or ``problem `name```."""
    if "scenario" in meta:
        return f"scenario `{meta['scenario']}`"
    return f"problem `{meta['problem']}`"


def _claims_intro(data: dict[str, Any]) -> Block:
    counts = data["claim_counts"]
    return Block("p", ("Every claim is marked PROVEN (a sound certificate or an exact identity, re-checkable), "
                       "MEASURED (deterministic numerics on the model) or SAMPLED (generalised from samples: it "
                       f"can miss cases). This report: {counts['proven']} proven, {counts['measured']} measured, "
                       f"{counts['sampled']} sampled."))


def report_blocks(data: dict[str, Any]) -> list[Block]:
    """The document as blocks: title, the verification (verdict table first), every claim, the other sections,
    versions and seeds."""
    meta = data["meta"]
    blocks = [Block("h1", f"Verification report — {_subject(meta)}" + (" (quick)" if meta["quick"] else ""))]
    first = [name for name in data["sections"] if name in ("verification", "saturated")]
    rest = [name for name in data["sections"] if name not in first]
    for name in first:
        blocks += SECTION_RENDERERS[name](data)
    blocks += [Block("h2", "Claims"), _claims_intro(data), Block("claims", data["claims"])]
    for name in rest:
        render = SECTION_RENDERERS.get(name)
        if render is None:
            blocks += [Block("h2", name.capitalize()), Block("claims", _claims_of(data, name))]
        else:
            blocks += render(data)
    versions = meta["versions"]
    blocks += [
        Block("h2", "Reproducibility"),
        Block("p", (f"Regenerate with `{meta['command']}`. The same "
                    + ("scenario" if "scenario" in meta else "problem") + ", seed, budgets and dependency versions "
                    "give a byte-identical report.json and report.md.")),
        Block("table", (["seed", "value"], [[k, _fmt(v)] for k, v in meta["seeds"].items()]
                        + [[f"budget: {k}", _fmt(v)] for k, v in meta["budgets"].items()])),
        Block("table", (["package", "version"], [[k, v] for k, v in versions.items()])),
    ]
    return blocks


# --------------------------------------------------------------------------- Markdown


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _markdown_lines(blocks: list[Block], figure_paths: dict[str, str]) -> list[str]:
    out: list[str] = []
    for block in blocks:
        if block.kind in ("h1", "h2", "h3"):
            out.append("#" * int(block.kind[1]) + " " + block.content)
        elif block.kind == "p":
            out.append(block.content)
        elif block.kind == "table":
            header, rows = block.content
            out.append("| " + " | ".join(_md_cell(h) for h in header) + " |")
            out.append("|" + "---|" * len(header))
            out += ["| " + " | ".join(_md_cell(str(c)) for c in row) + " |" for row in rows]
        elif block.kind == "figure":
            stem, caption = block.content
            out.append(f"![{caption}]({figure_paths[stem]})")
        elif block.kind == "claims":
            out += [f"- **{_BADGE[c['status']]}** {c['text']}" for c in block.content] or ["(none)"]
        elif block.kind == "details":  # an HTML block: GitHub renders the Markdown between the blank lines
            summary, inner = block.content
            out += ["<details>", f"<summary>{html.escape(summary)}</summary>", ""]
            out += _markdown_lines(inner, figure_paths)
            out.append("</details>")
        out.append("")
    return out


def render_markdown(data: dict[str, Any], figure_paths: dict[str, str]) -> str:
    """Markdown text; figures link to ``figure_paths[stem]`` (relative paths)."""
    return "\n".join(_markdown_lines(report_blocks(data), figure_paths))


# --------------------------------------------------------------------------- HTML

_CSS = """
body { font-family: system-ui, sans-serif; max-width: 1100px; margin: 2em auto; padding: 0 1em; color: #222; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #f2f2f2; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #555; }
.badge { display: inline-block; min-width: 6.5em; font-size: 0.75em; font-weight: bold; padding: 0.1em 0.4em;
         border-radius: 3px; color: white; text-align: center; margin-right: 0.5em; }
.proven { background: #1a7f37; } .measured { background: #0969da; } .sampled { background: #9a6700; }
ul.claims { list-style: none; padding-left: 0; } ul.claims li { margin: 0.3em 0; }
code { background: #f6f8fa; padding: 0 0.2em; }
details { margin: 0.8em 0; } summary { cursor: pointer; color: #0969da; }
"""


_LINK = re.compile(r"\[([^\[\]]+)\]\(([^()\s]+)\)")
"""A Markdown link ``[text](relative/path)`` (no scheme: the report links only its own files)."""


def _links(escaped: str) -> str:
    return _LINK.sub(lambda m: f'<a href="{m.group(2)}">{m.group(1)}</a>' if ":" not in m.group(2) else m.group(0),
                     escaped)


def _inline(text: str) -> str:
    """Escape, then turn `code` spans into <code> and [text](path) links into <a>."""
    parts = html.escape(text).split("`")
    return "".join(f"<code>{p}</code>" if i % 2 else _links(p) for i, p in enumerate(parts))


def _html_parts(blocks: list[Block], figure_png: dict[str, bytes]) -> list[str]:
    body: list[str] = []
    for block in blocks:
        if block.kind in ("h1", "h2", "h3"):
            body.append(f"<{block.kind}>{_inline(block.content)}</{block.kind}>")
        elif block.kind == "p":
            body.append(f"<p>{_inline(block.content)}</p>")
        elif block.kind == "table":
            header, rows = block.content
            head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
            cells = "".join("<tr>" + "".join(f"<td>{_inline(str(c))}</td>" for c in row) + "</tr>" for row in rows)
            body.append(f"<table><thead><tr>{head}</tr></thead><tbody>{cells}</tbody></table>")
        elif block.kind == "figure":
            stem, caption = block.content
            encoded = base64.b64encode(figure_png[stem]).decode("ascii")
            body.append(f'<figure id="fig-{html.escape(stem)}"><img alt="{html.escape(caption)}" '
                        f'src="data:image/png;base64,{encoded}"><figcaption>{html.escape(caption)}</figcaption>'
                        "</figure>")
        elif block.kind == "claims":
            items = "".join(f'<li><span class="badge {c["status"]}">{_BADGE[c["status"]]}</span>'
                            f"{_inline(c['text'])}</li>" for c in block.content)
            body.append(f'<ul class="claims">{items}</ul>')
        elif block.kind == "details":
            summary, inner = block.content
            body.append(f"<details><summary>{_inline(summary)}</summary>\n" + "\n".join(_html_parts(inner, figure_png))
                        + "\n</details>")
    return body


def render_html(data: dict[str, Any], figure_png: dict[str, bytes]) -> str:
    """Self-contained HTML: figures embedded as ``data:image/png;base64`` URIs, no script."""
    body = _html_parts(report_blocks(data), figure_png)
    meta = data["meta"]
    title = html.escape(f"visnav verification report — {meta.get('scenario') or meta['problem']}")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{title}</title><style>{_CSS}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")
