"""Random layouts: whole scenarios for the closed-loop properties.

:func:`scenarios` draws obstacles, heights, a target and a goal on the paper
scenario's robot, camera, envelopes and gains, keeping the paper's
hypotheses or breaking them on purpose.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from typing import Any

from hypothesis import strategies as st

from visnav.parameters import Obstacle, Pose, Scenario, Target
from visnav.scenario import load_scenario, target_square

__all__ = ["scenarios"]


@functools.lru_cache(maxsize=1)
def _base_scenario() -> Scenario:
    return dataclasses.replace(load_scenario("paper"), duration_s=90.0, description="random layout (visnav.fuzzing.layouts)")


@st.composite
def _layouts(draw: Callable[[st.SearchStrategy[Any]], Any], respect: bool) -> Scenario:
    base = _base_scenario()
    env = base.envelopes
    goal_x = draw(st.floats(4.0, 8.0))
    goal_y = draw(st.floats(-1.0, 1.0))
    theta0 = draw(st.floats(-0.3, 0.3))
    n = draw(st.integers(1, 3))
    goal_clearance = env.d_plus_m + 0.5
    obstacles: list[Obstacle] = []
    cursor = draw(st.floats(0.2, 1.5)) if not respect else 1.2
    for i in range(n):
        radius = draw(st.floats(0.2, 1.2))
        tall = draw(st.booleans())
        y = draw(st.floats(-1.2, 1.2))
        gap = draw(st.floats(0.0, 1.0))
        if not respect:
            gap -= 2.0 * env.d_plus_m * draw(st.floats(0.0, 1.0))  # may bring them closer than 2 d+
        x = cursor + radius
        cursor = x + radius + 2.0 * env.d_plus_m + gap
        too_near_goal = math.hypot(goal_x - x, goal_y - y) - radius < goal_clearance
        near_start = math.hypot(x, y) - radius < env.d_plus_m
        if respect and (too_near_goal or near_start):
            continue
        obstacles.append(Obstacle(name=f"o{i}", center_m=(x, y), radius_m=radius, height_m=1.5 if tall else 0.3))
    if not respect and draw(st.booleans()):  # an obstacle in the goal's neighbourhood
        radius = draw(st.floats(0.2, 0.6))
        dx = draw(st.floats(-1.5, -0.2))
        obstacles.append(Obstacle(name="near-goal", center_m=(goal_x + dx - radius, goal_y + draw(st.floats(-0.6, 0.6))),
                                  radius_m=radius, height_m=1.5 if draw(st.booleans()) else 0.3))
    normal = math.pi + draw(st.floats(-0.2, 0.2))
    centre = (goal_x + base.robot.pan_offset_m + 1.0, goal_y, base.robot.camera_height_m)
    target = Target(points_m=target_square(centre, normal, 0.3))
    return dataclasses.replace(
        base,
        name=f"random-{'respecting' if respect else 'breaking'}",
        obstacles=tuple(obstacles),
        target=target,
        start=Pose(x_m=0.0, y_m=0.0, theta_rad=theta0, pan_rad=0.0),
        goal=Pose(x_m=goal_x, y_m=goal_y, theta_rad=0.0, pan_rad=0.0),
    )


def scenarios(*, respect: bool = True) -> st.SearchStrategy[Scenario]:
    """Random scenarios on the paper's robot, camera, envelopes and gains.

    ``respect=True`` keeps the paper's hypotheses: 1–3 obstacles (low or
    tall, radius 0.2–1.2 m) between the start and the goal, at least 2 d+
    apart surface to surface, none within d+ of the start nor within
    d+ + 0.5 m of the goal; a 0.3 m square target 1 m in front of the goal's
    camera, the goal 4–8 m ahead, start heading within ±0.3 rad.
    ``respect=False`` breaks them on purpose: obstacles closer than 2 d+ (or
    overlapping), one possibly near the start or in the goal's neighbourhood.
    The scenario validator is bypassed (it would reject those).
    """
    return _layouts(respect)
