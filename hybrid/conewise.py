"""Conewise linear systems of the plane: ``ẋ = A_i x`` on equal-angle sectors around the origin.

:func:`conewise_linear_system` builds the :class:`~hybrid.system.HybridSystem` of a state-dependent
switched linear system in ``ℝ²``: the plane is cut by ``count = len(matrices)`` rays at the angles
``θ_i = 2πi/count`` into sectors, and sector ``i`` is the convex cone

    ``S_i = {x : n_iᵀx ≥ 0, −n_{i+1}ᵀx ≥ 0}``,  ``n_i = (−sin θ_i, cos θ_i)``

(indices modulo ``count``; ``n_i`` is the normal of the ray ``θ_i`` pointing counter-clockwise), where
the flow is ``ẋ = matrices[i] x``.  Mode ``S<i>`` has these two affine terms as its invariant
(:func:`hybrid.all_of`); transition ``S<i>->S<i+1>`` fires when the state crosses the ray
``θ_{i+1}`` counter-clockwise (guard ``n_{i+1}ᵀx ≥ 0`` and ``d_{i+1}ᵀx ≥ 0`` with the ray's direction
``d = (cos θ, sin θ)``), ``S<i>->S<i-1>`` when it crosses ``θ_i`` clockwise; no transition has a jump
map (the state is kept) or writes memory.

The guards are crossing-triggered (``direction = +1``): on the shared ray both neighbours' guards
are ``0``, so a level-triggered pair would fire back and forth at one instant whenever the located
state lies exactly on the ray; a crossing fires once, when the flow carries the state across.  At the origin both guards of a
mode hold: the priorities (counter-clockwise first) keep the automaton deterministic there.  Every
function is symbolic (:mod:`hybrid.symbolic`), so the exports and the SMT-decided checks read it.

The construction is the textbook example of stability under state-dependent switching that no
common quadratic Lyapunov function proves (Liberzon, *Switching in Systems and Control*, 2003,
§2.1.5: two unstable spirals, each alone divergent, stable when switched on the quadrants), which
:func:`analysis.stability.analyse_stability` proves with a piecewise quadratic Lyapunov function.

Examples
--------
>>> import numpy as np
>>> spiral_1, spiral_2 = np.array([[0.1, -1.0], [2.0, 0.1]]), np.array([[0.1, -2.0], [1.0, 0.1]])
>>> system = conewise_linear_system("spirals", [spiral_2, spiral_1, spiral_2, spiral_1])
>>> system.automaton.mode_names
('S0', 'S1', 'S2', 'S3')
>>> [t.name for t in system.automaton.outgoing("S0")]
['S0->S1', 'S0->S3']
>>> system.flow("S1", 0.0, (1.0, 0.0), {})
(0.1, 2.0)
>>> inside = system.automaton.mode("S0").invariant
>>> inside((1.0, 1.0), {}) >= 0, inside((1.0, -1.0), {}) >= 0
(True, False)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .errors import ParameterError
from .model import HybridAutomaton, Mode, Transition, all_of
from .symbolic import Coordinates, Expr, coordinates, flow_map
from .system import HybridSystem

__all__ = ["conewise_linear_system", "sector_normals"]


def sector_normals(count: int) -> tuple[tuple[float, float], ...]:
    """The normals ``n_i = (−sin θ_i, cos θ_i)``, ``θ_i = 2πi/count``, of the rays between the sectors.

    Parameters
    ----------
    count : int
        Number of sectors, ``>= 3``.

    Returns
    -------
    tuple of (float, float)
        ``n_0 … n_{count−1}``; sector ``i`` is ``{x : n_iᵀx ≥ 0, −n_{i+1}ᵀx ≥ 0}``.

    Raises
    ------
    ParameterError
        ``count`` is not an integer ``>= 3``.
    """
    _check_count(count)
    return tuple((-math.sin(2.0 * math.pi * i / count), math.cos(2.0 * math.pi * i / count)) for i in range(count))


def _check_count(count: Any) -> None:
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 3:
        raise ParameterError("count", count, "an integer >= 3 (each sector must be a convex cone, < 180°)",
                             "give at least three matrices, one per sector")


def _matrices(matrices: Any) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """The sectors' matrices as nested float tuples, each checked to be finite and 2×2."""
    if isinstance(matrices, np.ndarray) and matrices.ndim != 3:
        raise ParameterError("matrices", matrices.shape, "a sequence of 2×2 matrices (or an array of shape (m, 2, 2))",
                             "wrap the matrices in a list: [A_0, A_1, A_2, ...]")
    if isinstance(matrices, (str, bytes)) or not hasattr(matrices, "__len__"):
        raise ParameterError("matrices", type(matrices).__name__, "a sequence of 2×2 matrices, one per sector",
                             "give a list [A_0, A_1, ...] of at least three 2×2 arrays")
    if len(matrices) < 3:
        raise ParameterError("matrices", f"{len(matrices)} matrices", "at least 3 matrices (one per sector, each "
                             "sector a convex cone)", "give at least three 2×2 matrices (repeat one to split a "
                             "region into several sectors)")
    out = []
    for k, a in enumerate(matrices):
        try:
            array = np.array(a, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"matrices[{k}]", type(a).__name__, "a 2×2 matrix of real numbers",
                                 "give a numpy array or nested lists of numbers") from None
        if array.shape != (2, 2):
            raise ParameterError(f"matrices[{k}]", array.shape, "shape (2, 2): the plane's linear flow",
                                 "give a 2×2 matrix A with ẋ = A x in that sector")
        if not np.all(np.isfinite(array)):
            raise ParameterError(f"matrices[{k}]", array.tolist(), "finite entries",
                                 "replace the NaN or infinite entries by numbers")
        out.append(((float(array[0, 0]), float(array[0, 1])), (float(array[1, 0]), float(array[1, 1]))))
    return out


