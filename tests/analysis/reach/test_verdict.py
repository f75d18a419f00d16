"""Verdicts from reachability: the fragment, proofs with margins, the independent re-check, the problem wiring.

Yardsticks are closed forms computed here, not by the engine: the thermostat reaches exactly its
thresholds 19 and 21 from ``T0 ∈ [19.5, 20.5]`` (``T(t) = a + (T0 − a) e^{−rt}`` meets them within
the window), so a band ``[19 − m, 21 + m]`` has the true slack ``m``; the switched pair has the
common quadratic Lyapunov function ``|x|²`` (``A + Aᵀ ≺ 0`` in both modes, checked with numpy), so
``|x(t)| <= max |x0|`` over the box.
"""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from analysis.verify.problems import hybrid_problem
from analysis.reach import reach
from analysis.reach.fragment import Conj, LinearAtom, NotInFragment, atoms, safety_fragment
from analysis.reach.recheck import recheck_flowpipe
from analysis.reach.verdict import decide, reach_proof
from analysis.verify.requirements import Requirement
from analysis.stl.syntax import parse_tree
from analysis.verify.verdicts import verify
from analysis.verify.verification import Parameter, ProblemError
from hybrid import HybridAutomaton, Mode, Transition
from hybrid.examples import thermostat
from hybrid.symbolic import coordinates, flow_map
from hybrid.system import HybridSystem

ROOM = thermostat().system
BAND = "always[0, 30] (T >= 18.95 and T <= 21.05)"
A1 = np.array([[-1.0, 0.5], [-0.5, -1.0]])
A2 = np.array([[-2.0, 1.0], [0.3, -1.0]])


def _pair() -> HybridSystem:
    v = coordinates("x", "y")
    automaton = HybridAutomaton(
        name="pair", modes=(Mode(name="a", invariant=v.x <= 0.1), Mode(name="b", invariant=v.x >= -0.1)),
        transitions=(Transition(name="ab", source="a", target="b", guard=v.x >= 0.1),
                     Transition(name="ba", source="b", target="a", guard=v.x <= -0.1)),
        variables=("x", "y"), initial_mode="a")
    X = coordinates("x", "y")
    return HybridSystem(automaton=automaton, state_names=("x", "y"), flows={
        "a": flow_map(A1[0, 0] * X.x + A1[0, 1] * X.y, A1[1, 0] * X.x + A1[1, 1] * X.y),
        "b": flow_map(A2[0, 0] * X.x + A2[0, 1] * X.y, A2[1, 0] * X.x + A2[1, 1] * X.y)})


def _fragment(text: str, names=("T",)):
    return safety_fragment(parse_tree(text), names)


def test_fragment_reads_affine_atoms_exactly_and_refuses_the_rest():
    f = _fragment("always[0, 5] (T >= 18.5 and not (2 * T - 1 > T + 0.1) and mode != 'on')")
    lin = [a for a in atoms(f.body) if isinstance(a, LinearAtom)]
    assert (f.start, f.end) == (0.0, 5.0) and isinstance(f.body, Conj)
    # T >= 18.5  ->  -T <= -18.5 ;  not (2T - 1 > T + 0.1)  ->  T <= 1.1 (exact: 0.1 and 1 as rationals)
    assert (lin[0].coefficients, lin[0].bound, lin[0].strict) == ((-1,), -18.5, False)
    from fractions import Fraction
    assert (lin[1].coefficients, lin[1].bound, lin[1].strict) == ((1,), Fraction(1) + Fraction(0.1), False)
    for text, why in [("eventually[0, 5] T > 1", "not always"), ("always[1, 5] T > 1", "does not start at 0"),
                      ("always[0, 5] T * T <= 500", "not affine"), ("always[0, 5] abs(T - 20) + T <= 1", "abs"),
                      ("always[0, 5] time <= 5", "not a state"),
                      ("always[0, 5] (T > 1 -> eventually[0, 1] T > 2)", "eventually")]:
        with pytest.raises(NotInFragment, match=why):
            _fragment(text)


