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
  :mod:`~visnav.fuzzing.scenario_properties`.

Every property is a named, documented check in :data:`PROPERTIES`
(:mod:`~visnav.fuzzing.registry`; ``visnav fuzz --property NAME``).
:func:`fuzz` (:mod:`~visnav.fuzzing.run`) runs a selection on one variant and
returns a :class:`FuzzReport`; a failure comes with a shrunk
:class:`Counterexample` (:mod:`~visnav.fuzzing.counterexamples`, the file
machinery of :mod:`analysis.counterexamples`) that :func:`replay`
(:mod:`~visnav.fuzzing.replay`) runs again.  Nothing here prints or writes files.
"""

from visnav.fuzzing.closed_loop import (
    OUTCOMES,
    TARGET_LOST_WINDOW_S,
    ScenarioRun,
    VariantLoop,
    classify_outcome,
    simulate_variant,
)
from visnav.fuzzing.counterexamples import (
    FORMAT,
    FORMAT_VERSION,
    Counterexample,
    CounterexampleError,
    counterexample_from_json,
    counterexample_to_json,
)
from visnav.fuzzing.layouts import scenarios
from visnav.fuzzing.machine import STATEFUL_STEPS, supervisor_machine
from visnav.fuzzing.properties import (
    CONTROL_TOLERANCE,
    MAX_JUMPS_BOUNDED,
    TOLERANCE,
    check_control_continuity,
    check_determinism,
    check_differential,
    check_flag_consistency,
    check_leave_release,
    check_leave_timing,
    check_mu_continuity,
    check_mu_range,
    check_no_chatter,
    check_stateful,
    hypotheses_prefix,
)
from visnav.fuzzing.registry import PROPERTIES, RESPECTING, Property, budget, property_names
from visnav.fuzzing.replay import Replay, replay
from visnav.fuzzing.run import FuzzReport, PropertyResult, fuzz, fuzz_property
from visnav.fuzzing.runner import MAX_JUMPS_PER_SAMPLE, Jump, Step, SupervisorRunner, run_supervisor
from visnav.fuzzing.scenario_properties import (
    check_classified_outcome,
    check_closed_loop_continuity,
    check_no_collision,
)
from visnav.fuzzing.space import MeasurementSpace, bypass_runs, respect_hypotheses, signal_runs
from visnav.fuzzing.variants import PAPER, RESOLVED, VARIANTS, make_variant

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
