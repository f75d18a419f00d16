"""ARCH-COMP FALS benchmark CC: five chasing cars (after Hu et al.), as verification problems.

The model is ARCH-COMP's ``cars.mdl`` (a Simulink model of five Stateflow charts; the copy read is the one
FalStar ships, ``falstar/resource/simulink/cars.mdl``, the model ARCH-COMP 2019-2022 used).  Car 1 leads,
driven by the inputs ``throttle, brake ∈ [0, 1]``; cars 2..5 each follow the car ahead with a three-mode
automaton.  Positions ``y_i`` decrease as the cars advance (car ``i`` starts at ``10 (i - 1)``, at rest);
``d_i = y_i - y_{i-1}`` is the gap to the car ahead::

    car 1:      v1' = -throttle - brake v1,   y1' = v1
    Chasing:    v' = 1,    y' = -v           Chasing -> Keeping  when d <= 10
    Keeping:    v' = 0,    y' = +v (!)       Keeping -> Chasing  when d >= 15,  Keeping -> Braking when d <= 5
    Braking:    v' = -v,   y' = -v           Braking -> Chasing  when d >= 20

Every follower starts in Keeping.  **The sign of Keeping** (``docs/arch.md``): in ``cars.mdl`` the keeping
mode reads ``y_dot = v`` while chasing and braking read ``y_dot = -v``: a keeping car *backs away* at its
speed instead of holding it, which is what the competition's model does and what its published results were
obtained with.  The benchmark is that model, so it is the default; ``keeping_sign=-1`` gives the
consistent reading (``y' = -v``, the speed held), which is what the follower's description ("keeping" the
distance at a constant speed) and the two other modes suggest.

Between events the dynamics are linear with constant inputs and are solved in closed form; a guard is
detected at the 0.05 s samples (and at every input switch) and its crossing located by bisection on the
closed form (to 1e-12 s), as Simulink's zero-crossing detection locates it; a guard crossed and crossed back
within one 0.05 s step is not seen (nor is it by a solver that checks signs at its step ends).

Requirements (ARCH-COMP 2019-2022 FALS reports, "CC")::

    CC1  always[0,100] y5 - y4 <= 40
    CC2  always[0,70] eventually[0,30] y5 - y4 >= 15
    CC3  always[0,80] ((always[0,20] y2 - y1 <= 20) or (eventually[0,20] y5 - y4 >= 40))
    CC4  always[0,65] eventually[0,30] always[0,5] y5 - y4 >= 8
    CC5  always[0,72] eventually[0,8] ((always[0,5] y2 - y1 >= 9) -> (always[5,20] y5 - y4 >= 9))
    CCx  always[0,50] (y2 - y1 > 7.5 and y3 - y2 > 7.5 and y4 - y3 > 7.5 and y5 - y4 > 7.5)

Inputs: throttle and brake piecewise constant over [0, 100] s, 7 and 3 control points by default.

Sensitivities (the ``whitebox`` search's gradients): :func:`sensitivities_cars` runs the same closed forms on
dual numbers (:mod:`analysis.dual`), each event time given its derivative by the implicit function theorem.
Plain float inputs take :func:`simulate_floats`, the same closed forms with the same floating-point operations in
the same order (bit-identical traces), without the dual-number checks and with each step's state-free terms
computed once per input segment and step length.

Load them with ``visnav verify examples/arch/chasing_cars.py:cc1`` (``cc2`` .. ``cc5``, ``ccx``); :func:`problems`
returns them keyed by requirement name.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from functools import partial

import numpy as np

from analysis.dual import Dual, exp, expm1, split, value_of
from analysis.verify.signals import InputSignal, PiecewiseConstantInput, signal_problem
from analysis.stl import SignalTrace
from analysis.verify import Requirement, VerificationProblem

HORIZON = 100.0
"""Simulated time and span of the inputs' control points [s]."""
SAMPLE = 0.05
"""Sample period of the trace and of guard detection [s]."""
CARS = 5
MODES = ("chasing", "keeping", "braking")
OUTPUTS = ("y1", "y2", "y3", "y4", "y5", "v1", "v2", "v3", "v4", "v5")

