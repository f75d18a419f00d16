"""Stateful testing of a supervisor variant: a hypothesis rule-based state machine.

:class:`SupervisorMachine` is defined once, here; it is parametrised by two
class attributes, the variant it drives and the measurement space.  The
rules' argument strategies depend on the space (the number of obstacles, the
channels' landmarks), so :func:`supervisor_machine` is the small factory that
makes the subclass for one ``(variant, space)``: it sets the attributes and
declares the rule methods of the base class as hypothesis rules with the
space's strategies (:func:`rule_arguments`).  The ``stateful`` property runs
it (:func:`analysis.fuzzing.run_machine`) and replays the measurements it fed
like any sequence (:func:`visnav.fuzzing.properties.check_stateful`).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from visnav.fuzzing.mutants import SupervisorVariant
from visnav.fuzzing.properties import check_sample
from visnav.fuzzing.runner import Step, SupervisorRunner
from visnav.fuzzing.space import MeasurementSpace, respect_hypotheses
from visnav.fuzzing.variants import variant_flags

__all__ = ["STATEFUL_STEPS", "SupervisorMachine", "rule_arguments", "supervisor_machine"]

STATEFUL_STEPS = 25
"""Rules per run of the state machine."""


class SupervisorMachine(RuleBasedStateMachine):
    """Drives :attr:`variant` step by step; the invariants are checked on every sample a rule fed.

    Rules move the measurements the way a robot and its camera can (ramps of
    a distance, of the pan angle, of the occluder at their rate bounds; holds;
    a flip of the bypass side) and the way they cannot (jumps of a distance or
    of ``d_occ``, including to ``inf``, the occluder leaving the image at
    once); the hypotheses are kept: obstacles more than 2 d+ apart (H1,
    :func:`~visnav.fuzzing.space.respect_hypotheses`) and, as the path
    follower does in closed loop, the avoided obstacle within d+ until LEAVE
    (H2, :func:`~visnav.fuzzing.properties.hypotheses_prefix`).  After every
    rule the invariants of :func:`~visnav.fuzzing.properties.check_stateful`
    are checked on every sample the rule fed.  The machine's ``measurements``
    are replayable with the ``stateful`` property.

    This class has no rules of its own: use :func:`supervisor_machine`.
    """

    variant: ClassVar[SupervisorVariant]
    """The supervisor driven (set by :func:`supervisor_machine`)."""
    space: ClassVar[MeasurementSpace]
    """The measurement model (set by :func:`supervisor_machine`)."""

    def __init__(self) -> None:
        super().__init__()
        space = self.space
        self.runner = SupervisorRunner(self.variant, space)
        far = space.envelopes.d_plus_m + 1.0
        self.current = ([far] * space.n_obstacles
                        + [1.0, 2.0 * space.envelopes.D_plus_px, space.camera_half_width_px, 0.0, 0.0, 1.0])
        self.measurements: list[tuple[float, ...]] = []
        self.fresh: list[Step] = []
        self.last: Step | None = None
        self.steps = 0
        self.avoided = 0
        self.avoiding = False
        self.avoid_before = False

    def _feed(self, count: int = 1) -> None:
        space = self.space
        n = space.n_obstacles
        d_plus = space.envelopes.d_plus_m
        for _ in range(count):
            if self.avoiding:  # (H2) the path follower keeps the avoided obstacle within d+ ...
                a = self.avoided
                self.current[a] = min(self.current[a], d_plus)
                for j in range(n):  # ... so the others are >= 2 d+ - d_a away (H1 around it)
                    if j != a:
                        self.current[j] = max(self.current[j], 2.0 * d_plus - self.current[a])
            row = respect_hypotheses([self.current], space)[0]
            self.current = list(row)
            self.measurements.append(row)
            step = self.runner.step(row)
            self.fresh.append(step)
            self.steps += 1
            avoid, leave, _ = variant_flags(self.variant, step.mode)
            if avoid and not self.avoid_before:
                self.avoided = min(range(n), key=row.__getitem__)
            self.avoiding = bool(avoid and not leave)
            self.avoid_before = avoid

    def _ramp(self, column: int, goal: float, rate: float, limit: int = 250) -> None:
        self.fresh = []
        for _ in range(limit):
            now = self.current[column]
            if now == goal:
                break
            self.current[column] = min(goal, now + rate) if goal > now else max(goal, now - rate)
            self._feed()
        if not self.fresh:
            self._feed()

    # ---- rules (declared with their strategies by supervisor_machine) ---------------------------------

    def move_obstacle(self, i: int, goal: float) -> None:
        """Ramp the distance to obstacle ``i`` to ``goal`` at its rate bound."""
        self._ramp(i, goal, self.space.max_step_d_m)

    def swing_pan(self, goal: float) -> None:
        """Ramp the pan angle to ``goal`` at its rate bound."""
        self._ramp(self.space.index("pan_rad"), goal, self.space.max_step_pan_rad)

    def move_occluder(self, goal: float) -> None:
        """Ramp ``d_occ`` to ``goal`` at its rate bound."""
        self._ramp(self.space.index("d_occ_px"), goal, self.space.max_step_d_occ_px)

    def move_border(self, goal: float) -> None:
        """Ramp ``d_bord`` to ``goal`` at its rate bound."""
        self._ramp(self.space.index("d_bord_px"), goal, self.space.max_step_d_bord_px)

    def bypass(self, i: int, sign: float, swing: float, back: float, away: float) -> None:
        """The whole story: into ξ−, the pan out past the arming angle and back through 0, then away."""
        space = self.space
        i_pan = space.index("pan_rad")
        arm = space.settings.arm_angle_rad
        offset = 2.0 * math.pi * round(self.current[i_pan] / (2.0 * math.pi))
        fed: list[Step] = []
        for column, goal, rate in (
            (i, space.envelopes.d_minus_m, space.max_step_d_m),
            (i_pan, offset + sign * (arm + swing), space.max_step_pan_rad),
            (i_pan, offset - sign * back, space.max_step_pan_rad),
            (i, away, space.max_step_d_m),
        ):
            self._ramp(column, goal, rate)
            fed += self.fresh
        self.fresh = fed

    def hold(self, count: int) -> None:
        """Hold every measurement for ``count`` samples."""
        self.fresh = []
        self._feed(count)

    def flip_side(self) -> None:
        """Flip the bypass side (one sample)."""
        self.fresh = []
        i_side = self.space.index("side")
        self.current[i_side] = -self.current[i_side]
        self._feed()

    def jump_obstacle(self, i: int, value: float) -> None:
        """Jump the distance to obstacle ``i`` to ``value`` (one sample)."""
        self.fresh = []
        self.current[i] = value
        self._feed()

    def jump_occluder(self, value: float, border: bool) -> None:
        """Jump ``d_occ`` to ``value`` (``inf`` too), the occluder possibly at the image border (one sample)."""
        self.fresh = []
        self.current[self.space.index("d_occ_px")] = value
        if border:
            self.current[self.space.index("d_bord_px")] = 0.0
        self._feed()

    @invariant()
    def invariants_hold(self) -> None:
        """:func:`~visnav.fuzzing.properties.check_sample` on every sample fed since the last check."""
        prev = self.last
        for s in self.fresh:
            check_sample(self.variant, self.space, s, prev)
            prev = s
        self.last = prev
        self.fresh = []


def rule_arguments(space: MeasurementSpace) -> dict[str, dict[str, st.SearchStrategy[Any]]]:
    """The argument strategies of every rule of :class:`SupervisorMachine` for ``space`` (rule name -> arguments)."""
    by_name = {ch.name: ch for ch in space.channels()}
    n = space.n_obstacles

    def waypoints(name: str, adversarial: bool = False) -> st.SearchStrategy[float]:
        ch = by_name[name]
        options = [st.sampled_from(ch.waypoints()), st.floats(ch.low, ch.high)]
        if adversarial and ch.specials:
            options.append(st.sampled_from(ch.specials))
        return st.one_of(*options)

    return {
        "move_obstacle": {"i": st.integers(0, n - 1), "goal": waypoints("d_coll_0_m")},
        "swing_pan": {"goal": waypoints("pan_rad")},
        "move_occluder": {"goal": waypoints("d_occ_px")},
        "move_border": {"goal": waypoints("d_bord_px")},
        "bypass": {"i": st.integers(0, n - 1), "sign": st.sampled_from((1.0, -1.0)), "swing": st.floats(0.0, 1.0),
                   "back": st.floats(0.0, 0.5), "away": waypoints("d_coll_0_m")},
        "hold": {"count": st.integers(1, 30)},
        "flip_side": {},
        "jump_obstacle": {"i": st.integers(0, n - 1), "value": waypoints("d_coll_0_m")},
        "jump_occluder": {"value": waypoints("d_occ_px", adversarial=True), "border": st.booleans()},
    }


def supervisor_machine(variant: SupervisorVariant, space: MeasurementSpace) -> type[SupervisorMachine]:
    """The :class:`SupervisorMachine` driving ``variant`` in ``space``, named ``SupervisorMachine_<variant>``.

    A subclass that sets :attr:`SupervisorMachine.variant` and
    :attr:`SupervisorMachine.space` and declares the rules with
    :func:`rule_arguments`; the name (hypothesis derives its derandomised
    seed from it) and the rules are those the machine always had, so the
    same seed gives the same runs.
    """
    name = f"SupervisorMachine_{variant.name}"
    rules = {rule_name: rule(**arguments)(getattr(SupervisorMachine, rule_name))
             for rule_name, arguments in rule_arguments(space).items()}
    namespace: dict[str, Any] = {"variant": variant, "space": space, "__module__": __name__, "__qualname__": name,
                                 "__doc__": SupervisorMachine.__doc__, **rules}
    return type(name, (SupervisorMachine,), namespace)
