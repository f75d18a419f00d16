"""Counterexample files of ``visnav verify`` and the command that replays one: one place for both, read by
``verify`` (:mod:`visnav.app.cli_verify`) and the report (:mod:`visnav.app.verification_report`).
"""

from __future__ import annotations

import json
import shlex
from collections.abc import Mapping
from typing import Any

__all__ = ["COUNTEREXAMPLE_FORMAT", "PAPER", "replay_command", "counterexample_text", "is_verification_counterexample"]

COUNTEREXAMPLE_FORMAT = "visnav-verification-counterexample"
PAPER = "paper"
"""The built-in problem: it names no user code, so ``visnav replay`` needs no ``--problem`` for it."""


def replay_command(path: Any, spec: str) -> str:
    """The command replaying the counterexample file ``path`` of problem ``spec`` (``--problem`` unless paper:
    ``visnav replay`` runs only a problem the command line names, :mod:`visnav.app.cli_replay`)."""
    command = f"visnav replay {shlex.quote(str(path))}"
    return command if spec == PAPER else f"{command} --problem {shlex.quote(spec)}"


def _trace_rows(trace: Any, labels: list[str], names: list[str], indices: Any,
                keep: Any = lambda value, kind: value) -> list[list[Any]]:
    times, jumps = trace.times[indices], trace.jumps[indices]
    label_values = [[trace.label(n)[k] for k in indices] for n in labels]
    signal_values = [trace.signal(n)[indices] for n in names]
    return [[keep(float(times[i]), "time"), int(jumps[i]), *(v[i] for v in label_values),
             *(keep(float(v[i]), "simulation") for v in signal_values)] for i in range(len(indices))]


def counterexample_text(result: Any, verdict: Any, problem: Any, spec: str, options: Mapping[str, Any], *,
                        rounded: bool = False) -> str:
    """The counterexample file of a falsified requirement: where, how much, and the trace it reads.

    The stored trace is bounded so that ``visnav replay`` can read the file back
    (:data:`analysis.counterexamples.TRACE_ROWS` samples, :data:`~analysis.counterexamples.TRACE_BYTES`):
    a longer trace is decimated (its first and last samples, the violation instant, every jump and
    mode change kept, :func:`~analysis.counterexamples.stored_sample_indices`) and the file says so in
    ``trace_decimated`` (the original sample count).  The point, the requirement and the robustness are
    always written whole: replay re-simulates the point, it does not read the trace.  ``rounded`` (the
    report's files): the trace, the robustness and the instant with the digits the report prints
    (:mod:`visnav.app.precision`: ``time``, ``simulation``); the unit coordinates that ``visnav replay``
    re-runs are kept bit for bit either way.
    """
    from analysis.counterexamples import (TRACE_BYTES, TRACE_ROWS, CounterexampleFormat, encode_value,
                                          stored_sample_indices)

    from visnav.app.precision import round_value

    def keep(value: float, kind: str) -> float:
        return round_value(value, kind) if rounded else value

    cx = verdict.counterexample
    parsed = next(p for p in problem.parsed if p.name == verdict.name)
    trace = problem.trace(problem.point(cx.unit))
    names = sorted(parsed.formula.signals - {"time", "jumps"})
    labels = sorted(parsed.formula.labels)
    fmt = CounterexampleFormat(name=COUNTEREXAMPLE_FORMAT, version=1, reader="this visnav")
    fields = {
        "problem": spec, "options": dict(options), "requirement": verdict.name, "formula": verdict.formula,
        "unit": list(cx.unit), "point": dict(cx.point), "robustness": keep(cx.robustness, "simulation"),
        "time": keep(cx.time, "time"),
        "atom": cx.atom, "how": cx.how, "seed": result.seed, "method": result.method,
        "columns": ["time", "jumps", *labels, *names],
        "replay": replay_command("<this file>", spec).replace("'<this file>'", "<this file>"),
    }
    n = trace.n
    ends = _trace_rows(trace, labels, names, [0, n - 1] if n else [], keep)
    row_bytes = max((len(json.dumps(encode_value(row)).encode("utf-8")) for row in ends), default=0) + 8
    budget = min(TRACE_ROWS, max(TRACE_BYTES // max(row_bytes, 1), 8))
    while True:
        changes = [trace.jumps, *(trace.label(name) for name in labels)]
        indices, all_changes = stored_sample_indices(trace.times, instants=(cx.time,), changes=changes,
                                                     max_rows=budget)
        extra = {} if len(indices) == n else {"trace_decimated": {
            "samples": n, "stored": len(indices), "every_change_kept": all_changes,
            "kept": "the first and last samples, the two around the violation time, both samples of every jump "
                    "and mode change, and evenly spaced samples between"}}
        text = fmt.dumps({**fields, **extra}, rows_key="trace", rows=_trace_rows(trace, labels, names, indices, keep))
        if len(text.encode("utf-8")) <= TRACE_BYTES or budget <= 8:
            return text
        budget = max(budget // 2, 8)  # the rows were longer than the ends said


def is_verification_counterexample(text: str) -> bool:
    """Whether ``text`` looks like a counterexample file of ``visnav verify`` (its format key)."""
    return f'"format": "{COUNTEREXAMPLE_FORMAT}"' in text[:4096]
