"""SpaceEx input, first layer: a safe XML reader and the expression language, without ``eval``.

The XML is read by :mod:`xml.parsers.expat` directly: a document type
declaration (``<!DOCTYPE``), and with it every entity declaration, is refused
before anything is expanded (no "billion laughs", no external entity), the
file size and the number of elements are bounded, and every element keeps its
line for the error messages.

Expressions (flows, invariants, guards, assignments, the ``.cfg`` sets) are
parsed by a small recursive-descent parser into a tuple tree:

* arithmetic: ``("num", value)``, ``("name", name)``, ``("neg", e)``,
  ``(op, a, b)`` for ``op`` in ``+ - * / ^``, ``("call", f, (args...))`` with
  ``f`` in :data:`FUNCTIONS`;
* constraints: ``("cmp", op, a, b)`` (``op`` in ``<= < >= > ==``; a chain
  ``a <= b <= c`` is two of them), ``("and", (c...))``, ``("or", (c...))``,
  ``("true",)``, ``("false",)``, ``("loc", component, location)``;
* flows ``x' == e``: ``("cmp", "==", ("deriv", "x"), e)``; assignments
  ``x := e`` (or ``x = e``): ``("assign", "x", e)``.

Everything else (an unknown function, ``x' <= e``, a stray token) is a
:class:`SpaceExError` naming the text, the position and what is supported.
"""

from __future__ import annotations

import re
import xml.parsers.expat
from dataclasses import dataclass, field
from typing import Any

from .errors import ParameterError

__all__ = [
    "SpaceExError",
    "XmlElement",
    "read_xml",
    "parse_expression",
    "parse_constraints",
    "MAX_FILE_BYTES",
    "MAX_ELEMENTS",
    "MAX_DEPTH",
    "MAX_TERMS",
    "FUNCTIONS",
]

MAX_FILE_BYTES = 64 * 1024 * 1024
"""Largest SpaceEx XML or configuration read [bytes] (the ARCH building model is 57 kB)."""

MAX_ELEMENTS = 2_000_000
"""Largest number of XML elements read: beyond it the file is refused before it is interpreted."""

MAX_DEPTH = 100
"""Deepest nesting of parentheses or operators in one expression (bounded recursion)."""

MAX_CONJUNCTS = 100_000
"""Most constraints of one conjunction (flat: no recursion, a bound on work only)."""

MAX_TERMS = 250
"""Most terms of one sum or factors of one product (the tree of a sum is as deep as it is long)."""

FUNCTIONS = ("sin", "cos", "exp", "sqrt", "log")
"""Functions of the SpaceEx expression language that the import maps onto :mod:`hybrid.symbolic`."""


class SpaceExError(ParameterError):
    """A SpaceEx model or configuration that cannot be imported (or a model that cannot be exported).

    The parameter names the file, the line and the element; the message says what is supported.
    """


@dataclass(frozen=True, kw_only=True, slots=True)
class XmlElement:
    """One XML element: tag, attributes, text (concatenated), children and line (1-based)."""

    tag: str
    attrs: dict[str, str]
    line: int
    children: list[XmlElement] = field(default_factory=list)
    text_parts: list[str] = field(default_factory=list)

    @property
    def text(self) -> str:
        """The element's own character data."""
        return "".join(self.text_parts)


def read_xml(data: bytes, source: str) -> XmlElement:
    """The root element of a SpaceEx XML document, read without DTDs or entities.

    Parameters
    ----------
    data : bytes
        The document.
    source : str
        Its name for the messages (a path).

    Raises
    ------
    SpaceExError
        Too large, not well-formed (with the line and column), a DOCTYPE or an entity declaration.
    """
    if len(data) > MAX_FILE_BYTES:
        raise SpaceExError(source, f"{len(data)} bytes", f"a SpaceEx file of at most {MAX_FILE_BYTES} bytes",
                           "split the model or check that this is the right file")
    parser = xml.parsers.expat.ParserCreate()
    stack: list[XmlElement] = []
    root: list[XmlElement] = []
    count = [0]

    def refuse(what: str) -> None:
        raise SpaceExError(f"{source}:{parser.CurrentLineNumber}", what,
                           "a SpaceEx XML document without a DOCTYPE, entity declarations or external entities",
                           "remove the <!DOCTYPE ...> and <!ENTITY ...> declarations (SpaceEx files have none)")

    def start(tag: str, attrs: dict[str, str]) -> None:
        count[0] += 1
        if count[0] > MAX_ELEMENTS:
            raise SpaceExError(source, f"more than {MAX_ELEMENTS} elements", f"at most {MAX_ELEMENTS} XML elements",
                               "reduce the model")
        node = XmlElement(tag=tag, attrs=dict(attrs), line=parser.CurrentLineNumber)
        (stack[-1].children if stack else root).append(node)
        stack.append(node)

    def end(tag: str) -> None:
        stack.pop()

    def chars(text: str) -> None:
        if stack:
            stack[-1].text_parts.append(text)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    parser.StartDoctypeDeclHandler = lambda *a: refuse("<!DOCTYPE ...>")
    parser.EntityDeclHandler = lambda *a: refuse(f"<!ENTITY {a[0]} ...>")
    parser.ExternalEntityRefHandler = lambda *a: refuse("an external entity reference")
    parser.SetParamEntityParsing(xml.parsers.expat.XML_PARAM_ENTITY_PARSING_NEVER)
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as error:
        raise SpaceExError(f"{source}:{error.lineno}:{error.offset}", xml.parsers.expat.errors.messages[error.code],
                           "a well-formed XML document", "repair the file (is it truncated?)") from None
    if not root:
        raise SpaceExError(source, "no root element", "a <sspaceex> document", "give a SpaceEx XML file")
    return root[0]


