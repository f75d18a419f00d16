"""Backward differentiation formulas (BDF): exact coefficients and a fixed-step integrator.

Generic tools, independent of the robot: the coefficients of the ``m``-step
BDF derived exactly from the backward-difference form, its characteristic
roots (zero-stability), the extrapolation weights of the natural predictor,
the histopolation weights that turn interval means into a point value, and a
dense-Newton fixed-step integrator for ``y' = f(t, y)`` used as a reference.

The ``m``-step BDF in backward-difference form is (Hairer, Nørsett & Wanner, *Solving
ODEs I*, §III.1)::

    sum_{j=1}^{m} (1/j) ∇^j y_{k+1} = h f(t_{k+1}, y_{k+1})

which, solved for ``y_{k+1}``, reads::

    y_{k+1} = sum_{j=1}^{m} c_j y_{k+1-j} + beta h f(t_{k+1}, y_{k+1}).

Orders 1–6 are zero-stable; from order 7 on a root of the characteristic
polynomial ``rho(zeta) = zeta^m - sum_j c_j zeta^(m-j)`` lies outside the unit
circle (see :func:`bdf_characteristic_roots`).

Examples
--------
>>> bdf_coefficients(4)
BdfCoefficients(order=4, history=(1.92, -1.44, 0.64, -0.12), beta=0.48)
>>> histopolation_weights(2)
(1.5, -0.5)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

import numpy as np

from hybrid.errors import NumericalFailure

# Helpers shared with analysis.integrators have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = [
    "MIN_ORDER",
    "MAX_ORDER",
    "STARTUP_METHODS",
    "NEWTON_TOL",
    "NEWTON_MAXITER",
    "RK4_SUBSTEPS",
    "BdfOrderError",
    "BdfStepSizeError",
    "BdfHistoryError",
    "BdfStartupError",
    "BdfConvergenceError",
    "BdfCoefficients",
    "BdfSolution",
    "bdf_coefficients",
    "bdf_coefficients_exact",
    "bdf_characteristic_roots",
    "extrapolation_weights",
    "histopolation_weights",
    "validate_order",
    "integrate_bdf",
]

MIN_ORDER = 1
"""Lowest BDF order (implicit Euler)."""
MAX_ORDER = 6
"""Highest zero-stable BDF order."""
STARTUP_METHODS = ("rk4", "exact", "ramp")
"""Start-up procedures accepted by :func:`integrate_bdf`."""
NEWTON_TOL = 1e-12
"""Default Newton tolerance on the update: ``max|Δy_i| / (1 + |y_i|)``."""
NEWTON_MAXITER = 10
"""Default Newton iteration limit of :func:`integrate_bdf`."""
RK4_SUBSTEPS = 16
"""Default number of classical RK4 substeps per BDF step in the ``"rk4"`` start-up."""


# --------------------------------------------------------------------------- errors


class BdfOrderError(ValueError):
    """A BDF order outside the zero-stable range 1–6 (or not an integer)."""


class BdfStepSizeError(ValueError):
    """A step size that is not positive and finite, or a negative step count."""


class BdfHistoryError(ValueError):
    """Start values missing, too short, or of the wrong shape."""


class BdfStartupError(ValueError):
    """An unknown start-up procedure."""


class BdfConvergenceError(NumericalFailure):
    """The Newton corrector of an implicit BDF step did not converge.

    Subclass of :class:`hybrid.errors.NumericalFailure` (hence of
    ``ArithmeticError``) so that an executor reports it as a divergence.

    Attributes
    ----------
    iterations : int
        Newton iterations performed.
    update_norm, residual_norm : float
        Max-norms of the last Newton update and of the residual at the last iterate.
    """

    def __init__(self, cause: str, *, iterations: int, update_norm: float, residual_norm: float) -> None:
        super().__init__(cause)
        self.iterations = iterations
        self.update_norm = update_norm
        self.residual_norm = residual_norm


def validate_order(order: object, *, name: str = "order") -> int:
    """Return ``order`` as an ``int`` if it is a zero-stable BDF order (1–6), else raise.

    Raises
    ------
    BdfOrderError
        Naming ``name``, the value, the allowed range and the fix.
    """
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
        raise BdfOrderError(
            f"{name} = {order!r} ({type(order).__name__}): expected an integer BDF order in "
            f"{MIN_ORDER}..{MAX_ORDER}; pass e.g. {name}=4"
        )
    if not MIN_ORDER <= order <= MAX_ORDER:
        raise BdfOrderError(
            f"{name} = {order!r}: expected a BDF order in {MIN_ORDER}..{MAX_ORDER} "
            f"(BDF of order >= 7 is not zero-stable, order <= 0 is meaningless); "
            f"choose {name} between {MIN_ORDER} and {MAX_ORDER}, e.g. 4 as in the paper"
        )
    return int(order)


# --------------------------------------------------------------------------- coefficients


@dataclass(frozen=True, kw_only=True, slots=True)
class BdfCoefficients:
    """Coefficients of ``y_{k+1} = sum_j history[j-1] y_{k+1-j} + beta h f(y_{k+1})``.

    Attributes
    ----------
    order : int
        Number of steps ``m``.
    history : tuple of float
        ``c_1 .. c_m`` (weights of ``y_k, y_{k-1}, ..., y_{k+1-m}``); they sum to 1.
    beta : float
        Weight of ``h f(y_{k+1})``.
    """

    order: int
    history: tuple[float, ...]
    beta: float


@lru_cache(maxsize=None)
def _backward_difference_weights(order: int) -> tuple[Fraction, ...]:
    """Exact weights ``a_0..a_m`` of ``sum_{j=1}^m (1/j) ∇^j y_{k+1} = sum_i a_i y_{k+1-i}``.

    ``∇^j y_{k+1} = sum_{i=0}^{j} (-1)^i C(j, i) y_{k+1-i}``.  No range check
    (order 7 and above are needed to exhibit their instability).
    """
    weights = [Fraction(0)] * (order + 1)
    for j in range(1, order + 1):
        for i in range(j + 1):
            weights[i] += Fraction((-1) ** i * math.comb(j, i), j)
    return tuple(weights)


@lru_cache(maxsize=None)
def bdf_coefficients_exact(order: int) -> tuple[tuple[Fraction, ...], Fraction]:
    """Exact ``(history, beta)`` of the ``order``-step BDF as fractions (any order >= 1).

    Derived from the backward-difference form; no table is typed in.  Orders
    above 6 are accepted here on purpose (to study their instability); use
    :func:`bdf_coefficients` for integration.

    Examples
    --------
    >>> hist, beta = bdf_coefficients_exact(2)
    >>> [str(c) for c in hist], str(beta)
    (['4/3', '-1/3'], '2/3')
    """
    if isinstance(order, bool) or not isinstance(order, int) or order < 1:
        raise BdfOrderError(f"order = {order!r}: expected an integer >= 1 for the coefficient derivation")
    a = _backward_difference_weights(order)
    a0 = a[0]
    return tuple(-ai / a0 for ai in a[1:]), 1 / a0


def bdf_coefficients(order: int) -> BdfCoefficients:
    """Coefficients of the zero-stable BDF of the given order (1–6), as floats.

    Raises
    ------
    BdfOrderError
        If ``order`` is not an integer in 1..6.

    Examples
    --------
    >>> c = bdf_coefficients(4)
    >>> [round(x * 25) for x in c.history], round(c.beta * 25)
    ([48, -36, 16, -3], 12)
    """
    order = validate_order(order)
    hist, beta = bdf_coefficients_exact(order)
    return BdfCoefficients(order=order, history=tuple(float(c) for c in hist), beta=float(beta))


def bdf_characteristic_roots(order: int) -> np.ndarray:
    """Roots of ``rho(zeta) = zeta^m - sum_j c_j zeta^(m-j)`` for any order ``m >= 1``.

    The BDF is zero-stable iff every root lies in the closed unit disc and those
    on the circle are simple; ``zeta = 1`` is always a root (consistency).
    From ``m = 7`` on, a root has modulus > 1.

    Returns
    -------
    numpy.ndarray of complex, shape (m,)
        Sorted by decreasing modulus.
    """
    hist, _ = bdf_coefficients_exact(order)
    poly = np.array([1.0] + [-float(c) for c in hist])
    roots = np.roots(poly).astype(complex)
    return roots[np.argsort(-np.abs(roots), kind="stable")]


@lru_cache(maxsize=None)
def _extrapolation_weights_exact(count: int) -> tuple[Fraction, ...]:
    return tuple(Fraction((-1) ** (j + 1) * math.comb(count, j)) for j in range(1, count + 1))


def extrapolation_weights(count: int) -> tuple[float, ...]:
    """Weights ``e_1..e_n`` with ``y_{k+1} ≈ sum_j e_j y_{k+1-j}`` (degree ``n-1`` polynomial).

    The polynomial through ``n`` equally spaced values, evaluated one step
    ahead: ``e_j = (-1)^(j+1) C(n, j)``.  Error ``O(h^n)``.  This is the
    natural predictor of an ``n``-step BDF.

    Examples
    --------
    >>> extrapolation_weights(4)
    (4.0, -6.0, 4.0, -1.0)
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"count = {count!r}: expected an integer >= 1 (number of past values)")
    return tuple(float(w) for w in _extrapolation_weights_exact(count))


