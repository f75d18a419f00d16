"""Stability of a user's hybrid system: the certificate that fits it, or the reason none does.

:func:`analyse_stability` looks at a :class:`hybrid.HybridSystem` as a switching engineer would:

1. **the equilibria of the modes** (:mod:`analysis.equilibria`): each mode's equilibrium found by
   Newton and checked against the mode's invariant — an equilibrium outside its mode is *virtual*,
   and its eigenvalues say nothing about the hybrid system;
2. **a common equilibrium under switching**: when every mode is linear about one point (the
   Jacobians constant, the flows vanishing at the same ``x*``), the family ``A_q`` is analysed by
   LMIs (:mod:`analysis.lmi`): a common quadratic Lyapunov function, re-checked in exact rational
   arithmetic, proves stability under *arbitrary* switching; its absence is proven by a re-checked
   dual certificate, and mode-dependent Lyapunov functions then give a dwell time that suffices;
3. **a limit cycle** when no mode has an equilibrium of its own (every one virtual, or none): the
   system is simulated from the given state, and the periodic orbit through the section of the
   transition it takes last is found by shooting (:mod:`analysis.periodic`): period, Floquet
   multipliers, orbitally stable or not.

Every conclusion is a :class:`StabilityClaim` marked ``proven`` (a re-checked certificate),
``measured`` (deterministic numerics: eigenvalues, multipliers of a converged orbit) or
``not decided`` (with why).  :class:`StabilityChecks` is the picklable ``() -> StabilityAnalysis``
that :func:`analysis.problems.hybrid_problem` attaches to a verification problem.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid import HybridSystem
from hybrid.errors import ExecutionError, ParameterError
from hybrid.jsonable import to_jsonable

from analysis.derivatives import mode_vector_field
from analysis.equilibria import ModeEquilibrium, mode_equilibria

__all__ = ["StabilityClaim", "StabilityAnalysis", "StabilityChecks", "analyse_stability", "STABILITY_VERDICTS"]

STABILITY_VERDICTS = ("stable", "unstable", "not decided")

_LINEAR_PROBES = 3
"""Points (besides the equilibrium) where a mode's Jacobian must equal its value at ``x*`` to call the mode linear."""


@dataclass(frozen=True, kw_only=True, slots=True)
class StabilityClaim:
    """One conclusion: ``text``, ``status`` (``proven``, ``measured``, ``not decided``) and ``method``."""

    text: str
    status: str
    method: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {"text": self.text, "status": self.status, "method": self.method}


