"""Running the properties: fuzz one property or a selection on one variant, keep the shrunk failures.

:func:`fuzz_property` runs one property of :data:`~visnav.fuzzing.registry.PROPERTIES`
under hypothesis (:func:`analysis.fuzzing.run_property` for measurement
sequences and scenarios, :func:`analysis.fuzzing.run_machine` for the state
machine) and returns a :class:`PropertyResult` with the shrunk
:class:`~visnav.fuzzing.counterexamples.Counterexample` of a failure;
:func:`fuzz` runs several and returns a :class:`FuzzReport`.  Nothing here
prints or writes files (``visnav fuzz`` does).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from analysis.fuzzing import Observer, PropertyRun, run_machine, run_property

from visnav.fuzzing.counterexamples import Counterexample
from visnav.fuzzing.machine import STATEFUL_STEPS, supervisor_machine
from visnav.fuzzing.mutants import RESOLVED
from visnav.fuzzing.properties import hypotheses_prefix
from visnav.fuzzing.registry import PROPERTIES, RESPECTING, Property, budget, scenario_strategy, signal_strategy
from visnav.fuzzing.runner import run_supervisor
from visnav.fuzzing.space import MeasurementSpace, scenario_space
from visnav.fuzzing.variants import VARIANTS, variant_for
from visnav.parameters import Scenario

__all__ = ["PropertyResult", "FuzzReport", "fuzz_property", "fuzz"]

_Found = tuple[PropertyRun, Counterexample | None]
"""A hypothesis run and the counterexample of its failure (``None`` when the property held)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class PropertyResult:
    """One property fuzzed on one variant.

    Attributes
    ----------
    name, kind, variant : str
    examples : int
        Examples run (generation, targeting and shrinking).
    steps : int
        Supervisor steps run (signal kinds; on hypothesis-respecting inputs
        the properties check the prefix where the hypotheses hold) or
        closed-loop samples (scenarios).
    counterexample : Counterexample or None
    wall_time_s : float
        Not part of :meth:`as_dict` (the JSON is byte-identical for one seed).
    """

    name: str
    kind: str
    variant: str
    examples: int
    steps: int
    counterexample: Counterexample | None = None
    wall_time_s: float = 0.0

    @property
    def passed(self) -> bool:
        """Whether the property held on every example."""
        return self.counterexample is None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary (deterministic)."""
        return {
            "name": self.name,
            "kind": self.kind,
            "variant": self.variant,
            "examples": self.examples,
            "steps": self.steps,
            "failures": 0 if self.passed else 1,
            "message": None if self.counterexample is None else self.counterexample.message,
        }


@dataclass(frozen=True, kw_only=True, slots=True)
class FuzzReport:
    """Results of :func:`fuzz`, in run order."""

    variant: str
    seed: int | None
    results: tuple[PropertyResult, ...]

    @property
    def passed(self) -> bool:
        """Whether every property held."""
        return all(r.passed for r in self.results)


def fuzz_property(
    name: str,
    *,
    variant: str = RESOLVED,
    examples: int | None = None,
    seed: int | None = None,
    shrink: bool = True,
    space: MeasurementSpace | None = None,
    on_example: Callable[[int], None] | None = None,
) -> PropertyResult:
    """Fuzz one property on one variant.

    Parameters
    ----------
    name : str
        A key of :data:`PROPERTIES`.
    variant : str
        One of :data:`VARIANTS`.
    examples : int or None
        Examples to generate; the CI budget (:func:`budget`) by default.
    seed : int or None
        ``None``: derandomised; otherwise the hypothesis seed.
    shrink : bool
        Shrink a failure to a minimal counterexample.
    space : MeasurementSpace or None
        Signal kinds: the measurement model (default :class:`MeasurementSpace`).
    on_example : callable or None
        Progress callback (examples run so far).

    Raises
    ------
    KeyError
        Unknown property or variant (the message lists the known ones).
    ValueError
        ``examples < 1``.
    """
    if name not in PROPERTIES:
        raise KeyError(f"unknown property {name!r}; known: {', '.join(PROPERTIES)}")
    if variant not in VARIANTS:
        raise KeyError(f"unknown supervisor variant {variant!r}; known: {', '.join(VARIANTS)}")
    prop = PROPERTIES[name]
    n_examples = budget(name) if examples is None else examples
    if not (isinstance(n_examples, int) and n_examples >= 1):
        raise ValueError(f"examples = {n_examples!r}: expected an integer >= 1")
    space = space or MeasurementSpace()
    start = time.perf_counter()
    runner = {"signals": _fuzz_signals, "stateful": _fuzz_stateful}.get(prop.kind, _fuzz_scenarios)
    run, cx = runner(prop, variant, space, n_examples, seed, shrink, on_example)
    return PropertyResult(
        name=name, kind=prop.kind, variant=variant, examples=run.examples, steps=run.steps, counterexample=cx,
        wall_time_s=time.perf_counter() - start,
    )


def _fuzz_signals(prop: Property, variant: str, space: MeasurementSpace, n_examples: int, seed: int | None,
                  shrink: bool, on_example: Callable[[int], None] | None) -> _Found:
    """A signal property: measurement sequences through the variant, the prefix within H2 when respecting."""
    name = prop.name
    model = variant_for(variant, space)
    check = prop.check

    respecting = prop.inputs in RESPECTING

    def signal_check(rows: tuple[tuple[float, ...], ...], observe: Observer) -> int:
        steps = run_supervisor(model, space, rows)
        checked = steps[:hypotheses_prefix(model, space, steps)] if respecting else steps
        check(model, space, checked, observe)
        return len(steps)

    run = run_property(name, signal_check, signal_strategy(prop.inputs, space), max_examples=n_examples,
                       seed=seed, shrink=shrink, on_example=on_example)
    cx = None if run.failure is None else Counterexample(
        property=name, variant=variant, kind=prop.kind, message=run.failure.message, sample=run.failure.sample,
        details=run.failure.details, space=space, measurements=tuple(run.failure.example), seed=seed,
    )
    return run, cx


def _fuzz_stateful(prop: Property, variant: str, space: MeasurementSpace, n_examples: int, seed: int | None,
                   shrink: bool, on_example: Callable[[int], None] | None) -> _Found:
    """The state machine; a failure is saved as the measurements the shrunk run fed."""
    name = prop.name
    model = variant_for(variant, space)
    run = run_machine(name, supervisor_machine(model, space), max_examples=n_examples,
                      steps_per_example=STATEFUL_STEPS, seed=seed, shrink=shrink,
                      record=lambda m: tuple(m.measurements), on_example=on_example)
    cx = None
    if run.failure is not None:
        rows = tuple(run.failure.example or ())
        cx = Counterexample(
            property=name, variant=variant, kind=prop.kind, message=run.failure.message,
            sample=run.failure.sample, details=run.failure.details, space=space, measurements=rows, seed=seed,
        )
    return run, cx


def _fuzz_scenarios(prop: Property, variant: str, space: MeasurementSpace, n_examples: int, seed: int | None,
                    shrink: bool, on_example: Callable[[int], None] | None) -> _Found:
    """A closed-loop property: random layouts through the variant's closed loop (``space`` unused)."""
    name = prop.name
    check = prop.check

    def scenario_check(scenario: Scenario, observe: Observer) -> int:
        return len(check(variant, scenario, observe).trace.times)

    run = run_property(name, scenario_check, scenario_strategy(prop.inputs), max_examples=n_examples,
                       seed=seed, shrink=shrink, on_example=on_example)
    cx = None if run.failure is None else Counterexample(
        property=name, variant=variant, kind=prop.kind, message=run.failure.message, sample=run.failure.sample,
        details=run.failure.details, space=scenario_space(run.failure.example), scenario=run.failure.example,
        seed=seed,
    )
    return run, cx


def fuzz(
    names: Sequence[str] | None = None,
    *,
    variant: str = RESOLVED,
    examples: int | None = None,
    seed: int | None = None,
    shrink: bool = True,
    on_property: Callable[[str, int, int], None] | None = None,
    on_example: Callable[[str, int], None] | None = None,
) -> FuzzReport:
    """Fuzz several properties (all by default, in registry order) on one variant.

    Parameters
    ----------
    on_property : callable or None
        ``on_property(name, index, total)`` before each property (progress).
    on_example : callable or None
        ``on_example(name, examples_so_far)`` (progress).
    Other parameters as :func:`fuzz_property`.
    """
    selected = tuple(names) if names else tuple(PROPERTIES)
    unknown = [n for n in selected if n not in PROPERTIES]
    if unknown:
        raise KeyError(f"unknown property {unknown[0]!r}; known: {', '.join(PROPERTIES)}")
    results = []
    for i, name in enumerate(selected):
        if on_property is not None:
            on_property(name, i, len(selected))
        callback = None if on_example is None else functools.partial(on_example, name)
        results.append(fuzz_property(name, variant=variant, examples=examples, seed=seed, shrink=shrink,
                                     on_example=callback))
    return FuzzReport(variant=variant, seed=seed, results=tuple(results))
