"""The float kernels of the producer's interval enclosures, written once.

:func:`hybrid.symbolic.enclose` (a tree walk) and :mod:`analysis.reach.enclose_compiled` (the same
enclosures compiled into a straight-line program) both compute a node's bounds with these functions, so
the two give the same floats by construction.  Each result is widened outward by whole ulps
(``math.nextafter``), infinite bounds kept; the argument why each covers the exact result is beside each
function.  (The independent re-check has its own interval arithmetic, :mod:`analysis.interval`.)
"""

from __future__ import annotations

import math

__all__ = ["round_down", "round_up", "mul_bounds", "pow_bounds", "trig_bounds"]


def round_down(x: float) -> float:
    """The float below ``x`` (``x`` itself when infinite or NaN): a lower bound of any real that rounds to
    ``x`` under round-to-nearest."""
    return math.nextafter(x, -math.inf) if math.isfinite(x) else x


def round_up(x: float) -> float:
    """The float above ``x`` (``x`` itself when infinite or NaN)."""
    return math.nextafter(x, math.inf) if math.isfinite(x) else x


def _corner(x: float, y: float) -> float:
    if (x == 0.0 and math.isinf(y)) or (y == 0.0 and math.isinf(x)):
        return 0.0
    return x * y


def mul_bounds(al: float, ah: float, bl: float, bh: float) -> tuple[float, float]:
    """``[al, ah] × [bl, bh]``: the least and greatest of the four corner products (``0·∞`` taken as 0, the
    product's limit), one ulp outward (each product is correctly rounded, so within half an ulp)."""
    p = (_corner(al, bl), _corner(al, bh), _corner(ah, bl), _corner(ah, bh))
    return round_down(min(p)), round_up(max(p))


def _power(x: float, k: int) -> float:
    try:
        return x ** k
    except OverflowError:
        return -math.inf if (x < 0.0 and k % 2 == 1) else math.inf


def pow_bounds(lo: float, hi: float, k: int) -> tuple[float, float]:
    """``[lo, hi] ** k`` for an integer ``k ≥ 0``: the end points' powers (0 the least of an even power of an
    interval holding 0), two ulps outward (``x ** k`` by repeated squaring may round more than once; the
    platform's ``pow`` is within an ulp for the exponents of a polynomial flow)."""
    if k == 0:
        return 1.0, 1.0
    ends = (_power(lo, k), _power(hi, k))
    low = 0.0 if (k % 2 == 0 and lo <= 0.0 <= hi) else min(ends)
    return round_down(round_down(low)), round_up(round_up(max(ends)))


def trig_bounds(op: str, lo: float, hi: float) -> tuple[float, float]:
    """``sin`` or ``cos`` (``op``) of ``[lo, hi]``: the values at the end points and at the interior extremes
    ``shift + kπ``, one ulp and ``1e-15`` outward (libm's sin/cos are within an ulp; the extremes' abscissae
    are found with a ``1e-12`` margin, so an extreme is never missed), clipped to ``[−1, 1]``; the whole
    ``[−1, 1]`` for an infinite interval or one of width ``2π`` or more."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi - lo >= 2.0 * math.pi:
        return -1.0, 1.0
    f = math.sin if op == "sin" else math.cos
    shift = 0.5 * math.pi if op == "sin" else 0.0  # extremes of f at shift + k pi
    values = [f(lo), f(hi)]
    k = math.ceil((lo - shift) / math.pi - 1e-12)
    while shift + k * math.pi <= hi + 1e-12:
        values.append(f(shift + k * math.pi))
        k += 1
    return max(-1.0, round_down(min(values)) - 1e-15), min(1.0, round_up(max(values)) + 1e-15)
