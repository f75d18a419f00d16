"""Sum-of-squares programming with cvxpy: Lyapunov functions and invariant regions of polynomial fields.

A polynomial ``p`` of degree ``2d`` is a *sum of squares* (SOS) iff there is a
positive semidefinite Gram matrix ``Q`` with ``p = zᵀ Q z``, where ``z`` is the
vector of monomials of degree ``<= d`` (Parrilo's Gram-matrix method).
Matching the coefficients of both sides monomial by monomial gives linear
equations in the entries of ``Q`` and in the unknown coefficients of ``p``;
with ``Q ⪰ 0`` this is a semidefinite program (SDP).  An SOS polynomial is
nonnegative everywhere; the converse fails in general, which is why a search
of too low a degree can fail although a certificate exists at a higher one.

Nonnegativity on a semialgebraic set ``K = {g_i >= 0, h_j = 0}`` is certified
in Putinar's form (the S-procedure, generalised)::

    p = σ_0 + Σ_i σ_i g_i + Σ_j λ_j h_j,     σ_i SOS,  λ_j free polynomials,

because on ``K`` every term but ``σ_0`` is nonnegative or zero.  Equality
multipliers handle polynomialised trigonometry: with ``s = sin α``,
``c = cos α`` and ``h = s² + c² − 1`` the identity holds only on the circle.

Lyapunov functions (Papachristodoulou & Prajna): for a polynomial field
``ẋ = f(x)`` with ``f(0) = 0`` (shift the variables so that the equilibrium
is the origin), find ``V`` with ``V(0) = 0`` such that ``V − φ`` and
``−V̇ − ε φ`` are nonnegative on ``K`` (``φ`` positive definite, by default
``Σ x_i²``; the scale of ``V`` is free, so ``V >= φ`` fixes it without loss),
:func:`sos_lyapunov`; ``V̇ = ∇V · f`` is linear in the unknown coefficients
of ``V``, so this is one SDP.  Every polynomial certified nonnegative
vanishes at the origin, so the constant monomial is left out of the Gram
bases there (see :meth:`SosProgram.add_nonnegative`): without it the SDP has
no strictly feasible point and interior-point solvers stall.

Invariant regions, three formulations:

* :func:`invariant_region` (volume heuristic): minimise ``∫_box V`` subject to
  ``V ≥ b_i`` on ``K`` for *boundary functions* ``b_i`` that exceed 1 on the
  box's faces, and ``−V̇ ≥ ε φ`` on ``K``; then ``{V <= 1}`` lies inside the box
  and is as large as the integral objective makes it.  Linear in ``V``.
* :func:`region_of_attraction` (the formulation of Drake's
  ``RegionOfAttraction`` for a fixed ``V``): maximise ``ρ`` such that
  ``(xᵀx)^d (V − ρ) + λ(x) V̇`` is SOS with ``λ`` free.  Wherever ``V̇ = 0`` and
  ``x ≠ 0`` this forces ``V ≥ ρ``, so ``V̇`` keeps its sign (negative near the
  origin) on ``{V < ρ} \\ {0}``.  Linear in ``(ρ, λ)``.
* :func:`bounding_region` (an invariant set through given points, thinnest in
  given targets): maximise ``γ`` with ``V <= 1`` at the points and
  ``V >= γ t_j``, so that ``t_j <= 1/γ`` on ``{V <= 1}``; it bounds the
  solutions from those points once ``{V <= 1}`` is proven invariant.

The numbers an SDP solver returns are floating point and satisfy the
constraints only up to its tolerances, so nothing here is a proof.  Every
result carries its ``V`` with coefficients rounded to dyadic rationals
(:class:`fractions.Fraction`, exactly representable as floats) as an exact
:class:`analysis.polynomial.Polynomial`; :mod:`analysis.sublevel` then
re-certifies the claim about the *rounded* ``V`` by interval branch and
bound, on the true functions (``sin``/``cos``, not their polynomialisation).
That re-check is the proof; the SDP is only a search.

Failures are statuses, never solver tracebacks: an infeasible SDP means no
certificate of the requested degree exists for the constraints as posed
(status ``"infeasible"``, message "degree too low to certify ..." with the
next degree to try); a solver that fails (``cvxpy.error.SolverError``) gives
``"solver_error"``.

Examples
--------
>>> x, y = SosPoly.variable("x", ("x", "y")), SosPoly.variable("y", ("x", "y"))
>>> sos_lyapunov({"x": -x + y * y, "y": -y}, degree=2).status
'infeasible'
>>> sos_lyapunov({"x": -x + y * y, "y": -y}, degree=4).found
True
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import cvxpy as cp
import numpy as np
import scipy.sparse as sparse

from analysis.interval import box_bounds
from analysis.polynomial import Atom, Polynomial
from analysis.sos_poly import Exponent, SosError, SosPoly, check_exponent, checked_names, is_real_number, monomial_basis

__all__ = [
    "DEFAULT_SOLVERS",
    "ROUNDING_BITS",
    "SOLVE_STATUSES",
    "Exponent",
    "SosError",
    "SosPoly",
    "SemialgebraicSet",
    "monomial_basis",
    "SosProgram",
    "SolveOutcome",
    "round_polynomial",
    "to_polynomial",
    "from_polynomial",
    "LyapunovSos",
    "RegionSos",
    "RoaSos",
    "sos_lyapunov",
    "invariant_region",
    "region_of_attraction",
    "BoundingSos",
    "bounding_region",
    "box_moments",
]

DEFAULT_SOLVERS = ("CLARABEL", "SCS")
"""Solvers tried in order until one gives a conclusive status."""
ROUNDING_BITS = 30
"""Coefficients are rounded to multiples of ``2**(e − ROUNDING_BITS)``, ``2**e`` above the largest magnitude."""
SOLVE_STATUSES = ("solved", "inaccurate", "infeasible", "unbounded", "solver_error")
"""Statuses of :class:`SolveOutcome`."""


# --------------------------------------------------------------------------- polynomials


@dataclass(frozen=True, kw_only=True, slots=True)
class SemialgebraicSet:
    """``{x : g_i(x) >= 0, h_j(x) = 0}`` with numeric polynomials.

    Attributes
    ----------
    inequalities : tuple of SosPoly
        The ``g_i`` (numeric).
    equalities : tuple of SosPoly
        The ``h_j`` (numeric).
    """

    inequalities: tuple[SosPoly, ...] = ()
    equalities: tuple[SosPoly, ...] = ()

    def __post_init__(self) -> None:
        for name, polys in (("inequalities", self.inequalities), ("equalities", self.equalities)):
            for p in polys:
                if not isinstance(p, SosPoly) or not p.is_numeric:
                    raise SosError(name, p, "numeric SosPoly", "build the set from numeric polynomials")


# --------------------------------------------------------------------------- programs


@dataclass(frozen=True, kw_only=True, slots=True)
class SolveOutcome:
    """How an SDP ended.

    Attributes
    ----------
    status : str
        One of :data:`SOLVE_STATUSES`.
    solver_status : str
        cvxpy's status text (or the error for ``"solver_error"``).
    solver : str
        The solver that produced the outcome.
    objective : float or None
    """

    status: str
    solver_status: str
    solver: str
    objective: float | None

    @property
    def ok(self) -> bool:
        """A (possibly inaccurate) solution is available."""
        return self.status in ("solved", "inaccurate")


class SosProgram:
    """Builder of one SOS program over fixed variables (a mutable builder, not a result).

    Parameters
    ----------
    variables : sequence of str
        The indeterminates of every polynomial of the program.

    Attributes
    ----------
    constraints : list of cvxpy constraints
        Append further cvxpy constraints directly if needed.
    gram_sizes : list of int
        Size of each Gram matrix (for reporting the SDP's size).
    gram_caps : Mapping[str, int]
        Per-variable exponent caps of every Gram basis the program builds, e.g. ``{"c": 1}``
        when ``s² + c² = 1`` is an equality of the domain: modulo it ``c² ≡ 1 − s²``, so a
        square of a polynomial equals a square of one of ``c``-degree <= 1 (no loss of generality
        once the equality multiplier has the degree to absorb the difference).
    """

    def __init__(self, variables: Sequence[str], *, gram_caps: Mapping[str, int] | None = None) -> None:
        self.variables = checked_names(variables)
        caps = dict(gram_caps or {})
        bad = {k: x for k, x in caps.items() if k not in self.variables or not isinstance(x, int) or x < 0}
        if bad:
            raise SosError("gram_caps", bad, f"integer caps >= 0 for variables among {list(self.variables)}",
                           "e.g. {'c': 1} when s**2 + c**2 = 1 is an equality of the domain")
        self.gram_caps = caps
        self.constraints: list[Any] = []
        self.gram_sizes: list[int] = []
        self.grams: list[Any] = []

    def free_polynomial(self, basis: Sequence[Exponent]) -> SosPoly:
        """A polynomial with unknown coefficients on ``basis``."""
        basis = tuple(check_exponent(m, len(self.variables)) for m in basis)
        if not basis:
            raise SosError("basis", basis, "at least one monomial", "give a non-empty basis")
        return SosPoly(self.variables, basis, cp.Variable(len(basis)))

    def sos_polynomial(self, half_basis: Sequence[Exponent]) -> SosPoly:
        """``zᵀ Q z`` with a new ``Q ⪰ 0`` over the monomials ``z = half_basis``."""
        z = tuple(check_exponent(m, len(self.variables)) for m in half_basis)
        n = len(z)
        if n == 0:
            raise SosError("half_basis", z, "at least one monomial", "give a non-empty basis")
        gram = cp.Variable((n, n), symmetric=True)
        self.constraints.append(gram >> 0)
        self.gram_sizes.append(n)
        self.grams.append(gram)
        index: dict[Exponent, int] = {}
        rows, cols = [], []
        for j in range(n):
            for i in range(n):
                m = tuple(a + b for a, b in zip(z[i], z[j]))
                rows.append(index.setdefault(m, len(index)))
                cols.append(i + n * j)
        matrix = sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(index), n * n))
        return SosPoly(self.variables, tuple(index), cp.Constant(matrix) @ cp.vec(gram, order="F"))

    def trace_sum(self) -> Any:
        """``Σ trace(Q)`` over the Gram matrices so far (a regulariser: it bounds the multipliers)."""
        return sum((cp.trace(g) for g in self.grams), cp.Constant(0.0))

    def add_equal(self, p: SosPoly, q: SosPoly | float = 0.0) -> None:
        """Coefficient-wise ``p = q``."""
        diff = p - q
        if diff.is_numeric:
            if np.max(np.abs(diff.coefficients), initial=0.0) > 0.0:
                raise SosError("equality", "numeric polynomials that differ", "equal polynomials",
                               "an equality between numeric polynomials must hold exactly")
            return
        self.constraints.append(diff.coefficients == 0)

    def add_sos(self, p: SosPoly, *, half_basis: Sequence[Exponent] | None = None) -> SosPoly:
        """Constrain ``p`` to be SOS; returns the Gram polynomial ``zᵀ Q z``."""
        if half_basis is None:
            caps = {v: min(p.degree_in(v) // 2, self.gram_caps.get(v, p.degree)) for v in p.variables}
            half_basis = monomial_basis(p.variables, _even_up(p.degree) // 2, max_exponents=caps)
        gram = self.sos_polynomial(half_basis)
        self.add_equal(p, gram)
        return gram

    def add_nonnegative(self, p: SosPoly, *, on: SemialgebraicSet | None = None, degree: int | None = None,
                        half_basis: Sequence[Exponent] | None = None, zero_at_origin: bool = False) -> None:
        """Certify ``p >= 0`` on ``on`` in Putinar's form (module docstring), at total degree ``degree``.

        Parameters
        ----------
        p : SosPoly
        on : SemialgebraicSet, optional
            ``None``: globally (``p`` SOS).
        degree : int, optional
            Even degree of the certificate; default: the smallest even number
            ``>=`` the degrees of ``p`` and of the constraints.
        half_basis : sequence of Exponent, optional
            Monomials of ``σ_0`` (default: all of degree ``<= degree/2``, capped by :attr:`gram_caps`).
        zero_at_origin : bool
            ``p(0) = 0`` is imposed elsewhere.  Then ``σ_0(0) = 0`` and ``σ_i(0) = 0`` wherever
            ``g_i(0) > 0``, so their Gram matrices have a zero first row: the constant monomial is
            left out of those bases, without loss of generality, which keeps the SDP strictly
            feasible (interior-point solvers fail without it).
        """
        on = on or SemialgebraicSet()
        d = degree if degree is not None else _even_up(max([p.degree] + [g.degree for g in on.inequalities]
                                                           + [h.degree for h in on.equalities]))
        _check_even_degree("degree", d, minimum=0)
        origin = {v: 0.0 for v in self.variables}
        rest = p
        for g in on.inequalities:
            half = (d - g.degree) // 2
            if half >= 0:
                low = 1 if zero_at_origin and g.evaluate(origin) > 0.0 else 0
                if half >= low:
                    basis = monomial_basis(self.variables, half, min_degree=low, max_exponents=self.gram_caps)
                    rest = rest - self.sos_polynomial(basis) * g
        for h in on.equalities:
            if d - h.degree >= 0:
                rest = rest - self.free_polynomial(monomial_basis(self.variables, d - h.degree)) * h
        if half_basis is None:
            caps = dict(self.gram_caps)
            if not (on.inequalities or on.equalities):
                caps = {v: min(rest.degree_in(v) // 2, caps.get(v, d)) for v in self.variables}
            half_basis = monomial_basis(self.variables, d // 2, min_degree=int(zero_at_origin), max_exponents=caps)
        self.add_sos(rest, half_basis=half_basis)

    def solve(self, objective: Any = None, *, sense: str = "minimize",
              solvers: Sequence[str] = DEFAULT_SOLVERS) -> SolveOutcome:
        """Solve; never raises on solver trouble (see :class:`SolveOutcome`).

        The next solver of ``solvers`` is tried only when one fails outright
        (``cvxpy.error.SolverError`` or an unknown status).
        """
        if sense not in ("minimize", "maximize"):
            raise SosError("sense", sense, "'minimize' or 'maximize'", "choose a sense")
        goal = cp.Minimize(0) if objective is None else (cp.Minimize(objective) if sense == "minimize"
                                                         else cp.Maximize(objective))
        problem = cp.Problem(goal, self.constraints)
        outcome = SolveOutcome(status="solver_error", solver_status="no solver tried", solver="", objective=None)
        for solver in solvers:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    problem.solve(solver=solver)
            except (cp.error.SolverError, ValueError, ArithmeticError) as err:
                outcome = SolveOutcome(status="solver_error", solver_status=f"{type(err).__name__}: {err}"[:300],
                                       solver=solver, objective=None)
                continue
            outcome = _outcome(problem, solver)
            if outcome.status != "solver_error":
                return outcome
        return outcome


def _outcome(problem: cp.Problem, solver: str) -> SolveOutcome:
    status = str(problem.status)
    kind = {cp.OPTIMAL: "solved", cp.OPTIMAL_INACCURATE: "inaccurate", cp.INFEASIBLE: "infeasible",
            cp.INFEASIBLE_INACCURATE: "infeasible", cp.UNBOUNDED: "unbounded",
            cp.UNBOUNDED_INACCURATE: "unbounded"}.get(status, "solver_error")
    value = problem.value if kind in ("solved", "inaccurate") else None
    objective = float(value) if value is not None and np.isfinite(value) else None
    return SolveOutcome(status=kind, solver_status=status, solver=solver, objective=objective)


def _even_up(d: int) -> int:
    return d + (d % 2)


def _check_even_degree(name: str, d: object, *, minimum: int = 2) -> int:
    if isinstance(d, bool) or not isinstance(d, int) or d < minimum or d % 2:
        hint = max(minimum, _even_up(d)) if isinstance(d, int) and not isinstance(d, bool) else minimum
        raise SosError(name, d, f"an even integer >= {minimum}", f"use {hint} or higher")
    return d


# --------------------------------------------------------------------------- exact rounding


def round_polynomial(p: SosPoly, *, bits: int = ROUNDING_BITS) -> dict[Exponent, Fraction]:
    """Round a numeric polynomial's coefficients to dyadic rationals (exact floats).

    Each coefficient becomes the nearest multiple of ``2**(e − bits)``, where
    ``2**e > max |c|``; coefficients below that quantum vanish.
    """
    if not p.is_numeric:
        p = p.value()
    c = np.asarray(p.coefficients, dtype=float)
    if not np.all(np.isfinite(c)):
        raise SosError("coefficients", c.tolist(), "finite numbers", "the solver returned NaN/inf; re-solve")
    biggest = float(np.max(np.abs(c), initial=0.0))
    if biggest == 0.0:
        return {}
    quantum = Fraction(2) ** (math.frexp(biggest)[1] - bits)
    out: dict[Exponent, Fraction] = {}
    for m, x in zip(p.monomials, c):
        q = round(Fraction(float(x)) / quantum) * quantum
        if q:
            out[m] = out.get(m, Fraction(0)) + q
    return out


def to_polynomial(p: SosPoly | Mapping[Exponent, Fraction], variables: Sequence[str] | None = None, *,
                  atoms: Mapping[str, Atom] | None = None, bits: int = ROUNDING_BITS) -> Polynomial:
    """Exact :class:`~analysis.polynomial.Polynomial` of a (rounded) SOS polynomial.

    Parameters
    ----------
    p : SosPoly or Mapping[Exponent, Fraction]
        A numeric polynomial (rounded by :func:`round_polynomial`) or exact terms.
    variables : sequence of str, optional
        Needed when ``p`` is a mapping.
    atoms : Mapping[str, Atom], optional
        The atom each variable stands for (default ``Atom.var(name)``), e.g.
        ``{"s": Atom.sin("alpha"), "c": Atom.cos("alpha")}``.
    """
    if isinstance(p, SosPoly):
        variables, terms = p.variables, round_polynomial(p, bits=bits)
    else:
        if variables is None:
            raise SosError("variables", None, "the variable names of the exponent tuples", "pass variables")
        variables, terms = checked_names(variables), dict(p)
    atoms = dict(atoms or {})
    unknown = sorted(set(atoms) - set(variables))
    if unknown:
        raise SosError("atoms", unknown, f"names among {list(variables)}", "map only declared variables")
    table = [atoms.get(v, Atom.var(v)) for v in variables]
    out: dict[tuple[tuple[Atom, int], ...], Fraction] = {}
    for m, c in terms.items():
        powers: dict[Atom, int] = {}
        for atom, e in zip(table, m):
            if e:
                powers[atom] = powers.get(atom, 0) + e
        key = tuple(powers.items())
        out[key] = out.get(key, Fraction(0)) + Fraction(c)
    return Polynomial(out)


def from_polynomial(poly: Polynomial, variables: Sequence[str], atoms: Mapping[Atom, str]) -> SosPoly:
    """Numeric :class:`SosPoly` of an exact polynomial, each atom mapped to a program variable.

    Coefficients are rounded to floats (a search needs no exactness).
    """
    variables = checked_names(variables)
    table = {Atom(*a): n for a, n in atoms.items()}
    terms: dict[Exponent, float] = {}
    for monomial, c in poly.terms.items():
        e = [0] * len(variables)
        for atom, power in monomial:
            if atom not in table or table[atom] not in variables:
                raise SosError("atoms", sorted(map(str, table)), f"a program variable for the atom {atom}",
                               "map every atom of the polynomial to a variable")
            e[variables.index(table[atom])] += power
        terms[tuple(e)] = terms.get(tuple(e), 0.0) + float(c)
    return SosPoly.from_terms(variables, terms)


# --------------------------------------------------------------------------- Lyapunov and regions


def _status_message(outcome: SolveOutcome, degree: int, what: str) -> str:
    if outcome.status == "solved":
        return f"{what} of degree {degree} found (numerically; the interval re-check decides)"
    if outcome.status == "inaccurate":
        return (f"{what} of degree {degree} found with reduced accuracy ({outcome.solver_status}); "
                "the interval re-check decides")
    if outcome.status == "infeasible":
        return (f"degree too low to certify: no {what} of degree {degree} with these multipliers exists "
                f"(the SDP is infeasible); try degree {degree + 2}, or the property does not hold as posed")
    if outcome.status == "unbounded":
        return f"the SDP is unbounded at degree {degree}: add constraints (e.g. a bounded box)"
    return (f"the SDP solver failed at degree {degree} ({outcome.solver_status}); try degree {degree + 2} or "
            "rescale the variables")


@dataclass(frozen=True, kw_only=True, slots=True)
class LyapunovSos:
    """Result of :func:`sos_lyapunov` (and the function inside :class:`RegionSos`).

    Attributes
    ----------
    found : bool
        The SDP returned a (possibly inaccurate) solution.
    status : str
        :attr:`SolveOutcome.status`.
    message : str
        What happened; for an infeasible SDP "degree too low to certify ..." with the next degree.
    degree : int
    variables : tuple of str
        Program variables (the exponent order of :attr:`terms`).
    terms : Mapping[Exponent, Fraction]
        ``V`` with dyadic rational coefficients (empty when not found).
    lyapunov : Polynomial or None
        The same ``V`` as an exact :class:`~analysis.polynomial.Polynomial` (atoms ``Atom.var(name)``).
    outcome : SolveOutcome
    """

    found: bool
    status: str
    message: str
    degree: int
    variables: tuple[str, ...]
    terms: Mapping[Exponent, Fraction]
    lyapunov: Polynomial | None
    outcome: SolveOutcome

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (coefficients as exact fraction strings)."""
        return {"found": self.found, "status": self.status, "message": self.message, "degree": self.degree,
                "variables": list(self.variables), "lyapunov": None if self.lyapunov is None else str(self.lyapunov),
                "terms": [[list(m), str(c)] for m, c in self.terms.items()],
                "solver": self.outcome.solver, "solver_status": self.outcome.solver_status}


@dataclass(frozen=True, kw_only=True, slots=True)
class RegionSos:
    """Result of :func:`invariant_region`: ``V`` whose ``{V <= level}`` is the candidate region.

    Attributes
    ----------
    lyapunov : LyapunovSos
    level : float
        The level of the candidate region (1).
    objective : float or None
        ``∫_box V`` at the optimum.
    """

    lyapunov: LyapunovSos
    level: float
    objective: float | None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {"lyapunov": self.lyapunov.as_dict(), "level": self.level, "objective": self.objective}


@dataclass(frozen=True, kw_only=True, slots=True)
class RoaSos:
    """Result of :func:`region_of_attraction`: the largest ``ρ`` found for the given ``V``.

    Attributes
    ----------
    found : bool
    status, message : str
    rho : float or None
        Largest level (numerical; certify ``{V <= rho}`` with :func:`analysis.sublevel.certify_sublevel`).
    multiplier_degree : int
    outcome : SolveOutcome
    """

    found: bool
    status: str
    message: str
    rho: float | None
    multiplier_degree: int
    outcome: SolveOutcome

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {"found": self.found, "status": self.status, "message": self.message, "rho": self.rho,
                "multiplier_degree": self.multiplier_degree, "solver": self.outcome.solver}


def _check_rates(rates: Mapping[str, SosPoly]) -> tuple[str, ...]:
    if not isinstance(rates, Mapping) or not rates:
        raise SosError("rates", rates, "a non-empty mapping {variable: numeric SosPoly}", "give one rate per state")
    polys = list(rates.values())
    if not all(isinstance(p, SosPoly) and p.is_numeric for p in polys):
        raise SosError("rates", rates, "numeric SosPoly rates", "build the rates from numbers")
    variables = polys[0].variables
    for name, p in rates.items():
        if p.variables != variables:
            raise SosError("rates", name, f"rates over the same variables {variables}", "use one variable tuple")
        if name not in variables:
            raise SosError("rates", name, f"a state among the variables {list(variables)}",
                           "key the rates by declared variable names")
        if not np.all(np.isfinite(p.coefficients)):
            raise SosError(f"rates[{name!r}]", p.terms(), "finite coefficients", "remove NaN/inf")
    return variables


def _lyapunov_setup(rates: Mapping[str, SosPoly], degree: int, lyapunov_variables: Sequence[str] | None,
                    basis: Sequence[Exponent] | None, positive: SosPoly | None, stationary: Sequence[str] | None,
                    gram_caps: Mapping[str, int] | None = None,
                    ) -> tuple[tuple[str, ...], SosProgram, SosPoly, SosPoly, SosPoly]:
    """Program with the unknown ``V`` (``V(0) = 0``, ``∂V/∂x(0) = 0`` for ``stationary``), ``V̇`` and ``φ``."""
    variables = _check_rates(rates)
    _check_even_degree("degree", degree)
    origin = {v: 0.0 for v in variables}
    moving = {name: f.evaluate(origin) for name, f in rates.items() if f.evaluate(origin) != 0.0}
    if moving:
        raise SosError("rates", moving, "rates that vanish at the origin (the equilibrium)",
                       "shift the variables so that the equilibrium is the origin (e.g. r = 1 - cos(alpha))")
    lv = tuple(rates) if lyapunov_variables is None else tuple(lyapunov_variables)
    unknown = [v for v in lv if v not in rates]
    if unknown or not lv:
        raise SosError("lyapunov_variables", list(lv), f"state variables with a rate, among {list(rates)}",
                       "name only variables of the rates")
    flat = lv if stationary is None else tuple(stationary)
    if [x for x in flat if x not in variables]:
        raise SosError("stationary", list(flat), f"variables among {list(variables)}", "name declared variables")
    program = SosProgram(variables, gram_caps=gram_caps)
    v_basis = tuple(basis) if basis is not None else monomial_basis(variables, degree, min_degree=1, only=lv)
    if any(sum(m) > degree for m in v_basis) or any(not sum(m) for m in v_basis):
        raise SosError("basis", list(v_basis), f"non-constant monomials of degree <= {degree}",
                       "drop the constant monomial (V(0) = 0) and raise the degree or trim the basis")
    v = program.free_polynomial(v_basis)
    for x in flat:  # V is stationary at the origin: no first-order term there
        gradient = v.derivative(x)
        if not gradient.is_numeric:
            program.constraints.append(gradient.evaluate(origin) == 0)
    phi = positive if positive is not None else sum(
        (SosPoly.variable(x, variables) ** 2 for x in lv), SosPoly.constant(0.0, variables))
    if not isinstance(phi, SosPoly) or not phi.is_numeric or phi.variables != variables or phi.evaluate(origin):
        raise SosError("positive", phi, f"a numeric SosPoly over {variables} vanishing at the origin",
                       "use a positive definite polynomial such as the sum of squares of the states")
    return variables, program, v, v.lie_derivative(rates), phi


def _lyapunov_result(program_v: SosPoly, outcome: SolveOutcome, degree: int, what: str,
                     variables: tuple[str, ...]) -> LyapunovSos:
    found = outcome.ok
    terms: dict[Exponent, Fraction] = {}
    poly = None
    status = outcome.status
    if found:
        try:
            terms = round_polynomial(program_v.value())
            poly = to_polynomial(terms, variables)
        except SosError:
            found, status = False, "solver_error"
    return LyapunovSos(found=found, status=status, message=_status_message(outcome, degree, what), degree=degree,
                       variables=variables, terms=terms, lyapunov=poly, outcome=outcome)


def _check_epsilon(epsilon: object) -> float:
    if not (is_real_number(epsilon) and math.isfinite(float(epsilon)) and float(epsilon) >= 0):  # type: ignore[arg-type]
        raise SosError("epsilon", epsilon, "a finite number >= 0", "use e.g. 1e-3")
    return float(epsilon)  # type: ignore[arg-type]


def sos_lyapunov(rates: Mapping[str, SosPoly], *, degree: int, lyapunov_variables: Sequence[str] | None = None,
                 domain: SemialgebraicSet | None = None, epsilon: float = 1e-3, positive: SosPoly | None = None,
                 stationary: Sequence[str] | None = None,
                 basis: Sequence[Exponent] | None = None, certificate_degree: int | None = None,
                 gram_caps: Mapping[str, int] | None = None,
                 solvers: Sequence[str] = DEFAULT_SOLVERS) -> LyapunovSos:
    """Search ``V`` with ``V − φ >= 0`` and ``−V̇ − ε φ >= 0`` (globally or on ``domain``).

    Parameters
    ----------
    rates : Mapping[str, SosPoly]
        ``ẋ = f(x)``: a numeric rate per state variable, all over the same variables.
    degree : int
        Even degree ``>= 2`` of ``V``.
    lyapunov_variables : sequence of str, optional
        Variables ``V`` may depend on (default: every state).
    domain : SemialgebraicSet, optional
        Where the inequalities must hold (Putinar multipliers); ``None``: globally.
    epsilon : float
        Decay margin ``ε >= 0``.
    positive : SosPoly, optional
        ``φ``, vanishing at the origin (default ``Σ x_i²`` over ``lyapunov_variables``).
    stationary : sequence of str, optional
        Variables in which ``∂V/∂x(0) = 0`` is imposed (default ``lyapunov_variables``; on the
        circle ``s² + r² − 2r = 0``, ``r = 1 − cos α``, only ``s``: ``r >= 0`` there, so ``V`` may be
        linear in ``r``).
    basis : sequence of Exponent, optional
        Monomials of ``V`` (default: all of degree ``1 .. degree`` in ``lyapunov_variables``).
    certificate_degree : int, optional
        Degree of the Putinar certificates (default: the smallest even degree that fits).
    gram_caps : Mapping[str, int], optional
        Exponent caps of the Gram bases (:class:`SosProgram`).
    solvers : sequence of str

    Returns
    -------
    LyapunovSos

    Raises
    ------
    SosError
        Bad degree (< 2 or odd), unknown variable names, NaN coefficients.
    """
    epsilon = _check_epsilon(epsilon)
    variables, program, v, vdot, phi = _lyapunov_setup(rates, degree, lyapunov_variables, basis, positive,
                                                        stationary, gram_caps)
    program.add_nonnegative(v - phi, on=domain, degree=certificate_degree, zero_at_origin=True)
    program.add_nonnegative(-vdot - epsilon * phi, on=domain, degree=certificate_degree, zero_at_origin=True)
    outcome = program.solve(solvers=solvers)
    return _lyapunov_result(v, outcome, degree, "Lyapunov function", variables)


def box_moments(box: Mapping[str, tuple[float, float]], monomials: Sequence[Exponent],
                variables: Sequence[str]) -> np.ndarray:
    """``∫_box x^m dx`` for each monomial (products of 1-D integrals), shape ``(len(monomials),)``.

    Variables absent from ``box`` are integrated over ``[0, 1]``.
    """
    variables = checked_names(variables)
    region = _check_box(box, variables)
    out = []
    for m in monomials:
        value = 1.0
        for v, e in zip(variables, m):
            lo, hi = region.get(v, (0.0, 1.0))
            value *= (hi ** (e + 1) - lo ** (e + 1)) / (e + 1)
        out.append(value)
    return np.array(out)


def _check_box(box: Mapping[str, tuple[float, float]], variables: Sequence[str]) -> dict[str, tuple[float, float]]:
    return box_bounds("box", box, error=SosError, variables=variables, fix="bound each variable of the region")


def _box_set(box: Mapping[str, tuple[float, float]], variables: tuple[str, ...]) -> SemialgebraicSet:
    return SemialgebraicSet(inequalities=tuple(
        (SosPoly.variable(v, variables) - lo) * (hi - SosPoly.variable(v, variables)) for v, (lo, hi) in box.items()))


def invariant_region(rates: Mapping[str, SosPoly], *, degree: int, boundary: Sequence[SosPoly] | None = None,
                     box: Mapping[str, tuple[float, float]] | None = None,
                     lyapunov_variables: Sequence[str] | None = None, domain: SemialgebraicSet | None = None,
                     epsilon: float = 1e-3, positive: SosPoly | None = None, stationary: Sequence[str] | None = None,
                     moments: Sequence[float] | None = None, basis: Sequence[Exponent] | None = None,
                     shrink: float = 0.98, certificate_degree: int | None = None,
                     gram_caps: Mapping[str, int] | None = None,
                     solvers: Sequence[str] = DEFAULT_SOLVERS) -> RegionSos:
    """Volume heuristic: minimise ``∫_box V`` s.t. ``V >= b_i`` and ``−V̇ >= ε φ`` on the domain.

    Parameters
    ----------
    rates, degree, lyapunov_variables, epsilon, positive, stationary, basis, certificate_degree, \
    gram_caps, solvers
        As :func:`sos_lyapunov`.
    boundary : sequence of SosPoly, optional
        Boundary functions ``b_i`` (numeric), each ``> 1`` on a face of the box, so that
        ``{V <= 1}`` stays inside.  Default: ``((x − mid)/(shrink · half width))²`` per box variable.
    box : Mapping[str, (float, float)], optional
        The box (needed for the default boundary functions, domain and moments).
    domain : SemialgebraicSet, optional
        Where the inequalities must hold (default: the box as ``(x − lo)(hi − x) >= 0``).
    moments : sequence of float, optional
        ``∫_box m`` for each monomial of ``V``'s basis (default :func:`box_moments`).
    shrink : float
        In ``(0, 1]``: the default boundary functions reach 1 at ``shrink`` times the half widths.

    Returns
    -------
    RegionSos

    Raises
    ------
    SosError
        As :func:`sos_lyapunov`; empty or reversed box bounds; nothing to bound the region.
    """
    epsilon = _check_epsilon(epsilon)
    variables = _check_rates(rates)
    region = _check_box(box, variables) if box is not None else None
    if not (is_real_number(shrink) and 0.0 < shrink <= 1.0):
        raise SosError("shrink", shrink, "a number in (0, 1]", "use e.g. 0.98")
    if boundary is None:
        if region is None:
            raise SosError("boundary", None, "boundary functions or a box", "pass box= or boundary=")
        boundary = [((SosPoly.variable(v, variables) - 0.5 * (lo + hi)) * (2.0 / (shrink * (hi - lo)))) ** 2
                    for v, (lo, hi) in region.items()]
    if domain is None and region is not None:
        domain = _box_set(region, variables)
    variables, program, v, vdot, phi = _lyapunov_setup(rates, degree, lyapunov_variables, basis, positive,
                                                        stationary, gram_caps)
    origin = {x: 0.0 for x in variables}
    for b in boundary:
        if not isinstance(b, SosPoly) or not b.is_numeric or b.variables != variables:
            raise SosError("boundary", b, f"numeric SosPoly over {variables}", "build b_i from numbers")
        program.add_nonnegative(v - b, on=domain, degree=certificate_degree, zero_at_origin=b.evaluate(origin) == 0)
    program.add_nonnegative(-vdot - epsilon * phi, on=domain, degree=certificate_degree, zero_at_origin=True)
    if moments is None:
        if region is None:
            raise SosError("moments", None, "moments or a box", "pass box= or moments=")
        moments = box_moments(region, v.monomials, variables)
    weights = np.asarray(moments, dtype=float)
    if weights.shape != (len(v.monomials),) or not np.all(np.isfinite(weights)):
        raise SosError("moments", weights.shape, f"{len(v.monomials)} finite numbers", "one moment per basis monomial")
    outcome = program.solve(weights @ v.coefficients, solvers=solvers)
    return RegionSos(lyapunov=_lyapunov_result(v, outcome, degree, "invariant-region function", variables),
                     level=1.0, objective=outcome.objective)


def region_of_attraction(rates: Mapping[str, SosPoly], lyapunov: SosPoly, *, multiplier_degree: int = 2,
                         solvers: Sequence[str] = DEFAULT_SOLVERS) -> RoaSos:
    """Drake's formulation for a fixed ``V``: max ``ρ`` s.t. ``(xᵀx)^d (V − ρ) + λ V̇`` is SOS.

    Parameters
    ----------
    rates : Mapping[str, SosPoly]
        Numeric rates; the equilibrium is the origin.
    lyapunov : SosPoly
        Numeric ``V`` (e.g. the quadratic Lyapunov function of the linearisation).
    multiplier_degree : int
        Even degree of the free multiplier ``λ``; ``d`` is the smallest that balances the degrees.

    Returns
    -------
    RoaSos
        ``rho`` is numerical: certify ``{V <= rho}`` with :func:`analysis.sublevel.certify_sublevel`.
    """
    variables = _check_rates(rates)
    _check_even_degree("multiplier_degree", multiplier_degree, minimum=0)
    if not isinstance(lyapunov, SosPoly) or not lyapunov.is_numeric or lyapunov.variables != variables:
        raise SosError("lyapunov", lyapunov, f"a numeric SosPoly over {variables}", "fix V before the search")
    _check_even_degree("lyapunov degree", lyapunov.degree)
    vdot = lyapunov.lie_derivative(rates)
    d = max(0, math.ceil((multiplier_degree + vdot.degree - lyapunov.degree) / 2))
    program = SosProgram(variables)
    rho = cp.Variable()
    norm = sum((SosPoly.variable(x, variables) ** 2 for x in rates), SosPoly.constant(0.0, variables)) ** d
    lam = program.free_polynomial(monomial_basis(variables, multiplier_degree))
    rho_poly = SosPoly.from_terms(variables, {(0,) * len(variables): rho})
    top = max(norm.degree + lyapunov.degree, multiplier_degree + vdot.degree)
    program.add_sos(norm * lyapunov - rho_poly * norm + lam * vdot,
                    half_basis=monomial_basis(variables, _even_up(top) // 2))
    outcome = program.solve(rho, sense="maximize", solvers=solvers)
    found = outcome.ok and rho.value is not None
    return RoaSos(found=found, status=outcome.status,
                  message=_status_message(outcome, multiplier_degree, "region-of-attraction multiplier"),
                  rho=float(rho.value) if found else None, multiplier_degree=multiplier_degree, outcome=outcome)


@dataclass(frozen=True, kw_only=True, slots=True)
class BoundingSos:
    """Result of :func:`bounding_region`: ``V`` with ``V(x0) <= 1`` and ``t_j <= 1/γ`` on ``{V <= 1}``.

    Attributes
    ----------
    lyapunov : LyapunovSos
    gamma : float or None
        The optimal ``γ`` (numerical).
    bounds : tuple of float
        ``1/γ``: the SOS (numerical) bound of every target on ``{V <= 1}``.
    """

    lyapunov: LyapunovSos
    gamma: float | None
    bounds: tuple[float, ...]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {"lyapunov": self.lyapunov.as_dict(), "gamma": self.gamma, "bounds": list(self.bounds)}


def bounding_region(rates: Mapping[str, SosPoly], *, points: Sequence[Mapping[str, float]], targets: Sequence[SosPoly],
                    degree: int, boundary: Sequence[SosPoly] = (), lyapunov_variables: Sequence[str] | None = None,
                    domain: SemialgebraicSet | None = None, epsilon: float = 1e-3, positive: SosPoly | None = None,
                    stationary: Sequence[str] | None = None, basis: Sequence[Exponent] | None = None,
                    min_gamma: float = 0.0, regularisation: float = 0.0, certificate_degree: int | None = None,
                    gram_caps: Mapping[str, int] | None = None,
                    solvers: Sequence[str] = DEFAULT_SOLVERS) -> BoundingSos:
    """The invariant region through given points that is smallest in the targets: maximise ``γ`` subject to

    ``V(x0) <= 1`` at every given point ``x0``, ``V − γ t_j >= 0`` (every target), ``V − b_i >= 0`` (every boundary function) and
    ``−V̇ − ε φ >= 0``, all on ``domain``.  Linear in ``(V, γ)``.  On ``{V <= 1}``, which contains
    the points, every target is at most ``1/γ``; once ``{V <= 1}`` is certified invariant
    (:func:`analysis.sublevel.certify_sublevel`) it bounds the solutions through the points.

    Parameters
    ----------
    rates, degree, lyapunov_variables, domain, epsilon, positive, stationary, basis, certificate_degree, \
    gram_caps, solvers
        As :func:`sos_lyapunov`.
    points : sequence of Mapping[str, float]
        Initial states ``x0`` (a value for every program variable each), e.g. the corners of an entry set.
    targets : sequence of SosPoly
        Numeric ``t_j`` vanishing at the origin (e.g. ``δ²``, normalised by their allowed values).
    boundary : sequence of SosPoly
        Boundary functions as in :func:`invariant_region`.
    min_gamma : float
        Lower limit of ``γ`` (e.g. keeping ``{V <= 1}`` inside a strip when a target is ``x²/d²``).
    regularisation : float
        ``μ >= 0``: maximise ``γ − μ ‖v‖₁`` over the coefficients ``v`` of ``V``.  The optimum of ``γ``
        alone is often degenerate, with large coefficients that cancel (``a r − (a/2) s²`` for
        ``r = 1 − cos α``, ``s = sin α``); such a ``V`` is the same function but its interval
        enclosures are wide, which makes the re-check expensive.
    """
    epsilon = _check_epsilon(epsilon)
    if not targets:
        raise SosError("targets", targets, "at least one numeric SosPoly", "give the quantity to bound, e.g. x**2")
    variables, program, v, vdot, phi = _lyapunov_setup(rates, degree, lyapunov_variables, basis, positive,
                                                        stationary, gram_caps)
    origin = {x: 0.0 for x in variables}
    for name, group in (("targets", targets), ("boundary", boundary)):
        for t in group:
            if not isinstance(t, SosPoly) or not t.is_numeric or t.variables != variables:
                raise SosError(name, t, f"numeric SosPoly over {variables}", "build it from numbers")
    if any(t.evaluate(origin) != 0.0 for t in targets):
        raise SosError("targets", [t.evaluate(origin) for t in targets], "targets vanishing at the origin",
                       "bound the deviation from the equilibrium value")
    if not (is_real_number(min_gamma) and math.isfinite(float(min_gamma)) and min_gamma >= 0):
        raise SosError("min_gamma", min_gamma, "a finite number >= 0", "use 0 for no limit")
    gamma = cp.Variable()
    if not points:
        raise SosError("points", points, "at least one point", "give the initial state(s)")
    program.constraints += [v.evaluate(p) <= 1.0 for p in points] + [gamma >= float(min_gamma)]
    for t in targets:
        program.add_nonnegative(v - t * _gamma_poly(gamma, variables), on=domain, degree=certificate_degree,
                                zero_at_origin=True)
    for b in boundary:
        program.add_nonnegative(v - b, on=domain, degree=certificate_degree, zero_at_origin=b.evaluate(origin) == 0)
    program.add_nonnegative(-vdot - epsilon * phi, on=domain, degree=certificate_degree, zero_at_origin=True)
    if not (is_real_number(regularisation) and math.isfinite(float(regularisation)) and regularisation >= 0):
        raise SosError("regularisation", regularisation, "a finite number >= 0", "use 0 or e.g. 1e-3")
    goal = gamma - float(regularisation) * cp.norm1(v.coefficients) if regularisation else gamma
    outcome = program.solve(goal, sense="maximize", solvers=solvers)
    result = _lyapunov_result(v, outcome, degree, "bounding invariant-region function", variables)
    g = float(gamma.value) if result.found and gamma.value is not None else None
    bounds = (1.0 / g,) * len(targets) if g and g > 0 else ()
    return BoundingSos(lyapunov=result, gamma=g, bounds=bounds)


def _gamma_poly(gamma: Any, variables: Sequence[str]) -> SosPoly:
    """The constant polynomial with the cvxpy scalar ``gamma`` as coefficient."""
    return SosPoly.from_terms(variables, {(0,) * len(checked_names(variables)): gamma})
