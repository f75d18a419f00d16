"""Signal Temporal Logic for sampled hybrid traces: grammar, parser, robustness, boolean semantics.

Generic (no robot in here): a :class:`SignalTrace` holds numeric signals and
string labels on a hybrid time domain (a repeated time is a jump);
:func:`parse_formula` turns a formula's text into an immutable
:class:`Formula` whose :meth:`~Formula.robustness`,
:meth:`~Formula.satisfied` and :meth:`~Formula.explain` evaluate it on a
trace.  Grammar, semantics and error messages: ``docs/stl.md``.

Examples
--------
>>> trace = SignalTrace(times=[0.0, 1.0, 2.0], signals={"x": [2.0, 0.5, 1.5]}, labels={"mode": ("A", "B", "A")})
>>> parse_formula('always[0, 2] (x > 0 and (mode == "B" -> x < 1))').robustness(trace)
0.5
"""

from analysis.stl.semantics import TIME_RESOLUTION, Explanation, Formula, FormulaValueError, parse_formula
from analysis.stl.syntax import FormulaError
from analysis.stl.trace import SignalTrace, TraceError

__all__ = [
    "TIME_RESOLUTION",
    "Explanation",
    "Formula",
    "FormulaError",
    "FormulaValueError",
    "SignalTrace",
    "TraceError",
    "parse_formula",
]
