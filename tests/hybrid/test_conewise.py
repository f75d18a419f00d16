"""hybrid.conewise: sectors of the plane as modes, crossings of the rays as transitions, runs that go around."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scipy.linalg import expm

from hybrid import Box, check
from hybrid.conewise import conewise_linear_system, sector_normals
from hybrid.continuous import simulate_continuous
from hybrid.errors import ParameterError

SPIRAL_1, SPIRAL_2 = np.array([[0.1, -1.0], [2.0, 0.1]]), np.array([[0.1, -2.0], [1.0, 0.1]])
#: a damped rotation, clockwise: ẋ = y, ẏ = −x (minus a little damping)
CLOCKWISE = np.array([[-0.05, 1.0], [-1.0, -0.05]])


def sector_of(x: np.ndarray, count: int) -> float:
    """The angle of ``x`` in units of a sector (sector ``i`` is ``[i, i + 1]``), independent of the module."""
    return (math.atan2(x[1], x[0]) % (2 * math.pi)) / (2 * math.pi) * count


def test_modes_invariants_and_flows_are_the_sectors():
    mats = [SPIRAL_1 * (k + 1) for k in range(6)]
    system = conewise_linear_system("six", mats, state_names=("p", "q"), initial_sector=2)
    a = system.automaton
    assert a.mode_names == tuple(f"S{i}" for i in range(6)) and a.initial_mode == "S2"
    assert system.state_names == ("p", "q") and a.variables == ("p", "q")
    assert [t.name for t in a.outgoing("S0")] == ["S0->S1", "S0->S5"]
    assert all(t.direction == +1 and not t.writes for t in a.transitions) and not system.jumps
    normals = sector_normals(6)
    assert normals[0] == (-0.0, 1.0) and normals[3] == pytest.approx((0.0, -1.0), abs=1e-15)
    rng = np.random.default_rng(0)
    for x in rng.normal(size=(200, 2)):
        inside = int(sector_of(x, 6))
        for i in range(6):  # the invariant holds exactly in the sector the angle says
            assert (a.mode(f"S{i}").invariant(tuple(x), {}) >= 0) == (i == inside)
        np.testing.assert_allclose(system.flow(f"S{inside}", 0.0, tuple(x), {}), mats[inside] @ x, rtol=1e-14)


def test_a_run_goes_around_the_sectors_in_order():
    count = 8
    mats = [(SPIRAL_2, SPIRAL_1)[int((i + 0.5) / count * 4) % 2] for i in range(count)]
    system = conewise_linear_system("spirals", mats)
    x0 = np.array([-0.2, 1.0])
    start = int(sector_of(x0, count))
    run = simulate_continuous(system, tuple(x0), duration=15.0, initial_mode=f"S{start}")
    assert run.termination == "end_time" and not run.unresolved
    assert len(run.events) >= 3 * count  # (both spirals turn at about 1.4 rad/s: more than three laps)
    for k, e in enumerate(run.events):  # counter-clockwise, one sector after the other, never back
        i, j = (start + k) % count, (start + k + 1) % count
        assert (e.transition, e.source, e.target) == (f"S{i}->S{j}", f"S{i}", f"S{j}")
        assert e.state_before == e.state_after  # no jump map: the state is kept
        assert abs(sector_of(np.array(e.state_before), count) - j) % count < 1e-9  # on the ray θ_j
    for x, mode in zip(run.states, run.modes):  # every sample flows in the sector it is in
        where = sector_of(np.asarray(x), count)
        i = int(mode[1:])
        assert i - 1e-9 <= where <= i + 1 + 1e-9 or (i == count - 1 and where < 1e-9) or (i == 0 and where > count - 1e-9)


def test_the_jumps_keep_the_state_so_one_matrix_everywhere_gives_the_linear_solution():
    system = conewise_linear_system("rotation", [CLOCKWISE] * 5)
    x0 = np.array([1.0, 0.2])
    run = simulate_continuous(system, tuple(x0), duration=10.0, initial_mode="S0")
    assert run.termination == "end_time"
    names = [e.transition for e in run.events]
    assert names[:3] == ["S0->S4", "S4->S3", "S3->S2"]  # clockwise: the S<i>->S<i-1> transitions
    assert names == [f"S{-k % 5}->S{-(k + 1) % 5}" for k in range(len(names))]
    assert len(names) == 8  # 10 rad (573°) clockwise from 11.3°: the rays at 0°, −72°, ..., −504°
    np.testing.assert_allclose(run.final_state, expm(CLOCKWISE * 10.0) @ x0, rtol=0, atol=1e-8)


def test_the_structural_checks_prove_no_deadlock_and_no_nondeterminism():
    system = conewise_linear_system("spirals", [SPIRAL_2, SPIRAL_1, SPIRAL_2, SPIRAL_1])
    report = check(system, Box(bounds={"x": (-1.0, 1.0), "y": (-1.0, 1.0)}))
    assert report.claims["deadlock"].status == "proven" and report.claims["nondeterminism"].status == "proven"
    assert {f.severity for f in report.findings} <= {"info"}  # both rays' guards hold at the origin: priorities


BAD = [
    (dict(name="", matrices=[np.eye(2)] * 3), "name", "''", "a non-empty string"),
    (dict(name="s", matrices=[np.eye(2)] * 2), "matrices", "'2 matrices'", "at least 3 matrices"),
    (dict(name="s", matrices=np.eye(2)), "matrices", r"\(2, 2\)", r"an array of shape \(m, 2, 2\)"),
    (dict(name="s", matrices="abc"), "matrices", "'str'", "a sequence of 2×2 matrices"),
    (dict(name="s", matrices=[np.eye(2), np.eye(3), np.eye(2)]), "matrices[1]", r"\(3, 3\)", r"shape \(2, 2\)"),
    (dict(name="s", matrices=[np.eye(2), [[1.0, np.nan], [0.0, 1.0]], np.eye(2)]), "matrices[1]",
     r"\[\[1\.0, nan\], \[0\.0, 1\.0\]\]", "finite entries"),
    (dict(name="s", matrices=[np.eye(2), [["a", 1], [0, 1]], np.eye(2)]), "matrices[1]", "'list'", "real numbers"),
    (dict(name="s", matrices=[np.eye(2)] * 3, state_names=("x",)), "state_names", r"\('x',\)", "two distinct"),
    (dict(name="s", matrices=[np.eye(2)] * 3, state_names=("x", "x")), "state_names", r"\('x', 'x'\)", "two distinct"),
    (dict(name="s", matrices=[np.eye(2)] * 3, initial_sector=3), "initial_sector", "3", r"an integer in 0\.\.2"),
    (dict(name="s", matrices=[np.eye(2)] * 3, initial_sector=True), "initial_sector", "True", "an integer"),
]


@pytest.mark.parametrize("kwargs, parameter, value, expected", BAD, ids=[f"{b[1]}-{k}" for k, b in enumerate(BAD)])
def test_bad_input_names_the_parameter_the_value_and_the_fix(kwargs, parameter, value, expected):
    with pytest.raises(ParameterError) as info:
        conewise_linear_system(**kwargs)
    err = info.value
    assert err.parameter == parameter and "; fix: " in str(err)
    assert re.match(rf"^{re.escape(parameter)} = ({value}): expected .*{expected}", str(err)), str(err)


def test_sector_normals_refuses_fewer_than_three():
    with pytest.raises(ParameterError, match=r"^count = 2: expected an integer >= 3"):
        sector_normals(2)
