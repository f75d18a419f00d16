"""Exports: DOT, JSON, affinity detection (hybrid.affine) and the SpaceEx round trip."""

import json
import math
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from hybrid import (
    AffineForm,
    Box,
    HybridAutomaton,
    HybridSystem,
    MemoryVariable,
    Mode,
    ModelDefinitionError,
    NotAffine,
    NotAffineError,
    Transition,
    affine_form,
    all_of,
    spacex_config,
    to_dot,
    to_json,
    to_spacex,
)
from hybrid.affine import system_affinity
from hybrid.examples import reference_models
from hybrid.export import SPACEEX_NAMESPACE

NS = {"sx": SPACEEX_NAMESPACE}
GRAVITY, RESTITUTION = 9.81, 0.8


# ---------------------------------------------------------------------------- fixtures


def bouncing_ball(guard=None, flow=None, direction=0):
    automaton = HybridAutomaton(
        name="ball",
        variables=("h", "v"),
        modes=(Mode(name="fall", invariant=lambda v, m: v[0], invariant_text="h >= 0",
                    description="free fall"),),
        transitions=(
            Transition(name="bounce", source="fall", target="fall",
                       guard=guard or all_of(lambda v, m: -v[0], lambda v, m: -v[1]),
                       guard_text="h <= 0 and v <= 0", reset_text="v := -e v", direction=direction),
        ),
    )
    return HybridSystem(
        automaton=automaton,
        state_names=("h", "v"),
        flows={"fall": flow or (lambda t, x, m: (x[1], -GRAVITY))},
        jumps={"bounce": lambda x, m: (x[0], -RESTITUTION * x[1])},
    )


BALL_BOX = Box(bounds={"h": (0.0, 10.0), "v": (-20.0, 20.0)})

RATE, T_LOW, T_HIGH = 0.1, 10.0, 30.0


def fahrenheit(celsius):
    return 1.8 * celsius + 32.0


def thermostat():
    """Exponential flows ``T' = -a (T - T_target)``; guards read Fahrenheit through the output map."""
    automaton = HybridAutomaton(
        name="thermostat",
        variables=("T_F",),
        memory=(MemoryVariable(name="switches", initial=0.0, description="number of switchings"),
                MemoryVariable(name="count", initial=3.0)),
        modes=(
            Mode(name="off", invariant=lambda v, m: v[0] - fahrenheit(18.0), invariant_text="T >= 18"),
            Mode(name="on", invariant=lambda v, m: fahrenheit(22.0) - v[0], invariant_text="T <= 22"),
        ),
        transitions=(
            Transition(name="heat", source="off", target="on", guard=lambda v, m: fahrenheit(19.0) - v[0],
                       guard_text="T <= 19", direction=+1, reset=lambda v, m: {"switches": m["switches"] + 1.0},
                       writes=("switches",), reset_text="switches := switches + 1"),
            Transition(name="cool", source="on", target="off", guard=lambda v, m: v[0] - fahrenheit(21.0),
                       guard_text="T >= 21", direction=-1, reset=lambda v, m: {"switches": m["switches"] + 1.0},
                       writes=("switches",)),
        ),
        initial_mode="off",
    )
    return HybridSystem(
        automaton=automaton,
        state_names=("T",),
        flows={"off": lambda t, x, m: (-RATE * (x[0] - T_LOW),), "on": lambda t, x, m: (-RATE * (x[0] - T_HIGH),)},
        output=lambda t, x: (fahrenheit(x[0]),),
    )


THERMOSTAT_BOX = Box(bounds={"T": (15.0, 25.0)}, memory={"switches": (0.0, 50.0)})

INFLOW, OUT1, OUT2, R1, R2 = 0.75, 0.5, 0.5, 0.5, 0.5


def water_tanks():
    automaton = HybridAutomaton(
        name="tanks",
        description='two tanks, one "hose"',
        variables=("x1", "x2"),
        modes=(
            Mode(name="fill1", description='hose in tank "1"', invariant=lambda v, m: v[1] - R2,
                 invariant_text="x2 >= r2", labels={"tank": 1, "levels": (R1, R2), "where": np.array([1.0, 0.0]),
                                                     "tags": {"b", "a"}, "f": fahrenheit}),
            Mode(name="fill2", description='hose in tank "2"',
                 invariant=all_of(lambda v, m: v[0] - R1, lambda v, m: 10.0 - v[1]),
                 invariant_text="x1 >= r1 and x2 <= 10"),
        ),
        transitions=(
            Transition(name="to2", source="fill1", target="fill2", guard=lambda v, m: R2 - v[1],
                       guard_text='x2 <= "r2"', priority=1),
            Transition(name="to1", source="fill2", target="fill1", guard=lambda v, m: R1 - v[0],
                       guard_text="x1 <= r1", priority=0),
            Transition(name="overflow", source="fill2", target="fill1", guard=lambda v, m: v[1] - 9.0,
                       guard_text="x2 >= 9", priority=2),
        ),
    )
    return HybridSystem(
        automaton=automaton,
        state_names=("x1", "x2"),
        flows={"fill1": lambda t, x, m: (INFLOW - OUT1, -OUT2), "fill2": lambda t, x, m: (-OUT1, INFLOW - OUT2)},
    )


