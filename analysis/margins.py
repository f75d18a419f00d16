"""Stability margins of linearised feedback loops, continuous and sampled.

Generic tools, independent of the robot.  A linearised multi-loop system is
described once, as a plant and a controller in negative feedback
(:class:`LoopModel`, ``u = −K y``); :func:`loop_transfer` cuts it at one
plant input (an actuator: pan rate, angular velocity ω) or at one plant
output (a measurement: the visual-servoing error) with every other loop
closed, and returns the SISO loop transfer ``L`` whose closed loop is
``1 / (1 + L)``.  :func:`sampled_loop_transfer` does the same for the
sampled-data loop (plant under zero-order hold, controller evaluated at the
samples, ``d`` samples of computation delay); :func:`sampled_loop` samples a
SISO loop ``L = K·P`` directly.

Margins are computed by two independent routes that must agree:

* :func:`margins` — python-control's polynomial crossover solver
  (``control.stability_margins(..., returnall=True, method="poly")``); a
  sampled loop is first mapped exactly to the w-plane,
  ``z = (1 + sT/2) / (1 − sT/2)``, so that the solver works on ``s = jν``
  and ``ω = (2/T) atan(νT/2)`` (python-control's own z-plane roots lose
  digits when fast sampling clusters the poles near ``z = 1``: crossovers
  off by 2–7 % were seen at ``T ≈ 0.035 s``);
* :func:`margins_by_sweep` — a dense frequency sweep of ``L(jω)`` (or
  ``L(e^{jωT})``) evaluated by numpy from the state-space matrices, each
  crossover refined by :func:`scipy.optimize.brentq` on ``log|L| = 0`` and
  on the locally unwrapped phase ``arg L + 180° = 360° m``.

Both return a :class:`Margins`.  Conventions (both routes):

* gain margin ``1 / |L(jω_π)|`` at each *phase crossover* ``ω_π`` (where
  ``L`` crosses the negative real axis).  For a stable closed loop the
  gain multipliers ``g`` that keep it stable form an interval around 1
  bounded by these margins: the headline ``gain_margin`` is the *upper*
  one, the smallest margin above 1 (``inf`` when none: any gain increase is
  tolerated), and ``lower_gain_margin`` the largest margin below 1 (``None``
  when none).  A phase crossover at the frequency of an open-loop pole on
  the imaginary axis (unit circle) — where ``|L| = ∞``, as for the
  oscillating kinematics of a path-following loop opened at ω — is an
  artefact of the polynomial solver (``Im(num·conj den)`` vanishes with
  ``den``), not a crossing of the negative real axis: it is dropped and a
  note names the boundary poles.  For an unstable
  closed loop the headline is the margin closest to 1 in the log sense (as
  python-control);
* phase margin ``(arg L(jω_c) mod 360°) − 180°`` at each *gain crossover*
  ``ω_c`` (``|L| = 1``); the headline value is the smallest in absolute
  value, ``inf`` when there is no gain crossover;
* delay margin at each gain crossover ``((PM mod 360°) in rad) / ω_c`` [s]:
  the smallest pure delay ``e^{−jωτ}`` that rotates ``L(jω_c)`` onto −1;
  the headline value is the smallest one, i.e. the smallest delay that puts
  a closed-loop pole on the stability boundary (0 when the closed loop is
  already unstable).  For a sampled loop the same formula holds on the unit
  circle, ``τ = PM_rad / ω_c`` in seconds with ``ω_c`` in rad/s, and it is
  also given in samples, ``τ / T`` (fractional): an extra delay of ``n``
  whole samples (``z^−n``) keeps a stable closed loop stable if
  ``n < delay_margin_samples`` (the rotated Nyquist curve cannot reach −1);

* crossovers found at ``ω <= min_frequency`` (default 1e-9 rad/s, or
  ``1e-9 π/T`` for a sampled loop) are discarded as round-off of the static
  gain; instead, when ``L(0)`` (``L(1)`` sampled) is finite and negative,
  ``ω = 0`` is reported as a phase crossover with gain margin ``1/|L(0)|``
  (typical of an unstable open loop such as ``k/(s − 1)``); likewise a
  sampled loop with ``L(−1)`` finite and negative has a phase crossover at
  the Nyquist frequency ``ω = π/T`` (the end of its Nyquist curve); a
  sampled loop is examined on ``0 <= ω <= π/T``.

The classical margins certify robustness of a *stable* closed loop whose
open loop is stable.  Each result therefore also reports the open-loop poles
outside the stability region (right half plane, or outside the unit circle)
and whether the closed loop is stable, decided from its poles; with ``P``
unstable open-loop poles the Nyquist criterion requires ``P``
counter-clockwise encirclements of −1 and a note says so.

python-control (which imports matplotlib) is imported lazily, inside the
functions that need it, so that ``import analysis.margins`` stays light.

Examples
--------
>>> import control
>>> m = margins(control.tf([2.0], [1.0, 0.0]), name="integrator")
>>> round(m.phase_margin_deg, 9), m.gain_margin, round(m.gain_crossover_frequency, 9)
(90.0, inf, 2.0)
>>> bool(abs(m.delay_margin_s - math.pi / 4) < 1e-12)
True
"""

