"""Closed-form flows of affine modes, and fast point evaluation of a step's dense output.

A mode whose symbolic flow (:func:`hybrid.symbolic.flow_map`) is *exactly* affine in the state,
``ẋ = A x + b`` (read from the expression tree, never sampled: a product of two
states, the time ``t``, ``min``/``max``/``abs``/``ite`` of the state, a transcendental function or a
plain Python flow is not affine), has the solution

.. math:: x(t_0 + τ) = e^{Aτ} x_0 + \\int_0^τ e^{As} b \\, ds
          = [I_n \\; 0] \\exp\\left(\\begin{bmatrix} A & b \\\\ 0 & 0 \\end{bmatrix} τ\\right)
            \\begin{bmatrix} x_0 \\\\ 1 \\end{bmatrix}.

:func:`hybrid.continuous.simulate_continuous` (``closed_form=True``; :func:`analysis.verify.problems.hybrid_problem`
sets it when the trace has its own sample period) then steps the mode with
:class:`ClosedFormSolver` instead of a Runge–Kutta solver: the steps are pieces of the exact solution
(length at most ``0.5 / ρ(A)``, ρ the spectral radius, and ``max_step``), their dense output *is* the
solution, and the event search (:func:`hybrid.events.find_switch`, :func:`hybrid.events.locate_event`) runs
on it unchanged, so the guards, the invariant and the stop functions are watched and located by the same
rules and to the same ``event_tol`` as on a numerical step.  Only the integration error is gone.  A
one-state mode whose watches are affine in the state goes further (:func:`scalar_switch`): each watch is
monotone along the flow, so the first switch-on is the root of the closed form, computed, then confirmed by
evaluating the watches at both ends of a bracket of width ``event_tol`` — no step search at all.

:class:`AffinePropagator` evaluates the solution by the cheapest exact route: a scalar mode by
``x₀ e^{aτ} + b τ φ₁(aτ)`` (``φ₁(z) = (e^z − 1)/z`` by ``expm1``); a nilpotent augmented matrix (a chain
of integrators: the bouncing ball) by its finite Taylor polynomial; a diagonalisable ``A`` with
well-conditioned eigenvectors and a well-conditioned ``A`` by its eigen-decomposition around the
equilibrium, a singular ``A`` by the augmented matrix's; anything else by :func:`scipy.linalg.expm` of the
augmented matrix at each time, for small systems only (:data:`EXPM_SIZE`; a larger one is not solved in
closed form: :func:`affine_flow` gives ``None``).

:func:`point_evaluator` is the fast scalar evaluation of a step's dense output the event search uses: the
closed form's own, and for scipy's explicit Runge–Kutta interpolants the same formula as scipy's in plain
floats.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .events import LocatedEvent, is_on, switched_on
from .symbolic_core import Apply, Const, Coordinate, MemoryRef, Param, SymbolicVector

try:  # the explicit Runge-Kutta interpolants, for a fast scalar evaluation (see point_evaluator)
    from scipy.integrate._ivp.rk import Dop853DenseOutput as _Dop853DenseOutput
    from scipy.integrate._ivp.rk import RkDenseOutput as _RkDenseOutput
except ImportError:  # pragma: no cover - private names moved: fall back to interp(t)
    _Dop853DenseOutput = _RkDenseOutput = type("_Unavailable", (), {})

__all__ = [
    "AffineFlow",
    "affine_flow",
    "AffinePropagator",
    "ClosedFormSolver",
    "point_evaluator",
    "sample_segments",
    "scalar_watch_forms",
    "scalar_switch",
    "closed_form_switch",
    "ScalarSwitch",
    "STEP_FRACTION",
    "EIGEN_CONDITION",
    "EXPM_SIZE",
]

STEP_FRACTION = 0.5
"""A closed-form step lasts at most this over the spectral radius of ``A`` [s] (no limit when it is 0)."""

EXPM_SIZE = 8
"""Largest augmented matrix (``n + 1``) evaluated by :func:`scipy.linalg.expm` at each time; a larger system
without a cheaper exact route (defective, ill-conditioned eigenvectors) keeps the numerical solver."""

EIGEN_CONDITION = 1e6
"""Largest condition number of the eigenvectors (and of ``A``) for which the eigen route is used."""

_CACHE_LIMIT = 10_000
_CACHE: dict[tuple[int, tuple[tuple[str, float], ...]], tuple[Any, AffineFlow | None]] = {}


@dataclass(frozen=True, kw_only=True, slots=True)
class AffineFlow:
    """``ẋ = A x + b``, read exactly from a symbolic flow.

    Attributes
    ----------
    matrix : ndarray, shape (n, n)
        ``A`` [1/s] (read-only).
    offset : ndarray, shape (n,)
        ``b`` [state unit / s] (read-only).
    step : float
        The longest closed-form step [s]: :data:`STEP_FRACTION` over the spectral radius of ``A``
        (``inf`` when it is 0: a chain of integrators, whose solution is a polynomial).
    route : tuple
        How :class:`AffinePropagator` evaluates the solution (``"scalar"``, ``"poly"``, ``"eigen"`` or
        ``"expm"`` and what it needs), decided once per flow.
    """

    matrix: np.ndarray
    offset: np.ndarray
    step: float
    route: tuple[Any, ...]


def affine_flow(flow: Any, dimension: int, memory: Mapping[str, float]) -> AffineFlow | None:
    """The exact affine form of a mode's flow, or ``None`` when it is not exactly affine (or not symbolic).

    Parameters
    ----------
    flow : hybrid.symbolic.SymbolicVector or callable
        The mode's flow; only a symbolic ``flow_map`` can be read.
    dimension : int
        Number of states ``n``.
    memory : Mapping[str, float]
        The memory during the segment (constant on it): a memory variable the flow reads is a constant.

    Returns
    -------
    AffineFlow or None
        Cached per flow object and memory values read (a system built once is read once).
    """
    if not isinstance(flow, SymbolicVector) or flow.kind != "flow" or len(flow.components) != dimension:
        return None
    key = (id(flow), tuple(sorted((k, float(v)) for k, v in memory.items())) if memory else ())
    hit = _CACHE.get(key)
    if hit is not None:
        return hit[1]
    result = _read(flow, dimension, memory)
    if len(_CACHE) >= _CACHE_LIMIT:
        _CACHE.clear()
    _CACHE[key] = (flow, result)  # the flow is kept alive with its form, so its id stays unique
    return result


def _read(flow: SymbolicVector, n: int, memory: Mapping[str, float]) -> AffineFlow | None:
    memo: dict[int, tuple[list[float], float] | None] = {}
    rows, offsets = [], []
    for component in flow.components:
        form = _form(component, n, memory, memo)
        if form is None:
            return None
        rows.append(form[0])
        offsets.append(form[1])
    matrix, offset = np.array(rows, dtype=float), np.array(offsets, dtype=float)
    if not (np.all(np.isfinite(matrix)) and np.all(np.isfinite(offset))):
        return None
    matrix.setflags(write=False)
    offset.setflags(write=False)
    route = _route(matrix, offset)
    if route[0] == "expm" and n + 1 > EXPM_SIZE:  # no cheap exact route: the numerical solver is faster
        return None
    radius = float(np.max(np.abs(np.linalg.eigvals(matrix))))
    return AffineFlow(matrix=matrix, offset=offset, step=STEP_FRACTION / radius if radius > 0.0 else math.inf,
                      route=route)


def _form(node: Any, n: int, memory: Mapping[str, float],
          memo: dict[int, tuple[list[float], float] | None]) -> tuple[list[float], float] | None:
    """``(coefficients, constant)`` of ``node``, ``None`` when it is not affine (structure read exactly; the
    coefficients in floats: a coefficient differs from the rational one by rounding, ~1e-16 relative)."""
    key = id(node)
    if key in memo:
        return memo[key]
    out: tuple[list[float], float] | None = None
    if isinstance(node, (Const, Param)):
        out = ([0.0] * n, node.value) if math.isfinite(node.value) else None
    elif isinstance(node, Coordinate):
        if 0 <= node.index < n:
            coefficients = [0.0] * n
            coefficients[node.index] = 1.0
            out = (coefficients, 0.0)
    elif isinstance(node, MemoryRef):
        value = memory.get(node.name)
        out = ([0.0] * n, float(value)) if value is not None and math.isfinite(value) else None
    elif isinstance(node, Apply):
        args = [_form(a, n, memory, memo) for a in node.args]
        out = None if any(a is None for a in args) else _apply(node.op, args)  # type: ignore[arg-type]
    memo[key] = out  # Time, Ite, Select, Unsupported: not affine
    return out


def _apply(op: str, args: list[tuple[list[float], float]]) -> tuple[list[float], float] | None:
    def constant(form: tuple[list[float], float]) -> bool:
        return not any(form[0])

    if op in ("add", "sub"):
        sign = 1 if op == "add" else -1
        return [a + sign * b for a, b in zip(args[0][0], args[1][0])], args[0][1] + sign * args[1][1]
    if op == "neg":
        return [-a for a in args[0][0]], -args[0][1]
    if op == "mul":
        if constant(args[0]) or constant(args[1]):
            k, other = (args[0][1], args[1]) if constant(args[0]) else (args[1][1], args[0])
            return [k * a for a in other[0]], k * other[1]
        return None
    if op == "div":
        if not constant(args[1]) or args[1][1] == 0:
            return None
        k = args[1][1]
        return [a / k for a in args[0][0]], args[0][1] / k
    if op == "pow" and constant(args[1]) and float(args[1][1]).is_integer():
        power = int(args[1][1])
        if power == 1:
            return args[0]
        if constant(args[0]) and (power >= 0 or args[0][1] != 0):
            return [0.0] * len(args[0][0]), args[0][1] ** power
        return None
    if op in ("abs", "min", "max") and all(constant(a) for a in args):
        values = [a[1] for a in args]
        value = abs(values[0]) if op == "abs" else (min(values) if op == "min" else max(values))
        return [0.0] * len(args[0][0]), value
    return None  # a transcendental function, or min/max/abs of the state: not affine


# ---------------------------------------------------------------------- the solution
class AffinePropagator:
    """``x(t)`` of ``ẋ = A x + b`` from ``(t0, x0)``, exactly (to rounding), by the cheapest route.

    Parameters
    ----------
    flow : AffineFlow
    t0 : float
        Initial time [s].
    x0 : sequence of float, shape (n,)
        Initial state.
    """

    __slots__ = ("t0", "x0", "_scalar", "_point", "_many")

    def __init__(self, flow: AffineFlow, t0: float, x0: Sequence[float]) -> None:
        self.t0 = float(t0)
        self.x0 = np.array(x0, dtype=float)
        route = flow.route
        if route[0] == "scalar":  # the common case, evaluated inline (no closures to build per segment)
            self._scalar = (route[1], route[2], float(self.x0[0]))
        else:
            self._scalar = None
            self._point, self._many = _evaluators(route, self.x0)

    def point(self, t: float) -> tuple[float, ...]:
        """State at one time ``t`` [s], shape ``(n,)`` as a tuple of floats."""
        if self._scalar is not None:
            a, b, x = self._scalar
            tau = t - self.t0
            z = a * tau
            return (x * math.exp(z) + b * (math.expm1(z) / a if z != 0.0 else tau),)
        return self._point(t - self.t0)

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        """State at ``t``: shape ``(n,)`` for a scalar, ``(n, k)`` for ``k`` times (scipy's dense-output shape)."""
        if self._scalar is not None and t.__class__ is np.ndarray and t.ndim == 1:  # the trace's grid
            a, b, x = self._scalar
            tau = t - self.t0
            z = a * tau
            return ((x + b * tau) if a == 0.0 else (x * np.exp(z) + b * (np.expm1(z) / a)))[None, :]
        if np.ndim(t) == 0:
            return np.array(self.point(float(t)))
        tau = np.asarray(t, dtype=float) - self.t0
        if self._scalar is not None:
            a, b, x = self._scalar
            flat = tau.reshape(-1)
            z = a * flat
            out = (x + b * flat) if a == 0.0 else (x * np.exp(z) + b * (np.expm1(z) / a))
            return out.reshape(1, *tau.shape)
        return self._many(tau.reshape(-1)).reshape(self.x0.size, *tau.shape)


def _route(a: np.ndarray, b: np.ndarray) -> tuple[Any, ...]:
    """How to evaluate the solution: ("scalar", a, b), ("poly", M), ("eigen", ...) or ("expm", M)."""
    n = b.size
    if n == 1:
        return ("scalar", float(a[0, 0]), float(b[0]))
    augmented = np.zeros((n + 1, n + 1))
    augmented[:n, :n], augmented[:n, n] = a, b
    power = augmented.copy()
    for _ in range(n):
        power = power @ augmented
    if not power.any():  # nilpotent: the Taylor series stops at degree n
        return ("poly", augmented)
    try:
        if np.linalg.cond(a) <= EIGEN_CONDITION:  # around the equilibrium
            values, vectors = np.linalg.eig(a)
            if np.linalg.cond(vectors) <= EIGEN_CONDITION:
                return ("eigen", values, vectors, np.linalg.inv(vectors), np.linalg.solve(a, -b), False)
        values, vectors = np.linalg.eig(augmented)  # a singular A (inputs, clocks): the augmented matrix
        if np.linalg.cond(vectors) <= EIGEN_CONDITION:
            return ("eigen", values, vectors, np.linalg.inv(vectors), np.zeros(n + 1), True)
    except np.linalg.LinAlgError:
        pass
    return ("expm", augmented)


def _evaluators(route: tuple[Any, ...], x0: np.ndarray) -> tuple[Callable[[float], tuple[float, ...]],
                                                                   Callable[[np.ndarray], np.ndarray]]:
    kind = route[0]
    if kind == "poly":
        m = route[1]
        n = x0.size
        term = np.append(x0, 1.0)
        terms = [term]
        for k in range(1, n + 1):  # M^k x̃0 / k!
            term = m @ term / k
            terms.append(term)
        coefficients = np.array(terms)[::-1, :n]  # highest degree first, shape (n + 1, n)
        rows = coefficients.tolist()

        def poly(tau: float) -> tuple[float, ...]:
            acc = rows[0]
            for row in rows[1:]:
                acc = [c * tau + r for c, r in zip(acc, row)]
            return tuple(acc)

        def poly_many(tau: np.ndarray) -> np.ndarray:
            acc = np.repeat(coefficients[0][:, None], tau.size, axis=1)
            for row in coefficients[1:]:
                acc = acc * tau + row[:, None]
            return acc

        return poly, poly_many
    if kind == "eigen":
        values, vectors, inverse, rest, augmented = route[1:]
        n = x0.size
        weights = inverse @ ((np.append(x0, 1.0) if augmented else x0) - rest)

        def eigen_many(tau: np.ndarray) -> np.ndarray:
            out = vectors[:n] @ (weights[:, None] * np.exp(np.outer(values, tau)))
            return (out.real if np.iscomplexobj(out) else out) + rest[:n, None]

        return (lambda tau: tuple(eigen_many(np.array([tau]))[:, 0].tolist())), eigen_many
    from scipy.linalg import expm

    m = route[1]
    start = np.append(x0, 1.0)
    n = x0.size

    def expm_many(tau: np.ndarray) -> np.ndarray:
        return np.stack([(expm(m * s) @ start)[:n] for s in tau], axis=1) if tau.size else np.empty((n, 0))

    return (lambda tau: tuple((expm(m * tau) @ start)[:n].tolist())), expm_many


class ClosedFormSolver:
    """The scipy ``OdeSolver`` interface the executor uses (``step``, ``t``, ``t_old``, ``y``, ``status``,
    ``dense_output``, ``nfev``), stepping the exact solution of an affine mode.

    Parameters
    ----------
    flow : AffineFlow
    t0, t_bound : float
        Start and end of the integration [s].
    x0 : sequence of float, shape (n,)
    max_step : float
        The user's step limit [s] (with :attr:`AffineFlow.step`).
    watched : bool
        Whether anything is watched along the flow; if not, the steps are as long as ``max_step`` allows.
    """

    nfev = 0

    def __init__(self, flow: AffineFlow, t0: float, x0: Sequence[float], t_bound: float, max_step: float,
                 watched: bool = True) -> None:
        self.propagator = AffinePropagator(flow, t0, x0)
        self.flow = flow
        self.t = self.t_old = float(t0)
        self.t_bound = float(t_bound)
        self.h = min(max_step, flow.step) if watched else max_step  # nothing to watch: no step limit but yours
        self.y = self.propagator.x0
        self.status = "running" if self.t < self.t_bound else "finished"

    def step(self) -> str | None:
        """Advance one piece of the solution; ``status`` becomes ``"finished"`` at ``t_bound``, ``"failed"``
        when the state is no longer finite."""
        self.t_old = self.t
        t_new = self.t + self.h
        self.t = self.t_bound if t_new >= self.t_bound or self.t_bound - t_new < 1e-12 * self.h else t_new
        self.y = np.array(self.propagator.point(self.t))
        if not np.all(np.isfinite(self.y)):
            self.status = "failed"
            return "the closed-form solution of the affine flow overflowed (it grows without bound)"
        if self.t >= self.t_bound:
            self.status = "finished"
        return None

    def dense_output(self) -> AffinePropagator:
        """The exact solution (valid over the whole segment, not only the last step)."""
        return self.propagator


def sample_segments(pieces: Sequence[tuple[Any, np.ndarray]]) -> list[np.ndarray]:
    """The states of each ``(segment, times)`` on its dense output, shape ``(len(times), n)`` each.

    What ``np.asarray(segment(times)).T.reshape(len(times), -1)`` gives for every piece (a
    :class:`hybrid.continuous.FlowSegment` and its sample times), with the one-state closed forms
    (:class:`AffinePropagator`) evaluated together in one vectorised pass: a trace of a long run of short
    flows costs one numpy expression instead of one per flow.
    """
    out: list[np.ndarray | None] = [None] * len(pieces)
    group = [i for i, (seg, _) in enumerate(pieces)
             if isinstance(seg.dense, AffinePropagator) and seg.dense._scalar is not None]
    if len(group) > 1:
        sizes = np.array([pieces[i][1].size for i in group])
        params = np.array([(d.t0, *d._scalar) for d in (pieces[i][0].dense for i in group)])  # t0, a, b, x0
        t0, a, b, x0 = (np.repeat(params[:, k], sizes) for k in range(4))
        tau = np.concatenate([pieces[i][1] for i in group]) - t0
        z = a * tau
        linear = a == 0.0
        x = np.where(linear, x0 + b * tau, x0 * np.exp(z) + b * (np.expm1(z) / np.where(linear, 1.0, a)))
        column, start = x.reshape(-1, 1), 0
        for i, size in zip(group, sizes.tolist()):
            out[i] = column[start:start + size]
            start += size
    return [x if x is not None else np.asarray(seg(t)).T.reshape(t.size, -1) for x, (seg, t) in zip(out, pieces)]


def point_evaluator(interp: Any) -> Callable[[float], tuple[float, ...]]:
    """Fast scalar evaluation of a step's dense output (same formula as scipy's).

    scipy's ``DenseOutput.__call__`` costs ~15 µs for one time (array plumbing); event location calls it a
    dozen times per event, so the two explicit Runge–Kutta interpolants are evaluated here in plain floats
    (Horner's scheme), and an :class:`AffinePropagator` by its own scalar route.  Other solvers fall back to
    ``interp(t)``.
    """
    if isinstance(interp, AffinePropagator):
        return interp.point
    if isinstance(interp, _RkDenseOutput):
        t_old, h = float(interp.t_old), float(interp.h)
        rows = interp.Q.tolist()
        y_old = interp.y_old.tolist()

        def rk(t: float) -> tuple[float, ...]:
            x = (t - t_old) / h
            out = []
            for y0, q in zip(y_old, rows):
                acc = 0.0
                for c in reversed(q):
                    acc = acc * x + c
                out.append(y0 + h * x * acc)
            return tuple(out)

        return rk
    if isinstance(interp, _Dop853DenseOutput):
        t_old, h = float(interp.t_old), float(interp.h)
        layers = [f.tolist() for f in reversed(interp.F)]
        y_old = interp.y_old.tolist()

        def dop(t: float) -> tuple[float, ...]:
            x = (t - t_old) / h
            y = [0.0] * len(y_old)
            for i, f in enumerate(layers):
                factor = x if i % 2 == 0 else 1.0 - x
                y = [(a + b) * factor for a, b in zip(y, f)]
            return tuple(a + b for a, b in zip(y, y_old))

        return dop
    return lambda t: tuple(interp(t).tolist())


# ---------------------------------------------------------------------- events of a scalar affine mode
_FORMS: dict[tuple[Any, ...], tuple[Any, tuple[tuple[float, float], ...] | None]] = {}


def scalar_watch_forms(outgoing: Sequence[Any], invariant: Any, memory: Mapping[str, float]
                       ) -> tuple[tuple[float, float], ...] | None:
    """``(c_k, d_k)`` with ``phi_k = c_k x + d_k`` for every watch of a one-state mode, or ``None``.

    The watches are the guards of ``outgoing`` (``-g`` for a downward crossing) then the invariant's
    ``-inv`` (:func:`hybrid.watch_values.watch_terms`), read exactly; ``None`` when one is not symbolic or
    not affine in the state (a conjunction, ``abs``, ...).  Cached per guard objects and memory values.
    """
    key = (id(outgoing), id(invariant), tuple(sorted((k, float(v)) for k, v in memory.items())) if memory else ())
    hit = _FORMS.get(key)
    if hit is not None:
        return hit[1]
    from .watch_values import watch_terms

    terms = watch_terms(outgoing, invariant)
    forms: tuple[tuple[float, float], ...] | None = None
    if terms:
        memo: dict[int, tuple[list[float], float] | None] = {}
        read = [_form(term, 1, memory, memo) for term in terms]
        if all(f is not None for f in read):
            forms = tuple((f[0][0], f[1]) for f in read)  # type: ignore[index]
    if len(_FORMS) >= _CACHE_LIMIT:
        _FORMS.clear()
    _FORMS[key] = ((outgoing, invariant), forms)  # keeps the ids unique
    return forms


def _first_switch(flow: AffineFlow, x0: float, form: tuple[float, float], phi0: float, kind: str) -> float:
    """When ``phi = c x(τ) + d`` first switches on from ``phi0`` (``inf``: never); ``phi`` is monotone in ``τ``."""
    c, d = form
    off = phi0 <= 0.0 if (kind == "strict" or kind == "from_zero") else phi0 < 0.0
    _, a, b = flow.route  # ("scalar", a, b)
    if not off or c == 0.0 or c * (a * x0 + b) <= 0.0:  # on already (it cannot switch on again), or not rising
        return math.inf
    target = -d / c
    if a == 0.0:
        tau = (target - x0) / b
    else:
        rest = -b / a
        ratio = (target - rest) / (x0 - rest)
        if not ratio > 0.0:
            return math.inf
        tau = math.log(ratio) / a
    return tau if tau > 0.0 else 0.0 if tau == tau else math.inf


@dataclass(frozen=True, slots=True)
class ScalarSwitch:
    """The end of a one-state affine segment found on the closed form (see :func:`scalar_switch`).

    ``time``, ``state``: the segment's end; ``candidates``: the watches switched on there (empty: the horizon
    was reached); ``left_time``, ``left_state``, ``left_values``, ``values``: the final bracket, as
    :class:`hybrid.events.LocatedEvent`; ``evaluations``: of the watches.
    """

    time: float
    state: tuple[float, ...]
    values: list[float]
    candidates: list[int]
    left_time: float
    left_state: tuple[float, ...]
    left_values: list[float]
    evaluations: int

    def event(self, watches: Sequence[Any]) -> tuple[Any, tuple[int, ...]]:
        """The :class:`hybrid.events.LocatedEvent` (``None`` at the horizon) and the invariant or stop watches
        on there (as the executor's search reports them)."""
        if not self.candidates:
            return None, ()
        located = LocatedEvent(self.time, self.state, self.values, self.left_time, self.left_state, self.left_values)
        return located, tuple([k for k in self.candidates if watches[k].role != "guard"
                               and is_on(watches[k].kind, self.values[k])])


def scalar_switch(values: Callable[[float, tuple[float, ...]], list[float]], watches: Sequence[Any],
                  phi0: list[float], solver: ClosedFormSolver, flow: AffineFlow,
                  forms: Sequence[tuple[float, float]], event_tol: float) -> ScalarSwitch | None:
    """The first switch-on of a one-state affine mode's affine watches, on the closed form; ``None``: undecided.

    Each ``phi_k(τ) = c_k x(τ) + d_k`` is monotone (``x`` is), so it switches on at most once, at the root
    of the closed form: the earliest root ``τ*`` is computed, then the watches are *evaluated* (by
    ``values``, as the event search does) at ``t0 + τ*`` and ``event_tol`` before, the bracket moved by its
    width until nothing is on at its left end and a watch is on at its right end — the event search's
    result (:func:`hybrid.events.locate_event`: the right end of a bracket of width ``event_tol``), found
    without searching.  ``None`` (the caller runs the search instead) when rounding leaves it undecided.
    """
    prop = solver.propagator
    t0, t_end = prop.t0, solver.t_bound
    x0 = prop._scalar[2] if prop._scalar is not None else float(prop.x0[0])
    first = math.inf
    for form, phi, watch in zip(forms, phi0, watches):
        tau = _first_switch(flow, x0, form, phi, watch.kind)
        first = tau if tau < first else first
    evaluations = 1
    if not t0 + first <= t_end:
        state = prop.point(t_end)
        phi = values(t_end, state)
        if switched_on(watches, phi0, phi):
            return None
        return ScalarSwitch(time=t_end, state=state, values=phi, candidates=[], left_time=t_end, left_state=state,
                            left_values=phi, evaluations=evaluations)
    hi = max(t0 + first, math.nextafter(t0, math.inf))
    width = max(event_tol, 4.0 * math.ulp(max(abs(t0), abs(t_end))))
    step = math.ulp(hi)
    for _ in range(48):  # the root, rounded: move right until a watch is on, by 1, 4, 16, ... ulp up to the width
        state = prop.point(hi)
        phi = values(hi, state)
        evaluations += 1
        on = switched_on(watches, phi0, phi)
        if on:
            break
        if hi >= t_end:
            return None
        hi, step = min(hi + step, t_end), min(4.0 * step, width)
    else:
        return None
    for _ in range(16):  # then left until none is on at the bracket's left end
        lo = max(hi - width, t0)
        left_state = prop.point(lo) if lo > t0 else tuple(prop.x0.tolist())
        left = values(lo, left_state) if lo > t0 else phi0
        evaluations += lo > t0
        if not switched_on(watches, phi0, left):
            return ScalarSwitch(time=hi, state=state, values=phi, candidates=on, left_time=lo,
                                left_state=left_state, left_values=left, evaluations=evaluations)
        hi, state, phi, on = lo, left_state, left, switched_on(watches, phi0, left)
    return None


def closed_form_switch(solver: Any, values: Callable[[float, tuple[float, ...]], list[float]],
                       watches: Sequence[Any], phi: list[float], *, outgoing: Sequence[Any], invariant: Any,
                       memory: Mapping[str, float], system: Any, stops: bool, max_step: float,
                       event_tol: float, forms: Any = None) -> ScalarSwitch | None:
    """The end of a segment on the closed form (:func:`scalar_switch`) where it applies, else ``None``.

    It applies to a :class:`ClosedFormSolver` of a one-state mode whose watches (``phi``, their values at the
    start) are the affine guards of ``outgoing`` and the affine ``invariant`` of the state itself: the
    ``system`` has no output map, the run no stop function (``stops``) and no ``max_step`` (a step limit
    asks for the steps).  ``None``: the executor steps and searches as usual.  ``forms``: what
    :func:`scalar_watch_forms` gives for them, when the caller has it.
    """
    if not (isinstance(solver, ClosedFormSolver) and solver.propagator.x0.size == 1 and watches and not stops
            and system.output is None and max_step == math.inf):
        return None
    forms = scalar_watch_forms(outgoing, invariant, memory) if forms is None else forms
    if forms is None or len(forms) != len(watches):
        return None
    return scalar_switch(values, watches, phi, solver, solver.flow, forms, event_tol)