REQUIREMENTS: dict[str, tuple[str, str]] = {
    "CC1": ("always[0, 100] (y5 - y4 <= 40)", "car 5 never falls more than 40 behind car 4"),
    "CC2": ("always[0, 70] eventually[0, 30] (y5 - y4 >= 15)", "every 30 s, car 5 is at least 15 behind car 4"),
    "CC3": ("always[0, 80] ((always[0, 20] (y2 - y1 <= 20)) or (eventually[0, 20] (y5 - y4 >= 40)))",
            "a gap above 20 between cars 1 and 2 within 20 s means a gap of 40 between cars 4 and 5 within 20 s"),
    "CC4": ("always[0, 65] eventually[0, 30] always[0, 5] (y5 - y4 >= 8)",
            "every 30 s, cars 4 and 5 keep 8 apart for 5 s"),
    "CC5": ("always[0, 72] eventually[0, 8] ((always[0, 5] (y2 - y1 >= 9)) -> (always[5, 20] (y5 - y4 >= 9)))",
            "within every 8 s, a gap of 9 between cars 1 and 2 for 5 s is followed by one between cars 4 and 5"),
    "CCx": ("always[0, 50] ((y2 - y1 > 7.5) and (y3 - y2 > 7.5) and (y4 - y3 > 7.5) and (y5 - y4 > 7.5))",
            "every gap stays above 7.5 for 50 s"),
}
"""Requirement name -> (formula, description), as published in the ARCH-COMP FALS reports."""

_GUARDS = {  # mode -> ((comparison, threshold, next mode), ...): d <= c is "le", d >= c is "ge"
    "chasing": (("le", 10.0, "keeping"),),
    "keeping": (("ge", 15.0, "chasing"), ("le", 5.0, "braking")),
    "braking": (("ge", 20.0, "chasing"),),
}

_CALM = {mode: (max((c for kind, c, _ in guards if kind == "le"), default=-math.inf),
                min((c for kind, c, _ in guards if kind == "ge"), default=math.inf))
         for mode, guards in _GUARDS.items()}
"""Mode -> ``(lo, hi)``: no guard of the mode holds while ``lo < d < hi`` (read off :data:`_GUARDS`)."""


def _phi1(x: float) -> float:
    """(1 - e^-x) / x, accurate for small x."""
    return 1.0 - x / 2 + x * x / 6 if abs(x) < 1e-5 else -expm1(-x) / x


def _phi2(x: float) -> float:
    """(x - 1 + e^-x) / x^2, accurate for small x."""
    return 0.5 - x / 6 + x * x / 24 if abs(x) < 1e-3 else (x + expm1(-x)) / (x * x)


def lead(y: float, v: float, throttle: float, brake: float, s: float) -> tuple[float, float]:
    """Car 1 after ``s`` seconds of ``v' = -throttle - brake v``, ``y' = v`` (closed form)."""
    x = brake * s
    return (y + v * s * _phi1(x) - throttle * s * s * _phi2(x),
            v * exp(-x) - throttle * s * _phi1(x))


def follower(mode: str, y: float, v: float, s: float, keeping_sign: float) -> tuple[float, float]:
    """A follower after ``s`` seconds in ``mode`` (closed form)."""
    if mode == "chasing":
        return y - v * s - s * s / 2, v + s
    if mode == "keeping":
        return y + keeping_sign * v * s, v
    decay = exp(-s)
    return y - v * (1.0 - decay), v * decay


def _advance(state: list[tuple[float, float]], modes: list[str], u: float, b: float, s: float,
             sign: float) -> list[tuple[float, float]]:
    first = lead(state[0][0], state[0][1], u, b, s)
    return [first] + [follower(modes[i], state[i][0], state[i][1], s, sign) for i in range(1, CARS)]


def _fires(kind: str, gap: float, threshold: float) -> bool:
    return gap <= threshold if kind == "le" else gap >= threshold


def _switch(positions: list[float], modes: list[str]) -> bool:
    """Take every enabled transition (in car order, chains at one instant allowed) at the cars' ``positions``
    ``y1..y5``; whether any was taken."""
    taken = False
    for _ in range(3):  # no guard of a mode's successor is enabled by the same gap twice: chains have length <= 2
        changed = False
        for i in range(1, CARS):
            gap = positions[i] - positions[i - 1]
            lo, hi = _CALM[modes[i]]
            if lo < gap < hi:
                continue  # no guard of the mode holds
            for kind, threshold, target in _GUARDS[modes[i]]:
                if _fires(kind, gap, threshold):
                    modes[i], changed = target, True
                    break
        taken |= changed
        if not changed:
            break
    return taken


def _gap(state, modes, u, b, i, s, sign) -> float:
    """``y_i - y_{i-1}`` after ``s`` seconds in the current modes."""
    ahead = lead(*state[0], u, b, s) if i == 1 else follower(modes[i - 1], *state[i - 1], s, sign)
    return follower(modes[i], *state[i], s, sign)[0] - ahead[0]