from __future__ import annotations

import cmath
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import brentq

from hybrid.jsonable import to_jsonable
from analysis.loop_models import (
    FrequencyGridError,
    ILL_POSED_CONDITION,
    LoopBreakError,
    LoopDefinitionError,
    LoopModel,
    LoopShapeError,
    LoopTypeError,
    Matrices,
    NonFiniteLoopError,
    SamplingError,
    loop_model,
    loop_transfer,
    sampled_loop,
    sampled_loop_transfer,
    siso_state_space,
    transfer_function_of,
)

__all__ = [
    "DEFAULT_SWEEP_POINTS",
    "MIN_FREQUENCY_FRACTION",
    "STABILITY_TOLERANCE",
    "LoopDefinitionError",
    "LoopShapeError",
    "NonFiniteLoopError",
    "LoopTypeError",
    "LoopBreakError",
    "SamplingError",
    "FrequencyGridError",
    "LoopModel",
    "Margins",
    "LoopFrequencyResponse",
    "loop_model",
    "loop_transfer",
    "sampled_loop_transfer",
    "sampled_loop",
    "margins",
    "margins_by_sweep",
    "frequency_response_data",
]

DEFAULT_SWEEP_POINTS = 20_000
"""Default number of log-spaced frequencies of :func:`margins_by_sweep`."""
MIN_FREQUENCY_FRACTION = 1e-9
"""Crossovers below this frequency are static: ``x`` rad/s (continuous) or ``x π/T`` (sampled)."""
STABILITY_TOLERANCE = 1e-10
"""A pole ``p`` counts as on the stability boundary when ``|Re p| <= tol max(1, |p|)``
(continuous) or ``||p| − 1| <= tol`` (sampled)."""
_BRENTQ_RTOL = 1e-15
_BRENTQ_MAXITER = 200
_NYQUIST_BAND = 1e-9
_TINY = 1e-300
_POLE_CROSSOVER_RTOL = 1e-6


# --------------------------------------------------------------------------- margins


