import dataclasses
import itertools
import math

import networkx as nx
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hybrid import Conjunction, ModelDefinitionError, mode_graph
from hybrid import examples
from hybrid.examples import (
    FINDING_KINDS,
    ReferenceModel,
    bad_reset,
    bouncing_ball,
    bouncing_ball_apex_heights,
    bouncing_ball_impact_times,
    bouncing_ball_zeno_time,
    deadlock,
    nondeterministic,
    reference_models,
    retrigger,
    thermostat,
    thermostat_switch_times,
    unreachable,
    water_tanks,
    water_tanks_switch_times,
    water_tanks_zeno_time,
)

# Closed forms evaluated in double precision: a few hundred operations, each
# with a relative rounding error <= 2^-53 ≈ 1.1e-16, stay far below 1e-12.
CLOSED_FORM_RTOL = 1e-12

BALL_CASES = [
    dict(gravity=9.81, restitution=0.8, h0=1.0, v0=0.0),
    dict(gravity=9.81, restitution=0.5, h0=2.0, v0=3.0),  # thrown upwards
    dict(gravity=1.62, restitution=0.9, h0=0.5, v0=-2.0),  # thrown downwards (moon)
    dict(gravity=9.81, restitution=0.7, h0=1e-9, v0=-5.0),  # first-impact formula would cancel
    dict(gravity=9.81, restitution=0.6, h0=0.0, v0=4.0),  # launched from the ground
]


# ---------------------------------------------------------------------- catalogue
def test_reference_models_names_and_order():
    models = reference_models()
    assert list(models) == [
        "bouncing_ball",
        "thermostat",
        "water_tanks",
        "nondeterministic",
        "deadlock",
        "bad_reset",
        "retrigger",
        "unreachable",
    ]
    for name, model in models.items():
        assert isinstance(model, ReferenceModel)
        assert model.name == name == model.system.name
        assert model.duration > 0.0
        assert set(model.planted) <= set(FINDING_KINDS)
        assert model.description


def test_all_is_complete():
    # the physical models live in hybrid.examples_physical (issue 26: module length) and are re-exported here
    defined = {
        n for n, obj in vars(examples).items()
        if not n.startswith("_") and getattr(obj, "__module__", None) in (examples.__name__, "hybrid.examples_physical")
    }
    assert defined == set(examples.__all__) - {"FINDING_KINDS"}


@pytest.mark.parametrize("name", list(reference_models()))
def test_initial_state_in_box_and_invariant(name):
    model = reference_models()[name]
    a = model.system.automaton
    assert model.initial_mode == a.initial_mode
    assert model.box.names == model.system.state_names
    assert model.box.contains(model.x0)
    invariant = a.mode(model.initial_mode).invariant
    assert invariant is not None and invariant(model.x0, {}) >= 0.0


@pytest.mark.parametrize("name", list(reference_models()))
def test_texts_present(name):
    a = reference_models()[name].system.automaton
    for mode in a.modes:
        assert mode.description and mode.invariant_text
    for t in a.transitions:
        assert t.guard_text and t.reads
        # A transition without a jump map keeps the state; its reset text is then empty.
        assert bool(t.reset_text) == (t.name in reference_models()[name].system.jumps)


@pytest.mark.parametrize("name", list(reference_models()))
def test_maps_are_affine(name):
    """Flows, invariants (each conjunct), guards (each conjunct) and jump maps are affine on the box.

    An affine map satisfies f(a x + (1 - a) y) = a f(x) + (1 - a) f(y); with
    values of order 10 a mismatch above 1e-9 cannot be rounding.
    """
    model = reference_models()[name]
    system, a = model.system, model.system.automaton
    rng = np.random.default_rng(1)
    points = model.box.sample(rng, 20)
    maps = [lambda x, f=f: f(0.0, x, {}) for f in system.flows.values()]
    maps += [lambda x, r=r: r(x, {}) for r in system.jumps.values()]
    for g in [m.invariant for m in a.modes] + [t.guard for t in a.transitions]:
        terms = g.terms if isinstance(g, Conjunction) else (g,)
        maps += [lambda x, term=term: (term(x, {}),) for term in terms]
    for f in maps:
        for x, y, w in zip(points[::2], points[1::2], rng.uniform(-1.0, 2.0, 10)):
            lhs = np.asarray(f(tuple(w * x + (1.0 - w) * y)))
            rhs = w * np.asarray(f(tuple(x))) + (1.0 - w) * np.asarray(f(tuple(y)))
            np.testing.assert_allclose(lhs, rhs, rtol=0.0, atol=1e-9)