def _crossing(g, lo: float, hi: float, g_lo: float, g_hi: float) -> float:
    """The root of ``g`` in ``(lo, hi]`` (``g_lo < 0 <= g_hi``, ``g`` continuous) by the Illinois method, to 1e-12 s."""
    side = 0
    for _ in range(200):
        if hi - lo <= 1e-12:
            break
        mid = hi - g_hi * (hi - lo) / (g_hi - g_lo)
        if not lo < mid < hi:
            mid = (lo + hi) / 2
        g_mid = g(mid)
        if g_mid >= 0:
            hi, g_hi = mid, g_mid
            if side == 1:
                g_lo /= 2
            side = 1
        else:
            lo, g_lo = mid, g_mid
            if side == -1:
                g_hi /= 2
            side = -1
        if g_mid == 0 or abs(hi - lo) <= 1e-12:
            break
    return hi


def _first_event(state, modes, u, b, h, sign, end) -> float | None:
    """The earliest guard crossing in ``(0, h]`` seen at the step's end state ``end``, located on the closed form.

    A guard ``d <= c`` is the root of ``c - d``, ``d >= c`` of ``d - c``: negative before, non-negative at the end.
    ``None`` when no guard holds at the end.  The root is found on the values; on dual numbers (sensitivities)
    its derivative is the implicit function's, ``d tau / d p = -(d g / d p) / (d g / d s)`` (:func:`_event_time`).
    """
    values = [(value_of(y), value_of(v)) for y, v in state]
    uv, bv = value_of(u), value_of(b)
    dual = isinstance(u, Dual) or isinstance(b, Dual) or any(isinstance(x, Dual) for pair in state for x in pair)
    best = None
    for i in range(1, CARS):
        gap_end = value_of(end[i][0]) - value_of(end[i - 1][0])
        for kind, threshold, _ in _GUARDS[modes[i]]:
            if not _fires(kind, gap_end, threshold):
                continue
            sense = 1.0 if kind == "ge" else -1.0

            def g(s, i=i, threshold=threshold, sense=sense, state=values, u=uv, b=bv):
                return sense * (_gap(state, modes, u, b, i, s, sign) - threshold)

            tau = _crossing(g, 0.0, value_of(h), g(0.0), sense * (gap_end - threshold))
            if best is None or tau < value_of(best):
                best = _event_time(tau, g, partial(g, state=state, u=u, b=b)) if dual else tau
    return best


def _event_time(tau: float, g_values, g_duals) -> Dual:
    """The crossing time ``tau`` of ``g(s, p) = 0`` (found on the values) with its derivative by the implicit
    function theorem: ``d tau / d p = -(dg/dp) / (dg/ds)`` at ``tau`` (the event-time correction: advancing the
    closed form by this ``tau`` gives the states after the event their saltation).  ``dg/ds``: ``g`` of the
    values on a dual time; ``dg/dp``: ``g`` of the dual state at the float time."""
    slope = g_values(Dual(tau, np.ones(1))).grad[0]
    partial = g_duals(tau)
    if not isinstance(partial, Dual) or slope == 0:
        return tau  # a grazing crossing: no derivative (the event time is not differentiable there)
    return Dual(tau, -partial.grad / slope)


# The float fast path (no sensitivities asked): the same closed forms with the same floating-point operations in the
# same order, so its traces are bit-identical to the generic path's on floats
# (tests/examples/test_arch_chasing_cars_fast.py checks the two against each other).  Per input segment and step
# length, the state-free terms of the closed forms (``e^-bs``, ``phi1``, ``phi2``, ``e^-s`` and the input terms) are
# computed once; the state is two flat lists.


def _phi1_float(x: float) -> float:
    """:func:`_phi1` on a float (``math.expm1``, which :func:`analysis.dual.expm1` calls on floats)."""
    return 1.0 - x / 2 + x * x / 6 if abs(x) < 1e-5 else -math.expm1(-x) / x


def _phi2_float(x: float) -> float:
    """:func:`_phi2` on a float."""
    return 0.5 - x / 6 + x * x / 24 if abs(x) < 1e-3 else (x + math.expm1(-x)) / (x * x)


def _lead_curve(y: float, v: float, throttle: float, brake: float) -> Callable[[float], float]:
    """``s -> lead(y, v, throttle, brake, s)[0]`` on floats (the same operations)."""
    def position(s: float) -> float:
        x = brake * s
        return y + v * s * _phi1_float(x) - throttle * s * s * _phi2_float(x)
    return position


