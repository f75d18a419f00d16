"""visnav.fuzzing.space: the measurement space, the hypothesis projection and the signal-run strategies."""

from __future__ import annotations

import dataclasses
import os

from hypothesis import HealthCheck, given, settings

from analysis.fuzzing import max_rate_ratio
from visnav.fuzzing.space import MeasurementSpace, bypass_runs, respect_hypotheses, signal_runs

PROFILE = "ci" if os.environ.get("CI") else "dev"
SPACE = MeasurementSpace()
ENV, SETTINGS = SPACE.envelopes, SPACE.settings
EXPLICIT = settings(max_examples=40 if PROFILE == "dev" else 150, derandomize=True, database=None, deadline=None,
                    suppress_health_check=list(HealthCheck))


def row(d0, d1=1.6, side=1.0, d_occ=160.0, d_bord=320.0, pan=0.0, alpha=0.0, visible=1.0):
    return (d0, d1, side, d_occ, d_bord, pan, alpha, visible)


@given(signal_runs(SPACE, bounded=True, respect=True))
@EXPLICIT
def test_bounded_runs_are_plausible_and_keep_obstacles_apart(rows):
    assert max_rate_ratio(rows, SPACE.channels()) <= 1.0 + 1e-9
    assert all(r[0] + r[1] >= 2 * ENV.d_plus_m - 1e-12 for r in rows)


@given(bypass_runs(SPACE))
@EXPLICIT
def test_bypass_runs_enter_xi_minus_and_swing_the_pan(rows):
    assert max_rate_ratio(rows, SPACE.channels()) <= 1.0 + 1e-9
    assert min(min(r[0], r[1]) for r in rows) <= ENV.d_minus_m
    offset = rows[0][5]
    assert max(abs(r[5] - offset) for r in rows) >= SETTINGS.arm_angle_rad - 0.05 - 1e-9


def test_respect_hypotheses_projects_the_second_obstacle_only_as_needed():
    rows = respect_hypotheses([row(0.3, 0.2), row(0.9, 0.2), row(1.5, 1.5)], SPACE)
    assert [r[:2] for r in rows] == [(0.3, 0.8999999999999999), (0.9, 0.29999999999999993), (1.5, 1.5)]


def test_dataclass_space_is_replaceable():
    space = dataclasses.replace(SPACE, max_step_d_m=0.005, max_step_d_occ_px=2.0)
    assert space.min_reversal_gap() == 4 and SPACE.min_reversal_gap() == 2
