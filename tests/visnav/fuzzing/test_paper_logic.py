"""visnav.fuzzing.paper_logic: the flag logic as printed, and what the fuzzer finds in it (docs/fuzzing.md)."""

from __future__ import annotations

import math

import pytest

from visnav.fuzzing.paper_logic import mu_coll_cases, mu_occ_cases
from visnav.fuzzing.run import fuzz_property
from visnav.fuzzing.runner import run_supervisor
from visnav.fuzzing.space import MeasurementSpace
from visnav.fuzzing.variants import make_variant

SPACE = MeasurementSpace()
ENV, SETTINGS = SPACE.envelopes, SPACE.settings
PAPER = make_variant("paper", ENV, SETTINGS, SPACE.n_obstacles)


def row(d0, d1=1.6, side=1.0, d_occ=160.0, d_bord=320.0, pan=0.0, alpha=0.0, visible=1.0):
    return (d0, d1, side, d_occ, d_bord, pan, alpha, visible)


def test_printed_cases_overlap_exactly_where_notes_says():
    # (2): with LEAVE = 1 and AVOID = 0, cases 2 and 3 overlap in [dL, d0] (question 3)
    assert mu_coll_cases(0.45, avoid=0, leave=1, d_leave=0.4, envelopes=ENV) == (
        (2, pytest.approx(0.25)), (3, pytest.approx(0.75)))
    # with LEAVE = 1 beyond d+, "otherwise": 1 for ever (question 2)
    assert mu_coll_cases(2.0, avoid=1, leave=1, d_leave=0.4, envelopes=ENV) == ((4, 1.0),)
    # (3): right after OCCLU is reset at d_occ >= D0, cases 1 and 3 overlap (question 8)
    assert mu_occ_cases(65.0, 10.0, occlu=0, D_leave=60.0, envelopes=ENV) == ((1, 0.0), (3, 0.75))
    assert mu_occ_cases(30.0, 10.0, occlu=1, D_leave=math.inf, envelopes=ENV) == ((4, 1.0),)


def _paper_run(seq):
    return run_supervisor(PAPER, SPACE, seq)


def test_as_written_mu_occ_jumps_when_occlu_is_reset():
    seq = [row(1.6, d_occ=100.0 - 4 * k) for k in range(20)] + [row(1.6, d_occ=24.0 + 4 * k) for k in range(1, 10)]
    steps = _paper_run(seq)
    i = next(i for i, s in enumerate(steps) if any(j.transition.endswith("OCCLUDED->CLEAR") for j in s.jumps))
    assert steps[i - 1].mu_occ == 1.0 and steps[i].mu_occ == 0.0  # d_occ 56 -> 60: one step of 4 px


def test_as_written_occlu_is_zeno_when_the_occluder_leaves_the_image_while_close():
    steps = _paper_run([row(1.6, d_occ=30.0, d_bord=0.0)])
    assert steps[0].zeno and len(steps[0].jumps) == 8


def test_as_written_leave_never_ends_and_mu_coll_jumps_back_to_one_beyond_d_plus():
    seq = [row(0.8 - 0.01 * k, pan=0.01) for k in range(60)]        # into xi-, pan slightly positive
    seq += [row(0.2 + 0.01 * k, pan=-0.01) for k in range(1, 60)]   # pan through 0: LEAVE; then move away
    steps = _paper_run(seq)
    modes = [s.mode for s in steps]
    assert "LEAVE|CLEAR" in modes and modes[-1] == "LEAVE|CLEAR"  # never reset
    mus = [(s.measurement[0], s.mu_coll) for s in steps if s.mode == "LEAVE|CLEAR"]
    at_d_plus = [mu for d, mu in mus if ENV.d_plus_m - 0.011 < d <= ENV.d_plus_m]
    beyond = [mu for d, mu in mus if d > ENV.d_plus_m]
    assert at_d_plus and max(at_d_plus) < 0.1 and beyond and min(beyond) == 1.0


@pytest.mark.parametrize("name", ["mu_continuity", "no_chatter", "leave_release", "stateful"])
def test_the_fuzzer_finds_the_as_written_defects(name):
    result = fuzz_property(name, variant="paper", shrink=False)
    assert not result.passed


def test_as_written_a_pan_crossing_is_lost_when_occlu_switches_at_the_same_sample():
    """The instant rule (hybrid.instant): a crossing guard fires on the first jump of a sample only.

    In the product automaton the occlusion switch (priority 0) is that first jump, so the pan's sign
    change at the same sample ("ϑ = 0" of section V.A) is not seen, and at the next sample it is over:
    HELD, hence LEAVE, does not come.  (Before the single kernel the crossing fired as a second jump.)
    """
    steps = _paper_run([row(0.25, pan=-0.01), row(0.25, pan=0.01, d_occ=20.0), row(0.25, pan=0.01, d_occ=20.0)])
    assert [[j.transition for j in s.jumps] for s in steps] == [["FREE->AVOID@CLEAR"], ["AVOID@CLEAR->OCCLUDED"], []]
    assert steps[-1].mode == "AVOID|OCCLUDED"
    alone = _paper_run([row(0.25, pan=-0.01), row(0.25, pan=0.01)])  # without the occluder it is seen
    assert [j.transition for j in alone[1].jumps] == ["AVOID->HELD:up@CLEAR", "HELD->LEAVE@CLEAR"]
