"""A verification problem from a SpaceEx model and its configuration (``visnav verify FILE.xml --config FILE.cfg``).

The model is imported by :mod:`hybrid.spaceex_import`, the configuration by
:mod:`hybrid.spaceex_config`: the initial set becomes the problem's box (a
fixed value where the set is a point, a :class:`~analysis.verification.Parameter`
named ``<state>0`` where it is a range), ``loc(...) == name`` the initial mode,
``time-horizon`` the horizon and the forbidden set the requirement
``safe: always[0, T] not (forbidden)``.  docs/spaceex.md describes the
mapping and what it leaves out.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from hybrid.spaceex_config import forbidden_formula, initial_box, parse_config
from hybrid.spaceex_import import load_spaceex, read_bytes
from hybrid.spaceex_syntax import SpaceExError

from analysis.problems import hybrid_problem
from analysis.requirements import Requirement
from analysis.verification import Parameter, VerificationProblem

__all__ = ["spaceex_problem", "split_spaceex_spec", "is_spaceex_spec", "InitialLocation", "LOCATION_PARAMETER",
           "TRACE_SAMPLES"]

TRACE_SAMPLES = 2000
"""Samples of the STL trace over the horizon (plus both sides of every jump)."""

LOCATION_PARAMETER = "initial_location"
"""The parameter choosing the initial location when the initial set names none (its value rounded: an index)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class InitialLocation:
    """``point -> mode``: the initial location of index ``round(point[LOCATION_PARAMETER])``."""

    modes: tuple[str, ...]

    def __call__(self, point: Mapping[str, float]) -> str:
        index = int(round(float(point.get(LOCATION_PARAMETER, 0.0))))
        return self.modes[min(max(index, 0), len(self.modes) - 1)]


def is_spaceex_spec(spec: str) -> bool:
    """Whether a problem spec names a SpaceEx model (``FILE.xml`` or ``FILE.xml:COMPONENT``)."""
    if not isinstance(spec, str):
        return False
    head = spec.rsplit(":", 1)[0] if spec.count(":") and not spec.endswith(".xml") else spec
    return head.lower().endswith(".xml")


def split_spaceex_spec(spec: str) -> tuple[str, str | None]:
    """``(file, component or None)`` of ``FILE.xml[:COMPONENT]``."""
    if spec.lower().endswith(".xml"):
        return spec, None
    head, _, tail = spec.rpartition(":")
    return head, (tail or None)


def spaceex_problem(xml: str | Path, config: str | Path, component: str | None = None, *,
                    sample_period: float | None = None) -> VerificationProblem:
    """The verification problem of a SpaceEx model and configuration.

    Parameters
    ----------
    xml : str or Path
        The SpaceEx model file.
    config : str or Path
        Its ``.cfg`` (system, initially, forbidden, time-horizon).
    component : str or None
        The component to analyse; default: the configuration's ``system``, else the file's last component.
    sample_period : float or None
        Uniform sampling of the flows for the STL trace [s] (default: horizon / :data:`TRACE_SAMPLES`; the
        integrator's own steps would be too sparse on smooth arcs: an exactly integrated parabola takes one
        step, and its apex would not be a sample).

    Raises
    ------
    SpaceExError
        A model or configuration that cannot be imported (naming file, line and element), a missing
        horizon, an initial set that is not a box.
    """
    cfg = parse_config(read_bytes(config, "SpaceEx configuration (--config)").decode("utf-8", "replace"),
                       str(config))
    name = component or cfg.system
    model = load_spaceex(xml, name)
    if cfg.horizon is None:
        raise SpaceExError(f"{config}: time-horizon", None, "a time horizon [s]", "write time-horizon = 10")
    box, modes = initial_box(model, cfg)
    initial: dict[str, Parameter | float] = {}
    for s, (lo, hi) in box.items():
        initial[s] = lo if lo == hi else Parameter(name=f"{s}_0", low=lo, high=hi)
    formula = forbidden_formula(model, cfg, cfg.horizon)
    if formula is None:
        raise SpaceExError(f"{config}: forbidden", None, "a forbidden set (the property to verify)",
                           'write forbidden = "x >= 10" (the states that must never be reached)')
    requirements = (Requirement(name="safe", formula=formula,
                                description=f"the forbidden set of {Path(config).name} is never reached"),)
    notes = list(model.notes)
    parameters: tuple[Parameter, ...] = ()
    mode: str | InitialLocation = modes[0]
    if len(modes) > 1:
        parameters = (Parameter(name=LOCATION_PARAMETER, low=0.0, high=float(len(modes) - 1)),)
        mode = InitialLocation(modes=tuple(modes))
        notes.append(f"the initial set names no location: every location is initial ({', '.join(modes)}), "
                     f"chosen by the parameter {LOCATION_PARAMETER} (rounded to an index)")
    if cfg.ignored:
        notes.append(f"configuration keys ignored (SpaceEx algorithm settings): {', '.join(cfg.ignored)}")
    notes.append("hybrid fires each transition as soon as its guard holds; SpaceEx may fire it later while the "
                 "invariant holds: the simulated runs are runs of the SpaceEx model, not all of them")
    return hybrid_problem(
        name=f"spaceex-{Path(xml).stem}-{model.system.automaton.name}",
        system=model.system, initial=initial, horizon=cfg.horizon, requirements=requirements,
        parameters=parameters, initial_mode=mode, sample_period=sample_period or cfg.horizon / TRACE_SAMPLES,
        description=f"SpaceEx model {xml} (component {model.system.automaton.name!r}) with {config}. "
                    + " ".join(notes),
        source=f"{xml}:{model.system.automaton.name} --config {config}",
    )
