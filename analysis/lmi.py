"""Lyapunov certificates of switched linear systems by linear matrix inequalities, re-checked outside the solver.

A switched linear system ``ẋ = A_σ(t) x`` with modes ``A_1 … A_m`` (shape ``(n, n)``):

**Common quadratic Lyapunov function** (Boyd, El Ghaoui, Feron & Balakrishnan, *LMIs in System and
Control Theory*, §5.1): ``V = xᵀPx`` with ``P ≻ 0`` and ``A_iᵀP + PA_i ≺ 0`` for every ``i`` proves
exponential stability under *arbitrary* switching.  The conditions are homogeneous in ``P``, so they
hold iff the normalised ``P ⪰ I``, ``A_iᵀP + PA_i ⪯ −I`` are feasible (scale any strict solution).

**Its absence, proven** (a theorem of alternatives, the LMI form of Farkas' lemma): if there are
``Z_i ⪰ 0``, not all zero, with ``Σ_i (A_iZ_i + Z_iA_iᵀ) ⪰ 0``, no such ``P`` exists.  Proof: for a
feasible ``P``, ``tr(P Σ_i(A_iZ_i + Z_iA_iᵀ)) = Σ_i tr((A_iᵀP + PA_i)Z_i) < 0`` (each term is the
inner product of a negative definite and a non-zero positive semidefinite matrix), but the left
side is ``≥ 0`` as the inner product of two positive semidefinite matrices.  The dual program
maximises ``t`` subject to ``Z_i ⪰ 0``, ``Σ tr Z_i = 1``, ``Σ(A_iZ_i + Z_iA_iᵀ) ⪰ tI``; ``t > 0`` is a
certificate with a margin.  When the certificate cannot be strict (a family with stable directions
that no ``Z_i`` can excite, where the best ``t`` is 0), absence is proven by its rank-one special case:
nonnegative weights ``w_i`` with ``Ā = Σ w_iA_i`` not Hurwitz (``Z_i = w_i Re(vv*)`` for an
eigenvector ``v`` of ``Ā`` with ``Re λ ≥ 0`` gives ``Σ(A_iZ_i + Z_iA_iᵀ) = 2 Re λ · Re(vv*) ⪰ 0``);
the weights come from the dual's ``tr Z_i``, the pairs' midpoints and a local search, and the
decision is exact (:func:`analysis.exact.is_hurwitz`, Routh–Hurwitz on rationals).

**Re-check** (:mod:`analysis.exact`): the solver's float answer is converted to exact rationals and
the definiteness of every matrix of the certificate is decided by an exact ``LDLᵀ`` — on the user's
float data, converted exactly too.  The dual ``Z_i`` are usually singular at the optimum; each is
first shifted by ``ηI`` (``η`` a small share of the margin ``t`` over ``Σ‖A_i + A_iᵀ‖``, which
``Σ(A_iZ_i + Z_iA_iᵀ)`` can lose by the shift), and the exact test decides the shifted
certificate, which is a certificate in its own right.  Only an answer whose exact test passes is
**proven**; any other outcome (solver failure, margin too small: a borderline family) is
``"undecided"``, never "not found".

**Dwell time** (Geromel & Colaneri, *Stability and stabilization of continuous-time switched linear
systems*, SIAM J. Control Optim. 2006): if ``P_i ≻ 0``, ``A_iᵀP_i + P_iA_i ≺ 0`` and
``e^{A_iᵀT} P_j e^{A_iT} − P_i ≺ 0`` for all ``i ≠ j``, every switching signal whose dwell time is at
least ``T`` is stable; the smallest such ``T`` is found by bisection.  ``e^{AT}`` is not rational:
the re-check computes the residuals' eigenvalues in float64 and asks for a margin far above the
error of ``expm`` and of the products.

Examples
--------
>>> import numpy as np
>>> r = common_quadratic_lyapunov_lmi([np.array([[-1.0, 2.0], [0.0, -1.0]]), np.array([[-1.0, 0.0], [1.0, -2.0]])])
>>> r.status, r.proven
('exists', True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid.errors import ParameterError
from hybrid.jsonable import to_jsonable

from analysis import exact

__all__ = ["LmiError", "Recheck", "CommonLyapunovLMI", "DwellTimeLMI", "common_quadratic_lyapunov_lmi",
           "dwell_time_lyapunov", "recheck_common_lyapunov", "recheck_no_common_lyapunov", "LMI_STATUSES",
           "SOLVERS"]

LMI_STATUSES = ("exists", "none", "undecided")
SOLVERS = ("CLARABEL", "SCS")
"""Tried in order: the interior-point Clarabel first, the splitting-cone SCS when it fails."""

_DUAL_SHIFT_SHARE = 0.25
"""Share of the dual margin ``t`` that the shift of the ``Z_i`` may cost."""

_FLOAT_MARGIN = 1e-6
"""Dwell-time re-check: residual eigenvalues must lie below ``−1e-6`` (scaled data; ``expm`` errors ~1e-13)."""


class LmiError(ParameterError):
    """Bad input to an LMI analysis (shapes, non-finite entries, names)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class Recheck:
    """How a certificate was re-checked outside the solver: ``method``, ``passed`` and ``detail``."""

    method: str
    passed: bool
    detail: str


