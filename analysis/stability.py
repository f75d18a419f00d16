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
3. **a piecewise quadratic Lyapunov function** (Johansson & Rantzer 1998,
   :func:`analysis.lmi.piecewise_quadratic_lyapunov`) when no common one exists and the automaton is
   *conewise linear about* ``x*`` (:func:`conewise_cells`): every invariant a conjunction of terms
   affine in the state that vanish at ``x*`` (each mode a polyhedral cone through ``x*``, found by
   :func:`hybrid.affine.system_affinity`), every jump map the identity, no memory written, and every
   transition between two modes jumping on a hyperplane ``hᵀ(x − x*) = 0`` that both cones bound
   (opposite rows ``h``, ``−h``), where ``V`` is made continuous.  Then ``V(x, q) = (x − x*)ᵀP_q(x − x*)``
   is positive on each mode's cone, decreases along each mode's flow there and does not change at a
   jump: it proves that every execution converges to ``x*`` under the automaton's *own*
   state-dependent switching (not under arbitrary switching), for executions that cross the switching
   surfaces into the next mode's region (no sliding or Zeno chattering along one, no jump into a mode
   whose invariant fails there: :func:`hybrid.check` looks for those).  The exact re-check covers the
   cones as the affinity test reads them off the model (to its relative ``1e-9``).  Otherwise
   :attr:`StabilityAnalysis.piecewise_note` says which mode, term or transition rules it out;
4. **a region of attraction** of each mode's own Hurwitz equilibrium when the modes do not share
   one linear equilibrium (:func:`analysis.mode_region.mode_region_of_attraction`: polynomial flow,
   invariant and guards; an SOS search re-proven by interval branch and bound that the set stays in
   the mode, no transition is enabled in it, and every execution from it converges);
5. **a limit cycle** when no mode has an equilibrium of its own (every one virtual, or none): the
   system is simulated from the given state, and the periodic orbit through the section of the
   transition it takes last is found by shooting (:mod:`analysis.periodic`): period, Floquet
   multipliers, orbitally stable or not.

Every conclusion is a :class:`StabilityClaim` marked ``proven`` (a re-checked certificate),
``measured`` (deterministic numerics: eigenvalues, multipliers of a converged orbit) or
``not decided`` (with why).  :class:`StabilityChecks` is the picklable ``() -> StabilityAnalysis``
that :func:`analysis.verify.problems.hybrid_problem` attaches to a verification problem.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid import Box, HybridSystem
from hybrid.affine import NotAffine, SystemAffinity, system_affinity
from hybrid.errors import ExecutionError, ModelDefinitionError, ParameterError
from hybrid.jsonable import to_jsonable
from hybrid.system import state_vector

from analysis.derivatives import mode_vector_field
from analysis.equilibria import ModeEquilibrium, mode_equilibria

__all__ = ["StabilityClaim", "StabilityAnalysis", "StabilityChecks", "ConewiseCells", "analyse_stability",
           "conewise_cells", "STABILITY_VERDICTS"]

STABILITY_VERDICTS = ("stable", "unstable", "not decided")

_LINEAR_PROBES = 3
"""Points (besides the equilibrium) where a mode's Jacobian must equal its value at ``x*`` to call the mode linear."""

_VANISH_TOL = 1e-9
"""Relative size of ``a·x* + b`` below which an invariant term vanishes at ``x*``: the coefficients come
from :func:`hybrid.affine.affine_form`, accepted at a relative defect of ``1e-9``, so a term through
``x*`` is only known to that accuracy (rounding alone leaves about ``1e-16``)."""

_IDENTITY_TOL = 1e-12
"""Largest deviation of a jump map's matrix from ``I`` (and of its offset, relative to ``1 + |x*|``) still
called the identity: the affinity test's central differences of ``x ↦ x`` err by rounding only (a few
ulp, about ``1e-16``); anything larger is a genuine change of state that ``V`` would have to absorb."""