@dataclass(frozen=True, kw_only=True, slots=True)
class Margins:
    """Classical stability margins of a SISO loop ``L`` (closed loop ``1 / (1 + L)``).

    Attributes
    ----------
    name : str
    method : {"polynomial", "sweep"}
        The route that found the crossovers (:func:`margins` or :func:`margins_by_sweep`).
    period : float or None
        Sampling period [s] of a sampled loop, ``None`` for a continuous one.
    gain_margin : float
        Upper gain margin of a stable closed loop: the smallest ``1 / |L(jω_π)|``
        above 1 over the phase crossovers, ``inf`` when none (unstable closed
        loop: the margin closest to 1 in the log sense).
    gain_margin_db : float
        ``20 log10(gain_margin)`` [dB].
    lower_gain_margin : float or None
        Largest margin below 1 (stable closed loop): the gain may be divided
        by up to ``1/lower_gain_margin``; ``None`` when no crossover
        bounds the gain from below (or the closed loop is unstable).
    lower_gain_margin_db : float or None
        Its value in dB.
    phase_margin_deg : float
        Smallest phase margin in absolute value [deg]; ``inf`` without a gain crossover.
    delay_margin_s : float
        Smallest delay margin over the gain crossovers [s]; ``inf`` without a
        gain crossover; 0 when the closed loop is unstable.
    delay_margin_samples : float or None
        ``delay_margin_s / period`` for a sampled loop, else ``None``.
    phase_crossover_frequency : float
        ``ω_π`` of the reported gain margin [rad/s]; ``nan`` if none.
    gain_crossover_frequency : float
        ``ω_c`` of the reported phase margin [rad/s]; ``nan`` if none.
    phase_crossovers : tuple of float
        Every phase crossover [rad/s], increasing; may include ``0`` (``L(0) < 0``)
        and, for a sampled loop, ``π/T`` (``L(−1) < 0``).
    gain_margins : tuple of float
        Gain margin at each phase crossover (absolute).
    gain_crossovers : tuple of float
        Every gain crossover [rad/s], increasing.
    phase_margins_deg : tuple of float
        Phase margin at each gain crossover [deg].
    delay_margins_s : tuple of float
        Delay margin at each gain crossover [s].
    open_loop_unstable_poles : int
        Poles of ``L`` (of its realisation) with ``Re p > 0`` (``|p| > 1`` sampled).
    open_loop_boundary_poles : int
        Poles on the imaginary axis (unit circle), e.g. integrators.
    closed_loop_stable : bool
        Every pole of the closed loop ``1 / (1 + L)`` strictly inside the
        stability region (within :data:`STABILITY_TOLERANCE`).
    closed_loop_poles : tuple of complex
        Sorted by real part then imaginary part [1/s], or z-plane poles.
    notes : tuple of str
        What limits the meaning of the numbers (unstable open or closed loop).
    """

    name: str
    method: str
    period: float | None
    gain_margin: float
    gain_margin_db: float
    lower_gain_margin: float | None
    lower_gain_margin_db: float | None
    phase_margin_deg: float
    delay_margin_s: float
    delay_margin_samples: float | None
    phase_crossover_frequency: float
    gain_crossover_frequency: float
    phase_crossovers: tuple[float, ...]
    gain_margins: tuple[float, ...]
    gain_crossovers: tuple[float, ...]
    phase_margins_deg: tuple[float, ...]
    delay_margins_s: tuple[float, ...]
    open_loop_unstable_poles: int
    open_loop_boundary_poles: int
    closed_loop_stable: bool
    closed_loop_poles: tuple[complex, ...]
    notes: tuple[str, ...]

    @property
    def open_loop_stable(self) -> bool:
        """No open-loop pole outside the stability region (boundary poles allowed)."""
        return self.open_loop_unstable_poles == 0

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: every field and ``open_loop_stable``; non-finite numbers become ``None``,
        poles ``[re, im]`` pairs."""
        return {**to_jsonable(self), "open_loop_stable": self.open_loop_stable}


def margins(L: Any, *, name: str = "", min_frequency: float | None = None) -> Margins:
    """Gain, phase and delay margins by python-control's polynomial crossover solver.

    Crossovers come from ``control.stability_margins(L, returnall=True,
    method="poly")``: roots of ``|num|² − |den|²`` and of ``Im(num·conj den)``
    on ``s = jω``.  A sampled loop is first transformed exactly to the
    w-plane, ``L_w(s) = L((1 + sT/2) / (1 − sT/2))``, whose ``s = jν`` is the
    unit circle, and the crossovers are mapped back with
    ``ω = (2/T) atan(νT/2)`` (if ``L`` has a pole at ``z = −1`` the z-domain
    solver of python-control is used instead).  A state-space ``L`` is
    converted to ``num/den`` with its relative degree kept exact (see
    ``transfer_function_of``).  The selection of the headline values, the
    delay margins and the pole analysis are described in the module
    docstring.

    Parameters
    ----------
    L : control.StateSpace or control.TransferFunction
        SISO loop transfer, continuous (``dt = 0``) or sampled (``dt = T > 0``).
    name : str
        Label carried by the result.
    min_frequency : float, optional
        Crossovers at or below this frequency [rad/s] are not reported
        (static gain).  Default ``MIN_FREQUENCY_FRACTION`` rad/s, or
        ``MIN_FREQUENCY_FRACTION π/T`` for a sampled loop.

    Returns
    -------
    Margins

    Raises
    ------
    LoopTypeError
        ``L`` is not a SISO python-control system with a numeric timebase.
    NonFiniteLoopError
        NaN/inf in ``L``.
    LoopBreakError
        ``1 + D_L = 0``: the closed loop is not well-posed.

    Examples
    --------
    >>> import control
    >>> m = margins(control.tf([1.0], [1.0, 1.0, 0.0]))
    >>> round(m.phase_margin_deg, 6), round(m.gain_crossover_frequency, 6)
    (51.827292, 0.786151)
    """
    import control

    a, b, c, d, period = siso_state_space(L, "L")
    eps_w = _min_frequency(min_frequency, period)
    w_plane = None if period is None else _w_plane((a, b, c, d), period)
    if w_plane is not None:
        # z = (1 + νT/2) / (1 − νT/2) maps the unit circle onto s = jν: L(e^{jωT}) = L_w(jν), ν = (2/T) tan(ωT/2)
        tf = transfer_function_of(w_plane, None)
        eps_solver = 2.0 / period * math.tan(eps_w * period / 2.0)
    elif isinstance(L, control.TransferFunction):
        tf = L  # as given: a round trip through state space would add round-off to structural zeros
        eps_solver = eps_w
    else:
        tf = transfer_function_of((a, b, c, d), period)
        eps_solver = eps_w
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # |L| = inf at an integrator's ω = 0 root
        gm, pm, _sm, w_pc, w_gc, _wms = control.stability_margins(tf, returnall=True, epsw=eps_solver,
                                                                  method="poly")
    gm, pm = np.asarray(gm, dtype=float), np.asarray(pm, dtype=float)
    w_pc, w_gc = np.real(np.asarray(w_pc)).astype(float), np.real(np.asarray(w_gc)).astype(float)
    if w_plane is not None:
        w_pc = 2.0 / period * np.arctan(w_pc * period / 2.0)
        w_gc = 2.0 / period * np.arctan(w_gc * period / 2.0)
    keep_pc = (w_pc > eps_w) & np.isfinite(gm) & (gm > 0)
    keep_gc = (w_gc > eps_w) & np.isfinite(pm)
    return _assemble(name=name, method="polynomial", period=period, matrices=(a, b, c, d),
                     phase_crossovers=w_pc[keep_pc], gain_margins=gm[keep_pc],
                     gain_crossovers=w_gc[keep_gc], phase_margins_deg=pm[keep_gc])


def margins_by_sweep(L: Any, *, w_min: float, w_max: float, points: int = DEFAULT_SWEEP_POINTS,
                     name: str = "", min_frequency: float | None = None) -> Margins:
    """Gain, phase and delay margins by a dense frequency sweep and Brent root refinement.

    Independent of :func:`margins`: ``L(jω)`` (``L(e^{jωT})`` for a sampled
    loop) is evaluated from the state-space matrices by solving
    ``(sI − A) X = B`` with numpy on ``points`` log-spaced frequencies.

    * gain crossovers: sign changes of ``log|L|`` between grid points,
      refined by :func:`scipy.optimize.brentq` on ``log|L(jω)|``;
    * phase crossovers: the phase is unwrapped along the grid
      (``numpy.unwrap``); a cell where ``(φ + 180°) / 360°`` changes its
      integer part ``m`` holds a crossing of the negative real axis, refined
      by ``brentq`` on ``φ(ω) + 180° − 360° m``, with ``φ(ω)`` unwrapped
      locally against the cell's left end.

    Two crossings closer than one grid cell (or a tangency) can be missed:
    the grid must resolve the loop (lightly damped modes need more points).

    Parameters
    ----------
    L : control.StateSpace or control.TransferFunction
        SISO loop transfer, continuous or sampled.
    w_min, w_max : float
        Sweep range [rad/s], ``0 < w_min < w_max``; for a sampled loop
        ``w_max <= π / T``.
    points : int
        Number of grid frequencies, >= 2.
    name : str
    min_frequency : float, optional
        As in :func:`margins`.

    Returns
    -------
    Margins
        With ``method = "sweep"``.

    Raises
    ------
    FrequencyGridError
        A bad range or number of points, or a grid frequency on a pole of ``L``.
    LoopTypeError, NonFiniteLoopError, LoopBreakError
        As :func:`margins`.
    """
    a, b, c, d, period = siso_state_space(L, "L")
    eps_w = _min_frequency(min_frequency, period)
    w_lo, w_hi = _validate_range(w_min, w_max, period)
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 2:
        raise FrequencyGridError(f"points = {points!r}: expected an integer >= 2, e.g. {DEFAULT_SWEEP_POINTS}")
    grid = np.geomspace(w_lo, w_hi, int(points))
    response = _evaluate((a, b, c, d), _frequency_points(grid, period), grid)

    def at(w: float) -> complex:
        return complex(_evaluate((a, b, c, d), _frequency_points(np.array([w]), period), np.array([w]))[0])

    # gain crossovers: log|L| = 0
    above = np.abs(response) >= 1.0
    gain_cross = []
    for k in np.flatnonzero(above[:-1] != above[1:]):
        root = _refine(lambda w: math.log(max(abs(at(w)), _TINY)), grid[k], grid[k + 1])
        if root is not None:
            gain_cross.append(root)

    # phase crossovers: unwrapped phase through −180° + 360° m
    phase = np.unwrap(np.angle(response))
    turns = np.floor((phase + math.pi) / (2.0 * math.pi))
    phase_cross = []
    for k in np.flatnonzero(turns[:-1] != turns[1:]):
        target = 2.0 * math.pi * max(turns[k], turns[k + 1]) - math.pi
        left = phase[k]

        def shifted(w: float, left: float = left, target: float = target) -> float:
            return left + _wrap(cmath.phase(at(w)) - left) - target

        root = _refine(shifted, grid[k], grid[k + 1])
        if root is not None:
            phase_cross.append(root)

    w_gc = np.array([w for w in gain_cross if w > eps_w])
    w_pc = np.array([w for w in phase_cross if w > eps_w])
    resp_gc = np.array([at(w) for w in w_gc], dtype=complex)
    resp_pc = np.array([at(w) for w in w_pc], dtype=complex)
    with np.errstate(divide="ignore"):
        gm = 1.0 / np.abs(resp_pc)
    pm = np.remainder(np.angle(resp_gc, deg=True), 360.0) - 180.0
    return _assemble(name=name, method="sweep", period=period, matrices=(a, b, c, d),
                     phase_crossovers=w_pc, gain_margins=gm, gain_crossovers=w_gc, phase_margins_deg=pm)


# --------------------------------------------------------------------------- frequency response


@dataclass(frozen=True, kw_only=True, slots=True)
class LoopFrequencyResponse:
    """Frequency response of a SISO loop, for Bode and Nyquist plots drawn elsewhere.

    Attributes
    ----------
    name : str
    period : float or None
        Sampling period [s] of a sampled loop (evaluated at ``z = e^{jωT}``), else ``None``.
    omega : ndarray, shape (N,)
        Frequencies [rad/s], increasing (read-only, like every array here).
    magnitude_db : ndarray, shape (N,)
        ``20 log10 |L|`` [dB].
    phase_deg : ndarray, shape (N,)
        ``arg L`` [deg], unwrapped along ``omega`` and offset by a multiple of
        360° so that the first value lies in (−300°, 60°] (an integrator of
        type ``r <= 3`` starts near ``−90° r``).
    nyquist_real, nyquist_imag : ndarray, shape (N,)
        ``Re L`` and ``Im L``.
    """

    name: str
    period: float | None
    omega: np.ndarray
    magnitude_db: np.ndarray
    phase_deg: np.ndarray
    nyquist_real: np.ndarray
    nyquist_imag: np.ndarray

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: every field, arrays as lists, non-finite numbers as ``None``."""
        return to_jsonable(self)