# ---------------------------------------------------------------------- tokens
_TOKEN = re.compile(r"""
    (?P<ws>\s+)
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<name>[A-Za-z_][A-Za-z0-9_.]*'?)
  | (?P<op>:=|<=|>=|==|&&|\|\||[-+*/^()<>=&|,])
""", re.VERBOSE)


@dataclass(frozen=True, slots=True)
class _Token:
    kind: str
    text: str
    pos: int


def _tokens(text: str, where: str) -> list[_Token]:
    out: list[_Token] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise SpaceExError(where, text, f"a SpaceEx expression; character {text[pos]!r} at offset {pos} is not "
                               "part of the language (numbers, names, x', + - * / ^, < <= > >= ==, & |, :=, "
                               f"( ), functions {', '.join(FUNCTIONS)})", "rewrite the expression")
        kind = m.lastgroup or ""
        if kind != "ws":
            tok = m.group()
            if kind == "op" and tok in ("&&", "||"):
                tok = tok[0]
            out.append(_Token(kind, tok, pos))
        pos = m.end()
    out.append(_Token("end", "", len(text)))
    return out


class _Parser:
    def __init__(self, text: str, where: str) -> None:
        self.text = text
        self.where = where
        self.toks = _tokens(text, where)
        self.i = 0
        self.depth = 0

    # helpers
    def peek(self) -> _Token:
        return self.toks[self.i]

    def take(self) -> _Token:
        tok = self.toks[self.i]
        self.i += 1
        return tok

    def error(self, what: str, tok: _Token | None = None) -> SpaceExError:
        tok = tok or self.peek()
        found = f"{tok.text!r} at offset {tok.pos}" if tok.kind != "end" else "the end of the text"
        return SpaceExError(self.where, self.text.strip(), f"{what} (found {found})", "rewrite the expression "
                            "in SpaceEx syntax (docs/spaceex.md lists what is supported)")

    def expect(self, text: str) -> None:
        if self.peek().text != text or self.peek().kind == "end":
            raise self.error(f"{text!r}")
        self.take()

    def nest(self) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.error(f"an expression nested at most {MAX_DEPTH} deep")

    # constraints
    def formula(self) -> Any:
        self.nest()
        parts = [self.conjunction()]
        while self.peek().text == "|":
            self.take()
            parts.append(self.conjunction())
        self.depth -= 1
        return parts[0] if len(parts) == 1 else ("or", tuple(parts))

    def conjunction(self) -> Any:
        parts = [self.atom()]
        while self.peek().text == "&":
            self.take()
            parts.append(self.atom())
            if len(parts) > MAX_CONJUNCTS:
                raise self.error(f"a conjunction of at most {MAX_CONJUNCTS} constraints")
        flat: list[Any] = []
        for p in parts:
            flat.extend(p[1] if p[0] == "and" else (p,))
        return flat[0] if len(flat) == 1 else ("and", tuple(flat))

    def atom(self) -> Any:
        tok = self.peek()
        if tok.kind == "name" and tok.text in ("true", "false"):
            self.take()
            return (tok.text,)
        if tok.kind == "name" and tok.text == "loc" and self.toks[self.i + 1].text == "(":
            return self.location()
        if tok.kind == "name" and self.toks[self.i + 1].text in (":=", "="):
            self.take()
            self.take()
            if tok.text.endswith("'"):
                raise self.error("an assignment to a variable (x := e), not to a derivative", tok)
            return ("assign", tok.text, self.expr())
        if tok.text == "(" and self.holds_constraint():  # "(" opens a constraint, or an expression
            start = self.i
            try:
                self.take()
                inner = self.formula()
                self.expect(")")
                if self.peek().text in ("&", "|", ")") or self.peek().kind == "end":
                    return inner
            except SpaceExError:
                pass
            self.i = start
        return self.comparison()

    def holds_constraint(self) -> bool:
        """Whether the parenthesis at the cursor encloses a comparison or a connective (no blind backtracking)."""
        level = 0
        for tok in self.toks[self.i:]:
            if tok.text == "(":
                level += 1
            elif tok.text == ")":
                level -= 1
                if level == 0:
                    return False
            elif tok.text in ("<=", "<", ">=", ">", "==", "&", "|", ":=", "=") or tok.text in ("true", "false", "loc"):
                return True
        return False

    def location(self) -> Any:
        self.take()
        self.expect("(")
        comp = None
        if self.peek().kind == "name":
            comp = self.take().text
        self.expect(")")
        self.expect("==")
        tok = self.take()
        if tok.kind not in ("name", "num"):
            raise self.error("a location name after loc(...) ==", tok)
        return ("loc", comp, tok.text)

    def comparison(self) -> Any:
        left = self.expr()
        ops = ("<=", "<", ">=", ">", "==")
        if self.peek().text not in ops:
            raise self.error("a comparison (<, <=, >, >=, ==) or an assignment (:=)")
        parts = []
        while self.peek().text in ops:
            op = self.take().text
            right = self.expr()
            if left[0] == "deriv" and op != "==":
                raise self.error(f"a flow x' == expression (SpaceEx's differential inclusion {op} is not supported)")
            parts.append(("cmp", op, left, right))
            left = right
        return parts[0] if len(parts) == 1 else ("and", tuple(parts))

    # arithmetic
    def expr(self) -> Any:
        self.nest()
        node = self.term()
        count = 1
        while self.peek().text in ("+", "-"):
            op = self.take().text
            node = (op, node, self.term())
            count += 1
            if count > MAX_TERMS:
                raise self.error(f"a sum of at most {MAX_TERMS} terms")
        self.depth -= 1
        return node

    def term(self) -> Any:
        node = self.unary()
        count = 1
        while self.peek().text in ("*", "/"):
            op = self.take().text
            node = (op, node, self.unary())
            count += 1
            if count > MAX_TERMS:
                raise self.error(f"a product of at most {MAX_TERMS} factors")
        return node

    def unary(self) -> Any:
        if self.peek().text in ("-", "+"):
            op = self.take().text
            self.nest()
            inner = self.unary()
            self.depth -= 1
            return ("neg", inner) if op == "-" else inner
        return self.power()

    def power(self) -> Any:
        base = self.primary()
        if self.peek().text == "^":
            self.take()
            self.nest()
            exponent = self.unary()
            self.depth -= 1
            return ("^", base, exponent)
        return base

    def primary(self) -> Any:
        tok = self.take()
        if tok.kind == "num":
            value = float(tok.text)
            if value == float("inf"):
                raise self.error("a number within double precision", tok)
            return ("num", value)
        if tok.kind == "name" and self.peek().text == "(":
            if tok.text not in FUNCTIONS:
                raise self.error(f"a function among {', '.join(FUNCTIONS)}", tok)
            self.take()
            args = [self.expr()]
            while self.peek().text == ",":
                self.take()
                args.append(self.expr())
            self.expect(")")
            if len(args) != 1:
                raise self.error(f"one argument to {tok.text}()", tok)
            return ("call", tok.text, tuple(args))
        if tok.kind == "name":
            if tok.text in ("true", "false", "loc"):
                raise self.error("an arithmetic operand", tok)
            if tok.text.endswith("'"):
                return ("deriv", tok.text[:-1])
            return ("name", tok.text)
        if tok.text == "(":
            node = self.expr()
            self.expect(")")
            return node
        raise self.error("a number, a name, a function call or '('", tok)


def parse_constraints(text: str, where: str) -> Any:
    """The constraint tree of ``text`` (a flow, invariant, guard, assignment or ``.cfg`` set).

    An empty text is ``("true",)``.

    Raises
    ------
    SpaceExError
        Naming ``where`` (file, line, element), the text, the offending token and what is supported.
    """
    if not text.strip():
        return ("true",)
    p = _Parser(text, where)
    node = p.formula()
    if p.peek().kind != "end":
        raise p.error("the end of the constraint, '&' or '|'")
    return node


def parse_expression(text: str, where: str) -> Any:
    """The arithmetic tree of ``text`` (a bind map value, say).

    Raises
    ------
    SpaceExError
        As :func:`parse_constraints`.
    """
    p = _Parser(text, where)
    node = p.expr()
    if p.peek().kind != "end":
        raise p.error("the end of the expression")
    return node