@dataclass(frozen=True, kw_only=True, slots=True)
class CommonLyapunovLMI:
    """Whether a common quadratic Lyapunov function exists, proven either way or undecided.

    Attributes
    ----------
    names : tuple of str
    status : str
        ``"exists"`` (``P`` re-checked), ``"none"`` (dual certificate re-checked) or ``"undecided"``.
    proven : bool
        ``status != "undecided"``.
    P : ndarray or None, shape (n, n)
        ``V = xᵀPx`` (trace 1, read-only).
    dual : tuple of ndarray or None
        The ``Z_i`` of the certificate of absence (shifted as re-checked).
    margin : float
        Decay margin ``−max_i λmax(A_iᵀP + PA_i)/λmax(P)`` [1/s], or the dual's ``t`` (scaled data).
    recheck : Recheck
    solver : str
    finding : str
    witness_weights : tuple of float or None
        When absence is proven by a convex combination that is not Hurwitz: its weights.
    """

    names: tuple[str, ...]
    status: str
    proven: bool
    P: np.ndarray | None
    dual: tuple[np.ndarray, ...] | None
    margin: float
    recheck: Recheck
    solver: str
    finding: str
    witness_weights: tuple[float, ...] | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return to_jsonable(self, nonfinite="string")


@dataclass(frozen=True, kw_only=True, slots=True)
class DwellTimeLMI:
    """The smallest dwell time certified by mode-dependent quadratic Lyapunov functions.

    Attributes
    ----------
    names : tuple of str
    dwell_time_s : float
        Every switching signal with dwell time ``>= dwell_time_s`` is stable (``inf``: none certified).
    proven : bool
    P : tuple of ndarray
        ``P_i`` at ``dwell_time_s`` (empty when none).
    recheck : Recheck
    solver : str
    finding : str
    """

    names: tuple[str, ...]
    dwell_time_s: float
    proven: bool
    P: tuple[np.ndarray, ...]
    recheck: Recheck
    solver: str
    finding: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return to_jsonable(self, nonfinite="string")


def _family(family: Sequence[Any], names: Sequence[str] | None) -> tuple[list[np.ndarray], tuple[str, ...]]:
    mats = list(family) if not isinstance(family, np.ndarray) or family.ndim == 3 else [family]
    if not mats:
        raise LmiError("family", [], "at least one square matrix", "give the matrices A_i of the modes")
    out = []
    for i, a in enumerate(mats):
        arr = np.asarray(a, dtype=float)
        if arr.ndim != 2 or arr.shape[0] != arr.shape[1]:
            raise LmiError(f"family[{i}]", arr.shape, "a square matrix (n, n)", "give A_i with as many rows as columns")
        if not np.all(np.isfinite(arr)):
            raise LmiError(f"family[{i}]", arr.tolist(), "finite entries", "remove NaN and infinite values")
        out.append(arr)
    shapes = sorted({a.shape for a in out})
    if len(shapes) > 1:
        raise LmiError("family", [a.shape for a in out], "matrices of one size", "give every mode the same states")
    labels = tuple(f"A{i}" for i in range(len(out))) if names is None else tuple(str(n) for n in names)
    if len(labels) != len(out):
        raise LmiError("names", labels, f"{len(out)} names, one per matrix", "name every mode once")
    return out, labels


