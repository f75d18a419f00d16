"""Affinity analysis: whether the functions of a hybrid system are affine on a box, and their coefficients.

* :func:`affine_form` decides it for one vector function of named
  coordinates and returns an :class:`AffineForm` (``A z + b``) or a
  :class:`NotAffine` witness;
* :func:`system_affinity` runs it on every flow, invariant term, guard term,
  jump map and memory reset of a :class:`~hybrid.system.HybridSystem` and
  returns a :class:`SystemAffinity`, which the writers of :mod:`hybrid.export`
  (JSON, SpaceEx) turn into text.

Affinity is decided numerically by :func:`affine_form`: the model's functions
are Python callables, so "affine" means "affine on the declared box, up to a
relative tolerance, on every point tried".  The coefficients are central
differences along each coordinate axis through the centre of the box, so a
coordinate a component does not depend on gets an exact ``0.0`` and slopes
such as ``-0.8`` usually come out exactly; the resulting ``A z + b`` is then
verified on the corners of the box, on random points and with second
differences ``f(c + d) - 2 f(c) + f(c - d)`` along random chords.

Memory variables are coordinates of the test when the box gives them a
non-degenerate interval (``Box.memory``); any other memory variable is held
at its fixed value (the box's degenerate value, else its initial value) and
its contribution folds into the offsets.  A memory variable written by a
reset must therefore have an interval in ``Box.memory``.

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
>>> affinity = system_affinity(system, box)
>>> [label for label, result in affinity.items() if isinstance(result, NotAffine)]
[]
>>> affinity.transitions["bounce"].jump_map.coefficients(1)
{'v': -0.8}
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import ModelDefinitionError
from .jsonable import to_jsonable
from .model import Conjunction, Transition
from .region import Box
from .system import HybridSystem

__all__ = [
    "DEFAULT_SAMPLES",
    "MAX_CORNERS",
    "TIME_PROBES",
    "AffineForm",
    "NotAffine",
    "NotAffineError",
    "AffineResult",
    "affine_form",
    "AffinityCoordinates",
    "ModeAffinity",
    "TransitionAffinity",
    "SystemAffinity",
    "system_affinity",
]

DEFAULT_SAMPLES = 64
"""Random points (and as many random chords) tried by :func:`affine_form`."""

MAX_CORNERS = 64
"""At most this many vertices of the box are tried (all of them when ``2^d <= 64``)."""

TIME_PROBES = (1.0, 10.0, 1000.0)
"""Times at which flows and the output map are compared with ``t = 0`` (autonomy check)."""


# ---------------------------------------------------------------------------- results


@dataclass(frozen=True, kw_only=True, slots=True)
class AffineForm:
    """A vector function found affine on a box: ``f(z) = matrix @ z + offset``.

    Attributes
    ----------
    names : tuple of str
        Coordinate names, the order of ``z``.
    matrix : tuple of tuple of float
        One row per output component, one column per coordinate of ``names``.
    offset : tuple of float
        One value per output component.
    max_residual : float
        Largest relative deviation from affinity seen (residuals ``|f - A z - b|``
        and second differences, each divided by the size of the terms of that
        output component over the points tried, ``max(|f(z)|, |A| |z| + |b|)``).
    points_checked : int
        Number of function evaluations the decision rests on (0 for forms built
        exactly, such as the identity of a missing jump map).
    """

    names: tuple[str, ...]
    matrix: tuple[tuple[float, ...], ...]
    offset: tuple[float, ...]
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
        """JSON-ready description: every field (:func:`hybrid.jsonable.to_jsonable`)."""
        return to_jsonable(self)


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

    @property
    def point_by_name(self) -> dict[str, float]:
        """:attr:`point` keyed by coordinate name."""
        return dict(zip(self.names, self.point))

    @property
    def direction_by_name(self) -> dict[str, float] | None:
        """:attr:`direction` keyed by coordinate name (``None`` when there is none)."""
        return None if self.direction is None else dict(zip(self.names, self.direction))

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready description with the reason and the witness by name (non-finite numbers as strings)."""
        return to_jsonable(
            {
                "kind": self.kind,
                "reason": self.reason,
                "point": self.point_by_name,
                "direction": self.direction_by_name,
                "second_difference": self.second_difference,
                "relative": self.relative,
                "component": self.component,
                "time": self.time,
            },
            nonfinite="string",
        )


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
        self.point = witness.point_by_name
        self.direction = witness.direction_by_name
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
    corners, chords = _chords(domain, rng, samples)
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

    return _verdict(domain, matrix, offset, seconds, residuals, size, float(tol), evaluations)


