"""Reachability under arbitrary switching by the relaxation (analysis.reach.relaxed) and its own re-check.

Yardstick: seeded random switching signals (dwell times log-uniform in [1e-3, 0.3] s) with bang-bang inputs, and
greedy adversarial runs (every 1e-3 s the mode and the input that push ``d·x`` fastest, for 8 directions ``d`` from
4 corners of the initial box), integrated piece by piece exactly by ``scipy.linalg.expm`` of the augmented matrix
``[[A_i, B u], [0, 0]]`` (no code of the producer or of the re-check).  ``expm`` is accurate to about 1e-15
relative on these O(1) matrices and a run has at most 3,000 pieces, so a sample is compared with the flowpipe's
boxes within 1e-9.  The greedy runs are what make the test able to fail: a flowpipe whose switching disturbance is
scaled by 0.8 leaves about 17 % of their samples outside (measured), while the random runs stay inside it.
"""

from __future__ import annotations


import numpy as np
import pytest
from scipy.linalg import expm

from analysis.reach import ModeInput
from analysis.reach.fragment import safety_fragment
from analysis.reach.model import affine_model
from analysis.reach.recheck_relaxed import recheck_relaxed
from analysis.reach.relaxed import NoGroup, relaxed_reach, switching_group
from analysis.reach.verdict import decide
from analysis.spaceex_relaxed import NOT_USED, relaxed_outcome
from analysis.stl.syntax import parse_tree
from hybrid import HybridAutomaton, Mode, Transition
from hybrid.symbolic import Const, coordinates, flow_map, jump_map
from hybrid.system import HybridSystem

A1 = np.array([[0.0, 1.0], [-2.0, -1.0]])
A2 = np.array([[0.0, 1.0], [-0.5, -0.25]])
B = np.array([[0.0], [1.0]])
INPUTS = {m: ModeInput(matrix=B.tolist(), bounds=([-0.5], [0.5])) for m in ("a", "b")}
INITIAL = {"x": (0.9, 1.1), "y": (-0.1, 0.1)}
HORIZON = 3.0
STEP = 0.01


def _switched(invariant_a=None, reset=None, invariant_b=None) -> HybridSystem:
    automaton = HybridAutomaton(
        name="switched", modes=(Mode(name="a", invariant=invariant_a), Mode(name="b", invariant=invariant_b)),
        transitions=(Transition(name="ab", source="a", target="b", guard=Const(1.0)),
                     Transition(name="ba", source="b", target="a", guard=Const(1.0))),
        variables=("x", "y"), initial_mode="a")
    X = coordinates("x", "y")
    return HybridSystem(automaton=automaton, state_names=("x", "y"), jumps=reset or {}, flows={
        "a": flow_map(A1[0, 0] * X.x + A1[0, 1] * X.y, A1[1, 0] * X.x + A1[1, 1] * X.y),
        "b": flow_map(A2[0, 0] * X.x + A2[0, 1] * X.y, A2[1, 0] * X.x + A2[1, 1] * X.y)})