TANKS_BOX = Box(bounds={"x1": (0.0, 10.0), "x2": (0.0, 10.0)})


def pendulum():
    automaton = HybridAutomaton(name="pendulum", variables=("theta", "omega"), modes=(Mode(name="swing"),),
                                transitions=())
    return HybridSystem(automaton=automaton, state_names=("theta", "omega"),
                        flows={"swing": lambda t, x, m: (x[1], -math.sin(x[0]))})


PENDULUM_BOX = Box(bounds={"theta": (-1.0, 1.0), "omega": (-2.0, 2.0)})


# ---------------------------------------------------------------------------- DOT


def test_dot_lists_modes_transitions_and_start_arrow():
    system = water_tanks()
    dot = to_dot(system)
    assert dot.startswith('digraph "tanks" {')
    assert dot.endswith("}\n")
    assert '"__start__" -> "fill1";' in dot
    for mode in system.automaton.mode_names:
        assert f'  "{mode}" [label="{mode}\\ninv: ' in dot
    assert '"fill1" -> "fill2" [label="[1] x2 <= \\"r2\\""];' in dot
    assert '"fill2" -> "fill1" [label="[0] x1 <= r1"];' in dot
    assert '"fill2" -> "fill1" [label="[2] x2 >= 9"];' in dot
    assert 'tooltip="hose in tank \\"1\\""' in dot
    assert dot == to_dot(water_tanks())


def test_dot_shows_direction_resets_and_jump_maps():
    dot = to_dot(thermostat())
    assert '"off" -> "on" [label="[0] T <= 19 ↑ / switches := switches + 1"];' in dot
    assert '"on" -> "off" [label="[0] T >= 21 ↓ / reset switches"];' in dot
    assert '"off" [label="off\\ninv: T >= 18"];' in dot
    ball = to_dot(bouncing_ball())
    assert '[label="[0] h <= 0 and v <= 0 / v := -e v; x⁺ = jump map"];' in ball
    assert "jump map" not in to_dot(bouncing_ball().automaton)


def test_dot_start_node_avoids_mode_names():
    a = HybridAutomaton(name='we"ird', modes=(Mode(name="__start__"),), transitions=(), variables=())
    dot = to_dot(a)
    assert dot.startswith('digraph "we\\"ird" {')
    assert '"__start___" -> "__start__";' in dot


def test_dot_rejects_other_objects():
    with pytest.raises(ModelDefinitionError, match="to_dot: model = 42; expected a HybridAutomaton or a HybridSystem"):
        to_dot(42)


# ---------------------------------------------------------------------------- affine_form


def test_affine_form_exact_coefficients():
    box = Box(bounds={"x": (-1.0, 3.0), "y": (0.0, 2.0)})
    form = affine_form(lambda z: (2.0 * z[0] - 0.5 * z[1] + 1.0, 7.0), ("x", "y"), box)
    assert isinstance(form, AffineForm)
    assert form.matrix == ((2.0, -0.5), (0.0, 0.0))
    assert form.offset == (1.0, 7.0)
    assert form.names == ("x", "y")
    assert form.max_residual <= 1e-15
    assert form.points_checked > 100
    assert form((1.0, 2.0)) == (2.0, 7.0)
    assert form.coefficients(0) == {"x": 2.0, "y": -0.5}


def test_affine_form_is_deterministic_for_a_seed():
    box = Box(bounds={"x": (0.0, 1.0)})
    results = {affine_form(lambda z: 0.1 * z[0] + 0.2, ("x",), box, seed=s) for s in (3, 3)}
    assert len(results) == 1


def test_affine_form_second_difference_witness():
    box = Box(bounds={"x": (-2.0, 2.0), "y": (0.0, 1.0)})

    def f(z):
        return (z[1], z[0] ** 2 - 1.0)

    result = affine_form(f, ("x", "y"), box)
    assert isinstance(result, NotAffine)
    assert result.kind == "second difference" and result.component == 1
    p, d = np.array(result.point), np.array(result.direction)
    second = f(p + d)[1] - 2.0 * f(p)[1] + f(p - d)[1]
    assert abs(second) == pytest.approx(result.second_difference, rel=1e-9)
    assert second == pytest.approx(2.0 * d[0] ** 2, rel=1e-9)
    assert result.relative > 1e-9
    assert "second difference" in result.reason and "along direction (x=" in result.reason


