"""The report of any verification problem: the verdict table first, then its evidence, figures and structure.

:func:`build_problem_report` verifies a :class:`analysis.verify.verification.VerificationProblem`
(:func:`analysis.verify.verdicts.verify`) and assembles a :class:`Report` of two
sections:

``verification`` (:func:`verification_section`)
    the overall verdict and one row per requirement: its verdict (PROVEN,
    FALSIFIED, NOT FALSIFIED), the lowest robustness seen and the nominal one,
    the evidence (the proof's method; or how many simulations, where the lowest
    robustness was and how the box was covered; or the counterexample's
    instant and atom) and the counterexample file
    (``counterexamples/NAME.json``, re-run by ``visnav replay``); the figures
    (:mod:`visnav.app.figures_verification`) of the nominal run, of every
    counterexample and of the robustness against the simulations.
``structure`` (:func:`structure_section`, when the problem has ``structural``)
    the structural checks: one claim per check (PROVEN when the SMT solver
    decided the problem's symbolic model, SAMPLED when searched by sampling,
    MEASURED when a defect's witness re-checks), the Zeno cycles grouped in one
    line, and the findings summarised (:func:`findings_summary`): counts by
    severity and kind, the worst few findings, and the full list (collapsed
    when rendered).

The case study's report (:func:`visnav.app.report.build_report`) puts the
same verification section first, then its own sections; both are assembled
by :func:`assemble_report`.  The data is JSON-ready and deterministic: the same
problem, seed, budget and dependency versions give the same bytes (no
wall-clock time, no date; infinite robustness written as ``"inf"``/``"-inf"``).

Claims (:class:`Claim`) are marked ``proven`` (a sound certificate or an exact
identity, re-checkable), ``measured`` (deterministic numerics on the model: a
simulation that violates a requirement is one; so is a structural defect
with a re-checked witness) or ``sampled`` (generalised from samples: a
requirement not falsified, structural checks by sampling); a structural
check decided by the SMT solver is ``proven``.
"""

from __future__ import annotations

import platform
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any

from hybrid.jsonable import to_jsonable

from visnav.app.cli_types import VERDICT_EXIT_CODES, VERIFY_BUDGET, VERIFY_BUDGET_QUICK
from visnav.app.precision import round_section, round_value

__all__ = [
    "CLAIM_STATUSES",
    "DEPENDENCIES",
    "VERDICT_LABELS",
    "STRUCTURAL_ERROR",
    "REPORT_EXIT_CODES",
    "COUNTEREXAMPLE_DIR",
    "VERIFY_BUDGET",
    "VERIFY_BUDGET_QUICK",
    "WORST_FINDINGS",
    "Claim",
    "Report",
    "Section",
    "dependency_versions",
    "verification_section",
    "structure_section",
    "stability_section",
    "findings_summary",
    "assemble_report",
    "structural_errors",
    "overall_verdict",
    "build_problem_report",
    "report_command",
]

CLAIM_STATUSES = ("proven", "measured", "sampled")
"""How a claim was obtained, strongest first."""

DEPENDENCIES = ("numpy", "scipy", "casadi", "control", "hypothesis", "networkx", "matplotlib", "dask",
                "distributed", "z3-solver", "cvxpy", "clarabel", "scs")
"""Packages whose versions the report records."""

STRUCTURAL_ERROR = "structural_error"
"""A report's overall verdict when its requirements are proven or not falsified but a structural check found an
error (a defect whose witness re-checked on the model): the model is wrong whatever its runs showed."""

VERDICT_LABELS = {"proven": "PROVEN", "falsified": "FALSIFIED", "not_falsified": "NOT FALSIFIED",
                  "diverged": "DIVERGED", "incomplete": "INCOMPLETE", "error": "MODEL ERROR",
                  STRUCTURAL_ERROR: "STRUCTURAL ERROR"}
"""How the documents write a verdict (:data:`analysis.verify.verdicts.OVERALL` and :data:`STRUCTURAL_ERROR`)."""

REPORT_EXIT_CODES = {**VERDICT_EXIT_CODES, STRUCTURAL_ERROR: 1}
"""Exit code of ``visnav report`` by the report's overall verdict (:data:`visnav.app.cli_types.VERDICT_EXIT_CODES`,
and 1 (a finding) for :data:`STRUCTURAL_ERROR`)."""

