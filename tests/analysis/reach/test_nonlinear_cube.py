"""``x' = -x³`` from a box around 0: a wide set at a degenerate equilibrium (issue 27's defect).

The Jacobian ``-3x²`` vanishes at 0, so the linearisation at the set's centre saw almost no contraction while the
Lagrange remainder of the set's edges (an input to the affine step) kept growing: the flowpipe blew up within
0.1 s ("the Lagrange remainder is not finite").  Yardstick, independent of the reachability code: the closed form
``x(t) = x0 / sqrt(1 + 2 x0² t)`` (evaluated in floats: relative error ~1e-16, so points are accepted within
``TOL = 1e-12``).  It is monotone in ``x0``, so the true reach set at time ``t`` is ``[x(t; lo), x(t; hi)]`` and over
``[0, T]`` it is the initial box: a planted set 0.01 inside it is reachable (never proven), one 0.05 outside is
not (proven, a precision check).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.reach import reach, unsafe_set
from hybrid import HybridAutomaton, Mode
from hybrid.symbolic import coordinates, flow_map
from hybrid.system import HybridSystem

TOL = 1e-12
X = coordinates("x")


def _cube() -> HybridSystem:
    automaton = HybridAutomaton(name="cube", modes=(Mode(name="m"),), transitions=(), variables=("x",))
    return HybridSystem(automaton=automaton, state_names=("x",), flows={"m": flow_map(-X.x ** 3)})


def _closed(x0: float, t: float) -> float:
    return x0 / math.sqrt(1.0 + 2.0 * x0 * x0 * t)


@pytest.mark.parametrize("box", [(-0.5, 1.0), (-1.0, 1.0), (0.0, 1.0)])
def test_cube_flowpipe_is_complete_and_holds_the_closed_form(box):
    lo, hi = box
    horizon = 2.0
    planted = [unsafe_set("inside hi", X.x >= hi - 0.01, ("x",)), unsafe_set("inside lo", X.x <= lo + 0.01, ("x",)),
               unsafe_set("outside hi", X.x >= hi + 0.05, ("x",)), unsafe_set("outside lo", X.x <= lo - 0.05, ("x",))]
    result = reach(_cube(), {"x": box}, horizon=horizon, time_step=0.01, unsafe=planted)
    assert result.status == "complete", [t.detail for t in result.terminations]
    for x0 in np.linspace(lo, hi, 41):
        for t in np.linspace(0.0, horizon, 201):
            assert result.contains("m", float(t), [_closed(float(x0), float(t))], tol=TOL), (x0, t)
    distances = dict(result.distances)
    # reachable (the box's own edges at t = 0): never proven
    assert distances["inside hi"] <= 0.0 and distances["inside lo"] <= 0.0
    # unreachable by 0.05: proven (the flowpipe's first segment overshoots the box by ~0.015)
    assert distances["outside hi"] > 0.0 and distances["outside lo"] > 0.0
    # the set contracts as the closed form does: at the horizon the box is within 0.1 of the true extent
    last = [s for s in result.segments if s.t_hi >= horizon]
    top, bottom = max(s.hi[0] for s in last), min(s.lo[0] for s in last)
    assert top >= _closed(hi, horizon) - TOL and bottom <= _closed(lo, horizon) + TOL
    assert top - _closed(hi, horizon) < 0.1 and _closed(lo, horizon) - bottom < 0.1
