"""Fuzzing the supervisor's switching logic with hypothesis.

The supervisor is driven in two ways:

* **signal sequences**: the raw measurements of every sample
  (:mod:`~visnav.fuzzing.space`: :class:`MeasurementSpace`, the strategies of
  signal runs) fed sample by sample to a supervisor variant
  (:mod:`~visnav.fuzzing.variants`: the resolved automaton, the paper as
  written of :mod:`~visnav.fuzzing.paper_logic`, the mutants of
  :mod:`~visnav.fuzzing.mutants`) by :mod:`~visnav.fuzzing.runner` (the
  measurement stage and µ around the generic :mod:`analysis.sequences`),
  checked by the properties of :mod:`~visnav.fuzzing.properties` and by the
  state machine of :mod:`~visnav.fuzzing.machine`;
* **whole scenarios**: random layouts (:mod:`~visnav.fuzzing.layouts`) run
  through the closed loop (:mod:`~visnav.fuzzing.closed_loop`), checked by
  :mod:`~visnav.fuzzing.scenario_properties` and :mod:`~visnav.fuzzing.loop_properties`
  (whose yardsticks, :mod:`~visnav.fuzzing.reconstruction_reference` and
  :mod:`~visnav.fuzzing.blend_reference`, share no code with what they judge).

Every property is a named, documented check in :data:`PROPERTIES`
(:mod:`~visnav.fuzzing.registry`; ``visnav fuzz --property NAME``).
:func:`fuzz` (:mod:`~visnav.fuzzing.run`) runs a selection on one variant and
returns a :class:`FuzzReport`; a failure comes with a shrunk
:class:`Counterexample` (:mod:`~visnav.fuzzing.counterexamples`, the file
machinery of :mod:`analysis.counterexamples`) that :func:`replay`
(:mod:`~visnav.fuzzing.replay`) runs again.  Nothing here prints or writes files.

The names are imported from their submodules on first use: importing one
submodule (say :mod:`~visnav.fuzzing.space`) does not load the closed loop.
"""

import importlib
import sys
import types
from typing import Any

_LAZY = {
    **dict.fromkeys(('OUTCOMES', 'ScenarioRun', 'TARGET_LOST_WINDOW_S', 'VariantLoop', 'classify_outcome', 'simulate_variant'), 'closed_loop'),
    **dict.fromkeys(('Counterexample', 'CounterexampleError', 'FORMAT', 'FORMAT_VERSION', 'counterexample_from_json', 'counterexample_to_json'), 'counterexamples'),
    **dict.fromkeys(('scenarios',), 'layouts'),
    **dict.fromkeys(('STATEFUL_STEPS', 'supervisor_machine'), 'machine'),
    **dict.fromkeys(('CONTROL_TOLERANCE', 'MAX_JUMPS_BOUNDED', 'TOLERANCE', 'check_control_continuity', 'check_determinism', 'check_differential', 'check_flag_consistency', 'check_leave_release', 'check_leave_timing', 'check_mu_continuity', 'check_mu_range', 'check_no_chatter', 'check_stateful', 'hypotheses_prefix'), 'properties'),
    **dict.fromkeys(('PROPERTIES', 'Property', 'RESPECTING', 'budget', 'property_names'), 'registry'),
    **dict.fromkeys(('Replay', 'replay'), 'replay'),
    **dict.fromkeys(('FuzzReport', 'PropertyResult', 'fuzz', 'fuzz_property'), 'run'),
    **dict.fromkeys(('Jump', 'MAX_JUMPS_PER_SAMPLE', 'Step', 'SupervisorRunner', 'run_supervisor'), 'runner'),
    **dict.fromkeys(('check_classified_outcome', 'check_closed_loop_continuity', 'check_no_collision'), 'scenario_properties'),
    **dict.fromkeys(('MeasurementSpace', 'bypass_runs', 'respect_hypotheses', 'signal_runs'), 'space'),
    **dict.fromkeys(('PAPER', 'RESOLVED', 'VARIANTS', 'make_variant'), 'variants'),
}


def __getattr__(name: str) -> Any:
    """Each name is imported from its submodule on first use (importing the package costs nothing)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'visnav.fuzzing' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"visnav.fuzzing.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


class _Package(types.ModuleType):
    """Keeps an exported function whose name is also a submodule's (``replay``) from being replaced by the
    submodule when the import system binds it on the package after loading it."""

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, types.ModuleType) and _LAZY.get(name) == name:
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "MAX_JUMPS_PER_SAMPLE",
    "OUTCOMES",
    "VARIANTS",
    "RESOLVED",
    "PAPER",
    "MeasurementSpace",
    "Jump",
    "Step",
    "SupervisorRunner",
    "run_supervisor",
    "respect_hypotheses",
    "hypotheses_prefix",
    "signal_runs",
    "bypass_runs",
    "scenarios",
    "Property",
    "PROPERTIES",
    "property_names",
    "make_variant",
    "VariantLoop",
    "simulate_variant",
    "ScenarioRun",
    "classify_outcome",
    "supervisor_machine",
    "Counterexample",
    "CounterexampleError",
    "counterexample_to_json",
    "counterexample_from_json",
    "PropertyResult",
    "FuzzReport",
    "budget",
    "fuzz_property",
    "fuzz",
    "Replay",
    "replay",
    "RESPECTING",
    "STATEFUL_STEPS",
    "TOLERANCE",
    "CONTROL_TOLERANCE",
    "MAX_JUMPS_BOUNDED",
    "TARGET_LOST_WINDOW_S",
    "check_mu_range",
    "check_mu_continuity",
    "check_determinism",
    "check_no_chatter",
    "check_flag_consistency",
    "check_control_continuity",
    "check_leave_timing",
    "check_leave_release",
    "check_differential",
    "check_stateful",
    "check_no_collision",
    "check_classified_outcome",
    "check_closed_loop_continuity",
]
