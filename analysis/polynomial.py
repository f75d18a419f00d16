"""Exact polynomial normal form of CasADi SX expressions in variables, sines and cosines.

A CasADi expression built from ``+ - *``, division by constants, non-negative
integer powers and ``sin``/``cos`` of the variables is a polynomial with
real coefficients in the *atoms* ``x``, ``sin(x)``, ``cos(x)`` of its
variables ``x``.  :func:`normal_form` walks the instructions of the
``casadi.Function`` of the expression and expands it into such a
:class:`Polynomial` with exact :class:`fractions.Fraction` coefficients:
every float constant of the expression is taken at its exact binary value
(``Fraction(0.1) = 3602879701896397 / 2**55``), and all further arithmetic is
exact.  Cancellations that plain interval arithmetic cannot see (the
*dependency problem*) therefore happen exactly: the normal form of
``(k d)(v s) - s v (k d + a + 2 k s)`` has no ``d`` term.

What is and is not simplified
-----------------------------
:func:`normal_form` collects like monomials exactly (it is a canonical form
of the polynomial in the atoms viewed as independent indeterminates) and
maps ``sin(-x) = -sin(x)``, ``cos(-x) = cos(x)``.  It does *not* use
``sin(x)**2 + cos(x)**2 = 1``; :meth:`Polynomial.reduce_pythagorean`
applies it (replacing ``cos(x)**2`` by ``1 - sin(x)**2``), which yields a
form that is zero iff the function is identically zero.  Trigonometric
functions of anything but ``±x`` (``sin(2 x)``, ``sin(x + y)``) are not
expanded: they raise :class:`UnsupportedExpression`.

The form is exact *for the float constants present in the expression*.  If
CasADi has already folded constants (``k * v`` rounded into one float in one
place but kept as ``k`` and ``v`` in another) terms that cancel in real
arithmetic may leave a residue of the order of one ulp, and the normal form
shows it.

Examples
--------
>>> import casadi as ca
>>> d, a = ca.SX.sym("delta"), ca.SX.sym("alpha")
>>> p = normal_form((4 * d) * (0.5 * ca.sin(a)) - ca.sin(a) * 0.5 * (4 * d + a), [d, a])
>>> str(p)
'-0.5*alpha*sin(alpha)'
>>> p.depends_on("delta")
False
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from types import MappingProxyType
from typing import NamedTuple

import casadi

__all__ = [
    "ATOM_KINDS",
    "MAX_EXPONENT",
    "PolynomialError",
    "UnsupportedExpression",
    "InvalidVariables",
    "Atom",
    "Monomial",
    "atom_sort_key",
    "Polynomial",
    "normal_form",
]

ATOM_KINDS = ("var", "sin", "cos")
"""Kinds of atoms: the variable itself, its sine, its cosine."""
MAX_EXPONENT = 256
"""Largest integer exponent :func:`normal_form` expands."""


# --------------------------------------------------------------------------- errors


class PolynomialError(ValueError):
    """Base class of the errors of :mod:`analysis.polynomial`."""


class UnsupportedExpression(PolynomialError):
    """The expression uses an operation outside polynomials in ``x``, ``sin(x)``, ``cos(x)``.

    Attributes
    ----------
    operation : str
        Name of the offending operation (e.g. ``"sqrt"``, ``"sin"``).
    """

    def __init__(self, message: str, *, operation: str) -> None:
        super().__init__(message)
        self.operation = operation


class InvalidVariables(PolynomialError):
    """Variables that are not distinct scalar SX symbols, or an expression with free symbols."""


# --------------------------------------------------------------------------- atoms and monomials


class Atom(NamedTuple):
    """An indeterminate of a :class:`Polynomial`: ``x``, ``sin(x)`` or ``cos(x)``.

    A named tuple (hence ordered and hashable, and equal to the plain tuple
    ``(kind, variable)``, e.g. ``("sin", "alpha")``).

    Attributes
    ----------
    kind : str
        One of :data:`ATOM_KINDS`.
    variable : str
        Name of the variable.
    """

    kind: str
    variable: str

    @classmethod
    def var(cls, name: str) -> Atom:
        """The atom ``name`` itself."""
        return cls("var", name)

    @classmethod
    def sin(cls, name: str) -> Atom:
        """The atom ``sin(name)``."""
        return cls("sin", name)

    @classmethod
    def cos(cls, name: str) -> Atom:
        """The atom ``cos(name)``."""
        return cls("cos", name)

    def __str__(self) -> str:
        return self.variable if self.kind == "var" else f"{self.kind}({self.variable})"


Monomial = tuple[tuple[Atom, int], ...]
"""A product of atom powers ``((atom, power), ...)``, powers >= 1, ``()`` is 1.

