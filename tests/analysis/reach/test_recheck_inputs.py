"""The independent re-check with bounded inputs (analysis.reach.recheck_inputs) and its refusals.

Yardstick: ``x' = -x + u``, ``|u| <= 1``, ``|x(0)| <= 0.8``.  Closed form: ``x(t) = e^{-t} x₀ + ∫ e^{-(t-s)} u``,
so ``|x(t)| <= e^{-t}·0.8 + (1 − e^{-t}) <= max(|x₀|, 1) = 1``, and the bound ``1 − 0.2 e^{-t}`` is reached
(``x₀ = 0.8``, ``u ≡ 1``): on ``[0, 3]`` the supremum is ``1 − 0.2 e^{-3} = 0.99004``.  A band ``|x| <= 1.05``
holds with margin ``>= 0.05``; a band ``|x| <= 0.99`` is violated (by ``u ≡ 1`` at ``t = 3``) and must never pass.
"""

from __future__ import annotations

import json
import math
from fractions import Fraction

import pytest

from analysis.reach import ModeInput, reach
from analysis.reach.fragment import safety_fragment
from analysis.reach.recheck import recheck_flowpipe
from analysis.reach.recheck_inputs import input_tube, tube_at
from analysis.stl.syntax import parse_tree
from hybrid import HybridAutomaton, Mode
from hybrid.errors import ParameterError
from hybrid.symbolic import coordinates, flow_map
from hybrid.system import HybridSystem

X = coordinates("x")
SYSTEM = HybridSystem(automaton=HybridAutomaton(name="decay", modes=(Mode(name="m"),), transitions=(),
                                                variables=("x",), initial_mode="m"),
                      state_names=("x",), flows={"m": flow_map(-X.x)})
INPUTS = {"m": ModeInput(matrix=[[1.0]], bounds=([-1.0], [1.0]))}
START = {"x": (-0.8, 0.8)}
HORIZON, STEP = 3.0, 0.02


def _band(bound: float, end: float = HORIZON):
    return safety_fragment(parse_tree(f"always[0, {end}] (x <= {bound} and x >= -{bound})"), ("x",))


@pytest.fixture(scope="module")
def saved() -> str:
    return reach(SYSTEM, START, horizon=HORIZON, time_step=STEP, inputs=INPUTS).to_json()


def test_the_json_carries_b_and_u(saved):
    assert json.loads(saved)["inputs"] == {"m": {"matrix": [[1.0]], "low": [-1.0], "high": [1.0]}}
    plain = reach(SYSTEM, START, horizon=0.1, time_step=STEP).to_json()
    assert "inputs" not in json.loads(plain)  # an input-free run's JSON is unchanged


def test_a_bound_just_above_the_closed_form_is_rechecked_and_one_below_never(saved):
    sup = 1.0 - 0.2 * math.exp(-HORIZON)  # 0.99004: the true supremum on [0, 3]
    check = recheck_flowpipe(saved, SYSTEM, START, _band(1.05), inputs=INPUTS)
    assert check.passed, check.failure
    # the exact margin is a lower bound of the true one (1.05 - sup), and not much below it (step 0.02)
    assert 0.0 < check.margin <= 1.05 - sup and check.margin > 1.05 - sup - 0.03
    below = recheck_flowpipe(saved, SYSTEM, START, _band(0.99), inputs=INPUTS)
    assert not below.passed and "requirement" in below.failure


def test_without_the_models_inputs_the_larger_flowpipe_still_covers_the_input_free_model(saved):
    assert recheck_flowpipe(saved, SYSTEM, START, _band(1.05)).passed


def test_the_tube_bound_against_the_closed_form():
    # v' = -v + u, |u| <= 1, v(0) = 0: sup |v(s)| = 1 - e^{-s}; the bound is above it and within O(δ^5)
    step = Fraction(1, 8)
    w, series, first, rest = input_tube([[Fraction(-1)]], [[Fraction(1)]], [Fraction(1)], step)
    for s in (Fraction(1, 32), Fraction(1, 16), step):
        bound = float(tube_at(w, series, s)[0])
        # above the truth; at most the series Σ_{k<6} s^{k+1}/(k+1)! <= e^s - 1 plus the remainder
        # |A^6| w s^6/6! <= 0.15 s^6/720
        assert 1 - math.exp(-float(s)) <= bound <= math.exp(float(s)) - 1 + 0.15 * float(s) ** 6 / 720 + 1e-15
    # v(δ) ∈ P₀ = ⊕ δ^{k+1}/(k+1)! (-1)^k [-1, 1] ⊕ [-rest, rest]: the true range is ±(1 - e^{-δ}); P₀'s radius
    # Σ_{k<6} δ^{k+1}/(k+1)! + rest <= e^δ - 1 + 0.15 δ^6/720 (first order: δ; the signs are lost per term)
    d = float(step)
    radius = sum(abs(float(g[0])) for g in first) + float(rest[0])
    assert len(first) == 6 and 1 - math.exp(-d) <= radius <= math.exp(d) - 1 + 0.15 * d ** 6 / 720 + 1e-15


