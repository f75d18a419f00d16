"""Periodic orbits of hybrid systems: shooting on a Poincaré section, monodromy with saltation matrices.

**Section and Poincaré map.**  The section is the guard surface ``Σ = {x : g(h(x)) = 0}`` of one
transition ``σ`` (``h`` the system's output, ``g`` the guard), met in ``σ``'s source mode.  The
Poincaré map ``Π`` takes a point ``x⁻ ∈ Σ`` just before the jump, applies ``σ``'s jump map
``x⁺ = r(x⁻)`` (and its memory reset), lets the executor (:func:`hybrid.simulate_continuous`, exact
event location, ``rtol = atol = 1e-12``) flow and jump until ``σ`` fires again, and returns the
new ``x⁻`` with the return time ``τ(x⁻)``.  A periodic orbit is a fixed point ``x* = Π(x*)``; its
period is ``T = τ(x*)``.  Only autonomous systems are treated (flows and output that do not read
the time ``t``; a time-driven switching is modelled with a clock state).

**Flow.**  Along a flow segment of mode ``q`` the state-transition matrix ``Φ(t) = ∂x(t)/∂x(t₀)``
solves the variational equation ``Φ̇ = ∂f_q/∂x (x(t)) Φ``, ``Φ(t₀) = I``, integrated beside the
state (scipy's DOP853 at ``rtol = atol = 1e-12``) from the segment's first state.

**Saltation.**  A jump is not differentiable in time: a neighbour ``x⁻ + δ`` of the pre-jump point
reaches the guard at a shifted time ``τ``.  To first order ``∇gᵀ(δ + f⁻τ) = 0``, so
``τ = −∇gᵀδ / ∇gᵀf⁻``; the neighbour jumps from ``x⁻ + δ + f⁻τ`` and then flows back over ``−τ``
in the new mode, so ``δ⁺ = R (δ + f⁻τ) − f⁺τ``, that is

    δ⁺ = S δ,      S = R + (f⁺ − R f⁻) ∇gᵀ / (∇gᵀ f⁻),

with ``R = ∂r/∂x (x⁻)``, ``f⁻ = f_q(x⁻)``, ``f⁺ = f_q'(r(x⁻))`` and ``∇g = (∂g/∂v ∂h/∂x)ᵀ (x⁻)``: the
**saltation matrix** of the discontinuous-systems theory of Aizerman & Gantmacher (1958), used for
the periodic orbits of power systems by Hiskens & Pai (2000) ("Trajectory sensitivity analysis of
hybrid systems").  ``S f⁻ = f⁺``: the flow direction is carried across the jump.  It needs a
transversal crossing, ``∇gᵀf⁻ ≠ 0``.  Several jumps at one instant (the later guards already true
at the landing point) act as one jump with ``R`` the product of their Jacobians, the first
jump's guard, the first source's ``f⁻`` and the last target's ``f⁺``.

**Monodromy and Floquet multipliers.**  Over one revolution from ``x*`` the jumps and flows give

    M = Φ_k S_{k−1} Φ_{k−1} ⋯ S_1 Φ_1 S_σ      (n × n),

the derivative of the fixed-time map ``x ↦ x(T)`` at ``x*``.  Its eigenvalues are the **Floquet
multipliers** of the orbit.  One of them is the *trivial* multiplier 1 with eigenvector ``f⁻(x*)``
(a shift along the orbit is a shift in time, ``M f⁻ = f⁻``); it is identified by that eigenvector.
The others, the *nontrivial* multipliers, are the eigenvalues of the Poincaré map's Jacobian

    DΠ = P M,      P = I − f⁻ ∇gᵀ / (∇gᵀ f⁻)

(the end point slides along the flow back onto ``Σ``), which maps into the tangent plane of
``Σ``.  In an orthonormal basis ``V`` (``n × (n−1)``) of that plane, ``Vᵀ DΠ V`` is the Jacobian of
``Π`` in the ``n − 1`` section coordinates; its eigenvalues are the nontrivial multipliers (the
reported ones).  The orbit is **orbitally asymptotically stable** when every one of them lies
inside the unit circle (``|μ| < 1 − margin``), **unstable** when one lies outside
(``|μ| > 1 + margin``) and **undecided** otherwise.

**Shooting.**  Newton's method on ``Π(x) − x = 0`` is run on the full state with the section as a
constraint: the step ``δ`` solves ``[DΠ − I; ∇gᵀ] δ = [x − Π(x); −g(x)]`` in the least-squares
sense (the system is consistent near a hyperbolic orbit: ``DΠ − I`` is invertible on the tangent
plane exactly when no nontrivial multiplier is 1), and the new iterate is put back on ``Σ`` by
Newton steps along ``∇g``.  This is Newton on the ``n − 1`` section coordinates without having to
choose them.  Convergence: ``‖Π(x) − x‖∞ <= tol · (1 + ‖x‖∞)``.

**Derivatives.**  ``∂f/∂x``, ``∇g`` and ``R`` come from CasADi by tracing the user's own flow,
output, guard and jump functions with ``SX`` symbols (symbolic models of :mod:`hybrid.symbolic`
are converted by :func:`hybrid.symbolic.to_casadi`); where a function does not trace, central
finite differences are used and the result says so (``derivatives``, ``derivative_notes``).
:func:`finite_difference_monodromy` is an independent check that uses only the executor: the
fixed-time map over one period, differenced at a point in the middle of a flow segment (the
monodromy there is similar to ``M``, so the eigenvalues agree).

Examples
--------
>>> from hybrid.examples import thermostat
>>> orbit = periodic_orbit(thermostat().system, section="heat_on", initial_state=(19.0,))
>>> round(orbit.period, 9), orbit.jumps, orbit.verdict
(4.013413909, ('heat_off', 'heat_on'), 'orbitally stable')
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from hybrid import HybridSystem
from hybrid.continuous import FlowSegment, HybridTrajectory, simulate_continuous
from hybrid.diagnostics import estimate_zeno
from hybrid.errors import DivergenceError, ExecutionError, ParameterError, ZenoError, format_named_state, format_time
from hybrid.jsonable import to_jsonable
from hybrid.model import Conjunction, Transition
from hybrid.system import state_vector

from analysis.derivatives import DifferentiableMap, VectorField, differentiable_map, mode_vector_field

__all__ = [
    "STABILITY_MARGIN",
    "MACHINE_EVENT_TOL",
    "PeriodicOrbitError",
    "ShootingError",
    "PoincareReturn",
    "PeriodicOrbit",
    "saltation_matrix",
    "poincare_map",
    "periodic_orbit",
    "finite_difference_monodromy",
]

STABILITY_MARGIN = 1e-6
"""Default margin: a nontrivial multiplier within this of the unit circle leaves the verdict undecided."""

SAMPLES_PER_FLOW = 33
"""Evenly spaced points per flow segment in :attr:`PeriodicOrbit.times` (besides the solver's step points)."""

MACHINE_EVENT_TOL = sys.float_info.min
"""The ``event_tol`` given to the executor by default: it clamps it to 4 ulp of the event time."""

_MEMORY_RTOL = 1e-12


class PeriodicOrbitError(ParameterError):
    """Bad input to a periodic-orbit search, or a section the trajectory does not come back to.

    The message is ``"<parameter> = <value>: expected <expected>; fix: <fix>"``
    (:class:`hybrid.errors.ParameterError`).
    """


class ShootingError(ExecutionError):
    """Newton's method on the Poincaré map did not converge.

    Attributes
    ----------
    iterations : int
        Revolutions computed.
    residual : float
        ``‖Π(x) − x‖∞`` at the last iterate.
    """

    def __init__(self, message: str, iterations: int, residual: float) -> None:
        super().__init__(message)
        self.iterations = iterations
        self.residual = residual

    def __reduce__(self):  # picklable across processes, with its attributes
        return (type(self), (str(self), self.iterations, self.residual))


@dataclass(frozen=True, kw_only=True, slots=True)
class _Options:
    rtol: float
    atol: float
    event_tol: float
    max_period: float
    max_jumps: int
    divergence_bound: float


@dataclass(frozen=True, kw_only=True, slots=True)
class PoincareReturn:
    """One application of the Poincaré map (:func:`poincare_map`).

    Attributes
    ----------
    state : tuple of float, shape (n,)
        ``Π(x)``: the state just before the section's transition fires again.
    time : float
        Return time ``τ(x)`` [s].
    jumps : tuple of str
        Transitions taken, the section's first (at ``t = 0``) and last.
    jump_times : tuple of float
        Their times [s].
    memory : tuple of (str, float)
        Memory just before the return.
    """

    state: tuple[float, ...]
    time: float
    jumps: tuple[str, ...]
    jump_times: tuple[float, ...]
    memory: tuple[tuple[str, float], ...]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return to_jsonable(self)


@dataclass(frozen=True, kw_only=True, slots=True)
class PeriodicOrbit:
    """A periodic orbit through a guard section (module docstring).

    Attributes
    ----------
    system, section, mode : str
        The system, the transition whose guard is the section, and its source mode.
    fixed_point : tuple of float, shape (n,)
        ``x*`` on the section, just before the section's jump.
    period : float
        Return time ``T`` [s].
    jumps : tuple of str
        Transitions taken in one revolution; the section's is the last.
    jump_times : tuple of float
        Their times from the revolution's start (the section's jump at ``t = 0``) [s]; the last is ``T``.
    monodromy : ndarray, shape (n, n)
        ``M`` at ``x*`` (read-only).
    multipliers : tuple of complex
        Eigenvalues of ``M`` (all Floquet multipliers), by decreasing modulus.
    trivial_multiplier : complex
        The one along the flow (eigenvector ``f⁻(x*)``); 1 up to the integration error.
    nontrivial_multipliers : tuple of complex, length n − 1
        Eigenvalues of the Poincaré map's Jacobian in section coordinates, by decreasing modulus.
    poincare_jacobian : ndarray, shape (n − 1, n − 1)
        ``Vᵀ DΠ V`` in the orthonormal basis ``section_basis`` of the section's tangent plane.
    section_basis : ndarray, shape (n, n − 1)
    verdict : str
        ``"orbitally stable"``, ``"unstable"`` or ``"undecided"`` (module docstring).
    margin : float
        The margin of the verdict.
    iterations : int
        Revolutions computed by the shooting.
    residual : float
        ``‖Π(x*) − x*‖∞``.
    derivatives : str
        ``"casadi"`` when every flow, guard, output and jump map traced, else ``"finite differences"``.
    derivative_notes : tuple of str
        Why a function did not trace (empty for ``"casadi"``).
    memory : tuple of (str, float)
        Memory at the section (it repeats every revolution).
    first_flow_s : float
        Duration of the first flow after the section's jump [s].
    flow_intervals : tuple of (str, float, float)
        ``(mode, t_start, t_end)`` of every flow of positive length in one revolution [s].
    rtol, atol, event_tol : float
        The executor's tolerances used (also by :func:`finite_difference_monodromy`); ``event_tol`` is
        :data:`MACHINE_EVENT_TOL` unless one was given.
    times : ndarray, shape (k,)
        One revolution sampled for drawing [s], from 0 to ``T``; a jump appears as two rows at one time.
    states : ndarray, shape (k, n)
    modes : tuple of str, length k
    state_names : tuple of str
    """

    system: str
    section: str
    mode: str
    fixed_point: tuple[float, ...]
    period: float
    jumps: tuple[str, ...]
    jump_times: tuple[float, ...]
    monodromy: np.ndarray
    multipliers: tuple[complex, ...]
    trivial_multiplier: complex
    nontrivial_multipliers: tuple[complex, ...]
    poincare_jacobian: np.ndarray
    section_basis: np.ndarray
    verdict: str
    margin: float
    iterations: int
    residual: float
    derivatives: str
    derivative_notes: tuple[str, ...]
    memory: tuple[tuple[str, float], ...]
    first_flow_s: float
    flow_intervals: tuple[tuple[str, float, float], ...]
    rtol: float
    atol: float
    event_tol: float
    times: np.ndarray = field(metadata={"json": False})
    states: np.ndarray = field(metadata={"json": False})
    modes: tuple[str, ...] = field(metadata={"json": False})
    state_names: tuple[str, ...] = ()

    @property
    def finding(self) -> str:
        """One sentence: the period, the multipliers and the verdict."""
        mods = ", ".join(f"{abs(m):.4g}" for m in self.nontrivial_multipliers) or "none (one state)"
        return (f"periodic orbit through {self.section!r}: period {self.period:.10g} s, {len(self.jumps)} jump(s) per "
                f"revolution, nontrivial Floquet multipliers of modulus {mods}: {self.verdict}")

    def extent(self, name: str) -> tuple[float, float]:
        """``(min, max)`` of the state ``name`` over the sampled revolution (e.g. a ripple is ``max − min``)."""
        if name not in self.state_names:
            raise PeriodicOrbitError("name", name, f"one of the states {list(self.state_names)}", "name a state")
        column = np.asarray(self.states)[:, self.state_names.index(name)]
        return float(column.min()), float(column.max())

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (multipliers as ``[re, im]``; the revolution's samples left out)."""
        data = to_jsonable(self, nonfinite="string")
        data["finding"] = self.finding
        return data


# ---------------------------------------------------------------------- saltation
def saltation_matrix(reset_jacobian: np.ndarray, f_before: np.ndarray, f_after: np.ndarray,
                     guard_gradient: np.ndarray) -> np.ndarray:
    """``S = R + (f⁺ − R f⁻) ∇gᵀ / (∇gᵀ f⁻)`` (derived in the module docstring).

    Parameters
    ----------
    reset_jacobian : ndarray, shape (n, n)
        ``R = ∂r/∂x`` at the pre-jump state.
    f_before, f_after : ndarray, shape (n,)
        Flow of the source mode before and of the target mode after the jump.
    guard_gradient : ndarray, shape (n,)
        Gradient of the guard with respect to the state (through the output).

    Returns
    -------
    ndarray, shape (n, n)

    Raises
    ------
    ArithmeticError
        ``∇gᵀ f⁻ = 0`` (or not finite): the flow grazes the guard, the crossing is not transversal.
    """
    r = np.asarray(reset_jacobian, dtype=float)
    f_minus = np.asarray(f_before, dtype=float).reshape(-1)
    grad = np.asarray(guard_gradient, dtype=float).reshape(-1)
    rate = float(grad @ f_minus)
    if rate == 0.0 or not math.isfinite(rate):
        raise ArithmeticError(f"the flow is tangent to the guard (∇g·f = {rate!r}): the crossing is not transversal")
    return r + np.outer(np.asarray(f_after, dtype=float).reshape(-1) - r @ f_minus, grad) / rate


# ---------------------------------------------------------------------- derivatives of the user's functions
def _memory_key(memory: Mapping[str, float]) -> tuple[tuple[str, float], ...]:
    return tuple(sorted((k, float(v)) for k, v in memory.items()))


def _symbolic_output(system: HybridSystem, xs: list[Any]) -> list[Any]:
    from hybrid.symbolic import SymbolicVector, to_casadi

    output = system.output
    if output is None:
        return xs
    if isinstance(output, SymbolicVector):
        coords = dict(zip(system.state_names, xs))
        return [to_casadi(c, coords, {}, 0.0) for c in output.components]
    return list(output(0.0, xs))


def _symbolic_level(function: Any, v: list[Any], names: Sequence[str], memory: Mapping[str, float]) -> Any:
    """A guard's value on CasADi symbols: symbolic expressions converted, conjunctions as ``fmin``, else called."""
    import casadi as ca

    from hybrid.symbolic import Condition, Expr, level_form, to_casadi

    if isinstance(function, Conjunction):
        terms = [_symbolic_level(term, v, names, memory) for term in function.terms]
        out = terms[0]
        for term in terms[1:]:
            out = ca.fmin(out, term)
        return out
    if isinstance(function, (Expr, Condition)):
        return to_casadi(level_form(function), dict(zip(names, v)), dict(memory))
    return function(v, memory)


class _Derivatives:
    """Traced (or finite-difference) flows, guards and jump maps of one system, cached per mode and memory."""

    def __init__(self, system: HybridSystem) -> None:
        self.system = system
        self._cache: dict[tuple[Any, ...], Any] = {}
        self.methods: set[str] = set()
        self.notes: set[str] = set()

    def _note(self, item: VectorField | DifferentiableMap) -> None:
        self.methods.add(item.method)
        if item.reason:
            self.notes.add(item.reason)

    def field(self, mode: str, memory: Mapping[str, float], probe: np.ndarray) -> VectorField:
        key = ("flow", mode, _memory_key(memory))
        if key not in self._cache:
            self._cache[key] = mode_vector_field(self.system, mode, memory=dict(memory), probe=probe)
            self._note(self._cache[key])
        return self._cache[key]

    def guard(self, transition: Transition, memory: Mapping[str, float], probe: np.ndarray) -> DifferentiableMap:
        key = ("guard", transition.name, _memory_key(memory))
        if key not in self._cache:
            system, mem = self.system, dict(memory)
            names = system.automaton.variables

            def symbolic(xs: list[Any]) -> list[Any]:
                return [_symbolic_level(transition.guard, _symbolic_output(system, xs), names, mem)]

            def plain(x: np.ndarray) -> list[float]:
                xt = tuple(float(c) for c in x)
                return [system.guard(transition, 0.0, xt, system.signals(0.0, xt, transition.source), mem)]

            self._cache[key] = differentiable_map(f"guard of transition {transition.name!r}", symbolic, plain,
                                                  system.dimension, probe)
            self._note(self._cache[key])
        return self._cache[key]

    def reset(self, name: str, memory: Mapping[str, float], probe: np.ndarray) -> DifferentiableMap:
        key = ("jump", name, _memory_key(memory))
        if key not in self._cache:
            from hybrid.symbolic import SymbolicVector, to_casadi

            system, mem, jump = self.system, dict(memory), self.system.jumps.get(name)
            if jump is None:
                symbolic: Any = lambda xs: xs  # noqa: E731 - identity: no jump map
            elif isinstance(jump, SymbolicVector):
                symbolic = lambda xs: [to_casadi(c, dict(zip(system.state_names, xs)), mem)  # noqa: E731
                                       for c in jump.components]
            else:
                symbolic = lambda xs: jump(xs, mem)  # noqa: E731
            self._cache[key] = differentiable_map(
                f"jump map of transition {name!r}", symbolic,
                lambda x: system.jump(name, 0.0, tuple(float(c) for c in x), mem), system.dimension, probe)
            self._note(self._cache[key])
        return self._cache[key]

    @property
    def method(self) -> str:
        return "casadi" if self.methods <= {"casadi"} else "finite differences"


# ---------------------------------------------------------------------- one revolution
@dataclass(frozen=True, slots=True)
class _Jump:
    transition: Transition
    before: np.ndarray
    after: np.ndarray
    memory_before: dict[str, float]
    memory_after: dict[str, float]


@dataclass(slots=True)
class _Instant:
    time: float
    jumps: list[_Jump]


@dataclass(frozen=True, slots=True)
class _Leg:
    """Flows (FlowSegment) and instants (_Instant) in order, up to the section's next firing."""

    pieces: tuple[Any, ...]
    end_state: np.ndarray
    end_time: float
    end_memory: dict[str, float]
    jumps: tuple[str, ...]
    jump_times: tuple[float, ...]


class _Shooter:
    """The system, the section and the options of one search; runs legs and revolutions (private)."""

    def __init__(self, system: HybridSystem, section: Transition, opts: _Options) -> None:
        self.system, self.section, self.opts = system, section, opts
        self.transitions = {t.name: t for t in system.automaton.transitions}
        self.derivatives = _Derivatives(system)

    def simulate(self, x: Sequence[float], mode: str, memory: Mapping[str, float], t0: float, duration: float,
                 max_jumps: int) -> HybridTrajectory:
        """The executor with this search's tolerances and the divergence stop."""
        bound = self.opts.divergence_bound
        return simulate_continuous(
            self.system, tuple(float(c) for c in x), t0=t0, duration=duration, initial_mode=mode,
            initial_memory=dict(memory), rtol=self.opts.rtol, atol=self.opts.atol, event_tol=self.opts.event_tol,
            max_jumps=max_jumps, stops={"diverged": lambda t, xx, q, m: max(abs(c) for c in xx) - bound})

    def section_jump(self, x: np.ndarray, memory: Mapping[str, float]) -> _Jump:
        """The section's jump from ``x`` (its jump map and memory reset), as the revolution's first."""
        xt = tuple(float(c) for c in x)
        after = np.asarray(self.system.jump(self.section.name, 0.0, xt, memory), dtype=float)
        v = self.system.signals(0.0, xt, self.section.source)
        new_memory = self.system.reset(self.section, 0.0, xt, v, memory)
        return _Jump(self.section, np.array(x, dtype=float), after, dict(memory), dict(new_memory))

    def leg(self, x: np.ndarray, mode: str, memory: Mapping[str, float], first: _Jump | None) -> _Leg:
        """Flow from ``(x, mode)`` at ``t = 0`` (after ``first``, when given) until the section's transition fires.

        The executor is chained one jump at a time, so that nothing past the return is computed.
        """
        pieces: list[Any] = [_Instant(0.0, [first])] if first is not None else []
        names, times = ([first.transition.name], [0.0]) if first is not None else ([], [])
        t, state, q, mem = 0.0, np.asarray(x, dtype=float), mode, dict(memory)
        while True:
            if t >= self.opts.max_period:
                raise self._not_returned(x, mode, q, state)
            run = self.simulate(state, q, mem, t, self.opts.max_period - t, 1)
            for item in _ordered(run):
                if isinstance(item, FlowSegment):
                    if item.t_end > item.t_start:
                        pieces.append(item)
                    mem = dict(item.memory)
                    continue
                landing = bool(pieces) and isinstance(pieces[-1], _Instant) and pieces[-1].time == item.time
                if item.transition == self.section.name and (first is not None or not landing):
                    if first is not None:
                        self._check_return(item, pieces, first)
                    return _Leg(tuple(pieces), np.asarray(item.state_before, dtype=float), float(item.time), mem,
                                tuple(names + [item.transition]), tuple(times + [float(item.time)]))
                jump = _Jump(self.transitions[item.transition], np.asarray(item.state_before, dtype=float),
                             np.asarray(item.state_after, dtype=float), mem, dict(item.memory))
                if landing:
                    pieces[-1].jumps.append(jump)
                else:
                    pieces.append(_Instant(float(item.time), [jump]))
                names.append(item.transition)
                times.append(float(item.time))
                mem = dict(item.memory)
            self._check_run(run, x, mode, times)
            t, state, q, mem = run.final_time, np.asarray(run.final_state, dtype=float), run.final_mode, \
                dict(run.final_memory)

    def _not_returned(self, x0: np.ndarray, mode0: str, mode: str, state: Sequence[float]) -> PeriodicOrbitError:
        name, names = self.section.name, self.system.state_names
        return PeriodicOrbitError(
            "section", name,
            f"a transition the flow takes again: from x = {format_named_state(x0, names)} in mode {mode0!r} it was "
            f"not taken within max_period = {self.opts.max_period:g} s (it ended in mode {mode!r} at "
            f"x = {format_named_state(state, names)})",
            "choose the guard of a transition the steady state crosses, another initial state, or a larger "
            "max_period")

    def _check_return(self, event: Any, pieces: list[Any], first: _Jump | None) -> None:
        """The section must be reached by flowing: not at time 0 of a revolution, not at a jump's landing point."""
        name = self.section.name
        if first is not None and event.time <= 0.0:
            raise ZenoError(
                f"periodic orbit of {self.system.name!r} through {name!r}: the revolution from "
                f"x = {format_named_state(first.after, self.system.state_names)} takes no time (an instantaneous "
                "cycle of jumps, Zeno), so there is no periodic orbit to analyse; separate the guards (hysteresis)")
        if pieces and isinstance(pieces[-1], _Instant) and pieces[-1].time == event.time:
            raise PeriodicOrbitError(
                "section", name, f"a transition whose guard the flow crosses; {name!r} fired at t = "
                f"{format_time(event.time)} s right after {pieces[-1].jumps[-1].transition.name!r}, at the landing "
                "point of a jump (the Poincaré map is then not defined by a crossing)",
                "choose as section a transition entered by flowing (its guard crossed transversally)")

    def _check_run(self, run: HybridTrajectory, x0: np.ndarray, mode0: str, times: list[float]) -> None:
        """Raise the error that fits a run that ended otherwise than at its one jump."""
        system, name, opts = self.system, self.section.name, self.opts
        start = f"from x = {format_named_state(x0, system.state_names)} in mode {mode0!r}"
        if len(times) > opts.max_jumps:
            zeno = estimate_zeno(times, window=10)
            if zeno is not None and zeno.ratio < 0.95 and zeno.scatter < 0.25:
                raise ZenoError(
                    f"periodic orbit of {system.name!r} through {name!r}: {start} the jumps accumulate (Zeno: "
                    f"intervals shrink by {zeno.ratio:.3g} per jump, towards t ≈ {format_time(zeno.zeno_time)} s) "
                    f"before {name!r} fires again; there is no periodic orbit through this section")
            raise PeriodicOrbitError(
                "max_jumps", opts.max_jumps, f"enough jumps for one revolution back to {name!r}: {start} it took "
                f"{len(times)} jumps by t = {format_time(times[-1])} s without firing {name!r}",
                "raise max_jumps, or choose a section the orbit crosses")
        if run.termination == "jump_limit":
            return
        if run.termination == "end_time":
            raise self._not_returned(x0, mode0, run.final_mode, run.final_state)
        if run.termination in ("stop:diverged", "solver_failure"):
            cause = (f"|x|∞ exceeds divergence_bound = {opts.divergence_bound:g}" if run.termination != "solver_failure"
                     else run.detail)
            raise DivergenceError(run.final_time, run.final_mode,
                                  f"{cause} on the way back to the section {name!r} {start} (no periodic orbit there)",
                                  state=run.final_state, state_names=system.state_names)
        if run.termination == "zeno":
            raise ZenoError(f"periodic orbit of {system.name!r} through {name!r}: {start}: {run.detail}")
        raise ExecutionError(f"periodic orbit of {system.name!r} through {name!r}: {start} the run ended "
                             f"({run.termination}): {run.detail}")


def _ordered(run: HybridTrajectory) -> list[Any]:
    """The run's segments and events in time order (event ``j`` comes after segment ``j − 1``)."""
    keyed = [(2 * s.jump, 0, s) for s in run.segments] + [(2 * e.jump - 1, 1, e) for e in run.events]
    return [item for _, _, item in sorted(keyed, key=lambda k: (k[0], k[1]))]


# ---------------------------------------------------------------------- monodromy
def _variational(field_: VectorField, x0: np.ndarray, duration: float, rtol: float, atol: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """State and ``Φ`` after ``duration`` of ``Φ̇ = ∂f/∂x Φ`` from ``(x0, I)`` (DOP853)."""
    n = x0.size

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        x, phi = z[:n], z[n:].reshape(n, n)
        return np.concatenate([field_.value(x), (field_.jacobian(x) @ phi).reshape(-1)])

    sol = solve_ivp(rhs, (0.0, duration), np.concatenate([x0, np.eye(n).reshape(-1)]), method="DOP853",
                    rtol=rtol, atol=atol)
    if not sol.success:
        raise ExecutionError(f"the variational equation in mode {field_.mode!r} failed: {sol.message}")
    z = sol.y[:, -1]
    return z[:n], z[n:].reshape(n, n)


def _instant_saltation(shooter: _Shooter, instant: _Instant) -> np.ndarray:
    """Saltation of one instant's jumps (one jump, or a chain at one time acting as one)."""
    d, system = shooter.derivatives, shooter.system
    first, last = instant.jumps[0], instant.jumps[-1]
    r = np.eye(system.dimension)
    for jump in instant.jumps:
        r = d.reset(jump.transition.name, jump.memory_before, jump.before).jacobian(jump.before) @ r
    grad = d.guard(first.transition, first.memory_before, first.before).jacobian(first.before).reshape(-1)
    f_before = np.asarray(system.flow(first.transition.source, 0.0, tuple(first.before), first.memory_before))
    f_after = np.asarray(system.flow(last.transition.target, 0.0, tuple(last.after), last.memory_after))
    try:
        return saltation_matrix(r, f_before, f_after, grad)
    except ArithmeticError as err:
        raise PeriodicOrbitError(
            "section" if first.transition is shooter.section else "transition", first.transition.name,
            f"a guard crossed transversally; at x = {format_named_state(first.before, system.state_names)} {err}",
            "choose another section or initial state (a grazing orbit has no saltation matrix)") from None


def _monodromy(shooter: _Shooter, leg: _Leg) -> np.ndarray:
    """``M`` over the leg: the saltations of its instants and the ``Φ`` of its flows, in order."""
    m = np.eye(shooter.system.dimension)
    opts = shooter.opts
    for piece in leg.pieces:
        if isinstance(piece, _Instant):
            m = _instant_saltation(shooter, piece) @ m
            continue
        start = np.asarray(piece.states[0], dtype=float)
        field_ = shooter.derivatives.field(piece.mode, dict(piece.memory), start)
        _, phi = _variational(field_, start, piece.t_end - piece.t_start, opts.rtol, opts.atol)
        m = phi @ m
    return m


def _projector(shooter: _Shooter, x: np.ndarray, memory: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """``P = I − f⁻∇gᵀ/∇gᵀf⁻`` at ``x`` on the section, and ``∇g``."""
    grad = shooter.derivatives.guard(shooter.section, memory, x).jacobian(x).reshape(-1)
    f = np.asarray(shooter.system.flow(shooter.section.source, 0.0, tuple(x), memory), dtype=float)
    rate = float(grad @ f)
    if rate == 0.0 or not math.isfinite(rate):
        raise PeriodicOrbitError(
            "section", shooter.section.name, f"a guard the flow crosses transversally; at x = "
            f"{format_named_state(x, shooter.system.state_names)} the flow is tangent to it (∇g·f = {rate!r})",
            "choose another section or initial state")
    return np.eye(x.size) - np.outer(f, grad) / rate, grad


def _onto_section(guard: DifferentiableMap, x: np.ndarray) -> np.ndarray:
    """Newton along the gradient so that ``g(x) = 0`` (a guess need not lie on the section)."""
    for _ in range(20):
        g = float(guard.value(x)[0])
        grad = guard.jacobian(x).reshape(-1)
        if abs(g) <= 1e-14 * (1.0 + float(np.abs(x).max())) or not np.any(grad):
            break
        x = x - g * grad / float(grad @ grad)
    return x


# ---------------------------------------------------------------------- checks
def _real_option(name: str, value: Any, positive_finite: bool = True) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and value == value and value > 0
    if not ok or (positive_finite and not math.isfinite(value)):
        raise PeriodicOrbitError(name, value, "a positive finite number", f"give e.g. {name}=1e-12" if "tol" in name
                                 else f"give a positive {name}")
    return float(value)


def _int_option(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise PeriodicOrbitError(name, value, "a positive integer", f"give e.g. {name}=30")
    return value


def _options(rtol: Any, atol: Any, event_tol: Any, max_period: Any, max_jumps: Any, divergence_bound: Any) -> _Options:
    return _Options(rtol=_real_option("rtol", rtol), atol=_real_option("atol", atol),
                    event_tol=MACHINE_EVENT_TOL if event_tol is None else _real_option("event_tol", event_tol),
                    max_period=_real_option("max_period", max_period),
                    max_jumps=_int_option("max_jumps", max_jumps),
                    divergence_bound=_real_option("divergence_bound", divergence_bound))


def _section(system: Any, section: Any) -> Transition:
    if not isinstance(system, HybridSystem):
        raise PeriodicOrbitError("system", system, "a hybrid.HybridSystem", "build the system with hybrid.HybridSystem")
    names = [t.name for t in system.automaton.transitions]
    if section not in names:
        raise PeriodicOrbitError("section", section, f"one of the transitions {names}",
                                 "name the transition whose guard is the Poincaré section")
    return next(t for t in system.automaton.transitions if t.name == section)


def _state(system: HybridSystem, name: str, value: Any) -> np.ndarray:
    return state_vector(name, value, system.state_names, error=PeriodicOrbitError)


def _memory(system: HybridSystem, memory: Mapping[str, float] | None) -> dict[str, float]:
    out = system.automaton.initial_memory()
    if memory:
        unknown = sorted(set(memory) - set(out))
        if unknown:
            raise PeriodicOrbitError("memory", dict(memory), f"values of the memory variables {sorted(out)}",
                                     f"drop {unknown}")
        out.update({k: float(v) for k, v in memory.items()})
    return out


def _same_memory(a: Mapping[str, float], b: Mapping[str, float]) -> bool:
    return set(a) == set(b) and all(abs(a[k] - b[k]) <= _MEMORY_RTOL * (1.0 + abs(a[k])) for k in a)


def _check_autonomous(shooter: _Shooter, leg: _Leg) -> None:
    """Refuse flows or an output that read the time: the Poincaré map would then depend on the start time."""
    system = shooter.system
    for piece in leg.pieces:
        if not isinstance(piece, FlowSegment):
            continue
        x = tuple(float(c) for c in piece.states[0])
        memory = dict(piece.memory)
        later = piece.t_start + 0.37 * leg.end_time + 1.3
        same = np.allclose(system.flow(piece.mode, piece.t_start, x, memory), system.flow(piece.mode, later, x, memory),
                           rtol=1e-12, atol=1e-300)
        same = same and np.allclose(system.signals(piece.t_start, x), system.signals(later, x), rtol=1e-12, atol=1e-300)
        if not same:
            raise PeriodicOrbitError(
                "system", system.name, f"an autonomous system: the flow of mode {piece.mode!r} or the output reads "
                "the time t, so the return map depends on when the revolution starts",
                "make the time dependence a state (a clock with flow 1, reset by a transition at the period's end)")


# ---------------------------------------------------------------------- public functions
def poincare_map(
    system: HybridSystem,
    *,
    section: str,
    state: Sequence[float],
    memory: Mapping[str, float] | None = None,
    max_period: float = 1e4,
    max_jumps: int = 1000,
    rtol: float = 1e-12,
    atol: float = 1e-12,
    event_tol: float | None = None,
    divergence_bound: float = 1e9,
) -> PoincareReturn:
    """``Π(x)``: from ``state`` just before ``section`` fires, jump, then flow until it fires again.

    Parameters
    ----------
    system : HybridSystem
    section : str
        The transition whose guard is the section.
    state : sequence of float, shape (n,)
        The point ``x⁻`` (used as given: it is not projected onto the guard).
    memory : Mapping or None
        Memory just before the jump (default: the initial memory).
    max_period, max_jumps, rtol, atol, event_tol, divergence_bound
        As for :func:`periodic_orbit`.

    Returns
    -------
    PoincareReturn

    Raises
    ------
    PeriodicOrbitError, ZenoError, hybrid.errors.DivergenceError
        As :func:`periodic_orbit`.
    """
    transition = _section(system, section)
    x = _state(system, "state", state)
    opts = _options(rtol, atol, event_tol, max_period, max_jumps, divergence_bound)
    shooter = _Shooter(system, transition, opts)
    first = shooter.section_jump(x, _memory(system, memory))
    leg = shooter.leg(first.after, transition.target, first.memory_after, first)
    return PoincareReturn(state=tuple(leg.end_state.tolist()), time=leg.end_time, jumps=leg.jumps,
                          jump_times=leg.jump_times, memory=_memory_key(leg.end_memory))


def periodic_orbit(
    system: HybridSystem,
    *,
    section: str,
    initial_state: Sequence[float],
    initial_mode: str | None = None,
    memory: Mapping[str, float] | None = None,
    tol: float = 1e-11,
    max_iterations: int = 30,
    max_period: float = 1e4,
    max_jumps: int = 1000,
    rtol: float = 1e-12,
    atol: float = 1e-12,
    event_tol: float | None = None,
    divergence_bound: float = 1e9,
    margin: float = STABILITY_MARGIN,
) -> PeriodicOrbit:
    """The periodic orbit through the guard of ``section`` nearest ``initial_state`` (module docstring).

    Parameters
    ----------
    system : HybridSystem
        An autonomous system (flows and output that do not read ``t``).
    section : str
        The transition whose guard is the Poincaré section.
    initial_state : sequence of float, shape (n,)
        Without ``initial_mode``: a guess of the orbit's point just before ``section`` fires, projected
        onto the guard surface.  With it: any state of that mode, simulated until ``section`` first
        fires, where the shooting starts.
    initial_mode : str or None
        See ``initial_state``.
    memory : Mapping or None
        Memory at the start (default: the initial memory).  When a revolution ends with other
        memory values, those are taken; at convergence the memory repeats.
    tol : float
        Convergence: ``‖Π(x) − x‖∞ <= tol · (1 + ‖x‖∞)``.
    max_iterations : int
        Most revolutions computed (Newton iterations).
    max_period : float
        Longest return time searched (also the longest transient with ``initial_mode``) [s].
    max_jumps : int
        Most jumps in one revolution.
    rtol, atol : float
        Tolerances of the executor and of the variational equation.
    event_tol : float or None
        Width of the event location bracket [s]; ``None`` (default): as narrow as the executor goes,
        4 ulp of the time (a bracket of fixed width would be a fixed fraction of a short period).
    divergence_bound : float
        A revolution whose state leaves ``‖x‖∞ <= divergence_bound`` diverges.
    margin : float
        Of the stability verdict.

    Returns
    -------
    PeriodicOrbit

    Raises
    ------
    PeriodicOrbitError
        Bad input (unknown section, mode or memory, a state of the wrong length or not finite, bad
        options); a section the flow does not come back to within ``max_period`` (naming the start
        state and mode), meets only tangentially, or reaches only at a jump's landing point; a
        revolution of more than ``max_jumps`` jumps; a non-autonomous system.
    ShootingError
        Newton did not converge within ``max_iterations`` (``iterations`` and ``residual`` attached).
    hybrid.errors.ZenoError
        An instantaneous cycle of jumps, or jumps accumulating before the return.
    hybrid.errors.DivergenceError
        A revolution leaves the divergence bound, or the solver fails.
    """
    transition = _section(system, section)
    x = _state(system, "initial_state", initial_state)
    opts = _options(rtol, atol, event_tol, max_period, max_jumps, divergence_bound)
    tol = _real_option("tol", tol)
    max_iterations = _int_option("max_iterations", max_iterations)
    margin = _margin(margin)
    mem = _memory(system, memory)
    shooter = _Shooter(system, transition, opts)
    if initial_mode is not None:
        if initial_mode not in system.automaton.mode_names:
            modes = list(system.automaton.mode_names)
            raise PeriodicOrbitError("initial_mode", initial_mode, f"one of the modes {modes} or None",
                                     "name the mode of initial_state, or give a point of the section")
        transient = shooter.leg(x, initial_mode, mem, None)
        x, mem = transient.end_state, transient.end_memory
    else:
        x = _onto_section(shooter.derivatives.guard(transition, mem, x), x)
    return _shoot(shooter, x, mem, tol, max_iterations, margin)


def _margin(margin: Any) -> float:
    if isinstance(margin, bool) or not isinstance(margin, (int, float)) or not 0.0 <= margin < 1.0:
        raise PeriodicOrbitError("margin", margin, "a number in [0, 1)", f"give e.g. margin={STABILITY_MARGIN:g}")
    return float(margin)


def _shoot(shooter: _Shooter, x: np.ndarray, memory: dict[str, float], tol: float, max_iterations: int,
           margin: float) -> PeriodicOrbit:
    """Newton's method on ``Π(x) − x`` from ``x`` on the section (module docstring)."""
    system, transition = shooter.system, shooter.section
    residual, first_period = math.inf, math.nan
    for iteration in range(1, max_iterations + 1):
        first = shooter.section_jump(x, memory)
        leg = shooter.leg(first.after, transition.target, first.memory_after, first)
        if iteration == 1:
            _check_autonomous(shooter, leg)
            first_period = leg.end_time
        _check_shrinking(shooter, leg, first_period)
        r = leg.end_state - x
        residual = float(np.abs(r).max())
        if not _same_memory(leg.end_memory, memory):  # the cycle's memory differs: take it, iterate on
            memory, x = dict(leg.end_memory), leg.end_state
            continue
        m = _monodromy(shooter, leg)
        if residual <= tol * (1.0 + float(np.abs(x).max())):
            return _orbit(shooter, x, memory, leg, m, iteration, residual, margin)
        p, _ = _projector(shooter, leg.end_state, memory)
        grad = shooter.derivatives.guard(transition, memory, x)
        g_x = float(grad.value(x)[0])
        lhs = np.vstack([p @ m - np.eye(x.size), grad.jacobian(x).reshape(1, -1)])
        step, *_ = np.linalg.lstsq(lhs, np.concatenate([-r, [-g_x]]), rcond=None)
        x = _onto_section(grad, x + step)
    raise ShootingError(
        f"periodic orbit of {system.name!r} through {transition.name!r}: Newton's method on the Poincaré map did "
        f"not converge after {max_iterations} iterations (residual ‖Π(x) − x‖∞ = {residual:.3g}, tolerance "
        f"{tol:g}·(1 + ‖x‖∞)) at x = {format_named_state(x, system.state_names)}; fix: start from a point of the "
        "steady state just before the jump (or give initial_mode to simulate there), allow more iterations, "
        "or check that the steady state is periodic", max_iterations, residual)


ZENO_SHRINK = 1e-9
"""Iterates whose return time falls below this fraction of the first one approach a Zeno point, not an orbit."""


def _check_shrinking(shooter: _Shooter, leg: _Leg, first_period: float) -> None:
    """A return time collapsing towards zero: the iterates approach the point where jumps accumulate."""
    if leg.end_time < ZENO_SHRINK * first_period:
        raise ZenoError(
            f"periodic orbit of {shooter.system.name!r} through {shooter.section.name!r}: the return time fell from "
            f"{format_time(first_period)} s to {format_time(leg.end_time)} s at x = "
            f"{format_named_state(leg.end_state, shooter.system.state_names)}: the iterates approach a point where "
            "the jumps accumulate (Zeno), not a periodic orbit")


def _section_basis(grad: np.ndarray) -> np.ndarray:
    """Orthonormal basis of ``{δ : ∇gᵀδ = 0}``, shape ``(n, n − 1)``."""
    _, _, vt = np.linalg.svd(grad.reshape(1, -1))
    return vt[1:].T.copy()


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


def _by_modulus(values: Sequence[complex]) -> tuple[complex, ...]:
    return tuple(complex(z) for z in sorted(values, key=lambda z: (-abs(z), -z.real, -z.imag)))


def _verdict(nontrivial: Sequence[complex], margin: float) -> str:
    if any(abs(m) > 1.0 + margin for m in nontrivial):
        return "unstable"
    if all(abs(m) < 1.0 - margin for m in nontrivial):
        return "orbitally stable"
    return "undecided"


def _orbit(shooter: _Shooter, x: np.ndarray, memory: dict[str, float], leg: _Leg, m: np.ndarray, iterations: int,
           residual: float, margin: float) -> PeriodicOrbit:
    system, transition = shooter.system, shooter.section
    p, grad = _projector(shooter, x, memory)
    basis = _section_basis(grad)
    reduced = basis.T @ p @ m @ basis
    values, vectors = np.linalg.eig(m)
    f = np.asarray(system.flow(transition.source, 0.0, tuple(x), memory), dtype=float)
    align = np.abs(vectors.conj().T @ f) / (np.linalg.norm(vectors, axis=0) * np.linalg.norm(f))
    k = int(np.argmax(align - 1e-9 * np.abs(values - 1.0)))  # the eigenvector along the flow
    nontrivial = _by_modulus(np.linalg.eigvals(reduced)) if reduced.size else ()
    flows = [piece for piece in leg.pieces if isinstance(piece, FlowSegment)]
    times, states, modes = _samples(flows)
    d = shooter.derivatives
    return PeriodicOrbit(
        system=system.name, section=transition.name, mode=transition.source, fixed_point=tuple(x.tolist()),
        period=leg.end_time, jumps=leg.jumps[1:], jump_times=leg.jump_times[1:], monodromy=_readonly(m),
        multipliers=_by_modulus(values), trivial_multiplier=complex(values[k]), nontrivial_multipliers=nontrivial,
        poincare_jacobian=_readonly(reduced), section_basis=_readonly(basis), verdict=_verdict(nontrivial, margin),
        margin=margin, iterations=iterations, residual=residual, derivatives=d.method,
        derivative_notes=tuple(sorted(d.notes)), memory=_memory_key(memory),
        first_flow_s=float(flows[0].t_end - flows[0].t_start) if flows else 0.0,
        flow_intervals=tuple((s.mode, float(s.t_start), float(s.t_end)) for s in flows),
        rtol=shooter.opts.rtol, atol=shooter.opts.atol, event_tol=shooter.opts.event_tol,
        times=times, states=states, modes=modes, state_names=system.state_names)


def _samples(flows: Sequence[FlowSegment]) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Step points and :data:`SAMPLES_PER_FLOW` even points (dense output) of every flow, in time order."""
    times: list[np.ndarray] = []
    states: list[np.ndarray] = []
    modes: list[str] = []
    for seg in flows:
        t = np.union1d(seg.times, np.linspace(seg.t_start, seg.t_end, SAMPLES_PER_FLOW))
        x = np.asarray(seg(t), dtype=float).T.reshape(t.size, -1)
        x[0], x[-1] = seg.states[0], seg.states[-1]
        times.append(t)
        states.append(x)
        modes += [seg.mode] * t.size
    return _readonly(np.concatenate(times)), _readonly(np.concatenate(states)), tuple(modes)


def finite_difference_monodromy(system: HybridSystem, orbit: PeriodicOrbit, *, step: float = 1e-6) -> np.ndarray:
    """Central differences of the fixed-time map over one period, at the middle of the longest flow.

    Independent of the saltation matrices and of the variational equation: only the executor is
    used (with the orbit's tolerances).  The matrix is the monodromy at that point, similar to
    :attr:`PeriodicOrbit.monodromy` (conjugated by the flow from ``x*``), so its eigenvalues are
    the Floquet multipliers.

    Parameters
    ----------
    system : HybridSystem
        The system of ``orbit``.
    orbit : PeriodicOrbit
    step : float
        Relative perturbation of each coordinate (absolute below 1).

    Returns
    -------
    ndarray, shape (n, n)

    Raises
    ------
    PeriodicOrbitError
        Not the orbit's system, or a non-positive step.
    """
    if not isinstance(system, HybridSystem) or system.name != orbit.system or system.state_names != orbit.state_names:
        raise PeriodicOrbitError("system", getattr(system, "name", system), f"the system {orbit.system!r} of the orbit",
                                 "pass the system the orbit was computed for")
    h0 = _real_option("step", step)
    transition = _section(system, orbit.section)
    opts = _Options(rtol=orbit.rtol, atol=orbit.atol, event_tol=orbit.event_tol, max_period=orbit.period,
                    max_jumps=1, divergence_bound=math.inf)
    first = _Shooter(system, transition, opts).section_jump(np.asarray(orbit.fixed_point), dict(orbit.memory))
    mode, start, end = max(orbit.flow_intervals, key=lambda item: item[2] - item[1])
    mid = 0.5 * (start + end)
    run = simulate_continuous(system, tuple(first.after), duration=mid, initial_mode=transition.target,
                              initial_memory=first.memory_after, rtol=opts.rtol, atol=opts.atol,
                              event_tol=opts.event_tol)
    if run.final_mode != mode:
        raise ExecutionError(f"finite_difference_monodromy: the orbit of {orbit.system!r} re-simulated is in mode "
                             f"{run.final_mode!r} at t = {format_time(mid)} s, not {mode!r}; the orbit does not "
                             "reproduce (recompute it with the same system and tolerances)")
    base, memory = np.asarray(run.final_state, dtype=float), dict(run.final_memory)

    def fixed_time(x: np.ndarray) -> np.ndarray:
        out = simulate_continuous(system, tuple(x), t0=mid, duration=orbit.period, initial_mode=mode,
                                  initial_memory=memory, rtol=opts.rtol, atol=opts.atol, event_tol=opts.event_tol)
        return np.asarray(out.final_state, dtype=float)

    cols = []
    for i in range(base.size):
        h = h0 * max(1.0, abs(base[i]))
        e = np.zeros(base.size)
        e[i] = h
        cols.append((fixed_time(base + e) - fixed_time(base - e)) / (2.0 * h))
    return np.column_stack(cols)