Sorted by :func:`atom_sort_key` (by variable name, then ``x``, ``sin(x)``, ``cos(x)``).
"""


def atom_sort_key(atom: Atom) -> tuple[str, int]:
    """Order of atoms inside a monomial: by variable name, then ``var < sin < cos``."""
    return atom.variable, ATOM_KINDS.index(atom.kind)


def _sorted_monomial(powers: Mapping[Atom, int]) -> Monomial:
    return tuple(sorted(powers.items(), key=lambda item: atom_sort_key(item[0])))


def _as_atom(atom: Atom | tuple[str, str] | str, *, name: str = "atom") -> Atom:
    if isinstance(atom, str):
        return Atom.var(atom)
    if isinstance(atom, tuple) and len(atom) == 2 and atom[0] in ATOM_KINDS and isinstance(atom[1], str):
        return Atom(*atom)
    raise TypeError(
        f"{name} = {atom!r}: expected an Atom such as Atom.sin('alpha') / ('sin', 'alpha'), "
        f"or a variable name"
    )


def _mono_mul(m1: Monomial, m2: Monomial) -> Monomial:
    if not m1:
        return m2
    if not m2:
        return m1
    powers = dict(m1)
    for atom, power in m2:
        powers[atom] = powers.get(atom, 0) + power
    return _sorted_monomial(powers)


def _format_coefficient(c: Fraction) -> str:
    f = float(c)
    if Fraction(f) == c:
        return repr(f).removesuffix(".0") if f.is_integer() and abs(f) < 2**53 else repr(f)
    return f"({c})"


# --------------------------------------------------------------------------- the polynomial


@dataclass(frozen=True, slots=True)
class Polynomial:
    """A polynomial with exact rational coefficients in :class:`Atom` indeterminates.

    Parameters
    ----------
    terms : Mapping[Monomial, Fraction]
        Coefficient of each monomial; zero coefficients are dropped, ``int``
        and ``float`` coefficients are converted exactly.  Stored read-only.

    Examples
    --------
    >>> s = Polynomial.atom(Atom.sin("alpha"))
    >>> a = Polynomial.atom("alpha")
    >>> p = -a * s - 2 * s**2
    >>> str(p)
    '-alpha*sin(alpha) - 2*sin(alpha)^2'
    >>> p.degree_in(Atom.sin("alpha")), p.depends_on("delta")
    (2, False)
    >>> p.evaluate({Atom.var("alpha"): 0.0, Atom.sin("alpha"): 0.0})
    0.0
    """

    terms: Mapping[Monomial, Fraction]

    def __post_init__(self) -> None:
        clean: dict[Monomial, Fraction] = {}
        for monomial, coefficient in dict(self.terms).items():
            key = self._check_monomial(monomial)
            if isinstance(coefficient, bool) or not isinstance(coefficient, (int, float, Fraction)):
                raise TypeError(
                    f"coefficient of {monomial!r} = {coefficient!r}: expected a Fraction, int or float"
                )
            if isinstance(coefficient, float) and not math.isfinite(coefficient):
                raise PolynomialError(
                    f"coefficient of {monomial!r} = {coefficient!r}: expected a finite number"
                )
            value = Fraction(coefficient)
            if value:
                clean[key] = clean.get(key, Fraction(0)) + value
        object.__setattr__(self, "terms", MappingProxyType({m: c for m, c in clean.items() if c}))

    @staticmethod
    def _check_monomial(monomial: object) -> Monomial:
        if not isinstance(monomial, tuple):
            raise TypeError(f"monomial {monomial!r}: expected a tuple of (atom, power) pairs")
        powers: dict[Atom, int] = {}
        for item in monomial:
            if not (isinstance(item, tuple) and len(item) == 2):
                raise TypeError(f"monomial {monomial!r}: item {item!r} is not an (atom, power) pair")
            atom, power = _as_atom(item[0], name="atom"), item[1]
            if isinstance(power, bool) or not isinstance(power, int) or power < 1:
                raise PolynomialError(
                    f"monomial {monomial!r}: power of {atom} = {power!r}; expected an integer >= 1"
                )
            powers[atom] = powers.get(atom, 0) + power
        return _sorted_monomial(powers)

    def __hash__(self) -> int:
        return hash(frozenset(self.terms.items()))

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Polynomial):
            return dict(self.terms) == dict(other.terms)
        return NotImplemented

    # ---- construction

    @classmethod
    def constant(cls, value: Fraction | int | float) -> Polynomial:
        """The constant polynomial ``value`` (a float is taken exactly)."""
        return cls({(): value})

    @classmethod
    def atom(cls, atom: Atom | tuple[str, str] | str) -> Polynomial:
        """The polynomial consisting of one atom (a string names the variable atom)."""
        return cls({((_as_atom(atom), 1),): 1})

    # ---- queries

    @property
    def atoms(self) -> tuple[Atom, ...]:
        """Sorted atoms that occur with a nonzero coefficient."""
        return tuple(sorted({atom for monomial in self.terms for atom, _ in monomial}, key=atom_sort_key))

    @property
    def variables(self) -> tuple[str, ...]:
        """Sorted names of the variables the polynomial depends on (through any atom)."""
        return tuple(sorted({atom.variable for atom in self.atoms}))

    @property
    def is_zero(self) -> bool:
        """True for the zero polynomial."""
        return not self.terms

    @property
    def constant_term(self) -> Fraction:
        """Coefficient of the empty monomial."""
        return self.terms.get((), Fraction(0))

    def degree_in(self, atom: Atom | tuple[str, str] | str) -> int:
        """Largest power of ``atom`` in a monomial (0 if absent; a string names the variable atom)."""
        atom = _as_atom(atom)
        return max((dict(m).get(atom, 0) for m in self.terms), default=0)

    def coefficient_of(self, atom: Atom | tuple[str, str] | str, power: int) -> Polynomial:
        """The polynomial ``c`` in the other atoms with ``self = sum_p c_p * atom**p``, for ``p = power``.

        Examples
        --------
        >>> a, s = Polynomial.atom("alpha"), Polynomial.atom(Atom.sin("alpha"))
        >>> str((3 * a * s + s + 2).coefficient_of(Atom.sin("alpha"), 1))
        '3*alpha + 1'
        """
        atom = _as_atom(atom)
        if isinstance(power, bool) or not isinstance(power, int) or power < 0:
            raise PolynomialError(f"power = {power!r}: expected an integer >= 0")
        out: dict[Monomial, Fraction] = {}
        for monomial, c in self.terms.items():
            powers = dict(monomial)
            if powers.get(atom, 0) == power:
                powers.pop(atom, None)
                out[_sorted_monomial(powers)] = c
        return Polynomial(out)

    def depends_on(self, what: Atom | tuple[str, str] | str) -> bool:
        """Whether an atom occurs; a string means the variable through *any* of its atoms."""
        if isinstance(what, str):
            return what in self.variables
        return _as_atom(what) in self.atoms

    def evaluate(self, values: Mapping[Atom, float]) -> float:
        """Value for given atom values (floats give a float, Fractions an exact Fraction).

        Parameters
        ----------
        values : Mapping[Atom, float]
            A value for every atom in :attr:`atoms` (keys may be plain tuples).

        Raises
        ------
        KeyError
            Naming the missing atom.
        """
        total: float | Fraction = 0
        for monomial, c in self.terms.items():
            term: float | Fraction = c
            for atom, power in monomial:
                try:
                    x = values[atom]
                except KeyError:
                    raise KeyError(
                        f"no value for atom {atom} = {tuple(atom)!r}; pass every atom of {self.atoms}"
                    ) from None
                term = term * x**power
            total = total + term
        return total if isinstance(total, Fraction) else float(total)

    def evaluate_at(self, point: Mapping[str, float]) -> float:
        """Float value at a point given by variable values (sin/cos computed with :mod:`math`)."""
        values: dict[Atom, float] = {}
        for name in self.variables:
            if name not in point:
                raise KeyError(f"no value for variable {name!r}; pass all of {self.variables}")
            x = float(point[name])
            values.update({Atom.var(name): x, Atom.sin(name): math.sin(x), Atom.cos(name): math.cos(x)})
        return float(self.evaluate(values))

    def reduce_pythagorean(self) -> Polynomial:
        """Replace ``cos(x)**2`` by ``1 - sin(x)**2`` until every cosine power is 0 or 1.

        The result is the canonical representative modulo ``sin² + cos² = 1``:
        two such polynomials define the same function iff they are equal.

        Examples
        --------
        >>> s, c = Polynomial.atom(Atom.sin("a")), Polynomial.atom(Atom.cos("a"))
        >>> (s**2 + c**2).reduce_pythagorean() == Polynomial.constant(1)
        True
        """
        result = Polynomial({})
        for monomial, c in self.terms.items():
            factor = Polynomial.constant(c)
            for atom, power in monomial:
                if atom.kind == "cos" and power >= 2:
                    one_minus_s2 = 1 - Polynomial.atom(Atom.sin(atom.variable)) ** 2
                    factor = factor * one_minus_s2 ** (power // 2)
                    if power % 2:
                        factor = factor * Polynomial.atom(atom)
                else:
                    factor = factor * Polynomial({((atom, power),): 1})
            result = result + factor
        return result

    # ---- arithmetic

    def __neg__(self) -> Polynomial:
        return Polynomial({m: -c for m, c in self.terms.items()})

    def __add__(self, other: object) -> Polynomial:
        other = _as_polynomial(other)
        if other is NotImplemented:
            return NotImplemented
        out = dict(self.terms)
        for m, c in other.terms.items():
            out[m] = out.get(m, Fraction(0)) + c
        return Polynomial(out)

    __radd__ = __add__

    def __sub__(self, other: object) -> Polynomial:
        other = _as_polynomial(other)
        if other is NotImplemented:
            return NotImplemented
        return self + (-other)

    def __rsub__(self, other: object) -> Polynomial:
        other = _as_polynomial(other)
        if other is NotImplemented:
            return NotImplemented
        return other + (-self)

    def __mul__(self, other: object) -> Polynomial:
        other = _as_polynomial(other)
        if other is NotImplemented:
            return NotImplemented
        out: dict[Monomial, Fraction] = {}
        for m1, c1 in self.terms.items():
            for m2, c2 in other.terms.items():
                m = _mono_mul(m1, m2)
                out[m] = out.get(m, Fraction(0)) + c1 * c2
        return Polynomial(out)

    __rmul__ = __mul__

    def __pow__(self, n: int) -> Polynomial:
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise PolynomialError(f"exponent n = {n!r}: expected an integer >= 0")
        result, base = Polynomial.constant(1), self
        while n:
            if n & 1:
                result = result * base
            n >>= 1
            if n:
                base = base * base
        return result

    def __str__(self) -> str:
        if not self.terms:
            return "0"
        order = sorted(
            self.terms, key=lambda m: (-sum(p for _, p in m), [(atom_sort_key(a), -p) for a, p in m])
        )
        parts: list[str] = []
        for monomial in order:
            c = self.terms[monomial]
            factors = "*".join(str(a) if p == 1 else f"{a}^{p}" for a, p in monomial)
            sign = "-" if c < 0 else "+"
            magnitude = abs(c)
            if not factors:
                body = _format_coefficient(magnitude)
            elif magnitude == 1:
                body = factors
            else:
                body = f"{_format_coefficient(magnitude)}*{factors}"
            parts.append(f"{sign} {body}")
        text = " ".join(parts)
        return text[2:] if text.startswith("+ ") else "-" + text[2:]


def _as_polynomial(value: object) -> Polynomial:
    if isinstance(value, Polynomial):
        return value
    if isinstance(value, (int, float, Fraction)) and not isinstance(value, bool):
        return Polynomial.constant(value)
    return NotImplemented  # type: ignore[return-value]


# --------------------------------------------------------------------------- CasADi -> polynomial

_OP_NAMES = {
    getattr(casadi, name): name[3:].lower() for name in dir(casadi) if name.startswith("OP_")
}
_SUPPORTED = (
    "constants, inputs, +, -, * (also sq, twice, neg), division by a nonzero constant, "
    "integer powers >= 0 with a constant exponent, sin(±x) and cos(±x) of a variable x"
)


def _unsupported(operation: str, index: int, detail: str) -> UnsupportedExpression:
    return UnsupportedExpression(
        f"normal_form: operation {operation!r} (instruction {index}) is not supported: {detail}; "
        f"supported are {_SUPPORTED}; rewrite the expression in these terms",
        operation=operation,
    )


def _check_variables(variables: Sequence[casadi.SX]) -> tuple[list[casadi.SX], list[str]]:
    if isinstance(variables, casadi.SX):
        variables = [variables[i] for i in range(variables.numel())]
    variables = list(variables)
    names: list[str] = []
    for i, v in enumerate(variables):
        if not isinstance(v, casadi.SX) or not v.is_scalar() or not v.is_symbolic():
            raise InvalidVariables(
                f"variables[{i}] = {v!r}: expected a scalar casadi.SX symbol such as ca.SX.sym('x')"
            )
        name = v.name()
        if name in names:
            raise InvalidVariables(
                f"variables[{i}] is named {name!r} like an earlier variable; give every variable a distinct name"
            )
        names.append(name)
    return variables, names


def _constant_value(poly: Polynomial) -> Fraction | None:
    if not poly.terms:
        return Fraction(0)
    if set(poly.terms) == {()}:
        return poly.terms[()]
    return None


def _trig_of(poly: Polynomial, kind: str, index: int) -> Polynomial:
    value = _constant_value(poly)
    if value == 0:
        return Polynomial.constant(0 if kind == "sin" else 1)
    if len(poly.terms) == 1:
        (monomial, c), = poly.terms.items()
        if len(monomial) == 1 and monomial[0][1] == 1 and monomial[0][0].kind == "var" and abs(c) == 1:
            atom = Atom(kind, monomial[0][0].variable)
            result = Polynomial.atom(atom)
            return -result if (c < 0 and kind == "sin") else result
    raise _unsupported(kind, index, f"{kind} of {poly} (only {kind}(x) or {kind}(-x) of a variable x)")


def normal_form(expr: casadi.SX, variables: Sequence[casadi.SX]) -> Polynomial:
    """Exact polynomial normal form of a scalar SX expression in the atoms of ``variables``.

    Parameters
    ----------
    expr : casadi.SX, shape (1, 1)
        The expression; every parameter must already be a number in it.
    variables : sequence of casadi.SX
        Distinct scalar symbols; every symbol of ``expr`` must be among them.

    Returns
    -------
    Polynomial
        Exact expansion, atoms named by the symbols' names.

    Raises
    ------
    UnsupportedExpression
        For an operation outside the supported set (its name in ``operation``).
    InvalidVariables
        For variables that are not distinct scalar symbols, or free symbols in ``expr``.
    PolynomialError
        For a non-scalar or non-SX ``expr`` or a non-finite constant.

    Examples
    --------
    >>> import casadi as ca
    >>> x = ca.SX.sym("x")
    >>> str(normal_form((x + 1) ** 2 - ca.cos(-x), [x]))
    'x^2 + 2*x - cos(x) + 1'
    """
    if isinstance(expr, (int, float)) and not isinstance(expr, bool):
        expr = casadi.SX(expr)
    if not isinstance(expr, casadi.SX):
        raise PolynomialError(
            f"expr is a {type(expr).__name__}: expected a casadi.SX expression (build it with SX symbols)"
        )
    if expr.shape != (1, 1):
        raise PolynomialError(f"expr has shape {expr.shape}: expected a scalar (1, 1) expression")
    symbols, names = _check_variables(variables)
    free = [s.name() for s in casadi.symvar(expr) if not any(casadi.is_equal(s, v) for v in symbols)]
    if free:
        raise InvalidVariables(
            f"expr contains the symbols {free} that are not in variables {names}; substitute numbers "
            f"for parameters (ca.substitute) or add them to variables"
        )
    function = casadi.Function("normal_form", symbols, [expr])
    work: dict[int, Polynomial] = {}
    result = Polynomial({})
    for k in range(function.n_instructions()):
        op = function.instruction_id(k)
        inputs = function.instruction_input(k)
        outputs = function.instruction_output(k)
        name = _OP_NAMES.get(op, str(op))
        if op == casadi.OP_OUTPUT:
            result = work[inputs[0]]
            continue
        if op == casadi.OP_CONST:
            value = function.instruction_constant(k)
            if not math.isfinite(value):
                raise PolynomialError(f"normal_form: constant {value!r} (instruction {k}) is not finite")
            out = Polynomial.constant(value)
        elif op == casadi.OP_INPUT:
            out = Polynomial.atom(names[inputs[0]])
        elif op == casadi.OP_ADD:
            out = work[inputs[0]] + work[inputs[1]]
        elif op == casadi.OP_SUB:
            out = work[inputs[0]] - work[inputs[1]]
        elif op == casadi.OP_MUL:
            out = work[inputs[0]] * work[inputs[1]]
        elif op == casadi.OP_NEG:
            out = -work[inputs[0]]
        elif op == casadi.OP_SQ:
            out = work[inputs[0]] * work[inputs[0]]
        elif op == casadi.OP_TWICE:
            out = 2 * work[inputs[0]]
        elif op == casadi.OP_ASSIGN:
            out = work[inputs[0]]
        elif op in (casadi.OP_DIV, casadi.OP_INV):
            numerator = work[inputs[0]] if op == casadi.OP_DIV else Polynomial.constant(1)
            divisor = work[inputs[1] if op == casadi.OP_DIV else inputs[0]]
            value = _constant_value(divisor)
            if value is None or value == 0:
                raise _unsupported(name, k, f"division by {divisor} (only by a nonzero constant)")
            out = numerator * Polynomial.constant(1 / value)
        elif op in (casadi.OP_POW, casadi.OP_CONSTPOW):
            exponent = _constant_value(work[inputs[1]])
            if exponent is None or exponent.denominator != 1 or not 0 <= exponent <= MAX_EXPONENT:
                raise _unsupported(
                    name, k, f"exponent {work[inputs[1]]} (only a constant integer in 0..{MAX_EXPONENT})"
                )
            out = work[inputs[0]] ** int(exponent)
        elif op == casadi.OP_SIN:
            out = _trig_of(work[inputs[0]], "sin", k)
        elif op == casadi.OP_COS:
            out = _trig_of(work[inputs[0]], "cos", k)
        else:
            raise _unsupported(name, k, "not a polynomial or sin/cos operation")
        work[outputs[0]] = out
    return result
