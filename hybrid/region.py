"""Declared regions of the state space: the boxes that structural checks search.

The state-space questions of :mod:`hybrid.check` (non-determinism, deadlock,
resets landing outside an invariant) and the affinity test of
:mod:`hybrid.affine` are answered on a :class:`Box` that the *user* declares:
an interval per continuous coordinate, a finite set of values per discrete
coordinate (an obstacle index, a side ±1), and an interval or a fixed value
per memory variable (memory not named keeps its initial value).

Examples
--------
>>> import numpy as np
>>> box = Box(bounds={"h": (0.0, 10.0), "v": (-20.0, 20.0)})
>>> points = box.sample(np.random.default_rng(0), 3)
>>> points.shape
(3, 2)
>>> bool(box.contains(points[0]))
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from .errors import ModelDefinitionError
from .jsonable import to_jsonable

__all__ = ["Box"]


@dataclass(frozen=True, kw_only=True, slots=True)
class Box:
    """A product of intervals and finite sets over named coordinates.

    Attributes
    ----------
    bounds : Mapping[str, tuple[float, float]]
        ``name -> (lower, upper)`` of each continuous coordinate, finite, ``lower <= upper``.
    choices : Mapping[str, tuple[float, ...]]
        ``name -> values`` of each discrete coordinate (non-empty).
    memory : Mapping[str, tuple[float, float]]
        ``name -> (lower, upper)`` of memory variables to search over (equal
        bounds fix a value).

    The coordinate order (:attr:`names`) is ``bounds`` then ``choices``, in
    declaration order; :meth:`vector` rearranges a point into any other order.
    """

    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    choices: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    memory: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        bounds = {}
        for name, pair in dict(self.bounds).items():
            bounds[name] = _interval(f"Box.bounds[{name!r}]", pair)
        choices = {}
        for name, values in dict(self.choices).items():
            try:
                values = tuple(float(c) for c in values)
            except (TypeError, ValueError):
                raise ModelDefinitionError(
                    f"Box.choices[{name!r}] = {values!r}: expected a sequence of real values"
                ) from None
            if not values or not all(math.isfinite(c) for c in values):
                raise ModelDefinitionError(
                    f"Box.choices[{name!r}] = {values!r}: expected at least one finite value"
                )
            choices[name] = values
        both = sorted(set(bounds) & set(choices))
        if both:
            raise ModelDefinitionError(f"Box: coordinate(s) {both} given both as bounds and as choices; keep one")
        memory = {}
        for name, pair in dict(self.memory).items():
            if isinstance(pair, (int, float)) and not isinstance(pair, bool):
                pair = (float(pair), float(pair))
            memory[name] = _interval(f"Box.memory[{name!r}]", pair)
        if not bounds and not choices:
            raise ModelDefinitionError("Box: no coordinates; give bounds={name: (lower, upper)} or choices")
        object.__setattr__(self, "bounds", MappingProxyType(bounds))
        object.__setattr__(self, "choices", MappingProxyType(choices))
        object.__setattr__(self, "memory", MappingProxyType(memory))

    # ------------------------------------------------------------------ queries
    @property
    def names(self) -> tuple[str, ...]:
        """Coordinate names: continuous ones, then discrete ones."""
        return tuple(self.bounds) + tuple(self.choices)

    @property
    def continuous_names(self) -> tuple[str, ...]:
        """Names of the interval coordinates."""
        return tuple(self.bounds)

    @property
    def lower(self) -> np.ndarray:
        """Lower bounds of the continuous coordinates, shape ``(len(bounds),)``."""
        return np.array([lo for lo, _ in self.bounds.values()], dtype=float)

    @property
    def upper(self) -> np.ndarray:
        """Upper bounds of the continuous coordinates, shape ``(len(bounds),)``."""
        return np.array([hi for _, hi in self.bounds.values()], dtype=float)

    def require(self, names: Sequence[str], what: str) -> None:
        """Raise unless the box declares exactly the coordinates ``names``.

        Raises
        ------
        ModelDefinitionError
            Naming the missing and the unknown coordinates.
        """
        missing = [n for n in names if n not in self.bounds and n not in self.choices]
        unknown = [n for n in self.names if n not in names]
        if missing or unknown:
            raise ModelDefinitionError(
                f"Box for {what}: missing coordinate(s) {missing}, unknown coordinate(s) {unknown}; "
                f"declare bounds or choices for exactly {list(names)}"
            )

    def sample(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """``count`` points drawn uniformly, shape ``(count, len(names))``."""
        n_cont = len(self.bounds)
        out = np.empty((count, len(self.names)))
        if n_cont:
            out[:, :n_cont] = rng.uniform(self.lower, self.upper, size=(count, n_cont))
        for k, values in enumerate(self.choices.values()):
            out[:, n_cont + k] = rng.choice(np.asarray(values), size=count)
        return out

    def sample_memory(self, rng: np.random.Generator, count: int) -> list[dict[str, float]]:
        """``count`` memory assignments drawn uniformly from :attr:`memory`."""
        if not self.memory:
            return [{} for _ in range(count)]
        lows = np.array([lo for lo, _ in self.memory.values()])
        highs = np.array([hi for _, hi in self.memory.values()])
        draws = rng.uniform(lows, highs, size=(count, len(lows)))
        return [dict(zip(self.memory, map(float, row))) for row in draws]

    def corners(self, limit: int = 256) -> np.ndarray:
        """Up to ``limit`` vertices of the box (all when ``2^d <= limit``), shape ``(k, len(names))``."""
        axes = [(lo, hi) if lo < hi else (lo,) for lo, hi in self.bounds.values()]
        axes += [tuple(values) for values in self.choices.values()]
        total = math.prod(len(a) for a in axes)
        count = min(total, limit)
        out = np.empty((count, len(axes)))
        for i in range(count):
            rest = i
            for k, a in enumerate(axes):
                out[i, k] = a[rest % len(a)]
                rest //= len(a)
        return out

    def contains(self, point: Sequence[float], tol: float = 0.0) -> bool:
        """Whether ``point`` (in :attr:`names` order) lies in the box."""
        p = np.asarray(point, dtype=float)
        n_cont = len(self.bounds)
        inside = bool(np.all(p[:n_cont] >= self.lower - tol) and np.all(p[:n_cont] <= self.upper + tol))
        for k, values in enumerate(self.choices.values()):
            inside = inside and float(p[n_cont + k]) in values
        return inside

    def clip(self, point: Sequence[float]) -> np.ndarray:
        """``point`` with its continuous coordinates clipped into the box."""
        p = np.array(point, dtype=float)
        n_cont = len(self.bounds)
        p[:n_cont] = np.clip(p[:n_cont], self.lower, self.upper)
        return p

    def vector(self, point: Sequence[float], order: Sequence[str]) -> tuple[float, ...]:
        """Coordinates of ``point`` rearranged into ``order``."""
        index = {n: i for i, n in enumerate(self.names)}
        return tuple(float(point[index[n]]) for n in order)

    def describe(self) -> str:
        """One-line description, e.g. ``"h ∈ [0, 10], v ∈ [-20, 20]"`` (for reports)."""
        parts = [f"{n} ∈ [{lo:g}, {hi:g}]" for n, (lo, hi) in self.bounds.items()]
        parts += [f"{n} ∈ {{{', '.join(f'{c:g}' for c in values)}}}" for n, values in self.choices.items()]
        parts += [f"memory {n} ∈ [{lo:g}, {hi:g}]" for n, (lo, hi) in self.memory.items()]
        return ", ".join(parts)

    def as_dict(self) -> dict[str, object]:
        """JSON-ready description: ``bounds``, ``choices`` and ``memory`` with lists for the tuples."""
        return to_jsonable(self)


def _interval(what: str, pair: object) -> tuple[float, float]:
    try:
        lo, hi = (float(c) for c in pair)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ModelDefinitionError(f"{what} = {pair!r}: expected (lower, upper)") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise ModelDefinitionError(
            f"{what} = ({lo!r}, {hi!r}): expected finite bounds with lower <= upper; swap or bound them"
        )
    return lo, hi
