"""The producer's compiled interval enclosures (``analysis.reach.enclose_compiled``) and the vectorised interval form
of the quadratic term (``analysis.reach.nonlinear``).

References by independent routes: the exact value of every expression at random points of the box, in rationals
(``fractions.Fraction``, a tree evaluation written here), must lie inside the compiled enclosure; the enclosure must
equal :func:`hybrid.symbolic.enclose`'s tree walk float for float (the same arithmetic, so the flowpipes do not
change); ``½ dᵀ H d`` at random points, in rationals, must lie inside the quadratic term's enclosure.
"""

from __future__ import annotations

import math
import random
from fractions import Fraction

import numpy as np
import pytest

from analysis.reach.enclose_compiled import compile_enclosure
from analysis.reach.nonlinear import _Evaluator, _quadratic_zonotope  # noqa: PLC2701 - the units under test
from analysis.reach.smooth import smooth_flow
from hybrid.symbolic import Apply, Const, Coordinate, coordinates, cos, enclose, exp, flow_map, sin

NAMES = ("x", "y")


def _flows():
    x = coordinates(*NAMES)
    return {
        "vdp": flow_map(x.y, 1.0 * (1.0 - x.x ** 2) * x.y - x.x),
        "lovo": flow_map(1.5 * x.x - x.x * x.y, x.x * x.y - 3.0 * x.y),
        "cubic": flow_map(-(x.x ** 3) + x.y / 4.0, x.x * x.y ** 2 - 0.3 * x.y),
        "pendulum": flow_map(x.y, -9.81 * sin(x.x) - 0.1 * x.y + 0.5 * cos(x.x) * x.y),
    }


def _roots(flow) -> list:
    """Every component, Jacobian and Hessian entry of the flow (what the producer encloses)."""
    out = list(flow.components)
    out += [e for row in flow.jacobian for e in row]
    out += [e for plane in flow.hessian for row in plane for e in row]
    return out


def _exact(node, point: dict[str, Fraction]) -> Fraction:
    """The exact rational value of a polynomial expression (an independent tree evaluation)."""
    if isinstance(node, Const):
        return Fraction(node.value)
    if isinstance(node, Coordinate):
        return point[node.name]
    a = [_exact(arg, point) for arg in node.args] if node.op != "pow" else [_exact(node.args[0], point)]
    if node.op == "add":
        return a[0] + a[1]
    if node.op == "sub":
        return a[0] - a[1]
    if node.op == "neg":
        return -a[0]
    if node.op == "mul":
        return a[0] * a[1]
    if node.op == "div":
        return a[0] / a[1]
    if node.op == "pow":
        return a[0] ** int(node.args[1].value)
    raise AssertionError(f"not polynomial: {node.op}")


def _polynomial(node) -> bool:
    if isinstance(node, (Const, Coordinate)):
        return True
    return isinstance(node, Apply) and node.op in ("add", "sub", "neg", "mul", "div", "pow") and all(
        _polynomial(a) for a in node.args)


def _boxes(rng: random.Random, count: int):
    for _ in range(count):
        lo = [rng.uniform(-3.0, 3.0) for _ in NAMES]
        width = [rng.choice([0.0, 1e-9, 1e-3, 0.2, 2.5]) for _ in NAMES]
        yield lo, [a + w for a, w in zip(lo, width)]


@pytest.mark.parametrize("name", ["vdp", "lovo", "cubic", "pendulum"])
def test_compiled_enclosure_equals_the_tree_walk_and_holds_the_exact_value(name):
    flow = smooth_flow(_flows()[name], NAMES)
    roots = _roots(flow)
    tape = compile_enclosure(roots, NAMES)
    assert tape is not None and tape.size == len(roots)
    rng = random.Random(27)
    checked = 0
    for lo, hi in _boxes(rng, 150):
        lows, highs = tape(lo, hi)
        bounds = {n: (a, b) for n, a, b in zip(NAMES, lo, hi)}
        for root, low, high in zip(roots, lows, highs):
            assert (low, high) == enclose(root, bounds), root
            assert low <= high
            if _polynomial(root):
                for _ in range(3):
                    point = {n: Fraction(a) + (Fraction(b) - Fraction(a)) * Fraction(rng.randint(0, 1000), 1000)
                             for n, a, b in zip(NAMES, lo, hi)}
                    value = _exact(root, point)
                    assert Fraction(low) <= value <= Fraction(high), (root, point)
                    checked += 1
            else:  # sin/cos: the float value at the box's corners (within 1e-15 of the true one) with room
                for corner in ((lo[0], lo[1]), (hi[0], hi[1])):
                    value = root(list(corner), {})
                    assert low - 1e-12 <= value <= high + 1e-12
    assert checked > 0 or name == "pendulum"