def test_thermostat_band_is_proven_with_the_closed_form_margin_and_rechecked():
    start = time.perf_counter()
    proof, decision = reach_proof(ROOM, _fragment(BAND), {"T": (19.5, 20.5)})
    took = time.perf_counter() - start
    assert proof.holds and proof.rechecked and proof.proven
    # the true slack is 0.05 (T reaches 19 and 21 exactly); a sound margin is below it, and close
    # (the flowpipe's excess is its step bloat, ~1e-4 at δ = 0.03 s)
    assert 0.049 < decision.margin <= 0.05
    assert "re-checked from the saved flowpipe" in proof.evidence and "exact margin" in proof.evidence
    assert decision.result.status == "complete" and len(decision.result.jumps) >= 10
    assert took < 60, took


def test_planted_band_just_inside_the_true_one_is_not_proven_and_is_falsified():
    text = "always[0, 30] (T >= 19.01 and T <= 21.05)"  # T reaches 19 < 19.01: false
    proof, decision = reach_proof(ROOM, _fragment(text), {"T": (19.5, 20.5)})
    assert not proof.holds and not proof.rechecked and decision.margin < 0
    assert "does not prove it" in proof.evidence


def test_verify_proves_the_band_and_keeps_the_violated_requirement_falsified():
    problem = hybrid_problem(
        name="room", system=ROOM, initial={"T": Parameter(name="T0", low=19.5, high=20.5)}, horizon=30.0,
        requirements=(Requirement(name="band", formula=BAND),
                      Requirement(name="tight", formula="always[0, 30] (T >= 19.01)"),
                      Requirement(name="warm", formula="eventually[0, 30] (T >= 20.9)")))
    assert set(problem.proofs) == {"band", "tight"}  # "warm" is not in the fragment: no proof
    start = time.perf_counter()
    result = verify(problem, budget=30, seed=1)
    took = time.perf_counter() - start
    verdicts = {v.name: v for v in result.requirements}
    assert verdicts["band"].verdict == "proven" and verdicts["band"].proof.method.startswith("reachability")
    assert verdicts["tight"].verdict == "falsified" and not verdicts["tight"].proof.holds
    assert verdicts["warm"].verdict in ("not_falsified", "falsified") and verdicts["warm"].proof is None
    assert took < 120, took


def test_switched_linear_pair_is_proven_through_a_jump():
    for a in (A1, A2):  # the common quadratic Lyapunov function |x|^2: A + A^T negative definite
        assert np.max(np.linalg.eigvalsh(a + a.T)) < 0
    box = {"x": (-0.5, -0.3), "y": (2.0, 2.5)}
    radius = math.hypot(0.5, 2.5)  # max |x0| over the box: |x(t)| <= 2.5495
    bound = 2.6
    text = (f"always[0, 5] ((mode == 'b' -> x >= -0.11) and x <= {bound} and x >= -{bound} "
            f"and y <= {bound} and y >= -{bound} and x + y <= 2.25)")
    assert radius < bound
    start = time.perf_counter()
    proof, decision = reach_proof(_pair(), _fragment(text, ("x", "y")), box)
    took = time.perf_counter() - start
    assert proof.proven, proof.evidence
    assert len(decision.result.jumps) >= 1  # the flowpipe crosses the switching surface
    # x + y = 2.2 at the corner (-0.3, 2.5) at t = 0: the slack of the diagonal atom x + y <= 2.25 is at most
    # 0.05; the re-check decides it on its own zonotopes as well as boxes (its exact margin is printed)
    assert 0.04 < decision.margin <= 0.05 + 1e-12
    assert "exact margin 0.04" in proof.evidence
    assert took < 60, took


