"""Equilibria of the modes of a hybrid system, checked against the mode they belong to.

An equilibrium ``x*`` of a mode's flow (``f_q(x*) = 0``) is only a steady state of the *hybrid*
system when the mode can stay there: ``x*`` must satisfy the mode's invariant and no outgoing guard
may force a jump there.  A thermostat's ``off`` mode cools towards 10 °C, but its invariant is
``T >= 19.5``: 10 °C is a **virtual equilibrium**, outside the mode; the system never rests there,
it switches, and its steady state is a limit cycle (:mod:`analysis.periodic`).  Calling that mode
"exponentially stable" from its eigenvalues alone would be wrong; :func:`mode_equilibrium` says
which of the three it is:

* ``"equilibrium"``: inside the invariant, no outgoing guard enabled (the linearisation speaks for
  the hybrid system near ``x*``);
* ``"virtual"``: outside the mode's invariant (the linearisation describes a point never reached in
  this mode);
* ``"switching"``: inside the invariant but an outgoing guard holds there strictly (the system
  jumps away before it settles).

A point on the boundary of the invariant (within ``tol``, relative) counts as inside: a common
equilibrium of modes whose regions meet there, as the origin of a switched linear system.

The equilibrium is found by Newton's method on ``f_q`` with the Jacobian of
:func:`analysis.derivatives.mode_vector_field` (CasADi through the user's own flow; one step for an
affine flow); the linearisation is :func:`analysis.linearise.eigen_modes` of that Jacobian.

Examples
--------
>>> from hybrid.examples import thermostat
>>> eq = mode_equilibrium(thermostat().system, "off", guess=(20.0,))
>>> eq.kind, [round(c, 9) for c in eq.point]
('virtual', [10.0])
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid import HybridSystem
from hybrid.errors import ParameterError
from hybrid.jsonable import to_jsonable
from hybrid.system import state_vector

from analysis.derivatives import mode_vector_field
from analysis.eigen import EigenMode, eigen_modes

__all__ = ["ModeEquilibrium", "mode_equilibrium", "mode_equilibria", "EQUILIBRIUM_KINDS"]

EQUILIBRIUM_KINDS = ("equilibrium", "virtual", "switching", "none")
"""``none``: Newton found no zero of the flow from the guess (a clock, a drift)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ModeEquilibrium:
    """An equilibrium of one mode's flow and whether it belongs to the mode.

    Attributes
    ----------
    system, mode : str
    kind : str
        One of :data:`EQUILIBRIUM_KINDS`.
    point : tuple of float or None
        ``x*`` (``None`` when ``kind == "none"``).
    residual_norm : float
        ``‖f_q(x*)‖∞`` (or at the last Newton iterate).
    invariant_value : float
        The invariant's value at ``x*`` (``>= 0`` inside; ``inf`` without an invariant).
    enabled_transitions : tuple of str
        Outgoing transitions whose guard holds at ``x*``.
    jacobian : ndarray or None, shape (n, n)
    modes : tuple of EigenMode
    hurwitz : bool
        Every eigenvalue in the open left half-plane (by more than ``tol``).
    derivatives : str
        ``"casadi"`` or ``"finite differences"`` (:class:`analysis.derivatives.VectorField`).
    finding : str
    """

    system: str
    mode: str
    kind: str
    point: tuple[float, ...] | None
    residual_norm: float
    invariant_value: float
    enabled_transitions: tuple[str, ...]
    jacobian: np.ndarray | None
    modes: tuple[EigenMode, ...]
    hurwitz: bool
    derivatives: str
    finding: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (eigenvalues as ``[re, im]`` pairs)."""
        data = {name: getattr(self, name) for name in self.__slots__ if name != "modes"}
        data["eigenvalues"] = [[m.real, m.imag] for m in self.modes]
        return to_jsonable(data)


def _newton(field: Any, x0: np.ndarray, tol: float, max_iterations: int) -> tuple[np.ndarray, float, bool]:
    x = x0.copy()
    for _ in range(max_iterations):
        f = field.value(x)
        res = float(np.abs(f).max())
        if res <= tol:
            return x, res, True
        step, *_ = np.linalg.lstsq(field.jacobian(x), -f, rcond=None)
        if not np.all(np.isfinite(step)) or float(np.abs(step).max()) == 0.0:
            return x, res, False
        x = x + step
    f = field.value(x)
    res = float(np.abs(f).max())
    return x, res, res <= tol


def _point(name: str, value: Sequence[float], n: int, states: Sequence[str]) -> np.ndarray:
    return state_vector(name, value, states)


def _classify(system: HybridSystem, mode: str, x: np.ndarray, memory: Mapping[str, float],
              tol: float) -> tuple[str, float, tuple[str, ...]]:
    """Inside when ``inv >= −tol·(1 + ‖x‖∞)``: Newton's round-off must not push a point of the boundary out."""
    v = system.signals(0.0, tuple(x), mode)
    margin = tol * (1.0 + float(np.abs(x).max(initial=0.0)))
    inv = system.invariant(mode, 0.0, tuple(x), v, memory)
    enabled = tuple(t.name for t in system.automaton.outgoing(mode)
                    if system.guard(t, 0.0, tuple(x), v, memory) > margin)
    if inv < -margin:
        return "virtual", inv, enabled
    return ("switching" if enabled else "equilibrium"), inv, enabled