def test_affine_form_residual_with_discrete_coordinates():
    box = Box(bounds={"x": (0.0, 1.0)}, choices={"s": (-1.0, 1.0)})
    assert isinstance(affine_form(lambda z: 3.0 * z[1] + z[0], ("x", "s"), box), AffineForm)
    bilinear = affine_form(lambda z: z[0] * z[1], ("x", "s"), box)
    assert isinstance(bilinear, NotAffine)
    assert bilinear.kind == "residual" and bilinear.direction is None


def test_affine_form_non_finite_and_small_tolerance():
    box = Box(bounds={"x": (0.0, 1.0)})
    result = affine_form(lambda z: (z[0], math.inf if z[0] == 0.0 else 1.0), ("x",), box)
    assert isinstance(result, NotAffine) and result.kind == "non-finite"
    tiny = affine_form(lambda z: z[0] + 1e-7 * z[0] ** 2, ("x",), box)
    assert isinstance(tiny, NotAffine)
    assert isinstance(affine_form(lambda z: z[0] + 1e-7 * z[0] ** 2, ("x",), box, tol=1e-6), AffineForm)


def test_affine_form_memory_coordinate_and_errors():
    box = Box(bounds={"x": (0.0, 1.0)}, memory={"k": (0.0, 4.0)})
    assert affine_form(lambda z: z[1] + 2.0 * z[0], ("x", "k"), box).coefficients() == {"x": 2.0, "k": 1.0}
    with pytest.raises(ModelDefinitionError, match=r"coordinate 'q' is not declared by the box"):
        affine_form(lambda z: z[0], ("q",), box)
    with pytest.raises(ModelDefinitionError, match=r"tol = 0; expected a finite positive real"):
        affine_form(lambda z: z[0], ("x",), box, tol=0)
    with pytest.raises(ModelDefinitionError, match=r"samples = 0; expected a positive int"):
        affine_form(lambda z: z[0], ("x",), box, samples=0)
    with pytest.raises(ModelDefinitionError, match=r"function returned 'a'; expected a real number"):
        affine_form(lambda z: "a", ("x",), box)


def test_affine_form_as_dict_lists_every_field_in_order():
    form = affine_form(lambda z: (2.0 * z[0] - 0.5 * z[1] + 1.0, 7.0), ("x", "y"), Box(bounds={"x": (-1.0, 3.0),
                                                                                            "y": (0.0, 2.0)}))
    data = form.as_dict()
    assert list(data) == ["names", "matrix", "offset", "max_residual", "points_checked"]
    assert data["names"] == ["x", "y"] and data["matrix"] == [[2.0, -0.5], [0.0, 0.0]]
    assert data["offset"] == [1.0, 7.0] and data["points_checked"] == form.points_checked
    assert json.loads(json.dumps(data, allow_nan=False)) == data


def test_not_affine_as_dict_names_the_witness_and_writes_nonfinite_as_strings():
    box = Box(bounds={"x": (0.0, 1.0), "y": (0.0, 1.0)})
    result = affine_form(lambda z: (z[0], math.inf if z[0] == 0.5 else 1.0), ("x", "y"), box)
    assert isinstance(result, NotAffine) and result.kind == "non-finite"
    data = result.as_dict()
    assert list(data) == ["kind", "reason", "point", "direction", "second_difference", "relative", "component",
                          "time"]
    assert data["point"] == {"x": 0.5, "y": 0.5} and data["direction"] is None
    assert data["second_difference"] == "inf" and data["relative"] == "inf" and data["component"] == 1
    assert data["reason"] == result.reason and data["time"] is None
    json.dumps(data, allow_nan=False)
    curved = affine_form(lambda z: z[0] * z[0], ("x", "y"), box)
    assert curved.as_dict()["direction"] == curved.direction_by_name == dict(zip(("x", "y"), curved.direction))
    assert curved.point_by_name == dict(zip(("x", "y"), curved.point))


# ---------------------------------------------------------------------------- system_affinity