# ---------------------------------------------------------------------- a reference checker
def _grid(lo: float, hi: float) -> np.ndarray:
    """Points of [lo, hi] with step 1/32 when it divides the interval (then thresholds such
    as 0.5, 1.5 or 19 are exact grid points), else 129 points; both ends are included."""
    steps = (hi - lo) * 32.0
    n = int(steps) + 1 if steps == int(steps) and steps <= 4096 else 129
    return np.linspace(lo, hi, n)


def _exits(system, mode, x, invariant, steps=3, dt=1e-6):
    """Whether a few tiny Euler steps of the flow leave the invariant (second order included)."""
    y = np.asarray(x, dtype=float)
    for _ in range(steps):
        y = y + dt * np.asarray(system.flow(mode, 0.0, tuple(y), {}))
    return invariant(tuple(y), {}) < 0.0


def reference_findings(model: ReferenceModel) -> set[str]:
    """A brute-force structural check on a grid of the box (for these tests only).

    * unreachable_mode / unreachable_transition: not reachable from the
      initial mode in the mode graph; a transition also counts as unreachable
      when its guard holds at no grid point of its source invariant;
    * sink_mode: a reachable mode with no outgoing transition;
    * nondeterminism: two level-triggered transitions of one mode with equal
      priority enabled at one grid point of the mode's invariant;
    * deadlock: a grid point on the invariant's boundary where the flow leaves
      the invariant and no transition is enabled;
    * reset_outside_invariant: a jump from a grid point of the jump set that
      lands outside the target's invariant;
    * reset_retriggers: a level-triggered self-loop whose jump lands back on
      its guard for more than half of the jump-set grid points (a single
      Zeno point, like the bouncing ball's (0, 0), is not a defect).
    """
    system, a = model.system, model.system.automaton
    grids = [_grid(*model.box.bounds[n]) for n in system.state_names]
    points = [tuple(float(c) for c in p) for p in itertools.product(*grids)]
    graph = mode_graph(a)
    reachable = nx.descendants(graph, a.initial_mode) | {a.initial_mode}
    found = set()
    if set(a.mode_names) - reachable:
        found.add("unreachable_mode")
    for mode in a.mode_names:
        if mode in reachable and not a.outgoing(mode):
            found.add("sink_mode")
    for t in a.transitions:
        inv_src = a.mode(t.source).invariant or (lambda v, m: 0.0)
        inv_tgt = a.mode(t.target).invariant or (lambda v, m: 0.0)
        jump_set = [p for p in points if inv_src(p, {}) >= 0.0 and t.guard(p, {}) >= 0.0]
        if t.source not in reachable or not jump_set:
            found.add("unreachable_transition")
        landed = [system.jump(t.name, 0.0, p, {}) for p in jump_set]
        if any(inv_tgt(q, {}) < 0.0 for q in landed):
            found.add("reset_outside_invariant")
        if t.source == t.target and t.direction == 0 and landed:
            if sum(t.guard(q, {}) >= 0.0 for q in landed) > len(landed) / 2:
                found.add("reset_retriggers")
    for mode in a.modes:
        inv = mode.invariant or (lambda v, m: 1.0)
        out = a.outgoing(mode.name)
        for p in points:
            if inv(p, {}) < 0.0:
                continue
            enabled = [t for t in out if t.direction == 0 and t.guard(p, {}) >= 0.0]
            priorities = [t.priority for t in enabled]
            if len(priorities) != len(set(priorities)):
                found.add("nondeterminism")
            if inv(p, {}) == 0.0 and not enabled and _exits(system, mode.name, p, inv):
                found.add("deadlock")
    return found


