"""Rigorous certificates that a polynomial in ``x``, ``sin x``, ``cos x`` is ``<= 0`` on a box.

Typical use: prove that a Lyapunov derivative ``V̇ = ∇V · f`` is
non-positive on a region, *everywhere* and not only at sampled points.
The expression is first put in exact normal form
(:func:`analysis.polynomial.normal_form`), which removes the cancellations
that interval arithmetic cannot see; then :func:`certify_nonpositive`
runs a branch and bound:

1. the region is cut at the points of ``split_at`` (so that a known zero
   set such as ``alpha = 0`` lies on box faces, where exact interval bounds
   reach exactly 0);
2. on each box the polynomial is enclosed by *monomial-wise* interval
   evaluation (:func:`enclose`): every monomial is its exact coefficient's
   enclosure times the interval powers of its atoms (``x`` by the variable's
   interval, ``sin x`` and ``cos x`` by :meth:`Interval.sin` /
   :meth:`Interval.cos` of it), and the monomials are summed, all with
   outward rounding (:mod:`analysis.interval`).  No Horner scheme: the
   normal form is sparse and already exact, and even powers of an atom are
   enclosed tightly (``[-1, 2]**2 = [0, 4]``);
3. a box whose upper bound is ``<= 0`` is accepted; otherwise its midpoint
   is tried as a counterexample (rigorously: the enclosure at the point must
   be ``> 0``), and the box is bisected at the midpoint of its widest variable
   among those the polynomial depends on, unless all of them are narrower
   than ``min_width``, in which case it is recorded as failed.

The result is a :class:`Certificate` listing the accepted boxes, which tile
the region.  :func:`recheck` re-verifies a certificate independently of the
search: it checks that the boxes cover the region (an exact recursive cover
check on the float bounds) and recomputes every box's enclosure.

Examples
--------
>>> from analysis.polynomial import Atom, Polynomial
>>> a, s = Polynomial.atom("alpha"), Polynomial.atom(Atom.sin("alpha"))
>>> vdot = -0.1 * a * s - 0.8 * s**2
>>> cert = certify_nonpositive(vdot, {"alpha": (-3.0, 3.0)}, split_at={"alpha": (0.0,)})
>>> cert.certified, len(cert.boxes)
(True, 2)
>>> recheck(vdot, cert)
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from analysis.interval import Interval
from analysis.polynomial import Atom, Polynomial

# Helpers shared with analysis.sublevel have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = [
    "CERTIFICATE_FORMAT",
    "STATUSES",
    "DEFAULT_MIN_WIDTH",
    "DEFAULT_MAX_BOXES",
    "DEFAULT_MAX_FAILURES",
    "InvalidRegion",
    "InvalidSearchParameter",
    "InvalidCertificate",
    "Box",
    "Certificate",
    "enclose",
    "certify_nonpositive",
    "covers",
    "recheck",
    "recheck_problems",
]

CERTIFICATE_FORMAT = "analysis.certificate/1"
"""Value of the ``"format"`` key of :meth:`Certificate.as_dict`."""
STATUSES = ("certified", "counterexample", "min_width", "max_boxes")
"""Possible :attr:`Certificate.status` values."""
DEFAULT_MIN_WIDTH = 1e-9
"""Default width below which a failing box is not split further (units of the variables)."""
DEFAULT_MAX_BOXES = 200_000
"""Default budget of box evaluations of :func:`certify_nonpositive`."""
DEFAULT_MAX_FAILURES = 16
"""Default number of failed boxes after which :func:`certify_nonpositive` stops."""

Box = tuple[tuple[float, float], ...]
"""An axis-aligned closed box: one ``(lo, hi)`` per variable, in the certificate's variable order."""


# --------------------------------------------------------------------------- errors


class InvalidRegion(ValueError):
    """A region or ``split_at`` that is malformed or does not match the polynomial's variables."""


