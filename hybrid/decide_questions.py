"""The solver side of :mod:`hybrid.decide`: the symbolic view of a model (:class:`SymbolicView`), z3 frames, the
memory hulls, and the questions (:class:`Questions`: overlaps, deadlock, resets, instantaneous cycles, dwell
bounds) each answered with a proof or a re-checked witness.

See :mod:`hybrid.decide` for what "proven" assumes; that module assembles the answers into a
:class:`~hybrid.decide_results.Decision`.
"""

from __future__ import annotations

import itertools
import math
import time as _time
from collections.abc import Mapping, Sequence
from typing import Any

from .findings import KIND_SEVERITY, Finding, Oracle, Witness, format_g
from .instant import MAX_JUMPS_PER_INSTANT, settle_instant
from .model import Conjunction, HybridAutomaton, Transition
from .region import Box
from .smt import Translation, all_of, any_of, check_sat, compare, context, rational, to_float
from .symbolic import (
    Condition,
    Coordinate,
    Expr,
    SymbolicReset,
    SymbolicVector,
    diff,
    enclose,
    free_symbols,
    level_form,
    minimum,
    substitute,
)
from .system import HybridSystem
from .decide_results import PairVerdict, ParameterSpace

# Helpers shared with hybrid.decide have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = ["HULL_ROUNDS"]


HULL_ROUNDS = 12
"""Fixpoint rounds of the memory hulls before a still-growing variable is widened to the whole line."""

RECHECK_TOL = 1e-9
"""Relative tolerance of a witness re-check (a solver's rational rounded to floats)."""

DWELL_REL = 1e-9
"""Relative safety margin taken off a minimised dwell before it is verified as a lower bound."""

BISECTIONS = 12
"""Bisection steps of a dwell bound when the optimiser's value cannot be verified."""

RETRIGGER_PROBE = 1e-3
"""Half-width (fraction of each coordinate's width) of the neighbourhood of a re-triggering state examined
to tell a modelling defect (every neighbour re-triggers) from a Zeno point (one does not), as :mod:`hybrid.check`."""


# ====================================================================== the symbolic view of a model
class SymbolicView:
    """The model's functions as expressions over its coordinates (``None`` where a function is not symbolic)."""

    def __init__(self, model: HybridSystem | HybridAutomaton) -> None:
        self.oracle = Oracle(model)
        self.system = self.oracle.system
        self.automaton: HybridAutomaton = self.oracle.automaton
        self.coords = self.oracle.coords
        a = self.automaton
        self.memory_names = tuple(mv.name for mv in a.memory)
        self.signals: dict[str, Expr] | None = {}
        if self.system is not None and self.system.output is not None:
            out = self.system.output
            if isinstance(out, SymbolicVector) and len(out) == len(a.variables):
                self.signals = dict(zip(a.variables, out.components))
            else:
                self.signals = None
        self._cache: dict[tuple[str, str], Any] = {}

    def _in_coords(self, e: Expr) -> Expr:
        assert self.signals is not None
        return substitute(e, coordinates=self.signals) if self.signals else e

    def condition(self, fn: Any) -> Expr | None:
        """A guard or invariant over the coordinates, or ``None`` when it is not symbolic."""
        if isinstance(fn, Conjunction):
            terms = [self.condition(t) for t in fn.terms]
            return None if any(t is None for t in terms) else minimum(*terms)  # type: ignore[arg-type]
        if isinstance(fn, Condition):
            fn = level_form(fn)
        if not isinstance(fn, Expr) or self.signals is None:
            return None
        return self._in_coords(fn)

    def guard(self, t: Transition) -> Expr | None:
        key = ("guard", t.name)
        if key not in self._cache:
            self._cache[key] = self.condition(t.guard)
        return self._cache[key]

    def invariant(self, q: str) -> Expr | None | bool:
        """The invariant over the coordinates; ``True`` for "always"; ``None`` when not symbolic."""
        key = ("inv", q)
        if key not in self._cache:
            inv = self.automaton.mode(q).invariant
            self._cache[key] = True if inv is None else self.condition(inv)
        return self._cache[key]

    def reset(self, t: Transition) -> dict[str, Expr] | None:
        """New values of the written memory over (coordinates, pre-jump memory); ``{}`` without a reset."""
        if t.reset is None:
            return {}
        if not isinstance(t.reset, SymbolicReset) or self.signals is None:
            return None
        return {k: self._in_coords(e) for k, e in t.reset.assignments.items()}

    def jump(self, t: Transition) -> tuple[Expr, ...] | None:
        """Post-jump coordinates; the identity when the transition has no jump map."""
        identity = tuple(Coordinate(n, i) for i, n in enumerate(self.coords))
        if self.system is None:
            return identity
        r = self.system.jumps.get(t.name)
        if r is None:
            return identity
        if isinstance(r, SymbolicVector) and r.kind == "jump" and len(r) == len(self.coords):
            return r.components
        return None

    def flow(self, q: str) -> tuple[Expr, ...] | None:
        if self.system is None:
            return None
        f = self.system.flows[q]
        if isinstance(f, SymbolicVector) and f.kind == "flow" and len(f) == len(self.coords):
            if any(free_symbols(c)["time"] for c in f.components):
                return None
            return f.components
        return None


# ====================================================================== z3 frames
class _Frame:
    """One state point of a query: z3 reals for the coordinates and the memory."""

    def __init__(self, tag: str, coords: Sequence[str], memory_names: Sequence[str]) -> None:
        import z3

        self.tag = tag
        self.x = {n: z3.Real(f"{tag}.{n}", context()) for n in coords}
        self.m = {n: z3.Real(f"{tag}.m.{n}", context()) for n in memory_names}


