"""Signal Temporal Logic: the lexer, the parser, the syntax tree and its static properties.

:func:`parse_tree` turns a formula's text into an immutable syntax tree
(frozen dataclasses, hashable, picklable); :func:`canonical` prints a tree
fully parenthesised, and ``parse_tree(canonical(tree)) == tree``.  The
grammar, with precedence from lowest to highest (``docs/stl.md`` has the EBNF)::

    implies, ->           right associative
    or, |                 left associative
    and, &                left associative
    not, !, always[a,b] (G), eventually[a,b] (F), historically[a,b] (H), once[a,b] (O)
    phi until[a,b] psi (U), phi since[a,b] psi (S)      not associative
    comparisons  e1 < e2, <=, >, >=, ==, !=  (chains: 0 <= x <= 1 is a conjunction)
    label atoms  mode == "AVOID|*", mode != "X"  (wildcards * and ?)
    arithmetic   + -, * /, unary -, abs(e), min(e1, e2), max(e1, e2), prev(e)

Future operators need a bounded interval ``[a, b]`` (or ``[a:b]``) with
``0 <= a <= b`` finite; on past operators the interval is optional and
defaults to the whole past.  Every error is a :class:`FormulaError` with the
line, the column and a caret under the offending place.

Examples
--------
>>> canonical(parse_tree("G[0, 2] x > 1 -> F[0:1] (y <= -x or mode == 'A*')"))
'((always[0, 2] (x > 1)) implies (eventually[0, 1] ((y <= (-x)) or (mode == "A*"))))'
>>> future_horizon(parse_tree("always[0, 2] eventually[1, 3] x > 0"))
5.0
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Collection, Iterator, Mapping
import dataclasses
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple, Union

from analysis.stl.patterns import LabelPattern

__all__ = [
    "BUILTIN_SIGNALS",
    "KEYWORDS",
    "FUTURE_OPERATORS",
    "PAST_OPERATORS",
    "FormulaError",
    "Num",
    "Var",
    "Neg",
    "BinOp",
    "Func",
    "Const",
    "Compare",
    "LabelIs",
    "Not",
    "And",
    "Or",
    "Implies",
    "Temporal",
    "Until",
    "Edge",
    "Expr",
    "Node",
    "parse_tree",
    "canonical",
    "signals_of",
    "labels_of",
    "future_horizon",
    "past_horizon",
    "label_pattern",
]

BUILTIN_SIGNALS = ("time", "jumps")
"""Numeric signals every trace provides (see :mod:`analysis.stl.trace`)."""

KEYWORDS = frozenset({"and", "or", "not", "implies", "true", "false", "always", "eventually", "historically",
                      "once", "until", "since"})
"""Reserved words: never signal names.  The aliases G F H O U S and the function names abs, min, max, prev,
rise, fall are keywords only where an operator fits (G, F, H, O before ``[`` or ``(``; U, S after an operand;
a function name before ``(``), elsewhere they are signal names."""

FUTURE_OPERATORS = {"always": "always", "eventually": "eventually", "G": "always", "F": "eventually"}
PAST_OPERATORS = {"historically": "historically", "once": "once", "H": "historically", "O": "once"}
_BINARY = {"until": "until", "since": "since", "U": "until", "S": "since"}
_FUNCTIONS = {"abs": 1, "prev": 1, "min": 2, "max": 2}
_COMPARISONS = ("<", "<=", ">", ">=", "==", "!=")
_HORIZON_SLACK = 1e-9
"""Relative slack of the ``horizon`` test (sums of decimal bounds are not exact in binary)."""


class FormulaError(ValueError):
    """A formula that does not parse or does not fit its signals, labels or horizon.

    ``str(error)`` is ``"formula error at line L, column C: REASON"`` followed by
    the offending line and a caret under the column.

    Attributes
    ----------
    text : str
        The whole formula text.
    line, column : int
        1-based position of the offending place.
    reason : str
        What is wrong and, where possible, how to fix it.
    """

    def __init__(self, text: str, line: int, column: int, reason: str) -> None:
        self.text = text
        self.line = line
        self.column = column
        self.reason = reason
        super().__init__(self.render())

    @classmethod
    def at(cls, text: str, offset: int, reason: str) -> FormulaError:
        """The error at character ``offset`` (0-based) of ``text``."""
        before = text[:offset]
        line = before.count("\n") + 1
        column = offset - (before.rfind("\n") + 1) + 1
        return cls(text, line, column, reason)

    def render(self) -> str:
        """The multi-line message."""
        lines = self.text.split("\n")
        source = lines[self.line - 1] if 0 < self.line <= len(lines) else ""
        shown = source.rstrip("\r").replace("\t", " ")
        return (f"formula error at line {self.line}, column {self.column}: {self.reason}\n"
                f"  {shown}\n  {' ' * (self.column - 1)}^")

    def __reduce__(self):  # picklable with its fields
        return (type(self), (self.text, self.line, self.column, self.reason))


# --------------------------------------------------------------------------- syntax tree


@dataclass(frozen=True)
class Num:
    """A number literal."""

    value: float


@dataclass(frozen=True)
class Var:
    """A numeric signal, read at the current sample."""

    name: str


@dataclass(frozen=True)
class Neg:
    """Unary minus."""

    arg: Expr


@dataclass(frozen=True)
class BinOp:
    """``left op right`` with ``op`` in ``+ - * /``."""

    op: str
    left: Expr
    right: Expr


@dataclass(frozen=True)
class Func:
    """``abs(e)``, ``min(e1, e2)``, ``max(e1, e2)`` or ``prev(e)``."""

    name: str
    args: tuple[Expr, ...]


@dataclass(frozen=True)
class Const:
    """``true`` or ``false``."""

    value: bool


@dataclass(frozen=True)
class Compare:
    """The atom ``left op right``, ``op`` in ``< <= > >= == !=``."""

    op: str
    left: Expr
    right: Expr


@dataclass(frozen=True)
class LabelIs:
    """The label atom ``label == "pattern"`` (``op == "=="``) or ``label != "pattern"``."""

    label: str
    op: str
    pattern: str


@dataclass(frozen=True)
class Not:
    """Negation."""

    arg: Node


@dataclass(frozen=True)
class And:
    """Conjunction."""

    left: Node
    right: Node


@dataclass(frozen=True)
class Or:
    """Disjunction."""

    left: Node
    right: Node


@dataclass(frozen=True)
class Implies:
    """Implication ``left -> right``."""

    left: Node
    right: Node


@dataclass(frozen=True)
class Temporal:
    """``op[a, b] arg``, ``op`` in always, eventually (future) or historically, once (past).

    ``interval`` is ``(a, b)`` in seconds, or ``None`` (past operators only) for the whole past.
    """

    op: str
    interval: tuple[float, float] | None
    arg: Node


@dataclass(frozen=True)
class Until:
    """``left until[a, b] right`` (future) or ``left since[a, b] right`` (past; ``interval`` may be ``None``)."""

    op: str
    interval: tuple[float, float] | None
    left: Node
    right: Node


@dataclass(frozen=True)
class Edge:
    """``rise(arg)`` or ``fall(arg)``: an edge of a boolean subformula."""

    op: str
    arg: Node


Expr = Union[Num, Var, Neg, BinOp, Func]
Node = Union[Const, Compare, LabelIs, Not, And, Or, Implies, Temporal, Until, Edge]


# --------------------------------------------------------------------------- lexer


class _Token(NamedTuple):
    kind: str  # "num", "ident", "str", "op", "eof"
    text: str
    start: int
    end: int


_TOKEN = re.compile(r"""
    (?P<ws>[ \t\r\n\f\v]+|\#[^\n]*)
  | (?P<num>(?:\d+\.\d*|\.\d+|\d+)(?:[eE][+-]?\d+)?)
  | (?P<ident>[A-Za-z_][A-Za-z0-9_.]*)
  | (?P<str>"[^"\n]*"|'[^'\n]*')
  | (?P<op>->|<=|>=|==|!=|[<>!&|()\[\],:+\-*/])
""", re.VERBOSE)


def _lex(text: str) -> list[_Token]:
    tokens: list[_Token] = []
    pos = 0
    while pos < len(text):
        match = _TOKEN.match(text, pos)
        if match is None:
            char = text[pos]
            if char in "\"'":
                reason = f"unterminated string: the {char} opened here has no closing {char} on its line"
            elif char == "=":
                reason = "'=' is not an operator: write == for equality"
            else:
                reason = f"unexpected character {char!r}"
            raise FormulaError.at(text, pos, reason)
        if match.lastgroup != "ws":
            tokens.append(_Token(match.lastgroup, match.group(), pos, match.end()))
        pos = match.end()
    end = tokens[-1].end if tokens else 0
    tokens.append(_Token("eof", "", end, end))
    return tokens


# --------------------------------------------------------------------------- parser


class _Item(NamedTuple):
    node: object  # a Node, an Expr or the str of a string literal
    kind: str  # "formula", "expr" or "string"
    start: int
    end: int


def _describe(token: _Token) -> str:
    return "the end of the formula" if token.kind == "eof" else repr(token.text)


def _unexpected(token: _Token) -> str:
    return "unexpected end of the formula" if token.kind == "eof" else f"unexpected {token.text!r}"


def _known_list(names: Collection[str]) -> str:
    return ", ".join(sorted(names)) or "(none)"


def _did_you_mean(name: str, known: Collection[str], quote: str = "'") -> str:
    close = difflib.get_close_matches(name, sorted(known), n=1, cutoff=0.5)
    return f" (did you mean {quote}{close[0]}{quote}?)" if close else ""


class _Parser:
    """Recursive descent, one method per precedence level."""

    def __init__(self, text: str, signals: Collection[str] | None, labels: Mapping[str, Collection[str]] | None,
                 horizon: float | None) -> None:
        self.text = text
        self.tokens = _lex(text)
        self.pos = 0
        self.signals = None if signals is None else frozenset(signals) | frozenset(BUILTIN_SIGNALS)
        self.labels = None if labels is None else {str(k): tuple(map(str, v)) for k, v in labels.items()}
        self.horizon = None if horizon is None else float(horizon)
        self.uses: dict[str, str] = {}  # name -> "signal" | "label", to refuse a name used both ways
        self.spans: dict[int, tuple[int, int]] = {}  # id(Var) -> its span, to place errors on names

    # -- tokens

    def peek(self, ahead: int = 0) -> _Token:
        return self.tokens[min(self.pos + ahead, len(self.tokens) - 1)]

    def advance(self) -> _Token:
        token = self.tokens[self.pos]
        self.pos = min(self.pos + 1, len(self.tokens) - 1)
        return token

    def fail(self, offset: int, reason: str) -> FormulaError:
        return FormulaError.at(self.text, offset, reason)

    def expect(self, texts: tuple[str, ...], what: str) -> _Token:
        token = self.peek()
        if token.kind == "op" and token.text in texts:
            return self.advance()
        raise self.fail(token.start, f"expected {what}, found {_describe(token)}")

    def formula(self, item: _Item, role: str) -> object:
        """The node of ``item``, which must be a formula (``role`` says where it stands)."""
        if item.kind == "formula":
            return item.node
        if item.kind == "string":
            raise self.fail(item.start, f"a string stands only in a label atom such as mode == \"NAME\", "
                                        f"not as {role}")
        shown = canonical(item.node)
        raise self.fail(item.start, f"expected a formula as {role}, found the expression {shown}: "
                                    f"compare it, e.g. {shown} > 0")

    def expression(self, item: _Item, role: str) -> object:
        """The node of ``item``, which must be an arithmetic expression."""
        if item.kind == "expr":
            return item.node
        what = "a string" if item.kind == "string" else f"the formula {canonical(item.node)}"
        raise self.fail(item.start, f"expected an arithmetic expression as {role}, found {what}")

    # -- formula levels

    def parse(self) -> object:
        if self.peek().kind == "eof":
            raise self.fail(0, "empty formula: write e.g. always[0, 10] (x > 0)")
        item = self.implies()
        token = self.peek()
        if token.kind != "eof":
            raise self.fail(token.start, f"{_unexpected(token)} after a complete formula "
                                         f"(missing operator, or unbalanced ')'?)")
        if item.kind == "expr":
            raise self.fail(item.end, f"expected a comparison ({', '.join(_COMPARISONS)}) after the expression "
                                      f"{canonical(item.node)}")
        return self.formula(item, "the formula")

    def implies(self) -> _Item:
        left = self.or_()
        if self.peek().text not in ("implies", "->") or self.peek().kind not in ("ident", "op"):
            return left
        self.advance()
        right = self.implies()
        node = Implies(self.formula(left, "the premise of implies"), self.formula(right, "the conclusion of implies"))
        return _Item(node, "formula", left.start, right.end)

    def or_(self) -> _Item:
        return self._left_assoc(self.and_, ("or", "|"), Or, "an operand of or")

    def and_(self) -> _Item:
        return self._left_assoc(self.unary, ("and", "&"), And, "an operand of and")

    def _left_assoc(self, operand, texts: tuple[str, ...], build, role: str) -> _Item:
        left = operand()
        while self.peek().text in texts and self.peek().kind in ("ident", "op"):
            self.advance()
            right = operand()
            left = _Item(build(self.formula(left, role), self.formula(right, role)), "formula", left.start, right.end)
        return left

    def _prefix_operator(self) -> str | None:
        token = self.peek()
        if token.kind != "ident":
            return None
        if token.text in ("always", "eventually", "historically", "once"):
            return token.text
        if token.text in ("G", "F", "H", "O") and self.peek(1).text in ("[", "("):
            return {**FUTURE_OPERATORS, **PAST_OPERATORS}[token.text]
        return None

    def unary(self) -> _Item:
        token = self.peek()
        if token.text in ("not", "!") and token.kind in ("ident", "op"):
            self.advance()
            arg = self.unary()
            return _Item(Not(self.formula(arg, "the operand of not")), "formula", token.start, arg.end)
        op = self._prefix_operator()
        if op is None:
            return self.binary()
        self.advance()
        future = op in ("always", "eventually")
        interval, bracket = self.interval(token.text, required=future)
        arg = self.unary()
        node = Temporal(op, interval, self.formula(arg, f"the operand of {op}"))
        if future:
            self.check_horizon(node, bracket)
        return _Item(node, "formula", token.start, arg.end)

    def _binary_operator(self) -> str | None:
        token = self.peek()
        return _BINARY.get(token.text) if token.kind == "ident" else None

    def binary(self) -> _Item:
        left = self.comparison()
        op = self._binary_operator()
        if op is None:
            return left
        written = self.advance().text
        interval, bracket = self.interval(written, required=op == "until")
        right = self.comparison()
        node = Until(op, interval, self.formula(left, f"the left operand of {op}"),
                     self.formula(right, f"the right operand of {op}"))
        if op == "until":
            self.check_horizon(node, bracket)
        follow = self.peek()
        if self._binary_operator() is not None:
            raise self.fail(follow.start, f"{follow.text!r} after {op}: until and since do not chain; "
                                          f"parenthesise, e.g. (a until[0, 1] b) until[0, 1] c")
        return _Item(node, "formula", left.start, right.end)

    # -- intervals and the horizon

    def interval(self, op: str, *, required: bool) -> tuple[tuple[float, float] | None, int]:
        token = self.peek()
        if token.text != "[" or token.kind != "op":
            if required:
                raise self.fail(token.start, f"{op} needs a bounded interval, e.g. {op}[0, 1.5]: a future "
                                             f"operator must look a finite time ahead")
            return None, token.start
        self.advance()
        lower, lower_at = self.bound(op)
        self.expect((",", ":"), "',' or ':' between the interval bounds")
        upper, _ = self.bound(op)
        self.expect(("]",), "']' closing the interval")
        if lower < 0:
            raise self.fail(lower_at, f"interval [{_number(lower)}, {_number(upper)}] of {op} starts before 0: "
                                      f"expected 0 <= a <= b")
        if upper < lower:
            raise self.fail(token.start, f"reversed interval [{_number(lower)}, {_number(upper)}] of {op}: "
                                         f"expected a <= b; write [{_number(upper)}, {_number(lower)}]")
        return (lower, upper), token.start

    def bound(self, op: str) -> tuple[float, int]:
        token = self.peek()
        sign = 1.0
        if token.text == "-" and token.kind == "op":
            self.advance()
            sign = -1.0
        number = self.peek()
        if number.kind != "num":
            raise self.fail(number.start, f"expected a number as a bound of the interval of {op}, found "
                                          f"{_describe(number)} (bounds are finite numbers of seconds)")
        self.advance()
        value = float(number.text)
        if not math.isfinite(value):
            raise self.fail(number.start, f"interval bound {number.text} is not a finite number")
        return sign * value, token.start

    def check_horizon(self, node: object, at: int) -> None:
        if self.horizon is None:
            return
        extent = future_horizon(node)
        if extent > self.horizon * (1.0 + _HORIZON_SLACK) + _HORIZON_SLACK:
            raise self.fail(at, f"this window makes the formula look {_number(extent)} s ahead, more than the "
                                f"horizon {_number(self.horizon)} s: shorten the interval or extend the horizon")

    # -- atoms

    def comparison(self) -> _Item:
        first = self.additive()
        if not self._at_comparison():
            return first
        operands, ops = [first], []
        while self._at_comparison():
            ops.append(self.advance())
            operands.append(self.additive())
        if any(item.kind == "string" for item in operands):
            return self.label_atom(operands, ops)
        if any(item.kind == "formula" for item in operands):
            bad = next(item for item in operands if item.kind == "formula")
            raise self.fail(bad.start, f"cannot compare the formula {canonical(bad.node)}: comparisons are "
                                       f"between arithmetic expressions")
        atoms = []
        for left, token, right in zip(operands, ops, operands[1:]):
            self.use_signals(left.node)
            self.use_signals(right.node)
            atoms.append(Compare(token.text, left.node, right.node))
        node = atoms[0]
        for atom in atoms[1:]:
            node = And(node, atom)
        return _Item(node, "formula", first.start, operands[-1].end)

    def _at_comparison(self) -> bool:
        token = self.peek()
        return token.kind == "op" and token.text in _COMPARISONS

    def label_atom(self, operands: list[_Item], ops: list[_Token]) -> _Item:
        if len(ops) > 1:
            raise self.fail(ops[1].start, "a label atom does not chain: write mode == \"A\" and ... instead")
        (left, right), (op,) = operands, ops
        string, name = (left, right) if left.kind == "string" else (right, left)
        if name.kind == "string":
            raise self.fail(right.start, "two strings compared: one side of a label atom is a label name")
        if not isinstance(name.node, Var):
            raise self.fail(name.start, "a string is compared with a label name only, e.g. mode == \"AVOID\"")
        if op.text not in ("==", "!="):
            raise self.fail(op.start, f"labels are compared with == or != only, not {op.text}")
        label, pattern = name.node.name, string.node
        self.use(label, "label", name.start)
        if self.labels is not None:
            self.check_pattern(label, pattern, string.start)
        return _Item(LabelIs(label, op.text, pattern), "formula", left.start, right.end)

    def check_pattern(self, label: str, pattern: str, at: int) -> None:
        known = self.labels[label]
        regex = label_pattern(pattern)
        if not any(regex.fullmatch(value) for value in known):
            hint = _did_you_mean(pattern, known, quote='"')
            raise self.fail(at, f"label pattern \"{pattern}\" matches no value of label '{label}'{hint}; "
                                f"known values: {_known_list(known)}")

    def use_signals(self, expr: object) -> None:
        for var in _vars(expr):
            self.use(var.name, "signal", self.spans.get(id(var), (0, 0))[0])

    def use(self, name: str, kind: str, at: int) -> None:
        """Record that ``name`` is read as a ``kind`` ("signal" or "label"); refuse unknown or ambiguous names."""
        before = self.uses.setdefault(name, kind)
        if before != kind:
            raise self.fail(at, f"'{name}' is used both as a numeric signal and as a label")
        signals, labels = self.signals, self.labels
        if kind == "signal" and signals is not None and name not in signals:
            if labels is not None and name in labels:
                raise self.fail(at, f"'{name}' is a label (string-valued): compare it with a string, "
                                    f"e.g. {name} == \"NAME\"")
            raise self.fail(at, f"unknown signal '{name}'{_did_you_mean(name, signals)}; "
                                f"known signals: {_known_list(signals)}")
        if kind == "label" and labels is not None and name not in labels:
            if signals is not None and name in signals:
                raise self.fail(at, f"'{name}' is a numeric signal, not a label: compare it with a number")
            raise self.fail(at, f"unknown label '{name}'{_did_you_mean(name, labels)}; "
                                f"known labels: {_known_list(labels)}")

    # -- arithmetic

    def additive(self) -> _Item:
        return self._arithmetic(self.multiplicative, ("+", "-"))

    def multiplicative(self) -> _Item:
        return self._arithmetic(self.negation, ("*", "/"))

    def _arithmetic(self, operand, texts: tuple[str, ...]) -> _Item:
        left = operand()
        while self.peek().kind == "op" and self.peek().text in texts:
            token = self.advance()
            right = operand()
            role = f"an operand of {token.text}"
            node = BinOp(token.text, self.expression(left, role), self.expression(right, role))
            left = _Item(node, "expr", left.start, right.end)
        return left

    def negation(self) -> _Item:
        token = self.peek()
        if token.kind == "op" and token.text == "-":
            self.advance()
            arg = self.negation()
            return _Item(Neg(self.expression(arg, "the operand of unary -")), "expr", token.start, arg.end)
        return self.primary()

    def primary(self) -> _Item:
        token = self.peek()
        if token.kind == "num":
            self.advance()
            value = float(token.text)
            if not math.isfinite(value):
                raise self.fail(token.start, f"number {token.text} is not finite in double precision")
            return _Item(Num(value), "expr", token.start, token.end)
        if token.kind == "str":
            self.advance()
            return _Item(token.text[1:-1], "string", token.start, token.end)
        if token.kind == "op" and token.text == "(":
            self.advance()
            inner = self.implies()
            close = self.peek()
            if close.text != ")" or close.kind != "op":
                raise self.fail(close.start, f"expected ')' closing the '(' at column "
                                             f"{FormulaError.at(self.text, token.start, '').column}, "
                                             f"found {_describe(close)}")
            self.advance()
            return _Item(inner.node, inner.kind, token.start, close.end)
        if token.kind == "ident":
            return self.name_or_call()
        raise self.fail(token.start, f"{_unexpected(token)}: expected an operand (a number, a signal, "
                                     f"true, false, a function or a parenthesised formula)")

    def name_or_call(self) -> _Item:
        token = self.advance()
        follow = self.peek()
        opens = follow.kind == "op" and follow.text == "("
        word = token.text
        if word in ("true", "false"):
            return _Item(Const(word == "true"), "formula", token.start, token.end)
        prefix = word in ("not", "always", "eventually", "historically", "once") or (
            word in ("G", "F", "H", "O") and follow.kind == "op" and follow.text in ("(", "["))
        if prefix:
            raise self.fail(token.start, f"unexpected '{word}': an operand is expected here; put a prefixed "
                                         f"formula in parentheses, e.g. ({word} ...)")
        if word in KEYWORDS:
            raise self.fail(token.start, f"unexpected '{word}': an operand is expected here")
        if word in ("rise", "fall") and opens:
            self.advance()
            arg = self.implies()
            close = self.expect((")",), f"')' closing {word}(")
            return _Item(Edge(word, self.formula(arg, f"the operand of {word}")), "formula", token.start, close.end)
        if word in _FUNCTIONS and opens:
            return self.call(token)
        var = Var(word)
        self.spans[id(var)] = (token.start, token.end)
        return _Item(var, "expr", token.start, token.end)

    def call(self, name: _Token) -> _Item:
        self.advance()
        args = [self.expression(self.implies(), f"an argument of {name.text}()")]
        while self.peek().text == "," and self.peek().kind == "op":
            self.advance()
            args.append(self.expression(self.implies(), f"an argument of {name.text}()"))
        close = self.expect((")",), f"')' closing {name.text}(")
        wanted = _FUNCTIONS[name.text]
        if len(args) != wanted:
            raise self.fail(name.start, f"{name.text}() takes {wanted} argument{'s' * (wanted > 1)}, "
                                        f"{len(args)} given")
        return _Item(Func(name.text, tuple(args)), "expr", name.start, close.end)


def parse_tree(text: str, *, signals: Collection[str] | None = None,
               labels: Mapping[str, Collection[str]] | None = None, horizon: float | None = None) -> Node:
    """Parse ``text`` into a syntax tree.

    Parameters
    ----------
    text : str
        The formula; ``#`` starts a comment to the end of the line, newlines are spaces.
    signals : collection of str, optional
        Known numeric signals (``time`` and ``jumps`` are always known); an
        unknown one is refused.
    labels : mapping of str to collection of str, optional
        Known labels and their possible values; an unknown label, or a pattern
        matching none of the label's values, is refused.
    horizon : float, optional
        Largest future extent [s] (:func:`future_horizon`) accepted.

    Returns
    -------
    Node

    Raises
    ------
    FormulaError
        With the position and the reason.
    """
    if not isinstance(text, str):
        raise FormulaError(str(text), 1, 1, f"a formula is a str, not {type(text).__name__}")
    if horizon is not None and not (isinstance(horizon, int | float) and math.isfinite(horizon) and horizon >= 0):
        raise FormulaError(text, 1, 1, f"horizon = {horizon!r}: expected a finite number of seconds >= 0")
    try:
        tree = _Parser(text, signals, labels, horizon).parse()
    except RecursionError:
        tree = None
    if tree is None or _depth(tree) > MAX_DEPTH:
        raise FormulaError(text, 1, 1, f"the formula nests too deeply (at most {MAX_DEPTH} levels of operators and "
                                       "parentheses): split it into "
                                       "several requirements, or drop redundant parentheses")
    return tree


MAX_DEPTH = 200
"""Deepest syntax tree accepted: evaluation and printing recurse over the tree."""


def _depth(tree: object) -> int:
    """Depth of a syntax tree, computed without recursion (any depth)."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if dataclasses.is_dataclass(node):
            for f in dataclasses.fields(node):
                value = getattr(node, f.name)
                for child in (value if isinstance(value, tuple) else (value,)):
                    if dataclasses.is_dataclass(child):
                        stack.append((child, depth + 1))
    return deepest


# --------------------------------------------------------------------------- printing and static properties


def _number(value: float) -> str:
    """Shortest text that reads back as ``value`` (integers without a decimal point)."""
    if value.is_integer() and abs(value) < 1e16:
        return str(int(value))
    return repr(value)


def _interval(interval: tuple[float, float] | None) -> str:
    return "" if interval is None else f"[{_number(interval[0])}, {_number(interval[1])}]"


def _quote(pattern: str) -> str:
    return f"'{pattern}'" if '"' in pattern else f'"{pattern}"'


def canonical(node: object) -> str:
    """Fully parenthesised text of a tree or an expression; it parses back to an equal tree."""
    match node:
        case Num(value):
            return _number(value)
        case Var(name):
            return name
        case Neg(arg):
            return f"(-{canonical(arg)})"
        case BinOp(op, left, right) | Compare(op, left, right):
            return f"({canonical(left)} {op} {canonical(right)})"
        case Func(name, args):
            return f"{name}({', '.join(canonical(a) for a in args)})"
        case Const(value):
            return "true" if value else "false"
        case LabelIs(label, op, pattern):
            return f"({label} {op} {_quote(pattern)})"
        case Not(arg):
            return f"(not {canonical(arg)})"
        case And(left, right) | Or(left, right) | Implies(left, right):
            word = {And: "and", Or: "or", Implies: "implies"}[type(node)]
            return f"({canonical(left)} {word} {canonical(right)})"
        case Temporal(op, interval, arg):
            return f"({op}{_interval(interval)} {canonical(arg)})"
        case Until(op, interval, left, right):
            return f"({canonical(left)} {op}{_interval(interval)} {canonical(right)})"
        case Edge(op, arg):
            return f"{op}({canonical(arg)})"
    raise TypeError(f"not a formula or expression node: {node!r}")


def _children(node: object) -> tuple[object, ...]:
    match node:
        case Neg(arg) | Not(arg) | Temporal(_, _, arg) | Edge(_, arg):
            return (arg,)
        case BinOp(_, left, right) | Compare(_, left, right) | Until(_, _, left, right):
            return (left, right)
        case And(left, right) | Or(left, right) | Implies(left, right):
            return (left, right)
        case Func(_, args):
            return args
    return ()


def _walk(node: object) -> Iterator[object]:
    yield node
    for child in _children(node):
        yield from _walk(child)


def _vars(expr: object) -> Iterator[Var]:
    return (n for n in _walk(expr) if isinstance(n, Var))


def signals_of(node: object) -> frozenset[str]:
    """Numeric signals a tree reads."""
    return frozenset(n.name for n in _walk(node) if isinstance(n, Var))


def labels_of(node: object) -> frozenset[str]:
    """Labels a tree reads."""
    return frozenset(n.label for n in _walk(node) if isinstance(n, LabelIs))


def future_horizon(node: object) -> float:
    """How far ahead [s] the value at a sample looks: nested upper bounds of future operators, summed.

    0 for atoms; ``b + h(arg)`` for ``always``/``eventually``; ``b + max(h(left), h(right))`` for
    ``until``; past operators, ``rise``/``fall`` and the boolean connectives pass their operands' maximum on.
    """
    inner = max((future_horizon(c) for c in _children(node) if not _is_expr(c)), default=0.0)
    if isinstance(node, Temporal | Until) and node.op in ("always", "eventually", "until"):
        return node.interval[1] + inner
    return inner


def past_horizon(node: object) -> float:
    """How far back [s] the value at a sample looks through past operators (``inf`` for an untimed one).

    ``prev``, ``rise`` and ``fall`` look one *sample* back, which is no fixed time: they add nothing here.
    """
    inner = max((past_horizon(c) for c in _children(node) if not _is_expr(c)), default=0.0)
    if isinstance(node, Temporal | Until) and node.op in ("historically", "once", "since"):
        return math.inf if node.interval is None else node.interval[1] + inner
    return inner


def _is_expr(node: object) -> bool:
    return isinstance(node, Num | Var | Neg | BinOp | Func)


@lru_cache(maxsize=256)
def label_pattern(pattern: str) -> LabelPattern:
    """The compiled pattern of a label atom (:class:`~analysis.stl.patterns.LabelPattern`: ``*`` is any string,
    ``?`` any one character, the rest literal; ``.fullmatch(value)`` in linear time, no backtracking)."""
    return LabelPattern(pattern)
