"""SpaceEx round trips: import -> export -> import is the same model (symbolically and by simulation), and the
symbolic reference systems of hybrid.examples survive export -> import with their closed-form event times."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from hybrid import HybridAutomaton, HybridSystem, Mode, Transition
from hybrid.continuous import simulate_continuous
from hybrid.examples import bouncing_ball, bouncing_ball_impact_times, thermostat, thermostat_switch_times
from hybrid.examples import water_tanks, water_tanks_switch_times
from hybrid.spaceex_config import parse_config
from hybrid.spaceex_export import spaceex_cfg, spaceex_names, to_spaceex
from hybrid.spaceex_import import import_spaceex, load_spaceex
from hybrid.spaceex_syntax import SpaceExError
from hybrid.symbolic import atan2, coordinates, flow_map, ite, jump_map, minimum, render

DATA = Path(__file__).resolve().parents[1] / "data" / "spaceex"
IMPORTABLE = [
    ("arch2017/Building/SpaceEx/BLDC01.xml", "sys"),
    ("arch2017/Building/SpaceEx/BLDF01-simu.xml", "sys"),
    ("arch2017/Gear/SpaceEx/GRBX01-MES01.xml", "mesh_timed"),
    ("arch2017/Gear/SpaceEx/GRBX01.xml", None),
    ("spaceexparser/bball/bball.xml", None),
    ("spaceexparser/bball/bball_flattened.xml", None),
    ("spaceexparser/bball_timed/bball_timed.xml", None),
    ("spaceexparser/circle/circle.xml", None),
    ("spaceexparser/filtered_oscillator/filtered_oscillator.xml", None),
    ("spaceexparser/filtered_oscillator_16/filtered_oscillator_16.xml", None),
    ("spaceexparser/hamiltonian_system_1/hamiltonian_system_1.xml", None),
    ("spaceexparser/lotka_volterra_fourth_quadrant/lotka_volterra_fourth_quadrant.xml", None),
    ("spaceexparser/van_der_pol_fourth_quadrant/van_der_pol_fourth_quadrant.xml", None),
    ("hyst/heaterLygeros/heaterLygeros.xml", "sys1"),
]
CONSTANTS = {"heaterLygeros.xml": {"Tmax": 50.0}}  # its .cfg's initial set gives it


def signature(system: HybridSystem, names: dict[str, str] | None = None) -> list:
    """Every mode (name, invariant, flow) and transition (name, ends, guard, jump) as rendered text."""
    rename = (lambda n: names.get(n, n)) if names else (lambda n: n)

    def text(node):
        out = render(node) if node is not None else None
        if out and names:
            for old, new in sorted(names.items(), key=lambda kv: -len(kv[0])):
                out = out.replace(old, new)
        return out

    a = system.automaton
    out = [tuple(rename(s) for s in system.state_names)]
    for m in a.modes:
        out.append((rename(m.name), text(m.invariant), tuple(text(c) for c in system.flows[m.name].components)))
    for t in a.transitions:
        jump = system.jumps.get(t.name)
        out.append((rename(t.name), rename(t.source), rename(t.target), text(t.guard),
                    None if jump is None else tuple(text(c) for c in jump.components)))
    return out


def _run(system, x0, mode, duration):
    return simulate_continuous(system, tuple(x0), duration=duration, initial_mode=mode, rtol=1e-11, atol=1e-13)


@pytest.mark.parametrize("path, component", IMPORTABLE, ids=[Path(p).name for p, _ in IMPORTABLE])
def test_import_export_import_is_the_same_model(path, component):
    first = load_spaceex(DATA / path, component, constants=CONSTANTS.get(Path(path).name))
    xml = to_spaceex(first.system)
    second = import_spaceex(xml.encode(), source="export")
    names = {k: v for k, v in spaceex_names(first.system).items() if k != v}
    # the same expressions, up to the documented renaming to SpaceEx identifiers (a.b -> a_b)
    assert signature(second.system) == signature(first.system, names)
    # a fixed point: exporting the re-import writes the same XML (but for the comment listing the renaming)
    assert re.sub(r"<!--.*?-->", "", to_spaceex(second.system)) == re.sub(r"<!--.*?-->", "", xml)
    # the same simulation from a point inside the initial mode's invariant
    system = first.system
    rng = np.random.default_rng(7)
    for _ in range(500):
        x0 = rng.uniform(-1.0, 1.0, system.dimension)
        modes = [m for m in system.automaton.modes if m.invariant is None or m.invariant(tuple(x0), {}) > 0]
        if modes:
            break
    else:
        pytest.fail("no starting point found")
    mode = modes[0].name
    a = _run(system, x0, mode, 0.3)
    b = _run(second.system, x0, names.get(mode, mode), 0.3)
    assert [e.time for e in a.events] == pytest.approx([e.time for e in b.events], abs=1e-9)
    assert np.allclose(a.final_state, b.final_state, rtol=1e-9, atol=1e-9)


def _events(system, x0, mode, duration):
    return [e.time for e in simulate_continuous(system, x0, duration=duration, initial_mode=mode).events]


def test_the_reference_ball_exported_and_imported_bounces_at_the_closed_form_times():
    ref = bouncing_ball(restitution=0.5, h0=4.905, gravity=9.81)
    back = import_spaceex(to_spaceex(ref.system).encode()).system
    expected = bouncing_ball_impact_times(restitution=0.5, h0=4.905, gravity=9.81, count=6)
    got = _events(back, ref.x0, "fly", ref.duration)
    assert got[:6] == pytest.approx(expected, abs=1e-8)
    assert got == pytest.approx(_events(ref.system, ref.x0, "fly", ref.duration), abs=1e-9)


def test_the_reference_thermostat_and_tanks_survive_the_round_trip():
    ref = thermostat()
    back = import_spaceex(to_spaceex(ref.system).encode()).system
    got = _events(back, ref.x0, ref.initial_mode, ref.duration)
    assert got == pytest.approx(list(thermostat_switch_times(count=len(got))), abs=1e-8)
    tanks = water_tanks(inflow=0.75, outflow1=0.5, outflow2=0.5, x1_0=1.0, x2_0=1.0)
    back = import_spaceex(to_spaceex(tanks.system).encode()).system
    got = _events(back, tanks.x0, tanks.initial_mode, tanks.duration)
    assert got == pytest.approx(list(water_tanks_switch_times(inflow=0.75, outflow1=0.5, outflow2=0.5, x1_0=1.0,
                                                              x2_0=1.0, count=len(got))), abs=1e-8)


def test_the_exported_configuration_reads_back():
    ref = bouncing_ball()
    cfg = spaceex_cfg(ref.system, {"h": (1.0, 1.5), "v": (0.0, 0.0)}, horizon=3.0, forbidden="h >= 10")
    parsed = parse_config(cfg, "exported.cfg")
    assert parsed.system == "bouncing_ball" and parsed.horizon == 3.0
    assert parsed.forbidden == ("cmp", ">=", ("name", "h"), ("num", 10.0))
    assert ("loc", "bouncing_ball", "fly") in parsed.initially[1]
    with pytest.raises(SpaceExError, match="missing: \\['v'\\]"):
        spaceex_cfg(ref.system, {"h": (1.0, 1.5)}, horizon=3.0)


def _one_mode(flow, name="m"):
    x = coordinates("p", "q")
    automaton = HybridAutomaton(name="s", modes=(Mode(name=name, invariant=x.p >= 0),), transitions=(),
                                variables=("p", "q"), initial_mode=name)
    return HybridSystem(automaton=automaton, state_names=("p", "q"), flows={name: flow(x)})


@pytest.mark.parametrize("make, function", [
    (lambda x: flow_map(atan2(x.q, x.p), x.p), "atan2"),
    (lambda x: flow_map(minimum(x.q, x.p), x.p), "min"),
    (lambda x: flow_map(abs(x.q), x.p), "abs"),
    (lambda x: flow_map(ite(x.q >= 0, 1.0, -1.0), x.p), "Ite"),
])
def test_non_expressible_functions_are_named_with_their_place(make, function):
    with pytest.raises(SpaceExError) as info:
        to_spaceex(_one_mode(make))
    message = str(info.value)
    assert function in message and "mode 'm'" in message and "flow of" in message


def test_a_python_function_is_refused_by_name():
    with pytest.raises(SpaceExError, match="Python function"):
        to_spaceex(_one_mode(lambda x: (lambda t, s, m: (s[1], s[0]))))


def test_a_disjunctive_guard_becomes_one_transition_per_disjunct():
    x = coordinates("p", "q")
    automaton = HybridAutomaton(
        name="s", modes=(Mode(name="a"), Mode(name="b")),
        transitions=(Transition(name="go", source="a", target="b", guard=(x.p >= 1) | (x.q >= 2)),),
        variables=("p", "q"), initial_mode="a")
    system = HybridSystem(automaton=automaton, state_names=("p", "q"),
                          flows={"a": flow_map(1.0, 0.0), "b": flow_map(0.0, 0.0)},
                          jumps={"go": jump_map(x.p, 0.0)})
    back = import_spaceex(to_spaceex(system).encode()).system
    assert [t.name for t in back.automaton.transitions] == ["go_1", "go_2"]
    assert [render(t.guard) for t in back.automaton.transitions] == ["(p - 1)", "(q - 2)"]
    run = simulate_continuous(back, (0.0, 5.0), duration=1.0, initial_mode="a")
    assert run.events[0].time == 0.0 and run.final_state == (0.0, 0.0)


def _piecewise_system() -> HybridSystem:
    """p' = 1, q' = 0; when |p| >= 1 the jump p := ite(q >= 0, -0.5, -0.25)."""
    x = coordinates("p", "q")
    automaton = HybridAutomaton(
        name="saw", modes=(Mode(name="m"),),
        transitions=(Transition(name="back", source="m", target="m", guard=abs(x.p) >= 1.0),),
        variables=("p", "q"), initial_mode="m")
    return HybridSystem(automaton=automaton, state_names=("p", "q"), flows={"m": flow_map(1.0, 0.0)},
                        jumps={"back": jump_map(ite(x.q >= 0.0, -0.5, -0.25), x.q)})


def test_piecewise_guards_and_jumps_are_split_into_cases():
    system = _piecewise_system()
    xml = to_spaceex(system)
    assert xml.count("<transition ") == 4 and "split into 4 SpaceEx transitions" in xml
    back = import_spaceex(xml.encode()).system
    assert [t.name for t in back.automaton.transitions] == ["back_1", "back_2", "back_3", "back_4"]
    # closed form: from p = 0 the first jump is at t = 1, then every 1.5 s (q >= 0) or 1.25 s (q < 0)
    for q, period in ((1.0, 1.5), (-1.0, 1.25)):
        expected = [1.0 + k * period for k in range(3)]
        for model in (system, back):
            run = simulate_continuous(model, (0.0, q), duration=expected[-1] + 0.1, initial_mode="m")
            assert [e.time for e in run.events] == pytest.approx(expected, abs=1e-9)


def test_the_case_study_supervisor_exports_as_far_as_it_is_expressible():
    import dataclasses

    from visnav.scenario import load_scenario
    from visnav.supervisor import build_supervisor, measurement_box, measurement_system

    scenario = load_scenario("paper")
    model = build_supervisor(scenario.envelopes, scenario.supervisor, 2)
    system = measurement_system(model)
    with pytest.raises(SpaceExError, match="mode 'FAR\\|CLEAR': flow .*Python function"):
        to_spaceex(system)  # its zero flows are Python lambdas
    zero = flow_map(*([0.0] * system.dimension))
    symbolic = dataclasses.replace(system, flows={m: zero for m in system.automaton.mode_names})
    xml = to_spaceex(symbolic)
    back = import_spaceex(xml.encode()).system
    memory = [m.name for m in system.automaton.memory]
    assert back.state_names == (*system.state_names, *memory)
    names = spaceex_names(symbolic)
    assert back.automaton.mode_names == tuple(names[m] for m in system.automaton.mode_names)
    # every original transition is enabled exactly where one of its SpaceEx cases is, with the same reset
    box = measurement_box(model, 320.0)
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(300):
        x = tuple(float(rng.uniform(*box.bounds[n])) if n in box.bounds else float(rng.choice(box.choices[n]))
                  for n in system.state_names)
        m = {name: float(rng.choice([-1.0, 1.0])) if name in ("side", "arm_sign")
             else float(rng.choice([0.0, 1.0])) if name == "obstacle"
             else float(rng.uniform(0.0, 2.0)) for name in memory}
        v = system.signals(0.0, x)
        xb = (*x, *(m[k] for k in memory))
        for t in system.automaton.transitions:
            label = names[t.name]
            cases = [u for u in back.automaton.transitions if re.fullmatch(rf"{re.escape(label)}(_\d+)?", u.name)]
            assert cases
            enabled = [u for u in cases if u.guard(xb, {}) >= 0]
            assert bool(enabled) == (t.guard(v, m) >= 0), t.name
            if enabled and t.reset is not None:
                after = back.jump(enabled[0].name, 0.0, xb, {})
                for k, value in t.reset(v, m).items():
                    assert after[back.state_names.index(k)] == pytest.approx(value, abs=1e-12), (t.name, k)
                checked += 1
    assert checked >= 20