def test_a_tampered_flowpipe_fails_the_recheck():
    fragment = _fragment(BAND)
    proof, decision = reach_proof(ROOM, fragment, {"T": (19.5, 20.5)})
    assert proof.proven
    clean = json.loads(decision.result.to_json())
    assert recheck_flowpipe(clean, ROOM, {"T": (19.5, 20.5)}, fragment).passed

    # the saved boxes are a schedule, not a containment target: a shrunk segment box changes nothing when the
    # requirement holds on the true reach set (the re-check decides it on its own sets, the same margin)
    shrunk = json.loads(decision.result.to_json())
    lo, hi = shrunk["segments"][10]["box"]
    shrunk["segments"][10]["box"] = [lo, [hi[0] - 0.3 * (hi[0] - lo[0])]]
    check = recheck_flowpipe(shrunk, ROOM, {"T": (19.5, 20.5)}, fragment)
    assert check.passed and check.margin == recheck_flowpipe(clean, ROOM, {"T": (19.5, 20.5)}, fragment).margin

    jumped = json.loads(decision.result.to_json())
    jumped["jumps"][0]["before"] = [[21.0], [21.0 - 1e-9]]  # an empty box: malformed
    check = recheck_flowpipe(jumped, ROOM, {"T": (19.5, 20.5)}, fragment)
    assert not check.passed and check.failure.startswith("jumps") and "malformed or empty" in check.failure

    reset = json.loads(decision.result.to_json())  # a flowpipe of another reset (T+ = T - 1): refused
    reset["jumps"][0]["after"] = [[v - 1.0 for v in reset["jumps"][0]["before"][0]],
                                  [v - 1.0 for v in reset["jumps"][0]["before"][1]]]
    check = recheck_flowpipe(reset, ROOM, {"T": (19.5, 20.5)}, fragment)
    assert not check.passed and "reset image" in check.failure

    capped = json.loads(decision.result.to_json())
    capped["terminations"][-1]["reason"] = "max_jumps"
    check = recheck_flowpipe(capped, ROOM, {"T": (19.5, 20.5)}, fragment)
    assert not check.passed and check.failure.startswith("ends")

    wider = recheck_flowpipe(clean, ROOM, {"T": (19.4, 20.5)}, fragment)  # not the box the flowpipe started from
    assert not wider.passed and "chaining" in wider.failure


def test_corrupted_saved_boxes_cannot_fool_the_recheck():
    # the room's temperature reaches the switching level 21 (closed form: T0 <= 20.5 heats up to 21 then cools),
    # so "T <= 20.9" is false on the true reach set.  Every saved box (segments and jumps) is squeezed below
    # 20.9 and the producer's claim is forged: the re-check decides on its own sets and refuses
    fragment = _fragment(BAND)
    _, decision = reach_proof(ROOM, fragment, {"T": (19.5, 20.5)})
    false = _fragment("always[0, 30] (T <= 20.9)")
    forged = json.loads(decision.result.to_json())
    for seg in forged["segments"]:
        (lo,), (hi,) = seg["box"]
        seg["box"] = [[min(lo, 20.8)], [min(hi, 20.85)]]
    for jump in forged["jumps"]:
        for key in ("before", "after"):
            (lo,), (hi,) = jump[key]
            jump[key] = [[min(lo, 20.8)], [min(hi, 20.85)]]
    check = recheck_flowpipe(forged, ROOM, {"T": (19.5, 20.5)}, false)
    assert not check.passed and check.failure.startswith("requirement"), check.failure
    # and with the true requirement the forged boxes change nothing: the re-check's own margin (<= the closed
    # form's 0.05) is that of the clean flowpipe
    clean = recheck_flowpipe(decision.result.to_json(), ROOM, {"T": (19.5, 20.5)}, fragment)
    assert clean.passed and 0.049 < clean.margin <= 0.05
    squeezed = json.loads(decision.result.to_json())
    for seg in squeezed["segments"][1:]:  # the first entry must hold the initial box (the producer's claim)
        (lo,), (hi,) = seg["box"]
        mid = (lo + hi) / 2
        seg["box"] = [[mid], [mid]]
    again = recheck_flowpipe(squeezed, ROOM, {"T": (19.5, 20.5)}, fragment)
    assert again.passed and again.margin == clean.margin


