"""Linearisation by automatic differentiation, eigen-analysis and quadratic Lyapunov functions.

A closed-loop vector field is given once, as a CasADi function ``F(x) -> ẋ``
(the single symbolic source); :func:`linearise` checks that the point is an
equilibrium (and says by how much it is not), differentiates ``F`` exactly
by CasADi's AD, and reports the eigenvalues with their damping ratios,
natural frequencies and time constants.  :func:`quadratic_lyapunov` solves
``Aᵀ P + P A + Q = 0`` with python-control's ``lyap``;
:func:`common_quadratic_lyapunov` looks for one ``P`` that serves a family
of matrices (a switched linear system) and otherwise gives the minimum
dwell time that the individual Lyapunov functions guarantee.

Examples
--------
>>> import casadi as ca
>>> x = ca.SX.sym("x", 2)
>>> F = ca.Function("F", [x], [ca.vertcat(x[1], -2.0 * x[0] - 3.0 * x[1])])
>>> lin = linearise(F, (0.0, 0.0), state_names=("p", "q"))
>>> sorted(round(e.real, 12) for e in lin.eigenvalues)
[-2.0, -1.0]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from hybrid.jsonable import to_jsonable

from analysis.eigen import EigenMode, eigen_modes

__all__ = [
    "LinearisationError",
    "NotAnEquilibriumError",
    "EigenMode",
    "Linearisation",
    "QuadraticLyapunov",
    "CommonLyapunov",
    "linearise",
    "eigen_modes",
    "quadratic_lyapunov",
    "common_quadratic_lyapunov",
    "to_numpy",
]


class LinearisationError(ValueError):
    """Bad input to a linearisation (shapes, NaN, unknown names)."""


class NotAnEquilibriumError(LinearisationError):
    """The linearisation point is not an equilibrium; carries the residual ``F(x*)``."""

    def __init__(self, message: str, residual: tuple[float, ...]) -> None:
        super().__init__(message)
        self.residual = residual


def to_numpy(value: Any) -> np.ndarray:
    """The one adapter from CasADi values to numpy: ``DM`` → float array (vectors as ``(n,)``)."""
    array = np.array(ca.DM(value).full(), dtype=float)
    if array.ndim == 2 and 1 in array.shape:
        return array.reshape(-1)
    return array


@dataclass(frozen=True, kw_only=True, slots=True)
class Linearisation:
    """``ẋ ≈ A (x − x*)`` around an equilibrium.

    Attributes
    ----------
    name : str
    state_names : tuple of str
    point : tuple of float
        The equilibrium ``x*``.
    residual : tuple of float
        ``F(x*)`` (within the tolerance of zero).
    jacobian : ndarray, shape (n, n)
        ``A = ∂F/∂x (x*)`` by automatic differentiation (read-only).
    modes : tuple of EigenMode
    hurwitz : bool
        Every eigenvalue has a negative real part (by more than ``tol``).
    spectral_abscissa : float
        Largest real part [1/s].
    """

    name: str
    state_names: tuple[str, ...]
    point: tuple[float, ...]
    residual: tuple[float, ...]
    jacobian: np.ndarray
    modes: tuple[EigenMode, ...]
    hurwitz: bool
    spectral_abscissa: float

    @property
    def eigenvalues(self) -> tuple[complex, ...]:
        """The eigenvalues as complex numbers."""
        return tuple(complex(m.real, m.imag) for m in self.modes)

    @property
    def finding(self) -> str:
        """One sentence: stable, or why not (reported, never raised)."""
        if self.hurwitz:
            slowest = max(m.time_constant_s for m in self.modes)
            return f"Hurwitz: exponentially stable, slowest time constant {slowest:.4g} s"
        zero = [m for m in self.modes if abs(m.real) <= 1e-12 * max(1.0, m.natural_frequency_radps)]
        if zero and self.spectral_abscissa <= 1e-12:
            return (f"not Hurwitz: {len(zero)} eigenvalue(s) on the imaginary axis (a continuum of equilibria "
                    "or an uncontrolled direction); linearisation decides nothing about those directions")
        return f"not Hurwitz: unstable, spectral abscissa {self.spectral_abscissa:.4g} 1/s"

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: the residual as its norm ``residual_norm``, the eigenvalues as ``[re, im]``
        pairs, the modes, and the :attr:`finding`."""
        return to_jsonable({
            "name": self.name,
            "state_names": self.state_names,
            "point": self.point,
            "residual_norm": float(np.linalg.norm(self.residual)),
            "jacobian": self.jacobian,
            "eigenvalues": self.eigenvalues,
            "modes": self.modes,
            "hurwitz": self.hurwitz,
            "spectral_abscissa": self.spectral_abscissa,
            "finding": self.finding,
        })


