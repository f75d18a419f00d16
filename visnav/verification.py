"""The built-in verification problem: the paper's scenario, its perturbation box and its requirements.

``visnav verify paper`` loads :func:`paper_problem`: the box is the Monte-Carlo
campaign's perturbation of the situation (start pose, obstacle centres, radii and
heights, target pose; :meth:`visnav.studies.campaign.CampaignSpec.perturbation`
without its gain factors: the gains are the design's), the
nominal point is the scenario as written, the requirements are the scenario
TOML's ``[[requirements]]`` (``docs/requirements.md``), evaluated on the
closed loop's trace on the hybrid time domain
(:func:`visnav.requirements.run_trace`).  A point whose perturbed scenario
breaks a rule of the paper's hypotheses (``docs/scenarios.md``) is outside
the problem (:class:`analysis.verify.verification.InvalidPoint`).  ``variant``
drives the closed loop with another supervisor: ``paper`` (the logic as
printed) or a planted mutant (``visnav/fuzzing``).

``variant="saturated"`` is the design answer to actuator saturation: the
resolved loop whose applied command is clipped to the scenario's ``[limits]``
(:attr:`visnav.closed_loop.ClosedLoop.saturate`); ``NAME+saturated`` clips the
loop of another supervisor.  :func:`loop_variant` splits a name into the
supervisor and the clipping.  The requirements that read the demand of (19)
before clipping (:func:`visnav.requirements.demand_requirements`,
``demand_within_limits`` in ``paper.toml``) are verified only in a loop that
clips: in the paper's loop the demand *is* the applied command, and they would
repeat the requirement on it (``controls_within_limits``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from analysis.stl import SignalTrace
from analysis.verify.verification import InvalidPoint, Parameter, VerificationProblem

from visnav.parameters import Scenario
from visnav.perturbation import Perturbation, Symmetric, apply_perturbation

__all__ = ["paper_problem", "paper_box", "PaperSimulation", "SATURATED", "loop_variant", "variant_names"]

SATURATED = "saturated"
"""The closed-loop option of :func:`loop_variant`: the applied command clipped to ``[limits]``."""


def paper_box(scenario: Scenario) -> tuple[Perturbation, tuple[Parameter, ...]]:
    """The campaign's perturbation of the situation (start pose, obstacles, target), and its parameters.

    The gains are the design's and stay fixed: the requirements are claims about the
    controller as designed over the situations the paper's hypotheses admit (the
    campaign, ``visnav sweep``, also varies the gains).  Nominal: no change.
    """
    from visnav.studies.campaign import CampaignSpec

    campaign = CampaignSpec(scenario=scenario, samples=1, seed=0).perturbation()
    perturbation = Perturbation(moves=tuple(m for m in campaign.moves if not m.field.startswith("gains.")))
    params = []
    for move in perturbation.moves:
        low, high = move.draw.bounds
        nominal = 0.0 if isinstance(move.draw, Symmetric) else (1.0 if move.change == "factor" else None)
        unit = "rad" if move.field.endswith("_rad") else ("m" if move.field.endswith("_m") else "")
        params.append(Parameter(name=move.label, low=low, high=high, nominal=nominal, unit=unit))
    return perturbation, tuple(params)


def variant_names() -> tuple[str, ...]:
    """The names :func:`loop_variant` accepts, for messages: the supervisors, ``saturated``, ``NAME+saturated``."""
    from visnav.fuzzing.variants import VARIANTS

    return (*VARIANTS, SATURATED, f"NAME+{SATURATED}")


def loop_variant(name: str) -> tuple[str, bool]:
    """The supervisor variant and whether the loop clips its command, for a ``--variant`` name.

    ``"saturated"`` is ``("resolved", True)``, ``"NAME+saturated"`` is ``(NAME, True)`` and a supervisor of
    :data:`visnav.fuzzing.variants.VARIANTS` is ``(NAME, False)``.

    Raises
    ------
    analysis.verify.verification.ProblemError
        Any other name (the message lists the known ones).
    """
    from analysis.verify.verification import ProblemError

    from visnav.fuzzing.variants import RESOLVED, VARIANTS

    if isinstance(name, str):
        supervisor, plus, option = name.rpartition("+")
        if not plus and option == SATURATED:
            return RESOLVED, True
        if not plus and option in VARIANTS:
            return option, False
        if plus and option == SATURATED and supervisor in VARIANTS:
            return supervisor, True
    raise ProblemError("variant", name, f"one of {', '.join(variant_names())} (NAME a supervisor)",
                       f"use the variant {RESOLVED!r}, or {SATURATED!r} for the loop that clips its command")


@dataclass(frozen=True, kw_only=True, slots=True)
class PaperSimulation:
    """Simulate the perturbed scenario's closed loop around the supervisor ``variant``; picklable.

    ``saturate``: the applied command clipped to the scenario's ``[limits]``.
    """

    scenario: Scenario
    perturbation: Perturbation
    labels: tuple[str, ...]
    variant: str
    saturate: bool = False

    def __call__(self, point: Mapping[str, float]) -> SignalTrace:
        from visnav.fuzzing.closed_loop import simulate_variant
        from visnav.fuzzing.variants import make_variant
        from visnav.requirements import run_trace

        values = [point[label] for label in self.labels]
        drawn = apply_perturbation(self.scenario, self.perturbation, values, source=f"{self.scenario.name}+box")
        if drawn.scenario is None:
            raise InvalidPoint(str(drawn.error))
        scenario = drawn.scenario
        run = simulate_variant(scenario, self.variant, saturate=self.saturate)
        model = make_variant(self.variant, scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
        return run_trace(scenario, run.trace, model)


def paper_problem(scenario: str | Scenario = "paper", variant: str = "resolved") -> VerificationProblem:
    """The verification problem of a case-study scenario (built-in name, TOML path or Scenario).

    Parameters
    ----------
    scenario : str or Scenario
    variant : str
        A supervisor (:data:`visnav.fuzzing.variants.VARIANTS`), ``"saturated"`` (the resolved
        loop clipping its command to ``[limits]``) or ``"NAME+saturated"`` (:func:`loop_variant`).
        A loop that does not clip leaves out the requirements on the demand
        (:func:`visnav.requirements.demand_requirements`), and its description says so.

    Raises
    ------
    visnav.scenario.ScenarioError
        The scenario does not load or its requirements do not parse.
    analysis.verify.verification.ProblemError
        An unknown variant (the message lists the known ones), or a loop that does not clip for a
        scenario whose every requirement reads the demand.
    """
    from visnav.requirements import demand_requirements, signal_catalogue
    from visnav.scenario import load_scenario

    supervisor, saturate = loop_variant(variant)
    base = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    perturbation, params = paper_box(base)
    signals, labels = signal_catalogue(base)
    left_out = () if saturate else demand_requirements(base)
    requirements = tuple(r for r in base.requirements if r.name not in left_out)
    if left_out and not requirements:
        from analysis.verify.verification import ProblemError

        raise ProblemError("variant", variant, f"a loop that clips ({SATURATED}): every requirement of scenario "
                           f"{base.name!r} reads the demand, which a loop that does not clip applies as it is",
                           f"use the variant {SATURATED!r}, or add a requirement on the applied command (v_mps, ...)")
    suffix = "" if variant == "resolved" else f"~{variant}"
    description = f"Folio & Cadenat closed loop, scenario {base.name}, supervisor {supervisor}"
    if saturate:
        description += ", applied commands clipped to the actuator limits (saturated loop)"
    if left_out:
        description += (f"; not verified here: {', '.join(left_out)} (they read the demand of (19), which this "
                        f"loop applies unclipped: the variant {SATURATED!r} verifies them)")
    return VerificationProblem(
        name=f"{base.name}{suffix}",
        simulate=PaperSimulation(scenario=base, perturbation=perturbation, labels=tuple(p.name for p in params),
                                 variant=supervisor, saturate=saturate),
        parameters=params, horizon=base.duration_s, requirements=requirements,
        signals=tuple(signals), labels=labels, description=description, source="paper",
    )