_OPPOSITE_TOL = 1e-9
"""Relative distance of a row ``q`` from the ray of ``−r`` below which the two cones share the hyperplane
``rᵀx = 0``: the rows are affinity coefficients, known to the ``1e-9`` of :data:`_VANISH_TOL`."""


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
    piecewise : object or None
        :class:`analysis.lmi.PiecewiseQuadraticLMI` when no common quadratic Lyapunov function exists
        and the automaton is conewise linear about the common equilibrium (:func:`conewise_cells`).
    piecewise_note : str
        Why no piecewise quadratic function was searched for (empty when it was).
    regions : tuple of analysis.mode_region.ModeRegion
        The SOS region of attraction of each mode's own Hurwitz equilibrium (when the modes do not
        share one linear equilibrium), proven or with why not.
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
    piecewise: Any = None
    piecewise_note: str = ""
    regions: tuple[Any, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view of every part."""
        return to_jsonable({
            "system": self.system, "verdict": self.verdict, "finding": self.finding,
            "equilibria": [e.as_dict() for e in self.equilibria],
            "switched": None if self.switched is None else self.switched.as_dict(),
            "dwell": None if self.dwell is None else self.dwell.as_dict(),
            "piecewise": None if self.piecewise is None else self.piecewise.as_dict(),
            "piecewise_note": self.piecewise_note,
            "regions": [r.as_dict() for r in self.regions],
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


@dataclass(frozen=True, kw_only=True, slots=True)
class ConewiseCells:
    """The cells of an automaton that is conewise linear about ``x*`` (:func:`conewise_cells`), or why it is not.

    Attributes
    ----------
    cells : tuple of analysis.lmi.LinearCell
        One per mode, in declaration order, named by the mode: ``A`` the mode's matrix and ``E`` the
        rows ``a`` of its invariant's terms ``a·x + b`` (a cone ``E(x − x*) ≥ 0``; no rows without an
        invariant).  Empty when :attr:`reason` is set.
    boundaries : tuple of (str, str, tuple of float)
        ``(mode, mode, h)`` for every pair of distinct modes joined by a transition: a hyperplane
        ``hᵀ(x − x*) = 0`` bounding both cones, on which that transition's jumps happen.
    reason : str
        Empty for a conewise linear automaton; else the mode, term or transition that rules it out.
    """

    cells: tuple[Any, ...] = ()
    boundaries: tuple[tuple[str, str, tuple[float, ...]], ...] = ()
    reason: str = ""


def _affinity(system: HybridSystem, point: np.ndarray, memory: Mapping[str, float]) -> SystemAffinity | str:
    """:func:`hybrid.affine.system_affinity` on ``x* ± (1 + |x*|∞)``, memory held fixed; or why it failed."""
    scale = 1.0 + float(np.abs(point).max())
    declared = {m.name for m in system.automaton.memory}
    box = Box(bounds={name: (float(c) - scale, float(c) + scale) for name, c in zip(system.state_names, point)},
              memory={name: (float(v), float(v)) for name, v in memory.items() if name in declared})
    try:
        return system_affinity(system, box, what=f"the conewise-linear test of system {system.name!r}")
    except (ModelDefinitionError, ExecutionError, ArithmeticError, ValueError) as err:  # the model raised on the box
        return f"the affinity test of its functions on the box x* ± {scale:g} failed: {err}"


def _cone_rows(affinity: SystemAffinity, point: np.ndarray) -> dict[str, np.ndarray] | str:
    """Each mode's rows ``a`` (invariant terms ``a·x + b`` vanishing at ``x*``), or the first term that is not."""
    n = point.size
    rows: dict[str, np.ndarray] = {}
    for mode, result in affinity.modes.items():
        kept = []
        for k, term in enumerate(result.invariant):
            what = f"invariant term {k} of mode {mode!r}"
            if isinstance(term, NotAffine):
                return f"{what} is not affine in the state about x*: {term.reason}"
            a, b = np.array(term.matrix[0][:n], dtype=float), float(term.offset[0])
            value = float(a @ point) + b
            if abs(value) > _VANISH_TOL * (float(np.abs(a) @ np.abs(point)) + abs(b) + 1.0):
                return (f"{what} is {value:.6g} at x* = {point.tolist()}, not 0: the mode's region is not a cone "
                        "through the equilibrium")
            if np.any(a):  # a term a = 0, b = 0 holds everywhere: no constraint
                kept.append(a)
        rows[mode] = np.array(kept, dtype=float).reshape(len(kept), n)
    return rows