def linearise(
    function: Any,
    point: Sequence[float],
    *,
    state_names: Sequence[str] | None = None,
    name: str = "",
    tol: float = 1e-9,
    mode: str | None = None,
    memory: Any = None,
) -> Any:
    """Check the equilibrium and linearise ``F`` there by automatic differentiation.

    Parameters
    ----------
    function : casadi.Function or hybrid.HybridSystem
        ``F(x) -> ẋ`` with one input and one output of size ``n``; or a hybrid system, whose ``mode``
        is linearised (see Returns).
    point : sequence of float, shape (n,)
        Candidate equilibrium.
    state_names : sequence of str, length n
        Required for a CasADi function (a system has its own).
    name : str
        Label for reports.
    tol : float
        Largest acceptable ``‖F(x*)‖∞``.
    mode : str or None
        The mode of a hybrid system (required for one, refused otherwise).
    memory : Mapping or None
        Memory values of a hybrid system's flow (default: its initial memory).

    Returns
    -------
    Linearisation
        For a CasADi function.
    analysis.equilibria.ModeEquilibrium
        For a mode of a hybrid system: the equilibrium checked against the mode's invariant and
        outgoing guards (``kind`` ``"virtual"`` — "virtual equilibrium, outside the mode", whose
        eigenvalues say nothing about the hybrid system — or ``"switching"`` or ``"equilibrium"``),
        derivatives by CasADi through the user's own flow function.

    Raises
    ------
    LinearisationError
        Wrong shapes or a non-finite point; a system without ``mode``, a function with one.
    NotAnEquilibriumError
        ``‖F(x*)‖∞ > tol``; the message and the exception carry the residual.
    """
    from hybrid import HybridSystem

    if isinstance(function, HybridSystem):
        return _linearise_mode(function, point, mode=mode, memory=memory, tol=tol)
    if mode is not None or memory is not None:
        raise LinearisationError(f"linearise {name!r}: mode = {mode!r}, memory = {memory!r} apply to a hybrid "
                                 "system; a casadi.Function has no modes: drop them")
    if not isinstance(function, ca.Function) or function.n_in() != 1 or function.n_out() != 1:
        raise LinearisationError(f"linearise: function = {function!r}; expected a casadi.Function F(x) -> xdot "
                                 "or a hybrid.HybridSystem with mode=...")
    if state_names is None:
        raise LinearisationError(f"linearise {name!r}: state_names = None; give one name per state of F")
    n = function.size1_in(0)
    x = np.asarray(point, dtype=float).reshape(-1)
    if x.size != n or len(state_names) != n:
        raise LinearisationError(
            f"linearise {name!r}: point has {x.size} components and state_names {len(state_names)}, "
            f"the function takes {n}; give one value and one name per state"
        )
    if not np.all(np.isfinite(x)):
        raise LinearisationError(f"linearise {name!r}: point = {x.tolist()} is not finite")
    residual = to_numpy(function(x))
    if residual.size != n:
        raise LinearisationError(f"linearise {name!r}: F returns {residual.size} values for {n} states")
    if not np.all(np.abs(residual) <= tol):
        worst = int(np.argmax(np.abs(residual)))
        raise NotAnEquilibriumError(
            f"linearise {name!r}: the point {dict(zip(state_names, x.tolist()))} is not an equilibrium: "
            f"F = {residual.tolist()} (largest |d{state_names[worst]}/dt| = {abs(residual[worst]):.3g} > tol = {tol:g}); "
            "linearise at an equilibrium, or analyse the error dynamics in coordinates where it is one",
            tuple(float(r) for r in residual),
        )
    sym = ca.SX.sym("x", n)
    jac = ca.Function("jacobian_of_F", [sym], [ca.jacobian(function(sym), sym)])
    a = to_numpy(jac(x)).reshape(n, n)
    a.setflags(write=False)
    modes = eigen_modes(a)
    abscissa = max(m.real for m in modes)
    return Linearisation(
        name=name, state_names=tuple(state_names), point=tuple(float(c) for c in x),
        residual=tuple(float(r) for r in residual), jacobian=a, modes=modes,
        hurwitz=bool(abscissa < -tol), spectral_abscissa=float(abscissa),
    )


