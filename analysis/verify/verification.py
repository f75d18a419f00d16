"""A verification problem for any switching system: a box of inputs, a simulator, named signals, requirements.

The user describes *what* is to be verified; :mod:`analysis.verify.falsification`
searches the box and gives the verdicts, and the application renders them.

:class:`Parameter`
    One coordinate of the box searched: an initial state component or a
    model parameter, with its nominal value and a distribution for
    Monte-Carlo.  Searches work in unit coordinates ``u ∈ [-1, 1]``: ``u = 0``
    is the nominal value, ``u = ±1`` the ends of the interval (so a shrunk
    counterexample is the smallest departure from nominal).
:class:`VerificationProblem`
    The simulator ``simulate(point) -> SignalTrace`` (a mapping of parameter
    names to values in, a trace on the hybrid time domain out), the signals
    and labels the traces carry, the horizon and the requirements; optional
    proofs (certificates that decide a requirement) and structural checks.
:class:`Proof`
    The outcome of a certificate: whether it holds, how it was obtained, and
    whether it was re-checked outside the tool that produced it (only such a
    proof gives the verdict ``proven``).
:class:`InvalidPoint`
    Raised by a simulator for a point outside the problem's hypotheses (the
    sample is discarded and counted, never a counterexample).

The constructors for the two kinds of system the toolkit executes are in
:mod:`analysis.verify.problems` (a continuous-time hybrid system, a sampled-data
closed loop).

Examples
--------
>>> import numpy as np
>>> from analysis.stl import SignalTrace
>>> def simulate(p):
...     t = np.linspace(0.0, 1.0, 11)
...     return SignalTrace(times=t, signals={"x": p["x0"] * np.exp(-t)})
>>> problem = VerificationProblem(
...     name="decay", simulate=simulate, parameters=(Parameter(name="x0", low=0.5, high=2.0, nominal=1.0),),
...     horizon=1.0, signals=("x",),
...     requirements=(Requirement(name="positive", formula="always[0, 1] (x > 0)"),))
>>> problem.point((1.0,))
{'x0': 2.0}
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from hybrid.errors import ParameterError

from analysis.verify.requirements import ParsedRequirement, Requirement, parse_requirements
from analysis.stl import SignalTrace

__all__ = [
    "DISTRIBUTIONS",
    "Parameter",
    "Proof",
    "InvalidPoint",
    "ProblemError",
    "VerificationProblem",
]

DISTRIBUTIONS = ("uniform", "normal")
"""Monte-Carlo distributions of a parameter: uniform on the box, or a normal of mean nominal and
standard deviation a sixth of the interval, truncated to the box (redrawn)."""


class ProblemError(ParameterError):
    """A verification problem that cannot be searched (bad box, horizon, requirement, simulator)."""


class InvalidPoint(Exception):
    """A point of the box outside the problem's hypotheses; the simulator raises it, the search skips the point.

    The message says which hypothesis fails (it is reported with the count of skipped points).
    """


def _real(parameter: str, value: object, fix: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) or not math.isfinite(value):
        raise ProblemError(parameter, value, "a finite number", fix)
    return float(value)


@dataclass(frozen=True, kw_only=True, slots=True)
class Parameter:
    """One coordinate of the searched box.

    Attributes
    ----------
    name : str
        The key of the point passed to the simulator.
    low, high : float
        The interval searched, ``low <= nominal <= high`` (``low == high`` fixes the value).
    nominal : float or None
        The nominal value (``u = 0``); the midpoint when ``None``.
    distribution : {"uniform", "normal"}
        How Monte-Carlo draws it (:data:`DISTRIBUTIONS`).
    unit : str
        Its unit, for reports (``"m"``, ``"rad"``, ``""``).
    """

    name: str
    low: float
    high: float
    nominal: float | None = None
    distribution: str = "uniform"
    unit: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ProblemError("Parameter.name", self.name, "a non-empty string", "name the parameter")
        where = f"Parameter {self.name!r}"
        low = _real(f"{where}: low", self.low, "give a finite lower bound")
        high = _real(f"{where}: high", self.high, "give a finite upper bound")
        if high < low:
            raise ProblemError(f"{where}: [low, high]", (low, high), "low <= high", "swap the two bounds")
        nominal = (low + high) / 2 if self.nominal is None else _real(f"{where}: nominal", self.nominal,
                                                                      "give a finite nominal value or None")
        if not low <= nominal <= high:
            raise ProblemError(f"{where}: nominal", nominal, f"a value in [{low}, {high}]", "move it into the box")
        if self.distribution not in DISTRIBUTIONS:
            raise ProblemError(f"{where}: distribution", self.distribution, f"one of {DISTRIBUTIONS}",
                               "write distribution='uniform'")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)
        object.__setattr__(self, "nominal", nominal)

    def at(self, u: float) -> float:
        """The value at unit coordinate ``u ∈ [-1, 1]``: 0 is nominal, ±1 the two ends, piecewise linear.

        When the nominal value is an end of the interval, both signs of ``u`` cover the
        whole interval (``|u|`` measures the departure), so no half of the unit box is wasted.
        """
        u = min(1.0, max(-1.0, float(u)))
        nominal = float(self.nominal)  # type: ignore[arg-type]
        up, down = self.high - nominal, nominal - self.low
        if up == 0 or down == 0:
            return nominal + abs(u) * (up - down)
        return nominal + u * (up if u >= 0 else down)

    def unit_of(self, value: float) -> float:
        """A unit coordinate of ``value`` (the inverse of :meth:`at`; 0 for a fixed parameter)."""
        nominal = float(self.nominal)  # type: ignore[arg-type]
        up, down = self.high - nominal, nominal - self.low
        if up == 0 and down == 0:
            return 0.0
        if up == 0 or down == 0:
            return (value - nominal) / (up - down)
        return (value - nominal) / (up if value >= nominal else down)

    def draw(self, rng: np.random.Generator) -> float:
        """A Monte-Carlo unit coordinate drawn from :attr:`distribution`."""
        if self.distribution == "uniform":
            return self.unit_of(float(rng.uniform(self.low, self.high)))
        sd = (self.high - self.low) / 6.0
        for _ in range(1000):
            value = float(rng.normal(self.nominal, sd))
            if self.low <= value <= self.high:
                return self.unit_of(value)
        return 0.0


@dataclass(frozen=True, kw_only=True, slots=True)
class Proof:
    """A certificate's answer for one requirement.

    Attributes
    ----------
    holds : bool
        Whether the certificate proves the requirement over the whole box.
    method : str
        How it was obtained (``"Lyapunov function, interval branch and bound"``).
    evidence : str
        What was checked, in one or two sentences (with numbers).
    rechecked : bool
        Whether it was re-checked outside the tool that produced it; a proof that
        holds but was not re-checked does not give the verdict ``proven``.
    assumptions : tuple of str
        What it assumed (the box, the hypotheses).
    margin : float or None
        The smallest slack the method found, in the requirement's units (reachability: the smallest
        ``d − max c·x`` over the flowpipe); ``None`` when the method gives none or decided nothing.
    """

    holds: bool
    method: str
    evidence: str
    rechecked: bool
    assumptions: tuple[str, ...] = ()
    margin: float | None = None

    @property
    def proven(self) -> bool:
        return bool(self.holds and self.rechecked)


Simulator = Callable[[Mapping[str, float]], SignalTrace]
"""``simulate(point) -> SignalTrace``: the point maps every parameter name to its value."""


@dataclass(frozen=True, kw_only=True, slots=True)
class VerificationProblem:
    """What to verify: a simulator over a box, the signals it exposes, a horizon and requirements.

    Attributes
    ----------
    name : str
        Identifier of the problem (file names, reports).
    simulate : callable
        ``simulate(point) -> SignalTrace`` for a point of the box (a mapping
        parameter name -> value); deterministic; may raise :class:`InvalidPoint`
        or :class:`hybrid.DivergenceError` (the search records both).
    parameters : tuple of Parameter
        The initial set and the parameter box, together (may be empty: one run).
    horizon : float
        The simulated time span [s]; no formula may look further than it.
    requirements : tuple of Requirement
    signals : tuple of str
        Numeric signals every trace carries (formulas are checked against them).
    labels : Mapping[str, tuple of str]
        String-valued signals and their possible values (``{"mode": mode names}``).
    description : str
    proofs : Mapping[str, callable]
        Requirement name -> ``() -> Proof``: a certificate to try before searching.
    structural : callable or None
        ``() -> hybrid.check.CheckReport`` (or any object with ``findings``): the
        structural checks of the automaton, summarised in reports.
    stability : callable or None
        ``() -> analysis.stability.StabilityAnalysis`` (or any object with ``claims``,
        ``verdict`` and ``as_dict()``): the stability analysis the report adds
        (:class:`analysis.stability.StabilityChecks`).
    automaton : hybrid.HybridAutomaton or None
        The switching logic (``visnav mode-graph``); ``None`` when the simulator hides it.
    source : str
        How to load the problem again (``"pkg.mod:problem"``, ``"file.py:problem"``,
        ``"paper"``); written into counterexample files for ``replay``.
    min_budget : int
        The fewest simulations a search of the problem may be given (0: any); a problem over input
        signals (:func:`analysis.verify.signals.signal_problem`) needs at least one per control point.
    sensitivities : callable or None
        ``sensitivities(point) -> (trace, {signal: array (n, k)})``: the run of ``simulate(point)`` (the same
        trace) and, for each numeric signal, ``d signal(t_i) / d p_j`` at its ``n`` samples with respect to the
        ``k`` parameters of the box in their own units (:meth:`trace_sensitivities`); the ``whitebox`` search
        takes its gradients from them (one simulation each).  ``None``: the model gives none (``whitebox``
        uses finite differences, and says so).
    """

    name: str
    simulate: Simulator
    parameters: tuple[Parameter, ...]
    horizon: float
    requirements: tuple[Requirement, ...]
    signals: tuple[str, ...]
    labels: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    description: str = ""
    proofs: Mapping[str, Callable[[], Proof]] = field(default_factory=dict)
    structural: Callable[[], Any] | None = None
    stability: Callable[[], Any] | None = None
    source: str = ""
    automaton: Any = None
    min_budget: int = 0
    sensitivities: Callable[[Mapping[str, float]], tuple[SignalTrace, Mapping[str, np.ndarray]]] | None = None
    parsed: tuple[ParsedRequirement, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ProblemError("VerificationProblem.name", self.name, "a non-empty string", "name the problem")
        if not callable(self.simulate):
            raise ProblemError("VerificationProblem.simulate", self.simulate, "a callable point -> SignalTrace",
                               "pass the function that simulates one point of the box")
        params = tuple(self.parameters)
        for p in params:
            if not isinstance(p, Parameter):
                raise ProblemError("VerificationProblem.parameters", p, "Parameter objects",
                                   "write Parameter(name=..., low=..., high=...)")
        names = [p.name for p in params]
        if len(set(names)) != len(names):
            raise ProblemError("VerificationProblem.parameters", names, "distinct names", "rename the duplicate")
        horizon = _real("VerificationProblem.horizon", self.horizon, "give the simulated time span in seconds")
        if horizon <= 0:
            raise ProblemError("VerificationProblem.horizon", horizon, "a positive duration [s]", "give horizon > 0")
        signals = tuple(self.signals)
        labels = MappingProxyType({k: tuple(v) for k, v in dict(self.labels).items()})
        requirements = tuple(self.requirements)
        if not requirements:
            raise ProblemError("VerificationProblem.requirements", requirements, "at least one Requirement",
                               "add Requirement(name=..., formula=...)")
        if self.stability is not None and not callable(self.stability):
            raise ProblemError("VerificationProblem.stability", self.stability, "a callable () -> StabilityAnalysis",
                               "pass analysis.stability.StabilityChecks(...) or stability=True to hybrid_problem")
        unknown = sorted(set(self.proofs) - {r.name for r in requirements if isinstance(r, Requirement)})
        if unknown:
            raise ProblemError("VerificationProblem.proofs", unknown, "names of the problem's requirements",
                               "key each proof by the requirement it decides")
        if self.sensitivities is not None and not callable(self.sensitivities):
            raise ProblemError("VerificationProblem.sensitivities", self.sensitivities,
                               "a callable point -> (SignalTrace, {signal: array (n, k)}) or None",
                               "pass the function that simulates one point with its sensitivities, or None")
        if isinstance(self.min_budget, bool) or not isinstance(self.min_budget, (int, np.integer)) \
                or self.min_budget < 0:
            raise ProblemError("VerificationProblem.min_budget", self.min_budget, "a non-negative integer",
                               "give the fewest simulations a search needs, or 0")
        constants = tuple(p.name for p in params if p.name not in signals and p.name not in labels)
        parsed = parse_requirements(requirements, signals=(*signals, *constants, "time", "jumps"), labels=labels,
                                    horizon=horizon)
        object.__setattr__(self, "parameters", params)
        object.__setattr__(self, "horizon", horizon)
        object.__setattr__(self, "signals", signals)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "requirements", requirements)
        object.__setattr__(self, "proofs", MappingProxyType(dict(self.proofs)))
        object.__setattr__(self, "parsed", parsed)

    @property
    def dimension(self) -> int:
        """Number of searched coordinates (fixed parameters included)."""
        return len(self.parameters)

    @property
    def requirement_names(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.requirements)

    def point(self, unit: Sequence[float]) -> dict[str, float]:
        """The point (parameter name -> value) at unit coordinates ``unit``, shape ``(dimension,)``."""
        if len(unit) != len(self.parameters):
            raise ProblemError("unit point", tuple(unit), f"{len(self.parameters)} coordinates",
                               "give one coordinate per parameter")
        return {p.name: p.at(u) for p, u in zip(self.parameters, unit)}

    def trace(self, point: Mapping[str, float]) -> SignalTrace:
        """``simulate(point)``, with every parameter a formula reads and the trace lacks added as a constant
        signal (``always (d >= d_min)`` with ``d_min`` a parameter of the box)."""
        return self._with_parameters(point, self.simulate(point))

    def trace_sensitivities(self, point: Mapping[str, float]) -> tuple[SignalTrace, dict[str, np.ndarray]]:
        """``sensitivities(point)``: the trace (as :meth:`trace` gives it) and ``d signal(t_i) / d p_j``, shape
        ``(n, k)``, per numeric signal; a parameter a formula reads as a constant signal has the unit column of
        its own coordinate.  Raises :class:`ProblemError` when the problem gives no sensitivities."""
        if self.sensitivities is None:
            raise ProblemError("VerificationProblem.sensitivities", None, "a callable giving the sensitivities",
                               "use finite differences, or give the problem sensitivities=")
        trace, given = self.sensitivities(point)
        trace = self._with_parameters(point, trace)
        out = {name: np.asarray(value, dtype=float) for name, value in dict(given).items()}
        if isinstance(trace, SignalTrace):
            for j, p in enumerate(self.parameters):
                if p.name in trace.signals and p.name not in out and p.name not in self.signals:
                    column = np.zeros((trace.n, len(self.parameters)))
                    column[:, j] = 1.0
                    out[p.name] = column
        return trace, out

    def without_sensitivities(self) -> VerificationProblem:
        """The same problem with ``sensitivities=None`` (a search then differentiates by finite differences)."""
        return self.with_requirements(self.requirements, sensitivities=None)

    def _with_parameters(self, point: Mapping[str, float], trace: Any) -> Any:
        """``trace`` with the parameters a formula reads and it lacks added as constant signals."""
        if not isinstance(trace, SignalTrace):
            return trace
        read = set().union(*(r.formula.signals for r in self.parsed)) if self.parsed else set()
        missing = [p.name for p in self.parameters if p.name in read and p.name not in trace.signals]
        if not missing:
            return trace
        signals = {**trace.signals, **{name: np.full(trace.n, float(point[name])) for name in missing}}
        return SignalTrace(times=trace.times, signals=signals, labels=trace.labels, jumps=trace.jumps,
                           termination=trace.termination, termination_detail=trace.termination_detail)

    def traces(self, points: Sequence[Mapping[str, float]], executor: Any = None) -> list[SignalTrace]:
        """:meth:`trace` of every point, in order: the same traces as one by one.

        Parameters
        ----------
        points : sequence of Mapping[str, float]
            Points of the box (parameter name -> value), e.g. a Monte-Carlo batch or a finite-difference stencil.
        executor : concurrent.futures.Executor or None
            ``None``: in this process.  An executor (a process pool, :func:`analysis.campaigns.campaign_executor`'s
            backend's ``executor``) runs the simulations there with ``map`` (the simulator must pickle: a
            module-level object, as :func:`analysis.verify.problems.hybrid_problem` builds with a picklable system);
            every simulation is deterministic, so the traces do not depend on the executor.
        """
        batch = [dict(p) for p in points]
        if executor is None:
            return [self.trace(p) for p in batch]
        return [self._with_parameters(p, t) for p, t in zip(batch, executor.map(self.simulate, batch))]

    def nominal(self) -> dict[str, float]:
        """The nominal point."""
        return self.point((0.0,) * len(self.parameters))

    def with_requirements(self, requirements: Sequence[Requirement], *, sensitivities: Any = "same"
                          ) -> VerificationProblem:
        """The same problem with other requirements (proofs of dropped ones removed); ``sensitivities``: the
        problem's own (``"same"``) or another (``None``: none)."""
        names = {r.name for r in requirements}
        return VerificationProblem(
            name=self.name, simulate=self.simulate, parameters=self.parameters, horizon=self.horizon,
            requirements=tuple(requirements), signals=self.signals, labels=self.labels,
            description=self.description, proofs={k: v for k, v in self.proofs.items() if k in names},
            structural=self.structural, stability=self.stability, source=self.source, automaton=self.automaton,
            min_budget=self.min_budget,
            sensitivities=self.sensitivities if isinstance(sensitivities, str) else sensitivities,
        )
