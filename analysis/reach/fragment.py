"""The STL safety fragment that reachability decides: ``always[a, b] φ`` over affine state predicates.

:func:`safety_fragment` reads a parsed formula's syntax tree (:mod:`analysis.stl.syntax`) and
returns a :class:`SafetyFragment` — the window ``[a, b]`` and ``φ`` in negation normal form,
whose leaves are

* :class:`LinearAtom` ``c·x <= d`` or ``c·x < d`` over the state names, with exact rational
  ``c`` and ``d`` (every number of the formula read exactly from its float), and
* :class:`LabelAtom` ``mode == pattern`` or ``mode != pattern`` (decided exactly per mode, with
  the STL pattern matcher :func:`analysis.stl.syntax.label_pattern`).

Anything else is refused with :class:`NotInFragment` and the reason (the falsifier then decides
the requirement alone): another temporal operator at the top or inside ``φ`` (``eventually``,
``until``, past operators, edges), a window not starting at 0, a variable that is not a state
(``time``, ``jumps``, a parameter, an output), and *non-affine* atoms — products of states,
``abs`` inside a sum, ``min``, ``max``, ``prev``.  Polynomial atoms are not in this first version.
(``abs(e) <= r`` and ``abs(e) >= r`` with affine ``e``, ``r`` are read as two affine atoms.)

The fragment is only a *reading* of the formula; deciding it on sets is done separately by the
producer (:mod:`analysis.reach.verdict`, on zonotopes) and by the re-check
(:mod:`analysis.reach.recheck`, on boxes in exact rationals).

Examples
--------
>>> from analysis.stl.syntax import parse_tree
>>> f = safety_fragment(parse_tree("always[0, 5] (T >= 18.5 and T <= 21.5)"), ("T",), ("mode",))
>>> f.start, f.end, len(atoms(f.body))
(0.0, 5.0, 2)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Union

from analysis.stl import syntax as s
from analysis.stl.syntax import label_pattern

__all__ = ["NotInFragment", "LinearAtom", "LabelAtom", "Conj", "Disj", "Nnf", "SafetyFragment",
           "safety_fragment", "atoms", "label_holds"]


class NotInFragment(ValueError):
    """The formula is not in the reachability fragment; the message says why (``"not in the fragment: ..."``)."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"not in the fragment: {reason}")
        self.reason = reason


@dataclass(frozen=True, kw_only=True, slots=True)
class LinearAtom:
    """``coefficients · x <= bound`` (``strict``: ``<``), over the state vector; ``text`` for messages."""

    coefficients: tuple[Fraction, ...]
    bound: Fraction
    strict: bool
    text: str


@dataclass(frozen=True, kw_only=True, slots=True)
class LabelAtom:
    """``label == pattern`` (``negated``: ``!=``); only the mode label is allowed."""

    label: str
    pattern: str
    negated: bool

    def holds(self, mode: str) -> bool:
        """Whether the atom holds in ``mode`` (exact)."""
        return label_holds(self, mode)


@dataclass(frozen=True, kw_only=True, slots=True)
class Conj:
    """Conjunction of the parts (empty: true)."""

    parts: tuple["Nnf", ...]


@dataclass(frozen=True, kw_only=True, slots=True)
class Disj:
    """Disjunction of the parts (empty: false)."""

    parts: tuple["Nnf", ...]


Nnf = Union[LinearAtom, LabelAtom, Conj, Disj]


@dataclass(frozen=True, kw_only=True, slots=True)
class SafetyFragment:
    """``always[start, end] body`` with ``body`` in negation normal form over ``state_names``."""

    start: float
    end: float
    body: Nnf
    state_names: tuple[str, ...]
    text: str


def label_holds(atom: LabelAtom, mode: str) -> bool:
    """``mode`` matched against the atom's pattern (the STL matcher), negated for ``!=``."""
    return label_pattern(atom.pattern).fullmatch(mode) != atom.negated


def atoms(node: Nnf) -> tuple[LinearAtom | LabelAtom, ...]:
    """The leaves of an NNF formula, left to right."""
    if isinstance(node, (Conj, Disj)):
        return tuple(a for p in node.parts for a in atoms(p))
    return (node,)


def safety_fragment(tree: s.Node, state_names: Sequence[str], labels: Sequence[str] = ("mode",)) -> SafetyFragment:
    """The fragment reading of a formula's syntax tree.

    Parameters
    ----------
    tree : analysis.stl.syntax.Node
        ``problem.parsed[i].formula.tree``.
    state_names : sequence of str
        The system's states, in vector order (the only numeric variables allowed).
    labels : sequence of str
        Label names read as the automaton's mode (``"mode"``).

    Raises
    ------
    NotInFragment
        With the reason.
    """
    names = tuple(state_names)
    if not (isinstance(tree, s.Temporal) and tree.op == "always"):
        raise NotInFragment(f"the formula is not always[a, b] φ (its top is {_kind(tree)})")
    a, b = tree.interval if tree.interval is not None else (0.0, float("inf"))
    if a != 0:
        raise NotInFragment(f"the window [{a:g}, {b:g}] does not start at 0 (windows from time 0 only)")
    if not (b < float("inf")):
        raise NotInFragment("the window is unbounded")
    body = _nnf(tree.arg, False, names, tuple(labels))
    return SafetyFragment(start=float(a), end=float(b), body=body, state_names=names, text=s.canonical(tree))


