"""The eigenbasis bound of accumulated rounding errors (``analysis.reach.errorbound``) against exact arithmetic.

Yardstick: ``E_k = Σ_{j<k} Φ^{k−j} e_j`` computed in exact rationals (``Fraction``) for an exact rational ``Φ``
(a rotation by the Pythagorean angle (3/5, 4/5) — whose float entries are *not* exact — and a clock driven by a
constant), with seeded error vectors at the corners of their boxes (the worst case for boxes), and the tracker's
box must contain every ``|E_k|``.  The error zonotope of the flowpipe wraps on the same rotation (its box grows
like ``(cos + sin)^k = 1.4^k``); the tracker's bound stays within a small factor of the errors' sum.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from analysis.reach.errorbound import error_tracker
from analysis.reach.flowpipe import mode_dynamics

PHI = [[Fraction(3, 5), Fraction(-4, 5), Fraction(0), Fraction(0)],
       [Fraction(4, 5), Fraction(3, 5), Fraction(0), Fraction(0)],
       [Fraction(0), Fraction(0), Fraction(1), Fraction(1, 8)],
       [Fraction(0), Fraction(0), Fraction(0), Fraction(1)]]
A_PATTERN = np.array([[0.0, -1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0]])


def _enclosure():
    c = np.array([[float(q) for q in row] for row in PHI])
    r = np.array([[abs(float(q - Fraction(float(q)))) * 2 + 1e-300 for q in row] for row in PHI])
    return c, r


def test_tracker_contains_the_exact_accumulated_errors():
    c, r = _enclosure()
    tracker = error_tracker(A_PATTERN, c, r)
    assert tracker is not None and list(tracker.free) == [2, 3] and list(tracker.rest) == [0, 1]
    rng = np.random.default_rng(7)
    bound = tracker.start()
    exact = [Fraction(0)] * 4
    for k in range(120):
        eps = rng.uniform(0.5, 1.5, size=4) * 2.0 ** -40
        signs = rng.choice([-1.0, 1.0], size=4)
        e = [Fraction(float(s * v)) for s, v in zip(signs, eps)]
        exact = [sum((PHI[i][j] * exact[j] for j in range(4)), Fraction(0)) + e[i] for i in range(4)]
        bound = tracker.step(bound, eps)
        box = tracker.box(bound)
        assert all(abs(exact[i]) <= Fraction(float(box[i])) for i in range(4)), (k, exact, box)
    # no wrapping: after 120 steps the rotation's errors are at most ~ the sum of the new ones (120 * 1.5 * 2^-40)
    assert float(np.max(tracker.box(bound)[:2])) < 120 * 1.5 * 2.0 ** -40 * 1.5


def test_tracker_used_where_the_error_zonotope_wraps():
    """A rotation ``ẋ = −y, ẏ = x`` gets the tracker (``ρ(|Φ|) > 1``); a decoupled decay does not need it."""
    rot = [[Fraction(0), Fraction(-1)], [Fraction(1), Fraction(0)]]
    dyn = mode_dynamics("rot", rot, [Fraction(0), Fraction(0)], 0.01)
    assert dyn.tracker is not None
    decay = [[Fraction(-1), Fraction(0)], [Fraction(0), Fraction(-2)]]
    assert mode_dynamics("decay", decay, [Fraction(0), Fraction(0)], 0.01).tracker is None


def test_defective_matrix_is_refused_or_bounded():
    """A Jordan block in ``R`` is not diagonalisable: no tracker (the flowpipe keeps its error zonotope)."""
    jordan = np.array([[1.0, 1e-3, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    pattern = np.array([[0.0, 1.0, 0.0], [-1e-9, 0.0, 0.0], [0.0, 0.0, 0.0]])
    tracker = error_tracker(pattern, jordan, np.full((3, 3), 1e-20))
    if tracker is not None:  # if a basis was accepted, its bound must still hold for a long run of errors
        bound = tracker.start()
        exact = np.zeros(3)
        for _ in range(50):
            exact = jordan @ exact + 1e-12
            bound = tracker.step(bound, np.full(3, 1e-12))
        assert np.all(np.abs(exact) <= tracker.box(bound) * (1 + 1e-9))