def _solve(problem: Any) -> str:
    """Solve with :data:`SOLVERS` in turn; the status of the first that answers (or the last error)."""
    import cvxpy as cp

    import warnings

    last = "no solver ran"
    for solver in SOLVERS:
        try:
            with warnings.catch_warnings():  # "may be inaccurate": the status says so, and the re-check decides
                warnings.simplefilter("ignore", UserWarning)
                problem.solve(solver=solver)
        except (cp.error.SolverError, ArithmeticError, ValueError) as err:
            last = f"{solver}: {err}"
            continue
        if problem.status in ("optimal", "optimal_inaccurate", "infeasible", "infeasible_inaccurate"):
            return f"{solver}: {problem.status}"
        last = f"{solver}: {problem.status}"
    return last


def _primal(mats: list[np.ndarray]) -> tuple[np.ndarray | None, str]:
    import cvxpy as cp

    n = mats[0].shape[0]
    p = cp.Variable((n, n), symmetric=True)
    cons = [p >> np.eye(n)] + [-(a.T @ p + p @ a) >> np.eye(n) for a in mats]
    problem = cp.Problem(cp.Minimize(cp.lambda_max(p)), cons)
    status = _solve(problem)
    if problem.status in ("optimal", "optimal_inaccurate") and p.value is not None:
        return np.asarray(p.value, dtype=float), status
    return None, status


def _dual(mats: list[np.ndarray]) -> tuple[list[np.ndarray] | None, float, str]:
    import cvxpy as cp

    n = mats[0].shape[0]
    zs = [cp.Variable((n, n), symmetric=True) for _ in mats]
    t = cp.Variable()
    total = sum(a @ z + z @ a.T for a, z in zip(mats, zs))
    cons = [z >> 0 for z in zs] + [sum(cp.trace(z) for z in zs) == 1, total >> t * np.eye(n)]
    problem = cp.Problem(cp.Maximize(t), cons)
    status = _solve(problem)
    if problem.status in ("optimal", "optimal_inaccurate") and t.value is not None:
        return [np.asarray(z.value, dtype=float) for z in zs], float(t.value), status
    return None, math.nan, status


def _symmetric_rational(m: np.ndarray) -> exact.RationalMatrix:
    r = exact.rational_matrix(m)
    n = len(r)
    return [[(r[i][j] + r[j][i]) / 2 for j in range(n)] for i in range(n)]


def recheck_common_lyapunov(family: Sequence[np.ndarray], p: np.ndarray) -> Recheck:
    """Exactly: ``P ≻ 0`` and ``−(A_iᵀP + PA_i) ≻ 0`` for every ``A_i`` (``P`` symmetrised exactly)."""
    pr = _symmetric_rational(p)
    if not exact.is_positive_definite(pr):
        return Recheck(method="exact rational LDLᵀ on the float data", passed=False, detail="P is not positive definite")
    for i, a in enumerate(family):
        ar = exact.rational_matrix(a)
        lie = exact.mat_add(exact.mat_mul(exact.transpose(ar), pr), exact.mat_mul(pr, ar))
        if not exact.is_positive_definite(exact.scaled(lie, -1)):
            return Recheck(method="exact rational LDLᵀ on the float data", passed=False,
                           detail=f"A_{i}ᵀP + PA_{i} is not negative definite")
    return Recheck(method="exact rational LDLᵀ on the float data", passed=True,
                   detail=f"P ≻ 0 and A_iᵀP + PA_i ≺ 0 for the {len(family)} matrices, in exact arithmetic")