@pytest.mark.parametrize("name", list(reference_models()))
def test_planted_is_exactly_what_a_checker_finds(name):
    model = reference_models()[name]
    assert reference_findings(model) == set(model.planted)


def test_the_reference_checker_sees_the_bouncing_ball_zeno_point():
    """The bounce lands on its own guard at (0, 0) only: one jump-set point in many."""
    ball = bouncing_ball()
    bounce = ball.system.automaton.transitions[0]
    assert bounce.guard(ball.system.jump("bounce", 0.0, (0.0, 0.0), {}), {}) >= 0.0
    assert bounce.guard(ball.system.jump("bounce", 0.0, (0.0, -1e-9), {}), {}) < 0.0


# ---------------------------------------------------------------------- bouncing ball
def _ball_by_roots(gravity, restitution, h0, v0, count):
    """Impact times by an independent route: each flight's end is the largest root of
    h + v t - g t²/2 (numpy.roots), the state is advanced with the model's own flow
    (constant acceleration, exact) and the bounce applied with the model's jump map."""
    system = bouncing_ball(gravity=gravity, restitution=restitution, h0=h0, v0=v0).system
    t, x = 0.0, (h0, v0)
    times = []
    for _ in range(count):
        roots = np.roots([-0.5 * gravity, x[1], x[0]])
        dt = max(0.0, float(np.max(roots.real)))
        accel = system.flow("fly", t, x, {})[1]
        t += dt
        x = (0.0, x[1] + accel * dt)
        times.append(t)
        x = system.jump("bounce", t, x, {})
    return times


@pytest.mark.parametrize("case", BALL_CASES)
def test_ball_impact_times_against_quadratic_roots(case):
    closed = bouncing_ball_impact_times(**case, count=12)
    independent = _ball_by_roots(**case, count=12)
    # numpy.roots goes through a companion-matrix eigenvalue solver: relative
    # error a few ulp per root; summed over 12 flights, 1e-12 relative is ample.
    # The absolute floor covers the first impact of the (1e-9 m, -5 m/s) case,
    # where numpy.roots' root 2e-10 s is only as accurate as eps times the
    # other root's size (1 s).
    np.testing.assert_allclose(closed, independent, rtol=1e-12, atol=1e-14)
    assert all(b > a for a, b in zip(closed, closed[1:]))


def test_ball_first_impact_stable_for_downward_throw():
    """h0 = 1e-9 m, v0 = -5 m/s: the impact is at t ≈ h0/|v0| = 2e-10 s, computed without cancellation."""
    (t1,) = bouncing_ball_impact_times(gravity=9.81, restitution=0.7, h0=1e-9, v0=-5.0, count=1)
    # Series h0/|v0| (1 - g h0/(2 v0²) + ...): the correction is ~2e-10 relative.
    assert t1 == pytest.approx(2e-10, rel=1e-9)


@pytest.mark.parametrize("case", BALL_CASES)
def test_ball_apex_heights_by_energy_and_by_flight_time(case):
    g, e, h0, v0 = case["gravity"], case["restitution"], case["h0"], case["v0"]
    heights = bouncing_ball_apex_heights(**case, count=10)
    # Energy: the k-th bounce keeps e^(2k) of the energy m (g h0 + v0²/2).
    energy = g * h0 + 0.5 * v0 * v0
    np.testing.assert_allclose(heights, [e ** (2 * k) * energy / g for k in range(1, 11)], rtol=CLOSED_FORM_RTOL)
    # Kinematics: a flight of duration Δ rises to g Δ²/8.  Δ is a difference of
    # impact times of order 1 s, so it carries ~1e-15 s of absolute rounding,
    # i.e. ~1e-13 relative for the shortest flights here: 1e-11 is safe.
    times = bouncing_ball_impact_times(**case, count=11)
    flights = np.diff(times)
    np.testing.assert_allclose(heights, g * flights**2 / 8.0, rtol=1e-11)


@pytest.mark.parametrize("case", BALL_CASES)
def test_ball_zeno_time_is_the_limit_of_impact_times(case):
    zeno = bouncing_ball_zeno_time(**case)
    # e <= 0.9: after 400 impacts the tail of the series is below 0.9^400 ≈ 5e-19 of it.
    times = bouncing_ball_impact_times(**case, count=400)
    assert times[-1] == pytest.approx(zeno, rel=CLOSED_FORM_RTOL)
    assert times[-1] <= zeno * (1.0 + CLOSED_FORM_RTOL)