def _names(state_names: Any) -> tuple[str, str]:
    if state_names is None:
        return ("x", "y")
    if isinstance(state_names, (str, bytes)) or not hasattr(state_names, "__len__"):
        raise ParameterError("state_names", state_names, "two distinct non-empty strings", "give e.g. ('x', 'y')")
    names = tuple(state_names)
    if len(names) != 2 or not all(isinstance(s, str) and s for s in names) or names[0] == names[1]:
        raise ParameterError("state_names", names, "two distinct non-empty strings", "give e.g. ('x', 'y')")
    return names  # type: ignore[return-value]


def _linear(row: Sequence[float], v: Coordinates) -> Expr:
    """``row[0]·v_0 + row[1]·v_1`` (terms with a zero coefficient are dropped by the symbolic folding)."""
    first, second = list(v)
    return row[0] * first + row[1] * second


def conewise_linear_system(name: str, matrices: Sequence[Any], *, state_names: Sequence[str] | None = None,
                           initial_sector: int = 0) -> HybridSystem:
    """The conewise linear system ``ẋ = matrices[i] x`` on sector ``i`` of the plane (module docstring).

    Parameters
    ----------
    name : str
        The automaton's name.
    matrices : sequence of array_like, each shape (2, 2)
        ``A_i`` [1/s] of sector ``i`` (between the rays ``θ_i`` and ``θ_{i+1}``), at least three.
    state_names : sequence of two str or None
        The states (default ``("x", "y")``); the automaton reads them as its variables.
    initial_sector : int
        The automaton's initial mode ``S<initial_sector>``.

    Returns
    -------
    HybridSystem
        Modes ``S0 … S<count−1>``, transitions ``S<i>->S<i+1>`` (priority 0) and ``S<i>->S<i-1>``
        (priority 1), crossing-triggered, without jump maps or memory.

    Raises
    ------
    ParameterError
        A name that is not a non-empty string, fewer than three matrices, a matrix that is not a
        finite 2×2 array, bad state names, an initial sector out of range.
    """
    if not isinstance(name, str) or not name:
        raise ParameterError("name", name, "a non-empty string", "name the system, e.g. 'spirals'")
    mats = _matrices(matrices)
    names = _names(state_names)
    count = len(mats)
    if isinstance(initial_sector, bool) or not isinstance(initial_sector, (int, np.integer)) or not (
            0 <= initial_sector < count):
        raise ParameterError("initial_sector", initial_sector, f"an integer in 0..{count - 1}",
                             "give the index of the sector the state starts in")
    normals = sector_normals(count)
    directions = [(ny, -nx) for nx, ny in normals]  # d_i = (cos θ_i, sin θ_i): n_i turned clockwise
    v, x = coordinates(*names), coordinates(*names)
    modes, transitions, flows = [], [], {}
    for i, a in enumerate(mats):
        j, k = (i + 1) % count, (i - 1) % count
        below, above = normals[i], normals[j]
        modes.append(Mode(name=f"S{i}", description=f"sector {i}: between the rays at {360.0 * i / count:g}° and "
                          f"{360.0 * (i + 1) / count:g}°",
                          invariant=all_of(_linear(below, v), _linear((-above[0], -above[1]), v)),
                          invariant_text=f"n_{i}·x >= 0 and n_{j}·x <= 0"))
        transitions.append(Transition(
            name=f"S{i}->S{j}", source=f"S{i}", target=f"S{j}", direction=+1, priority=0, reads=names,
            guard=all_of(_linear(above, v), _linear(directions[j], v)),
            guard_text=f"x crosses the ray at {360.0 * (i + 1) / count:g}° counter-clockwise"))
        transitions.append(Transition(
            name=f"S{i}->S{k}", source=f"S{i}", target=f"S{k}", direction=+1, priority=1, reads=names,
            guard=all_of(_linear((-below[0], -below[1]), v), _linear(directions[i], v)),
            guard_text=f"x crosses the ray at {360.0 * i / count:g}° clockwise"))
        flows[f"S{i}"] = flow_map(_linear(a[0], x), _linear(a[1], x))
    automaton = HybridAutomaton(name=name, modes=tuple(modes), transitions=tuple(transitions), variables=names,
                                initial_mode=f"S{int(initial_sector)}",
                                description=f"conewise linear system on {count} sectors of the plane")
    return HybridSystem(automaton=automaton, state_names=names, flows=flows)