def _kind(node: object) -> str:
    if isinstance(node, (s.Temporal, s.Until, s.Edge)):
        return f"the operator {node.op!r}"
    return type(node).__name__


def _nnf(node: s.Node, negate: bool, names: tuple[str, ...], labels: tuple[str, ...]) -> Nnf:
    if isinstance(node, s.Not):
        return _nnf(node.arg, not negate, names, labels)
    if isinstance(node, s.Const):
        return Conj(parts=()) if node.value != negate else Disj(parts=())
    if isinstance(node, (s.And, s.Or)):
        parts = (_nnf(node.left, negate, names, labels), _nnf(node.right, negate, names, labels))
        return Conj(parts=parts) if isinstance(node, s.And) != negate else Disj(parts=parts)
    if isinstance(node, s.Implies):  # a -> b  ==  not a or b
        parts = (_nnf(node.left, not negate, names, labels), _nnf(node.right, negate, names, labels))
        return Disj(parts=parts) if not negate else Conj(parts=parts)
    if isinstance(node, s.LabelIs):
        if node.label not in labels:
            raise NotInFragment(f"the label {node.label!r} is not the mode label ({', '.join(labels)})")
        return LabelAtom(label=node.label, pattern=node.pattern, negated=(node.op == "!=") != negate)
    if isinstance(node, s.Compare):
        return _compare(node, negate, names)
    raise NotInFragment(f"{_kind(node)} inside always[a, b] (only and, or, not, implies over state predicates)")


def _abs_split(node: s.Compare) -> s.Node | None:
    """``abs(e) <= r`` as ``e <= r and -e <= r``, ``abs(e) >= r`` as ``e >= r or -e >= r`` (either side)."""
    op, left, right = node.op, node.left, node.right
    if isinstance(right, s.Func) and right.name == "abs" and not (isinstance(left, s.Func) and left.name == "abs"):
        op, left, right = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}[op], right, left
    if not (isinstance(left, s.Func) and left.name == "abs") or op in ("==", "!="):
        return None
    e = left.args[0]
    both = (s.Compare(op=op, left=e, right=right), s.Compare(op=op, left=s.Neg(arg=e), right=right))
    return s.And(left=both[0], right=both[1]) if op in ("<", "<=") else s.Or(left=both[0], right=both[1])


def _compare(node: s.Compare, negate: bool, names: tuple[str, ...]) -> Nnf:
    """``left op right`` as atoms ``c·x <= d`` / ``< d`` (``==`` two atoms, ``!=`` a disjunction)."""
    split = _abs_split(node)
    if split is not None:
        return _nnf(split, negate, names, ())  # comparisons only: no label inside
    text = s.canonical(node)
    left, lc = _affine(node.left, names, text)
    right, rc = _affine(node.right, names, text)
    diff = tuple(p - q for p, q in zip(left, right))  # left - right = diff·x + (lc - rc)
    off = rc - lc  # left op right  <=>  diff·x op off
    neg = tuple(-v for v in diff)
    op = node.op
    if negate:
        op = {"<": ">=", "<=": ">", ">": "<=", ">=": "<", "==": "!=", "!=": "=="}[op]
    shown = f"not ({text})" if negate else text
    le = LinearAtom(coefficients=diff, bound=off, strict=False, text=shown)
    lt = LinearAtom(coefficients=diff, bound=off, strict=True, text=shown)
    ge = LinearAtom(coefficients=neg, bound=-off, strict=False, text=shown)
    gt = LinearAtom(coefficients=neg, bound=-off, strict=True, text=shown)
    return {"<=": le, "<": lt, ">=": ge, ">": gt, "==": Conj(parts=(le, ge)), "!=": Disj(parts=(lt, gt))}[op]


def _affine(e: s.Expr, names: tuple[str, ...], text: str) -> tuple[tuple[Fraction, ...], Fraction]:
    """``e`` as ``(c, k)`` with ``e = c·x + k`` exactly."""
    n = len(names)
    if isinstance(e, s.Num):
        return (Fraction(0),) * n, Fraction(e.value)
    if isinstance(e, s.Var):
        if e.name not in names:
            raise NotInFragment(f"{e.name!r} in {text} is not a state of the system ({', '.join(names)}); "
                                "only states are read by reachability")
        return tuple(Fraction(int(k == names.index(e.name))) for k in range(n)), Fraction(0)
    if isinstance(e, s.Neg):
        c, k = _affine(e.arg, names, text)
        return tuple(-v for v in c), -k
    if isinstance(e, s.BinOp):
        lc, lk = _affine(e.left, names, text)
        rc, rk = _affine(e.right, names, text)
        if e.op in "+-":
            sign = 1 if e.op == "+" else -1
            return tuple(p + sign * q for p, q in zip(lc, rc)), lk + sign * rk
        if e.op == "*" and not any(lc):
            return tuple(lk * q for q in rc), lk * rk
        if e.op == "*" and not any(rc):
            return tuple(rk * p for p in lc), rk * lk
        if e.op == "/" and not any(rc) and rk != 0:
            return tuple(p / rk for p in lc), lk / rk
        raise NotInFragment(f"{text} is not affine in the states (a product or quotient of states: polynomial "
                            "atoms are not decided by reachability in this version)")
    if isinstance(e, s.Func):
        raise NotInFragment(f"{text} uses {e.name}() (abs, min, max and prev atoms are not affine; write the "
                            "two cases as a conjunction or disjunction of affine comparisons)")
    raise NotInFragment(f"{text}: unsupported term {type(e).__name__}")
