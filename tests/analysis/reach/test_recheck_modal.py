"""The re-check's modal error bound (analysis.reach.recheck_modal) against exact rationals and scipy.

Yardsticks: the exact worst case of the error recursion ``ε_{k+1} = Φ ε_k + f_k``, ``|f_k| <= e``, which is
``Σ_{j<k} |Φ^j| e`` entrywise (each row attains it with the signs of its own row of ``Φ^j``), computed in exact
rationals from the float matrix; ``scipy.linalg.expm`` for the matrix; the closed-form circle for the oscillator.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from scipy.linalg import expm

import analysis.reach.recheck_own as recheck_own
from analysis.reach.fragment import safety_fragment
from analysis.reach.recheck_modal import modal_tracker
from analysis.reach.verdict import reach_proof
from analysis.stl.syntax import parse_tree
from hybrid import HybridAutomaton, Mode
from hybrid.symbolic import coordinates, flow_map
from hybrid.system import HybridSystem


def _exact_worst(phi: np.ndarray, e: np.ndarray, steps: int) -> list[list[Fraction]]:
    """``Σ_{j<k} |Φ^j| e`` for k = 1..steps, exact rationals (``Φ`` the float matrix read exactly)."""
    m = phi.shape[0]
    p = [[Fraction(float(v)) for v in row] for row in phi]
    ef = [Fraction(float(v)) for v in e]
    power = [[Fraction(int(i == j)) for j in range(m)] for i in range(m)]
    total = [Fraction(0)] * m
    out = []
    for _ in range(steps):
        total = [total[i] + sum(abs(power[i][j]) * ef[j] for j in range(m)) for i in range(m)]
        out.append(list(total))
        power = [[sum(power[i][l] * p[l][j] for l in range(m)) for j in range(m)] for i in range(m)]
    return out


def test_the_modal_bound_holds_the_exact_worst_case_and_does_not_wrap():
    # a lightly damped fast rotation (50 rad/s) coupled to a real mode: the basis is not orthogonal
    a = np.array([[-0.1, 50.0, 1.0], [-50.0, -0.1, 0.0], [0.0, 0.0, -2.0]])
    phi = expm(a * 0.01)
    tracker = modal_tracker(phi)
    assert tracker is not None and sorted(len(b) for b in tracker.blocks) == [1, 2]
    e = np.array([1e-15, 2e-15, 1e-15])
    worst = _exact_worst(phi, e, 150)
    r = np.zeros(len(tracker.blocks))
    box = np.zeros(3)
    for k in range(150):
        r = tracker.advance(r, e)
        box = np.abs(phi) @ box + e
        bound = tracker.box(r)
        # sound: at or above the exact worst case at every step
        assert all(Fraction(float(b)) >= w for b, w in zip(bound, worst[k])), k
    # tight: within a small factor of the exact worst case (the factor is the basis' condition and the
    # Euclidean norms of the blocks), while the box recursion has wrapped by many orders of magnitude
    ratio = max(float(b) / float(w) for b, w in zip(tracker.box(r), worst[-1]))
    assert ratio < 10.0, ratio
    assert float(np.max(box / np.array([float(w) for w in worst[-1]]))) > 1e6


def test_no_tracker_for_a_defective_matrix():
    # a Jordan block: no basis of eigenvectors; the tracker refuses (the box alone is then used)
    assert modal_tracker(np.array([[1.0, 1.0], [0.0, 1.0]])) is None


def _oscillator(omega: float) -> HybridSystem:
    v = coordinates("x", "y")
    automaton = HybridAutomaton(name="osc", modes=(Mode(name="run", invariant=v.x <= 10.0),), transitions=(),
                                variables=("x", "y"), initial_mode="run")
    return HybridSystem(automaton=automaton, state_names=("x", "y"),
                        flows={"run": flow_map(omega * v.y, -omega * v.x)})


def test_the_own_recheck_of_a_fast_oscillator_needs_the_modal_bound(monkeypatch):
    # x' = 20 y, y' = -20 x over 10 s (32 turns) from a box around (1, 0): |(x, y)| <= sqrt(1.01² + 0.01²)
    system = _oscillator(20.0)
    fragment = safety_fragment(parse_tree("always[0, 10] (x <= 1.2)"), ("x", "y"))
    box = {"x": (0.99, 1.01), "y": (-0.01, 0.01)}
    proof, decision = reach_proof(system, fragment, box)
    assert proof.proven, proof.evidence
    true_slack = 1.2 - np.hypot(1.01, 0.01)
    assert 0 < proof.margin <= true_slack
    margin = float(proof.evidence.rsplit("exact margin ", 1)[1].split()[0])
    assert 0 < margin <= true_slack
    # without the modal bound the re-check's error box is mapped by |Φ| (row sums cos 0.2 + sin 0.2 = 1.18 per
    # step) and blows up: the re-check fails, so the proof is not proven
    monkeypatch.setattr(recheck_own, "modal_tracker", lambda phi: None)
    again, _ = reach_proof(system, fragment, box)
    assert again.holds and not again.rechecked and "re-check FAILED" in again.evidence
