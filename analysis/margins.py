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
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import brentq

from hybrid.jsonable import to_jsonable

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
_ILL_POSED_CONDITION = 1e12
_NYQUIST_BAND = 1e-9
_TINY = 1e-300
_POLE_CROSSOVER_RTOL = 1e-6


# --------------------------------------------------------------------------- errors


class LoopDefinitionError(ValueError):
    """Base class: a loop, a sampling or a frequency grid is ill-defined."""


class LoopShapeError(LoopDefinitionError):
    """A matrix is not 2-D, not square, or does not fit the others."""


class NonFiniteLoopError(LoopDefinitionError):
    """A matrix or a coefficient contains NaN or ±inf."""


class LoopTypeError(LoopDefinitionError, TypeError):
    """A loop transfer is not a python-control LTI system, or not SISO, or has no usable timebase."""


class LoopBreakError(LoopDefinitionError):
    """The break point is unknown or ambiguous, or the loop is not well-posed (``I + D K`` singular)."""


class SamplingError(LoopDefinitionError):
    """A sampling period that is not positive and finite, a negative or non-integer delay,
    or a controller whose timebase does not fit the loop."""


class FrequencyGridError(LoopDefinitionError):
    """Frequencies that are not positive, finite and increasing, or that hit a pole of ``L``."""


# --------------------------------------------------------------------------- the loop model


