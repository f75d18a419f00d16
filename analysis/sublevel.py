"""Claims about sublevel sets ``{V <= ρ}`` proven by interval branch and bound on the true functions.

The polynomials here are exact :class:`analysis.polynomial.Polynomial` s in
the atoms ``x``, ``sin x``, ``cos x`` (and auxiliary variables, below), so a
claim is about the real trigonometric functions, not about a
polynomialisation ``s² + c² = 1``.  An SOS search (:mod:`analysis.sos`) is a
floating-point computation with tolerances; the claims below are proven from
the exact (rounded-to-rational) ``V`` alone, which is why the interval
re-check, not the SDP, is the proof.

Invariance and attraction (:func:`certify_sublevel`)
----------------------------------------------------
Given ``V``, its derivative ``V̇ = ∇V · f`` along the field
(:func:`lie_derivative`, exact), a box ``B`` and levels ``0 <= ρ_in < ρ_out``,
the box is tiled by boxes ``X`` each discharged by one of

* *outside*: the enclosure of ``V`` on ``X`` is ``> ρ_out``;
* *inside*: the enclosure of ``V`` on ``X`` is ``< ρ_in`` (needed where
  ``V̇ = 0``, at the equilibrium);
* *decreasing*: the enclosure of ``V̇`` on ``X`` is ``<= 0`` (``< 0`` when ``strict``);

boxes that are none of these are bisected until ``min_width`` or
``max_boxes`` (then the claim is *not* certified, never reported clean),
along the variable of largest *smear* ``|∂p/∂x_j(X)| · width_j`` of the
polynomials that decide the box (``V`` and ``V̇``, each normalised), the
variable whose splitting shrinks the enclosures most.  Separately every face of ``B`` is tiled by boxes on which
``V > ρ_out``.  Proven then: ``S = {x ∈ B : V(x) <= ρ_out}`` does not meet
``∂B``, and every level set ``{V = ρ}``, ``ρ ∈ [ρ_in, ρ_out]``, has a
neighbourhood on which ``V̇ <= 0`` (a point with ``V = ρ`` lies only in
*decreasing* boxes, and the finitely many closed boxes not containing it
leave a neighbourhood of it free), so each ``{x ∈ B : V <= ρ}`` is
positively invariant.  When ``strict``, ``V̇ <= −m < 0`` on the annulus
(``−m`` the largest certified rate bound), so every solution in ``S`` enters
``{V <= ρ_in}`` within ``(ρ_out − ρ_in)/m``.  Region variables declared
``parameters`` (a gain ``k``) are constant along solutions: they have no
faces, and the claim holds for each of their values.

Bounds (:func:`bound_on_sublevel`)
----------------------------------
An upper bound of a polynomial ``p`` (or ``|p|``) over ``{V_i <= ρ_i for
all i} ∩ B``: every box is either excluded (``V_i > ρ_i`` on it for some
``i``) or contributes the upper end of the enclosure of ``p`` on it; the
bound is the maximum of those.  The search keeps the best value found at a
point proven inside the set and stops refining a box whose enclosure is
within ``tolerance`` of it (or, in decision mode, below ``good_enough``); the
bound is valid whatever the budget (a box left unrefined still contributes
its enclosure).  Boxes straddling a set's boundary are split by that set's
smear, the others by ``p``'s.

Enclosures
----------
A polynomial is first reduced modulo ``sin² + cos² = 1``
(:meth:`~analysis.polynomial.Polynomial.reduce_pythagorean`) and every
``cos x`` is then written ``1 − ver x`` with the *versine* ``ver x = 1 − cos x``
as an extra column (the same function, exactly).  Near ``x = 0`` a function
such as ``a δ² (1 − cos α)`` expands to ``a δ² − a δ² cos α``, two large
terms whose interval difference is wide (the dependency problem); with the
versine column it is one small term.  On a box the enclosure of a
polynomial is the intersection of its natural (monomial-wise) interval
evaluation and its mean-value form ``p(m) + Σ_j ∂p/∂y_j(Y) (Y_j − m_j)`` over
the columns ``y`` (region variables, auxiliary variables and versines, each
over its range on the box; sound because the true point lies in that
product box), which is quadratically tight where the natural form is only
linearly tight.

The search evaluates whole batches of boxes at once with numpy, with outward
rounding: every inexact product or quotient is widened by one ulp
(``numpy.nextafter``), sums by the a-priori bound ``2 n u Σ|x_i|`` of
recursive summation (``u = 2⁻⁵³``), two-term sums by TwoSum, exact zeros
kept exact; ``sin``/``cos`` of the endpoints come from ``math`` (libm,
< 1 ulp) widened by ``2⁻⁵⁰``, with interior extrema and the sign of ``sin``
on ``[0, π]`` and of ``cos`` on ``[−π/2, π/2]`` handled as in
:mod:`analysis.interval`.

Certificates are re-checkable: every box is written exactly (``float.hex``),
and :func:`recheck_sublevel` / :func:`recheck_bound` recompute every box's
claim from the written boxes alone and check with
:func:`analysis.certificate.covers` that the boxes cover the box and each
face.  By default (``arithmetic="scalar"``) the boxes are re-evaluated in the
scalar outward-rounded arithmetic of :mod:`analysis.interval` through
:mod:`analysis.certificate`'s enclosures, an implementation independent of
the search's; ``arithmetic="batched"`` re-uses the search's numpy arithmetic
(milliseconds instead of seconds; it re-checks the search's logic, not its
arithmetic).

Auxiliary variables (:class:`Reciprocal`) stand for ``κ = 1/(o + x)`` with
``o`` in an interval (the curvature ``1/ρ`` for a family of radii): a
polynomial may use ``κ`` as a variable, and on a box its range is the
enclosure of ``1/(o + X)``.

Examples
--------
>>> from analysis.polynomial import Polynomial
>>> x, y = Polynomial.atom("x"), Polynomial.atom("y")
>>> v = x**2 + y**2
>>> vdot = lie_derivative(v, {"x": -x + y, "y": -x - y})
>>> cert = certify_sublevel(v, vdot, {"x": (-2.0, 2.0), "y": (-2.0, 2.0)}, rho_out=1.0, rho_in=0.01)
>>> cert.certified, recheck_sublevel(v, vdot, cert)
(True, ())
>>> bound_on_sublevel(x, {"x": (-2.0, 2.0), "y": (-2.0, 2.0)}, sets=[(v, 1.0)]).bound >= 1.0
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.certificate import covers
from analysis.interval import box_bounds
from analysis.polynomial import Polynomial
from analysis.sublevel_enclosure import (
    Box,
    Columns,
    Enclosure,
    Reciprocal,
    ScalarEnclosure,
    SublevelError,
    checked_aux,
    enclose_batch,
    lie_derivative,
    partial_derivative,
)

__all__ = [
    "SUBLEVEL_FORMAT",
    "BOUND_FORMAT",
    "DEFAULT_MAX_BOXES",
    "DEFAULT_MIN_WIDTH",
    "SublevelError",
    "Reciprocal",
    "partial_derivative",
    "lie_derivative",
    "enclose_batch",
    "SublevelCertificate",
    "BoundCertificate",
    "certify_sublevel",
    "bound_on_sublevel",
    "recheck_sublevel",
    "recheck_bound",
    "ARITHMETICS",
]

SUBLEVEL_FORMAT = "analysis.sublevel/1"
"""``"format"`` of :meth:`SublevelCertificate.as_dict`."""
BOUND_FORMAT = "analysis.sublevel.bound/1"
"""``"format"`` of :meth:`BoundCertificate.as_dict`."""
DEFAULT_MAX_BOXES = 100_000
"""Default budget of box evaluations."""
DEFAULT_MIN_WIDTH = 1e-7
"""Default smallest width (relative to the region's width in that variable) that is still split."""

_MARGIN = 1e-9
"""Relative slack between the search's decisions and the re-check's (so that an ulp never flips a claim)."""


# --------------------------------------------------------------------------- inputs and box bookkeeping


def _check_region(region: Mapping[str, tuple[float, float]], *, flat_ok: bool = False,
                  ) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    bounds = box_bounds("region", region, error=SublevelError, allow_flat=flat_ok)
    return (tuple(bounds), np.array([lo for lo, _ in bounds.values()]), np.array([hi for _, hi in bounds.values()]))


def _check_budget(max_boxes: int, min_width: float) -> None:
    if isinstance(max_boxes, bool) or not isinstance(max_boxes, int) or max_boxes < 1:
        raise SublevelError("max_boxes", max_boxes, "an integer >= 1", f"use e.g. {DEFAULT_MAX_BOXES}")
    if not (isinstance(min_width, (int, float)) and math.isfinite(min_width) and min_width >= 0):
        raise SublevelError("min_width", min_width, "a finite number >= 0", f"use e.g. {DEFAULT_MIN_WIDTH}")


def _check_level(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SublevelError(name, value, "a finite number", "give a finite level")
    return float(value)


def _initial(names: tuple[str, ...], lo: np.ndarray, hi: np.ndarray,
             split_at: Mapping[str, Sequence[float]] | None) -> tuple[np.ndarray, np.ndarray]:
    cuts = [[a, b] for a, b in zip(lo, hi)]
    for name, points in (split_at or {}).items():
        if name not in names:
            raise SublevelError("split_at", name, f"a region variable among {list(names)}", "fix the name")
        i = names.index(name)
        inner = sorted({float(p) + 0.0 for p in points if lo[i] < float(p) < hi[i]})
        cuts[i] = [lo[i], *inner, hi[i]]
    boxes: list[list[tuple[float, float]]] = [[]]
    for edges in cuts:
        pieces = list(zip(edges[:-1], edges[1:])) if len(edges) > 2 else [(edges[0], edges[-1])]
        boxes = [b + [piece] for b in boxes for piece in pieces]
    arr = np.array(boxes, dtype=float)
    return arr[:, :, 0].copy(), arr[:, :, 1].copy()


def _split(lo: np.ndarray, hi: np.ndarray, depends: tuple[int, ...], scale: np.ndarray, min_width: float,
           weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bisect each box along one dependent variable; returns the children and a mask of boxes not split.

    The variable is the one with the largest ``weights`` (the smear ``|∂p/∂x_j| · width_j`` of the
    deciding polynomial) among those wider than ``min_width`` relative to the region; without
    weights, the relatively widest.
    """
    if not depends:
        return lo[:0], hi[:0], np.ones(lo.shape[0], dtype=bool)
    dep = np.array(depends)
    rel = (hi[:, dep] - lo[:, dep]) / scale[dep]
    score = rel.copy() if weights is None else np.nan_to_num(weights[:, dep], nan=np.inf, posinf=np.inf) + 1e-9 * rel
    score[rel <= min_width] = -1.0
    pick = np.argmax(score, axis=1)
    j = dep[pick]
    rows = np.arange(lo.shape[0])
    a, b = lo[rows, j], hi[rows, j]
    mid = 0.5 * a + 0.5 * b
    failed = (score[rows, pick] < 0.0) | ~((a < mid) & (mid < b))
    keep = ~failed
    lo, hi, j, mid = lo[keep], hi[keep], j[keep], mid[keep]
    rows = np.arange(lo.shape[0])
    left_hi, right_lo = hi.copy(), lo.copy()
    left_hi[rows, j] = mid
    right_lo[rows, j] = mid
    return np.vstack((lo, right_lo)), np.vstack((left_hi, hi)), failed


def _smears(encs: Sequence[Enclosure], cols: Columns, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Splitting weights: the smears of several polynomials, each normalised to sum 1 per box, added."""
    xlo, xhi = cols.extend(lo, hi)
    total = np.zeros((lo.shape[0], len(cols.names)))
    for enc in encs:
        w = enc.smear(xlo, xhi, cols.owner, len(cols.names))
        with np.errstate(invalid="ignore", divide="ignore"):
            total += np.nan_to_num(w / w.sum(axis=1, keepdims=True), nan=0.0, posinf=1.0)
    return total


class _Search:
    """Box bookkeeping shared by the branch-and-bound loops."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, encs: Sequence[Enclosure], cols: Columns,
                 min_width: float, max_boxes: int, *, fixed: int | None = None) -> None:
        self.depends = tuple(sorted({cols.owner[j] for e in encs for j in e.depends} - {fixed}))
        self.scale = np.where(hi > lo, hi - lo, 1.0)
        self.min_width, self.max_boxes = min_width, max_boxes
        self.examined = 0
        self.failed: list[Box] = []

    def split(self, lo: np.ndarray, hi: np.ndarray, weights: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
        clo, chi, failed = _split(lo, hi, self.depends, self.scale, self.min_width, weights)
        if failed.any():
            self.failed.extend(_boxes(lo[failed], hi[failed])[: max(0, 16 - len(self.failed))])
        return clo, chi


def _boxes(lo: np.ndarray, hi: np.ndarray) -> list[Box]:
    return [tuple(zip(map(float, a), map(float, b))) for a, b in zip(lo.tolist(), hi.tolist())]


def _margin(rho: float) -> float:
    return _MARGIN * max(1.0, abs(rho))


def _hex_box(box: Box) -> list[list[str]]:
    return [[float.hex(a), float.hex(b)] for a, b in box]


def _unhex_box(data: Sequence[Sequence[str]]) -> Box:
    return tuple((float.fromhex(a), float.fromhex(b)) for a, b in data)


def _hex(x: float | None) -> str | None:
    return None if x is None else float.hex(float(x))


def _unhex(x: str | None) -> float | None:
    return None if x is None else float.fromhex(x)


def _aux_from(data: Mapping[str, Any]) -> Reciprocal:
    return Reciprocal(name=str(data["name"]), of=str(data["of"]),
                      offset=(float.fromhex(data["offset"][0]), float.fromhex(data["offset"][1])))


# --------------------------------------------------------------------------- invariance and attraction


@dataclass(frozen=True, kw_only=True, slots=True)
class SublevelCertificate:
    """Outcome of :func:`certify_sublevel` (see the module docstring for the claim).

    Attributes
    ----------
    certified : bool
        True iff the boxes tile the region and its faces and every box's claim holds.
    status : str
        ``"certified"``, ``"counterexample"`` (a point of the annulus with ``V̇ > 0`` proven),
        ``"reaches_boundary"`` (a point of a face with ``V <= ρ_out`` proven), ``"min_width"`` or
        ``"max_boxes"`` (undecided boxes remain).
    claim : str
        The precise statement proven when ``certified``.
    variables : tuple of str
    region : Box
        The box ``B`` (one ``(lo, hi)`` per variable).
    aux : tuple of Reciprocal
    parameters : tuple of str
        Region variables constant along solutions (no faces; the claim holds for each value).
    rho_out, rho_in : float
    strict : bool
    boxes : tuple of Box
        Tiling of ``B``.
    labels : tuple of str
        Per box: ``"outside"`` (``V > ρ_out``), ``"inside"`` (``V < ρ_in``) or ``"decreasing"``.
    rate_bounds : tuple of (float or None)
        Per box: an upper bound of ``V̇`` on it (``None`` unless ``"decreasing"``).
    faces : tuple of (str, str, tuple of Box)
        ``(variable, "lo" | "hi", boxes)``: tilings of the faces of ``B`` with ``V > ρ_out``.
    max_rate : float or None
        Largest rate bound (``−m``); ``None`` when no box needed it.
    entry_time_bound : float or None
        ``(ρ_out − ρ_in)/m`` when ``strict`` (time to enter ``{V <= ρ_in}``).
    counterexample : dict or None
        ``{"point": {...}, "V": (lo, hi), "rate": (lo, hi)}`` for a disproof.
    failed_boxes : tuple of Box
        Undecided boxes (at most 16).
    boxes_examined : int
    method : str
    """

    certified: bool
    status: str
    claim: str
    variables: tuple[str, ...]
    region: Box
    aux: tuple[Reciprocal, ...]
    parameters: tuple[str, ...]
    rho_out: float
    rho_in: float
    strict: bool
    boxes: tuple[Box, ...]
    labels: tuple[str, ...]
    rate_bounds: tuple[float | None, ...]
    faces: tuple[tuple[str, str, tuple[Box, ...]], ...]
    max_rate: float | None
    entry_time_bound: float | None
    counterexample: dict[str, Any] | None
    failed_boxes: tuple[Box, ...]
    boxes_examined: int
    method: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready; every float of the claim in ``float.hex`` (exact), read back by :meth:`from_dict`."""
        return {
            "format": SUBLEVEL_FORMAT, "certified": self.certified, "status": self.status, "claim": self.claim,
            "variables": list(self.variables), "region": _hex_box(self.region),
            "aux": [r.as_dict() for r in self.aux], "parameters": list(self.parameters),
            "rho_out": _hex(self.rho_out), "rho_in": _hex(self.rho_in),
            "strict": self.strict, "boxes": [_hex_box(b) for b in self.boxes], "labels": list(self.labels),
            "rate_bounds": [_hex(r) for r in self.rate_bounds],
            "faces": [[v, side, [_hex_box(b) for b in boxes]] for v, side, boxes in self.faces],
            "max_rate": _hex(self.max_rate), "entry_time_bound": _hex(self.entry_time_bound),
            "counterexample": self.counterexample, "failed_boxes": [_hex_box(b) for b in self.failed_boxes],
            "boxes_examined": self.boxes_examined, "method": self.method,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SublevelCertificate:
        """Inverse of :meth:`as_dict`.

        Raises
        ------
        SublevelError
            Wrong format or a missing/malformed key.
        """
        if not isinstance(data, Mapping) or data.get("format") != SUBLEVEL_FORMAT:
            raise SublevelError("certificate", type(data).__name__, f"a dict with format {SUBLEVEL_FORMAT!r}",
                                "pass SublevelCertificate.as_dict() output")
        try:
            return cls(
                certified=bool(data["certified"]), status=str(data["status"]), claim=str(data["claim"]),
                variables=tuple(data["variables"]), region=_unhex_box(data["region"]),
                aux=tuple(_aux_from(a) for a in data["aux"]), parameters=tuple(data.get("parameters", ())),
                rho_out=float.fromhex(data["rho_out"]),
                rho_in=float.fromhex(data["rho_in"]), strict=bool(data["strict"]),
                boxes=tuple(_unhex_box(b) for b in data["boxes"]), labels=tuple(data["labels"]),
                rate_bounds=tuple(_unhex(r) for r in data["rate_bounds"]),
                faces=tuple((str(v), str(s), tuple(_unhex_box(b) for b in boxes)) for v, s, boxes in data["faces"]),
                max_rate=_unhex(data["max_rate"]), entry_time_bound=_unhex(data["entry_time_bound"]),
                counterexample=data.get("counterexample"),
                failed_boxes=tuple(_unhex_box(b) for b in data.get("failed_boxes", ())),
                boxes_examined=int(data.get("boxes_examined", 0)), method=str(data.get("method", "")))
        except (KeyError, TypeError, ValueError) as err:
            raise SublevelError("certificate", str(err), "every key of SublevelCertificate.as_dict()",
                                "pass an unmodified as_dict() output") from err


def _sublevel_claim(names: tuple[str, ...], region: Box, rho_out: float, rho_in: float, strict: bool,
                    entry: float | None, parameters: tuple[str, ...] = ()) -> str:
    box = " x ".join(f"{n} in [{a:.6g}, {b:.6g}]" for n, (a, b) in zip(names, region) if n not in parameters)
    if parameters:
        ranges = ", ".join(f"{n} in [{a:.6g}, {b:.6g}]" for n, (a, b) in zip(names, region) if n in parameters)
        box += f" (for every value of the parameters {ranges})"
    text = (f"S = {{x in B : V(x) <= {rho_out:.9g}}} with B = {box} does not meet the boundary of B "
            f"(V > {rho_out:.9g} on every face), and dV/dt <= 0 on a neighbourhood of every level set "
            f"{{V = rho}}, {rho_in:.9g} <= rho <= {rho_out:.9g}: every {{x in B : V(x) <= rho}} with rho in that "
            "range is positively invariant")
    if strict and entry is not None:
        text += (f"; dV/dt < 0 on the annulus {{{rho_in:.9g} <= V <= {rho_out:.9g}}}, so every solution starting in "
                 f"S enters {{V <= {rho_in:.9g}}} within {entry:.6g} time units")
    return text


def certify_sublevel(lyapunov: Polynomial, rate: Polynomial, region: Mapping[str, tuple[float, float]], *,
                     rho_out: float, rho_in: float = 0.0, strict: bool = True,
                     split_at: Mapping[str, Sequence[float]] | None = None, aux: Sequence[Reciprocal] = (),
                     parameters: Sequence[str] = (), max_boxes: int = DEFAULT_MAX_BOXES,
                     min_width: float = DEFAULT_MIN_WIDTH) -> SublevelCertificate:
    """Prove that ``{x ∈ B : V <= ρ_out}`` is invariant (and attracted to ``{V <= ρ_in}``) by branch and bound.

    Parameters
    ----------
    lyapunov : Polynomial
        ``V`` (exact, atoms of the region's variables).
    rate : Polynomial
        ``V̇`` along the field (:func:`lie_derivative`).
    region : Mapping[str, (float, float)]
        The box ``B``; key order is the variable order of the certificate.
    rho_out, rho_in : float
        Levels ``0 <= ρ_in < ρ_out`` (``ρ_in`` excludes the equilibrium, where ``V̇ = 0``).
    strict : bool
        Require ``V̇ < 0`` (then the entry-time bound) or only ``V̇ <= 0``.
    split_at : Mapping[str, sequence of float], optional
        Initial cuts (e.g. ``{"alpha": (0.0,)}`` where ``V̇`` vanishes on ``α = 0``).
    aux : sequence of Reciprocal
        Auxiliary variables the polynomials may use.
    parameters : sequence of str
        Region variables that are constant along solutions (a gain ``k`` in a range): they have
        no faces to check, and the claim holds for every value in their range.
    max_boxes : int
        Budget of box evaluations (each face search has its own).
    min_width : float
        Boxes narrower than this fraction of the region in every relevant variable are not split.

    Returns
    -------
    SublevelCertificate
    """
    names, rlo, rhi = _check_region(region)
    _check_budget(max_boxes, min_width)
    rho_out, rho_in = _check_level("rho_out", rho_out), _check_level("rho_in", rho_in)
    if not 0.0 <= rho_in < rho_out:
        raise SublevelError("rho_in", rho_in, f"0 <= rho_in < rho_out = {rho_out}", "choose a smaller inner level")
    parameters = tuple(parameters)
    if any(p not in names for p in parameters) or len(parameters) >= len(names):
        raise SublevelError("parameters", parameters, f"some (not all) of the region variables {list(names)}",
                            "name the parameters among the region's variables")
    cols = Columns(names, checked_aux(aux, names), [lyapunov, rate])
    v_enc, w_enc = Enclosure(lyapunov, cols), Enclosure(rate, cols)
    search = _Search(rlo, rhi, (v_enc, w_enc), cols, float(min_width), max_boxes)
    lo, hi = _initial(names, rlo, rhi, split_at)
    acc: list[tuple[np.ndarray, np.ndarray, str, np.ndarray | None]] = []
    status, counterexample = "", None
    while lo.shape[0]:
        if search.examined >= max_boxes:
            status = "max_boxes"
            search.failed.extend(_boxes(lo, hi)[: max(0, 16 - len(search.failed))])
            break
        search.examined += lo.shape[0]
        lo, hi = _discharge(v_enc, w_enc, cols, lo, hi, rho_in, rho_out, strict, acc)
        if not lo.shape[0]:
            break
        counterexample = _annulus_counterexample(v_enc, w_enc, cols, lo, hi, rho_in, rho_out)
        if counterexample is not None:
            status = "counterexample"
            break
        lo, hi = search.split(lo, hi, _smears((v_enc, w_enc), cols, lo, hi))
    if not status and search.failed:
        status = "min_width"
    faces, face_status = _faces(v_enc, cols, rlo, rhi, rho_out, max_boxes, float(min_width), parameters)
    if not status:
        status = face_status
    return _sublevel_result(status, names, rlo, rhi, cols.aux, rho_out, rho_in, strict, acc, faces, counterexample,
                            search, split_at, parameters)


def _discharge(v_enc: Enclosure, w_enc: Enclosure, cols: Columns, lo: np.ndarray, hi: np.ndarray,
               rho_in: float, rho_out: float, strict: bool,
               acc: list[tuple[np.ndarray, np.ndarray, str, np.ndarray | None]]) -> tuple[np.ndarray, np.ndarray]:
    """Record the boxes of the batch that are outside, inside or decreasing; return the others."""
    xlo, xhi = cols.extend(lo, hi)
    top, bottom = rho_out + _margin(rho_out), rho_in - _margin(rho_in)
    outside = v_enc.lower(xlo, xhi, top) > top
    inside = np.zeros(lo.shape[0], dtype=bool)
    if (~outside).any():
        inside[~outside] = v_enc.upper(xlo[~outside], xhi[~outside], bottom) < bottom
    rest = ~(outside | inside)
    whi = np.full(lo.shape[0], np.nan)
    if rest.any():
        whi[rest] = w_enc.upper(xlo[rest], xhi[rest], 0.0)
    bound = whi + _MARGIN * np.abs(whi)
    with np.errstate(invalid="ignore"):
        decreasing = rest & ((bound < 0.0) if strict else (bound <= 0.0))
    for mask, label in ((outside, "outside"), (inside, "inside"), (decreasing, "decreasing")):
        if mask.any():
            acc.append((lo[mask], hi[mask], label, bound[mask] if label == "decreasing" else None))
    keep = rest & ~decreasing
    return lo[keep], hi[keep]


def _annulus_counterexample(v_enc: Enclosure, w_enc: Enclosure, cols: Columns, lo: np.ndarray, hi: np.ndarray,
                            rho_in: float, rho_out: float) -> dict[str, Any] | None:
    """A box midpoint proven in the annulus with ``V̇ > 0`` (the claim is then false), or None."""
    mid = 0.5 * lo + 0.5 * hi
    xlo, xhi = cols.extend(mid, mid)
    vlo, vhi = v_enc.natural.enclose(xlo, xhi)
    wlo, whi = w_enc.natural.enclose(xlo, xhi)
    bad = (vlo >= rho_in) & (vhi <= rho_out) & (wlo > 0.0)
    if not bad.any():
        return None
    k = int(np.argmax(bad))
    return {"point": {n: float(x) for n, x in zip(cols.names, mid[k])}, "V": [float(vlo[k]), float(vhi[k])],
            "rate": [float(wlo[k]), float(whi[k])]}


def _faces(v_enc: Enclosure, cols: Columns, rlo: np.ndarray, rhi: np.ndarray, rho_out: float, max_boxes: int,
           min_width: float, parameters: tuple[str, ...]) -> tuple[list[tuple[str, str, tuple[Box, ...]]], str]:
    """Tile every face of the region (but the parameters') with boxes on which ``V > ρ_out``."""
    out: list[tuple[str, str, tuple[Box, ...]]] = []
    status = "certified"
    for i, name in enumerate(cols.names):
        if name in parameters:
            continue
        for side in ("lo", "hi"):
            flo, fhi = rlo.copy(), rhi.copy()
            flo[i] = fhi[i] = rlo[i] if side == "lo" else rhi[i]
            lo, hi = flo[None, :], fhi[None, :]
            search = _Search(rlo, rhi, (v_enc,), cols, min_width, max_boxes, fixed=i)
            accepted: list[Box] = []
            while lo.shape[0] and status == "certified":
                if search.examined >= max_boxes:
                    status = "max_boxes"
                    break
                search.examined += lo.shape[0]
                xlo, xhi = cols.extend(lo, hi)
                ok = v_enc.enclose(xlo, xhi)[0] > rho_out + _margin(rho_out)
                accepted.extend(_boxes(lo[ok], hi[ok]))
                lo, hi = lo[~ok], hi[~ok]
                if not lo.shape[0]:
                    break
                mid = 0.5 * lo + 0.5 * hi
                if (v_enc.natural.enclose(*cols.extend(mid, mid))[1] <= rho_out).any():
                    status = "reaches_boundary"
                    break
                lo, hi = search.split(lo, hi, v_enc.smear(*cols.extend(lo, hi), cols.owner, len(cols.names)))
                if search.failed:
                    status = "min_width"
            out.append((name, side, tuple(accepted)))
    return out, status


def _sublevel_result(status: str, names: tuple[str, ...], rlo: np.ndarray, rhi: np.ndarray,
                     aux: tuple[Reciprocal, ...], rho_out: float, rho_in: float, strict: bool,
                     acc: list[tuple[np.ndarray, np.ndarray, str, np.ndarray | None]],
                     faces: list[tuple[str, str, tuple[Box, ...]]], counterexample: dict[str, Any] | None,
                     search: _Search, split_at: Mapping[str, Sequence[float]] | None,
                     parameters: tuple[str, ...]) -> SublevelCertificate:
    boxes: list[Box] = []
    labels: list[str] = []
    rates: list[float | None] = []
    for lo, hi, label, bound in acc:
        boxes.extend(_boxes(lo, hi))
        labels.extend([label] * lo.shape[0])
        rates.extend([None] * lo.shape[0] if bound is None else [float(b) for b in bound])
    known = [r for r in rates if r is not None]
    max_rate = max(known) if known else None
    certified = status == "certified"
    entry = None
    if certified and strict:
        entry = 0.0 if max_rate is None else float(np.nextafter((rho_out - rho_in) / -max_rate, np.inf))
    region = tuple((float(a), float(b)) for a, b in zip(rlo, rhi))
    return SublevelCertificate(
        certified=certified, status=status,
        claim=_sublevel_claim(names, region, rho_out, rho_in, strict, entry, parameters),
        variables=names, region=region, aux=aux, parameters=parameters, rho_out=rho_out, rho_in=rho_in, strict=strict,
        boxes=tuple(boxes), labels=tuple(labels), rate_bounds=tuple(rates), faces=tuple(faces), max_rate=max_rate,
        entry_time_bound=entry, counterexample=counterexample, failed_boxes=tuple(search.failed[:16]),
        boxes_examined=search.examined,
        method=("batched interval branch and bound (natural ∩ mean-value enclosures over region, auxiliary and "
                "versine columns, outward rounded); bisection of the relatively widest dependent variable; "
                f"split_at={dict(split_at or {})}; min_width={search.min_width!r} (relative); "
                f"max_boxes={search.max_boxes}"),
    )


# --------------------------------------------------------------------------- bounds


@dataclass(frozen=True, kw_only=True, slots=True)
class BoundCertificate:
    """Outcome of :func:`bound_on_sublevel`: ``p <= bound`` (or ``|p| <= bound``) on the set.

    Attributes
    ----------
    certified : bool
        The boxes tile the region and every one is excluded or bounded by a finite ``bound``.
    bound : float
        The proven upper bound.
    attained : float or None
        The best value found at a point proven inside the set (auxiliary variables at an end of
        their range); ``bound − attained`` is the gap.
    witness : dict or None
        That point.
    absolute : bool
        Whether the bound is on ``|p|``.
    status : str
        ``"converged"`` (gap within tolerance), ``"decided"`` (below ``good_enough``, not refined further),
        ``"budget"`` (budget spent; the bound is still valid), ``"unbounded"`` (some box has an infinite
        enclosure: not certified).
    variables : tuple of str
    region : Box
    aux : tuple of Reciprocal
    levels : tuple of float
        ``ρ_i`` of the sets ``{V_i <= ρ_i}``, in the order given.
    boxes : tuple of Box
    labels : tuple of str
        ``"excluded:i"`` (``V_i > ρ_i`` on the box) or ``"bounded"``.
    uppers : tuple of (float or None)
        Enclosure upper ends on the bounded boxes.
    boxes_examined : int
    method : str
    """

    certified: bool
    bound: float
    attained: float | None
    witness: dict[str, float] | None
    absolute: bool
    status: str
    variables: tuple[str, ...]
    region: Box
    aux: tuple[Reciprocal, ...]
    levels: tuple[float, ...]
    boxes: tuple[Box, ...]
    labels: tuple[str, ...]
    uppers: tuple[float | None, ...]
    boxes_examined: int
    method: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready; floats of the claim in ``float.hex``."""
        return {
            "format": BOUND_FORMAT, "certified": self.certified, "bound": _hex(self.bound),
            "attained": _hex(self.attained), "witness": self.witness, "absolute": self.absolute,
            "status": self.status, "variables": list(self.variables), "region": _hex_box(self.region),
            "aux": [r.as_dict() for r in self.aux], "levels": [_hex(x) for x in self.levels],
            "boxes": [_hex_box(b) for b in self.boxes], "labels": list(self.labels),
            "uppers": [_hex(u) for u in self.uppers], "boxes_examined": self.boxes_examined, "method": self.method,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> BoundCertificate:
        """Inverse of :meth:`as_dict` (raises :class:`SublevelError` on a malformed dict)."""
        if not isinstance(data, Mapping) or data.get("format") != BOUND_FORMAT:
            raise SublevelError("certificate", type(data).__name__, f"a dict with format {BOUND_FORMAT!r}",
                                "pass BoundCertificate.as_dict() output")
        try:
            return cls(
                certified=bool(data["certified"]), bound=float.fromhex(data["bound"]),
                attained=_unhex(data["attained"]), witness=data.get("witness"), absolute=bool(data["absolute"]),
                status=str(data["status"]), variables=tuple(data["variables"]), region=_unhex_box(data["region"]),
                aux=tuple(_aux_from(a) for a in data["aux"]), levels=tuple(float.fromhex(x) for x in data["levels"]),
                boxes=tuple(_unhex_box(b) for b in data["boxes"]), labels=tuple(data["labels"]),
                uppers=tuple(_unhex(u) for u in data["uppers"]), boxes_examined=int(data.get("boxes_examined", 0)),
                method=str(data.get("method", "")))
        except (KeyError, TypeError, ValueError) as err:
            raise SublevelError("certificate", str(err), "every key of BoundCertificate.as_dict()",
                                "pass an unmodified as_dict() output") from err


def _magnitude(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Enclosure of ``|x|`` for ``x`` in ``[lo, hi]``."""
    low = np.where(lo >= 0.0, lo, np.where(hi <= 0.0, -hi, 0.0))
    return low, np.fmax(np.abs(lo), np.abs(hi))


class _Maximiser:
    """State of the maximisation: the polynomial, the sets and the best value proven attained."""

    def __init__(self, p_enc: Enclosure, v_encs: list[tuple[Enclosure, float]], cols: Columns,
                 absolute: bool, tolerance: float, good_enough: float | None = None) -> None:
        self.p_enc, self.v_encs, self.cols, self.absolute = p_enc, v_encs, cols, absolute
        self.tolerance, self.good_enough = tolerance, good_enough
        self.best, self.witness = -math.inf, None

    def target(self) -> float:
        """Boxes whose upper bound is below this need no further refinement."""
        tight = self.best + self.tolerance * max(abs(self.best), 1e-12) if math.isfinite(self.best) else -math.inf
        return tight if self.good_enough is None else max(tight, self.good_enough)

    def upper(self, xlo: np.ndarray, xhi: np.ndarray) -> np.ndarray:
        plo, phi = self.p_enc.natural.enclose(xlo, xhi)
        out = _magnitude(plo, phi)[1] if self.absolute else phi
        need = ~(out <= self.target())
        if need.any():
            plo, phi = self.p_enc.enclose(xlo[need], xhi[need])
            out[need] = np.fmin(out[need], _magnitude(plo, phi)[1] if self.absolute else phi)
        return out

    def excluded(self, xlo: np.ndarray, xhi: np.ndarray) -> np.ndarray:
        """Per box: index of a set it lies outside of, or -1."""
        which = np.full(xlo.shape[0], -1)
        for i, (enc, rho) in enumerate(self.v_encs):
            open_ = which < 0
            if open_.any():
                vlo = np.full(xlo.shape[0], -np.inf)
                vlo[open_] = enc.lower(xlo[open_], xhi[open_], rho + _margin(rho))
                which[open_ & (vlo > rho + _margin(rho))] = i
        return which

    def weights(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Splitting weights: the smears of the sets a box straddles, or of ``p`` if it straddles none."""
        xlo, xhi = self.cols.extend(lo, hi)
        n = len(self.cols.names)
        total = np.zeros((lo.shape[0], n))
        straddles = np.zeros(lo.shape[0], dtype=bool)
        for enc, rho in self.v_encs:
            open_ = enc.natural.enclose(xlo, xhi)[1] > rho
            if open_.any():
                w = enc.smear(xlo[open_], xhi[open_], self.cols.owner, n)
                with np.errstate(invalid="ignore", divide="ignore"):
                    total[open_] += np.nan_to_num(w / w.sum(axis=1, keepdims=True), nan=0.0, posinf=1.0)
                straddles |= open_
        if (~straddles).any():
            total[~straddles] = self.p_enc.smear(xlo[~straddles], xhi[~straddles], self.cols.owner, n)
        return total

    def try_points(self, points: np.ndarray) -> None:
        """Raise ``best`` with points proven inside every set (each auxiliary column at an end of its range)."""
        xlo, xhi = self.cols.extend(points, points)
        inside = np.ones(points.shape[0], dtype=bool)
        for enc, rho in self.v_encs:
            inside &= enc.natural.enclose(xlo, xhi)[1] <= rho
        if not inside.any():
            return
        xlo, xhi, pts = xlo[inside], xhi[inside], points[inside]
        n = len(self.cols.names)
        value = np.full(pts.shape[0], -np.inf)
        for corner in range(2 ** len(self.cols.aux)):  # each value of an auxiliary variable is attained
            clo, chi = xlo.copy(), xhi.copy()
            for i in range(len(self.cols.aux)):
                end = clo[:, n + i] if (corner >> i) & 1 == 0 else chi[:, n + i]
                clo[:, n + i], chi[:, n + i] = end, end
            vlo, vhi = self.p_enc.natural.enclose(clo, chi)
            value = np.fmax(value, _magnitude(vlo, vhi)[0] if self.absolute else vlo)
        k = int(np.argmax(value))
        if value[k] > self.best:
            self.best, self.witness = float(value[k]), {nm: float(x) for nm, x in zip(self.cols.names, pts[k])}


def bound_on_sublevel(poly: Polynomial, region: Mapping[str, tuple[float, float]], *,
                      sets: Sequence[tuple[Polynomial, float]] = (), absolute: bool = False,
                      aux: Sequence[Reciprocal] = (), tolerance: float = 1e-3,
                      split_at: Mapping[str, Sequence[float]] | None = None,
                      seeds: Sequence[Mapping[str, float]] = (), good_enough: float | None = None,
                      max_boxes: int = DEFAULT_MAX_BOXES, min_width: float = DEFAULT_MIN_WIDTH) -> BoundCertificate:
    """Certified upper bound of ``p`` (or ``|p|``) over ``{x ∈ B : V_i(x) <= ρ_i for all i}``.

    Parameters
    ----------
    poly : Polynomial
        ``p`` (may use auxiliary variables).
    region : Mapping[str, (float, float)]
        The box ``B`` (a range may be a single point, ``lo == hi``).
    sets : sequence of (Polynomial, float)
        The sublevel sets ``(V_i, ρ_i)`` intersected (none: the whole box).
    absolute : bool
        Bound ``|p|`` instead of ``p``.
    aux : sequence of Reciprocal
    tolerance : float
        Relative gap at which a box is no longer refined.
    split_at : Mapping[str, sequence of float], optional
    seeds : sequence of Mapping[str, float]
        Points believed to lie in the set (e.g. where the maximum is expected); each one proven
        inside starts the search's best value (others are ignored).
    good_enough : float, optional
        Decision mode: a box whose enclosure is below this value is not refined (the bound is then
        only guaranteed to be ``<= max(good_enough, tight bound)``: enough to decide ``p <= good_enough``).
    max_boxes, min_width
        As :func:`certify_sublevel`.

    Returns
    -------
    BoundCertificate
    """
    names, rlo, rhi = _check_region(region, flat_ok=True)
    _check_budget(max_boxes, min_width)
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise SublevelError("tolerance", tolerance, "a finite number > 0", "use e.g. 1e-3")
    sets = [(v, _check_level("rho", rho)) for v, rho in sets]
    cols = Columns(names, checked_aux(aux, names), [poly] + [v for v, _ in sets])
    if good_enough is not None and not (isinstance(good_enough, (int, float)) and math.isfinite(good_enough)):
        raise SublevelError("good_enough", good_enough, "a finite number or None", "give the value to decide")
    m = _Maximiser(Enclosure(poly, cols), [(Enclosure(v, cols), rho) for v, rho in sets], cols, absolute,
                   float(tolerance), good_enough)
    search = _Search(rlo, rhi, [m.p_enc] + [e for e, _ in m.v_encs], cols, float(min_width), max_boxes)
    _seed(m, seeds, names, rlo, rhi)
    lo, hi = _initial(names, rlo, rhi, split_at)
    leaves: list[tuple[np.ndarray, np.ndarray, str, np.ndarray | None]] = []
    while lo.shape[0] and search.examined < max_boxes:
        search.examined += lo.shape[0]
        xlo, xhi = cols.extend(lo, hi)
        which = m.excluded(xlo, xhi)
        for i in sorted(set(which.tolist()) - {-1}):
            leaves.append((lo[which == i], hi[which == i], f"excluded:{i}", None))
        keep = which < 0
        lo, hi, xlo, xhi = lo[keep], hi[keep], xlo[keep], xhi[keep]
        if not lo.shape[0]:
            break
        m.try_points(0.5 * lo + 0.5 * hi)
        phi = m.upper(xlo, xhi)
        done = phi <= m.target()
        if done.any():
            leaves.append((lo[done], hi[done], "bounded", phi[done]))
        lo, hi, phi = lo[~done], hi[~done], phi[~done]
        weights = m.weights(lo, hi)
        clo, chi, failed = _split(lo, hi, search.depends, search.scale, search.min_width, weights)
        if failed.any():
            leaves.append((lo[failed], hi[failed], "bounded", phi[failed]))
        lo, hi = clo, chi
    spent = bool(lo.shape[0])
    if spent:  # budget spent: the unrefined boxes still bound p
        leaves.append((lo, hi, "bounded", m.upper(*cols.extend(lo, hi))))
    return _bound_result(leaves, m, names, rlo, rhi, [r for _, r in sets], search, tolerance, spent)


def _seed(m: _Maximiser, seeds: Sequence[Mapping[str, float]], names: tuple[str, ...], rlo: np.ndarray,
          rhi: np.ndarray) -> None:
    if not seeds:
        return
    try:
        points = np.array([[float(p[n]) for n in names] for p in seeds])
    except (KeyError, TypeError, ValueError):
        raise SublevelError("seeds", list(seeds), f"points with a value for each of {list(names)}",
                            "give every seed a value per region variable") from None
    inside = np.all((points >= rlo) & (points <= rhi), axis=1)
    if inside.any():
        m.try_points(points[inside])


def _bound_result(leaves: list[tuple[np.ndarray, np.ndarray, str, np.ndarray | None]], m: _Maximiser,
                  names: tuple[str, ...], rlo: np.ndarray, rhi: np.ndarray, levels: list[float], search: _Search,
                  tolerance: float, spent: bool) -> BoundCertificate:
    boxes: list[Box] = []
    labels: list[str] = []
    uppers: list[float | None] = []
    for lo, hi, label, up in leaves:
        boxes.extend(_boxes(lo, hi))
        labels.extend([label] * lo.shape[0])
        uppers.extend([None] * lo.shape[0] if up is None else [float(u) for u in up])
    known = [u for u in uppers if u is not None]
    finite = all(math.isfinite(u) for u in known)
    if not known:
        bound = -math.inf
    elif finite:
        top = max(known)
        bound = float(np.nextafter(top + _MARGIN * abs(top), np.inf))
    else:
        bound = math.inf
    attained = m.best if math.isfinite(m.best) else None
    close = attained is not None and bound <= attained + 2 * tolerance * max(abs(attained), 1e-12)
    status = "unbounded" if not finite else ("converged" if (close or not known) and not spent else "budget")
    if finite and m.good_enough is not None and bound <= m.good_enough and status != "converged":
        status = "decided"
    return BoundCertificate(
        certified=finite, bound=bound, attained=attained, witness=m.witness, absolute=m.absolute, status=status,
        variables=names, region=tuple((float(a), float(b)) for a, b in zip(rlo, rhi)), aux=m.cols.aux,
        levels=tuple(levels), boxes=tuple(boxes), labels=tuple(labels), uppers=tuple(uppers),
        boxes_examined=search.examined,
        method=("batched interval branch and bound for the maximum (natural ∩ mean-value enclosures, outward "
                f"rounded); tolerance={tolerance!r} relative; min_width={search.min_width!r}; "
                f"max_boxes={search.max_boxes}"),
    )


# --------------------------------------------------------------------------- re-check (scalar arithmetic)


def _well_formed(boxes: Sequence[Box], n: int) -> list[str]:
    return [f"box {k} = {b} is malformed" for k, b in enumerate(boxes)
            if len(b) != n or any(not (math.isfinite(x) and math.isfinite(y) and x <= y) for x, y in b)]


def _holds(test: Any, box: Box) -> bool:
    try:
        return bool(test(box))
    except (ArithmeticError, ValueError, OverflowError):
        return False


ARITHMETICS = ("scalar", "batched")
"""Arithmetics of the re-checks: :mod:`analysis.interval` box by box (independent of the search's), or the
search's batched numpy arithmetic (fast; still recomputed from the written boxes alone)."""


class _Checker:
    """Claims about one polynomial on many written boxes, in the chosen arithmetic."""

    def __init__(self, poly: Polynomial, cols: Columns, arithmetic: str) -> None:
        self.cols, self.arithmetic = cols, arithmetic
        self.scalar = ScalarEnclosure(poly, cols) if arithmetic == "scalar" else None
        self.batched = Enclosure(poly, cols) if arithmetic == "batched" else None

    def _arrays(self, boxes: Sequence[Box]) -> tuple[np.ndarray, np.ndarray]:
        arr = np.array(boxes, dtype=float).reshape(len(boxes), len(self.cols.names), 2)
        return self.cols.extend(arr[:, :, 0].copy(), arr[:, :, 1].copy())

    def above(self, boxes: Sequence[Box], level: float) -> np.ndarray:
        """Per box: the enclosure's lower end is ``> level``."""
        if not boxes:
            return np.zeros(0, dtype=bool)
        if self.batched is not None:
            with np.errstate(invalid="ignore"):
                return self.batched.lower(*self._arrays(boxes), level) > level
        enc = self.scalar
        return np.array([_holds(lambda b: enc.enclose(b, mean_value=False).lo > level or enc.enclose(b).lo > level,
                                self.cols.scalar(box)) for box in boxes], dtype=bool)

    def below(self, boxes: Sequence[Box], levels: Sequence[float], *, strict: bool, absolute: bool = False
              ) -> np.ndarray:
        """Per box: the enclosure's upper end (of ``|p|`` if ``absolute``) is ``< level`` (``<=`` unless strict)."""
        if not boxes:
            return np.zeros(0, dtype=bool)
        levels = np.asarray(levels, dtype=float)
        if self.batched is not None:
            xlo, xhi = self._arrays(boxes)
            if absolute:
                lo, hi = self.batched.enclose(xlo, xhi)
                top = _magnitude(lo, hi)[1]
            else:
                top = self.batched.upper(xlo, xhi, float(np.max(levels)))
                need = ~(top < levels if strict else top <= levels)
                if need.any():
                    top[need] = np.fmin(top[need], self.batched.enclose(xlo[need], xhi[need])[1])
            with np.errstate(invalid="ignore"):
                return top < levels if strict else top <= levels
        enc = self.scalar

        def ok(box: Box, level: float) -> bool:
            for mean_value in (False, True):
                iv = enc.enclose(box, mean_value=mean_value)
                top = max(abs(iv.lo), abs(iv.hi)) if absolute else iv.hi
                if (top < level) if strict else (top <= level):
                    return True
            return False

        return np.array([_holds(lambda b, lv=lv: ok(b, lv), self.cols.scalar(box)) for box, lv in zip(boxes, levels)],
                        dtype=bool)


def _check_arithmetic(arithmetic: str) -> None:
    if arithmetic not in ARITHMETICS:
        raise SublevelError("arithmetic", arithmetic, f"one of {ARITHMETICS}", "use 'scalar' (independent) or 'batched'")


def recheck_sublevel(lyapunov: Polynomial, rate: Polynomial, certificate: SublevelCertificate | Mapping[str, Any],
                     *, region: Mapping[str, tuple[float, float]] | None = None,
                     aux: Sequence[Reciprocal] | None = None, arithmetic: str = "scalar") -> tuple[str, ...]:
    """Reasons why ``certificate`` does not prove its claim about ``V``, ``V̇`` (empty tuple: it does).

    Recomputes every box's label from the written boxes alone and checks that the boxes cover the
    region and each face.

    Parameters
    ----------
    lyapunov, rate : Polynomial
        The ``V`` and ``V̇`` the claim is about (not taken from the certificate).
    certificate : SublevelCertificate or its ``as_dict()``
    region : Mapping, optional
        The expected box (else the certificate's).
    aux : sequence of Reciprocal, optional
        The expected auxiliary variables (else the certificate's).
    arithmetic : str
        One of :data:`ARITHMETICS`: ``"scalar"`` (default) re-evaluates every box in
        :mod:`analysis.interval` arithmetic, independently of the search's.
    """
    _check_arithmetic(arithmetic)
    if isinstance(certificate, Mapping):
        try:
            certificate = SublevelCertificate.from_dict(certificate)
        except SublevelError as err:
            return (f"unreadable certificate: {err}",)
    c = certificate
    problems = _sublevel_preamble(c, region, aux)
    if problems:
        return tuple(problems)
    try:
        cols = Columns(c.variables, c.aux, [lyapunov, rate])
        v, w = _Checker(lyapunov, cols, arithmetic), _Checker(rate, cols, arithmetic)
    except Exception as err:  # noqa: BLE001 - any compile failure is a reason
        return (f"the polynomials do not fit the certificate's variables: {err}",)
    if not covers(c.region, c.boxes):
        problems.append("the boxes do not cover the region")
    ok = np.zeros(len(c.boxes), dtype=bool)
    labels = np.array(c.labels, dtype=object)
    for label in ("outside", "inside", "decreasing"):
        index = np.nonzero(labels == label)[0]
        boxes = [c.boxes[i] for i in index]
        if label == "outside":
            ok[index] = v.above(boxes, c.rho_out)
        elif label == "inside":
            ok[index] = v.below(boxes, [c.rho_in] * len(boxes), strict=True)
        else:
            bounds = [c.rate_bounds[i] for i in index]
            valid = np.array([b is not None and (b < 0.0 if c.strict else b <= 0.0) for b in bounds], dtype=bool)
            ok[index] = valid & w.below(boxes, [b if b is not None else -math.inf for b in bounds], strict=False)
    problems += [f"box {k} = {c.boxes[k]}: the claim {c.labels[k]!r} does not hold on re-check"
                 for k in np.nonzero(~ok)[0]]
    problems += _recheck_faces(v, c)
    problems += _recheck_rates(c)
    return tuple(problems)


def _sublevel_preamble(c: SublevelCertificate, region: Mapping[str, tuple[float, float]] | None,
                       aux: Sequence[Reciprocal] | None) -> list[str]:
    problems: list[str] = []
    if not c.certified:
        problems.append(f"the certificate does not claim certification (status {c.status!r})")
    if region is not None:
        expected = tuple((float(a), float(b)) for a, b in region.values())
        if tuple(region) != c.variables or expected != c.region:
            problems.append(f"region {dict(zip(c.variables, c.region))} differs from the expected {dict(region)}")
    if aux is not None and tuple(aux) != c.aux:
        problems.append(f"auxiliary variables {c.aux} differ from the expected {tuple(aux)}")
    if not 0.0 <= c.rho_in < c.rho_out:
        problems.append(f"levels rho_in = {c.rho_in}, rho_out = {c.rho_out} are not 0 <= rho_in < rho_out")
    if len(c.labels) != len(c.boxes) or len(c.rate_bounds) != len(c.boxes):
        problems.append("labels/rate_bounds do not match the boxes")
    return problems + _well_formed(c.boxes, len(c.variables))


def _recheck_faces(v: _Checker, c: SublevelCertificate) -> list[str]:
    problems = []
    seen = {(name, side) for name, side, _ in c.faces}
    for name in c.variables:
        if name in c.parameters:
            continue
        for side in ("lo", "hi"):
            if (name, side) not in seen:
                problems.append(f"no tiling of the face {name} = {side}")
    for name, side, boxes in c.faces:
        if name not in c.variables or name in c.parameters or side not in ("lo", "hi"):
            problems.append(f"face ({name!r}, {side!r}) is not a face of the region")
            continue
        i = c.variables.index(name)
        x = c.region[i][0 if side == "lo" else 1]
        face = c.region[:i] + ((x, x),) + c.region[i + 1:]
        if _well_formed(boxes, len(c.variables)) or not covers(face, boxes):
            problems.append(f"the boxes of the face {name} = {x!r} do not cover it")
            continue
        above = v.above(list(boxes), c.rho_out)
        problems += [f"face {name} = {x!r}, box {k}: V > rho_out does not hold on re-check"
                     for k in np.nonzero(~above)[0]]
    return problems


def _recheck_rates(c: SublevelCertificate) -> list[str]:
    rates = [r for r, label in zip(c.rate_bounds, c.labels) if label == "decreasing" and r is not None]
    if not rates:
        return []
    top = max(rates)
    if c.max_rate is None or top > c.max_rate:
        return [f"max_rate {c.max_rate!r} is below the largest box rate bound {top!r}"]
    if c.strict and c.certified and (c.entry_time_bound is None
                                      or c.entry_time_bound * -c.max_rate < c.rho_out - c.rho_in):
        return [f"entry_time_bound {c.entry_time_bound!r} is smaller than (rho_out - rho_in)/m"]
    return []


def recheck_bound(poly: Polynomial, sets: Sequence[tuple[Polynomial, float]],
                  certificate: BoundCertificate | Mapping[str, Any], *,
                  region: Mapping[str, tuple[float, float]] | None = None,
                  aux: Sequence[Reciprocal] | None = None, arithmetic: str = "scalar") -> tuple[str, ...]:
    """Reasons why ``certificate`` does not prove ``p <= bound`` (``|p|``) on the set (empty: it does).

    ``sets`` are the ``(V_i, ρ_i)`` the claim is about; their levels must equal the certificate's.
    ``arithmetic`` as in :func:`recheck_sublevel`.
    """
    _check_arithmetic(arithmetic)
    if isinstance(certificate, Mapping):
        try:
            certificate = BoundCertificate.from_dict(certificate)
        except SublevelError as err:
            return (f"unreadable certificate: {err}",)
    c = certificate
    problems = _bound_preamble(c, sets, region, aux)
    if problems:
        return tuple(problems)
    try:
        cols = Columns(c.variables, c.aux, [poly] + [v for v, _ in sets])
        p = _Checker(poly, cols, arithmetic)
        vs = [(_Checker(v, cols, arithmetic), float(r)) for v, r in sets]
    except Exception as err:  # noqa: BLE001
        return (f"the polynomials do not fit the certificate's variables: {err}",)
    if not covers(c.region, c.boxes):
        problems.append("the boxes do not cover the region")
    ok = np.zeros(len(c.boxes), dtype=bool)
    groups: dict[str, list[int]] = {}
    for k, label in enumerate(c.labels):
        groups.setdefault(label, []).append(k)
    for label, index in groups.items():
        boxes = [c.boxes[i] for i in index]
        if label == "bounded":
            ok[index] = p.below(boxes, [c.bound] * len(boxes), strict=False, absolute=c.absolute)
        elif label.startswith("excluded:") and label[9:].isdigit() and int(label[9:]) < len(vs):
            checker, rho = vs[int(label[9:])]
            ok[index] = checker.above(boxes, rho)
    problems += [f"box {k} = {c.boxes[k]}: the claim {c.labels[k]!r} does not hold on re-check"
                 for k in np.nonzero(~ok)[0]]
    return tuple(problems)


def _bound_preamble(c: BoundCertificate, sets: Sequence[tuple[Polynomial, float]],
                    region: Mapping[str, tuple[float, float]] | None, aux: Sequence[Reciprocal] | None) -> list[str]:
    problems: list[str] = []
    if not c.certified or not math.isfinite(c.bound):
        problems.append(f"the certificate does not claim a finite bound (status {c.status!r})")
    if tuple(float(r) for _, r in sets) != c.levels:
        problems.append(f"levels {c.levels} differ from the expected {[r for _, r in sets]}")
    if region is not None and (tuple(region) != c.variables
                               or tuple((float(a), float(b)) for a, b in region.values()) != c.region):
        problems.append(f"region {dict(zip(c.variables, c.region))} differs from the expected {dict(region)}")
    if aux is not None and tuple(aux) != c.aux:
        problems.append(f"auxiliary variables {c.aux} differ from the expected {tuple(aux)}")
    if len(c.labels) != len(c.boxes) or len(c.uppers) != len(c.boxes):
        problems.append("labels/uppers do not match the boxes")
    return problems + _well_formed(c.boxes, len(c.variables))
