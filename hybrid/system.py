"""Continuous-time hybrid systems: an automaton plus flow maps, jump maps and an output.

In the vocabulary of the HyEQ toolbox, a :class:`HybridSystem` gives

* the **flow map** ``f_q(t, x, m)`` of every mode ``q`` (continuous state ``x``,
  memory ``m``), so that ``ẋ = f_q(t, x, m)`` while the mode is kept;
* the **flow set** of a mode through its invariant ``inv_q(v, m) >= 0``;
* the **jump set** of a transition through its guard ``g(v, m) >= 0`` (or
  its zero crossing, see :class:`hybrid.model.Transition`);
* the **jump map** of a transition: the continuous state reset
  ``x⁺ = r(x, m)`` (identity when absent) together with the memory reset of
  the transition itself;
* the **output** ``v = h(t, x)``: the signals that guards and invariants read
  (the identity when ``automaton.variables == state_names``).

The jump map and the memory reset both read the *pre-jump* values.

Examples
--------
>>> from hybrid import HybridAutomaton, Mode, Transition
>>> ball = HybridAutomaton(
...     name="ball", modes=(Mode(name="fall", invariant=lambda v, m: v[0]),),
...     transitions=(Transition(name="bounce", source="fall", target="fall",
...                             guard=lambda v, m: -v[0], direction=+1),),
...     variables=("h", "v"))
>>> system = HybridSystem(automaton=ball, state_names=("h", "v"),
...     flows={"fall": lambda t, x, m: (x[1], -9.81)},
...     jumps={"bounce": lambda x, m: (0.0, -0.8 * x[1])})
>>> system.flow("fall", 0.0, (1.0, 0.0), {})
(0.0, -9.81)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

from .errors import ExecutionError, ModelDefinitionError
from .model import HybridAutomaton

__all__ = ["FlowMap", "JumpMap", "OutputMap", "HybridSystem"]

FlowMap = Callable[[float, Sequence[float], Mapping[str, float]], Sequence[float]]
"""``f(t, x, m) -> ẋ`` of one mode, shape ``(n,)``."""

JumpMap = Callable[[Sequence[float], Mapping[str, float]], Sequence[float]]
"""``r(x, m) -> x⁺`` of one transition, shape ``(n,)``."""

OutputMap = Callable[[float, Sequence[float]], Sequence[float]]
"""``h(t, x) -> v``, one value per automaton variable."""


@dataclass(frozen=True, kw_only=True, slots=True)
class HybridSystem:
    """A hybrid automaton with continuous dynamics, validated at construction.

    Attributes
    ----------
    automaton : HybridAutomaton
        Modes, transitions (guards, memory resets, priorities), invariants.
    state_names : tuple of str
        Names of the continuous state components (dimension ``n``).
    flows : Mapping[str, FlowMap]
        One flow map per mode (every mode must have one).
    jumps : Mapping[str, JumpMap]
        Continuous-state resets keyed by transition name; missing means identity.
    output : OutputMap or None
        Signals read by guards and invariants; ``None`` means ``v = x`` and then
        ``automaton.variables`` must equal ``state_names``.

    Raises
    ------
    ModelDefinitionError
        A mode without a flow, a flow or jump for an unknown mode or
        transition, a non-callable map, or ``output=None`` with variables that
        are not the state names.
    """

    automaton: HybridAutomaton
    state_names: tuple[str, ...]
    flows: Mapping[str, FlowMap]
    jumps: Mapping[str, JumpMap] = field(default_factory=dict)
    output: OutputMap | None = None

    def __post_init__(self) -> None:
        a = self.automaton
        if not isinstance(a, HybridAutomaton):
            raise ModelDefinitionError(
                f"HybridSystem.automaton = {a!r}: expected a HybridAutomaton"
            )
        object.__setattr__(self, "state_names", tuple(self.state_names))
        if not self.state_names:
            raise ModelDefinitionError(
                f"system {a.name!r}: state_names is empty; name at least one continuous state"
            )
        if len(set(self.state_names)) != len(self.state_names):
            raise ModelDefinitionError(f"system {a.name!r}: duplicate state names in {list(self.state_names)}")
        flows = dict(self.flows)
        missing = [m for m in a.mode_names if m not in flows]
        if missing:
            raise ModelDefinitionError(
                f"system {a.name!r}: no flow map for mode(s) {missing}; give flows={{mode: f(t, x, m)}} for "
                f"every mode of {list(a.mode_names)}"
            )
        unknown = [m for m in flows if m not in a.mode_names]
        if unknown:
            raise ModelDefinitionError(
                f"system {a.name!r}: flows given for unknown mode(s) {unknown}; modes are {list(a.mode_names)}"
            )
        for mode, f in flows.items():
            if not callable(f):
                raise ModelDefinitionError(
                    f"system {a.name!r}: flow of mode {mode!r} = {f!r} is not callable; pass f(t, x, m) -> dx/dt"
                )
        jumps = dict(self.jumps)
        names = {t.name for t in a.transitions}
        unknown = [t for t in jumps if t not in names]
        if unknown:
            raise ModelDefinitionError(
                f"system {a.name!r}: jump maps given for unknown transition(s) {unknown}; "
                f"transitions are {sorted(names)}"
            )
        for name, r in jumps.items():
            if not callable(r):
                raise ModelDefinitionError(
                    f"system {a.name!r}: jump map of transition {name!r} = {r!r} is not callable; "
                    "pass r(x, m) -> new state"
                )
        if self.output is None:
            if tuple(a.variables) != self.state_names:
                raise ModelDefinitionError(
                    f"system {a.name!r}: output is None, so the automaton's variables {list(a.variables)} must be "
                    f"the state names {list(self.state_names)}; give output=h(t, x) -> signals otherwise"
                )
        elif not callable(self.output):
            raise ModelDefinitionError(f"system {a.name!r}: output = {self.output!r} is not callable")
        from .model import refuse_misplaced, refuse_unsupported

        for mode, f in flows.items():
            refuse_unsupported(f, f"system {a.name!r}: flow of mode {mode!r}")
            refuse_misplaced(f, self.state_names, f"system {a.name!r}: flow of mode {mode!r}", "state names")
        for name, r in jumps.items():
            refuse_unsupported(r, f"system {a.name!r}: jump map of transition {name!r}", timed=False)
            refuse_misplaced(r, self.state_names, f"system {a.name!r}: jump map of transition {name!r}",
                             "state names")
        refuse_unsupported(self.output, f"system {a.name!r}: output")
        refuse_misplaced(self.output, self.state_names, f"system {a.name!r}: output", "state names")
        object.__setattr__(self, "flows", MappingProxyType(flows))
        object.__setattr__(self, "jumps", MappingProxyType(jumps))

    # ------------------------------------------------------------------ evaluation
    @property
    def name(self) -> str:
        """Name of the automaton."""
        return self.automaton.name

    @property
    def dimension(self) -> int:
        """Number of continuous states ``n``."""
        return len(self.state_names)

    def flow(self, mode: str, t: float, x: Sequence[float], memory: Mapping[str, float]) -> tuple[float, ...]:
        """``ẋ`` in ``mode``, checked for shape and NaN.

        Raises
        ------
        ExecutionError
            Wrong length or a NaN, naming the mode, the state and the time.
        """
        value = self.flows[mode](t, x, memory)
        return self._checked(value, f"flow of mode {mode!r}", t, x)

    def jump(self, transition: str, t: float, x: Sequence[float], memory: Mapping[str, float]) -> tuple[float, ...]:
        """Continuous state after ``transition`` (identity without a jump map)."""
        r = self.jumps.get(transition)
        if r is None:
            return tuple(float(c) for c in x)
        return self._checked(r(x, memory), f"jump map of transition {transition!r}", t, x)

    def signals(self, t: float, x: Sequence[float]) -> tuple[float, ...]:
        """Signals ``v`` read by guards and invariants."""
        if self.output is None:
            return tuple(float(c) for c in x)
        v = self.output(t, x)
        try:
            n = len(v)
        except TypeError:
            raise ExecutionError(
                f"system {self.name!r}: output returned {v!r} at t = {t:.17g} s, x = {format_state(x)}; "
                f"expected {len(self.automaton.variables)} values ({', '.join(self.automaton.variables)})"
            ) from None
        if n != len(self.automaton.variables):
            raise ExecutionError(
                f"system {self.name!r}: output returned {n} values at t = {t:.17g} s, x = {format_state(x)}; "
                f"expected {len(self.automaton.variables)} ({', '.join(self.automaton.variables)})"
            )
        for name, value in zip(self.automaton.variables, v):
            if value != value:
                raise ExecutionError(
                    f"system {self.name!r}: output {name!r} is NaN at t = {t:.17g} s, x = {format_state(x)}"
                )
        return tuple(v)

    def _checked(self, value: Sequence[float], what: str, t: float, x: Sequence[float]) -> tuple[float, ...]:
        try:
            out = tuple(float(c) for c in value)
        except (TypeError, ValueError):
            raise ExecutionError(
                f"system {self.name!r}: {what} returned {value!r} at t = {t:.17g} s, x = {format_state(x)}; "
                f"expected {self.dimension} real numbers ({', '.join(self.state_names)})"
            ) from None
        if len(out) != self.dimension:
            raise ExecutionError(
                f"system {self.name!r}: {what} returned {len(out)} values at t = {t:.17g} s, x = {format_state(x)}; "
                f"expected {self.dimension} ({', '.join(self.state_names)})"
            )
        for name, c in zip(self.state_names, out):
            if math.isnan(c):
                raise ExecutionError(
                    f"system {self.name!r}: {what} gives NaN for {name!r} at t = {t:.17g} s, x = {format_state(x)}"
                )
        return out


def format_state(x: Sequence[float]) -> str:
    """``(x1, x2, ...)`` with 10 significant digits, for error messages (``repr`` if not numeric)."""
    try:
        return "(" + ", ".join(f"{float(c):.10g}" for c in x) + ")"
    except (TypeError, ValueError):
        return repr(x)
