"""SpaceEx inputs (uncontrolled variables without a flow, bounded by the invariants): import, signals, export.

Yardsticks: closed forms of ``x' = -x + u`` under a piecewise-constant ``u``; the platoon's matrices as published
by JuliaReach's ARCH model (ReachabilityModels / ReachabilityAnalysis ``Platoon.jl``, typed in here, not read from
the XML) with ``scipy.linalg.expm`` of the input-augmented matrix; the XML text itself (regular expressions).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from hybrid.continuous import simulate_continuous
from hybrid.spaceex_export import model_to_spaceex
from hybrid.spaceex_import import import_spaceex, load_spaceex
from hybrid.spaceex_inputs import input_signal, with_inputs
from hybrid.spaceex_syntax import SpaceExError
from hybrid.symbolic import render

DATA = Path(__file__).resolve().parents[1] / "data" / "spaceex"
PLATOON = DATA / "arch2017" / "Platoon" / "SpaceEx"
BUILDING = DATA / "arch2017" / "Building" / "SpaceEx"
HEAD = '<?xml version="1.0"?>\n<sspaceex xmlns="http://www-verimag.imag.fr/xml-namespaces/sspaceex" version="0.2">\n'

# JuliaReach's transcription of the ARCH-COMP platoon (connected mode): x' = A x + B aL, B = e_2
A_CONNECTED = np.array([
    [0, 1.0, 0, 0, 0, 0, 0, 0, 0],
    [0, 0, -1.0, 0, 0, 0, 0, 0, 0],
    [1.6050, 4.8680, -3.5754, -0.8198, 0.4270, -0.0450, -0.1942, 0.3626, -0.0946],
    [0, 0, 0, 0, 1.0, 0, 0, 0, 0],
    [0, 0, 1.0, 0, 0, -1.0, 0, 0, 0],
    [0.8718, 3.8140, -0.0754, 1.1936, 3.6258, -3.2396, -0.5950, 0.1294, -0.0796],
    [0, 0, 0, 0, 0, 0, 0, 1.0, 0],
    [0, 0, 0, 0, 0, 1.0, 0, 0, -1.0],
    [0.7132, 3.5730, -0.0964, 0.8472, 3.2568, -0.0876, 1.2726, 3.0720, -3.1356]])


def one_state(invariant: str, flow: str = "x' == -x + u", extra: str = "") -> bytes:
    params = "".join(f'<param name="{p}" type="real" local="false" d1="1" d2="1" dynamics="any"/>\n' for p in "xu")
    body = f'<location id="1" name="a"><invariant>{invariant}</invariant><flow>{flow}</flow></location>\n{extra}'
    return (HEAD + f'<component id="c">\n{params}{body}</component>\n</sspaceex>\n').encode()


def test_an_input_is_imported_with_its_bounds_and_held_at_its_middle():
    model = import_spaceex(one_state("0 &lt;= u &amp; u &lt;= 1"), source="lag.xml")
    (u,) = model.inputs
    assert (u.name, u.low, u.high, u.symbol, u.middle) == ("u", 0.0, 1.0, "input_u", 0.5)
    assert model.system.state_names == ("x",) and model.system.automaton.modes[0].invariant is None
    assert render(model.input_flows["a"].components[0]) == "(-x + input_u)"
    # the imported system holds u = 1/2: x(t) = 1/2 + (x0 - 1/2) e^{-t}
    run = simulate_continuous(model.system, (2.0,), duration=3.0)
    assert run.final_state[0] == pytest.approx(0.5 + 1.5 * math.exp(-3.0), abs=1e-8)
    assert any("input u in [0.0, 1.0]" in n for n in model.notes)


def test_a_piecewise_constant_signal_gives_the_closed_form():
    model = import_spaceex(one_state("0 &lt;= u &amp; u &lt;= 1"), source="lag.xml")
    system = with_inputs(model.system, model.input_flows, model.inputs, {"u": input_signal((1.0, 0.0, 1.0), 3.0)})
    run = simulate_continuous(system, (0.0,), duration=3.0, max_step=0.05)
    x1 = 1.0 - math.exp(-1.0)            # u = 1 on [0, 1) from 0
    x2 = x1 * math.exp(-1.0)             # u = 0 on [1, 2)
    x3 = 1.0 + (x2 - 1.0) * math.exp(-1.0)  # u = 1 on [2, 3)
    assert run.final_state[0] == pytest.approx(x3, abs=1e-7)
    # after the horizon the last value is held
    late = simulate_continuous(system, (0.0,), duration=4.0, max_step=0.05)
    assert late.final_state[0] == pytest.approx(1.0 + (x3 - 1.0) * math.exp(-1.0), abs=1e-7)


@pytest.mark.parametrize("invariant, expected", [
    ("0 &lt;= u", "u in [0.0, inf]"),
    ("u &lt;= x &amp; 0 &lt;= u &amp; u &lt;= 1", "bounds of the input 'u' by constants"),
    ("1 &lt;= u &amp; u &lt;= 0", "non-empty range"),
])
def test_inputs_that_are_not_bounded_by_constants_are_refused(invariant, expected):
    with pytest.raises(SpaceExError) as info:
        import_spaceex(one_state(invariant), source="bad.xml")
    assert expected in str(info.value) and "'u'" in str(info.value)


def test_an_input_read_by_a_jump_or_bounded_differently_per_location_is_refused():
    jump = '<transition source="1" target="1"><guard>x &gt;= 1</guard><assignment>x := u</assignment></transition>\n'
    with pytest.raises(SpaceExError, match="an input acts on the flows only"):
        import_spaceex(one_state("0 &lt;= u &amp; u &lt;= 1", extra=jump), source="bad.xml")
    two = one_state("0 &lt;= u &amp; u &lt;= 1", extra='<location id="2" name="b"><invariant>0 &lt;= u &amp; '
                    "u &lt;= 2</invariant><flow>x' == u</flow></location>\n")
    with pytest.raises(SpaceExError, match="the same bounds of the input in every location"):
        import_spaceex(two, source="bad.xml")


def test_with_inputs_names_a_missing_signal_and_input_signal_checks_its_arguments():
    model = import_spaceex(one_state("0 &lt;= u &amp; u &lt;= 1"), source="lag.xml")
    with pytest.raises(SpaceExError, match=r"\['u'\] missing"):
        with_inputs(model.system, model.input_flows, model.inputs, {})
    for values, horizon in (((), 1.0), ((1.0,), 0.0), ((1.0,), math.inf)):
        with pytest.raises(SpaceExError, match="horizon"):
            input_signal(values, horizon)


def test_the_building_with_a_time_varying_input():
    model = load_spaceex(BUILDING / "BLDF01.xml")
    text = (BUILDING / "BLDF01.xml").read_text()
    low, high = re.search(r"u1\s*&gt;=\s*([\d.]+)\s*&amp;\s*u1\s*&lt;=\s*([\d.]+)", text).groups()
    assert [(i.name, i.low, i.high) for i in model.inputs] == [("model.u1", float(low), float(high))]
    assert "model.u1" not in model.system.state_names and len(model.system.state_names) == 49  # 48 + t


def test_the_platoon_with_the_leader_acceleration_as_input_against_the_published_matrices():
    model = load_spaceex(PLATOON / "PLAD01-BND.xml", "sys_platoon")
    assert [(i.name, i.low, i.high) for i in model.inputs] == [("aL", -9.0, 1.0)]
    names = model.system.state_names
    assert names[:9] == ("e1", "v1", "a1", "e2", "v2", "a2", "e3", "v3", "a3")
    start = model.system.automaton.initial_mode
    assert "platoon.communication" in start
    values = (1.0, -9.0, 0.5, -3.0, 1.0, -9.0, -1.0, 0.0, 1.0, -5.0)
    horizon = 4.5  # the break pattern switches at 5 s
    system = with_inputs(model.system, model.input_flows, model.inputs, {"aL": input_signal(values, horizon)})
    run = simulate_continuous(system, (0.0,) * len(names), duration=horizon, max_step=0.05)
    assert run.final_mode == start
    # independent: x(t_{k+1}) = expm([[A, B u_k], [0, 0]] h) [x(t_k); 1] over the ten pieces
    x = np.zeros(9)
    h = horizon / len(values)
    for u in values:
        aug = np.zeros((10, 10))
        aug[:9, :9] = A_CONNECTED
        aug[1, 9] = u
        x = (expm(aug * h) @ np.append(x, 1.0))[:9]
    assert np.allclose(run.final_state[:9], x, atol=1e-6 * (1 + np.abs(x).max()))


def test_the_published_platoon_constants_and_the_missing_ones():
    path = PLATOON / "PLAN01-UNB.xml"
    with pytest.raises(SpaceExError) as info:
        load_spaceex(path, "sys_platoon_Global_clock")
    assert "'tc'" in str(info.value) and "constants={'tc'" in str(info.value)
    # ARCH-COMP AFF: PLAN01 tb = 10, tc = 20, tr = 20 s (published); the global clock's bound T is not (UNB)
    published = {"tb": 10.0, "tc": 20.0, "tr": 20.0}
    with pytest.raises(SpaceExError, match="'T'"):
        load_spaceex(path, "sys_platoon_Global_clock", constants=published)
    model = load_spaceex(path, "sys_platoon_Global_clock", constants={**published, "T": 40.0})
    text = " ".join(render(m.invariant) for m in model.system.automaton.modes)
    assert "(20 - break_pattern.t)" in text and "(40 - t)" in text
    with pytest.raises(SpaceExError, match="constants of component"):
        load_spaceex(path, "sys_platoon_Global_clock", constants={"nope": 1.0})
    with pytest.raises(SpaceExError, match="a finite number"):
        load_spaceex(path, "sys_platoon_Global_clock", constants={**published, "T": math.nan})
    # the file's own sys_platoon binds the published values
    own = load_spaceex(path, "sys_platoon")
    guards = " ".join(render(t.guard) for t in own.system.automaton.transitions)
    assert "(break_pattern.t - 10)" in guards


@pytest.mark.parametrize("path, component", [
    (PLATOON / "PLAD01-BND.xml", "sys_platoon"), (PLATOON / "PLAD01-BND.xml", "sys_platoon_Global_clock"),
    (PLATOON / "PLAA01-BND.xml", "sys_platoon"), (PLATOON / "PLAN01-UNB.xml", "sys_platoon"),
    (BUILDING / "BLDF01.xml", None), (DATA / "spaceexparser" / "motor" / "motor.xml", None)])
def test_models_with_inputs_export_and_reimport_with_the_same_flows_and_bounds(path, component):
    model = load_spaceex(path, component)
    again = import_spaceex(model_to_spaceex(model).encode(), source="again.xml")
    assert [(i.low, i.high) for i in again.inputs] == [(i.low, i.high) for i in model.inputs]
    rename = {i.symbol: re.sub(r"\W", "_", i.symbol) for i in model.inputs}
    modes_a, modes_b = model.system.automaton.modes, again.system.automaton.modes
    assert len(modes_a) == len(modes_b)
    for qa, qb in zip(modes_a, modes_b):
        flows_a = [render(c) for c in model.input_flows[qa.name].components]
        flows_b = [render(c) for c in again.input_flows[qb.name].components]
        canon = [re.sub(r"\W", "_", f) for f in flows_a]
        assert [re.sub(r"\W", "_", f) for f in flows_b] == canon, qa.name
    # and by simulation: the same signal in both
    signals_a = {i.name: input_signal((i.low, i.high, i.middle), 3.0) for i in model.inputs}
    signals_b = {j.name: input_signal((i.low, i.high, i.middle), 3.0) for i, j in zip(model.inputs, again.inputs)}
    sa = with_inputs(model.system, model.input_flows, model.inputs, signals_a)
    sb = with_inputs(again.system, again.input_flows, again.inputs, signals_b)
    x0 = tuple(0.0 for _ in sa.state_names)
    ra = simulate_continuous(sa, x0, duration=3.0, max_step=0.05)
    rb = simulate_continuous(sb, x0, duration=3.0, max_step=0.05)
    assert np.allclose(ra.final_state, rb.final_state, rtol=1e-9, atol=1e-12)
    assert [e.time for e in ra.events] == pytest.approx([e.time for e in rb.events], abs=1e-9)
    assert rename  # every input has a placeholder
