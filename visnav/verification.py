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


@dataclass(frozen=True, kw_only=True, slots=True)
class PaperSimulation:
    """Simulate the perturbed scenario's closed loop around ``variant``; picklable."""

    scenario: Scenario
    perturbation: Perturbation
    labels: tuple[str, ...]
    variant: str

    def __call__(self, point: Mapping[str, float]) -> SignalTrace:
        from visnav.fuzzing.closed_loop import simulate_variant
        from visnav.fuzzing.variants import make_variant
        from visnav.requirements import run_trace

        values = [point[label] for label in self.labels]
        drawn = apply_perturbation(self.scenario, self.perturbation, values, source=f"{self.scenario.name}+box")
        if drawn.scenario is None:
            raise InvalidPoint(str(drawn.error))
        scenario = drawn.scenario
        run = simulate_variant(scenario, self.variant)
        model = make_variant(self.variant, scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
        return run_trace(scenario, run.trace, model)


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

    from visnav.fuzzing.variants import VARIANTS
    from visnav.requirements import signal_catalogue
    from visnav.scenario import load_scenario

    base = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if variant not in VARIANTS:
        raise ProblemError("--variant", variant, f"one of {', '.join(VARIANTS)}", "use --variant resolved")
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
