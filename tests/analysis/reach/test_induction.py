"""Unbounded-time safety by cycle induction (analysis.reach.induction, analysis.spaceex_induction), end to end from a
SpaceEx file with ``time-horizon = -1``.

The automaton: states ``x, y``, a dwell clock ``t`` and an input ``u ∈ [-1, 1]``; location ``fast`` (a damped
rotation, 1 s <= dwell <= 2 s) and ``slow`` (a slow decay, dwell <= 1 s), the clock reset on both transitions.

Yardstick (no code of the producer or of the re-check): seeded runs with random dwell times and bang-bang inputs
(piecewise constant, ±1, pieces of 0.05–0.3 s), integrated piece by piece exactly by ``scipy.linalg.expm`` of the
augmented matrix ``[[A, B u], [0, 0]]`` over 12 cycles: at every entry into ``fast`` the state must lie in the
proven ``W`` (to 1e-9: expm is accurate to ~1e-15 relative on these O(1) matrices, runs have < 500 pieces).  The
unstable variant (its cycle map expands) must not be proven: ``W`` never closes.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scipy.linalg import expm

from analysis.reach.induction import ENTERED, NoCycle, cycle_bound, cycle_model
from analysis.reach.model import affine_model
from analysis.spaceex import spaceex_problem
from hybrid.spaceex_syntax import SpaceExError

FAST = np.array([[-1.0, 1.0], [-1.0, -1.0]])
SLOW = np.array([[-0.25, 0.0], [0.0, -0.25]])
GROW_FAST = np.array([[0.6, 0.0], [0.0, -1.0]])
GROW_SLOW = np.array([[0.3, 0.0], [0.0, -1.0]])


def _flow(a: np.ndarray, clock: str = "1") -> str:
    c = [[repr(float(v)) for v in row] for row in a]
    return f"x' == {c[0][0]}*x + {c[0][1]}*y + u &amp; y' == {c[1][0]}*x + {c[1][1]}*y &amp; t' == {clock}"


def _xml(fast: np.ndarray, slow: np.ndarray, fast_invariant: str = "t &lt;= 2", fast_clock: str = "1") -> str:
    params = "".join(f'<param name="{v}" type="real" local="false" d1="1" d2="1" dynamics="any" />' for v in "xyt")
    return f"""<?xml version="1.0" encoding="iso-8859-1"?>
<sspaceex xmlns="http://www-verimag.imag.fr/xml-namespaces/sspaceex" version="0.2" math="SpaceEx">
  <component id="dwell">
    {params}
    <param name="u" type="real" local="false" d1="1" d2="1" dynamics="any" controlled="false" />
    <param name="brk" type="label" local="false" />
    <param name="rst" type="label" local="false" />
    <location id="1" name="fast">
      <invariant>{fast_invariant} &amp; -1 &lt;= u &lt;= 1</invariant>
      <flow>{_flow(fast, fast_clock)}</flow>
    </location>
    <location id="2" name="slow">
      <invariant>t &lt;= 1 &amp; -1 &lt;= u &lt;= 1</invariant>
      <flow>{_flow(slow)}</flow>
    </location>
    <transition source="1" target="2"><label>brk</label><guard>t &gt;= 1</guard><assignment>t := 0</assignment></transition>
    <transition source="2" target="1"><label>rst</label><assignment>t := 0</assignment></transition>
  </component>
</sspaceex>
"""


def _files(tmp_path, fast=FAST, slow=SLOW, forbidden="x >= 3", horizon="-1", fast_invariant="t &lt;= 2",
           fast_clock="1"):
    xml = tmp_path / "dwell.xml"
    xml.write_text(_xml(fast, slow, fast_invariant, fast_clock))
    cfg = tmp_path / "dwell.cfg"
    cfg.write_text(f'system = dwell\ninitially = "x == 0 & y == 0 & t == 0 & loc() == fast"\n'
                   f'forbidden = "{forbidden}"\ntime-horizon = {horizon}\n')
    return xml, cfg


def _entries(seed: int, cycles: int, runs: int) -> np.ndarray:
    """The (x, y) of every entry into ``fast`` (and the largest x on the way) of seeded random runs."""
    rng = np.random.default_rng(seed)
    out, top = [], -math.inf
    for _ in range(runs):
        z = np.zeros(2)
        for _ in range(cycles):
            for a, dwell in ((FAST, rng.uniform(1.0, 2.0)), (SLOW, rng.uniform(0.0, 1.0))):
                left = dwell
                while left > 0:
                    piece = min(left, rng.uniform(0.05, 0.3))
                    aug = np.zeros((3, 3))
                    aug[:2, :2] = a
                    aug[0, 2] = rng.choice((-1.0, 1.0))
                    z = (expm(aug * piece) @ np.append(z, 1.0))[:2]
                    top = max(top, z[0])
                    left -= piece
            out.append(z.copy())
    return np.array(out), top


def test_the_cycle_model_redirects_the_returns_and_bounds_the_cycle(tmp_path):
    xml, cfg = _files(tmp_path)
    problem = spaceex_problem(xml, cfg)
    model = affine_model(_zero(problem))
    cycle = cycle_model(model, "fast", {"x": (0.0, 0.0), "y": (0.0, 0.0), "t": (0.0, 0.0)})
    assert cycle.bound == 3  # fast <= 2 s, slow <= 1 s (exact)
    assert cycle.redirected == ("rst",) and [model.state_names[k] for k in cycle.carried] == ["x", "y"]
    assert {t.name: t.target for t in cycle.model.transitions} == {"brk": "slow", "rst": ENTERED}
    assert not any(any(row) for row in cycle.model.modes[ENTERED].a)


def _zero(problem):
    from analysis.spaceex_reach import input_reach_model

    proof = problem.proofs["safe"]
    return input_reach_model(proof.system, proof.input_flows, proof.inputs)[0]


def test_a_stable_dwell_cycle_is_proven_for_all_time_and_its_w_holds_every_simulated_entry(tmp_path):
    xml, cfg = _files(tmp_path)
    problem = spaceex_problem(xml, cfg)
    assert problem.horizon == 9.0  # SAMPLED_CYCLES × the longest cycle: the sampled part covers [0, 9] s only
    assert "for all t >= 0" in problem.requirements[0].description
    proof = problem.proofs["safe"]()
    assert proof.holds and proof.rechecked and "all time t >= 0 (unbounded)" in proof.assumptions, proof.evidence
    assert "re-checked from the saved flowpipe" in proof.evidence and "the initial box lies in W" in proof.evidence
    w = _w(proof.evidence)
    assert set(w) == {"x", "y"}
    entries, top = _entries(seed=7, cycles=12, runs=60)
    assert top < 3.0
    for name, k in (("x", 0), ("y", 1)):
        lo, hi = w[name]
        assert np.all(entries[:, k] >= lo - 1e-9) and np.all(entries[:, k] <= hi + 1e-9), (name, w[name])
    # W is no toy bound: the simulated entries reach a fair part of it
    assert entries[:, 0].max() > 0.25 * w["x"][1]


def _w(evidence: str) -> dict[str, tuple[float, float]]:
    """W from the proof's evidence (``W = x in [lo, hi], ...;``)."""
    text = evidence.split("W = ")[1].split(";")[0]
    return {m.group(1): (float(m.group(2)), float(m.group(3)))
            for m in re.finditer(r"(\w+) in \[([^,]+), ([^\]]+)\]", text)}


