"""What the LMI programs of :mod:`analysis.lmi` share: their results (:class:`CommonLyapunovLMI`,
:class:`DwellTimeLMI`, :class:`PiecewiseQuadraticLMI` with their solver runs and re-checks), the input checks,
the solver calls (Clarabel, then SCS), the common-Lyapunov primal and dual programs, and the exact helpers.

:mod:`analysis.lmi` re-exports the public names; see its docstring for the method.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hybrid.errors import ParameterError
from hybrid.jsonable import to_jsonable
from analysis import exact
from analysis.exact import RationalMatrix

# Helpers shared with analysis.lmi have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = [
    "LmiError",
    "SolverRun",
    "Recheck",
    "CommonLyapunovLMI",
    "DwellTimeLMI",
    "LinearCell",
    "Boundary",
    "PiecewiseQuadraticLMI",
    "LMI_STATUSES",
    "DWELL_STATUSES",
    "SOLVERS",
]


LMI_STATUSES = ("exists", "none", "undecided")
"""``exists``/``none``: proven by an exact re-check; ``undecided``: neither re-checks."""

DWELL_STATUSES = ("arbitrary", "certified", "unstable_mode", "undecided")
"""``arbitrary``: a common quadratic Lyapunov function (dwell time 0); ``certified``: the LMI dwell
time re-checked; ``unstable_mode``: a mode is not Hurwitz (exactly), so no dwell time helps."""

SOLVERS = ("CLARABEL", "SCS")
"""Tried in order: the interior-point Clarabel, then the splitting-cone SCS when Clarabel fails."""

_SOLVER_OPTIONS = {"SCS": {"eps_abs": 1e-9, "eps_rel": 1e-9, "max_iters": 20000}}

_DUAL_SHIFT_SHARE = 0.25
"""Share of the dual margin ``t`` the shift ``δI`` of the ``Z_i`` may cost (module docstring)."""

MARGIN_DISCOUNTS = (1.0 - 2.0**-10, 0.5)
"""Certified margins: the float estimate times these factors, tried in order, decided exactly."""


class LmiError(ParameterError):
    """Bad input to an LMI analysis: the parameter, the value found (a shape), what was expected, the fix."""


@dataclass(frozen=True, kw_only=True, slots=True)
class SolverRun:
    """One call of a solver.

    Attributes
    ----------
    problem : str
        Which program (``"primal"``, ``"alternative"``, ``"dwell T=…"``, ``"piecewise"``).
    solver : str
        cvxpy's solver name.
    status : str
        cvxpy's status (``"optimal"``, ``"optimal_inaccurate"``, ``"infeasible"``, …) or ``"error"``.
    message : str
        The solver's error message (``""`` when it answered).
    """

    problem: str
    solver: str
    status: str
    message: str = ""


@dataclass(frozen=True, kw_only=True, slots=True)
class Recheck:
    """How a certificate was re-checked outside the solver.

    Attributes
    ----------
    method : str
        E.g. ``"exact rational LDLᵀ on the float data"``.
    passed : bool
    detail : str
        What was shown, or the first condition that failed.
    margin : float
        The margin certified by the re-check (see the result's ``margin``); ``nan`` when none.
    """

    method: str
    passed: bool
    detail: str
    margin: float = math.nan

EXACT_METHOD = "exact rational LDLᵀ (Sylvester pivots) on the float data converted exactly"


@dataclass(frozen=True, kw_only=True, slots=True)
class CommonLyapunovLMI:
    """Whether a common quadratic Lyapunov function of a family exists: proven either way, or undecided.

    Attributes
    ----------
    names : tuple of str
        The family members.
    status : str
        One of :data:`LMI_STATUSES`.
    proven : bool
        ``status != "undecided"`` (the re-check passed).
    P : ndarray or None, shape (n, n)
        ``V = xᵀPx`` (trace 1, read-only), exactly the matrix re-checked; ``None`` unless ``"exists"``.
    dual : tuple of ndarray or None, each shape (n, n)
        The ``Z_i`` of a certificate of absence (repaired, exactly as re-checked, read-only).
    witness_weights : tuple of float or None
        When absence is proven by a combination ``Σ w_iA_i`` that is not Hurwitz: the weights ``w_i ≥ 0``.
    margin : float
        ``"exists"``: ``α`` [1/s] with ``A_iᵀP + PA_i + αP ≺ 0`` exactly (``V̇ ≤ −αV`` in every mode;
        ``0`` if only strict decrease re-checks).  ``"none"`` by ``dual``: ``t`` [1/s] with
        ``Σ(A_iZ_i + Z_iA_iᵀ) ⪰ t·(Σ tr Z_i)·I`` exactly; by a witness: the combination's spectral
        abscissa (float) [1/s].  ``nan`` (JSON ``null``) when undecided.
    recheck : Recheck
    solver : tuple of SolverRun
    finding : str
        One sentence.
    """

    names: tuple[str, ...]
    status: str
    proven: bool
    P: np.ndarray | None
    dual: tuple[np.ndarray, ...] | None
    witness_weights: tuple[float, ...] | None
    margin: float
    recheck: Recheck
    solver: tuple[SolverRun, ...]
    finding: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: every field (``null`` for non-finite numbers); byte-stable across runs."""
        return to_jsonable(self)


@dataclass(frozen=True, kw_only=True, slots=True)
class DwellTimeLMI:
    """The smallest dwell time certified by mode-dependent quadratic Lyapunov functions (Geromel–Colaneri).

    Attributes
    ----------
    names : tuple of str
    status : str
        One of :data:`DWELL_STATUSES`.
    proven : bool
        The answer re-checked (exactly for ``"arbitrary"`` and ``"unstable_mode"``; in float64 with a
        stated error bound for ``"certified"``, see :func:`recheck_dwell_time`).
    dwell_time_s : float
        ``T`` [s]: every switching signal that stays ``≥ T`` in each mode is stable (an upper bound on
        the minimum dwell time); ``0`` for ``"arbitrary"``, ``inf`` (JSON ``null``) when none is certified.
    lower_bound_s : float
        The largest ``T`` tried at which the LMIs were not certified (bisection bracket, not a proof).
    baseline_dwell_time_s : float
        ``ln μ / λ0`` from the modes' own Lyapunov functions (the formula of
        :func:`analysis.linearise.common_quadratic_lyapunov`); the LMI ``T`` is never larger.
    P : tuple of ndarray
        The ``P_i`` at ``dwell_time_s`` (read-only; empty when none).
    recheck : Recheck
    solver : tuple of SolverRun
        The runs of the certifying solve.
    solves : int
        LMIs solved in the bisection.
    finding : str
    """

    names: tuple[str, ...]
    status: str
    proven: bool
    dwell_time_s: float
    lower_bound_s: float
    baseline_dwell_time_s: float
    P: tuple[np.ndarray, ...]
    recheck: Recheck
    solver: tuple[SolverRun, ...]
    solves: int
    finding: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: every field (``null`` for non-finite numbers)."""
        return to_jsonable(self)


@dataclass(frozen=True, kw_only=True, slots=True)
class LinearCell:
    """One cell of a state-dependent switched linear system: ``ẋ = A x`` on ``{x : E x ≥ 0}``.

    Attributes
    ----------
    A : array_like, shape (n, n)
        The mode's matrix [1/s].
    E : array_like, shape (r, n)
        The cone's inequalities (one row per half-space through the origin; ``r = 0``: all of ``ℝⁿ``).
    name : str or None
        Label (``cell<k>`` when ``None``).
    """

    A: Any
    E: Any
    name: str | None = None


@dataclass(frozen=True, kw_only=True, slots=True)
class Boundary:
    """A boundary hyperplane ``hᵀx = 0`` between two cells, across which ``V`` is continuous.

    Attributes
    ----------
    cells : tuple of str
        The two cells.
    normal : tuple of float
        ``h``.
    derived : bool
        Found from opposite rows of the cells' ``E`` (``False``: given by the caller).
    """

    cells: tuple[str, str]
    normal: tuple[float, ...]
    derived: bool


@dataclass(frozen=True, kw_only=True, slots=True)
class PiecewiseQuadraticLMI:
    """A piecewise quadratic Lyapunov function (Johansson–Rantzer), re-checked exactly, or undecided.

    Attributes
    ----------
    names : tuple of str
        The cells.
    status : str
        ``"exists"`` (re-checked) or ``"undecided"`` (a failed search proves nothing).
    proven : bool
    P : tuple of ndarray or None
        ``V = xᵀP_ix`` on cell ``i`` (floats nearest to the exact rational ``P_i`` of :attr:`exact_P`).
    U, W : tuple of ndarray or None
        The S-procedure multipliers, exactly as re-checked (symmetric, ``≥ 0``, zero diagonal).
    boundaries : tuple of Boundary
        Where continuity was imposed.
    margin : float
        ``α`` [1/s] with ``A_iᵀP_i + P_iA_i + E_iᵀW_iE_i + αP_i ≺ 0`` exactly (``V̇ ≤ −αV`` on every
        cell; ``0`` if only strict decrease re-checks); ``nan`` when undecided.
    recheck : Recheck
    solver : tuple of SolverRun
    finding : str
    exact_P : tuple of RationalMatrix or None
        The re-checked ``P_i`` in exact rationals (not in the JSON view).
    """

    names: tuple[str, ...]
    status: str
    proven: bool
    P: tuple[np.ndarray, ...] | None
    U: tuple[np.ndarray, ...] | None
    W: tuple[np.ndarray, ...] | None
    boundaries: tuple[Boundary, ...]
    margin: float
    recheck: Recheck
    solver: tuple[SolverRun, ...]
    finding: str
    exact_P: tuple[RationalMatrix, ...] | None = field(default=None, metadata={"json": False})

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: every field but :attr:`exact_P` (``null`` for non-finite numbers)."""
        return to_jsonable(self)


def checked_matrix(value: Any, parameter: str, *, columns: int | None = None) -> np.ndarray:
    """A finite float matrix: square when ``columns`` is ``None``, else ``(r, columns)``."""
    raw = np.asarray(value) if not isinstance(value, (str, bytes)) else None
    if raw is not None and np.iscomplexobj(raw):
        raise LmiError(parameter, "complex", "a matrix of real numbers",
                       "give the real matrix of the mode (complex entries would be cut to their real parts)")
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise LmiError(parameter, type(value).__name__, "a matrix of real numbers",
                       "give a numpy array or nested lists of numbers") from None
    if columns is None and (array.ndim != 2 or array.shape[0] != array.shape[1]):
        raise LmiError(parameter, array.shape, "a square matrix, shape (n, n)",
                       "give the mode's matrix A with as many rows as columns")
    if columns is not None and (array.ndim != 2 or array.shape[1] != columns):
        raise LmiError(parameter, array.shape, f"a matrix of shape (r, {columns}): one column per state",
                       f"give each inequality row with {columns} coefficients")
    bad = np.argwhere(~np.isfinite(array))
    if bad.size:
        raise LmiError(parameter, array.shape, "finite entries",
                       f"replace the non-finite entry at {tuple(int(i) for i in bad[0])} (NaN or inf) by a number")
    array.setflags(write=False)
    return array


def checked_family(family: Any, parameter: str = "family") -> list[np.ndarray]:
    """The matrices of ``family`` (``m`` square matrices of one size, finite), or :class:`LmiError` naming ``parameter``."""
    if isinstance(family, np.ndarray) and family.ndim != 3:
        raise LmiError(parameter, family.shape, "a sequence of square matrices (or an array of shape (m, n, n))",
                       "wrap a single matrix in a list: [A]")
    if isinstance(family, (str, bytes)) or not hasattr(family, "__len__"):
        raise LmiError(parameter, type(family).__name__, "a sequence of square matrices", "give a list [A_1, ..., A_m]")
    if len(family) == 0:
        raise LmiError(parameter, "empty", "at least one square matrix", "give the matrices A_i of the modes")
    mats = [checked_matrix(a, f"{parameter}[{i}]") for i, a in enumerate(family)]
    n = mats[0].shape[0]
    for i, a in enumerate(mats):
        if a.shape != (n, n):
            raise LmiError(f"{parameter}[{i}]", a.shape, f"shape ({n}, {n}) like {parameter}[0]",
                           "give every mode the same states")
    if n == 0:
        raise LmiError(f"{parameter}[0]", (0, 0), "at least one state", "give matrices of size n >= 1")
    return mats


def checked_names(names: Any, count: int, prefix: str, parameter: str = "names") -> tuple[str, ...]:
    """``count`` distinct names (``prefix0``, ``prefix1``, ... when ``names`` is ``None``), or :class:`LmiError`."""
    if names is None:
        return tuple(f"{prefix}{i}" for i in range(count))
    if isinstance(names, (str, bytes)) or not hasattr(names, "__len__"):
        raise LmiError(parameter, names, f"a sequence of {count} strings", "give one name per mode, e.g. ('a', 'b')")
    labels = tuple(names)
    if len(labels) != count or not all(isinstance(s, str) for s in labels):
        raise LmiError(parameter, labels, f"{count} strings, one per mode", "give one name per mode")
    if len(set(labels)) != count:
        raise LmiError(parameter, labels, "distinct names", "rename the duplicates")
    return labels

_SDP_SOLVERS = frozenset({"CLARABEL", "SCS", "MOSEK", "CVXOPT", "SDPA", "COPT"})
"""cvxpy solvers that take semidefinite constraints (an LP/QP solver such as HiGHS or OSQP cannot)."""


def checked_solvers(solver: Any) -> tuple[str, ...]:
    """The solvers to try in order (default :data:`SOLVERS`); :class:`LmiError` for one that cannot take an SDP."""
    if solver is None:
        return SOLVERS
    chosen = (solver,) if isinstance(solver, str) else tuple(solver)
    import cvxpy as cp

    installed = set(cp.installed_solvers()) & _SDP_SOLVERS
    if not chosen or not all(isinstance(s, str) and s.upper() in installed for s in chosen):
        raise LmiError("solver", solver, f"None or names of installed SDP solvers {sorted(installed)}",
                       "leave solver=None (Clarabel, then SCS)")
    return tuple(s.upper() for s in chosen)


def solve_first(problem: Any, variables: Sequence[Any], solvers: Sequence[str],
           label: str) -> tuple[list[np.ndarray] | None, tuple[SolverRun, ...]]:
    """Values of ``variables`` from the first solver that answers ``optimal``, else from an inaccurate one."""
    import cvxpy as cp

    runs: list[SolverRun] = []
    fallback = None
    for name in solvers:
        try:
            with warnings.catch_warnings():  # "may be inaccurate": the status says so and the re-check decides
                warnings.simplefilter("ignore")
                problem.solve(solver=name, **_SOLVER_OPTIONS.get(name, {}))
        except (cp.error.SolverError, ArithmeticError, ValueError) as err:
            runs.append(SolverRun(problem=label, solver=name, status="error", message=str(err)[:300]))
            continue
        status = str(problem.status)
        runs.append(SolverRun(problem=label, solver=name, status=status))
        if status in ("optimal", "optimal_inaccurate") and all(v.value is not None for v in variables):
            values = [np.array(v.value, dtype=float) for v in variables]
            if status == "optimal":
                return values, tuple(runs)
            fallback = fallback or values
    return fallback, tuple(runs)


def failure_text(what: str, runs: Sequence[SolverRun]) -> str:
    """``"<what> did not solve (CLARABEL: <status or message>; SCS: …)"``."""
    last = runs[-1].problem if runs else None
    told = "; ".join(f"{r.solver}: {r.message or r.status}" for r in runs if r.problem == last)
    return f"{what} did not solve ({told})" if told else f"{what} did not solve"


def rate_text(alpha: float) -> str:
    """``"V̇ <= -α·V"``, or ``"V̇ < 0"`` when no rate was certified."""
    return f"V̇ <= -{alpha:.4g}·V" if alpha > 0 else "V̇ < 0"


def symmetrised(m: np.ndarray) -> np.ndarray:
    """``(M + Mᵀ)/2`` in floats: exactly symmetric (IEEE addition commutes)."""
    return 0.5 * (m + m.T)


def frozen_copy(m: np.ndarray) -> np.ndarray:
    """A read-only float copy of ``m``."""
    m = np.array(m, dtype=float)
    m.setflags(write=False)
    return m


def primal_lyapunov(
    scaled: list[np.ndarray], solvers: Sequence[str]
) -> tuple[np.ndarray | None, float, tuple[SolverRun, ...]]:
    """The primal program of a common quadratic Lyapunov function of ``scaled``: ``(P or None, margin, runs)``."""
    import cvxpy as cp

    n = scaled[0].shape[0]
    eye = np.eye(n)
    p, eps = cp.Variable((n, n), symmetric=True), cp.Variable()
    cons = [p << eye, p >> eps * eye] + [a.T @ p + p @ a << -eps * eye for a in scaled]
    values, runs = solve_first(cp.Problem(cp.Maximize(eps), cons), [p, eps], solvers, "primal")
    if values is None:
        return None, math.nan, runs
    return values[0], float(values[1]), runs


def dual_alternative(
    scaled: list[np.ndarray], solvers: Sequence[str]
) -> tuple[list[np.ndarray] | None, float, tuple[SolverRun, ...]]:
    """The dual (theorem of alternatives) program of ``scaled``: ``(Z_i or None, margin t, runs)``."""
    import cvxpy as cp

    n = scaled[0].shape[0]
    zs = [cp.Variable((n, n), PSD=True) for _ in scaled]
    t = cp.Variable()
    total = sum(a @ z + z @ a.T for a, z in zip(scaled, zs))
    cons = [total >> t * np.eye(n), sum(cp.trace(z) for z in zs) == 1]
    values, runs = solve_first(cp.Problem(cp.Maximize(t), cons), [*zs, t], solvers, "alternative")
    if values is None:
        return None, math.nan, runs
    return values[:-1], float(values[-1]), runs


def repaired_dual(scaled: list[np.ndarray], zs: list[np.ndarray], t: float,
                  scales: np.ndarray) -> tuple[np.ndarray, ...]:
    """Symmetrise, clip to the cone, shift by ``δI`` (module docstring), map to the unscaled family, trace 1."""
    spread = sum(float(np.linalg.norm(a + a.T, 2)) for a in scaled)
    delta = _DUAL_SHIFT_SHARE * t / spread if spread > 0 else _DUAL_SHIFT_SHARE * t
    n = scaled[0].shape[0]
    out = []
    for z, c in zip(zs, scales):
        values, vectors = np.linalg.eigh(symmetrised(z))
        z = (vectors * np.maximum(values, 0.0)) @ vectors.T + delta * np.eye(n)
        out.append(symmetrised(z) / c)  # Ã_i = A_i / c_i: the certificate of the A_i is Z_i / c_i
    total = sum(float(np.trace(z)) for z in out)
    return tuple(frozen_copy(symmetrised(z / total)) for z in out)


def exact_lie(a: RationalMatrix, p: RationalMatrix) -> RationalMatrix:
    """``AᵀP + PA`` exactly."""
    return a.T @ p + p @ a


def certified_rate(lies: list[RationalMatrix], p: RationalMatrix, estimate: float) -> float:
    """The largest of ``estimate·discounts`` with ``L_i + αP ≺ 0`` for all ``i`` exactly; 0 if none."""
    if not (estimate > 0 and math.isfinite(estimate)):
        return 0.0
    for factor in MARGIN_DISCOUNTS:
        alpha = float(estimate * factor)
        shifted = p.scaled(alpha)
        if all(exact.is_negative_definite(lie + shifted) for lie in lies):
            return alpha
    return 0.0
