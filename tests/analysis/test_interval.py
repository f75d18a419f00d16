"""Tests of analysis.interval: enclosure property (exact references), tightness, exactness, errors."""

from __future__ import annotations

import math
from decimal import Decimal, localcontext
from fractions import Fraction

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from analysis.interval import (
    Interval,
    IntervalDomainError,
    InvalidInterval,
    add_bounds,
    div_bounds,
    mul_bounds,
    sqrt_bounds,
)

# 100 digits of pi: an independent high-precision reference for sin and cos
PI = Decimal(
    "3.141592653589793238462643383279502884197169399375105820974944592307816406286208998628034825342117068"
)


def reference_sin_cos(x: float) -> tuple[Decimal, Decimal]:
    """sin(x), cos(x) of the exact float x to ~55 digits (Taylor series after reduction mod 2 pi)."""
    with localcontext() as ctx:
        ctx.prec = 70
        r = Decimal(x)
        r -= (r / (2 * PI)).to_integral_value() * 2 * PI
        s = term = r
        c, cterm = Decimal(1), Decimal(1)
        k = 1
        while abs(term) > Decimal(10) ** -60 or abs(cterm) > Decimal(10) ** -60:
            term = -term * r * r / ((2 * k) * (2 * k + 1))
            cterm = -cterm * r * r / ((2 * k - 1) * (2 * k))
            s += term
            c += cterm
            k += 1
        return s, c


def contains_exact(iv: Interval, value: Fraction | Decimal) -> bool:
    return Fraction(iv.lo) <= Fraction(value) <= Fraction(iv.hi)


finite = st.floats(min_value=-1e300, max_value=1e300, allow_nan=False, allow_infinity=False)
moderate = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
tiny = st.floats(min_value=-1e-300, max_value=1e-300, allow_nan=False, allow_infinity=False)
anyfloat = st.one_of(moderate, finite, tiny, st.sampled_from([0.0, 1.0, -1.0, 0.1, 3.0, math.pi]))


@st.composite
def interval_and_point(draw, values=anyfloat):
    a, b = sorted((draw(values) + 0.0, draw(values) + 0.0))
    x = draw(st.one_of(st.floats(min_value=a, max_value=b), st.sampled_from([a, b])))
    return Interval(a, b), x


# --------------------------------------------------------------------------- kernels


@given(anyfloat, anyfloat)
def test_add_bounds_are_the_tightest_floats_around_the_exact_sum(a, b):
    lo, hi = add_bounds(a, b)
    exact = Fraction(a) + Fraction(b)
    assert Fraction(lo) <= exact <= Fraction(hi)
    assert (lo == hi) == (Fraction(lo) == exact)
    if lo != hi:
        assert math.nextafter(lo, math.inf) == hi


@given(anyfloat, anyfloat)
def test_mul_bounds_are_the_tightest_floats_around_the_exact_product(a, b):
    lo, hi = mul_bounds(a, b)
    exact = Fraction(a) * Fraction(b)
    if math.isinf(hi) or math.isinf(lo):  # overflow: the exact value is beyond max_float
        assert abs(exact) > Fraction(1.7976931348623157e308)
        return
    assert Fraction(lo) <= exact <= Fraction(hi)
    assert (lo == hi) == (Fraction(lo) == exact)
    if lo != hi:
        assert math.nextafter(lo, math.inf) == hi


@given(anyfloat, anyfloat)
def test_div_bounds_are_the_tightest_floats_around_the_exact_quotient(a, b):
    assume(b != 0.0)
    lo, hi = div_bounds(a, b)
    exact = Fraction(a) / Fraction(b)
    if math.isinf(hi) or math.isinf(lo):
        assert abs(exact) > Fraction(1.7976931348623157e308)
        return
    assert Fraction(lo) <= exact <= Fraction(hi)
    assert (lo == hi) == (Fraction(lo) == exact)


@given(st.one_of(st.floats(min_value=0.0, max_value=1e300), st.floats(min_value=0.0, max_value=1e-300)))
def test_sqrt_bounds_enclose_the_exact_root(x):
    lo, hi = sqrt_bounds(x)
    assert Fraction(lo) ** 2 <= Fraction(x) <= Fraction(hi) ** 2
    assert hi == lo or math.nextafter(lo, math.inf) == hi


