"""``reach`` options for long and hybrid runs: per-mode steps, jump clusters, merged stored segments.

Yardstick: the thermostat's closed form (from ``T0 ∈ [19.5, 20.5]`` it switches at exactly 19 and 21, so the band
``[19, 21]`` is reached and nothing beyond it), and seeded executor runs checked against the stored boxes.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.reach import ReachError, reach, unsafe_set
from hybrid.continuous import simulate_continuous
from hybrid.examples import thermostat
from hybrid.symbolic import coordinates

ROOM = thermostat().system
T = coordinates("T").T
BOX = {"T": (19.5, 20.5)}


def _band_checks(result):
    assert result.status == "complete"
    assert result.distance_to(unsafe_set("hot", T >= 21.01, ("T",))) > 0  # unreachable: proven
    assert result.distance_to(unsafe_set("cold", T <= 18.99, ("T",))) > 0
    assert result.distance_to(unsafe_set("reached hot", T >= 20.99, ("T",))) <= 0  # reachable: never proven
    assert result.distance_to(unsafe_set("reached cold", T <= 19.01, ("T",))) <= 0


def _runs_inside(result, seed):
    rng = np.random.default_rng(seed)
    for t0 in [19.5, 20.5, *rng.uniform(19.5, 20.5, size=20)]:
        tr = simulate_continuous(ROOM, (t0,), duration=12.0, rtol=1e-10, atol=1e-12)
        for t, mode, x in zip(tr.times, tr.modes, np.asarray(tr.states)):
            assert any(s.mode == mode and s.t_lo - 1e-6 <= t <= s.t_hi + 1e-6
                       and s.lo[0] - 1e-6 <= x[0] <= s.hi[0] + 1e-6 for s in result.segments), (t0, t, mode, x)


def test_jump_clusters_split_the_jumps_and_stay_sound():
    one = reach(ROOM, BOX, horizon=12.0, time_step=0.01, max_jumps=20)
    split = reach(ROOM, BOX, horizon=12.0, time_step=0.01, max_jumps=40, jump_cluster=10, max_flowpipes=5000)
    assert len(split.jumps) > len(one.jumps)
    assert all(j.t_hi - j.t_lo <= 10 * 0.01 + one.jumps[0].t_hi - one.jumps[0].t_lo + 1e-9 for j in split.jumps[:3])
    _band_checks(split)
    _runs_inside(split, seed=11)


def test_merged_segments_hold_the_runs_with_fewer_segments():
    full = reach(ROOM, BOX, horizon=12.0, time_step=0.01, max_jumps=20)
    merged = reach(ROOM, BOX, horizon=12.0, time_step=0.01, max_jumps=20, merge_segments=25)
    assert len(merged.segments) * 10 < len(full.segments)
    _band_checks(merged)
    _runs_inside(merged, seed=12)


def test_mode_time_steps_replace_the_step_in_their_mode():
    result = reach(ROOM, BOX, horizon=12.0, time_step=0.02, max_jumps=20, mode_time_steps={"on": 0.005})
    steps = {}
    for a, b in zip(result.segments, result.segments[1:]):  # consecutive flowed segments of one flowpipe
        if a.mode == b.mode and not a.entry and not b.entry:
            steps.setdefault(a.mode, set()).add(round(b.t_lo - a.t_lo, 9))
    assert steps["on"] == {0.005} and steps["off"] == {0.02}
    _band_checks(result)
    _runs_inside(result, seed=13)


@pytest.mark.parametrize(("kwargs", "name"), [
    ({"mode_time_steps": {"nowhere": 0.01}}, "mode_time_steps"),
    ({"mode_time_steps": {"on": 0.0}}, "mode_time_steps['on']"),
    ({"mode_time_steps": {"on": float("nan")}}, "mode_time_steps['on']"),
    ({"mode_time_steps": [0.01]}, "mode_time_steps"),
    ({"jump_cluster": 0}, "jump_cluster"),
    ({"jump_cluster": True}, "jump_cluster"),
    ({"merge_segments": 0}, "merge_segments"),
    ({"merge_segments": 2.5}, "merge_segments"),
])
def test_bad_options_name_the_parameter(kwargs, name):
    with pytest.raises(ReachError) as err:
        reach(ROOM, BOX, horizon=1.0, time_step=0.01, **kwargs)
    assert err.value.parameter == name


def test_runs_with_these_options_are_rechecked_on_the_rechecks_own_sets():
    from analysis.reach.fragment import safety_fragment
    from analysis.reach.recheck import recheck_flowpipe
    from analysis.stl.syntax import parse_tree

    # the band [18.95, 21.05] holds with slack 0.05 (closed form: the room cools to 19 within 1.5 s and heats to 21
    # within 2 s more, both inside the 6 s window); [19.01, 21.05] does not (T reaches 19)
    band = safety_fragment(parse_tree("always[0, 6] (T >= 18.95 and T <= 21.05)"), ("T",))
    tight = safety_fragment(parse_tree("always[0, 6] (T >= 19.01 and T <= 21.05)"), ("T",))
    for options in ({"mode_time_steps": {"on": 0.005}}, {"jump_cluster": 10, "max_jumps": 60},
                    {"merge_segments": 25}):
        result = reach(ROOM, BOX, horizon=6.0, time_step=0.02, **{"max_jumps": 20, **options})
        saved = result.to_json()
        assert ('"schedule"' in saved) == ("merge_segments" not in options)  # the hints the re-check takes
        check = recheck_flowpipe(saved, ROOM, BOX, band)
        assert check.passed and 0.045 < check.margin <= 0.05, (options, check.failure)
        assert not recheck_flowpipe(saved, ROOM, BOX, tight).passed


def test_verify_takes_the_engine_options_and_names_bad_ones():
    from analysis.verify.problems import hybrid_problem
    from analysis.verify.requirements import Requirement
    from analysis.verify.verification import Parameter, ProblemError

    def problem(**options):
        return hybrid_problem(name="room", system=ROOM, initial={"T": Parameter(name="T0", low=19.5, high=20.5)},
                              horizon=6.0, requirements=(Requirement(name="band", formula="always[0, 6] (T >= "
                                                                                           "18.95 and T <= 21.05)"),),
                              reach_options={"time_step": 0.02, **options})
    proof = problem(mode_time_steps={"on": 0.005}, jump_cluster=10, max_jumps=60).proofs["band"]()
    assert proof.proven and "exact margin 0.04" in proof.evidence, proof.evidence
    for bad, name in (({"mode_time_steps": {"on": -1.0}}, "mode_time_steps"), ({"jump_cluster": 0}, "jump_cluster"),
                      ({"merge_segments": 1.5}, "merge_segments")):
        with pytest.raises(ProblemError, match=name):
            problem(**bad)