def recheck_no_common_lyapunov(family: Sequence[np.ndarray], zs: Sequence[np.ndarray]) -> Recheck:
    """Exactly: every ``Z_i ≻ 0`` and ``Σ(A_iZ_i + Z_iA_iᵀ) ≻ 0`` (the alternative, module docstring)."""
    method = "exact rational LDLᵀ of the dual certificate"
    zr = [_symmetric_rational(z) for z in zs]
    for i, z in enumerate(zr):
        if not exact.is_positive_definite(z):
            return Recheck(method=method, passed=False, detail=f"Z_{i} is not positive definite")
    terms = []
    for a, z in zip(family, zr):
        ar = exact.rational_matrix(a)
        terms += [exact.mat_mul(ar, z), exact.mat_mul(z, exact.transpose(ar))]
    if not exact.is_positive_definite(exact.mat_add(*terms)):
        return Recheck(method=method, passed=False, detail="Σ(A_iZ_i + Z_iA_iᵀ) is not positive definite")
    return Recheck(method=method, passed=True,
                   detail="Z_i ≻ 0 and Σ(A_iZ_i + Z_iA_iᵀ) ≻ 0 in exact arithmetic: no P can exist")


def _shifted(mats: list[np.ndarray], zs: list[np.ndarray], t: float) -> list[np.ndarray]:
    spread = sum(np.linalg.norm(a + a.T, 2) for a in mats) + 1e-300
    eta = _DUAL_SHIFT_SHARE * t / spread / len(zs)
    n = mats[0].shape[0]
    out = []
    for z in zs:
        z = 0.5 * (z + z.T)
        low = float(np.linalg.eigvalsh(z).min())
        out.append(z + (max(0.0, -low) + eta) * np.eye(n))
    return out


def _combination_candidates(mats: list[np.ndarray], zs: list[np.ndarray] | None) -> list[np.ndarray]:
    """Weights of convex combinations worth testing: the dual's traces, every pair's midpoint, every vertex."""
    m = len(mats)
    out = []
    if zs is not None:
        w = np.array([max(0.0, float(np.trace(z))) for z in zs])
        if w.sum() > 0:
            out.append(w / w.sum())
    for i in range(m):
        for j in range(i + 1, m):
            w = np.zeros(m)
            w[[i, j]] = 0.5
            out.append(w)
    return out + [np.eye(m)[i] for i in range(m)]


def _abscissa(mats: list[np.ndarray], w: np.ndarray) -> float:
    return float(np.linalg.eigvals(sum(wi * a for wi, a in zip(w, mats))).real.max())


def _unstable_combination(mats: list[np.ndarray], zs: list[np.ndarray] | None) -> np.ndarray | None:
    """Nonnegative weights whose combination of ``mats`` is not Hurwitz in exact arithmetic, or ``None``.

    The best candidate is polished by Nelder–Mead on the spectral abscissa over the simplex (softmax
    weights); the decision is :func:`analysis.exact.is_hurwitz` on the exact rational combination.
    """
    from scipy.optimize import minimize

    candidates = sorted(_combination_candidates(mats, zs), key=lambda w: -_abscissa(mats, w))
    best = candidates[0]
    if _abscissa(mats, best) < 0:
        logits0 = np.log(np.maximum(best, 1e-3))
        res = minimize(lambda z: -_abscissa(mats, np.exp(z) / np.exp(z).sum()), logits0, method="Nelder-Mead",
                       options={"maxiter": 400, "xatol": 1e-6, "fatol": 1e-9})
        best = np.exp(res.x) / np.exp(res.x).sum()
    if _abscissa(mats, best) < -1e-12:
        return None
    rational = [exact.rational_matrix(a) for a in mats]
    total = exact.mat_add(*[exact.scaled(r, exact.rational_matrix([[w]])[0][0]) for r, w in zip(rational, best)])
    return None if exact.is_hurwitz(total) else best


