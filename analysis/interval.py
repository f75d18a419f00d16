"""Sound interval arithmetic on binary64 floats with outward rounding.

An :class:`Interval` ``[lo, hi]`` stands for every real number ``x`` with
``lo <= x <= hi``.  Every operation returns an interval that contains the
exact real result for every choice of real operands in the operand
intervals (the *enclosure property*), and keeps results that are exactly
representable exact.  It is the evaluation engine of
:mod:`analysis.certificate`, where exactness matters: a product or sum with
an exact ``0`` bound stays exactly ``0``, so an enclosure can prove ``<= 0``
on a box that touches the zero set of the function.

Rounding argument
-----------------
Python floats are IEEE-754 binary64 with round-to-nearest.  For ``+``, ``-``,
``*``, ``/`` and ``sqrt`` the rounded result ``r`` of ``a op b`` is computed,
then the *exact sign* of the rounding error ``(a op b) - r`` is determined by
an error-free transformation (Knuth's TwoSum for sums; Dekker's TwoProduct
with Veltkamp splitting for products, quotient residuals and squares, valid
when every operand lies in ``[2**-450, 2**450]`` in magnitude; exact
:class:`fractions.Fraction` arithmetic outside that range).  The lower bound
is ``r`` if the error is ``>= 0`` and the next float below ``r`` otherwise
(``math.nextafter``); symmetrically for the upper bound.  Hence exact
results stay exact and inexact ones are widened by one ulp, which is the
tightest enclosure with float bounds.  A zero operand of a product gives
exactly ``0``.  Overflow gives ``±inf`` on the outward side and
``±max_float`` on the inward side (the exact value is beyond ``max_float``).

``sin`` and ``cos`` use the platform ``libm`` (``math.sin``, ``math.cos``),
which is not correctly rounded but is accurate to within one ulp on every
mainstream platform; each endpoint value is widened by
:data:`TRIG_WIDENING_ULPS` ulps on each side and clipped to ``[-1, 1]``.
Interior extrema (``±1`` at ``pi/2 + m pi`` for sine, ``m pi`` for cosine)
are detected with a tolerance of :data:`TRIG_CRITICAL_TOLERANCE` relative to
the critical point, so a nearby extremum is included rather than missed
(including it is always sound).  Exact values are kept exact: ``sin(0) = 0``
and ``cos(0) = 1``; on ``[0, pi]`` (resp. ``[-pi, 0]``) the lower (resp.
upper) bound of ``sin`` is clipped to ``0``, and on ``[-pi/2, pi/2]`` the
lower bound of ``cos`` is clipped to ``0`` — sound because ``math.pi < pi``.

Examples
--------
>>> Interval(1.0, 2.0) + Interval(3.0, 4.0)
Interval(lo=4.0, hi=6.0)
>>> Interval(0.0, 2.0) * Interval(-3.0, -1.0)
Interval(lo=-6.0, hi=0.0)
>>> Interval(0.0, 1.0).sin().lo
0.0
>>> x = Interval.point(0.1) + Interval.point(0.2)   # 0.1 + 0.2 is not a float
>>> x.lo < x.hi
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Collection, Mapping
from fractions import Fraction
from numbers import Rational
from typing import Any

__all__ = [
    "TRIG_WIDENING_ULPS",
    "TRIG_CRITICAL_TOLERANCE",
    "InvalidInterval",
    "IntervalDomainError",
    "Interval",
    "add_bounds",
    "mul_bounds",
    "div_bounds",
    "sqrt_bounds",
    "box_bounds",
]

TRIG_WIDENING_ULPS = 2
"""Ulps by which ``libm`` ``sin``/``cos`` values are widened on each side (libm error < 1 ulp)."""
TRIG_CRITICAL_TOLERANCE = 2.0**-40
"""Relative tolerance with which an interval is deemed to contain a critical point of sin/cos."""
_TRIG_MAX_ARGUMENT = 2.0**40
"""Beyond this magnitude sin/cos enclosures are ``[-1, 1]`` (critical points cannot be located)."""

_MAX_FLOAT = 1.7976931348623157e308
_SPLITTER = 134217729.0  # 2**27 + 1 (Veltkamp)
_SAFE_LOW = 2.0**-450
_SAFE_HIGH = 2.0**450
_INF = math.inf
_PI = math.pi  # the float just below pi
_HALF_PI = math.pi / 2  # exact halving: just below pi/2


# --------------------------------------------------------------------------- errors


class InvalidInterval(ValueError):
    """Bounds that do not define an interval (NaN, ``lo > hi``, ``lo = +inf`` or ``hi = -inf``)."""


class IntervalDomainError(ValueError):
    """An operation outside its domain: division by an interval containing 0, sqrt of negatives."""


# --------------------------------------------------------------------------- error-free kernels


def _safe(x: float) -> bool:
    """True if ``|x|`` is 0 or in ``[2**-450, 2**450]`` (Dekker's TwoProduct is exact there)."""
    ax = abs(x)
    return ax == 0.0 or _SAFE_LOW <= ax <= _SAFE_HIGH


def _two_product_error(a: float, b: float, p: float) -> float:
    """Return ``a*b - p`` exactly (Dekker), for ``p = fl(a*b)`` and ``a``, ``b`` safe."""
    c = _SPLITTER * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLITTER * b
    bh = c - (c - b)
    bl = b - bh
    return ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _sign(x: float | Fraction) -> int:
    return (x > 0) - (x < 0)


def _round_pair(r: float, error_sign: int) -> tuple[float, float]:
    """``(down, up)`` bounds of the exact value ``r + e`` given ``sign(e)``."""
    if error_sign == 0:
        return r, r
    if error_sign > 0:
        return r, math.nextafter(r, _INF)
    return math.nextafter(r, -_INF), r


def _overflow_pair(r: float) -> tuple[float, float]:
    """Bounds of an exact value whose rounding overflowed to ``r = ±inf`` from finite operands."""
    return (_MAX_FLOAT, _INF) if r > 0 else (-_INF, -_MAX_FLOAT)


def add_bounds(a: float, b: float) -> tuple[float, float]:
    """Tightest float bounds ``(down, up)`` of the exact sum ``a + b``.

    ``down == up`` exactly when the sum is a float.  Infinite operands
    (never ``+inf + -inf``) give the exact infinite sum.

    Examples
    --------
    >>> add_bounds(1.0, 2.0)
    (3.0, 3.0)
    >>> lo, hi = add_bounds(0.1, 0.2)
    >>> math.nextafter(lo, 1.0) == hi
    True
    """
    s = a + b
    if math.isinf(s):
        if math.isinf(a) or math.isinf(b):
            return s, s
        return _overflow_pair(s)
    bb = s - a
    err = (a - (s - bb)) + (b - bb)  # TwoSum: a + b = s + err exactly
    return _round_pair(s + 0.0, _sign(err))


def mul_bounds(a: float, b: float) -> tuple[float, float]:
    """Tightest float bounds ``(down, up)`` of the exact product ``a * b``.

    A zero factor gives exactly ``(0.0, 0.0)``, also against an infinite
    factor (an infinite bound stands for unbounded reals, whose product
    with 0 is 0).

    Examples
    --------
    >>> mul_bounds(0.0, -math.inf)
    (0.0, 0.0)
    >>> mul_bounds(3.0, 0.5)
    (1.5, 1.5)
    """
    if a == 0.0 or b == 0.0:
        return 0.0, 0.0
    p = a * b
    if math.isinf(p):
        if math.isinf(a) or math.isinf(b):
            return p, p
        return _overflow_pair(p)
    if _safe(a) and _safe(b):
        return _round_pair(p, _sign(_two_product_error(a, b, p)))
    return _round_pair(p, _sign(Fraction(a) * Fraction(b) - Fraction(p)))


def div_bounds(a: float, b: float) -> tuple[float, float]:
    """Tightest float bounds ``(down, up)`` of the exact quotient ``a / b`` (``b != 0``, finite).

    Examples
    --------
    >>> div_bounds(1.0, 4.0)
    (0.25, 0.25)
    >>> lo, hi = div_bounds(1.0, 3.0)
    >>> Fraction(lo) < Fraction(1, 3) < Fraction(hi)
    True
    """
    if a == 0.0:
        return 0.0, 0.0
    if math.isinf(a):
        q = a / b
        return q, q
    q = a / b
    if math.isinf(q):
        return _overflow_pair(q)
    if q == 0.0 or not (_safe(a) and _safe(b) and _safe(q)):
        residual = Fraction(a) - Fraction(q) * Fraction(b)
    else:
        p = q * b
        residual = (a - p) - _two_product_error(q, b, p)  # a - p is exact (Sterbenz)
    # a / b = q + residual / b
    return _round_pair(q + 0.0, _sign(residual) * _sign(b))


def sqrt_bounds(x: float) -> tuple[float, float]:
    """Tightest float bounds ``(down, up)`` of ``sqrt(x)`` for ``x >= 0``.

    Examples
    --------
    >>> sqrt_bounds(4.0)
    (2.0, 2.0)
    """
    if x == 0.0 or math.isinf(x):
        return x + 0.0, x + 0.0
    s = math.sqrt(x)
    if _safe(s) and _safe(x):
        p = s * s
        excess = (p - x) + _two_product_error(s, s, p)  # s*s - x, sign exact (p - x is exact)
    else:
        excess = Fraction(s) * Fraction(s) - Fraction(x)
    # sqrt(x) > s iff s*s < x
    return _round_pair(s, -_sign(excess))


def _widen(value: float, ulps: int) -> tuple[float, float]:
    lo = hi = value
    for _ in range(ulps):
        lo = math.nextafter(lo, -_INF)
        hi = math.nextafter(hi, _INF)
    return max(lo, -1.0), min(hi, 1.0)


def _fraction_bounds(q: Fraction) -> tuple[float, float]:
    try:
        f = float(q)  # int / int true division: correctly rounded
    except OverflowError:
        return _overflow_pair(_INF if q > 0 else -_INF)
    if math.isinf(f):
        return _overflow_pair(f)
    return _round_pair(f, _sign(q - Fraction(f)))


def _to_interval(value: object) -> Interval:
    if isinstance(value, Interval):
        return value
    if isinstance(value, (bool,)):
        raise TypeError(f"cannot use a bool ({value!r}) as an interval operand; pass a number")
    if isinstance(value, (float, int, Rational)):
        return Interval.enclosing(value)
    return NotImplemented  # type: ignore[return-value]


# --------------------------------------------------------------------------- the interval


@dataclass(frozen=True, slots=True)
class Interval:
    """A closed interval ``[lo, hi]`` of reals with float bounds.

    Positional construction ``Interval(lo, hi)`` is allowed (unlike the
    keyword-only models of the project) because the order is universal.

    Parameters
    ----------
    lo, hi : float
        Bounds, ``lo <= hi``; ``lo`` may be ``-inf`` and ``hi`` may be
        ``+inf`` (unbounded), but not ``lo = +inf`` or ``hi = -inf``.
        ``-0.0`` is normalised to ``0.0``.

    Raises
    ------
    InvalidInterval
        If a bound is NaN or not a real number, or ``lo > hi``.
    """

    lo: float
    hi: float

    def __post_init__(self) -> None:
        try:
            lo, hi = float(self.lo), float(self.hi)
        except (TypeError, ValueError) as err:
            raise InvalidInterval(
                f"Interval(lo={self.lo!r}, hi={self.hi!r}): bounds must be real numbers; pass floats"
            ) from err
        if math.isnan(lo) or math.isnan(hi):
            raise InvalidInterval(f"Interval(lo={lo!r}, hi={hi!r}): NaN bound; bounds must be numbers")
        if lo > hi:
            raise InvalidInterval(
                f"Interval(lo={lo!r}, hi={hi!r}): expected lo <= hi; swap the bounds"
            )
        if lo == _INF or hi == -_INF:
            raise InvalidInterval(
                f"Interval(lo={lo!r}, hi={hi!r}): an interval cannot lie entirely at infinity; "
                f"use finite bounds (only lo = -inf or hi = +inf are allowed)"
            )
        object.__setattr__(self, "lo", lo + 0.0)
        object.__setattr__(self, "hi", hi + 0.0)

    # ---- construction

    @classmethod
    def point(cls, x: float) -> Interval:
        """The degenerate interval ``[x, x]`` for a float ``x`` (exact)."""
        return cls(x, x)

    @classmethod
    def enclosing(cls, value: float | int | Fraction) -> Interval:
        """Tightest interval around an exact number (``int`` and ``Fraction`` may not be floats).

        Examples
        --------
        >>> Interval.enclosing(Fraction(1, 2))
        Interval(lo=0.5, hi=0.5)
        >>> iv = Interval.enclosing(Fraction(1, 3))
        >>> iv.lo < iv.hi
        True
        """
        if isinstance(value, float):
            return cls(value, value)
        if isinstance(value, bool) or not isinstance(value, (int, Rational)):
            raise TypeError(
                f"value = {value!r} ({type(value).__name__}): expected a float, int or Fraction"
            )
        return cls(*_fraction_bounds(Fraction(value)))

    # ---- queries

    @property
    def width(self) -> float:
        """Upper bound of ``hi - lo`` (rounded up)."""
        return add_bounds(self.hi, -self.lo)[1]

    @property
    def mid(self) -> float:
        """A float in ``[lo, hi]`` near the midpoint (``lo`` if unbounded below, ``hi`` if above)."""
        if math.isinf(self.lo) or math.isinf(self.hi):
            return self.hi if math.isinf(self.lo) else self.lo
        m = 0.5 * self.lo + 0.5 * self.hi
        return min(max(m, self.lo), self.hi)

    @property
    def is_point(self) -> bool:
        """True if ``lo == hi``."""
        return self.lo == self.hi

    def __contains__(self, x: object) -> bool:
        """``x in iv``: exact comparison for floats, ints and Fractions."""
        if isinstance(x, Interval):
            return self.lo <= x.lo and x.hi <= self.hi
        return self.lo <= x <= self.hi  # type: ignore[operator]

    def __str__(self) -> str:
        return f"[{self.lo!r}, {self.hi!r}]"

    # ---- arithmetic

    def __neg__(self) -> Interval:
        return Interval(-self.hi, -self.lo)

    def __pos__(self) -> Interval:
        return self

    def __add__(self, other: object) -> Interval:
        other = _to_interval(other)
        if other is NotImplemented:
            return NotImplemented
        return Interval(add_bounds(self.lo, other.lo)[0], add_bounds(self.hi, other.hi)[1])

    __radd__ = __add__

    def __sub__(self, other: object) -> Interval:
        other = _to_interval(other)
        if other is NotImplemented:
            return NotImplemented
        return self + (-other)

    def __rsub__(self, other: object) -> Interval:
        other = _to_interval(other)
        if other is NotImplemented:
            return NotImplemented
        return other + (-self)

    def __mul__(self, other: object) -> Interval:
        other = _to_interval(other)
        if other is NotImplemented:
            return NotImplemented
        a, b, c, d = self.lo, self.hi, other.lo, other.hi
        if a >= 0.0 and c >= 0.0:  # common case: both non-negative
            return Interval(mul_bounds(a, c)[0], mul_bounds(b, d)[1])
        products = (mul_bounds(a, c), mul_bounds(a, d), mul_bounds(b, c), mul_bounds(b, d))
        return Interval(min(p[0] for p in products), max(p[1] for p in products))

    __rmul__ = __mul__

    def __truediv__(self, other: object) -> Interval:
        other = _to_interval(other)
        if other is NotImplemented:
            return NotImplemented
        if other.lo <= 0.0 <= other.hi:
            raise IntervalDomainError(
                f"division by {other}: the divisor interval contains 0; split it or bound it away from 0"
            )
        a, b, c, d = self.lo, self.hi, other.lo, other.hi
        quotients = (div_bounds(a, c), div_bounds(a, d), div_bounds(b, c), div_bounds(b, d))
        return Interval(min(q[0] for q in quotients), max(q[1] for q in quotients))

    def __rtruediv__(self, other: object) -> Interval:
        other = _to_interval(other)
        if other is NotImplemented:
            return NotImplemented
        return other / self

    def __pow__(self, n: int) -> Interval:
        """``x**n`` for an integer ``n >= 0``, tight for even ``n`` (``[-1, 2]**2 = [0, 4]``)."""
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise TypeError(f"exponent n = {n!r}: expected an integer >= 0 (interval powers are integer)")
        if n == 0:
            return Interval(1.0, 1.0)
        if n == 1:
            return self
        lo, hi = self.lo, self.hi
        if lo >= 0.0:
            return Interval(_pow_nonneg(lo, n)[0], _pow_nonneg(hi, n)[1])
        if hi <= 0.0:
            if n % 2 == 0:
                return Interval(_pow_nonneg(-hi, n)[0], _pow_nonneg(-lo, n)[1])
            return Interval(-_pow_nonneg(-lo, n)[1], -_pow_nonneg(-hi, n)[0])
        if n % 2 == 0:
            return Interval(0.0, max(_pow_nonneg(-lo, n)[1], _pow_nonneg(hi, n)[1]))
        return Interval(-_pow_nonneg(-lo, n)[1], _pow_nonneg(hi, n)[1])

    # ---- elementary functions

    def sqrt(self) -> Interval:
        """Square root; the interval must lie in ``[0, inf]``.

        Raises
        ------
        IntervalDomainError
            If ``lo < 0``.
        """
        if self.lo < 0.0:
            raise IntervalDomainError(
                f"sqrt of {self}: the interval contains negative numbers; clip it to lo >= 0 first"
            )
        return Interval(sqrt_bounds(self.lo)[0], sqrt_bounds(self.hi)[1])

    def sin(self) -> Interval:
        """Enclosure of ``{sin x : x in self}`` (see the module docstring for the rounding).

        Examples
        --------
        >>> Interval(0.0, 0.0).sin()
        Interval(lo=0.0, hi=0.0)
        >>> Interval(1.0, 2.0).sin().hi   # contains pi/2
        1.0
        """
        return _trig(self, math.sin, phase=0.5)

    def cos(self) -> Interval:
        """Enclosure of ``{cos x : x in self}`` (see the module docstring for the rounding).

        Examples
        --------
        >>> Interval(0.0, 0.0).cos()
        Interval(lo=1.0, hi=1.0)
        >>> Interval(3.0, 3.5).cos().lo   # contains pi
        -1.0
        """
        return _trig(self, math.cos, phase=0.0)


def _pow_nonneg(x: float, n: int) -> tuple[float, float]:
    """Bounds ``(down, up)`` of ``x**n`` for ``x >= 0`` by square-and-multiply with directed rounding."""
    down, up = 1.0, 1.0
    base_down, base_up = x, x
    while True:
        if n & 1:
            down = mul_bounds(down, base_down)[0]
            up = mul_bounds(up, base_up)[1]
        n >>= 1
        if not n:
            return down, up
        base_down = mul_bounds(base_down, base_down)[0]
        base_up = mul_bounds(base_up, base_up)[1]


def _trig_point(func, x: float) -> tuple[float, float]:
    if x == 0.0:
        value = func(0.0)  # sin 0 = 0, cos 0 = 1: exact
        return value, value
    return _widen(func(x), TRIG_WIDENING_ULPS)


def _trig(iv: Interval, func, *, phase: float) -> Interval:
    """Enclose ``func`` (sin or cos) over ``iv``; critical points are ``(m + phase) * pi``.

    Maxima (value 1) at even ``m``, minima (value -1) at odd ``m``.
    """
    lo, hi = iv.lo, iv.hi
    if math.isinf(lo) or math.isinf(hi) or max(abs(lo), abs(hi)) > _TRIG_MAX_ARGUMENT or hi - lo >= 2 * _PI:
        return Interval(-1.0, 1.0)
    low_lo, low_hi = _trig_point(func, lo)
    high_lo, high_hi = _trig_point(func, hi)
    out_lo, out_hi = min(low_lo, high_lo), max(low_hi, high_hi)
    first = math.floor(lo / _PI - phase) - 1
    last = math.ceil(hi / _PI - phase) + 1
    for m in range(first, last + 1):
        c = (m + phase) * _PI
        tol = TRIG_CRITICAL_TOLERANCE * max(1.0, abs(c))
        if lo - tol <= c <= hi + tol:
            if m % 2 == 0:
                out_hi = 1.0
            else:
                out_lo = -1.0
    # sign information that rounding must not destroy (math.pi < pi, math.pi / 2 < pi / 2)
    if phase == 0.5:  # sine
        if 0.0 <= lo and hi <= _PI:
            out_lo = max(out_lo, 0.0)
        elif -_PI <= lo and hi <= 0.0:
            out_hi = min(out_hi, 0.0)
    elif -_HALF_PI <= lo and hi <= _HALF_PI:  # cosine
        out_lo = max(out_lo, 0.0)
    return Interval(out_lo, out_hi)


def box_bounds(parameter: str, box: Any, *, error: type[ValueError], allow_flat: bool = False,
               variables: Collection[str] | None = None,
               fix: str = "bound every variable") -> dict[str, tuple[float, float]]:
    """A box ``{variable: (lo, hi)}`` given by a caller, checked: the one validation of such a parameter.

    Parameters
    ----------
    parameter : str
        Its name in messages (``box``, ``region``).
    box : Mapping[str, (float, float)]
    error : type
        A :class:`hybrid.errors.ParameterError` subclass, called as ``error(name, value, expected, fix)``.
    allow_flat : bool
        Accept ``lo == hi`` (a fixed value) instead of asking for an interior.
    variables : collection of str or None
        The names allowed (``None``: any).
    fix : str
        The fix of an empty or non-mapping box.

    Returns
    -------
    dict of str -> (float, float)
        Finite bounds ``lo <= hi`` (``lo < hi`` unless ``allow_flat``), in the box's order.
    """
    if not isinstance(box, Mapping) or not box:
        raise error(parameter, box, "a non-empty mapping {variable: (lo, hi)}", fix)
    out = {}
    for name, pair in box.items():
        if variables is not None and name not in variables:
            raise error(parameter, name, f"a variable among {list(variables)}", "bound only declared variables")
        where = f"{parameter}[{name!r}]"
        try:
            lo, hi = (float(x) for x in pair)
        except (TypeError, ValueError):
            raise error(where, pair, "a pair (lo, hi) of numbers", "give two numbers") from None
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise error(where, pair, "finite bounds", "bound the variable")
        if lo > hi:
            raise error(where, pair, "lo <= hi", f"swap the bounds: ({hi}, {lo})")
        if lo == hi and not allow_flat:
            raise error(where, pair, "lo < hi (a box with interior)", "widen the range")
        out[str(name)] = (lo + 0.0, hi + 0.0)
    return out
