"""The independent re-check (``analysis.reach.recheck``) on flowpipes with adaptive steps (a non-uniform grid).

The re-check reads each segment's saved step, runs its own sets over exactly those steps and never passes a saved
flowpipe it did not check: a segment shrunk inside the true reach, a step changed or removed, a step that is not a
positive number, and a saved horizon the steps do not reach all fail it, with the place.
"""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from analysis.reach import reach, recheck_flowpipe, safety_fragment
from analysis.stl.syntax import parse_tree
from hybrid import HybridAutomaton, Mode
from hybrid.symbolic import coordinates, flow_map
from hybrid.system import HybridSystem

NAMES = ("x", "y")
X = coordinates(*NAMES)
BOX = {"x": (1.25, 1.3), "y": (2.35, 2.4)}
HORIZON = 1.0


def _vdp() -> HybridSystem:
    automaton = HybridAutomaton(name="vdp", modes=(Mode(name="m"),), transitions=(), variables=NAMES)
    return HybridSystem(automaton=automaton, state_names=NAMES, flows={"m": flow_map(X.y, (1.0 - X.x ** 2) * X.y - X.x)})


@pytest.fixture(scope="module")
def saved() -> dict:
    result = reach(_vdp(), BOX, horizon=HORIZON, time_step=0.01, adaptive_step=2.0, order=160)
    assert result.status == "complete", result.terminations
    data = json.loads(result.to_json())
    steps = [seg["step"] for seg in data["segments"][1:]]
    assert len(set(steps)) >= 2, steps  # a non-uniform grid
    return data


FRAGMENT = safety_fragment(parse_tree(f"always[0, {HORIZON}] (y < 3)"), NAMES)


def _check(data):
    return recheck_flowpipe(data, _vdp(), BOX, FRAGMENT)


def test_the_untouched_adaptive_flowpipe_is_rechecked(saved):
    good = _check(saved)
    assert good.passed, good.failure
    assert good.segments == len(saved["segments"])


def _true_state(t: float) -> np.ndarray:
    """The state at ``t`` from the box's corner (1.3, 2.4) by a fine DOP853 run: a point of the true reach."""
    sol = solve_ivp(lambda _, z: [z[1], (1.0 - z[0] ** 2) * z[1] - z[0]], (0.0, t), [1.3, 2.4], method="DOP853",
                    rtol=1e-11, atol=1e-13)
    return sol.y[:, -1]


@pytest.mark.parametrize("index", [5, 20, 41])
def test_a_segment_shrunk_inside_the_true_reach_fails(saved, index):
    """One flowed segment's box moved so that the true state at its start time (a corner's run, 1e-3 beyond it in
    ``x``: far above the run's error) lies outside: the re-check's own sets must leave it."""
    data = copy.deepcopy(saved)
    seg = data["segments"][index]
    state = _true_state(max(seg["t"][0], 0.0))
    lo, hi = seg["box"]
    if state[0] - lo[0] < hi[0] - state[0]:
        lo[0] = float(state[0] + 1e-3)  # the state is 1e-3 below the new lower bound
    else:
        hi[0] = float(state[0] - 1e-3)
    assert lo[0] < hi[0]
    bad = _check(data)
    assert not bad.passed
    assert f"segment {index - 1}:" in bad.failure, bad.failure


def test_a_changed_or_removed_step_fails(saved):
    data = copy.deepcopy(saved)
    k = next(i for i, seg in enumerate(data["segments"]) if not seg["entry"] and seg["step"] > 0.01)
    data["segments"][k]["step"] = 2 * data["segments"][k]["step"]  # the saved times no longer cover it
    assert not _check(data).passed
    data = copy.deepcopy(saved)
    del data["segments"][k]["step"]  # read as time_step: the later segments' times no longer chain
    assert not _check(data).passed


@pytest.mark.parametrize("value", [0.0, -0.01, float("nan"), float("inf"), 10 ** 400, "0.01", True, None])
def test_a_step_that_is_not_a_positive_number_fails(saved, value):
    data = copy.deepcopy(saved)
    data["segments"][3]["step"] = value
    bad = _check(data)
    assert not bad.passed
    assert "segment 2:" in bad.failure, bad.failure


def test_steps_that_stop_short_of_the_horizon_fail(saved):
    """The last segments dropped (the termination still claims the horizon): the steps end before it."""
    data = copy.deepcopy(saved)
    data["segments"] = data["segments"][:-3]
    bad = _check(data)
    assert not bad.passed and "claims the horizon" in bad.failure, bad.failure
