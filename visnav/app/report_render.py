"""Render a report's data as Markdown and as self-contained HTML.

Both renderers consume the same list of blocks built by :func:`report_blocks`
from ``report.json``'s content, so the two documents say the same things.
The HTML embeds every figure as a base64 PNG ``data:`` URI and carries no
script: it renders offline, in any browser, with nothing to fetch.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = ["Block", "report_blocks", "render_markdown", "render_html", "SECTION_RENDERERS"]

_BADGE = {"proven": "PROVEN", "measured": "MEASURED", "sampled": "SAMPLED"}


@dataclass(frozen=True, slots=True)
class Block:
    """One element of the document.

    ``kind`` is ``"h1"``, ``"h2"``, ``"h3"``, ``"p"``, ``"table"`` (``content`` =
    ``(header, rows)``), ``"figure"`` (``content`` = ``(stem, caption)``) or
    ``"claims"`` (``content`` = list of claim dicts).
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
                rows.append([table, key, _fmt(value)])
        elif isinstance(values, list):
            rows.append([table, f"{len(values)} entries", _fmt([v.get("name", "") if isinstance(v, dict) else v
                                                                 for v in values])])
        else:
            rows.append(["", table, _fmt(values)])
    blocks.append(Block("table", (["table", "parameter", "value"], rows)))
    blocks.append(Block("figure", ("mode_graph", "Mode graph of the supervisor automaton")))
    checks = model["structural_checks"]
    blocks.append(Block("h3", "Structural checks (hybrid.check)"))
    findings = checks.get("findings", [])
    blocks.append(Block("p", ("Clean: no unreachable or sink mode, no non-determinism, no deadlock, no reset "
                              "outside an invariant or re-triggering its guard." if checks["clean"] else
                              f"{len(findings)} finding(s):")))
    if findings:
        blocks.append(Block("table", (["severity", "kind", "modes / transitions", "message"],
                                      [[f["severity"], f["kind"], _fmt(f["modes"] + f["transitions"]),
                                        f["message"]] for f in findings])))
    blocks.append(Block("claims", _claims_of(data, "model")))
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


def _analysis_blocks(data: dict[str, Any]) -> list[Block]:
    ana = data["analysis"]
    pf = ana["path_following"]
    blocks = [Block("h2", "Linearisation, Lyapunov certificate, margins")]
    blocks.append(Block("p", f"V̇ normal form: `{pf['lyapunov']['normal_form']}`. {pf['lyapunov']['lasalle']}"))
    blocks.append(Block("p", f"Region of attraction: {pf['lyapunov']['region_of_attraction']}"))
    blocks.append(Block("p", f"Admissible gains: {pf['admissible']['finding']}"))
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
    rows = [[order, _fmt(row["alpha_deg"]), _fmt(row.get("published_deg")), _fmt(row["error_deg"])]
            for order, row in st["stability"]["a_alpha"].items()]
    blocks.append(Block("table", (["BDF order", "A(α) measured [deg]", "published [deg]", "difference [deg]"], rows)))
    rows = [[scheme, _fmt(row["max_error_px"]), _fmt(row["max_depth_error_mm"]), _fmt(row.get("truncation_error_px"))]
            for scheme, row in st["reconstruction"].items()]
    blocks.append(Block("table", ([f"scheme (h = {st['period_s']:g} s)", "max |s - s~| [px]", "max |z - z~| [mm]",
                                   "truncation error [px]"], rows)))
    orders = st["observed_order"]
    blocks.append(Block("p", "Observed orders (exact-solution orbit problem): "
                        + ", ".join(f"{k} {_fmt(v)}" for k, v in orders.items()) + "."))
    captions = {"stiffness_regions": "Stability regions with the trajectory's h·λ cloud",
                "stiffness_error_vs_step": "Error against the step (observed order)",
                "stiffness_error_vs_time": "Error against wall time (measured on the machine that wrote this "
                                           "report: the one figure that is not reproducible byte for byte)",
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
    "model": _model_blocks,
    "simulation": _simulation_blocks,
    "analysis": _analysis_blocks,
    "stiffness": _stiffness_blocks,
    "fuzzing": _fuzzing_blocks,
    "campaign": _campaign_blocks,
}
"""Block builders per section name (sections without one are listed by their claims only)."""


def report_blocks(data: dict[str, Any]) -> list[Block]:
    """The document as blocks: title, claim summary, each section, versions and seeds."""
    meta = data["meta"]
    counts = data["claim_counts"]
    blocks = [
        Block("h1", f"Verification report — scenario `{meta['scenario']}`" + (" (quick)" if meta["quick"] else "")),
        Block("p", ("Every claim is marked PROVEN (a sound certificate or an exact identity, re-checkable), "
                    "MEASURED (deterministic numerics on the model) or SAMPLED (generalised from samples: it can "
                    f"miss cases). This report: {counts['proven']} proven, {counts['measured']} measured, "
                    f"{counts['sampled']} sampled.")),
        Block("h2", "Claims"),
        Block("claims", data["claims"]),
    ]
    for name in data["sections"]:
        render = SECTION_RENDERERS.get(name)
        if render is None:
            blocks += [Block("h2", name.capitalize()), Block("claims", _claims_of(data, name))]
        else:
            blocks += render(data)
    versions = meta["versions"]
    blocks += [
        Block("h2", "Reproducibility"),
        Block("p", (f"Regenerate with `visnav report --scenario {meta['scenario']}"
                    + (" --quick" if meta["quick"] else "") + f" --seed {meta['seeds']['report']}`. "
                    "The same scenario, seed and dependency versions give a byte-identical report.json "
                    "and report.md.")),
        Block("table", (["seed", "value"], [[k, _fmt(v)] for k, v in meta["seeds"].items()]
                        + [[f"budget: {k}", _fmt(v)] for k, v in meta["budgets"].items()])),
        Block("table", (["package", "version"], [[k, v] for k, v in versions.items()])),
    ]
    return blocks


# --------------------------------------------------------------------------- Markdown


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def render_markdown(data: dict[str, Any], figure_paths: dict[str, str]) -> str:
    """Markdown text; figures link to ``figure_paths[stem]`` (relative paths)."""
    out: list[str] = []
    for block in report_blocks(data):
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
        out.append("")
    return "\n".join(out)


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
"""


def _inline(text: str) -> str:
    """Escape, then turn `code` spans into <code>."""
    parts = html.escape(text).split("`")
    return "".join(f"<code>{p}</code>" if i % 2 else p for i, p in enumerate(parts))


def render_html(data: dict[str, Any], figure_png: dict[str, bytes]) -> str:
    """Self-contained HTML: figures embedded as ``data:image/png;base64`` URIs, no script."""
    body: list[str] = []
    for block in report_blocks(data):
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
    title = html.escape(f"visnav verification report — {data['meta']['scenario']}")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{title}</title><style>{_CSS}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")
