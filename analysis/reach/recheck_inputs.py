"""Bounded non-deterministic inputs in the independent re-check (:mod:`analysis.reach.recheck`).

A mode with an input has the flow ``ẋ = A x + c + B u``, ``u(t) ∈ U = [lo, hi]`` measurable.  Write
``u = u_c + u₀`` with ``u_c = (lo + hi)/2`` and ``u₀ ∈ U₀ = [−r, r]``; ``B u_c`` joins the constant
(exactly: :meth:`InputSet.shift`).  By linearity, a solution at ``kδ + s`` (``0 <= s <= δ``) after the
flowpipe's entry is

``x(kδ + s) = φ_s(h_k + σ_k) + v_k(s)``

where ``φ_s`` is the input-free flow (constant ``c + B u_c``), ``h_k ∈ H_k`` the re-checker's own
input-free set, ``σ_k ∈ S_k`` the inputs of the earlier steps carried by ``ẋ = A x``, and ``v_k`` the
solution of ``v̇ = A v + B u₀``, ``v(0) = 0``.  This module bounds the two input terms, in exact
rationals and without the producer's set code:

* **Tube of one step.**  With ``b = |B| r`` and ``q = ‖δ|A|‖∞ < 1``, a vector ``w >= δ(|A| w + b)``
  (componentwise) bounds ``|v(s)| <= w`` for ``s ∈ [0, δ]``: ``y = max_{τ<=δ} |v(τ)|`` satisfies
  ``y <= δ(|A| y + b)``, so ``(I − δ|A|) y <= δ b``; ``(I − δ|A|)⁻¹ >= 0`` (Neumann series) gives
  ``y <= (I − δ|A|)⁻¹ δ b <= w``.  ``w₀ = δ‖b‖∞/(1 − q)`` satisfies it and ``w ← δ(|A| w + b)`` decreases
  it monotonically; Picard iterations of ``v(s) = ∫₀^s (B u₀ + A v)`` then sharpen it to the series
  ``Σ_k |A^k B| r s^{k+1}/(k+1)!`` plus a remainder ``|A^K| w s^K/K!`` (:func:`input_tube`).
* **End of one step.**  ``v(δ) ∈ P₀ = ⊕_{k<K} δ^{k+1}/(k+1)! A^k B U₀ ⊕ [−ρ, ρ]``, ``ρ = |A^K| w δ^K/K!``
  (the same series with signed generators): a zonotope with ``K p + n`` generators.
* **Carried inputs, wrapping-free.**  ``S_k ⊇ Σ_{j<k} e^{Ajδ} P₀`` is kept as a box, the sum of the
  interval hulls of ``P_j = e^{Ajδ} P₀``; ``P_{j+1} = e^{Aδ} P_j`` is mapped by an enclosure of
  ``e^{Aδ}`` (the Taylor polynomial of order ``K`` in exact rationals, its float rounding and the tail
  ``‖Aδ‖∞^{K+1}/(K+1)! / (1 − ‖Aδ‖∞/(K+2))`` entrywise, below ``2⁻⁷⁰``); the generators are mapped
  exactly and rounded to floats, the roundings and the enclosure's radius go to an error box.

The re-check then runs its own tube on ``H_k ⊕ S_k`` (constant ``c + B u_c``) and adds ``[−w, w]`` to
every time piece before clipping to the invariant.  The saved JSON must carry every mode's ``B`` and
``U`` (key ``"inputs"``): the same ``B`` and a box holding the model's ``U``, or the re-check refuses
(:func:`checked_inputs`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

__all__ = ["InputSet", "InputMismatch", "model_inputs", "checked_inputs", "input_tube", "tube_at", "InputDynamics",
           "InputFlow"]

Box = list[tuple[Fraction, Fraction]]
TAIL = Fraction(1, 2 ** 70)
KEPT = 4
"""Generators of the carried inputs per state before the smallest are boxed."""


class InputMismatch(ValueError):
    """The saved flowpipe's inputs do not cover the model's (the re-check fails with this message)."""


def _up(q: Fraction) -> Fraction:
    f = float(q)
    if Fraction(f) < q:
        f = math.nextafter(f, math.inf)
    return Fraction(f)


@dataclass(frozen=True, kw_only=True, slots=True)
class InputSet:
    """``B`` (``n × p``, exact) and the box ``U = [low, high]`` (``p``) of one mode."""

    matrix: tuple[tuple[Fraction, ...], ...]
    low: tuple[Fraction, ...]
    high: tuple[Fraction, ...]

    def shift(self) -> list[Fraction]:
        """``B u_c`` with ``u_c = (low + high)/2`` (exact), shape ``(n,)``."""
        centre = [(lo + hi) / 2 for lo, hi in zip(self.low, self.high)]
        return [sum((b * u for b, u in zip(row, centre)), Fraction(0)) for row in self.matrix]

    def radius(self) -> list[Fraction]:
        """``r = (high − low)/2``, shape ``(p,)``."""
        return [(hi - lo) / 2 for lo, hi in zip(self.low, self.high)]


def _parse(mode: str, spec: Any, n: int, where: str) -> InputSet:
    """One input from ``ModeInput``-like (``matrix``, ``bounds``) or ``(matrix, (lo, hi))``; a zonotope
    ``bounds`` (``center``, ``generators``) as its exact interval hull."""
    matrix, bounds = (spec.matrix, spec.bounds) if hasattr(spec, "matrix") else spec
    rows = tuple(tuple(Fraction(float(v)) for v in row) for row in matrix)
    if hasattr(bounds, "generators"):
        centre = [Fraction(float(v)) for v in bounds.center]
        spread = [sum((abs(Fraction(float(g))) for g in row), Fraction(0)) for row in bounds.generators]
        low, high = [c - s for c, s in zip(centre, spread)], [c + s for c, s in zip(centre, spread)]
    else:
        low, high = ([Fraction(float(v)) for v in side] for side in bounds)
    p = len(low)
    if len(rows) != n or any(len(r) != p for r in rows) or len(high) != p or any(a > b for a, b in zip(low, high)):
        raise InputMismatch(f"{where}: the input of mode {mode!r} is not a {n}×p matrix with a box lo <= hi of "
                            f"dimension p")
    return InputSet(matrix=rows, low=tuple(low), high=tuple(high))


def model_inputs(inputs: Mapping[str, Any] | None, n: int) -> dict[str, InputSet]:
    """The model's inputs ``{mode: ModeInput or (B, (lo, hi))}`` in exact rationals."""
    return {mode: _parse(mode, spec, n, "the model's inputs") for mode, spec in dict(inputs or {}).items()}


