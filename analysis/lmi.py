"""Lyapunov certificates of switched linear systems by linear matrix inequalities, re-checked outside the solver.

A switched linear system ``ẋ = A_σ(t) x`` has modes ``A_1 … A_m`` (each ``(n, n)``, [1/s]).  Every
certificate below is computed by a semidefinite-programming solver (cvxpy: Clarabel, SCS when
Clarabel fails numerically) and then **re-checked outside the solver**; only a re-checked answer
is reported as proven.

Common quadratic Lyapunov function (Boyd, El Ghaoui, Feron & Balakrishnan, *Linear Matrix
Inequalities in System and Control Theory*, SIAM 1994, ch. 5: quadratic stability)
    ``V = xᵀPx`` with ``P ≻ 0`` and ``A_iᵀP + PA_i ≺ 0`` for every ``i`` proves global exponential
    stability under *arbitrary* switching.  The conditions are homogeneous in ``P`` and invariant
    under a positive scaling of each ``A_i``, so the solver sees ``Ã_i = A_i/‖A_i‖₂`` and the bounded
    program ``max ε`` s.t. ``εI ⪯ P ⪯ I``, ``Ã_iᵀP + PÃ_i ⪯ −εI``: a strict solution exists iff
    ``ε* > 0``, and the bound ``P ⪯ I`` keeps ``P`` well conditioned (``κ(P) ≤ 1/ε*``).

Its absence, proven (a theorem of alternatives for LMIs, Boyd et al. ch. 2)
    If ``Z_1 … Z_m ⪰ 0``, not all zero, satisfy ``Σ_i (A_iZ_i + Z_iA_iᵀ) ⪰ 0``, no such ``P``
    exists.  Proof: for a feasible ``P``, by ``tr(XY) = tr(YX)``,
    ``tr(P Σ_i(A_iZ_i + Z_iA_iᵀ)) = Σ_i tr((A_iᵀP + PA_i) Z_i)``; each term is the inner product of
    a negative definite matrix with a positive semidefinite one, so ``≤ 0``, and ``< 0`` for a
    non-zero ``Z_i``: the sum is negative.  The left side is the inner product of ``P ≻ 0`` with a
    positive semidefinite matrix, so ``≥ 0``: a contradiction.  (Conversely, if no strict ``P``
    exists such ``Z_i`` exist: the cone of the ``(P, −A_iᵀP − PA_i)`` misses the interior of the
    semidefinite cone and a separating hyperplane gives them.)  The program solved is
    ``max t`` s.t. ``Z_i ⪰ 0``, ``Σ tr Z_i = 1``, ``Σ(Ã_iZ_i + Z_iÃ_iᵀ) ⪰ tI``; ``t > 0`` is a
    certificate with room for round-off.  When no strict certificate exists (``t* = 0``, e.g. a
    common stable direction), absence may still be proven by the rank-one case: weights
    ``w_i ≥ 0`` with ``Σ w_iA_i`` not Hurwitz (``Z_i = w_i·Re(vv*)`` for an eigenvector ``v`` with
    ``Re λ ≥ 0``; equivalently a common ``P`` would be a Lyapunov matrix of the combination), decided
    by :func:`analysis.exact.is_hurwitz`.

Re-check (:mod:`analysis.exact`)
    The user's float data and the solver's float answer are converted to rationals *exactly*, and
    the definiteness of every matrix of the certificate is decided by exact ``LDLᵀ`` (Sylvester)
    pivots.  The solver's answer is first *repaired* where it is slightly off the cone: ``P`` is
    symmetrised (and scaled to trace 1); each ``Z_i`` is symmetrised, its negative eigenvalues are
    clipped to zero, and it is shifted by ``δI`` with ``δ = t/(4 Σ‖Ã_i + Ã_iᵀ‖₂)``: the shift changes
    ``Σ(Ã_iZ_i + Z_iÃ_iᵀ)`` by ``δΣ(Ã_i + Ã_iᵀ)``, of norm at most ``t/4``, so a margin ``t``
    certificate stays one with margin ``≥ 3t/4`` while every ``Z_i`` becomes positive definite; then
    ``Z_i/‖A_i‖₂`` is the certificate of the unscaled ``A_i``, normalised to ``Σ tr Z_i = 1``.  The
    repair is a heuristic only; soundness comes from the exact test of the *repaired* matrices,
    which are certificates in their own right (they are what the result stores).  The certified
    margins are exact too: ``A_iᵀP + PA_i + αP ≺ 0`` for the reported ``α`` (``V̇ ≤ −αV``), and
    ``Σ(A_iZ_i + Z_iA_iᵀ) ⪰ t·(Σ tr Z_i)·I`` for the reported ``t``.  Any other outcome (solver
    failure, inaccurate answer, margin below the solver's accuracy: a borderline family) is
    ``"undecided"`` with the reason; failing to find ``P`` is never reported as a proof.

Dwell time (Geromel & Colaneri, *Stability and stabilization of continuous-time switched linear
systems*, SIAM J. Control Optim. 45(5), 2006)
    If ``P_i ≻ 0``, ``A_iᵀP_i + P_iA_i ≺ 0`` and ``e^{A_iᵀT} P_j e^{A_iT} − P_i ≺ 0`` for all ``i ≠ j``,
    every switching signal that stays at least ``T`` in each mode is globally asymptotically
    stable: ``V_σ`` decreases inside a mode, and at a switch after ``τ ≥ T`` in mode ``i``,
    ``e^{A_iᵀτ}P_je^{A_iτ} ≺ e^{A_iᵀ(τ−T)}P_ie^{A_i(τ−T)} ⪯ P_i``.  The same argument shows feasibility
    is monotone in ``T``, so the smallest certified ``T`` is found by bisection, each step an LMI.
    ``e^{AT}`` is not rational: this re-check computes the eigenvalues of the residual matrices in
    float64 (``scipy.linalg.expm``) and requires each to clear a stated floating-point error bound
    ten times over (:func:`recheck_dwell_time`).

Piecewise quadratic Lyapunov functions (Johansson & Rantzer, *Computation of piecewise quadratic
Lyapunov functions for hybrid systems*, IEEE TAC 43(4), 1998)
    State-dependent switching of linear modes through the origin: cell ``i`` is the polyhedral cone
    ``{x : E_ix ≥ 0}`` with ``ẋ = A_ix`` there, and the cells partition ``ℝⁿ``.  ``V = xᵀP_ix`` on cell
    ``i`` with, by the S-procedure (``U_i, W_i`` symmetric, elementwise ``≥ 0``, zero diagonal, so
    ``xᵀE_iᵀU_iE_ix ≥ 0`` on the cell), ``P_i − E_iᵀU_iE_i ≻ 0`` (``V > 0`` on the cell) and
    ``A_iᵀP_i + P_iA_i + E_iᵀW_iE_i ≺ 0`` (``V̇ < 0`` there), and ``V`` continuous across every shared
    boundary ``hᵀx = 0``: ``Nᵀ(P_i − P_j)N = 0`` for a basis ``N`` of ``h^⊥`` (equivalently
    ``P_i − P_j = hgᵀ + ghᵀ`` for some ``g``).  Continuity is imposed *exactly*: the ``P_i`` are
    parametrised by an exact rational basis of the continuity subspace
    (:func:`analysis.exact.nullspace`), so the rational ``P_i`` rebuilt from the solver's
    coefficients satisfy it with no round-off.  The certificate covers solutions that cross the
    boundaries (no sliding motion along a boundary).

Examples
--------
>>> import numpy as np
>>> r = common_quadratic_lyapunov_lmi([np.array([[-1.0, 2.0], [0.0, -1.0]]), np.array([[-1.0, 0.0], [1.0, -2.0]])])
>>> r.status, r.proven, r.recheck.passed
('exists', True, True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from analysis import exact
from analysis.exact import RationalMatrix
from analysis.lmi_core import (
    Boundary,
    CommonLyapunovLMI,
    DWELL_STATUSES,
    DwellTimeLMI,
    EXACT_METHOD,
    LMI_STATUSES,
    LinearCell,
    LmiError,
    MARGIN_DISCOUNTS,
    PiecewiseQuadraticLMI,
    Recheck,
    SOLVERS,
    SolverRun,
    certified_rate,
    checked_family,
    checked_matrix,
    checked_names,
    checked_solvers,
    dual_alternative,
    exact_lie,
    failure_text,
    frozen_copy,
    primal_lyapunov,
    rate_text,
    repaired_dual,
    solve_first,
    symmetrised,
)

__all__ = [
    "LmiError",
    "SolverRun",
    "Recheck",
    "CommonLyapunovLMI",
    "DwellTimeLMI",
    "LinearCell",
    "Boundary",
    "PiecewiseQuadraticLMI",
    "common_quadratic_lyapunov_lmi",
    "recheck_common_lyapunov",
    "recheck_no_common_lyapunov",
    "dwell_time_lyapunov",
    "recheck_dwell_time",
    "piecewise_quadratic_lyapunov",
    "recheck_piecewise_quadratic",
    "planted_common_lyapunov",
    "planted_no_common_lyapunov",
    "LMI_STATUSES",
    "DWELL_STATUSES",
    "SOLVERS",
]

_DWELL_MIN_EPSILON = 1e-7
"""A dwell-time LMI counts as feasible when its margin ``ε*`` exceeds this (the solver's accuracy ~1e-8)."""
_DWELL_SAFETY = 10.0
"""Dwell-time re-check: each residual must clear its floating-point error bound this many times."""
_EXPM_RELATIVE_ERROR = 1e-12
"""Assumed relative accuracy of ``scipy.linalg.expm`` (scaling and squaring, moderate ``‖AT‖``)."""
_MULTIPLIER_BOUND = 1e4
"""Upper bound on the S-procedure multipliers ``U_i, W_i`` (keeps the program bounded)."""
_UNIT_ROUNDOFF = 2.0**-53


# ----------------------------------------------------------------------------------------- exact re-checks


def recheck_common_lyapunov(family: Sequence[Any], P: Any) -> Recheck:
    """Exactly: ``P ≻ 0`` and ``A_iᵀP + PA_i ≺ 0`` for every member, on the float data converted exactly.

    Parameters
    ----------
    family : sequence of array_like, each shape (n, n)
    P : array_like, shape (n, n)
        Must be exactly symmetric (symmetrise with ``(P + P.T)/2`` in floats).

    Returns
    -------
    Recheck
        ``margin``: the certified ``α`` [1/s] with ``A_iᵀP + PA_i + αP ≺ 0`` (``V̇ ≤ −αV``).

    Raises
    ------
    LmiError
        Bad shapes or non-finite entries.
    """
    from scipy.linalg import eigh

    mats = checked_family(family)
    p_float = checked_matrix(P, "P")
    if p_float.shape != mats[0].shape:
        raise LmiError("P", p_float.shape, f"shape {mats[0].shape} like the family", "give an n×n matrix")
    p = exact.as_rational(p_float)
    if not p.is_symmetric():
        return Recheck(method=EXACT_METHOD, passed=False, detail="P is not symmetric")
    test = exact.pivot_test(p)
    if not test.positive_definite:
        return Recheck(method=EXACT_METHOD, passed=False,
                       detail=f"P is not positive definite (pivot {test.failed_at} is {test.smallest_pivot:.3g})")
    lies = []
    for i, a in enumerate(mats):
        lie = exact_lie(exact.as_rational(a), p)
        test = exact.pivot_test(-lie)
        if not test.positive_definite:
            return Recheck(method=EXACT_METHOD, passed=False,
                           detail=f"A_{i}ᵀP + PA_{i} is not negative definite (pivot {test.failed_at} of its "
                                  f"negative is {test.smallest_pivot:.3g})")
        lies.append(lie)
    estimate = min(float(eigh(-(a.T @ p_float + p_float @ a), p_float, eigvals_only=True).min()) for a in mats)
    alpha = certified_rate(lies, p, estimate)
    return Recheck(method=EXACT_METHOD, passed=True, margin=alpha,
                   detail=f"P ≻ 0 and A_iᵀP + PA_i + αP ≺ 0 with α = {alpha:.6g} 1/s for all {len(mats)} "
                          "members, in exact arithmetic")


def recheck_no_common_lyapunov(family: Sequence[Any], dual: Sequence[Any]) -> Recheck:
    """Exactly: every ``Z_i ⪰ 0``, ``Σ tr Z_i > 0`` and ``Σ(A_iZ_i + Z_iA_iᵀ) ⪰ 0`` (the alternative).

    Parameters
    ----------
    family : sequence of array_like, each shape (n, n)
    dual : sequence of array_like, one ``Z_i`` per member, each shape (n, n), exactly symmetric

    Returns
    -------
    Recheck
        ``margin``: the certified ``t`` [1/s] with ``Σ(A_iZ_i + Z_iA_iᵀ) ⪰ t·(Σ tr Z_i)·I``
        (``0`` when only ``⪰ 0`` re-checks, which is still a proof).
    """
    method = "exact rational LDLᵀ / inertia of the alternative certificate on the float data"
    mats = checked_family(family)
    zs_float = checked_family(dual, "dual")
    if len(zs_float) != len(mats) or zs_float[0].shape != mats[0].shape:
        raise LmiError("dual", [z.shape for z in zs_float], f"{len(mats)} matrices of shape {mats[0].shape}",
                       "give one Z_i per member")
    zs = [exact.as_rational(z) for z in zs_float]
    for i, z in enumerate(zs):
        if not exact.is_positive_semidefinite(z):
            return Recheck(method=method, passed=False, detail=f"Z_{i} is not positive semidefinite")
    tau = sum((z.trace() for z in zs), Fraction(0))
    if tau <= 0:
        return Recheck(method=method, passed=False, detail="every Z_i is zero")
    total = None
    for a, z in zip(mats, zs):
        ar = exact.as_rational(a)
        term = ar @ z + z @ ar.T
        total = term if total is None else total + term
    t_float = float(np.linalg.eigvalsh(sum(a @ z + z @ a.T for a, z in zip(mats, zs_float))).min()) / float(tau)
    eye = RationalMatrix.identity(mats[0].shape[0]).scaled(tau)
    for t in ([t_float * f for f in MARGIN_DISCOUNTS] if t_float > 0 else []):
        if exact.is_positive_definite(total - eye.scaled(float(t))):
            return Recheck(method=method, passed=True, margin=float(t),
                           detail=f"Z_i ⪰ 0 and Σ(A_iZ_i + Z_iA_iᵀ) ⪰ t·(Σ tr Z_i)·I with t = {float(t):.6g} "
                                  "1/s, in exact arithmetic: no common P can exist")
    if exact.is_positive_semidefinite(total):
        return Recheck(method=method, passed=True, margin=0.0,
                       detail="Z_i ⪰ 0, not all zero, and Σ(A_iZ_i + Z_iA_iᵀ) ⪰ 0 in exact arithmetic: "
                              "no common P")
    return Recheck(method=method, passed=False, detail="Σ(A_iZ_i + Z_iA_iᵀ) is not positive semidefinite")


# ----------------------------------------------------------------------------------------- absence by a witness


def _abscissa(mats: Sequence[np.ndarray], w: np.ndarray) -> float:
    return float(np.linalg.eigvals(sum(wi * a for wi, a in zip(w, mats))).real.max())


def _witness_candidates(scaled: list[np.ndarray], zs: list[np.ndarray] | None) -> list[np.ndarray]:
    """Weights on the scaled members: the dual's traces, each pair on a grid, each vertex."""
    m = len(scaled)
    out = [np.eye(m)[i] for i in range(m)]
    if zs is not None:
        w = np.array([max(0.0, float(np.trace(z))) for z in zs])
        if w.sum() > 0:
            out.append(w / w.sum())
    for i in range(m):
        for j in range(i + 1, m):
            for s in np.linspace(0.05, 0.95, 19):
                w = np.zeros(m)
                w[i], w[j] = s, 1.0 - s
                out.append(w)
    return out


def _unstable_combination(mats: list[np.ndarray], scales: np.ndarray,
                          zs: list[np.ndarray] | None) -> np.ndarray | None:
    """Weights ``w ≥ 0`` (on the unscaled members) with ``Σ w_iA_i`` not Hurwitz exactly, or ``None``."""
    from scipy.optimize import minimize

    scaled = [a / c for a, c in zip(mats, scales)]
    best = max(_witness_candidates(scaled, zs), key=lambda w: _abscissa(scaled, w))
    if _abscissa(scaled, best) < 0:
        def objective(z: np.ndarray) -> float:
            w = np.exp(z - z.max())
            return -_abscissa(scaled, w / w.sum())

        res = minimize(objective, np.log(np.maximum(best, 1e-3)), method="Nelder-Mead",
                       options={"maxiter": 200 * len(mats), "xatol": 1e-8, "fatol": 1e-12})
        w = np.exp(res.x - res.x.max())
        best = w / w.sum()
    if _abscissa(scaled, best) < -1e-12:
        return None
    weights = best / scales
    total = None
    for a, w in zip(mats, weights):
        term = exact.as_rational(a).scaled(float(w))
        total = term if total is None else total + term
    return None if exact.is_hurwitz(total) else weights


# ----------------------------------------------------------------------------------------- part 1


def common_quadratic_lyapunov_lmi(family: Sequence[Any], names: Sequence[str] | None = None, *,
                                  solver: str | Sequence[str] | None = None) -> CommonLyapunovLMI:
    """Decide whether ``P ≻ 0`` with ``A_iᵀP + PA_i ≺ 0`` for all members exists (module docstring).

    Parameters
    ----------
    family : sequence of array_like, each shape (n, n)
        The modes ``A_i`` [1/s].
    names : sequence of str or None
        One per member (``A0, A1, …`` by default).
    solver : str, sequence of str or None
        cvxpy solver name(s) tried in order (default :data:`SOLVERS`).

    Returns
    -------
    CommonLyapunovLMI
        ``"exists"`` with ``P`` or ``"none"`` with a certificate, both re-checked exactly, or
        ``"undecided"`` with the reason.  Solver exceptions become ``"undecided"``.

    Raises
    ------
    LmiError
        An empty family, a non-square, non-finite or mismatched matrix, names of the wrong length.
    """
    mats = checked_family(family)
    labels = checked_names(names, len(mats), "A")
    solvers = checked_solvers(solver)
    scales = np.array([float(np.linalg.norm(a, 2)) or 1.0 for a in mats])
    scaled = [a / c for a, c in zip(mats, scales)]  # positive scaling of a member changes nothing
    reasons = []
    p, eps, runs = primal_lyapunov(scaled, solvers)
    if p is not None and eps > 0:
        p = symmetrised(p)
        p = frozen_copy(symmetrised(p / np.trace(p)))
        check = recheck_common_lyapunov(mats, p)
        if check.passed:
            return CommonLyapunovLMI(
                names=labels, status="exists", proven=True, P=p, dual=None, witness_weights=None,
                margin=check.margin, recheck=check, solver=runs,
                finding=(f"a common quadratic Lyapunov function exists (proven exactly): V = xᵀPx decreases in every "
                         f"mode, {rate_text(check.margin)}: exponentially stable under arbitrary switching"))
        reasons.append(f"the primal P (solver margin {eps:.3g}) fails the exact re-check: {check.detail}")
    else:
        reasons.append(failure_text("the primal", runs) if p is None else f"the primal margin is {eps:.3g} <= 0")
    zs, t, dual_runs = dual_alternative(scaled, solvers)
    runs = runs + dual_runs
    if zs is not None and t > 0:
        repaired = repaired_dual(scaled, zs, t, scales)
        check = recheck_no_common_lyapunov(mats, repaired)
        if check.passed:
            return CommonLyapunovLMI(
                names=labels, status="none", proven=True, P=None, dual=repaired, witness_weights=None,
                margin=check.margin, recheck=check, solver=runs,
                finding=("no common quadratic Lyapunov function exists (proven by a dual certificate re-checked "
                         "exactly): stability under arbitrary switching needs another argument (dwell time, "
                         "state-dependent switching)"))
        reasons.append(f"the dual certificate (solver margin {t:.3g}) fails the exact re-check: {check.detail}")
    else:
        reasons.append(failure_text("the alternative", dual_runs) if zs is None else f"the dual margin is {t:.3g} <= 0")
    weights = _unstable_combination(mats, scales, zs)
    if weights is not None:
        abscissa = _abscissa(mats, weights)
        text = " + ".join(f"{w:.4g}·{name}" for w, name in zip(weights, labels) if w > 0)
        check = Recheck(method="exact Routh–Hurwitz test of the rational combination Σ w_i A_i", passed=True,
                        margin=abscissa, detail=f"{text} is not Hurwitz (float spectral abscissa {abscissa:.4g} "
                                                "1/s); a common P would be a Lyapunov matrix of it")
        return CommonLyapunovLMI(
            names=labels, status="none", proven=True, P=None, dual=None,
            witness_weights=tuple(float(w) for w in weights), margin=abscissa, recheck=check, solver=runs,
            finding=f"no common quadratic Lyapunov function exists (proven exactly: {text} is not Hurwitz)")
    why = "; ".join(reasons)
    cause = ("a solver failed" if any(r.status == "error" for r in runs)
             else "the family is at the border of the solvers' accuracy")
    return CommonLyapunovLMI(
        names=labels, status="undecided", proven=False, P=None, dual=None, witness_weights=None, margin=math.nan,
        recheck=Recheck(method=EXACT_METHOD, passed=False, detail=why), solver=runs,
        finding=f"undecided: neither a common quadratic Lyapunov function nor a proof of its absence re-checks "
                f"({why}); {cause}")


# ----------------------------------------------------------------------------------------- part 2: dwell time


def _baseline_dwell(mats: list[np.ndarray]) -> float:
    """``ln μ / λ0`` from ``A_iᵀP_i + P_iA_i = −I``.

    ``μ = max λmax(P_i)/λmin(P_j)``, ``λ0 = min 1/λmax(P_i)``: the formula of
    :func:`analysis.linearise.common_quadratic_lyapunov`.
    """
    from scipy.linalg import solve_continuous_lyapunov

    n = mats[0].shape[0]
    eigs = [np.linalg.eigvalsh(symmetrised(solve_continuous_lyapunov(a.T, -np.eye(n)))) for a in mats]
    if any(e.min() <= 0 for e in eigs):
        return math.inf
    mu = max(ei.max() / ej.min() for ei in eigs for ej in eigs)
    lambda0 = min(1.0 / e.max() for e in eigs)
    return float(math.log(mu) / lambda0) if mu > 1 else 0.0


def _dwell_lmi(scaled: list[np.ndarray], expms: list[np.ndarray], solvers: Sequence[str],
               label: str) -> tuple[list[np.ndarray] | None, float, tuple[SolverRun, ...]]:
    """``max ε``: ``εI ⪯ P_i ⪯ I``, ``ÃᵢᵀP_i + P_iÃ_i ⪯ −εI``, ``e^{A_iᵀT}P_je^{A_iT} − P_i ⪯ −εI`` (``i ≠ j``).

    ``expms`` are the ``e^{A_iT}`` of the unscaled modes (the time scale is the user's).
    """
    import cvxpy as cp

    n, m = scaled[0].shape[0], len(scaled)
    eye = np.eye(n)
    ps = [cp.Variable((n, n), symmetric=True) for _ in range(m)]
    eps = cp.Variable()
    cons = [c for p in ps for c in (p << eye, p >> eps * eye)]
    cons += [a.T @ p + p @ a << -eps * eye for a, p in zip(scaled, ps)]
    cons += [e.T @ ps[j] @ e - ps[i] << -eps * eye for i, e in enumerate(expms) for j in range(m) if j != i]
    values, runs = solve_first(cp.Problem(cp.Maximize(eps), cons), [*ps, eps], solvers, label)
    if values is None:
        return None, math.nan, runs
    return values[:-1], float(values[-1]), runs


def recheck_dwell_time(family: Sequence[Any], P: Sequence[Any], dwell_time_s: float) -> Recheck:
    """Float64 re-check of the Geromel–Colaneri LMIs at ``T = dwell_time_s``, with a stated error bound.

    ``e^{AT}`` is irrational, so no exact test applies.  Each residual ``R`` (``P_i``,
    ``A_iᵀP_i + P_iA_i``, ``e^{A_iᵀT}P_je^{A_iT} − P_i``) is formed in float64 with
    ``scipy.linalg.expm`` and its extreme eigenvalue (``numpy.linalg.eigvalsh``) must lie beyond
    ``10·β(R)`` on the right side of zero, where ``β`` bounds the floating-point error: with
    ``u = 2⁻⁵³`` and ``γ = nu/(1 − nu)``, a product ``XY`` is off by at most ``nγ‖X‖‖Y‖`` in norm,
    ``expm`` is assumed accurate to ``η = 1e-12·(1 + ‖AT‖₁)`` relative, and ``eigvalsh`` to
    ``4nu‖R‖``; so ``β(P) = 4nu‖P‖``, ``β(AᵀP + PA) = 2nγ‖A‖‖P‖ + 5nu‖R‖`` and
    ``β(EᵀP_jE − P_i) = (2nγ + 2η)‖E‖²‖P_j‖ + 5nu(‖R‖ + ‖P_i‖)``.  A model bound, not interval
    arithmetic: say so when you cite the result.

    Parameters
    ----------
    family : sequence of array_like, each shape (n, n)
    P : sequence of array_like, one exactly symmetric ``P_i`` per member
    dwell_time_s : float
        ``T`` [s], finite and ``>= 0``.

    Returns
    -------
    Recheck
        ``margin``: the smallest factor by which a residual clears its bound (``>= 10`` to pass).
    """
    from scipy.linalg import expm

    mats = checked_family(family)
    ps = checked_family(P, "P")
    if len(ps) != len(mats) or ps[0].shape != mats[0].shape:
        raise LmiError("P", [p.shape for p in ps], f"{len(mats)} matrices of shape {mats[0].shape}",
                       "give one P_i per mode")
    if isinstance(dwell_time_s, bool) or not isinstance(dwell_time_s, (int, float)) or not (
            math.isfinite(dwell_time_s) and dwell_time_s >= 0):
        raise LmiError("dwell_time_s", dwell_time_s, "a finite number >= 0 [s]", "give the dwell time T")
    n = mats[0].shape[0]
    u = _UNIT_ROUNDOFF
    gamma = n * u / (1 - n * u)
    method = ("float64 eigenvalues of the LMI residuals (scipy.linalg.expm, numpy.linalg.eigvalsh), each "
              f"clearing {_DWELL_SAFETY:g}× a stated rounding-error bound; not exact (e^(AT) is irrational)")
    ratios = []

    def clears(name: str, value: float, bound: float) -> str | None:
        """``value`` is the signed distance from zero on the good side; ``None`` when it clears ``10·bound``."""
        ratios.append(value / bound if bound > 0 else math.inf)
        if value > _DWELL_SAFETY * bound:
            return None
        return f"{name}: {value:.3g} does not clear {_DWELL_SAFETY:g}×{bound:.3g}"

    for i, (a, p) in enumerate(zip(mats, ps)):
        if not np.array_equal(p, p.T):
            return Recheck(method=method, passed=False, detail=f"P_{i} is not symmetric")
        norm_p = float(np.linalg.norm(p, 2))
        fail = clears(f"λmin(P_{i})", float(np.linalg.eigvalsh(p).min()), 4 * n * u * norm_p)
        lie = a.T @ p + p @ a
        bound = 2 * n * gamma * float(np.linalg.norm(a, 2)) * norm_p + 5 * n * u * float(np.linalg.norm(lie, 2))
        fail = fail or clears(f"−λmax(A_{i}ᵀP_{i} + P_{i}A_{i})", -float(np.linalg.eigvalsh(lie).max()), bound)
        e = expm(a * float(dwell_time_s))
        eta = _EXPM_RELATIVE_ERROR * (1.0 + float(np.linalg.norm(a * float(dwell_time_s), 1)))
        norm_e2 = float(np.linalg.norm(e, 2)) ** 2
        for j, q in enumerate(ps):
            if j == i or fail:
                continue
            r = e.T @ q @ e - p
            bound = ((2 * n * gamma + 2 * eta) * norm_e2 * float(np.linalg.norm(q, 2))
                     + 5 * n * u * (float(np.linalg.norm(r, 2)) + norm_p))
            fail = clears(f"−λmax(e^(A_{i}ᵀT)P_{j}e^(A_{i}T) − P_{i})", -float(np.linalg.eigvalsh(r).max()),
                          bound)
        if fail:
            return Recheck(method=method, passed=False, detail=fail, margin=min(ratios))
    return Recheck(method=method, passed=True, margin=min(ratios),
                   detail=(f"at T = {dwell_time_s:.6g} s every residual clears its error bound at least "
                           f"{min(ratios):.3g} times (>= {_DWELL_SAFETY:g} required)"))


def _dwell_result(labels: tuple[str, ...], status: str, **fields: Any) -> DwellTimeLMI:
    defaults: dict[str, Any] = {"proven": False, "dwell_time_s": math.inf, "lower_bound_s": math.nan,
                                "baseline_dwell_time_s": math.nan, "P": (), "solver": (), "solves": 0}
    defaults.update(fields)
    return DwellTimeLMI(names=labels, status=status, **defaults)


@dataclass(frozen=True, slots=True)
class _DwellSearch:
    """Outcome of :func:`_dwell_search`: the bracket ``(lo, hi]``, the certified ``(P_i, recheck)`` at ``hi``."""

    lo: float
    hi: float
    best: tuple[tuple[np.ndarray, ...], Recheck] | None
    runs: tuple[SolverRun, ...]
    solves: int


def _dwell_search(mats: Sequence[np.ndarray], solvers: tuple[str, ...], baseline: float, rel_tol: float,
                  max_doublings: int) -> _DwellSearch:
    """Double ``T`` from the baseline until certified, then bisect towards 0 (see :func:`dwell_time_lyapunov`)."""
    from scipy.linalg import expm

    scale = max(float(np.linalg.norm(a, 2)) for a in mats)
    scaled = [a / scale for a in mats]
    solves = 0

    def attempt(t: float) -> tuple[tuple[tuple[np.ndarray, ...], Recheck] | None, tuple[SolverRun, ...]]:
        nonlocal solves
        solves += 1
        ps, eps, runs = _dwell_lmi(scaled, [expm(a * t) for a in mats], solvers, f"dwell T={t:.6g}")
        if ps is None or not eps > _DWELL_MIN_EPSILON:
            return None, runs
        ps = tuple(frozen_copy(symmetrised(p)) for p in ps)
        check = recheck_dwell_time(mats, ps, t)
        return ((ps, check) if check.passed else None), runs

    lo, hi = 0.0, baseline * (1.0 + rel_tol) if 0.0 < baseline < math.inf else 1.0 / scale
    found, runs = attempt(hi)
    for _ in range(max_doublings):
        if found is not None:
            break
        lo, hi = hi, 2.0 * hi
        found, runs = attempt(hi)
    if found is None:
        return _DwellSearch(lo=lo, hi=hi, best=None, runs=runs, solves=solves)
    best, best_runs = found, runs
    while hi - lo > rel_tol * hi:
        mid = 0.5 * (lo + hi)
        found, runs = attempt(mid)
        if found is None:
            lo = mid
        else:
            hi, best, best_runs = mid, found, runs
    return _DwellSearch(lo=lo, hi=hi, best=best, runs=best_runs, solves=solves)


def dwell_time_lyapunov(family: Sequence[Any], names: Sequence[str] | None = None, *, rel_tol: float = 1e-3,
                        max_doublings: int = 20, solver: str | Sequence[str] | None = None) -> DwellTimeLMI:
    """The smallest dwell time certified by the Geromel–Colaneri LMIs, by bisection (module docstring).

    Order of the analysis: a mode that is not Hurwitz (exactly, Routh–Hurwitz) gives
    ``"unstable_mode"``; a common quadratic Lyapunov function (:func:`common_quadratic_lyapunov_lmi`)
    gives ``"arbitrary"`` with dwell time 0; otherwise the LMIs are solved at the baseline
    ``ln μ/λ0`` (where the modes' own Lyapunov functions satisfy them strictly, so the result does not
    exceed it unless that solve fails), doubled until certified, then bisected towards 0 until the
    bracket is below ``rel_tol`` of ``T``.  Each step is certified only when the solver's margin
    exceeds ``1e-7`` and :func:`recheck_dwell_time` passes; a step that is not only narrows the search
    (the reported ``T`` is always a certified one).

    Parameters
    ----------
    family : sequence of array_like, each shape (n, n)
    names : sequence of str or None
    rel_tol : float
        Relative width of the final bisection bracket, in ``(0, 1)``.
    max_doublings : int
        How often ``T`` may double when the baseline is not certified.
    solver : str, sequence of str or None
        As :func:`common_quadratic_lyapunov_lmi`.

    Raises
    ------
    LmiError
        As :func:`common_quadratic_lyapunov_lmi`, or ``rel_tol`` / ``max_doublings`` out of range.
    """
    mats = checked_family(family)
    labels = checked_names(names, len(mats), "A")
    solvers = checked_solvers(solver)
    if isinstance(rel_tol, bool) or not isinstance(rel_tol, (int, float)) or not 0.0 < rel_tol < 1.0:
        raise LmiError("rel_tol", rel_tol, "a number in (0, 1)", "give e.g. rel_tol=1e-3")
    if isinstance(max_doublings, bool) or not isinstance(max_doublings, int) or max_doublings < 0:
        raise LmiError("max_doublings", max_doublings, "an integer >= 0", "give e.g. max_doublings=20")
    unstable = [name for a, name in zip(mats, labels) if not exact.is_hurwitz(a)]
    if unstable:
        return _dwell_result(labels, "unstable_mode", proven=True, recheck=Recheck(
            method="exact Routh–Hurwitz test of each mode", passed=True, detail=f"not Hurwitz: {unstable}"),
            finding=f"no dwell time makes the system stable: mode(s) {unstable} are not Hurwitz (exactly)")
    baseline = _baseline_dwell(mats)
    common = common_quadratic_lyapunov_lmi(mats, labels, solver=solvers)
    if common.status == "exists":
        return _dwell_result(labels, "arbitrary", proven=True, dwell_time_s=0.0, lower_bound_s=0.0,
                             baseline_dwell_time_s=baseline, P=(common.P,) * len(mats), recheck=common.recheck,
                             solver=common.solver, finding="dwell time 0: a common quadratic Lyapunov function "
                                                          "exists, stable under arbitrary switching")
    search = _dwell_search(mats, solvers, baseline, rel_tol, max_doublings)
    lo, hi, solves = search.lo, search.hi, search.solves
    if search.best is None:
        return _dwell_result(labels, "undecided", lower_bound_s=hi, baseline_dwell_time_s=baseline,
                             solver=search.runs, solves=solves,
                             recheck=Recheck(method="float64 residual eigenvalues", passed=False,
                                             detail=f"no T <= {hi:.4g} s certified"),
                             finding=f"undecided: the dwell-time LMIs are not certified for any T <= {hi:.4g} s")
    best, best_runs = search.best, search.runs
    ps, check = best
    return _dwell_result(
        labels, "certified", proven=True, dwell_time_s=float(hi), lower_bound_s=float(lo),
        baseline_dwell_time_s=baseline, P=ps, recheck=check, solver=best_runs, solves=solves,
        finding=(f"every switching signal that stays at least {hi:.4g} s in each mode is stable (Geromel–Colaneri "
                 f"LMIs re-checked in float64; the modes' own Lyapunov functions give {baseline:.4g} s; no common "
                 f"quadratic Lyapunov function: {common.status})"))


# ----------------------------------------------------------------------------------------- part 3: piecewise quadratic


def _cells(cells: Any) -> tuple[list[np.ndarray], list[np.ndarray], tuple[str, ...]]:
    if isinstance(cells, (str, bytes)) or not hasattr(cells, "__len__") or len(cells) == 0:
        raise LmiError("cells", "empty" if hasattr(cells, "__len__") else type(cells).__name__,
                       "a non-empty sequence of LinearCell(A=..., E=...) or pairs (A, E)", "give one cell per region")
    mats, es, labels = [], [], []
    for k, cell in enumerate(cells):
        if isinstance(cell, LinearCell):
            a, e, name = cell.A, cell.E, cell.name
        elif isinstance(cell, (tuple, list)) and len(cell) in (2, 3):
            a, e, name = cell[0], cell[1], (cell[2] if len(cell) == 3 else None)
        else:
            raise LmiError(f"cells[{k}]", type(cell).__name__, "a LinearCell(A=..., E=...) or a pair (A, E)",
                           "describe the cell by its matrix A and its cone {x : E x >= 0}")
        a = checked_matrix(a, f"cells[{k}].A")
        n = mats[0].shape[0] if mats else a.shape[0]
        if a.shape != (n, n):
            raise LmiError(f"cells[{k}].A", a.shape, f"shape ({n}, {n}) like cells[0].A",
                           "give every cell the same states")
        mats.append(a)
        es.append(checked_matrix(e, f"cells[{k}].E", columns=n))
        labels.append(f"cell{k}" if name is None else name)
    if not all(isinstance(s, str) for s in labels) or len(set(labels)) != len(labels):
        raise LmiError("cells names", tuple(labels), "distinct strings", "name every cell once")
    return mats, es, tuple(labels)


def _opposite(r: np.ndarray, q: np.ndarray) -> bool:
    """Exactly whether ``q = −c·r`` for some ``c > 0`` (``r ≠ 0``)."""
    fr, fq = [Fraction(float(x)) for x in r], [Fraction(float(x)) for x in q]
    if not any(fr):
        return False
    parallel = all(fr[a] * fq[b] == fr[b] * fq[a] for a in range(len(fr)) for b in range(a + 1, len(fr)))
    return parallel and sum(x * y for x, y in zip(fr, fq)) < 0


def _boundaries(boundaries: Any, es: list[np.ndarray], labels: tuple[str, ...],
                n: int) -> list[tuple[int, int, np.ndarray, bool]]:
    """``(i, j, h, derived)``: given, or every pair of cells with opposite rows (a superset: sound)."""
    if boundaries is None:
        out: list[tuple[int, int, np.ndarray, bool]] = []
        for i in range(len(es)):
            for j in range(i + 1, len(es)):
                for r in es[i]:
                    if any(_opposite(r, q) for q in es[j]) and not any(
                            b[:2] == (i, j) and (_opposite(r, -b[2])) for b in out):
                        out.append((i, j, np.array(r, dtype=float), True))
        return out
    if isinstance(boundaries, (str, bytes)) or not hasattr(boundaries, "__len__"):
        raise LmiError("boundaries", type(boundaries).__name__, "None or a sequence of (cell, cell, normal)",
                       "leave boundaries=None to derive them from the cells' E rows")
    out = []
    for k, item in enumerate(boundaries):
        if not isinstance(item, (tuple, list)) or len(item) != 3:
            raise LmiError(f"boundaries[{k}]", item, "a triple (cell, cell, normal h)", "give e.g. (0, 1, (1.0, 0.0))")
        ends = []
        for end in item[:2]:
            if isinstance(end, str) and end in labels:
                ends.append(labels.index(end))
            elif isinstance(end, (int, np.integer)) and not isinstance(end, bool) and 0 <= end < len(labels):
                ends.append(int(end))
            else:
                raise LmiError(f"boundaries[{k}]", end, f"a cell index 0..{len(labels) - 1} or a name in {labels}",
                               "name the two cells that share the boundary")
        h = np.array(item[2], dtype=float).reshape(-1) if np.ndim(item[2]) <= 1 else np.array([np.nan])
        if h.shape != (n,) or not np.all(np.isfinite(h)) or not np.any(h):
            raise LmiError(f"boundaries[{k}] normal", np.shape(item[2]), f"{n} finite numbers, not all zero",
                           "give the normal h of the hyperplane hᵀx = 0")
        if ends[0] == ends[1]:
            raise LmiError(f"boundaries[{k}]", item[:2], "two different cells", "name two neighbouring cells")
        out.append((ends[0], ends[1], h, False))
    return out


def _svec_index(n: int) -> dict[tuple[int, int], int]:
    return {pair: k for k, pair in enumerate((i, j) for i in range(n) for j in range(i, n))}


def _perp_basis(h: np.ndarray) -> list[list[Fraction]]:
    """Exact basis of ``h^⊥``: ``e_c − (h_c/h_p)e_p`` for ``c ≠ p``, ``p`` the largest ``|h_p|`` (ratios <= 1)."""
    hf = [Fraction(float(x)) for x in h]
    p = max(range(len(hf)), key=lambda k: abs(hf[k]))
    basis = []
    for col in (c for c in range(len(hf)) if c != p):
        v = [Fraction(0)] * len(hf)
        v[col], v[p] = Fraction(1), -hf[col] / hf[p]
        basis.append(v)
    return basis


def _continuity_basis(n: int, m: int,
                      bounds: list[tuple[int, int, np.ndarray, bool]]) -> tuple[tuple[Fraction, ...], ...]:
    """Exact basis of ``{(svec P_1, …, svec P_m) : N_eᵀ(P_i − P_j)N_e = 0 for every boundary e}``."""
    index = _svec_index(n)
    d = len(index)
    rows = []
    for i, j, h, _ in bounds:
        basis = _perp_basis(h)
        for a in range(len(basis)):
            for b in range(a, len(basis)):
                va, vb = basis[a], basis[b]
                row = [Fraction(0)] * (m * d)
                for (k, l), idx in index.items():
                    coef = va[k] * vb[l] + va[l] * vb[k] if k < l else va[k] * vb[k]
                    row[i * d + idx] += coef
                    row[j * d + idx] -= coef
                rows.append(row)
    return exact.nullspace(rows, m * d)


def _unpack(n: int) -> np.ndarray:
    """``D`` with ``vec(P) = D·svec(P)`` (row-major ``vec``), shape ``(n², n(n+1)/2)``."""
    index = _svec_index(n)
    d = np.zeros((n * n, len(index)))
    for (k, l), idx in index.items():
        d[k * n + l, idx] = d[l * n + k, idx] = 1.0
    return d


def _multiplier(e: np.ndarray, cons: list[Any]) -> tuple[Any, Any]:
    """An S-procedure multiplier ``V`` (symmetric, ``0 <= V <= bound``, zero diagonal) and ``EᵀVE``.

    A cell with fewer than two rows has none (``(E_kx)²`` is ``>= 0`` everywhere: no information).
    """
    import cvxpy as cp

    r, n = e.shape
    if r < 2:
        return None, np.zeros((n, n))
    v = cp.Variable((r, r), symmetric=True)
    cons += [v >= 0, v <= _MULTIPLIER_BOUND, cp.diag(v) == 0]
    return v, e.T @ v @ e


def _pwq_program(scaled: list[np.ndarray], es: list[np.ndarray], basis: np.ndarray,
                 solvers: Sequence[str]) -> tuple[Any, tuple[SolverRun, ...]]:
    """``max ε``: ``P_i − E_iᵀU_iE_i ⪰ εI``, ``ÃᵢᵀP_i + P_iÃ_i + E_iᵀW_iE_i ⪯ −εI``, ``P_i ⪯ I``, ``svec P = Kθ``

    Returns ``((θ, ε, U's, W's), runs)`` (a multiplier ``None`` for a cell with fewer than two rows).
    """
    import cvxpy as cp

    n = scaled[0].shape[0]
    d = n * (n + 1) // 2
    eye, unpack = np.eye(n), _unpack(n)
    q, r = np.linalg.qr(basis)  # orthonormal columns for the solver; θ = R⁻¹θ' for the exact rebuild
    theta, eps = cp.Variable(basis.shape[1]), cp.Variable()
    us, ws, cons = [], [], []
    for i, (a, e) in enumerate(zip(scaled, es)):
        p = cp.reshape((unpack @ q[i * d:(i + 1) * d]) @ theta, (n, n), order="C")
        p = 0.5 * (p + p.T)
        u, u_term = _multiplier(e, cons)
        w, w_term = _multiplier(e, cons)
        us.append(u)
        ws.append(w)
        cons += [p - u_term >> eps * eye, a.T @ p + p @ a + w_term << -eps * eye, p << eye]
    free = [v for v in us + ws if v is not None]
    values, runs = solve_first(cp.Problem(cp.Maximize(eps), cons), [theta, eps, *free], solvers, "piecewise")
    if values is None:
        return None, runs
    it = iter(values[2:])
    found = [None if v is None else next(it) for v in us + ws]
    from scipy.linalg import solve_triangular

    coefficients = solve_triangular(r, values[0])
    return (coefficients, float(values[1]), found[:len(us)], found[len(us):]), runs


def _clean_multiplier(v: np.ndarray | None, r: int, factor: float = 1.0) -> np.ndarray:
    """Symmetric, elementwise ``>= 0``, zero diagonal: exactly (the repair before the exact re-check)."""
    if v is None:
        return frozen_copy(np.zeros((r, r)))
    v = np.maximum(symmetrised(factor * v), 0.0)
    np.fill_diagonal(v, 0.0)
    return frozen_copy(v)


def _multiplier_fault(name: str, v: RationalMatrix, r: int) -> str | None:
    """Why ``v`` is no S-procedure multiplier (shape ``(r, r)``, symmetric, ``>= 0``, zero diagonal), or ``None``."""
    if v.shape != (r, r):
        return f"{name} has shape {v.shape}, expected ({r}, {r})"
    rows = v.numerators
    if not v.is_symmetric() or any(x < 0 for row in rows for x in row) or any(rows[k][k] for k in range(r)):
        return f"{name} is not symmetric, elementwise >= 0 with a zero diagonal"
    return None


def _pwq_conditions(mats: list[np.ndarray], es: list[np.ndarray], ps: list[RationalMatrix],
                    us: list[RationalMatrix], ws: list[RationalMatrix]) -> tuple[list[RationalMatrix] | None, str]:
    """The cells' exact conditions; the matrices ``A_iᵀP_i + P_iA_i + E_iᵀW_iE_i`` when all hold."""
    lies = []
    for i, (a, e, p, u, w) in enumerate(zip(mats, es, ps, us, ws)):
        fault = (None if p.is_symmetric() else f"P_{i} is not symmetric") or _multiplier_fault(
            f"U_{i}", u, e.shape[0]) or _multiplier_fault(f"W_{i}", w, e.shape[0])
        if fault:
            return None, fault
        er = exact.as_rational(e) if e.shape[0] else None
        if not exact.is_positive_definite(p if er is None else p - er.T @ u @ er):
            return None, f"P_{i} − E_{i}ᵀU_{i}E_{i} is not positive definite"
        lie = exact_lie(exact.as_rational(a), p) if er is None else exact_lie(exact.as_rational(a), p) + er.T @ w @ er
        if not exact.is_negative_definite(lie):
            return None, f"A_{i}ᵀP_{i} + P_{i}A_{i} + E_{i}ᵀW_{i}E_{i} is not negative definite"
        lies.append(lie)
    return lies, ""


def recheck_piecewise_quadratic(cells: Sequence[Any], P: Sequence[Any], U: Sequence[Any], W: Sequence[Any], *,
                                boundaries: Sequence[Any] | None = None) -> Recheck:
    """Exact re-check of a piecewise quadratic Lyapunov function (module docstring), on the data converted exactly.

    Checks, in rationals: every ``U_i, W_i`` symmetric, elementwise ``>= 0`` with a zero diagonal;
    ``P_i − E_iᵀU_iE_i ≻ 0`` and ``A_iᵀP_i + P_iA_i + E_iᵀW_iE_i ≺ 0`` on every cell; and
    ``Nᵀ(P_i − P_j)N = 0`` (``V`` continuous) across every boundary.

    Parameters
    ----------
    cells, boundaries
        As :func:`piecewise_quadratic_lyapunov`.
    P : sequence of array_like or RationalMatrix, one symmetric ``(n, n)`` per cell
    U, W : sequence of array_like, one ``(r_i, r_i)`` per cell

    Returns
    -------
    Recheck
        ``margin``: the certified ``α`` [1/s] with ``A_iᵀP_i + P_iA_i + E_iᵀW_iE_i + αP_i ≺ 0``
        (``V̇ ≤ −αV`` on every cell; ``0`` when only strict decrease re-checks).
    """
    mats, es, labels = _cells(cells)
    n = mats[0].shape[0]
    bounds = _boundaries(boundaries, es, labels, n)
    method = ("exact rational LDLᵀ (Sylvester pivots) of every cell's conditions, multipliers and continuity "
              "checked exactly")
    parts = []
    for name, values in (("P", P), ("U", U), ("W", W)):
        if isinstance(values, (str, bytes)) or not hasattr(values, "__len__") or len(values) != len(mats):
            raise LmiError(name, type(values).__name__, f"one matrix per cell ({len(mats)})", "give one per cell")
        parts.append([exact.as_rational(v, where=f"{name}[{k}]") for k, v in enumerate(values)])
    ps, us, ws = parts
    if any(p.shape != (n, n) for p in ps):
        raise LmiError("P", [p.shape for p in ps], f"matrices of shape ({n}, {n})", "give one P_i per cell")
    lies, fault = _pwq_conditions(mats, es, ps, us, ws)
    if lies is None:
        return Recheck(method=method, passed=False, detail=fault)
    for i, j, h, _ in bounds:
        diff = (ps[i] - ps[j]).entries()
        if any(sum(va[k] * diff[k][l] * vb[l] for k in range(n) for l in range(n)) != 0
               for va in _perp_basis(h) for vb in _perp_basis(h)):
            return Recheck(method=method, passed=False,
                           detail=f"V is not continuous across {h.tolist()} between {labels[i]} and {labels[j]}")
    floats = [p.to_array() for p in ps]
    estimate = min(float(np.linalg.eigvalsh(-lie.to_array()).min()) / max(float(np.linalg.eigvalsh(p).max()), 1e-300)
                   for lie, p in zip(lies, floats))  # −L ⪰ μI and P ⪯ λI: L + αP ≺ 0 for α < μ/λ
    alpha = 0.0
    for factor in MARGIN_DISCOUNTS:
        trial = float(estimate * factor)
        if trial > 0 and all(exact.is_negative_definite(lie + p.scaled(trial)) for lie, p in zip(lies, ps)):
            alpha = trial
            break
    return Recheck(method=method, passed=True, margin=alpha,
                   detail=(f"on every cell P_i − E_iᵀU_iE_i ≻ 0 and A_iᵀP_i + P_iA_i + E_iᵀW_iE_i + αP_i ≺ 0 "
                           f"with α = {alpha:.6g} 1/s, V continuous across {len(bounds)} boundaries, in exact "
                           "arithmetic"))


def piecewise_quadratic_lyapunov(cells: Sequence[Any], *, boundaries: Sequence[Any] | None = None,
                                 solver: str | Sequence[str] | None = None) -> PiecewiseQuadraticLMI:
    """A piecewise quadratic Lyapunov function of a state-dependent switched linear system (Johansson–Rantzer).

    Parameters
    ----------
    cells : sequence of LinearCell or (A, E) or (A, E, name)
        Cell ``i``: ``ẋ = A_ix`` on ``{x : E_ix ≥ 0}``; the cells must cover ``ℝⁿ`` with disjoint
        interiors (the caller's responsibility) and ``A_i`` is ``(n, n)``, ``E_i`` is ``(r_i, n)``.
    boundaries : sequence of (cell, cell, h) or None
        Hyperplanes ``hᵀx = 0`` across which ``V`` must be continuous (cells by index or name).  By
        default every pair of cells with a row of ``E`` in common up to a negative factor: a superset
        of the facets shared, so continuity is never missed (an extra pair only restricts the search).
    solver : str, sequence of str or None
        As :func:`common_quadratic_lyapunov_lmi`.

    Returns
    -------
    PiecewiseQuadraticLMI
        ``"exists"`` re-checked exactly, or ``"undecided"`` (an infeasible search proves nothing).

    Raises
    ------
    LmiError
        No cells, a non-square or non-finite ``A``, an ``E`` with the wrong number of columns, a bad boundary.
    """
    mats, es, labels = _cells(cells)
    solvers = checked_solvers(solver)
    n, m = mats[0].shape[0], len(mats)
    bounds = _boundaries(boundaries, es, labels, n)
    shown = tuple(Boundary(cells=(labels[i], labels[j]), normal=tuple(float(x) for x in h), derived=dv)
                  for i, j, h, dv in bounds)
    basis_exact = _continuity_basis(n, m, bounds)

    def undecided(detail: str, runs: tuple[SolverRun, ...] = ()) -> PiecewiseQuadraticLMI:
        return PiecewiseQuadraticLMI(
            names=labels, status="undecided", proven=False, P=None, U=None, W=None, boundaries=shown,
            margin=math.nan, recheck=Recheck(method="exact rational LDLᵀ", passed=False, detail=detail),
            solver=runs, finding=f"undecided: no piecewise quadratic Lyapunov function re-checks ({detail}); "
                                 "this proves nothing about stability")

    if not basis_exact:
        return undecided("continuity leaves only P_i = 0")
    basis = np.array([[float(x) for x in v] for v in basis_exact]).T
    scales = np.array([float(np.linalg.norm(a, 2)) or 1.0 for a in mats])
    solved, runs = _pwq_program([a / c for a, c in zip(mats, scales)], es, basis, solvers)
    if solved is None:
        return undecided(failure_text("the program", runs), runs)
    theta, eps, us_raw, ws_raw = solved
    if not eps > 0:
        return undecided(f"the best margin is {eps:.3g} <= 0", runs)
    coefficients = [Fraction(float(x)) for x in theta]
    d = n * (n + 1) // 2
    ps = []
    for i in range(m):
        svec = [sum((c * v[i * d + k] for c, v in zip(coefficients, basis_exact)), Fraction(0)) for k in range(d)]
        full = [[Fraction(0)] * n for _ in range(n)]
        for (k, l), idx in _svec_index(n).items():
            full[k][l] = full[l][k] = svec[idx]
        ps.append(exact.as_rational(full))
    us = tuple(_clean_multiplier(u, e.shape[0]) for u, e in zip(us_raw, es))
    ws = tuple(_clean_multiplier(w, e.shape[0], c) for w, e, c in zip(ws_raw, es, scales))
    given = None if boundaries is None else [(i, j, h) for i, j, h, _ in bounds]
    check = recheck_piecewise_quadratic(cells, ps, us, ws, boundaries=given)
    if not check.passed:
        return undecided(f"the solver's answer (margin {eps:.3g}) fails the exact re-check: {check.detail}", runs)
    return PiecewiseQuadraticLMI(
        names=labels, status="exists", proven=True, P=tuple(frozen_copy(p.to_array()) for p in ps), U=us, W=ws,
        boundaries=shown, margin=check.margin, recheck=check, solver=runs, exact_P=tuple(ps),
        finding=(f"a piecewise quadratic Lyapunov function exists (proven exactly) on {m} cells: V continuous, "
                 f"{rate_text(check.margin)} on every cell: the origin is exponentially stable for solutions that "
                 "cross the boundaries (no sliding)"))


# ----------------------------------------------------------------------------------------- planted families


def _check_sizes(n: Any, m: Any, n_min: int, m_min: int) -> None:
    for name, value, low in (("n", n, n_min), ("m", m, m_min)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise LmiError(name, value, f"an integer >= {low}", f"give {name} >= {low}")


def _random_conditioned(rng: np.random.Generator, n: int, condition: float) -> np.ndarray:
    """``Q₁ diag(σ) Q₂`` with random orthogonal ``Q`` and singular values log-uniform in ``[1, condition]``."""
    q1, _ = np.linalg.qr(rng.standard_normal((n, n)))
    q2, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return q1 @ np.diag(np.exp(rng.uniform(0.0, math.log(condition), n))) @ q2


def _skew_minus_pd(rng: np.random.Generator, n: int) -> np.ndarray:
    """``S − Q``: ``S`` skew, ``Q ⪰ 0.1 I``; its symmetric part is ``−Q ≺ 0``."""
    s = rng.standard_normal((n, n))
    g = rng.standard_normal((n, n))
    return (s - s.T) - (g @ g.T / n + 0.1 * np.eye(n))


def planted_common_lyapunov(rng: np.random.Generator, n: int, m: int, *,
                            condition: float = 30.0) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """A random family with a planted common quadratic Lyapunov function (tests and benchmarks).

    ``A_i = c_i P⁻¹(S_i − Q_i)`` with ``S_i`` skew, ``Q_i ⪰ 0.1I``, ``c_i`` log-uniform in
    ``[0.1, 10]`` and ``P`` random with condition number up to ``condition``:
    ``A_iᵀP + PA_i = −2c_iQ_i ≺ 0``.

    Returns
    -------
    family : tuple of ndarray, each shape (n, n)
    P : ndarray, shape (n, n)
        The planted common Lyapunov matrix.
    """
    _check_sizes(n, m, 1, 1)
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    p = symmetrised(q @ np.diag(np.exp(rng.uniform(0.0, math.log(condition), n))) @ q.T)
    family = tuple(10.0 ** rng.uniform(-1.0, 1.0) * np.linalg.solve(p, _skew_minus_pd(rng, n)) for _ in range(m))
    return family, p


def _bad_pair(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Block-diagonal ``X, Xᵀ`` (``X = −I + a·(super-diagonal chain)`` per block): Hurwitz, ``X + Xᵀ`` is not."""
    sizes = [2] * (n // 2) if n % 2 == 0 else [3] + [2] * ((n - 3) // 2)
    x = -np.eye(n)
    start = 0
    for size in sizes:
        a = rng.uniform(3.0, 6.0)
        for k in range(start, start + size - 1):
            x[k, k + 1] = a
        start += size
    return x, x.T.copy()


def planted_no_common_lyapunov(rng: np.random.Generator, n: int,
                               m: int) -> tuple[tuple[np.ndarray, ...], tuple[float, ...]]:
    """A random family of Hurwitz matrices with no common quadratic Lyapunov function (tests and benchmarks).

    Two members are ``c·T X T⁻¹`` and ``c'·T Xᵀ T⁻¹`` with ``X`` block diagonal, each block ``−I`` plus
    ``a ∈ [3, 6]`` on its super-diagonal (2×2 blocks, one 3×3 when ``n`` is odd): both Hurwitz, but
    ``X + Xᵀ`` has the eigenvalue ``a − 2 > 0`` (``a√2 − 2`` for the 3×3 block), so the combination
    with weights ``(1/c, 1/c')`` is not Hurwitz, which rules out a common ``P``.  The other ``m − 2``
    members are random Hurwitz matrices; order and scalings ``c`` are random.

    Returns
    -------
    family : tuple of ndarray, each shape (n, n)
    weights : tuple of float
        ``w ≥ 0`` with ``Σ w_iA_i`` not Hurwitz (the planted reason).
    """
    _check_sizes(n, m, 2, 2)
    x1, x2 = _bad_pair(rng, n)
    t = _random_conditioned(rng, n, 5.0)
    members = [t @ np.linalg.solve(t.T, x1.T).T, t @ np.linalg.solve(t.T, x2.T).T]  # T X T⁻¹
    for _ in range(m - 2):
        s = _random_conditioned(rng, n, 5.0)
        members.append(s @ np.linalg.solve(s.T, _skew_minus_pd(rng, n).T).T)
    scales = 10.0 ** rng.uniform(-1.0, 1.0, m)
    order = rng.permutation(m)
    family = tuple(scales[k] * members[k] for k in order)
    weights = tuple(float(1.0 / scales[k]) if k < 2 else 0.0 for k in order)
    return family, weights