def _finding(kind: str, mode: str, point: np.ndarray | None, inv: float, enabled: Sequence[str], hurwitz: bool,
             text: str) -> str:
    where = "" if point is None else f" at x* = {[float(f'{c:.6g}') for c in point]}"
    stable = "Hurwitz" if hurwitz else "not Hurwitz"
    if kind == "virtual":
        return (f"virtual equilibrium, outside the mode{where}: the invariant of {mode!r} ({text or 'inv'}) is "
                f"{inv:.4g} < 0 there; the linearisation ({stable}) says nothing about the hybrid system, which "
                "leaves the mode before reaching it")
    if kind == "switching":
        return (f"equilibrium{where} on a switching surface: transition(s) {list(enabled)} are enabled there; "
                f"the linearisation ({stable}) holds only until the jump")
    if kind == "none":
        return f"no equilibrium of {mode!r} found from the guess (the flow does not vanish nearby)"
    return f"equilibrium of the mode{where}, inside its invariant: {stable}" + (
        ", exponentially stable while the mode is kept" if hurwitz else "")


def mode_equilibrium(
    system: HybridSystem,
    mode: str,
    *,
    guess: Sequence[float] | None = None,
    memory: Mapping[str, float] | None = None,
    tol: float = 1e-9,
    max_iterations: int = 50,
) -> ModeEquilibrium:
    """The equilibrium of ``mode`` nearest ``guess`` by Newton, linearised and classified (module docstring).

    Parameters
    ----------
    system : HybridSystem
    mode : str
    guess : sequence of float or None, shape (n,)
        Start of Newton's method (default: the origin).
    memory : Mapping or None
        Memory values (default: the automaton's initial memory).
    tol : float
        Largest acceptable ``‖f_q(x*)‖∞``.
    max_iterations : int

    Raises
    ------
    ParameterError
        Unknown mode, a guess of the wrong length or not finite, a non-positive ``tol``.
    """
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol > 0):
        raise ParameterError("tol", tol, "a positive number", "give e.g. tol=1e-9")
    mem = dict(system.automaton.initial_memory() if memory is None else memory)
    n = system.dimension
    x0 = np.zeros(n) if guess is None else _point("guess", guess, n, system.state_names)
    field = mode_vector_field(system, mode, memory=mem, probe=x0 + 0.5)  # near the guess, off its special values
    x, residual, converged = _newton(field, x0, tol, max_iterations)
    text = system.automaton.mode(mode).invariant_text
    if not converged:
        return ModeEquilibrium(system=system.name, mode=mode, kind="none", point=None, residual_norm=residual,
                               invariant_value=math.nan, enabled_transitions=(), jacobian=None, modes=(),
                               hurwitz=False, derivatives=field.method,
                               finding=_finding("none", mode, None, math.nan, (), False, text))
    kind, inv, enabled = _classify(system, mode, x, mem, tol)
    a = field.jacobian(x)
    a.setflags(write=False)
    modes = eigen_modes(a)
    hurwitz = bool(max(m.real for m in modes) < -tol)
    return ModeEquilibrium(
        system=system.name, mode=mode, kind=kind, point=tuple(float(c) for c in x), residual_norm=residual,
        invariant_value=float(inv), enabled_transitions=enabled, jacobian=a, modes=modes, hurwitz=hurwitz,
        derivatives=field.method, finding=_finding(kind, mode, x, inv, enabled, hurwitz, text),
    )


def mode_equilibria(system: HybridSystem, *, guess: Sequence[float] | None = None,
                    memory: Mapping[str, float] | None = None) -> tuple[ModeEquilibrium, ...]:
    """:func:`mode_equilibrium` of every mode, in declaration order, from one guess."""
    if not isinstance(system, HybridSystem):
        raise ParameterError("system", system, "a hybrid.HybridSystem", "build the system with hybrid.HybridSystem")
    return tuple(mode_equilibrium(system, m, guess=guess, memory=memory) for m in system.automaton.mode_names)
