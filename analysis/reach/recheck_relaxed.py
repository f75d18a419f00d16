"""The independent re-check of a relaxed flowpipe: two locations that switch arbitrarily (own code).

The producer (:mod:`analysis.reach.relaxed`) reaches the relaxation ``ẋ = A_c x + c_c + λ(t)(D x + d) + B u``,
``λ ∈ [−1, 1]``, ``A_c = (A_1 + A_2)/2``, ``D = (A_2 − A_1)/2`` (and the same for the constants) of a pair of
locations joined by transitions with identity resets and no transition out of the pair.  This module re-derives
that claim from the model alone, in its own sets (:class:`~analysis.reach.recheck_sets.FZ`: float zonotopes read as
exact reals, every rounding bounded by :mod:`analysis.reach.recheck_interval`); the saved JSON gives only the step,
the group's names and the inputs.  It shares no code with the producer (no ``zonotope``, ``series``, ``flowpipe``,
``relaxed``).

Per step ``δ`` from ``Z_k`` (augmented with the constant coordinate ``s``):

* the tube over ``[kδ, (k+1)δ]``: ``(I + δ/2 A_c) Z ⊕ (δ/2) sym(A_c Z) ⊕ δ B U₀ ⊕ box(R |Z| + δ(e^{Mδ} − I)|B U₀|)``
  with ``M = |A_c| + |D|`` (every ``A(t)`` of the pair is below it entrywise) and
  ``R >= δ|D| + e^{Mδ} − I − Mδ`` (the Peano–Baker terms of order ``>= 2``; the first-order term
  ``∫ A(s) ds ∈ t A_c ± t|D|``);
* the disturbance ``λ (D x + d)`` over the tube: the zonotope of generators ``[D c_T + d, D G_T]`` (weights
  ``λ``, ``λ ξ``), reduced to a few generators and a box in the disturbed rows;
* ``Z_{k+1} = e^{A_c δ} Z_k ⊕ ∫₀^δ e^{A_c(δ−s)} (w(s) + B u₀(s)) ds`` with the integral in
  ``(δ I + δ²/2 A_c) G a' ⊕ (δ²/4) A_c G r' ⊕ box(Σ_{k>=2} |A_c|^k δ^{k+1}/(k+1)! |G|𝟙)`` (``|a'|, |r'| <= 1``), and
  each step's rounding box turned into generators (an error box mapped by ``|e^{A_c δ}|`` would grow like
  ``ρ(|Φ|)^k``).

Each tube is checked inside every invariant of the pair (exact rationals; else the re-check fails: a run could
leave it) and against the requirement (a rigorous upper bound of ``c·x`` per atom, compared exactly).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from .fragment import Conj, Disj, LabelAtom, LinearAtom, Nnf, SafetyFragment
from .model import affine_model
from .recheck_inputs import InputMismatch, model_inputs
from .recheck_interval import TINY, U, add_up, expm_taylor, float_interval, nn_up, point_product, sum_up, up
from .recheck_sets import FZ

__all__ = ["RelaxedRecheck", "recheck_relaxed", "KEPT_DISTURBANCE"]

KEPT_DISTURBANCE = 2
"""Generators of a step's disturbance kept per disturbed row (the rest boxed)."""

_LIMIT = 1e6
"""A set wider than this fails the re-check."""


class _Fail(Exception):
    pass


@dataclass(frozen=True, kw_only=True, slots=True)
class RelaxedRecheck:
    """The re-check's answer: ``passed``, the first ``failure``, the steps checked and the exact margin (a float
    rounded down; ``None`` when the re-check stopped before deciding)."""

    passed: bool
    failure: str
    steps: int
    margin: float | None


def _down(q: Fraction) -> float:
    f = float(q)
    return f if Fraction(f) <= q else math.nextafter(f, -math.inf)


