"""The one-step input set ``V`` of the flowpipe, through sub-steps: no ``e^{‖|A|‖δ}`` factor.

For ``ẋ = A x + w``, ``w(t) ∈ W = B U₀`` (a zero-centred zonotope, measurable ``w``), the states the input adds over
one step from 0 are the reach set

``R(τ) = {∫₀^τ e^{A s} w(s) ds : w(·) ∈ W}``  (``τ ∈ [0, δ]``).

The flowpipe (:mod:`analysis.reach.flowpipe`) needs ``V ⊇ R(τ)`` for every ``τ ∈ [0, δ]``.  Since ``0 ∈ W``,
``R(τ) ⊆ R(δ)`` (play ``w = 0`` for ``δ − τ`` first: the state stays 0, then the input reaching ``v`` at ``τ``
reaches it at ``δ``), so ``V ⊇ R(δ)`` suffices.  The former ``V = δ W ⊕ box(S |W|)``,
``S = Σ_{k>=1} |A|^k δ^{k+1}/(k+1)!``, bounds ``e^{As} − I`` by the series of ``|A|``: for a stiff mode
(``κ = ‖A‖∞ δ ≈ 4``) up to ``e^κ ≈ 50`` times the reach set (a scalar ``ẋ = −a x + u`` gives ``δ (e^κ − 1)/κ``
against the exact ``δ (1 − e^{−κ})/κ``).

Here ``R(δ)`` is split into ``m`` sub-steps ``h = δ/m`` (``m`` a power of two with ``‖A‖∞ h <= 1/8``), exactly:

``R(δ) = ⊕_{j<m} e^{A j h} R(h)``

(the integral over ``[jh, (j+1)h]`` is ``e^{Ajh} ∫₀^h e^{Aσ} w(jh + σ) dσ`` and the input's pieces are independent).
One sub-step is enclosed by the first two Taylor terms kept as generators and the rest as a box:

``∫₀^h e^{Aσ} w dσ = ∫₀^h w + A ∫₀^h σ w + ∫₀^h (e^{Aσ} − I − Aσ) w ∈ h W ⊕ (h²/2) A W ⊕ [−ρ, ρ]``,

``ρ = Σ_{k>=2} |A|^k |W| h^{k+1}/(k+1)!`` (``∫₀^h w`` and ``∫₀^h σ w / (h²/2)`` are averages of ``w``, so in ``W``;
``|W|`` the magnitude vector of ``W``).  ``ρ`` is about ``(‖A‖h)²/6`` of ``h|W|``: below 0.3 %.  Each sub-step's set
is mapped by an interval enclosure of ``e^{Ah}`` (:func:`analysis.reach.series.exp_enclosure`) with the roundings and
the enclosure's radius in a box that is mapped by ``|Φc| + Φr`` (``m`` maps only: no wrapping to speak of).  The
generators ``e^{Ajh} h W`` and ``e^{Ajh} (h²/2) A W`` keep the input's correlations; the sum has ``2 q m``
generators (``q`` those of ``W``) and one box.  What remains of the over-approximation is the independence of the two
Taylor terms (about ``‖A‖h / 2 <= 6 %`` of the first) and the box ``ρ``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction

import numpy as np

from .series import exp_enclosure
from .zonotope import UNIT_ROUNDOFF, Zonotope, box_generators, linear_map, magnitude, upper

__all__ = ["input_step_set", "substeps", "SUBSTEP_NORM", "REMAINDER_ORDER"]

SUBSTEP_NORM = 0.125
"""The largest ``‖A‖∞ h`` of a sub-step."""
REMAINDER_ORDER = 12
"""Terms ``k = 2 .. REMAINDER_ORDER`` of ``ρ`` are summed; the rest is bounded by a geometric tail."""


def substeps(a: Sequence[Sequence[Fraction]], step: float) -> int:
    """``m``: the smallest power of two with ``‖A‖∞ δ / m <= SUBSTEP_NORM`` (``1`` for a zero ``A``)."""
    norm = max((sum((abs(q) for q in row), Fraction(0)) for row in a), default=Fraction(0))
    m = 1
    while norm * Fraction(step) > m * Fraction(SUBSTEP_NORM):
        m *= 2
    return m


def _abs_up(a: Sequence[Sequence[Fraction]]) -> np.ndarray:
    """Floats ``>= |a_ij|`` entrywise."""
    out = np.array([[float(abs(q)) for q in row] for row in a], dtype=float).reshape(len(a), -1)
    for i, row in enumerate(a):
        for j, q in enumerate(row):
            if Fraction(out[i, j]) < abs(q):
                out[i, j] = float(np.nextafter(out[i, j], np.inf))
    return out


def _remainder(abs_a: np.ndarray, mag: np.ndarray, h: float) -> np.ndarray:
    """``>= Σ_{k>=2} |A|^k mag h^{k+1}/(k+1)!`` entrywise (``abs_a >= |A|``), shape ``(n,)``.

    ``y_k = |A| y_{k−1} h/(k+1)`` from ``y_0 = h mag`` is computed upward (:func:`upper`); beyond
    :data:`REMAINDER_ORDER` every entry of ``y_k`` is at most ``q^k ‖mag‖∞ h/(k+1)!`` with ``q >= ‖|A| h‖∞``, whose sum
    is below its first term over ``1 − q/(K+3)``.
    """
    n = mag.size
    y = upper(mag * h, 1)
    total = np.zeros(n)
    for k in range(1, REMAINDER_ORDER + 1):
        y = upper((abs_a @ y) * h / (k + 1), n + 3)
        if k >= 2:
            total = total + y
    q = float(upper(abs_a.sum(axis=1).max(initial=0.0) * h, n + 1))
    first = float(upper(q ** (REMAINDER_ORDER + 1) * float(np.max(mag, initial=0.0)) * h
                        / math.factorial(REMAINDER_ORDER + 2), REMAINDER_ORDER + 4))
    tail = float(upper(first / (1.0 - q / (REMAINDER_ORDER + 3)), 3))
    return upper(total + tail, REMAINDER_ORDER + 2)


def input_step_set(a: Sequence[Sequence[Fraction]], w: Zonotope, step: float) -> Zonotope:
    """A zero-centred zonotope ``V ⊇ R(τ)`` for every ``τ ∈ [0, step]`` (module docstring).

    Parameters
    ----------
    a : n × n Fractions
        ``A`` (exact).
    w : Zonotope of dimension n
        Zero-centred, holding ``B U₀`` (the caller's float map of the input box, its roundings included).
    step : float
        ``δ > 0`` [s].

    Returns
    -------
    Zonotope
        Dimension ``n``, centre 0, ``2 q m`` generators (``q`` those of ``w``, ``m`` :func:`substeps`) and a box.
    """
    n = len(a)
    m = substeps(a, step)
    h = step / m  # a power-of-two division: exact
    gens = w.generators
    mag = magnitude(w)
    abs_a = _abs_up(a)
    ac = np.array([[float(q) for q in row] for row in a], dtype=float).reshape(n, n)
    ar = upper(np.array([[float(abs(q - Fraction(float(q)))) for q in row] for row in a]).reshape(n, n), 1)
    first = gens * h
    image, e_a = linear_map(Zonotope(center=np.zeros(n), generators=gens), ac, ar)  # A W ⊆ image ⊕ [−e_a, e_a]
    half = h * h * 0.5
    second = image.generators * half
    err = (upper(UNIT_ROUNDOFF * np.abs(first).sum(axis=1), w.order + 1)
           + upper(e_a * half + 3.0 * UNIT_ROUNDOFF * (np.abs(second).sum(axis=1) + e_a * half), w.order + 4)
           + _remainder(abs_a, mag, h))
    err = upper(err, 3)
    phi = exp_enclosure(a, Fraction(h))
    abs_phi = upper(np.abs(phi.center) + phi.radius, 1)
    part = Zonotope(center=np.zeros(n), generators=np.hstack([first, second]))
    kept, box = [], np.zeros(n)
    for j in range(m):
        kept.append(part.generators)
        box = box + err
        if j + 1 < m:
            part, e_map = linear_map(part, phi.center, phi.radius)
            err = upper(abs_phi @ err, n + 1) + e_map
    box = upper(box, m + 1)
    return Zonotope(center=np.zeros(n), generators=np.hstack([*kept, box_generators(box)]))