class InvalidSearchParameter(ValueError):
    """A non-positive budget or width given to :func:`certify_nonpositive`."""


class InvalidCertificate(ValueError):
    """A certificate dictionary that cannot be parsed (missing key, malformed float)."""


# --------------------------------------------------------------------------- the certificate


@dataclass(frozen=True, kw_only=True, slots=True)
class Certificate:
    """Outcome of :func:`certify_nonpositive`: the claim ``p <= 0`` on ``region`` and its evidence.

    Attributes
    ----------
    certified : bool
        True iff the accepted boxes tile the region (then ``p <= 0`` there).
    status : str
        One of :data:`STATUSES`: ``"certified"``; ``"counterexample"`` (a point
        with ``p > 0`` was proven); ``"min_width"`` (some box narrower than
        ``min_width`` could not be accepted); ``"max_boxes"`` (budget exhausted).
    variables : tuple of str
        Variable order of every box (the key order of the region given).
    region : Box
        The region the claim is about.
    boxes : tuple of Box
        Accepted boxes; when ``certified`` they tile ``region``.
    upper_bounds : tuple of float
        Interval upper bound of the polynomial on each accepted box (all ``<= 0``).
    failed_boxes : tuple of Box
        Boxes not accepted when the search stopped: narrower than ``min_width``
        with a positive bound, the box holding the counterexample, or (status
        ``"max_boxes"``) pending boxes; at most ``max_failures``.
    counterexample : tuple of float or None
        A point (in ``variables`` order) where ``p > 0`` is proven.
    counterexample_bounds : tuple of float or None
        Interval enclosure ``(lo, hi)`` of ``p`` at ``counterexample``; ``lo > 0``.
    boxes_examined : int
        Number of box enclosures computed by the search.
    method : str
        How the bounds were obtained (enclosure, splitting rule, parameters).
    polynomial : str
        ``str`` of the polynomial, for the record (:func:`recheck` takes the polynomial itself).
    """

    certified: bool
    status: str
    variables: tuple[str, ...]
    region: Box
    boxes: tuple[Box, ...]
    upper_bounds: tuple[float, ...]
    failed_boxes: tuple[Box, ...] = ()
    counterexample: tuple[float, ...] | None = None
    counterexample_bounds: tuple[float, float] | None = None
    boxes_examined: int = 0
    method: str = ""
    polynomial: str = ""

    def counterexample_point(self) -> dict[str, float] | None:
        """The counterexample as ``{variable: value}``, or None."""
        if self.counterexample is None:
            return None
        return dict(zip(self.variables, self.counterexample))

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary; every float is written exactly with :meth:`float.hex`.

        :meth:`from_dict` inverts it exactly, so :func:`recheck` on a
        certificate read back from JSON checks exactly the same boxes.
        """
        return {
            "format": CERTIFICATE_FORMAT,
            "claim": f"polynomial <= 0 on region (variables {', '.join(self.variables)})",
            "certified": self.certified,
            "status": self.status,
            "variables": list(self.variables),
            "region": _box_hex(self.region),
            "boxes": [_box_hex(b) for b in self.boxes],
            "upper_bounds": [float.hex(u) for u in self.upper_bounds],
            "failed_boxes": [_box_hex(b) for b in self.failed_boxes],
            "counterexample": None if self.counterexample is None else [float.hex(x) for x in self.counterexample],
            "counterexample_bounds": (
                None if self.counterexample_bounds is None else [float.hex(x) for x in self.counterexample_bounds]
            ),
            "boxes_examined": self.boxes_examined,
            "method": self.method,
            "polynomial": self.polynomial,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Certificate:
        """Rebuild a certificate from :meth:`as_dict` output (e.g. after a JSON round trip).

        Raises
        ------
        InvalidCertificate
            Naming the key that is missing or malformed.
        """
        if not isinstance(data, Mapping):
            raise InvalidCertificate(f"certificate data is a {type(data).__name__}: expected a mapping from as_dict()")
        if data.get("format") != CERTIFICATE_FORMAT:
            raise InvalidCertificate(
                f"format = {data.get('format')!r}: expected {CERTIFICATE_FORMAT!r} (a dict from Certificate.as_dict())"
            )
        key = "?"
        try:
            key = "variables"
            variables = tuple(str(v) for v in data["variables"])
            key = "region"
            region = _box_from_hex(data["region"])
            key = "boxes"
            boxes = tuple(_box_from_hex(b) for b in data["boxes"])
            key = "upper_bounds"
            upper = tuple(float.fromhex(u) for u in data["upper_bounds"])
            key = "failed_boxes"
            failed = tuple(_box_from_hex(b) for b in data.get("failed_boxes", ()))
            key = "counterexample"
            cex = data.get("counterexample")
            cex = None if cex is None else tuple(float.fromhex(x) for x in cex)
            key = "counterexample_bounds"
            cexb = data.get("counterexample_bounds")
            cexb = None if cexb is None else (float.fromhex(cexb[0]), float.fromhex(cexb[1]))
            key = "certified"
            certified = data["certified"]
            if not isinstance(certified, bool):
                raise TypeError("not a bool")
            key = "status"
            status = str(data["status"])
            key = "boxes_examined"
            examined = int(data.get("boxes_examined", 0))
        except (KeyError, TypeError, ValueError, IndexError) as err:
            raise InvalidCertificate(
                f"certificate key {key!r} is missing or malformed ({err}); floats must be float.hex strings "
                f"as written by Certificate.as_dict()"
            ) from err
        return cls(
            certified=certified,
            status=status,
            variables=variables,
            region=region,
            boxes=boxes,
            upper_bounds=upper,
            failed_boxes=failed,
            counterexample=cex,
            counterexample_bounds=cexb,
            boxes_examined=examined,
            method=str(data.get("method", "")),
            polynomial=str(data.get("polynomial", "")),
        )


def _box_hex(box: Box) -> list[list[str]]:
    return [[float.hex(lo), float.hex(hi)] for lo, hi in box]


def _box_from_hex(data: Sequence[Sequence[str]]) -> Box:
    box = []
    for pair in data:
        lo, hi = pair
        box.append((float.fromhex(lo), float.fromhex(hi)))
    return tuple(box)


# --------------------------------------------------------------------------- enclosure


@dataclass(frozen=True, slots=True)
class CompiledPolynomial:
    """A polynomial prepared for interval evaluation on boxes over ``variables``."""

    variables: tuple[str, ...]
    atoms: tuple[tuple[str, int], ...]  # (kind, index of the variable in the box)
    terms: tuple[tuple[Interval, tuple[tuple[int, int], ...]], ...]  # (coefficient, ((atom index, power), ...))
    depends: tuple[int, ...]  # indices of variables the polynomial depends on


def compile_polynomial(poly: Polynomial, variables: Sequence[str]) -> CompiledPolynomial:
    """``poly`` prepared for :func:`enclose_compiled` on boxes over ``variables`` (which must bound every variable
    of ``poly``, else :class:`InvalidRegion`)."""
    if not isinstance(poly, Polynomial):
        raise TypeError(
            f"poly is a {type(poly).__name__}: expected an analysis.polynomial.Polynomial "
            f"(build it with normal_form(expr, variables))"
        )
    variables = tuple(variables)
    missing = [v for v in poly.variables if v not in variables]
    if missing:
        raise InvalidRegion(
            f"the polynomial depends on {missing}, which the region does not bound (region variables "
            f"{list(variables)}); add a (lo, hi) range for each"
        )
    atoms: list[Atom] = list(poly.atoms)
    atom_index = {atom: i for i, atom in enumerate(atoms)}
    terms = tuple(
        (Interval.enclosing(c), tuple((atom_index[a], p) for a, p in monomial))
        for monomial, c in poly.terms.items()
    )
    return CompiledPolynomial(
        variables=variables,
        atoms=tuple((a.kind, variables.index(a.variable)) for a in atoms),
        terms=terms,
        depends=tuple(sorted({variables.index(v) for v in poly.variables})),
    )


def enclose_compiled(compiled: CompiledPolynomial, box: Box) -> Interval:
    """An interval enclosing the compiled polynomial over ``box`` (one ``(lo, hi)`` per variable, in order)."""
    var_ivs: dict[int, Interval] = {}
    atom_ivs: list[Interval] = []
    for kind, index in compiled.atoms:
        x = var_ivs.get(index)
        if x is None:
            x = var_ivs[index] = Interval(*box[index])
        atom_ivs.append(x if kind == "var" else x.sin() if kind == "sin" else x.cos())
    total = Interval(0.0, 0.0)
    for coefficient, factors in compiled.terms:
        term = coefficient
        for atom, power in factors:
            term = term * atom_ivs[atom] ** power
        total = total + term
    return total


def enclose(poly: Polynomial, box: Mapping[str, tuple[float, float]]) -> Interval:
    """Interval enclosure of ``poly`` on ``box`` (monomial-wise, outward rounded).

    Parameters
    ----------
    poly : Polynomial
    box : Mapping[str, tuple of float]
        ``(lo, hi)`` for each variable of ``poly`` (extra variables are ignored).

    Returns
    -------
    Interval
        Contains ``poly(x)`` for every ``x`` in the box.

    Examples
    --------
    >>> from analysis.polynomial import Atom, Polynomial
    >>> a, s = Polynomial.atom("alpha"), Polynomial.atom(Atom.sin("alpha"))
    >>> enclose(-a * s, {"alpha": (0.0, 1.0)}).hi
    0.0
    """
    variables, region = _check_region(box)
    return enclose_compiled(compile_polynomial(poly, variables), region)


# --------------------------------------------------------------------------- search


def _check_region(box: Mapping[str, tuple[float, float]]) -> tuple[tuple[str, ...], Box]:
    if not isinstance(box, Mapping) or not box:
        raise InvalidRegion(
            f"box = {box!r}: expected a non-empty mapping {{variable: (lo, hi)}}, e.g. {{'alpha': (-1.0, 1.0)}}"
        )
    variables, bounds = [], []
    for name, pair in box.items():
        try:
            lo, hi = (float(b) for b in pair)
        except (TypeError, ValueError) as err:
            raise InvalidRegion(f"box[{name!r}] = {pair!r}: expected a pair (lo, hi) of numbers") from err
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
            raise InvalidRegion(
                f"box[{name!r}] = ({lo!r}, {hi!r}): expected finite bounds with lo <= hi; fix the range"
            )
        variables.append(str(name))
        bounds.append((lo + 0.0, hi + 0.0))
    return tuple(variables), tuple(bounds)


def _normalise_splits(
    variables: tuple[str, ...], split_at: Mapping[str, Sequence[float]] | None
) -> dict[str, tuple[float, ...]]:
    if split_at is None:
        return {}
    if not isinstance(split_at, Mapping):
        raise InvalidRegion(
            f"split_at = {split_at!r}: expected a mapping {{variable: points}}, e.g. {{'alpha': (0.0,)}}"
        )
    splits: dict[str, tuple[float, ...]] = {}
    for name, points in split_at.items():
        if name not in variables:
            raise InvalidRegion(
                f"split_at names {name!r}, which is not a region variable {list(variables)}; fix the name"
            )
        try:
            splits[name] = (points,) if isinstance(points, (int, float)) else tuple(points)
        except TypeError as err:
            raise InvalidRegion(f"split_at[{name!r}] = {points!r}: expected a sequence of numbers") from err
    return splits


def _initial_boxes(variables: tuple[str, ...], region: Box, splits: Mapping[str, tuple[float, ...]]) -> list[Box]:
    cuts: list[list[float]] = [[lo, hi] for lo, hi in region]
    for name, points in splits.items():
        i = variables.index(name)
        lo, hi = region[i]
        try:
            inner = sorted({float(p) + 0.0 for p in points if lo < float(p) < hi})
        except (TypeError, ValueError) as err:
            raise InvalidRegion(f"split_at[{name!r}] = {points!r}: expected a sequence of numbers") from err
        cuts[i] = [lo, *inner, hi]
    boxes: list[Box] = [()]
    for edges in cuts:
        pieces = list(zip(edges[:-1], edges[1:])) if len(edges) > 2 else [(edges[0], edges[-1])]
        boxes = [box + (piece,) for box in boxes for piece in pieces]
    return boxes


def _split(box: Box, depends: tuple[int, ...], min_width: float) -> tuple[Box, Box] | None:
    best, best_width = -1, min_width
    for i in depends:
        lo, hi = box[i]
        width = hi - lo
        if width > best_width:
            best, best_width = i, width
    if best < 0:
        return None
    lo, hi = box[best]
    mid = 0.5 * lo + 0.5 * hi
    if not lo < mid < hi:
        return None
    return box[:best] + ((lo, mid),) + box[best + 1:], box[:best] + ((mid, hi),) + box[best + 1:]


def _method(splits: Mapping[str, tuple[float, ...]], min_width: float, max_boxes: int) -> str:
    return (
        "branch and bound over axis-aligned boxes; enclosure: monomial-wise interval evaluation of the "
        "exact polynomial normal form (atoms x, sin x, cos x) with outward rounding (analysis.interval); "
        "a box is accepted iff its upper bound is <= 0, otherwise bisected at the midpoint of its widest "
        "variable among those the polynomial depends on; "
        f"initial splits {splits}; min_width={min_width!r}; max_boxes={max_boxes}"
    )


def certify_nonpositive(
    poly: Polynomial,
    box: Mapping[str, tuple[float, float]],
    *,
    max_boxes: int = DEFAULT_MAX_BOXES,
    min_width: float = DEFAULT_MIN_WIDTH,
    split_at: Mapping[str, Sequence[float]] | None = None,
    max_failures: int = DEFAULT_MAX_FAILURES,
) -> Certificate:
    """Prove ``poly <= 0`` on ``box`` by interval branch and bound, or find where it fails.

    Parameters
    ----------
    poly : Polynomial
        Exact normal form (:func:`analysis.polynomial.normal_form`).
    box : Mapping[str, tuple of float]
        Region ``{variable: (lo, hi)}``, finite bounds; its key order is the
        variable order of the certificate.  Must bound every variable of ``poly``.
    max_boxes : int, optional
        Budget of box enclosures; when exhausted the status is ``"max_boxes"``.
    min_width : float, optional
        A failing box whose relevant variables are all at most this wide is
        not split further (recorded in ``failed_boxes``, status ``"min_width"``).
    split_at : Mapping[str, sequence of float], optional
        Points at which the region is cut before any bisection, e.g.
        ``{"alpha": (0.0,)}`` to put the zero set ``alpha = 0`` on box faces.
        Points not strictly inside the range are ignored.
    max_failures : int, optional
        Stop after this many failed boxes.

    Returns
    -------
    Certificate
        ``certified`` is True iff every box was accepted.  The search stops at
        the first proven counterexample (``status == "counterexample"``).

    Raises
    ------
    InvalidRegion
        For a malformed region or ``split_at``, or a variable of ``poly`` not bounded.
    InvalidSearchParameter
        For ``max_boxes``, ``max_failures`` < 1 or a negative / non-finite ``min_width``.
    """
    for name, value in (("max_boxes", max_boxes), ("max_failures", max_failures)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InvalidSearchParameter(f"{name} = {value!r}: expected an integer >= 1")
    if not (isinstance(min_width, (int, float)) and math.isfinite(min_width) and min_width >= 0):
        raise InvalidSearchParameter(
            f"min_width = {min_width!r}: expected a finite width >= 0 (e.g. {DEFAULT_MIN_WIDTH})"
        )
    variables, region = _check_region(box)
    compiled = compile_polynomial(poly, variables)
    splits = _normalise_splits(variables, split_at)
    stack = _initial_boxes(variables, region, splits)
    stack.reverse()
    accepted: list[Box] = []
    bounds: list[float] = []
    failed: list[Box] = []
    counterexample: tuple[float, ...] | None = None
    counterexample_bounds: tuple[float, float] | None = None
    examined = 0
    status = ""
    while stack:
        if examined >= max_boxes:
            status = "max_boxes"
            failed.extend(stack[::-1][: max(0, max_failures - len(failed))])
            break
        current = stack.pop()
        examined += 1
        enclosure = enclose_compiled(compiled, current)
        if enclosure.hi <= 0.0:
            accepted.append(current)
            bounds.append(enclosure.hi)
            continue
        point = tuple(0.5 * lo + 0.5 * hi for lo, hi in current)
        at_point = enclose_compiled(compiled, tuple((x, x) for x in point))
        if at_point.lo > 0.0:
            failed.append(current)
            counterexample, counterexample_bounds = point, (at_point.lo, at_point.hi)
            status = "counterexample"
            break
        halves = _split(current, compiled.depends, min_width)
        if halves is None:
            failed.append(current)
            if len(failed) >= max_failures:
                status = "min_width"
                break
            continue
        stack.append(halves[1])
        stack.append(halves[0])
    if not status:
        status = "min_width" if failed else "certified"
    return Certificate(
        certified=status == "certified",
        status=status,
        variables=variables,
        region=region,
        boxes=tuple(accepted),
        upper_bounds=tuple(bounds),
        failed_boxes=tuple(failed),
        counterexample=counterexample,
        counterexample_bounds=counterexample_bounds,
        boxes_examined=examined,
        method=_method(splits, float(min_width), max_boxes),
        polynomial=str(poly),
    )


# --------------------------------------------------------------------------- re-check


def covers(region: Box, boxes: Sequence[Box]) -> bool:
    """Exactly decide whether the union of closed ``boxes`` contains the closed box ``region``.

    Recursive cover check on the float bounds (no rounding involved): boxes
    are clipped to the current sub-region; those of zero width in a direction
    where the sub-region has positive width are dropped (they cover a
    null set, and a closed union covering a dense subset covers all); if a
    remaining box contains the sub-region it is covered, otherwise the
    sub-region is cut at an inner box face and both parts are checked.
    Overlaps are allowed.

    Examples
    --------
    >>> covers(((0.0, 1.0),), [((0.0, 0.5),), ((0.5, 1.0),)])
    True
    >>> covers(((0.0, 1.0), (0.0, 1.0)), [((0.0, 0.5), (0.0, 1.0)), ((0.5, 1.0), (0.0, 0.9))])
    False
    """
    n = len(region)
    pending: list[tuple[Box, list[Box]]] = [(tuple(region), list(boxes))]
    while pending:
        sub, candidates = pending.pop()
        active = [i for i in range(n) if sub[i][0] < sub[i][1]]
        fat: list[Box] = []
        for box in candidates:
            if len(box) != n:
                return False
            clipped = tuple((max(b[0], s[0]), min(b[1], s[1])) for b, s in zip(box, sub))
            if any(lo > hi for lo, hi in clipped) or any(clipped[i][0] == clipped[i][1] for i in active):
                continue
            fat.append(clipped)
        if not fat:
            return False
        if any(all(box[i] == sub[i] for i in active) for box in fat):
            continue
        best: tuple[float, int, float] | None = None  # (-sub width, dim, cut)
        for i in active:
            lo, hi = sub[i]
            middle = 0.5 * lo + 0.5 * hi
            faces = {b[i][0] for b in fat if b[i][0] > lo} | {b[i][1] for b in fat if b[i][1] < hi}
            if faces:
                cut = min(faces, key=lambda f: abs(f - middle))
                key = (-(hi - lo), i, cut)
                if best is None or key < best:
                    best = key
        if best is None:  # cannot happen: no box contains sub, so some face is inside
            return False
        _, i, cut = best
        left = sub[:i] + ((sub[i][0], cut),) + sub[i + 1:]
        right = sub[:i] + ((cut, sub[i][1]),) + sub[i + 1:]
        pending.append((left, fat))
        pending.append((right, fat))
    return True


def recheck_problems(
    poly: Polynomial,
    certificate: Certificate | Mapping[str, Any],
    *,
    region: Mapping[str, tuple[float, float]] | None = None,
) -> tuple[str, ...]:
    """Reasons why ``certificate`` does not prove ``poly <= 0`` on its region (empty if it does).

    Independent of the search: parses the certificate (a :class:`Certificate`
    or its :meth:`~Certificate.as_dict`), checks that it claims
    ``certified``, that its variables bound every variable of ``poly``, that
    its region equals ``region`` if given, that its boxes cover the region
    (:func:`covers`), and recomputes the enclosure of ``poly`` on every box
    (the stored ``upper_bounds`` are not trusted).
    """
    problems: list[str] = []
    if isinstance(certificate, Mapping):
        try:
            certificate = Certificate.from_dict(certificate)
        except InvalidCertificate as err:
            return (f"unreadable certificate: {err}",)
    if not isinstance(certificate, Certificate):
        return (f"certificate is a {type(certificate).__name__}: expected a Certificate or its as_dict()",)
    if not certificate.certified:
        problems.append(f"the certificate does not claim certification (status {certificate.status!r})")
    variables, cert_region = certificate.variables, certificate.region
    if len(cert_region) != len(variables) or len(set(variables)) != len(variables):
        return (*problems, f"region has {len(cert_region)} ranges for variables {list(variables)}")
    if region is not None:
        expected_vars, expected = _check_region(region)
        if expected_vars != variables or expected != cert_region:
            problems.append(
                f"the certificate's region {dict(zip(variables, cert_region))} differs from the expected "
                f"{dict(zip(expected_vars, expected))}"
            )
    try:
        compiled = compile_polynomial(poly, variables)
    except InvalidRegion as err:
        return (*problems, str(err))
    for k, box in enumerate(certificate.boxes):
        if len(box) != len(variables) or any(not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi) for lo, hi in box):
            problems.append(f"box {k} = {box} is malformed (expected {len(variables)} finite (lo, hi) with lo <= hi)")
    if problems:
        return tuple(problems)
    if not covers(cert_region, certificate.boxes):
        problems.append("the boxes do not cover the region")
    for k, box in enumerate(certificate.boxes):
        upper = enclose_compiled(compiled, box).hi
        if not upper <= 0.0:
            problems.append(f"box {k} = {box}: the enclosure's upper bound is {upper!r} > 0")
    return tuple(problems)


def recheck(
    poly: Polynomial,
    certificate: Certificate | Mapping[str, Any],
    *,
    region: Mapping[str, tuple[float, float]] | None = None,
) -> bool:
    """True iff ``certificate`` proves ``poly <= 0`` on its region; see :func:`recheck_problems`.

    Examples
    --------
    >>> import json
    >>> from analysis.polynomial import Atom, Polynomial
    >>> s = Polynomial.atom(Atom.sin("a"))
    >>> cert = certify_nonpositive(-s**2, {"a": (-4.0, 4.0)})
    >>> recheck(-s**2, json.loads(json.dumps(cert.as_dict())))
    True
    >>> recheck(s, cert)
    False
    """
    return not recheck_problems(poly, certificate, region=region)

