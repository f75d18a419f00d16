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

Load them with ``visnav verify examples/arch/chasing_cars.py:cc1`` (``cc2`` .. ``cc5``, ``ccx``); :func:`problems`
returns them keyed by requirement name.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

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


def _phi1(x: float) -> float:
    """(1 - e^-x) / x, accurate for small x."""
    return 1.0 - x / 2 + x * x / 6 if abs(x) < 1e-5 else -math.expm1(-x) / x


def _phi2(x: float) -> float:
    """(x - 1 + e^-x) / x^2, accurate for small x."""
    return 0.5 - x / 6 + x * x / 24 if abs(x) < 1e-3 else (x + math.expm1(-x)) / (x * x)


def lead(y: float, v: float, throttle: float, brake: float, s: float) -> tuple[float, float]:
    """Car 1 after ``s`` seconds of ``v' = -throttle - brake v``, ``y' = v`` (closed form)."""
    x = brake * s
    return (y + v * s * _phi1(x) - throttle * s * s * _phi2(x),
            v * math.exp(-x) - throttle * s * _phi1(x))


def follower(mode: str, y: float, v: float, s: float, keeping_sign: float) -> tuple[float, float]:
    """A follower after ``s`` seconds in ``mode`` (closed form)."""
    if mode == "chasing":
        return y - v * s - s * s / 2, v + s
    if mode == "keeping":
        return y + keeping_sign * v * s, v
    decay = math.exp(-s)
    return y - v * (1.0 - decay), v * decay


_CHASING, _KEEPING, _BRAKING = 0, 1, 2
_GUARD_TABLE = tuple(tuple((kind == "le", threshold, MODES.index(target)) for kind, threshold, target in _GUARDS[m])
                     for m in MODES)
"""``_GUARDS`` by mode index: ``(is d <= c, c, next mode index)``."""
_BAND = tuple((min((c for le, c, _ in guards if le), default=-math.inf),
               min((c for le, c, _ in guards if not le), default=math.inf)) for guards in _GUARD_TABLE)
"""By mode index, ``(low, high)``: no guard of the mode holds while ``low < d < high`` (the common case, checked
first)."""


def _advance(ys: list[float], vs: list[float], modes: list[int], u: float, b: float, s: float,
             sign: float) -> tuple[list[float], list[float]]:
    """Positions and speeds of the five cars after ``s`` seconds in their modes (closed forms of :func:`lead`
    and :func:`follower`, written out: this is the simulation's inner loop)."""
    x = b * s
    p1 = 1.0 - x / 2 + x * x / 6 if abs(x) < 1e-5 else -math.expm1(-x) / x  # _phi1(x) and _phi2(x), inlined
    p2 = 0.5 - x / 6 + x * x / 24 if abs(x) < 1e-3 else (x + math.expm1(-x)) / (x * x)
    ny = [ys[0] + vs[0] * s * p1 - u * s * s * p2]
    nv = [vs[0] * math.exp(-x) - u * s * p1]
    decay = None
    for i in range(1, CARS):
        mode, y, v = modes[i], ys[i], vs[i]
        if mode == _CHASING:
            ny.append(y - v * s - s * s / 2)
            nv.append(v + s)
        elif mode == _KEEPING:
            ny.append(y + sign * v * s)
            nv.append(v)
        else:
            if decay is None:
                decay = math.exp(-s)
            ny.append(y - v * (1.0 - decay))
            nv.append(v * decay)
    return ny, nv


def _position_of(j: int, ys: list[float], vs: list[float], modes: list[int], u: float, b: float, sign: float):
    """Position of car ``j`` as a function of the time ``s`` spent in its mode (the closed forms of
    :func:`_advance`, the same operations in the same order)."""
    y, v = ys[j], vs[j]
    if j == 0:
        return lambda s: y + v * s * _phi1(b * s) - u * s * s * _phi2(b * s)
    mode = modes[j]
    if mode == _CHASING:
        return lambda s: y - v * s - s * s / 2
    if mode == _KEEPING:
        return lambda s: y + sign * v * s
    return lambda s: y - v * (1.0 - math.exp(-s))