def _pair(model: Any, initial_mode: str) -> tuple[str, str]:
    """The two modes switching freely from the initial mode (identity resets, closed), else :class:`_Fail`."""
    n = len(model.state_names)
    group = [initial_mode]
    for mode in group:
        for t in model.transitions:
            if t.source != mode:
                continue
            if any(t.r_matrix[i][j] != (1 if i == j else 0) for i in range(n) for j in range(n)) or any(t.r_offset):
                raise _Fail(f"transition {t.name!r} resets the state: not an arbitrary-switching pair")
            if t.target not in group:
                group.append(t.target)
    if len(group) != 2:
        raise _Fail(f"the modes reached from {initial_mode!r} are {group}: the relaxed re-check takes exactly two")
    for m in group:
        if model.modes[m].smooth is not None:
            raise _Fail(f"mode {m!r} is not affine")
    return group[0], group[1]


def _exact_series(m: list[list[Fraction]], first: int) -> np.ndarray:
    """An upper bound of ``Σ_{k>=first} m^k/k!`` for a non-negative exact ``m`` with ``‖m‖∞ <= 4`` (floats)."""
    size = len(m)
    mf = np.array([[float(q) for q in row] for row in m]).reshape(size, size)
    mf = up(mf)
    q = max((sum(row, Fraction(0)) for row in m), default=Fraction(0))
    term = np.eye(size)
    total = np.zeros((size, size))
    k = 0
    while True:
        k += 1
        term = up(nn_up(term, mf) / k * (1 + 4 * U))
        if k >= first:
            total = up(total + term)
        tail = q ** (k + 1) / math.factorial(k + 1) / (1 - q / (k + 2)) if q < k + 2 else None
        if k >= first and tail is not None and tail < Fraction(1, 2 ** 70):
            return up(total + float(up(float(tail))))
        if k > 90:
            raise _Fail("the series of |A|δ did not converge")


@dataclass(slots=True)
class _Step:
    delta: float
    phi: tuple[np.ndarray, np.ndarray]
    half: tuple[np.ndarray, np.ndarray]
    slope: tuple[np.ndarray, np.ndarray]
    push1: tuple[np.ndarray, np.ndarray]
    push2: tuple[np.ndarray, np.ndarray]
    rem: np.ndarray
    push_rest: np.ndarray
    rows: list[int]
    dev: tuple[np.ndarray, np.ndarray]
    u_tube: np.ndarray  # δ B U₀ generators (n + 1, p)
    u_box: np.ndarray  # the tube's input box
    u_push: np.ndarray  # pushed generators of B U₀
    u_push_box: np.ndarray
    scale: float


