"""The input route (``InputReachProof``) chooses its steps from the dynamics when none is given (issue 28).

Yardstick: ``ẋ = −5000 x + u``, ``|u| <= 1``, ``x(0) = 0`` over 1 s: ``|x(t)| <= (1 − e^{−5000 t})/5000 < 2·10⁻⁴``
(closed form, the worst input ``u ≡ ±1``).  The default step 1 s / 1000 gives ``‖A_aug‖·δ = 5001·0.001 > 4``:
refused before.  A step for ``‖A‖·step <= κ`` is ``κ/5001`` s (row sum 5000, plus the constant column); the
flowpipe's input term over-approximates the input's reach set by up to ``e^κ`` (docs/reachability.md, "Steps
chosen with inputs"): about ``49 · 2·10⁻⁴ ≈ 0.01`` at ``κ = 3.9``, ``1.49 · 2·10⁻⁴ ≈ 3·10⁻⁴`` at ``κ = 0.4``.
So ``x <= 0.05`` is proven by the first choice and ``x <= 5·10⁻⁴`` only by the second.
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
    assert 0.05 - 0.012 < proof.margin <= 0.05 - TRUE_MAX + 1e-12  # a lower bound of the true slack, within 49x


def test_the_inputs_wrapping_needs_the_finer_choice(tmp_path):
    proof = _proof(tmp_path, 5e-4)
    assert proof.holds and proof.rechecked, proof.evidence
    assert "‖A‖·step <= 0.4: 'a' 7.998e-05 s" in proof.evidence  # 0.4 / 5001: the first choice's 49x is too wide
    assert 0.0 < proof.margin <= 5e-4 - TRUE_MAX + 1e-12


def test_a_sampling_time_is_the_input_routes_step(tmp_path):
    proof = _proof(tmp_path, 0.05, "sampling-time = 0.0005\n")
    assert proof.holds and proof.rechecked and "step 0.0005 s" in proof.evidence
    assert "steps chosen" not in proof.evidence  # 5001 · 0.0005 < 3.9: the user's step alone