def test_ball_zeno_time_elastic_is_infinite():
    assert bouncing_ball_zeno_time(restitution=1.0) == math.inf
    times = bouncing_ball_impact_times(restitution=1.0, count=4)
    np.testing.assert_allclose(np.diff(times), 2.0 * times[0], rtol=CLOSED_FORM_RTOL)


def test_ball_model_maps():
    ball = bouncing_ball(gravity=9.81, restitution=0.8, h0=1.0, v0=0.0)
    system, a = ball.system, ball.system.automaton
    assert system.state_names == ("h", "v") and a.mode_names == ("fly",)
    assert system.flow("fly", 0.3, (0.5, 2.0), {}) == (2.0, -9.81)
    (bounce,) = a.transitions
    assert (bounce.source, bounce.target, bounce.direction, bounce.guard_text) == ("fly", "fly", 0, "h <= 0 and v <= 0")
    assert isinstance(bounce.guard, Conjunction) and len(bounce.guard.terms) == 2
    assert bounce.guard((0.0, -1.0), {}) == 0.0  # on the ground, falling: enabled
    assert bounce.guard((0.0, 1.0), {}) < 0.0  # on the ground, rising: not enabled
    assert bounce.guard((0.2, -1.0), {}) < 0.0  # in the air
    assert system.jump("bounce", 1.0, (-1e-6, -5.0), {}) == (-1e-6, 4.0)  # h kept, not clamped
    assert a.mode("fly").invariant((0.0, 0.0), {}) == 0.0 and a.mode("fly").invariant((-0.1, 0.0), {}) < 0.0
    assert ball.x0 == (1.0, 0.0)
    assert ball.box.bounds["h"] == (0.0, 2.0)
    v1 = math.sqrt(2 * 9.81)
    assert ball.box.bounds["v"] == pytest.approx((-2 * v1, 2 * v1), rel=1e-15)
    impacts = bouncing_ball_impact_times(count=9)
    assert impacts[7] < ball.duration < impacts[8] < bouncing_ball_zeno_time()


def test_ball_box_contains_the_whole_motion_when_thrown_up_or_down():
    for v0 in (-3.0, 3.0):
        ball = bouncing_ball(h0=0.5, v0=v0)
        top = 0.5 + v0 * v0 / (2 * 9.81)
        assert ball.box.bounds["h"][1] >= top
        assert ball.box.bounds["v"][1] >= math.sqrt(2 * 9.81 * top)


@pytest.mark.parametrize(
    "kwargs, pattern",
    [
        (dict(gravity=0.0), r"bouncing_ball: gravity = 0\.0; expected a finite acceleration \[m/s²\] > 0"),
        (dict(gravity=math.nan), r"gravity = nan"),
        (dict(restitution=1.5), r"restitution = 1\.5; expected a coefficient of restitution in \(0, 1\]"),
        (dict(restitution=0.0), r"restitution = 0\.0"),
        (dict(h0=-1.0), r"h0 = -1\.0; expected an initial height >= 0 m"),
        (dict(v0=math.inf), r"v0 = inf; expected a finite initial velocity"),
        (dict(h0=0.0, v0=0.0), r"h0 = 0\.0, v0 = 0\.0 is the ball at rest on the ground"),
        (dict(gravity=True), r"gravity = True"),
        (dict(restitution="0.8"), r"restitution = '0\.8'"),
    ],
)
def test_ball_validation(kwargs, pattern):
    with pytest.raises(ModelDefinitionError, match=pattern):
        bouncing_ball(**kwargs)


def test_ball_closed_forms_validate():
    with pytest.raises(ModelDefinitionError, match=r"bouncing_ball_impact_times: count = -1; expected an integer >= 0"):
        bouncing_ball_impact_times(count=-1)
    with pytest.raises(ModelDefinitionError, match=r"bouncing_ball_apex_heights: count = 2\.0"):
        bouncing_ball_apex_heights(count=2.0)
    with pytest.raises(ModelDefinitionError, match=r"bouncing_ball_zeno_time: restitution = -0\.1"):
        bouncing_ball_zeno_time(restitution=-0.1)
    assert bouncing_ball_impact_times(count=0) == ()