def checked_inputs(data: Mapping[str, Any], given: Mapping[str, InputSet], n: int) -> dict[str, InputSet]:
    """The model's inputs once the saved JSON is shown to carry them: per mode, the same ``B`` and a box
    holding the model's ``U``.  Raises :class:`InputMismatch` (a refusal) otherwise."""
    saved = data.get("inputs", {})
    for mode, spec in given.items():
        if mode not in saved:
            raise InputMismatch(f"inputs: mode {mode!r} has an input in the model but the saved flowpipe has none "
                                "(it was computed without it)")
        entry = saved[mode]
        kept = _parse(mode, (entry["matrix"], (entry["low"], entry["high"])), n, "the saved inputs")
        if kept.matrix != spec.matrix:
            raise InputMismatch(f"inputs: mode {mode!r}: the saved input matrix is not the model's")
        if any(s > m for s, m in zip(kept.low, spec.low)) or any(s < m for s, m in zip(kept.high, spec.high)) \
                or len(kept.low) != len(spec.low):
            raise InputMismatch(f"inputs: mode {mode!r}: the saved input box [{[float(v) for v in kept.low]}, "
                                f"{[float(v) for v in kept.high]}] does not hold the model's "
                                f"[{[float(v) for v in spec.low]}, {[float(v) for v in spec.high]}]")
    return dict(given)


def _powers(absa: list[list[Fraction]], v: list[Fraction], count: int) -> list[list[Fraction]]:
    """``[v, |A| v, |A|² v, ...]`` (``count`` vectors)."""
    out = [list(v)]
    for _ in range(count - 1):
        out.append([sum((x * y for x, y in zip(row, out[-1])), Fraction(0)) for row in absa])
    return out


