"""What the structural checks report and how they reach the model: findings, witnesses, model access.

Shared by the sampled search (:mod:`hybrid.check`) and the SMT-decided checks
(:mod:`hybrid.decide`), so that neither imports the other's internals:

* :data:`KIND_SEVERITY`, :class:`Finding`, :class:`Witness`: what a check reports;
* ``Oracle``: every call into the model (counted, checked for NaN and bools,
  errors re-raised with the state), and ``checked_boxes``: the declared region per mode,
  validated against the model.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from .errors import ExecutionError, ModelDefinitionError, UserFunctionError
from .model import HybridAutomaton, Transition, real_number
from .region import Box
from .system import HybridSystem

# Helpers shared with hybrid.check and hybrid.decide have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = ["KIND_SEVERITY", "SEVERITIES", "SIGNIFICANT_DIGITS", "Witness", "Finding", "SearchBudgetExceeded"]

KIND_SEVERITY: Mapping[str, str] = MappingProxyType(
    {
        "nondeterminism": "error",
        "deadlock": "error",
        "reset_outside_invariant": "error",
        "reset_retriggers": "error",
        "unreachable_mode": "warning",
        "unreachable_transition": "warning",
        "sink_mode": "warning",
        "zeno_candidate": "info",
        "zeno_point": "info",
        "priority_overlap": "info",
    }
)
"""Severity of every finding kind."""


SEVERITIES = ("error", "warning", "info")


SIGNIFICANT_DIGITS = 12
"""Digits kept by :meth:`CheckReport.as_dict`."""


def _frozen(values: Mapping[str, float] | None) -> Mapping[str, float]:
    return MappingProxyType({str(k): float(v) for k, v in dict(values or {}).items()})


@dataclass(frozen=True, kw_only=True, slots=True)
class Witness:
    """A point that proves a finding.

    Attributes
    ----------
    state : Mapping[str, float]
        The continuous state ``x`` (system) or the signals (bare automaton).
    memory : Mapping[str, float]
        Memory variables at the point (before any reset).
    signals : Mapping[str, float]
        Signals ``v`` the guards and invariants read there.
    values : Mapping[str, float]
        The guard, invariant and derivative values that prove the finding,
        keyed like ``"guard heat"``, ``"invariant on"``,
        ``"invariant off after cool"``, ``"d/dt invariant on"``,
        ``"post T"`` (state after the jump).
    """

    state: Mapping[str, float]
    memory: Mapping[str, float]
    signals: Mapping[str, float]
    values: Mapping[str, float]

    def __post_init__(self) -> None:
        for name in ("state", "memory", "signals", "values"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))

    def as_dict(self) -> dict[str, dict[str, float | str]]:
        """JSON-ready copy, numbers rounded to :data:`SIGNIFICANT_DIGITS`."""
        return {
            name: {k: finding_number(v) for k, v in getattr(self, name).items()}
            for name in ("state", "memory", "signals", "values")
        }


@dataclass(frozen=True, kw_only=True, slots=True)
class Finding:
    """One problem (or remark) about the model.

    Attributes
    ----------
    kind : str
        A key of :data:`KIND_SEVERITY`.
    severity : str
        ``"error"``, ``"warning"`` or ``"info"``.
    message : str
        Names the modes and transitions and gives the witness values.
    modes, transitions : tuple of str
        What the finding is about (a cycle or a jump chain in order).
    witness : Witness or None
        The point that proves a state-space finding; ``None`` for graph findings.
    """

    kind: str
    severity: str
    message: str
    modes: tuple[str, ...] = ()
    transitions: tuple[str, ...] = ()
    witness: Witness | None = None

    def __post_init__(self) -> None:
        if self.kind not in KIND_SEVERITY:
            raise ValueError(f"Finding.kind = {self.kind!r}; expected one of {sorted(KIND_SEVERITY)}")
        if self.severity not in SEVERITIES:
            raise ValueError(f"Finding.severity = {self.severity!r}; expected one of {list(SEVERITIES)}")
        object.__setattr__(self, "modes", tuple(self.modes))
        object.__setattr__(self, "transitions", tuple(self.transitions))

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {
            "kind": self.kind,
            "severity": self.severity,
            "message": self.message,
            "modes": list(self.modes),
            "transitions": list(self.transitions),
            "witness": None if self.witness is None else self.witness.as_dict(),
        }



def finding_number(x: float) -> float | str:
    """``x`` rounded to :data:`SIGNIFICANT_DIGITS` for a finding's JSON; a non-finite ``x`` as its string."""
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    return float(f"{x + 0.0:.{SIGNIFICANT_DIGITS}g}")