def test_system_affinity_of_the_ball():
    affinity = system_affinity(bouncing_ball(), BALL_BOX)
    assert affinity.coordinates.names == ("h", "v") and dict(affinity.coordinates.fixed_memory) == {}
    fall = affinity.modes["fall"]
    assert fall.flow.matrix == ((0.0, 1.0), (0.0, 0.0)) and fall.flow.offset == (0.0, -GRAVITY)
    assert [r.coefficients() for r in fall.invariant] == [{"h": 1.0}]
    bounce = affinity.transitions["bounce"]
    assert [g.coefficients() for g in bounce.guard] == [{"h": -1.0}, {"v": -1.0}]
    assert bounce.jump_map.matrix == ((1.0, 0.0), (0.0, -RESTITUTION)) and bounce.memory_reset is None
    assert [label for label, _ in affinity.items()] == [
        "flow of mode 'fall'", "invariant term 0 of mode 'fall'", "guard term 0 of transition 'bounce'",
        "guard term 1 of transition 'bounce'", "jump map of transition 'bounce'",
    ]
    assert affinity.first_defect() is None


def test_system_affinity_memory_identity_jump_and_defects():
    affinity = system_affinity(thermostat(), THERMOSTAT_BOX)
    assert affinity.coordinates.names == ("T", "switches")
    assert dict(affinity.coordinates.fixed_memory) == {"count": 3.0}
    heat = affinity.transitions["heat"]
    assert heat.jump_map.matrix == ((1.0, 0.0),) and heat.jump_map.points_checked == 0
    assert heat.memory_reset.matrix == ((0.0, 1.0),) and heat.memory_reset.offset == (1.0,)
    label, witness = system_affinity(pendulum(), PENDULUM_BOX).first_defect()
    assert label == "flow of mode 'swing'" and witness.kind == "second difference"
    clock = bouncing_ball(flow=lambda t, x, m: (x[1], -GRAVITY + 0.01 * t))
    label, witness = system_affinity(clock, BALL_BOX).first_defect()
    assert label == "flow of mode 'fall'" and witness.kind == "time" and witness.time == 1.0


def test_system_affinity_errors_name_the_purpose():
    with pytest.raises(ModelDefinitionError, match=r"system_affinity: system = .*expected a HybridSystem"):
        system_affinity(bouncing_ball().automaton, BALL_BOX)
    with pytest.raises(ModelDefinitionError, match=r"affinity test of system 'ball': box = 3"):
        system_affinity(bouncing_ball(), 3)
    with pytest.raises(ModelDefinitionError, match=r"my export: Box.memory names unknown memory"):
        system_affinity(bouncing_ball(), Box(bounds=dict(BALL_BOX.bounds), memory={"q": (0.0, 1.0)}),
                        what="my export")
    with pytest.raises(ModelDefinitionError, match=r"'switches' is written by a reset but the box gives it no"):
        system_affinity(thermostat(), Box(bounds={"T": (15.0, 25.0)}))


def test_affinity_lives_in_hybrid_affine_and_the_package_names_are_unchanged():
    import hybrid
    import hybrid.affine
    import hybrid.export

    for name in ("AffineForm", "NotAffine", "NotAffineError", "affine_form"):
        assert getattr(hybrid, name) is getattr(hybrid.affine, name)
        assert name not in hybrid.export.__all__
    assert set(hybrid.export.__all__) == {"SPACEEX_NAMESPACE", "to_dot", "to_json", "to_spacex", "spacex_config"}


# ---------------------------------------------------------------------------- JSON


def test_json_is_deterministic_and_has_ball_coefficients():
    first = json.dumps(to_json(bouncing_ball(), BALL_BOX), sort_keys=True)
    second = json.dumps(to_json(bouncing_ball(), BALL_BOX), sort_keys=True)
    assert first == second
    data = json.loads(first)
    assert data["kind"] == "hybrid_system"
    assert data["state_names"] == ["h", "v"]
    fall = data["modes"][0]
    assert fall["affine"]["flow"]["matrix"] == [[0.0, 1.0], [0.0, 0.0]]
    assert fall["affine"]["flow"]["offset"] == [0.0, -GRAVITY]
    assert fall["affine"]["invariant"][0]["matrix"] == [[1.0, 0.0]]
    bounce = data["transitions"][0]
    assert [g["matrix"] for g in bounce["affine"]["guard"]] == [[[-1.0, 0.0]], [[0.0, -1.0]]]
    assert bounce["affine"]["jump_map"]["matrix"] == [[1.0, 0.0], [0.0, -RESTITUTION]]
    assert bounce["affine"]["memory_reset"] is None and bounce["affine"]["not_affine"] == {}
    assert bounce["has_jump_map"] is True and bounce["direction"] == 0
    assert data["affinity"]["coordinates"] == ["h", "v"]


