"""visnav.fuzzing.layouts: random scenarios that keep or break the paper's hypotheses."""

from __future__ import annotations

import math

from hypothesis import HealthCheck, find, given, settings

from visnav.fuzzing.layouts import scenarios
from visnav.fuzzing.space import MeasurementSpace
from visnav.scenario import scenario_from_toml, scenario_to_toml

SPACE = MeasurementSpace()
ENV, SETTINGS = SPACE.envelopes, SPACE.settings


@given(scenarios(respect=True))
@settings(max_examples=20, derandomize=True, database=None, deadline=None, suppress_health_check=list(HealthCheck))
def test_respecting_scenarios_pass_the_validator_and_keep_obstacles_apart(scenario):
    assert scenario_from_toml(scenario_to_toml(scenario), "fuzz") == scenario
    for i, a in enumerate(scenario.obstacles):
        for b in scenario.obstacles[i + 1:]:
            assert math.dist(a.center_m, b.center_m) - a.radius_m - b.radius_m >= 2 * ENV.d_plus_m


def test_breaking_scenarios_break_a_hypothesis():
    def too_close(scenario):
        obs = scenario.obstacles
        return any(math.dist(a.center_m, b.center_m) - a.radius_m - b.radius_m < 2 * ENV.d_plus_m
                   for i, a in enumerate(obs) for b in obs[i + 1:])

    scenario = find(scenarios(respect=False), too_close, settings=settings(database=None, derandomize=True))
    assert too_close(scenario)