def _follower_curve(mode: str, y: float, v: float, keeping_sign: float) -> Callable[[float], float]:
    """``s -> follower(mode, y, v, s, keeping_sign)[0]`` on floats (the same operations, the mode's branch taken
    once)."""
    if mode == "chasing":
        return lambda s: y - v * s - s * s / 2
    if mode == "keeping":
        speed = keeping_sign * v
        return lambda s: y + speed * s
    return lambda s: y - v * (1.0 - math.exp(-s))


def _coefficients(u: float, b: float, s: float) -> tuple[float, ...]:
    """The state-free terms of the closed forms over ``s`` seconds: ``lead`` is ``(y + v s phi1 - c2, v e - c1)``,
    chasing ``(y - v s - s^2/2, v + s)``, braking ``(y - v (1 - e^-s), v e^-s)``."""
    x = b * s
    p1 = _phi1_float(x)
    decay = math.exp(-s)
    return p1, math.exp(-x), u * s * p1, u * s * s * _phi2_float(x), s * s / 2, 1.0 - decay, decay


def _chain(modes: list[str]) -> tuple[tuple[int, str, float, float], ...]:
    """The followers as ``(car, mode, lo, hi)``: their gap is calm (no guard holds) while ``lo < d < hi``."""
    return tuple((i, modes[i], *_CALM[modes[i]]) for i in range(1, CARS))


def _step_floats(ys: list[float], vs: list[float], chain: tuple, u: float, b: float, s: float, sign: float,
                 cache: dict) -> tuple[list[float], list[float], bool]:
    """:func:`_advance` on flat float lists (positions, speeds; ``chain``: :func:`_chain` of the modes), the terms of
    ``(u, b, s)`` kept in ``cache``; and whether every gap at the end is calm."""
    c = cache.get(s)
    if c is None:
        c = cache[s] = _coefficients(u, b, s)
    p1, e, c1, c2, half, lost, decay = c
    y, v = ys[0], vs[0]
    ahead = y + v * s * p1 - c2
    ny, nv, calm = [ahead], [v * e - c1], True
    for i, mode, lo, hi in chain:
        y, v = ys[i], vs[i]
        if mode == "keeping":
            y = y + sign * v * s
        elif mode == "chasing":
            y, v = y - v * s - half, v + s
        else:
            y, v = y - v * lost, v * decay
        ny.append(y)
        nv.append(v)
        if not lo < y - ahead < hi:
            calm = False
        ahead = y
    return ny, nv, calm


def _first_event_floats(ys: list[float], vs: list[float], chain: tuple, u: float, b: float, h: float,
                        sign: float, end: list[float]) -> float | None:
    """:func:`_first_event` on floats (``end``: the positions after ``h``).  ``g(0)`` is taken from the positions:
    every closed form at ``s = 0`` gives ``y`` (up to the sign of a zero, which ``- threshold`` erases)."""
    best = None
    for i, mode, lo, hi in chain:
        gap_end = end[i] - end[i - 1]
        if lo < gap_end < hi:
            continue  # no guard of the mode holds
        for kind, threshold, _ in _GUARDS[mode]:
            if not _fires(kind, gap_end, threshold):
                continue
            sense = 1.0 if kind == "ge" else -1.0
            car = _follower_curve(mode, ys[i], vs[i], sign)
            ahead = (_lead_curve(ys[0], vs[0], u, b) if i == 1
                     else _follower_curve(chain[i - 2][1], ys[i - 1], vs[i - 1], sign))

            def g(s, car=car, ahead=ahead, threshold=threshold, sense=sense):
                return sense * (car(s) - ahead(s) - threshold)

            tau = _crossing(g, 0.0, h, sense * (ys[i] - ys[i - 1] - threshold), sense * (gap_end - threshold))
            if best is None or tau < best:
                best = tau
    return best