def test_a_flowpipe_of_another_flow_is_decided_for_the_given_model():
    # a flowpipe of the slow room (rate 0.05) proves T <= 20.75 over 3 s from T0 in [19.5, 20.5]; the fast room
    # (rate 0.2) cools from 19.5 to 19 in 0.26 s and heats at 0.2·(30 − 19) = 2.2 °C/s, so it exceeds 20.75 before
    # t = 1.2 s: re-checked against the fast model, the slow flowpipe's JSON is refused (its sets are not used)
    slow, fast = thermostat(rate=0.05).system, thermostat(rate=0.2).system
    fragment = _fragment("always[0, 3] (T <= 20.75)")
    saved = reach(slow, {"T": (19.5, 20.5)}, horizon=3.0, time_step=0.003, max_jumps=20).to_json()
    assert recheck_flowpipe(saved, slow, {"T": (19.5, 20.5)}, fragment).passed
    check = recheck_flowpipe(saved, fast, {"T": (19.5, 20.5)}, fragment)
    assert not check.passed and check.failure.startswith("requirement") and "mode 'on'" in check.failure


def test_the_recheck_imports_no_set_code_of_the_engine(reach_imports):
    seen = reach_imports("recheck")
    # smooth: the reading of nonlinear flows (no set code); recheck_smooth: the re-check's own nonlinear step;
    # recheck_inputs: the re-check's own bound of bounded inputs; recheck_schedule, recheck_own, recheck_sets,
    # recheck_interval: the own-set re-check of affine flowpipes; recheck_modal: its own modal error bound;
    # deadlock: the exact face check (boxes); interval_tape: the re-check's own vectorised interval evaluation
    # (analysis.interval's arithmetic, no code of the producer); recheck_jumps: the own zonotope jump sets (exact
    # rationals, not analysis.reach.jumpsets); recheck_carry: its own carried input sum (not analysis.reach.input_sum)
    assert seen == {"recheck", "recheck_inputs", "fragment", "model", "affine", "smooth", "recheck_smooth",
                    "recheck_schedule", "recheck_own", "recheck_sets", "recheck_interval", "recheck_modal",
                    "deadlock", "interval_tape", "recheck_jumps", "recheck_carry"}, seen


def test_inconclusive_or_capped_flowpipes_prove_nothing():
    x = coordinates("x")
    grow = HybridSystem(automaton=HybridAutomaton(name="g", modes=(Mode(name="m"),), transitions=(), variables=("x",)),
                        state_names=("x",), flows={"m": flow_map(x.x)})
    # x' = x from [0, 1]: x(20) <= e^20 ≈ 4.9e8 < 1e12, true, but the flowpipe blows up (size limit 1e6)
    proof, decision = reach_proof(grow, _fragment("always[0, 20] x <= 1e12", ("x",)), {"x": (0.0, 1.0)})
    assert not proof.holds and "inconclusive" in decision.reason
    capped, _ = reach_proof(ROOM, _fragment(BAND), {"T": (19.5, 20.5)}, max_jumps=2)
    assert not capped.holds and "jump bound" in capped.evidence
    assert decide(_.result, _fragment(BAND))[0] is False


def test_non_symbolic_models_and_builders():
    automaton = HybridAutomaton(name="s", modes=(Mode(name="m"),), transitions=(), variables=("x",))
    plain = HybridSystem(automaton=automaton, state_names=("x",), flows={"m": lambda t, x, m: (-x[0],)})
    req = (Requirement(name="r", formula="always[0, 1] x <= 2"),)
    initial = {"x": Parameter(name="x0", low=0.0, high=1.0)}
    with pytest.raises(ProblemError, match="reachability needs a symbolic model") as err:
        hybrid_problem(name="p", system=plain, initial=initial, horizon=1.0, requirements=req, reach=True)
    assert "flow_map" in str(err.value) and "falsification still runs" in str(err.value)
    auto = hybrid_problem(name="p", system=plain, initial=initial, horizon=1.0, requirements=req)
    assert dict(auto.proofs) == {}
    assert verify(auto, budget=5, seed=0).requirements[0].verdict == "not_falsified"
    with pytest.raises(ProblemError, match="reach"):
        hybrid_problem(name="p", system=plain, initial=initial, horizon=1.0, requirements=req, reach="yes")

    rate = Parameter(name="rate", low=0.05, high=0.15)
    def build(p):
        return thermostat(rate=p.get("rate", 0.1)).system

    built = hybrid_problem(name="b", system=build, initial={"T": Parameter(name="T0", low=19.5, high=20.5)},
                           parameters=(rate,), horizon=30.0, requirements=(Requirement(name="band", formula=BAND),))
    # thermostat() checks its rate as a number, so it cannot be built with symbolic parameters: "auto" says why
    # no proof (a builder that takes them is read with its parameters as constant states: test_parameters.py)
    proof = built.proofs["band"]()
    assert not proof.holds and not proof.rechecked and "does not take symbolic values" in proof.evidence
    assert "builds a different system per parameter value" in proof.evidence


