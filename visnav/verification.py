"""The built-in verification problem: the paper's scenario, its perturbation box and its requirements.

``visnav verify paper`` loads :func:`paper_problem`: the box is the Monte-Carlo
campaign's (start pose, obstacle centres, radii and heights, target pose,
gain factors; :meth:`visnav.studies.campaign.CampaignSpec.perturbation`), the
nominal point is the scenario as written, the requirements are the scenario
TOML's ``[[requirements]]`` (``docs/requirements.md``), evaluated on the
closed loop's trace on the hybrid time domain
(:func:`visnav.requirements.run_trace`).  A point whose perturbed scenario
breaks a rule of the paper's hypotheses (``docs/scenarios.md``) is outside
the problem (:class:`analysis.verification.InvalidPoint`).  ``variant``
drives the closed loop with another supervisor: ``paper`` (the logic as
printed) or a planted mutant (``visnav/fuzzing``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from analysis.stl import SignalTrace
from analysis.verification import InvalidPoint, Parameter, VerificationProblem

from visnav.parameters import Scenario
from visnav.perturbation import Perturbation, Symmetric, apply_perturbation

__all__ = ["paper_problem", "paper_box", "PaperSimulation"]


def paper_box(scenario: Scenario) -> tuple[Perturbation, tuple[Parameter, ...]]:
    """The campaign's perturbation of ``scenario`` and its parameters (nominal: no change)."""
    from visnav.studies.campaign import CampaignSpec

    perturbation = CampaignSpec(scenario=scenario, samples=1, seed=0).perturbation()
    params = []
    for move in perturbation.moves:
        low, high = move.draw.bounds
        nominal = 0.0 if isinstance(move.draw, Symmetric) else (1.0 if move.change == "factor" else None)
        unit = "rad" if move.field.endswith("_rad") else ("m" if move.field.endswith("_m") else "")
        params.append(Parameter(name=move.label, low=low, high=high, nominal=nominal, unit=unit))
    return perturbation, tuple(params)


@dataclass(frozen=True, kw_only=True, slots=True)
class PaperSimulation:
    """Simulate the perturbed scenario's closed loop around ``variant``; picklable."""

    scenario: Scenario
    perturbation: Perturbation
    labels: tuple[str, ...]
    variant: str

    def __call__(self, point: Mapping[str, float]) -> SignalTrace:
        from visnav.fuzzing.closed_loop import simulate_variant
        from visnav.requirements import run_trace

        values = [point[label] for label in self.labels]
        drawn = apply_perturbation(self.scenario, self.perturbation, values, source=f"{self.scenario.name}+box")
        if drawn.scenario is None:
            raise InvalidPoint(str(drawn.error))
        run = simulate_variant(drawn.scenario, self.variant)
        return run_trace(drawn.scenario, run.trace, self.variant)


def paper_problem(scenario: str | Scenario = "paper", variant: str = "resolved") -> VerificationProblem:
    """The verification problem of a case-study scenario (built-in name, TOML path or Scenario).

    Raises
    ------
    visnav.scenario.ScenarioError
        The scenario does not load or its requirements do not parse.
    analysis.verification.ProblemError
        An unknown variant (the message lists the known ones).
    """
    from analysis.verification import ProblemError

    from visnav.fuzzing.closed_loop import closed_loop_variants
    from visnav.requirements import signal_catalogue
    from visnav.scenario import load_scenario

    base = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    known = closed_loop_variants()
    if variant not in known:
        raise ProblemError("--variant", variant, f"one of {', '.join(known)}", "use --variant resolved")
    perturbation, params = paper_box(base)
    signals, labels = signal_catalogue(base)
    suffix = "" if variant == "resolved" else f"~{variant}"
    source = "paper"
    return VerificationProblem(
        name=f"{base.name}{suffix}",
        simulate=PaperSimulation(scenario=base, perturbation=perturbation, labels=tuple(p.name for p in params),
                                 variant=variant),
        parameters=params, horizon=base.duration_s, requirements=tuple(base.requirements),
        signals=tuple(signals), labels=labels,
        description=f"Folio & Cadenat closed loop, scenario {base.name}, supervisor {variant}",
        source=source,
    )