# ---------------------------------------------------------------------- thermostat
def _thermostat_by_solve_ivp(model: ReferenceModel, count: int) -> list[float]:
    """Switch times from the model's own flows and guards, integrated by solve_ivp with a
    terminal event on the guard of the mode's only outgoing transition."""
    system, a = model.system, model.system.automaton
    t, y, mode = 0.0, np.array(model.x0), model.initial_mode
    times = []
    while len(times) < count:
        (out,) = a.outgoing(mode)
        if out.guard(tuple(y), {}) < 0.0:  # level-triggered: a guard already enabled fires at once

            def event(s, z, out=out):
                return out.guard(tuple(z), {})

            event.terminal = True
            event.direction = 1.0
            sol = solve_ivp(lambda s, z, mode=mode: system.flow(mode, s, tuple(z), {}), (t, t + 1e3), y,
                            method="DOP853", rtol=1e-12, atol=1e-12, events=event)
            assert sol.status == 1, sol.message
            t, y = float(sol.t_events[0][0]), sol.y_events[0][0]
        times.append(t)
        y = np.array(system.jump(out.name, t, tuple(y), {}))
        mode = out.target
    return times


THERMOSTAT_CASES = [
    dict(),
    dict(ambient=-5.0, heater=40.0, rate=0.3, low=18.0, high=22.5, T0=30.0),
    dict(ambient=0.0, heater=25.0, rate=0.05, low=15.0, high=20.0, T0=12.0, initially_on=True),
    dict(T0=19.0),  # on the threshold: the first switch is at t = 0
]


@pytest.mark.parametrize("case", THERMOSTAT_CASES)
def test_thermostat_switch_times_against_solve_ivp(case):
    closed = thermostat_switch_times(**case, count=9)
    numeric = _thermostat_by_solve_ivp(thermostat(**case), 9)
    # rtol = atol = 1e-12 keeps the temperature (of order 20) within ~1e-10 of
    # the true solution over these horizons; the guard is crossed at a rate
    # |Ṫ| >= 0.05 K/s, so each event time is off by at most ~1e-9 s, and nine
    # switches accumulate less than 1e-8 s (observed: at most 4e-10 s).
    np.testing.assert_allclose(numeric, closed, rtol=0.0, atol=1e-8)


def test_thermostat_phase_durations():
    times = thermostat_switch_times(count=5)
    off = math.log((21.0 - 10.0) / (19.0 - 10.0)) / 0.1
    on = math.log((30.0 - 19.0) / (30.0 - 21.0)) / 0.1
    assert times[0] == pytest.approx(math.log((20.0 - 10.0) / (19.0 - 10.0)) / 0.1, rel=CLOSED_FORM_RTOL)
    np.testing.assert_allclose(np.diff(times), [on, off, on, off], rtol=CLOSED_FORM_RTOL)
    assert thermostat_switch_times(T0=19.0, count=1) == (0.0,)


def test_thermostat_model_maps():
    room = thermostat()
    system, a = room.system, room.system.automaton
    assert a.mode_names == ("off", "on") and a.initial_mode == "off"
    assert system.flow("off", 0.0, (20.0,), {}) == pytest.approx((-1.0,))
    assert system.flow("on", 0.0, (20.0,), {}) == pytest.approx((1.0,))
    heat_on, heat_off = a.transitions
    assert (heat_on.name, heat_on.source, heat_on.target) == ("heat_on", "off", "on")
    assert (heat_off.name, heat_off.source, heat_off.target) == ("heat_off", "on", "off")
    assert heat_on.guard((19.0,), {}) == 0.0 and heat_on.guard((19.5,), {}) < 0.0 < heat_on.guard((18.0,), {})
    assert heat_off.guard((21.0,), {}) == 0.0 and heat_off.guard((20.5,), {}) < 0.0 < heat_off.guard((22.0,), {})
    assert a.mode("off").invariant((19.0,), {}) == 0.0 and a.mode("on").invariant((21.0,), {}) == 0.0
    assert room.box.bounds == {"T": (10.0, 30.0)}
    switches = thermostat_switch_times(count=9)
    assert switches[7] < room.duration < switches[8]
    assert thermostat(initially_on=True).initial_mode == "on"