def test_a_deadlock_at_the_invariants_end_proves_nothing():
    from hybrid.examples import deadlock

    # x' = 1, invariant x <= 1 and no transition: the executor's run ends early (deadlock) at t = 1
    proof, decision = reach_proof(deadlock().system, _fragment("always[0, 10] (x < 5)", ("x",)), {"x": (0.0, 0.0)})
    assert not proof.holds and "deadlock" in decision.reason


def test_abs_atoms_are_two_affine_atoms():
    # |T - 20| <= 1.05 is the band [18.95, 21.05]: proven like BAND, the same closed-form slack 0.05
    proof, decision = reach_proof(ROOM, _fragment("always[0, 30] abs(T - 20) <= 1.05"), {"T": (19.5, 20.5)})
    assert proof.proven and 0.049 < decision.margin <= 0.05
    far = _fragment("always[0, 30] not (abs(T - 20) < 1.0 - 1e-9 or mode == 'on')")  # |T-20| >= 1 in off: false
    assert not reach_proof(ROOM, far, {"T": (19.5, 20.5)})[0].holds


def test_a_failed_recheck_keeps_the_verdict_from_proven(monkeypatch):
    import analysis.reach.verdict as verdict_module
    from analysis.reach.recheck import RecheckResult

    failed = RecheckResult(passed=False, failure="segments: planted failure", segments=0, jumps=0, margin=None)
    monkeypatch.setattr(verdict_module, "recheck_flowpipe", lambda *a, **k: failed)
    proof, _ = reach_proof(ROOM, _fragment(BAND), {"T": (19.5, 20.5)})
    assert proof.holds and not proof.rechecked and not proof.proven
    assert "re-check FAILED (segments: planted failure)" in proof.evidence
    problem = hybrid_problem(name="room", system=ROOM, initial={"T": Parameter(name="T0", low=19.5, high=20.5)},
                             horizon=30.0, requirements=(Requirement(name="band", formula=BAND),))
    assert verify(problem, budget=5, seed=0).requirements[0].verdict == "not_falsified"


def test_bad_reach_options_are_named():
    initial = {"T": Parameter(name="T0", low=19.5, high=20.5)}
    req = (Requirement(name="band", formula=BAND),)
    for options, name in [({"time_step": -1.0}, "time_step"), ({"time_step": math.nan}, "time_step"),
                          ({"max_jumps": 1.5}, "max_jumps"), ({"step": 0.1}, "reach_options")]:
        with pytest.raises(ProblemError, match=name):
            hybrid_problem(name="room", system=ROOM, initial=initial, horizon=30.0, requirements=req,
                           reach_options=options)
    off = hybrid_problem(name="room", system=ROOM, initial=initial, horizon=30.0, requirements=req, reach=False)
    assert dict(off.proofs) == {}


def test_the_recheck_refuses_bad_input_by_name():
    fragment = _fragment(BAND)
    from hybrid.errors import ParameterError

    with pytest.raises(ParameterError, match="initial"):
        recheck_flowpipe("{}", ROOM, {"x": (0.0, 1.0)}, fragment)
    for text in ("not json", "{}", json.dumps({"segments": [], "jumps": [], "terminations": []})):
        check = recheck_flowpipe(text, ROOM, {"T": (19.5, 20.5)}, fragment)
        assert not check.passed and check.failure


def test_a_deadlock_of_some_states_before_the_horizon_proves_nothing():
    from hybrid.examples import deadlock

    # x0 in [0, 0.9]: the states from 0.9 reach x = 1 at t = 0.1 and deadlock there while the others
    # still flow; a window of 0.5 s ends before the flowpipe leaves the invariant (termination "horizon")
    proof, decision = reach_proof(deadlock().system, _fragment("always[0, 0.5] (x < 5)", ("x",)), {"x": (0.0, 0.9)})
    assert {t.reason for t in decision.result.terminations} == {"horizon"}
    assert not proof.holds and "deadlock" in decision.reason
    # far from the face, nothing can deadlock: proven
    far, _ = reach_proof(deadlock().system, _fragment("always[0, 0.5] (x < 5)", ("x",)), {"x": (0.0, 0.4)})
    assert far.proven


