"""Closed-loop mutants: slips in the feature estimator and in the blend of the controllers.

The supervisor mutants of :mod:`visnav.fuzzing.mutants` change the automaton;
these change what sits around it in the closed loop, with the resolved
supervisor.  Each is a documented transform, nothing is monkeypatched:

* an **estimator** mutant is a :class:`~visnav.estimator.FeatureEstimator`
  subclass whose screw for the implicit BDF stage is not the one
  ``EstimatorSettings.screw_model`` asks for (the loop builds it instead of
  the resolved estimator);
* a **blend** mutant is a blending law written with one wrong weight: it
  combines the loop's own pure controls (visual servoing, occlusion
  avoidance, avoidance with the real and with the reconstructed pan rate,
  :class:`PureControls`, computed by the resolved
  :meth:`visnav.closed_loop.ClosedLoop.command`) with the real
  :func:`~visnav.controllers.avoidance_control` (18) and
  :func:`~visnav.controllers.blend` (19), but passes them the wrong µ.

They run in the closed loop only (:func:`visnav.fuzzing.closed_loop.simulate_variant`
by name, and ``visnav fuzz --variant NAME`` for the closed-loop properties);
the open-loop fuzzer drives supervisors, and the supervisor of a loop mutant
is the resolved one, so the signal properties hold on it by construction.

==========================  ==========================================================================
mutant                      slip
==========================  ==========================================================================
``held_screw_end``          the BDF stage uses the held screw ``J_r(ϑ_{k+1}) q̇_k`` at the end of the
                            period whatever ``screw_model`` says (a silent fallback)
``held_screw_start``        the same with the held screw ``J_r(ϑ_k) q̇_k`` at the start of the period
``blend_one_minus_mu_occ``  eq. (19) is evaluated with ``1 − µ_occ`` where it reads ``µ_occ``: q̇_VS and
                            q̇_occ swap weights
``pan_mix_mu_coll``         eq. (18) mixes the real and the reconstructed pan rates with ``µ_coll``
                            where it reads ``µ_occ``
==========================  ==========================================================================

Examples
--------
>>> sorted(LOOP_MUTANTS)[:2]
['blend_one_minus_mu_occ', 'held_screw_end']
>>> loop_mutant("pan_mix_mu_coll").part
'blend'
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

from visnav.controllers import avoidance_control, blend
from visnav.estimator import FeatureEstimator
from visnav.model import camera_screw

__all__ = ["LOOP_MUTANTS", "LoopMutant", "PureControls", "loop_mutant", "resolved_blend"]

Joint = tuple[float, float, float]


class PureControls:
    """The loop's pure controls at one sample, each computed on first use.

    ``corner(µ_coll, µ_occ)`` is the loop's resolved control (19) at those
    risk values: at ``(0, 0)`` visual servoing q̇_VS, at ``(0, 1)`` occlusion
    avoidance q̇_occ, at ``(1, 0)`` the avoidance control (18) with the real
    pan rate ϖ and at ``(1, 1)`` with the reconstructed one ϖ~ (the blend is
    bilinear in (µ_coll, µ_occ), so these four determine it).  Only the
    controls a law reads are computed, as the resolved loop computes only
    those with a non-zero weight.
    """

    __slots__ = ("_corner", "_cache")

    def __init__(self, corner: Callable[[float, float], Joint]) -> None:
        self._corner = corner
        self._cache: dict[tuple[float, float], Joint] = {}

    def _at(self, mu_coll: float, mu_occ: float) -> Joint:
        key = (mu_coll, mu_occ)
        if key not in self._cache:
            self._cache[key] = tuple(self._corner(mu_coll, mu_occ))  # type: ignore[assignment]
        return self._cache[key]

    @property
    def vs(self) -> Joint:
        """q̇_VS, visual servoing (7)."""
        return self._at(0.0, 0.0)

    @property
    def occ(self) -> Joint:
        """q̇_occ, occlusion avoidance (8)–(9) (visual servoing when no occluder is in front)."""
        return self._at(0.0, 1.0)

    @property
    def coll_real(self) -> Joint:
        """``(v_coll, ω_coll, ϖ)``: path following (11) with the pan tracking (16) on the measured features."""
        return self._at(1.0, 0.0)

    @property
    def coll_reconstructed(self) -> Joint:
        """``(v_coll, ω_coll, ϖ~)``: the same with the pan tracking (17) on the reconstructed features."""
        return self._at(1.0, 1.0)


BlendLaw = Callable[[float, float, PureControls], Joint]
"""``law(µ_coll, µ_occ, pure) -> (v, ω, ϖ)``: how a loop combines its pure controls."""


def resolved_blend(mu_coll: float, mu_occ: float, pure: PureControls) -> Joint:
    """Eqs. (18)–(19) as ``docs/supervisor.md`` states them, on the pure controls (the reference).

    ``q̇ = (1 − µ_occ)(1 − µ_coll) q̇_VS + (1 − µ_coll) µ_occ q̇_occ + µ_coll q̇_coll`` with
    ``q̇_coll = (v_coll, ω_coll, (1 − µ_occ) ϖ + µ_occ ϖ~)``; a control of weight 0 is not computed.
    """
    return _blend_with(mu_coll, mu_occ, mu_occ, mu_occ, pure)


def _blend_with(mu_coll: float, mu_occ: float, mu_pan: float, mu_occ_blend: float, pure: PureControls) -> Joint:
    """(19) with ``mu_occ_blend`` for its µ_occ, the pan rates of (18) mixed by ``mu_pan``."""
    q_vs = pure.vs if (1.0 - mu_occ_blend) * (1.0 - mu_coll) > 0.0 else None
    q_occ = pure.occ if (1.0 - mu_coll) * mu_occ_blend > 0.0 else None
    q_coll = None
    if mu_coll > 0.0:
        v, w, pan_real = pure.coll_real if mu_pan < 1.0 else (*pure.coll_reconstructed[:2], None)
        pan_rec = pure.coll_reconstructed[2] if mu_pan > 0.0 else None
        q_coll = avoidance_control(v, w, pan_real, pan_rec, mu_pan)
    return blend(mu_coll, mu_occ_blend, q_vs, q_occ, q_coll)


def _blend_one_minus_mu_occ(mu_coll: float, mu_occ: float, pure: PureControls) -> Joint:
    # the slip: blend(mu_coll, 1 - mu_occ, ...) -- (18) still reads the right mu_occ
    return _blend_with(mu_coll, mu_occ, mu_occ, 1.0 - mu_occ, pure)


def _pan_mix_mu_coll(mu_coll: float, mu_occ: float, pure: PureControls) -> Joint:
    # the slip: avoidance_control(v, omega, pan, pan_rec, mu_coll) -- (19) still reads the right mu
    return _blend_with(mu_coll, mu_occ, mu_coll, mu_occ, pure)


class _HeldScrewEstimator(FeatureEstimator):
    """A :class:`FeatureEstimator` whose BDF stage takes the held screw whatever ``screw_model`` says.

    ``at_end``: ``J_r(ϑ_k + ϖ h) q̇_k`` (the left limit at t_{k+1}); otherwise ``J_r(ϑ_k) q̇_k``.
    The RK4 start-up (exact ODE of the period) is untouched: only the BDF steps slip.
    """

    at_end = True

    def _screw(self, pan: float, v: float, omega: float, pan_rate: float, h: float,
               mean: tuple[float, float, float]) -> tuple[float, float, float]:
        g = self._geometry
        return camera_screw(pan + pan_rate * h if self.at_end else pan, v, omega, pan_rate,
                            g.pan_offset_m, g.camera_forward_m, g.camera_lateral_m)


class _HeldStartScrewEstimator(_HeldScrewEstimator):
    at_end = False


@dataclass(frozen=True, kw_only=True, slots=True)
class LoopMutant:
    """A slip in the closed loop around the resolved supervisor.

    Attributes
    ----------
    name, description : str
    part : str
        ``"estimator"`` or ``"blend"``: what is mutated.
    estimator : type of FeatureEstimator or None
        The estimator class the loop builds (``None``: the resolved one).
    blend_law : callable or None
        ``law(µ_coll, µ_occ, pure)`` replacing (18)–(19) (``None``: the resolved
        :meth:`~visnav.closed_loop.ClosedLoop.command`).
    """

    name: str
    description: str
    part: str
    estimator: type[FeatureEstimator] | None = None
    blend_law: BlendLaw | None = None


_MUTANTS = (
    LoopMutant(name="held_screw_end", part="estimator", estimator=_HeldScrewEstimator,
               description="the estimator uses the held screw J_r(pan_{k+1}) q_k at the end of the period "
                           "whatever screw_model says"),
    LoopMutant(name="held_screw_start", part="estimator", estimator=_HeldStartScrewEstimator,
               description="the estimator uses the held screw J_r(pan_k) q_k at the start of the period "
                           "whatever screw_model says"),
    LoopMutant(name="blend_one_minus_mu_occ", part="blend", blend_law=_blend_one_minus_mu_occ,
               description="eq. (19) reads 1 - mu_occ where it reads mu_occ: q_VS and q_occ swap weights"),
    LoopMutant(name="pan_mix_mu_coll", part="blend", blend_law=_pan_mix_mu_coll,
               description="eq. (18) mixes the real and reconstructed pan rates with mu_coll instead of mu_occ"),
)

LOOP_MUTANTS: Mapping[str, str] = MappingProxyType({m.name: m.description for m in _MUTANTS})
"""Closed-loop planted defects: name -> one-line description (not fuzzable open-loop)."""

_BY_NAME = {m.name: m for m in _MUTANTS}


def loop_mutant(name: str) -> LoopMutant:
    """The :class:`LoopMutant` called ``name``.

    Raises
    ------
    KeyError
        For an unknown name (the message lists the known ones).
    """
    try:
        return _BY_NAME[name]
    except KeyError:
        raise KeyError(f"unknown loop mutant {name!r}; known: {', '.join(LOOP_MUTANTS)}") from None