def frequency_response_data(L: Any, w: Any, *, name: str = "") -> LoopFrequencyResponse:
    """Evaluate a SISO loop on given frequencies (numpy, from its state-space matrices).

    Parameters
    ----------
    L : control.StateSpace or control.TransferFunction
        Continuous or sampled SISO loop.
    w : array_like, shape (N,)
        Frequencies [rad/s], positive, finite, strictly increasing (a sampled
        loop may be evaluated beyond ``π/T``; the response is then aliased).
    name : str

    Returns
    -------
    LoopFrequencyResponse

    Raises
    ------
    FrequencyGridError
        Bad frequencies, or one of them on a pole of ``L``.
    LoopTypeError, NonFiniteLoopError
        As :func:`margins`.
    """
    a, b, c, d, period = siso_state_space(L, "L")
    omega = np.array(w, dtype=float).reshape(-1) if np.ndim(w) <= 1 else None
    if omega is None or omega.size == 0:
        raise FrequencyGridError(f"w has shape {np.shape(w)}: expected a non-empty 1-D array of frequencies [rad/s]")
    if not np.all(np.isfinite(omega)) or omega[0] <= 0.0 or np.any(np.diff(omega) <= 0.0):
        raise FrequencyGridError(
            f"w = [{omega[0]:.6g}, ..., {omega[-1]:.6g}] ({omega.size} values): expected positive, finite, "
            f"strictly increasing frequencies [rad/s], e.g. numpy.geomspace(1e-2, 1e2, 500)"
        )
    response = _evaluate((a, b, c, d), _frequency_points(omega, period), omega)
    with np.errstate(divide="ignore"):
        magnitude = 20.0 * np.log10(np.abs(response))
    phase = np.degrees(np.unwrap(np.angle(response)))
    phase -= 360.0 * math.ceil((phase[0] - 60.0) / 360.0)
    arrays = [omega, magnitude, phase, response.real.copy(), response.imag.copy()]
    for array in arrays:
        array.setflags(write=False)
    return LoopFrequencyResponse(name=name, period=period, omega=arrays[0], magnitude_db=arrays[1],
                                 phase_deg=arrays[2], nyquist_real=arrays[3], nyquist_imag=arrays[4])