def test_json_of_automaton_and_labels():
    data = to_json(water_tanks().automaton)
    text = json.dumps(data, sort_keys=True)
    assert text == json.dumps(to_json(water_tanks().automaton), sort_keys=True)
    assert data["kind"] == "hybrid_automaton" and data["state_names"] is None
    assert data["description"] == 'two tanks, one "hose"'
    labels = data["modes"][0]["labels"]
    assert labels["levels"] == [R1, R2] and labels["where"] == [1.0, 0.0] and labels["tags"] == ["a", "b"]
    assert labels["f"].startswith("<function fahrenheit") and "0x" not in labels["f"]
    assert [t["priority"] for t in data["transitions"]] == [1, 0, 2]
    assert all(t["affine"] is None and t["has_jump_map"] is False for t in data["transitions"])
    with pytest.raises(ModelDefinitionError, match="pass the HybridSystem to get affine coefficients"):
        to_json(water_tanks().automaton, TANKS_BOX)


def test_json_labels_follow_the_policy_for_user_data():
    labels = {"z": math.inf, "a": (np.float64(-math.inf), math.nan), 3: {"y": 1, "b": 2}, "c": 1 + 2j, "s": {2, 1}}
    automaton = HybridAutomaton(name="a", modes=(Mode(name="x", labels=labels),), transitions=(), variables=())
    data = to_json(automaton)["modes"][0]["labels"]
    assert list(data) == ["3", "a", "c", "s", "z"] and list(data["3"]) == ["b", "y"]
    assert data == {"3": {"b": 2, "y": 1}, "a": ["-inf", "nan"], "c": [1.0, 2.0], "s": [1, 2], "z": "inf"}
    json.dumps(data, allow_nan=False)


def test_json_memory_and_reasons():
    data = to_json(thermostat(), THERMOSTAT_BOX)
    assert data["memory"] == [
        {"name": "switches", "initial": 0.0, "description": "number of switchings"},
        {"name": "count", "initial": 3.0, "description": ""},
    ]
    assert data["affinity"]["coordinates"] == ["T", "switches"]
    assert data["affinity"]["fixed_memory"] == {"count": 3.0}
    heat = data["transitions"][0]["affine"]
    assert heat["memory_reset"]["matrix"] == [[0.0, 1.0]] and heat["memory_reset"]["offset"] == [1.0]
    bad = to_json(pendulum(), PENDULUM_BOX)["modes"][0]["affine"]
    assert bad["flow"] is None
    assert bad["not_affine"]["flow"]["kind"] == "second difference"
    assert set(bad["not_affine"]["flow"]["point"]) == {"theta", "omega"}
    json.dumps(bad)


# ---------------------------------------------------------------------------- SpaceEx round trip


def parse_linear(text):
    """``(coefficients, constant)`` of a sum of ``c*name``, ``name`` and numbers, as emitted by the export."""
    coefficients, constant, sign = {}, 0.0, 1.0
    for token in re.findall(r"[+-]|[^\s+-]+", text):
        if token in "+-":
            sign = -sign if token == "-" else sign
            continue
        if "*" in token:
            value, name = token.split("*")
            coefficients[name] = coefficients.get(name, 0.0) + sign * float(value)
        elif re.fullmatch(r"[A-Za-z_]\w*", token):
            coefficients[token] = coefficients.get(token, 0.0) + sign
        else:
            constant += sign * float(token)
        sign = 1.0
    return coefficients, constant


def parse_constraints(text):
    """Each ``lhs op rhs`` of a ``&`` conjunction as ``(coefficients, constant)`` of ``expr >= 0``."""
    out = []
    for part in text.split(" & "):
        lhs, op, rhs = re.split(r"\s*(<=|>=)\s*", part)
        (a, b), (c, d) = parse_linear(lhs), parse_linear(rhs)
        if op == "<=":
            (a, b), (c, d) = (c, d), (a, b)
        coefficients = dict(a)
        for name, value in c.items():
            coefficients[name] = coefficients.get(name, 0.0) - value
        out.append((coefficients, b - d))
    return out


def parse_equations(text):
    """``name' == expr`` conjunctions as ``{name: (coefficients, constant)}``."""
    out = {}
    for part in text.split(" & "):
        lhs, rhs = part.split(" == ")
        assert lhs.endswith("'")
        out[lhs[:-1]] = parse_linear(rhs)
    return out


def evaluate(parsed, env):
    coefficients, constant = parsed
    return math.fsum([c * env[n] for n, c in coefficients.items()] + [constant])


def close(parsed_value, model_value, size):
    return abs(parsed_value - model_value) <= 1e-12 * max(1.0, abs(model_value), size)


def random_environments(system, box, count=25, seed=1):
    """Random states in ``box``, memory in its interval (or fixed at its initial value)."""
    rng = np.random.default_rng(seed)
    envs = []
    for _ in range(count):
        env = {n: float(rng.uniform(*box.bounds[n])) for n in system.state_names}
        for m in system.automaton.memory:
            interval = box.memory.get(m.name)
            env[m.name] = float(rng.uniform(*interval)) if interval else float(m.initial)
        envs.append(env)
    return envs


