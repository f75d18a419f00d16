"""Planted-bug benchmark: an adaptive cruise control (ACC) whose switching logic can carry a defect.

An ego car follows a lead car on a straight road.  States: the gap ``d`` [m] (lead's rear bumper
to ego's front), the ego speed ``v`` [m/s] and the lead speed ``vl`` [m/s].  The lead brakes from
t = 0 with deceleration ``b`` [m/s²], fading out as it stops (``vl' = -b min(1, vl)``: the lead
never reverses).  The ego's controller switches between three modes, each a symbolic flow
(:mod:`hybrid.symbolic`: guards and flows are expressions, so the model is exact and inspectable):

``cruise``
    speed control to the set speed, ``v' = K_CRUISE (V_SET - v)``; enters ``follow`` when the gap
    falls below the headway ``D_MIN + H v + 10``;
``follow``
    gap control, ``v' = K_GAP (d - D_MIN - H v) + K_REL (vl - v)`` clipped to ``[-A_COMFORT, 2]``
    (comfortable braking only); back to ``cruise`` above ``D_MIN + H v + 25``;
``brake``
    emergency braking, ``v' = -A_BRAKE min(1, 2 v)`` (fading as the ego stops), entered from either
    mode when the safe-distance margin ``d - D_MIN - v²/(2 A_BRAKE) + vl²/(2 B_MAX)`` reaches 0 (the
    ego's stopping distance against the lead's, braking at the box's hardest); back to ``follow``
    once the margin is 10 m and the ego is not faster than the lead.

Requirement ``no_collision``: ``always[0, 40] (d >= 2)``.

The box (uniform): initial gap ``d0`` ∈ [50, 90] m (nominal 65), ego speed ``v0`` ∈ [15, 30] m/s
(25), lead speed ``vl0`` ∈ [15, 30] m/s (22), lead deceleration ``b`` ∈ [0, 8] m/s² (3).

Variants (:data:`BUGS`):

``"correct"``
    the design above; no violation in a dense sample of the box (lowest robustness ≈ 3: the gap
    settles at ``D_MIN`` behind a stopped lead).
``"gross"``
    the emergency braking was tuned for a lighter car: 7.1 instead of 8 m/s² in the ``brake`` mode,
    while its guard still assumes 8: a harsh lead braking at speed ends in a collision.
``"subtle"``
    the brake guard assumes the lead brakes at 5 m/s² at most, where the box goes to 8: only the
    hardest lead braking at the highest speeds from the shortest gaps collides.

The violating fractions of the box were measured by dense sampling (:func:`violating_fraction`,
a scrambled Sobol sample of 2,048 points, seed 0; 512 for ``correct``) and are stated in
:data:`MEASURED`.

Verify with::

    visnav verify examples/acc.py:gross
    visnav verify examples/acc.py:subtle --budget 200
"""

from __future__ import annotations

from collections.abc import Mapping

from analysis.verify import Parameter, Requirement, VerificationProblem, hybrid_problem
from hybrid import HybridAutomaton, HybridSystem, Mode, Transition, coordinates, flow_map
from hybrid.symbolic import maximum, minimum

__all__ = ["BUGS", "MEASURED", "acc_system", "acc_problem", "problems", "violating_fraction", "correct", "gross",
           "subtle"]

V_SET = 30.0
"""Set speed of the cruise mode [m/s]."""
D_MIN = 5.0
"""Standstill distance of the gap law [m]."""
H = 1.2
"""Time headway of the gap law [s]."""
K_CRUISE, K_GAP, K_REL = 0.4, 0.25, 0.9
A_BRAKE = 8.0
"""Emergency deceleration [m/s²]."""
A_COMFORT = 3.0
"""The gap law's largest deceleration [m/s²]: harder braking is the brake mode's."""
B_MAX = 8.0
"""The largest lead deceleration the brake guard assumes [m/s²] (the box's)."""
HORIZON_S = 40.0

BUGS: Mapping[str, Mapping[str, float]] = {
    "correct": {"a_brake": A_BRAKE, "guard_a": A_BRAKE, "guard_b": B_MAX},
    "gross": {"a_brake": 7.1, "guard_a": A_BRAKE, "guard_b": B_MAX},
    "subtle": {"a_brake": A_BRAKE, "guard_a": A_BRAKE, "guard_b": 5.0},
}
"""The variants: keyword arguments of :func:`acc_system` (decelerations [m/s²])."""

MEASURED: Mapping[str, float] = {"correct": 0.0, "gross": 530 / 2048, "subtle": 28 / 2048}
"""Violating fraction of the box per variant: :func:`violating_fraction` on 2,048 scrambled Sobol points, seed 0
(512 for ``correct``); a binomial standard error of at most 0.011."""

REQUIREMENT = Requirement(name="no_collision", formula=f"always[0, {HORIZON_S:g}] (d >= 2)",
                          description="the gap never falls below 2 m")


