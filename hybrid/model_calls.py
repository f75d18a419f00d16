"""The continuous executor's access to the user's model: every call counted, checked, its errors named.

:class:`ModelCalls` is what :func:`hybrid.continuous.simulate_continuous` calls the guards, invariants,
output map, flows, jump maps, resets and stop functions through, for one run: a fast path for a call that
returns a real number (symbolic guards and invariants through their compiled functions,
:func:`hybrid.watch_values.direct_function`; all the watches of a mode at once,
:func:`hybrid.watch_values.watch_function`), and on any doubt the checked path of
:class:`hybrid.system.HybridSystem`, which raises the error naming the function, the mode, the time and the
state (a :class:`~hybrid.errors.NumericalFailure` becomes a :class:`~hybrid.errors.DivergenceError`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .closed_form import AffineFlow, affine_flow, scalar_watch_forms
from .errors import DivergenceError, NumericalFailure
from .events import UnresolvedLog, Watch
from .model import Transition, not_a_number
from .system import HybridSystem, call_user, real_value
from .watch_values import direct_function, evaluate_watches, watch_function

__all__ = ["ModelCalls"]


class ModelCalls:
    """Calls into the user's model for one execution of :func:`hybrid.continuous.simulate_continuous`: counted,
    checked, errors named.

    Parameters
    ----------
    system : HybridSystem
    stops : Mapping[str, callable]
        The run's stop functions ``s(t, x, mode, memory)`` by name.
    invariant_tol : float
        How far below zero an invariant may be at a jump's landing point.
    """

    def __init__(self, system: HybridSystem, stops: Mapping[str, Callable[..., float]], invariant_tol: float) -> None:
        self.system = system
        self.automaton = system.automaton
        self.stops = dict(stops)
        self.invariant_tol = invariant_tol
        self.outgoing = {name: self.automaton.outgoing(name) for name in self.automaton.mode_names}
        self.invariants = {m.name: m.invariant for m in self.automaton.modes}
        self.crossing_names = frozenset(t.name for t in self.automaton.transitions if t.direction != 0)
        self.n_signals = len(self.automaton.variables)
        self.shape = (system.dimension,)
        self.guard_evaluations = 0
        self.refinement_evaluations = 0
        self.unresolved = UnresolvedLog()
        self.last_point: tuple[float, tuple[float, ...]] | None = None  # last accepted (t, x), for DivergenceError
        self.compiled: dict[str, Callable[..., tuple[float, ...]] | None] = {}  # per mode, see values()
        self.watch_sets: dict[str, tuple[Watch, ...]] = {}  # per mode, see watches()
        self.direct: dict[int, Callable[..., Any]] = {}  # id of a guard or invariant -> direct_function of it
        self.affine_flows: dict[str, AffineFlow | None] = {}  # per mode, see affine()
        self.forms: dict[str, Any] = {}  # per mode, see watch_forms()
        self.evaluators: dict[str, Any] = {}  # per mode, see evaluator()
        self.guard_sets: dict[int, Any] = {}  # id of a watch tuple -> (it, guard_watches of it)

    def diverged(self, err: NumericalFailure, mode: str, t: float, x: Sequence[float]) -> DivergenceError:
        """:class:`DivergenceError` for a :class:`NumericalFailure` raised at ``(t, x)`` in ``mode``.

        It carries the state at the last finite point: ``x`` itself, or the last
        accepted step point when ``x`` is not finite (a solver stage that blew up).
        """
        at: float = t
        try:
            state: tuple[float, ...] | None = tuple(float(c) for c in x)
        except (TypeError, ValueError):
            state = None
        if (state is None or not all(math.isfinite(c) for c in state)) and self.last_point is not None:
            at, state = self.last_point
        return DivergenceError(t, mode, err.cause, state=state, state_names=self.system.state_names, state_time=at)

    def call(self, fn: Callable[..., Any], what: str, mode: str, t: float, x: Sequence[float], *args: Any) -> Any:
        """A user function not reached through a :class:`HybridSystem` method (the stop functions)."""
        try:
            return call_user(fn, args, function=what, mode=mode, time=t, state=x,
                             state_names=self.system.state_names, system=self.system.name)
        except NumericalFailure as err:
            raise self.diverged(err, mode, t, x) from err

    def checked(self, method: Callable[..., Any], mode: str, t: float, x: Sequence[float], *args: Any) -> Any:
        """A :class:`HybridSystem` method (it names the failing function); a :class:`NumericalFailure` diverges."""
        try:
            return method(*args)
        except NumericalFailure as err:
            raise self.diverged(err, mode, t, x) from err

    def signals(self, mode: str, t: float, x: Sequence[float]) -> tuple[float, ...]:
        if self.system.output is None:  # HybridSystem.signals without the call: the state itself
            return tuple([float(c) for c in x])
        return self.checked(self.system.signals, mode, t, x, t, x, mode)

    def guard(self, tr: Transition, v: Sequence[float], memory: Mapping[str, float], t: float, x: Sequence[float]) -> float:
        self.guard_evaluations += 1
        g = self.fast(tr.guard, v, memory)  # on any doubt the checked path raises the precise error
        return g if g is not None else self.checked(self.system.guard, tr.source, t, x, tr, t, x, v, memory)

    def invariant(self, mode: str, v: Sequence[float], memory: Mapping[str, float], t: float, x: Sequence[float]) -> float:
        inv = self.invariants[mode]
        if inv is None:
            return math.inf
        value = self.fast(inv, v, memory)
        return value if value is not None else self.checked(self.system.invariant, mode, t, x, mode, t, x, v, memory)

    def fast(self, fn: Callable[..., Any], v: Sequence[float], memory: Mapping[str, float]) -> float | None:
        """``fn(v, memory)`` when it is a float and not NaN (a pure guard or invariant), else ``None``."""
        try:
            call = self.direct.get(id(fn))
            if call is None:
                call = self.direct[id(fn)] = direct_function(fn)
            g = call(v, memory)
            if type(g) is float and g == g:
                return g
        except Exception:
            pass
        return None

    def flow_function(self, mode: str, memory: Mapping[str, float]) -> Callable[[float, np.ndarray], np.ndarray]:
        """``fun(t, y)`` for the scipy solver in ``mode``: a fast path, and the checked one on any doubt."""
        user_flow = self.system.flows[mode]
        shape = self.shape

        def fun(tt: float, y: np.ndarray) -> np.ndarray:
            state = tuple(y.tolist())
            try:
                result = user_flow(tt, state, memory)
                total = sum(result)  # NaN (or inf - inf) makes it NaN
                if total == total:
                    out = np.array(result, dtype=float)
                    if out.shape == shape:
                        return out
            except Exception:
                pass
            return np.array(self.checked(self.system.flow, mode, tt, state, mode, tt, state, memory))

        return fun

    def watches(self, mode: str, memory: Mapping[str, float], t: float, x: Sequence[float]) -> tuple[Watch, ...]:
        """The watches of a segment starting at ``(t, x)`` (immutable: built once per mode)."""
        known = self.watch_sets.get(mode)
        if known is not None:
            return known
        out = [Watch(role="guard", name=tr.name, kind="level" if tr.direction == 0 else "crossing", transition=tr)
               for tr in self.outgoing[mode]]
        if self.invariants[mode] is not None:
            out.append(Watch(role="invariant", name=mode, kind="strict"))
        out += [Watch(role="stop", name=name, kind="level") for name in self.stops]
        self.watch_sets[mode] = tuple(out)
        return self.watch_sets[mode]

    def affine(self, mode: str, memory: Mapping[str, float]) -> AffineFlow | None:
        """:func:`hybrid.closed_form.affine_flow` of ``mode``'s flow (looked up once per mode without memory)."""
        if memory:
            return affine_flow(self.system.flows[mode], self.system.dimension, memory)
        hit = self.affine_flows.get(mode, self)
        if hit is self:
            hit = self.affine_flows[mode] = affine_flow(self.system.flows[mode], self.system.dimension, memory)
        return hit  # type: ignore[return-value]

    def watch_forms(self, mode: str, memory: Mapping[str, float]) -> Any:
        """:func:`hybrid.closed_form.scalar_watch_forms` of ``mode`` (looked up once per mode without memory)."""
        if memory:
            return scalar_watch_forms(self.outgoing[mode], self.invariants[mode], memory)
        hit = self.forms.get(mode, self)
        if hit is self:
            hit = self.forms[mode] = scalar_watch_forms(self.outgoing[mode], self.invariants[mode], memory)
        return hit

    def guard_watches(self, watches: tuple[Watch, ...]) -> tuple[list[tuple[int, int, float]], bool]:
        """``(k, id of the transition, sign of phi)`` of the guard watches, and whether one is a crossing."""
        known = self.guard_sets.get(id(watches))
        if known is None or known[0] is not watches:
            guards = [(k, w.transition) for k, w in enumerate(watches) if w.role == "guard"]
            known = self.guard_sets[id(watches)] = (watches, [
                (k, id(tr), -1.0 if tr.direction < 0 else 1.0) for k, tr in guards],  # type: ignore[union-attr]
                any(tr.direction != 0 for _, tr in guards))  # type: ignore[union-attr]
        return known[1], known[2]

    def evaluator(self, watches: Sequence[Watch], mode: str, memory: Mapping[str, float]
                  ) -> Callable[[float, Sequence[float]], list[float]]:
        """``values(t, x)``: :meth:`values` of ``watches`` in ``mode`` with ``memory``, the fast pass bound once
        (once per mode when the automaton has no memory)."""
        if not memory and not self.automaton.memory:
            known = self.evaluators.get(mode)
            if known is not None and known[0] is watches:
                return known[1]
            values = self._evaluator(watches, mode, {})
            self.evaluators[mode] = (watches, values)
            return values
        return self._evaluator(watches, mode, memory)

    def _evaluator(self, watches: Sequence[Watch], mode: str, memory: Mapping[str, float]
                   ) -> Callable[[float, Sequence[float]], list[float]]:
        compiled = self.compiled.get(mode, self) if not self.stops else None
        if compiled is self:
            compiled = self.compiled[mode] = watch_function(self.outgoing[mode], self.invariants[mode])
        if compiled is None:
            return lambda t, x: self.values(watches, mode, memory, t, x)
        output, n_signals, count = self.system.output, self.n_signals, len(watches)

        def values(t: float, x: Sequence[float]) -> list[float]:
            try:
                fast = evaluate_watches(compiled, output, t, x, memory, n_signals, count)
            except Exception:
                return self.values_checked(watches, mode, memory, t, x)
            self.guard_evaluations += count
            return fast

        def state_values(t: float, x: Sequence[float]) -> list[float]:  # evaluate_watches without an output map
            try:
                fast = [float(c) for c in compiled(x, memory)]
                if len(x) != n_signals or len(fast) != count:
                    raise ValueError
                for c in fast:
                    if c != c:
                        raise ValueError
                for c in x:
                    if c != c:
                        raise ValueError
            except Exception:
                return self.values_checked(watches, mode, memory, t, x)
            self.guard_evaluations += count
            return fast

        return values if output is not None else state_values

    def values(
        self, watches: Sequence[Watch], mode: str, memory: Mapping[str, float], t: float, x: Sequence[float]
    ) -> list[float]:
        """``phi`` of every watch (see :class:`Watch`).

        A fast pass calls the user functions directly (all the symbolic guards and the invariant of the
        mode as one compiled function, :func:`hybrid.watch_values.watch_function`); if anything raises or
        is not a real number, a careful pass re-evaluates them one by one and
        raises the error that names the culprit (the functions are pure).
        """
        compiled = self.compiled.get(mode, self) if not self.stops else None
        if compiled is self:
            compiled = self.compiled[mode] = watch_function(self.outgoing[mode], self.invariants[mode])
        if compiled is not None:
            try:
                fast = evaluate_watches(compiled, self.system.output, t, x, memory, self.n_signals, len(watches))
                self.guard_evaluations += len(watches)
                return fast
            except Exception:
                return self.values_checked(watches, mode, memory, t, x)
        try:
            v = x if self.system.output is None else self.system.output(t, x)
            if len(v) != self.n_signals:
                raise ValueError
            out = []
            for w in watches:
                if w.role == "guard":
                    tr = w.transition
                    raw = tr.guard(v, memory)  # type: ignore[union-attr]
                    if raw.__class__ is not float and raw.__class__ is not np.float64 and not_a_number(raw) is not None:
                        raise ValueError  # the careful pass names it
                    g = float(raw)
                    out.append(-g if tr.direction < 0 else g)  # type: ignore[union-attr]
                elif w.role == "invariant":
                    raw = self.invariants[mode](v, memory)  # type: ignore[misc]
                    if raw.__class__ is not float and raw.__class__ is not np.float64 and not_a_number(raw) is not None:
                        raise ValueError
                    out.append(-float(raw))
                else:
                    raw = self.stops[w.name](t, x, mode, memory)
                    if raw.__class__ is not float and raw.__class__ is not np.float64 and not_a_number(raw) is not None:
                        raise ValueError
                    out.append(float(raw))
            self.guard_evaluations += len(watches)
            for value in out:
                if value != value:
                    raise ValueError
            for value in v:
                if value != value:
                    raise ValueError
            return out
        except Exception:
            return self.values_checked(watches, mode, memory, t, x)

    def values_checked(
        self, watches: Sequence[Watch], mode: str, memory: Mapping[str, float], t: float, x: Sequence[float]
    ) -> list[float]:
        """:meth:`values` with every call wrapped: raises the precise error."""
        v = self.signals(mode, t, x)
        out = []
        for w in watches:
            if w.role == "guard":
                tr = w.transition
                assert tr is not None
                g = self.guard(tr, v, memory, t, x)
                out.append(-g if tr.direction < 0 else g)
            elif w.role == "invariant":
                out.append(-self.invariant(mode, v, memory, t, x))
            else:
                what = f"stop function {w.name!r}"
                s = self.call(self.stops[w.name], what, mode, t, x, t, x, mode, memory)
                out.append(real_value(s, what, mode, t, x))
        return out

    def jump(self, tr: Transition, x: tuple[float, ...], v: Sequence[float], memory: Mapping[str, float], t: float
             ) -> tuple[tuple[float, ...], dict[str, float]]:
        """The kernel's ``fire`` at time ``t``: jump map and memory reset, both reading pre-jump values."""
        if tr.reset is None and tr.name not in self.system.jumps:  # what HybridSystem.jump and .reset return
            return tuple([float(c) for c in x]), dict(memory)
        mode = tr.source
        new_x = self.checked(self.system.jump, mode, t, x, tr.name, t, x, memory)
        new_memory = self.checked(self.system.reset, mode, t, x, tr, t, x, v, memory)
        return new_x, new_memory