def always_true(system, term, envs):
    """Whether a guard term is a non-negative constant on ``envs`` (the export drops such terms)."""
    memory_names = [m.name for m in system.automaton.memory]
    values = {term(system.signals(0.0, tuple(env[n] for n in system.state_names)), {n: env[n] for n in memory_names})
              for env in envs}
    return len(values) == 1 and values.pop() >= 0.0


def round_trip(system, box):
    xml = to_spacex(system, box)
    root = ET.fromstring(xml)
    assert root.tag == f"{{{SPACEEX_NAMESPACE}}}sspaceex"
    assert root.get("version") == "0.2" and root.get("math") == "SpaceEx"
    components = root.findall("sx:component", NS)
    assert len(components) == 1 and components[0].get("id") == system.name
    component = components[0]
    a = system.automaton
    memory_names = [m.name for m in a.memory]
    params = [(p.get("name"), p.get("type")) for p in component.findall("sx:param", NS)]
    assert params == ([(n, "real") for n in (*system.state_names, *memory_names)]
                      + [(t.name, "label") for t in a.transitions])
    for p in component.findall("sx:param", NS):
        if p.get("type") == "real":
            assert (p.get("local"), p.get("d1"), p.get("d2"), p.get("dynamics")) == ("false", "1", "1", "any")
    locations = {loc.get("id"): loc for loc in component.findall("sx:location", NS)}
    by_name = {loc.get("name"): loc for loc in locations.values()}
    assert list(by_name) == list(a.mode_names)
    envs = random_environments(system, box)
    for mode in a.modes:
        loc = by_name[mode.name]
        flows = parse_equations(loc.find("sx:flow", NS).text)
        assert list(flows) == [*system.state_names, *memory_names]
        for env in envs:
            x = tuple(env[n] for n in system.state_names)
            memory = {n: env[n] for n in memory_names}
            dx = system.flow(mode.name, 0.0, x, memory)
            for name, value in zip(system.state_names, dx):
                assert close(evaluate(flows[name], env), value, max(map(abs, x)))
            for name in memory_names:
                assert flows[name] == ({}, 0.0)
        invariant = loc.find("sx:invariant", NS)
        if mode.invariant is None:
            assert invariant is None
            continue
        terms = parse_constraints(invariant.text)
        model_terms = getattr(mode.invariant, "terms", (mode.invariant,))
        assert len(terms) == len(model_terms)
        for env in envs:
            x = tuple(env[n] for n in system.state_names)
            memory = {n: env[n] for n in memory_names}
            for parsed, term in zip(terms, model_terms):
                assert close(evaluate(parsed, env), term(system.signals(0.0, x), memory), max(map(abs, x)))
    transitions = component.findall("sx:transition", NS)
    assert len(transitions) == len(a.transitions)
    for element, t in zip(transitions, a.transitions):
        assert element.find("sx:label", NS).text == t.name
        assert locations[element.get("source")].get("name") == t.source
        assert locations[element.get("target")].get("name") == t.target
        guard_element = element.find("sx:guard", NS)
        guard = parse_constraints(guard_element.text) if guard_element is not None else []
        model_terms = [term for term in getattr(t.guard, "terms", (t.guard,)) if not always_true(system, term, envs)]
        assert len(guard) == len(model_terms)
        assignment = parse_equations(element.find("sx:assignment", NS).text)
        assert list(assignment) == [*system.state_names, *memory_names]
        for env in envs:
            x = tuple(env[n] for n in system.state_names)
            memory = {n: env[n] for n in memory_names}
            size = max(map(abs, [*x, *memory.values()]))
            signals = system.signals(0.0, x)
            for parsed, term in zip(guard, model_terms):
                assert close(evaluate(parsed, env), term(signals, memory), size)
            after = system.jump(t.name, 0.0, x, memory)
            for name, value in zip(system.state_names, after):
                assert close(evaluate(assignment[name], env), value, size)
            new_memory = dict(memory)
            if t.reset is not None:
                new_memory.update(t.reset(signals, memory))
            for name in memory_names:
                assert close(evaluate(assignment[name], env), new_memory[name], size)
    return xml


def test_spacex_round_trip_bouncing_ball():
    xml = round_trip(bouncing_ball(), BALL_BOX)
    assert "<flow>h' == v &amp; v' == -9.81</flow>" in xml
    assert "<guard>h &lt;= 0.0 &amp; v &lt;= 0.0</guard>" in xml
    assert "<assignment>h' == h &amp; v' == -0.8*v</assignment>" in xml
    assert "level guard" not in xml
    assert xml == to_spacex(bouncing_ball(), BALL_BOX)