@pytest.mark.parametrize(
    "kwargs, pattern",
    [
        (dict(low=22.0), r"ambient = 10\.0, low = 22\.0, high = 21\.0, heater = 30\.0; expected ambient < low < high"),
        (dict(ambient=19.0), r"expected ambient < low < high < heater"),
        (dict(heater=20.0), r"heater = 20\.0; expected ambient < low < high < heater"),
        (dict(rate=-0.1), r"thermostat: rate = -0\.1; expected a finite rate \[1/s\] > 0"),
        (dict(T0=18.0), r"T0 = 18\.0; expected a temperature in \[low, heater\) = \[19, 30\)"),
        (dict(T0=22.0, initially_on=True), r"T0 = 22\.0; expected a temperature in \(ambient, high\] = \(10, 21\]"),
        (dict(initially_on=1), r"initially_on = 1; expected True or False"),
    ],
)
def test_thermostat_validation(kwargs, pattern):
    with pytest.raises(ModelDefinitionError, match=pattern):
        thermostat(**kwargs)
    with pytest.raises(ModelDefinitionError, match=pattern.replace("thermostat:", "thermostat_switch_times:")):
        thermostat_switch_times(**kwargs, count=1)


# ---------------------------------------------------------------------- water tanks
TANK_CASES = [
    dict(),
    dict(inflow=0.9, outflow1=0.5, outflow2=0.6, r1=0.2, r2=0.1, x1_0=0.2, x2_0=1.5),
    dict(inflow=1.05, outflow1=0.55, outflow2=0.55, x1_0=0.3, x2_0=2.0),  # slow accumulation
    dict(inflow=1.6, outflow1=1.5, outflow2=0.3, r1=1.0, r2=0.5, x1_0=3.0, x2_0=0.6),  # uneven drains
]


def _tanks_by_flows(model: ReferenceModel, count: int) -> list[float]:
    """Switch times from the model's own flows and guards: the flow is constant in each
    mode and the guard affine, so the guard reaches zero at t* = -g(x) / (g(x + f) - g(x))."""
    system, a = model.system, model.system.automaton
    t, x, mode = 0.0, np.array(model.x0), model.initial_mode
    times = []
    for _ in range(count):
        (out,) = a.outgoing(mode)
        f = np.array(system.flow(mode, t, tuple(x), {}))
        g0 = out.guard(tuple(x), {})
        dt = max(0.0, -g0 / (out.guard(tuple(x + f), {}) - g0))
        t, x = t + dt, x + dt * f
        times.append(t)
        x = np.array(system.jump(out.name, t, tuple(x), {}))
        mode = out.target
    return times


@pytest.mark.parametrize("case", TANK_CASES)
def test_tanks_switch_times_against_the_flows(case):
    closed = water_tanks_switch_times(**case, count=40)
    independent = _tanks_by_flows(water_tanks(**case), 40)
    # Both are exact up to rounding; the independent route divides differences
    # of guard values, losing a few ulp of the state per phase (1e-13 relative
    # over 40 phases is still two orders below the tolerance).
    np.testing.assert_allclose(independent, closed, rtol=1e-11, atol=1e-13)


@pytest.mark.parametrize("case", TANK_CASES)
def test_tanks_switch_times_conserve_the_volume(case):
    """At each switch one tank sits at its threshold; the excess volume E falls at
    v1 + v2 - w, so the next phase lasts E(t_k) / v of the tank now draining."""
    w = case.get("inflow", 0.75)
    v1, v2 = case.get("outflow1", 0.5), case.get("outflow2", 0.5)
    r1, r2 = case.get("r1", 0.0), case.get("r2", 0.0)
    e0 = case.get("x1_0", 1.0) - r1 + case.get("x2_0", 1.0) - r2
    times = (0.0,) + water_tanks_switch_times(**case, count=30)
    for k in range(1, len(times) - 1):
        excess = e0 - (v1 + v2 - w) * times[k]
        draining = v1 if k % 2 == 1 else v2  # after to_fill2 (odd k) tank 1 drains
        # Both sides are differences of times of order 10 s that carry ~30
        # roundings of ~1e-15 s each: an absolute 1e-12 s is ample, and it is
        # needed once the phases are microseconds long.
        assert times[k + 1] - times[k] == pytest.approx(excess / draining, rel=CLOSED_FORM_RTOL, abs=1e-12)