class _Decider:
    def __init__(self, view: SymbolicView, boxes: Mapping[str, Box], *, rates: Mapping[str, float] | None,
                 timeout_s: float, tol: float, max_cycles: int, parameters: ParameterSpace | None = None) -> None:
        self.v = view
        self.a = view.automaton
        self.boxes = boxes
        self.declared_rates = dict(rates or {})
        self.timeout_s = timeout_s
        self.tol = tol
        self.max_cycles = max_cycles
        self.queries = 0
        self.solver_s = 0.0
        self.unknown: list[str] = []
        self.count = itertools.count()
        self._states: dict[tuple[Any, ...], Any] = {}
        self.param_vars: dict[str, Any] = {}
        self.param_bounds: dict[str, tuple[float, float]] = {}
        self.param_constraints: list[Any] = []
        if parameters is not None:
            self._free(parameters)
        self.hulls = self._memory_hulls()

    def _free(self, parameters: ParameterSpace) -> None:
        """Parameters as solver variables, within their bounds and under the assumptions."""
        import z3

        self.param_vars = {n: z3.Real(f"param.{n}", context()) for n in parameters.bounds}
        self.param_bounds = dict(parameters.bounds)
        for n, (lo, hi) in parameters.bounds.items():
            if math.isfinite(lo):
                self.param_constraints.append(self.param_vars[n] >= rational(lo))
            if math.isfinite(hi):
                self.param_constraints.append(self.param_vars[n] <= rational(hi))
        tr = Translation(coordinates={}, memory={}, params=self.param_vars, param_bounds=self.param_bounds,
                         prefix="param.aux")
        for c in parameters.assumptions:
            self.param_constraints.append(tr.term(c))
        self.param_constraints += tr.side

    # ------------------------------------------------------------------ solver
    def solve(self, constraints: list[Any], what: str) -> tuple[str, Any]:
        answer = check_sat([*constraints, *self.param_constraints], self.timeout_s)
        self.solver_s += answer.seconds
        self.queries += 1
        if answer.status == "unknown":
            self.unknown.append(f"{what}: undecided within {self.timeout_s:g} s ({answer.reason})")
        return answer.status, answer.model

    def minimise(self, constraints: list[Any], objective: Any, what: str) -> float | None:
        """The optimiser's minimum of ``objective`` (a candidate, verified by the caller), or ``None``."""
        import z3

        o = z3.Optimize(ctx=context())
        o.set("timeout", max(1, int(round(self.timeout_s * 1000))))
        o.add(*constraints)
        h = o.minimize(objective)
        start = _time.perf_counter()
        r = o.check()
        self.solver_s += _time.perf_counter() - start
        self.queries += 1
        if r != z3.sat:
            return None
        value = o.lower(h)
        try:
            return to_float(value)
        except Exception:  # noqa: BLE001 - an infinite or symbolic optimum: no candidate
            return None

    # ------------------------------------------------------------------ memory abstraction
    def _box_bounds(self, q: str) -> dict[str, tuple[float, float]]:
        b = self.boxes[q]
        out = {n: (float(lo), float(hi)) for n, (lo, hi) in b.bounds.items()}
        for n, values in b.choices.items():
            out[n] = (float(min(values)), float(max(values)))
        return out

    def _memory_hulls(self) -> dict[str, dict[str, tuple[float, float]] | None]:
        a = self.a
        hulls: dict[str, dict[str, tuple[float, float]] | None] = {q: None for q in a.mode_names}
        hulls[a.initial_mode] = {k: (c, c) for k, c in a.initial_memory().items()}
        growth: dict[tuple[str, str], int] = {}
        changed = True
        while changed:  # terminates: a (mode, variable) grows at most HULL_ROUNDS times before it is widened
            changed = False
            for t in a.transitions:
                src = hulls[t.source]
                if src is None or t.source not in self.boxes:
                    continue
                written = self.v.reset(t)
                bounds = self._box_bounds(t.source)
                new = {}
                for k in self.v.memory_names:
                    if k in t.writes:
                        e = None if written is None else written.get(k)
                        new[k] = ((-math.inf, math.inf) if e is None else
                                  enclose(e, bounds, src, param_bounds=self.param_bounds))
                    else:
                        new[k] = src[k]
                old = hulls[t.target]
                if old is None:
                    hulls[t.target] = new
                    changed = True
                    continue
                joined = {k: (min(old[k][0], new[k][0]), max(old[k][1], new[k][1])) for k in old}
                if joined != old:
                    for k in old:
                        if joined[k] != old[k]:
                            n = growth[(t.target, k)] = growth.get((t.target, k), 0) + 1
                            if n > HULL_ROUNDS:
                                joined[k] = (-math.inf, math.inf)
                    hulls[t.target] = joined
                    changed = True
        return hulls

    # ------------------------------------------------------------------ constraints
    def frame(self, hint: str) -> _Frame:
        return _Frame(f"{hint}#{next(self.count)}", self.v.coords, self.v.memory_names)

    def translation(self, f: _Frame, q: str) -> Translation:
        return Translation(coordinates=f.x, memory=f.m, params=self.param_vars, bounds=self._box_bounds(q),
                           memory_bounds=self.hulls[q] or {}, param_bounds=self.param_bounds, prefix=f"{f.tag}.aux")

    def box(self, f: _Frame, q: str) -> list[Any]:
        import z3

        b = self.boxes[q]
        out = []
        for n, (lo, hi) in b.bounds.items():
            out += [compare(">=", f.x[n], rational(float(lo))), compare("<=", f.x[n], rational(float(hi)))]
        for n, values in b.choices.items():
            out.append(any_of([compare("==", f.x[n], rational(float(c))) for c in values]))
        return out

    def hull(self, f: _Frame, q: str) -> list[Any]:
        out = []
        for k, (lo, hi) in (self.hulls[q] or {}).items():
            if math.isfinite(lo):
                out.append(compare(">=", f.m[k], rational(lo)))
            if math.isfinite(hi):
                out.append(compare("<=", f.m[k], rational(hi)))
        return out

    def enabled(self, tr: Translation, t: Transition, strict: bool = False) -> Any:
        g, zero = tr.term(self.v.guard(t)), rational(0.0)
        if t.direction < 0:
            return compare("<" if strict else "<=", g, zero)
        return compare(">" if strict else ">=", g, zero)

    def disabled(self, tr: Translation, t: Transition, margin: float = 0.0) -> Any:
        g = tr.term(self.v.guard(t))
        if t.direction < 0:
            return g > rational(margin) if margin else g > 0
        return g < -rational(margin) if margin else g < 0

    def inside(self, tr: Translation, q: str, strict: bool = False) -> list[Any]:
        inv = self.v.invariant(q)
        if inv is True or inv is None:
            return []
        term = tr.term(inv)
        return [term > 0 if strict else term >= 0]

    def entry(self, f: _Frame, q: str, only: Transition | None = None) -> tuple[list[Any], list[tuple[str, Any, _Frame]]]:
        """Constraints saying ``f.m`` is a memory the transitions entering ``q`` can write (module docstring).

        Returns the constraint and, per disjunct, ``(transition name or "initial", its formula, its pre-frame)``.
        """
        import z3

        if not self.v.memory_names:
            return [], []
        disjuncts: list[tuple[str, Any, _Frame | None]] = []
        if q == self.a.initial_mode and only is None:
            init = self.a.initial_memory()
            disjuncts.append(("initial", all_of([compare("==", f.m[k], rational(c)) for k, c in init.items()]), None))
        entering = [t for t in self.a.transitions if t.target == q and self.hulls[t.source] is not None
                    and t.source in self.boxes]
        if only is not None:
            entering = [only]
        for t in entering:
            p = self.frame(f"{f.tag}<{t.name}")
            tr = self.translation(p, t.source)
            parts = self.box(p, t.source) + self.hull(p, t.source) + self.inside(tr, t.source)
            if self.v.guard(t) is not None:
                parts.append(self.enabled(tr, t))
            written = self.v.reset(t)
            for k in self.v.memory_names:
                if k in t.writes:
                    if written is not None:
                        parts.append(compare("==", f.m[k], tr.term(written[k])))
                else:
                    parts.append(compare("==", f.m[k], p.m[k]))
            parts += tr.side
            disjuncts.append((t.name, all_of(parts), p))
        if not disjuncts:
            return [z3.BoolVal(False, context())], []
        return [any_of([d for _, d, _ in disjuncts])], disjuncts  # type: ignore[misc]

    def last_writers(self, q: str, k: str) -> list[Transition | None]:
        """Transitions that can have written memory ``k`` last when in ``q`` (``None``: its initial value)."""
        key = ("writers", q, k)
        if key not in self._states:
            out: list[Transition | None] = []
            starts: list[tuple[Transition | None, str]] = [(None, self.a.initial_mode)]
            starts += [(t, t.target) for t in self.a.transitions if k in t.writes and self.hulls[t.source] is not None]
            for writer, mode in starts:
                seen, stack = {mode}, [mode]
                while stack:
                    here = stack.pop()
                    for u in self.a.outgoing(here):
                        if k not in u.writes and u.target not in seen:
                            seen.add(u.target)
                            stack.append(u.target)
                if q in seen:
                    out.append(writer)
            self._states[key] = out
        return self._states[key]

    def written(self, f: _Frame, q: str, always: bool = False, names: Sequence[str] | None = None) -> list[Any]:
        """Each memory variable equals what one of its last writers can write.

        Sound like the hulls, and tighter for carried values: a value carried through modes that do
        not write it is still an image of its writer's reset, at a state where the writer was
        enabled (and, with free parameters, under the same parameters).  Used by parametric
        questions, and (``always``) to confirm a witness whose memory was carried.
        """
        import z3

        if not self.param_vars and not always:
            return []
        out = []
        for k in self.v.memory_names:
            if names is not None and k not in names:
                continue
            options = []
            for t in self.last_writers(q, k):
                if t is None:
                    options.append(compare("==", f.m[k], rational(self.a.initial_memory()[k])))
                    continue
                reset = self.v.reset(t)
                if reset is None or t.source not in self.boxes:
                    options.append(z3.BoolVal(True, context()))
                    continue
                p = self.frame(f"{f.tag}<{t.name}.{k}")
                tr = self.translation(p, t.source)
                parts = self.box(p, t.source) + self.hull(p, t.source) + self.inside(tr, t.source)
                if self.v.guard(t) is not None:
                    parts.append(self.enabled(tr, t))
                parts.append(compare("==", f.m[k], tr.term(reset[k])))
                options.append(all_of(parts + list(tr.side)))
            out.append(any_of(options))
        return out

    def state(self, q: str, only: Transition | None = None, strict: bool = False, role: str = "main",
              entry: bool = True, writers: frozenset[str] = frozenset()
              ) -> tuple[_Frame, list[Any], Translation, list[tuple[str, Any, _Frame]]]:
        """A point of ``q``: in its box, its memory reachable by the abstraction, inside its invariant.

        Frames and their constraints are built once per (mode, role) and reused by every query
        (each query is a fresh solver); the translation's domain conditions restart per query.
        """
        key = (q, None if only is None else only.name, strict, role, entry, writers)
        hit = self._states.get(key)
        if hit is None:
            # the frame, its translation and its entry formula are shared by every role whose queries hold
            # one point of the mode (each query is its own solver); only "pre" needs a frame of its own
            base_key = ("frame", q, None if only is None else only.name, "pre" if role == "pre" else "point", entry)
            base = self._states.get(base_key)
            if base is None:
                f = self.frame(f"{role} {q}")
                tr = self.translation(f, q)
                memory, disjuncts = self.entry(f, q, only) if entry else ([], [])
                base = self._states[base_key] = (f, tr, _conjoin(self.box(f, q) + self.hull(f, q) + memory),
                                                 disjuncts)
            f, tr, core, disjuncts = base
            tr.begin()
            inside = self.inside(tr, q, strict)
            last = self.written(f, q, bool(writers), sorted(writers) if writers else None)
            hit = (f, [core, _conjoin(last + inside + list(tr.side))], tr, disjuncts)
            self._states[key] = hit
        f, cons, tr, disjuncts = hit
        tr.begin()
        return f, list(cons), tr, disjuncts

    def landing(self, q: str, role: str) -> tuple[_Frame, list[Any], Translation]:
        """A point of ``q`` whose memory the caller fixes: box, hull and invariant only (cached)."""
        key = (q, "landing", False, role)
        hit = self._states.get(key)
        if hit is None:
            f = self.frame(f"{role} {q}")
            tr = self.translation(f, q)
            tr.begin()
            inside = self.inside(tr, q)
            hit = (f, [_conjoin(self.box(f, q) + self.hull(f, q) + inside + list(tr.side))], tr, [])
            self._states[key] = hit
        f, cons, tr, _ = hit
        tr.begin()
        return f, list(cons), tr

    # ------------------------------------------------------------------ witnesses
    def point(self, model: Any, f: _Frame) -> tuple[tuple[float, ...], dict[str, float]]:
        x = tuple(to_float(model.eval(f.x[n], model_completion=True)) for n in self.v.coords)
        m = {k: to_float(model.eval(f.m[k], model_completion=True)) for k in self.v.memory_names}
        return x, m

    def provenance(self, model: Any, disjuncts: list[tuple[str, Any, _Frame]], m: Mapping[str, float]
                   ) -> tuple[bool, dict[str, float], str]:
        """Re-check that ``m`` is written by an entering transition at the solver's pre-jump state."""
        if not disjuncts:
            return True, {}, ""
        for name, _formula, pre in disjuncts:  # each candidate checked numerically (no solver evaluation)
            if pre is None:
                init = self.a.initial_memory()
                if all(_close(m[k], c) for k, c in init.items()):
                    return True, {}, "initial memory"
                continue
            t = next(tr for tr in self.a.transitions if tr.name == name)
            x0, m0 = self.point(model, pre)
            o = self.v.oracle
            v0 = o.signals(x0, m0)
            g = o.guard(t, x0, v0, m0)
            _, post = o.jump(t, x0, v0, m0)
            enabled = g >= -self.tol * (1.0 + abs(g)) if t.direction >= 0 else g <= self.tol
            ok = enabled and all(_close(post[k], m[k]) for k in self.v.memory_names)
            if not ok:
                continue
            values = {f"entry {name} guard": g}
            values.update({f"entry {name} pre {n}": c for n, c in zip(self.v.coords, x0)})
            return ok, values, f"memory written by {name}"
        return False, {}, "no entering transition matches"

    def witness(self, x: tuple[float, ...], m: Mapping[str, float], values: Mapping[str, float]) -> Witness:
        o = self.v.oracle
        v = o.signals(x, m)
        return Witness(state=dict(zip(self.v.coords, x)), memory=dict(m),
                       signals=dict(zip(self.a.variables, v)), values=dict(values))


