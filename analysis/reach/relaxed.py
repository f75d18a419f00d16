"""Reachability of an affine automaton whose locations switch arbitrarily: the relaxed flowpipe (producer).

**The group.**  :func:`switching_group` finds, from the initial mode, the modes reached by *free* transitions:
identity reset (``x⁺ = x``), a guard that always holds there (each halfspace trivially true, ``0·x <= b`` with
``b >= 0``, or one of the source invariant's own halfspaces), and a target invariant equal to the source's (the
same halfspaces) or the whole space.  The group must be closed (no transition leaves it), every mode affine, and
the bounded inputs the same in every mode (``B`` and ``U``).  Otherwise it returns the reason (:class:`NoGroup`)
and the caller keeps its own route.

**The relaxation.**  A run of the automaton inside the group is absolutely continuous (identity resets) and
follows ``ẋ = A_σ(t) x + c_σ(t) + B u`` with ``σ`` piecewise constant, so it is a solution of
``ẋ = A_c x + c_c + w(t) + B u`` with ``w(t) = Σ_i μ_i(t) (D_i x + d_i)``, ``μ(t)`` in the simplex,
``A_c``, ``c_c`` the entrywise midpoints and ``D_i = A_i − A_c``, ``d_i = c_i − c_c`` (exact rationals): whatever
the number of switches, Zeno included.  Conversely the solutions of the convexified inclusion
``ẋ ∈ conv{A_i x + c_i} + B U`` are limits of switched runs (Filippov–Ważewski relaxation theorem: Aubin & Cellina,
*Differential Inclusions*, Springer 1984, §2.4), so the convexification itself loses nothing.

**The flowpipe** (docs/reachability.md, "Arbitrary switching").  Per step ``δ``: a tube of the step from ``Z_k``
(the Peano–Baker terms of ``A(t)`` bounded by ``M = |A_c| + A_r``), the disturbance ``w`` over the tube as a
zonotope in the disturbed rows (two modes: ``λ (D_2 x + d_2)``, ``|λ| <= 1``; more: a box), and
``Z_{k+1} = e^{A_c δ} Z_k ⊕ ∫₀^δ e^{A_c(δ−s)} (w + B u₀) ds`` with the integral's first- and second-order parts as
generators (no ``O(δ²)`` box).  The segments are stored once per mode of the group (a label atom on the mode sees
every mode), in a :class:`~analysis.reach.result.ReachResult` without jumps.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from fractions import Fraction
from typing import Any

import numpy as np

from .flowpipe import ERROR_ORDER
from .initial import ReachError
from .model import AffineHybridModel, AffineTransition
from .result import ReachResult, ReachSegment, Termination
from .series import MAX_NORM_STEP, bloating_matrices, exp_enclosure
from .sets import box_position, polyhedra_to_float
from .zonotope import UNIT_ROUNDOFF, Zonotope, box_generators, from_box, gamma, interval_hull, linear_map, \
    magnitude, reduce_order, round_up, upper, with_error

__all__ = ["NoGroup", "SwitchingGroup", "switching_group", "relaxed_reach"]


W_ORDER = 2
"""The disturbance set of a step is reduced to ``W_ORDER`` generators per disturbed row."""


class NoGroup(ValueError):
    """No arbitrary-switching group: the message says why (the caller keeps its own route)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class SwitchingGroup:
    """Modes that switch arbitrarily, and the interval hull of their affine flows.

    Attributes
    ----------
    modes : tuple of str
        The group, the initial mode first.
    a_center, a_radius : n × n Fractions
        ``[A] = [a_center ± a_radius]`` holds every mode's ``A``.
    c_center, c_radius : n Fractions
        ``[c]`` holds every mode's constant plus ``B u_c`` (the input's centre).
    input_matrix : n × p Fractions or None
    input_set : Zonotope of dimension p or None
        ``U`` (its generators are used; its centre is in ``[c]``).
    deviations : tuple of (n × n Fractions, n Fractions)
        Per mode ``(D_i, d_i) = (A_i − A_c, c_i − c_c)``: the flow is ``A_c x + c_c + D_i x + d_i``.
    invariant : tuple of Polyhedron
        The common invariant.
    """

    modes: tuple[str, ...]
    a_center: tuple[tuple[Fraction, ...], ...]
    a_radius: tuple[tuple[Fraction, ...], ...]
    c_center: tuple[Fraction, ...]
    c_radius: tuple[Fraction, ...]
    input_matrix: tuple[tuple[Fraction, ...], ...] | None
    input_set: Zonotope | None
    deviations: tuple[tuple[tuple[tuple[Fraction, ...], ...], tuple[Fraction, ...]], ...]
    invariant: tuple[Any, ...]