@pytest.mark.parametrize("case", TANK_CASES)
def test_tanks_zeno_time_is_the_limit_of_switch_times(case):
    zeno = water_tanks_zeno_time(**case)
    # Two phases shrink the durations by (w - v1)(w - v2)/(v1 v2) <= 0.83 here:
    # after 800 switches the tail is below 0.83^400 ≈ 1e-32 of the total.
    times = water_tanks_switch_times(**case, count=800)
    assert times[-1] == pytest.approx(zeno, rel=CLOSED_FORM_RTOL)


def test_tanks_default_numbers():
    assert water_tanks_switch_times(count=4) == (2.0, 5.0, 6.5, 7.25)
    assert water_tanks_zeno_time() == 8.0


def test_tanks_without_zeno():
    case = dict(inflow=1.2, outflow1=0.5, outflow2=0.6)
    assert water_tanks_zeno_time(**case) == math.inf
    times = water_tanks_switch_times(**case, count=20)
    assert min(np.diff(times)) > 0.1  # the phases do not shrink
    assert "not Zeno" in water_tanks(**case).description


def test_tanks_model_maps():
    tanks = water_tanks(inflow=0.75, outflow1=0.5, outflow2=0.4, r1=0.1, r2=0.2)
    system, a = tanks.system, tanks.system.automaton
    assert a.mode_names == ("fill1", "fill2") and tanks.initial_mode == "fill1"
    assert system.flow("fill1", 0.0, (1.0, 1.0), {}) == pytest.approx((0.25, -0.4))
    assert system.flow("fill2", 0.0, (1.0, 1.0), {}) == pytest.approx((-0.5, 0.35))
    to_fill2, to_fill1 = a.transitions
    assert (to_fill2.source, to_fill2.target, to_fill1.source, to_fill1.target) == ("fill1", "fill2", "fill2", "fill1")
    assert to_fill2.guard((5.0, 0.2), {}) == 0.0 and to_fill2.guard((5.0, 0.3), {}) < 0.0
    assert to_fill1.guard((0.1, 5.0), {}) == 0.0 and to_fill1.guard((0.2, 5.0), {}) < 0.0
    assert a.mode("fill1").invariant((0.0, 0.2), {}) == 0.0 and a.mode("fill2").invariant((0.1, 0.0), {}) == 0.0
    assert tanks.box.bounds["x1"][0] == 0.1 and tanks.box.bounds["x2"][0] == 0.2
    switches = water_tanks_switch_times(outflow2=0.4, r1=0.1, r2=0.2, count=9)
    assert switches[7] < tanks.duration < switches[8]


@pytest.mark.parametrize(
    "kwargs, pattern",
    [
        (dict(inflow=0.5), r"inflow = 0\.5 with outflow1 = 0\.5, outflow2 = 0\.5; expected inflow > max"),
        (dict(outflow1=0.0), r"outflow1 = 0\.0; expected a finite flow rate > 0"),
        (dict(r2=-1.0), r"r2 = -1\.0; expected a threshold level >= 0"),
        (dict(x1_0=-0.5), r"x1_0 = -0\.5; expected an initial level >= r1 = 0"),
        (dict(x2_0=0.0), r"x2_0 = 0\.0; expected an initial level > r2 = 0 \(the model starts in 'fill1'"),
    ],
)
def test_tanks_validation(kwargs, pattern):
    for f in (water_tanks, water_tanks_zeno_time):
        with pytest.raises(ModelDefinitionError, match=pattern):
            f(**kwargs)
    with pytest.raises(ModelDefinitionError, match=pattern):
        water_tanks_switch_times(**kwargs, count=3)
    with pytest.raises(ModelDefinitionError, match=r"water_tanks_switch_times: count = True"):
        water_tanks_switch_times(count=True)