def _jump_fault(system: HybridSystem, affinity: SystemAffinity, point: np.ndarray) -> str:
    """Why some jump map is not the identity (``""`` when every one is)."""
    n = point.size
    for t in system.automaton.transitions:
        jump = affinity.transitions[t.name].jump_map
        what = f"the jump map of transition {t.name!r} ({t.source!r} -> {t.target!r})"
        if isinstance(jump, NotAffine):
            return f"{what} is not affine, let alone the identity: {jump.reason}"
        m, c = np.array(jump.matrix, dtype=float)[:, :n], np.array(jump.offset, dtype=float)
        if float(np.abs(m - np.eye(n)).max()) > _IDENTITY_TOL or \
                float(np.abs(c).max()) > _IDENTITY_TOL * (1.0 + float(np.abs(point).max())):
            return (f"{what} is x⁺ = M x + c with M = {m.tolist()}, c = {c.tolist()}, not the identity: the state "
                    "changes at the jump, and V is only known not to change when the state is kept")
    return ""


def _opposite_rows(r: np.ndarray, q: np.ndarray) -> bool:
    """Whether ``q = −c·r`` for some ``c > 0``, to the relative :data:`_OPPOSITE_TOL`."""
    dot, rr = float(r @ q), float(r @ r)
    if dot >= 0.0 or rr == 0.0:
        return False
    return float(np.linalg.norm(q - (dot / rr) * r)) <= _OPPOSITE_TOL * float(np.linalg.norm(q))


def _jump_surfaces(system: HybridSystem,
                   rows: Mapping[str, np.ndarray]) -> list[tuple[str, str, tuple[float, ...]]] | str:
    """The hyperplanes of the transitions between distinct modes, or the first transition that has none.

    A jump ``i → j`` happens at a state in the cone of ``i`` (the flow kept it there) from which mode
    ``j`` flows, so in its cone too: opposite rows ``h`` of ``E_i`` and ``−c·h`` of ``E_j`` put the
    state on ``hᵀ(x − x*) = 0``, where continuity of ``V`` is imposed.
    """
    out: list[tuple[str, str, tuple[float, ...]]] = []
    for t in system.automaton.transitions:
        if t.source == t.target:
            continue
        shared = [r for r in rows[t.source] if any(_opposite_rows(r, q) for q in rows[t.target])]
        if not shared:
            return (f"transition {t.name!r} from mode {t.source!r} to mode {t.target!r}: no row h of the cone of "
                    f"{t.source!r} has a row −c·h (c > 0) in the cone of {t.target!r}, so its jumps are not confined "
                    "to a hyperplane hᵀ(x − x*) = 0 on which V can be continuous (overlapping regions, as with "
                    "hysteresis, or regions that do not touch)")
        for h in shared:
            if not any({b[0], b[1]} == {t.source, t.target} and (_opposite_rows(h, np.array(b[2]))
                                                                  or _opposite_rows(h, -np.array(b[2])))
                       for b in out):
                out.append((t.source, t.target, tuple(float(x) for x in h)))
    return out


def conewise_cells(system: HybridSystem, point: Sequence[float], family: Sequence[Any],
                   memory: Mapping[str, float] | None = None) -> ConewiseCells:
    """Whether ``system`` is a conewise linear system about ``point`` (module docstring, item 3), and its cells.

    Parameters
    ----------
    system : HybridSystem
    point : sequence of float, shape (n,)
        The common equilibrium ``x*``.
    family : sequence of array_like, each shape (n, n)
        The modes' matrices about ``x*``, in the automaton's mode order (see :func:`analyse_stability`).
    memory : Mapping or None
        The memory the flows and invariants are evaluated with (default: the initial memory).

    Returns
    -------
    ConewiseCells
        The cells and the jump hyperplanes, or the reason (a memory write, an invariant term that is
        not affine or does not vanish at ``x*``, a jump map that is not the identity, a transition
        between two modes whose cones share no hyperplane).
    """
    from analysis.lmi import LinearCell

    x_star = np.asarray(point, dtype=float).reshape(-1)
    for t in system.automaton.transitions:
        if t.writes:
            return ConewiseCells(reason=f"transition {t.name!r} writes memory {list(t.writes)}: the flows are "
                                        "analysed with the memory fixed")
    mem = dict(system.automaton.initial_memory() if memory is None else memory)
    affinity = _affinity(system, x_star, mem)
    if isinstance(affinity, str):
        return ConewiseCells(reason=affinity)
    rows = _cone_rows(affinity, x_star)
    if isinstance(rows, str):
        return ConewiseCells(reason=rows)
    fault = _jump_fault(system, affinity, x_star)
    if fault:
        return ConewiseCells(reason=fault)
    surfaces = _jump_surfaces(system, rows)
    if isinstance(surfaces, str):
        return ConewiseCells(reason=surfaces)
    cells = tuple(LinearCell(A=np.asarray(a, dtype=float), E=rows[mode], name=mode)
                  for mode, a in zip(system.automaton.mode_names, family))
    return ConewiseCells(cells=cells, boundaries=tuple(surfaces))