def _linearise_mode(system: Any, point: Sequence[float], *, mode: str | None, memory: Any, tol: float) -> Any:
    """:func:`linearise` of a hybrid system's mode: the residual at ``point``, then the classified equilibrium."""
    from analysis.equilibria import mode_equilibrium

    modes = list(system.automaton.mode_names)
    if mode not in modes:
        raise LinearisationError(f"linearise {system.name!r}: mode = {mode!r}; expected one of {modes}: a hybrid "
                                 "system is linearised mode by mode, name the mode")
    x = np.asarray(point, dtype=float).reshape(-1)
    n = len(system.state_names)
    if x.size != n or not np.all(np.isfinite(x)):
        raise LinearisationError(f"linearise {system.name!r}: point = {x.tolist()}; expected {n} finite values, one "
                                 f"per state {list(system.state_names)}")
    mem = dict(system.automaton.initial_memory() if memory is None else memory)
    residual = np.asarray(system.flow(mode, 0.0, tuple(float(c) for c in x), mem), dtype=float).reshape(-1)
    if not np.all(np.abs(residual) <= tol):
        worst = int(np.argmax(np.abs(residual)))
        names = system.state_names
        raise NotAnEquilibriumError(
            f"linearise {system.name!r} mode {mode!r}: the point {dict(zip(names, x.tolist()))} is not an "
            f"equilibrium: f = {residual.tolist()} (largest |d{names[worst]}/dt| = {abs(residual[worst]):.3g} > "
            f"tol = {tol:g}); give the equilibrium, or find it with analysis.equilibria.mode_equilibrium",
            tuple(float(r) for r in residual))
    return mode_equilibrium(system, mode, guess=tuple(float(c) for c in x), memory=mem, tol=tol)


@dataclass(frozen=True, kw_only=True, slots=True)
class QuadraticLyapunov:
    """``V = xᵀ P x`` with ``Aᵀ P + P A = −Q``.

    Attributes
    ----------
    P, Q : ndarray, shape (n, n)
    valid : bool
        ``P`` positive definite (so ``V`` proves exponential stability).
    decay_rate : float
        ``λmin(Q) / λmax(P)``: ``V̇ ≤ −decay_rate V`` [1/s].
    residual : float
        ``‖Aᵀ P + P A + Q‖∞`` (accuracy of the solve).
    """

    P: np.ndarray
    Q: np.ndarray
    valid: bool
    decay_rate: float
    residual: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: every field, ``None`` for non-finite numbers (``P`` and ``residual`` of a failed solve)."""
        return to_jsonable(self)


def quadratic_lyapunov(a: np.ndarray, q: np.ndarray | None = None) -> QuadraticLyapunov:
    """Solve ``Aᵀ P + P A + Q = 0`` with ``control.lyap`` (``Q = I`` by default).

    A non-Hurwitz ``A`` gives ``valid = False`` (``P`` indefinite or the solve
    singular), never an exception.
    """
    import control

    a = np.asarray(a, dtype=float)
    n = a.shape[0]
    if a.ndim != 2 or a.shape != (n, n):
        raise LinearisationError(f"quadratic_lyapunov: A has shape {a.shape}; expected a square matrix")
    q = np.eye(n) if q is None else np.asarray(q, dtype=float)
    if np.linalg.eigvals(a).real.max() >= 0.0:  # no positive definite solution exists: say so, do not solve
        nan = np.full((n, n), np.nan)
        return QuadraticLyapunov(P=nan, Q=q, valid=False, decay_rate=math.nan, residual=math.inf)
    try:
        p = np.asarray(control.lyap(a.T, q), dtype=float)  # solves Aᵀ P + P A + Q = 0
    except Exception:  # singular Sylvester operator: A has eigenvalues λ_i + λ_j = 0
        nan = np.full((n, n), np.nan)
        return QuadraticLyapunov(P=nan, Q=q, valid=False, decay_rate=math.nan, residual=math.inf)
    p = 0.5 * (p + p.T)
    eig_p = np.linalg.eigvalsh(p)
    valid = bool(np.all(np.isfinite(p)) and eig_p.min() > 0)
    decay = float(np.linalg.eigvalsh(q).min() / eig_p.max()) if valid else math.nan
    residual = float(np.abs(a.T @ p + p @ a + q).max())
    p.setflags(write=False)
    return QuadraticLyapunov(P=p, Q=q, valid=valid, decay_rate=decay, residual=residual)


@dataclass(frozen=True, kw_only=True, slots=True)
class CommonLyapunov:
    """Common quadratic Lyapunov function of a switched linear family, or a dwell time.

    Attributes
    ----------
    names : tuple of str
        The family members.
    found : bool
        A ``P > 0`` with ``A_iᵀ P + P A_i < 0`` for every member was found and verified.
    P : ndarray or None
    worst_margin : float
        ``max_i λmax(A_iᵀ P + P A_i) / λmin(P)`` at the best ``P`` found (< 0 when found) [1/s].
    dwell_time_s : float
        Minimum dwell time guaranteed by the individual ``V_i = xᵀ P_i x``
        (``ln μ / λ0``, ``μ = max λmax(P_i)/λmin(P_j)``, ``λ0`` the smallest
        decay rate); ``0`` when a common ``P`` exists, ``inf`` when a member is not Hurwitz.
    """

    names: tuple[str, ...]
    found: bool
    P: np.ndarray | None
    worst_margin: float
    dwell_time_s: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: every field, ``None`` for non-finite numbers."""
        return to_jsonable(self)


