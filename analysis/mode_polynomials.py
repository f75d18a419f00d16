"""The polynomial view of one mode of a hybrid system, for :mod:`analysis.mode_region`: its flow traced through
CasADi to polynomials (:func:`mode_polynomials`, :class:`ModePolynomials`), checked at probe points against the
system's own flow, and the coefficient helpers of those polynomials.

:mod:`analysis.mode_region` re-exports the public names.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import casadi as ca
import numpy as np

from analysis.polynomial import Atom, Polynomial, PolynomialError, UnsupportedExpression, normal_form
from hybrid import Conjunction, HybridSystem
from hybrid.errors import ParameterError
from hybrid.system import state_vector

# Helpers shared with analysis.mode_region have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = ["NotPolynomialError", "ModePolynomials", "mode_polynomials"]


_SHIFT = "Δ"
"""Prefix of the shifted coordinates ``Δx = x − x*`` of the certificates."""

_OPS = {"div": "division by a state-dependent expression", "inv": "division by a state-dependent expression",
        "fabs": "abs", "fmin": "min", "fmax": "max", "pow": "a non-integer or state-dependent power",
        "constpow": "a non-integer power", "sqrt": "sqrt", "exp": "exp", "log": "log"}


class NotPolynomialError(ParameterError):
    """A flow, invariant or guard of the mode is not a polynomial in the state (or depends on time)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ModePolynomials:
    """The exact polynomial data of one mode about ``x*``, in the shifted coordinates ``Δx = x − x*``.

    Attributes
    ----------
    mode : str
    state_names : tuple of str
        ``n`` names of the state.
    variables : tuple of str
        The shifted coordinates, ``"Δ" + name`` (the variables of every polynomial and certificate).
    equilibrium : tuple of float, shape (n,)
        ``x*`` (each float is taken at its exact binary value).
    memory : dict
        The memory values the functions were traced with.
    rates : Mapping[str, Polynomial]
        ``dΔx_i/dt = f_i(x* + Δx)``, keyed by the shifted names.
    invariant_terms : tuple of (str, Polynomial)
        ``(label, h(x* + Δx))`` per term of the mode's invariant (the mode may be kept where all are ``>= 0``).
    guards : tuple of (str, tuple of (str, Polynomial))
        Per outgoing transition: its name and its guard terms (enabled where all are ``>= 0``).
    """

    mode: str
    state_names: tuple[str, ...]
    variables: tuple[str, ...]
    equilibrium: tuple[float, ...]
    memory: dict[str, float]
    rates: Mapping[str, Polynomial]
    invariant_terms: tuple[tuple[str, Polynomial], ...]
    guards: tuple[tuple[str, tuple[tuple[str, Polynomial], ...]], ...]


def _symbolic_types() -> tuple[type, type, Callable[..., Any]]:
    from hybrid.symbolic import Expr, SymbolicVector, to_casadi

    return Expr, SymbolicVector, to_casadi


def _float_conversion(what: str, mode: str) -> NotPolynomialError:
    return NotPolynomialError(
        f"{what} of mode {mode!r}", "NaN for a symbolic state", "a polynomial in the state traced by CasADi",
        "the function converts the state to a float (a math.* function such as math.sin or math.exp, float(), "
        "or a numpy conversion); write it with + - * and integer powers")


def _as_sx(value: Any, what: str, mode: str) -> ca.SX:
    """A traced scalar as SX; a NaN float means the function converted a symbol to a float."""
    if isinstance(value, ca.SX) and value.shape == (1, 1):
        return value
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        if not math.isfinite(float(value)):
            raise _float_conversion(what, mode)
        return ca.SX(float(value))
    raise NotPolynomialError(f"{what} of mode {mode!r}", type(value).__name__,
                             "a number or CasADi expression per component", "return one scalar per component")