def acc_system(b: float, a_brake: float = A_BRAKE, guard_a: float = A_BRAKE, guard_b: float = B_MAX) -> HybridSystem:
    """The ACC loop for lead deceleration ``b`` [m/s²]; states ``(d, v, vl)``.

    ``a_brake`` is the brake mode's deceleration [m/s²]; the brake guard fires when the safe-distance
    margin ``d - D_MIN - v²/(2 guard_a) + vl²/(2 guard_b)`` reaches 0 (``guard_a``: the ego deceleration
    it assumes, ``guard_b``: the largest lead deceleration it assumes) [m/s²].
    """
    x = coordinates("d", "v", "vl")
    margin = x.d - D_MIN - x.v * x.v * (0.5 / guard_a) + x.vl * x.vl * (0.5 / guard_b)
    modes = (Mode(name="cruise", description="speed control"), Mode(name="follow", description="gap control"),
             Mode(name="brake", description="emergency braking"))
    transitions = (
        Transition(name="cruise_brake", source="cruise", target="brake", guard=margin <= 0.0, priority=0),
        Transition(name="cruise_follow", source="cruise", target="follow", guard=x.d <= D_MIN + H * x.v + 10.0,
                   priority=1),
        Transition(name="follow_brake", source="follow", target="brake", guard=margin <= 0.0, priority=0),
        Transition(name="follow_cruise", source="follow", target="cruise", guard=x.d >= D_MIN + H * x.v + 25.0,
                   priority=1),
        Transition(name="brake_follow", source="brake", target="follow", guard=(margin >= 10.0) & (x.v <= x.vl)),
    )
    automaton = HybridAutomaton(name="acc", modes=modes, transitions=transitions, variables=("d", "v", "vl"),
                                initial_mode="cruise")
    lead = -b * minimum(1.0, x.vl)
    gap_law = maximum(-A_COMFORT, minimum(2.0, K_GAP * (x.d - D_MIN - H * x.v) + K_REL * (x.vl - x.v)))
    flows = {
        "cruise": flow_map(x.vl - x.v, K_CRUISE * (V_SET - x.v), lead),
        "follow": flow_map(x.vl - x.v, gap_law, lead),
        "brake": flow_map(x.vl - x.v, -a_brake * minimum(1.0, 2.0 * x.v), lead),
    }
    return HybridSystem(automaton=automaton, state_names=("d", "v", "vl"), flows=flows)


class _Build:
    """``build(point)`` of one variant (a module-level class: picklable for process pools)."""

    def __init__(self, bug: str) -> None:
        self.bug = bug

    def __call__(self, point: Mapping[str, float]) -> HybridSystem:
        return acc_system(point["b"], **BUGS[self.bug])


class _InitialMode:
    def __init__(self, bug: str) -> None:
        self.guard_a, self.guard_b = BUGS[bug]["guard_a"], BUGS[bug]["guard_b"]

    def __call__(self, point: Mapping[str, float]) -> str:
        d, v, vl = point["d0"], point["v0"], point["vl0"]
        if d - D_MIN - v * v * (0.5 / self.guard_a) + vl * vl * (0.5 / self.guard_b) <= 0.0:
            return "brake"
        return "follow" if d <= D_MIN + H * v + 10.0 else "cruise"


def acc_problem(bug: str = "gross") -> VerificationProblem:
    """The verification problem of variant ``bug`` (:data:`BUGS`): the box of the module docstring, 40 s."""
    if bug not in BUGS:
        from analysis.verify.verification import ProblemError

        raise ProblemError("bug", bug, f"one of {', '.join(BUGS)}", "use acc_problem('gross')")
    return hybrid_problem(
        name=f"acc-{bug}",
        system=_Build(bug),
        initial={"d": Parameter(name="d0", low=50.0, high=90.0, nominal=65.0, unit="m"),
                 "v": Parameter(name="v0", low=15.0, high=30.0, nominal=25.0, unit="m/s"),
                 "vl": Parameter(name="vl0", low=15.0, high=30.0, nominal=22.0, unit="m/s")},
        parameters=(Parameter(name="b", low=0.0, high=8.0, nominal=3.0, unit="m/s^2"),),
        initial_mode=_InitialMode(bug),
        horizon=HORIZON_S,
        sample_period=0.1,
        requirements=(REQUIREMENT,),
        reach=False,
        description=f"adaptive cruise control, variant {bug!r} (examples/acc.py)",
        source=f"examples/acc.py:{bug}",
    )


def violating_fraction(problem: VerificationProblem, samples: int = 2048, seed: int = 0) -> float:
    """Share of a scrambled Sobol sample of the box (``samples`` points, a power of 2) where the first
    requirement is violated."""
    from scipy.stats import qmc

    from analysis.verify.falsification import evaluate

    units = qmc.Sobol(d=problem.dimension, scramble=True, seed=seed).random(samples) * 2.0 - 1.0
    hits = sum(1 for u in units if evaluate(problem, tuple(float(c) for c in u)).satisfied[:1] == (False,))
    return hits / samples


def problems() -> dict[str, VerificationProblem]:
    """The three variants keyed ``"ACC-correct"``, ``"ACC-gross"``, ``"ACC-subtle"``."""
    return {f"ACC-{bug}": acc_problem(bug) for bug in BUGS}


correct = acc_problem("correct")
gross = acc_problem("gross")
subtle = acc_problem("subtle")