def common_quadratic_lyapunov_lmi(family: Sequence[Any], names: Sequence[str] | None = None) -> CommonLyapunovLMI:
    """Decide whether a common quadratic Lyapunov function of ``family`` exists (module docstring).

    Parameters
    ----------
    family : sequence of array_like, each shape (n, n)
    names : sequence of str or None

    Raises
    ------
    LmiError
        An empty family, a non-square or non-finite matrix, sizes that differ, names of the wrong length.
    """
    mats, labels = _family(family, names)
    scale = max(float(np.abs(a).max()) for a in mats) or 1.0
    scaled = [a / scale for a in mats]  # the LMIs are homogeneous in A: same answer, better numerics
    p, status = _primal(scaled)
    if p is not None:
        check = recheck_common_lyapunov(mats, p)
        if check.passed:
            p = p / np.trace(p)
            margin = float(-max(np.linalg.eigvalsh(a.T @ p + p @ a).max() for a in mats) / np.linalg.eigvalsh(p).max())
            p.setflags(write=False)
            return CommonLyapunovLMI(
                names=labels, status="exists", proven=True, P=p, dual=None, margin=margin, recheck=check,
                solver=status, finding=(f"a common quadratic Lyapunov function exists (proven): V = xᵀPx decreases "
                                        f"in every mode of {list(labels)}, at rate >= {margin:.3g} 1/s: stable "
                                        "under arbitrary switching"))
    zs, t, dual_status = _dual(scaled)
    if zs is not None and t > 0:
        shifted = _shifted(scaled, zs, t)
        check = recheck_no_common_lyapunov(mats, shifted)
        if check.passed:
            for z in shifted:
                z.setflags(write=False)
            return CommonLyapunovLMI(
                names=labels, status="none", proven=True, P=None, dual=tuple(shifted), margin=t, recheck=check,
                solver=f"{status}; dual {dual_status}",
                finding=(f"no common quadratic Lyapunov function exists for {list(labels)} (proven by a re-checked "
                         "dual certificate): stability under arbitrary switching needs another argument "
                         "(dwell time, state-dependent switching)"))
        why = check.detail
    else:
        why = f"the dual margin is {t:.3g}" if zs is not None else "the dual did not solve"
    weights = _unstable_combination(mats, zs)
    if weights is not None:
        abscissa = _abscissa(mats, weights)
        text = " + ".join(f"{w:.4g}·{name}" for w, name in zip(weights, labels) if w > 0)
        return CommonLyapunovLMI(
            names=labels, status="none", proven=True, P=None, dual=None, margin=abscissa,
            recheck=Recheck(method="exact Routh–Hurwitz test of a rational convex combination", passed=True,
                            detail=f"{text} is not Hurwitz (spectral abscissa {abscissa:.4g} 1/s), in exact "
                                   "arithmetic; a common P would make every convex combination Hurwitz"),
            solver=f"{status}; dual {dual_status}",
            finding=(f"no common quadratic Lyapunov function exists for {list(labels)} (proven: the convex "
                     f"combination {text} is not Hurwitz, re-checked exactly; the dual certificate Z_i = w_i·Re(vv*) "
                     "of its unstable eigenvector v)"), witness_weights=tuple(float(w) for w in weights))
    return CommonLyapunovLMI(
        names=labels, status="undecided", proven=False, P=None, dual=None, margin=math.nan,
        recheck=Recheck(method="exact rational LDLᵀ", passed=False, detail=why), solver=f"{status}; dual {dual_status}",
        finding=f"undecided: neither a common quadratic Lyapunov function nor a certificate of its absence re-checks "
                f"({why}); the family is at the border (its margin is below the solver's accuracy)")


def _dwell_lmi(mats: list[np.ndarray], expms: list[np.ndarray]) -> tuple[list[np.ndarray] | None, str]:
    import cvxpy as cp

    n, m = mats[0].shape[0], len(mats)
    ps = [cp.Variable((n, n), symmetric=True) for _ in range(m)]
    eye = np.eye(n)
    cons = [p >> eye for p in ps] + [-(a.T @ p + p @ a) >> eye for a, p in zip(mats, ps)]
    cons += [ps[i] - e.T @ ps[j] @ e >> eye for i, e in enumerate(expms) for j in range(m) if j != i]
    problem = cp.Problem(cp.Minimize(sum(cp.trace(p) for p in ps)), cons)
    status = _solve(problem)
    if problem.status in ("optimal", "optimal_inaccurate") and all(p.value is not None for p in ps):
        return [np.asarray(p.value, dtype=float) for p in ps], status
    return None, status