@lru_cache(maxsize=None)
def _histopolation_weights_exact(count: int) -> tuple[Fraction, ...]:
    # Let P be a primitive of the smooth signal T, so h*Tbar_{k-i} = ∇P_{k+1-i}.  The
    # polynomial of degree `count` interpolating P at t_{k+1-count}..t_{k+1} has the
    # derivative  h P'(t_{k+1}) = sum_{j=1}^{count} (1/j) ∇^j P_{k+1}
    #                           = h sum_{j=1}^{count} (1/j) ∇^{j-1} Tbar_k.
    weights = [Fraction(0)] * count
    for j in range(1, count + 1):
        for i in range(j):  # ∇^{j-1} Tbar_k = sum_i (-1)^i C(j-1, i) Tbar_{k-i}
            weights[i] += Fraction((-1) ** i * math.comb(j - 1, i), j)
    return tuple(weights)


def histopolation_weights(count: int) -> tuple[float, ...]:
    """Weights ``w_0..w_{p-1}``: point value at ``t_{k+1}`` from the last ``p`` interval means.

    ``T(t_{k+1}) ≈ sum_i w_i Tbar_{k-i}`` where ``Tbar_{k-i}`` is the mean of
    ``T`` over ``[t_{k-i}, t_{k+1-i}]``: the value at the right end of the
    polynomial of degree ``p-1`` whose means over the ``p`` cells match
    (histopolation).  Exact for polynomials of degree ``< p``; error ``O(h^p)``.
    They sum to 1.  Derived exactly via the primitive (see the source).

    Examples
    --------
    >>> histopolation_weights(3)  # (11, -7, 2) / 6
    (1.8333333333333333, -1.1666666666666667, 0.3333333333333333)
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"count = {count!r}: expected an integer >= 1 (number of interval means)")
    return tuple(float(w) for w in _histopolation_weights_exact(count))


# --------------------------------------------------------------------------- integrator


@dataclass(frozen=True, kw_only=True, slots=True)
class BdfSolution:
    """Result of :func:`integrate_bdf`.

    Attributes
    ----------
    t : numpy.ndarray, shape (n_steps + 1,)
        Grid ``t0 + k h`` (read-only).
    y : numpy.ndarray, shape (n_steps + 1, n)
        States on the grid (read-only); ``y[0] = y0``.
    order : int
        BDF order used once the start-up is over.
    startup : str
        Start-up procedure used.
    newton_iterations : int
        Total Newton iterations over all BDF steps.
    """

    t: np.ndarray
    y: np.ndarray
    order: int
    startup: str
    newton_iterations: int


def _validate_step(h: float, n_steps: int) -> tuple[float, int]:
    try:
        h_value = float(h)
    except (TypeError, ValueError) as err:
        raise BdfStepSizeError(f"h = {h!r}: expected a positive finite step size (a number)") from err
    if not (h_value > 0.0 and math.isfinite(h_value)):
        raise BdfStepSizeError(f"h = {h!r}: expected a positive finite step size; pass h > 0")
    if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 0:
        raise BdfStepSizeError(f"n_steps = {n_steps!r}: expected a non-negative integer number of steps")
    return h_value, int(n_steps)


def rk4_step(f: Callable, t: float, y: np.ndarray, h: float, substeps: int) -> np.ndarray:
    """``substeps`` classical RK4 steps of size ``h / substeps`` from ``(t, y)``."""
    dt = h / substeps
    for i in range(substeps):
        ti = t + i * dt
        k1 = np.asarray(f(ti, y), dtype=float)
        k2 = np.asarray(f(ti + 0.5 * dt, y + 0.5 * dt * k1), dtype=float)
        k3 = np.asarray(f(ti + 0.5 * dt, y + 0.5 * dt * k2), dtype=float)
        k4 = np.asarray(f(ti + dt, y + dt * k3), dtype=float)
        y = y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return y


def _newton_bdf_step(
    f: Callable,
    jac: Callable,
    t_new: float,
    rhs: np.ndarray,
    beta_h: float,
    guess: np.ndarray,
    tol: float,
    maxiter: int,
    step_index: int,
) -> tuple[np.ndarray, int]:
    """Solve ``y - beta_h f(t_new, y) - rhs = 0`` by dense Newton from ``guess``."""
    y = guess.copy()
    eye = np.eye(y.size)
    update_norm = math.inf
    for iteration in range(1, maxiter + 1):
        residual = y - beta_h * np.asarray(f(t_new, y), dtype=float) - rhs
        matrix = eye - beta_h * np.asarray(jac(t_new, y), dtype=float).reshape(y.size, y.size)
        try:
            delta = np.linalg.solve(matrix, residual)
        except np.linalg.LinAlgError as err:
            raise BdfConvergenceError(
                f"BDF step {step_index} to t = {t_new:.6g}: the Newton matrix I - beta*h*J is singular "
                f"at iteration {iteration}; reduce h",
                iterations=iteration,
                update_norm=update_norm,
                residual_norm=float(np.max(np.abs(residual))),
            ) from err
        y = y - delta
        update_norm = float(np.max(np.abs(delta)))
        if np.all(np.abs(delta) <= tol * (1.0 + np.abs(y))):
            return y, iteration
    residual = y - beta_h * np.asarray(f(t_new, y), dtype=float) - rhs
    residual_norm = float(np.max(np.abs(residual)))
    raise BdfConvergenceError(
        f"BDF step {step_index} to t = {t_new:.6g}: Newton did not converge after {maxiter} iterations "
        f"(last update max-norm {update_norm:.3e}, residual max-norm {residual_norm:.3e}, "
        f"tolerance {tol:.1e} relative); reduce h or raise newton_maxiter",
        iterations=maxiter,
        update_norm=update_norm,
        residual_norm=residual_norm,
    )


def integrate_bdf(
    f: Callable[[float, np.ndarray], Sequence[float]],
    jac: Callable[[float, np.ndarray], Sequence[Sequence[float]]],
    t0: float,
    y0: Sequence[float],
    h: float,
    n_steps: int,
    order: int,
    startup: str = "rk4",
    *,
    start_values: Sequence[Sequence[float]] | None = None,
    rk4_substeps: int = RK4_SUBSTEPS,
    newton_tol: float = NEWTON_TOL,
    newton_maxiter: int = NEWTON_MAXITER,
) -> BdfSolution:
    """Fixed-step BDF of the given order for ``y' = f(t, y)``, dense Newton corrector.

    Parameters
    ----------
    f : callable ``f(t, y) -> array (n,)``
    jac : callable ``jac(t, y) -> array (n, n)``
        ``∂f/∂y``.
    t0 : float
    y0 : array_like, shape (n,)
    h : float
        Step size, > 0.
    n_steps : int
        Number of steps; the grid is ``t0 + k h``, ``k = 0..n_steps``.
    order : int
        BDF order 1–6.
    startup : {"rk4", "exact", "ramp"}
        How the first ``order - 1`` values after ``y0`` are obtained:

        * ``"rk4"``: classical RK4 with ``rk4_substeps`` substeps per step
          (local error ``O((h/s)^5 h^0)``, negligible against the BDF error
          for the default 16 substeps);
        * ``"exact"``: taken from ``start_values`` (values at
          ``t0 + h, ..., t0 + (order-1) h``, e.g. an exact solution);
        * ``"ramp"``: BDF1, BDF2, ... with the orders the history allows
          (cheap, but its ``O(h^2)`` first step limits the global accuracy).
    start_values : array_like, shape (>= order - 1, n), optional
        Required by ``startup="exact"``; only the first ``order - 1`` rows are used.
    newton_tol, newton_maxiter : float, int
        Newton stops when ``|Δy_i| <= newton_tol (1 + |y_i|)`` for every component.
        The predictor is the extrapolation polynomial through the past ``order`` values.

    Returns
    -------
    BdfSolution

    Raises
    ------
    BdfOrderError, BdfStepSizeError, BdfHistoryError, BdfStartupError
        Invalid arguments (all ``ValueError``).
    BdfConvergenceError
        Newton did not converge (an ``ArithmeticError``); the message gives the
        step, the iterations and the residual.

    Examples
    --------
    >>> sol = integrate_bdf(lambda t, y: -y, lambda t, y: [[-1.0]], 0.0, [1.0], 0.01, 100, 4)
    >>> bool(abs(sol.y[-1, 0] - math.exp(-1.0)) < 1e-9)
    True
    """
    order = validate_order(order)
    h, n_steps = _validate_step(h, n_steps)
    if startup not in STARTUP_METHODS:
        raise BdfStartupError(f"startup = {startup!r}: expected one of {', '.join(map(repr, STARTUP_METHODS))}")
    if not (newton_tol > 0.0 and math.isfinite(newton_tol)):
        raise ValueError(f"newton_tol = {newton_tol!r}: expected a positive finite tolerance, e.g. 1e-12")
    if isinstance(newton_maxiter, bool) or not isinstance(newton_maxiter, int) or newton_maxiter < 1:
        raise ValueError(f"newton_maxiter = {newton_maxiter!r}: expected an integer >= 1, e.g. 10")
    y_start = np.array(y0, dtype=float).reshape(-1)
    n = y_start.size
    t = t0 + h * np.arange(n_steps + 1)
    y = np.empty((n_steps + 1, n))
    y[0] = y_start
    needed = min(order - 1, n_steps)

    if startup == "exact" and order > 1:
        if start_values is None:
            raise BdfHistoryError(
                f"startup='exact' with order = {order} needs start_values: the {order - 1} values at "
                f"t0 + h .. t0 + {order - 1} h; pass start_values=... or use startup='rk4'"
            )
        values = np.array(start_values, dtype=float)
        if values.ndim == 1 and n == 1:
            values = values.reshape(-1, 1)
        if values.ndim != 2 or values.shape[1] != n:
            raise BdfHistoryError(
                f"start_values has shape {values.shape}: expected (order - 1, n) = ({order - 1}, {n})"
            )
        if values.shape[0] < order - 1:
            raise BdfHistoryError(
                f"start_values has {values.shape[0]} rows but order = {order} needs {order - 1} "
                f"(values at t0 + h .. t0 + {order - 1} h); supply more values or lower the order"
            )
        y[1 : needed + 1] = values[:needed]
    elif startup == "rk4":
        if isinstance(rk4_substeps, bool) or not isinstance(rk4_substeps, int) or rk4_substeps < 1:
            raise ValueError(f"rk4_substeps = {rk4_substeps!r}: expected an integer >= 1, e.g. {RK4_SUBSTEPS}")
        for k in range(needed):
            y[k + 1] = rk4_step(f, float(t[k]), y[k], h, rk4_substeps)
    first_bdf = 0 if startup == "ramp" else needed

    iterations = 0
    for k in range(first_bdf, n_steps):
        q = min(order, k + 1)  # equals `order` except during a "ramp" start-up
        hist, beta = bdf_coefficients_exact(q)
        past = y[k::-1][:q]  # y_k, y_{k-1}, ..., y_{k+1-q}
        rhs = sum(float(c) * past[j] for j, c in enumerate(hist))
        guess = sum(w * past[j] for j, w in enumerate(extrapolation_weights(q)))
        y[k + 1], used = _newton_bdf_step(
            f, jac, float(t[k + 1]), rhs, float(beta) * h, guess, newton_tol, newton_maxiter, k + 1
        )
        iterations += used
    t.flags.writeable = False
    y.flags.writeable = False
    return BdfSolution(t=t, y=y, order=order, startup=startup, newton_iterations=iterations)
