"""The structural checks of a scenario's supervisor: one definition for ``visnav check-model`` and ``visnav report``.

:func:`check_supervisor` runs :func:`hybrid.check` on the supervisor over its
measurements (:func:`visnav.supervisor.measurement_system`, the box of
:func:`visnav.supervisor.measurement_box`) with the rate bounds of the fuzzer's
measurement space (:meth:`visnav.fuzzing.space.MeasurementSpace.rates_per_s`):
the dwell bounds of the Zeno check and the bounded-rate fuzz runs read the same
numbers.  The supervisor is symbolic, so with ``method="auto"`` every check is
decided by the SMT solver (each clean answer PROVEN, each finding with a
re-checked witness); ``method="sampled"`` searches by sampling only.

:func:`claims_table`, :func:`pairs_line` and :func:`zeno_line` put a
:class:`hybrid.check.CheckReport`'s claims into words for the command's human
summary; :func:`structural_data` and :func:`report_claims` give the reports
(``visnav report``, with or without ``--problem``) the same claims: one per
check, PROVEN when the solver proved it, SAMPLED when a search found nothing,
MEASURED when a finding's witness was re-checked.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from visnav.parameters import Scenario

__all__ = [
    "CHECK_METHODS",
    "CLAIM_CHECKS",
    "DEFAULT_TIMEOUT_S",
    "REPORT_STATUS",
    "supervisor_space",
    "supervisor_rates",
    "check_supervisor",
    "verdict_line",
    "completeness_data",
    "claim_label",
    "pairs_line",
    "zeno_line",
    "claims_table",
    "structural_data",
    "report_claims",
]

CHECK_METHODS = ("auto", "sampled", "smt")
"""How the state-space questions are answered (:func:`hybrid.check`)."""

DEFAULT_TIMEOUT_S = 5.0
"""Timeout of one solver call [s]."""


def supervisor_space(scenario: Scenario) -> Any:
    """The fuzzer's measurement space of ``scenario`` (envelopes, settings, obstacles, camera, period;
    the default per-sample rate bounds): :func:`visnav.fuzzing.space.scenario_space`."""
    from visnav.fuzzing.space import scenario_space

    return scenario_space(scenario)


def supervisor_rates(scenario: Scenario) -> dict[str, float]:
    """Rate bounds [unit/s] of the coordinates of the scenario's :func:`~visnav.supervisor.measurement_system`
    (:meth:`~visnav.fuzzing.space.MeasurementSpace.rates_per_s`).

    A scenario without obstacles has no ``d_coll_i_m`` coordinate, while its measurement space holds
    one distance: only the coordinates of the system are kept.
    """
    n = len(scenario.obstacles)
    distances = {f"d_coll_{i}_m" for i in range(n)}
    return {name: rate for name, rate in supervisor_space(scenario).rates_per_s().items()
            if not name.startswith("d_coll_") or name in distances}


def check_supervisor(scenario: Scenario, *, samples: int, starts: int, seed: int, method: str = "auto",
                     timeout_s: float = DEFAULT_TIMEOUT_S, budget_s: float | None = None) -> Any:
    """:func:`hybrid.check` of ``scenario``'s supervisor over its measurement box.

    Parameters
    ----------
    scenario : Scenario
    samples, starts, seed : int
        Of the sampled search (modes the solver cannot take, or every mode with ``method="sampled"``).
    method : {"auto", "sampled", "smt"}
    timeout_s : float
        Timeout of one solver call [s], ``> 0``.
    budget_s : float or None
        Wall-clock budget of the sampled searches [s] (``None``: :data:`hybrid.check.SEARCH_BUDGET_S`).

    Returns
    -------
    hybrid.check.CheckReport

    Raises
    ------
    ValueError
        An unknown method or a timeout that is not a finite number > 0.
    """
    import math

    from hybrid import check

    from visnav.supervisor import build_supervisor, measurement_box, measurement_system

    if method not in CHECK_METHODS:
        raise ValueError(f"method = {method!r}; expected one of {', '.join(CHECK_METHODS)}")
    if isinstance(timeout_s, bool) or not isinstance(timeout_s, (int, float)) or not (
            math.isfinite(timeout_s) and timeout_s > 0):
        raise ValueError(f"timeout_s = {timeout_s!r}; expected a number of seconds > 0")
    model = build_supervisor(scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    system = measurement_system(model)
    return check(system, measurement_box(model, scenario.camera.half_width_px), samples=samples, starts=starts,
                 seed=seed, method=method, rates=supervisor_rates(scenario),
                 timeout_s=float(timeout_s), **({} if budget_s is None else {"budget_s": float(budget_s)}))


# --------------------------------------------------------------------------- the claims in words

CLAIM_CHECKS = ("nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers", "zeno")
"""The checks that carry a claim, in the order they are shown."""


def verdict_line(report: Any) -> tuple[str, str]:
    """``(verdict, text)`` of a structural check report, ``verdict`` one of ``"finding"``, ``"incomplete"``,
    ``"clean"``: ``CLEAN`` only when every check ran and decided and nothing was found.

    ``text`` names the errors and warnings, and every check that was skipped or undecided with why
    (:attr:`hybrid.check.CheckReport.incomplete`).  A report that does not say whether it is complete
    (a user's own structural callable returning another type) is incomplete.
    """
    findings = tuple(getattr(report, "findings", ()))
    errors = sum(f.severity == "error" for f in findings)
    warnings = sum(f.severity == "warning" for f in findings)
    incomplete = getattr(report, "incomplete", None)
    if incomplete is None:
        incomplete = ("the problem's own structural checks do not say whether every check decided "
                      "(return a hybrid.check.CheckReport)",)
    groups: dict[str, list[str]] = {}  # "skipped: why" -> the checks
    for line in incomplete:
        name, _, rest = line.partition(" ")
        groups.setdefault(rest, []).append(name)
    gaps = ((f"INCOMPLETE, {len(incomplete)} check(s) did not decide: "
             + "; ".join(f"{', '.join(names)} {rest}" for rest, names in groups.items())) if incomplete else "")
    if errors or warnings:
        return "finding", f"{errors} error(s), {warnings} warning(s)" + (f"; {gaps}" if gaps else "")
    if incomplete:
        return "incomplete", gaps
    return "clean", "CLEAN"


def completeness_data(report: Any) -> dict[str, Any]:
    """``{"complete", "incomplete", "statuses"}`` of a report, JSON-ready (:func:`verdict_line`'s reading of
    a report that does not say)."""
    if callable(getattr(report, "completeness", None)):
        return report.completeness()
    return {"complete": False, "incomplete": list(verdict_line(report)[1:]), "statuses": {}}


def claim_label(status: str) -> str:
    """``PROVEN``, ``FOUND``, ``SAMPLED``, ``UNDECIDED`` or ``SKIPPED``."""
    return status.upper()


def _claims(report: Any) -> Mapping[str, Any]:
    return getattr(report, "claims", None) or {}


def claims_table(report: Any) -> list[dict[str, str]]:
    """One row per check with a claim: ``check``, ``status``, ``method``, ``assumptions``, ``detail``."""
    claims = _claims(report)
    order = [c for c in CLAIM_CHECKS if c in claims] + [c for c in claims if c not in CLAIM_CHECKS]
    return [{"check": name, "status": claims[name].status, "method": claims[name].method,
             "assumptions": "; ".join(claims[name].assumptions), "detail": claims[name].detail}
            for name in order]


def pairs_line(pairs: Any, findings: Any) -> str | None:
    """``43 pairs of transitions sharing a source mode: 29 can be enabled together (re-checked witnesses),
    14 exclusive (proven); equal-priority overlaps: 0`` (``None`` without decided pairs).

    ``pairs`` is a sequence of :class:`hybrid.decide.PairVerdict` or of their JSON dicts; the overlaps
    are counted from ``findings`` (:func:`hybrid.completeness.finding_counts`), the proofs and the
    pairs the solver left undecided from ``pairs``.
    """
    from hybrid.completeness import finding_counts

    rows = [p if isinstance(p, Mapping) else p.as_dict() for p in (pairs or ())]
    if not rows:
        return None
    counts = finding_counts(findings)
    overlap, same = counts["overlap"], counts["equal_priority_overlap"]
    exclusive = sum(r["verdict"] == "exclusive" for r in rows)
    undecided = sum(r["verdict"] not in ("overlap", "exclusive") for r in rows)
    text = (f"{len(rows)} pair{'s' if len(rows) != 1 else ''} of transitions sharing a source mode: {overlap} can be "
            f"enabled together (re-checked witnesses), {exclusive} exclusive (proven)")
    if undecided:
        text += f", {undecided} not decided by the solver"
    return text + f"; equal-priority overlaps: {same}"


def _seconds(value: Any) -> str:
    return f"{float(value):.4g} s"


def zeno_line(zeno: Any, findings: Any) -> str | None:
    """The cycles grouped by verdict, one line: ``578 cycles: 578 non-Zeno (proven), smallest dwell bound
    0.05 s in LEAVE|CLEAR between ...; 0 instantaneous; 0 undecided`` (``None`` when not decided).

    ``zeno`` is a :class:`hybrid.decide.ZenoSummary` or its JSON dict; the instantaneous cycles and
    the Zeno points are counted from ``findings`` (``reset_retriggers``, ``zeno_point``:
    :func:`hybrid.completeness.finding_counts`), the proofs and the undecided cycles from ``zeno``.
    """
    from hybrid.completeness import finding_counts

    if zeno is None:
        return None
    z = zeno if isinstance(zeno, Mapping) else zeno.as_dict(verdicts=False)
    counts = {**dict(z["counts"]), **{k: v for k, v in finding_counts(findings).items()
                                      if k in ("instantaneous", "zeno_point")}}
    cycles = f"{z['cycles']}{'+' if z.get('capped') else ''} cycle{'s' if z['cycles'] != 1 else ''}"
    text = f"{cycles}: {counts.get('non_zeno', 0)} non-Zeno (proven)"
    if z.get("min_dwell_s") is not None:
        binding = str(z.get("binding") or "")
        text += f", smallest dwell bound {_seconds(z['min_dwell_s'])}"
        if binding.startswith("dwell >= ") and " s in " in binding:  # "dwell >= 0.05 s in Q between a and b"
            text += " " + binding.split(" s ", 1)[1]
        elif binding:  # "x must travel ... per lap at <= ... per s"
            text += f" ({binding})"
    if counts.get("infeasible"):
        text += f"; {counts['infeasible']} infeasible (proven)"
    text += f"; {counts.get('instantaneous', 0)} instantaneous"
    if counts.get("zeno_point"):
        text += f"; {counts['zeno_point']} with a Zeno point"
    return text + f"; {counts.get('undecided', 0)} undecided"


# --------------------------------------------------------------------------- the claims of a report

REPORT_STATUS = {"proven": "proven", "found": "measured", "sampled": "sampled"}
"""The report's claim status (:data:`visnav.app.verification_report.CLAIM_STATUSES`) of a check's claim:
a proof is PROVEN, a finding with a re-checked witness MEASURED (as a counterexample to a requirement), a
search that found nothing SAMPLED.  An ``undecided`` or ``skipped`` check makes no claim (the structural
checks' table lists it)."""

_ABSENT = {
    "nondeterminism": "no two transitions of equal priority enabled together",
    "deadlock": "no deadlock (wherever the flow leaves an invariant, a transition is enabled)",
    "reset_outside_invariant": "no jump lands outside its target's invariant",
    "reset_retriggers": "no jump re-enables its own guard at the same instant",
    "zeno": "no Zeno cycle (every cycle of jumps takes time)",
}
_KIND = {"nondeterminism": ("nondeterminism",), "deadlock": ("deadlock",),
         "reset_outside_invariant": ("reset_outside_invariant",), "reset_retriggers": ("reset_retriggers",),
         "zeno": ("reset_retriggers", "zeno_point")}
_GRAPH_KINDS = ("unreachable_mode", "unreachable_transition", "sink_mode")
_MESSAGE_CHARS = 240


def _short(text: str) -> str:
    return text if len(text) <= _MESSAGE_CHARS else text[:_MESSAGE_CHARS - 1] + "…"


def structural_data(report: Any) -> dict[str, Any]:
    """The claims, the grouped Zeno answer, the pairs and the solver of a :class:`hybrid.check.CheckReport`,
    JSON-ready, keyed as :meth:`~hybrid.check.CheckReport.as_dict` (empty for a report without them, e.g.
    a user's own structural callable)."""
    zeno = getattr(report, "zeno", None)
    return {"claims": {name: claim.as_dict() for name, claim in _claims(report).items()},
            "zeno": None if zeno is None else zeno.as_dict(verdicts=False),
            "pairs": [p.as_dict() for p in getattr(report, "pairs", ())],
            "solver": str(getattr(report, "solver", "") or "")}


def report_claims(report: Any, *, section: str, subject: str, claim: Callable[..., Any]) -> list[Any]:
    """The report's claims of a structural check report: one for the graph checks, one per check with a claim.

    Parameters
    ----------
    report : hybrid.check.CheckReport
        (or any object with ``findings``; without ``claims`` only the graph claim and one sampled claim
        of the whole are made).
    section : str
        The report section the claims belong to.
    subject : str
        What was checked, e.g. ``"the 18-mode supervisor"``.
    claim : callable
        ``claim(section=..., status=..., text=...)``: the report's claim type
        (:class:`visnav.app.verification_report.Claim`, passed in so that this module does not import
        the report that imports it).

    Returns
    -------
    list of what ``claim`` returns
    """
    Claim = claim  # noqa: N806 - the report's claim class

    findings = tuple(getattr(report, "findings", ()))
    graph = [f for f in findings if f.kind in _GRAPH_KINDS]
    if graph:
        counts: dict[str, int] = {}
        for f in graph:
            counts[f.kind] = counts.get(f.kind, 0) + 1
        text = (f"graph checks of {subject} (exact, on the mode graph): FOUND "
                + ", ".join(f"{n} {k.replace('_', ' ')}" for k, n in counts.items())
                + f"; first: {_short(graph[0].message)}")
        claims = [Claim(section=section, status="measured", text=text)]
    else:
        claims = [Claim(section=section, status="proven",
                        text=f"graph checks of {subject} (exact, on the mode graph): every mode and transition "
                             "reachable from the initial mode, no sink mode")]
    searched = getattr(report, "searched", None)
    sampling = ("" if searched is None else
                f"{searched.samples} samples per mode + corners and faces, {searched.starts} optimiser starts, "
                f"seed {searched.seed}; ")
    table = claims_table(report)
    if not table:  # a report without claims: the state-space checks as one sampled statement
        errors = sum(f.severity == "error" for f in findings)
        claims.append(Claim(section=section, status="sampled",
                            text=(f"state-space checks of {subject}: "
                                  + (f"{errors} error(s)" if errors else "no error found")
                                  + f" ({sampling}by sampling: a search that finds nothing can miss cases)")))
        return claims
    pairs, zeno = pairs_line(getattr(report, "pairs", ()), findings), zeno_line(getattr(report, "zeno", None), findings)
    for row in table:
        name, status = row["check"], row["status"]
        if status not in REPORT_STATUS:
            continue
        if status == "found":
            hits = [f for f in findings if f.kind in _KIND.get(name, (name,)) and f.severity != "info"] or [
                f for f in findings if f.kind in _KIND.get(name, (name,))]
            text = (f"{name} of {subject}: FOUND, {len(hits)} finding(s) with a witness re-checked on the model"
                    + (f"; first: {_short(hits[0].message)}" if hits else ""))
        else:
            evidence = {"nondeterminism": pairs, "zeno": zeno}.get(name) if status == "proven" else None
            how = row["method"] if status == "proven" else f"{sampling}{row['method']}"
            absent = _ABSENT.get(name, "nothing found")
            z = getattr(report, "zeno", None)
            if name == "zeno" and z is not None and z.counts.get("zeno_point"):
                absent = "no cycle of jumps instantaneous on an open set of states (Zeno points of the dynamics only)"
            text = f"{name} of {subject}: {absent}"  # the badge says PROVEN or SAMPLED
            if evidence:
                text += f"; {evidence}"
            text += f" ({how}"
            if status == "proven" and row["assumptions"]:
                text += f"; over {row['assumptions']}"
            text += ")"
        claims.append(Claim(section=section, status=REPORT_STATUS[status], text=text))
    return claims
