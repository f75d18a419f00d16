"""hybrid.interval_kernels: each kernel's bounds hold the exact result (products and powers in rationals, sin/cos
at many points of the interval and at its interior extremes, whose values are exactly ±1)."""

from __future__ import annotations

import math
import random
from fractions import Fraction

import pytest

from hybrid.interval_kernels import mul_bounds, pow_bounds, round_down, round_up, trig_bounds


def _point(rng: random.Random, lo: float, hi: float) -> float:
    return rng.choice((lo, hi, rng.uniform(lo, hi)))


def test_rounding_moves_one_ulp_outward_and_keeps_infinities():
    assert round_down(1.0) < 1.0 < round_up(1.0)
    assert round_up(1.0) - 1.0 == math.ulp(1.0)
    assert round_down(-math.inf) == -math.inf and round_up(math.inf) == math.inf


@pytest.mark.parametrize("seed", range(5))
def test_a_product_of_points_lies_in_the_product_bounds_exactly(seed):
    rng = random.Random(seed)
    for _ in range(400):
        al, ah = sorted(rng.uniform(-1e3, 1e3) for _ in range(2))
        bl, bh = sorted(rng.uniform(-1e-3, 1e3) for _ in range(2))
        lo, hi = mul_bounds(al, ah, bl, bh)
        x, y = _point(rng, al, ah), _point(rng, bl, bh)
        assert Fraction(lo) <= Fraction(x) * Fraction(y) <= Fraction(hi)


def test_zero_times_infinity_is_taken_as_its_limit():
    assert mul_bounds(0.0, 0.0, -math.inf, math.inf) == (round_down(0.0), round_up(0.0))


@pytest.mark.parametrize("k", [0, 1, 2, 3, 4, 7])
def test_a_power_of_points_lies_in_the_power_bounds_exactly(k):
    rng = random.Random(k)
    for _ in range(400):
        lo, hi = sorted(rng.uniform(-20.0, 20.0) for _ in range(2))
        low, high = pow_bounds(lo, hi, k)
        x = _point(rng, lo, hi)
        assert Fraction(low) <= Fraction(x) ** k <= Fraction(high)
    assert pow_bounds(-1.0, 2.0, 2)[0] <= 0.0  # an even power of an interval holding 0 reaches 0


@pytest.mark.parametrize("op", ["sin", "cos"])
def test_sine_and_cosine_bounds_hold_every_sampled_value_and_reach_the_extremes(op):
    f = getattr(math, op)
    rng = random.Random(11)
    for _ in range(300):
        lo = rng.uniform(-10.0, 10.0)
        hi = lo + rng.choice((1e-9, 0.1, 1.0, 3.0, 6.0))
        low, high = trig_bounds(op, lo, hi)
        values = [f(lo + (hi - lo) * i / 64) for i in range(65)]
        assert low <= min(values) and max(values) <= high
        assert -1.0 <= low <= high <= 1.0
    assert trig_bounds("sin", 1.0, 2.0)[1] == 1.0  # pi/2 inside: the maximum is reached exactly
    assert trig_bounds("cos", 3.0, 3.5)[0] == -1.0  # pi inside
    assert trig_bounds("sin", 0.0, 7.0) == (-1.0, 1.0)
