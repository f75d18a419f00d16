"""Deadlock freedom where a flow can leave its invariant, decided exactly on the part of the face it reaches.

The executor ends a run early when a flow leaves its mode's invariant while no guard is enabled (a deadlock);
reachability proves nothing about such runs.  :func:`face_uncovered` checks, for boxes holding every flowed
state of a mode (the producer's segment boxes, or the re-check's own pieces), that each state on the boundary of
the invariant lies in an outgoing guard:

* the invariant is one polyhedron ``{a_i·x <= b_i}`` (a disjunctive one is refused with a message);
* for each row ``a·x <= b`` and each box that may reach it (``max a·x >= b`` over the box), the *face part*
  ``box ∩ {a·x = b} ∩ invariant ∩ {a·ẋ >= 0 possible}`` (an affine flow: where the flow, with any input, may
  point outward or along the face; :func:`outward_row`) is enclosed by exact box clipping (rationals; optionally narrowed by a
  callback, e.g. the re-check's zonotope), and ``that box ∩ {a·x = b}`` must lie in one guard polyhedron of an
  outgoing transition (exact: ``max g·x <= e`` over it for every row ``g·x <= e`` of the guard, by LP duality with
  the one equality, :func:`_in_on_face`).

A flowing state that leaves the invariant does so through a face point that it reaches while flowing, so that
point is in a flowed box and in the face part: every exit is covered.

*The horizon.*  A run that reaches a face at a time ``>= H`` (``H`` at or after the requirement window's end) is
complete over the window: the run is over, no guard needs to be enabled there.  Times are read through a *clock*
(:func:`clock_offsets`): a state ``x_i`` with ``ẋ_i = 1`` exactly in the mode (a zero row of ``A``, ``c_i = 1``,
no input on it).  Along a flowpipe ``x_i(τ) − τ = d`` is constant, with ``d <= x_i^entry_hi − τ_entry_lo`` over
its entry box and entry times; a state reached at a time ``τ < H`` has ``x_i = τ + d < H + d_hi``.  So a face part
whose ``x_i >= H + d_hi`` everywhere (:func:`reached_late`) holds no state reached before ``H`` and is skipped.
The building's clock face ``t <= 20``, reached exactly at the 20 s horizon, is no deadlock; the same face reached
before the horizon still is.  The check is sufficient, not necessary
(a face part covered only by a union of guards fails it).  A whole-face test (the closed outside of the row lies
in one guard: the earlier check) accepts a row at once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from fractions import Fraction
from typing import Any

__all__ = ["face_uncovered", "clip_exact", "box_in_polyhedron", "FaceRow", "open_rows", "outward_row", "bounded_on",
           "image_covered", "entry_uncovered", "clock_offsets", "reached_late",
           "contract_zonotope"]

Box = list[tuple[Fraction, Fraction]]


class FaceRow:
    """``−a·x <= −b`` (the closed outside of an invariant row), duck-typed like a model halfspace."""

    __slots__ = ("normal", "offset", "text")

    def __init__(self, normal: Sequence[Fraction], offset: Fraction) -> None:
        self.normal = tuple(-v for v in normal)
        self.offset = -offset
        self.text = ""


def clip_exact(box: Box, rows: Sequence[Any], rounds: int = 2) -> Box | None:
    """A box holding ``box ∩ {a·x <= b for each row}`` (exact interval propagation, ``rounds`` rounds over the
    rows); ``None``: empty.
    Only the coordinates the rows read (non-zero coefficients) are read and changed; the others are returned as
    given (a caller may leave them ``None``)."""
    out = list(box)
    sparse = [(h, [(i, ai) for i, ai in enumerate(h.normal) if ai]) for h in rows]  # zero terms change nothing
    for _ in range(rounds):
        for h, terms in sparse:
            b = h.offset
            mins = {i: min(ai * out[i][0], ai * out[i][1]) for i, ai in terms}
            total = sum(mins.values(), Fraction(0))
            if total > b:
                return None
            for i, ai in terms:
                room = (b - (total - mins[i])) / ai
                lo, hi = out[i]
                out[i] = (lo, min(hi, room)) if ai > 0 else (max(lo, room), hi)
                if out[i][0] > out[i][1]:
                    return None
    return out


def contract_zonotope(center: Sequence[Fraction], gens: Sequence[Sequence[Fraction]], rows: Sequence[Any],
                      rounds: int) -> Box | None:
    """A box holding ``{center + Σ_j ξ_j gens[j] : ξ ∈ [-1, 1]^p} ∩ {a·x <= b for each row}`` (exact rationals).

    The weights ``ξ`` are narrowed row by row by interval propagation, ``rounds`` times over the rows; the box
    of the narrowed zonotope is returned, ``None`` when the intersection is shown empty.  Zero coefficients
    add exactly 0 and are skipped."""
    lo, hi = [Fraction(-1)] * len(gens), [Fraction(1)] * len(gens)
    for _ in range(rounds):
        for row in rows:
            a, b = row.normal, row.offset
            nonzero = [(i, ai) for i, ai in enumerate(a) if ai != 0]
            g = [sum((ai * col[i] for i, ai in nonzero if col[i]), Fraction(0)) for col in gens]
            mins = [min(gj * l, gj * u) if gj else Fraction(0) for gj, l, u in zip(g, lo, hi)]
            total = sum((ai * center[i] for i, ai in nonzero), Fraction(0)) + sum(mins, Fraction(0))
            if total > b:
                return None
            for j, gj in enumerate(g):
                if gj == 0:
                    continue
                room = (b - (total - mins[j])) / gj
                if gj > 0:
                    hi[j] = min(hi[j], room)
                else:
                    lo[j] = max(lo[j], room)
                if lo[j] > hi[j]:
                    return None
                narrowed = min(gj * lo[j], gj * hi[j])
                total += narrowed - mins[j]  # exact rationals: the sum with mins[j] replaced
                mins[j] = narrowed
    return [(c + sum((min(col[i] * l, col[i] * u) for col, l, u in zip(gens, lo, hi) if col[i]), Fraction(0)),
             c + sum((max(col[i] * l, col[i] * u) for col, l, u in zip(gens, lo, hi) if col[i]), Fraction(0)))
            for i, c in enumerate(center)]


def _top(a: Sequence[Fraction], box: Box) -> Fraction:
    return sum((max(ai * lo, ai * hi) for ai, (lo, hi) in zip(a, box) if ai), Fraction(0))


def box_in_polyhedron(box: Box, poly: Any) -> bool:
    """Whether the box lies in the polyhedron (exact)."""
    return all(_top(h.normal, box) <= h.offset for h in poly.halfspaces)


def _in_on_face(box: Box, poly: Any, face: Any) -> bool:
    """Whether ``box ∩ {a·x = b}`` lies in the polyhedron (exact): for a row ``g·x <= e``, on the face
    ``g·x = (g − μa)·x + μb`` for every ``μ``, so ``max g·x <= min_μ [max_box (g − μa)·x + μb]``; the minimum
    of this convex piecewise-linear function of ``μ`` is at ``μ = 0`` or a breakpoint ``g_i/a_i`` (LP duality with
    one equality), all tried exactly."""
    a, b = face.normal, face.offset
    for h in poly.halfspaces:
        g, e = h.normal, h.offset
        if _top(g, box) <= e:
            continue
        candidates = {Fraction(0), *(gi / ai for gi, ai in zip(g, a) if ai)}
        if not any(_top([gi - mu * ai for gi, ai in zip(g, a)], box) + mu * b <= e for mu in candidates):
            return False
    return True


def _whole_face_in(a: Sequence[Fraction], b: Fraction, row: Any) -> bool:
    """Whether ``{x : a·x >= b}`` lies in ``{x : g·x <= e}`` (exact: ``g = −λ a``, ``λ >= 0``, ``−λ b <= e``)."""
    g, e = row.normal, row.offset
    if not any(g):
        return e >= 0
    k = next((i for i, v in enumerate(a) if v != 0), None)
    if k is None:
        return False
    lam = -g[k] / a[k]
    return lam >= 0 and all(gi == -lam * ai for gi, ai in zip(g, a)) and -lam * b <= e


def open_rows(model: Any, mode: str, inputs: Any = None) -> list[Any]:
    """The rows of a one-polyhedron invariant whose whole closed outside no single guard polyhedron holds and
    through which a flow may leave (the rows :func:`face_uncovered` must look at; a row ``a·x <= b`` with
    ``a·ẋ <= 0`` for every state and input, e.g. the bounds of a constant, is left out: ``a·x`` never increases,
    :func:`outward_row`); every row of a disjunctive invariant.  ``inputs`` as in :func:`outward_row`."""
    invariant = model.modes[mode].invariant
    rows = [h for poly in invariant for h in poly.halfspaces]
    if len(invariant) != 1:
        return rows
    guards = [poly for t in model.outgoing(mode) for poly in t.guard]
    out = []
    for h in rows:
        if any(all(_whole_face_in(h.normal, h.offset, g) for g in poly.halfspaces) for poly in guards):
            continue
        row = outward_row(model, mode, h, inputs)
        if row is not None and not any(row.normal) and row.offset < 0:
            continue  # never increases: nothing leaves through this face
        out.append(h)
    return out


def outward_row(model: Any, mode: str, row: Any, inputs: Any = None) -> FaceRow | None:
    """The states where the flow may point out of ``row`` (``a·x <= b``): ``a·(A x + c) + max_u a·B u >= 0``, as a
    row ``−(aA)·x <= a·c + max_u a·B u``; ``None`` for a nonlinear mode (no such restriction).

    A state on the face where this is negative moves strictly inside (continuity of the solution and of the bound,
    for every measurable input): it cannot leave there.  When ``aA = 0`` the bound is a constant ``d``; ``d <= 0``
    means ``a·x`` never increases along any solution, so nothing leaves through the face (an infeasible row).  ``inputs`` is ``(B, low, high)`` (exact) or ``None``.
    """
    m = model.modes[mode]
    if getattr(m, "smooth", None) is not None or m.a is None:
        return None
    a = row.normal
    n = len(a)
    aa = [sum((a[i] * m.a[i][j] for i in range(n) if a[i]), Fraction(0)) for j in range(n)]
    offset = sum((ai * ci for ai, ci in zip(a, m.c) if ai), Fraction(0))
    if inputs is not None:
        b, low, high = inputs
        ab = [sum((a[i] * b[i][k] for i in range(n) if a[i]), Fraction(0)) for k in range(len(low))]
        offset += sum((max(v * lo, v * hi) for v, lo, hi in zip(ab, low, high)), Fraction(0))
    out = FaceRow(aa, Fraction(0))
    out.offset = offset
    if not any(aa) and offset <= 0:  # a·ẋ <= offset <= 0 everywhere: a·x never increases, nothing leaves here
        out.offset = Fraction(-1)
    return out


def clock_offsets(model: Any, mode: str, entry: Box, t_lo: Fraction, inputs: Any = None) -> dict[int, Fraction]:
    """``{i: d_hi}`` for each clock ``x_i`` of ``mode`` (``ẋ_i = 1`` exactly, no input on it): ``x_i − τ <= d_hi``
    along a flowpipe entered in ``entry`` (a box holding the entry set) at times ``>= t_lo`` (see the module)."""
    m = model.modes[mode]
    if getattr(m, "smooth", None) is not None or m.a is None:
        return {}
    out = {}
    for i, (row, c) in enumerate(zip(m.a, m.c)):
        if c != 1 or any(row):
            continue
        if inputs is not None and any(inputs[0][i]):
            continue
        out[i] = entry[i][1] - t_lo
    return out


def reached_late(face: Box, offsets: dict[int, Fraction], horizon: Fraction) -> bool:
    """Whether every state of ``face`` is reached at a time ``>= horizon`` by the clocks ``offsets``
    (:func:`clock_offsets`): ``x_i >= horizon + d_hi`` on the whole box for one clock ``x_i``."""
    return any(face[i][0] >= horizon + d for i, d in offsets.items())


def face_uncovered(model: Any, mode: str, parts: Iterable[tuple[Box, Callable[[Sequence[Any]], Box | None] | None]],
                   where: Callable[[int], str] | None = None, inputs: Any = None,
                   late: Callable[[int, Box], bool] | None = None) -> str | None:
    """``None`` when every face part of the boxes lies in a guard of ``mode`` (see the module); else the message.

    Parameters
    ----------
    model : AffineHybridModel
    mode : str
    parts : iterable of (box, narrow)
        Boxes (exact rationals) holding the flowed states of the mode; ``narrow(rows)`` (or ``None``) returns a
        box holding the set ∩ the rows (``None``: empty), intersected with the clipped box.
    inputs : (B, low, high) or None
        The mode's bounded input (exact), for the flow's direction (:func:`outward_row`).
    where : callable or None
        ``where(i)`` names the ``i``-th box in the message.
    late : callable or None
        ``late(i, face)`` true when every state of the ``i``-th box's face part is reached at or after the horizon
        (:func:`reached_late`): such a part needs no guard (the run is over).
    """
    invariant = model.modes[mode].invariant
    if len(invariant) == 1 and not invariant[0].halfspaces:
        return None
    if len(invariant) != 1:
        return f"mode {mode!r}: a disjunctive invariant (deadlock freedom at its exits is not checked)"
    rows = list(invariant[0].halfspaces)
    guards = [poly for t in model.outgoing(mode) for poly in t.guard]
    remaining = open_rows(model, mode, inputs)
    if not remaining:
        return None
    outward = {id(h): outward_row(model, mode, h, inputs) for h in remaining}
    for i, (box, narrow) in enumerate(parts):
        for h in remaining:
            if _top(h.normal, box) < h.offset:
                continue
            face_rows = [*rows, FaceRow(h.normal, h.offset)]
            if outward[id(h)] is not None:
                face_rows.append(outward[id(h)])
            face = clip_exact(box, face_rows)
            if face is not None and narrow is not None:
                tight = narrow(face_rows)
                face = None if tight is None else _meet(face, tight)
            if face is None or any(_in_on_face(face, poly, h) for poly in guards):
                continue
            if late is not None and late(i, face):
                continue
            place = f" ({where(i)})" if where is not None else ""
            return (f"mode {mode!r}: where the flow may leave the invariant ({h.text or 'a face'}){place}, the states "
                    f"[{[float(lo) for lo, _ in face]}, {[float(hi) for _, hi in face]}] lie in no guard "
                    "(a possible deadlock: the run would end early)")
    return None


def _meet(a: Box, b: Box) -> Box | None:
    out = [(max(p[0], q[0]), min(p[1], q[1])) for p, q in zip(a, b)]
    return None if any(lo > hi for lo, hi in out) else out


def bounded_on(g: Sequence[Fraction], e: Fraction, box: Box, rows: Sequence[Any]) -> bool:
    """Whether ``g·x <= e`` on ``box ∩ {c·x <= d for each row}`` is shown exactly by weak duality with one row:
    ``g·x <= max_box (g − μc)·x + μd`` for ``μ >= 0`` on that set; ``μ = 0`` and the breakpoints ``g_i/c_i > 0``
    are tried (a sufficient test)."""
    if _top(g, box) <= e:
        return True
    for row in rows:
        c, d = row.normal, row.offset
        for mu in {gi / ci for gi, ci in zip(g, c) if ci and gi / ci > 0}:
            if _top([gi - mu * ci for gi, ci in zip(g, c)], box) + mu * d <= e:
                return True
    return False


def image_covered(model: Any, transition: Any, before: Box, rows: Sequence[Any]) -> bool:
    """Whether the reset image of ``before ∩ rows`` (the states a jump leaves from: its guard, and the source's
    invariant for flowed states) lies in the target's invariant or in one of its guard polyhedra (exact, sufficient:
    each row of the target's polyhedron pulled back through the reset, :func:`bounded_on`)."""
    r, off = transition.r_matrix, transition.r_offset
    n = len(r)

    def inside(poly: Any) -> bool:
        for h in poly.halfspaces:
            g = [sum((h.normal[i] * r[i][j] for i in range(n) if h.normal[i]), Fraction(0)) for j in range(len(before))]
            e = h.offset - sum((a * b for a, b in zip(h.normal, off) if a), Fraction(0))
            if not bounded_on(g, e, before, rows):
                return False
        return True
    target = transition.target
    return any(inside(p) for p in model.modes[target].invariant) or any(
        inside(p) for t in model.outgoing(target) for p in t.guard)


def entry_uncovered(model: Any, mode: str, box: Box) -> str | None:
    """``None`` when a start box of ``mode`` lies in its invariant (exact), or in one guard polyhedron."""
    def inside(poly: Any) -> bool:
        return all(sum((max(a * lo, a * hi) for a, (lo, hi) in zip(h.normal, box)), Fraction(0)) <= h.offset
                   for h in poly.halfspaces)
    if any(inside(p) for p in model.modes[mode].invariant):
        return None
    if any(inside(p) for t in model.outgoing(mode) for p in t.guard):
        return None
    return (f"mode {mode!r}: a start box is not inside the invariant nor inside a guard (a possible deadlock "
            "at entry)")