def _trivial(h: Any) -> bool:
    return all(q == 0 for q in h.normal) and h.offset >= 0


def _invariant_key(poly: tuple[Any, ...]) -> frozenset[Any] | None:
    """The invariant's non-trivial halfspaces (one polyhedron), or ``None`` for a disjunctive invariant."""
    if len(poly) != 1:
        return None
    return frozenset((h.normal, h.offset) for h in poly[0].halfspaces if not _trivial(h))


def _free(model: AffineHybridModel, t: AffineTransition) -> str | None:
    """Why ``t`` is not a free switch (``None`` when it is)."""
    n = len(model.state_names)
    if any(t.r_matrix[i][j] != (1 if i == j else 0) for i in range(n) for j in range(n)) or any(t.r_offset):
        return f"transition {t.name!r} has a reset that is not the identity"
    source = _invariant_key(model.modes[t.source].invariant)
    target = _invariant_key(model.modes[t.target].invariant)
    if source is None or target is None:
        return f"transition {t.name!r}: a disjunctive invariant"
    if target and target != source:
        return f"transition {t.name!r}: the invariant of {t.target!r} differs from that of {t.source!r}"
    held = any(all(_trivial(h) or (h.normal, h.offset) in source for h in p.halfspaces) for p in t.guard)
    if not held:
        return f"transition {t.name!r}: its guard is not implied by the invariant of {t.source!r}"
    return None


def _members(model: AffineHybridModel, initial_mode: str) -> tuple[str, ...]:
    group = [initial_mode]
    for mode in group:  # grows while it is walked
        for t in model.outgoing(mode):
            why = _free(model, t)
            if why is not None:
                raise NoGroup(f"{why}: no arbitrary-switching group")
            if t.target not in group:
                group.append(t.target)
    if len(group) < 2:
        raise NoGroup("no transition leaves the initial mode: no arbitrary-switching group")
    return tuple(group)


def _same_input(inputs: Mapping[str, Any], modes: Sequence[str]) -> tuple[Any, Any]:
    specs = [inputs.get(m) for m in modes]
    if all(s is None for s in specs):
        return None, None
    first = specs[0]
    for m, s in zip(modes, specs):
        if s is None or first is None or not np.array_equal(np.asarray(s.matrix, float), np.asarray(first.matrix, float)) \
                or not _same_bounds(s.bounds, first.bounds):
            raise NoGroup(f"the inputs of mode {m!r} differ from those of {modes[0]!r}: no arbitrary-switching group")
    u = first.bounds
    if not isinstance(u, Zonotope):
        lo, hi = (np.asarray(v, dtype=float).reshape(-1) for v in u)
        u = from_box(lo, hi)
    return tuple(tuple(Fraction(float(v)) for v in row) for row in np.asarray(first.matrix, float)), u


def _same_bounds(a: Any, b: Any) -> bool:
    if isinstance(a, Zonotope) or isinstance(b, Zonotope):
        return a is b
    return all(np.array_equal(np.asarray(x, float), np.asarray(y, float)) for x, y in zip(a, b))