def test_kernels_known_values():
    assert add_bounds(1.0, 2.0) == (3.0, 3.0)
    assert add_bounds(1e308, 1e308) == (1.7976931348623157e308, math.inf)
    assert mul_bounds(0.0, math.inf) == (0.0, 0.0)
    assert mul_bounds(-0.0, 5.0) == (0.0, 0.0)
    assert div_bounds(1.0, 4.0) == (0.25, 0.25)
    assert sqrt_bounds(2.25) == (1.5, 1.5)
    lo, hi = sqrt_bounds(2.0)
    assert lo < hi and lo * lo < 2.0 < hi * hi or Fraction(lo) ** 2 < 2 < Fraction(hi) ** 2


# --------------------------------------------------------------------------- enclosure property


@given(interval_and_point(), interval_and_point())
def test_arithmetic_encloses_exact_results(xp, yp):
    (x, px), (y, py) = xp, yp
    fx, fy = Fraction(px), Fraction(py)
    assert contains_exact(x + y, fx + fy)
    assert contains_exact(x - y, fx - fy)
    assert contains_exact(-x, -fx)
    product = x * y
    if not (math.isinf(product.lo) or math.isinf(product.hi)):
        assert contains_exact(product, fx * fy)
    if not y.lo <= 0.0 <= y.hi:
        quotient = x / y
        if not (math.isinf(quotient.lo) or math.isinf(quotient.hi)):
            assert contains_exact(quotient, fx / fy)


@given(interval_and_point(moderate), st.integers(min_value=0, max_value=7))
def test_integer_powers_enclose_exact_results(xp, n):
    x, px = xp
    result = x**n
    assume(not math.isinf(result.hi) and not math.isinf(result.lo))
    assert contains_exact(result, Fraction(px) ** n)
    if n % 2 == 0:
        assert result.lo >= 0.0


@given(interval_and_point(st.floats(min_value=-60.0, max_value=60.0)))
def test_sin_cos_enclose_high_precision_values(xp):
    x, px = xp
    s, c = reference_sin_cos(px)
    assert contains_exact(x.sin(), s)
    assert contains_exact(x.cos(), c)
    assert -1.0 <= x.sin().lo <= x.sin().hi <= 1.0


@given(st.floats(min_value=-60.0, max_value=60.0), st.floats(min_value=0.0, max_value=7.0))
def test_sin_cos_enclose_interior_samples(lo, width):
    x = Interval(lo, lo + width)
    for t in (0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0):
        p = min(x.lo + t * (x.hi - x.lo), x.hi)
        s, c = reference_sin_cos(p)
        assert contains_exact(x.sin(), s), p
        assert contains_exact(x.cos(), c), p


@pytest.mark.parametrize("m", range(-6, 7))
def test_intervals_around_critical_points_reach_plus_minus_one(m):
    c = (m + 0.5) * math.pi  # sine extremum (up to rounding of c)
    iv = Interval(c - 1e-9, c + 1e-9)
    assert (iv.sin().hi if m % 2 == 0 else -iv.sin().lo) == 1.0
    c = m * math.pi  # cosine extremum
    iv = Interval(c - 1e-9, c + 1e-9)
    assert (iv.cos().hi if m % 2 == 0 else -iv.cos().lo) == 1.0


def test_wide_intervals_give_minus_one_one():
    assert Interval(-10.0, 10.0).sin() == Interval(-1.0, 1.0)
    assert Interval(0.0, 1e50).cos() == Interval(-1.0, 1.0)
    assert Interval(-math.inf, 0.0).sin() == Interval(-1.0, 1.0)


# --------------------------------------------------------------------------- exactness