def _conjoin(constraints: list[Any]) -> Any:
    """One formula for a cached list of constraints (one assertion instead of many)."""
    return all_of(constraints)


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= RECHECK_TOL * (1.0 + abs(a) + abs(b))


# ====================================================================== the questions
class Questions(_Decider):
    """The checks of the module docstring, one method each."""

    def not_symbolic(self, q: str) -> str:
        """Why mode ``q`` cannot be decided (empty when every function the checks read is symbolic)."""
        v = self.v
        if v.signals is None:
            return "the output map is not symbolic"
        if v.invariant(q) is None:
            return "the invariant is not symbolic"
        for t in self.a.outgoing(q):
            if v.guard(t) is None:
                return f"the guard of {t.name!r} is not symbolic"
            if v.reset(t) is None:
                return f"the reset of {t.name!r} is not symbolic"
            if v.jump(t) is None:
                return f"the jump map of {t.name!r} is not symbolic"
            if t.target in self.boxes and v.invariant(t.target) is None:
                return f"the invariant of {t.target!r} is not symbolic"
        if v.invariant(q) is not True and v.system is not None and v.flow(q) is None:
            return "the flow is not symbolic (needed for the deadlock question)"
        return ""

    # ------------------------------------------------------------------ overlaps
    def carried(self, q: str, reads: Sequence[Any]) -> frozenset[str]:
        """The memory the functions ``reads`` read that some transition entering ``q`` only carries."""
        names: set[str] = set()
        for e in reads:
            if isinstance(e, (Expr, Condition)):
                names |= free_symbols(e)["memory"]
        out: set[str] = set()
        for t in self.a.transitions:
            if t.target == q:
                out |= names - set(t.writes)
        return frozenset(out)

    def pair(self, q: str, t1: Transition, t2: Transition) -> PairVerdict:
        same = t1.priority == t2.priority
        base = dict(mode=q, first=t1.name, second=t2.name, same_priority=same)
        if self.v.guard(t1) is None or self.v.guard(t2) is None or self.v.invariant(q) is None:
            return PairVerdict(**base, verdict="undecided", detail="a guard or the invariant is not symbolic")
        what = f"overlap of {t1.name} and {t2.name} in {q}"
        f, cons, tr, disjuncts = self.state(q)
        cons = cons + [self.enabled(tr, t1), self.enabled(tr, t2)] + tr.side
        status, model = self.solve(cons, what)
        carried = self.carried(q, [self.v.guard(t1), self.v.guard(t2), self.v.invariant(q)])
        if status == "sat" and not self.param_vars and carried:
            # the memory it reads may have been carried from a looser hull: confirm under its last writers
            f, cons, tr, disjuncts = self.state(q, role="confirm", writers=carried)
            cons = cons + [self.enabled(tr, t1), self.enabled(tr, t2)] + tr.side
            status, model = self.solve(cons, what)
        if status == "unsat":
            return PairVerdict(**base, verdict="exclusive", detail="proven: no state of the box enables both")
        if status == "unknown":
            return PairVerdict(**base, verdict="undecided",
                               detail=f"undecided within {self.timeout_s:g} s")
        x, m = self.point(model, f)
        if self.param_vars:
            return self._parametric_pair(base, model, x, m, t1, t2, disjuncts)
        o = self.v.oracle
        vv = o.signals(x, m)
        g1, g2 = o.guard(t1, x, vv, m), o.guard(t2, x, vv, m)
        inv = o.invariant(q, x, vv, m)
        ok_mem, values, how = self.provenance(model, disjuncts, m)
        ok = _on(g1, t1, self.tol) and _on(g2, t2, self.tol) and inv >= -self.tol * (1 + abs(inv)) and ok_mem
        values.update({f"guard {t1.name}": g1, f"guard {t2.name}": g2})
        if math.isfinite(inv):
            values[f"invariant {q}"] = inv
        w = self.witness(x, m, values)
        if not ok:
            return PairVerdict(**base, verdict="undecided", witness=w,
                               detail=f"the solver's witness does not re-check ({_approx_note(tr)}); {how}")
        return PairVerdict(**base, verdict="overlap", witness=w, detail=f"witness re-checked; {how}")

    def _parametric_pair(self, base: dict[str, Any], model: Any, x: tuple[float, ...], m: Mapping[str, float],
                         t1: Transition, t2: Transition, disjuncts: list[Any]) -> PairVerdict:
        """Re-check an overlap found with free parameters: the symbolic guards (and the memory's provenance:
        the entering transition's guard and reset) evaluated with the witness's parameter values."""
        from .symbolic import Const, evaluate

        values = {n: to_float(model.eval(z, model_completion=True)) for n, z in self.param_vars.items()}
        fixed = {n: Const(c) for n, c in values.items()}

        def at(e: Any, xx: Sequence[float], mm: Mapping[str, float]) -> float:
            return float(evaluate(substitute(e, params=fixed), xx, mm))

        g = [at(self.v.guard(t), x, m) for t in (t1, t2)]
        ok = _on(g[0], t1, self.tol) and _on(g[1], t2, self.tol)
        provenance = not disjuncts
        for name, _formula, pre in disjuncts:
            if pre is None:
                init = self.a.initial_memory()
                provenance = all(_close(m[k], c) for k, c in init.items())
            else:
                t = next(tr for tr in self.a.transitions if tr.name == name)
                x0, m0 = self.point(model, pre)
                written = self.v.reset(t) or {}
                post = {k: (at(written[k], x0, m0) if k in written else m0[k]) for k in self.v.memory_names}
                provenance = (_on(at(self.v.guard(t), x0, m0), t, self.tol)  # type: ignore[arg-type]
                              and all(_close(post[k], m[k]) for k in self.v.memory_names))
            if provenance:
                break
        w = self.witness(x, m, {f"guard {t1.name}": g[0], f"guard {t2.name}": g[1],
                                **{f"param {n}": c for n, c in values.items()}})
        if not ok or not provenance:
            why = "the guards do not re-check" if not ok else (
                "its memory is not written by an entering transition with these parameters (the interval hull of "
                "the memory loses its relation to the free parameters)")
            return PairVerdict(**base, verdict="undecided", witness=w, detail=f"the parametric witness: {why}")
        return PairVerdict(**base, verdict="overlap", witness=w,
                           detail="witness re-checked with the parameter values " +
                           ", ".join(f"{n} = {format_g(c)}" for n, c in values.items()))

    # ------------------------------------------------------------------ deadlock
    def deadlock(self, q: str) -> tuple[str, Finding | None, str]:
        """``("proven"|"found"|"undecided"|"skipped", finding, detail)`` for mode ``q``."""
        inv = self.v.invariant(q)
        if inv is True:
            return "proven", None, "no invariant"
        out = self.a.outgoing(q)
        if inv is None or any(self.v.guard(t) is None for t in out):
            return "skipped", None, "invariant or a guard not symbolic"
        flow = self.v.flow(q)
        if self.v.system is not None and flow is None:
            return "skipped", None, "flow not symbolic"
        f, cons, tr, disjuncts = self.state(q)
        cons.append(tr.term(inv) == 0)
        lie = None
        if flow is not None:
            lie = _lie(inv, flow, self.v.coords)
            cons.append(tr.term(lie) <= -rational(self.tol))
        cons += [self.disabled(tr, t, self.tol) for t in out] + tr.side
        status, model = self.solve(cons, f"deadlock in {q}")
        if status == "unsat":
            return "proven", None, ""
        if status == "unknown":
            return "undecided", None, f"undecided within {self.timeout_s:g} s"
        x, m = self.point(model, f)
        o = self.v.oracle
        vv = o.signals(x, m)
        value = o.invariant(q, x, vv, m)
        guards = {t.name: o.guard(t, x, vv, m) for t in out}
        rate = None if lie is None else _evaluate_lie(lie, x, m)
        ok_mem, values, how = self.provenance(model, disjuncts, m)
        ok = (abs(value) <= self.tol * 1e3 and all(not _on(g, t, 0.0) for t, g in zip(out, guards.values()))
              and (rate is None or rate < 0.0) and ok_mem)
        values.update({f"invariant {q}": value, **{f"guard {n}": g for n, g in guards.items()}})
        if rate is not None:
            values[f"d/dt invariant {q}"] = rate
        if not ok:
            return "undecided", None, f"witness does not re-check ({_approx_note(tr)})"
        text = self.a.mode(q).invariant_text or "inv"
        msg = (f"deadlock in mode {q!r}: at {self.v.oracle.where(x, m)} the state is on the boundary of the "
               f"invariant ({text} = {format_g(value)})"
               + ("" if rate is None else f", the flow leaves it (d/dt = {format_g(rate)})")
               + " and no outgoing transition is enabled (guards "
               + ", ".join(f"{n} = {format_g(g)}" for n, g in guards.items())
               + "); SMT witness, re-checked; widen a guard or the invariant")
        return "found", Finding(kind="deadlock", severity=KIND_SEVERITY["deadlock"], message=msg,
                                modes=(q,), witness=self.witness(x, m, values)), how

    # ------------------------------------------------------------------ resets
    def reset_outside(self, t: Transition) -> tuple[str, Finding | None, str]:
        inv_t = self.v.invariant(t.target)
        if inv_t is True:
            return "proven", None, ""
        jump, written, guard = self.v.jump(t), self.v.reset(t), self.v.guard(t)
        if inv_t is None or jump is None or written is None or guard is None:
            return "skipped", None, "a guard, reset, jump map or the target invariant is not symbolic"
        f, cons, tr, disjuncts = self.state(t.source)
        post_x = {n: tr.term(e) for n, e in zip(self.v.coords, jump)}
        post_m = {k: (tr.term(written[k]) if k in written else f.m[k]) for k in self.v.memory_names}
        after = Translation(coordinates=post_x, memory=post_m, bounds=_unbounded(self.v.coords),
                            prefix=f"{f.tag}.post")
        cons = cons + [self.enabled(tr, t), after.term(inv_t) <= -rational(self.tol)] + tr.side + after.side
        status, model = self.solve(cons, f"reset of {t.name}")
        if status == "unsat":
            return "proven", None, ""
        if status == "unknown":
            return "undecided", None, f"undecided within {self.timeout_s:g} s"
        x, m = self.point(model, f)
        o = self.v.oracle
        vv = o.signals(x, m)
        g = o.guard(t, x, vv, m)
        x2, m2 = o.jump(t, x, vv, m)
        landed = o.invariant(t.target, x2, o.signals(x2, m2), m2)
        ok_mem, values, how = self.provenance(model, disjuncts, m)
        ok = _on(g, t, self.tol) and landed < -self.tol * 0.5 and ok_mem
        values.update({f"guard {t.name}": g, f"invariant {t.target} after {t.name}": landed,
                       **{f"post {n}": c for n, c in zip(self.v.coords, x2)}})
        if not ok:
            return "undecided", None, f"witness does not re-check ({_approx_note(tr)})"
        msg = (f"the jump of {t.name!r} ({t.source} -> {t.target}) from {o.where(x, m)} lands outside the "
               f"invariant of {t.target!r} ({self.a.mode(t.target).invariant_text or 'inv'} = {format_g(landed)} < 0); "
               "SMT witness, re-checked; fix the jump map/reset or the guard")
        return "found", Finding(kind="reset_outside_invariant", severity=KIND_SEVERITY["reset_outside_invariant"],
                                message=msg, modes=(t.source, t.target), transitions=(t.name,),
                                witness=self.witness(x, m, values)), how

    # ------------------------------------------------------------------ instantaneous laps
    def lap(self, cycle: Sequence[Transition], role: str = "lap"
            ) -> tuple[str, Any, _Frame | None, list[Any]]:
        """Can the jumps of ``cycle`` follow one another at one instant and enable its first one again?"""
        if any(t.direction != 0 for t in cycle):
            return "unsat", None, None, []
        if any(self.v.guard(t) is None or self.v.jump(t) is None or self.v.reset(t) is None for t in cycle):
            return "unknown", None, None, []
        f, cons, tr, disjuncts = self.state(cycle[0].source, role=role)
        cons += self.lap_formula(f, tr, cycle)
        status, model = self.solve(cons, "instantaneous lap " + " -> ".join(t.name for t in cycle))
        return status, model, f, disjuncts

    def lap_formula(self, f: _Frame, tr: Translation, cycle: Sequence[Transition]) -> list[Any]:
        """The lap's conditions from state ``f``: each jump wins in turn (priorities), then the first is enabled."""
        cons: list[Any] = []
        m_terms = dict(f.m)
        sequence = list(cycle) + [cycle[0]]
        current = tr
        for i, t in enumerate(sequence):
            cons.append(self.enabled(current, t))
            cons += [self.disabled(current, u) for u in self.a.outgoing(t.source)
                     if u.direction == 0 and u.priority < t.priority and self.v.guard(u) is not None]
            if i == len(sequence) - 1:
                break
            jump, written = self.v.jump(t), self.v.reset(t)
            x_terms = {n: current.term(e) for n, e in zip(self.v.coords, jump)}  # type: ignore[arg-type]
            m_terms = {k: (current.term(written[k]) if k in written else m_terms[k])  # type: ignore[index]
                       for k in self.v.memory_names}
            cons += current.side
            current = Translation(coordinates=x_terms, memory=m_terms, bounds=_unbounded(self.v.coords),
                                  prefix=f"{f.tag}.j{i}")
        return cons + current.side

    def isolated(self, cycle: Sequence[Transition], w: Witness) -> tuple[str, dict[str, float]]:
        """Is there, within :data:`RETRIGGER_PROBE` of ``w`` (per coordinate width), a state enabling the
        cycle's first transition from which the lap does *not* happen?  ``("isolated", neighbour)``,
        ``("robust", {})`` (proven: every such state re-triggers) or ``("undecided", {})``."""
        import z3

        q0 = cycle[0].source
        f, cons, tr, _ = self.state(q0, role="neighbour")
        cons.append(self.enabled(tr, cycle[0]))
        cons.append(z3.Not(all_of(self.lap_formula(f, tr, cycle))))
        for n, (lo, hi) in self.boxes[q0].bounds.items():
            step = RETRIGGER_PROBE * (float(hi) - float(lo))
            c = w.state[n]
            cons += [f.x[n] >= rational(c - step), f.x[n] <= rational(c + step)]
        for n in self.boxes[q0].choices:
            cons.append(f.x[n] == rational(w.state[n]))
        for k, c in w.memory.items():
            cons.append(f.m[k] == rational(c))
        cons += tr.side
        status, model = self.solve(cons, "neighbourhood of a re-triggering state")
        if status == "sat":
            x, _ = self.point(model, f)
            return "isolated", {f"neighbour {n}": c for n, c in zip(self.v.coords, x)}
        return ("robust", {}) if status == "unsat" else ("undecided", {})

    def lap_witness(self, cycle: Sequence[Transition], model: Any, f: _Frame,
                    disjuncts: list[Any]) -> Witness | None:
        """Re-check a lap witness on the executors' instant rule: ``cycle[0]`` fires and wins again."""
        first = cycle[0]
        o = self.v.oracle
        x, m = self.point(model, f)
        vv = o.signals(x, m)
        g = o.guard(first, x, vv, m)
        if g < -self.tol * (1 + abs(g)):
            return None
        ok_mem, values, _ = self.provenance(model, disjuncts, m)
        if not ok_mem:
            return None
        x1, m1 = o.jump(first, x, vv, m)

        def signals(_q: str, state: tuple[float, ...]) -> tuple[float, ...]:
            return o.signals(state, m1)

        def fire(u: Transition, state: Any, vs: Sequence[float], mm: Mapping[str, float]) -> Any:
            return o.jump(u, state, vs, mm)

        instant = settle_instant(o.outgoing, first.target, x1, m1, signals=signals,
                                 guard=lambda u, vs, mm: o.guard(u, x1, vs, mm), fire=fire, ties="record",
                                 max_jumps=max(len(cycle) + 1, MAX_JUMPS_PER_INSTANT), stop_before=first)
        if not instant.stopped:
            return None
        values.update({f"guard {first.name}": g,
                       "chain": float(len(instant.jumps) + 1)})
        values.update({f"post {n}": c for n, c in zip(self.v.coords, x1)})
        return self.witness(x, m, values)

    # ------------------------------------------------------------------ dwell bounds
    def rates(self, q: str) -> dict[str, float]:
        """``|dx_j/dt| <= R_j`` in mode ``q``: declared, else the enclosure of a symbolic flow, else inf."""
        out = {n: math.inf for n in self.v.coords}
        flow = self.v.flow(q)
        if flow is not None and q in self.boxes:
            bounds = self._box_bounds(q)
            for n, e in zip(self.v.coords, flow):
                lo, hi = enclose(e, bounds, self.hulls[q] or {})
                out[n] = max(abs(lo), abs(hi))
        for n, r in self.declared_rates.items():
            out[n] = min(out[n], float(r))
        return out

    def dwell(self, t_in: Transition, t_out: Transition) -> tuple[float, str]:
        """Proven lower bound on the time between ``t_in`` entering a mode and ``t_out`` leaving it."""
        q = t_in.target
        rates = self.rates(q)
        if all(math.isinf(r) for r in rates.values()):
            return 0.0, "no rate bound"
        if any(self.v.guard(t) is None for t in (t_in, t_out)) or self.v.jump(t_in) is None \
                or self.v.reset(t_in) is None:
            return 0.0, "not symbolic"
        shortcut = self.independent_exit(t_in, t_out)
        if shortcut is not None:
            return shortcut
        import z3

        pre, cons, tr, _ = self.state(t_in.source, role="pre", entry=False)
        b, landing, tb = self.landing(q, "exit")
        cons.append(self.enabled(tr, t_in))
        jump, written = self.v.jump(t_in), self.v.reset(t_in)
        cons += [b.m[k] == (tr.term(written[k]) if k in written else pre.m[k])  # type: ignore[index]
                 for k in self.v.memory_names]
        a_x = {n: tr.term(e) for n, e in zip(self.v.coords, jump)}  # type: ignore[arg-type]
        after = Translation(coordinates=a_x, memory=b.m, bounds=_unbounded(self.v.coords), prefix=f"{b.tag}.a")
        cons += tr.side + self.inside(after, q) + after.side
        cons += landing + [self.enabled(tb, t_out)] + tb.side
        s = z3.Real(f"{b.tag}.s", context())
        moves = []
        for n, r in rates.items():
            if math.isinf(r):
                continue
            delta = b.x[n] - a_x[n]
            if r == 0.0:
                moves.append(delta == 0)
            else:
                moves += [delta <= s * rational(r), -delta <= s * rational(r)]
        what = f"dwell between {t_in.name} and {t_out.name}"
        candidate = self.minimise(cons + moves + [s >= 0], s, what)
        if candidate is not None and candidate <= 0.0:
            return 0.0, ""
        if candidate is None:
            status, _ = self.solve(cons + moves + [s >= 0], what)
            if status == "unsat":
                return math.inf, "infeasible"
            if status != "sat":
                return 0.0, "undecided"
        if candidate is not None and candidate > 0.0:
            bound = candidate * (1.0 - DWELL_REL)
            status, _ = self.solve(cons + moves + [s >= 0, s <= rational(bound)], what)
            if status == "unsat":
                return bound, _binding(q, t_in, t_out)
        low, high = 0.0, max((w / rates[n] for n, w in _widths(self.boxes[q]).items()
                              if rates.get(n, math.inf) not in (0.0, math.inf)), default=1.0)
        for _ in range(BISECTIONS):
            mid = 0.5 * (low + high)
            status, _ = self.solve(cons + moves + [s >= 0, s <= rational(mid)], what)
            if status == "unsat":
                low = mid
            else:
                high = mid
        return low, _binding(q, t_in, t_out) if low > 0.0 else ""

    def _symbols(self, e: Any) -> set[str]:
        if not isinstance(e, (Expr, Condition)):
            return set()
        f = free_symbols(e)
        return {f"x.{n}" for n in f["coordinates"]} | {f"m.{n}" for n in f["memory"]}

    def independent_exit(self, t_in: Transition, t_out: Transition) -> tuple[float, str] | None:
        """The dwell of a pair whose exit reads nothing the entry constrains, without the optimiser.

        When ``t_out``'s guard shares no coordinate or memory with ``t_in``'s guard and reset (nor
        with an invariant), ``t_in``'s jump is the identity and both modes have the same box, the
        query splits into two independent parts over a product of intervals: ``t_out`` can then
        fire at the very state ``t_in`` lands on (dwell 0) iff its guard holds somewhere on the box
        with the memory it reads in the source's hull, and never otherwise (infeasible).  ``None``
        when the shortcut does not apply.
        """
        q = t_in.target
        jump = self.v.jump(t_in)
        if jump is None or any(not (isinstance(e, Coordinate) and e.name == n) for e, n in zip(jump, self.v.coords)):
            return None
        if self.v.invariant(q) is not True or self.v.invariant(t_in.source) is not True:
            return None
        if self.boxes[q] != self.boxes[t_in.source]:
            return None
        written = self.v.reset(t_in) or {}
        entry = self._symbols(self.v.guard(t_in)) | {f"m.{k}" for k in t_in.writes}
        for e in written.values():
            entry |= self._symbols(e)
        exit_reads = self._symbols(self.v.guard(t_out))
        if exit_reads & entry:
            return None
        hull = self.hulls[t_in.source] or {}
        reads = sorted(n[2:] for n in exit_reads if n.startswith("m."))
        key = ("fires", t_out.name, tuple((k, hull.get(k)) for k in reads))
        if key not in self._states:
            f, cons, tr = self.landing(q, "fires")
            cons = [c for c in self.box(f, q)] + [self.enabled(tr, t_out)] + tr.side
            for k in reads:
                lo, hi = hull.get(k, (-math.inf, math.inf))
                if math.isfinite(lo):
                    cons.append(f.m[k] >= rational(lo))
                if math.isfinite(hi):
                    cons.append(f.m[k] <= rational(hi))
            status, _ = self.solve(cons, f"dwell exit {t_out.name}")
            self._states[key] = status
        status = self._states[key]
        if status == "sat":
            return 0.0, ""
        if status == "unsat":
            return math.inf, "infeasible"
        return None

    def projection(self, t: Transition, n: str, entry: bool) -> tuple[float, float]:
        """A sound interval of coordinate ``n`` over the states where ``t`` can fire (verified optimum).

        ``entry``: the source's memory as its entering transitions write it (tighter); otherwise within
        its hull only (cheaper, and as sound).
        """
        lo_box, hi_box = self._box_bounds(t.source)[n]
        guard = self.v.guard(t)
        if guard is None or n not in free_symbols(guard)["coordinates"]:
            return lo_box, hi_box
        if entry:
            f, cons, tr, _ = self.state(t.source)
        else:
            f, cons, tr = self.landing(t.source, "projection")
        cons = cons + [self.enabled(tr, t)] + tr.side
        out = []
        for sign in (1.0, -1.0):
            target = f.x[n] if sign > 0 else -f.x[n]
            best = self.minimise(cons, target, f"projection of {t.name} on {n}")
            fallback = lo_box if sign > 0 else -hi_box
            if best is None or not math.isfinite(best):
                out.append(fallback)
                continue
            margin = 1e-12 * (1.0 + abs(best))
            status, _ = self.solve(cons + [target < rational(best - margin)], f"projection of {t.name} on {n}")
            out.append(best - margin if status == "unsat" else fallback)
        return max(out[0], lo_box), min(-out[1], hi_box)


