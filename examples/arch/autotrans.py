"""ARCH-COMP FALS benchmark AT: the automatic transmission of MathWorks' Simulink demo, as verification problems.

The model (Simulink ``sf_car``, "Modeling an Automatic Transmission Controller"; ARCH-COMP's
``Autotrans_shift``): an engine driving a torque converter, a four-speed gearbox chosen by a Stateflow
shift logic, and the vehicle.  Inputs: the throttle ``u_t ∈ [0, 100]`` % and the brake torque
``u_b ∈ [0, 325]`` lbf ft.  Outputs: the vehicle speed ``speed`` [mph], the engine speed ``rpm``
[rev/min] and the gear ``gear`` (1..4); the trace also carries ``throttle`` and ``brake``.

Equations (the Simulink block diagram; names of the MathWorks documentation)::

    Iei dNe/dt = Te(u_t, Ne) - Ti                     engine, Ne limited to [600, 6000] rpm
    Ti = (Ne / K(SR))^2,  Tt = TR(SR) Ti,  SR = Nin / Ne      torque converter (impeller, turbine)
    Nin = R(g) Nout,  Tout = R(g) Tt,  Nout = Rfd w            gearbox (transmission rpm Nout)
    Iv dw/dt = Rfd Tout - sign(v) (Kf + Cd v^2 + u_b)          vehicle, wheel speed w [rpm]
    v = 2 pi Rw w 60 / 5280                                    speed [mph]

with the lookup tables of ``data/autotrans_tables.json`` (engine torque over throttle and rpm; K factor and
torque ratio over the speed ratio, linear interpolation, linear extrapolation outside), Iei = 0.0219915,
Iv = 12.0941, Rfd = 3.23, Rw = 1 ft, Kf = 40, Cd = 0.02, gear ratios 2.393, 1.450, 1.000, 0.677.  The shift
logic runs every 0.04 s (its sample time): a speed above the up-shift threshold (table over throttle and
gear) moves it from ``steady`` to ``upshifting``; if the speed is still above the threshold TWAIT = 2 ticks
later it shifts up (and symmetrically down; a speed back between the thresholds returns to ``steady``).
Between ticks the two states are integrated by classical Runge-Kutta (steps of at most 0.02 s; every tick
and every input switch is a step boundary).  ``docs/arch.md``: sources, the validation against the Simulink
reference trace, what is faithful and what is not.

Requirements (ARCH-COMP 2019-2022 FALS reports, "AT"; written in visnav's STL, ``docs/stl.md``)::

    AT1   always[0,20] speed < 120
    AT2   always[0,10] rpm < 4750
    AT5i  always[0,30] ((gear != i and eventually[0.001,0.1] gear == i)
                         -> eventually[0.001,0.1] always[0,2.5] gear == i)          i = 1..4 (AT51..AT54)
    AT6a  (always[0,30] rpm < 3000) -> always[0,4] speed < 35
    AT6b  (always[0,30] rpm < 3000) -> always[0,8] speed < 50
    AT6c  (always[0,30] rpm < 3000) -> always[0,20] speed < 65

Inputs as parameters (``analysis/verify/signals.py``): the throttle and the brake are piecewise constant over
[0, 30] s with 7 and 3 control points by default (``autotrans_problems(throttle_points=, brake_points=)``);
the last value holds to the end of the run.  Each problem simulates up to its requirement's horizon
(AT5i: 32.6 s).

Sensitivities (the ``whitebox`` search's gradients): :func:`sensitivities_inputs` runs the same
:func:`simulate_autotrans` on dual numbers (:mod:`analysis.dual`), forward-mode through the Runge-Kutta steps and
the tables, the shift logic deciding on the values; ``docs/arch.md``.

Load them with ``visnav verify examples/arch/autotrans.py:at1`` (``at2``, ``at51`` .. ``at54``, ``at6a`` ..
``at6c``); :func:`problems` returns them all keyed by requirement name.
"""

from __future__ import annotations

import json
import math
from bisect import bisect_right
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from analysis.dual import split
from analysis.verify.signals import InputSignal, PiecewiseConstantInput, signal_problem
from analysis.stl import FormulaError, SignalTrace, parse_formula
from analysis.verify import Requirement, VerificationProblem

TABLES_FILE = Path(__file__).resolve().parent / "data" / "autotrans_tables.json"
_T = json.loads(TABLES_FILE.read_text(encoding="utf-8"))