@dataclass(frozen=True, kw_only=True, slots=True)
class StabilityAnalysis:
    """Result of :func:`analyse_stability`.

    Attributes
    ----------
    system : str
    verdict : str
        One of :data:`STABILITY_VERDICTS`.
    equilibria : tuple of ModeEquilibrium
    switched : object or None
        :class:`analysis.lmi.CommonLyapunovLMI` when the modes share a linear equilibrium.
    dwell : object or None
        :class:`analysis.lmi.DwellTimeLMI` when no common quadratic Lyapunov function exists.
    orbit : object or None
        :class:`analysis.periodic.PeriodicOrbit` when the steady state is a limit cycle.
    orbit_error : str
        Why the orbit search failed (empty otherwise).
    claims : tuple of StabilityClaim
    finding : str
    """

    system: str
    verdict: str
    equilibria: tuple[ModeEquilibrium, ...]
    switched: Any
    dwell: Any
    orbit: Any
    orbit_error: str
    claims: tuple[StabilityClaim, ...]
    finding: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view of every part."""
        return to_jsonable({
            "system": self.system, "verdict": self.verdict, "finding": self.finding,
            "equilibria": [e.as_dict() for e in self.equilibria],
            "switched": None if self.switched is None else self.switched.as_dict(),
            "dwell": None if self.dwell is None else self.dwell.as_dict(),
            "orbit": None if self.orbit is None else self.orbit.as_dict(),
            "orbit_error": self.orbit_error,
            "claims": [c.as_dict() for c in self.claims],
        }, nonfinite="string")


def _common_linear_family(system: HybridSystem, equilibria: Sequence[ModeEquilibrium],
                          memory: Mapping[str, float]) -> list[np.ndarray] | None:
    """The Jacobians ``A_q`` when every mode is linear about one common equilibrium, else ``None``."""
    points = [e.point for e in equilibria]
    if any(p is None for p in points):
        return None
    first = np.asarray(points[0])
    scale = 1.0 + float(np.abs(first).max())
    if any(float(np.abs(np.asarray(p) - first).max()) > 1e-9 * scale for p in points):
        return None
    rng = np.random.default_rng(0)
    family = []
    for eq in equilibria:
        field_ = mode_vector_field(system, eq.mode, memory=memory)
        for _ in range(_LINEAR_PROBES):
            x = first + scale * rng.uniform(-1.0, 1.0, first.size)
            if not np.allclose(field_.jacobian(x), eq.jacobian, rtol=1e-9, atol=1e-9 * scale):
                return None
        family.append(np.asarray(eq.jacobian))
    return family


def _equilibrium_claims(equilibria: Sequence[ModeEquilibrium]) -> list[StabilityClaim]:
    return [StabilityClaim(text=f"mode {e.mode!r}: {e.finding}", status="measured",
                           method=f"Newton on the flow, eigenvalues of the Jacobian ({e.derivatives})")
            for e in equilibria]


def _solver_text(runs: Any) -> str:
    """The solver runs of an LMI result in words (``CLARABEL: optimal; ...``)."""
    if isinstance(runs, str):
        return runs
    return "; ".join(f"{r.solver}: {r.status}" for r in runs) or "no solve"


def _switched_claims(switched: Any, dwell: Any) -> tuple[list[StabilityClaim], str]:
    claims = [StabilityClaim(text=switched.finding, status="proven" if switched.proven else "not decided",
                             method=f"LMI ({_solver_text(switched.solver)}), {switched.recheck.method}")]
    if switched.status == "exists":
        return claims, "stable"
    if dwell is not None:
        claims.append(StabilityClaim(text=dwell.finding, status="proven" if dwell.proven else "not decided",
                                     method=f"LMI with matrix exponentials ({_solver_text(dwell.solver)}), {dwell.recheck.method}"))
    return claims, "not decided"


def _orbit_claims(orbit: Any) -> tuple[list[StabilityClaim], str]:
    claim = StabilityClaim(text=orbit.finding, status="measured",
                           method=f"shooting on the section of {orbit.section!r}, monodromy with saltation "
                                  f"matrices ({orbit.derivatives})")
    verdict = {"orbitally stable": "stable", "unstable": "unstable"}.get(orbit.verdict, "not decided")
    return [claim], verdict


def _find_orbit(system: HybridSystem, x0: Sequence[float], initial_mode: str | None, horizon: float,
                section: str | None) -> tuple[Any, str]:
    """Simulate, take the section (the last transition taken, or ``section``) and shoot from its last crossing."""
    from hybrid.continuous import simulate_continuous

    from analysis.periodic import periodic_orbit

    try:
        run = simulate_continuous(system, tuple(x0), duration=horizon, initial_mode=initial_mode)
    except ExecutionError as err:
        return None, f"the run from x0 = {list(x0)} to find a limit cycle failed: {err}"
    events = [e for e in run.events if section is None or e.transition == section]
    if not events:
        return None, (f"no jump {'through ' + repr(section) + ' ' if section else ''}in the {horizon:g} s run from "
                      f"x0 = {list(x0)}: no periodic switching to analyse (give another initial state, a longer "
                      "horizon or the section)")
    last = events[-1]
    try:
        orbit = periodic_orbit(system, section=last.transition, initial_state=last.state_before)
    except (ParameterError, ExecutionError, ArithmeticError) as err:
        return None, f"shooting on the section of {last.transition!r} failed: {err}"
    return orbit, ""


def analyse_stability(
    system: HybridSystem,
    *,
    initial_state: Sequence[float],
    initial_mode: str | None = None,
    horizon: float = 100.0,
    section: str | None = None,
    memory: Mapping[str, float] | None = None,
) -> StabilityAnalysis:
    """The stability analysis of ``system`` (module docstring).

    Parameters
    ----------
    system : HybridSystem
    initial_state : sequence of float, shape (n,)
        The guess for the equilibria and the start of the run that looks for a limit cycle.
    initial_mode : str or None
        The run's initial mode (default: the automaton's).
    horizon : float
        Length of that run [s]: long enough to settle on the cycle.
    section : str or None
        The transition whose guard is the Poincaré section (default: the last one taken).
    memory : Mapping or None
        Memory values for the flows (default: the initial memory).

    Raises
    ------
    ParameterError
        Not a system, a state of the wrong length, a non-positive horizon, an unknown section.
    """
    if not isinstance(system, HybridSystem):
        raise ParameterError("system", system, "a hybrid.HybridSystem", "build the system with hybrid.HybridSystem")
    if not (isinstance(horizon, (int, float)) and math.isfinite(horizon) and horizon > 0):
        raise ParameterError("horizon", horizon, "a positive duration [s]", "give e.g. horizon=100.0")
    names = [t.name for t in system.automaton.transitions]
    if section is not None and section not in names:
        raise ParameterError("section", section, f"one of the transitions {names}", "name the transition whose "
                             "guard is the Poincaré section")
    mem = dict(system.automaton.initial_memory() if memory is None else memory)
    equilibria = mode_equilibria(system, guess=initial_state, memory=mem)
    claims = _equilibrium_claims(equilibria)
    switched = dwell = orbit = None
    orbit_error = ""
    own = [e for e in equilibria if e.kind == "equilibrium"]
    family = _common_linear_family(system, equilibria, mem)
    if family is not None:
        from analysis.lmi import common_quadratic_lyapunov_lmi, dwell_time_lyapunov

        modes = [e.mode for e in equilibria]
        switched = common_quadratic_lyapunov_lmi(family, modes)
        if switched.status != "exists" and all(e.hurwitz for e in equilibria):
            dwell = dwell_time_lyapunov(family, modes)
        more, verdict = _switched_claims(switched, dwell)
    elif not own:
        orbit, orbit_error = _find_orbit(system, initial_state, initial_mode, float(horizon), section)
        if orbit is not None:
            more, verdict = _orbit_claims(orbit)
        else:
            more, verdict = [StabilityClaim(text=orbit_error, status="not decided", method="periodic orbit")], \
                "not decided"
    else:
        unstable = [e for e in own if not e.hurwitz]
        verdict = "unstable" if any(max(m.real for m in e.modes) > 0 for e in unstable) else (
            "stable" if not unstable and len(own) == 1 else "not decided")
        more = [StabilityClaim(
            text=("local: the equilibrium of mode(s) " + ", ".join(repr(e.mode) for e in own)
                  + (" is exponentially stable while the mode is kept (Hurwitz Jacobian)" if verdict == "stable"
                     else " decides the local behaviour: " + "; ".join(e.finding for e in own))),
            status="measured", method="eigenvalues of the Jacobian at the equilibrium")]
    claims += more
    finding = f"{system.name}: {verdict}: " + more[-1].text
    return StabilityAnalysis(system=system.name, verdict=verdict, equilibria=equilibria, switched=switched,
                             dwell=dwell, orbit=orbit, orbit_error=orbit_error, claims=tuple(claims),
                             finding=finding)


@dataclass(frozen=True, kw_only=True, slots=True)
class StabilityChecks:
    """``() -> StabilityAnalysis`` of a system from a state (picklable when the system is)."""

    model: HybridSystem
    initial_state: tuple[float, ...]
    initial_mode: str | None = None
    horizon: float = 100.0
    section: str | None = None

    def __call__(self) -> StabilityAnalysis:
        return analyse_stability(self.model, initial_state=self.initial_state, initial_mode=self.initial_mode,
                                 horizon=self.horizon, section=self.section)