def _equilibrium_claims(equilibria: Sequence[ModeEquilibrium]) -> list[StabilityClaim]:
    return [StabilityClaim(text=f"mode {e.mode!r}: {e.finding}", status="measured",
                           method=f"Newton on the flow, eigenvalues of the Jacobian ({e.derivatives})")
            for e in equilibria]


def _solver_text(runs: Any) -> str:
    """The solver runs of an LMI result in words (``CLARABEL: optimal; ...``)."""
    if isinstance(runs, str):
        return runs
    return "; ".join(f"{r.solver}: {r.status}" for r in runs) or "no solve"


def _piecewise_claim(piecewise: Any, note: str, point: Sequence[float]) -> StabilityClaim:
    """The claim of the piecewise quadratic search: proven, undecided, or not applicable (with ``note``)."""
    if piecewise is None:
        return StabilityClaim(text="no piecewise quadratic Lyapunov function was searched for: the automaton is not "
                                   f"conewise linear about x*: {note}", status="not decided",
                              method="conewise-linear test: memory writes, affinity of the invariants and jump maps "
                                     "(hybrid.affine.system_affinity), switching surfaces shared by the cones")
    method = (f"piecewise quadratic LMI, Johansson–Rantzer ({_solver_text(piecewise.solver)}), "
              f"{piecewise.recheck.method}, on the cones found by the affinity test of the invariants")
    if not piecewise.proven:
        return StabilityClaim(text=piecewise.finding, status="not decided", method=method)
    rate = f"V̇ <= -{piecewise.margin:.4g}·V" if piecewise.margin > 0 else "V̇ < 0"
    return StabilityClaim(
        text=(f"every execution of the automaton converges exponentially to x* = "
              f"({', '.join(f'{float(c):.6g}' for c in point)}) under "
              "its own state-dependent switching (not under arbitrary switching): V = (x − x*)ᵀP_q(x − x*) in mode q "
              f"is positive on the mode's cone, continuous on the {len(piecewise.boundaries)} switching surface(s) "
              f"where the transitions jump, and {rate} along each mode's flow in its cone (exact rational re-check); "
              "this covers executions that cross the switching surfaces into the next mode's region (no sliding "
              "or Zeno chattering along one, no jump into a mode whose invariant fails)"),
        status="proven", method=method)


def _switched_claims(switched: Any, dwell: Any, piecewise: Any, note: str,
                     point: Sequence[float]) -> tuple[list[StabilityClaim], str]:
    """Claims and verdict of the LMI analyses: common quadratic, dwell time, piecewise quadratic (in that order)."""
    claims = [StabilityClaim(text=switched.finding, status="proven" if switched.proven else "not decided",
                             method=f"LMI ({_solver_text(switched.solver)}), {switched.recheck.method}")]
    if switched.status == "exists":
        return claims, "stable"
    if dwell is not None:
        claims.append(StabilityClaim(text=dwell.finding, status="proven" if dwell.proven else "not decided",
                                     method=f"LMI with matrix exponentials ({_solver_text(dwell.solver)}), {dwell.recheck.method}"))
    claims.append(_piecewise_claim(piecewise, note, point))
    return claims, "stable" if piecewise is not None and piecewise.proven else "not decided"