IEI = 0.021991488283555904
"""Engine and impeller inertia [lbf ft s^2] (the MathWorks model's 0.022, as its reference trace computes it)."""
IV = 12.0941
"""Vehicle inertia [lbf ft s^2]."""
RFD = 3.23
"""Final drive ratio."""
KF = 40.0
"""Wheel friction load [lbf ft]."""
CD = 0.02
"""Aerodynamic drag coefficient [lbf ft / mph^2]."""
MPH_PER_WHEEL_RPM = 2.0 * math.pi * 1.0 * 60.0 / 5280.0
"""Vehicle speed [mph] per wheel speed [rpm] (wheel radius 1 ft)."""
GEAR_RATIOS = (2.393, 1.450, 1.000, 0.677)
RPM_LIMITS = (600.0, 6000.0)
"""Limits of the engine-speed integrator [rpm]."""
INITIAL_RPM = 1000.0
TICK = 0.04
"""Sample time of the shift logic [s]."""
TWAIT = 2
"""Ticks a shift condition must persist before the gear changes."""
MAX_STEP = 0.02
"""Largest Runge-Kutta step [s]."""
INPUT_SPAN = 30.0
"""The span of the input signals' control points [s]."""
THROTTLE_RANGE = (0.0, 100.0)
BRAKE_RANGE = (0.0, 325.0)
OUTPUTS = ("speed", "rpm", "gear", "throttle", "brake")

_THR = tuple(_T["engine_torque"]["throttle_percent"])
_RPM = tuple(_T["engine_torque"]["engine_rpm"])
_TE = tuple(tuple(row) for row in _T["engine_torque"]["torque_lbf_ft"])
_SR = tuple(_T["torque_converter"]["speed_ratio"])
_K = tuple(_T["torque_converter"]["k_factor_rpm_per_sqrt_lbf_ft"])
_TR = tuple(_T["torque_converter"]["torque_ratio"])
_UP_THR = tuple(_T["upshift"]["throttle_percent"])
_UP = tuple(tuple(row) for row in _T["upshift"]["speed_mph"])
_DOWN_THR = tuple(_T["downshift"]["throttle_percent"])
_DOWN = tuple(tuple(row) for row in _T["downshift"]["speed_mph"])

REQUIREMENTS: dict[str, tuple[str, str]] = {
    "AT1": ("always[0, 20] (speed < 120)", "the speed stays below 120 mph for 20 s"),
    "AT2": ("always[0, 10] (rpm < 4750)", "the engine speed stays below 4750 rpm for 10 s"),
    **{f"AT5{i}": (f"always[0, 30] (((gear != {i}) and eventually[0.001, 0.1] (gear == {i})) -> "
                   f"eventually[0.001, 0.1] always[0, 2.5] (gear == {i}))",
                   f"once shifted into gear {i}, the transmission stays in it for 2.5 s") for i in (1, 2, 3, 4)},
    "AT6a": ("(always[0, 30] (rpm < 3000)) -> always[0, 4] (speed < 35)",
             "an engine below 3000 rpm for 30 s keeps the speed below 35 mph for 4 s"),
    "AT6b": ("(always[0, 30] (rpm < 3000)) -> always[0, 8] (speed < 50)",
             "an engine below 3000 rpm for 30 s keeps the speed below 50 mph for 8 s"),
    "AT6c": ("(always[0, 30] (rpm < 3000)) -> always[0, 20] (speed < 65)",
             "an engine below 3000 rpm for 30 s keeps the speed below 65 mph for 20 s"),
}
"""Requirement name -> (formula, description), as published in the ARCH-COMP FALS reports."""


def _segment(breaks: Sequence[float], x: float) -> int:
    """Index ``j`` of the table segment ``[breaks[j], breaks[j+1]]`` used for ``x`` (end segments extrapolate)."""
    return min(max(bisect_right(breaks, x) - 1, 0), len(breaks) - 2)


def _lookup(breaks: Sequence[float], values: Sequence[float], x: float) -> float:
    j = _segment(breaks, x)
    x0 = breaks[j]
    return values[j] + (x - x0) * (values[j + 1] - values[j]) / (breaks[j + 1] - x0)


def engine_torque(throttle: float, rpm: float) -> float:
    """The engine torque table [lbf ft] at ``throttle`` [%] and ``rpm``: bilinear, linear extrapolation."""
    i, j = _segment(_THR, throttle), _segment(_RPM, rpm)
    fx = (throttle - _THR[i]) / (_THR[i + 1] - _THR[i])
    fy = (rpm - _RPM[j]) / (_RPM[j + 1] - _RPM[j])
    a, b = _TE[i], _TE[i + 1]
    low = a[j] + fy * (a[j + 1] - a[j])
    high = b[j] + fy * (b[j + 1] - b[j])
    return low + fx * (high - low)