def _margin(p: np.ndarray, family: Sequence[np.ndarray]) -> float:
    low = np.linalg.eigvalsh(p).min()
    if low <= 0:
        return math.inf
    return max(np.linalg.eigvalsh(a.T @ p + p @ a).max() for a in family) / low


def common_quadratic_lyapunov(
    family: Sequence[np.ndarray], names: Sequence[str] | None = None, *, seed: int = 0
) -> CommonLyapunov:
    """Search a common quadratic Lyapunov function; fall back on a dwell time (superseded: see below).

    Kept as the baseline of ``benchmarks/bench_lmi.py``.  The toolkit decides the question with
    :func:`analysis.lmi.common_quadratic_lyapunov_lmi` (an LMI, re-checked exactly, with a proof of
    absence) and :func:`analysis.lmi.dwell_time_lyapunov`; this local search proves nothing when it
    fails.

    The search minimises ``max_i λmax(A_iᵀ P + P A_i)/λmin(P)`` over
    ``P = L Lᵀ`` (Nelder–Mead from the individual solutions and their sum,
    seeded); a ``P`` is accepted only if the margin is negative when
    re-evaluated.  Failure to find one is *not* a proof that none exists; the
    dwell time then says how slowly switching must happen.
    """
    from scipy.optimize import minimize

    mats = [np.asarray(a, dtype=float) for a in family]
    if not mats:
        raise LinearisationError("common_quadratic_lyapunov: empty family; give at least one matrix")
    n = mats[0].shape[0]
    if any(a.shape != (n, n) for a in mats):
        raise LinearisationError(
            f"common_quadratic_lyapunov: shapes {[a.shape for a in mats]}; expected square matrices of one size"
        )
    labels = tuple(names) if names is not None else tuple(f"A{i}" for i in range(len(mats)))
    singles = [quadratic_lyapunov(a) for a in mats]
    if not all(s.valid for s in singles):
        return CommonLyapunov(names=labels, found=False, P=None, worst_margin=math.inf, dwell_time_s=math.inf)
    mu = max(np.linalg.eigvalsh(si.P).max() / np.linalg.eigvalsh(sj.P).min() for si in singles for sj in singles)
    lambda0 = min(s.decay_rate for s in singles)
    dwell = math.log(mu) / lambda0 if mu > 1 else 0.0
    tril = np.tril_indices(n)

    def unpack(theta: np.ndarray) -> np.ndarray:
        lower = np.zeros((n, n))
        lower[tril] = theta
        return lower @ lower.T

    starts = [s.P / np.trace(s.P) for s in singles] + [sum(s.P / np.trace(s.P) for s in singles)]
    rng = np.random.default_rng(seed)
    best_p, best = None, math.inf
    for start in starts:
        theta0 = np.linalg.cholesky(start + 1e-12 * np.eye(n))[tril]
        theta0 = theta0 + 1e-3 * rng.standard_normal(theta0.size)
        result = minimize(lambda th: _margin(unpack(th), mats), theta0, method="Nelder-Mead",
                          options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 4000})
        p = unpack(result.x)
        value = _margin(p, mats)
        if value < best:
            best_p, best = p, value
    found = bool(best < 0)
    if best_p is not None:
        best_p = best_p / np.trace(best_p)
        best_p.setflags(write=False)
    return CommonLyapunov(names=labels, found=found, P=best_p if found else None, worst_margin=float(best),
                          dwell_time_s=0.0 if found else float(dwell))
