"""Window bounds compared with a slack relative to the window and the sample period, not to the time stamps.

The expected windows are computed from sample *indices* (a uniform grid of
period ``h`` has sample ``k`` at offset ``k * h``, so the window ``[a, b]`` of
sample ``i`` is ``i + ceil(a / h) .. i + floor(b / h)`` in integers), an
independent route from the float comparisons of ``window_bounds``.  The
traces are stamped around 1.7e9 s (Unix time), where the old slack
``1e-9 * |t|`` was 1.7 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.stl import SignalTrace, parse_formula
from analysis.stl.semantics import STAMP_ULPS, TIME_RESOLUTION, time_slack, window_bounds

EPOCH = 1.7e9


def _grid(start: float, period: float, n: int) -> np.ndarray:
    return start + period * np.arange(n)  # each time rounded once (ulp(1.7e9) = 2.4e-7 s)


def _expected_always(x: np.ndarray, samples_ahead: int) -> np.ndarray:
    return np.array([x[i:min(i + samples_ahead, x.size - 1) + 1].min() for i in range(x.size)])


@pytest.mark.parametrize("start", [0.0, 1000.0, EPOCH])
def test_always_sees_a_violation_at_the_right_sample_whatever_the_epoch(start):
    x = np.ones(40)
    x[25] = -2.0  # one violation, at offset 2.5 s
    trace = SignalTrace(times=_grid(start, 0.1, 40), signals={"x": x})
    rho = parse_formula("always[0, 1] x > 0").robustness_signal(trace)
    np.testing.assert_array_equal(rho, _expected_always(x, 10))  # [0, 1] at 0.1 s: this sample and the 10 next
    # the first sample whose window holds the violation is 15 (offset 1.5 s): not 10 (1.7 s of slack), not 16
    assert int(np.flatnonzero(rho < 0)[0]) == 15


@pytest.mark.parametrize("start", [0.0, EPOCH])
def test_eventually_on_a_window_between_two_samples_is_empty(start):
    # samples every 0.5 s; [0.1, 0.4] after each sample holds none: -inf, false (docs/stl.md: empty window)
    trace = SignalTrace(times=_grid(start, 0.5, 6), signals={"x": np.ones(6)})
    f = parse_formula("eventually[0.1, 0.4] x > 0")
    assert f.robustness_signal(trace).tolist() == [-math.inf] * 6
    assert f.satisfied_signal(trace).tolist() == [False] * 6
    lo, hi = window_bounds(trace.times, (0.1, 0.4), past=False)
    assert np.all(lo > hi)


def test_past_windows_are_translation_invariant():
    rng = np.random.default_rng(7)
    x = rng.normal(size=200)
    formulas = ["historically[0.3, 1.2] x > -1", "once[0, 0.5] x > 1", "x > 0 since[0.2, 0.9] x > 1.5",
                "always[0.2, 0.6] (x > 0 -> eventually[0, 0.3] x < 0)"]
    near = SignalTrace(times=_grid(0.0, 0.05, 200), signals={"x": x})
    far = SignalTrace(times=_grid(EPOCH, 0.05, 200), signals={"x": x})
    for text in formulas:
        f = parse_formula(text)
        np.testing.assert_array_equal(f.robustness_signal(near), f.robustness_signal(far), err_msg=text)
        np.testing.assert_array_equal(f.satisfied_signal(near), f.satisfied_signal(far), err_msg=text)


def test_accumulated_drift_still_lands_in_the_window():
    # times summed step by step drift by a few ulps; 2.6 - 1.1 = 1.5000000000000002 is in [0, 1.5]
    times = np.cumsum(np.full(40, 0.05)) - 0.05
    x = np.arange(40.0)
    trace = SignalTrace(times=times, signals={"x": x})
    rho = parse_formula("eventually[0, 1.5] x > 0").robustness_signal(trace)
    np.testing.assert_array_equal(rho, [x[min(i + 30, 39)] for i in range(40)])  # 1.5 s = 30 steps
    at_epoch = SignalTrace(times=EPOCH + times, signals={"x": x})
    np.testing.assert_array_equal(parse_formula("eventually[0, 1.5] x > 0").robustness_signal(at_epoch), rho)


def test_the_slack_is_bounded_by_a_quarter_period_and_does_not_grow_with_the_epoch():
    near, far = _grid(0.0, 0.1, 50), _grid(EPOCH, 0.1, 50)
    assert time_slack(near, (0.0, 1.0)) == pytest.approx(TIME_RESOLUTION, rel=1e-3)
    # at 1.7e9 s only the stamps' own rounding is added: 4 ulps per step spanned, far below the period
    stamp = STAMP_ULPS * math.ulp(far[-1]) * 11
    # (the steps between stamps differ from 0.1 s by up to ulp(1.7e9) = 2.4e-7 s: 2.4e-6 relative)
    assert time_slack(far, (0.0, 1.0)) == pytest.approx(TIME_RESOLUTION + stamp, rel=1e-5)
    assert time_slack(far, (0.0, 1.0)) < 1e-4
    fine = _grid(EPOCH, 1e-3, 5000)  # 1 ms steps: the stamp term would pass h / 4; it is capped there
    assert time_slack(fine, (0.0, 5.0)) == pytest.approx(np.diff(fine)[np.diff(fine) > 0].min() / 4)
    assert time_slack(np.array([3.0, 3.0]), (0.0, 1.0)) == pytest.approx(TIME_RESOLUTION)  # no positive step
