"""A family of ODE integrators behind one interface: fixed-step schemes and adaptive references.

Generic tools, independent of the robot.  :func:`integrate` solves
``y' = f(t, y)``, ``y(t0) = y0`` on ``[t0, t1]`` (an :class:`OdeProblem`) with
one of

* the fixed-step schemes of :data:`FIXED_STEP_SCHEMES`, on the grid
  ``t0 + k h`` (``h`` must divide ``t1 - t0``):

  ============  =====  =======================================================
  scheme        order  one step
  ============  =====  =======================================================
  ``euler``     1      explicit Euler, 1 evaluation of ``f``
  ``rk4``       4      classical Runge–Kutta, 4 evaluations
  ``abm4``      4      Adams–Bashforth 4 predictor, Adams–Moulton 3-step
                       corrector (order 4), PECE: 2 evaluations
  ``bdf1``…     1–6    backward differentiation formula, Newton corrector:
  ``bdf6``             :func:`analysis.bdf.integrate_bdf` (the BDF code is not
                       duplicated here)
  ============  =====  =======================================================

* the adaptive references of :data:`REFERENCE_SCHEMES`: scipy's ``BDF``,
  ``Radau``, ``LSODA`` and ``DOP853`` (:func:`scipy.integrate.solve_ivp`) and
  SUNDIALS CVODES through :func:`casadi.integrator` (needs the symbolic
  right-hand side :attr:`OdeProblem.casadi_rhs`), with tolerances ``rtol``,
  ``atol``, output on a requested grid.

Start-up of the multistep schemes
---------------------------------
``abm4`` and ``bdf2``–``bdf6`` need ``m - 1`` values after ``y0`` (``m`` = 4
for ``abm4``, the order for BDF).  ``startup="rk4"`` (default) computes them by
classical RK4 with ``startup_substeps`` (default 16) equal substeps per step:
their local error ``O((h/16)^5)`` is far below the scheme's own error, so the
start-up does not limit the observed order.  ``startup="exact"`` takes them from
``start_values`` (values at ``t0 + h, …, t0 + (m-1) h``, e.g. an exact
solution), which removes the start-up from an order study altogether.

Examples
--------
>>> import numpy as np
>>> p = OdeProblem(f=lambda t, y: -y, jac=lambda t, y: -np.eye(1), t0=0.0, t1=1.0, y0=[1.0])
>>> r = integrate(p, "rk4", h=0.1)
>>> bool(abs(r.y[-1, 0] - np.exp(-1.0)) < 1e-6)
True
>>> integrate(p, "bdf4", h=0.1).n_steps
10
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis.bdf import (
    NEWTON_MAXITER,
    NEWTON_TOL,
    RK4_SUBSTEPS,
    BdfHistoryError,
    BdfStartupError,
    BdfStepSizeError,
    integrate_bdf,
    rk4_step,
    validate_order,
)
from hybrid.errors import NumericalFailure

__all__ = [
    "FIXED_STEP_SCHEMES",
    "REFERENCE_SCHEMES",
    "SCHEMES",
    "SCHEME_ORDERS",
    "STARTUPS",
    "STEP_RELATIVE_TOLERANCE",
    "UnknownSchemeError",
    "ProblemDefinitionError",
    "ReferenceSolverError",
    "OdeProblem",
    "IntegrationResult",
    "integrate",
    "scheme_order",
    "step_count",
    "finite_difference_jacobian",
    "observed_order",
    "pareto_front",
]

FIXED_STEP_SCHEMES = ("euler", "rk4", "abm4", "bdf1", "bdf2", "bdf3", "bdf4", "bdf5", "bdf6")
"""Fixed-step schemes of :func:`integrate`."""
REFERENCE_SCHEMES = ("scipy_bdf", "scipy_radau", "scipy_lsoda", "scipy_dop853", "cvodes")
"""Adaptive reference integrators of :func:`integrate` (tolerances ``rtol``, ``atol``)."""
SCHEMES = FIXED_STEP_SCHEMES + REFERENCE_SCHEMES
"""Every scheme name :func:`integrate` accepts."""
SCHEME_ORDERS = {"euler": 1, "rk4": 4, "abm4": 4, **{f"bdf{q}": q for q in range(1, 7)}}
"""Classical order of each fixed-step scheme."""
STARTUPS = ("rk4", "exact")
"""Start-up procedures of the multistep schemes (``abm4``, ``bdf2``–``bdf6``)."""
STEP_RELATIVE_TOLERANCE = 1e-9
"""``(t1 - t0)/h`` must be within this relative distance of an integer."""

_SCIPY_METHODS = {"scipy_bdf": "BDF", "scipy_radau": "Radau", "scipy_lsoda": "LSODA", "scipy_dop853": "DOP853"}
_IMPLICIT_SCIPY = ("scipy_bdf", "scipy_radau", "scipy_lsoda")
_CVODES_MAX_STEPS = 100_000
# Adams–Bashforth 4 (predictor) and Adams–Moulton 3-step, order 4 (corrector), over 24.
_AB4 = (55.0, -59.0, 37.0, -9.0)
_AM4 = (9.0, 19.0, -5.0, 1.0)


class UnknownSchemeError(ValueError):
    """A scheme name that :func:`integrate` does not know."""


class ProblemDefinitionError(ValueError):
    """An :class:`OdeProblem` whose interval, initial value or right-hand side is malformed."""


class ReferenceSolverError(NumericalFailure):
    """An adaptive reference integrator (scipy or CVODES) reported a failure."""


@dataclass(frozen=True, kw_only=True, slots=True)
class OdeProblem:
    """The initial-value problem ``y' = f(t, y)``, ``y(t0) = y0``, on ``[t0, t1]``.

    Attributes
    ----------
    f : callable ``f(t, y) -> array (n,)``
        Right-hand side; ``t`` a float, ``y`` a float array of shape ``(n,)``.
    t0, t1 : float
        Interval, ``t1 > t0`` [s, or the problem's time unit].
    y0 : numpy.ndarray, shape (n,)
        Initial value (stored read-only).
    jac : callable ``jac(t, y) -> array (n, n)``, optional
        ``∂f/∂y``; the BDF Newton corrector and scipy's implicit methods use it.
        Without it the BDF schemes use forward differences
        (:func:`finite_difference_jacobian`) and scipy its own.
    casadi_rhs : casadi.Function, optional
        The same right-hand side as a CasADi function of ``(t, y)`` (inputs of
        sizes 1 and ``n``, one output of size ``n``) that accepts ``MX``
        arguments: required by the ``"cvodes"`` reference only.
    name : str
        Label for reports.
    """

    f: Callable[[float, np.ndarray], Any]
    t0: float
    t1: float
    y0: np.ndarray
    jac: Callable[[float, np.ndarray], Any] | None = None
    casadi_rhs: Any = None
    name: str = ""

    def __post_init__(self) -> None:
        if not callable(self.f):
            raise ProblemDefinitionError(f"OdeProblem.f = {self.f!r}: expected a callable f(t, y) -> array (n,)")
        if self.jac is not None and not callable(self.jac):
            raise ProblemDefinitionError(f"OdeProblem.jac = {self.jac!r}: expected None or a callable jac(t, y)")
        try:
            t0, t1 = float(self.t0), float(self.t1)
        except (TypeError, ValueError) as err:
            raise ProblemDefinitionError(
                f"OdeProblem.t0 = {self.t0!r}, t1 = {self.t1!r}: expected two numbers with t0 < t1"
            ) from err
        if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
            raise ProblemDefinitionError(
                f"OdeProblem.t0 = {self.t0!r}, t1 = {self.t1!r}: expected finite t0 < t1; swap or fix the interval"
            )
        y0 = np.array(self.y0, dtype=float)
        if y0.ndim != 1 or y0.size == 0 or not np.all(np.isfinite(y0)):
            raise ProblemDefinitionError(
                f"OdeProblem.y0 has shape {y0.shape} (values {y0.ravel()[:6].tolist()}...): expected a non-empty "
                f"finite 1-D array (n,)"
            )
        y0.flags.writeable = False
        object.__setattr__(self, "t0", t0)
        object.__setattr__(self, "t1", t1)
        object.__setattr__(self, "y0", y0)

    @property
    def dimension(self) -> int:
        """``n``, the number of state components."""
        return int(self.y0.size)


@dataclass(frozen=True, kw_only=True, slots=True)
class IntegrationResult:
    """What :func:`integrate` returns.

    Attributes
    ----------
    scheme : str
    t : numpy.ndarray, shape (m,)
        Output times (read-only): the step grid for a fixed-step scheme, the
        requested grid for a reference.
    y : numpy.ndarray, shape (m, n)
        Solution at ``t`` (read-only); ``y[0] = y0``.
    step : float or None
        Fixed step ``h``; ``None`` for an adaptive reference.
    rtol, atol : float or None
        Tolerances of a reference; ``None`` for a fixed-step scheme.
    n_steps : int or None
        Steps taken; for CVODES the steps it reports, ``None`` for scipy
        (``solve_ivp`` does not report them: ``n_rhs`` and ``n_jac`` measure its cost).
    n_rhs : int
        Evaluations of ``f`` (for CVODES: of its symbolic right-hand side).
    n_jac : int
        Evaluations of the Jacobian.
    newton_iterations : int
        Newton iterations of the BDF corrector (0 for other schemes).
    startup : str or None
        Start-up of a multistep scheme (``"rk4"`` or ``"exact"``), else ``None``.
    """

    scheme: str
    t: np.ndarray
    y: np.ndarray
    step: float | None
    rtol: float | None
    atol: float | None
    n_steps: int | None
    n_rhs: int
    n_jac: int
    newton_iterations: int
    startup: str | None = field(default=None)


def scheme_order(scheme: str) -> int:
    """Classical order of a fixed-step scheme (``"bdf4"`` → 4).

    Raises
    ------
    UnknownSchemeError, analysis.bdf.BdfOrderError
        As :func:`integrate`.
    """
    _check_scheme(scheme)
    if scheme not in SCHEME_ORDERS:
        raise UnknownSchemeError(f"scheme = {scheme!r}: an adaptive reference has no fixed order")
    return SCHEME_ORDERS[scheme]


def _check_scheme(scheme: object) -> str:
    if isinstance(scheme, str) and scheme.startswith("bdf") and scheme[3:].lstrip("-").isdigit():
        validate_order(int(scheme[3:]), name=f"scheme {scheme!r}: BDF order")
    if scheme not in SCHEMES:
        raise UnknownSchemeError(
            f"scheme = {scheme!r}: expected one of {', '.join(SCHEMES)} (fixed-step schemes need h, "
            f"references take rtol/atol)"
        )
    return scheme  # type: ignore[return-value]


def step_count(t0: float, t1: float, h: object) -> int:
    """Number of steps ``n`` with ``t0 + n h = t1``, after checking ``h``.

    Raises
    ------
    analysis.bdf.BdfStepSizeError
        ``h`` missing, not a number, not positive and finite, or not a divisor
        of ``t1 - t0`` (within :data:`STEP_RELATIVE_TOLERANCE`); the message
        proposes the nearest step that divides the interval.
    """
    if h is None:
        raise BdfStepSizeError("h = None: a fixed-step scheme needs a step size; pass h=... (> 0)")
    try:
        value = float(h)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise BdfStepSizeError(f"h = {h!r}: expected a positive finite step size (a number)") from err
    if not (value > 0.0 and math.isfinite(value)):
        raise BdfStepSizeError(f"h = {h!r}: expected a positive finite step size; pass h > 0")
    span = t1 - t0
    steps = span / value
    n = max(1, round(steps))
    if abs(steps - n) > STEP_RELATIVE_TOLERANCE * max(1.0, steps):
        raise BdfStepSizeError(
            f"h = {h!r} does not divide t1 - t0 = {span!r} ({steps:.6g} steps): a fixed-step scheme ends "
            f"exactly at t1; choose h = (t1 - t0)/n, e.g. h = {span / n!r} ({n} steps)"
        )
    return int(n)


def finite_difference_jacobian(f: Callable[[float, np.ndarray], Any], t: float, y: np.ndarray) -> np.ndarray:
    """Forward-difference ``∂f/∂y`` at ``(t, y)``, shape ``(n, n)``.

    Step ``sqrt(eps) max(1, |y_j|)`` per column: error ``O(sqrt(eps))``
    relative, enough for a Newton corrector (which then converges linearly
    instead of quadratically).
    """
    y = np.asarray(y, dtype=float)
    f0 = np.asarray(f(t, y), dtype=float)
    jac = np.empty((f0.size, y.size))
    root_eps = math.sqrt(np.finfo(float).eps)
    for j in range(y.size):
        dy = root_eps * max(1.0, abs(y[j]))
        shifted = y.copy()
        shifted[j] += dy
        jac[:, j] = (np.asarray(f(t, shifted), dtype=float) - f0) / dy
    return jac


class _Counted:
    """A callable that counts its calls (evaluations of ``f`` or of the Jacobian)."""

    __slots__ = ("func", "calls", "size", "label")

    def __init__(self, func: Callable, size: int, label: str) -> None:
        self.func = func
        self.calls = 0
        self.size = size
        self.label = label

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        self.calls += 1
        out = np.asarray(self.func(t, y), dtype=float)
        if out.size != self.size:
            shape = "(n,)" if self.label == "f" else "(n, n)"
            raise ProblemDefinitionError(
                f"OdeProblem.{self.label} returned {out.size} values at t = {t!r}: expected {self.size}, an "
                f"array of shape {shape}; fix the right-hand side"
            )
        return out


def integrate(
    problem: OdeProblem,
    scheme: str,
    *,
    h: float | None = None,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    t_eval: Sequence[float] | None = None,
    startup: str = "rk4",
    start_values: Sequence[Sequence[float]] | None = None,
    startup_substeps: int = RK4_SUBSTEPS,
    newton_tol: float = NEWTON_TOL,
    newton_maxiter: int = NEWTON_MAXITER,
) -> IntegrationResult:
    """Solve ``problem`` with ``scheme`` (see the module docstring for the schemes).

    Parameters
    ----------
    problem : OdeProblem
    scheme : str
        One of :data:`SCHEMES`.
    h : float, optional
        Step of a fixed-step scheme (required; must divide ``t1 - t0``).  For a
        reference, when ``t_eval`` is not given, the output grid ``t0 + k h``.
    rtol, atol : float
        Tolerances of a reference (ignored by the fixed-step schemes).
    t_eval : sequence of float, optional
        Output times of a reference, increasing, within ``[t0, t1]``; default
        ``t0 + k h`` if ``h`` is given, else ``(t0, t1)``.
    startup : {"rk4", "exact"}
        Start-up of ``abm4`` and ``bdf2``–``bdf6`` (module docstring).
    start_values : array_like, shape (>= m - 1, n), optional
        Values at ``t0 + h, …, t0 + (m - 1) h`` for ``startup="exact"``.
    startup_substeps : int
        RK4 substeps per step of the ``"rk4"`` start-up.
    newton_tol, newton_maxiter : float, int
        BDF Newton corrector (:func:`analysis.bdf.integrate_bdf`).

    Returns
    -------
    IntegrationResult

    Raises
    ------
    UnknownSchemeError
        Unknown scheme name.
    analysis.bdf.BdfOrderError
        ``"bdf<q>"`` with ``q`` outside 1–6.
    analysis.bdf.BdfStepSizeError
        Fixed-step scheme without a positive step dividing the interval.
    analysis.bdf.BdfStartupError, analysis.bdf.BdfHistoryError
        Unknown start-up, or ``start_values`` missing or shorter than the
        scheme's history needs.
    analysis.bdf.BdfConvergenceError
        The BDF Newton corrector did not converge (the message gives the step,
        the iterations and the residual).
    ReferenceSolverError
        A reference integrator failed (its message is included).
    ProblemDefinitionError
        ``f`` or ``jac`` returned the wrong number of values; ``"cvodes"``
        without ``casadi_rhs``; a bad ``t_eval``.
    """
    _check_scheme(scheme)
    n = problem.dimension
    f = _Counted(problem.f, n, "f")
    jac = None if problem.jac is None else _Counted(problem.jac, n * n, "jac")
    if scheme in FIXED_STEP_SCHEMES:
        n_steps = step_count(problem.t0, problem.t1, h)
        return _fixed_step(problem, scheme, f, jac, float(h), n_steps, startup, start_values,  # type: ignore[arg-type]
                           startup_substeps, newton_tol, newton_maxiter)
    grid = _output_grid(problem, h, t_eval)
    if not (rtol > 0.0 and atol > 0.0 and math.isfinite(rtol) and math.isfinite(atol)):
        raise ProblemDefinitionError(f"rtol = {rtol!r}, atol = {atol!r}: expected positive finite tolerances")
    if scheme == "cvodes":
        return _cvodes(problem, grid, rtol, atol)
    return _scipy(problem, scheme, f, jac, grid, rtol, atol)


def _output_grid(problem: OdeProblem, h: float | None, t_eval: Sequence[float] | None) -> np.ndarray:
    if t_eval is not None:
        grid = np.array(t_eval, dtype=float).reshape(-1)
        span = problem.t1 - problem.t0
        slack = 1e-12 * max(1.0, abs(problem.t0), abs(problem.t1))
        if (
            grid.size == 0
            or not np.all(np.isfinite(grid))
            or np.any(np.diff(grid) <= 0.0)
            or grid[0] < problem.t0 - slack
            or grid[-1] > problem.t1 + slack
        ):
            raise ProblemDefinitionError(
                f"t_eval = {grid[:4].tolist()}... ({grid.size} values): expected increasing times within "
                f"[t0, t1] = [{problem.t0!r}, {problem.t1!r}] (span {span!r})"
            )
        return np.clip(grid, problem.t0, problem.t1)
    if h is not None:
        n_steps = step_count(problem.t0, problem.t1, h)
        return problem.t0 + float(h) * np.arange(n_steps + 1)
    return np.array([problem.t0, problem.t1])


def _fixed_step(
    problem: OdeProblem,
    scheme: str,
    f: _Counted,
    jac: _Counted | None,
    h: float,
    n_steps: int,
    startup: str,
    start_values: Sequence[Sequence[float]] | None,
    substeps: int,
    newton_tol: float,
    newton_maxiter: int,
) -> IntegrationResult:
    if startup not in STARTUPS:
        raise BdfStartupError(f"startup = {startup!r}: expected one of {', '.join(map(repr, STARTUPS))}")
    if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
        raise ValueError(f"startup_substeps = {substeps!r}: expected an integer >= 1, e.g. {RK4_SUBSTEPS}")
    t0 = problem.t0
    iterations = 0
    used_startup: str | None = None
    n_jac = 0
    if scheme.startswith("bdf"):
        order = int(scheme[3:])
        jac_func = jac if jac is not None else _Counted(lambda t, y: finite_difference_jacobian(problem.f, t, y),
                                                        problem.dimension ** 2, "jac")
        solution = integrate_bdf(
            f, jac_func, t0, problem.y0, h, n_steps, order, startup,
            start_values=start_values, rk4_substeps=substeps, newton_tol=newton_tol, newton_maxiter=newton_maxiter,
        )
        t, y = solution.t, solution.y
        iterations = solution.newton_iterations
        used_startup = startup if order > 1 else None
        n_jac = jac_func.calls
        if jac is None:  # each finite-difference Jacobian costs n + 1 evaluations of f
            f.calls += jac_func.calls * (problem.dimension + 1)
    else:
        t = t0 + h * np.arange(n_steps + 1)
        y = np.empty((n_steps + 1, problem.dimension))
        y[0] = problem.y0
        if scheme == "euler":
            for k in range(n_steps):
                y[k + 1] = y[k] + h * f(float(t[k]), y[k])
        elif scheme == "rk4":
            for k in range(n_steps):
                y[k + 1] = rk4_step(f, float(t[k]), y[k], h, 1)
        else:
            used_startup = startup
            _abm4(f, t, y, h, startup, start_values, substeps)
        t.flags.writeable = False
        y.flags.writeable = False
    return IntegrationResult(
        scheme=scheme, t=t, y=y, step=h, rtol=None, atol=None, n_steps=n_steps, n_rhs=f.calls, n_jac=n_jac,
        newton_iterations=iterations, startup=used_startup,
    )


def _abm4(
    f: _Counted,
    t: np.ndarray,
    y: np.ndarray,
    h: float,
    startup: str,
    start_values: Sequence[Sequence[float]] | None,
    substeps: int,
) -> None:
    """Adams–Bashforth–Moulton 4 in PECE mode, in place on ``y``; start-up as documented."""
    n_steps = y.shape[0] - 1
    needed = min(3, n_steps)
    if startup == "exact":
        if start_values is None:
            raise BdfHistoryError(
                "startup='exact' with scheme 'abm4' needs start_values: the 3 values at t0 + h .. t0 + 3 h; "
                "pass start_values=... or use startup='rk4'"
            )
        values = np.array(start_values, dtype=float)
        if values.ndim == 1 and y.shape[1] == 1:
            values = values.reshape(-1, 1)
        if values.ndim != 2 or values.shape[1] != y.shape[1] or values.shape[0] < 3:
            raise BdfHistoryError(
                f"start_values has shape {values.shape}: scheme 'abm4' (4-step history) needs at least (3, n) = "
                f"(3, {y.shape[1]}), the values at t0 + h .. t0 + 3 h; supply 3 rows"
            )
        y[1 : needed + 1] = values[:needed]
    else:
        for k in range(needed):
            y[k + 1] = rk4_step(f, float(t[k]), y[k], h, substeps)
    if n_steps <= 3:
        return
    scale = h / 24.0
    derivs = [f(float(t[k]), y[k]) for k in range(4)]  # f_{k-3}, ..., f_k
    b0, b1, b2, b3 = _AB4
    m0, m1, m2, m3 = _AM4
    for k in range(3, n_steps):
        f3, f2, f1, f0 = derivs  # f0 = f_k (newest)
        predictor = y[k] + scale * (b0 * f0 + b1 * f1 + b2 * f2 + b3 * f3)
        t_next = float(t[k + 1])
        corrected = y[k] + scale * (m0 * f(t_next, predictor) + m1 * f0 + m2 * f1 + m3 * f2)
        y[k + 1] = corrected
        derivs = [f2, f1, f0, f(t_next, corrected)]


def _scipy(
    problem: OdeProblem, scheme: str, f: _Counted, jac: _Counted | None, grid: np.ndarray, rtol: float, atol: float
) -> IntegrationResult:
    from scipy.integrate import solve_ivp

    kwargs: dict[str, Any] = {}
    if scheme in _IMPLICIT_SCIPY and jac is not None:
        kwargs["jac"] = jac
    sol = solve_ivp(
        f, (problem.t0, problem.t1), np.array(problem.y0), method=_SCIPY_METHODS[scheme], t_eval=grid,
        rtol=rtol, atol=atol, **kwargs,
    )
    if not sol.success or sol.y.shape[1] != grid.size:
        raise ReferenceSolverError(
            f"{scheme} (solve_ivp method {_SCIPY_METHODS[scheme]!r}, rtol={rtol:g}, atol={atol:g}) failed on "
            f"{problem.name or 'the problem'} at t = {sol.t[-1] if sol.t.size else problem.t0!r}: {sol.message}"
        )
    t = np.array(sol.t)
    y = np.array(sol.y.T)
    t.flags.writeable = False
    y.flags.writeable = False
    return IntegrationResult(
        scheme=scheme, t=t, y=y, step=None, rtol=rtol, atol=atol, n_steps=None, n_rhs=int(sol.nfev),
        n_jac=int(sol.njev), newton_iterations=0,
    )


def _cvodes(problem: OdeProblem, grid: np.ndarray, rtol: float, atol: float) -> IntegrationResult:
    import casadi as ca

    if problem.casadi_rhs is None:
        raise ProblemDefinitionError(
            f"scheme 'cvodes' needs OdeProblem.casadi_rhs (the right-hand side as a casadi.Function of (t, y)); "
            f"{problem.name or 'this problem'} has none: give it one or use a scipy reference"
        )
    t_sym = ca.MX.sym("t")
    y_sym = ca.MX.sym("y", problem.dimension)
    ode = problem.casadi_rhs(t_sym, y_sym)
    outputs = grid[grid > problem.t0]
    integrator = ca.integrator(
        "reference", "cvodes", {"t": t_sym, "x": y_sym, "ode": ode}, problem.t0, [float(v) for v in outputs],
        {"abstol": atol, "reltol": rtol, "max_num_steps": _CVODES_MAX_STEPS},
    )
    try:
        values = integrator(x0=ca.DM(np.array(problem.y0)))["xf"]
    except RuntimeError as err:
        raise ReferenceSolverError(
            f"cvodes (rtol={rtol:g}, atol={atol:g}) failed on {problem.name or 'the problem'}: {err}"
        ) from err
    stats = integrator.stats()
    y_out = np.array(ca.DM(values).full(), dtype=float).reshape(problem.dimension, -1).T
    y = np.vstack([np.array(problem.y0)[None, :], y_out]) if outputs.size < grid.size else y_out
    t = np.array(grid)
    t.flags.writeable = False
    y.flags.writeable = False
    return IntegrationResult(
        scheme="cvodes", t=t, y=y, step=None, rtol=rtol, atol=atol, n_steps=int(stats.get("nsteps", 0)),
        n_rhs=int(stats.get("nfevals", 0)), n_jac=int(stats.get("n_call_jacF", 0)), newton_iterations=0,
    )


def observed_order(steps: Sequence[float], errors: Sequence[float]) -> float:
    """Least-squares slope of ``log(error)`` against ``log(step)`` (the observed order).

    Raises
    ------
    ValueError
        Fewer than two pairs, different lengths, or a non-positive step or error.

    Examples
    --------
    >>> round(observed_order([0.1, 0.05, 0.025], [1e-4, 6.25e-6, 3.90625e-7]), 12)
    4.0
    """
    h = np.asarray(steps, dtype=float).reshape(-1)
    e = np.asarray(errors, dtype=float).reshape(-1)
    if h.size < 2 or h.size != e.size:
        raise ValueError(f"observed_order: need at least two (step, error) pairs, got {h.size} steps and {e.size} errors")
    if np.any(~(h > 0)) or np.any(~(e > 0)):
        raise ValueError(f"observed_order: steps {h.tolist()} and errors {e.tolist()} must all be positive")
    slope, _ = np.polyfit(np.log(h), np.log(e), 1)
    return float(slope)


def pareto_front(costs: Sequence[float], errors: Sequence[float]) -> tuple[int, ...]:
    """Indices of the non-dominated ``(cost, error)`` points, by increasing cost.

    A point is dominated when another is no more costly and no less accurate,
    and strictly better in one of the two.

    Examples
    --------
    >>> pareto_front([1.0, 2.0, 3.0, 2.5], [1e-3, 1e-5, 1e-6, 1e-4])
    (0, 1, 2)
    """
    c = np.asarray(costs, dtype=float)
    e = np.asarray(errors, dtype=float)
    if c.shape != e.shape:
        raise ValueError(f"pareto_front: {c.size} costs but {e.size} errors")
    order = np.lexsort((e, c))
    front: list[int] = []
    best = math.inf
    for i in order:
        if e[i] < best:
            front.append(int(i))
            best = float(e[i])
    return tuple(front)