def _call_traced(function: Callable[..., Any], args: Sequence[Any], what: str, mode: str) -> Any:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return function(*args)
    except Exception as err:  # noqa: BLE001 - any failure on symbols means "does not trace"
        hint = ("it compares or branches on the state (min, max, if); write an invariant or guard as "
                "hybrid.all_of(term, ...)" if "truth value" in str(err) else "it does not accept CasADi symbols")
        raise NotPolynomialError(f"{what} of mode {mode!r}", f"{type(err).__name__}: {err}"[:200],
                                 "a polynomial in the state traced by CasADi", hint) from None


def _components(value: Any) -> list[Any]:
    """The components of a traced vector: a CasADi column, a numpy array of SX, a tuple or list."""
    if isinstance(value, ca.SX):
        return [value[i] for i in range(value.numel())]
    try:
        return list(value)
    except TypeError:
        return [value]


def _normal(expr: ca.SX, xs: list[ca.SX], t: ca.SX, what: str, mode: str) -> Polynomial:
    """Exact polynomial of ``expr`` in the state symbols, or :class:`NotPolynomialError` naming the function."""
    if ca.depends_on(expr, t):
        raise NotPolynomialError(f"{what} of mode {mode!r}", "depends on the time t",
                                 "an autonomous polynomial in the state",
                                 "a region of attraction needs a time-invariant mode")
    try:
        poly = normal_form(expr, xs)
    except UnsupportedExpression as err:
        used = _OPS.get(err.operation, err.operation)
        raise NotPolynomialError(f"{what} of mode {mode!r}", f"uses {used}", "a polynomial in the state",
                                 f"rewrite it with + - * and integer powers ({err})") from None
    except PolynomialError as err:
        if "not finite" in str(err):
            raise _float_conversion(what, mode) from None
        raise NotPolynomialError(f"{what} of mode {mode!r}", str(err)[:200], "a polynomial in the state",
                                 "write it with + - * and integer powers") from None
    trig = sorted({a.kind for a in poly.atoms if a.kind != "var"})
    if trig:
        raise NotPolynomialError(f"{what} of mode {mode!r}", f"uses {', '.join(trig)}", "a polynomial in the state",
                                 "a sine or cosine of the state is not polynomial; polynomialise the model first")
    return poly


def _split_terms(function: Any) -> list[Any]:
    """Terms of a conjunction: :class:`hybrid.Conjunction` terms, or a symbolic ``min(...)`` flattened."""
    expr_type, _, _ = _symbolic_types()
    from hybrid.symbolic import Apply

    out: list[Any] = []
    for term in (function.terms if isinstance(function, Conjunction) else (function,)):
        if isinstance(term, expr_type) and isinstance(term, Apply) and term.op == "min":
            out.extend(_split_terms(Conjunction(tuple(term.args))))
        else:
            out.append(term)
    return out


def _trace_mode(system: HybridSystem, mode: str, memory: Mapping[str, float]
                ) -> tuple[list[Polynomial], list[tuple[str, Any, Polynomial]],
                           list[tuple[str, list[tuple[str, Any, Polynomial]]]]]:
    """Flow components, invariant terms and guard terms as exact polynomials in the (unshifted) state."""
    expr_type, vector_type, to_casadi = _symbolic_types()
    from hybrid.symbolic import render

    names = system.state_names
    xs, t = [ca.SX.sym(n) for n in names], ca.SX.sym("t")
    flow = system.flows[mode]
    if isinstance(flow, vector_type):
        comps = [_call_traced(to_casadi, (c, dict(zip(names, xs)), dict(memory), t), "flow", mode)
                 for c in flow.components]
    else:
        comps = _components(_call_traced(flow, (t, xs, dict(memory)), "flow", mode))
    if len(comps) != len(names):
        raise NotPolynomialError(f"flow of mode {mode!r}", f"{len(comps)} components", f"{len(names)}",
                                 "return one rate per state")
    rates = [_normal(_as_sx(c, f"flow (component d{n}/dt)", mode), xs, t, f"flow (component d{n}/dt)", mode)
             for c, n in zip(comps, names)]
    out = system.output
    if out is None:
        signals = list(xs)
    elif isinstance(out, vector_type):
        signals = [_call_traced(to_casadi, (c, dict(zip(names, xs)), {}, t), "output map", mode)
                   for c in out.components]
    else:
        signals = _components(_call_traced(out, (t, xs), "output map", mode))
    signals = [_as_sx(v, "output map", mode) for v in signals]
    variables = dict(zip(system.automaton.variables, signals))

    def terms(function: Any, label: str, text: str) -> list[tuple[str, Any, Polynomial]]:
        found = []
        split = _split_terms(function)
        for k, term in enumerate(split):
            what = f"{label} term {k}" if len(split) > 1 else label
            shown = f"{render(term)} >= 0" if isinstance(term, expr_type) else text
            what += f" ({shown})" if shown else ""
            value = (_call_traced(to_casadi, (term, variables, dict(memory)), what, mode)
                     if isinstance(term, expr_type) else _call_traced(term, (signals, dict(memory)), what, mode))
            found.append((what, term, _normal(_as_sx(value, what, mode), xs, t, what, mode)))
        return found

    q = system.automaton.mode(mode)
    inv = [] if q.invariant is None else terms(q.invariant, "invariant", q.invariant_text)
    guards = [(tr.name, terms(tr.guard, f"guard of transition {tr.name!r}", tr.guard_text))
              for tr in system.automaton.outgoing(mode)]
    return rates, inv, guards