def _samples(seed: int, runs: int) -> list[tuple[float, np.ndarray]]:
    """(t, state) at every switch and at 4 interior points per piece, of ``runs`` random switched runs."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(runs):
        x = np.array([rng.uniform(*INITIAL["x"]), rng.uniform(*INITIAL["y"])])
        t = 0.0
        while t < HORIZON:
            dwell = min(float(np.exp(rng.uniform(np.log(1e-3), np.log(0.3)))), HORIZON - t)
            a = A1 if rng.random() < 0.5 else A2
            u = 0.5 if rng.random() < 0.5 else -0.5
            aug = np.zeros((3, 3))
            aug[:2, :2], aug[:2, 2] = a, B[:, 0] * u
            for s in np.linspace(0.0, dwell, 5)[1:]:
                out.append((t + s, (expm(aug * s) @ np.append(x, 1.0))[:2]))
            x = out[-1][1]
            t += dwell
    return out


def _greedy(direction: np.ndarray, start: tuple[float, float], dwell: float = 1e-3) -> list[tuple[float, np.ndarray]]:
    """A run that, every ``dwell`` seconds, takes the mode and input maximising ``direction · ẋ``."""
    steps = {}
    for k, a in enumerate((A1, A2)):
        for u in (-0.5, 0.5):
            aug = np.zeros((3, 3))
            aug[:2, :2], aug[:2, 2] = a, B[:, 0] * u
            steps[(k, u)] = (a, u, expm(aug * dwell))
    x, out = np.array(start, dtype=float), []
    for i in range(1, int(round(HORIZON / dwell)) + 1):
        _, _, phi = max(steps.values(), key=lambda e: float(direction @ (e[0] @ x + B[:, 0] * e[1])))
        x = (phi @ np.append(x, 1.0))[:2]
        out.append((i * dwell, x))
    return out


def _adversarial() -> list[tuple[float, np.ndarray]]:
    out = []
    for angle in np.linspace(0.0, 2 * np.pi, 8, endpoint=False):
        for start in ((1.1, 0.1), (0.9, -0.1), (1.1, -0.1), (0.9, 0.1)):
            out.extend(_greedy(np.array([np.cos(angle), np.sin(angle)]), start))
    return out


@pytest.fixture(scope="module")
def flowpipe():
    model = affine_model(_switched())
    group = switching_group(model, INPUTS)
    return model, group, relaxed_reach(model, group, INITIAL, horizon=HORIZON, time_step=STEP)


def _outside(result, samples: list[tuple[float, np.ndarray]], tol: float = 1e-9) -> list[tuple[float, np.ndarray]]:
    """The samples in no box of a segment of mode ``a`` whose time interval holds their time."""
    segs = [s for s in result.segments if s.mode == "a"]
    t_lo = np.array([s.t_lo for s in segs])
    t_hi = np.array([s.t_hi for s in segs])
    lo = np.array([s.lo for s in segs]) - tol
    hi = np.array([s.hi for s in segs]) + tol
    out = []
    for t, x in samples:
        near = (t_lo <= t) & (t <= t_hi)
        if not np.any(near & np.all(x >= lo, axis=1) & np.all(x <= hi, axis=1)):
            out.append((t, x))
    return out


def test_the_group_is_the_pair_with_its_midpoint_and_deviations(flowpipe):
    _, group, result = flowpipe
    assert group.modes == ("a", "b")
    # dyadic entries: the midpoint and the half-spread are exact
    assert np.array_equal(np.array(group.a_center, dtype=float), (A1 + A2) / 2)
    assert np.array_equal(np.array(group.a_radius, dtype=float), np.abs(A2 - A1) / 2)
    assert result.terminations[0].reason == "horizon" and result.complete
    assert {s.mode for s in result.segments} == {"a", "b"}


def test_every_switched_run_lies_in_the_relaxed_flowpipe(flowpipe):
    _, _, result = flowpipe
    samples = _samples(seed=7, runs=60) + _adversarial()
    outside = _outside(result, samples)
    assert len(samples) > 100_000 and not outside, outside[:3]


def test_a_planted_set_a_switched_run_reaches_is_never_proven(flowpipe):
    model, _, result = flowpipe
    reached = max(float(x[0]) for _, x in _greedy(np.array([1.0, 0.0]), (1.1, 0.1)))
    fragment = safety_fragment(parse_tree(f"always[0, {HORIZON}] (x <= {reached - 0.01})"), ("x", "y"))
    holds, _, _ = decide(result, fragment, model, INITIAL)
    check = recheck_relaxed({"time_step": STEP, "schedule": {"relaxed_group": ["a", "b"]}}, _switched(), INITIAL,
                            fragment, inputs=INPUTS)
    assert not holds and not check.passed and check.failure.startswith("requirement")


def test_a_safe_bound_is_proven_and_rechecked_with_a_margin_below_the_true_one(flowpipe):
    model, _, result = flowpipe
    top = max(float(s.hi[0]) for s in result.segments)
    bound = top + 0.05
    fragment = safety_fragment(parse_tree(f"always[0, {HORIZON}] (x <= {bound})"), ("x", "y"))
    holds, margin, _ = decide(result, fragment, model, INITIAL)
    check = recheck_relaxed({"time_step": STEP, "schedule": {"relaxed_group": ["a", "b"]}}, _switched(), INITIAL,
                            fragment, inputs=INPUTS)
    reached = max(float(x[0]) for _, x in _greedy(np.array([1.0, 0.0]), (1.1, 0.1)))
    # both margins are lower bounds of the true one, which is at most bound − (a run's largest x)
    assert holds and 0.0 < margin <= bound - reached
    assert check.passed and 0.0 < check.margin <= bound - reached


def test_the_relaxed_flowpipe_is_deterministic():
    model = affine_model(_switched())
    group = switching_group(model, INPUTS)
    one = relaxed_reach(model, group, INITIAL, horizon=1.0, time_step=0.05).to_json()
    two = relaxed_reach(model, group, INITIAL, horizon=1.0, time_step=0.05).to_json()
    assert one == two


def test_invariants_that_differ_give_no_group_and_the_route_says_why():
    X = coordinates("x", "y")
    system = _switched(invariant_a=X.x <= 5.0)
    with pytest.raises(NoGroup, match="invariant of 'a' differs"):
        switching_group(affine_model(system), INPUTS)
    note = relaxed_outcome(system, INPUTS, INITIAL, safety_fragment(parse_tree("always[0, 1] (x <= 9)"), ("x", "y")),
                           "a", 0.01, method="m", bounds="u", assumptions=())
    assert isinstance(note, str) and NOT_USED in note and "differs" in note


def test_a_reset_that_is_not_the_identity_gives_no_group_and_the_route_says_why():
    X = coordinates("x", "y")
    system = _switched(reset={"ab": jump_map(0.5 * X.x, X.y)})
    with pytest.raises(NoGroup, match="reset that is not the identity"):
        switching_group(affine_model(system), INPUTS)
    note = relaxed_outcome(system, INPUTS, INITIAL, safety_fragment(parse_tree("always[0, 1] (x <= 9)"), ("x", "y")),
                           "a", 0.01, method="m", bounds="u", assumptions=())
    assert isinstance(note, str) and "reset that is not the identity" in note
    # the re-check refuses it on its own reading of the model
    check = recheck_relaxed({"time_step": 0.01, "schedule": {"relaxed_group": ["a", "b"]}}, system, INITIAL,
                            safety_fragment(parse_tree("always[0, 1] (x <= 9)"), ("x", "y")), inputs=INPUTS)
    assert not check.passed and "resets the state" in check.failure


def test_a_flowpipe_not_proven_inside_the_common_invariant_decides_nothing():
    X = coordinates("x", "y")
    system = _switched(invariant_a=X.x <= 1.05, invariant_b=X.x <= 1.05)  # the initial box reaches x = 1.1
    model = affine_model(system)
    group = switching_group(model, INPUTS)
    result = relaxed_reach(model, group, INITIAL, horizon=1.0, time_step=STEP)
    fragment = safety_fragment(parse_tree("always[0, 1] (x <= 9)"), ("x", "y"))
    end = result.terminations[0]
    assert not result.complete and end.reason == "blow_up" and "may leave the common invariant" in end.detail
    assert not decide(result, fragment, model, INITIAL)[0]
    check = recheck_relaxed({"time_step": STEP, "schedule": {"relaxed_group": ["a", "b"]}}, system, INITIAL, fragment,
                            inputs=INPUTS)
    assert not check.passed and "may leave the invariant" in check.failure


def test_bad_boxes_and_steps_are_refused_by_name():
    from hybrid.errors import ParameterError

    model = affine_model(_switched())
    group = switching_group(model, INPUTS)
    with pytest.raises(ParameterError, match="initial"):
        relaxed_reach(model, group, {"x": (0.0, 1.0)}, horizon=1.0, time_step=0.1)
    with pytest.raises(ParameterError, match="initial"):
        relaxed_reach(model, group, {"x": (1.0, 0.0), "y": (0.0, 0.0)}, horizon=1.0, time_step=0.1)
    with pytest.raises(ParameterError, match="time_step"):
        relaxed_reach(model, group, INITIAL, horizon=1.0, time_step=0.0)
    with pytest.raises(ParameterError, match="time_step"):
        relaxed_reach(model, group, INITIAL, horizon=10.0, time_step=5.0)  # ‖|A_c| + A_r‖ δ > 4


def test_inputs_that_differ_give_no_group():
    other = dict(INPUTS, b=ModeInput(matrix=B.tolist(), bounds=([-0.5], [0.6])))
    with pytest.raises(NoGroup, match="inputs of mode 'b' differ"):
        switching_group(affine_model(_switched()), other)


def test_the_relaxed_recheck_imports_no_set_code_of_the_producer(reach_imports):
    seen = reach_imports("recheck_relaxed")
    assert seen == {"recheck_relaxed", "fragment", "model", "affine", "smooth", "recheck_inputs",
                    "recheck_interval", "recheck_sets"}, seen