def format_g(x: float) -> str:
    """``x`` in ``%.10g`` for a finding's message (``-0.0`` shown as ``0``)."""
    return f"{x + 0.0:.10g}"  # + 0.0 turns -0.0 into 0.0



# ====================================================================== model access
class SearchBudgetExceeded(Exception):
    """The sampled search ran past its wall-clock budget (raised by the oracle's next call into the model)."""


class Oracle:
    """Every call into the model: counted, checked for NaN, errors re-raised with context; past ``deadline``
    (``time.monotonic()``) the next call raises :class:`SearchBudgetExceeded`."""

    def __init__(self, model: HybridSystem | HybridAutomaton) -> None:
        if isinstance(model, HybridSystem):
            self.system: HybridSystem | None = model
            self.automaton = model.automaton
            self.coords = tuple(model.state_names)
        elif isinstance(model, HybridAutomaton):
            self.system = None
            self.automaton = model
            self.coords = tuple(model.variables)
        else:
            raise ModelDefinitionError(
                f"check(): model = {model!r}; expected a HybridSystem or a HybridAutomaton"
            )
        a = self.automaton
        self.what = f"{'system' if self.system is not None else 'automaton'} {a.name!r}"
        self.outgoing = {q: a.outgoing(q) for q in a.mode_names}
        self.invariants = {mode.name: mode.invariant for mode in a.modes}
        self.calls = 0
        self.deadline: float | None = None

    def _tick(self) -> None:
        self.calls += 1
        if self.deadline is not None and time.monotonic() > self.deadline:
            raise SearchBudgetExceeded()

    # ---------------------------------------------------------------- messages
    def where(self, x: Sequence[float], m: Mapping[str, float]) -> str:
        state = ", ".join(f"{n}={format_g(c)}" for n, c in zip(self.coords, x))
        text = f"{'x' if self.system is not None else 'v'} = ({state})"
        if m:
            text += ", memory {" + ", ".join(f"{k}={format_g(c)}" for k, c in m.items()) + "}"
        return text

    def _raised(self, what: str, x: Sequence[float], m: Mapping[str, float], err: Exception) -> ExecutionError:
        # the system's methods already wrap the user's exception (UserFunctionError): name the original once
        if isinstance(err, UserFunctionError) and isinstance(err.__cause__, Exception):
            err = err.__cause__
        return ExecutionError(
            f"check of {self.what}: {what} raised {type(err).__name__}: {err} at {self.where(x, m)}; "
            "the structural checks evaluate it all over the declared Box: make it total there or shrink the Box"
        )

    def _real(self, value: Any, what: str, x: Sequence[float], m: Mapping[str, float]) -> float:
        r = real_number(value, f"check of {self.what}: {what}", f"at {self.where(x, m)}")
        if r != r:
            raise ExecutionError(
                f"check of {self.what}: {what} returned NaN at {self.where(x, m)}; "
                "guards and invariants must be real-valued all over the declared Box"
            )
        return r

    # ---------------------------------------------------------------- evaluations
    def signals(self, x: tuple[float, ...], m: Mapping[str, float]) -> tuple[float, ...]:
        if self.system is None:
            return x
        self._tick()
        try:
            return tuple(float(c) for c in self.system.signals(0.0, x))
        except Exception as err:
            raise self._raised("output h(t, x)", x, m, err) from err

    def invariant(self, q: str, x: tuple[float, ...], v: Sequence[float], m: Mapping[str, float]) -> float:
        f = self.invariants[q]
        if f is None:
            return math.inf
        self._tick()
        what = f"invariant of mode {q!r}"
        try:
            value = f(v, m)
        except Exception as err:
            raise self._raised(what, x, m, err) from err
        return self._real(value, what, x, m)

    def guard(self, t: Transition, x: tuple[float, ...], v: Sequence[float], m: Mapping[str, float]) -> float:
        self._tick()
        what = f"guard of transition {t.name!r}"
        try:
            value = t.guard(v, m)
        except Exception as err:
            raise self._raised(what, x, m, err) from err
        return self._real(value, what, x, m)

    def flow(self, q: str, x: tuple[float, ...], m: Mapping[str, float]) -> tuple[float, ...]:
        assert self.system is not None
        self._tick()
        try:
            return self.system.flow(q, 0.0, x, m)
        except Exception as err:
            raise self._raised(f"flow of mode {q!r}", x, m, err) from err

    def jump(
        self, t: Transition, x: tuple[float, ...], v: Sequence[float], m: Mapping[str, float]
    ) -> tuple[tuple[float, ...], dict[str, float]]:
        """State and memory after ``t`` (both maps read the pre-jump values)."""
        if self.system is not None:
            self._tick()
            try:
                post = self.system.jump(t.name, 0.0, x, m)
            except Exception as err:
                raise self._raised(f"jump map of transition {t.name!r}", x, m, err) from err
        else:
            post = x
        memory = dict(m)
        if t.reset is not None:
            self._tick()
            what = f"reset of transition {t.name!r}"
            try:
                update = t.reset(v, m)
            except Exception as err:
                raise self._raised(what, x, m, err) from err
            if set(update) != set(t.writes):
                raise ExecutionError(
                    f"check of {self.what}: {what} returned {sorted(update)} at {self.where(x, m)}, "
                    f"declared writes {sorted(t.writes)}; return exactly the declared memory variables"
                )
            for k, c in update.items():
                memory[k] = self._real(c, f"{what} (memory {k!r})", x, m)
        return post, memory



