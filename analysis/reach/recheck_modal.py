"""The re-check's rounding errors bounded in a real modal basis, so that they do not wrap (own code, no engine sets).

Each step of the own sets (:meth:`analysis.reach.recheck_sets.FZ.mapped`) maps the error part ``ε`` of a set by the
float matrix ``Φm`` and adds a fresh error ``f`` with ``|f| <= e`` (the products' roundings, ``Φr |x|``, the shift's
radius): ``ε' = Φm ε + f``.  Bounded as a box, ``|ε'| <= |Φm| |ε| + e`` grows like ``ρ(|Φm|)^k``: for lightly damped
fast oscillations (the 48-state building) that is ``e^{ρ(|A|) t}``, a blow-up within a second.

Here ``ε`` is carried in the coordinates ``η = V⁻¹ ε`` of a *real* modal basis ``V`` of ``Φm`` (float; a real
eigenvector per real eigenvalue, ``[Re v, Im v]`` per complex pair), as a vector ``r`` of Euclidean norms of its
blocks (``‖η_J‖₂ <= r_J``, ``J`` of size 1 or 2).  In these coordinates ``Φm`` is nearly block-diagonal, each
2 × 2 block nearly a scaled rotation, and Euclidean norms do not grow under rotations: ``r' = N r + g`` with

* ``N_JK >= ‖(V⁻¹ Φm V)_JK‖₂``: the product enclosed in midpoint-radius arithmetic (:func:`point_product`), and
  a 2 × 2 block's norm bounded *exactly* by ``|z| + |w|`` with ``z = ((p + s) + i(r − q))/2``,
  ``w = ((p − s) + i(r + q))/2`` for ``[[p, q], [r, s]]`` (its singular values are ``|z| ± |w|``); other
  blocks by their Frobenius norm;
* ``g_J >= ‖(V⁻¹ f)_J‖₂``, from ``|V⁻¹| e``;
* ``V⁻¹`` itself enclosed, never assumed: ``W = fl(V⁻¹)``, ``R = I − W V`` bounded entrywise with its rounding,
  ``ρ = ‖|R|‖∞ < 1/2`` required; then ``V⁻¹ = (I − R)⁻¹ W = W + Σ_{k>=1} R^k W`` and every entry of
  ``V⁻¹ − W`` is at most ``ρ/(1 − ρ) ‖|W|‖∞`` (Neumann series).

The box of the error is ``|ε_i| <= Σ_J ‖V_{i,J}‖₂ r_J`` (Cauchy–Schwarz per block).  It is a bound of the same
``ε`` as the box recursion's, so the re-check keeps the smaller of the two (:func:`step`).  A basis whose residual
is not below 1/2, or whose condition ``‖|W|‖∞ ‖|V|‖∞`` exceeds ``10¹⁰``, gives no tracker (``None``): the box
alone is used, as before.  All float operations are rounded outward (``recheck_interval``'s argument).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .recheck_interval import TINY, U, add_up, nn_up, point_product, sum_up, up

__all__ = ["ModalTracker", "modal_tracker", "MAX_MODAL_CONDITION"]

MAX_MODAL_CONDITION = 1e10
"""The largest ``‖|W|‖∞ ‖|V|‖∞`` accepted for a modal basis."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ModalTracker:
    """``r' = N r + g`` of the module (every array non-negative).

    Attributes
    ----------
    blocks : tuple of tuple of int
        The coordinates of each block ``J`` of ``η`` (size 1 or 2), in order.
    n : ndarray, shape (b, b)
        ``N_JK >= ‖(V⁻¹ Φm V)_JK‖₂``.
    w_abs : ndarray, shape (m, m)
        ``>= |V⁻¹|`` entrywise.
    v_norm : ndarray, shape (m, b)
        ``>= ‖V_{i,J}‖₂``.
    """

    blocks: tuple[tuple[int, ...], ...]
    n: np.ndarray
    w_abs: np.ndarray
    v_norm: np.ndarray

    def coordinates(self, box: np.ndarray) -> np.ndarray:
        """``g``: upper bounds of the block norms of ``V⁻¹ f`` over ``|f| <= box`` (shape ``(b,)``)."""
        return _block_norms(nn_up(self.w_abs, box), self.blocks)

    def advance(self, r: np.ndarray, fresh: np.ndarray) -> np.ndarray:
        """``N r + g(fresh)`` (rounded up)."""
        return add_up(nn_up(self.n, r), self.coordinates(fresh))

    def box(self, r: np.ndarray) -> np.ndarray:
        """``|ε| <= v_norm r`` (rounded up)."""
        return nn_up(self.v_norm, r)


def _block_norms(x: np.ndarray, blocks: tuple[tuple[int, ...], ...]) -> np.ndarray:
    """Upper bounds of the Euclidean norms of the blocks of a non-negative vector (the blocks are consecutive
    coordinates in order, as :func:`_real_basis` makes them)."""
    starts = np.fromiter((idx[0] for idx in blocks), dtype=np.intp, count=len(blocks))
    sq = np.add.reduceat(up(x * x), starts)  # at most two terms: one rounding each
    single = np.fromiter((len(idx) == 1 for idx in blocks), dtype=bool, count=len(blocks))
    return np.where(single, x[starts], up(up(np.sqrt(up(sq))) * (1 + 4 * U) + TINY))


