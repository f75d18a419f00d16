"""The polynomials of :mod:`analysis.sos`: :class:`SosPoly` (exact-exponent polynomials with float or cvxpy
coefficients), their monomial bases and the name and exponent checks.

:mod:`analysis.sos` re-exports the public names.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import cvxpy as cp
import numpy as np
import scipy.sparse as sparse

from hybrid.errors import ParameterError

# Helpers shared with analysis.sos have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = ["Exponent", "SosError", "SosPoly", "monomial_basis"]


Exponent = tuple[int, ...]
"""Exponents of a monomial, one per variable of the polynomial, in its variable order."""


class SosError(ParameterError):
    """A bad input to :mod:`analysis.sos` (degree, variable names, coefficients, box)."""


def _is_numeric(c: Any) -> bool:
    return isinstance(c, np.ndarray)


def _apply(matrix: sparse.spmatrix, c: Any) -> Any:
    """``matrix @ c`` for a numeric array or a cvxpy vector expression."""
    if _is_numeric(c):
        return np.asarray(matrix @ c, dtype=float).reshape(-1)
    return cp.Constant(matrix) @ c


def _selection(target: Sequence[Exponent], source: Sequence[Exponent]) -> sparse.csr_matrix:
    index = {m: i for i, m in enumerate(target)}
    rows = [index[m] for m in source]
    return sparse.csr_matrix((np.ones(len(source)), (rows, list(range(len(source))))),
                             shape=(len(target), len(source)))


def is_real_number(x: object) -> bool:
    """Whether ``x`` is a real number (int, float, Fraction, numpy scalar; not a bool)."""
    return isinstance(x, (int, float, Fraction, np.floating, np.integer)) and not isinstance(x, bool)


@dataclass(frozen=True, slots=True)
class SosPoly:
    """A polynomial over named variables whose coefficients are numbers or cvxpy expressions.

    Parameters
    ----------
    variables : tuple of str
        Variable names; every exponent tuple has one entry per name.
    monomials : tuple of Exponent
        Distinct exponent tuples, ``n`` of them, each of length ``len(variables)``.
    coefficients : numpy.ndarray or cvxpy.Expression, shape (n,)
        Coefficient of each monomial: a float array (a *numeric* polynomial) or an
        affine cvxpy expression in the decision variables of a :class:`SosProgram`.

    Notes
    -----
    Arithmetic is by sparse matrices acting on the coefficient vector, so a
    polynomial with hundreds of unknown coefficients costs a handful of cvxpy
    operations.  A product is defined when at least one factor is numeric
    (the product of two unknown polynomials is not affine).
    """

    variables: tuple[str, ...]
    monomials: tuple[Exponent, ...]
    coefficients: Any

    # ---- construction

    @classmethod
    def from_terms(cls, variables: Sequence[str], terms: Mapping[Exponent, Any]) -> SosPoly:
        """From ``{exponent tuple: coefficient}``: numbers give a numeric polynomial, else cvxpy scalars.

        Raises
        ------
        SosError
            Exponents of the wrong length or negative, NaN/inf coefficients.
        """
        variables = checked_names(variables)
        monomials = tuple(check_exponent(m, len(variables)) for m in terms) or ((0,) * len(variables),)
        values = list(terms.values()) or [0.0]
        if all(is_real_number(v) for v in values):
            coefficients = np.array([float(v) for v in values], dtype=float)
            if not np.all(np.isfinite(coefficients)):
                bad = [m for m, v in zip(monomials, coefficients) if not math.isfinite(v)]
                raise SosError("coefficients", bad, "finite numbers", "remove NaN/inf coefficients")
            return _collect(cls(variables, monomials, coefficients))
        exprs = [v if isinstance(v, cp.Expression) else cp.Constant(float(v)) for v in values]
        return _collect(cls(variables, monomials, cp.hstack([cp.reshape(e, (1,), order="F") for e in exprs])))

    @classmethod
    def constant(cls, value: float, variables: Sequence[str]) -> SosPoly:
        """The constant polynomial ``value``."""
        variables = checked_names(variables)
        return cls.from_terms(variables, {(0,) * len(variables): value})

    @classmethod
    def variable(cls, name: str, variables: Sequence[str]) -> SosPoly:
        """The polynomial ``name`` (one of ``variables``)."""
        variables = checked_names(variables)
        if name not in variables:
            raise SosError("name", name, f"one of the variables {list(variables)}", "use a declared variable name")
        return cls.from_terms(variables, {tuple(int(v == name) for v in variables): 1.0})

    # ---- queries

    @property
    def is_numeric(self) -> bool:
        """True when every coefficient is a number."""
        return _is_numeric(self.coefficients)

    @property
    def degree(self) -> int:
        """Total degree (0 for the zero polynomial)."""
        if self.is_numeric:
            return max((sum(m) for m, c in zip(self.monomials, self.coefficients) if c != 0.0), default=0)
        return max((sum(m) for m in self.monomials), default=0)

    def degree_in(self, name: str) -> int:
        """Largest exponent of ``name``."""
        i = self._index_of(name)
        if self.is_numeric:
            return max((m[i] for m, c in zip(self.monomials, self.coefficients) if c != 0.0), default=0)
        return max((m[i] for m in self.monomials), default=0)

    def terms(self) -> dict[Exponent, Any]:
        """``{exponent: coefficient}`` (nonzero floats, or cvxpy scalar expressions)."""
        if self.is_numeric:
            return {m: float(c) for m, c in zip(self.monomials, self.coefficients) if c != 0.0}
        return {m: self.coefficients[i] for i, m in enumerate(self.monomials)}

    def value(self) -> SosPoly:
        """The numeric polynomial of the solved decision variables (``expression.value``)."""
        if self.is_numeric:
            return self
        values = self.coefficients.value
        if values is None:
            raise SosError("polynomial", "unsolved", "a polynomial of a solved program", "solve the program first")
        return _collect(SosPoly(self.variables, self.monomials, np.asarray(values, dtype=float).reshape(-1)))

    def evaluate(self, point: Mapping[str, float]) -> Any:
        """Value at a point: a float, or a cvxpy scalar affine in the unknown coefficients."""
        missing = [v for v in self.variables if v not in point]
        if missing:
            raise SosError("point", dict(point), f"a value for each of {list(self.variables)}",
                           f"add values for {missing}")
        row = np.array([math.prod(float(point[v]) ** e for v, e in zip(self.variables, m)) for m in self.monomials])
        if self.is_numeric:
            return float(row @ self.coefficients)
        return row @ self.coefficients

    def _index_of(self, name: str) -> int:
        if name not in self.variables:
            raise SosError("variable", name, f"one of {list(self.variables)}", "use a variable of the polynomial")
        return self.variables.index(name)

    # ---- arithmetic

    def _same_space(self, other: SosPoly) -> None:
        if other.variables != self.variables:
            raise SosError("variables", other.variables, f"the same variables {self.variables}",
                           "build every polynomial of one program over one variable tuple")

    def _lift(self, other: object) -> SosPoly:
        if isinstance(other, SosPoly):
            return other
        if is_real_number(other):
            return SosPoly.constant(float(other), self.variables)  # type: ignore[arg-type]
        return NotImplemented  # type: ignore[return-value]

    def __add__(self, other: object) -> SosPoly:
        other = self._lift(other)
        if other is NotImplemented:
            return NotImplemented
        self._same_space(other)
        monomials = tuple(dict.fromkeys(self.monomials + other.monomials))
        a, b = _selection(monomials, self.monomials), _selection(monomials, other.monomials)
        return SosPoly(self.variables, monomials, _apply(a, self.coefficients) + _apply(b, other.coefficients))

    __radd__ = __add__

    def __neg__(self) -> SosPoly:
        return SosPoly(self.variables, self.monomials, -self.coefficients)

    def __sub__(self, other: object) -> SosPoly:
        other = self._lift(other)
        if other is NotImplemented:
            return NotImplemented
        return self + (-other)

    def __rsub__(self, other: object) -> SosPoly:
        return (-self) + other

    def __mul__(self, other: object) -> SosPoly:
        if is_real_number(other):
            if not math.isfinite(float(other)):  # type: ignore[arg-type]
                raise SosError("factor", other, "a finite number", "remove NaN/inf")
            return SosPoly(self.variables, self.monomials, self.coefficients * float(other))  # type: ignore[arg-type]
        if not isinstance(other, SosPoly):
            return NotImplemented
        self._same_space(other)
        if self.is_numeric and not other.is_numeric:
            return _product(other, self)
        if not other.is_numeric:
            raise SosError("factor", "a polynomial with unknown coefficients",
                           "at least one numeric factor (a product of unknowns is not affine)",
                           "fix one factor, or use a multiplier from SosProgram")
        return _product(self, other)

    __rmul__ = __mul__

    def __pow__(self, n: int) -> SosPoly:
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise SosError("exponent", n, "an integer >= 0", "use a nonnegative integer power")
        if not self.is_numeric and n > 1:
            raise SosError("exponent", n, "0 or 1 for a polynomial with unknown coefficients",
                           "raise only numeric polynomials to powers")
        result = SosPoly.constant(1.0, self.variables)
        for _ in range(n):
            result = result * self
        return result

    def derivative(self, name: str) -> SosPoly:
        """``∂/∂name``."""
        i = self._index_of(name)
        keep = [(k, m) for k, m in enumerate(self.monomials) if m[i] > 0]
        if not keep:
            return SosPoly.constant(0.0, self.variables)
        monomials = tuple(m[:i] + (m[i] - 1,) + m[i + 1:] for _, m in keep)
        matrix = sparse.csr_matrix(([float(m[i]) for _, m in keep], (list(range(len(keep))), [k for k, _ in keep])),
                                   shape=(len(keep), len(self.monomials)))
        return SosPoly(self.variables, monomials, _apply(matrix, self.coefficients))

    def lie_derivative(self, rates: Mapping[str, SosPoly]) -> SosPoly:
        """``Σ_x ∂self/∂x · rates[x]`` over the variables ``self`` may depend on (``rates`` numeric)."""
        total = SosPoly.constant(0.0, self.variables)
        for name in self.variables:
            if all(m[self.variables.index(name)] == 0 for m in self.monomials):
                continue
            if name not in rates:
                raise SosError("rates", sorted(rates), f"a rate for the variable {name!r}",
                               f"add rates[{name!r}] (every variable V depends on needs a rate)")
            total = total + rates[name] * self.derivative(name)
        return total


def _collect(p: SosPoly) -> SosPoly:
    """Merge repeated monomials (keeps the order of first occurrence)."""
    unique = tuple(dict.fromkeys(p.monomials))
    if len(unique) == len(p.monomials):
        return p
    return SosPoly(p.variables, unique, _apply(_selection(unique, p.monomials), p.coefficients))


def _product(a: SosPoly, b: SosPoly) -> SosPoly:
    """``a * b`` with ``b`` numeric."""
    out: dict[Exponent, int] = {}
    rows, cols, vals = [], [], []
    for j, mb in enumerate(b.monomials):
        cb = float(b.coefficients[j])
        if cb == 0.0:
            continue
        for i, ma in enumerate(a.monomials):
            m = tuple(x + y for x, y in zip(ma, mb))
            rows.append(out.setdefault(m, len(out)))
            cols.append(i)
            vals.append(cb)
    if not out:
        return SosPoly.constant(0.0, a.variables)
    matrix = sparse.csr_matrix((vals, (rows, cols)), shape=(len(out), len(a.monomials)))
    return SosPoly(a.variables, tuple(out), _apply(matrix, a.coefficients))


def checked_names(variables: Sequence[str]) -> tuple[str, ...]:
    """``variables`` as a tuple of distinct non-empty names (a single string is one name), or :class:`SosError`."""
    names = (variables,) if isinstance(variables, str) else tuple(variables)
    if not names or not all(isinstance(n, str) and n for n in names) or len(set(names)) != len(names):
        raise SosError("variables", variables, "a non-empty sequence of distinct non-empty names",
                       "name every variable once, e.g. ('x', 'y')")
    return names


def check_exponent(m: object, n: int) -> Exponent:
    """``m`` as an exponent of ``n`` variables (a tuple of ``n`` ints >= 0), or :class:`SosError`."""
    if not (isinstance(m, tuple) and len(m) == n
            and all(isinstance(e, int) and not isinstance(e, bool) and e >= 0 for e in m)):
        raise SosError("exponent", m, f"a tuple of {n} integers >= 0", "give one exponent per variable")
    return m


def monomial_basis(variables: Sequence[str], degree: int, *, min_degree: int = 0,
                   only: Sequence[str] | None = None, max_exponents: Mapping[str, int] | None = None
                   ) -> tuple[Exponent, ...]:
    """Exponent tuples of total degree in ``[min_degree, degree]``.

    Parameters
    ----------
    variables : sequence of str
        The variables of the polynomial space.
    degree, min_degree : int
    only : sequence of str, optional
        Variables allowed to appear (the others get exponent 0).
    max_exponents : Mapping[str, int], optional
        Per-variable caps (e.g. ``{"c": 1}`` after reducing ``c² = 1 − s²``).

    Returns
    -------
    tuple of Exponent
        Sorted by total degree, then lexicographically (higher powers of earlier variables first).
    """
    variables = checked_names(variables)
    if isinstance(degree, bool) or not isinstance(degree, int) or degree < 0:
        raise SosError("degree", degree, "an integer >= 0", "give a nonnegative degree")
    allowed = set(variables if only is None else only)
    unknown = sorted(allowed - set(variables)) + sorted(set(max_exponents or {}) - set(variables))
    if unknown:
        raise SosError("only", unknown, f"names among {list(variables)}", "use declared variable names")
    caps = [0 if v not in allowed else min(degree, (max_exponents or {}).get(v, degree)) for v in variables]
    out = [m for m in itertools.product(*(range(c + 1) for c in caps)) if min_degree <= sum(m) <= degree]
    return tuple(sorted(out, key=lambda m: (sum(m), tuple(-e for e in m))))
