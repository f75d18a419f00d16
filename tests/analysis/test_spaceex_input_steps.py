"""The input route (``InputReachProof``) chooses its steps from the dynamics when none is given (issue 28).

Yardstick: ``ẋ = −5000 x + u``, ``|u| <= 1``, ``x(0) = 0`` over 1 s: ``|x(t)| <= (1 − e^{−5000 t})/5000 < 2·10⁻⁴``
(closed form, the worst input ``u ≡ ±1``).  The default step 1 s / 1000 gives ``‖A_aug‖·δ = 5001·0.001 > 4``:
refused before.  A step for ``‖A‖·step <= κ`` is ``κ/5001`` s (row sum 5000, plus the constant column).  The
input's one-step set is computed through sub-steps (analysis.reach.input_step; the re-check's own through its
own sub-steps): within about 14 % of the reach set at ``κ = 3.9`` (the former ``V`` was up to ``e^κ ≈ 49`` times
it, and ``x <= 5·10⁻⁴`` needed the finer choice ``κ = 0.4``).  So ``x <= 0.05`` and ``x <= 2.5·10⁻⁴`` (25 % above
the truth) are both proven by the first choice.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from analysis.spaceex import spaceex_problem

HEAD = '<?xml version="1.0"?>\n<sspaceex xmlns="http://www-verimag.imag.fr/xml-namespaces/sspaceex" version="0.2">\n'
PARAMS = "".join(f'<param name="{p}" type="real" local="false" d1="1" d2="1" dynamics="any"/>\n' for p in "xu")
XML = (HEAD + '<component id="c">\n' + PARAMS + '<location id="1" name="a"><invariant>-1 &lt;= u &amp; u &lt;= 1'
       "</invariant><flow>x' == -5000*x + u</flow></location>\n</component>\n</sspaceex>\n")
TRUE_MAX = 1.0 / 5000.0


def _proof(tmp_path: Path, bound: float, extra: str = ""):
    (tmp_path / "lag.xml").write_text(XML)
    (tmp_path / "lag.cfg").write_text(f'system = "c"\ninitially = "x==0"\nforbidden = "x >= {bound!r}"\n'
                                      f"time-horizon = 1\n{extra}")
    proof = spaceex_problem(tmp_path / "lag.xml", tmp_path / "lag.cfg").proofs["safe"]
    assert type(proof).__name__ == "InputReachProof"
    assert proof.time_step == (None if not extra else 0.0005)
    return proof()


def test_a_stiff_mode_with_an_input_gets_a_step_and_is_proven(tmp_path):
    proof = _proof(tmp_path, 0.05)
    assert proof.holds and proof.rechecked, proof.evidence
    assert "steps chosen from the dynamics, ‖A‖·step <= 3.9: 'a' 0.0007798 s" in proof.evidence  # 3.9 / 5001
    # a lower bound of the true slack, within 30 % of the reach set (measured: 13 %, the re-check's sub-steps)
    assert 0.05 - 1.3 * TRUE_MAX < proof.margin <= 0.05 - TRUE_MAX + 1e-12


def test_the_tight_input_set_needs_no_finer_choice(tmp_path):
    proof = _proof(tmp_path, 2.5e-4)
    assert proof.holds and proof.rechecked, proof.evidence
    assert "‖A‖·step <= 3.9: 'a' 0.0007798 s" in proof.evidence  # the first choice: no e^κ in the input's set
    assert 0.0 < proof.margin <= 2.5e-4 - TRUE_MAX + 1e-12


def test_a_sampling_time_is_the_input_routes_step(tmp_path):
    proof = _proof(tmp_path, 0.05, "sampling-time = 0.0005\n")
    assert proof.holds and proof.rechecked and "step 0.0005 s" in proof.evidence
    assert "steps chosen" not in proof.evidence  # 5001 · 0.0005 < 3.9: the user's step alone