def test_an_expanding_cycle_is_not_proven(tmp_path):
    xml, cfg = _files(tmp_path, fast=GROW_FAST, slow=GROW_SLOW, forbidden="x >= 1000")
    problem = spaceex_problem(xml, cfg)
    proof = problem.proofs["safe"]()
    assert not proof.holds and not proof.rechecked
    assert "open" in proof.evidence and "closed" not in proof.evidence.split("re-check")[0].split("W = ")[1]


def test_no_clock_bounding_a_dwell_is_refused_by_name(tmp_path):
    xml, cfg = _files(tmp_path, fast_invariant="x &lt;= 100")
    problem = spaceex_problem(xml, cfg)
    proof = problem.proofs["safe"]()
    assert not proof.holds and not proof.rechecked
    assert "no clock bounds the dwell in 'fast'" in proof.evidence
    assert problem.horizon == 100.0  # no bounded cycle: SAMPLED_HORIZON


def test_a_clock_driven_by_the_input_bounds_no_dwell(tmp_path):
    xml, cfg = _files(tmp_path, fast_clock="1 + 0.5*u")  # t' in [0.5, 1.5]: t <= 2 no longer bounds the dwell by 2 s
    proof = spaceex_problem(xml, cfg).proofs["safe"]()
    assert not proof.holds and "no clock bounds the dwell in 'fast'" in proof.evidence


def test_a_loop_avoiding_home_is_refused():
    from fractions import Fraction

    from analysis.reach.affine import Polyhedron
    from analysis.reach.model import AffineHybridModel, AffineMode, AffineTransition

    one = (Fraction(1),)
    mode = AffineMode(name="m", a=((Fraction(0),),), c=one, invariant=(Polyhedron(halfspaces=()),))
    loop = AffineTransition(name="loop", source="b", target="b", guard=(Polyhedron(halfspaces=()),),
                            r_matrix=((Fraction(1),),), r_offset=(Fraction(0),), direction=0, priority=0)
    go = AffineTransition(name="go", source="a", target="b", guard=(Polyhedron(halfspaces=()),),
                          r_matrix=((Fraction(0),),), r_offset=(Fraction(0),), direction=0, priority=0)
    model = AffineHybridModel(name="m", state_names=("t",), modes={"a": mode, "b": mode}, transitions=(go, loop),
                              initial_mode="a")
    with pytest.raises(NoCycle, match="loop that avoids 'a'"):
        cycle_bound(model, "a", {0: Fraction(0)})


@pytest.mark.parametrize("given, expected", [(0.0, "finite time > 0"), (math.inf, "finite time > 0"),
                                             (-5.0, "finite time > 0"), ("10", "finite time > 0")])
def test_a_bad_sampled_horizon_is_refused_by_name(tmp_path, given, expected):
    xml, cfg = _files(tmp_path)
    with pytest.raises(SpaceExError, match="sampled_horizon") as info:
        spaceex_problem(xml, cfg, sampled_horizon=given)
    assert expected in str(info.value)


def test_a_sampled_horizon_is_refused_for_a_bounded_configuration(tmp_path):
    xml, cfg = _files(tmp_path, horizon="5")
    with pytest.raises(SpaceExError, match="sampled_horizon.*bounded time-horizon"):
        spaceex_problem(xml, cfg, sampled_horizon=10.0)
    problem = spaceex_problem(xml, cfg)  # a bounded one keeps the bounded input proof
    assert problem.horizon == 5.0 and type(problem.proofs["safe"]).__name__ == "InputReachProof"


def test_a_given_sampled_horizon_is_the_problem_horizon(tmp_path):
    xml, cfg = _files(tmp_path)
    problem = spaceex_problem(xml, cfg, sampled_horizon=4.5)
    assert problem.horizon == 4.5 and problem.requirements[0].formula.startswith("always[0, 4.5]")
    assert type(problem.proofs["safe"]).__name__ == "CycleInductionProof"