def switching_group(model: AffineHybridModel, inputs: Mapping[str, Any] | None = None,
                    initial_mode: str | None = None) -> SwitchingGroup:
    """The arbitrary-switching group of ``initial_mode`` (default: the model's; see the module).

    Raises
    ------
    NoGroup
        No such group, with the reason (a reset that is not the identity, invariants that differ, a guard not
        implied by the invariant, a nonlinear mode, inputs that differ, a single mode).
    """
    modes = _members(model, initial_mode or model.initial_mode)
    for m in modes:
        if model.modes[m].smooth is not None:
            raise NoGroup(f"mode {m!r} is not affine: no arbitrary-switching group")
    b, u = _same_input(dict(inputs or {}), modes)
    n = len(model.state_names)
    shift = [Fraction(0)] * n
    if b is not None:
        centre = [Fraction(float(v)) for v in u.center]
        shift = [sum((b[i][j] * centre[j] for j in range(len(centre))), Fraction(0)) for i in range(n)]
    a_lo = [[min(model.modes[m].a[i][j] for m in modes) for j in range(n)] for i in range(n)]
    a_hi = [[max(model.modes[m].a[i][j] for m in modes) for j in range(n)] for i in range(n)]
    c_lo = [min(model.modes[m].c[i] for m in modes) + shift[i] for i in range(n)]
    c_hi = [max(model.modes[m].c[i] for m in modes) + shift[i] for i in range(n)]
    invariant = next((model.modes[m].invariant for m in modes if _invariant_key(model.modes[m].invariant)),
                     model.modes[modes[0]].invariant)
    a_c = tuple(tuple((lo + hi) / 2 for lo, hi in zip(rl, rh)) for rl, rh in zip(a_lo, a_hi))
    c_c = tuple((lo + hi) / 2 for lo, hi in zip(c_lo, c_hi))
    deviations = tuple((tuple(tuple(q - p for q, p in zip(row, rc)) for row, rc in zip(model.modes[m].a, a_c)),
                        tuple(q + shift[i] - c_c[i] for i, q in enumerate(model.modes[m].c))) for m in modes)
    return SwitchingGroup(
        modes=modes, invariant=invariant, input_matrix=b, input_set=u, a_center=a_c, c_center=c_c,
        a_radius=tuple(tuple((hi - lo) / 2 for lo, hi in zip(rl, rh)) for rl, rh in zip(a_lo, a_hi)),
        c_radius=tuple((hi - lo) / 2 for lo, hi in zip(c_lo, c_hi)), deviations=deviations)


@dataclass(frozen=True, kw_only=True, slots=True)
class _Setup:
    """The floats of one step ``δ`` of the relaxed flowpipe (augmented coordinates, dimension ``n + 1``)."""

    step: float
    scale: float
    phi: Any  # e^{A_c,aug δ} (MatrixEnclosure)
    half_step: tuple[np.ndarray, np.ndarray]  # I + δ/2 A_c,aug (float, residual)
    half_slope: tuple[np.ndarray, np.ndarray]  # δ/2 A_c,aug (float, residual)
    remainder: np.ndarray  # >= δ A_r,aug + e^{Mδ} − I − Mδ, M = |A_c,aug| + A_r,aug
    input_rest: np.ndarray  # >= S |B U₀| (n + 1): the tube's input part besides δ B U₀
    push_first: tuple[np.ndarray, np.ndarray]  # δ I + δ²/2 A_c,aug (float, residual)
    push_second: tuple[np.ndarray, np.ndarray]  # δ²/4 A_c,aug (float, residual)
    push_rest: np.ndarray  # >= Σ_{k>=2} |A_c,aug|^k δ^{k+1}/(k+1)!
    input_push: tuple[np.ndarray, np.ndarray]  # _push of B U₀'s generators (generators, box)
    s_matrix: np.ndarray  # S >= Σ_{k>=1} M^k δ^{k+1}/(k+1)!
    rows: np.ndarray  # the rows where some deviation is non-zero
    deviations: tuple[tuple[np.ndarray, np.ndarray], ...]  # per mode: (floats of [D_i, d_i/s] on rows, residual)
    input_first: np.ndarray  # generators of δ B U₀, shape (n + 1, q) (q may be 0)


def _float_up(q: Fraction) -> float:
    f = float(q)
    return f if Fraction(f) >= q else float(round_up(f))


