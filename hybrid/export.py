"""Exports of hybrid automata and systems: Graphviz DOT, JSON and SpaceEx XML.

* :func:`to_dot` draws the mode graph (invariants on the nodes; priority,
  guard, crossing direction and resets on the edges).
* :func:`to_json` gives a deterministic, JSON-ready description of a model
  and, for a :class:`~hybrid.system.HybridSystem` with a declared
  :class:`~hybrid.region.Box`, the affine coefficients of every flow,
  invariant term, guard term, jump map and memory reset (or why there are none).
* :func:`to_spacex` and :func:`spacex_config` write a SpaceEx model and its
  configuration, for systems that are affine on the box.

Affinity is decided numerically by :func:`affine_form`: the model's functions
are Python callables, so "affine" means "affine on the declared box, up to a
relative tolerance, on every point tried".  The coefficients are central
differences along each coordinate axis through the centre of the box, so a
coordinate a component does not depend on gets an exact ``0.0`` and slopes
such as ``-0.8`` usually come out exactly; the resulting ``A z + b`` is then
verified on the corners of the box, on random points and with second
differences ``f(c + d) - 2 f(c) + f(c - d)`` along random chords.

Memory variables become SpaceEx variables with flow ``m' == 0.0`` and the
identity assignment unless a transition writes them.  A memory variable that
the box gives a non-degenerate interval (``Box.memory``) is a coordinate of
the affinity test like a state; any other memory variable is held at its
fixed value (the box's degenerate value, else its initial value) and its
contribution folds into the offsets.  A memory variable written by a reset
must therefore have an interval in ``Box.memory``.

Examples
--------
>>> from hybrid import Box, HybridAutomaton, HybridSystem, Mode, Transition, all_of
>>> ball = HybridAutomaton(
...     name="ball", variables=("h", "v"),
...     modes=(Mode(name="fall", invariant=lambda v, m: v[0], invariant_text="h >= 0"),),
...     transitions=(Transition(name="bounce", source="fall", target="fall",
...                             guard=all_of(lambda v, m: -v[0], lambda v, m: -v[1]),
...                             guard_text="h <= 0 and v <= 0"),))
>>> system = HybridSystem(automaton=ball, state_names=("h", "v"),
...     flows={"fall": lambda t, x, m: (x[1], -9.81)},
...     jumps={"bounce": lambda x, m: (x[0], -0.8 * x[1])})
>>> box = Box(bounds={"h": (0.0, 10.0), "v": (-20.0, 20.0)})
>>> form = affine_form(lambda z: system.flow("fall", 0.0, z, {}), ("h", "v"), box)
>>> form.matrix, form.offset
(((0.0, 1.0), (0.0, 0.0)), (0.0, -9.81))
>>> xml = to_spacex(system, box)
>>> "h' == v &amp; v' == -9.81" in xml
True
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from decimal import Decimal
from typing import Any

import numpy as np

from .errors import ModelDefinitionError
from .graph import mode_graph
from .model import Conjunction, HybridAutomaton, Transition
from .region import Box
from .system import HybridSystem

__all__ = [
    "SPACEEX_NAMESPACE",
    "AffineForm",
    "NotAffine",
    "NotAffineError",
    "affine_form",
    "to_dot",
    "to_json",
    "to_spacex",
    "spacex_config",
]

SPACEEX_NAMESPACE = "http://www-verimag.imag.fr/xml-namespaces/sspaceex"
"""XML namespace of SpaceEx model files."""

DEFAULT_SAMPLES = 64
"""Random points (and as many random chords) tried by :func:`affine_form`."""

MAX_CORNERS = 64
"""At most this many vertices of the box are tried (all of them when ``2^d <= 64``)."""

TIME_PROBES = (1.0, 10.0, 1000.0)
"""Times at which flows and the output map are compared with ``t = 0`` (autonomy check)."""

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_ADDRESS = re.compile(r" at 0x[0-9A-Fa-f]+")


# ---------------------------------------------------------------------------- results


@dataclass(frozen=True, kw_only=True, slots=True)
class AffineForm:
    """A vector function found affine on a box: ``f(z) = matrix @ z + offset``.

    Attributes
    ----------
    matrix : tuple of tuple of float
        One row per output component, one column per coordinate of ``names``.
    offset : tuple of float
        One value per output component.
    names : tuple of str
        Coordinate names, the order of ``z``.
    max_residual : float
        Largest relative deviation from affinity seen (residuals ``|f - A z - b|``
        and second differences, each divided by the size of the terms of that
        output component over the points tried, ``max(|f(z)|, |A| |z| + |b|)``).
    points_checked : int
        Number of function evaluations the decision rests on (0 for forms built
        exactly, such as the identity of a missing jump map).
    """

    matrix: tuple[tuple[float, ...], ...]
    offset: tuple[float, ...]
    names: tuple[str, ...]
    max_residual: float
    points_checked: int

    def __call__(self, point: Sequence[float]) -> tuple[float, ...]:
        """``matrix @ point + offset`` evaluated with :func:`math.fsum`."""
        z = [float(c) for c in point]
        if len(z) != len(self.names):
            raise ModelDefinitionError(
                f"AffineForm: got {len(z)} coordinates, expected {len(self.names)} ({', '.join(self.names)})"
            )
        return tuple(math.fsum([a * c for a, c in zip(row, z)] + [b]) for row, b in zip(self.matrix, self.offset))

    def coefficients(self, row: int = 0) -> dict[str, float]:
        """Non-zero coefficients of output component ``row``, keyed by coordinate name."""
        return {n: a for n, a in zip(self.names, self.matrix[row]) if a != 0.0}

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "names": list(self.names),
            "matrix": [list(row) for row in self.matrix],
            "offset": list(self.offset),
            "max_residual": self.max_residual,
            "points_checked": self.points_checked,
        }


@dataclass(frozen=True, kw_only=True, slots=True)
class NotAffine:
    """Why a function is not affine on a box, with a witness.

    Attributes
    ----------
    names : tuple of str
        Coordinate names, the order of ``point`` and ``direction``.
    kind : str
        ``"second difference"``: ``f(point + direction) - 2 f(point) +
        f(point - direction)`` is not zero; ``"residual"``: the affine form
        through the axis differences misses ``f(point)`` (a coupling between
        discrete coordinates); ``"non-finite"``: ``f(point)`` is NaN or
        infinite; ``"time"``: ``f`` at time :attr:`time` differs from ``f`` at
        ``t = 0`` (not autonomous).
    point : tuple of float
        Where the defect shows.
    direction : tuple of float or None
        Half-chord of the second difference (``None`` for the other kinds).
    second_difference : float
        Size of the defect in output component :attr:`component`: the second
        difference, the residual or the change over time (``inf`` when non-finite).
    relative : float
        The defect divided by the size of the terms of that component over
        the points tried (or, for ``"time"``, by the size of the values compared).
    component : int
        Output component that shows the defect.
    tol : float
        Relative tolerance that was exceeded.
    time : float or None
        Probe time of a ``"time"`` defect.
    """

    names: tuple[str, ...]
    kind: str
    point: tuple[float, ...]
    direction: tuple[float, ...] | None
    second_difference: float
    relative: float
    component: int
    tol: float
    time: float | None = None

    @property
    def reason(self) -> str:
        """One sentence naming the defect and the witness."""
        at = _assignment(self.names, self.point)
        if self.kind == "second difference":
            return (
                f"second difference {self.second_difference:.6g} in component {self.component} "
                f"(relative {self.relative:.3g} > tol {self.tol:g}) at point ({at}) "
                f"along direction ({_assignment(self.names, self.direction or ())})"
            )
        if self.kind == "residual":
            return (
                f"affine fit misses the value by {self.second_difference:.6g} in component {self.component} "
                f"(relative {self.relative:.3g} > tol {self.tol:g}) at point ({at})"
            )
        if self.kind == "time":
            return (
                f"depends on time: component {self.component} changes by {self.second_difference:.6g} "
                f"between t = 0 and t = {self.time:g} at point ({at}); the export needs an autonomous "
                "system (add a clock state with flow 1)"
            )
        return f"value is not finite in component {self.component} at point ({at})"

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready description (non-finite numbers as strings)."""
        return {
            "kind": self.kind,
            "reason": self.reason,
            "point": dict(zip(self.names, self.point)),
            "direction": None if self.direction is None else dict(zip(self.names, self.direction)),
            "second_difference": _json_float(self.second_difference),
            "relative": _json_float(self.relative),
            "component": self.component,
            "time": self.time,
        }


