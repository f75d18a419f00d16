"""The enclosures behind :mod:`analysis.sublevel`: batched outward-rounded interval arithmetic over many boxes at
once (numpy), the columns of a region (its variables, their sines, cosines and versines, the reciprocal
auxiliaries), polynomials compiled for it, and the enclosures of a function, its rate and its gradient.

:mod:`analysis.sublevel` re-exports the public names (:class:`SublevelError`, :class:`Reciprocal`,
:func:`partial_derivative`, :func:`lie_derivative`, :func:`enclose_batch`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from analysis.certificate import compile_polynomial, enclose_compiled
from analysis.interval import Interval, IntervalDomainError
from analysis.polynomial import Atom, Polynomial
from hybrid.errors import ParameterError

# Helpers shared with analysis.sublevel have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = ["SublevelError", "Reciprocal", "partial_derivative", "lie_derivative", "enclose_batch", "Box"]


_U = 2.0 ** -53

_TRIG_PAD = 2.0 ** -50

_TINY = 5e-324

Box = tuple[tuple[float, float], ...]


class SublevelError(ParameterError):
    """A bad input to :mod:`analysis.sublevel` (region, level, polynomial, budget)."""

_HALF_ULP_SCALE = 2.0 ** -52

_SUBNORMAL_ZONE = 2.0 ** -1000


def _down(x: np.ndarray) -> np.ndarray:
    """A float ``<=`` every real within half an ulp of ``x`` (``x − |x| 2⁻⁵²``; zeros stay exact).

    ``|x| 2⁻⁵² >= ulp(x)`` exactly (a power-of-two scaling), and the subtraction rounds by at most
    half an ulp, so the result is at most ``x − ulp(x)/2``.  Below ``2⁻¹⁰⁰⁰`` (never reached in
    practice) ``numpy.nextafter`` is used instead.
    """
    out = x - np.abs(x) * _HALF_ULP_SCALE
    tiny = (np.abs(x) < _SUBNORMAL_ZONE) & (x != 0.0)
    if tiny.any():
        out = np.where(tiny, np.nextafter(x, -np.inf), out)
    return out


def _up(x: np.ndarray) -> np.ndarray:
    """A float ``>=`` every real within half an ulp of ``x`` (see :func:`_down`)."""
    out = x + np.abs(x) * _HALF_ULP_SCALE
    tiny = (np.abs(x) < _SUBNORMAL_ZONE) & (x != 0.0)
    if tiny.any():
        out = np.where(tiny, np.nextafter(x, np.inf), out)
    return out


def _imul(alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray, *,
          check_underflow: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Interval product, widened outward (zeros stay exact).

    A nonzero exact product that rounds to 0 (underflow) gets the smallest subnormal on each side;
    callers that know every nonzero factor exceeds ``2⁻⁹⁰`` in magnitude pass ``check_underflow=False``.
    """
    with np.errstate(invalid="ignore", over="ignore"):
        p1, p2, p3, p4 = alo * blo, alo * bhi, ahi * blo, ahi * bhi
        lo = _down(np.minimum(np.minimum(p1, p2), np.minimum(p3, p4)))
        hi = _up(np.maximum(np.maximum(p1, p2), np.maximum(p3, p4)))
    if check_underflow:
        under = np.zeros(np.broadcast(lo, hi).shape, dtype=bool)
        for (x, y), z in zip(((alo, blo), (alo, bhi), (ahi, blo), (ahi, bhi)), (p1, p2, p3, p4)):
            under |= (z == 0.0) & (x != 0.0) & (y != 0.0)
        if np.any(under):
            lo, hi = np.where(under, np.minimum(lo, -_TINY), lo), np.where(under, np.maximum(hi, _TINY), hi)
    return lo, hi


def _no_underflow(*arrays: np.ndarray, factors: int) -> bool:
    """True if no product of ``factors`` nonzero entries of the arrays can underflow (all ``>= 2**(-1000/factors)``)."""
    floor = 2.0 ** (-1000.0 / max(factors, 1))
    for a in arrays:
        m = np.abs(a[a != 0.0]) if a.size else a
        if m.size and not m.min() >= floor:
            return False
    return True