def input_tube(a: Sequence[Sequence[Fraction]], matrix: Sequence[Sequence[Fraction]], radius: Sequence[Fraction],
               step: Fraction, order: int = 6
               ) -> tuple[list[Fraction], list[list[Fraction]], list[list[Fraction]], list[Fraction]]:
    """``(w, series, first, rest)``: ``|v(s)| <= w`` on ``[0, δ]``; the vectors ``[|A^k B| r for k < K] + [|A^K| w]``
    of the sharper bound below (:func:`tube_at`); and ``v(δ) ∈ P₀ = ⊕ first ⊕ [−rest, rest]``: the generators
    ``δ^{k+1}/(k+1)! r_j (A^k B)_{:,j}`` (``k < K``) and ``rest = |A^K| w δ^K/K!`` (shape ``(n,)``).

    A first bound ``w >= δ(|A| w + |B| r)`` (see the module docstring) is sharpened by ``K = order`` Picard
    iterations of ``v(s) = ∫₀^s (B u₀ + A v)``: ``v(s) = Σ_{k<K} A^k B ∫₀^s u₀(τ)(s−τ)^k/k! dτ + A^K R(s)``
    with ``|R(s)| <= w s^K/K!``, and ``|∫₀^s u₀(τ)(s−τ)^k/k! dτ| <= r s^{k+1}/(k+1)!``; so
    ``|v(s)| <= Σ_{k<K} |A^k B| r s^{k+1}/(k+1)! + |A^K| w s^K/K!`` (increasing in ``s``); at ``s = δ`` the
    same sum kept as signed generators is ``P₀`` (each ``∫ u₀,j (δ−τ)^k/k!`` is one weight in
    ``[−r_j, r_j] δ^{k+1}/(k+1)!``).  The signed powers keep the cancellations of ``A`` that ``|A|^k``
    would lose.
    """
    absa = [[abs(v) for v in row] for row in a]
    b = [sum((abs(x) * y for x, y in zip(row, radius)), Fraction(0)) for row in matrix]
    q = step * max((sum(row, Fraction(0)) for row in absa), default=Fraction(0))
    if q >= 1:
        raise InputMismatch(f"inputs: δ‖A‖∞ = {float(q):.3g} >= 1 (the step is too large for the input bound)")

    def image(w: list[Fraction]) -> list[Fraction]:
        return [step * (sum((x * y for x, y in zip(row, w)), Fraction(0)) + bi) for row, bi in zip(absa, b)]

    w = [_up(step * max(b, default=Fraction(0)) / (1 - q))] * len(b)
    for _ in range(24):  # each iteration contracts the excess by q; a uniform w₀ would blur the chain's ends
        nxt = [_up(v) for v in image(w)]
        if not all(x >= y for x, y in zip(nxt, image(nxt))):
            break
        w = nxt
    n, f = len(b), math.factorial
    powers = [[[Fraction(int(i == j)) for j in range(n)] for i in range(n)]]  # A^k, signed
    for _ in range(order + 1):
        powers.append([[sum((x * a[m][j] for m, x in enumerate(row) if x), Fraction(0)) for j in range(n)]
                       for row in powers[-1]])
    pb = [[sum((abs(sum((p[i][m] * matrix[m][j] for m in range(n)), Fraction(0))) * r
                for j, r in enumerate(radius)), Fraction(0)) for i in range(n)] for p in powers]
    pw = [[sum((abs(x) * y for x, y in zip(row, w)), Fraction(0)) for row in p] for p in powers]
    first = [[step ** (k + 1) / f(k + 1) * r * sum((powers[k][i][m] * matrix[m][j] for m in range(n)), Fraction(0))
              for i in range(n)] for k in range(order) for j, r in enumerate(radius)]
    rest = [_up(v * step ** order / f(order)) for v in pw[order]]
    return w, pb[:order] + [pw[order]], [g for g in first if any(g)], rest


def tube_at(w: Sequence[Fraction], series: Sequence[Sequence[Fraction]], s: Fraction) -> list[Fraction]:
    """``|v(τ)| <= Σ_{k<K} |A^k B| r s^{k+1}/(k+1)! + |A^K| w s^K/K!`` for ``τ <= s <= δ`` (and ``<= w``)."""
    order = len(series) - 1
    f = math.factorial
    return [_up(min(w[i], sum((series[k][i] * s ** (k + 1) / f(k + 1) for k in range(order)), Fraction(0))
                    + series[order][i] * s ** order / f(order))) for i in range(len(w))]


def _expm_enclosure(a: Sequence[Sequence[Fraction]], step: Fraction) -> tuple[list[list[Fraction]], list[list[Fraction]]]:
    """``(Φc, Φr)``: floats with ``|e^{Aδ} − Φc| <= Φr`` entrywise."""
    n = len(a)
    ad = [[v * step for v in row] for row in a]
    q = max((sum((abs(v) for v in row), Fraction(0)) for row in ad), default=Fraction(0))
    total = [[Fraction(int(i == j)) for j in range(n)] for i in range(n)]
    term = [row[:] for row in total]
    k, tail = 0, Fraction(1)
    while True:
        k += 1
        term = [[sum((term[i][m] * ad[m][j] for m in range(n)), Fraction(0)) / k for j in range(n)] for i in range(n)]
        total = [[x + y for x, y in zip(r, t)] for r, t in zip(total, term)]
        if q < k + 2:
            tail = q ** (k + 1) / math.factorial(k + 1) / (1 - q / (k + 2))
            if tail < TAIL:
                break
        if k > 200:
            raise InputMismatch("inputs: e^{Aδ} could not be enclosed (‖Aδ‖ too large)")
    centre = [[Fraction(float(v)) for v in row] for row in total]
    radius = [[_up(abs(v - c) + tail) for v, c in zip(r, cr)] for r, cr in zip(total, centre)]
    return centre, radius