def _probe_points(xstar: np.ndarray) -> list[np.ndarray]:
    n = xstar.size
    pattern = np.array([0.37, -0.61, 0.83, -0.29, 0.53, -0.71, 0.19, -0.47])
    scale = 0.5 * (1.0 + np.abs(xstar))
    return [xstar + scale * np.resize(pattern, n), xstar - 0.7 * scale * np.resize(pattern[::-1], n)]


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= 1e-9 * (1.0 + abs(a) + abs(b))


def _probe_check(system: HybridSystem, mode: str, memory: Mapping[str, float], rates: list[Polynomial],
                 inv: list[tuple[str, Any, Polynomial]], guards: list[tuple[str, list[tuple[str, Any, Polynomial]]]],
                 xstar: np.ndarray) -> None:
    """The traced polynomials must equal the user's float functions at two probe points."""
    names = system.state_names
    for p in _probe_points(xstar):
        point = dict(zip(names, p.tolist()))
        state = tuple(p.tolist())
        try:
            flow = system.flow(mode, 0.0, state, dict(memory))
            signals = system.signals(0.0, state, mode)
        except Exception:  # noqa: BLE001 - the function is undefined there: nothing to compare
            continue
        checks = [(f"flow (component d{n}/dt)", r.evaluate_at(point), flow[i]) for i, (n, r) in
                  enumerate(zip(names, rates))]
        for what, term, poly in inv + [item for _, terms in guards for item in terms]:
            checks.append((what, poly.evaluate_at(point), float(term(signals, dict(memory)))))
        for what, traced, value in checks:
            if not _close(traced, float(value)):
                raise NotPolynomialError(
                    f"{what} of mode {mode!r}", f"traced {traced!r} but evaluates to {float(value)!r} at x = {state}",
                    "one polynomial expression for every state",
                    "the function branches on the state or the time; write it as one polynomial")


def substitute_exact(poly: Polynomial, table: Mapping[str, Polynomial]) -> Polynomial:
    """``poly`` with every variable ``v`` replaced by ``table[v]`` (exact)."""
    out = Polynomial({})
    powers: dict[tuple[str, int], Polynomial] = {}
    for monomial, c in poly.terms.items():
        term = Polynomial.constant(c)
        for atom, p in monomial:
            key = (atom.variable, p)
            if key not in powers:
                powers[key] = table[atom.variable] ** p
            term = term * powers[key]
        out = out + term
    return out