@dataclass(frozen=True, kw_only=True, slots=True)
class LoopModel:
    """A linear plant and a linear controller in negative feedback, ``u = −K y``.

    Plant (continuous time)::

        x' = A x + B u,   y = C x + D u

    Controller (static gain when it has no state; ``K(s)`` or ``K(z)``
    otherwise)::

        ξ' = A_K ξ + B_K y,   c = C_K ξ + D_K y,   u = −c

    Build it with :func:`loop_model` (accepts a gain matrix or a python-control
    system as the controller); direct construction validates as well.

    Attributes
    ----------
    plant_a : ndarray, shape (n, n)
        ``A`` [1/s] (read-only, like every array here).
    plant_b : ndarray, shape (n, m)
        ``B``: ``m`` plant inputs (actuators).
    plant_c : ndarray, shape (p, n)
        ``C``: ``p`` plant outputs (measurements).
    plant_d : ndarray, shape (p, m)
        ``D``.
    controller_a : ndarray, shape (q, q)
        ``A_K``; ``q = 0`` for a static gain.
    controller_b : ndarray, shape (q, p)
    controller_c : ndarray, shape (m, q)
    controller_d : ndarray, shape (m, p)
        ``D_K``; for a static gain this is ``K`` itself: rows are plant
        inputs, columns plant outputs.
    controller_dt : float or None
        ``None`` for a static gain, ``0.0`` for a continuous controller, the
        sampling period [s] for a discrete one.
    input_names : tuple of str, length m
    output_names : tuple of str, length p
    """

    plant_a: np.ndarray
    plant_b: np.ndarray
    plant_c: np.ndarray
    plant_d: np.ndarray
    controller_a: np.ndarray
    controller_b: np.ndarray
    controller_c: np.ndarray
    controller_d: np.ndarray
    controller_dt: float | None = None
    input_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        a = _matrix(self.plant_a, "A")
        n = a.shape[0]
        if a.shape != (n, n):
            raise LoopShapeError(f"A has shape {a.shape}: expected a square (n, n) state matrix")
        b = _matrix(self.plant_b, "B", rows=n, rows_meaning="n = A.shape[0] states")
        m = b.shape[1]
        c = _matrix(self.plant_c, "C", cols=n, cols_meaning="n = A.shape[0] states")
        p = c.shape[0]
        d = _matrix(self.plant_d, "D", rows=p, cols=m,
                    rows_meaning="p = C.shape[0] outputs", cols_meaning="m = B.shape[1] inputs")
        dk = _matrix(self.controller_d, "K (D_K)", rows=m, cols=p,
                     rows_meaning="m plant inputs (u = −K y)", cols_meaning="p plant outputs",
                     hint="; transpose it if you wrote y = K u")
        ak = _matrix(self.controller_a, "A_K")
        q = ak.shape[0]
        if ak.shape != (q, q):
            raise LoopShapeError(f"A_K has shape {ak.shape}: expected a square (q, q) controller state matrix")
        bk = _matrix(self.controller_b, "B_K", rows=q, cols=p,
                     rows_meaning="q = A_K.shape[0] controller states", cols_meaning="p plant outputs")
        ck = _matrix(self.controller_c, "C_K", rows=m, cols=q,
                     rows_meaning="m plant inputs", cols_meaning="q = A_K.shape[0] controller states")
        dt = self.controller_dt
        if q == 0:
            dt = None
        elif (not isinstance(dt, (int, float, np.integer, np.floating)) or isinstance(dt, bool)
              or not (float(dt) >= 0.0 and math.isfinite(float(dt)))):
            raise SamplingError(
                f"controller_dt = {self.controller_dt!r} with a {q}-state controller: expected 0.0 "
                f"(continuous) or the positive sampling period [s] of a discrete controller"
            )
        else:
            dt = float(dt)
        inputs = _names(self.input_names, m, "input_names", "u")
        outputs = _names(self.output_names, p, "output_names", "y")
        for field, value in (("plant_a", a), ("plant_b", b), ("plant_c", c), ("plant_d", d),
                             ("controller_a", ak), ("controller_b", bk), ("controller_c", ck),
                             ("controller_d", dk)):
            object.__setattr__(self, field, value)
        object.__setattr__(self, "controller_dt", dt)
        object.__setattr__(self, "input_names", inputs)
        object.__setattr__(self, "output_names", outputs)

    @property
    def n_inputs(self) -> int:
        """Number ``m`` of plant inputs."""
        return int(self.plant_b.shape[1])

    @property
    def n_outputs(self) -> int:
        """Number ``p`` of plant outputs."""
        return int(self.plant_c.shape[0])

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: ``plant`` and ``controller`` as ``{"A", "B", "C", "D"}`` nested lists, then the names."""
        return to_jsonable({
            "plant": {"A": self.plant_a, "B": self.plant_b, "C": self.plant_c, "D": self.plant_d},
            "controller": {"A": self.controller_a, "B": self.controller_b, "C": self.controller_c,
                           "D": self.controller_d, "dt": self.controller_dt},
            "input_names": self.input_names,
            "output_names": self.output_names,
        })


def loop_model(
    A: Any,
    B: Any,
    C: Any,
    D: Any,
    K: Any,
    *,
    input_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
) -> LoopModel:
    """Plant ``(A, B, C, D)`` with the negative-feedback controller ``u = −K y``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Plant state matrix (continuous time) [1/s].
    B : array_like, shape (n, m)
    C : array_like, shape (p, n)
    D : array_like, shape (p, m), or None
        ``None`` means zeros.
    K : array_like, shape (m, p), or python-control ``StateSpace`` / ``TransferFunction``
        A static gain (rows are plant inputs, columns plant outputs; a scalar
        when ``m = p = 1``), or a dynamic controller with ``p`` inputs and
        ``m`` outputs, continuous (``dt = 0``) or discrete (``dt = T``).  The
        sign is that of ``u = −K y``: a positive ``K`` on a positive plant is
        negative feedback.
    input_names, output_names : sequence of str, optional
        Names of the plant inputs / outputs, usable as break points, e.g.
        ``("pan_rate", "omega")``; default ``u0, u1, ...`` and ``y0, ...``.

    Returns
    -------
    LoopModel

    Raises
    ------
    LoopShapeError, NonFiniteLoopError, SamplingError, LoopTypeError
        Shapes that do not fit, NaN/inf entries, a controller with an
        unspecified timebase (``dt = True``) or of another type.
    """
    b = _matrix(B, "B")
    c = _matrix(C, "C")
    m, p = b.shape[1], c.shape[0]
    d = np.zeros((p, m)) if D is None else D
    if _is_lti(K):
        import control

        try:
            k_ss = control.ss(K)
        except Exception as err:  # improper transfer function
            raise LoopTypeError(
                f"K = {K!r} cannot be written in state-space form ({err}); pass a proper controller"
            ) from err
        if (k_ss.ninputs, k_ss.noutputs) != (p, m):
            raise LoopShapeError(
                f"K has {k_ss.ninputs} inputs and {k_ss.noutputs} outputs: expected p = {p} inputs "
                f"(plant outputs) and m = {m} outputs (plant inputs)"
            )
        dt = k_ss.dt
        if k_ss.nstates and (dt is True):
            raise SamplingError(
                "K has dt = True (discrete, unspecified period): create it with its sampling period, "
                "e.g. control.ss(..., dt=T)"
            )
        return LoopModel(
            plant_a=A, plant_b=b, plant_c=c, plant_d=d,
            controller_a=np.asarray(k_ss.A, dtype=float).reshape(k_ss.nstates, k_ss.nstates),
            controller_b=np.asarray(k_ss.B, dtype=float).reshape(k_ss.nstates, p),
            controller_c=np.asarray(k_ss.C, dtype=float).reshape(m, k_ss.nstates),
            controller_d=np.asarray(k_ss.D, dtype=float).reshape(m, p),
            controller_dt=(None if not k_ss.nstates else float(dt or 0.0)),
            input_names=tuple(input_names or ()), output_names=tuple(output_names or ()),
        )
    try:
        gain = np.array(K, dtype=float)
    except (TypeError, ValueError) as err:
        raise LoopTypeError(
            f"K = {K!r}: expected an (m, p) = ({m}, {p}) gain matrix or a python-control system"
        ) from err
    if gain.ndim == 0:
        gain = gain.reshape(1, 1)
    return LoopModel(
        plant_a=A, plant_b=b, plant_c=c, plant_d=d,
        controller_a=np.zeros((0, 0)), controller_b=np.zeros((0, p)), controller_c=np.zeros((m, 0)),
        controller_d=gain, controller_dt=None,
        input_names=tuple(input_names or ()), output_names=tuple(output_names or ()),
    )


# --------------------------------------------------------------------------- breaking loops


def loop_transfer(model: LoopModel, *, at_input: int | str | None = None,
                  at_output: int | str | None = None) -> Any:
    """Continuous loop transfer ``L(s)`` broken at one plant input or output, other loops closed.

    Convention (the loop "at the plant input" ``L_I = K G`` and "at the plant
    output" ``L_O = G K`` of multivariable control, one channel at a time):
    cut the chosen signal, inject ``v`` on the plant side of the cut, and
    measure what comes back to the other side of the cut with the sign
    flipped, ``L = −(returned) / v``, so that reconnecting the cut gives the
    closed loop ``1 / (1 + L)``.  The realisation keeps all ``n + q`` states,
    so the poles of its closed loop are exactly those of the whole
    multi-loop system, whichever channel is cut.

    * ``at_input=i`` (loop at the plant input, an actuator): the plant
      receives ``u_i = v``, the controller still drives the other inputs,
      and ``L_i = (K y)_i / v``; for a SISO loop ``L = K P``.
    * ``at_output=j`` (loop at the plant output, a measurement): the
      controller sees ``y_j = v``, the plant's ``y_j`` is returned and
      ``L_j = −y_j / v``; for a SISO loop ``L = P K``.

    Parameters
    ----------
    model : LoopModel
        With a static gain or a continuous controller.
    at_input, at_output : int or str
        Exactly one: the index or the name of the plant input / output.

    Returns
    -------
    control.StateSpace
        SISO, continuous (``dt = 0``), with ``n + q`` states (the other
        loops' modes included: some may be uncontrollable or unobservable
        from the cut, they still belong to the closed loop).

    Raises
    ------
    LoopBreakError
        No or two break points, an unknown index or name, or an ill-posed
        loop (``I + D_K D`` singular).
    SamplingError
        The controller is discrete; use :func:`sampled_loop_transfer`.
    """
    import control

    kind, index = _break_point(model, at_input, at_output)
    if model.controller_dt not in (None, 0.0):
        raise SamplingError(
            f"the controller is discrete (dt = {model.controller_dt} s): a continuous loop needs a static "
            f"or continuous controller; use sampled_loop_transfer(model, period={model.controller_dt}, ...)"
        )
    plant = (model.plant_a, model.plant_b, model.plant_c, model.plant_d)
    ctrl = (model.controller_a, model.controller_b, model.controller_c, model.controller_d)
    a, b, c, d = _break(plant, ctrl, kind, index, model)
    return control.ss(a, b, c, d, name=_loop_name(model, kind, index))


def sampled_loop_transfer(model: LoopModel, period: float, *, at_input: int | str | None = None,
                          at_output: int | str | None = None, delay_samples: int = 1) -> Any:
    """Sampled-data loop transfer ``L(z)`` broken at one plant input or output, other loops closed.

    The standard sampled-data loop: the plant is discretised exactly under a
    zero-order hold at period ``T`` (``control.c2d(..., method="zoh")``), the
    controller acts on the samples (a static gain, or a discrete controller
    with ``dt = T``), and every controller output reaches the hold
    ``delay_samples`` samples late (computation delay), on every channel, the
    cut one included.  The break convention is that of :func:`loop_transfer`.

    Parameters
    ----------
    model : LoopModel
    period : float
        Sampling period ``T`` [s], > 0.
    at_input, at_output : int or str
        Exactly one break point (index or name).
    delay_samples : int
        Computation delay ``d >= 0`` [samples]: ``u_k = −c_{k−d}``.

    Returns
    -------
    control.StateSpace
        SISO, discrete with ``dt = period``.

    Raises
    ------
    SamplingError
        Bad ``period`` or ``delay_samples``, a continuous dynamic controller
        (discretise it first, e.g. ``control.c2d(K, period, "tustin")``), or a
        discrete controller with another period.
    LoopBreakError
        As :func:`loop_transfer`.
    """
    import control

    period = _validate_period(period)
    delay = _validate_delay(delay_samples)
    kind, index = _break_point(model, at_input, at_output)
    dt = model.controller_dt
    if dt == 0.0:
        raise SamplingError(
            f"the controller is continuous with {model.controller_a.shape[0]} states: a sampled loop needs a "
            f"static gain or a discrete controller with dt = period = {period}; discretise it first, e.g. "
            f"control.c2d(K, {period}, 'tustin')"
        )
    if dt is not None and not math.isclose(dt, period, rel_tol=1e-12):
        raise SamplingError(
            f"the controller is discrete with dt = {dt} s but period = {period} s: pass period={dt} or "
            f"re-sample the controller"
        )
    plant_d = control.c2d(control.ss(model.plant_a, model.plant_b, model.plant_c, model.plant_d),
                          period, method="zoh")
    plant = _ss_matrices(plant_d)
    ctrl = _delay_output((model.controller_a, model.controller_b, model.controller_c, model.controller_d),
                         delay)
    a, b, c, d = _break(plant, ctrl, kind, index, model)
    return control.ss(a, b, c, d, period, name=_loop_name(model, kind, index) + f"_sampled_d{delay}")


def sampled_loop(L: Any, period: float, *, delay_samples: int = 1) -> Any:
    """Sampled-data version of a continuous SISO loop ``L(s) = K P(s)``: ``L_zoh(z) z^(−d)``.

    The whole of ``L`` is discretised with a zero-order hold
    (``control.c2d(L, period, method="zoh")``), then multiplied by
    ``z^(−delay_samples)``.  This is the exact sampled-data loop when the
    dynamics of ``L`` are the *plant's* and the controller is a static gain
    evaluated at the samples (a static gain commutes with the hold, so
    ``ZOH(K P) = K ZOH(P)``).  A continuous *dynamic* controller must not be
    sampled this way (it is not preceded by a hold): discretise it on its
    own and use :func:`sampled_loop_transfer`.  For a multi-loop plant,
    :func:`sampled_loop_transfer` also samples the other loops, which
    sampling a continuous :func:`loop_transfer` would not.

    Parameters
    ----------
    L : control.StateSpace or control.TransferFunction
        Continuous SISO loop transfer.
    period : float
        Sampling period ``T`` [s], > 0.
    delay_samples : int
        Computation delay ``d >= 0`` [samples].

    Returns
    -------
    control.StateSpace
        SISO, ``dt = period``, with ``n + d`` states.

    Examples
    --------
    >>> import control
    >>> Lz = sampled_loop(control.tf([2.0], [1.0, 0.0]), 0.1, delay_samples=1)
    >>> [round(float(v), 12) for v in control.tf(Lz).den[0][0]]  # kT / (z (z − 1)), kT = 0.2
    [1.0, -1.0, 0.0]
    """
    import control

    period = _validate_period(period)
    delay = _validate_delay(delay_samples)
    a, b, c, d, dt = _siso_state_space(L, "L")
    if dt is not None:
        raise SamplingError(
            f"L is already discrete (dt = {dt} s): sampled_loop needs the continuous loop L(s); for a "
            f"delay only, multiply by z^-d yourself"
        )
    sampled = control.c2d(control.ss(a, b, c, d), period, method="zoh")
    a, b, c, d = _delay_output(_ss_matrices(sampled), delay)
    return control.ss(a, b, c, d, period)


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
    ``_transfer_function``).  The selection of the headline values, the
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

    a, b, c, d, period = _siso_state_space(L, "L")
    eps_w = _min_frequency(min_frequency, period)
    w_plane = None if period is None else _w_plane((a, b, c, d), period)
    if w_plane is not None:
        # z = (1 + νT/2) / (1 − νT/2) maps the unit circle onto s = jν: L(e^{jωT}) = L_w(jν), ν = (2/T) tan(ωT/2)
        tf = _transfer_function(w_plane, None)
        eps_solver = 2.0 / period * math.tan(eps_w * period / 2.0)
    elif isinstance(L, control.TransferFunction):
        tf = L  # as given: a round trip through state space would add round-off to structural zeros
        eps_solver = eps_w
    else:
        tf = _transfer_function((a, b, c, d), period)
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
    a, b, c, d, period = _siso_state_space(L, "L")
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
    a, b, c, d, period = _siso_state_space(L, "L")
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


def _matrix(value: Any, name: str, *, rows: int | None = None, cols: int | None = None,
            rows_meaning: str = "", cols_meaning: str = "", hint: str = "") -> np.ndarray:
    """``value`` as a read-only 2-D float array of the expected shape, finite, or raise."""
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise LoopShapeError(f"{name} = {value!r}: expected a 2-D array of real numbers") from err
    if array.ndim != 2:
        raise LoopShapeError(
            f"{name} has shape {array.shape}: expected a 2-D matrix; reshape it, e.g. "
            f"numpy.reshape({name.split()[0]}, (-1, 1)) for a column"
        )
    for axis, (expected, meaning) in enumerate(((rows, rows_meaning), (cols, cols_meaning))):
        if expected is not None and array.shape[axis] != expected:
            shape = tuple("?" if x is None else x for x in (rows, cols))
            raise LoopShapeError(
                f"{name} has shape {array.shape}: expected {shape[0]} x {shape[1]} "
                f"({'rows' if axis == 0 else 'columns'}: {meaning}){hint}"
            )
    bad = np.argwhere(~np.isfinite(array))
    if bad.size:
        i, j = (int(v) for v in bad[0])
        raise NonFiniteLoopError(
            f"{name}[{i}, {j}] = {float(array[i, j])!r}: every entry must be finite; {len(bad)} entries are NaN or "
            f"inf — check the linearisation point"
        )
    array.setflags(write=False)
    return array


def _names(value: Sequence[str], count: int, field: str, prefix: str) -> tuple[str, ...]:
    names = tuple(value) if value else tuple(f"{prefix}{i}" for i in range(count))
    if len(names) != count or not all(isinstance(s, str) and s for s in names) or len(set(names)) != count:
        raise LoopShapeError(
            f"{field} = {names!r}: expected {count} distinct non-empty strings, one per "
            f"{'plant input' if prefix == 'u' else 'plant output'}"
        )
    return names


def _validate_period(period: Any) -> float:
    if isinstance(period, bool) or not isinstance(period, (int, float, np.integer, np.floating)):
        raise SamplingError(f"period = {period!r}: expected a positive finite sampling period [s], e.g. 0.05")
    value = float(period)
    if not (value > 0.0 and math.isfinite(value)):
        raise SamplingError(f"period = {period!r}: expected a positive finite sampling period [s], e.g. 0.05")
    return value


def _validate_delay(delay_samples: Any) -> int:
    if isinstance(delay_samples, bool) or not isinstance(delay_samples, (int, np.integer)) or delay_samples < 0:
        raise SamplingError(
            f"delay_samples = {delay_samples!r}: expected a non-negative integer number of samples of "
            f"computation delay (0 = none, 1 = the usual one-sample delay)"
        )
    return int(delay_samples)


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


def _is_lti(value: Any) -> bool:
    if not all(hasattr(value, attr) for attr in ("ninputs", "noutputs", "dt")):
        return False
    import control

    return isinstance(value, (control.StateSpace, control.TransferFunction))


def _siso_state_space(L: Any, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float | None]:
    """``(A, B, C, D, period)`` of a SISO python-control system; ``period`` is ``None`` if continuous."""
    if not _is_lti(L):
        raise LoopTypeError(
            f"{name} = {L!r} ({type(L).__name__}): expected a python-control StateSpace or TransferFunction, "
            f"e.g. control.tf([2.0], [1.0, 0.0])"
        )
    if (L.ninputs, L.noutputs) != (1, 1):
        raise LoopTypeError(
            f"{name} has {L.ninputs} inputs and {L.noutputs} outputs: expected a SISO loop transfer; break the "
            f"loop at one channel with loop_transfer(model, at_input=...)"
        )
    dt = L.dt
    if dt is True:
        raise LoopTypeError(f"{name} has dt = True (discrete, unspecified period): give it its sampling period")
    period = None if not dt else float(dt)
    import control

    try:
        system = control.ss(L)
    except Exception as err:
        raise LoopTypeError(f"{name} is not proper ({err}): a loop transfer must have deg num <= deg den") from err
    n = system.nstates
    a = _matrix(np.asarray(system.A, dtype=float).reshape(n, n), f"{name}.A")
    b = _matrix(np.asarray(system.B, dtype=float).reshape(n, 1), f"{name}.B")
    c = _matrix(np.asarray(system.C, dtype=float).reshape(1, n), f"{name}.C")
    d = _matrix(np.asarray(system.D, dtype=float).reshape(1, 1), f"{name}.D")
    return a, b, c, d, period


def _break_point(model: LoopModel, at_input: Any, at_output: Any) -> tuple[str, int]:
    if not isinstance(model, LoopModel):
        raise LoopTypeError(f"model = {model!r}: expected a LoopModel; build one with loop_model(A, B, C, D, K)")
    if (at_input is None) == (at_output is None):
        raise LoopBreakError(
            f"at_input = {at_input!r}, at_output = {at_output!r}: give exactly one break point, e.g. "
            f"at_input={model.input_names[0]!r} or at_output={model.output_names[0]!r}"
        )
    kind, value, names = (("input", at_input, model.input_names) if at_input is not None
                          else ("output", at_output, model.output_names))
    if isinstance(value, str):
        if value not in names:
            raise LoopBreakError(f"at_{kind} = {value!r}: not a plant {kind} name; known: {', '.join(names)}")
        return kind, names.index(value)
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < len(names):
        raise LoopBreakError(
            f"at_{kind} = {value!r}: expected a name ({', '.join(names)}) or an index in 0..{len(names) - 1}"
        )
    return kind, int(value)


def _loop_name(model: LoopModel, kind: str, index: int) -> str:
    names = model.input_names if kind == "input" else model.output_names
    return "L_" + kind + "_" + re.sub(r"[^0-9A-Za-z_]", "_", names[index])  # python-control rejects "."


# --------------------------------------------------------------------------- helpers: algebra


Matrices = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _ss_matrices(system: Any) -> Matrices:
    n, m, p = system.nstates, system.ninputs, system.noutputs
    return (np.asarray(system.A, dtype=float).reshape(n, n), np.asarray(system.B, dtype=float).reshape(n, m),
            np.asarray(system.C, dtype=float).reshape(p, n), np.asarray(system.D, dtype=float).reshape(p, m))


def _transfer_function(system: Matrices, period: float | None) -> Any:
    """SISO ``num/den`` of a state-space loop, its structural relative degree kept exact.

    ``scipy.signal.ss2tf`` (used by ``control.tf``) leaves round-off of order
    ``eps`` in numerator coefficients that are structurally zero; for a
    continuous loop such a coefficient is a spurious zero near ``|s| ~ 1/eps``
    whose phase creates fake crossovers at high frequency.  The relative
    degree ``r`` is read from the Markov parameters ``D, C B, C A B, ...``
    (negligible below ``1e-10 ‖C‖ ‖A‖^(k−1) ‖B‖``) and the ``r`` leading
    numerator coefficients are set to zero.
    """
    import control

    a, b, c, d = system
    dt = 0 if period is None else period
    tf = control.tf(control.ss(a, b, c, d, dt))
    num = np.atleast_1d(np.asarray(tf.num[0][0], dtype=float))
    den = np.atleast_1d(np.asarray(tf.den[0][0], dtype=float))
    n = a.shape[0]
    if den.size != n + 1 or num.size > n + 1:  # not the plain ss2tf layout: keep the conversion as is
        return tf
    num = np.concatenate([np.zeros(n + 1 - num.size), num])  # leading zeros may have been stripped
    relative_degree = n + 1  # L ≡ 0 unless a Markov parameter is significant
    if d[0, 0] != 0.0:
        relative_degree = 0
    else:
        norm_a, scale = np.linalg.norm(a, 2), np.linalg.norm(b) * np.linalg.norm(c)
        vector = b[:, 0]
        for k in range(1, n + 1):
            if abs(float(c[0] @ vector)) > 1e-10 * scale * norm_a ** (k - 1):
                relative_degree = k
                break
            vector = a @ vector
    num[:relative_degree] = 0.0
    num = np.trim_zeros(num, "f")
    return control.tf(num if num.size else [0.0], den, dt)


def _delay_output(system: Matrices, delay: int) -> Matrices:
    """``z^(−delay)`` after a discrete system: a shift register of ``delay`` blocks of its outputs."""
    a, b, c, d = system
    if delay == 0:
        return a, b, c, d
    q, p = a.shape[0], c.shape[0]
    m = b.shape[1]
    size = q + delay * p
    a_new = np.zeros((size, size))
    b_new = np.zeros((size, m))
    a_new[:q, :q] = a
    b_new[:q] = b
    a_new[q:q + p, :q] = c  # s_1(k+1) = c(k)
    b_new[q:q + p] = d
    for j in range(1, delay):  # s_{j+1}(k+1) = s_j(k)
        a_new[q + j * p:q + (j + 1) * p, q + (j - 1) * p:q + j * p] = np.eye(p)
    c_new = np.zeros((p, size))
    c_new[:, q + (delay - 1) * p:] = np.eye(p)
    return a_new, b_new, c_new, np.zeros((p, m))


def _break(plant: Matrices, ctrl: Matrices, kind: str, index: int, model: LoopModel) -> Matrices:
    """State-space of the loop cut at plant input/output ``index``, the other loops closed.

    Signals: plant ``y = C x + D u``; controller input ``ỹ = S_y y + e_y v``;
    controller output ``c = C_K ξ + D_K ỹ``; plant input ``u = −S_u c + e_u v``;
    returned signal ``w = a·c + b·y`` with ``L = w / v``.  Cut at input ``i``:
    ``S_u = I − e_i e_iᵀ``, ``e_u = e_i``, ``w = c_i``.  Cut at output ``j``:
    ``S_y = I − e_j e_jᵀ``, ``e_y = e_j``, ``w = −y_j``.
    """
    a, b, c, d = plant
    ak, bk, ck, dk = ctrl
    n, m = b.shape
    p, q = c.shape[0], ak.shape[0]
    s_u, e_u, s_y, e_y = np.eye(m), np.zeros(m), np.eye(p), np.zeros(p)
    w_c, w_y = np.zeros(m), np.zeros(p)
    if kind == "input":
        s_u[index, index] = 0.0
        e_u[index] = 1.0
        w_c[index] = 1.0
    else:
        s_y[index, index] = 0.0
        e_y[index] = 1.0
        w_y[index] = -1.0
    coupling = np.eye(m) + s_u @ dk @ s_y @ d
    if np.linalg.cond(coupling) > _ILL_POSED_CONDITION:
        names = model.input_names if kind == "input" else model.output_names
        raise LoopBreakError(
            f"cut at {kind} {names[index]!r}: I + D_K D (feedthrough around the other loops) is singular "
            f"(condition {np.linalg.cond(coupling):.3g}): the loop is not well-posed; check D and K"
        )
    f_u = np.linalg.solve(coupling, np.hstack([-s_u @ dk @ s_y @ c, -s_u @ ck]))  # u = F_u z + g_u v
    g_u = np.linalg.solve(coupling, e_u - s_u @ dk @ e_y)
    f_y = np.hstack([c, np.zeros((p, q))]) + d @ f_u
    g_y = d @ g_u
    f_yt, g_yt = s_y @ f_y, s_y @ g_y + e_y
    f_c = np.hstack([np.zeros((m, n)), ck]) + dk @ f_yt
    g_c = dk @ g_yt
    a_loop = np.zeros((n + q, n + q))
    a_loop[:n, :n] = a
    a_loop[n:, n:] = ak
    a_loop += np.vstack([b @ f_u, bk @ f_yt])
    b_loop = np.concatenate([b @ g_u, bk @ g_yt]).reshape(n + q, 1)
    c_loop = (w_c @ f_c + w_y @ f_y).reshape(1, n + q)
    d_loop = np.array([[w_c @ g_c + w_y @ g_y]])
    return a_loop, b_loop, c_loop, d_loop


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
    if np.linalg.cond(matrix) > _ILL_POSED_CONDITION:
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
    if np.linalg.cond(p) > _ILL_POSED_CONDITION:
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