def _setup(group: SwitchingGroup, step: float) -> _Setup:
    """The step's matrices (exact rationals rounded with bounds; see the module)."""
    n = len(group.c_center)
    biggest = max([abs(float(q)) for q in group.c_center] + [abs(float(q)) for q in group.c_radius] + [1.0])
    scale = 2.0 ** math.ceil(math.log2(biggest))
    s, delta = Fraction(scale), Fraction(step)
    zero = [Fraction(0)] * (n + 1)
    center = [list(row) + [c / s] for row, c in zip(group.a_center, group.c_center)] + [zero]
    big = [[abs(a) + r for a, r in zip(ra, rr)] + [(abs(c) + cr) / s]
           for ra, rr, c, cr in zip(group.a_center, group.a_radius, group.c_center, group.c_radius)] + [zero]
    norm = max(sum(row) for row in big)
    if float(norm) * step > MAX_NORM_STEP:
        raise ReachError("time_step", step, f"‖|A_c| + A_r‖∞ time_step <= {MAX_NORM_STEP:g} for the relaxed group "
                         f"(‖|A_c| + A_r‖∞ = {float(norm):.6g})", f"use time_step <= {MAX_NORM_STEP / float(norm):.3g}")
    phi = exp_enclosure(center, delta)
    rest, s_matrix = bloating_matrices(big, delta)  # rest >= e^{Mδ} − I − Mδ
    radius = [list(row) + [c / s] for row, c in zip(group.a_radius, group.c_radius)] + [zero]
    remainder = upper(np.array([[_float_up(q * delta) for q in row] for row in radius]) + rest, 2)
    half = [[(1 if i == j else 0) + q * delta / 2 for j, q in enumerate(row)] for i, row in enumerate(center)]
    slope = [[q * delta / 2 for q in row] for row in center]
    push_first = [[(delta if i == j else 0) + q * delta * delta / 2 for j, q in enumerate(row)]
                  for i, row in enumerate(center)]
    push_second = [[q * delta * delta / 4 for q in row] for row in center]
    abs_c = [[abs(q) for q in row] for row in center]
    x = np.array([[_float_up(q * delta) for q in row] for row in abs_c])
    exp_rest, _ = bloating_matrices(abs_c, delta)  # >= e^X − I − X, X = δ|A_c|
    # Σ_{k>=2} X^k/(k+1)! <= X² e^X / 6 ((k+1)! >= 6 (k−2)!), times δ
    push_rest = upper(upper(x @ x, n + 2) @ upper(np.eye(n + 1) + x + exp_rest, 2) / 6.0 * step, 2 * n + 8)
    rows = sorted({i for a, c in group.deviations for i in range(n) if c[i] or any(a[i])})
    devs = []
    for a, c in group.deviations:
        exact = [list(a[i]) + [c[i] / s] for i in rows]
        fl = np.array([[float(q) for q in row] for row in exact]).reshape(len(rows), n + 1)
        res = np.array([[_float_up(abs(q - Fraction(float(q)))) for q in row] for row in exact]).reshape(fl.shape)
        devs.append((fl, res))
    input_first, input_rest = np.zeros((n + 1, 0)), np.zeros(n + 1)
    gens, input_err = np.zeros((n + 1, 0)), np.zeros(n + 1)
    if group.input_matrix is not None and group.input_set is not None:
        u0 = Zonotope(center=np.zeros(group.input_set.dimension), generators=group.input_set.generators)
        bc = np.array([[float(q) for q in row] for row in group.input_matrix])
        bu, err = linear_map(u0, bc)  # B holds doubles exactly (the engine's ModeInput reads them so too)
        scaled = bu.generators * step
        rounding = upper(UNIT_ROUNDOFF * np.abs(scaled).sum(axis=1) + step * err, bu.order + 2)
        extra = upper(s_matrix[:n, :n] @ upper(magnitude(bu) + err, 1), n + 1) + rounding
        input_rest = np.append(extra, 0.0)
        input_first = np.vstack([scaled, np.zeros((1, scaled.shape[1]))])
        gens = np.vstack([bu.generators, np.zeros((1, bu.order))])
        input_err = np.append(err, 0.0)
    setup = _Setup(step=step, scale=scale, phi=phi, s_matrix=s_matrix, rows=np.array(rows, dtype=int),
                   half_step=_with_residual(half), half_slope=_with_residual(slope), remainder=remainder,
                   input_rest=input_rest, deviations=tuple(devs), input_first=input_first,
                   push_first=_with_residual(push_first), push_second=_with_residual(push_second), push_rest=push_rest,
                   input_push=(np.zeros((n + 1, 0)), np.zeros(n + 1)))
    pushed, box = _push(setup, gens)
    first = upper(np.abs(setup.push_first[0]) + setup.push_first[1], 1)
    box = upper(box + (setup.push_rest + first) @ input_err, 2 * n + 6)  # B U₀'s rounding, pushed as a box
    return replace(setup, input_push=(pushed, box))


