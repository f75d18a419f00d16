"""The re-check on its own sets (analysis.reach.recheck_own and its interval arithmetic) and the face deadlock check.

Yardsticks: ``scipy.linalg.expm`` for ``e^{Aδ}`` and the solutions of linear flows; exact rationals for mapped points;
closed forms for the two tanks (the total volume ``x1 + x2`` is constant: the inflow 1 always goes to one tank and the
outflows sum to 1) and for the face checks (a box against a guard, by hand).
"""

from __future__ import annotations

import os
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from analysis.reach.deadlock import face_uncovered
from analysis.reach.model import affine_model
from analysis.reach.recheck_interval import ExpEnclosure
from analysis.reach.recheck_sets import FZ, tube
from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.verify.verdicts import verify
from analysis.verify.verification import Parameter
from hybrid import HybridAutomaton, Mode, Transition
from hybrid.symbolic import coordinates, flow_map
from hybrid.system import HybridSystem

HEAVY = bool(os.environ.get("VISNAV_REACH_HEAVY"))
VISNAV = Path(__file__).resolve().parents[2] / "data" / "spaceex" / "visnav"


def _rational(a: np.ndarray) -> list[list[Fraction]]:
    return [[Fraction(float(v)) for v in row] for row in np.atleast_2d(a)]


def test_the_exponential_enclosure_holds_scipys():
    rng = np.random.default_rng(7)
    for _ in range(5):
        a = rng.normal(size=(4, 4))
        c = rng.normal(size=4)
        step = 0.05
        enc = ExpEnclosure(_rational(a), [Fraction(float(v)) for v in c], step)
        aug = np.zeros((5, 5))
        aug[:4, :4], aug[:4, 4] = a, c
        ref = expm(aug * step)
        # scipy's expm is accurate to ~1e-15 here; the enclosure must hold it with its radius (plus that accuracy)
        assert np.all(np.abs(ref[:4, :4] - enc.phi[0]) <= enc.phi[1] + 1e-14)
        assert np.all(np.abs(ref[:4, 4] - enc.shift[0]) <= enc.shift[1] + 1e-14)
        assert np.max(enc.phi[1]) < 1e-12  # and it is tight


def test_mapped_points_stay_in_the_mapped_set_exactly():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(3, 3)) * 0.3
    enc = ExpEnclosure(_rational(a), [Fraction(1, 3)] * 3, 0.1)
    z = FZ(center=rng.normal(size=3), gens=rng.normal(size=(3, 4)), err=np.full(3, 1e-9))
    image = z.mapped(enc.phi, enc.shift)
    # a point with the same weights, mapped by any matrix of the enclosure: exactly inside (rationals)
    for _ in range(50):
        xi = rng.uniform(-1, 1, size=4)
        eps = rng.uniform(-1e-9, 1e-9, size=3)
        pick = enc.phi[0] + enc.phi[1] * rng.uniform(-1, 1, size=(3, 3))
        point = [sum(Fraction(float(pick[i, k])) * (Fraction(float(z.center[k])) + sum(
            Fraction(float(z.gens[k, j])) * Fraction(float(xi[j])) for j in range(4)) + Fraction(float(eps[k])))
            for k in range(3)) + Fraction(float(enc.shift[0][i])) for i in range(3)]
        model = [Fraction(float(image.center[i])) + sum(Fraction(float(image.gens[i, j])) * Fraction(float(xi[j]))
                                                        for j in range(4)) for i in range(3)]
        assert all(abs(p - m) <= Fraction(float(image.err[i])) for i, (p, m) in enumerate(zip(point, model)))


def test_the_tube_holds_the_solutions_between_the_steps():
    # a rotation with a drift: x' = -y + 0.5, y' = x; solutions by expm at 41 times inside one step
    a = np.array([[0.0, -1.0], [1.0, 0.0]])
    c = np.array([0.5, 0.0])
    step = 0.2
    enc = ExpEnclosure(_rational(a), [Fraction(0.5), Fraction(0)], step)
    z0 = FZ.of_box(np.array([0.9, -0.1]), np.array([1.1, 0.1]))
    piece = tube(z0, z0.mapped(enc.phi, enc.shift), enc)
    lo, hi = piece.hull()
    aug = np.zeros((3, 3))
    aug[:2, :2], aug[:2, 2] = a, c
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(20, 2))
    spread = np.abs(directions @ piece.gens).sum(axis=1) + np.abs(directions) @ piece.err
    for start in rng.uniform([0.9, -0.1], [1.1, 0.1], size=(30, 2)):
        for t in np.linspace(0.0, step, 41):
            x = (expm(aug * t) @ np.append(start, 1.0))[:2]
            assert np.all(x >= lo - 1e-12) and np.all(x <= hi + 1e-12)
            assert np.all(directions @ x <= directions @ piece.center + spread + 1e-12)
    # the tube is tight: its box is within 2·δ²/2·|A|²|x| of the exact sweep's
    assert np.max(hi - lo) < 0.2 + 2 * 0.25 + 0.05


def _face_model(rate: float) -> object:
    v = coordinates("x", "y")
    auto = HybridAutomaton(name="face", modes=(Mode(name="m", invariant=v.x <= 1.0),),
                           transitions=(Transition(name="out", source="m", target="m",
                                                   guard=(v.x >= 1.0) & (v.y >= 0.0)),),
                           variables=("x", "y"), initial_mode="m")
    return affine_model(HybridSystem(automaton=auto, state_names=("x", "y"), flows={"m": flow_map(rate, 0.0)}))


