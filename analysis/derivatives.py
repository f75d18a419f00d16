"""Derivatives of a user's hybrid system, by CasADi through the user's own functions.

The one mechanism that turns a mode's flow ``f_q(t, x, m)`` into a vector field with a Jacobian:

* a symbolic flow (:func:`hybrid.symbolic.flow_map`) is converted by :func:`hybrid.symbolic.to_casadi`;
* a plain Python function is *traced*: it is called once with CasADi ``SX`` symbols in place of the
  state (``x[0]``, ``x[1] * 2``, ``-rate * (x[0] - 10)`` all trace), and the traced expression is
  compared with the float flow at a probe point;
* a function that does not trace (``math.sin`` on a symbol, a branch on the state, numpy
  conversions) falls back on central finite differences, and the result says so
  (``method = "finite differences"``).

Examples
--------
>>> from hybrid import HybridAutomaton, HybridSystem, Mode
>>> a = HybridAutomaton(name="decay", modes=(Mode(name="on"),), transitions=(), variables=("T",), initial_mode="on")
>>> s = HybridSystem(automaton=a, state_names=("T",), flows={"on": lambda t, x, m: (-0.5 * (x[0] - 30.0),)})
>>> field = mode_vector_field(s, "on")
>>> field.method, field.jacobian((20.0,)).tolist()
('casadi', [[-0.5]])
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from hybrid import HybridSystem
from hybrid.errors import ParameterError

__all__ = ["VectorField", "DifferentiableMap", "mode_vector_field", "differentiable_map", "FD_STEP"]

FD_STEP = 1e-6
"""Relative step of the central-difference fallback (error ~ step² · |f'''|, round-off ~ eps/step)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class VectorField:
    """The flow of one mode at fixed time and memory, with its Jacobian.

    Attributes
    ----------
    system, mode : str
    state_names : tuple of str
    method : str
        ``"casadi"`` (exact derivatives of the traced or symbolic flow) or ``"finite differences"``.
    reason : str
        Why tracing was not possible (empty for ``"casadi"``).
    flow : DifferentiableMap
        The map itself (:meth:`value`, :meth:`jacobian` delegate to it).
    """

    system: str
    mode: str
    state_names: tuple[str, ...]
    method: str
    reason: str
    flow: DifferentiableMap

    def value(self, x: Sequence[float]) -> np.ndarray:
        """``f(x)``, shape ``(n,)``."""
        return self.flow.value(x)

    def jacobian(self, x: Sequence[float]) -> np.ndarray:
        """``∂f/∂x (x)``, shape ``(n, n)``."""
        return self.flow.jacobian(x)


def _trace(function: Callable[[list[Any]], Sequence[Any]], n: int, probe: np.ndarray,
           plain: Callable[[np.ndarray], np.ndarray]) -> tuple[ca.Function, ca.Function] | str:
    """CasADi value and Jacobian functions of ``function`` (called with ``n`` SX scalars), or why it does not trace.

    The traced expression must equal ``plain`` (the float evaluation) at ``probe``: a function that
    branches on its input, or converts it to a float (``math.sin`` gives NaN on a symbol), is caught.
    """
    x = ca.SX.sym("x", n)
    try:
        out = function([x[i] for i in range(n)])
        expr = ca.vertcat(*[ca.SX(c) if isinstance(c, (int, float)) else c for c in out])
    except Exception as err:  # a function written for floats only: fall back, and say why
        return f"it does not accept CasADi symbols ({type(err).__name__}: {err})"
    if not isinstance(expr, ca.SX):
        return f"it returned {type(expr).__name__} values for symbolic input"
    names = {str(x[i]) for i in range(n)}
    if any(str(sym) not in names for sym in ca.symvar(expr)):
        return "its traced expression depends on symbols other than the state"
    value = ca.Function("f", [x], [expr])
    traced = np.asarray(value(probe).full(), dtype=float).reshape(-1)
    reference = np.asarray(plain(probe), dtype=float).reshape(-1)
    if traced.shape != reference.shape or not np.allclose(
            traced, reference, rtol=1e-12, atol=1e-12 * (1.0 + float(np.abs(reference).max(initial=0.0)))):
        return f"the traced values {traced.tolist()} differ from the function's {reference.tolist()} at x = {probe.tolist()}"
    return value, ca.Function("J", [x], [ca.jacobian(expr, x)])


def _central_differences(plain: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray]:
    def jacobian(x: np.ndarray) -> np.ndarray:
        cols = []
        for i in range(x.size):
            h = FD_STEP * max(1.0, abs(x[i]))
            e = np.zeros(x.size)
            e[i] = h
            cols.append((np.asarray(plain(x + e), dtype=float).reshape(-1)
                         - np.asarray(plain(x - e), dtype=float).reshape(-1)) / (2.0 * h))
        return np.column_stack(cols)

    return jacobian


@dataclass(frozen=True, kw_only=True, slots=True)
class DifferentiableMap:
    """A map ``x -> y`` of a system's states with its Jacobian (``method``: ``"casadi"`` or ``"finite differences"``)."""

    what: str
    method: str
    reason: str
    _value: Any
    _jacobian: Any

    def value(self, x: Sequence[float]) -> np.ndarray:
        """``F(x)``, shape ``(k,)``."""
        return np.asarray(self._value(np.asarray(x, dtype=float)), dtype=float).reshape(-1)

    def jacobian(self, x: Sequence[float]) -> np.ndarray:
        """``∂F/∂x (x)``, shape ``(k, n)``."""
        x = np.asarray(x, dtype=float)
        return np.asarray(self._jacobian(x), dtype=float).reshape(-1, x.size)


def differentiable_map(what: str, symbolic: Callable[[list[Any]], Sequence[Any]],
                       plain: Callable[[np.ndarray], Sequence[float]], n: int,
                       probe: Sequence[float] | None = None) -> DifferentiableMap:
    """``symbolic`` traced by CasADi (checked against ``plain`` at ``probe``), else central differences of ``plain``.

    Parameters
    ----------
    what : str
        Name for messages (``"flow of mode 'on'"``).
    symbolic : callable
        ``F(list of n scalars) -> sequence``: the user's functions composed, called once with SX symbols.
    plain : callable
        ``F(ndarray (n,)) -> sequence of float``: the same through the system's checked evaluation.
    n : int
    probe : sequence of float or None
        Where the two are compared (default ``0.5, …``).
    """
    point = np.full(n, 0.5) if probe is None else np.asarray(probe, dtype=float).reshape(-1)
    traced = _trace(symbolic, n, point, lambda x: np.asarray(plain(x), dtype=float))
    if isinstance(traced, str):
        return DifferentiableMap(what=what, method="finite differences", reason=f"{what}: {traced}",
                                 _value=lambda x: np.asarray(plain(x), dtype=float),
                                 _jacobian=_central_differences(lambda x: np.asarray(plain(x), dtype=float)))
    f, jac = traced
    return DifferentiableMap(what=what, method="casadi", reason="", _value=lambda x: f(x).full(),
                             _jacobian=lambda x: jac(x).full())


def mode_vector_field(system: HybridSystem, mode: str, *, t: float = 0.0, memory: Mapping[str, float] | None = None,
                      probe: Sequence[float] | None = None) -> VectorField:
    """The flow of ``mode`` as a :class:`VectorField` (CasADi derivatives where the flow traces).

    Parameters
    ----------
    system : HybridSystem
    mode : str
    t : float
        Time at which the flow is frozen [s].
    memory : Mapping or None
        Memory values (default: the automaton's initial memory).
    probe : sequence of float or None, shape (n,)
        Point where the traced expression is compared with the float flow (default: ``0.5, 0.5, ...``,
        away from symmetric special points).

    Raises
    ------
    ParameterError
        Not a system, unknown mode, a probe of the wrong length or not finite.
    """
    if not isinstance(system, HybridSystem):
        raise ParameterError("system", system, "a hybrid.HybridSystem", "build the system with hybrid.HybridSystem")
    if mode not in system.automaton.mode_names:
        raise ParameterError("mode", mode, f"one of the modes {list(system.automaton.mode_names)}",
                             "name a mode of the automaton")
    n = system.dimension
    point = np.full(n, 0.5) if probe is None else np.asarray(probe, dtype=float).reshape(-1)
    if point.size != n or not np.all(np.isfinite(point)):
        raise ParameterError("probe", tuple(np.asarray(probe).tolist()) if probe is not None else None,
                             f"{n} finite values ({', '.join(system.state_names)})", "give one value per state")
    mem = dict(system.automaton.initial_memory() if memory is None else memory)
    flow = system.flows[mode]
    ts = float(t)
    mapped = differentiable_map(
        f"flow of mode {mode!r}", lambda xs: _symbolic_flow(flow, system.state_names, xs, ts, mem),
        lambda x: system.flow(mode, ts, tuple(float(c) for c in x), mem), n, point)
    return VectorField(system=system.name, mode=mode, state_names=system.state_names, method=mapped.method,
                       reason=mapped.reason, flow=mapped)


def _symbolic_flow(flow: Any, names: Sequence[str], xs: list[Any], t: float, memory: Mapping[str, float]) -> Any:
    from hybrid.symbolic import SymbolicVector, to_casadi

    if isinstance(flow, SymbolicVector):
        coords = dict(zip(names, xs))
        return [to_casadi(c, coords, dict(memory), t) for c in flow.components]
    return flow(t, xs, memory)
