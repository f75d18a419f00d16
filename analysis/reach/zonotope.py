"""Zonotopes ``{c + G ξ : ξ ∈ [-1, 1]^m}`` with operations that account for floating-point rounding.

A :class:`Zonotope` stores a float center ``c`` (shape ``(n,)``) and a float
generator matrix ``G`` (shape ``(n, m)``); the set it denotes is the *exact*
real set of those float numbers.  Every operation that rounds (a linear map, a
sum of centers, a hull) returns, besides its float result, a non-negative
error vector ``e`` (shape ``(n,)``) such that the exact result lies in the
float result plus the box ``[-e, e]``; the caller adds that box (as diagonal
generators, :func:`box_generators`) where it belongs.  The bounds are the
classical a-priori bounds of floating-point dot products (Higham, *Accuracy and
Stability of Numerical Algorithms*, 2nd ed., §3.1): with unit roundoff
``u = 2⁻⁵³`` and ``γ_k = k u / (1 - k u)``, a computed dot product of length
``k`` satisfies ``|fl(aᵀb) - aᵀb| <= γ_k |a|ᵀ|b|``.  The bounds themselves are
computed in floating point on non-negative numbers and then inflated by
:func:`upper` (relative ``4 (k + 2) u`` and an absolute term for underflow),
which is an upper bound of the exact non-negative expression whatever the
rounding.  Nothing here changes the processor's rounding mode.

Linear maps take an *interval* matrix ``[Mc - Mr, Mc + Mr]`` (``Mr >= 0``): the
exact matrix (``e^{Aδ}``, a reset) is some matrix in it.

Examples
--------
>>> import numpy as np
>>> z = Zonotope(center=np.array([1.0, 0.0]), generators=np.array([[0.5, 0.0], [0.0, 0.25]]))
>>> lo, hi = interval_hull(z)
>>> bool(lo[0] <= 0.5 and hi[0] >= 1.5 and hi[0] - 1.5 < 1e-12)
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "UNIT_ROUNDOFF",
    "Zonotope",
    "upper",
    "gamma",
    "round_down",
    "round_up",
    "magnitude",
    "linear_map",
    "minkowski_sum",
    "box_generators",
    "from_box",
    "interval_hull",
    "reduce_order",
    "support_bounds",
    "with_error",
]

UNIT_ROUNDOFF = 2.0 ** -53
"""``u``: the relative error bound of one IEEE double operation rounded to nearest."""

_UNDERFLOW = 2.0 ** -1021
"""Absolute slack per operation for underflow (twice the smallest normal number)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class Zonotope:
    """The set ``{center + generators @ ξ : ξ ∈ [-1, 1]^m}``.

    Attributes
    ----------
    center : ndarray, shape (n,)
    generators : ndarray, shape (n, m)
        ``m`` may be 0.
    """

    center: np.ndarray
    generators: np.ndarray

    def __post_init__(self) -> None:
        c = np.array(self.center, dtype=float).reshape(-1)
        g = np.array(self.generators, dtype=float)
        if g.size == 0:
            g = np.zeros((c.size, 0))
        if g.ndim != 2 or g.shape[0] != c.size:
            raise ValueError(f"Zonotope: generators of shape {g.shape} for a center of length {c.size}; "
                             "expected shape (n, m)")
        c.setflags(write=False)
        g.setflags(write=False)
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "generators", g)

    @classmethod
    def of_arrays(cls, center: np.ndarray, generators: np.ndarray) -> Zonotope:
        """The zonotope of float64 arrays of shapes ``(n,)`` and ``(n, m)`` that the caller has just computed and
        will not write again: no copy and no check (the hot loops; the arrays are made read-only in place)."""
        z = object.__new__(cls)
        center.setflags(write=False)
        generators.setflags(write=False)
        object.__setattr__(z, "center", center)
        object.__setattr__(z, "generators", generators)
        return z

    @property
    def dimension(self) -> int:
        """``n``."""
        return int(self.center.size)

    @property
    def order(self) -> int:
        """Number of generators ``m``."""
        return int(self.generators.shape[1])

    def is_finite(self) -> bool:
        """Whether every number is finite (a NaN or inf makes the set meaningless)."""
        return bool(np.all(np.isfinite(self.center)) and np.all(np.isfinite(self.generators)))

    def project(self, k: int) -> Zonotope:
        """The first ``k`` coordinates (an exact projection)."""
        return Zonotope.of_arrays(self.center[:k], self.generators[:k])


def gamma(k: int) -> float:
    """``γ_k = k u / (1 - k u)``."""
    return k * UNIT_ROUNDOFF / (1.0 - k * UNIT_ROUNDOFF)


def upper(x: np.ndarray | float, ops: int) -> np.ndarray:
    """An upper bound of the exact value of a non-negative expression computed as ``x`` with ``ops`` roundings.

    Each rounding of a non-negative sum or product loses at most a relative ``u`` (plus an
    absolute half subnormal on underflow), so the exact value is at most
    ``x / (1 - γ_ops) + ops·η``; ``x (1 + 4 (ops + 2) u) + (ops + 2)·2⁻¹⁰²¹`` exceeds it (the
    product itself rounds by at most one more ``u``).
    """
    factor, slack = 1.0 + 4.0 * (ops + 2) * UNIT_ROUNDOFF, (ops + 2) * _UNDERFLOW
    if type(x) is np.ndarray and x.dtype == np.float64 or type(x) is np.float64:
        return x * factor + slack  # the same operations as below, without the conversion (hot path)
    return np.asarray(x, dtype=float) * factor + slack