def test_spacex_round_trip_thermostat_with_memory_and_output_map():
    xml = round_trip(thermostat(), THERMOSTAT_BOX)
    assert "fires on a rising zero crossing of its guard (direction +1); exported as the level guard g >= 0" in xml
    assert "fires on a falling zero crossing of its guard (direction -1)" in xml
    assert "switches' == switches + 1.0" in xml and "count' == count" in xml and "count' == 0.0" in xml
    assert "held fixed for the affinity test: count = 3.0" in xml


def test_spacex_round_trip_water_tanks():
    xml = round_trip(water_tanks(), TANKS_BOX)
    assert "priorities of the model are not exported" in xml


def test_spacex_crossing_guard_of_ball():
    xml = to_spacex(bouncing_ball(direction=+1), BALL_BOX)
    assert "exported as the level guard g &gt;= 0" not in xml
    assert "exported as the level guard g >= 0" in xml


def test_spacex_rejects_non_affine_flow_with_witness():
    system = pendulum()
    with pytest.raises(NotAffineError, match=r"system 'pendulum': flow of mode 'swing' is not affine on the box: "
                                             r"second difference .* in component 1") as info:
        to_spacex(system, PENDULUM_BOX)
    err = info.value
    assert isinstance(err, ModelDefinitionError)
    p = np.array([err.point["theta"], err.point["omega"]])
    d = np.array([err.direction["theta"], err.direction["omega"]])

    def f(z):
        return system.flow("swing", 0.0, tuple(z), {})[1]

    second = f(p + d) - 2.0 * f(p) + f(p - d)
    assert abs(second) == pytest.approx(err.second_difference, rel=1e-9)
    assert abs(second) > 1e-9 * max(abs(f(p + d)), abs(f(p)), abs(f(p - d)))


def test_spacex_rejects_non_affine_guard_term():
    system = bouncing_ball(guard=all_of(lambda v, m: -v[1], lambda v, m: v[0] ** 2 - 1.0))
    with pytest.raises(NotAffineError, match=r"guard term 1 of transition 'bounce' is not affine") as info:
        to_spacex(system, BALL_BOX)
    err = info.value
    assert err.what == "guard term 1 of transition 'bounce'"
    h, dh = err.point["h"], err.direction["h"]
    second = (h + dh) ** 2 - 2.0 * h ** 2 + (h - dh) ** 2
    assert second == pytest.approx(err.second_difference, rel=1e-9)
    assert second == pytest.approx(2.0 * dh ** 2, rel=1e-9)


def test_spacex_rejects_time_dependent_flow():
    system = bouncing_ball(flow=lambda t, x, m: (x[1], -GRAVITY + math.sin(t)))
    with pytest.raises(NotAffineError, match=r"flow of mode 'fall' is not affine on the box: depends on time"):
        to_spacex(system, BALL_BOX)


def test_spacex_requires_memory_interval_and_identifiers():
    with pytest.raises(ModelDefinitionError, match=r"memory variable 'switches' is written by a reset but the box "
                                                   r"gives it no interval; declare Box.memory\['switches'\]"):
        to_spacex(thermostat(), Box(bounds={"T": (15.0, 25.0)}))
    with pytest.raises(ModelDefinitionError, match=r"missing coordinate\(s\) \['v'\]"):
        to_spacex(bouncing_ball(), Box(bounds={"h": (0.0, 1.0)}))
    odd = HybridAutomaton(name="odd", modes=(Mode(name="a-b"),), transitions=(), variables=("x",))
    system = HybridSystem(automaton=odd, state_names=("x",), flows={"a-b": lambda t, x, m: (0.0,)})
    with pytest.raises(ModelDefinitionError, match=r"mode name\(s\) \['a-b'\] are not SpaceEx identifiers"):
        to_spacex(system, Box(bounds={"x": (0.0, 1.0)}))


def test_memory_reset_must_return_exactly_its_writes():
    system = thermostat()
    a = system.automaton
    heat = a.transitions[0]
    broken = Transition(name=heat.name, source=heat.source, target=heat.target, guard=heat.guard,
                        writes=heat.writes, reset=lambda v, m: {"switches": 1.0, "count": 0.0})
    automaton = HybridAutomaton(name=a.name, variables=a.variables, memory=a.memory, modes=a.modes,
                                transitions=(broken, a.transitions[1]), initial_mode=a.initial_mode)
    system = HybridSystem(automaton=automaton, state_names=system.state_names, flows=system.flows,
                          output=system.output)
    with pytest.raises(ModelDefinitionError, match=r"reset of transition 'heat' returned keys \['count', 'switches'\], "
                                                   r"expected exactly writes = \['switches'\]"):
        to_spacex(system, THERMOSTAT_BOX)


