"""Whether :func:`hybrid.check` decided every check, and the counts its summaries print, from one source.

A :class:`~hybrid.check.CheckReport` is *clean* only when it is *complete* (every
check ran and gave an answer) and has no error or warning.  :func:`check_statuses`
derives one :class:`CheckStatus` per check from the report itself (its claims, the
remarks of :class:`~hybrid.check.SearchSummary` and its findings):

* ``decided``: answered with nothing found (PROVEN by the solver, or exact on the mode graph);
* ``finding``: an error, warning or info of this check was found (each with a witness);
* ``sampled``: searched by sampling with nothing found (evidence, not proof: SAMPLED);
* ``skipped``: not run, or not run on every mode (no box, or functions the chosen method cannot take);
* ``undecided``: run, without an answer (a solver's ``unknown``, a timeout, cycles without a dwell bound).

``skipped`` and ``undecided`` make a report incomplete; :func:`incomplete_reasons` names
them with why.  :func:`finding_counts` counts the findings per summary item (overlaps,
instantaneous cycles, ...): the one function every summary line reads, so a line never
contradicts the findings below it.  :func:`state_claims` states each state-space check's
claim (:class:`hybrid.decide.Claim`) from what the solver decided and what was sampled.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .findings import KIND_SEVERITY, Finding

__all__ = [
    "CHECK_STATUSES",
    "CLAIMED_CHECKS",
    "CHECK_KINDS",
    "SMT_CANNOT_DECIDE",
    "SHORT_REASON",
    "CheckStatus",
    "check_statuses",
    "incomplete_reasons",
    "finding_counts",
    "state_claims",
    "undecided_cycles",
    "zeno_group",
]

CHECK_STATUSES = ("decided", "finding", "sampled", "skipped", "undecided")
"""The status of one check (module docstring); the last two make a report incomplete."""

CLAIMED_CHECKS = ("nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers", "zeno")
"""The state-space checks, each with a claim (``zeno``: the cycles of the mode graph)."""

EXACT_CHECKS = ("unreachable", "sink_mode")
"""The graph checks: exact on the mode graph, always decided."""

CHECK_KINDS: Mapping[str, tuple[str, ...]] = {
    "unreachable": ("unreachable_mode", "unreachable_transition"),
    "sink_mode": ("sink_mode",),
    "nondeterminism": ("nondeterminism", "priority_overlap"),
    "deadlock": ("deadlock",),
    "reset_outside_invariant": ("reset_outside_invariant",),
    "reset_retriggers": ("reset_retriggers", "zeno_point"),
    "zeno": ("reset_retriggers", "zeno_point"),
}
"""The finding kinds each check reports."""

SMT_CANNOT_DECIDE = "plain callables cannot be decided by SMT, use method 'auto' or 'sampled'"
"""Why a check is skipped under ``method="smt"`` on modes whose functions are not :mod:`hybrid.symbolic`."""

_FROM_CLAIM = {"proven": "decided", "found": "finding", "sampled": "sampled", "undecided": "undecided",
               "skipped": "skipped"}
_SAMPLED_METHOD = "sampling (uniform samples, corners, faces, Nelder-Mead); a search that finds nothing is evidence"


@dataclass(frozen=True, kw_only=True, slots=True)
class CheckStatus:
    """How one check ended.

    Attributes
    ----------
    check : str
        One of :data:`EXACT_CHECKS` or :data:`CLAIMED_CHECKS`.
    status : str
        One of :data:`CHECK_STATUSES`.
    reason : str
        How it was answered, or why it was not.
    covered : bool
        Whether every mode was searched (a ``finding`` over part of the modes is not complete).
    """

    check: str
    status: str
    reason: str = ""
    covered: bool = True

    def __post_init__(self) -> None:
        if self.status not in CHECK_STATUSES:
            raise ValueError(f"CheckStatus.status = {self.status!r}; expected one of {CHECK_STATUSES}")

    @property
    def complete(self) -> bool:
        """Ran on every mode and gave an answer (``decided``, ``finding`` or ``sampled``)."""
        return self.covered and self.status in ("decided", "finding", "sampled")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {"check": self.check, "status": self.status, "reason": self.reason, "covered": self.covered,
                "complete": self.complete}


def check_statuses(report: Any) -> tuple[CheckStatus, ...]:
    """One :class:`CheckStatus` per check of a :class:`~hybrid.check.CheckReport`, graph checks first.

    A report without claims (e.g. a user's own structural callable built on the same classes) is read
    from its :attr:`~hybrid.check.SearchSummary.checks` remarks: ``skipped: ...`` is skipped, a check
    that ran is sampled, and the Zeno question of a graph with cycles is undecided.
    """
    findings: Sequence[Finding] = tuple(getattr(report, "findings", ()))
    searched = getattr(report, "searched", None)
    remarks = dict(getattr(searched, "checks", {}) or {})
    claims = getattr(report, "claims", None) or {}
    out = []
    for name in EXACT_CHECKS:
        found = any(f.kind in CHECK_KINDS[name] for f in findings)
        out.append(CheckStatus(check=name, status="finding" if found else "decided", reason="exact, on the mode graph"))
    for name in CLAIMED_CHECKS:
        remark = str(remarks.get("zeno_candidate" if name == "zeno" else name, ""))
        found = any(f.kind in CHECK_KINDS[name] for f in findings)
        if name in claims:
            claim = claims[name]
            status = _FROM_CLAIM[claim.status]
            reason = claim.detail if claim.status in ("skipped", "undecided") and claim.detail else claim.method
        elif remark.startswith("skipped"):
            status, reason = "skipped", remark.removeprefix("skipped: ")
        elif name == "zeno":
            cycles = getattr(searched, "cycles_found", 0)
            status = "finding" if found else ("undecided" if cycles else "decided")
            reason = "cycles of the mode graph not decided" if cycles else "the mode graph has no cycle (exact)"
        else:
            status, reason = ("finding" if found else "sampled"), _SAMPLED_METHOD
        covered = "not searched" not in remark
        if name == "zeno" and status == "finding":  # a Zeno finding does not decide the other cycles
            z = getattr(report, "zeno", None)
            left = (getattr(searched, "cycles_found", 0) if z is None or reason.startswith("sampling") else
                    z.counts.get("undecided", 0) + int(bool(z.capped)))
            if left:
                covered, reason = False, f"{left} cycle(s) of the mode graph not decided; {reason}"
        if not covered and status in ("decided", "sampled"):
            status, reason = "skipped", remark.removeprefix("ran: ")
        out.append(CheckStatus(check=name, status=status, reason=reason, covered=covered))
    return tuple(out)


SHORT_REASON = 160
"""Most characters of the reason :func:`incomplete_reasons` gives (the statuses carry it whole)."""


def incomplete_reasons(statuses: Sequence[CheckStatus]) -> tuple[str, ...]:
    """``"deadlock skipped: <why>"`` for every check that is not complete, in check order.

    The reason is the first clause of :attr:`CheckStatus.reason` (up to ``"; "``), at most
    :data:`SHORT_REASON` characters.
    """
    out = []
    for s in statuses:
        if not s.complete:
            status = s.status if s.covered or s.status in ("skipped", "undecided") else f"{s.status}, not complete"
            why = _first_clause(s.reason)
            why = why if len(why) <= SHORT_REASON else why[:SHORT_REASON - 1] + "…"
            out.append(f"{s.check} {status}: {why}")
    return tuple(out)


def _first_clause(text: str) -> str:
    """``text`` up to its first ``"; "`` outside parentheses."""
    depth = 0
    for i, ch in enumerate(text):
        depth += (ch == "(") - (ch == ")")
        if depth == 0 and text.startswith("; ", i):
            return text[:i]
    return text


def finding_counts(findings: Sequence[Any]) -> dict[str, int]:
    """The counts every summary line prints, computed from the findings (objects or their JSON dicts).

    Returns
    -------
    dict
        ``overlap`` (two transitions enabled together: ``nondeterminism`` + ``priority_overlap``),
        ``equal_priority_overlap`` (``nondeterminism``), ``instantaneous`` (``reset_retriggers``),
        ``zeno_point``, ``deadlock``, ``reset_outside_invariant``, ``unreachable``
        (``unreachable_mode`` + ``unreachable_transition``), ``sink_mode``; and ``error``,
        ``warning``, ``info`` (per severity).
    """
    kinds: dict[str, int] = {}
    severities = {"error": 0, "warning": 0, "info": 0}
    for f in findings:
        kind, severity = (f["kind"], f["severity"]) if isinstance(f, Mapping) else (f.kind, f.severity)
        kinds[kind] = kinds.get(kind, 0) + 1
        severities[severity] = severities.get(severity, 0) + 1
    return {
        "overlap": kinds.get("nondeterminism", 0) + kinds.get("priority_overlap", 0),
        "equal_priority_overlap": kinds.get("nondeterminism", 0),
        "instantaneous": kinds.get("reset_retriggers", 0),
        "zeno_point": kinds.get("zeno_point", 0),
        "deadlock": kinds.get("deadlock", 0),
        "reset_outside_invariant": kinds.get("reset_outside_invariant", 0),
        "unreachable": kinds.get("unreachable_mode", 0) + kinds.get("unreachable_transition", 0),
        "sink_mode": kinds.get("sink_mode", 0),
        **severities,
    }


def state_claims(decision: Any, sampled: set[str], boxes: Mapping[str, Any] | None, findings: Sequence[Finding],
                 method: str, cycles: int) -> dict[str, Any]:
    """Per state-space check: PROVEN, FOUND, SAMPLED (a mode was sampled), UNDECIDED or SKIPPED.

    Parameters
    ----------
    decision : hybrid.decide.Decision or None
        What the solver decided (``None`` with ``method="sampled"`` or without a box).
    sampled : set of str
        The modes searched by sampling.
    boxes : Mapping[str, Box] or None
    findings : sequence of Finding
        Every finding of the report.
    method : {"auto", "sampled", "smt"}
    cycles : int
        Cycles of the mode graph (``0``: the Zeno question is settled on the graph).

    Returns
    -------
    dict
        Check name -> :class:`hybrid.decide.Claim`.  Under ``method="smt"``, a check the solver left
        to sampling (functions that are not symbolic) is ``skipped`` (:data:`SMT_CANNOT_DECIDE`),
        never labelled sampled: nothing was sampled.
    """
    from .decide import Claim

    kinds = {f.kind for f in findings}
    if boxes is None:
        why = "no box given; pass a Box (or a mapping mode -> Box) to search the state space"
        return {c: Claim(check=c, status="skipped", method="not run", detail=why) for c in CLAIMED_CHECKS}
    all_sampled = decision is None or (method != "smt" and set(boxes) <= sampled)
    undecidable = {} if decision is None else dict(decision.sampled_modes)
    if decision is None:
        why = "method sampled" if method == "sampled" else "not decided"
    else:
        why = "the model's functions are not symbolic: " + "; ".join(
            f"{q}: {undecidable[q]}" for q in sorted(sampled)[:2] if q in undecidable)
    out: dict[str, Any] = {}
    for c in CLAIMED_CHECKS:
        found = c in kinds or (c == "zeno" and "reset_retriggers" in kinds)
        if c == "zeno" and not cycles and not found:
            out[c] = Claim(check=c, status="proven", method="exact, on the mode graph",
                           detail="the mode graph has no cycle")
        elif all_sampled:
            out[c] = (Claim(check=c, status="found" if found else "undecided", method=_SAMPLED_METHOD,
                            detail=f"cycles not decided ({why})") if c == "zeno" else
                      Claim(check=c, status="found" if found else "sampled", method=_SAMPLED_METHOD,
                            detail=f"every mode sampled ({why})"))
        else:
            out[c] = _mixed_claim(Claim, c, decision.claims[c], found, sampled, undecidable, method)
    return out


def _mixed_claim(claim: Any, c: str, decided: Any, found: bool, sampled: set[str], undecidable: Mapping[str, str],
                 method: str) -> Any:
    """The claim of a check the solver answered (on every mode, or with some modes sampled)."""
    detail = decided.detail
    if method == "smt" and undecidable:
        names = "; ".join(f"{q}: {why}" for q, why in sorted(undecidable.items()))
        detail = (detail + "; " if detail else "") + f"not decided in modes {sorted(undecidable)} ({names})"
        if found:
            status = "found"
        elif decided.status == "sampled":
            status, detail = "skipped", f"{SMT_CANNOT_DECIDE}; {detail}"
        elif decided.status == "undecided":
            status = "undecided"
        else:
            status = decided.status
        return claim(check=c, status=status, method=decided.method, assumptions=decided.assumptions, detail=detail)
    if found:
        status = "found"
    elif decided.status == "undecided":
        status = "undecided"
    elif sampled:
        status = "sampled"
    else:
        status = decided.status
    if sampled:
        detail = (detail + "; " if detail else "") + f"modes sampled, not decided: {sorted(sampled)}"
    return claim(check=c, status=status, method=decided.method if not sampled else
                 decided.method + "; " + _SAMPLED_METHOD, assumptions=decided.assumptions, detail=detail)


def undecided_cycles(cycles: list[tuple[tuple[str, ...], tuple[str, ...]]], decision: Any
                     ) -> list[tuple[tuple[str, ...], tuple[str, ...]]]:
    """The cycles the solver left undecided (every cycle without a decision)."""
    if decision is None or decision.zeno is None:
        return cycles
    return [(v.modes, v.transitions) for v in decision.zeno.verdicts if v.verdict == "undecided"]


def zeno_group(cycles: Sequence[tuple[tuple[str, ...], tuple[str, ...]]], capped: bool, why: str) -> Finding:
    """One finding for every cycle left undecided (never one row per cycle)."""
    (first, names) = cycles[0]
    examples = "; ".join(f"{' -> '.join((*c, c[0]))} (transitions {list(n)})" for c, n in cycles[:3])
    more = f" and {len(cycles) - 3} more" if len(cycles) > 3 else ""
    count = f"{len(cycles)}{'+' if capped else ''} cycle{'s' if len(cycles) != 1 else ''}"
    return Finding(
        kind="zeno_candidate",
        severity=KIND_SEVERITY["zeno_candidate"],
        message=(
            f"{count} of the mode graph not decided for Zeno ({why}): {examples}{more}; if the jumps of a cycle "
            "can follow one another without time passing, executions are Zeno or chatter; a reset that leaves "
            "every guard of the cycle, hysteresis or a dwell time rules it out"
        ),
        modes=first,
        transitions=names,
    )