def checked_boxes(o: Oracle, box: Box | Mapping[str, Box] | None) -> dict[str, Box] | None:
    """The per-mode boxes of a check's ``box`` argument (one box for every mode, or a mapping), validated against
    the model of ``o``; ``None`` when no box was given. Raises :class:`ModelDefinitionError` on a bad box."""
    a = o.automaton
    if box is None:
        return None
    if isinstance(box, Box):
        boxes = {q: box for q in a.mode_names}
    elif isinstance(box, Mapping):
        unknown = [q for q in box if q not in a.mode_names]
        if unknown:
            raise ModelDefinitionError(
                f"check of {o.what}: box given for unknown mode(s) {unknown}; modes are {list(a.mode_names)}"
            )
        boxes = {q: box[q] for q in a.mode_names if q in box}
    else:
        raise ModelDefinitionError(
            f"check of {o.what}: box = {box!r}; expected a Box, a mapping mode name -> Box, or None"
        )
    coords_kind = "state names" if o.system is not None else "variables"
    memory_names = [mv.name for mv in a.memory]
    for q, b in boxes.items():
        if not isinstance(b, Box):
            raise ModelDefinitionError(f"check of {o.what}: box of mode {q!r} = {b!r}; expected a Box")
        b.require(o.coords, f"mode {q!r} of {o.what} (its {coords_kind})")
        unknown = [n for n in b.memory if n not in memory_names]
        if unknown:
            raise ModelDefinitionError(
                f"Box for mode {q!r} of {o.what}: memory {unknown} is not declared by the automaton; "
                f"its memory variables are {memory_names}"
            )
    return boxes