def simulate_floats(grid: np.ndarray, throttle: np.ndarray, brake: np.ndarray, keeping_sign: float
                    ) -> dict[str, object]:
    """:func:`simulate_cars` on float inputs: ``grid`` its time grid [s], ``throttle``, ``brake`` the inputs on each
    of its intervals (shape ``(grid.size - 1,)``); the same output, bit for bit."""
    ys, vs = [10.0 * i for i in range(CARS)], [0.0] * CARS
    modes = ["lead"] + ["keeping"] * (CARS - 1)
    now = tuple(modes[1:])
    chains = {now: _chain(modes)}  # modes -> their chain, built once per configuration
    chain, times, flat, mode_log = chains[now], [0.0], ys + vs, [now]
    fresh = np.ones(throttle.size, dtype=bool)  # a new input segment: the cached terms no longer hold
    fresh[1:] = ((throttle[1:] != throttle[:-1]) | (brake[1:] != brake[:-1])
                 | (np.signbit(throttle[1:]) != np.signbit(throttle[:-1]))
                 | (np.signbit(brake[1:]) != np.signbit(brake[:-1])))
    grid_list, sign, cache = grid.tolist(), keeping_sign, {}
    for k, (u, b, new) in enumerate(zip(throttle.tolist(), brake.tolist(), fresh.tolist())):
        if new:
            cache = {}
        t, end = grid_list[k], grid_list[k + 1]
        while t < end:
            ny, nv, calm = _step_floats(ys, vs, chain, u, b, end - t, sign, cache)
            if calm:
                ys, vs, t = ny, nv, end  # no guard holds at the step's end: no event, no switch
            else:
                tau = _first_event_floats(ys, vs, chain, u, b, end - t, sign, ny)
                if tau is None or t + tau >= end:
                    ys, vs, t = ny, nv, end
                else:
                    ys, vs, _ = _step_floats(ys, vs, chain, u, b, tau, sign, cache)
                    t = t + tau
                if _switch(ys, modes):
                    now = tuple(modes[1:])
                    chain = chains.get(now) or chains.setdefault(now, _chain(modes))
            if t > times[-1]:
                times.append(t), mode_log.append(now)
                flat += ys
                flat += vs
            else:  # an event at the sample's time: the sample shows the modes after it
                flat[-2 * CARS:], mode_log[-1] = ys + vs, now
    arr = np.array(flat).reshape(-1, 2 * CARS)
    out: dict[str, object] = {"time": np.asarray(times)}
    for i in range(CARS):
        out[f"y{i + 1}"], out[f"v{i + 1}"] = arr[:, i], arr[:, CARS + i]
    out["modes"] = tuple(mode_log)
    return out


def simulate_cars(throttle: InputSignal, brake: InputSignal, horizon: float = HORIZON, *,
                  keeping_sign: float = 1.0) -> dict[str, np.ndarray]:
    """Simulate the five cars over ``[0, horizon]``.

    Returns
    -------
    dict
        ``time`` [s] and ``y1..y5``, ``v1..v5`` (arrays, one sample every :data:`SAMPLE` s, at every input switch
        and at every mode switch), and ``modes`` (tuple of the followers' modes at each sample).
    """
    grid = np.unique(np.round(np.concatenate((np.arange(0.0, horizon + 1e-9, SAMPLE), throttle.starts,
                                              brake.starts, [horizon])), 9))
    grid = grid[grid <= horizon]
    if throttle.values.dtype != object and brake.values.dtype != object:  # plain floats: the fast path
        return simulate_floats(grid, throttle.at(grid[:-1]), brake.at(grid[:-1]), keeping_sign)
    state = [(10.0 * i, 0.0) for i in range(CARS)]
    modes = ["lead"] + ["keeping"] * (CARS - 1)
    times, states, mode_log = [0.0], [list(state)], [tuple(modes[1:])]
    us, bs = throttle.at(grid[:-1]).tolist(), brake.at(grid[:-1]).tolist()
    for k in range(grid.size - 1):
        t, end, u, b = float(grid[k]), float(grid[k + 1]), us[k], bs[k]
        while t < end:
            reached = _advance(state, modes, u, b, end - t, keeping_sign)
            tau = _first_event(state, modes, u, b, end - t, keeping_sign, reached)
            if tau is None or t + tau >= end:
                state, t = reached, end
            else:
                state, t = _advance(state, modes, u, b, tau, keeping_sign), t + tau
            _switch([y for y, _ in state], modes)
            if t > times[-1]:
                times.append(value_of(t)), states.append(list(state)), mode_log.append(tuple(modes[1:]))
            else:  # an event at the sample's time: the sample shows the modes after it
                states[-1], mode_log[-1] = list(state), tuple(modes[1:])
    arr = np.asarray(states)
    out = {"time": np.asarray(times)}
    for i in range(CARS):
        out[f"y{i + 1}"], out[f"v{i + 1}"] = arr[:, i, 0], arr[:, i, 1]
    out["modes"] = tuple(mode_log)
    return out