COUNTEREXAMPLE_DIR = "counterexamples"
"""Sub-folder of the report's counterexample files (``counterexamples/NAME.json``)."""

"""Simulations of the verification in the full and in the quick report."""

WORST_FINDINGS = 8
"""Structural findings shown outside the collapsed full list (errors first, then warnings)."""

_SEVERITY_RANK = {"error": 0, "warning": 1, "info": 2}
_POINT_COORDINATES = 4
"""Coordinates of a point written in an evidence cell (those farthest from nominal; the JSON has all)."""

Progress = Callable[[str], None]


@dataclass(frozen=True, kw_only=True, slots=True)
class Claim:
    """One statement of the report and how it was obtained.

    Attributes
    ----------
    text : str
    status : {"proven", "measured", "sampled"}
    section : str
        The report section that supports it.
    """

    text: str
    status: str
    section: str

    def __post_init__(self) -> None:
        if self.status not in CLAIM_STATUSES:
            raise ValueError(f"Claim.status = {self.status!r}; expected one of {', '.join(CLAIM_STATUSES)}")

    def as_dict(self) -> dict[str, str]:
        """JSON-ready view."""
        return {"section": self.section, "status": self.status, "text": self.text}


@dataclass(frozen=True, kw_only=True, slots=True)
class Report:
    """A built report.

    Attributes
    ----------
    data : dict
        JSON-ready content (what ``report.json`` holds), deterministic.
    figures : dict of str to matplotlib Figure
        Keyed by file stem; ``data`` refers to them by stem.
    files : dict of str to str
        Further files of the report by relative path (the counterexample files), deterministic text.
    timings_s : dict of str to float
        Wall time per section [s] (not part of ``data``: not reproducible).
    """

    data: dict[str, Any]
    figures: dict[str, Any] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def claims(self) -> tuple[Claim, ...]:
        """Every claim, in section order."""
        return tuple(Claim(**c) for c in self.data["claims"])

    @property
    def verdict(self) -> str | None:
        """The verification's overall verdict (``None`` for a report without verification)."""
        return self.data.get("verdict")


@dataclass(frozen=True, kw_only=True, slots=True)
class Section:
    """What one section contributes: its data (JSON-ready), claims, figures and files."""

    data: dict[str, Any]
    claims: tuple[Claim, ...] = ()
    figures: dict[str, Any] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)


