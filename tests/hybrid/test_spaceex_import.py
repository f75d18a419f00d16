"""SpaceEx import: the field's own files (ARCH-COMP 2017 AFF, SpaceExParser.jl examples) read, simulated and
checked against closed forms, hand-derived figures, scipy's expm and SpaceEx's own flattening."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from hybrid.continuous import simulate_continuous
from hybrid.examples import bouncing_ball_impact_times
from hybrid.spaceex_config import initial_box, parse_config
from hybrid.spaceex_import import load_spaceex
from hybrid.spaceex_syntax import SpaceExError, parse_constraints

DATA = Path(__file__).resolve().parents[1] / "data" / "spaceex"
ARCH = DATA / "arch2017"
JL = DATA / "spaceexparser"
HEATER = DATA / "hyst" / "heaterLygeros"

# files that are not imported, and the variable or construct the error must name: an input read by a jump (the
# ball's nondeterministic bounce w2), SpaceEx's internal "support_function" flattening output, a constant of the
# network without a value.  Inputs read by flows only (BLDF01's model.u1, the platoon's aL, the motor's u1, u2)
# are imported: tests/hybrid/test_spaceex_inputs.py.
REFUSED = {
    "PLAN01-UNB.xml": "tc",  # a constant of the network without a value (the dwell times of the break pattern)
    "bball_nondet.xml": "w2",
    "bball_nondet_revised.xml": "w2",
    "bball_nondet_revised_flattened.xml": "w2",
    "bball_nondet_flattened.xml": "support_function",
    "bball_nondet_revised_flattened_problem.xml": "support_function",
}
# the component analysed when the file's last component is not the system (the .cfg's system = ...)
SYSTEMS = {"PLAA01-BND.xml": "sys_platoon", "PLAD01-BND.xml": "sys_platoon_Global_clock",
           "PLAN01-UNB.xml": "sys_platoon_Global_clock"}
# files whose top component has a constant that only the .cfg's initial set gives a value (SpaceEx reads it there)
CONFIGS = {"heaterLygeros.xml": HEATER / "heaterLygeros.cfg"}
ALL = sorted(DATA.rglob("*.xml"))


def test_the_data_is_there_with_its_sources():
    assert len(ALL) == 31  # 27 + the spacecraft rendezvous SRNA01, SRA01, SRA02 written from the ARCH equations
    # + HyST's thermostat
    for name in ("SRNA01", "SRA01", "SRA02"):
        assert name in (DATA / "visnav" / "SOURCE.md").read_text()
    assert "GNU LESSER GENERAL PUBLIC LICENSE" in (DATA / "hyst" / "LICENSE").read_text()
    for folder in (ARCH, JL, DATA / "visnav", DATA / "hyst"):
        text = (folder / "SOURCE.md").read_text()
        assert "Source" in text or "visnav" in text
    assert "MIT" in (JL / "LICENSE").read_text()
    assert "d29d5e5f36d7b2e4ac792a756ea444d770bf9c09" in (ARCH / "SOURCE.md").read_text()


@pytest.mark.parametrize("path", ALL, ids=[p.name for p in ALL])
def test_every_shipped_file_imports_or_names_what_it_cannot_import(path):
    if path.name in REFUSED:
        with pytest.raises(SpaceExError) as info:
            load_spaceex(path, SYSTEMS.get(path.name))
        message = str(info.value)
        assert REFUSED[path.name] in message and str(path) in message
        assert re.search(r"\.xml:\d+", message), message  # the line
        return
    cfg = CONFIGS.get(path.name)
    initially = None if cfg is None else parse_config(cfg.read_text(), str(cfg)).initially
    model = load_spaceex(path, SYSTEMS.get(path.name), initially=initially)
    system = model.system
    assert system.dimension >= 1 and system.automaton.modes
    x0 = tuple(0.5 for _ in system.state_names)
    dx = system.flow(system.automaton.initial_mode, 0.0, x0, {})
    assert len(dx) == system.dimension and all(math.isfinite(v) for v in dx)


def test_the_bouncing_ball_bounces_at_the_closed_form_impact_times():
    model = load_spaceex(JL / "bball" / "bball.xml")
    assert model.system.state_names == ("x", "v")
    run = simulate_continuous(model.system, (10.0, 0.0), duration=20.0)
    times = [e.time for e in run.events]
    # g = 1, c = 0.75, eps = 0 from the bind; the closed form is an independent route (hybrid.examples)
    expected = bouncing_ball_impact_times(gravity=1.0, restitution=0.75, h0=10.0, count=4)
    assert times == pytest.approx(expected, abs=1e-8)
    assert [e.transition for e in run.events] == ["hop"] * 4
    # the reset v := -c*v
    first = run.events[0]
    assert first.state_after[1] == pytest.approx(-0.75 * first.state_before[1], rel=1e-12)


def test_the_timed_ball_fires_as_soon_as_its_guard_holds():
    # guard x <= 0.1 & v < 0: hybrid fires it at x = 0.1 (SpaceEx may fire anywhere in [0, 0.1]): the bounces are
    # those of a ball dropped from 9.9 m onto a floor at 0.1 m; t' = 1 is the clock of the second instance
    model = load_spaceex(JL / "bball_timed" / "bball_timed.xml")
    assert model.system.state_names == ("x", "v", "t")
    run = simulate_continuous(model.system, (10.0, 0.0, 0.0), duration=12.0)
    expected = bouncing_ball_impact_times(gravity=1.0, restitution=0.75, h0=9.9, count=2)
    assert [e.time for e in run.events] == pytest.approx(expected, abs=1e-8)
    assert run.final_state[2] == pytest.approx(12.0, abs=1e-9)


def test_the_hyst_thermostat_takes_its_constant_from_the_cfg_and_switches_at_the_closed_form_times():
    cfg = parse_config((HEATER / "heaterLygeros.cfg").read_text(), "heaterLygeros.cfg")
    with pytest.raises(SpaceExError, match="Tmax"):  # without the cfg the constant has no value
        load_spaceex(HEATER / "heaterLygeros.xml", cfg.system)
    model = load_spaceex(HEATER / "heaterLygeros.xml", cfg.system, initially=cfg.initially)
    assert model.constants == {"Tmax": 50.0} and model.system.state_names == ("x", "t")
    assert initial_box(model, cfg) == ({"x": (18.2, 18.2), "t": (0.0, 0.0)}, ["off"])
    run = simulate_continuous(model.system, (18.2, 0.0), duration=25.0, initial_mode="off")
    # off: x = x0 e^{-t/10} until x = 18.1; on: x = 37 - (37 - x0) e^{-t/10} until x = 29
    cool, heat = 10.0 * math.log(29.0 / 18.1), 10.0 * math.log((37.0 - 18.1) / (37.0 - 29.0))
    first = 10.0 * math.log(18.2 / 18.1)
    expected = [first, first + heat, first + heat + cool, first + 2 * heat + cool]
    assert [e.time for e in run.events] == pytest.approx(expected, abs=1e-8)
    assert [e.target for e in run.events] == ["on", "off", "on", "off"]


@pytest.mark.parametrize("initially, constants, message", [
    ("x==18.2 & t==0 & 40 <= Tmax & Tmax <= 50", None, "one value for the constant 'Tmax'"),
    ("x==18.2 & t==0 & Tmax >= 40", None, "one value for the constant 'Tmax'"),
    ("x==18.2 & t==0 & Tmax == 50", {"Tmax": 40.0}, "holds for Tmax = 40.0"),
])
def test_a_constant_the_cfg_does_not_pin_to_one_value_is_named(initially, constants, message):
    cfg = parse_config(f'system = sys1\ninitially = "{initially} & loc(ofOnn_1)==off"\n', "h.cfg")
    with pytest.raises(SpaceExError, match=message) as info:
        model = load_spaceex(HEATER / "heaterLygeros.xml", cfg.system, constants=constants, initially=cfg.initially)
        initial_box(model, cfg)
    assert "fix:" in str(info.value)


def test_the_circle_switches_at_half_turns():
    # x' = -y, y' = x from (0, 1): (x, y) = (-sin t, cos t); y changes sign at pi/2 + k pi
    model = load_spaceex(JL / "circle" / "circle.xml")
    run = simulate_continuous(model.system, (0.0, 1.0), duration=7.0, initial_mode="p")
    assert [e.time for e in run.events] == pytest.approx([math.pi / 2, 3 * math.pi / 2], abs=1e-7)
    assert [e.target for e in run.events] == ["n", "p"]
    assert run.final_state == pytest.approx((-math.sin(7.0), math.cos(7.0)), abs=1e-7)


def _flow_rows(xml: str, location: str) -> dict[str, str]:
    """``var -> right-hand side`` of a location's flow, read from the XML text with a regex (not the importer)."""
    block = re.search(rf'name="{location}".*?<flow>(.*?)</flow>', xml, re.S).group(1)
    block = block.replace("&amp;", "&")
    return {m.group(1): m.group(2).strip() for m in re.finditer(r"(\w+)'\s*==\s*([^&]+)", block)}