# --------------------------------------------------------------------------- helpers: validation


def _validate_range(w_min: Any, w_max: Any, period: float | None) -> tuple[float, float]:
    try:
        lo, hi = float(w_min), float(w_max)
    except (TypeError, ValueError) as err:
        raise FrequencyGridError(f"w_min = {w_min!r}, w_max = {w_max!r}: expected numbers [rad/s]") from err
    if not (0.0 < lo < hi and math.isfinite(hi)):
        raise FrequencyGridError(
            f"w_min = {w_min!r}, w_max = {w_max!r}: expected 0 < w_min < w_max < inf [rad/s], e.g. "
            f"w_min=1e-3, w_max=1e3"
        )
    if period is not None and hi > math.pi / period * (1.0 + 1e-12):
        raise FrequencyGridError(
            f"w_max = {w_max!r} rad/s exceeds the Nyquist frequency π/T = {math.pi / period:.6g} rad/s of the "
            f"sampled loop (T = {period} s): pass w_max <= π/T"
        )
    return lo, min(hi, math.pi / period) if period is not None else hi


def _min_frequency(min_frequency: float | None, period: float | None) -> float:
    if min_frequency is None:
        return MIN_FREQUENCY_FRACTION * (math.pi / period if period is not None else 1.0)
    value = float(min_frequency)
    if not (value >= 0.0 and math.isfinite(value)):
        raise FrequencyGridError(f"min_frequency = {min_frequency!r}: expected a finite frequency >= 0 [rad/s]")
    return value


