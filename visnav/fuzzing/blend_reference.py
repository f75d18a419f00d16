"""The yardstick of ``blend_weights``: the closed form of (18)–(19) on the pure controllers, computed here.

What ``blend_weights`` judges is how the loop mixes its controllers:
:func:`visnav.controllers.blend` (19), :func:`visnav.controllers.avoidance_control`
(18), the weights :meth:`visnav.closed_loop.ClosedLoop.command` uses to decide
which controllers to compute, and the blending laws of the closed-loop mutants.
None of them is imported here.  The pure controllers themselves (visual
servoing (7), occlusion avoidance (8)–(9), path following (11), pan tracking
(16)–(17)) are not what is judged: they are called directly, with the loop's
scenario, gains and desired features, at the sample's state, image, features
and latched memory, and combined by (18)–(19) written out in
:func:`eq_18_19`:

``q̇ = (1 − µ_occ)(1 − µ_coll) q̇_VS + (1 − µ_coll) µ_occ q̇_occ + µ_coll q̇_coll``,
``q̇_coll = (v_coll, ω_coll, (1 − µ_occ) ϖ + µ_occ ϖ~)``.

A controller of weight exactly 0 is not computed (as in the loop, whose
controllers may be undefined there, e.g. occlusion avoidance without an occluder).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Protocol

from visnav.controllers import occlusion_avoidance, pan_tracking, path_following, visual_servoing
from visnav.geometry import ImageMeasurement, proximity
from visnav.parameters import Scenario

__all__ = ["LoopView", "eq_18_19", "blend_reference"]

Joint = tuple[float, float, float]
Point = tuple[float, float, float]


class LoopView(Protocol):
    """What the reference reads of a loop: its scenario and the target's image at the goal."""

    scenario: Scenario
    desired: tuple[Point, ...]


def _given(name: str, value: object, weight: float) -> None:
    if value is None:
        raise ValueError(f"eq_18_19: {name} is None but its weight is {weight!r}; compute that controller "
                         "(only a controller of weight exactly 0 may be left out)")


def eq_18_19(mu_coll: float, mu_occ: float, q_vs: Joint | None, q_occ: Joint | None,
             coll: tuple[float, float, float | None, float | None] | None) -> Joint:
    """(19) with (18) inside, term by term; ``coll = (v_coll, ω_coll, ϖ, ϖ~)``.

    Terms of weight exactly 0 are left out (their controller may be ``None``).

    Raises
    ------
    ValueError
        A controller of non-zero weight is ``None``.
    """
    w_vs, w_occ = (1.0 - mu_occ) * (1.0 - mu_coll), (1.0 - mu_coll) * mu_occ
    v = omega = pan_rate = 0.0
    if w_vs != 0.0:
        _given("q_vs", q_vs, w_vs)
        v, omega, pan_rate = v + w_vs * q_vs[0], omega + w_vs * q_vs[1], pan_rate + w_vs * q_vs[2]  # type: ignore[index]
    if w_occ != 0.0:
        _given("q_occ", q_occ, w_occ)
        v, omega, pan_rate = v + w_occ * q_occ[0], omega + w_occ * q_occ[1], pan_rate + w_occ * q_occ[2]  # type: ignore[index]
    if mu_coll != 0.0:
        _given("coll", coll, mu_coll)
        v_coll, omega_coll, pan_real, pan_rec = coll  # type: ignore[misc]
        pan_coll = 0.0
        if mu_occ != 1.0:
            _given("the real pan rate", pan_real, 1.0 - mu_occ)
            pan_coll += (1.0 - mu_occ) * pan_real  # type: ignore[operator]
        if mu_occ != 0.0:
            _given("the reconstructed pan rate", pan_rec, mu_occ)
            pan_coll += mu_occ * pan_rec  # type: ignore[operator]
        v, omega, pan_rate = v + mu_coll * v_coll, omega + mu_coll * omega_coll, pan_rate + mu_coll * pan_coll
    return (v, omega, pan_rate)


def blend_reference(loop: LoopView, x: tuple[float, float, float, float], image: ImageMeasurement,
                    features: tuple[Point, ...], estimated: tuple[Point, ...], memory: Mapping[str, float],
                    mu: tuple[float, float]) -> Joint:
    """The control (18)–(19) at one sample from the pure controllers computed here.

    Parameters
    ----------
    loop : LoopView
        The loop (its ``scenario`` and ``desired`` features).
    x : (x, y, θ, ϑ)
        Robot pose and pan angle [m, m, rad, rad].
    image : ImageMeasurement
        The sample's image (occluder, d_occ).
    features, estimated : tuple of (X, Y, z)
        Features the image-based tasks use (measured where visible, reconstructed elsewhere)
        and the reconstructed ones [-, -, m].
    memory : mapping
        The latched ``obstacle`` and ``side`` the controllers read.
    mu : (µ_coll, µ_occ)
        The risk parameters the loop recorded.

    Raises
    ------
    hybrid.errors.NumericalFailure
        When a pure controller cannot be computed at this sample.
    """
    s, (mu_coll, mu_occ) = loop.scenario, mu
    g = s.gains
    px, py, theta, pan = x
    desired_xy = tuple((p[0], p[1]) for p in loop.desired)
    q_vs = q_occ = None
    if (1.0 - mu_occ) * (1.0 - mu_coll) != 0.0:
        q_vs = visual_servoing(features, desired_xy, pan, s.robot, g.lambda_vs, loop.desired)
    if (1.0 - mu_coll) * mu_occ != 0.0:
        if image.occluder_index >= 0 and math.isfinite(image.d_occ_px):
            q_occ = occlusion_avoidance(features, desired_xy, image, pan, s.robot, s.camera, s.envelopes,
                                        g.lambda_occ, g.beta_occ)
        else:  # no occluder in front: the occlusion task is void, visual servoing (docs/controllers.md)
            q_occ = visual_servoing(features, desired_xy, pan, s.robot, g.lambda_vs, loop.desired)
    coll = None
    if mu_coll != 0.0:
        prox = proximity(px, py, theta, s.obstacles[int(memory["obstacle"])], int(memory["side"]))
        v_coll, omega_coll = path_following(prox, s.envelopes.d_zero_m, g.v_coll_mps, g.k_path)
        y_gc = sum(p[1] for p in loop.desired) / len(loop.desired)
        pan_real = (pan_tracking(features, pan, v_coll, omega_coll, s.robot, g.lambda_gc, y_gc)
                    if mu_occ != 1.0 else None)
        pan_rec = (pan_tracking(estimated, pan, v_coll, omega_coll, s.robot, g.lambda_gc, y_gc)
                   if mu_occ != 0.0 else None)
        coll = (v_coll, omega_coll, pan_real, pan_rec)
    return eq_18_19(mu_coll, mu_occ, q_vs, q_occ, coll)