def _lmi_analyses(system: HybridSystem, family: Sequence[np.ndarray], equilibria: Sequence[ModeEquilibrium],
                  memory: Mapping[str, float]) -> tuple[Any, Any, Any, str]:
    """Common quadratic function; without one, a dwell time (Hurwitz modes) and a piecewise quadratic function.

    Returns ``(switched, dwell, piecewise, piecewise_note)``.
    """
    from analysis.lmi import common_quadratic_lyapunov_lmi, dwell_time_lyapunov

    modes = [e.mode for e in equilibria]
    switched = common_quadratic_lyapunov_lmi(family, modes)
    if switched.status == "exists":
        return switched, None, None, "not needed: a common quadratic Lyapunov function exists"
    dwell = dwell_time_lyapunov(family, modes) if all(e.hurwitz for e in equilibria) else None
    piecewise, note = _piecewise(system, family, equilibria[0].point, memory)
    return switched, dwell, piecewise, note


def _piecewise(system: HybridSystem, family: Sequence[np.ndarray], point: Sequence[float],
               memory: Mapping[str, float]) -> tuple[Any, str]:
    """The piecewise quadratic search on the automaton's cones, or ``None`` and why it does not apply."""
    from analysis.lmi import piecewise_quadratic_lyapunov

    cone = conewise_cells(system, point, family, memory)
    if cone.reason:
        return None, cone.reason
    return piecewise_quadratic_lyapunov(cone.cells, boundaries=cone.boundaries), ""


def _orbit_claims(orbit: Any) -> tuple[list[StabilityClaim], str]:
    claim = StabilityClaim(text=orbit.finding, status="measured",
                           method=f"shooting on the section of {orbit.section!r}, monodromy with saltation "
                                  f"matrices ({orbit.derivatives})")
    verdict = {"orbitally stable": "stable", "unstable": "unstable"}.get(orbit.verdict, "not decided")
    return [claim], verdict


def _local_claims(own: Sequence[ModeEquilibrium]) -> tuple[list[StabilityClaim], str]:
    """The verdict of the modes' own equilibria (no common linear family, not all virtual): eigenvalues."""
    unstable = [e for e in own if not e.hurwitz]
    verdict = "unstable" if any(max(m.real for m in e.modes) > 0 for e in unstable) else (
        "stable" if not unstable and len(own) == 1 else "not decided")
    return [StabilityClaim(
        text=("local: the equilibrium of mode(s) " + ", ".join(repr(e.mode) for e in own)
              + (" is exponentially stable while the mode is kept (Hurwitz Jacobian)" if verdict == "stable"
                 else " decides the local behaviour: " + "; ".join(e.finding for e in own))),
        status="measured", method="eigenvalues of the Jacobian at the equilibrium")], verdict


def _snapped(system: HybridSystem, e: ModeEquilibrium, memory: Mapping[str, float]) -> tuple[float, ...]:
    """Newton's ``x*`` with components below ``1e-12·(1 + ‖x*‖∞)`` set to 0 when the flow still vanishes there.

    Newton leaves ``1e-18`` where the equilibrium is ``0``; the region's claim is about the point it is
    given (exactly an equilibrium, or one nearby with a proven distance), so the clean point is kept
    only when the flow there is no larger than at Newton's.
    """
    point = np.asarray(e.point, dtype=float)
    clean = np.where(np.abs(point) <= 1e-12 * (1.0 + float(np.abs(point).max())), 0.0, point)
    size = [float(np.abs(np.asarray(system.flow(e.mode, 0.0, tuple(p), dict(memory)), dtype=float)).max())
            for p in (point, clean)]
    return tuple(float(c) for c in (clean if size[1] <= size[0] else point))