def dependency_versions() -> dict[str, str]:
    """Installed versions of :data:`DEPENDENCIES`, of Python and of visnav (``"not installed"`` when absent)."""
    out = {"python": platform.python_version()}
    for name in (*DEPENDENCIES, "visnav"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


# --------------------------------------------------------------------------- the verification section


def _number(value: float | None, kind: str = "simulation") -> str:
    """A robustness (or a number of ``kind``) as the report prints it: rounded by the policy
    (:func:`visnav.app.precision.round_value`), then written with 4 significant digits."""
    return "—" if value is None else f"{round_value(value, kind):.4g}"


def _point_text(point: Mapping[str, float] | None, problem: Any) -> str:
    """The coordinates farthest from nominal (in unit coordinates), at most :data:`_POINT_COORDINATES`."""
    if not point:
        return "the nominal point" if point is not None else "—"
    params = {p.name: p for p in problem.parameters}
    moved = [(abs(params[k].unit_of(v)) if k in params else 1.0, k, v) for k, v in point.items()]
    moved = [m for m in moved if m[0] > 0]
    if not moved:
        return "the nominal point"
    shown = sorted(moved, key=lambda m: (-m[0], m[1]))[:_POINT_COORDINATES]
    text = ", ".join(f"{k} = {_number(v, 'search_point')}" for _, k, v in sorted(shown, key=lambda m: m[1]))
    extra = len(moved) - len(shown)
    return text + (f" (+{extra} more off nominal)" if extra else "")


def _coverage_share(result: Any) -> float | None:
    hits = result.coverage.bins_hit
    return min(hits) if hits else None


def _where(cx: Any) -> str:
    """Where a counterexample is decided, in words: the instant it is violated most, or for an ``eventually`` the
    window in which it was never reached and the instant it came closest (``cx.window``)."""
    if getattr(cx, "window", None) is None:
        return f"violated at t = {_number(cx.time, 'time')} s by `{cx.atom.strip()}`"
    a, b = cx.window
    return (f"never reached within [{_number(a, 'time')}, {_number(b, 'time')}] s; closest at t = "
            f"{_number(cx.time, 'time')} s by `{cx.atom.strip()}`")


def _evidence(verdict: Any, result: Any, problem: Any) -> str:
    """One sentence of evidence for a requirement's verdict."""
    cx, proof = verdict.counterexample, verdict.proof
    if cx is not None:
        return (f"{_where(cx)} = {_number(cx.atom_value)} "
                f"(simulation {cx.evaluation}; {cx.how}) at {_point_text(cx.point, problem)}")
    if verdict.verdict == "proven":
        return f"{proof.method}: {proof.evidence}"
    share = _coverage_share(result)
    text = (f"{verdict.simulations} simulations, lowest at {_point_text(verdict.lowest_at, problem)}"
            + ("" if share is None else f", coverage {share:.0%}"))
    if proof is not None:
        text += f"; proof ({proof.method}) " + ("does not hold" if not proof.holds else "not re-checked")
    return text


def _requirement_claim(verdict: Any, result: Any, problem: Any, file: str | None, spec: str,
                       section: str = "verification") -> Claim:
    from visnav.app.counterexample_files import replay_command

    label = VERDICT_LABELS[verdict.verdict]
    if verdict.verdict == "proven":
        return Claim(section=section, status="proven",
                     text=f"requirement {verdict.name} {label} over the whole box: {verdict.proof.method} "
                          f"({verdict.proof.evidence})")
    if verdict.counterexample is not None:
        cx = verdict.counterexample
        return Claim(section=section, status="measured",
                     text=(f"requirement {verdict.name} {label}: robustness {_number(cx.robustness)} at "
                           f"{_point_text(cx.point, problem)}, {_where(cx)}; replay with "
                           f"`{replay_command(file, spec)}`"))
    share = _coverage_share(result)
    return Claim(section=section, status="sampled",
                 text=(f"requirement {verdict.name} {label} in {verdict.simulations} simulations (method "
                       f"{result.method}, seed {result.seed}): lowest robustness {_number(verdict.robustness)}, "
                       f"nominal {_number(verdict.nominal_robustness)}"
                       + ("" if share is None else f"; every parameter covered >= {share:.0%} of its bins")
                       + ("" if verdict.verdict != "incomplete" else
                          f"; {verdict.undecided} run(s) ended before deciding it, first: "
                          f"{verdict.undecided_reasons[0] if verdict.undecided_reasons else 'ended early'}")))


def _explained(formula: Any, trace: Any) -> dict[str, Any]:
    why = formula.explain(trace)
    return {"time": float(why.time), "atom": str(why.atom), "value": float(why.value),
            "robustness": float(formula.robustness(trace))}


def _nominal_run(problem: Any, result: Any) -> tuple[dict[str, Any], Any]:
    """The nominal point's status, where each requirement is decided on it, and its trace (or ``None``)."""
    first = result.evaluations[0] if result.evaluations and result.evaluations[0].phase == "nominal" else None
    data: dict[str, Any] = {"point": problem.nominal(), "status": None if first is None else first.outcome.status,
                            "detail": "" if first is None else first.outcome.detail, "decided": {}}
    if first is None or not first.outcome.evaluated:  # a run cut short is still shown, with how it ended
        return data, None
    data["end"], data["end_time"] = first.outcome.end, first.outcome.end_time
    trace = problem.trace(problem.nominal())
    data["decided"] = {p.name: _explained(p.formula, trace) for p in problem.parsed}
    return data, trace


def _nominal_figures(problem: Any, result: Any, trace: Any, prefix: str = "verification"
                     ) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The nominal run's figures, :data:`~visnav.app.figures_verification.PANELS_PER_FIGURE` requirements
    each, and their pages (stem, first and last requirement number)."""
    from visnav.app.figures_verification import PANELS_PER_FIGURE, RequirementPanel, run_figure

    parsed = {p.name: p.formula for p in problem.parsed}
    names = [r.name for r in result.requirements]
    figures: dict[str, Any] = {}
    pages = []
    for first in range(0, len(names), PANELS_PER_FIGURE):
        chunk = names[first:first + PANELS_PER_FIGURE]
        stem = f"{prefix}_nominal" + (f"_{first // PANELS_PER_FIGURE + 1}" if first else "")
        title = f"{problem.name}: nominal run" + (
            f" (requirements {first + 1}–{first + len(chunk)} of {len(names)})" if len(names) > len(chunk) else "")
        figures[stem] = run_figure(trace, [RequirementPanel(name=n, formula=parsed[n], violated=False)
                                           for n in chunk], title=title)
        pages.append({"stem": stem, "first": first + 1, "last": first + len(chunk)})
    return figures, pages


def _figures(problem: Any, result: Any, nominal_trace: Any, prefix: str = "verification"
             ) -> tuple[dict[str, Any], list[dict[str, Any]], dict[str, str | None]]:
    """The figures by stem, the nominal run's pages, and the stem of each requirement's counterexample figure."""
    from visnav.app.figures_verification import RequirementPanel, robustness_history_figure, run_figure

    parsed = {p.name: p.formula for p in problem.parsed}
    figures, pages = ({}, []) if nominal_trace is None else _nominal_figures(problem, result, nominal_trace, prefix)
    stems: dict[str, str | None] = {}
    for r in result.requirements:
        cx = r.counterexample
        stems[r.name] = None
        if cx is None:
            continue
        trace = problem.trace(problem.point(cx.unit))
        panel = RequirementPanel(name=r.name, formula=parsed[r.name], violated=True, time=cx.time, atom=cx.atom)
        stem = f"{prefix}_counterexample_{r.name}"
        figures[stem] = run_figure(trace, [panel], title=f"{problem.name}: counterexample to {r.name}")
        stems[r.name] = stem
    if result.evaluations:
        figures[f"{prefix}_robustness"] = robustness_history_figure(
            {r.name: r.history for r in result.requirements}, title=f"{problem.name}: {result.method} search")
    return figures, pages, stems


def _parameters(problem: Any, result: Any) -> list[dict[str, Any]]:
    coverage = {p["name"]: p for p in result.coverage.as_dict()["parameters"]}
    return [{"name": p.name, "low": p.low, "high": p.high, "nominal": p.nominal, "unit": p.unit,
             "distribution": p.distribution, "low_seen": coverage[p.name]["low_seen"],
             "high_seen": coverage[p.name]["high_seen"], "bins_hit": coverage[p.name]["bins_hit"]}
            for p in problem.parameters]


def verification_section(problem: Any, result: Any, *, spec: str, options: Mapping[str, Any] | None = None,
                         name: str = "verification") -> Section:
    """The verification section of ``problem`` verified as ``result``.

    Parameters
    ----------
    problem : analysis.verify.verification.VerificationProblem
    result : analysis.verify.verdicts.VerificationResult
        ``verify(problem, ...)``.
    spec : str
        How ``visnav replay`` loads the problem again (``paper``, ``pkg.mod:OBJ``, ``file.py:OBJ``).
    options : Mapping, optional
        The loading options (``{"scenario": ..., "variant": ...}`` for ``paper``).
    name : str
        The section's name: its claims' section, the prefix of its figure stems, and, for another
        name than ``verification``, of its counterexample files (``counterexamples/NAME~REQ.json``),
        so that two verification sections share a report.

    Returns
    -------
    Section
        Data keyed ``verdict``, ``requirements`` (one row each, counterexample file relative to
        the report folder), ``nominal``, ``parameters``, ``coverage``, ``figures``...; the
        counterexample files' text in ``files``.
    """
    from visnav.app.counterexample_files import counterexample_text

    options = dict(options or {})
    nominal, nominal_trace = _nominal_run(problem, result)
    figures, pages, stems = _figures(problem, result, nominal_trace, name)
    tag = "" if name == "verification" else f"{name}~"
    files: dict[str, str] = {}
    rows = []
    for r in result.requirements:
        file = None
        if r.counterexample is not None:
            file = f"{COUNTEREXAMPLE_DIR}/{tag}{r.name}.json"
            files[file] = counterexample_text(result, r, problem, spec, options, rounded=True)
        rows.append({**r.as_dict(), "history": list(r.history), "evidence": _evidence(r, result, problem),
                     "counterexample_file": file, "figure": stems[r.name]})
    claims = [_requirement_claim(r, result, problem, row["counterexample_file"], spec, name)
              for r, row in zip(result.requirements, rows)]
    if result.diverged:
        claims.append(Claim(section=name, status="measured",
                            text=f"{len(result.diverged)} simulation(s) diverged or cycled at one instant; first: "
                                 f"{result.diverged[0]['status']} at {_point_text(result.diverged[0]['point'], problem)}"
                                 f" ({result.diverged[0]['detail']})"))
    summary = result.as_dict()
    data = {
        "problem": problem.name, "source": spec, "options": options, "description": problem.description,
        "horizon_s": problem.horizon, "verdict": result.verdict, "exit_code": VERDICT_EXIT_CODES[result.verdict],
        "method": result.method, "seed": result.seed, "budget": result.budget, "simulations": result.simulations,
        "invalid": result.invalid, "invalid_reasons": summary["invalid_reasons"], "diverged": summary["diverged"],
        "coverage": summary["coverage"], "parameters": _parameters(problem, result), "requirements": rows,
        "nominal": {**nominal, "figures": pages},
        "robustness_figure": f"{name}_robustness" if f"{name}_robustness" in figures else None,
        "figures": list(figures),
    }
    return Section(data=to_jsonable(data, nonfinite="string"), claims=tuple(claims), figures=figures, files=files)


# --------------------------------------------------------------------------- structural checks


def _finding_dict(finding: Any) -> dict[str, Any]:
    if hasattr(finding, "as_dict"):
        return to_jsonable(finding.as_dict(), nonfinite="string")
    return {"kind": str(getattr(finding, "kind", "finding")), "severity": str(getattr(finding, "severity", "info")),
            "message": str(getattr(finding, "message", finding)), "modes": list(getattr(finding, "modes", ())),
            "transitions": list(getattr(finding, "transitions", ()))}


def findings_summary(findings: Sequence[Mapping[str, Any]], worst: int = WORST_FINDINGS) -> dict[str, Any]:
    """Counts of structural findings by severity and by kind, and the worst ``worst`` of them.

    Parameters
    ----------
    findings : sequence of mapping
        JSON findings (``kind``, ``severity``, ``message``, ``modes``, ``transitions``), as
        :meth:`hybrid.check.Finding.as_dict` writes them.
    worst : int
        How many to list: errors first, then warnings, then infos, each in the given order.

    Returns
    -------
    dict
        ``total``, ``by_severity`` (every severity, zero included), ``by_kind`` (rows
        ``{severity, kind, count}``, most severe first) and ``worst`` (the findings without witness).
    """
    def rank(severity: str) -> int:
        return _SEVERITY_RANK.get(severity, len(_SEVERITY_RANK))

    by_severity = {s: sum(f["severity"] == s for f in findings) for s in _SEVERITY_RANK}
    kinds: dict[tuple[str, str], int] = {}
    for f in findings:
        kinds[(f["severity"], f["kind"])] = kinds.get((f["severity"], f["kind"]), 0) + 1
    by_kind = [{"severity": s, "kind": k, "count": n}
               for (s, k), n in sorted(kinds.items(), key=lambda item: (rank(item[0][0]), item[0][1]))]
    ordered = sorted(range(len(findings)), key=lambda i: (rank(findings[i]["severity"]), i))[:worst]
    shown = [{k: findings[i].get(k) for k in ("severity", "kind", "message", "modes", "transitions")}
             for i in ordered]
    return {"total": len(findings), "by_severity": by_severity, "by_kind": by_kind, "worst": shown}


def structure_section(problem: Any) -> Section | None:
    """The structural checks of ``problem`` (``problem.structural()``) summarised; ``None`` when it has none.

    Data: ``automaton``, ``clean``, ``summary`` (:func:`findings_summary`), ``findings`` (all), and,
    from a :class:`hybrid.check.CheckReport`, ``checks`` (each check ran or skipped, and why),
    ``samples``, ``seed``, ``claims`` (per check: proven, found, sampled, undecided or skipped, how and
    under which assumptions), ``zeno`` (the cycles grouped by verdict), ``pairs`` (every decided pair of
    transitions sharing a mode) and ``solver``.  Claims: one for the graph checks and one per check
    with a claim (:func:`visnav.app.structural.report_claims`).
    """
    from visnav.app.structural import completeness_data, report_claims, structural_data, verdict_line

    if problem.structural is None:
        return None
    report = problem.structural()
    findings = [_finding_dict(f) for f in getattr(report, "findings", ())]
    summary = findings_summary(findings)
    errors, warnings = summary["by_severity"]["error"], summary["by_severity"]["warning"]
    searched = getattr(report, "searched", None)
    automaton = str(getattr(report, "automaton", problem.name))
    completeness = completeness_data(report)
    data = {"automaton": automaton, "clean": verdict_line(report)[0] == "clean",
            "complete": bool(completeness.get("complete")), "incomplete": list(completeness.get("incomplete", ())),
            "summary": summary, "findings": findings,
            "checks": dict(getattr(searched, "checks", {})), "samples": getattr(searched, "samples", None),
            "seed": getattr(searched, "seed", None), **structural_data(report)}
    claims = report_claims(report, section="structure", subject=automaton, claim=Claim)
    return Section(data=to_jsonable(data, nonfinite="string"), claims=tuple(claims))


def stability_section(problem: Any) -> Section | None:
    """The stability analysis of ``problem`` (``problem.stability()``); ``None`` when it has none.

    Data: the analysis (:meth:`analysis.stability.StabilityAnalysis.as_dict`). Claims: the analysis'
    proven claims as PROVEN and its measured ones as MEASURED; a conclusion it could not reach is not a
    claim (it stays in the data, with why, and the document shows it).  Figure: the periodic orbit
    when there is one (:func:`visnav.app.figures_verification.orbit_figure`).
    """
    from visnav.app.figures_verification import orbit_figure

    if problem.stability is None:
        return None
    analysis = problem.stability()
    data = analysis.as_dict()
    claims = tuple(Claim(text=c.text, status=c.status, section="stability") for c in analysis.claims
                   if c.status in CLAIM_STATUSES)
    figures = {}
    if analysis.orbit is not None:
        figures["stability_orbit"] = orbit_figure(analysis.orbit)
    data["figures"] = sorted(figures)
    return Section(data=to_jsonable(data, nonfinite="string"), claims=claims, figures=figures)


# --------------------------------------------------------------------------- the document


def structural_errors(data: Mapping[str, Any]) -> dict[str, Any]:
    """The structural errors of a report's data: the ``structure`` section's (a problem's checks) and the
    ``model`` section's (the scenario's supervisor).

    Returns
    -------
    dict
        ``count`` (errors: findings of severity ``error``, each a defect whose witness re-checked on the
        model), ``kinds`` (sorted) and ``sections`` (where they are, in report order).
    """
    count, kinds, sections, undecided = 0, set(), [], []
    for name, key in (("structure", None), ("model", "structural_checks")):
        section = data.get(name)
        checks = section.get(key) if isinstance(section, Mapping) and key else section
        if not isinstance(checks, Mapping) or "summary" not in checks:
            continue
        if checks.get("complete") is False:
            undecided += [f"{name}: {why}" for why in checks.get("incomplete", ())] or [f"{name}: not complete"]
        errors = [row for row in checks["summary"]["by_kind"] if row["severity"] == "error"]
        if errors:
            count += sum(row["count"] for row in errors)
            kinds.update(row["kind"] for row in errors)
            sections.append(name)
    out = {"count": count, "kinds": sorted(kinds), "sections": sections}
    if undecided:  # the checks that did not decide (a report says so only when there are some)
        out["undecided"] = undecided
    return out


def overall_verdict(verification: str | None, errors: Mapping[str, Any]) -> str | None:
    """A report's overall verdict: the verification's, except that structural errors turn a proven, not
    falsified or incomplete one into :data:`STRUCTURAL_ERROR` (a falsified, diverged or model-error
    verification keeps its verdict; the errors are listed beside it), and structural checks that did not all
    decide turn a pass into ``incomplete`` (never a pass over a check that did not complete)."""
    if verification in ("proven", "not_falsified", "incomplete", None) and errors["count"]:
        return STRUCTURAL_ERROR
    if verification in ("proven", "not_falsified") and errors.get("undecided"):
        return "incomplete"
    return verification


def assemble_report(meta: Mapping[str, Any], sections: Sequence[tuple[str, Section]],
                    timings: Mapping[str, float] | None = None) -> Report:
    """The report of ``sections`` in order: their data by name, every claim, the counts and the verdict.

    ``report.json``'s top-level ``verdict`` is the ``verification`` section's overall verdict
    (``None`` without one), turned into :data:`STRUCTURAL_ERROR` when a structural check found an error
    (:func:`overall_verdict`); ``exit_code`` is its :data:`REPORT_EXIT_CODES`, ``structural_errors``
    the errors counted (:func:`structural_errors`).
    """
    data: dict[str, Any] = {"meta": dict(meta), "sections": [name for name, _ in sections]}
    claims: list[Claim] = []
    figures: dict[str, Any] = {}
    files: dict[str, str] = {}
    for name, section in sections:
        data[name] = round_section(name, section.data)  # every number to its digits (visnav.app.precision)
        claims += section.claims
        figures.update(section.figures)
        files.update(section.files)
    data["claims"] = [c.as_dict() for c in claims]
    data["claim_counts"] = {s: sum(c.status == s for c in claims) for s in CLAIM_STATUSES}
    data["structural_errors"] = structural_errors(data)
    data["verdict"] = overall_verdict(data.get("verification", {}).get("verdict"), data["structural_errors"])
    data["exit_code"] = None if data["verdict"] is None else REPORT_EXIT_CODES[data["verdict"]]
    return Report(data=to_jsonable(data), figures=figures, files=files, timings_s=dict(timings or {}))


def report_command(target: str, *, quick: bool, seed: int, budget: int) -> str:
    """The command that regenerates a report: ``visnav report TARGET [--quick] --seed S [--budget B]``.

    ``--budget`` is written only when it differs from the mode's default.
    """
    default = VERIFY_BUDGET_QUICK if quick else VERIFY_BUDGET
    return (f"visnav report {target}" + (" --quick" if quick else "") + f" --seed {seed}"
            + (f" --budget {budget}" if budget != default else ""))


def build_problem_report(problem: Any, *, spec: str, options: Mapping[str, Any] | None = None, seed: int = 0,
                         budget: int = VERIFY_BUDGET, quick: bool = False, method: str = "guided",
                         progress: Progress | None = None) -> Report:
    """Verify ``problem`` and build its report (verification, then structure when it has checks).

    Parameters
    ----------
    problem : analysis.verify.verification.VerificationProblem
    spec : str
        How the problem was named on the command line (counterexample files, the regeneration command).
    options : Mapping, optional
        Its loading options (``paper`` only: scenario, variant).
    seed, budget, method :
        Of :func:`analysis.verify.verdicts.verify`.
    quick : bool
        Recorded (the quick report has the smaller default budget).
    progress : callable, optional
        Called with each section's name as it starts.

    Raises
    ------
    analysis.verify.falsification.FalsificationError, analysis.verify.falsification.SimulationFailed
        As :func:`analysis.verify.verdicts.verify`.
    """
    import time

    from analysis.verify.verdicts import verify

    timings: dict[str, float] = {}
    sections: list[tuple[str, Section]] = []
    start = time.perf_counter()
    if progress is not None:
        progress("verification")
    result = verify(problem, budget=budget, seed=seed, method=method)
    sections.append(("verification", verification_section(problem, result, spec=spec, options=options)))
    timings["verification"] = time.perf_counter() - start
    if problem.structural is not None:
        if progress is not None:
            progress("structure")
        start = time.perf_counter()
        sections.append(("structure", structure_section(problem)))
        timings["structure"] = time.perf_counter() - start
    if problem.stability is not None:
        if progress is not None:
            progress("stability")
        start = time.perf_counter()
        sections.append(("stability", stability_section(problem)))
        timings["stability"] = time.perf_counter() - start
    option_text = "".join(f" --{k} {v}" for k, v in sorted((options or {}).items()))
    meta = {"tool": "visnav report", "problem": problem.name, "source": spec, "quick": quick,
            "seeds": {"report": seed}, "budgets": {"verify_budget": budget}, "method": method,
            "command": report_command(f"--problem {spec}{option_text}", quick=quick, seed=seed, budget=budget),
            "versions": dependency_versions()}
    return assemble_report(meta, sections, timings)