def test_shrunk_segments_cannot_fool_the_recheck(saved):
    # segment 60 covers t in [1.18, 1.2]; the closed form reaches 1 - 0.2 e^{-1.18} = 0.9385 there (x₀ = 0.8,
    # u ≡ 1).  The saved boxes are only a schedule: with every box squeezed below 0.93 the band |x| <= 0.95 (false
    # after t = ln(0.2/0.05) = 1.39 s) is still refused, decided on the re-check's own sets
    data = json.loads(saved)
    seg = data["segments"][60]
    assert seg["t"][0] <= 1.18 and 1 - 0.2 * math.exp(-1.18) > 0.93
    for seg in data["segments"][1:]:
        seg["box"] = [[max(v, -0.93) for v in seg["box"][0]], [min(v, 0.93) for v in seg["box"][1]]]
    check = recheck_flowpipe(json.dumps(data), SYSTEM, START, _band(0.95), inputs=INPUTS)
    assert not check.passed and check.failure.startswith("requirement"), check.failure
    # the true band |x| <= 1.05 still holds and is re-checked with the clean flowpipe's margin
    clean = recheck_flowpipe(saved, SYSTEM, START, _band(1.05), inputs=INPUTS)
    squeezed = recheck_flowpipe(json.dumps(data), SYSTEM, START, _band(1.05), inputs=INPUTS)
    assert squeezed.passed and squeezed.margin == clean.margin


def test_dropped_input_bounds_are_refused(saved):
    data = json.loads(saved)
    del data["inputs"]
    check = recheck_flowpipe(json.dumps(data), SYSTEM, START, _band(1.05), inputs=INPUTS)
    assert not check.passed and "has an input in the model but the saved flowpipe has none" in check.failure


def test_a_model_input_wider_than_the_saved_one_is_refused(saved):
    wider = {"m": ModeInput(matrix=[[1.0]], bounds=([-1.0], [1.01]))}
    check = recheck_flowpipe(saved, SYSTEM, START, _band(1.05), inputs=wider)
    assert not check.passed and "does not hold the model's" in check.failure
    other = {"m": ModeInput(matrix=[[2.0]], bounds=([-1.0], [1.0]))}
    check = recheck_flowpipe(saved, SYSTEM, START, _band(1.05), inputs=other)
    assert not check.passed and "matrix is not the model's" in check.failure


def test_a_widened_input_in_the_json_alone_does_not_help():
    # a flowpipe computed with u in [-1, 1] but whose JSON claims u in [-1, 1.5]: the re-check uses the model's
    # U = [-1, 1.5] (the JSON covers it): with u ≡ 1.5, x(t) = 1.5 - 0.7 e^{-t} exceeds 1.05 after t = 0.44 s, and
    # the re-check's own sets (for the model's U) refuse the band, whatever the saved segments say
    data = json.loads(reach(SYSTEM, START, horizon=0.5, time_step=STEP, inputs=INPUTS).to_json())
    data["inputs"]["m"]["high"] = [1.5]
    wide = {"m": ModeInput(matrix=[[1.0]], bounds=([-1.0], [1.5]))}
    check = recheck_flowpipe(json.dumps(data), SYSTEM, START, _band(1.05, 0.5), inputs=wide)
    assert not check.passed and check.failure.startswith("requirement")
    assert recheck_flowpipe(json.dumps(data), SYSTEM, START, _band(1.05, 0.5), inputs=INPUTS).passed


def test_bad_model_inputs_are_named():
    with pytest.raises(ParameterError) as err:
        recheck_flowpipe("{}", SYSTEM, START, _band(1.05), inputs={"m": ModeInput(matrix=[[1.0, 2.0]],
                                                                                  bounds=([0.0], [1.0]))})
    assert "inputs" in str(err.value)


def test_a_zonotope_input_is_saved_and_rechecked_as_its_hull():
    import numpy as np

    from analysis.reach import Zonotope

    u = Zonotope(center=np.array([0.0]), generators=np.array([[0.5, 0.5]]))  # [-1, 1]
    inputs = {"m": ModeInput(matrix=[[1.0]], bounds=u)}
    data = reach(SYSTEM, START, horizon=0.5, time_step=STEP, inputs=inputs).to_json()
    saved_u = json.loads(data)["inputs"]["m"]
    assert saved_u["low"][0] <= -1.0 and saved_u["high"][0] >= 1.0 and saved_u["high"][0] - 1.0 < 1e-12
    assert recheck_flowpipe(data, SYSTEM, START, _band(1.05, 0.5), inputs=inputs).passed


def test_a_nonlinear_mode_with_an_input_is_never_rechecked():
    # x' = -x + x²/10 (a smooth, nonlinear mode): the engine refuses an input there, and a saved flowpipe claiming
    # one is not re-checked with it (the re-check takes inputs in affine modes only): it fails and says why
    quadratic = HybridSystem(automaton=HybridAutomaton(name="quadratic", modes=(Mode(name="m"),), transitions=(),
                                                   variables=("x",), initial_mode="m"),
                         state_names=("x",), flows={"m": flow_map(-X.x + 0.1 * X.x * X.x)})
    with pytest.raises(ParameterError) as err:
        reach(quadratic, START, horizon=0.2, time_step=STEP, inputs=INPUTS)
    assert "inputs" in str(err.value)
    data = json.loads(reach(quadratic, START, horizon=0.2, time_step=STEP).to_json())
    # x' = -x(1 - x/10): |x| decreases from |x₀| <= 0.8, so the input-free flowpipe is re-checked (the failure
    # below is the input's)
    assert recheck_flowpipe(json.dumps(data), quadratic, START, _band(1.05, 0.2)).passed
    data["inputs"] = {"m": {"matrix": [[1.0]], "low": [-1.0], "high": [1.0]}}
    check = recheck_flowpipe(json.dumps(data), quadratic, START, _band(1.05, 0.2), inputs=INPUTS)
    assert not check.passed and "nonlinear flow" in check.failure and "'m'" in check.failure