def _dwell_residual(mats: list[np.ndarray], expms: list[np.ndarray], ps: list[np.ndarray]) -> float:
    """Largest eigenvalue of the dwell LMIs' left sides (``P_i`` made symmetric; ``<= −1`` when exact)."""
    worst = -math.inf
    for i, (a, p) in enumerate(zip(mats, ps)):
        p = 0.5 * (p + p.T)
        worst = max(worst, float(np.linalg.eigvalsh(np.eye(len(p)) - p).max()) - 1.0)
        worst = max(worst, float(np.linalg.eigvalsh(a.T @ p + p @ a).max()))
        for j, q in enumerate(ps):
            if j != i:
                q = 0.5 * (q + q.T)
                worst = max(worst, float(np.linalg.eigvalsh(expms[i].T @ q @ expms[i] - p).max()))
    return worst


def dwell_time_lyapunov(family: Sequence[Any], names: Sequence[str] | None = None, *, rel_tol: float = 1e-3,
                        max_doublings: int = 30) -> DwellTimeLMI:
    """The smallest dwell time certified by the Geromel–Colaneri LMIs, by bisection (module docstring).

    Raises
    ------
    LmiError
        As :func:`common_quadratic_lyapunov_lmi`, or ``rel_tol`` outside ``(0, 1)``.
    """
    from scipy.linalg import expm

    mats, labels = _family(family, names)
    if not (isinstance(rel_tol, float) and 0.0 < rel_tol < 1.0):
        raise LmiError("rel_tol", rel_tol, "a number in (0, 1)", "give e.g. rel_tol=1e-3")
    scale = max(float(np.abs(a).max()) for a in mats) or 1.0
    scaled = [a / scale for a in mats]  # time in units of 1/scale

    def attempt(tau: float) -> tuple[list[np.ndarray] | None, str]:
        expms = [expm(a * tau) for a in scaled]
        ps, status = _dwell_lmi(scaled, expms)
        if ps is not None and _dwell_residual(scaled, expms, ps) > -_FLOAT_MARGIN:
            return None, status + " (residual check failed)"
        return ps, status

    if any(np.linalg.eigvals(a).real.max() >= 0 for a in mats):
        return DwellTimeLMI(names=labels, dwell_time_s=math.inf, proven=False, P=(),
                            recheck=Recheck(method="none", passed=False, detail="a mode is not Hurwitz"),
                            solver="not run", finding="no dwell time can stabilise: a mode is not Hurwitz")
    hi, ps_hi, status = 1.0, None, ""
    for _ in range(max_doublings):
        ps_hi, status = attempt(hi)
        if ps_hi is not None:
            break
        hi *= 2.0
    if ps_hi is None:
        return DwellTimeLMI(names=labels, dwell_time_s=math.inf, proven=False, P=(),
                            recheck=Recheck(method="float64 eigenvalues of the residuals", passed=False,
                                            detail=f"infeasible up to T = {hi / scale:.3g} s"),
                            solver=status, finding=f"no dwell time up to {hi / scale:.3g} s is certified")
    lo = 0.0
    while hi - lo > rel_tol * hi:
        mid = 0.5 * (lo + hi)
        ps, st = attempt(mid)
        if ps is None:
            lo = mid
        else:
            hi, ps_hi, status = mid, ps, st
    frozen = []
    for p in ps_hi:
        p = 0.5 * (p + p.T)
        p.setflags(write=False)
        frozen.append(p)
    t_s = hi / scale
    return DwellTimeLMI(
        names=labels, dwell_time_s=float(t_s), proven=True, P=tuple(frozen),
        recheck=Recheck(method="float64 eigenvalues of the LMI residuals (expm), margin 1e-6 on scaled data",
                        passed=True, detail=f"every residual <= -{_FLOAT_MARGIN:g} (the LMIs ask for -1)"),
        solver=status, finding=(f"every switching signal that dwells >= {t_s:.4g} s in each mode is stable "
                                "(proven: mode-dependent Lyapunov functions, Geromel–Colaneri)"))
