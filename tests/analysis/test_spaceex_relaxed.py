"""The input route's arbitrary-switching case (analysis.spaceex_relaxed), end to end from SpaceEx files.

A two-location SpaceEx model whose transitions have no guard (``x' = y``, ``y' = −2x − y + u`` and
``y' = −0.5x − 0.25y + u``, ``u ∈ [−0.5, 0.5]``): without assignments it takes the relaxed route and is proven; with an
assignment (a reset) or invariants that differ it falls back to the ordinary route, which names the reason.
Yardstick for the margin: a greedy switched run (every 1e-3 s the location and input that increase ``x`` fastest),
integrated exactly by ``scipy.linalg.expm`` piece by piece.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from analysis.spaceex import spaceex_problem
from analysis.spaceex_relaxed import NOT_USED

MODEL = """<?xml version="1.0" encoding="iso-8859-1"?>
<sspaceex xmlns="http://www-verimag.imag.fr/xml-namespaces/sspaceex" version="0.2" math="SpaceEx">
  <component id="sw">
    <param name="x" type="real" local="false" d1="1" d2="1" dynamics="any" />
    <param name="y" type="real" local="false" d1="1" d2="1" dynamics="any" />
    <param name="u" type="real" local="false" d1="1" d2="1" dynamics="any" controlled="false" />
    <location id="1" name="a">
      <invariant>-0.5&lt;=u&lt;=0.5</invariant>
      <flow>x'==y &amp; y'==-2*x-y+u</flow>
    </location>
    <location id="2" name="b">
      <invariant>INVARIANT_B</invariant>
      <flow>x'==y &amp; y'==-0.5*x-0.25*y+u</flow>
    </location>
    <transition source="1" target="2">RESET</transition>
    <transition source="2" target="1"></transition>
  </component>
</sspaceex>
"""
CONFIG = """system = sw
initially = "x>=0.9 & x<=1.1 & y>=-0.1 & y<=0.1 & loc(sw)==a"
forbidden = "x >= 3"
time-horizon = 3
"""
U_BOUNDS = "-0.5&lt;=u&lt;=0.5"


def _problem(tmp_path, reset: str = "", invariant_b: str = U_BOUNDS):
    xml = tmp_path / "sw.xml"
    xml.write_text(MODEL.replace("RESET", reset).replace("INVARIANT_B", invariant_b))
    cfg = tmp_path / "sw.cfg"
    cfg.write_text(CONFIG)
    return spaceex_problem(xml, cfg)


def _greedy_largest_x(dwell: float = 1e-3) -> float:
    b = np.array([0.0, 1.0])
    steps = []
    for a in (np.array([[0.0, 1.0], [-2.0, -1.0]]), np.array([[0.0, 1.0], [-0.5, -0.25]])):
        for u in (-0.5, 0.5):
            aug = np.zeros((3, 3))
            aug[:2, :2], aug[:2, 2] = a, b * u
            steps.append((a, u, expm(aug * dwell)))
    x, top = np.array([1.1, 0.1]), 1.1
    weight = np.array([1.0, 0.5])  # push x and its velocity up
    for _ in range(int(3.0 / dwell)):
        _, _, phi = max(steps, key=lambda e: float(weight @ (e[0] @ x + b * e[1])))
        x = (phi @ np.append(x, 1.0))[:2]
        top = max(top, float(x[0]))
    return top


def test_free_switching_is_proven_by_the_relaxation_and_rechecked(tmp_path):
    proof = _problem(tmp_path).proofs["safe"]()
    assert proof.holds and proof.rechecked, proof.evidence
    assert "under arbitrary switching of 'a' and 'b'" in proof.evidence and "re-checked on its own sets" in proof.evidence
    own = float(proof.evidence.split("exact margin ")[1].split()[0])
    # both margins are lower bounds of the true one, at most 3 − the largest x of a switched run
    assert 0.0 < proof.margin <= 3.0 - _greedy_largest_x() and 0.0 < own <= 3.0 - _greedy_largest_x()


def test_a_reset_falls_back_to_the_ordinary_route_and_says_why(tmp_path):
    proof = _problem(tmp_path, reset="<assignment>x=0.5*x</assignment>").proofs["safe"]()
    assert not proof.holds and not proof.rechecked
    assert f"{NOT_USED}: transition" in proof.evidence and "reset that is not the identity" in proof.evidence
    assert "flowpipe is inconclusive" in proof.evidence  # today's route: one flowpipe per jump set, then the limit


def test_invariants_that_differ_fall_back_and_say_why(tmp_path):
    proof = _problem(tmp_path, invariant_b=U_BOUNDS + " &amp; x&lt;=10").proofs["safe"]()
    assert not proof.rechecked and f"{NOT_USED}:" in proof.evidence and "differs" in proof.evidence