def _trace(run: dict) -> SignalTrace:
    modes = run.pop("modes")
    return SignalTrace(times=run.pop("time"), signals=run,
                       labels={f"mode{i + 2}": tuple(m[i] for m in modes) for i in range(CARS - 1)},
                       termination="end_time")


def sensitivities_cars(throttle: InputSignal, brake: InputSignal, horizon: float = HORIZON, *,
                       keeping_sign: float = 1.0) -> tuple[SignalTrace, dict[str, np.ndarray]]:
    """:func:`simulate_cars` on signals whose values are :class:`analysis.dual.Dual` (seeded with ``k`` parameters):
    the same run and code (the closed forms on dual numbers; each event time found on the values and given its
    derivative by the implicit function theorem, :func:`_event_time`, so the states after it carry the
    saltation), the trace and ``d signal(t_i) / d p``, shape ``(n, k)``, of ``y1..y5`` and ``v1..v5`` (an event's
    sample: the derivative of the state at the event, its time moving with ``p``)."""
    k = throttle.values[0].grad.size
    run = simulate_cars(throttle, brake, horizon, keeping_sign=keeping_sign)
    sens = {}
    for name in OUTPUTS:
        run[name], sens[name] = split(run[name], k)
    return _trace(run), sens


def _inputs(throttle_points: int, brake_points: int) -> tuple[PiecewiseConstantInput, PiecewiseConstantInput]:
    return (PiecewiseConstantInput(name="throttle", low=0.0, high=1.0, control_points=throttle_points, span=HORIZON),
            PiecewiseConstantInput(name="brake", low=0.0, high=1.0, control_points=brake_points, span=HORIZON))


def chasing_cars_problem(requirement: Requirement, *, throttle_points: int = 7, brake_points: int = 3,
                         keeping_sign: float = 1.0) -> VerificationProblem:
    """The CC problem of one requirement over the inputs' control points.

    Parameters
    ----------
    requirement : Requirement
        Reads ``y1..y5``, ``v1..v5`` (any other signal is refused).
    throttle_points, brake_points : int
        Control points of throttle and brake over [0, 100] s (positive).
    keeping_sign : {1.0, -1.0}
        ``y' = keeping_sign * v`` in Keeping: +1 as in ARCH-COMP's ``cars.mdl``, -1 the consistent reading.
    """
    if keeping_sign not in (1.0, -1.0):
        raise ValueError(f"keeping_sign = {keeping_sign!r}: expected 1.0 (ARCH-COMP's cars.mdl) or -1.0 (the "
                         "speed held); fix: pass one of the two")
    sign = float(keeping_sign)

    def simulate(signals: Mapping[str, InputSignal], point: Mapping[str, float]) -> SignalTrace:
        return _trace(simulate_cars(signals["throttle"], signals["brake"], keeping_sign=sign))

    def differentiate(signals: Mapping[str, InputSignal], point: Mapping[str, float]
                      ) -> tuple[SignalTrace, dict[str, np.ndarray]]:
        return sensitivities_cars(signals["throttle"], signals["brake"], keeping_sign=sign)

    name = getattr(requirement, "name", "requirement")
    variant = "" if sign > 0 else " (keeping mode holding its speed)"
    return signal_problem(name=f"arch-cc-{name}" + ("" if sign > 0 else "-keeping-held"), simulate=simulate,
                          inputs=_inputs(throttle_points, brake_points), outputs=OUTPUTS, horizon=HORIZON,
                          requirements=(requirement,), sensitivities=differentiate,
                          labels={f"mode{i}": MODES for i in range(2, CARS + 1)},
                          description=f"ARCH-COMP FALS chasing cars{variant}, {name}: throttle {throttle_points} "
                                      f"and brake {brake_points} piecewise-constant control points over "
                                      f"[0, {HORIZON:g}] s")


def problems(*, throttle_points: int = 7, brake_points: int = 3,
             keeping_sign: float = 1.0) -> dict[str, VerificationProblem]:
    """Every CC requirement's problem, keyed by requirement name (``CC1`` .. ``CC5``, ``CCx``)."""
    return {name: chasing_cars_problem(Requirement(name=name, formula=formula, description=text),
                                       throttle_points=throttle_points, brake_points=brake_points,
                                       keeping_sign=keeping_sign)
            for name, (formula, text) in REQUIREMENTS.items()}


_ALL = problems()
cc1, cc2, cc3, cc4, cc5, ccx = (_ALL[name] for name in ("CC1", "CC2", "CC3", "CC4", "CC5", "CCx"))
problem = cc1