def test_exact_zero_results_stay_exact():
    assert Interval(0.0, 0.0).sin() == Interval(0.0, 0.0)
    assert Interval(0.0, 0.0).cos() == Interval(1.0, 1.0)
    assert Interval(0.0, 0.5).sin().lo == 0.0
    assert Interval(0.0, math.pi).sin().lo == 0.0
    assert Interval(1e-300, 3.0).sin().lo >= 0.0
    assert Interval(-0.5, 0.0).sin().hi == 0.0
    assert Interval(-math.pi, 0.0).sin().hi == 0.0
    assert 0.0 < Interval(-math.pi / 2, math.pi / 2).cos().lo < 1e-16  # math.pi / 2 < pi / 2
    assert Interval(-0.5, 0.5).cos().hi == 1.0
    assert Interval(0.0, 2.0) * Interval(-3.0, -1.0) == Interval(-6.0, 0.0)
    assert (Interval(0.0, 0.3) * Interval(0.0, 0.7)).lo == 0.0
    assert Interval(0.0, 0.0) * Interval(-math.inf, math.inf) == Interval(0.0, 0.0)
    assert (Interval(0.0, 0.1) + Interval(0.0, 0.0)) == Interval(0.0, 0.1)
    assert (-0.1 * Interval(0.0, 0.3) + -0.8 * Interval(0.0, 0.2) ** 2).hi == 0.0
    assert Interval(-2.0, 3.0) ** 2 == Interval(0.0, 9.0)
    assert Interval(-2.0, 1.0) ** 3 == Interval(-8.0, 1.0)


def test_exact_results_are_not_widened():
    assert Interval(1.0, 2.0) + Interval(3.0, 4.0) == Interval(4.0, 6.0)
    assert Interval(0.5, 1.5) * Interval(2.0, 4.0) == Interval(1.0, 6.0)
    assert Interval(1.0, 2.0) / Interval(4.0, 8.0) == Interval(0.125, 0.5)
    assert Interval(4.0, 9.0).sqrt() == Interval(2.0, 3.0)
    assert Interval.enclosing(Fraction(3, 4)) == Interval(0.75, 0.75)
    assert 3 * Interval(1.0, 2.0) == Interval(3.0, 6.0)


def test_inexact_results_are_widened_by_one_ulp():
    s = Interval.point(0.1) + Interval.point(0.2)
    assert math.nextafter(s.lo, 1.0) == s.hi
    assert contains_exact(s, Fraction(0.1) + Fraction(0.2))
    third = Interval.enclosing(Fraction(1, 3))
    assert third.lo < Fraction(1, 3) < third.hi and math.nextafter(third.lo, 1.0) == third.hi
    assert Fraction(1, 3) in third


def test_known_values():
    assert Interval(1.0, 2.0).sin().hi == 1.0  # pi/2 inside
    assert Interval(3.0, 3.5).cos().lo == -1.0  # pi inside
    s = Interval(0.5, 1.0).sin()
    assert s.lo <= math.sin(0.5) <= s.lo + 1e-15 and s.hi - 1e-15 <= math.sin(1.0) <= s.hi
    assert Interval(2.0, 5.0).width == 3.0
    assert Interval(2.0, 4.0).mid == 3.0
    assert 2.5 in Interval(2.0, 4.0) and Interval(2.5, 3.0) in Interval(2.0, 4.0)
    assert str(Interval(1.0, 2.0)) == "[1.0, 2.0]"
    assert Interval(-0.0, 0.0).lo.hex() == "0x0.0p+0"


# --------------------------------------------------------------------------- errors


def test_invalid_intervals_raise():
    with pytest.raises(InvalidInterval, match=r"expected lo <= hi; swap the bounds"):
        Interval(2.0, 1.0)
    with pytest.raises(InvalidInterval, match=r"NaN bound"):
        Interval(math.nan, 1.0)
    with pytest.raises(InvalidInterval, match=r"bounds must be real numbers"):
        Interval("a", 1.0)
    with pytest.raises(InvalidInterval, match=r"cannot lie entirely at infinity"):
        Interval(math.inf, math.inf)


def test_domain_errors_raise():
    with pytest.raises(IntervalDomainError, match=r"divisor interval contains 0; split it"):
        Interval(1.0, 2.0) / Interval(-1.0, 1.0)
    with pytest.raises(IntervalDomainError, match=r"contains negative numbers; clip it"):
        Interval(-1.0, 1.0).sqrt()
    with pytest.raises(TypeError, match=r"expected an integer >= 0"):
        Interval(1.0, 2.0) ** -1
    with pytest.raises(TypeError, match=r"expected an integer >= 0"):
        Interval(1.0, 2.0) ** 0.5
    with pytest.raises(TypeError, match=r"expected a float, int or Fraction"):
        Interval.enclosing("1")
    with pytest.raises(TypeError, match=r"cannot use a bool"):
        Interval(1.0, 2.0) + True