class NotAffineError(ModelDefinitionError):
    """A system cannot be exported to SpaceEx: one of its functions is not affine on the box.

    Attributes
    ----------
    what : str
        The function, e.g. ``"guard term 1 of transition 'bounce'"``.
    witness : NotAffine
        The defect and where it shows.
    point, direction : dict of str to float, or None
        The witness point and half-chord by coordinate name.
    second_difference : float
        Size of the defect.
    """

    def __init__(self, system: str, what: str, witness: NotAffine) -> None:
        super().__init__(
            f"system {system!r}: {what} is not affine on the box: {witness.reason}; "
            "SpaceEx needs affine flows, invariants, guards and resets: restrict the box, "
            "or linearise the model before exporting"
        )
        self.system = system
        self.what = what
        self.witness = witness
        self.point = dict(zip(witness.names, witness.point))
        self.direction = None if witness.direction is None else dict(zip(witness.names, witness.direction))
        self.second_difference = witness.second_difference


# ---------------------------------------------------------------------------- affinity


class _Domain:
    """The coordinates ``names`` of a box: intervals (bounds, memory) and finite sets (choices)."""

    def __init__(self, box: Box, names: Sequence[str]) -> None:
        if not isinstance(box, Box):
            raise ModelDefinitionError(f"affinity test: box = {box!r}; expected a hybrid.Box")
        self.names = tuple(names)
        if not self.names:
            raise ModelDefinitionError("affinity test: names is empty; name the coordinates of the argument")
        lo, hi, sets = [], [], {}
        for i, name in enumerate(self.names):
            if name in box.bounds:
                a, b = box.bounds[name]
            elif name in box.choices:
                values = np.unique(np.asarray(box.choices[name], dtype=float))
                sets[i] = values
                a, b = float(values[0]), float(values[-1])
            elif name in box.memory:
                a, b = box.memory[name]
            else:
                raise ModelDefinitionError(
                    f"affinity test: coordinate {name!r} is not declared by the box ({box.describe()}); "
                    "give it bounds, choices or a memory interval"
                )
            lo.append(a)
            hi.append(b)
        self.lo = np.array(lo, dtype=float)
        self.hi = np.array(hi, dtype=float)
        self.sets = sets

    @property
    def dimension(self) -> int:
        return len(self.names)

    def center(self) -> np.ndarray:
        c = 0.5 * (self.lo + self.hi)
        for i, values in self.sets.items():
            c[i] = values[len(values) // 2]
        return c

    def random(self, rng: np.random.Generator, count: int) -> np.ndarray:
        out = rng.uniform(self.lo, self.hi, size=(count, self.dimension))
        for i, values in self.sets.items():
            out[:, i] = rng.choice(values, size=count)
        return out

    def corners(self, limit: int) -> np.ndarray:
        axes = [(a, b) if a < b else (a,) for a, b in zip(self.lo, self.hi)]
        count = min(math.prod(len(a) for a in axes), limit)
        out = np.empty((count, self.dimension))
        for k in range(count):
            rest = k
            for i, axis in enumerate(axes):
                out[k, i] = axis[rest % len(axis)]
                rest //= len(axis)
        return out

    def clip(self, z: np.ndarray) -> np.ndarray:
        return np.clip(z, self.lo, self.hi)


def _evaluate(function: Callable[[tuple[float, ...]], Any], z: np.ndarray, length: int | None) -> np.ndarray:
    value = function(tuple(float(c) for c in z))
    try:
        out = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise ModelDefinitionError(
            f"affinity test: function returned {value!r}; expected a real number or a sequence of them"
        ) from None
    if out.ndim != 1 or (length is not None and out.shape[0] != length):
        raise ModelDefinitionError(
            f"affinity test: function returned shape {out.shape} at {tuple(float(c) for c in z)}, "
            f"expected ({length},) as at the centre of the box"
        )
    return out


def affine_form(
    function: Callable[[tuple[float, ...]], float | Sequence[float]],
    names: Sequence[str],
    box: Box,
    *,
    seed: int = 0,
    samples: int = DEFAULT_SAMPLES,
    tol: float = 1e-9,
) -> AffineForm | NotAffine:
    """Decide numerically whether ``function`` is affine on ``box``, and give its coefficients.

    Parameters
    ----------
    function : callable
        ``f(z) -> float or sequence of float`` where ``z`` is a tuple of one
        value per coordinate of ``names``.
    names : sequence of str
        The coordinates of ``z``, each declared by ``box`` as bounds, choices
        or a memory interval.  A coordinate with a single value gets the
        coefficient ``0`` (its contribution is in the offset).
    box : Box
        The region on which affinity is decided.
    seed : int
        Seed of the random points; the answer is deterministic for a seed.
    samples : int
        Number of random points, and of random chords for second differences.
    tol : float
        Largest accepted relative defect.  Residuals and second differences
        are divided, per output component, by the size of the terms over the
        points tried, ``max_z max(|f(z)|, |A| |z| + |b|)``, so ``1e-9`` leaves
        room for rounding (about ``1e-16``) and rejects any curvature visible
        above it.

    Returns
    -------
    AffineForm or NotAffine
        The form ``A z + b`` when every check passes, else the worst defect
        with its witness (second differences are reported before residuals).

    Raises
    ------
    ModelDefinitionError
        A coordinate the box does not declare, a bad ``tol`` or ``samples``, or
        a function whose output is not a vector of fixed length.  Exceptions
        raised by ``function`` itself propagate unchanged.

    Examples
    --------
    >>> from hybrid import Box
    >>> box = Box(bounds={"x": (-1.0, 3.0)})
    >>> affine_form(lambda z: (2.0 * z[0] - 1.0,), ("x",), box).coefficients()
    {'x': 2.0}
    >>> bad = affine_form(lambda z: z[0] ** 2, ("x",), box)
    >>> bad.kind, bad.second_difference > 0
    ('second difference', True)
    """
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol > 0):
        raise ModelDefinitionError(f"affine_form: tol = {tol!r}; expected a finite positive real (e.g. 1e-9)")
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ModelDefinitionError(f"affine_form: samples = {samples!r}; expected a positive int")
    domain = _Domain(box, names)
    rng = np.random.default_rng(seed)
    d = domain.dimension
    evaluations = 0

    def value(z: np.ndarray, length: int | None) -> np.ndarray:
        nonlocal evaluations
        evaluations += 1
        return _evaluate(function, z, length)

    def non_finite(z: np.ndarray, fz: np.ndarray) -> NotAffine:
        k = int(np.flatnonzero(~np.isfinite(fz))[0])
        return NotAffine(names=domain.names, kind="non-finite", point=_floats(z), direction=None,
                         second_difference=math.inf, relative=math.inf, component=k, tol=float(tol))

    center = domain.center()
    fc = value(center, None)
    p = fc.shape[0]
    if not np.all(np.isfinite(fc)):
        return non_finite(center, fc)
    matrix = np.zeros((p, d))
    for i in range(d):
        lo, hi = domain.lo[i], domain.hi[i]
        if lo == hi:
            continue
        z_lo, z_hi = center.copy(), center.copy()
        z_lo[i], z_hi[i] = lo, hi
        f_lo, f_hi = value(z_lo, p), value(z_hi, p)
        for z, fz in ((z_lo, f_lo), (z_hi, f_hi)):
            if not np.all(np.isfinite(fz)):
                return non_finite(z, fz)
        matrix[:, i] = (f_hi - f_lo) / (hi - lo)
    offset = np.array(
        [math.fsum([float(fc[k])] + [-matrix[k, j] * center[j] for j in range(d) if matrix[k, j] != 0.0])
         for k in range(p)]
    )
    abs_matrix, abs_offset = np.abs(matrix), np.abs(offset)
    # Size of the terms per output component over every point evaluated: the defects are relative to it.
    size = np.abs(fc)
    residuals: list[tuple[np.ndarray, np.ndarray]] = []
    seconds: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def record(z: np.ndarray, fz: np.ndarray) -> None:
        nonlocal size
        size = np.maximum.reduce([size, np.abs(fz), abs_matrix @ np.abs(z) + abs_offset])
        residuals.append((np.abs(fz - (matrix @ z + offset)), z))

    # Second differences along chords: opposite corners, then random chords within the box
    # (discrete coordinates held fixed so that the midpoint stays in the box).
    corners = domain.corners(MAX_CORNERS)
    chords = [(c, domain.clip(domain.lo + domain.hi - c)) for c in corners]
    for i in domain.sets:
        for a, b in chords:
            b[i] = a[i]
    starts = domain.random(rng, samples)
    ends = domain.random(rng, samples)
    for i in domain.sets:
        ends[:, i] = starts[:, i]
    chords += list(zip(starts, ends))
    for a, b in chords:
        mid, half = 0.5 * (a + b), 0.5 * (b - a)
        if not np.any(half):
            continue
        minus, plus = domain.clip(mid - half), domain.clip(mid + half)
        f_minus, f_mid, f_plus = value(minus, p), value(mid, p), value(plus, p)
        for z, fz in ((minus, f_minus), (mid, f_mid), (plus, f_plus)):
            if not np.all(np.isfinite(fz)):
                return non_finite(z, fz)
            record(z, fz)
        seconds.append((np.abs(f_plus - 2.0 * f_mid + f_minus), mid, half))
    # Fresh points, never used above, and the corners themselves.
    for z in list(corners) + list(domain.random(rng, samples)):
        fz = value(z, p)
        if not np.all(np.isfinite(fz)):
            return non_finite(z, fz)
        record(z, fz)

    def relative(defect: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(defect == 0.0, 0.0, defect / size)

    worst = 0.0
    if seconds:
        rel = [relative(defect) for defect, _, _ in seconds]
        j = max(range(len(seconds)), key=lambda i: float(rel[i].max()))
        k = int(np.argmax(rel[j]))
        worst = float(rel[j][k])
        if worst > tol:
            defect, mid, half = seconds[j]
            return NotAffine(names=domain.names, kind="second difference", point=_floats(mid),
                             direction=_floats(half), second_difference=float(defect[k]), relative=worst,
                             component=k, tol=float(tol))
    rel = [relative(defect) for defect, _ in residuals]
    j = max(range(len(residuals)), key=lambda i: float(rel[i].max()))
    k = int(np.argmax(rel[j]))
    if rel[j][k] > tol:
        defect, z = residuals[j]
        return NotAffine(names=domain.names, kind="residual", point=_floats(z), direction=None,
                         second_difference=float(defect[k]), relative=float(rel[j][k]), component=k,
                         tol=float(tol))
    worst = max(worst, float(rel[j][k]))
    return AffineForm(
        matrix=tuple(_floats(row) for row in matrix),
        offset=_floats(offset),
        names=domain.names,
        max_residual=worst,
        points_checked=evaluations,
    )


def _floats(values: Any) -> tuple[float, ...]:
    return tuple(0.0 if float(c) == 0.0 else float(c) for c in values)


def _assignment(names: Sequence[str], values: Sequence[float]) -> str:
    return ", ".join(f"{n}={float(c):.10g}" for n, c in zip(names, values))


# ---------------------------------------------------------------------------- system analysis


@dataclass(frozen=True, slots=True)
class _Coordinates:
    """Coordinates of the affinity test of a system: its states, then its free memory variables."""

    states: tuple[str, ...]
    free_memory: tuple[str, ...]
    fixed_memory: Mapping[str, float]

    @property
    def names(self) -> tuple[str, ...]:
        return self.states + self.free_memory

    def split(self, z: Sequence[float]) -> tuple[tuple[float, ...], dict[str, float]]:
        n = len(self.states)
        memory = dict(self.fixed_memory)
        memory.update(zip(self.free_memory, (float(c) for c in z[n:])))
        return tuple(float(c) for c in z[:n]), memory


def _coordinates(system: HybridSystem, box: Box, what: str) -> _Coordinates:
    if not isinstance(box, Box):
        raise ModelDefinitionError(f"{what}: box = {box!r}; expected a hybrid.Box over {list(system.state_names)}")
    box.require(system.state_names, what)
    a = system.automaton
    clash = sorted(set(system.state_names) & {m.name for m in a.memory})
    if clash:
        raise ModelDefinitionError(
            f"{what}: memory variable(s) {clash} have the name of a state; rename one of them"
        )
    declared = {m.name for m in a.memory}
    unknown = [n for n in box.memory if n not in declared]
    if unknown:
        raise ModelDefinitionError(
            f"{what}: Box.memory names unknown memory variable(s) {unknown}; declared memory: {sorted(declared)}"
        )
    written = {w for t in a.transitions for w in t.writes}
    free, fixed = [], {}
    for m in a.memory:
        interval = box.memory.get(m.name)
        if interval is not None and interval[0] < interval[1]:
            free.append(m.name)
            continue
        if m.name in written:
            raise ModelDefinitionError(
                f"{what}: memory variable {m.name!r} is written by a reset but the box gives it no interval; "
                f"declare Box.memory[{m.name!r}] = (lower, upper) covering the values it takes"
            )
        fixed[m.name] = float(interval[0]) if interval is not None else float(m.initial)
    return _Coordinates(tuple(system.state_names), tuple(free), fixed)


def _terms(function: Callable[..., float]) -> tuple[Callable[..., float], ...]:
    return function.terms if isinstance(function, Conjunction) else (function,)


def _time_defect(
    function: Callable[[float, tuple[float, ...]], Any], points: np.ndarray, names: tuple[str, ...], tol: float
) -> NotAffine | None:
    """``None`` when ``function(t, z)`` does not change with ``t`` at ``points``."""
    for z in points:
        zt = tuple(float(c) for c in z)
        base = np.atleast_1d(np.asarray(function(0.0, zt), dtype=float))
        for t in TIME_PROBES:
            later = np.atleast_1d(np.asarray(function(t, zt), dtype=float))
            defect = np.abs(later - base)
            size = np.maximum(np.abs(later), np.abs(base))
            k = int(np.argmax(defect))
            if defect[k] > tol * size[k]:
                return NotAffine(names=names, kind="time", point=zt, direction=None,
                                 second_difference=float(defect[k]), relative=float(defect[k] / size[k]),
                                 component=k, tol=tol, time=t)
    return None


_Result = AffineForm | NotAffine


@dataclass(frozen=True, slots=True)
class _Analysis:
    coordinates: _Coordinates
    modes: Mapping[str, tuple[_Result, tuple[_Result, ...]]]
    transitions: Mapping[str, tuple[tuple[_Result, ...], _Result, _Result | None]]

    def items(self) -> list[tuple[str, _Result]]:
        """Every analysed function with a human name, in model order."""
        out: list[tuple[str, _Result]] = []
        for mode, (flow, invariant) in self.modes.items():
            out.append((f"flow of mode {mode!r}", flow))
            out += [(f"invariant term {k} of mode {mode!r}", r) for k, r in enumerate(invariant)]
        for name, (guard, jump, memory) in self.transitions.items():
            out += [(f"guard term {k} of transition {name!r}", r) for k, r in enumerate(guard)]
            out.append((f"jump map of transition {name!r}", jump))
            if memory is not None:
                out.append((f"memory reset of transition {name!r}", memory))
        return out


def _analyse(system: HybridSystem, box: Box, *, tol: float, seed: int, what: str) -> _Analysis:
    coords = _coordinates(system, box, what)
    names = coords.names
    domain = _Domain(box, names)
    probes = np.vstack([domain.center()[None, :], domain.random(np.random.default_rng(seed), 3)])
    n = len(coords.states)

    def check(function: Callable[[tuple[float, ...]], Any],
              timed: Callable[[float, tuple[float, ...]], Any] | None) -> _Result:
        result = affine_form(function, names, box, seed=seed, tol=tol)
        if isinstance(result, AffineForm) and timed is not None:
            return _time_defect(timed, probes, names, tol) or result
        return result

    def flow_of(mode: str) -> Callable[[float, tuple[float, ...]], tuple[float, ...]]:
        def f(t: float, z: tuple[float, ...]) -> tuple[float, ...]:
            x, m = coords.split(z)
            return system.flow(mode, t, x, m)
        return f

    def condition(term: Callable[..., float]) -> Callable[[float, tuple[float, ...]], float]:
        def g(t: float, z: tuple[float, ...]) -> float:
            x, m = coords.split(z)
            return term(system.signals(t, x), m)
        return g

    def at_zero(timed: Callable[[float, tuple[float, ...]], Any]) -> Callable[[tuple[float, ...]], Any]:
        return lambda z: timed(0.0, z)

    a = system.automaton
    modes: dict[str, tuple[_Result, tuple[_Result, ...]]] = {}
    for mode in a.modes:
        flow = flow_of(mode.name)
        invariant: tuple[_Result, ...] = ()
        if mode.invariant is not None:
            invariant = tuple(
                check(at_zero(condition(term)), condition(term)) for term in _terms(mode.invariant)
            )
        modes[mode.name] = (check(at_zero(flow), flow), invariant)
    transitions: dict[str, tuple[tuple[_Result, ...], _Result, _Result | None]] = {}
    for t in a.transitions:
        guard = tuple(check(at_zero(condition(term)), condition(term)) for term in _terms(t.guard))
        if t.name in system.jumps:
            def jump(z: tuple[float, ...], name: str = t.name) -> tuple[float, ...]:
                x, m = coords.split(z)
                return system.jump(name, 0.0, x, m)
            jump_result = check(jump, None)
        else:
            identity = tuple(tuple(1.0 if j == i else 0.0 for j in range(len(names))) for i in range(n))
            jump_result = AffineForm(matrix=identity, offset=(0.0,) * n, names=names, max_residual=0.0,
                                     points_checked=0)
        memory_result = None
        if t.writes:
            memory_result = check(_memory_reset(system, t, coords), None)
        transitions[t.name] = (guard, jump_result, memory_result)
    return _Analysis(coords, modes, transitions)


def _memory_reset(system: HybridSystem, t: Transition, coords: _Coordinates) -> Callable[[tuple[float, ...]], list]:
    def reset(z: tuple[float, ...]) -> list[float]:
        x, m = coords.split(z)
        new = t.reset(system.signals(0.0, x), m)  # type: ignore[misc]
        if set(new) != set(t.writes):
            raise ModelDefinitionError(
                f"system {system.name!r}: reset of transition {t.name!r} returned keys {sorted(new)}, "
                f"expected exactly writes = {list(t.writes)}"
            )
        return [new[w] for w in t.writes]
    return reset


# ---------------------------------------------------------------------------- DOT


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


_ARROWS = {1: " ↑", -1: " ↓", 0: ""}


def to_dot(model: HybridAutomaton | HybridSystem) -> str:
    """Graphviz DOT text of the mode graph.

    Nodes carry the mode name and invariant text (description as tooltip);
    edges carry ``[priority] guard`` followed by ``↑`` / ``↓`` for a rising /
    falling crossing, then ``/`` and the reset text (the written memory when
    the reset has no text) and, for a system, ``x⁺ = jump map`` when the
    transition has one.  A point node ``__start__`` points at the initial mode.
    Every identifier is quoted; output order is declaration order.

    Parameters
    ----------
    model : HybridAutomaton or HybridSystem

    Returns
    -------
    str
        DOT text ending with a newline.

    Examples
    --------
    >>> from hybrid import HybridAutomaton, Mode, Transition
    >>> a = HybridAutomaton(name="a", modes=(Mode(name="x"), Mode(name="y")), variables=("s",),
    ...     transitions=(Transition(name="go", source="x", target="y", guard=lambda v, m: v[0],
    ...                             guard_text="s >= 0", direction=+1),))
    >>> print(to_dot(a).splitlines()[-2])
      "x" -> "y" [label="[0] s >= 0 ↑"];
    """
    automaton, jumps = _automaton(model, "to_dot")
    graph = mode_graph(automaton)
    start = "__start__"
    while start in automaton.mode_names:
        start += "_"
    lines = [f"digraph {_quote(automaton.name)} {{", "  rankdir=LR;", "  node [shape=box, style=rounded];"]
    lines.append(f'  {_quote(start)} [shape=point, label=""];')
    lines.append(f"  {_quote(start)} -> {_quote(automaton.initial_mode)};")
    for name, data in graph.nodes(data=True):
        label = name if not data["invariant"] else f"{name}\ninv: {data['invariant']}"
        attributes = f"label={_quote(label)}"
        if data["description"]:
            attributes += f", tooltip={_quote(data['description'])}"
        lines.append(f"  {_quote(name)} [{attributes}];")
    by_name = {t.name: t for t in automaton.transitions}
    for source, target, key, data in graph.edges(keys=True, data=True):
        label = f"[{data['priority']}] {data['guard'] or key}{_ARROWS[data['direction']]}"
        parts = []
        if data["reset"]:
            parts.append(data["reset"])
        elif by_name[key].reset is not None:
            parts.append(f"reset {', '.join(by_name[key].writes) or 'memory'}")
        if key in jumps:
            parts.append("x⁺ = jump map")
        if parts:
            label += " / " + "; ".join(parts)
        lines.append(f"  {_quote(source)} -> {_quote(target)} [label={_quote(label)}];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _automaton(model: object, what: str) -> tuple[HybridAutomaton, Mapping[str, Any]]:
    if isinstance(model, HybridSystem):
        return model.automaton, model.jumps
    if isinstance(model, HybridAutomaton):
        return model, {}
    raise ModelDefinitionError(f"{what}: model = {model!r}; expected a HybridAutomaton or a HybridSystem")


# ---------------------------------------------------------------------------- JSON


def _json_float(x: float) -> float | str:
    x = float(x)
    return x if math.isfinite(x) else repr(x)


def _json_safe(value: Any) -> Any:
    """A JSON-ready, deterministic copy of ``value`` (labels are arbitrary user data)."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return _json_float(float(value))
    if isinstance(value, np.ndarray):
        return _json_safe(value.tolist())
    if isinstance(value, Mapping):
        return {str(k): _json_safe(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (set, frozenset)):
        return sorted((_json_safe(v) for v in value), key=repr)
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return _ADDRESS.sub("", repr(value))


def _result_json(result: _Result | None) -> dict[str, Any] | None:
    return result.as_dict() if isinstance(result, AffineForm) else None


def to_json(
    model: HybridAutomaton | HybridSystem, box: Box | None = None, *, tol: float = 1e-9, seed: int = 0
) -> dict[str, Any]:
    """A JSON-ready, deterministic description of an automaton or a system.

    Parameters
    ----------
    model : HybridAutomaton or HybridSystem
    box : Box or None
        With a system, the region on which to test affinity; every mode and
        transition then gets an ``"affine"`` entry (see below).  ``None``
        leaves the entries ``null``.
    tol, seed
        Passed to :func:`affine_form`.

    Returns
    -------
    dict
        Keys ``kind``, ``name``, ``description``, ``variables``,
        ``state_names`` (``null`` for an automaton), ``memory``,
        ``initial_mode``, ``modes``, ``transitions`` and ``affinity``
        (``null`` without a box, else the box, the coordinates of the
        coefficient columns, the fixed memory values and the tolerance).
        A mode's ``"affine"`` is ``{"flow": form, "invariant": [form, ...],
        "not_affine": {...}}`` and a transition's is ``{"guard": [form, ...],
        "jump_map": form, "memory_reset": form, "not_affine": {...}}``; a form
        is ``{"names", "matrix", "offset", "max_residual", "points_checked"}``
        or ``null`` when the function is not affine, and then ``not_affine``
        holds the reason and the witness under the same key (``"flow"``,
        ``"invariant[k]"``, ``"guard[k]"``, ``"jump_map"``, ``"memory_reset"``).
        Rows of a flow or jump map follow ``state_names``, rows of a memory
        reset follow the transition's ``writes``.  ``memory_reset`` is
        ``null`` without an entry in ``not_affine`` when nothing is written.

    Raises
    ------
    ModelDefinitionError
        A box with an automaton, a box that does not declare the states, or a
        written memory variable without a ``Box.memory`` interval.

    Examples
    --------
    >>> from hybrid import HybridAutomaton, Mode
    >>> to_json(HybridAutomaton(name="a", modes=(Mode(name="x"),), transitions=(), variables=()))["modes"]
    [{'name': 'x', 'description': '', 'invariant_text': '', 'has_invariant': False, 'labels': {}, 'affine': None}]
    """
    automaton, jumps = _automaton(model, "to_json")
    system = model if isinstance(model, HybridSystem) else None
    analysis = None
    if box is not None:
        if system is None:
            raise ModelDefinitionError(
                f"to_json: a box was given for automaton {automaton.name!r}, which has no flows; "
                "pass the HybridSystem to get affine coefficients"
            )
        analysis = _analyse(system, box, tol=tol, seed=seed, what=f"JSON export of system {system.name!r}")
    modes = []
    for mode in automaton.modes:
        entry: dict[str, Any] = {
            "name": mode.name,
            "description": mode.description,
            "invariant_text": mode.invariant_text,
            "has_invariant": mode.invariant is not None,
            "labels": _json_safe(dict(mode.labels)),
            "affine": None,
        }
        if analysis is not None:
            flow, invariant = analysis.modes[mode.name]
            reasons = {}
            if isinstance(flow, NotAffine):
                reasons["flow"] = flow.as_dict()
            reasons.update({f"invariant[{k}]": r.as_dict() for k, r in enumerate(invariant) if isinstance(r, NotAffine)})
            entry["affine"] = {
                "flow": _result_json(flow),
                "invariant": [_result_json(r) for r in invariant],
                "not_affine": reasons,
            }
        modes.append(entry)
    transitions = []
    for t in automaton.transitions:
        entry = {
            "name": t.name,
            "source": t.source,
            "target": t.target,
            "guard_text": t.guard_text,
            "reset_text": t.reset_text,
            "direction": t.direction,
            "priority": t.priority,
            "writes": list(t.writes),
            "reads": list(t.reads),
            "has_reset": t.reset is not None,
            "has_jump_map": t.name in jumps,
            "affine": None,
        }
        if analysis is not None:
            guard, jump, memory = analysis.transitions[t.name]
            reasons = {f"guard[{k}]": r.as_dict() for k, r in enumerate(guard) if isinstance(r, NotAffine)}
            for key, r in (("jump_map", jump), ("memory_reset", memory)):
                if isinstance(r, NotAffine):
                    reasons[key] = r.as_dict()
            entry["affine"] = {
                "guard": [_result_json(r) for r in guard],
                "jump_map": _result_json(jump),
                "memory_reset": _result_json(memory),
                "not_affine": reasons,
            }
        transitions.append(entry)
    affinity = None
    if analysis is not None and box is not None:
        affinity = {
            "box": box.as_dict(),
            "coordinates": list(analysis.coordinates.names),
            "fixed_memory": dict(analysis.coordinates.fixed_memory),
            "tol": float(tol),
            "seed": seed,
        }
    return {
        "kind": "hybrid_system" if system is not None else "hybrid_automaton",
        "name": automaton.name,
        "description": automaton.description,
        "variables": list(automaton.variables),
        "state_names": list(system.state_names) if system is not None else None,
        "memory": [
            {"name": m.name, "initial": float(m.initial), "description": m.description} for m in automaton.memory
        ],
        "initial_mode": automaton.initial_mode,
        "modes": modes,
        "transitions": transitions,
        "affinity": affinity,
    }


# ---------------------------------------------------------------------------- SpaceEx


def _num(x: float) -> str:
    """Shortest round-trip decimal of ``x`` (its ``repr``) written without exponent."""
    x = float(x)
    text = repr(0.0 if x == 0.0 else x)
    if "e" in text or "E" in text:
        text = format(Decimal(text), "f")
    return text


def _linear(names: Sequence[str], coefficients: Sequence[float], constant: float) -> str:
    parts: list[tuple[bool, str]] = []
    for name, a in zip(names, coefficients):
        if a == 0.0:
            continue
        magnitude = abs(a)
        parts.append((a < 0, name if magnitude == 1.0 else f"{_num(magnitude)}*{name}"))
    if constant != 0.0 or not parts:
        parts.append((constant < 0, _num(abs(constant))))
    text = ("-" if parts[0][0] else "") + parts[0][1]
    for negative, body in parts[1:]:
        text += (" - " if negative else " + ") + body
    return text


def _inequality(names: Sequence[str], coefficients: Sequence[float], constant: float) -> str | None:
    """``a·z + b >= 0`` as text; ``None`` when it always holds."""
    nonzero = [a for a in coefficients if a != 0.0]
    if not nonzero:
        return None if constant >= 0.0 else f"{_num(constant)} >= 0"
    if nonzero[0] < 0:
        return f"{_linear(names, [-a for a in coefficients], 0.0)} <= {_num(constant)}"
    return f"{_linear(names, coefficients, 0.0)} >= {_num(-constant)}"


def _ascii_box(box: Box) -> str:
    parts = [f"{n} in [{_num(lo)}, {_num(hi)}]" for n, (lo, hi) in box.bounds.items()]
    parts += [f"{n} in {{{', '.join(_num(c) for c in values)}}}" for n, values in box.choices.items()]
    parts += [f"memory {n} in [{_num(lo)}, {_num(hi)}]" for n, (lo, hi) in box.memory.items()]
    return ", ".join(parts)


def _comment(text: str) -> ET.Element:
    return ET.Comment(" " + text.replace("--", "- -") + " ")


def _require_identifiers(system: HybridSystem, what: str) -> None:
    a = system.automaton
    for kind, names in (
        ("system name", (a.name,)),
        ("state", system.state_names),
        ("memory variable", tuple(m.name for m in a.memory)),
        ("mode", a.mode_names),
        ("transition", tuple(t.name for t in a.transitions)),
    ):
        bad = [n for n in names if not _IDENTIFIER.match(n)]
        if bad:
            raise ModelDefinitionError(
                f"{what}: {kind} name(s) {bad} are not SpaceEx identifiers; "
                "use letters, digits and underscores, not starting with a digit"
            )


def to_spacex(system: HybridSystem, box: Box, *, tol: float = 1e-9, seed: int = 0) -> str:
    """SpaceEx XML model of a system that is affine on ``box``.

    One ``<component>`` named after the system holds a ``real`` parameter per
    state and per memory variable, a ``label`` parameter per transition, a
    ``<location>`` per mode (invariant terms joined by ``&``, flows
    ``x' == a·z + b``, memory flows ``m' == 0.0``) and a ``<transition>`` per
    transition (guard terms as linear inequalities, an assignment for every
    variable: jump map, memory reset, else identity).

    SpaceEx transitions are non-urgent and unprioritised, so the export
    over-approximates the executions of the model: a crossing-triggered
    transition (``direction = ±1``) is exported as its level guard ``g >= 0``
    and the XML says so in a comment, and priorities are dropped (a comment
    says so when a mode has several outgoing transitions).  Time is fixed at
    ``t = 0`` in flows and the output map after checking that they do not
    change at ``t`` in :data:`TIME_PROBES`.

    Parameters
    ----------
    system : HybridSystem
    box : Box
        Declares exactly the states (bounds or choices) and, in
        ``Box.memory``, an interval for every memory variable a reset writes.
    tol, seed
        Passed to :func:`affine_form`.

    Returns
    -------
    str
        The XML document, ending with a newline.

    Raises
    ------
    NotAffineError
        Naming the first function (model order) that is not affine, with the
        witness point, direction and second-difference size.
    ModelDefinitionError
        Names that are not SpaceEx identifiers, or a box that does not
        declare what is needed.
    """
    if not isinstance(system, HybridSystem):
        raise ModelDefinitionError(f"to_spacex: system = {system!r}; expected a HybridSystem")
    what = f"SpaceEx export of system {system.name!r}"
    _require_identifiers(system, what)
    analysis = _analyse(system, box, tol=tol, seed=seed, what=what)
    for label, result in analysis.items():
        if isinstance(result, NotAffine):
            raise NotAffineError(system.name, label, result)
    a = system.automaton
    names = analysis.coordinates.names
    memory_names = tuple(m.name for m in a.memory)

    root = ET.Element("sspaceex", {"xmlns": SPACEEX_NAMESPACE, "version": "0.2", "math": "SpaceEx"})
    root.append(_comment(
        f"generated by hybrid.export from system {system.name!r}; affine on {_ascii_box(box)} "
        f"(relative tolerance {tol:g})"
    ))
    component = ET.SubElement(root, "component", {"id": a.name})
    if memory_names:
        fixed = analysis.coordinates.fixed_memory
        note = f"memory variable(s) {', '.join(memory_names)} have flow 0 and change only by resets"
        if fixed:
            note += "; held fixed for the affinity test: " + ", ".join(f"{k} = {_num(v)}" for k, v in fixed.items())
        component.append(_comment(note))
    if any(len(a.outgoing(m)) > 1 for m in a.mode_names):
        component.append(_comment(
            "SpaceEx transitions are non-urgent and unprioritised: the priorities of the model are not exported"
        ))
    for name in system.state_names + memory_names:
        ET.SubElement(component, "param", {"name": name, "type": "real", "local": "false", "d1": "1",
                                           "d2": "1", "dynamics": "any"})
    for t in a.transitions:
        ET.SubElement(component, "param", {"name": t.name, "type": "label", "local": "false"})
    ids = {mode: str(i + 1) for i, mode in enumerate(a.mode_names)}
    for mode in a.modes:
        flow, invariant = analysis.modes[mode.name]
        location = ET.SubElement(component, "location", {"id": ids[mode.name], "name": mode.name})
        terms = [_inequality(names, f.matrix[0], f.offset[0]) for f in invariant]  # type: ignore[union-attr]
        terms = [term for term in terms if term is not None]
        if terms:
            ET.SubElement(location, "invariant").text = " & ".join(terms)
        assert isinstance(flow, AffineForm)
        equations = [f"{s}' == {_linear(names, row, b)}" for s, row, b in zip(system.state_names, flow.matrix,
                                                                               flow.offset)]
        equations += [f"{m}' == 0.0" for m in memory_names]
        ET.SubElement(location, "flow").text = " & ".join(equations)
    for t in a.transitions:
        guard, jump, memory = analysis.transitions[t.name]
        element = ET.SubElement(component, "transition", {"source": ids[t.source], "target": ids[t.target]})
        if t.direction:
            sense = "rising" if t.direction > 0 else "falling"
            element.append(_comment(
                f"transition {t.name!r} fires on a {sense} zero crossing of its guard "
                f"(direction {t.direction:+d}); exported as the level guard g >= 0"
            ))
        ET.SubElement(element, "label").text = t.name
        terms = [_inequality(names, g.matrix[0], g.offset[0]) for g in guard]  # type: ignore[union-attr]
        terms = [term for term in terms if term is not None]
        if terms:
            ET.SubElement(element, "guard").text = " & ".join(terms)
        assert isinstance(jump, AffineForm)
        equations = [f"{s}' == {_linear(names, row, b)}" for s, row, b in zip(system.state_names, jump.matrix,
                                                                               jump.offset)]
        written = dict(zip(t.writes, range(len(t.writes))))
        for m in memory_names:
            if m in written:
                assert isinstance(memory, AffineForm)
                k = written[m]
                equations.append(f"{m}' == {_linear(names, memory.matrix[k], memory.offset[k])}")
            else:
                equations.append(f"{m}' == {m}")
        ET.SubElement(element, "assignment").text = " & ".join(equations)
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def spacex_config(
    system: HybridSystem,
    x0: Mapping[str, float | tuple[float, float]] | Sequence[float],
    initial_mode: str | None = None,
    *,
    time_horizon: float,
    sampling_time: float | None = None,
    scenario: str = "supp",
    directions: str = "oct",
    set_aggregation: str = "chull",
    flowpipe_tolerance: float = 0.01,
    iter_max: int = -1,
    output_variables: Sequence[str] | None = None,
    output_format: str = "TXT",
    forbidden: str = "",
    rel_err: float = 1.0e-12,
    abs_err: float = 1.0e-15,
) -> str:
    """SpaceEx configuration (``.cfg``) text for the model written by :func:`to_spacex`.

    Parameters
    ----------
    system : HybridSystem
    x0 : mapping or sequence
        Initial set: one value per state (in ``state_names`` order), or a
        mapping ``name -> value`` or ``name -> (lower, upper)`` over states
        and memory variables.  Every state must be given; memory variables
        not given start at their initial value.
    initial_mode : str or None
        Initial location; ``None`` means the automaton's initial mode.
    time_horizon : float
        Analysis horizon (positive).
    sampling_time : float or None
        Time step of the flowpipe; ``None`` means ``time_horizon / 100``.
    scenario, directions, set_aggregation, flowpipe_tolerance, iter_max, output_format, rel_err, abs_err
        SpaceEx options written as given.
    output_variables : sequence of str or None
        Variables to output; ``None`` means every state.
    forbidden : str
        SpaceEx expression of the forbidden set (empty for none).

    Returns
    -------
    str
        The configuration, one ``key = value`` per line.

    Raises
    ------
    ModelDefinitionError
        Unknown or missing variables, an empty or reversed interval, an
        unknown mode, a non-positive horizon or an option that would break
        the quoting.

    Examples
    --------
    >>> from hybrid import HybridAutomaton, HybridSystem, Mode
    >>> a = HybridAutomaton(name="decay", modes=(Mode(name="run"),), transitions=(), variables=("x",))
    >>> s = HybridSystem(automaton=a, state_names=("x",), flows={"run": lambda t, x, m: (-x[0],)})
    >>> print(spacex_config(s, {"x": (0.9, 1.1)}, time_horizon=2.0).splitlines()[2])
    initially = "loc(decay)==run & x >= 0.9 & x <= 1.1"
    """
    if not isinstance(system, HybridSystem):
        raise ModelDefinitionError(f"spacex_config: system = {system!r}; expected a HybridSystem")
    what = f"SpaceEx configuration of system {system.name!r}"
    _require_identifiers(system, what)
    a = system.automaton
    mode = a.initial_mode if initial_mode is None else initial_mode
    a.mode(mode)
    for option, value in (("time_horizon", time_horizon), ("sampling_time", sampling_time)):
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ModelDefinitionError(f"{what}: {option} = {value!r}; expected a finite positive time in seconds")
    if isinstance(x0, Mapping):
        given = dict(x0)
    else:
        values = list(x0)
        if len(values) != system.dimension:
            raise ModelDefinitionError(
                f"{what}: x0 has {len(values)} values, expected {system.dimension} ({', '.join(system.state_names)})"
            )
        given = dict(zip(system.state_names, values))
    memory_names = tuple(m.name for m in a.memory)
    known = system.state_names + memory_names
    unknown = [n for n in given if n not in known]
    missing = [n for n in system.state_names if n not in given]
    if unknown or missing:
        raise ModelDefinitionError(
            f"{what}: x0 misses state(s) {missing} and names unknown variable(s) {unknown}; "
            f"give every state of {list(system.state_names)} (memory {list(memory_names)} optional)"
        )
    for m in a.memory:
        given.setdefault(m.name, float(m.initial))
    constraints = [f"loc({a.name})=={mode}"]
    for name in known:
        value = given[name]
        if isinstance(value, (tuple, list)):
            if len(value) != 2:
                raise ModelDefinitionError(f"{what}: x0[{name!r}] = {value!r}; expected a value or (lower, upper)")
            lo, hi = (float(c) for c in value)
            if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
                raise ModelDefinitionError(
                    f"{what}: x0[{name!r}] = ({lo!r}, {hi!r}); expected finite bounds with lower <= upper"
                )
            constraints.append(f"{name} == {_num(lo)}" if lo == hi else f"{name} >= {_num(lo)} & {name} <= {_num(hi)}")
        else:
            v = float(value)
            if not math.isfinite(v):
                raise ModelDefinitionError(f"{what}: x0[{name!r}] = {v!r}; expected a finite value")
            constraints.append(f"{name} == {_num(v)}")
    for option, text in (("forbidden", forbidden), ("scenario", scenario), ("directions", directions),
                         ("set_aggregation", set_aggregation), ("output_format", output_format)):
        if not isinstance(text, str) or '"' in text or "\n" in text:
            raise ModelDefinitionError(f"{what}: {option} = {text!r}; expected one line of text without '\"'")
    outputs = tuple(system.state_names if output_variables is None else output_variables)
    bad = [n for n in outputs if n not in known]
    if bad:
        raise ModelDefinitionError(f"{what}: output_variables {bad} are not variables of {list(known)}")
    step = time_horizon / 100.0 if sampling_time is None else sampling_time
    lines = [
        f"# SpaceEx configuration of system {a.name!r}, generated by hybrid.export",
        f'system = "{a.name}"',
        f'initially = "{" & ".join(constraints)}"',
        f'forbidden = "{forbidden}"',
        f'scenario = "{scenario}"',
        f'directions = "{directions}"',
        f'set-aggregation = "{set_aggregation}"',
        f"sampling-time = {_num(step)}",
        f"time-horizon = {_num(time_horizon)}",
        f"flowpipe-tolerance = {_num(flowpipe_tolerance)}",
        f"iter-max = {int(iter_max)}",
        f'output-variables = "{",".join(outputs)}"',
        f'output-format = "{output_format}"',
        f"rel-err = {rel_err!r}",
        f"abs-err = {abs_err!r}",
    ]
    return "\n".join(lines) + "\n"