def test_the_face_check_looks_only_at_the_reached_part_of_the_face():
    model = _face_model(1.0)
    half = [(Fraction(0), Fraction(1)), (Fraction(1, 2), Fraction(1))]  # reaches x = 1 with y in [0.5, 1]: guarded
    both = [(Fraction(0), Fraction(1)), (Fraction(-1, 2), Fraction(1))]  # y in [-0.5, 0) at x = 1: no guard
    below = [(Fraction(0), Fraction(9, 10)), (Fraction(-1), Fraction(1))]  # never at the face
    assert face_uncovered(model, "m", [(half, None)]) is None
    assert face_uncovered(model, "m", [(below, None)]) is None
    why = face_uncovered(model, "m", [(half, None), (both, None)])
    assert why is not None and "lie in no guard" in why and "-0.5" in why
    # the flow x' = -1 points inside at the face: no state can leave there, nothing to cover
    assert face_uncovered(_face_model(-1.0), "m", [(both, None)]) is None


def _two_tanks_problem():
    from hybrid.examples import water_tanks

    model = water_tanks(inflow=1.0, outflow1=0.5, outflow2=0.5, x1_0=1.0, x2_0=1.0)
    return hybrid_problem(
        name="two tanks", system=model.system, horizon=10.0,
        initial={"x1": Parameter(name="x1_0", low=0.9, high=1.1), "x2": Parameter(name="x2_0", low=0.9, high=1.1)},
        requirements=(Requirement(name="volume", formula="always[0, 10] (x1 + x2 <= 2.25 and x1 >= -0.05 and "
                                                          "x2 >= -0.05)"),
                      Requirement(name="planted", formula="always[0, 10] (x1 + x2 <= 2.19)")),
        reach_options={"time_step": 0.01, "max_jumps": 20})


def test_two_tanks_are_proven_through_verify_with_the_recheck():
    problem = _two_tanks_problem()
    start = time.perf_counter()
    result = verify(problem, budget=8, seed=0)
    took = time.perf_counter() - start
    volume = result.requirement("volume")
    assert volume.verdict == "proven" and volume.proof.rechecked, volume.proof.evidence
    assert volume.decided_by.startswith("reachability (re-checked)")
    # the volume x1 + x2 stays in [1.8, 2.2] (closed form): slack 0.05 for x1 + x2 <= 2.25, the margins below it
    producer = volume.proof.margin
    own = float(volume.proof.evidence.split("exact margin ")[1].split()[0].rstrip(")|"))
    assert 0.04 < producer <= 0.05 and 0.04 < own <= 0.05
    # a planted bound inside the true reach set (2.19 < 2.2) is never proven
    planted = result.requirement("planted")
    assert planted.verdict != "proven" and not planted.proof.rechecked
    assert took < 120, took


@pytest.mark.skipif(not HEAVY, reason="about 25 s a case: set VISNAV_REACH_HEAVY=1 (docs/reachability.md has the "
                                      "figures)")
@pytest.mark.parametrize("name", ["SRNA01", "SRA01"])
def test_the_spacecraft_is_proven_through_verify_with_the_recheck(name):
    from analysis.spaceex import spaceex_problem

    options = {"time_step": 0.5, "max_jumps": 5, "mode_time_steps": {"P3": 0.02}}
    if name != "SRNA01":
        options["mode_time_steps"]["passive"] = 0.5
        options["jump_cluster"] = 25
    problem = spaceex_problem(VISNAV / f"{name}.xml", VISNAV / f"{name}.cfg", reach_options=options)
    proof = problem.proofs["safe"]()
    assert proof.proven and proof.rechecked, proof.evidence
    own = float(proof.evidence.split("exact margin ")[1].split()[0])
    # the margin is in the units of the atoms (speed, line of sight); both margins are positive lower bounds
    assert proof.margin > 0 and own > 0


def test_the_spacecraft_steps_are_chosen_from_its_matrices():
    from analysis.reach.autostep import AUTO_NORM_STEPS, auto_options, mode_norms
    from analysis.reach.verdict import MAX_SEGMENTS
    from analysis.spaceex import spaceex_problem

    proof = spaceex_problem(VISNAV / "SRNA01.xml", VISNAV / "SRNA01.cfg").proofs["safe"]
    model = affine_model(proof.system)
    norms = mode_norms(model)
    for mode, norm in norms.items():  # the row sums of the XML's matrices (numpy), plus the constant's column
        a = np.array([[float(v) for v in row] for row in model.modes[mode].a])
        assert norm == pytest.approx(float(np.max(np.sum(np.abs(a), axis=1))) + 1, rel=1e-12)
    first = auto_options(model, 300.0, 0.3, {}, AUTO_NORM_STEPS[0], MAX_SEGMENTS)
    assert set(first["mode_time_steps"]) == {"P3"}  # only the fast attempt mode is refused at 0.3 min
    second = auto_options(model, 300.0, 0.3, {}, AUTO_NORM_STEPS[1], MAX_SEGMENTS)
    for mode, step in second["mode_time_steps"].items():
        assert step * norms[mode] <= AUTO_NORM_STEPS[1] * (1 + 1e-12)
    # a step given by the caller wins
    given = auto_options(model, 300.0, 0.3, {"mode_time_steps": {"P3": 0.02}}, AUTO_NORM_STEPS[1], MAX_SEGMENTS)
    assert given["mode_time_steps"]["P3"] == 0.02


@pytest.mark.skipif(not HEAVY, reason="about 75 s: set VISNAV_REACH_HEAVY=1 (docs/reachability.md has the figures)")
def test_the_spacecraft_is_proven_with_default_options():
    from analysis.spaceex import spaceex_problem

    proof = spaceex_problem(VISNAV / "SRNA01.xml", VISNAV / "SRNA01.cfg").proofs["safe"]()
    assert proof.proven and proof.rechecked, proof.evidence
    assert "steps chosen from the dynamics" in proof.evidence