def shift_thresholds(throttle: float, gear: int) -> tuple[float, float]:
    """(down, up) shift speeds [mph] of ``gear`` at ``throttle`` [%] (the shift schedule's tables)."""
    down = _lookup(_DOWN_THR, [row[gear - 1] for row in _DOWN], throttle)
    up = _lookup(_UP_THR, [row[gear - 1] for row in _UP], throttle)
    return down, up


_RPM_SLOPE_DENOM = tuple(_RPM[j + 1] - _RPM[j] for j in range(len(_RPM) - 1))
_K_SLOPE = tuple((_K[j + 1] - _K[j]) / (_SR[j + 1] - _SR[j]) for j in range(len(_SR) - 1))
_TR_SLOPE = tuple((_TR[j + 1] - _TR[j]) / (_SR[j + 1] - _SR[j]) for j in range(len(_SR) - 1))
_LAST_SR, _LAST_RPM = len(_SR) - 2, len(_RPM) - 2


def torque_row(throttle: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The engine torque table at ``throttle`` [%] as a function of rpm: values and slopes per rpm segment."""
    i = _segment(_THR, throttle)
    fx = (throttle - _THR[i]) / (_THR[i + 1] - _THR[i])
    a, b = _TE[i], _TE[i + 1]
    row = tuple(a[j] + fx * (b[j] - a[j]) for j in range(len(_RPM)))
    return row, tuple((row[j + 1] - row[j]) / _RPM_SLOPE_DENOM[j] for j in range(len(_RPM) - 1))


def derivatives(rpm: float, wheel: float, row: tuple[tuple[float, ...], tuple[float, ...]], brake: float,
                ratio: float) -> tuple[float, float]:
    """(dNe/dt [rpm/s], dw/dt [rpm/s]) at engine speed ``rpm``, wheel speed ``wheel`` [rpm], gear ratio ``ratio``.

    ``row`` is :func:`torque_row` of the throttle (the engine torque table at that throttle).
    """
    values, slopes = row
    j = bisect_right(_RPM, rpm) - 1
    j = 0 if j < 0 else (_LAST_RPM if j > _LAST_RPM else j)
    te = values[j] + (rpm - _RPM[j]) * slopes[j]
    sr = ratio * RFD * wheel / rpm
    k = bisect_right(_SR, sr) - 1
    k = 0 if k < 0 else (_LAST_SR if k > _LAST_SR else k)
    d = sr - _SR[k]
    impeller = (rpm / (_K[k] + d * _K_SLOPE[k])) ** 2
    speed = wheel * MPH_PER_WHEEL_RPM
    load = KF + CD * speed * speed + brake
    signed = load if speed > 0 else (-load if speed < 0 else 0.0)
    return (te - impeller) / IEI, (RFD * ratio * impeller * (_TR[k] + d * _TR_SLOPE[k]) - signed) / IV


class ShiftLogic:
    """The Stateflow shift logic: ``steady``/``upshifting``/``downshifting`` with a wait of :data:`TWAIT` ticks."""

    __slots__ = ("gear", "state", "count")

    def __init__(self, gear: int = 1) -> None:
        self.gear, self.state, self.count = gear, "steady", 0

    def tick(self, throttle: float, speed: float) -> int:
        """One execution of the chart with the inputs of this tick; the gear it leaves."""
        down, up = shift_thresholds(throttle, self.gear)
        if down < speed < up:
            self.state, self.count = "steady", 0
        elif self.state == "steady":
            self.state, self.count = ("upshifting" if speed >= up else "downshifting"), 1
        elif (self.state == "upshifting") == (speed >= up):  # the condition that started the shift still holds
            if self.count < TWAIT:
                self.count += 1
            else:
                self.gear = min(4, self.gear + 1) if self.state == "upshifting" else max(1, self.gear - 1)
                self.state, self.count = "steady", 0
        return self.gear


def _grid(horizon: float, breaks: Sequence[float]) -> tuple[list[float], list[bool]]:
    """Step boundaries: every tick and input break in [0, horizon]; and whether each is a tick."""
    ticks = np.arange(0.0, horizon + 1e-9, TICK)
    ticks = ticks[ticks <= horizon + 1e-9]
    extra = np.asarray([b for b in breaks if 0.0 <= b <= horizon], dtype=float)
    allt = np.unique(np.round(np.concatenate((ticks, extra, [horizon])), 9))
    tickset = set(np.round(ticks, 9).tolist())
    return allt.tolist(), [t in tickset for t in allt.tolist()]


def simulate_autotrans(throttle: Sequence[float], brake: Sequence[float], grid: Sequence[float],
                       is_tick: Sequence[bool], *, throttle_end: Sequence[float] | None = None,
                       brake_end: Sequence[float] | None = None) -> dict[str, np.ndarray]:
    """Simulate the transmission from rest (1000 rpm, gear 1) over ``grid``.

    Parameters
    ----------
    throttle, brake : sequence of float, shape (m - 1,)
        The inputs at the start of each interval ``[grid[i], grid[i+1]]`` (right limits) [%], [lbf ft].
    grid : sequence of float, shape (m,)
        Step boundaries [s], increasing; the shift logic runs at those with ``is_tick``.
    is_tick : sequence of bool, shape (m,)
    throttle_end, brake_end : sequence of float or None, shape (m - 1,)
        The inputs at the end of each interval (left limits), for inputs linear on the interval; ``None``:
        constant on each interval.

    Returns
    -------
    dict
        ``time``, ``speed`` [mph], ``rpm``, ``gear``, ``throttle``, ``brake``, arrays of the samples (every step end).
    """
    lo, hi = RPM_LIMITS
    rpm, wheel = INITIAL_RPM, 0.0
    logic = ShiftLogic()
    times, rpms, wheels, gears, thr_out, brk_out = [], [], [], [], [], []
    for i in range(len(grid) - 1):
        ta, tb = grid[i], grid[i + 1]
        u0, b0 = throttle[i], brake[i]
        du = 0.0 if throttle_end is None else (throttle_end[i] - u0) / (tb - ta)
        db = 0.0 if brake_end is None else (brake_end[i] - b0) / (tb - ta)
        if is_tick[i]:
            logic.tick(u0, wheel * MPH_PER_WHEEL_RPM)
            if gears:
                gears[-1] = logic.gear  # the chart's output at the tick is the gear it leaves (as Simulink logs it)
        ratio = GEAR_RATIOS[logic.gear - 1]
        if i == 0:
            times.append(ta), rpms.append(rpm), wheels.append(wheel), gears.append(logic.gear)
            thr_out.append(u0), brk_out.append(b0)
        row = torque_row(u0)
        n = max(1, math.ceil((tb - ta) / MAX_STEP - 1e-9))
        h = (tb - ta) / n
        for s in range(n):
            t = s * h  # time within the interval
            if du:
                ra, rm, re = torque_row(u0 + du * t), torque_row(u0 + du * (t + h / 2)), torque_row(u0 + du * (t + h))
            else:
                ra = rm = re = row
            ba, bm, be = b0 + db * t, b0 + db * (t + h / 2), b0 + db * (t + h)
            k1r, k1w = derivatives(rpm, wheel, ra, ba, ratio)
            k2r, k2w = derivatives(rpm + h / 2 * k1r, wheel + h / 2 * k1w, rm, bm, ratio)
            k3r, k3w = derivatives(rpm + h / 2 * k2r, wheel + h / 2 * k2w, rm, bm, ratio)
            k4r, k4w = derivatives(rpm + h * k3r, wheel + h * k3w, re, be, ratio)
            rpm = min(hi, max(lo, rpm + h / 6 * (k1r + 2 * k2r + 2 * k3r + k4r)))
            wheel = wheel + h / 6 * (k1w + 2 * k2w + 2 * k3w + k4w)
            times.append(tb if s == n - 1 else ta + (s + 1) * h)
            rpms.append(rpm), wheels.append(wheel), gears.append(logic.gear)
            thr_out.append(u0 + du * (t + h)), brk_out.append(be)
    return {"time": np.asarray(times), "speed": np.asarray(wheels) * MPH_PER_WHEEL_RPM, "rpm": np.asarray(rpms),
            "gear": np.asarray(gears, dtype=float), "throttle": np.asarray(thr_out), "brake": np.asarray(brk_out)}


def _run(inputs: Mapping[str, InputSignal], horizon: float) -> dict[str, np.ndarray]:
    throttle, brake = inputs["throttle"], inputs["brake"]
    grid, is_tick = _grid(horizon, [*throttle.starts.tolist(), *brake.starts.tolist()])
    starts = np.asarray(grid[:-1])
    run = simulate_autotrans(throttle.at(starts).tolist(), brake.at(starts).tolist(), grid, is_tick)
    run["throttle"], run["brake"] = throttle.at(run["time"]), brake.at(run["time"])  # right-continuous
    return run


def simulate_inputs(inputs: Mapping[str, InputSignal], horizon: float) -> SignalTrace:
    """The trace for piecewise-constant ``throttle`` and ``brake`` signals over ``[0, horizon]``."""
    return _trace(_run(inputs, horizon))


def sensitivities_inputs(inputs: Mapping[str, InputSignal], horizon: float
                         ) -> tuple[SignalTrace, dict[str, np.ndarray]]:
    """:func:`simulate_inputs` on signals whose values are :class:`analysis.dual.Dual` (seeded with ``k``
    parameters): the same run, the same code (:func:`simulate_autotrans` on dual numbers: forward-mode
    differentiation through the Runge-Kutta steps and the tables, the shift logic's decisions taken on the
    values), and ``d signal(t_i) / d p``, shape ``(n, k)``, of every output (the gear's is zero: it is discrete).
    """
    first = next(iter(inputs.values())).values[0]
    k = first.grad.size
    run = _run(inputs, horizon)
    values, sens = {"time": run["time"]}, {}
    for name in OUTPUTS:
        values[name], sens[name] = split(run[name], k)
    return _trace(values), sens


def _trace(run: Mapping[str, np.ndarray]) -> SignalTrace:
    # one sample per step end, at distinct times (a repeated time would read as a jump)
    return SignalTrace(times=run["time"], signals={k: v for k, v in run.items() if k != "time"},
                       termination="end_time")


def _inputs(throttle_points: int, brake_points: int) -> tuple[PiecewiseConstantInput, PiecewiseConstantInput]:
    return (PiecewiseConstantInput(name="throttle", low=THROTTLE_RANGE[0], high=THROTTLE_RANGE[1],
                                   control_points=throttle_points, span=INPUT_SPAN, unit="%"),
            PiecewiseConstantInput(name="brake", low=BRAKE_RANGE[0], high=BRAKE_RANGE[1], control_points=brake_points,
                                   span=INPUT_SPAN, nominal=0.0, unit="lbf ft"))


def autotrans_problem(requirement: Requirement, *, throttle_points: int = 7, brake_points: int = 3,
                      horizon: float | None = None) -> VerificationProblem:
    """The AT problem of one requirement: the inputs' control points are the box.

    Parameters
    ----------
    requirement : Requirement
        Reads ``speed``, ``rpm``, ``gear``, ``throttle``, ``brake`` (any other signal is refused).
    throttle_points, brake_points : int
        Control points of the throttle and the brake over [0, 30] s (positive).
    horizon : float or None
        The simulated time [s]; by default the requirement's horizon, at least one tick.
    """
    inputs = _inputs(throttle_points, brake_points)
    if horizon is None and isinstance(requirement, Requirement):
        known = (*OUTPUTS, *(p.name for item in inputs for p in item.parameters()), "time", "jumps")
        try:
            horizon = max(TICK, parse_formula(requirement.formula, signals=known).horizon)
        except FormulaError:
            horizon = None  # the problem refuses the formula below, naming the requirement
    span = INPUT_SPAN if horizon is None else horizon

    def simulate(signals: Mapping[str, InputSignal], point: Mapping[str, float]) -> SignalTrace:
        return simulate_inputs(signals, span)

    def differentiate(signals: Mapping[str, InputSignal], point: Mapping[str, float]
                      ) -> tuple[SignalTrace, dict[str, np.ndarray]]:
        return sensitivities_inputs(signals, span)

    name = getattr(requirement, "name", "requirement")
    return signal_problem(name=f"arch-at-{name}", simulate=simulate, inputs=inputs, outputs=OUTPUTS,
                          horizon=span, requirements=(requirement,), sensitivities=differentiate,
                          description=f"ARCH-COMP FALS automatic transmission, {name}: throttle "
                                      f"{throttle_points} and brake {brake_points} piecewise-constant control "
                                      f"points over [0, {INPUT_SPAN:g}] s, simulated over [0, {span:g}] s")


def problems(*, throttle_points: int = 7, brake_points: int = 3) -> dict[str, VerificationProblem]:
    """Every AT requirement's problem, keyed by requirement name (``AT1``, ``AT2``, ``AT51``..``AT54``, ``AT6a``..)."""
    return {name: autotrans_problem(Requirement(name=name, formula=formula, description=text),
                                    throttle_points=throttle_points, brake_points=brake_points)
            for name, (formula, text) in REQUIREMENTS.items()}


_ALL = problems()
at1, at2 = _ALL["AT1"], _ALL["AT2"]
at51, at52, at53, at54 = _ALL["AT51"], _ALL["AT52"], _ALL["AT53"], _ALL["AT54"]
at6a, at6b, at6c = _ALL["AT6a"], _ALL["AT6b"], _ALL["AT6c"]
problem = at1