def mode_polynomials(system: HybridSystem, mode: str, equilibrium: Sequence[float], *,
                     memory: Mapping[str, float] | None = None) -> ModePolynomials:
    """Trace ``mode``'s flow, invariant terms and outgoing guard terms to exact polynomials about ``x*``.

    Parameters
    ----------
    system : HybridSystem
    mode : str
    equilibrium : sequence of float, shape (n,)
        ``x*``, the origin of the shifted coordinates ``Δx = x − x*`` (exact binary values).
    memory : Mapping or None
        Memory values (default: the automaton's initial memory).

    Returns
    -------
    ModePolynomials

    Raises
    ------
    NotPolynomialError
        A function is not a polynomial in the state (naming it, the component and the operation:
        ``sin``, ``exp``, division, ``abs``, ``min`` ...), depends on time, or does not trace.
    ParameterError
        Unknown mode, wrong-length or non-finite equilibrium, bad memory.
    """
    check_system_mode(system, mode)
    xstar = state_point("equilibrium", equilibrium, system)
    mem = mode_memory(system, memory)
    rates, inv, guards = _trace_mode(system, mode, mem)
    _probe_check(system, mode, mem, rates, inv, guards, xstar)
    shifted = tuple(_SHIFT + n for n in system.state_names)
    table = {n: Polynomial.atom(z) + Fraction(float(c)) for n, z, c in zip(system.state_names, shifted, xstar)}
    return ModePolynomials(
        mode=mode, state_names=system.state_names, variables=shifted, equilibrium=tuple(float(c) for c in xstar),
        memory=mem, rates={z: substitute_exact(r, table) for z, r in zip(shifted, rates)},
        invariant_terms=tuple((label, substitute_exact(p, table)) for label, _, p in inv),
        guards=tuple((name, tuple((label, substitute_exact(p, table)) for label, _, p in terms)) for name, terms in guards))


def check_system_mode(system: Any, mode: Any) -> None:
    """Raise :class:`ParameterError` unless ``system`` is a :class:`hybrid.HybridSystem` with a mode ``mode``."""
    if not isinstance(system, HybridSystem):
        raise ParameterError("system", type(system).__name__, "a hybrid.HybridSystem",
                             "build the system with hybrid.HybridSystem")
    if mode not in system.automaton.mode_names:
        raise ParameterError("mode", mode, f"one of the modes {list(system.automaton.mode_names)}",
                             "name a mode of the automaton")


def state_point(name: str, value: Any, system: HybridSystem) -> np.ndarray:
    """``value`` as a state vector of ``system`` (shape ``(n,)``), or :class:`ParameterError` naming ``name``."""
    return state_vector(name, value, system.state_names)


def mode_memory(system: HybridSystem, memory: Mapping[str, float] | None) -> dict[str, float]:
    """The automaton's initial memory updated with ``memory`` (checked: known names, finite values)."""
    mem = system.automaton.initial_memory()
    if memory is None:
        return mem
    if not isinstance(memory, Mapping):
        raise ParameterError("memory", memory, "a mapping {memory variable: value}", "pass a dict or None")
    for key, value in memory.items():
        if key not in mem:
            raise ParameterError("memory", dict(memory), f"names among the memory variables {sorted(mem)}",
                                 f"drop {key!r}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ParameterError(f"memory[{key!r}]", value, "a finite number", "give a finite value")
        mem[key] = float(value)
    return mem


def coefficient_of(poly: Polynomial, powers: Mapping[str, int]) -> Fraction:
    """The exact coefficient of the monomial ``prod v**p`` (``powers``: variable -> power) in ``poly``."""
    key = tuple((Atom.var(v), p) for v, p in sorted(powers.items()) if p)
    return poly.terms.get(key, Fraction(0))


def linear_part(rates: Mapping[str, Polynomial], variables: Sequence[str]) -> list[list[Fraction]]:
    """Exact Jacobian ``A`` of the rates at the origin."""
    return [[coefficient_of(rates[zi], {zj: 1}) for zj in variables] for zi in variables]


def quadratic_matrix(v: Polynomial, variables: Sequence[str]) -> list[list[Fraction]]:
    """``P`` with ``zᵀPz`` the quadratic part of ``v`` (exact)."""
    n = len(variables)
    return [[coefficient_of(v, {variables[i]: 2}) if i == j else coefficient_of(v, {variables[i]: 1, variables[j]: 1}) / 2
             for j in range(n)] for i in range(n)]