def _mode_regions(system: HybridSystem, own: Sequence[ModeEquilibrium],
                  memory: Mapping[str, float]) -> tuple[tuple[Any, ...], list[StabilityClaim]]:
    """The SOS region of attraction of each Hurwitz equilibrium of ``own`` (:mod:`analysis.mode_region`)."""
    from analysis.mode_region import mode_region_of_attraction

    regions, claims = [], []
    for e in own:
        if not e.hurwitz:
            continue
        region = mode_region_of_attraction(system, e.mode, equilibrium=_snapped(system, e, memory), memory=memory)
        regions.append(region)
        if region.status == "proven":
            claims.append(StabilityClaim(
                text=f"mode {e.mode!r}: {region.claim}", status="proven",
                method=(f"SOS search (V of degree {region.degree}), interval branch and bound on the exact "
                        "polynomials of the flow, invariant and guards, every certificate re-checked")))
        else:
            claims.append(StabilityClaim(
                text=f"mode {e.mode!r}: no region of attraction proven ({region.status}): {region.why}",
                status="not decided", method="SOS region of attraction (analysis.mode_region)"))
    return tuple(regions), claims


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
    regions: bool = True,
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
    regions : bool
        Look for an SOS region of attraction of each mode's own Hurwitz equilibrium (when the modes
        do not share one linear equilibrium): a few seconds per mode in the plane, more above.

    Raises
    ------
    ParameterError
        Not a system, a state of the wrong length, a non-positive horizon, an unknown section.
    """
    if not isinstance(system, HybridSystem):
        raise ParameterError("system", system, "a hybrid.HybridSystem", "build the system with hybrid.HybridSystem")
    if not (isinstance(horizon, (int, float)) and math.isfinite(horizon) and horizon > 0):
        raise ParameterError("horizon", horizon, "a positive duration [s]", "give e.g. horizon=100.0")
    if not isinstance(regions, bool):
        raise ParameterError("regions", regions, "True or False", "write regions=False to skip the SOS regions")
    names = [t.name for t in system.automaton.transitions]
    if section is not None and section not in names:
        raise ParameterError("section", section, f"one of the transitions {names}", "name the transition whose "
                             "guard is the Poincaré section")
    initial_state = tuple(state_vector("initial_state", initial_state, system.state_names).tolist())
    mem = dict(system.automaton.initial_memory() if memory is None else memory)
    equilibria = mode_equilibria(system, guess=initial_state, memory=mem)
    claims = _equilibrium_claims(equilibria)
    switched = dwell = orbit = piecewise = None
    orbit_error = ""
    own = [e for e in equilibria if e.kind == "equilibrium"]
    family = _common_linear_family(system, equilibria, mem)
    note = "not tried: the modes are not all linear about one common equilibrium"
    if family is not None:
        switched, dwell, piecewise, note = _lmi_analyses(system, family, equilibria, mem)
        more, verdict = _switched_claims(switched, dwell, piecewise, note, equilibria[0].point)
    elif not own:
        orbit, orbit_error = _find_orbit(system, initial_state, initial_mode, float(horizon), section)
        if orbit is not None:
            more, verdict = _orbit_claims(orbit)
        else:
            more, verdict = [StabilityClaim(text=orbit_error, status="not decided", method="periodic orbit")], \
                "not decided"
    else:
        more, verdict = _local_claims(own)
    found, region_claims = _mode_regions(system, own, mem) if regions and family is None else ((), [])
    claims += more
    finding = f"{system.name}: {verdict}: " + more[-1].text
    proven = [r.mode for r in found if r.status == "proven"]
    if proven:
        finding += f"; a region of attraction is proven for mode(s) {', '.join(map(repr, proven))}"
    claims += region_claims
    return StabilityAnalysis(system=system.name, verdict=verdict, equilibria=equilibria, switched=switched,
                             dwell=dwell, orbit=orbit, orbit_error=orbit_error, claims=tuple(claims),
                             finding=finding, piecewise=piecewise, piecewise_note=note, regions=found)


@dataclass(frozen=True, kw_only=True, slots=True)
class StabilityChecks:
    """``() -> StabilityAnalysis`` of a system from a state (picklable when the system is)."""

    model: HybridSystem
    initial_state: tuple[float, ...]
    initial_mode: str | None = None
    horizon: float = 100.0
    section: str | None = None
    regions: bool = True

    def __call__(self) -> StabilityAnalysis:
        return analyse_stability(self.model, initial_state=self.initial_state, initial_mode=self.initial_mode,
                                 horizon=self.horizon, section=self.section, regions=self.regions)