def test_compiled_enclosure_matches_the_tree_walk_on_unbounded_and_degenerate_boxes():
    flow = smooth_flow(_flows()["cubic"], NAMES)
    roots = _roots(flow)
    tape = compile_enclosure(roots, NAMES)
    for lo, hi in [([-math.inf, 0.0], [math.inf, 1.0]), ([1e308, -1e308], [1.7e308, 1e308]), ([0.0, 0.0], [0.0, 0.0]),
                   ([-1e-300, 5e-324], [1e-300, 1e-300])]:
        lows, highs = tape(lo, hi)
        bounds = {n: (a, b) for n, a, b in zip(NAMES, lo, hi)}
        for root, low, high in zip(roots, lows, highs):
            assert (low, high) == enclose(root, bounds)


def test_an_expression_outside_the_smooth_operations_is_not_compiled():
    x = coordinates(*NAMES)
    assert compile_enclosure([x.x * x.y, exp(x.x)], NAMES) is None
    assert compile_enclosure([x.x + x.y], ("x",)) is None  # y is not a coordinate of this list
    assert compile_enclosure([], NAMES)([0.0, 1.0], [0.0, 1.0]) == ([], [])
    x = coordinates(*NAMES)
    infinite = x.x * Const(math.inf) + Const(-math.inf)  # enclose cleans [inf, inf] and [-inf, -inf]
    lows, highs = compile_enclosure([infinite], NAMES)([1.0, 0.0], [2.0, 0.0])
    assert (lows[0], highs[0]) == enclose(infinite, {"x": (1.0, 2.0), "y": (0.0, 0.0)})


@pytest.mark.parametrize("name", ["vdp", "cubic", "pendulum"])
def test_the_quadratic_term_holds_the_exact_form_at_random_points(name):
    flow = smooth_flow(_flows()[name], NAMES)
    ev = _Evaluator(flow)
    rng = np.random.default_rng(5)
    for _ in range(40):
        lo = rng.uniform(-2.0, 2.0, 2)
        hi = lo + rng.choice([1e-6, 0.05, 0.8], 2)
        h_lo, h_hi = ev.hessian(lo, hi)
        d_lo = rng.uniform(-0.3, 0.1, 2)
        d_hi = d_lo + rng.uniform(0.0, 0.3, 2)
        q_lo, q_hi = ev.quadratic(d_lo, d_hi, h_lo, h_hi)
        for _ in range(10):
            d = [Fraction(float(a)) + (Fraction(float(b)) - Fraction(float(a)))
                 * Fraction(int(rng.integers(0, 101)), 100) for a, b in zip(d_lo, d_hi)]
            for i in range(2):
                h = [[Fraction(float(h_lo[i, j, k])) + (Fraction(float(h_hi[i, j, k])) - Fraction(float(h_lo[i, j, k])))
                      * Fraction(int(rng.integers(0, 3)), 2) if math.isfinite(h_hi[i, j, k] - h_lo[i, j, k])
                      else Fraction(0) for k in range(2)] for j in range(2)]
                h[1][0] = h[0][1]  # a Hessian is symmetric
                value = Fraction(1, 2) * sum(d[j] * h[j][k] * d[k] for j in range(2) for k in range(2))
                assert Fraction(float(q_lo[i])) <= value <= Fraction(float(q_hi[i]))


def test_the_quadratic_form_on_a_zonotope_holds_the_exact_form_at_random_points():
    rng = np.random.default_rng(11)
    for n in (1, 2, 3):
        for _ in range(15):
            m = int(rng.integers(1, 12))
            gens = rng.normal(size=(n, m)) * rng.choice([1e-6, 1e-2, 1.0])
            h_mid = rng.normal(size=(n, n, n))
            h_mid = h_mid + np.transpose(h_mid, (0, 2, 1))
            h_rad = np.abs(rng.normal(size=(n, n, n))) * rng.choice([0.0, 1e-3, 0.5])
            h_rad = h_rad + np.transpose(h_rad, (0, 2, 1))
            h_lo, h_hi = h_mid - h_rad, h_mid + h_rad
            z_lo, z_hi = _quadratic_zonotope(gens, h_lo, h_hi)
            for _ in range(8):
                xi = [Fraction(int(v), 64) for v in rng.integers(-64, 65, m)]
                d = [sum(Fraction(float(gens[j, a])) * xi[a] for a in range(m)) for j in range(n)]
                for i in range(n):
                    pick = Fraction(int(rng.integers(0, 3)), 2)
                    h = [[Fraction(float(h_lo[i, j, k])) + (Fraction(float(h_hi[i, j, k]))
                                                             - Fraction(float(h_lo[i, j, k]))) * pick
                          for k in range(n)] for j in range(n)]
                    value = Fraction(1, 2) * sum(d[j] * h[j][k] * d[k] for j in range(n) for k in range(n))
                    assert Fraction(float(z_lo[i])) <= value <= Fraction(float(z_hi[i]))