# --------------------------------------------------------------------------- helpers: frequency domain


def _frequency_points(omega: np.ndarray, period: float | None) -> np.ndarray:
    """``s = jω`` (continuous) or ``z = e^{jωT}`` (sampled)."""
    return 1j * omega if period is None else np.exp(1j * omega * period)


def _evaluate(system: Matrices, points: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``C (λI − A)^{-1} B + D`` at each ``λ`` of ``points``, shape (N,) complex."""
    a, b, c, d = system
    n = a.shape[0]
    if n == 0:
        return np.full(points.shape, complex(d[0, 0]))
    matrices = points[:, None, None] * np.eye(n) - a
    try:
        x = np.linalg.solve(matrices, np.broadcast_to(b.astype(complex), (points.size, n, 1)))
    except np.linalg.LinAlgError:
        for k in range(points.size):
            if np.linalg.matrix_rank(matrices[k]) < n:
                raise FrequencyGridError(
                    f"ω = {omega[k]:.17g} rad/s is a pole of L (λI − A singular): move the frequency grid "
                    f"off the pole"
                ) from None
        raise
    return (c @ x)[:, 0, 0] + d[0, 0]


def _wrap(angle: float) -> float:
    """``angle`` wrapped into [−π, π)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _refine(func: Any, lo: float, hi: float) -> float | None:
    """Root of ``func`` in ``[lo, hi]`` by Brent's method, ``None`` if it does not change sign there."""
    f_lo, f_hi = float(func(lo)), float(func(hi))
    if f_lo == 0.0:
        return float(lo)
    if f_hi == 0.0:
        return float(hi)
    if f_lo * f_hi > 0.0:  # the grid values disagreed with the point evaluation (round-off at a tangency)
        return None
    return float(brentq(func, lo, hi, xtol=1e-300, rtol=_BRENTQ_RTOL, maxiter=_BRENTQ_MAXITER))


# --------------------------------------------------------------------------- helpers: assembling a result


def _pole_sort_key(p: complex) -> tuple[float, float]:
    return (round(p.real, 12), round(p.imag, 12))


def _assemble(*, name: str, method: str, period: float | None, matrices: Matrices,
              phase_crossovers: np.ndarray, gain_margins: np.ndarray,
              gain_crossovers: np.ndarray, phase_margins_deg: np.ndarray) -> Margins:
    a, b, c, d = matrices
    discrete = period is not None
    if discrete:  # the end of the Nyquist curve is examined below, not by the routes
        nyquist = math.pi / period * (1.0 - _NYQUIST_BAND)
        keep = np.asarray(phase_crossovers) < nyquist
        phase_crossovers, gain_margins = np.asarray(phase_crossovers)[keep], np.asarray(gain_margins)[keep]
        keep = np.asarray(gain_crossovers) < nyquist
        gain_crossovers, phase_margins_deg = np.asarray(gain_crossovers)[keep], np.asarray(phase_margins_deg)[keep]
    ends = [(0.0, 1.0 if discrete else 0.0)] + ([(math.pi / period, -1.0)] if discrete else [])
    for omega, point in ends:  # L(0) (or L(1), L(−1)) on the negative real axis: a phase crossover there
        value = _real_gain_at(matrices, point)
        if value is not None and value < 0.0:
            phase_crossovers = np.concatenate([[omega], phase_crossovers])
            gain_margins = np.concatenate([[1.0 / abs(value)], gain_margins])
    order_pc = np.argsort(phase_crossovers, kind="stable")
    w_pc = np.asarray(phase_crossovers, dtype=float)[order_pc]
    gm = np.asarray(gain_margins, dtype=float)[order_pc]
    order_gc = np.argsort(gain_crossovers, kind="stable")
    w_gc = np.asarray(gain_crossovers, dtype=float)[order_gc]
    pm = np.asarray(phase_margins_deg, dtype=float)[order_gc]
    dm = np.radians(np.remainder(pm, 360.0)) / w_gc if w_gc.size else np.zeros(0)

    open_poles = np.linalg.eigvals(a) if a.size else np.zeros(0, dtype=complex)
    pole_frequencies = _boundary_pole_frequencies(open_poles, period)
    at_pole = np.array([_near_any(w, pole_frequencies) for w in w_pc], dtype=bool)
    dropped = w_pc[at_pole]
    w_pc, gm = w_pc[~at_pole], gm[~at_pole]
    if pm.size:
        j = int(np.argmin(np.abs(pm)))
        phase_margin, w_c = float(pm[j]), float(w_gc[j])
        delay_margin = float(np.min(dm))
    else:
        phase_margin, w_c, delay_margin = math.inf, math.nan, math.inf

    # poles: open loop from the realisation (above), closed loop from u = r − y around it
    one_plus_d = 1.0 + float(d[0, 0])
    if abs(one_plus_d) <= 1e-12 * max(1.0, abs(float(d[0, 0]))):
        raise LoopBreakError(
            f"L({'z' if discrete else 's'}) has feedthrough D = {float(d[0, 0])!r}: 1 + D = 0, so the closed "
            f"loop 1/(1 + L) is not well-posed (infinite gain at {'the Nyquist frequency' if discrete else 'high frequency'})"
        )
    closed = a - np.outer(b[:, 0], c[0]) / one_plus_d if a.size else a
    closed_poles = np.linalg.eigvals(closed) if closed.size else np.zeros(0, dtype=complex)
    unstable, boundary = _count_poles(open_poles, discrete)
    cl_unstable, cl_boundary = _count_poles(closed_poles, discrete)
    closed_stable = cl_unstable == 0 and cl_boundary == 0

    gain_margin, w_pi, lower = _headline_gain_margins(gm, w_pc, closed_stable)
    notes = []
    positive = sorted({round(float(w), 12) for w in pole_frequencies if w > 0.0})
    if positive:
        where = "unit circle" if discrete else "imaginary axis"
        listed = ", ".join(f"{w:.6g}" for w in positive)
        notes.append(
            f"the open loop has poles on the {where} at ω = {listed} rad/s: |L| is infinite there and the Nyquist "
            "curve closes at infinity; the closed loop becomes marginal as the gain tends to 0"
            + (f"; the phase crossover(s) the solver returned at the pole(s) ({', '.join(f'{w:.6g}' for w in dropped)}"
               " rad/s, where Im(num·conj den) vanishes with den) are not crossings of the negative real axis and are "
               "dropped" if dropped.size else "")
        )
    region = "outside the unit circle" if discrete else "in the right half plane"
    if unstable:
        notes.append(
            f"the open loop has {unstable} pole(s) {region}: the margins alone do not certify stability; by the "
            f"Nyquist criterion the closed loop is stable iff L encircles −1 counter-clockwise {unstable} "
            f"time{'s' if unstable > 1 else ''} "
            f"— its poles say it is {'stable' if closed_stable else 'unstable'}"
        )
    if not closed_stable:
        notes.append(
            f"the closed loop 1/(1 + L) is unstable ({cl_unstable} pole(s) {region}, {cl_boundary} on the "
            f"boundary): the margins measure the distance to the boundary from the wrong side; delay margin 0"
        )
        delay_margin = 0.0
    return Margins(
        name=name, method=method, period=period,
        gain_margin=gain_margin,
        gain_margin_db=20.0 * math.log10(gain_margin) if math.isfinite(gain_margin) else math.inf,
        lower_gain_margin=lower,
        lower_gain_margin_db=_db(lower),
        phase_margin_deg=phase_margin, delay_margin_s=delay_margin,
        delay_margin_samples=(delay_margin / period if discrete else None),
        phase_crossover_frequency=w_pi, gain_crossover_frequency=w_c,
        phase_crossovers=tuple(float(v) for v in w_pc), gain_margins=tuple(float(v) for v in gm),
        gain_crossovers=tuple(float(v) for v in w_gc), phase_margins_deg=tuple(float(v) for v in pm),
        delay_margins_s=tuple(float(v) for v in dm),
        open_loop_unstable_poles=unstable, open_loop_boundary_poles=boundary,
        closed_loop_stable=closed_stable,
        closed_loop_poles=tuple(sorted((complex(p) for p in closed_poles), key=_pole_sort_key)),
        notes=tuple(notes),
    )


def _db(gain: float | None) -> float | None:
    """``20 log10(gain)`` [dB]; ``None`` for ``None``."""
    return None if gain is None else 20.0 * math.log10(gain)


def _boundary_pole_frequencies(poles: np.ndarray, period: float | None) -> np.ndarray:
    """Frequencies [rad/s] of the poles on the imaginary axis (unit circle when sampled)."""
    discrete = period is not None
    poles = np.asarray(poles, dtype=complex)
    if discrete:
        on = np.abs(np.abs(poles) - 1.0) <= STABILITY_TOLERANCE
        return np.abs(np.angle(poles[on])) / period
    on = np.abs(poles.real) <= STABILITY_TOLERANCE * np.maximum(1.0, np.abs(poles))
    return np.abs(poles[on].imag)


def _near_any(w: float, frequencies: np.ndarray) -> bool:
    """``w`` within ``_POLE_CROSSOVER_RTOL`` (relative) of one of ``frequencies`` (0 excluded)."""
    return bool(w > 0.0 and np.any(np.abs(frequencies - w) <= _POLE_CROSSOVER_RTOL * max(w, 1e-300)))


def _headline_gain_margins(gm: np.ndarray, w_pc: np.ndarray,
                           closed_stable: bool) -> tuple[float, float, float | None]:
    """``(gain_margin, its phase crossover, lower_gain_margin)`` as described in the module docstring."""
    if not gm.size:
        return math.inf, math.nan, None
    if not closed_stable:
        i = int(np.argmin(np.abs(np.log(np.maximum(gm, _TINY)))))
        return float(gm[i]), float(w_pc[i]), None
    above, below = gm > 1.0, gm < 1.0
    lower = float(np.max(gm[below])) if below.any() else None
    if not above.any():
        return math.inf, math.nan, lower
    i = int(np.flatnonzero(above)[np.argmin(gm[above])])
    return float(gm[i]), float(w_pc[i]), lower


def _real_gain_at(system: Matrices, point: float) -> float | None:
    """``L`` at the real point ``s = 0``, ``z = 1`` or ``z = −1``; ``None`` on a pole (e.g. an integrator)."""
    a, b, c, d = system
    if a.size == 0:
        return float(d[0, 0])
    matrix = point * np.eye(a.shape[0]) - a
    if np.linalg.cond(matrix) > ILL_POSED_CONDITION:
        return None
    return float((c @ np.linalg.solve(matrix, b))[0, 0] + d[0, 0])


def _w_plane(system: Matrices, period: float) -> Matrices | None:
    """Continuous ``L_w(s) = L(z)`` with ``z = (α + s) / (α − s)``, ``α = 2/T`` (exact, no approximation).

    With ``P = I + A_d``: ``A_w = α P⁻¹ (A_d − I)``, ``B_w = P⁻¹ B_d``,
    ``C_w = C_d (α I − A_w)``, ``D_w = D_d − C_d P⁻¹ B_d``.  ``None`` when
    ``L`` has a pole at ``z = −1`` (``P`` singular).
    """
    a, b, c, d = system
    n = a.shape[0]
    if n == 0:
        return system
    alpha = 2.0 / period
    p = np.eye(n) + a
    if np.linalg.cond(p) > ILL_POSED_CONDITION:
        return None
    a_w = alpha * np.linalg.solve(p, a - np.eye(n))
    b_w = np.linalg.solve(p, b)
    return a_w, b_w, c @ (alpha * np.eye(n) - a_w), d - c @ b_w


def _count_poles(poles: np.ndarray, discrete: bool) -> tuple[int, int]:
    """``(outside, on the boundary)`` of the stability region, within :data:`STABILITY_TOLERANCE`."""
    if discrete:
        distance = np.abs(poles) - 1.0
        band = STABILITY_TOLERANCE
    else:
        distance = poles.real
        band = STABILITY_TOLERANCE * np.maximum(1.0, np.abs(poles))
    return int(np.sum(distance > band)), int(np.sum(np.abs(distance) <= band))