def _switch(ys: list[float], modes: list[int]) -> bool:
    """Take every enabled transition (in car order, chains at one instant allowed); whether any was taken."""
    taken = False
    for _ in range(3):  # no guard of a mode's successor is enabled by the same gap twice: chains have length <= 2
        changed = False
        for i in range(1, CARS):
            gap = ys[i] - ys[i - 1]
            low, high = _BAND[modes[i]]
            if low < gap < high:
                continue
            for le, threshold, target in _GUARD_TABLE[modes[i]]:
                if (gap <= threshold) if le else (gap >= threshold):
                    modes[i], changed = target, True
                    break
        taken |= changed
        if not changed:
            break
    return taken


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


def _first_event(ys, vs, modes, u, b, h, sign, end_ys) -> float | None:
    """The earliest guard crossing in ``(0, h]`` seen at the step's end positions ``end_ys``, located on the
    closed form.

    A guard ``d <= c`` is the root of ``c - d``, ``d >= c`` of ``d - c``: negative before, non-negative at the end.
    ``None`` when no guard holds at the end.
    """
    best = None
    for i in range(1, CARS):
        gap_end = end_ys[i] - end_ys[i - 1]
        low, high = _BAND[modes[i]]
        if low < gap_end < high:
            continue
        for le, threshold, _ in _GUARD_TABLE[modes[i]]:
            if not ((gap_end <= threshold) if le else (gap_end >= threshold)):
                continue
            sense = -1.0 if le else 1.0
            mine, ahead = _position_of(i, ys, vs, modes, u, b, sign), _position_of(i - 1, ys, vs, modes, u, b, sign)

            def g(s, mine=mine, ahead=ahead, threshold=threshold, sense=sense):
                return sense * (mine(s) - ahead(s) - threshold)

            tau = _crossing(g, 0.0, h, g(0.0), sense * (gap_end - threshold))
            best = tau if best is None else min(best, tau)
    return best


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
    ys, vs = [10.0 * i for i in range(CARS)], [0.0] * CARS
    modes = [-1] + [_KEEPING] * (CARS - 1)
    times, rows, mode_log = [0.0], [ys + vs], [tuple(modes[1:])]
    sign = float(keeping_sign)
    points, us, bs = grid.tolist(), throttle.at(grid[:-1]).tolist(), brake.at(grid[:-1]).tolist()
    for k in range(len(points) - 1):
        t, end, u, b = points[k], points[k + 1], us[k], bs[k]
        while t < end:
            reached_y, reached_v = _advance(ys, vs, modes, u, b, end - t, sign)
            tau = _first_event(ys, vs, modes, u, b, end - t, sign, reached_y)
            if tau is None:  # no guard holds at the step's end: nothing to switch there
                ys, vs, t = reached_y, reached_v, end
            else:
                if t + tau >= end:
                    ys, vs, t = reached_y, reached_v, end
                else:
                    (ys, vs), t = _advance(ys, vs, modes, u, b, tau, sign), t + tau
                _switch(ys, modes)
            if t > times[-1]:
                times.append(t), rows.append(ys + vs), mode_log.append(tuple(modes[1:]))
            else:  # an event at the sample's time: the sample shows the modes after it
                rows[-1], mode_log[-1] = ys + vs, tuple(modes[1:])
    arr = np.asarray(rows)
    out = {"time": np.asarray(times)}
    for i in range(CARS):
        out[f"y{i + 1}"], out[f"v{i + 1}"] = arr[:, i], arr[:, CARS + i]
    out["modes"] = tuple(tuple(MODES[m] for m in row) for row in mode_log)
    return out


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
        run = simulate_cars(signals["throttle"], signals["brake"], keeping_sign=sign)
        modes = run.pop("modes")
        return SignalTrace(times=run.pop("time"), signals=run,
                           labels={f"mode{i + 2}": tuple(m[i] for m in modes) for i in range(CARS - 1)},
                           termination="end_time")

    name = getattr(requirement, "name", "requirement")
    variant = "" if sign > 0 else " (keeping mode holding its speed)"
    return signal_problem(name=f"arch-cc-{name}" + ("" if sign > 0 else "-keeping-held"), simulate=simulate,
                          inputs=_inputs(throttle_points, brake_points), outputs=OUTPUTS, horizon=HORIZON,
                          requirements=(requirement,),
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
