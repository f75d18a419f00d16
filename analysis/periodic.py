"""Periodic orbits of hybrid systems: shooting on a Poincaré section, monodromy with saltation matrices.

The **section** is the guard surface ``{g(x) = 0}`` of one transition ``σ``, met in its source mode.
The **Poincaré map** ``Π`` takes a point ``x⁻`` of the section just before the jump, applies the jump
map ``x⁺ = r(x⁻)``, flows (through whatever jumps happen) until ``σ`` fires again, and returns the new
``x⁻``.  A periodic orbit is a fixed point of ``Π``; its period is the return time.

**Monodromy.** Along a flow segment the state-transition matrix ``Φ`` solves ``Φ̇ = ∂f/∂x Φ`` (the
variational equation, integrated beside the state).  A jump at a guard ``g(x) = 0`` with reset
``r`` is not differentiable in time, and its first-order effect on a neighbouring solution, which
jumps slightly earlier or later, is the **saltation matrix** (Aizerman & Gantmacher 1958; Hiskens &
Pai 2000):

    S = R + (f⁺ − R f⁻) ∇gᵀ / (∇gᵀ f⁻),      R = ∂r/∂x (x⁻),  f⁻ = f_q(x⁻),  f⁺ = f_q'(x⁺).

(A neighbour ``x⁻ + δ`` reaches the guard ``τ = −∇gᵀδ / ∇gᵀf⁻`` later; it jumps from ``x⁻ + δ + f⁻τ``
and flows ``−τ`` in the new mode: ``δ⁺ = Rδ + (R f⁻ − f⁺) τ``.)  The monodromy at ``x⁻`` over one
revolution is ``M = Φ_k S_{k−1} ⋯ S_1 Φ_1 S_σ``; its eigenvalues are the **Floquet multipliers**.
One of them is 1, along the flow (``M f⁻ = f⁻``); the orbit is orbitally asymptotically stable when
every other one lies inside the unit circle.  The Jacobian of ``Π`` is ``(I − f⁻∇gᵀ/∇gᵀf⁻) M``,
whose eigenvalues are the nontrivial multipliers and 0 — Newton's method on ``Π(x) − x`` uses it,
with the step kept in the section's tangent plane.

Derivatives of the user's flows, guards and resets come from CasADi by tracing them
(:func:`analysis.derivatives.differentiable_map`), or from central differences when they do not
trace.  :func:`finite_difference_monodromy` is the independent check: the fixed-time map over one
period differenced from a point in the middle of a flow segment.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from hybrid import HybridSystem
from hybrid.continuous import HybridTrajectory, simulate_continuous
from hybrid.errors import ExecutionError, ParameterError, ZenoError
from hybrid.jsonable import to_jsonable

from analysis.derivatives import DifferentiableMap, differentiable_map, mode_vector_field

__all__ = ["PeriodicOrbitError", "ShootingError", "PeriodicOrbit", "periodic_orbit", "saltation_matrix",
           "finite_difference_monodromy", "STABILITY_MARGIN"]

STABILITY_MARGIN = 1e-6
"""A nontrivial multiplier within this of the unit circle leaves the verdict undecided."""

_RTOL, _ATOL = 1e-12, 1e-12


class PeriodicOrbitError(ParameterError):
    """Bad input to a periodic-orbit search (section, state, options), or a section the flow never reaches."""


class ShootingError(ExecutionError):
    """Newton's method on the Poincaré map did not converge; carries ``iterations`` and ``residual``."""

    def __init__(self, message: str, iterations: int, residual: float) -> None:
        super().__init__(message)
        self.iterations = iterations
        self.residual = residual