def _chords(
    domain: _Domain, rng: np.random.Generator, samples: int
) -> tuple[Any, list[tuple[np.ndarray, np.ndarray]]]:
    """The corners of :func:`affine_form`'s box and the chords of its second differences: opposite corners, then
    ``samples`` random chords (discrete coordinates held fixed so that the midpoint stays in the box)."""
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
    return corners, chords


def _verdict(domain: _Domain, matrix: np.ndarray, offset: np.ndarray,
             seconds: list[tuple[np.ndarray, np.ndarray, np.ndarray]], residuals: list[tuple[np.ndarray, np.ndarray]],
             size: np.ndarray, tol: float, evaluations: int) -> AffineForm | NotAffine:
    """:func:`affine_form`'s answer from its defects: the worst second difference, then the worst residual,
    relative to ``size`` (per output component); the form when both are within ``tol``."""

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
                             component=k, tol=tol)
    rel = [relative(defect) for defect, _ in residuals]
    j = max(range(len(residuals)), key=lambda i: float(rel[i].max()))
    k = int(np.argmax(rel[j]))
    if rel[j][k] > tol:
        defect, z = residuals[j]
        return NotAffine(names=domain.names, kind="residual", point=_floats(z), direction=None,
                         second_difference=float(defect[k]), relative=float(rel[j][k]), component=k,
                         tol=tol)
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


@dataclass(frozen=True, kw_only=True, slots=True)
class AffinityCoordinates:
    """Coordinates of the affinity test of a system: its states, then its free memory variables.

    Attributes
    ----------
    states : tuple of str
        The system's state names.
    free_memory : tuple of str
        Memory variables with a non-degenerate ``Box.memory`` interval (coordinates of the test).
    fixed_memory : Mapping[str, float]
        The other memory variables and the value they are held at.
    """

    states: tuple[str, ...]
    free_memory: tuple[str, ...]
    fixed_memory: Mapping[str, float]

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the coefficient columns: states, then free memory."""
        return self.states + self.free_memory

    def split(self, z: Sequence[float]) -> tuple[tuple[float, ...], dict[str, float]]:
        """A point ``z`` (in :attr:`names` order) as a state and a full memory assignment."""
        n = len(self.states)
        memory = dict(self.fixed_memory)
        memory.update(zip(self.free_memory, (float(c) for c in z[n:])))
        return tuple(float(c) for c in z[:n]), memory


AffineResult = AffineForm | NotAffine
"""Outcome of the affinity test of one function."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ModeAffinity:
    """Affinity of the functions of one mode.

    Attributes
    ----------
    flow : AffineForm or NotAffine
        The flow map at ``t = 0`` (rows follow the state names).
    invariant : tuple of (AffineForm or NotAffine)
        One per conjunct of the invariant (empty without invariant).
    """

    flow: AffineResult
    invariant: tuple[AffineResult, ...]


@dataclass(frozen=True, kw_only=True, slots=True)
class TransitionAffinity:
    """Affinity of the functions of one transition.

    Attributes
    ----------
    guard : tuple of (AffineForm or NotAffine)
        One per conjunct of the guard.
    jump_map : AffineForm or NotAffine
        The jump map (the exact identity form when the transition has none).
    memory_reset : AffineForm, NotAffine or None
        The memory reset, rows following the transition's ``writes``; ``None``
        when nothing is written.
    """

    guard: tuple[AffineResult, ...]
    jump_map: AffineResult
    memory_reset: AffineResult | None