# ---------------------------------------------------------------------- planted defects
def test_nondeterministic_overlap():
    model = nondeterministic()
    a = model.system.automaton
    assert [t.name for t in a.enabled("a", (1.2,), {})] == ["a_to_b"]
    both = a.enabled("a", (1.5,), {})
    assert [t.name for t in both] == ["a_to_b", "a_to_c"] and both[0].priority == both[1].priority
    assert a.mode("a").invariant((1.5,), {}) >= 0.0
    assert model.system.jump("b_to_a", 3.0, (3.0,), {}) == (0.0,)
    assert model.system.flow("c", 0.0, (1.0,), {}) == (-1.0,)


def test_deadlock_at_the_boundary():
    model = deadlock()
    a = model.system.automaton
    run = a.mode("run")
    assert run.invariant((1.0,), {}) == 0.0 and model.system.flow("run", 1.0, (1.0,), {}) == (1.0,)
    assert a.enabled("run", (1.0,), {}) == ()
    # The guard holds inside the invariant (x <= -0.5), and its jump lands inside, off the guard.
    assert [t.name for t in a.enabled("run", (-0.75,), {})] == ["rewind"]
    assert model.system.jump("rewind", 0.0, (-0.75,), {}) == (0.25,)


def test_bad_reset_lands_outside():
    model = bad_reset()
    a = model.system.automaton
    landed = model.system.jump("reverse", 1.0, (1.0,), {})
    assert landed == (2.0,) and a.mode("down").invariant(landed, {}) < 0.0
    assert isinstance(a.mode("down").invariant, Conjunction)


def test_retrigger_lands_on_its_guard():
    model = retrigger()
    (fire,) = model.system.automaton.transitions
    assert fire.source == fire.target and fire.direction == 0
    assert fire.guard(model.system.jump("fire", 1.0, (1.0,), {}), {}) >= 0.0


def test_unreachable_mode_has_no_incoming_transition():
    model = unreachable()
    graph = mode_graph(model.system.automaton)
    assert graph.in_degree("orphan") == 0 and model.initial_mode == "main"
    assert [t.name for t in model.system.automaton.outgoing("orphan")] == ["orphan_to_main"]


# ---------------------------------------------------------------------- ReferenceModel checks
@pytest.mark.parametrize(
    "change, pattern",
    [
        (dict(planted=("zeno",)), r"reference model 'thermostat': planted = \('zeno',\); expected distinct kinds"),
        (dict(planted=("deadlock", "deadlock")), r"planted = \('deadlock', 'deadlock'\)"),
        (dict(initial_mode="on"), r"initial_mode = 'on' but the automaton starts in 'off'"),
        (dict(x0=(20.0, 1.0)), r"x0 has 2 values; expected 1 \(T\)"),
        (dict(x0=(35.0,)), r"x0 = \(35\.0,\) lies outside the box T ∈ \[10, 30\]"),
        (dict(x0=(15.0,)), r"x0 = \(15\.0,\) violates the invariant of the initial mode 'off' \(T >= 19\)"),
        (dict(duration=0.0), r"duration = 0\.0; expected a finite time > 0 s"),
        (dict(system="system"), r"system = 'system'; expected a HybridSystem"),
    ],
)
def test_reference_model_validation(change, pattern):
    with pytest.raises(ModelDefinitionError, match=pattern):
        dataclasses.replace(thermostat(), **change)


def test_reference_model_box_must_cover_the_states():
    from hybrid import Box

    with pytest.raises(ModelDefinitionError, match=r"missing coordinate\(s\) \['T'\], unknown coordinate\(s\) \['x'\]"):
        dataclasses.replace(thermostat(), box=Box(bounds={"x": (0.0, 1.0)}))


def test_reference_model_is_frozen():
    model = thermostat()
    with pytest.raises(dataclasses.FrozenInstanceError):
        model.duration = 1.0  # type: ignore[misc]