def _push(setup: _Setup, gens: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``∫₀^δ e^{A_c(δ−s)} w(s) ds`` for every measurable ``w(s) ∈ W = G η``, ``|η|∞ <= 1``: generators and a box.

    ``e^{A_c(δ−s)} = I + (δ−s) A_c + R(δ−s)`` with ``|R(τ)| <= Σ_{k>=2} |A_c|^k τ^k/k!``.  With ``a = ∫ η`` and
    ``r = ∫ (δ/2 − s) η ds`` (``|a_j| <= δ``, ``|r_j| <= δ²/4``): ``∫ w = G a`` and ``∫ (δ−s) w = G (δ a/2 + r)``, so the
    integral is ``(I + δ/2 A_c) G a + A_c G r`` plus at most ``Σ_{k>=2} |A_c|^k δ^{k+1}/(k+1)! |G|𝟙``.
    """
    z = Zonotope.of_arrays(np.zeros(gens.shape[0]), gens)
    first, e_first = linear_map(z, *setup.push_first)
    second, e_second = linear_map(z, *setup.push_second)
    box = upper(setup.push_rest @ np.abs(gens).sum(axis=1) + e_first + e_second, gens.shape[0] + gens.shape[1] + 4)
    return np.hstack([first.generators, second.generators]), box


def _with_residual(matrix: Sequence[Sequence[Fraction]]) -> tuple[np.ndarray, np.ndarray]:
    """Nearest floats of an exact matrix and an upper bound of their distance to it."""
    fl = np.array([[float(q) for q in row] for row in matrix])
    res = np.array([[_float_up(abs(q - Fraction(float(q)))) for q in row] for row in matrix])
    return fl, res


def _row_bound(a: np.ndarray, residual: np.ndarray, z: Zonotope, mag: np.ndarray) -> np.ndarray:
    """``max_{x ∈ z} |a_r · x|`` bounded from above for each row ``r`` of the exact ``a`` (floats ``a`` within
    ``residual``)."""
    k = z.dimension
    value = np.abs(a @ z.center) + np.abs(a @ z.generators).sum(axis=1)
    rounding = gamma(k) * (np.abs(a) @ mag)
    return upper(value + rounding + residual @ mag, z.order + k + 4)


def _tube(setup: _Setup, z: Zonotope) -> tuple[Zonotope, np.ndarray, np.ndarray]:
    """Every state over the step from ``z`` (augmented), and the disturbance set ``W`` of the step as zero-centred
    generators (shape ``(n + 1, k)``) with its magnitude ``|W|`` (n + 1).

    For ``t ∈ [0, δ]`` (augmented, Peano–Baker): ``x̂(t) = Φ(t) x̂₀ + ∫₀ᵗ Φ(t, s) B u₀(s) ds`` with
    ``Φ(t) = I + ∫₀ᵗ A(s) ds + Σ_{k>=2} P_k(t)``, ``∫₀ᵗ A(s) ds ∈ t A_c ± t A_r`` and ``|P_k(t)| <= (Mt)^k/k!``;
    ``t A_c x̂₀ = (δ/2) A_c x̂₀ + (t − δ/2) A_c x̂₀``.  So the states lie in
    ``(I + δ/2 A_c) Z ⊕ (δ/2) sym(A_c Z) ⊕ δ B U₀ ⊕ box((δ A_r + e^{Mδ} − I − Mδ) |Z| + S |B U₀|)``
    (``sym(Y)``: the generators ``[c_Y, G_Y]``, weights ``μ ξ``; ``|Φ(t, s) − I| <= e^{M(t−s)} − I``).
    The disturbance ``w = Σ μ_i (D_i x + d_i)`` (``μ`` in the simplex) over that tube ``T = c + Gξ``: with two modes
    ``D_1 = −D_2`` (the centre is their midpoint), so ``w = λ (D_2 x + d_2)`` with ``λ ∈ [−1, 1]`` lies in the
    zonotope of generators ``[D_2 c + d_2, D_2 G]`` (the products ``λ ξ_j`` are weights in ``[−1, 1]``), reduced in
    the disturbed rows; with more modes, in the box ``|w_r| <= max_i max_T |D_i,r x + d_i,r|``.
    """
    mag = magnitude(z)
    mid, e_mid = linear_map(z, *setup.half_step)
    slope, e_slope = linear_map(z, *setup.half_slope)
    box = upper(setup.remainder @ mag + e_mid + e_slope + setup.input_rest, 2 * mag.size + 4)
    box[-1] = 0.0
    parts = [mid.generators, slope.center.reshape(-1, 1), slope.generators, box_generators(box)]
    parts.append(setup.input_first)
    tube = Zonotope.of_arrays(mid.center, np.hstack(parts))
    rows = setup.rows
    if rows.size == 0:  # the modes' flows coincide: no disturbance
        return tube, np.zeros((z.dimension, 0)), np.zeros(z.dimension)
    if len(setup.deviations) == 2:
        a, res = setup.deviations[1]
        image, err = linear_map(tube, a, res)
        w_set = reduce_order(Zonotope.of_arrays(np.zeros(rows.size), np.hstack(
            [image.center.reshape(-1, 1), image.generators, box_generators(err)])), W_ORDER)
        gens = np.zeros((z.dimension, w_set.order))
        gens[rows] = w_set.generators
        return tube, gens, magnitude(Zonotope.of_arrays(np.zeros(z.dimension), gens))
    tmag = magnitude(tube)
    w = np.zeros(z.dimension)
    for a, res in setup.deviations:
        w[rows] = np.maximum(w[rows], _row_bound(a, res, tube, tmag))
    return tube, box_generators(w), w


def _segments(setup: _Setup, start: Zonotope, order: int, max_generators: int) -> Any:
    """The tubes ``T_k`` (augmented) over ``[kδ, (k+1)δ]``, endless (the caller stops).

    ``Z_k = main ⊕ carried ⊕ error``: ``main = Φ^k Z₀`` (mapped, never reduced); ``carried`` holds the first-order
    parts of the inputs and disturbances (``δ B U₀`` and ``δ W`` on the disturbed rows: a few generators per
    step, mapped and reduced only beyond ``max_generators``, so it hardly wraps); ``error`` the ``O(δ²)`` boxes
    (``S |B U₀|``, ``S w``) and every rounding bound, mapped and reduced to ``order``.
    """
    dim = start.dimension
    empty = Zonotope(center=np.zeros(dim), generators=np.zeros((dim, 0)))
    main, error, carried = start, empty, empty
    pc, pr = setup.phi.center, setup.phi.radius
    sm = setup.s_matrix
    while True:
        z = Zonotope.of_arrays(main.center, np.hstack([main.generators, error.generators, carried.generators]))
        tube, w_gens, w = _tube(setup, z)
        yield tube
        # the disturbance and the input over the step: ∫ e^{A_c(δ−s)} (w(s) + B u₀(s)) ds
        pushed, spread = _push(setup, w_gens)
        spread = upper(spread + setup.input_push[1], 1)
        spread[-1] = 0.0
        main, e_main = linear_map(main, pc, pr)
        error, e_error = linear_map(error, pc, pr)
        carried, e_carried = linear_map(carried, pc, pr)
        fresh = upper(e_main + e_error + e_carried + spread, 4)
        error = reduce_order(with_error(error, fresh), order)
        carried = Zonotope.of_arrays(carried.center, np.hstack([carried.generators, pushed, setup.input_push[0]]))
        if carried.order > max_generators:
            carried = reduce_order(carried, max(max_generators // (2 * dim), 1))


def relaxed_reach(model: AffineHybridModel, group: SwitchingGroup, initial: Mapping[str, tuple[float, float]], *,
                  horizon: float, time_step: float, order: int = 20, stored_order: int = 10,
                  size_limit: float = 1e6, max_segments: int = 50_000,
                  max_generators: int = 30_000) -> ReachResult:
    """The flowpipe of the group's relaxation from the initial box over ``[0, horizon]`` (see the module).

    Parameters
    ----------
    initial : mapping {state: (lo, hi)}
    horizon, time_step : float
        [s], ``0 < time_step <= horizon``.

    Returns
    -------
    ReachResult
        One flowpipe per mode of the group (the same sets), no jumps; its terminations say ``"horizon"``, or
        ``"blow_up"`` (also when a segment is not proven inside the common invariant: the detail says so) or
        ``"segment_limit"``, both inconclusive: then nothing is decided.
    """
    names = model.state_names
    n = len(names)
    if set(initial) != set(names) or not all(
            len(v) == 2 and all(math.isfinite(float(e)) for e in v) and v[0] <= v[1] for v in initial.values()):
        raise ReachError("initial", dict(initial), f"{{state: (lo, hi)}} with finite lo <= hi for exactly {list(names)}",
                         "give a bounded box over the model's states")
    if not (math.isfinite(horizon) and math.isfinite(time_step) and 0 < time_step <= horizon):
        raise ReachError("time_step", time_step, f"0 < time_step <= horizon ({horizon!r}), both finite",
                         "give a positive step no longer than the horizon")
    lo = np.array([float(initial[s][0]) for s in names])
    hi = np.array([float(initial[s][1]) for s in names])
    start = from_box(lo, hi)
    setup = _setup(group, time_step)
    scale = setup.scale
    poly = polyhedra_to_float(group.invariant)[0]
    aug = Zonotope(center=np.append(start.center, scale),
                   generators=np.vstack([start.generators, np.zeros((1, start.order))]))
    flowed: list[tuple[float, float, Zonotope, np.ndarray, np.ndarray]] = []
    stop = None
    for k, seg in enumerate(_segments(setup, aug, order, max_generators)):
        t_lo = math.nextafter(math.nextafter(k * time_step, -math.inf), -math.inf)
        t_hi = math.nextafter(math.nextafter((k + 1) * time_step, math.inf), math.inf)
        if k * time_step > horizon:
            stop = ("horizon", f"time horizon {horizon:g} s reached (relaxed group {'+'.join(group.modes)})")
            break
        z = seg.project(n)
        s_lo, s_hi = interval_hull(z)
        radius = float(np.max(s_hi - s_lo)) / 2
        if not z.is_finite() or not math.isfinite(radius) or radius > size_limit:
            stop = ("blow_up", f"inconclusive: the over-approximation blew up at t = {t_lo:.6g} s (relaxed group)")
            break
        if len(flowed) * len(group.modes) >= max_segments:
            stop = ("segment_limit", f"inconclusive: {max_segments} segments stored by t = {t_lo:.6g} s")
            break
        if box_position(s_lo, s_hi, poly) < 1:
            # inconclusive (the runs may go on or deadlock): the set is too coarse for the invariant, as for a blow-up
            stop = ("blow_up", f"inconclusive: the relaxed flowpipe may leave the common invariant at t = {t_lo:.6g} s "
                               "(not followed: the runs may go on or deadlock)")
            break
        flowed.append((t_lo, t_hi, reduce_order(z, stored_order), s_lo, s_hi))
    assert stop is not None
    return _result(model, group, start, (lo, hi), flowed, stop, horizon, time_step)


def _result(model: AffineHybridModel, group: SwitchingGroup, start: Zonotope, box: tuple[np.ndarray, np.ndarray],
            flowed: Sequence[tuple[float, float, Zonotope, np.ndarray, np.ndarray]], stop: tuple[str, str],
            horizon: float, time_step: float) -> ReachResult:
    """The segments once per mode of the group (an entry at t = 0, then the flowed ones), one termination each."""
    out: list[ReachSegment] = []
    ends: list[Termination] = []
    for mode in group.modes:
        out.append(ReachSegment(mode=mode, t_lo=0.0, t_hi=0.0, jumps=0, zonotope=start, lo=box[0], hi=box[1],
                                entry=True))
        out.extend(ReachSegment(mode=mode, t_lo=a, t_hi=b, jumps=0, zonotope=z, lo=l, hi=h)
                   for a, b, z, l, h in flowed)
        time = flowed[-1][1] if flowed else 0.0
        ends.append(Termination(reason=stop[0], mode=mode, time=time, jumps=0, detail=stop[1]))
    inputs = ()
    if group.input_matrix is not None:
        u_lo, u_hi = interval_hull(group.input_set)
        b = [[float(q) for q in row] for row in group.input_matrix]
        inputs = tuple((m, b, u_lo.tolist(), u_hi.tolist()) for m in group.modes)
    return ReachResult(system=model.name, state_names=model.state_names, horizon=horizon, max_jumps=0,
                       time_step=time_step, segments=tuple(out), jumps=(), terminations=tuple(ends), inputs=inputs,
                       schedule=(("relaxed_group", list(group.modes)),))
