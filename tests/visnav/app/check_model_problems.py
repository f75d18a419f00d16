"""Problems for ``visnav check-model --problem`` (``test_cli_check_complete.py``): the models of
``tests/hybrid/check_fixtures.py`` as verification problems, and one without ``check_box``."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter

_spec = importlib.util.spec_from_file_location(
    "check_fixtures", Path(__file__).resolve().parents[2] / "hybrid" / "check_fixtures.py")
fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fixtures)

_COMFORT = (Requirement(name="comfort", formula="always[0, 10] (abs(T - 20) <= 5)",
                        description="the room stays within 5 of 20"),)


def _problem(name: str, system, check_box=fixtures.BOX):
    return hybrid_problem(name=name, system=system,
                          initial={"T": Parameter(name="T0", low=19.5, high=20.5, nominal=20.0)},
                          horizon=10.0, sample_period=0.5, requirements=_COMFORT, check_box=check_box)


plain_zero_band = _problem("plain-zero-band", fixtures.plain_zero_band())
time_flow_zero_band = _problem("time-flow-zero-band", fixtures.time_flow_zero_band())
time_flow = _problem("time-flow", fixtures.thermostat(19.0, 21.0, symbolic=True, time_flow=True))
guard_raises = _problem("guard-raises", fixtures.bad_guard("raises"))
guard_nan = _problem("guard-nan", fixtures.bad_guard("nan"))
guard_none = _problem("guard-none", fixtures.bad_guard("none"))
plain_overlap = _problem("plain-overlap", fixtures.plain_overlap())
symbolic = _problem("symbolic", fixtures.thermostat(19.0, 21.0, symbolic=True))
no_check_box = _problem("no-check-box", fixtures.thermostat(19.0, 21.0, symbolic=True), check_box=None)
partial_box = _problem("partial-box", fixtures.thermostat(19.0, 21.0, symbolic=True), check_box={"off": fixtures.BOX})
