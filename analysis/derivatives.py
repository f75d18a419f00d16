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

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from hybrid import HybridSystem
from hybrid.errors import ParameterError

__all__ = ["VectorField", "mode_vector_field", "FD_STEP"]

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
    """

    system: str
    mode: str
    state_names: tuple[str, ...]
    method: str
    reason: str
    _value: Any
    _jacobian: Any

    def value(self, x: Sequence[float]) -> np.ndarray:
        """``f(x)``, shape ``(n,)``."""
        return np.asarray(self._value(np.asarray(x, dtype=float)), dtype=float).reshape(-1)

    def jacobian(self, x: Sequence[float]) -> np.ndarray:
        """``∂f/∂x (x)``, shape ``(n, n)``."""
        n = len(self.state_names)
        return np.asarray(self._jacobian(np.asarray(x, dtype=float)), dtype=float).reshape(n, n)


def _symbolic_expression(system: HybridSystem, mode: str, x: Any, t: float, memory: Mapping[str, float]) -> Any:
    from hybrid.symbolic import SymbolicVector, to_casadi

    flow = system.flows[mode]
    if isinstance(flow, SymbolicVector):
        coords = {name: x[i] for i, name in enumerate(system.state_names)}
        return ca.vertcat(*[to_casadi(c, coords, dict(memory), t) for c in flow.components])
    out = flow(t, [x[i] for i in range(x.shape[0])], memory)
    return ca.vertcat(*[ca.SX(c) if isinstance(c, (int, float)) else c for c in out])


def _traced(system: HybridSystem, mode: str, t: float, memory: Mapping[str, float],
            probe: np.ndarray) -> tuple[ca.Function, ca.Function] | str:
    """The CasADi value and Jacobian functions, or why the flow does not trace."""
    n = system.dimension
    x = ca.SX.sym("x", n)
    try:
        expr = _symbolic_expression(system, mode, x, t, memory)
    except Exception as err:  # a function written for floats only: fall back, and say why
        return f"the flow does not accept CasADi symbols ({type(err).__name__}: {err})"
    if not isinstance(expr, ca.SX) or expr.numel() != n:
        return f"the traced flow has {getattr(expr, 'numel', lambda: '?')()} components for {n} states"
    value = ca.Function("f", [x], [expr])
    if ca.symvar(expr) and any(str(s) not in {str(x[i]) for i in range(n)} for s in ca.symvar(expr)):
        return "the traced flow depends on symbols other than the state"
    traced = np.asarray(value(probe).full(), dtype=float).reshape(-1)
    plain = np.asarray(system.flow(mode, t, tuple(probe), memory), dtype=float)
    if not np.allclose(traced, plain, rtol=1e-12, atol=1e-12 * (1.0 + np.abs(plain).max())):
        return f"the traced flow {traced.tolist()} differs from the flow {plain.tolist()} at x = {probe.tolist()}"
    return value, ca.Function("J", [x], [ca.jacobian(expr, x)])


def _finite_differences(system: HybridSystem, mode: str, t: float, memory: Mapping[str, float]) -> tuple[Any, Any]:
    def value(x: np.ndarray) -> np.ndarray:
        return np.asarray(system.flow(mode, t, tuple(float(c) for c in x), memory), dtype=float)

    def jacobian(x: np.ndarray) -> np.ndarray:
        cols = []
        for i in range(x.size):
            h = FD_STEP * max(1.0, abs(x[i]))
            e = np.zeros(x.size)
            e[i] = h
            cols.append((value(x + e) - value(x - e)) / (2.0 * h))
        return np.column_stack(cols)

    return value, jacobian


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
    traced = _traced(system, mode, float(t), mem, point)
    if isinstance(traced, str):
        value, jacobian = _finite_differences(system, mode, float(t), mem)
        method, reason = "finite differences", traced
    else:
        f, jac = traced
        value, jacobian = (lambda x, f=f: f(x).full()), (lambda x, j=jac: j(x).full())
        method, reason = "casadi", ""
    return VectorField(system=system.name, mode=mode, state_names=system.state_names, method=method, reason=reason,
                       _value=value, _jacobian=jacobian)
