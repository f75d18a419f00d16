"""The re-check's vectorised evaluation against :class:`analysis.interval.Interval` node by node.

Yardstick: the scalar evaluation of the same roots with ``Interval`` (error-free transformations in Python
scalars, ``Fraction`` where Dekker's product is not exact): the tape must give the same bounds bit for bit,
and fall back (``TapeFallback``) wherever its kernels could differ.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.interval import Interval
from analysis.reach.interval_tape import TapeFallback, compile_tape
from analysis.reach.model import affine_model
from analysis.reach.recheck_smooth import SmoothStepper
from hybrid.symbolic import Apply, Const, Coordinate, coordinates, cos, sin


def _scalar(roots, lo, hi):
    memo = {}

    def ev(node):
        if id(node) in memo:
            return memo[id(node)]
        if isinstance(node, Const):
            out = Interval.point(float(node.value))
        elif isinstance(node, Coordinate):
            out = Interval(float(lo[node.index]), float(hi[node.index]))
        else:
            a = [ev(x) for x in node.args]
            op = node.op
            out = {"add": lambda: a[0] + a[1], "sub": lambda: a[0] - a[1], "mul": lambda: a[0] * a[1],
                   "neg": lambda: -a[0], "div": lambda: a[0] / a[1],
                   "pow": lambda: a[0] ** int(node.args[1].value), "sin": lambda: a[0].sin(),
                   "cos": lambda: a[0].cos()}[op]()
        memo[id(node)] = out
        return out

    values = [ev(r) for r in roots]
    return np.array([v.lo for v in values]), np.array([v.hi for v in values])


def _bypass_stepper():
    from visnav.studies.path_following_reach import modal_basis, sampled_bypass_system

    system = sampled_bypass_system(k=4.0, v=0.2, period=0.05, basis=modal_basis(k=4.0, v=0.2))
    return SmoothStepper(affine_model(system, nonlinear=True).modes["follow"].smooth)


def test_the_tape_gives_interval_s_bounds_bit_for_bit():
    stepper = _bypass_stepper()
    rng = np.random.default_rng(11)
    lists = (stepper.f, stepper.at_point, stepper.over_hull, stepper.over_w)
    checked = 0
    for _ in range(40):
        centre = rng.uniform([-0.3, -0.3, 0.4, -0.3, -0.3, 0.4, 0.0], [0.3, 0.3, 0.6, 0.3, 0.3, 0.6, 0.05])
        width = rng.choice([0.0, 1e-9, 1e-3, 0.2]) * rng.uniform(0, 1, 7)
        lo, hi = centre - width, centre + width
        for roots in lists:
            tape = compile_tape(roots)
            got = tape.evaluate(lo, hi)
            want = _scalar(roots, lo, hi)
            assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
            assert np.all(got[0] <= got[1])
            checked += len(roots)
    assert checked == 40 * sum(len(r) for r in lists)


def test_merged_nodes_and_a_polynomial_with_rounding_in_every_operation():
    x = coordinates("x", "y")
    roots = [(x.x * 0.1 + x.y / 3.0) ** 3 - sin(x.x) * cos(x.y), -(x.x - 0.7) * (x.y + 1e-17),
             sin(x.x) * cos(x.y)]  # sin(x) written twice: one node of the tape
    tape = compile_tape(roots)
    rng = np.random.default_rng(3)
    for _ in range(200):
        a, b = np.sort(rng.uniform(-5, 5, (2, 2)), axis=0)
        got, want = tape.evaluate(a, b), _scalar(roots, a, b)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


@pytest.mark.parametrize("lo, hi", [((-np.inf, 0.0), (1.0, 1.0)), ((1e-300, 0.0), (2e-300, 1.0)),
                                    ((0.0, -1.0), (1.0, 1.0)), ((1.0, 0.0), (0.5, 1.0))])
def test_outside_its_exact_range_the_tape_falls_back(lo, hi):
    x = coordinates("x", "y")
    tape = compile_tape([x.x * x.x + x.x / 3.0, Apply("div", (x.x, x.y))])
    with pytest.raises(TapeFallback):
        tape.evaluate(np.array(lo), np.array(hi))


def test_a_node_it_does_not_evaluate_gives_no_tape():
    x = coordinates("x")
    assert compile_tape([Apply("sqrt", (x.x,))]) is None
    assert compile_tape([x.x + 1.0]) is not None