def _round_sum(a: np.ndarray, b: np.ndarray, direction: int) -> np.ndarray:
    """``a + b`` rounded down (``direction < 0``) or up, widened only when TwoSum finds an error that way."""
    with np.errstate(invalid="ignore", over="ignore"):
        s = a + b
        bb = s - a
        err = (a - (s - bb)) + (b - bb)
    if direction < 0:
        return np.where(err < 0, _down(s), s)
    return np.where(err > 0, _up(s), s)


def _iadd(alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return _round_sum(alo, blo, -1), _round_sum(ahi, bhi, 1)


def _pow_magnitude(m: np.ndarray, p: int, direction: int) -> np.ndarray:
    """``m**p`` for ``m >= 0`` rounded down or up by repeated multiplication."""
    r = m
    with np.errstate(over="ignore"):
        for _ in range(p - 1):
            r = r * m
            r = _up(r) if direction > 0 else _down(r)
    if direction > 0 and p > 1:
        r = np.where((r == 0.0) & (m != 0.0), _TINY, r)
    return r


def _ipow(lo: np.ndarray, hi: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    if p == 1:
        return lo, hi
    if p % 2 == 0:
        mlo = np.where(lo >= 0.0, lo, np.where(hi <= 0.0, -hi, 0.0))
        mhi = np.maximum(np.abs(lo), np.abs(hi))
        return _pow_magnitude(mlo, p, -1), _pow_magnitude(mhi, p, 1)
    low = np.where(lo >= 0.0, _pow_magnitude(np.abs(lo), p, -1), -_pow_magnitude(np.abs(lo), p, 1))
    high = np.where(hi >= 0.0, _pow_magnitude(np.abs(hi), p, 1), -_pow_magnitude(np.abs(hi), p, -1))
    return low, high


def _trig(lo: np.ndarray, hi: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Enclosure of ``sin`` or ``cos`` on ``[lo, hi]`` (see the module docstring)."""
    f = math.sin if kind == "sin" else math.cos
    fa = np.fromiter(map(f, lo.tolist()), float, lo.size)
    fb = np.fromiter(map(f, hi.tolist()), float, hi.size)
    rlo = np.minimum(fa, fb) - _TRIG_PAD
    rhi = np.maximum(fa, fb) + _TRIG_PAD
    peak, trough = (0.5 * math.pi, -0.5 * math.pi) if kind == "sin" else (0.0, math.pi)
    two_pi, tol = 2.0 * math.pi, 1e-9
    has_max = np.ceil((lo - peak) / two_pi - tol) <= np.floor((hi - peak) / two_pi + tol)
    has_min = np.ceil((lo - trough) / two_pi - tol) <= np.floor((hi - trough) / two_pi + tol)
    wide = (hi - lo) >= two_pi
    rhi = np.where(has_max | wide, 1.0, np.minimum(rhi, 1.0))
    rlo = np.where(has_min | wide, -1.0, np.maximum(rlo, -1.0))
    zero = (lo == 0.0) & (hi == 0.0)
    if kind == "sin":
        rlo = np.where((lo >= 0.0) & (hi <= math.pi), np.maximum(rlo, 0.0), rlo)
        rhi = np.where((lo >= -math.pi) & (hi <= 0.0), np.minimum(rhi, 0.0), rhi)
    else:
        rlo = np.where((lo >= -0.5 * math.pi) & (hi <= 0.5 * math.pi), np.maximum(rlo, 0.0), rlo)
        rlo, rhi = np.where(zero, 1.0, rlo), np.where(zero, 1.0, rhi)
    return rlo, rhi


@dataclass(frozen=True, kw_only=True, slots=True)
class Reciprocal:
    """Auxiliary variable ``name = 1/(offset + of)`` with ``offset`` anywhere in ``[lo, hi]``.

    Attributes
    ----------
    name : str
        The variable's name in the polynomials (e.g. ``"kappa"``).
    of : str
        The region variable it depends on (e.g. ``"delta"``).
    offset : (float, float)
        Range of the offset (e.g. ``R + d0`` over the obstacles' radii ``R``).
    """

    name: str
    of: str
    offset: tuple[float, float]

    def __post_init__(self) -> None:
        lo, hi = (float(x) for x in self.offset)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise SublevelError("offset", self.offset, "finite (lo, hi) with lo <= hi", "fix the offset range")
        object.__setattr__(self, "offset", (lo, hi))

    def interval(self, x: Interval) -> Interval:
        """Scalar enclosure of ``1/(offset + x)``; ``[-inf, inf]`` if the denominator may vanish."""
        try:
            return 1.0 / (Interval(*self.offset) + x)
        except IntervalDomainError:
            return Interval(-math.inf, math.inf)

    def batch(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Batched enclosure of ``1/(offset + x)`` for ``x`` in ``[lo, hi]``."""
        den_lo = _round_sum(np.full(lo.shape, self.offset[0]), lo, -1)
        den_hi = _round_sum(np.full(lo.shape, self.offset[1]), hi, 1)
        ok = den_lo > 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(ok, _down(1.0 / den_hi), -np.inf), np.where(ok, _up(1.0 / den_lo), np.inf)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (offset in ``float.hex``)."""
        return {"name": self.name, "of": self.of, "offset": [float.hex(self.offset[0]), float.hex(self.offset[1])]}


def _versine_name(variable: str) -> str:
    return f"ver({variable})"


class Columns:
    """The columns of the enclosures: region variables, user auxiliaries, versines of the trigonometric variables."""

    def __init__(self, names: tuple[str, ...], aux: tuple[Reciprocal, ...], polys: Sequence[Polynomial]) -> None:
        self.names, self.aux = names, aux
        trig = {a.variable for p in polys for a in p.atoms if a.kind in ("sin", "cos")}
        self.versines = tuple(v for v in names if v in trig)
        self.all = names + tuple(r.name for r in aux) + tuple(_versine_name(v) for v in self.versines)
        self.owner = tuple(range(len(names))) + tuple(names.index(r.of) for r in aux) + tuple(
            names.index(v) for v in self.versines)

    def extend(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Region boxes ``(N, n)`` -> boxes over all columns."""
        cols_lo, cols_hi = [lo], [hi]
        for r in self.aux:
            j = self.names.index(r.of)
            klo, khi = r.batch(lo[:, j], hi[:, j])
            cols_lo.append(klo[:, None])
            cols_hi.append(khi[:, None])
        for v in self.versines:
            j = self.names.index(v)
            clo, chi = _trig(lo[:, j], hi[:, j], "cos")
            cols_lo.append(np.maximum(_round_sum(np.ones_like(chi), -chi, -1), 0.0)[:, None])
            cols_hi.append(_round_sum(np.ones_like(clo), -clo, 1)[:, None])
        if len(cols_lo) == 1:
            return lo, hi
        return np.hstack(cols_lo), np.hstack(cols_hi)

    def scalar(self, box: Box) -> Box:
        """One region box -> a box over all columns (scalar :mod:`analysis.interval` arithmetic)."""
        extra = []
        for r in self.aux:
            k = r.interval(Interval(*box[self.names.index(r.of)]))
            extra.append((k.lo, k.hi))
        for v in self.versines:
            ver = 1.0 - Interval(*box[self.names.index(v)]).cos()
            extra.append((max(ver.lo, 0.0), ver.hi))
        return tuple(box) + tuple(extra)


def _versine_form(poly: Polynomial, cols: Columns) -> Polynomial:
    """``poly`` reduced modulo ``sin² + cos² = 1`` with ``cos x = 1 − ver x`` (the same function)."""
    return _versine_cached(poly, cols.versines)


@functools.lru_cache(maxsize=512)
def _versine_cached(poly: Polynomial, versines: tuple[str, ...]) -> Polynomial:
    """``cos^p = cos^(p mod 2) (1 − sin²)^(p // 2)``, then ``cos = 1 − ver`` for the versine variables."""
    out: dict[tuple[tuple[Atom, int], ...], Fraction] = {}
    for monomial, coefficient in poly.terms.items():
        expansions: list[tuple[dict[Atom, int], Fraction]] = [({}, Fraction(coefficient))]
        for atom, power in monomial:
            if atom.kind != "cos":
                expansions = [({**pw, atom: pw.get(atom, 0) + power}, c) for pw, c in expansions]
                continue
            sin, half, odd = Atom.sin(atom.variable), power // 2, power % 2
            expansions = [({**pw, sin: pw.get(sin, 0) + 2 * j} if j else dict(pw), c * math.comb(half, j) * (-1) ** j)
                          for pw, c in expansions for j in range(half + 1)]
            if odd and atom.variable in versines:
                ver = Atom.var(_versine_name(atom.variable))
                expansions = [({**pw, ver: 1} if j else dict(pw), -c if j else c) for pw, c in expansions
                              for j in (0, 1)]
            elif odd:
                expansions = [({**pw, atom: 1}, c) for pw, c in expansions]
        for powers, c in expansions:
            key = tuple((a, p) for a, p in powers.items() if p)
            out[key] = out.get(key, Fraction(0)) + c
    return Polynomial(out)


def partial_derivative(poly: Polynomial, variable: str) -> Polynomial:
    """Exact ``∂poly/∂variable`` through the atoms (``sin' = cos``, ``cos' = −sin``)."""
    sin, cos = Atom.sin(variable), Atom.cos(variable)
    out: dict[tuple[tuple[Atom, int], ...], Fraction] = {}
    for monomial, coefficient in poly.terms.items():
        for k, (atom, power) in enumerate(monomial):
            if atom.variable != variable:
                continue
            powers = dict(monomial)
            powers[atom] -= 1
            if not powers[atom]:
                del powers[atom]
            c = Fraction(coefficient) * power
            if atom.kind == "sin":
                powers[cos] = powers.get(cos, 0) + 1
            elif atom.kind == "cos":
                powers[sin] = powers.get(sin, 0) + 1
                c = -c
            key = tuple(powers.items())
            out[key] = out.get(key, Fraction(0)) + c
    return Polynomial(out)


def lie_derivative(poly: Polynomial, rates: Mapping[str, Polynomial]) -> Polynomial:
    """Exact ``Σ_x ∂poly/∂x · ẋ`` over the variables ``poly`` depends on.

    Raises
    ------
    SublevelError
        A variable of ``poly`` without a rate.
    """
    missing = [v for v in poly.variables if v not in rates]
    if missing:
        raise SublevelError("rates", sorted(rates), f"a rate for each of {missing}",
                            "give the rate of every variable the polynomial depends on")
    total = Polynomial({})
    for v in poly.variables:
        total = total + partial_derivative(poly, v) * rates[v]
    return total


class _Compiled:
    """Polynomials (atoms over the columns) stacked for one batched natural enclosure of all of them."""

    __slots__ = ("atoms", "exponents", "clo", "chi", "starts", "constant_rows", "maxpow", "depends", "count")

    def __init__(self, polys: Sequence[Polynomial], columns: Sequence[str]) -> None:
        columns = list(columns)
        for poly in polys:
            missing = [v for v in poly.variables if v not in columns]
            if missing:
                raise SublevelError("polynomial", str(poly)[:120], f"variables among {columns}",
                                    f"bound {missing} in the region (or declare them auxiliary)")
        atoms = sorted({a for poly in polys for a in poly.atoms})
        self.atoms = tuple((a.kind, columns.index(a.variable)) for a in atoms)
        rows: list[tuple[tuple[tuple[Atom, int], ...], Any]] = []
        starts = []
        for poly in polys:
            starts.append(len(rows))
            rows.extend(poly.terms.items() or [((), 0)])
        self.starts, self.count = np.array(starts), len(polys)
        self.exponents = np.zeros((len(rows), len(atoms)), dtype=int)
        bounds = []
        for t, (monomial, c) in enumerate(rows):
            for atom, power in monomial:
                self.exponents[t, atoms.index(atom)] = power
            iv = Interval.enclosing(c)
            bounds.append((iv.lo, iv.hi))
        self.clo, self.chi = (np.array(x) for x in zip(*bounds))
        self.maxpow = self.exponents.max(axis=0) if atoms else np.zeros(0, dtype=int)
        self.constant_rows = ~self.exponents.any(axis=1)
        self.depends = tuple(sorted({columns.index(v) for poly in polys for v in poly.variables}))

    def enclose_all(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Natural enclosures on boxes ``[lo, hi]`` (shape ``(N, columns)``): two ``(polys, N)`` arrays."""
        n_terms, n_boxes = self.exponents.shape[0], lo.shape[0]
        bases = []
        for kind, j in self.atoms:
            bases.append((lo[:, j], hi[:, j]) if kind == "var" else _trig(lo[:, j], hi[:, j], kind))
        factors = int(self.exponents.sum(axis=1).max(initial=0)) + 2
        check = not _no_underflow(self.clo, self.chi, *(x for pair in bases for x in pair), factors=factors)
        flo = fhi = None
        for a, (xlo, xhi) in enumerate(bases):
            top = int(self.maxpow[a])
            table_lo, table_hi = np.ones((top + 1, n_boxes)), np.ones((top + 1, n_boxes))
            for power in range(1, top + 1):
                table_lo[power], table_hi[power] = _ipow(xlo, xhi, power)
            glo, ghi = table_lo[self.exponents[:, a]], table_hi[self.exponents[:, a]]
            if flo is None:
                flo, fhi = glo, ghi
            else:  # multiplying by an exact 1 (exponent 0) only widens by an ulp, and keeps zeros exact
                flo, fhi = _imul(flo, fhi, glo, ghi, check_underflow=check)
        clo = np.broadcast_to(self.clo[:, None], (n_terms, n_boxes))
        chi = np.broadcast_to(self.chi[:, None], (n_terms, n_boxes))
        if flo is None:
            tlo, thi = np.array(clo), np.array(chi)
        else:
            tlo, thi = _imul(clo, chi, flo, fhi, check_underflow=check)
            const = self.constant_rows
            if const.any():
                tlo[const], thi[const] = clo[const], chi[const]
        return _segment_sums(tlo, thi, self.starts)

    def enclose(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The first polynomial's natural enclosure: two ``(N,)`` arrays."""
        rlo, rhi = self.enclose_all(lo, hi)
        return rlo[0], rhi[0]


def _segment_sums(lo: np.ndarray, hi: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward-rounded sums of the row segments (``|fl(Σ) − Σ| <= (n−1) u Σ|x|``, doubled for its own rounding)."""
    counts = np.diff(np.append(starts, lo.shape[0]))
    with np.errstate(invalid="ignore", over="ignore"):
        slo, shi = np.add.reduceat(lo, starts, axis=0), np.add.reduceat(hi, starts, axis=0)
        factor = (2.0 * counts * _U)[:, None]
        elo = factor * np.add.reduceat(np.abs(lo), starts, axis=0)
        ehi = factor * np.add.reduceat(np.abs(hi), starts, axis=0)
        single = (counts == 1)[:, None]
        return (np.where((elo == 0.0) | single, slo, _down(slo - elo)),
                np.where((ehi == 0.0) | single, shi, _up(shi + ehi)))


@functools.lru_cache(maxsize=512)
def _compiled(polys: tuple[Polynomial, ...], columns: tuple[str, ...]) -> _Compiled:
    return _Compiled(polys, columns)


@functools.lru_cache(maxsize=512)
def _partial(poly: Polynomial, variable: str) -> Polynomial:
    return partial_derivative(poly, variable)


class Enclosure:
    """Natural ∩ mean-value enclosure (batched) of one polynomial over the columns."""

    def __init__(self, poly: Polynomial, cols: Columns) -> None:
        self.poly = _versine_form(poly, cols)
        self.natural = _compiled((self.poly,), cols.all)
        self.columns = self.natural.depends
        grads = tuple(_versine_form(_partial(self.poly, cols.all[j]), cols) for j in self.columns)
        self.together = _compiled((self.poly,) + grads, cols.all)

    @property
    def depends(self) -> tuple[int, ...]:
        return self.natural.depends

    def lower(self, lo: np.ndarray, hi: np.ndarray, level: float) -> np.ndarray:
        """Lower ends of the enclosures, the mean-value form computed only where the natural one is ``<= level``."""
        out = self.natural.enclose(lo, hi)[0]
        need = ~(out > level)
        if need.any():
            out[need] = np.fmax(out[need], self.enclose(lo[need], hi[need])[0])
        return out

    def upper(self, lo: np.ndarray, hi: np.ndarray, level: float) -> np.ndarray:
        """Upper ends of the enclosures, the mean-value form computed only where the natural one is ``>= level``."""
        out = self.natural.enclose(lo, hi)[1]
        need = ~(out < level)
        if need.any():
            out[need] = np.fmin(out[need], self.enclose(lo[need], hi[need])[1])
        return out

    def smear(self, lo: np.ndarray, hi: np.ndarray, owner: Sequence[int], n: int) -> np.ndarray:
        """``Σ |∂p/∂y_j| · width(y_j)`` per region variable (columns added to the variable they derive from).

        Shape ``(N, n)``; a splitting heuristic only (rounding does not matter).
        """
        out = np.zeros((lo.shape[0], n))
        if not self.columns or lo.shape[0] == 0:
            return out
        alo, ahi = self.together.enclose_all(lo, hi)
        for g, j in enumerate(self.columns, start=1):
            with np.errstate(invalid="ignore", over="ignore"):
                out[:, owner[j]] += np.fmax(np.abs(alo[g]), np.abs(ahi[g])) * (hi[:, j] - lo[:, j])
        return out

    def enclose(self, lo: np.ndarray, hi: np.ndarray, *, mean_value: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Enclosures on boxes over all columns, shape ``(N, columns)``."""
        if not mean_value or not self.columns or lo.shape[0] == 0:
            return self.natural.enclose(lo, hi)
        alo, ahi = self.together.enclose_all(lo, hi)
        mid = 0.5 * lo + 0.5 * hi
        mlo, mhi = self.natural.enclose(mid, mid)
        for g, j in enumerate(self.columns, start=1):
            dlo = _round_sum(lo[:, j], -mid[:, j], -1)
            dhi = _round_sum(hi[:, j], -mid[:, j], 1)
            tlo, thi = _imul(alo[g], ahi[g], dlo, dhi)
            mlo, mhi = _iadd(mlo, mhi, tlo, thi)
        with np.errstate(invalid="ignore"):
            return np.fmax(alo[0], mlo), np.fmin(ahi[0], mhi)


class ScalarEnclosure:
    """The same enclosure in scalar :mod:`analysis.interval` arithmetic (analysis.certificate's evaluation)."""

    def __init__(self, poly: Polynomial, cols: Columns) -> None:
        form = _versine_form(poly, cols)
        self.natural = compile_polynomial(form, cols.all)
        self.gradient = tuple((cols.all.index(v), compile_polynomial(_versine_form(_partial(form, v), cols), cols.all))
                              for v in form.variables)

    def enclose(self, box: Box, *, mean_value: bool = True) -> Interval:
        natural = enclose_compiled(self.natural, box)
        if not mean_value or not self.gradient:
            return natural
        mid = tuple(0.5 * a + 0.5 * b for a, b in box)
        total = enclose_compiled(self.natural, tuple((m, m) for m in mid))
        for j, grad in self.gradient:
            total = total + enclose_compiled(grad, box) * (Interval(*box[j]) - Interval.point(mid[j]))
        lo, hi = max(natural.lo, total.lo), min(natural.hi, total.hi)
        return Interval(lo, hi) if lo <= hi else natural


def enclose_batch(poly: Polynomial, region: Mapping[str, tuple[float, float]], lo: np.ndarray, hi: np.ndarray, *,
                  aux: Sequence[Reciprocal] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Outward-rounded enclosures (natural ∩ mean-value) of ``poly`` on many boxes at once.

    Parameters
    ----------
    poly : Polynomial
    region : Mapping[str, (float, float)]
        Names the columns of ``lo``/``hi`` (its key order; the ranges themselves are not used).
    lo, hi : numpy.ndarray, shape (N, len(region))
        The boxes.
    aux : sequence of Reciprocal

    Returns
    -------
    (numpy.ndarray, numpy.ndarray), each shape (N,)
    """
    names = tuple(region)
    cols = Columns(names, checked_aux(aux, names), [poly])
    xlo, xhi = cols.extend(np.atleast_2d(np.asarray(lo, float)), np.atleast_2d(np.asarray(hi, float)))
    return Enclosure(poly, cols).enclose(xlo, xhi)


def checked_aux(aux: Sequence[Reciprocal], names: tuple[str, ...]) -> tuple[Reciprocal, ...]:
    """``aux`` as a tuple, or :class:`SublevelError` unless each is a :class:`Reciprocal` of a region variable
    (``names``) with a new name."""
    aux = tuple(aux)
    for r in aux:
        if not isinstance(r, Reciprocal) or r.of not in names or r.name in names:
            raise SublevelError("aux", r, f"Reciprocal of a region variable {list(names)} with a new name",
                                "declare auxiliary variables with Reciprocal(name=..., of=..., offset=...)")
    return aux