def _matrices(model: Any, pair: tuple[str, str], shift: list[Fraction], spread: list[list[Fraction]],
              delta: float) -> _Step:
    """The step's enclosures, from the exact flows of the pair (see the module)."""
    n = len(model.state_names)
    a1, a2 = (model.modes[m].a for m in pair)
    c1, c2 = ([q + s for q, s in zip(model.modes[m].c, shift)] for m in pair)
    ac = [[(p + q) / 2 for p, q in zip(r1, r2)] for r1, r2 in zip(a1, a2)]
    dd = [[(q - p) / 2 for p, q in zip(r1, r2)] for r1, r2 in zip(a1, a2)]
    cc = [(p + q) / 2 for p, q in zip(c1, c2)]
    dc = [(q - p) / 2 for p, q in zip(c1, c2)]
    s = Fraction(1)
    while s < max([abs(v) for v in cc] + [abs(v) for v in dc] + [Fraction(1)]):
        s *= 2
    zero = [Fraction(0)] * (n + 1)
    acx = [list(r) + [v / s] for r, v in zip(ac, cc)] + [zero]
    ddx = [list(r) + [v / s] for r, v in zip(dd, dc)] + [zero]
    d = Fraction(delta)
    m = [[(abs(p) + abs(q)) * d for p, q in zip(r1, r2)] for r1, r2 in zip(acx, ddx)]
    xc = [[abs(p) * d for p in r] for r in acx]
    if max(sum(r) for r in m) > 4:
        raise _Fail(f"step {delta:g}: ‖(|A_c| + |D|) δ‖∞ > 4")
    eye = [[Fraction(int(i == j)) for j in range(n + 1)] for i in range(n + 1)]
    phi, _, _ = expm_taylor(float_interval([[q * d for q in r] for r in acx]))
    e2 = _exact_series(m, 2)
    rem = up(up(np.array([[float(abs(q) * d) for q in r] for r in ddx]) * (1 + 2 * U) + TINY) + e2)
    xf = up(np.array([[float(q) for q in r] for r in xc]))
    push_rest = up(up(nn_up(nn_up(xf, xf), up(np.eye(n + 1) + xf + _exact_series(xc, 2))) / 6.0) * float(delta)
                   * (1 + 4 * U))
    rows = [i for i in range(n) if any(ddx[i])]
    dev = float_interval([ddx[i] for i in rows]) if rows else (np.zeros((0, n + 1)), np.zeros((0, n + 1)))
    mf = up(np.array([[float(q) for q in r] for r in m]))
    u_gens = float_interval(spread) if spread and spread[0] else (np.zeros((n, 0)), np.zeros((n, 0)))
    ug = np.vstack([u_gens[0], np.zeros((1, u_gens[0].shape[1]))])
    ur = np.append(sum_up(u_gens[1], axis=1) if u_gens[0].shape[1] else np.zeros(n), 0.0)
    umag = add_up(sum_up(np.abs(ug), axis=1), ur)
    step = _Step(delta=delta, phi=phi, half=float_interval([[e + q * d / 2 for e, q in zip(re, r)]
                                                             for re, r in zip(eye, acx)]),
                 slope=float_interval([[q * d / 2 for q in r] for r in acx]),
                 push1=float_interval([[e * d + q * d * d / 2 for e, q in zip(re, r)] for re, r in zip(eye, acx)]),
                 push2=float_interval([[q * d * d / 4 for q in r] for r in acx]), rem=rem, push_rest=push_rest,
                 rows=rows, dev=dev, u_tube=up(np.abs(ug) * delta) * np.sign(ug), u_box=np.zeros(n + 1),
                 u_push=np.zeros((n + 1, 0)), u_push_box=np.zeros(n + 1), scale=float(s))
    # the tube's input: δ B U₀ (its rounding and B's radius in the box) ⊕ δ (e^{Mδ} − I) |B U₀|
    step.u_box = add_up(up(ur * delta), up(umag * delta * 4 * U), nn_up(up(mf + e2), umag) * delta * (1 + 4 * U))
    step.u_push, box = _push(step, ug)
    # B U₀'s radius ur: ∫ |e^{A_c(δ−s)}| ds <= δ I + δ²/2 |A_c| + Σ_{k>=2} |A_c|^k δ^{k+1}/(k+1)!
    step.u_push_box = add_up(box, nn_up(up(np.abs(step.push1[0]) + step.push1[1]), ur), nn_up(step.push_rest, ur))
    return step