def _coefficients(text: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for sign, value, name in re.findall(r"([+-]?)\s*([0-9.]+(?:e-?\d+)?)\*(\w+)", text.replace(" ", "")):
        out[name] = out.get(name, 0.0) + (-1.0 if sign == "-" else 1.0) * float(value)
    return out


def _affine(system, mode):
    """``(A, b)`` of an affine flow, read from the imported model by evaluating it (exact for affine maps)."""
    n = system.dimension
    b = np.array(system.flow(mode, 0.0, (0.0,) * n, {}))
    a = np.column_stack([np.array(system.flow(mode, 0.0, tuple(np.eye(n)[j]), {})) - b for j in range(n)])
    return a, b


def test_the_building_matrix_reads_back_as_the_xml_writes_it_and_simulates_as_expm():
    path = ARCH / "Building" / "SpaceEx" / "BLDC01.xml"
    model = load_spaceex(path, "sys")
    system = model.system
    names = system.state_names
    assert names[:48] == tuple(f"x{i}" for i in range(1, 49)) and names[48:] == ("t", "model.u1")
    a, b = _affine(system, "Model")
    rows = _flow_rows(path.read_text(encoding="latin-1"), "Model")
    for row in ("x25", "x26", "x48"):
        coefficients = _coefficients(rows[row])
        i = names.index(row)
        for var, value in coefficients.items():
            column = names.index("model.u1" if var == "u1" else var)
            assert a[i, column] == pytest.approx(value, rel=1e-14), (row, var)
        assert np.count_nonzero(a[i]) == len(coefficients)
    assert a[0, names.index("x25")] == 1.0 and b[names.index("t")] == 1.0
    # 0.2 s from the initial box's upper corner with u1 = 0.9: the integrator against the matrix exponential
    x0 = np.array([0.00025] * 10 + [0.0] * 38 + [0.0, 0.9])
    run = simulate_continuous(system, tuple(x0), duration=0.2, rtol=1e-11, atol=1e-14)
    n = len(x0)
    augmented = np.zeros((n + 1, n + 1))
    augmented[:n, :n], augmented[:n, n] = a, b
    exact = (expm(augmented * 0.2) @ np.append(x0, 1.0))[:n]
    assert np.allclose(run.final_state, exact, rtol=1e-7, atol=1e-11)


def test_the_building_initial_box_takes_u1_from_the_invariant():
    model = load_spaceex(ARCH / "Building" / "SpaceEx" / "BLDC01.xml", "sys")
    cfg = parse_config((ARCH / "Building" / "SpaceEx" / "BLDC01-BDS01.cfg").read_text(), "BLDC01-BDS01.cfg")
    box, modes = initial_box(model, cfg)
    assert modes == ["Model"]
    assert box["model.u1"] == (0.8, 1.0)  # invariant u1 >= 0.8 & u1 <= 1: SpaceEx intersects the initial set with it
    assert box["x1"] == (0.0002, 0.00025) and box["x25"] == (-0.0001, 0.0001) and box["t"] == (0.0, 0.0)
    assert "flowpipe-tolerance" in cfg.ignored and "directions" in cfg.ignored


def test_the_gearbox_meshes_before_the_deadline_and_its_first_impact_is_the_hand_derived_one():
    model = load_spaceex(ARCH / "Gear" / "SpaceEx" / "GRBX01-MES01.xml", "mesh_timed")
    system = model.system
    assert system.state_names == ("t", "vx", "vy", "px", "py", "I")
    free, meshed = "Clock_1.loc01|Stateflow_2.move_free", "Clock_1.loc01|Stateflow_2.meshed"
    assert system.automaton.mode_names == (free, meshed)
    px0, py0 = -0.0167, 0.003
    run = simulate_continuous(system, (0.0, 0.0, 0.0, px0, py0, 0.0), duration=0.5, initial_mode=free)
    # free flight vx' = Fs/ms, vy' = -Rs*Tf/Jg2 until py >= -k px (k = tan(pi/5 - ...) of the tooth, from the XML)
    ax, ay, k = 70 / 3.2, 0.08 * 1 / 0.7, 0.726542528005361
    t1 = math.sqrt(-(py0 + k * px0) / (k * ax / 2 - ay / 2))
    first = run.events[0]
    assert first.transition == "Stateflow_2.transition1" and first.time == pytest.approx(t1, rel=1e-9)
    assert first.state_before[3] == pytest.approx(px0 + ax * t1 * t1 / 2, rel=1e-9)
    # the published verdict (ARCH-COMP 2017 AFF, GRBX01-MES01 safe): meshed before 0.2 s with I < 20
    last = run.events[-1]
    assert last.target == meshed and last.time < 0.2
    assert run.final_state[5] < 20.0 and run.final_state[3] == pytest.approx(-0.003, abs=1e-9)
    assert any("flow false" in note for note in model.notes)


def test_the_gearbox_without_location_constraint_starts_in_every_location():
    model = load_spaceex(ARCH / "Gear" / "SpaceEx" / "GRBX01-MES01.xml", "mesh_timed")
    cfg = parse_config((ARCH / "Gear" / "SpaceEx" / "GRBX01-MES01.cfg").read_text(), "GRBX01-MES01.cfg")
    box, modes = initial_box(model, cfg)
    assert modes == list(model.system.automaton.mode_names)
    assert box["px"] == (-0.0168, -0.0166) and box["I"] == (0.0, 0.0)


@pytest.mark.parametrize("network, flat, tol", [
    (JL / "bball" / "bball.xml", JL / "bball" / "bball_flattened.xml", 1e-8),
    # SpaceEx printed eps = 0.1 as 0.100001: the bounces move by 1e-6 / |v|
    (JL / "bball_timed" / "bball_timed.xml", JL / "bball_timed" / "bball_timed_flattened.xml", 1e-5),
    (JL / "circle" / "circle.xml", JL / "circle" / "circle_flattened.xml", 1e-8),
    # SpaceEx printed -5/7 as -0.714285 (the network's 0.714286): a relative change of 1.4e-6
    (JL / "filtered_oscillator" / "filtered_oscillator.xml",
     JL / "filtered_oscillator" / "filtered_oscillator_flattened.xml", 1e-4),
], ids=["bball", "bball_timed", "circle", "filtered_oscillator"])
def test_our_flattening_simulates_as_spaceex_own_flattened_file(network, flat, tol):
    """SpaceEx's own flattening of the network (shipped beside it) is the independent yardstick; its guards
    ``y == 0`` (with invariant ``y >= 0``) are read as ``y <= 0``, the same states within the invariant."""
    component = None
    ours = load_spaceex(network, component).system
    theirs = load_spaceex(flat).system
    short = {name: name.rsplit(".", 1)[-1] for name in ours.state_names}
    assert sorted(short.values()) == sorted(theirs.state_names)
    order = [ours.state_names.index(next(k for k, v in short.items() if v == s)) for s in theirs.state_names]
    rng = np.random.default_rng(3)
    compared = 0
    for _ in range(3):
        x0 = rng.uniform(-1.0, 1.0, ours.dimension)
        if "bball" in network.name:
            x0[0], x0[1] = 5.0 + x0[0], 0.0  # above the floor
        mine = [m for m in ours.automaton.modes if m.invariant is None or m.invariant(tuple(x0), {}) >= 0]
        if not mine:
            continue
        mode = mine[0]
        key = mode.name.split("|")[0].rsplit(".", 1)[-1]  # SpaceEx names a product location by concatenation
        twin = [m.name for m in theirs.automaton.modes
                if (m.name.startswith(key) or len(theirs.automaton.modes) == 1)
                and (m.invariant is None or m.invariant(tuple(x0[order]), {}) >= 0)]
        if len(twin) != 1:
            continue
        a = simulate_continuous(ours, tuple(x0), duration=3.0, initial_mode=mode.name)
        b = simulate_continuous(theirs, tuple(x0[order]), duration=3.0, initial_mode=twin[0])
        assert len(a.events) == len(b.events)
        assert np.allclose(np.array(a.final_state)[order], b.final_state, rtol=tol, atol=tol)
        compared += 1
    assert compared >= 1


def test_constraints_parse_to_trees():
    tree = parse_constraints("acc_min <= aL <= acc_max & x' == -2*x^2 + sin(y) && t := 0", "test")
    assert tree[0] == "and" and len(tree[1]) == 4
    assert tree[1][0] == ("cmp", "<=", ("name", "acc_min"), ("name", "aL"))
    assert tree[1][2][0] == "cmp" and tree[1][2][2] == ("deriv", "x")
    assert tree[1][3] == ("assign", "t", ("num", 0.0))
    assert parse_constraints("(loc(a)==on & x >= 1) | (y<=2)", "t")[0] == "or"
    assert parse_constraints("((x + 1)) * 2 <= 3", "t")[0] == "cmp"