@dataclass(frozen=True, kw_only=True, slots=True)
class SystemAffinity:
    """Affinity of every function of a system on a box (see :func:`system_affinity`).

    Attributes
    ----------
    coordinates : AffinityCoordinates
        The columns of every coefficient matrix.
    modes : Mapping[str, ModeAffinity]
        By mode name, in declaration order.
    transitions : Mapping[str, TransitionAffinity]
        By transition name, in declaration order.
    """

    coordinates: AffinityCoordinates
    modes: Mapping[str, ModeAffinity]
    transitions: Mapping[str, TransitionAffinity]

    def items(self) -> list[tuple[str, AffineResult]]:
        """Every analysed function with a human name, in model order."""
        out: list[tuple[str, AffineResult]] = []
        for mode, result in self.modes.items():
            out.append((f"flow of mode {mode!r}", result.flow))
            out += [(f"invariant term {k} of mode {mode!r}", r) for k, r in enumerate(result.invariant)]
        for name, result in self.transitions.items():
            out += [(f"guard term {k} of transition {name!r}", r) for k, r in enumerate(result.guard)]
            out.append((f"jump map of transition {name!r}", result.jump_map))
            if result.memory_reset is not None:
                out.append((f"memory reset of transition {name!r}", result.memory_reset))
        return out

    def first_defect(self) -> tuple[str, NotAffine] | None:
        """The first function (model order) that is not affine, with its name, or ``None``."""
        for label, result in self.items():
            if isinstance(result, NotAffine):
                return label, result
        return None


def system_affinity(
    system: HybridSystem, box: Box, *, tol: float = 1e-9, seed: int = 0, what: str | None = None
) -> SystemAffinity:
    """Test every flow, invariant term, guard term, jump map and memory reset of ``system`` on ``box``.

    Flows and conditions are tested at ``t = 0`` and must not change at the
    times :data:`TIME_PROBES` (else a ``"time"`` defect is reported).

    Parameters
    ----------
    system : HybridSystem
    box : Box
        Declares exactly the states (bounds or choices) and, in
        ``Box.memory``, an interval for every memory variable a reset writes.
    tol, seed
        Passed to :func:`affine_form`.
    what : str or None
        What the analysis is for, named in errors (default: the affinity test of the system).

    Returns
    -------
    SystemAffinity
        A result per function; defects are results (:class:`NotAffine`), not exceptions.

    Raises
    ------
    ModelDefinitionError
        Not a system, a box that does not declare the states, memory named like
        a state, unknown memory in the box, or a written memory variable
        without a ``Box.memory`` interval.
    """
    if not isinstance(system, HybridSystem):
        raise ModelDefinitionError(f"system_affinity: system = {system!r}; expected a HybridSystem")
    what = f"affinity test of system {system.name!r}" if what is None else what
    tester = _Tester(system, box, _coordinates(system, box, what), tol=tol, seed=seed)
    a = system.automaton
    return SystemAffinity(
        coordinates=tester.coordinates,
        modes={mode.name: tester.mode(mode.name, mode.invariant) for mode in a.modes},
        transitions={t.name: tester.transition(t) for t in a.transitions},
    )


def _coordinates(system: HybridSystem, box: Box, what: str) -> AffinityCoordinates:
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
    return AffinityCoordinates(states=tuple(system.state_names), free_memory=tuple(free), fixed_memory=fixed)


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


_Timed = Callable[[float, tuple[float, ...]], Any]