@dataclass(slots=True)
class InputFlow:
    """The input terms of one flowpipe: ``P_k`` (``gens`` ⊕ the box ``err``) and ``S_k`` (``carried_gens`` ⊕ the
    box ``carried``, zero-centred).

    ``S_{k+1} = S_k ⊕ P_k`` keeps ``P_k``'s generators (their correlations matter: a box of them, mapped by
    the next step's flow, would add corners no input reaches); beyond :data:`KEPT` generators per state, the
    ones with the smallest ``‖g‖₁ − ‖g‖∞`` go to the box (Girard's reduction; a box holds their sum).
    """

    dynamics: "InputDynamics"
    gens: list[list[Fraction]]
    err: list[Fraction]
    carried: list[Fraction]
    carried_gens: list[list[Fraction]] = field(default_factory=list)

    def generators(self) -> list[list[Fraction]]:
        """``S_k`` as generator columns (the box as diagonal ones)."""
        n = len(self.carried)
        return self.carried_gens + [[r if i == j else Fraction(0) for i in range(n)]
                                    for j, r in enumerate(self.carried) if r]

    def tube(self, s: Fraction) -> Box:
        """``[−t, t]`` holding ``v(τ)`` for ``τ <= s``: the current step's inputs up to ``s`` after its start."""
        cache = self.dynamics.tubes
        if s not in cache:
            cache[s] = [(-v, v) for v in tube_at(self.dynamics.bound, self.dynamics.series, s)]
        return cache[s]

    def advance(self) -> None:
        """``S_{k+1} = S_k + hull(P_k)``, ``P_{k+1} = e^{Aδ} P_k`` (enclosed)."""
        hull = [sum((abs(g[i]) for g in self.gens), Fraction(0)) + e for i, e in enumerate(self.err)]
        centre, radius = self.dynamics.phi
        n = len(centre)
        kept = self.carried_gens + self.gens
        box = list(self.carried)
        if len(kept) > KEPT * n:
            kept.sort(key=lambda g: sum((abs(v) for v in g), Fraction(0)) - max(abs(v) for v in g))
            for g in kept[:len(kept) - (KEPT - 1) * n]:
                box = [b + abs(v) for b, v in zip(box, g)]
            kept = kept[len(kept) - (KEPT - 1) * n:]
        self.carried = [_up(b + e) for b, e in zip(box, self.err)]
        self.carried_gens = kept
        err = [sum((abs(centre[i][k]) * self.err[k] + radius[i][k] * hull[k] for k in range(n)), Fraction(0))
               for i in range(n)]
        gens = []
        for g in self.gens:
            col = []
            for i in range(n):
                exact = sum((centre[i][k] * g[k] for k in range(n) if g[k]), Fraction(0))
                f = Fraction(float(exact))
                err[i] += abs(exact - f)
                col.append(f)
            gens.append(col)
        self.gens, self.err = gens, [_up(e) for e in err]


@dataclass(slots=True)
class InputDynamics:
    """One mode's input bounds for the step ``δ``: the tube ``w``, ``P₀`` and the ``e^{Aδ}`` enclosure."""

    a: list[list[Fraction]]
    spec: InputSet
    step: Fraction
    bound: list[Fraction] = field(init=False)
    series: list[list[Fraction]] = field(init=False)
    tubes: dict[Fraction, Box] = field(init=False)
    phi: tuple[list[list[Fraction]], list[list[Fraction]]] = field(init=False)
    first: list[list[Fraction]] = field(init=False)

    def __post_init__(self) -> None:
        r = self.spec.radius()
        self.bound, self.series, first, rest = input_tube(self.a, self.spec.matrix, r, self.step)
        self.tubes = {}
        n = len(self.a)
        gens = first + [[rest[i] if i == j else Fraction(0) for i in range(n)] for j in range(n)]
        self.first = [g for g in gens if any(g)]
        self.phi = _expm_enclosure(self.a, self.step)

    def start(self) -> InputFlow:
        """The input terms at a flowpipe's entry: ``S₀ = {0}``, ``P₀``; exact (floats kept by ``err``)."""
        n = len(self.a)
        err = [Fraction(0)] * n
        gens = []
        for g in self.first:
            col = []
            for i, v in enumerate(g):
                f = Fraction(float(v))
                err[i] += abs(v - f)
                col.append(f)
            gens.append(col)
        return InputFlow(dynamics=self, gens=gens, err=[_up(e) for e in err], carried=[Fraction(0)] * n)
