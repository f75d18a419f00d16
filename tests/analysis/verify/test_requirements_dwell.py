"""The built-in no-chatter requirement (analysis.verify.requirements.min_dwell) against hand-made mode sequences."""

from __future__ import annotations

import pytest

from analysis.verify.requirements import RequirementError, min_dwell, parse_requirements
from analysis.stl import SignalTrace


def _trace(switches):
    """Mode 'off' then the given (time, mode) switches, sampled every 0.05 s over 4 s, both sides of each jump."""
    times, modes = [], []
    mode, t, k = "off", 0.0, 0
    pending = list(switches)
    while t <= 4.0 + 1e-12:
        if pending and abs(pending[0][0] - t) < 1e-9:
            times.append(t)
            modes.append(mode)
            mode = pending.pop(0)[1]
        times.append(t)
        modes.append(mode)
        k += 1
        t = round(k * 0.05, 10)
    return SignalTrace(times=times, labels={"mode": tuple(modes)})


@pytest.mark.parametrize("switches, holds", [
    ([(1.0, "on"), (1.5, "off")], True),    # 0.5 s in 'on' >= 0.25 s
    ([(1.0, "on"), (1.2, "off")], False),   # 0.2 s in 'on'
    ([(1.0, "on"), (2.0, "off"), (2.1, "on")], False),  # 0.1 s back in 'off'
    ([], True),
])
def test_min_dwell_against_the_switch_times(switches, holds):
    requirement = min_dwell("dwell", 0.25, ("off", "on"), 4.0)
    parsed = parse_requirements((requirement,), signals=(), labels={"mode": ("off", "on")}, horizon=4.0)
    assert parsed[0].formula.satisfied(_trace(switches)) is holds


@pytest.mark.parametrize("seconds, modes", [(0.0, ("a",)), (5.0, ("a",)), (float("nan"), ("a",)), (True, ("a",)),
                                            (0.1, ()), (0.1, ('a"b',))])
def test_min_dwell_refuses_bad_arguments(seconds, modes):
    with pytest.raises(RequirementError):
        min_dwell("dwell", seconds, modes, 4.0)
