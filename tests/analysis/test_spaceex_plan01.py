"""ARCH-COMP AFF PLAN01-UNB50 (published safe): e1, e2, e3 >= -50 m for all t >= 0, by the relaxation's induction.

``specs/PLAN01-UNB50.cfg`` has ``time-horizon = -1`` (SpaceEx's unbounded horizon).  Yardstick of ``W`` and of the
property (no code of the producer or of the re-check): seeded runs of JuliaReach's published platoon matrices with
random dwell times (communication 10–20 s, no communication 0–20 s) and bang-bang leader accelerations
(``aL ∈ {-9, 1}``, pieces of 0.2–3 s), integrated piece by piece exactly by ``scipy.linalg.expm`` of the augmented
matrix: every state at ``P + kT`` (the induction's instants) must lie in the proven ``W`` and every sampled gap above
−50 m, at most 50 m + the proof's margin below (expm is accurate to ~1e-13 relative here; states are O(30), so 1e-9 m is the comparison's tolerance).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from analysis.spaceex import spaceex_problem

DATA = Path(__file__).resolve().parents[1] / "data" / "spaceex" / "arch2017"
XML = DATA / "Platoon" / "SpaceEx" / "PLAN01-UNB.xml"
CFG = DATA / "specs" / "PLAN01-UNB50.cfg"
HEAVY = bool(os.environ.get("VISNAV_REACH_HEAVY"))
C = "break_pattern.communication|platoon.communication"

COMM = np.array([[0, 1, 0, 0, 0, 0, 0, 0, 0], [0, 0, -1, 0, 0, 0, 0, 0, 0],
                 [1.6050, 4.8680, -3.5754, -0.8198, 0.4270, -0.0450, -0.1942, 0.3626, -0.0946],
                 [0, 0, 0, 0, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, -1, 0, 0, 0],
                 [0.8718, 3.8140, -0.0754, 1.1936, 3.6258, -3.2396, -0.5950, 0.1294, -0.0796],
                 [0, 0, 0, 0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1, 0, 0, -1],
                 [0.7132, 3.5730, -0.0964, 0.8472, 3.2568, -0.0876, 1.2726, 3.0720, -3.1356]])
NOCOMM = COMM.copy()
NOCOMM[2, 3:] = 0.0
NOCOMM[5, [0, 1, 2, 6, 7, 8]] = 0.0


def _runs(seed: int, runs: int, cycles: int) -> tuple[np.ndarray, float]:
    """The entries into communication (states, shape (k, 9)) and the lowest sampled gap of seeded random runs."""
    rng = np.random.default_rng(seed)
    entries, lowest = [], np.inf
    for _ in range(runs):
        x = np.zeros(9)
        for _ in range(cycles):
            for a, dwell in ((COMM, rng.uniform(10.0, 20.0)), (NOCOMM, rng.uniform(0.0, 20.0))):
                left = dwell
                while left > 1e-12:
                    piece = min(left, rng.uniform(0.2, 3.0))
                    aug = np.zeros((10, 10))
                    aug[:9, :9] = a
                    aug[1, 9] = rng.choice((-9.0, 1.0))
                    for part in (piece / 4,) * 4:  # samples inside each piece
                        x = (expm(aug * part) @ np.append(x, 1.0))[:9]
                        lowest = min(lowest, x[0], x[3], x[6])
                    left -= piece
            entries.append(x.copy())
    return np.array(entries), float(lowest)


def test_plan01_unb50_is_unbounded_sampled_over_three_cycles_and_takes_the_induction():
    problem = spaceex_problem(XML, CFG)
    assert problem.horizon == 120.0  # 3 × the longest cycle (tc + tr = 40 s): the sampled part covers [0, 120] s
    assert problem.requirements[0].formula.startswith("always[0, 120.0] not ")
    assert "for all t >= 0" in problem.requirements[0].description
    assert "time-horizon < 0" in problem.description and "[0, 120] s only" in problem.description
    proof = problem.proofs["safe"]
    assert type(proof).__name__ == "CycleInductionProof" and proof.initial_mode == C


def _w(evidence: str) -> dict[str, tuple[float, float]]:
    """W from the proof's evidence (``W = e1 in [lo, hi], ...;``)."""
    text = evidence.split("W = ")[1].split(";")[0]
    return {m.group(1): (float(m.group(2)), float(m.group(3)))
            for m in re.finditer(r"(\w+) in \[([^,]+), ([^\]]+)\]", text)}


def _states_at(times: tuple[float, ...], seed: int, runs: int) -> np.ndarray:
    """States of seeded random PLAN01 runs (dwell 10–20 s in communication, 0–20 s without, bang-bang ``aL`` in
    pieces of 0.2–3 s, exact ``expm`` per piece) at the given instants, shape ``(runs * len(times), 9)``."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(runs):
        x, now, mode, left = np.zeros(9), 0.0, 0, rng.uniform(10.0, 20.0)
        for target in times:
            while now < target - 1e-12:
                piece = min(rng.uniform(0.2, 3.0), left, target - now)
                aug = np.zeros((10, 10))
                aug[:9, :9] = COMM if mode == 0 else NOCOMM
                aug[1, 9] = rng.choice((-9.0, 1.0))
                x = (expm(aug * piece) @ np.append(x, 1.0))[:9]
                now, left = now + piece, left - piece
                if left <= 1e-12:
                    mode = 1 - mode
                    left = rng.uniform(10.0, 20.0) if mode == 0 else rng.uniform(0.0, 20.0)
            out.append(x.copy())
    return np.array(out)


@pytest.mark.skipif(not HEAVY, reason="about 16 min CPU: set VISNAV_REACH_HEAVY=1 (docs/reachability.md has the figures)")
def test_plan01_unb50_is_proven_for_all_time_by_the_relaxation_and_w_holds_the_simulated_states():
    problem = spaceex_problem(XML, CFG)
    proof = problem.proofs["safe"]()
    assert proof.holds and proof.rechecked and proof.proven, proof.evidence
    assert "the clocks break_pattern.t projected out" in proof.evidence
    assert "all time t >= 0 (unbounded)" in proof.assumptions
    w = _w(proof.evidence)
    names = ("e1", "v1", "a1", "e2", "v2", "a2", "e3", "v3", "a3")
    assert set(w) == set(names)
    period = float(proof.evidence.split("T = ")[1].split(" s")[0])
    # the induction's claim, sampled: every run is in W at P + kT (P = 60 s)
    states = _states_at(tuple(60.0 + k * period for k in range(3)), seed=5, runs=24)
    for k, name in enumerate(names):
        lo, hi = w[name]
        assert np.all(states[:, k] >= lo - 1e-9) and np.all(states[:, k] <= hi + 1e-9), (name, w[name])
    # the margin bounds the true slack from below: at most 50 m + the lowest gap of simulated runs
    _, lowest = _runs(seed=3, runs=24, cycles=6)
    assert lowest > -50.0 and 0.0 < proof.margin <= lowest + 50.0