class _Tester:
    """The functions of one system as functions of the test coordinates, and their affinity test."""

    def __init__(self, system: HybridSystem, box: Box, coordinates: AffinityCoordinates, *, tol: float,
                 seed: int) -> None:
        self.system = system
        self.box = box
        self.coordinates = coordinates
        self.tol = tol
        self.seed = seed
        domain = _Domain(box, coordinates.names)
        self.probes = np.vstack([domain.center()[None, :], domain.random(np.random.default_rng(seed), 3)])

    def check(self, function: Callable[[tuple[float, ...]], Any], timed: _Timed | None = None) -> AffineResult:
        """:func:`affine_form` of ``function``, then (when ``timed`` is given) the autonomy check."""
        names = self.coordinates.names
        result = affine_form(function, names, self.box, seed=self.seed, tol=self.tol)
        if isinstance(result, AffineForm) and timed is not None:
            return _time_defect(timed, self.probes, names, self.tol) or result
        return result

    def check_timed(self, timed: _Timed) -> AffineResult:
        """Affinity at ``t = 0`` and independence of ``t``."""
        return self.check(lambda z: timed(0.0, z), timed)

    def flow(self, mode: str) -> _Timed:
        """The flow map of ``mode`` as ``f(t, z)``."""
        def f(t: float, z: tuple[float, ...]) -> tuple[float, ...]:
            x, m = self.coordinates.split(z)
            return self.system.flow(mode, t, x, m)
        return f

    def condition(self, term: Callable[..., float]) -> _Timed:
        """A guard or invariant term ``g(v, m)`` as ``g(t, z)`` (through the output map)."""
        def g(t: float, z: tuple[float, ...]) -> float:
            x, m = self.coordinates.split(z)
            return term(self.system.signals(t, x), m)
        return g

    def mode(self, name: str, invariant: Callable[..., float] | None) -> ModeAffinity:
        """Invariant conjuncts first, then the flow (errors raised by the model come in that order)."""
        terms = () if invariant is None else _terms(invariant)
        conjuncts = tuple(self.check_timed(self.condition(term)) for term in terms)
        return ModeAffinity(flow=self.check_timed(self.flow(name)), invariant=conjuncts)

    def transition(self, t: Transition) -> TransitionAffinity:
        """Guard conjuncts, jump map, memory reset."""
        guard = tuple(self.check_timed(self.condition(term)) for term in _terms(t.guard))
        return TransitionAffinity(
            guard=guard,
            jump_map=self.jump_map(t.name),
            memory_reset=self.check(self.memory_reset(t)) if t.writes else None,
        )

    def jump_map(self, name: str) -> AffineResult:
        """The jump map of transition ``name`` at ``t = 0``, or the identity when it has none."""
        if name not in self.system.jumps:
            return self.identity()

        def jump(z: tuple[float, ...]) -> tuple[float, ...]:
            x, m = self.coordinates.split(z)
            return self.system.jump(name, 0.0, x, m)
        return self.check(jump)

    def identity(self) -> AffineForm:
        """The exact form of a missing jump map: ``x⁺ = x``."""
        names = self.coordinates.names
        n = len(self.coordinates.states)
        identity = tuple(tuple(1.0 if j == i else 0.0 for j in range(len(names))) for i in range(n))
        return AffineForm(names=names, matrix=identity, offset=(0.0,) * n, max_residual=0.0, points_checked=0)

    def memory_reset(self, t: Transition) -> Callable[[tuple[float, ...]], list[float]]:
        """The reset of ``t`` as ``r(z)``: the written values in ``writes`` order (checked to be exactly those)."""
        system = self.system

        def reset(z: tuple[float, ...]) -> list[float]:
            x, m = self.coordinates.split(z)
            new = t.reset(system.signals(0.0, x), m)  # type: ignore[misc]
            if set(new) != set(t.writes):
                raise ModelDefinitionError(
                    f"system {system.name!r}: reset of transition {t.name!r} returned keys {sorted(new)}, "
                    f"expected exactly writes = {list(t.writes)}"
                )
            return [new[w] for w in t.writes]
        return reset
