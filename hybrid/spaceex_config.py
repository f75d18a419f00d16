"""SpaceEx configuration files (``.cfg``): the system, the initial and forbidden sets, the horizon.

A ``.cfg`` is a list of ``key = value`` lines (``#`` comments, values quoted or
bare).  Read: ``system``, ``initially``, ``forbidden``, ``time-horizon``,
``output-variables`` and ``sampling-time`` (SpaceEx's time step, the flowpipe's step:
:attr:`SpaceExConfig.sampling_time`; in the scenarios ``stc`` and ``simu`` it is not a
fixed flowpipe step, so it is not read there).  Every other key (``scenario``,
``directions``, ``flowpipe-tolerance``, ``iter-max``, ``rel-err``, ...) tunes SpaceEx's own
reachability algorithm: it is ignored and listed in :attr:`SpaceExConfig.ignored`.

The initial set must be a conjunction of bounds ``c1 <= x <= c2``,
``x == c``, ``x >= c`` ... and location constraints ``loc(instance) == name``;
a variable the set leaves unbounded takes its bounds from the initial
location's invariant (SpaceEx intersects the initial set with the invariant).
Anything else (a disjunction, a constraint over two variables) is refused: the
problem's initial set is a box, and a bounding box would be a different set.
The forbidden set becomes the requirement ``always[0, T] not (forbidden)``.

A negative ``time-horizon`` (SpaceEx's ``time-horizon = -1``, with ``iter-max = -1``: no bound) is an *unbounded*
horizon: :attr:`SpaceExConfig.horizon` is ``math.inf`` (:attr:`SpaceExConfig.unbounded`); the property holds for
all ``t >= 0``.  Zero, NaN, infinities and text are refused.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

from .spaceex_flatten import constant_value
from .spaceex_import import SpaceExModel, substitute_tree
from .spaceex_syntax import SpaceExError, parse_constraints

__all__ = ["SpaceExConfig", "parse_config", "initial_box", "forbidden_formula", "USED_KEYS", "STEP_FREE_SCENARIOS"]

USED_KEYS = ("system", "initially", "forbidden", "time-horizon", "output-variables", "sampling-time")
"""The configuration keys the import reads; the others are SpaceEx algorithm settings, ignored (``sampling-time``
too in the scenarios of :data:`STEP_FREE_SCENARIOS`)."""

STEP_FREE_SCENARIOS = ("stc", "simu")
"""Scenarios whose ``sampling-time`` is not a fixed flowpipe step: ``stc`` adapts its time steps to the
``flowpipe-tolerance`` (the sampling time is where it starts), ``simu`` simulates (it is the output's sampling).
There the key is ignored; in ``supp`` (the LGG algorithm's fixed step, SpaceEx's default) it is read."""

_LINE = re.compile(r'^\s*([A-Za-z][A-Za-z0-9_-]*)\s*=\s*(.*?)\s*$')


@dataclass(frozen=True, kw_only=True, slots=True)
class SpaceExConfig:
    """A parsed ``.cfg``.

    Attributes
    ----------
    system : str or None
        The component to analyse.
    initially, forbidden : tree or None
        Constraint trees (:mod:`hybrid.spaceex_syntax`), ``None`` when absent or empty.
    horizon : float or None
        ``time-horizon`` [s]; ``math.inf`` for a negative ``time-horizon`` (unbounded, SpaceEx's ``-1``).
    sampling_time : float or None
        ``sampling-time`` [s], ``0 < sampling_time <= horizon``: the flowpipe's step the user chose
        (``None`` when absent or in a scenario of :data:`STEP_FREE_SCENARIOS`).
    outputs : tuple of str
        ``output-variables``.
    ignored : tuple of str
        Keys present but not used.
    source : str
        The file.
    """

    system: str | None
    initially: Any
    forbidden: Any
    horizon: float | None
    outputs: tuple[str, ...]
    ignored: tuple[str, ...]
    source: str
    sampling_time: float | None = None

    @property
    def unbounded(self) -> bool:
        """Whether the horizon is unbounded (a negative ``time-horizon``: the property is for all ``t >= 0``)."""
        return self.horizon is not None and math.isinf(self.horizon)


def _values(text: str, source: str) -> dict[str, tuple[str, int]]:
    values: dict[str, tuple[str, int]] = {}
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        raw = lines[i]
        i += 1
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        m = _LINE.match(raw)
        if m is None:
            raise SpaceExError(f"{source}:{i}", raw.strip()[:80], "a line key = value", "fix the line or comment it (#)")
        key, value, line = m.group(1), m.group(2), i
        if value.startswith('"') and value.count('"') == 1:  # a quoted value over several lines
            parts = [value]
            while i < len(lines) and '"' not in lines[i]:
                parts.append(lines[i])
                i += 1
            if i < len(lines):
                parts.append(lines[i])
                i += 1
            value = "\n".join(parts)
        if value.startswith('"'):
            end = value.find('"', 1)
            if end < 0:
                raise SpaceExError(f"{source}:{line}: {key}", value[:80], "a closing quote", "close the quoted value")
            value = value[1:end]
        elif "#" in value:
            value = value[:value.index("#")].strip()
        values[key] = (value, line)
    return values


def parse_config(text: str, source: str = "<cfg>") -> SpaceExConfig:
    """A :class:`SpaceExConfig` from the text of a ``.cfg`` file.

    Raises
    ------
    SpaceExError
        A malformed line, a set outside the expression language, a horizon that is neither a finite number > 0 nor
        a negative number (unbounded), a ``sampling-time`` that is not a finite number in ``(0, time-horizon]``.
    """
    values = _values(text, source)

    def tree(key: str) -> Any:
        if key not in values or not values[key][0].strip():
            return None
        value, line = values[key]
        return parse_constraints(value, f"{source}:{line}: {key}")

    horizon = None
    if "time-horizon" in values:
        value, line = values["time-horizon"]
        try:
            horizon = float(value)
        except ValueError:
            horizon = math.nan
        if not math.isfinite(horizon) or horizon == 0.0:
            raise SpaceExError(f"{source}:{line}: time-horizon", value, "a finite time > 0 [s], or a negative number "
                               "(SpaceEx's time-horizon = -1: unbounded, for all t >= 0)",
                               "write e.g. time-horizon = 10, or time-horizon = -1 for an unbounded property")
        horizon = math.inf if horizon < 0.0 else horizon
    outputs = tuple(v.strip() for v in values.get("output-variables", ("", 0))[0].split(",") if v.strip())
    scenario = values.get("scenario", ("", 0))[0].strip().strip('"').lower()
    sampling = None if scenario in STEP_FREE_SCENARIOS else _sampling_time(values, horizon, source)
    ignored = tuple(k for k in values if k not in USED_KEYS or (k == "sampling-time" and sampling is None))
    return SpaceExConfig(system=values["system"][0].strip() if "system" in values else None,
                         initially=tree("initially"), forbidden=tree("forbidden"), horizon=horizon, outputs=outputs,
                         ignored=ignored, source=source, sampling_time=sampling)


def _sampling_time(values: dict[str, tuple[str, int]], horizon: float | None, source: str) -> float | None:
    """``sampling-time`` [s] checked: a finite number ``0 < value <= time-horizon`` (``None`` when absent)."""
    if "sampling-time" not in values:
        return None
    value, line = values["sampling-time"]
    try:
        step = float(value)
    except ValueError:
        step = math.nan
    top = math.inf if horizon is None else horizon
    if not (math.isfinite(step) and 0.0 < step <= top):
        bound = "" if horizon is None or math.isinf(horizon) else f" <= time-horizon = {horizon!r}"
        example = 0.01 if horizon is None or math.isinf(horizon) else horizon / 1000.0
        raise SpaceExError(f"{source}:{line}: sampling-time", value, f"a finite time step 0 < sampling-time{bound} [s]",
                           f"write e.g. sampling-time = {example!r}, or remove the line (the steps are then chosen "
                           "from the dynamics)")
    return step


def _conjuncts(tree: Any) -> tuple[Any, ...]:
    if tree is None or tree[0] == "true":
        return ()
    return tree[1] if tree[0] == "and" else (tree,)


def _names(tree: Any) -> set[str]:
    if not isinstance(tree, tuple) or not tree:
        return set()
    if tree[0] == "name":
        return {tree[1]}
    return set().union(*(_names(t) for t in tree[1:]))


_FLIP = {"<=": ">=", "<": ">", ">=": "<=", ">": "<", "==": "=="}


def _pinned(c: Any, constants: dict[str, float], where: str) -> None:
    """Check that a constraint of the initial set on constants holds for their values (given or pinned)."""
    b = _bound(c, set(constants), where)
    if b is None:
        raise SpaceExError(f"{where}: initially", c, "bounds on single constants (Tmax == 50)",
                           "write the constant's value as name == number")
    var, op, value = b
    v = constants[var]
    if not {"<=": v <= value, "<": v < value, ">=": v >= value, ">": v > value, "==": v == value}[op]:
        raise SpaceExError(f"{where}: initially", f"{var} {op} {value!r}", f"a constraint that holds for {var} = {v!r} "
                           "(the value given to the constant)", f"give {var} one value in the set and the constants")


def _bound(c: Any, variables: set[str], where: str) -> tuple[str, str, float] | None:
    """``(var, op, value)`` for a comparison of one variable with a constant (``None`` for anything else)."""
    if c[0] != "cmp":
        return None
    a, b = c[2], c[3]
    op = c[1]
    if a[0] != "name" and b[0] == "name":
        a, b, op = b, a, _FLIP[op]
    if a[0] != "name" or a[1] not in variables:
        return None
    try:
        return a[1], op, constant_value(b, where)
    except SpaceExError:
        return None


def _location(model: SpaceExModel, locs: list[tuple[str | None, str]], where: str) -> list[str]:
    flat = model.flat
    candidates = []
    for loc in flat.locations:
        parts = dict(loc.parts)
        ok = True
        for comp, name in locs:
            if comp is None:
                ok = ok and len(parts) == 1 and next(iter(parts.values())) == name
            else:
                ok = ok and parts.get(comp) == name
        if ok:
            candidates.append(loc.name)
    if not candidates or (len(candidates) > 1 and locs):
        raise SpaceExError(f"{where}: initially", [f"loc({c})=={n}" for c, n in locs] or "no loc(...) constraint",
                           "location constraints selecting exactly one location of the flattened model "
                           f"(they select {len(candidates)}: {candidates[:6]})",
                           "add loc(instance)==name for every instance with several locations; instances are "
                           f"{list(flat.instances)}")
    return candidates


def initial_box(model: SpaceExModel, config: SpaceExConfig) -> tuple[dict[str, tuple[float, float]], list[str]]:
    """The initial box (state -> ``(low, high)``) and the initial modes of ``config``'s initial set.

    Without any ``loc(...)`` constraint every location is initial (SpaceEx's
    reading); then the bounds must come from the set itself.  With location
    constraints they must select exactly one location, whose invariant bounds
    the variables the set leaves unbounded.

    Raises
    ------
    SpaceExError
        No initial set, a constraint that is not a bound or a location, an empty
        range, a state left unbounded by the set and the initial invariant, or
        location constraints that do not select one location.
    """
    where = config.source
    if config.initially is None:
        raise SpaceExError(f"{where}: initially", None, "an initial set", 'write initially = "x == 0 & ..."')
    states = set(model.system.state_names)
    low = {s: -math.inf for s in states}
    high = {s: math.inf for s in states}
    locs: list[tuple[str | None, str]] = []
    for c in _conjuncts(config.initially):
        if c[0] == "loc":
            locs.append((c[1], c[2]))
            continue
        if _names(c) and _names(c) <= set(model.constants):  # the value it pins (hybrid.spaceex_import)
            _pinned(c, model.constants, where)
            continue
        b = _bound(c, states, where)
        unknown = sorted(_names(c) - states - set(model.outputs))
        if unknown:
            raise SpaceExError(f"{where}: initially", unknown, f"state variables of the model "
                               f"({sorted(states)[:12]})", "correct the names (a local variable is instance.name)")
        if b is None:
            raise SpaceExError(f"{where}: initially", c, "a conjunction of bounds var <= c, var >= c, var == c "
                               "(state variables) and loc(instance)==name", "the problem's initial set is a box: "
                               "write the set as bounds on single state variables")
        var, op, value = b
        if op in (">=", ">", "=="):
            low[var] = max(low[var], value)
        if op in ("<=", "<", "=="):
            high[var] = min(high[var], value)
    modes = _location(model, locs, where)
    invariant = next(loc.invariant for loc in model.flat.locations if loc.name == modes[0]) if len(modes) == 1 else ()
    for c in invariant:
        b = _bound(substitute_tree(c, model.outputs), states, where)
        if b is not None and (math.isinf(low[b[0]]) or math.isinf(high[b[0]])):
            var, op, value = b
            if op in (">=", ">", "==") and math.isinf(low[var]):
                low[var] = value
            if op in ("<=", "<", "==") and math.isinf(high[var]):
                high[var] = value
    for s in model.system.state_names:
        if not (math.isfinite(low[s]) and math.isfinite(high[s])) or low[s] > high[s]:
            raise SpaceExError(f"{where}: initially", f"{s} in [{low[s]}, {high[s]}]",
                               "a finite, non-empty range for every state variable",
                               f"bound {s} in the initial set (e.g. {s} == 0)")
    return {s: (low[s], high[s]) for s in model.system.state_names}, modes


def _stl(tree: Any, model: SpaceExModel, where: str) -> str:
    kind = tree[0]
    if kind == "num":
        return repr(float(tree[1])) if tree[1] >= 0 else f"({float(tree[1])!r})"
    if kind == "name":
        if tree[1] not in model.system.state_names:
            raise SpaceExError(where, tree[1], f"a state variable ({list(model.system.state_names)[:12]})",
                               "the forbidden set may read state variables and outputs")
        return tree[1]
    if kind == "neg":
        return f"(-{_stl(tree[1], model, where)})"
    if kind in ("+", "-", "*", "/"):
        return f"({_stl(tree[1], model, where)} {kind} {_stl(tree[2], model, where)})"
    if kind == "^" and tree[2][0] == "num" and float(tree[2][1]).is_integer() and 1 <= tree[2][1] <= 8:
        return "(" + " * ".join([_stl(tree[1], model, where)] * int(tree[2][1])) + ")"
    if kind == "cmp":
        return f"({_stl(tree[2], model, where)} {tree[1]} {_stl(tree[3], model, where)})"
    if kind in ("and", "or"):
        return "(" + f" {kind} ".join(_stl(c, model, where) for c in tree[1]) + ")"
    if kind in ("true", "false"):
        return kind
    if kind == "loc":
        modes = [loc.name for loc in model.flat.locations
                 if (tree[1] is None and len(loc.parts) == 1 and loc.parts[0][1] == tree[2])
                 or dict(loc.parts).get(tree[1]) == tree[2]]
        if not modes:
            raise SpaceExError(where, f"loc({tree[1]})=={tree[2]}", f"a location of an instance {list(model.flat.instances)}",
                               "correct the instance or location name")
        return "(" + " or ".join(f'mode == "{m}"' for m in modes) + ")"
    raise SpaceExError(where, tree, "bounds and linear/polynomial constraints (+ - * / and integer powers), "
                       "loc(instance)==name", "the STL requirement language has no other functions")


def forbidden_formula(model: SpaceExModel, config: SpaceExConfig, horizon: float) -> str | None:
    """``always[0, T] not (forbidden)`` in the STL of docs/stl.md, or ``None`` without a forbidden set.

    Raises
    ------
    SpaceExError
        ``horizon`` is not finite (the STL needs a bounded window: an unbounded ``time-horizon`` is written over its
        sampled horizon, :func:`analysis.spaceex.spaceex_problem`).
    """
    if config.forbidden is None:
        return None
    if not (isinstance(horizon, (int, float)) and math.isfinite(horizon) and horizon > 0):
        raise SpaceExError(f"{config.source}: time-horizon", horizon, "a finite window [0, T] for the STL formula",
                           "an unbounded time-horizon (< 0) is written over a finite sampled horizon: give that T")
    text = _stl(substitute_tree(config.forbidden, model.outputs), model, f"{config.source}: forbidden")
    return f"always[0, {horizon!r}] not {text}"