def _on(g: float, t: Transition, tol: float) -> bool:
    """Whether guard value ``g`` counts as enabled (within ``tol``) for ``t``'s direction."""
    if t.direction < 0:
        return g <= tol * (1.0 + abs(g))
    return g >= -tol * (1.0 + abs(g))


def _lie(inv: Expr, flow: Sequence[Expr], coords: Sequence[str]) -> Expr:
    total: Expr | None = None
    for n, f in zip(coords, flow):
        term = diff(inv, n) * f
        total = term if total is None else total + term
    assert total is not None
    return total


def _evaluate_lie(lie: Expr, x: Sequence[float], m: Mapping[str, float]) -> float:
    from .symbolic import evaluate

    return float(evaluate(lie, x, m))


def _unbounded(coords: Sequence[str]) -> dict[str, tuple[float, float]]:
    return {n: (-math.inf, math.inf) for n in coords}


def _widths(b: Box) -> dict[str, float]:
    return {n: float(hi) - float(lo) for n, (lo, hi) in b.bounds.items()}


def _binding(q: str, t_in: Transition, t_out: Transition) -> str:
    return f"in {q} between {t_in.name} and {t_out.name}"


def _approx_note(tr: Translation) -> str:
    if tr.approximated:
        return "transcendental terms enclosed by intervals: " + ", ".join(sorted(set(tr.approximated))[:3])
    return "rounding of the solver's rationals"