def test_spacex_config():
    system = thermostat()
    cfg = spacex_config(system, {"T": (17.0, 19.0)}, "on", time_horizon=20.0, sampling_time=0.5)
    lines = cfg.splitlines()
    assert 'system = "thermostat"' in lines
    assert 'initially = "loc(thermostat)==on & T >= 17.0 & T <= 19.0 & switches == 0.0 & count == 3.0"' in lines
    assert "sampling-time = 0.5" in lines and "time-horizon = 20.0" in lines
    assert 'output-variables = "T"' in lines
    ball = spacex_config(bouncing_ball(), (10.0, 0.0), time_horizon=5.0)
    assert 'initially = "loc(ball)==fall & h == 10.0 & v == 0.0"' in ball.splitlines()
    with pytest.raises(ModelDefinitionError, match=r"x0 misses state\(s\) \['T'\] and names unknown variable\(s\) "
                                                   r"\['y'\]"):
        spacex_config(system, {"y": 1.0}, time_horizon=1.0)
    with pytest.raises(ModelDefinitionError, match=r"no mode 'idle'"):
        spacex_config(system, {"T": 18.0}, "idle", time_horizon=1.0)
    with pytest.raises(ModelDefinitionError, match=r"time_horizon = -1.0; expected a finite positive time"):
        spacex_config(system, {"T": 18.0}, time_horizon=-1.0)
    with pytest.raises(ModelDefinitionError, match=r"forbidden = 'T >= \"1\"'; expected one line of text"):
        spacex_config(system, {"T": 18.0}, time_horizon=1.0, forbidden='T >= "1"')
    with pytest.raises(ModelDefinitionError, match=r"x0\['T'\] = \(2.0, 1.0\); expected finite bounds"):
        spacex_config(system, {"T": (2.0, 1.0)}, time_horizon=1.0)


# ---------------------------------------------------------------------------- reference models


@pytest.mark.parametrize("name", sorted(reference_models()))
def test_reference_models_export_to_spacex(name):
    """The reference models are symbolic: to_spacex writes them from their expressions (hybrid.spaceex_export);
    read back by the SpaceEx importer, every flow, invariant, guard and jump agrees with the model's own
    functions at random points of the box."""
    from hybrid.spaceex_import import import_spaceex

    model = reference_models()[name]
    system = model.system
    xml = to_spacex(system, model.box)
    assert xml == to_spacex(system, model.box)
    back = import_spaceex(xml.encode(), source=name).system
    assert back.state_names == system.state_names and back.automaton.mode_names == system.automaton.mode_names
    names = [t.name for t in system.automaton.transitions]
    assert [t.name for t in back.automaton.transitions] == names
    for env in random_environments(system, model.box):
        x = tuple(env[n] for n in system.state_names)
        v = system.signals(0.0, x)
        for mode in system.automaton.modes:
            assert np.allclose(back.flow(mode.name, 0.0, x, {}), system.flow(mode.name, 0.0, x, {}), rtol=1e-12,
                               atol=1e-12)
            if mode.invariant is not None:
                assert (back.automaton.mode(mode.name).invariant(x, {}) >= 0) == (mode.invariant(v, {}) >= 0)
        for t, u in zip(system.automaton.transitions, back.automaton.transitions):
            # SpaceEx lets a jump happen only into its target's invariant: the import conjoins it (after the jump);
            # compared where the source mode may be (its invariant holds)
            source = system.automaton.mode(t.source).invariant
            if source is not None and source(v, {}) < 0:
                continue
            target = system.automaton.mode(t.target).invariant
            after = system.jump(t.name, 0.0, x, {})
            lands = target is None or target(system.signals(0.0, after), {}) >= 0
            assert (u.guard(x, {}) >= 0) == (t.guard(v, {}) >= 0 and lands)
            assert np.allclose(back.jump(u.name, 0.0, x, {}), system.jump(t.name, 0.0, x, {}), rtol=1e-12, atol=1e-12)
    cfg = spacex_config(model.system, model.x0, model.initial_mode, time_horizon=model.duration)
    assert f'initially = "loc({model.system.name})=={model.initial_mode} & ' in cfg
    data = to_json(model.system, model.box)
    assert json.dumps(data, sort_keys=True) == json.dumps(to_json(model.system, model.box), sort_keys=True)
    assert all(mode["affine"]["not_affine"] == {} for mode in data["modes"])
    assert all(t["affine"]["not_affine"] == {} for t in data["transitions"])
