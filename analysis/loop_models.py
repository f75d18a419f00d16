"""Loops for :mod:`analysis.margins`: the linear model of a closed loop (:class:`LoopModel`, :func:`loop_model`),
the loop transfer broken at an input or output (continuous, :func:`loop_transfer`, and sampled with a delay,
:func:`sampled_loop_transfer`, :func:`sampled_loop`), their input errors and the state-space helpers the margin
computations share.

:mod:`analysis.margins` re-exports the public names.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid.jsonable import to_jsonable

# Helpers shared with analysis.margins have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = [
    "LoopDefinitionError",
    "LoopShapeError",
    "NonFiniteLoopError",
    "LoopTypeError",
    "LoopBreakError",
    "SamplingError",
    "FrequencyGridError",
    "LoopModel",
    "loop_model",
    "loop_transfer",
    "sampled_loop_transfer",
    "sampled_loop",
]


ILL_POSED_CONDITION = 1e12
"""Condition number above which ``I + D K`` (or a linear solve of the margins) counts as singular."""


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
    a, b, c, d, dt = siso_state_space(L, "L")
    if dt is not None:
        raise SamplingError(
            f"L is already discrete (dt = {dt} s): sampled_loop needs the continuous loop L(s); for a "
            f"delay only, multiply by z^-d yourself"
        )
    sampled = control.c2d(control.ss(a, b, c, d), period, method="zoh")
    a, b, c, d = _delay_output(_ss_matrices(sampled), delay)
    return control.ss(a, b, c, d, period)


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


def _is_lti(value: Any) -> bool:
    if not all(hasattr(value, attr) for attr in ("ninputs", "noutputs", "dt")):
        return False
    import control

    return isinstance(value, (control.StateSpace, control.TransferFunction))


def siso_state_space(L: Any, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float | None]:
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

Matrices = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _ss_matrices(system: Any) -> Matrices:
    n, m, p = system.nstates, system.ninputs, system.noutputs
    return (np.asarray(system.A, dtype=float).reshape(n, n), np.asarray(system.B, dtype=float).reshape(n, m),
            np.asarray(system.C, dtype=float).reshape(p, n), np.asarray(system.D, dtype=float).reshape(p, m))


def transfer_function_of(system: Matrices, period: float | None) -> Any:
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
    if np.linalg.cond(coupling) > ILL_POSED_CONDITION:
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