@dataclass(frozen=True, kw_only=True, slots=True)
class PeriodicOrbit:
    """A periodic orbit through a guard section.

    Attributes
    ----------
    system, section, mode : str
        The system, the transition whose guard is the section, and its source mode.
    fixed_point : tuple of float
        ``x⁻`` on the section, just before the jump.
    period : float
        Return time [s].
    jumps : tuple of str
        Transitions taken in one revolution, the section's last.
    monodromy : ndarray, shape (n, n)
    multipliers : tuple of complex
        Eigenvalues of the monodromy, sorted by decreasing modulus.
    trivial_multiplier : complex
        The one along the flow (closest to 1).
    nontrivial_multipliers : tuple of complex
    verdict : str
        ``"orbitally stable"``, ``"unstable"`` or ``"undecided"`` (a multiplier within
        :data:`STABILITY_MARGIN` of the unit circle).
    iterations : int
    residual : float
        ``‖Π(x) − x‖∞`` at the fixed point.
    derivatives : str
        ``"casadi"`` when every flow, guard and reset traced, else ``"finite differences"`` for some.
    first_flow_s : float
        Duration of the first flow after the section's jump [s].
    times, states, modes :
        One revolution sampled for drawing: shape ``(k,)``, ``(k, n)``, length ``k``.
    state_names : tuple of str
    """

    system: str
    section: str
    mode: str
    fixed_point: tuple[float, ...]
    period: float
    jumps: tuple[str, ...]
    monodromy: np.ndarray
    multipliers: tuple[complex, ...]
    trivial_multiplier: complex
    nontrivial_multipliers: tuple[complex, ...]
    verdict: str
    iterations: int
    residual: float
    derivatives: str
    first_flow_s: float
    times: np.ndarray
    states: np.ndarray
    modes: tuple[str, ...]
    state_names: tuple[str, ...]

    @property
    def finding(self) -> str:
        """One sentence: the period, the multipliers and the verdict."""
        mods = ", ".join(f"{abs(m):.4g}" for m in self.nontrivial_multipliers) or "none (one state)"
        return (f"periodic orbit through {self.section!r}: period {self.period:.10g} s, {len(self.jumps)} jump(s) per "
                f"revolution, nontrivial Floquet multipliers of modulus {mods}: {self.verdict}")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (multipliers as ``[re, im]``, the revolution's samples left out)."""
        data = {name: getattr(self, name) for name in self.__slots__ if name not in ("times", "states", "modes")}
        data["finding"] = self.finding
        return to_jsonable(data, nonfinite="string")


def saltation_matrix(reset_jacobian: np.ndarray, f_before: np.ndarray, f_after: np.ndarray,
                     guard_gradient: np.ndarray) -> np.ndarray:
    """``S = R + (f⁺ − R f⁻) ∇gᵀ / (∇gᵀ f⁻)`` (module docstring); shapes ``(n, n), (n,), (n,), (n,)``.

    Raises
    ------
    ArithmeticError
        ``∇gᵀ f⁻ = 0``: the flow grazes the guard (no transversal crossing).
    """
    rate = float(guard_gradient @ f_before)
    if rate == 0.0 or not math.isfinite(rate):
        raise ArithmeticError(f"the flow is tangent to the guard (∇g·f = {rate!r}): the crossing is not transversal")
    return reset_jacobian + np.outer(f_after - reset_jacobian @ f_before, guard_gradient) / rate


def _guard_map(system: HybridSystem, transition: Any, memory: dict[str, float], probe: np.ndarray) -> DifferentiableMap:
    output = system.output

    def symbolic(xs: list[Any]) -> list[Any]:
        v = xs if output is None else list(output(0.0, xs))
        return [transition.guard(v, memory)]

    def plain(x: np.ndarray) -> list[float]:
        xt = tuple(float(c) for c in x)
        return [system.guard(transition, 0.0, xt, system.signals(0.0, xt), memory)]

    return differentiable_map(f"guard of transition {transition.name!r}", symbolic, plain, system.dimension, probe)


def _reset_map(system: HybridSystem, name: str, memory: dict[str, float], probe: np.ndarray) -> DifferentiableMap:
    jump = system.jumps.get(name)
    if jump is None:
        return differentiable_map(f"jump map of {name!r}", lambda xs: xs, lambda x: x, system.dimension, probe)
    return differentiable_map(f"jump map of {name!r}", lambda xs: jump(xs, memory),
                              lambda x: system.jump(name, 0.0, tuple(float(c) for c in x), memory),
                              system.dimension, probe)


def _variational(system: HybridSystem, mode: str, x0: np.ndarray, duration: float, memory: dict[str, float]
                 ) -> tuple[np.ndarray, np.ndarray, str]:
    """State and ``Φ`` after ``duration`` in ``mode`` from ``x0`` (solve_ivp, DOP853, tight tolerances)."""
    n = x0.size
    field = mode_vector_field(system, mode, memory=memory, probe=x0)
    if duration <= 0.0:
        return x0.copy(), np.eye(n), field.method

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        x, phi = z[:n], z[n:].reshape(n, n)
        return np.concatenate([field.value(x), (field.jacobian(x) @ phi).reshape(-1)])

    sol = solve_ivp(rhs, (0.0, duration), np.concatenate([x0, np.eye(n).reshape(-1)]), method="DOP853",
                    rtol=_RTOL, atol=_ATOL)
    if not sol.success:
        raise ArithmeticError(f"the variational equation in mode {mode!r} failed: {sol.message}")
    z = sol.y[:, -1]
    return z[:n], z[n:].reshape(n, n), field.method


@dataclass(frozen=True, slots=True)
class _Revolution:
    end_state: np.ndarray
    period: float
    jumps: tuple[str, ...]
    trajectory: HybridTrajectory


def _revolve(system: HybridSystem, section: Any, x_minus: np.ndarray, memory: dict[str, float], max_period: float,
             max_jumps: int) -> _Revolution:
    """From ``x⁻`` on the section: jump, then flow until the section's transition fires again."""
    x_plus = np.asarray(system.jump(section.name, 0.0, tuple(x_minus), memory), dtype=float)
    horizon = min(max_period, 1.0)
    while True:
        run = simulate_continuous(system, tuple(x_plus), duration=horizon, initial_mode=section.target,
                                  initial_memory=memory, rtol=_RTOL, atol=_ATOL, max_jumps=max_jumps)
        hits = [e for e in run.events if e.transition == section.name]
        if hits:
            hit = hits[0]
            if hit.time <= 0.0:
                raise ZenoError(f"periodic orbit of {system.name!r} through {section.name!r}: the revolution from "
                                f"x = {x_plus.tolist()} takes no time (an instantaneous cycle of jumps, Zeno), "
                                "so there is no periodic orbit to analyse; separate the guards (hysteresis)")
            jumps = tuple(e.transition for e in run.events if e.jump <= hit.jump)
            return _Revolution(np.asarray(hit.state_before, dtype=float), float(hit.time), jumps, run)
        if len(run.events) >= max_jumps:
            raise PeriodicOrbitError("max_jumps", max_jumps, f"enough jumps for one revolution back to {section.name!r}",
                                     "raise max_jumps, or choose a section the orbit crosses")
        if horizon >= max_period:
            raise PeriodicOrbitError(
                "section", section.name,
                f"a transition the flow takes again: from x = {x_plus.tolist()} in mode {section.target!r} it was not "
                f"taken within max_period = {max_period:g} s (modes visited: {sorted({s.mode for s in run.segments})})",
                "choose the guard of a transition the steady state crosses, another initial state, or a larger "
                "max_period")
        horizon = min(2.0 * horizon, max_period)


def _monodromy(system: HybridSystem, section: Any, x_minus: np.ndarray, rev: _Revolution,
               memory: dict[str, float]) -> tuple[np.ndarray, set[str]]:
    """``M = Φ_k S_{k−1} ⋯ S_1 Φ_1 S_σ`` at ``x⁻``, and the derivative methods used."""
    n = x_minus.size
    methods: set[str] = set()
    events = [e for e in rev.trajectory.events if e.jump <= rev.jumps.__len__()]
    m = _jump_saltation(system, section, x_minus, memory, methods)
    x = np.asarray(system.jump(section.name, 0.0, tuple(x_minus), memory), dtype=float)
    t, mode = 0.0, section.target
    for event in events:
        x, phi, method = _variational(system, mode, x, event.time - t, memory)
        methods.add(method)
        m = phi @ m
        if event.transition == section.name and event is events[-1]:
            return m, methods
        transition = next(tr for tr in system.automaton.transitions if tr.name == event.transition)
        x_before = np.asarray(event.state_before, dtype=float)
        m = _jump_saltation(system, transition, x_before, memory, methods) @ m
        x, t, mode = np.asarray(event.state_after, dtype=float), event.time, event.target
    return m, methods


def _jump_saltation(system: HybridSystem, transition: Any, x_minus: np.ndarray, memory: dict[str, float],
                    methods: set[str]) -> np.ndarray:
    guard = _guard_map(system, transition, memory, x_minus)
    reset = _reset_map(system, transition.name, memory, x_minus)
    x_plus = reset.value(x_minus)
    methods.update((guard.method, reset.method))
    f_before = np.asarray(system.flow(transition.source, 0.0, tuple(x_minus), memory), dtype=float)
    f_after = np.asarray(system.flow(transition.target, 0.0, tuple(x_plus), memory), dtype=float)
    return saltation_matrix(reset.jacobian(x_minus), f_before, f_after, guard.jacobian(x_minus).reshape(-1))


def _verdict(nontrivial: Sequence[complex]) -> str:
    if any(abs(m) > 1.0 + STABILITY_MARGIN for m in nontrivial):
        return "unstable"
    if all(abs(m) < 1.0 - STABILITY_MARGIN for m in nontrivial):
        return "orbitally stable"
    return "undecided"


def _check_inputs(system: Any, section: str, initial_state: Sequence[float], tol: float,
                  max_iterations: int) -> tuple[Any, np.ndarray]:
    if not isinstance(system, HybridSystem):
        raise PeriodicOrbitError("system", system, "a hybrid.HybridSystem", "build the system with hybrid.HybridSystem")
    names = [t.name for t in system.automaton.transitions]
    if section not in names:
        raise PeriodicOrbitError("section", section, f"one of the transitions {names}",
                                 "name the transition whose guard is the Poincaré section")
    x = np.asarray(initial_state, dtype=float).reshape(-1)
    if x.size != system.dimension or not np.all(np.isfinite(x)):
        raise PeriodicOrbitError("initial_state", tuple(np.asarray(initial_state).reshape(-1).tolist()),
                                 f"{system.dimension} finite values ({', '.join(system.state_names)})",
                                 "give one value per state")
    if not (isinstance(tol, float) and 0.0 < tol < 1.0):
        raise PeriodicOrbitError("tol", tol, "a number in (0, 1)", "give e.g. tol=1e-10")
    if not (isinstance(max_iterations, int) and max_iterations >= 1):
        raise PeriodicOrbitError("max_iterations", max_iterations, "a positive integer", "give e.g. 30")
    return next(t for t in system.automaton.transitions if t.name == section), x


def _onto_section(guard: DifferentiableMap, x: np.ndarray) -> np.ndarray:
    """Newton along the gradient so that ``g(x) = 0`` (the guess need not lie on the section)."""
    for _ in range(20):
        g = float(guard.value(x)[0])
        grad = guard.jacobian(x).reshape(-1)
        if abs(g) <= 1e-14 * (1.0 + float(np.abs(x).max())) or not np.any(grad):
            break
        x = x - g * grad / float(grad @ grad)
    return x


def periodic_orbit(
    system: HybridSystem,
    *,
    section: str,
    initial_state: Sequence[float],
    tol: float = 1e-10,
    max_iterations: int = 30,
    max_period: float = 1e4,
    max_jumps: int = 1000,
) -> PeriodicOrbit:
    """The periodic orbit through the guard of ``section`` nearest ``initial_state`` (module docstring).

    Parameters
    ----------
    system : HybridSystem
    section : str
        The transition whose guard is the Poincaré section.
    initial_state : sequence of float, shape (n,)
        Guess of the orbit's point just before that jump (projected onto the guard surface).
    tol : float
        Convergence: ``‖Π(x) − x‖∞ <= tol · (1 + ‖x‖∞)``.
    max_iterations : int
    max_period : float
        Longest return time searched [s].
    max_jumps : int
        Most jumps in one revolution.

    Raises
    ------
    PeriodicOrbitError
        Bad input; or the flow does not come back to the section within ``max_period``.
    ShootingError
        Newton did not converge in ``max_iterations`` (the iterations and the residual are attached).
    hybrid.errors.ExecutionError
        The executor failed on the way (diverging, Zeno).
    """
    transition, x = _check_inputs(system, section, initial_state, tol, max_iterations)
    memory = dict(system.automaton.initial_memory())
    guard = _guard_map(system, transition, memory, x)
    x = _onto_section(guard, x)
    residual = math.inf
    for iteration in range(1, max_iterations + 1):
        rev = _revolve(system, transition, x, memory, max_period, max_jumps)
        r = rev.end_state - x
        residual = float(np.abs(r).max())
        m, methods = _monodromy(system, transition, x, rev, memory)
        if residual <= tol * (1.0 + float(np.abs(x).max())):
            return _orbit(system, transition, x, rev, m, methods, iteration, residual)
        grad = guard.jacobian(x).reshape(-1)
        f = np.asarray(system.flow(transition.source, 0.0, tuple(x), memory), dtype=float)
        d_pi = (np.eye(x.size) - np.outer(f, grad) / float(grad @ f)) @ m
        lhs = np.vstack([d_pi - np.eye(x.size), grad])
        step, *_ = np.linalg.lstsq(lhs, np.concatenate([-r, [0.0]]), rcond=None)
        x = _onto_section(guard, x + step)
    raise ShootingError(
        f"periodic orbit of {system.name!r} through {section!r}: Newton's method on the Poincaré map did not converge "
        f"after {max_iterations} iterations (residual ‖Π(x) − x‖∞ = {residual:.3g}, tolerance {tol:g}) from "
        f"x = {x.tolist()}; try another initial state (a point of the steady state just before the jump), more "
        "iterations, or check that the steady state is periodic", max_iterations, residual)


def _orbit(system: HybridSystem, transition: Any, x: np.ndarray, rev: _Revolution, m: np.ndarray,
           methods: set[str], iterations: int, residual: float) -> PeriodicOrbit:
    values = sorted(np.linalg.eigvals(m), key=lambda z: (-abs(z), z.real, z.imag))
    k = int(np.argmin([abs(z - 1.0) for z in values]))
    trivial = complex(values[k])
    nontrivial = tuple(complex(z) for i, z in enumerate(values) if i != k)
    times, states, modes = _samples(rev)
    m = np.array(m)
    m.setflags(write=False)
    return PeriodicOrbit(
        system=system.name, section=transition.name, mode=transition.source, fixed_point=tuple(float(c) for c in x),
        period=rev.period, jumps=rev.jumps, monodromy=m, multipliers=tuple(complex(z) for z in values),
        trivial_multiplier=trivial, nontrivial_multipliers=nontrivial, verdict=_verdict(nontrivial),
        iterations=iterations, residual=residual,
        derivatives="casadi" if methods == {"casadi"} else "finite differences",
        first_flow_s=float(rev.trajectory.segments[0].t_end), times=times, states=states,
        modes=modes, state_names=system.state_names)


def _samples(rev: _Revolution) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    times, states, modes = [], [], []
    for seg in rev.trajectory.segments:
        keep = seg.times <= rev.period
        times.append(seg.times[keep])
        states.append(seg.states[keep])
        modes += [seg.mode] * int(keep.sum())
    t = np.concatenate(times)
    s = np.concatenate(states)
    t.setflags(write=False)
    s.setflags(write=False)
    return t, s, tuple(modes)


def finite_difference_monodromy(system: HybridSystem, orbit: PeriodicOrbit, *, step: float = 1e-6) -> np.ndarray:
    """Central differences of the fixed-time map over one period, from the middle of the first flow segment.

    Independent of the saltation matrices: only the executor is used.  Its eigenvalues equal the
    Floquet multipliers (the two monodromies are similar: conjugated by the flow over half a segment).
    """
    memory = dict(system.automaton.initial_memory())
    start_state = np.asarray(system.jump(orbit.section, 0.0, orbit.fixed_point, memory), dtype=float)
    target = next(t.target for t in system.automaton.transitions if t.name == orbit.section)
    mid = 0.5 * orbit.first_flow_s
    run = simulate_continuous(system, tuple(start_state), duration=mid, initial_mode=target, rtol=_RTOL, atol=_ATOL)
    base = np.asarray(run.final_state, dtype=float)

    def fixed_time(x: np.ndarray) -> np.ndarray:
        out = simulate_continuous(system, tuple(x), duration=orbit.period, initial_mode=target, rtol=_RTOL, atol=_ATOL)
        return np.asarray(out.final_state, dtype=float)

    cols = []
    for i in range(base.size):
        h = step * max(1.0, abs(base[i]))
        e = np.zeros(base.size)
        e[i] = h
        cols.append((fixed_time(base + e) - fixed_time(base - e)) / (2.0 * h))
    return np.column_stack(cols)