def round_down(x: np.ndarray) -> np.ndarray:
    """The next float below (a value that was rounded to nearest is then a lower bound)."""
    return np.nextafter(np.asarray(x, dtype=float), -np.inf)


def round_up(x: np.ndarray) -> np.ndarray:
    """The next float above."""
    return np.nextafter(np.asarray(x, dtype=float), np.inf)


def magnitude(z: Zonotope) -> np.ndarray:
    """An upper bound of ``|x|`` (componentwise) over ``z``, shape ``(n,)``."""
    return upper(np.abs(z.center) + np.abs(z.generators).sum(axis=1), z.order + 1)


def linear_map(z: Zonotope, mc: np.ndarray, mr: np.ndarray | None = None) -> tuple[Zonotope, np.ndarray]:
    """``{M x : M ∈ [mc - mr, mc + mr], x ∈ z}`` as a float zonotope and an error vector.

    Returns
    -------
    image : Zonotope
        ``mc @ c``, ``mc @ G`` computed in floating point.
    error : ndarray, shape (k,)
        ``image ⊕ [-error, error]`` contains the exact set: each computed column is within
        ``γ_n |mc| |col|`` of the exact one, and ``|(M - mc) x| <= mr |x|``.
    """
    mc = np.asarray(mc, dtype=float)
    n = z.dimension
    center = mc @ z.center
    gens = mc @ z.generators
    mag = magnitude(z)
    bound = gamma(n) * (np.abs(mc) @ mag)
    if mr is not None:
        bound = bound + np.asarray(mr, dtype=float) @ mag
    return Zonotope.of_arrays(center, gens), upper(bound, 2 * n + 3)


def minkowski_sum(a: Zonotope, b: Zonotope) -> tuple[Zonotope, np.ndarray]:
    """``a ⊕ b``: the centers added (rounded: error ``<= 2u |sum|``), the generators concatenated (exact)."""
    center = a.center + b.center
    error = upper(2.0 * UNIT_ROUNDOFF * np.abs(center), 2)
    return Zonotope.of_arrays(center, np.hstack([a.generators, b.generators])), error


def box_generators(error: np.ndarray) -> np.ndarray:
    """The diagonal generators of the box ``[-error, error]`` (zero columns dropped), shape ``(n, k)``."""
    e = np.asarray(error, dtype=float)
    keep = np.nonzero(e > 0.0)[0]
    out = np.zeros((e.size, keep.size))
    out[keep, np.arange(keep.size)] = e[keep]
    return out


def with_error(z: Zonotope, error: np.ndarray) -> Zonotope:
    """``z ⊕ [-error, error]`` (exact: the box becomes generators)."""
    return Zonotope.of_arrays(z.center, np.hstack([z.generators, box_generators(error)]))


def from_box(lo: np.ndarray, hi: np.ndarray) -> Zonotope:
    """A zonotope containing the box ``[lo, hi]`` (center rounded, radius rounded up to cover both ends)."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    center = 0.5 * lo + 0.5 * hi  # no overflow for large bounds; rounding covered below
    radius = round_up(np.maximum(round_up(hi - center), round_up(center - lo)))
    return Zonotope(center=center, generators=box_generators(np.maximum(radius, 0.0)))


def interval_hull(z: Zonotope) -> tuple[np.ndarray, np.ndarray]:
    """Bounds ``lo <= x <= hi`` valid for every ``x`` in ``z`` (rounded outward), each shape ``(n,)``."""
    radius = upper(np.abs(z.generators).sum(axis=1), z.order)
    return round_down(round_down(z.center - radius)), round_up(round_up(z.center + radius))


def reduce_order(z: Zonotope, order: int) -> Zonotope:
    """Girard's box reduction to at most ``order · n`` generators (an over-approximation, sound).

    The generators with the smallest ``‖g‖₁ − ‖g‖∞`` (what boxing them costs) are replaced by
    the box of their summed absolute values (rounded up); the others are kept as they are.
    Girard, "Reachability of uncertain linear systems using zonotopes", HSCC 2005, §3.4.
    """
    n, m = z.dimension, z.order
    limit = max(order, 1) * n
    if m <= limit:
        return z
    g = z.generators
    absg = np.abs(g)
    cost = absg.sum(axis=0) - absg.max(axis=0)
    ranking = np.argsort(cost, kind="stable")
    boxed = ranking[: m - limit + n]
    kept = np.sort(ranking[m - limit + n:])
    box = upper(absg[:, boxed].sum(axis=1), boxed.size)
    return Zonotope.of_arrays(z.center, np.hstack([g[:, kept], box_generators(box)]))


def support_bounds(z: Zonotope, normal: np.ndarray, residual: np.ndarray | None = None) -> tuple[float, float]:
    """Rigorous bounds ``lo <= min_{x∈z} a·x`` and ``hi >= max_{x∈z} a·x`` for the exact normal ``a``.

    Parameters
    ----------
    z : Zonotope
    normal : ndarray, shape (n,)
        The float normal ``a_f``.
    residual : ndarray, shape (n,) or None
        ``|a - a_f| <= residual`` componentwise when the exact normal ``a`` is not a float.
    """
    a = np.asarray(normal, dtype=float)
    n = a.size
    s = float(a @ z.center)
    proj = np.abs(z.generators.T @ a)
    spread = float(proj.sum())
    err = gamma(n) * float(np.abs(a) @ (np.abs(z.center) + np.abs(z.generators).sum(axis=1)))
    if residual is not None:
        err += float(np.asarray(residual, dtype=float) @ magnitude(z))
    width = float(upper(spread + err + UNIT_ROUNDOFF * abs(s), z.order + n + 4))
    return float(round_down(round_down(s - width))), float(round_up(round_up(s + width)))