def _real_basis(phi: np.ndarray) -> tuple[np.ndarray, tuple[tuple[int, ...], ...]] | None:
    """A real modal basis of ``phi`` and its blocks (``None`` when numpy's eigenvectors are not finite)."""
    values, vectors = np.linalg.eig(phi)
    if not (np.all(np.isfinite(values)) and np.all(np.isfinite(vectors))):
        return None
    cols: list[np.ndarray] = []
    blocks: list[tuple[int, ...]] = []
    scale = max(float(np.max(np.abs(values))), 1.0)
    for k, lam in enumerate(values):
        if abs(lam.imag) <= 1e-13 * scale:
            blocks.append((len(cols),))
            cols.append(vectors[:, k].real / max(float(np.max(np.abs(vectors[:, k].real))), 1e-300))
        elif lam.imag > 0:
            v = vectors[:, k]
            norm = max(float(np.max(np.abs(v))), 1e-300)
            blocks.append((len(cols), len(cols) + 1))
            cols.extend([v.real / norm, v.imag / norm])
    if len(cols) != phi.shape[0]:
        return None  # conjugate pairs not matched (a numerically defective spectrum)
    return np.array(cols).T, tuple(blocks)


def _pair_norm(p: float, q: float, r: float, s: float, rad: float) -> float:
    """An upper bound of ``‖[[p, q], [r, s]] ± rad‖₂`` (entrywise radius): ``|z| + |w|`` (module) plus ``2 rad``."""
    z = np.hypot(abs(p + s) * 0.5, abs(r - q) * 0.5)
    w = np.hypot(abs(p - s) * 0.5, abs(r + q) * 0.5)
    return float(up(up(up(z + w) * (1 + 16 * U) + TINY) + up(2 * rad * (1 + 4 * U))))


def _block_matrix(mm: np.ndarray, mr: np.ndarray, blocks: tuple[tuple[int, ...], ...]) -> np.ndarray:
    """``N_JK >=`` the 2-norm of each block of ``[mm ± mr]``."""
    b = len(blocks)
    mag = up(np.abs(mm) + mr)
    out = np.empty((b, b))
    for j, rows in enumerate(blocks):
        for k, cols in enumerate(blocks):
            if len(rows) == 2 and len(cols) == 2:
                (i0, i1), (k0, k1) = rows, cols
                rad = float(np.max(mr[np.ix_(rows, cols)]))
                out[j, k] = _pair_norm(mm[i0, k0], mm[i0, k1], mm[i1, k0], mm[i1, k1], rad)
            else:
                sq = sum_up(up(mag[np.ix_(rows, cols)] ** 2))
                out[j, k] = float(up(up(np.sqrt(sq)) * (1 + 4 * U) + TINY))
    return out


def modal_tracker(phi_mid: np.ndarray) -> ModalTracker | None:
    """The tracker of ``ε' = Φm ε + f`` for the float matrix ``phi_mid`` (shape ``(m, m)``); ``None`` when no safe
    real modal basis exists (see the module)."""
    m = phi_mid.shape[0]
    if m == 0 or not np.all(np.isfinite(phi_mid)):
        return None
    got = _real_basis(phi_mid)
    if got is None:
        return None
    v, blocks = got
    try:
        w = np.linalg.inv(v)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(w)):
        return None
    wv, rwv = point_product(w, v)
    resid = add_up(np.abs(np.eye(m) - wv), up(np.abs(np.eye(m) - wv) * (2 * U)), rwv)
    rho = float(np.max(sum_up(resid, axis=1)))
    w_norm = float(np.max(sum_up(np.abs(w), axis=1)))
    v_norm_inf = float(np.max(sum_up(np.abs(v), axis=1)))
    if not rho < 0.5 or not w_norm * v_norm_inf <= MAX_MODAL_CONDITION:
        return None
    delta = float(up(up(rho / up(1.0 - rho) * (1 + 4 * U)) * w_norm * (1 + 4 * U)))  # every entry of V⁻¹ − W
    w_abs = up(np.abs(w) + delta)
    # V⁻¹ Φm V = (W + Δ)(P ± rP) with P = fl(Φm V): midpoint fl(W P), radius its rounding + |W| rP + Δ·(|P| + rP)
    p, rp = point_product(phi_mid, v)
    q, rq = point_product(w, p)
    colsum = sum_up(up(np.abs(p) + rp), axis=0)
    radius = add_up(rq, nn_up(np.abs(w), rp), up(np.broadcast_to(up(colsum * delta * (1 + 4 * U)), q.shape)))
    n_mat = _block_matrix(q, radius, blocks)
    v_norm = np.empty((m, len(blocks)))
    for k, cols in enumerate(blocks):
        v_norm[:, k] = up(up(np.sqrt(sum_up(up(v[:, list(cols)] ** 2), axis=1))) * (1 + 4 * U) + TINY)
    if not (np.all(np.isfinite(n_mat)) and np.all(np.isfinite(v_norm))):
        return None
    return ModalTracker(blocks=blocks, n=n_mat, w_abs=w_abs, v_norm=v_norm)
