"""LMI Lyapunov certificates: planted answers proven, checked independently of the re-check; dwell times;
piecewise quadratic functions; bad input."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from scipy.linalg import expm

from analysis import exact
from analysis.linearise import common_quadratic_lyapunov
from analysis.lmi import (
    Boundary,
    LinearCell,
    LmiError,
    common_quadratic_lyapunov_lmi,
    dwell_time_lyapunov,
    piecewise_quadratic_lyapunov,
    planted_common_lyapunov,
    planted_no_common_lyapunov,
    recheck_common_lyapunov,
    recheck_dwell_time,
    recheck_no_common_lyapunov,
    recheck_piecewise_quadratic,
)
from hybrid.errors import ParameterError

# 20 seeded (n, m) of mixed sizes each; the benchmark covers n = 10 with 10 modes (200 + 200 cases)
FEASIBLE = [(2, 1), (2, 4), (3, 2), (3, 6), (4, 3), (4, 5), (5, 1), (5, 4), (6, 2), (6, 6),
            (2, 8), (3, 3), (4, 2), (5, 6), (6, 3), (7, 2), (7, 4), (8, 3), (3, 10), (10, 2)]
INFEASIBLE = [(2, 2), (2, 5), (3, 2), (3, 4), (4, 2), (4, 3), (5, 2), (5, 5), (6, 2), (6, 4),
              (2, 3), (3, 3), (4, 5), (5, 3), (6, 3), (7, 2), (7, 3), (8, 2), (3, 6), (9, 2)]
#: classic pair: both Hurwitz, their average is not, so fast switching diverges
TRIANGULAR = (np.array([[-1.0, 4.0], [0.0, -2.0]]), np.array([[-2.0, 0.0], [4.0, -1.0]]))
#: lightly damped pair: the average is Hurwitz, yet switching every quarter turn diverges
DAMPED = (np.array([[-0.1, 1.0], [-10.0, -0.1]]), np.array([[-0.1, 10.0], [-1.0, -0.1]]))
#: Liberzon's unstable spirals: each mode diverges, quadrant switching (A2 on Q1, Q3) is stable
SPIRAL_1, SPIRAL_2 = np.array([[0.1, -1.0], [2.0, 0.1]]), np.array([[0.1, -2.0], [1.0, 0.1]])


def abscissa(a: np.ndarray) -> float:
    return float(np.linalg.eigvals(a).real.max())


def lie(a: np.ndarray, p: np.ndarray) -> np.ndarray:
    return a.T @ p + p @ a


@pytest.mark.parametrize("k", range(len(FEASIBLE)))
def test_a_planted_common_lyapunov_function_is_proven_and_checks_independently(k):
    n, m = FEASIBLE[k]
    family, planted = planted_common_lyapunov(np.random.default_rng(1000 + k), n, m)
    assert all(np.linalg.eigvalsh(lie(a, planted)).max() < 0 for a in family)  # the generator plants what it says
    result = common_quadratic_lyapunov_lmi(family)
    assert (result.status, result.proven, result.recheck.passed) == ("exists", True, True)
    p, alpha = result.P, result.margin
    assert not p.flags.writeable and np.array_equal(p, p.T) and np.trace(p) == pytest.approx(1.0, rel=1e-12)
    assert alpha > 0 and result.dual is None
    # independent of the module's re-check: float eigenvalues, and the exact test on freshly built matrices
    assert np.linalg.eigvalsh(p).min() > 0
    pr = exact.as_rational(p)
    for a in family:
        assert np.linalg.eigvalsh(lie(a, p) + alpha * p).max() < 0  # V̇ <= −αV
        ar = exact.as_rational(a)
        assert exact.is_negative_definite(ar.T @ pr + pr @ ar + pr.scaled(alpha))
    rng = np.random.default_rng(k)
    for w in rng.dirichlet(np.ones(m), size=20):  # a common P makes every convex combination Hurwitz
        assert abscissa(sum(wi * a for wi, a in zip(w, family))) < 0


def unstable_pair_combination(family: tuple[np.ndarray, ...]) -> tuple[int, int, float] | None:
    """A scalar search, independent of the module: a pair and a weight whose (normalised) combination is not Hurwitz."""
    unit = [a / np.linalg.norm(a, 2) for a in family]
    for i in range(len(unit)):
        for j in range(i + 1, len(unit)):
            for s in np.linspace(0.0, 1.0, 101):
                if abscissa(s * unit[i] + (1 - s) * unit[j]) >= 0:
                    return i, j, float(s)
    return None


@pytest.mark.parametrize("k", range(len(INFEASIBLE)))
def test_a_planted_absence_is_proven_by_a_dual_certificate(k):
    n, m = INFEASIBLE[k]
    family, weights = planted_no_common_lyapunov(np.random.default_rng(2000 + k), n, m)
    assert all(abscissa(a) < 0 for a in family)  # every mode is stable ...
    zero = exact.RationalMatrix.identity(n).scaled(0)
    planted = sum((exact.as_rational(a).scaled(w) for a, w in zip(family, weights) if w > 0), zero)
    assert not exact.is_hurwitz(planted)  # ... a planted combination is not (exactly)
    assert unstable_pair_combination(family) is not None  # and a scalar search finds one on its own
    result = common_quadratic_lyapunov_lmi(family)
    assert (result.status, result.proven, result.P) == ("none", True, None)
    zs, t = result.dual, result.margin
    assert zs is not None and len(zs) == m and t > 0
    # independent check of the theorem of alternatives on the stored (repaired) certificate
    assert all(np.array_equal(z, z.T) and np.linalg.eigvalsh(z).min() > 0 for z in zs)
    total = sum(a @ z + z @ a.T for a, z in zip(family, zs))
    tau = sum(np.trace(z) for z in zs)
    assert tau == pytest.approx(1.0, rel=1e-12)
    assert np.linalg.eigvalsh(total).min() >= t * tau * (1 - 1e-9) > 0
    exact_total = sum((exact.as_rational(a) @ exact.as_rational(z) + exact.as_rational(z) @ exact.as_rational(a).T
                       for a, z in zip(family, zs)), zero)
    assert exact.is_positive_definite(exact_total)
    # the sign of the argument: for any P, tr(P·Σ(A_iZ_i + Z_iA_iᵀ)) = Σ tr((A_iᵀP + PA_i)Z_i), and it is > 0
    rng = np.random.default_rng(k)
    for _ in range(3):
        g = rng.standard_normal((n, n))
        p = g @ g.T + 0.1 * np.eye(n)
        inner = sum(np.trace(lie(a, p) @ z) for a, z in zip(family, zs))
        assert np.trace(p @ total) == pytest.approx(inner, rel=1e-9, abs=1e-12) and inner > 0
        assert any(np.linalg.eigvalsh(lie(a, p)).max() >= 0 for a in family)  # so this P is no Lyapunov matrix


def test_the_rechecks_refuse_wrong_certificates():
    stable = [np.array([[-1.0, 0.0], [0.0, -2.0]])]
    assert recheck_common_lyapunov(stable, np.eye(2)).passed
    assert not recheck_common_lyapunov(stable, np.diag([1.0, -2.0**-60])).passed  # indefinite by a hair
    assert not recheck_common_lyapunov(stable, np.array([[1.0, 0.1], [0.0, 1.0]])).passed  # not symmetric
    assert not recheck_common_lyapunov([np.array([[0.0, 1.0], [-1.0, 0.0]])], np.eye(2)).passed  # only ⪯ 0
    saddle = np.diag([1.0, -1.0])  # AᵀP + PA = −2I ≺ 0 with P = diag(−1, 1): only P ≻ 0 refuses it
    assert np.linalg.eigvalsh(lie(saddle, np.diag([-1.0, 1.0]))).max() < 0
    check = recheck_common_lyapunov([saddle], np.diag([-1.0, 1.0]))
    assert not check.passed and "P is not positive definite" in check.detail
    tiny = 2.0**-60  # AᵀP + PA = −2·2⁻⁶⁰·I: negative definite exactly, which only exact arithmetic sees
    assert recheck_common_lyapunov([np.array([[-tiny, 1.0], [-1.0, -tiny]])], np.eye(2)).passed
    works_for_first = [-np.eye(2), DAMPED[0]]
    check = recheck_common_lyapunov(works_for_first, np.diag([1.0, 1e-3]))
    assert not check.passed and "A_1" in check.detail

    feasible, _ = planted_common_lyapunov(np.random.default_rng(3), 3, 3)
    m = len(feasible)
    eye = [np.eye(3) / m] * m  # Σ(A_iZ_i + Z_iA_iᵀ) = Σ(A_i + A_iᵀ)/m: not ⪰ 0 for this family
    assert np.linalg.eigvalsh(sum(a + a.T for a in feasible)).min() < 0
    assert not recheck_no_common_lyapunov(feasible, eye).passed  # a flipped sign would accept this
    family, _ = planted_no_common_lyapunov(np.random.default_rng(4), 3, 2)
    zs = common_quadratic_lyapunov_lmi(family).dual
    assert recheck_no_common_lyapunov(family, zs).passed
    assert not recheck_no_common_lyapunov(family, [-z for z in zs]).passed  # Z_i ⪯ 0
    assert not recheck_no_common_lyapunov(family, [0 * z for z in zs]).passed  # all zero
    v = np.linalg.eigh(zs[0])[1][:, 0]
    dented = zs[0] - (np.linalg.eigvalsh(zs[0]).min() + 1e-6) * np.outer(v, v)  # one eigenvalue −1e-6
    assert not recheck_no_common_lyapunov(family, [0.5 * (dented + dented.T), *zs[1:]]).passed
    skew = [np.array([[0.0, 1.0], [-1.0, 0.0]])]
    assert recheck_no_common_lyapunov(skew, [np.eye(2)]).passed  # A + Aᵀ = 0 ⪰ 0: a singular certificate


def test_absence_without_a_strict_certificate_is_proven_by_a_witness():
    result = common_quadratic_lyapunov_lmi([np.array([[0.0, 1.0], [-1.0, 0.0]])], ["centre"])
    assert (result.status, result.proven, result.dual, result.witness_weights) == ("none", True, None, (1.0,))
    saddle = common_quadratic_lyapunov_lmi([np.diag([1.0, -1.0]), -np.eye(2)])
    assert saddle.status == "none" and saddle.witness_weights[0] > 0


def test_a_borderline_family_is_undecided_never_a_false_proof():
    t = np.array([[1.0, 0.7], [0.2, 1.3]])
    a = t @ np.array([[-1e-11, 1.0], [-1.0, -1e-11]]) @ np.linalg.inv(t)  # Hurwitz by 1e-11: a P exists
    result = common_quadratic_lyapunov_lmi([a, 2.0 * a])
    assert result.status in ("exists", "undecided") and result.status != "none"
    if result.status == "undecided":
        assert not result.proven and result.P is None and math.isnan(result.margin)
        assert "margin" in result.recheck.detail and result.finding.startswith("undecided")


def test_a_solver_failure_is_undecided_with_its_message(monkeypatch):
    import cvxpy as cp

    def broken(self, *args, **kwargs):
        raise cp.error.SolverError("simulated breakdown")

    monkeypatch.setattr(cp.Problem, "solve", broken)
    family, _ = planted_common_lyapunov(np.random.default_rng(5), 3, 2)
    result = common_quadratic_lyapunov_lmi(family)
    assert (result.status, result.proven) == ("undecided", False)
    assert {(r.solver, r.status) for r in result.solver} == {("CLARABEL", "error"), ("SCS", "error")}
    assert "simulated breakdown" in result.finding


def test_scs_takes_over_when_clarabel_fails(monkeypatch):
    import cvxpy as cp

    solve = cp.Problem.solve

    def clarabel_breaks(self, *args, solver=None, **kwargs):
        if solver == "CLARABEL":
            raise cp.error.SolverError("simulated Clarabel breakdown")
        return solve(self, *args, solver=solver, **kwargs)

    monkeypatch.setattr(cp.Problem, "solve", clarabel_breaks)
    family, _ = planted_common_lyapunov(np.random.default_rng(7), 3, 3)
    result = common_quadratic_lyapunov_lmi(family)
    assert result.status == "exists" and result.recheck.passed
    assert [(r.solver, r.status) for r in result.solver] == [("CLARABEL", "error"), ("SCS", "optimal")]
    assert common_quadratic_lyapunov_lmi(family, solver="SCS").status == "exists"


def test_multipliers_are_repaired_onto_their_cone():
    from analysis.lmi import _clean_multiplier

    raw = np.array([[1e-3, -1e-12, 0.5], [2e-12, 0.2, 0.3], [0.5, 0.1, -4.0]])
    clean = _clean_multiplier(raw, 3, factor=2.0)
    assert np.array_equal(clean, clean.T) and np.all(clean >= 0) and not np.diag(clean).any()
    np.testing.assert_array_equal(clean, [[0.0, 1e-12, 1.0], [1e-12, 0.0, 0.4], [1.0, 0.4, 0.0]])
    assert not clean.flags.writeable and not _clean_multiplier(None, 2).any()


def test_results_are_json_and_byte_identical_across_runs():
    family, _ = planted_no_common_lyapunov(np.random.default_rng(6), 3, 3)
    texts = [json.dumps(common_quadratic_lyapunov_lmi(family, ["a", "b", "c"]).as_dict(), allow_nan=False)
             for _ in range(2)]
    assert texts[0] == texts[1]
    data = json.loads(texts[0])
    assert data["status"] == "none" and data["names"] == ["a", "b", "c"] and data["P"] is None
    assert set(data) == {"names", "status", "proven", "P", "dual", "witness_weights", "margin", "recheck", "solver",
                         "finding"}


def test_dwell_time_stabilises_where_fast_switching_diverges():
    a1, a2 = TRIANGULAR
    assert abscissa(0.5 * (a1 + a2)) > 0  # fast switching follows the average: it diverges
    assert common_quadratic_lyapunov_lmi(TRIANGULAR).status == "none"
    d = dwell_time_lyapunov(TRIANGULAR, ("one", "two"))
    assert (d.status, d.proven, d.recheck.passed) == ("certified", True, True)
    old = common_quadratic_lyapunov(list(TRIANGULAR))  # the former fallback: ln μ / λ0
    assert not old.found and d.baseline_dwell_time_s == pytest.approx(old.dwell_time_s, rel=1e-9)
    assert 0 < d.lower_bound_s < d.dwell_time_s <= old.dwell_time_s / 2  # far better than the fallback
    t = d.dwell_time_s
    fast = expm(a2 * t / 20) @ expm(a1 * t / 20)
    assert max(abs(np.linalg.eigvals(fast))) > 1  # switching every T/20 diverges
    assert max(abs(np.linalg.eigvals(expm(a2 * t) @ expm(a1 * t)))) < 1  # every T is stable
    rng = np.random.default_rng(0)  # any signal dwelling >= T: V_σ decreases at every switch
    x, mode = np.array([1.0, -0.5]), 0
    v0 = x @ d.P[0] @ x
    for _ in range(30):
        x_next = expm(TRIANGULAR[mode] * rng.uniform(t, 2 * t)) @ x
        assert x_next @ d.P[1 - mode] @ x_next < x @ d.P[mode] @ x
        x, mode = x_next, 1 - mode
    assert x @ d.P[mode] @ x < 1e-3 * v0
    assert recheck_dwell_time(TRIANGULAR, d.P, t).passed
    assert not recheck_dwell_time(TRIANGULAR, d.P, t / 4).passed  # the same P_i do not certify a shorter dwell
    assert not recheck_dwell_time(TRIANGULAR, (d.P[1], d.P[0]), t).passed  # nor swapped ones


def test_dwell_time_of_the_lightly_damped_pair_and_the_trivial_cases():
    d = dwell_time_lyapunov(DAMPED)
    assert d.status == "certified" and d.dwell_time_s < d.baseline_dwell_time_s
    quarter = math.pi / 2 / math.sqrt(10.0)  # switching each quarter turn diverges
    assert max(abs(np.linalg.eigvals(expm(DAMPED[1] * quarter) @ expm(DAMPED[0] * quarter)))) > 1
    assert max(abs(np.linalg.eigvals(expm(DAMPED[1] * d.dwell_time_s) @ expm(DAMPED[0] * d.dwell_time_s)))) < 1
    common = dwell_time_lyapunov([np.diag([-1.0, -2.0]), np.diag([-3.0, -0.5])])
    assert (common.status, common.dwell_time_s) == ("arbitrary", 0.0) and common.recheck.passed
    unstable = dwell_time_lyapunov([np.diag([-1.0, -2.0]), np.array([[0.0, 1.0], [-1.0, 0.0]])])
    assert (unstable.status, unstable.proven, unstable.dwell_time_s) == ("unstable_mode", True, math.inf)
    assert json.loads(json.dumps(unstable.as_dict()))["dwell_time_s"] is None


def sectors(count: int, modes: tuple[np.ndarray, ...]) -> list[LinearCell]:
    """``count`` cones of equal angle; ``modes[q]`` on the sectors inside quadrant ``q``."""
    normals = [np.array([-math.sin(2 * math.pi * i / count), math.cos(2 * math.pi * i / count)]) for i in range(count)]
    cells = []
    for i in range(count):
        quadrant = int(((i + 0.5) / count * 4)) % 4
        cells.append(LinearCell(A=modes[quadrant], E=np.vstack([normals[i], -normals[(i + 1) % count]]), name=f"S{i}"))
    return cells


def quadrant_of(x: np.ndarray) -> int:
    return (0 if x[1] >= 0 else 3) if x[0] >= 0 else (1 if x[1] >= 0 else 2)


def simulate(modes: tuple[np.ndarray, ...], x0: np.ndarray, horizon: float, dt: float = 2e-3) -> np.ndarray:
    steps = {q: expm(modes[q] * dt) for q in range(4)}
    xs = [np.asarray(x0, dtype=float)]
    for _ in range(int(horizon / dt)):
        xs.append(steps[quadrant_of(xs[-1])] @ xs[-1])
    return np.array(xs)


def test_a_piecewise_quadratic_function_where_no_common_one_exists():
    stable = (SPIRAL_2, SPIRAL_1, SPIRAL_2, SPIRAL_1)  # by quadrant
    assert abscissa(SPIRAL_1) > 0 and abscissa(SPIRAL_2) > 0  # each mode alone diverges
    assert common_quadratic_lyapunov_lmi([SPIRAL_1, SPIRAL_2]).status == "none"
    cells = sectors(8, stable)
    result = piecewise_quadratic_lyapunov(cells)
    assert (result.status, result.proven, result.recheck.passed) == ("exists", True, True)
    assert len(result.boundaries) == 8 and all(b.derived for b in result.boundaries)
    assert not np.allclose(result.P[0], result.P[2])  # genuinely piecewise
    alpha = result.margin
    assert alpha > 0
    for cell, p, u, w, pe in zip(cells, result.P, result.U, result.W, result.exact_P):
        e = cell.E
        assert np.all(u >= 0) and np.all(w >= 0) and not np.diag(u).any() and not np.diag(w).any()
        assert np.linalg.eigvalsh(p - e.T @ u @ e).min() > 0
        assert np.linalg.eigvalsh(lie(cell.A, p) + e.T @ w @ e + alpha * p).max() < 0
        ar, er = exact.as_rational(cell.A), exact.as_rational(e)
        assert exact.is_positive_definite(pe - er.T @ exact.as_rational(u) @ er)
    for b in result.boundaries:  # continuity, exactly, on the ray shared (direction ⊥ h)
        i, j = (int(name[1:]) for name in b.cells)
        ray = [exact.rational(-b.normal[1]), exact.rational(b.normal[0])]
        vi, vj = (sum(ray[k] * pe.entries()[k][l] * ray[l] for k in range(2) for l in range(2))
                  for pe in (result.exact_P[i], result.exact_P[j]))
        assert vi == vj
    # simulation: the switched system is stable and V never grows along it
    def value(x):
        angle = math.atan2(x[1], x[0]) % (2 * math.pi)
        return x @ result.P[min(int(angle / (2 * math.pi) * 8), 7)] @ x
    for x0 in ([1.0, 0.3], [-0.2, 1.0], [0.5, -1.0]):
        xs = simulate(stable, np.array(x0), 15.0)
        assert np.linalg.norm(xs[-1]) < 0.05 * np.linalg.norm(xs[0])
        vs = np.array([value(x) for x in xs[::25]])
        assert np.all(np.diff(vs) < 1e-9 * vs[:-1])
    assert "exact_P" not in result.as_dict() and json.dumps(result.as_dict(), allow_nan=False)


def test_no_piecewise_quadratic_function_is_claimed_when_none_can_exist():
    unstable = (SPIRAL_1, SPIRAL_2, SPIRAL_1, SPIRAL_2)
    xs = simulate(unstable, np.array([1.0, 0.3]), 15.0)
    assert np.linalg.norm(xs[-1]) > 10 * np.linalg.norm(xs[0])  # this switching diverges
    result = piecewise_quadratic_lyapunov(sectors(8, unstable))
    assert (result.status, result.proven, result.P) == ("undecided", False, None)
    quadrants = [np.array([[1.0, 0.0], [0.0, 1.0]]), np.array([[-1.0, 0.0], [0.0, 1.0]]),
                 np.array([[-1.0, 0.0], [0.0, -1.0]]), np.array([[1.0, 0.0], [0.0, -1.0]])]
    # one quadratic per quadrant cannot work for the stable assignment either (the radial growth at both
    # axes asks for cross terms of opposite signs): undecided, proving nothing
    coarse = piecewise_quadratic_lyapunov([(m, e) for m, e in zip((SPIRAL_2, SPIRAL_1, SPIRAL_2, SPIRAL_1), quadrants)])
    assert coarse.status == "undecided"
    # the lightly damped pair on quadrants: no common P, but V = |x|² with the S-procedure works
    assert common_quadratic_lyapunov_lmi(DAMPED).status == "none"
    damped = piecewise_quadratic_lyapunov([(DAMPED[q % 2], e) for q, e in enumerate(quadrants)])
    assert damped.status == "exists" and damped.proven


def test_the_piecewise_recheck_refuses_a_doctored_certificate():
    cells = sectors(8, (SPIRAL_2, SPIRAL_1, SPIRAL_2, SPIRAL_1))
    r = piecewise_quadratic_lyapunov(cells)
    assert recheck_piecewise_quadratic(cells, r.exact_P, r.U, r.W).passed
    rounded = recheck_piecewise_quadratic(cells, r.P, r.U, r.W)  # the floats nearest to the exact P_i ...
    assert not rounded.passed and "continuous" in rounded.detail  # ... lose exact continuity: exact_P is the proof
    negative = np.array(r.U[0])
    negative[0, 1] = negative[1, 0] = -1e-300  # a multiplier below zero by a hair
    check = recheck_piecewise_quadratic(cells, r.exact_P, (negative, *r.U[1:]), r.W)
    assert not check.passed and "U_0" in check.detail
    diagonal = np.array(r.W[3]) + np.diag([1e-9, 0.0])  # (E_kx)² terms are not allowed
    assert "W_3" in recheck_piecewise_quadratic(cells, r.exact_P, r.U, (*r.W[:3], diagonal, *r.W[4:])).detail
    bumped = list(r.exact_P)
    bumped[0] = bumped[0] + exact.as_rational([[2.0**-40, 0.0], [0.0, 0.0]])  # V jumps on the ray θ = 0
    check = recheck_piecewise_quadratic(cells, bumped, r.U, r.W)
    assert not check.passed and "continuous" in check.detail


def test_boundaries_given_explicitly_give_the_same_function():
    cells = sectors(8, (SPIRAL_2, SPIRAL_1, SPIRAL_2, SPIRAL_1))
    derived = piecewise_quadratic_lyapunov(cells)
    given = [(b.cells[0], b.cells[1], b.normal) for b in derived.boundaries]
    explicit = piecewise_quadratic_lyapunov(cells, boundaries=given)
    assert explicit.status == "exists" and not any(b.derived for b in explicit.boundaries)
    for p, q in zip(derived.P, explicit.P):
        np.testing.assert_allclose(p, q, atol=1e-9)
    assert isinstance(explicit.boundaries[0], Boundary) and explicit.boundaries[0].cells == ("S0", "S1")


BAD = [
    (lambda: common_quadratic_lyapunov_lmi([]), "family", "'empty'", "at least one square matrix"),
    (lambda: common_quadratic_lyapunov_lmi([np.eye(2), np.ones((2, 3))]), "family[1]", r"\(2, 3\)", "a square matrix"),
    (lambda: common_quadratic_lyapunov_lmi([np.eye(2), np.eye(3)]), "family[1]", r"\(3, 3\)", r"shape \(2, 2\)"),
    (lambda: common_quadratic_lyapunov_lmi([np.array([[np.nan, 0.0], [0.0, -1.0]])]), "family[0]", r"\(2, 2\)",
     "finite entries"),
    (lambda: common_quadratic_lyapunov_lmi([np.array([[-1.0, np.inf], [0.0, -1.0]])]), "family[0]", r"\(2, 2\)",
     "finite entries"),
    (lambda: common_quadratic_lyapunov_lmi(-np.eye(2)), "family", r"\(2, 2\)", "a sequence of square matrices"),
    (lambda: common_quadratic_lyapunov_lmi([-np.eye(2)] * 2, ["a"]), "names", r"\('a',\)", "2 strings"),
    (lambda: common_quadratic_lyapunov_lmi([-np.eye(2)] * 2, ["a", "a"]), "names", r"\('a', 'a'\)", "distinct"),
    (lambda: common_quadratic_lyapunov_lmi([-np.eye(2)], solver="NOPE"), "solver", "'NOPE'", "installed SDP"),
    # an LP/QP solver cvxpy has installed cannot take the semidefinite constraints: refused, not tried
    (lambda: common_quadratic_lyapunov_lmi([-np.eye(2)], solver="OSQP"), "solver", "'OSQP'", "installed SDP"),
    # complex entries would silently lose their imaginary parts in a float conversion
    (lambda: common_quadratic_lyapunov_lmi([np.array([[1j, 0.0], [0.0, -1.0]])]), "family[0]", "'complex'",
     "a matrix of real numbers"),
    (lambda: dwell_time_lyapunov([-np.eye(2)], rel_tol=2.0), "rel_tol", "2.0", r"a number in \(0, 1\)"),
    (lambda: piecewise_quadratic_lyapunov([]), "cells", "'empty'", "a non-empty sequence"),
    (lambda: piecewise_quadratic_lyapunov([(-np.eye(2), np.ones((1, 3)))]), "cells[0].E", r"\(1, 3\)",
     r"shape \(r, 2\)"),
    (lambda: piecewise_quadratic_lyapunov([(-np.eye(2), np.eye(2))], boundaries=[(0, 5, (1.0, 0.0))]),
     "boundaries[0]", "5", "a cell index"),
    (lambda: piecewise_quadratic_lyapunov([(-np.eye(2), np.eye(2))] * 2, boundaries=[(0, 1, (0.0, 0.0))]),
     "boundaries[0] normal", r"\(2,\)", "not all zero"),
    (lambda: recheck_common_lyapunov([-np.eye(2)], np.eye(3)), "P", r"\(3, 3\)", r"shape \(2, 2\)"),
]


@pytest.mark.parametrize("call, parameter, value, expected", BAD, ids=[b[1] + f"-{k}" for k, b in enumerate(BAD)])
def test_bad_input_raises_one_error_shape(call, parameter, value, expected):
    with pytest.raises(LmiError) as info:
        call()
    err = info.value
    assert isinstance(err, ParameterError) and err.parameter == parameter
    assert str(err).startswith(f"{parameter} = ") and "; fix: " in str(err)
    assert info.match(rf"^{re.escape(parameter)} = {value}: expected .*{expected}")
    assert err.__cause__ is None  # never a chained solver or numpy traceback