def _push(step: _Step, gens: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Generators and box of ``∫₀^δ e^{A_c(δ−s)} G η(s) ds`` over ``|η|∞ <= 1`` (see the module)."""
    (p1, r1), (p2, r2) = step.push1, step.push2
    g1, e1 = point_product(p1, gens)
    g2, e2 = point_product(p2, gens)
    absg = sum_up(np.abs(gens), axis=1) if gens.shape[1] else np.zeros(gens.shape[0])
    box = add_up(sum_up(e1, axis=1) if gens.shape[1] else 0.0, sum_up(e2, axis=1) if gens.shape[1] else 0.0,
                 nn_up(r1, absg), nn_up(r2, absg), nn_up(step.push_rest, absg))
    return np.hstack([g1, g2]), box


def _tube(step: _Step, z: FZ) -> FZ:
    mid = z.mapped(step.half, None)
    sl = z.mapped(step.slope, None)
    err = add_up(mid.err, sl.err, nn_up(step.rem, z.magnitude()), step.u_box)
    err[-1] = 0.0
    return FZ(center=mid.center, gens=np.hstack([mid.gens, sl.center.reshape(-1, 1), sl.gens, step.u_tube]), err=err)


def _disturbance(step: _Step, tube: FZ) -> np.ndarray:
    """Generators (``n + 1`` rows) holding ``λ (D x + d)`` over the tube, ``|λ| <= 1``."""
    size = tube.center.size
    if not step.rows:
        return np.zeros((size, 0))
    image = tube.mapped(step.dev, None)
    gens = np.hstack([image.center.reshape(-1, 1), image.gens])
    cost = np.abs(gens).sum(axis=0)
    keep = np.argsort(-cost, kind="stable")[:KEPT_DISTURBANCE * len(step.rows)]
    rest = np.ones(gens.shape[1], dtype=bool)
    rest[keep] = False
    box = add_up(sum_up(np.abs(gens[:, rest]), axis=1) if rest.any() else np.zeros(len(step.rows)), image.err)
    local = np.hstack([gens[:, keep], np.diag(box)])
    out = np.zeros((size, local.shape[1]))
    out[step.rows] = local
    return out


def _upper(fz: FZ, a: np.ndarray, residual: np.ndarray) -> Fraction:
    """A rigorous upper bound of ``a·x`` over the set (``a`` exact within ``residual``)."""
    v, rv = point_product(a.reshape(1, -1), fz.center.reshape(-1, 1))
    if fz.gens.shape[1]:
        g, rg = point_product(a.reshape(1, -1), fz.gens)
        spread = add_up(sum_up(np.abs(g)), sum_up(rg))
    else:
        spread = 0.0
    total = add_up(spread, rv[0, 0], nn_up(np.abs(a).reshape(1, -1), fz.err.reshape(-1, 1))[0, 0],
                   nn_up(residual.reshape(1, -1), fz.magnitude().reshape(-1, 1))[0, 0])
    return Fraction(float(v[0, 0])) + Fraction(float(up(total)))


def _value(node: Nnf, mode: str, tops: Mapping[int, Fraction], index: dict[int, LinearAtom]) -> tuple[bool, Any]:
    if isinstance(node, LinearAtom):
        slack = node.bound - tops[id(node)]
        return (slack > 0 if node.strict else slack >= 0), slack
    if isinstance(node, LabelAtom):
        return node.holds(mode), None
    parts = [_value(p, mode, tops, index) for p in node.parts]
    if isinstance(node, Conj):
        slacks = [s for _, s in parts if s is not None]
        return all(h for h, _ in parts), (min(slacks) if slacks else None)
    held = [(h, s) for h, s in parts if h]
    if any(s is None for _, s in held):
        return True, None
    return bool(held), (max(s for _, s in held) if held else max((s for _, s in parts if s is not None),
                                                                  default=None))


def _leaves(node: Nnf) -> list[LinearAtom]:
    if isinstance(node, LinearAtom):
        return [node]
    if isinstance(node, (Conj, Disj)):
        return [a for p in node.parts for a in _leaves(p)]
    return []


def _inside(model: Any, pair: Sequence[str], fz: FZ, n: int) -> str | None:
    """Why the tube may leave an invariant of the pair (``None``: inside every one, proven)."""
    for m in pair:
        polys = model.modes[m].invariant
        if len(polys) != 1:
            return f"mode {m!r} has a disjunctive invariant"
        for h in polys[0].halfspaces:
            a = np.append([float(q) for q in h.normal], 0.0)
            res = np.append([float(up(float(abs(q - Fraction(float(q)))))) if q != Fraction(float(q)) else 0.0
                             for q in h.normal], 0.0)
            if any(h.normal) and _upper(fz, a, res) > h.offset:
                return f"the tube may leave the invariant of {m!r} ({h.text or 'a halfspace'})"
            if not any(h.normal) and h.offset < 0:
                return f"the invariant of {m!r} is empty"
    return None


def recheck_relaxed(saved: str | Mapping[str, Any], system: Any, initial: Mapping[str, tuple[float, float]],
                    fragment: SafetyFragment, *, initial_mode: str | None = None,
                    inputs: Mapping[str, Any] | None = None) -> RelaxedRecheck:
    """Re-check a relaxed flowpipe's proof of ``fragment`` on own sets (see the module).

    Parameters
    ----------
    saved : str or mapping
        The producer's :meth:`~analysis.reach.result.ReachResult.to_json` (its ``time_step``, ``schedule``).
    system : HybridSystem
        The input-free symbolic system.
    initial : mapping {state: (lo, hi)}
    fragment : SafetyFragment
    initial_mode : str or None
    inputs : mapping {mode: ModeInput} or None
        The model's bounded inputs (the same in both modes).

    Returns
    -------
    RelaxedRecheck
        ``passed`` only when every tube up to the window's end is inside the invariants and satisfies the
        requirement.
    """
    try:
        data = json.loads(saved) if isinstance(saved, str) else saved
        return _run(data, system, initial, fragment, initial_mode, inputs)
    except (_Fail, InputMismatch) as fail:
        return RelaxedRecheck(passed=False, failure=str(fail), steps=0, margin=None)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        return RelaxedRecheck(passed=False, failure=f"the saved flowpipe is malformed: {exc!r}", steps=0, margin=None)


def _setup(data: Mapping[str, Any], model: Any, pair: tuple[str, str], inputs: Any) -> _Step:
    n = len(model.state_names)
    if list(dict(data.get("schedule", {})).get("relaxed_group", [])) != list(pair):
        raise _Fail(f"the saved flowpipe is not a relaxed flowpipe of the pair {list(pair)}")
    given = model_inputs(inputs, n)
    specs = [given.get(m) for m in pair]
    if specs[0] != specs[1]:
        raise _Fail("the two modes' inputs differ")
    shift = specs[0].shift() if specs[0] is not None else [Fraction(0)] * n
    spread = ([[b * r for b, r in zip(row, specs[0].radius())] for row in specs[0].matrix]
              if specs[0] is not None else [])
    delta = float(data["time_step"])
    if not (math.isfinite(delta) and delta > 0):
        raise _Fail(f"time_step {delta!r} is not a positive number")
    return _matrices(model, pair, shift, spread, delta)


def _run(data: Mapping[str, Any], system: Any, initial: Mapping[str, tuple[float, float]],
         fragment: SafetyFragment, initial_mode: str | None, inputs: Any) -> RelaxedRecheck:
    model = affine_model(system)
    n = len(model.state_names)
    pair = _pair(model, initial_mode or model.initial_mode)
    step = _setup(data, model, pair, inputs)
    lo = np.array([float(initial[s][0]) for s in model.state_names] + [step.scale])
    hi = np.array([float(initial[s][1]) for s in model.state_names] + [step.scale])
    z = FZ.of_box(lo, hi)
    atoms = _leaves(fragment.body)
    coeffs = [(np.append([float(q) for q in a.coefficients], 0.0),
               np.append([float(up(float(abs(q - Fraction(float(q)))))) if q != Fraction(float(q)) else 0.0
                          for q in a.coefficients], 0.0)) for a in atoms]
    end = Fraction(fragment.end)
    margin: Fraction | None = None
    k = 0
    while Fraction(step.delta) * k <= end:
        tube = _tube(step, z)
        if not np.all(np.isfinite(tube.center)) or float(np.max(tube.radius())) > _LIMIT:
            raise _Fail(f"the re-check's set blew up at step {k}")
        why = _inside(model, pair, tube, n)
        if why:
            raise _Fail(f"step {k} (t in [{k * step.delta:.6g}, {(k + 1) * step.delta:.6g}] s): {why}")
        if Fraction(step.delta) * (k + 1) >= Fraction(fragment.start):
            tops = {id(a): _upper(tube, c, r) for a, (c, r) in zip(atoms, coeffs)}
            for mode in pair:
                holds, slack = _value(fragment.body, mode, tops, {})
                if not holds:
                    raise _Fail(f"requirement at step {k} (t in [{k * step.delta:.6g}, {(k + 1) * step.delta:.6g}]"
                                f" s, mode {mode!r}): slack {float(slack) if slack is not None else 'n/a'}")
                if slack is not None:
                    margin = slack if margin is None else min(margin, slack)
        z = _next(step, z, tube)
        k += 1
    return RelaxedRecheck(passed=True, failure="", steps=k, margin=_down(margin) if margin is not None else None)


def _next(step: _Step, z: FZ, tube: FZ) -> FZ:
    """``Z_{k+1}``: the mapped set, the pushed disturbance and input, the step's errors as generators."""
    w = _disturbance(step, tube)
    pushed, box = _push(step, w)
    mapped = z.mapped(step.phi, None)
    err = add_up(mapped.err, box, step.u_push_box)
    err[-1] = 0.0
    keep = err > 0
    diag = np.diag(err)[:, keep]
    return FZ(center=mapped.center, gens=np.hstack([mapped.gens, pushed, step.u_push, diag]),
              err=np.zeros_like(err))
