"""visnav.fuzzing.machine: the rule-based state machine, as a TestCase and as the ``stateful`` property."""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

from visnav.fuzzing.machine import SupervisorMachine, supervisor_machine
from visnav.fuzzing.replay import replay
from visnav.fuzzing.run import fuzz_property
from visnav.fuzzing.space import MeasurementSpace
from visnav.fuzzing.variants import make_variant

PROFILE = "ci" if os.environ.get("CI") else "dev"
SPACE = MeasurementSpace()
ENV, SETTINGS = SPACE.envelopes, SPACE.settings
RESOLVED = make_variant("resolved", ENV, SETTINGS, SPACE.n_obstacles)

TestResolvedSupervisorMachine = supervisor_machine(RESOLVED, SPACE).TestCase
TestResolvedSupervisorMachine.settings = settings(
    max_examples=15 if PROFILE == "dev" else 60, stateful_step_count=20, derandomize=True, database=None,
    deadline=None, suppress_health_check=list(HealthCheck),
)


def test_the_state_machine_catches_a_removed_priority():
    result = fuzz_property("stateful", variant="equal_priority", shrink=False)
    assert not result.passed
    assert "enabled together with the same priority" in result.counterexample.message
    assert replay(result.counterexample).violated


def test_the_factory_parametrises_the_module_level_machine():
    machine = supervisor_machine(RESOLVED, SPACE)
    assert issubclass(machine, SupervisorMachine) and machine is not SupervisorMachine
    assert machine.__name__ == machine.__qualname__ == "SupervisorMachine_resolved"
    assert machine.variant is RESOLVED and machine.space is SPACE
    assert machine.__module__ == SupervisorMachine.__module__ == "visnav.fuzzing.machine"
    instance = machine()
    instance.hold(3)
    assert instance.steps == 3 and len(instance.measurements) == 3
    instance.invariants_hold()
    assert instance.fresh == [] and instance.last.index == 2