def test_a_face_reached_only_at_the_horizon_is_no_deadlock():
    from hybrid.examples import deadlock

    # x' = 1 (x is a clock), invariant x <= 1, no enabled guard: from x0 = 0 the face x = 1 is reached at
    # exactly t = 1. Over the window [0, 1] the run is complete (it ends at the horizon): proven, re-checked
    at_end, decision = reach_proof(deadlock().system, _fragment("always[0, 1] (x < 5)", ("x",)), {"x": (0.0, 0.0)})
    assert at_end.proven, (decision.reason, at_end.evidence)
    # the same face reached before the window's end (t = 1 < 1.5) is still a possible deadlock
    before, decision = reach_proof(deadlock().system, _fragment("always[0, 1.5] (x < 5)", ("x",)), {"x": (0.0, 0.0)})
    assert not before.holds and "deadlock" in decision.reason
    # x0 in [0, 0.1]: some runs reach x = 1 at t = 0.9 < 1, inside the window: a possible deadlock
    some, decision = reach_proof(deadlock().system, _fragment("always[0, 1] (x < 5)", ("x",)), {"x": (0.0, 0.1)})
    assert not some.holds and "deadlock" in decision.reason


def test_reached_late_is_exact_at_the_horizon():
    from fractions import Fraction as F

    from analysis.reach.model import affine_model
    from analysis.reach.deadlock import clock_offsets, reached_late
    from hybrid.examples import deadlock

    model = affine_model(deadlock().system)
    # entered at t in [0.25, ...] with x in [0, 0.5]: x − τ <= 0.5 − 0.25 = 0.25 (exact)
    offsets = clock_offsets(model, "run", [(F(0), F(1, 2))], F(1, 4))
    assert offsets == {0: F(1, 4)}
    face = [(F(1), F(1))]
    assert reached_late(face, offsets, F(3, 4))                          # x = 1 >= 3/4 + 1/4: at or after 3/4
    assert not reached_late(face, offsets, F(3, 4) + F(1, 2**60))        # a hair later horizon: maybe before
    # with an input on the clock's row it is no clock
    assert clock_offsets(model, "run", [(F(0), F(1, 2))], F(0), ([[F(1)]], [F(0)], [F(1)])) == {}


def test_a_fast_mode_gets_its_step_from_the_dynamics():
    # x' = -5000 (x - 1), ‖A_aug‖ ≈ 5001: a step of 0.001 s has ‖A‖·step ≈ 5 > 4 and used to be refused. Closed
    # form x(t) = 1 − (1 − x0) e^{−5000 t} <= 1: the true slack of x <= 1.01 is 0.01
    v = coordinates("x")
    automaton = HybridAutomaton(name="fast", modes=(Mode(name="run", invariant=v.x <= 10.0),), transitions=(),
                                variables=("x",), initial_mode="run")
    system = HybridSystem(automaton=automaton, state_names=("x",), flows={"run": flow_map(-5000.0 * v.x + 5000.0)})
    fragment = _fragment("always[0, 0.2] (x <= 1.01)", ("x",))
    proof, decision = reach_proof(system, fragment, {"x": (0.0, 0.5)})
    # the first choice (‖A‖·step <= 3.9) is too coarse for the first segment; the second (<= 0.4) proves it
    assert proof.proven, proof.evidence
    assert "steps chosen from the dynamics, ‖A‖·step <= 0.4" in proof.evidence
    assert 0 < proof.margin <= 0.01
    # a step given by the user: only the first choice (the run is no longer refused), which proves nothing here
    coarse, _ = reach_proof(system, fragment, {"x": (0.0, 0.5)}, time_step=0.001)
    assert not coarse.holds and "‖A‖·step <= 3.9" in coarse.evidence
