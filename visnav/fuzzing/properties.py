"""The properties on signal sequences: each a check whose docstring is its specification.

A check is ``check(variant, space, steps, observe)``: ``steps`` are the
samples of one measurement sequence through the variant
(:func:`visnav.fuzzing.runner.run_supervisor`); it raises
:class:`analysis.fuzzing.PropertyViolation` on failure and passes margins to
``observe`` (guided search).  On hypothesis-respecting inputs the runner
checks the prefix where the closed-loop hypothesis holds
(:func:`hypotheses_prefix`).  :func:`check_sample` is the state machine's
invariant at one sample (:mod:`visnav.fuzzing.machine`, :func:`check_stateful`).
The registry of named properties is :mod:`visnav.fuzzing.registry`.

The properties written against slips (``docs/fuzzing.md``, "Slips") are
monitors of ``docs/supervisor.md`` that do not read the automaton's guards:
``occlu_timing`` (when OCCLU is set and reset), ``release_band`` (µ along the
LEAVE and RELEASE bands and where they end), ``side_latched`` (the bypass side
the controllers get); the two closed-loop checks written against slips,
``reconstruction_bounded`` and ``blend_weights``, are in
:mod:`visnav.fuzzing.loop_properties`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from analysis.fuzzing import Channel, Observer, PropertyViolation

from visnav import model as kinematics
from visnav.controllers import avoidance_control, blend
from visnav.fuzzing.mutants import SupervisorVariant
from visnav.fuzzing.paper_logic import mu_coll_cases, mu_occ_cases
from visnav.fuzzing.runner import MAX_JUMPS_PER_SAMPLE, Step
from visnav.fuzzing.space import MeasurementSpace, cached_channels
from visnav.fuzzing.variants import variant_flags
from visnav.geometry import wrap_angle
from visnav.supervisor import I_D_BORD, I_D_NEAREST, I_D_OCC, split_mode

__all__ = [
    "MAX_JUMPS_BOUNDED",
    "TOLERANCE",
    "CONTROL_TOLERANCE",
    "hypotheses_prefix",
    "check_mu_range",
    "check_mu_continuity",
    "check_determinism",
    "check_no_chatter",
    "check_flag_consistency",
    "check_control_continuity",
    "check_leave_timing",
    "check_leave_release",
    "check_differential",
    "check_occlu_timing",
    "check_release_band",
    "check_side_latched",
    "check_sample",
    "check_stateful",
]

MAX_JUMPS_BOUNDED = 4
"""Jumps per sample that bounded-rate measurements may cause (two per component)."""

TOLERANCE = 1e-12
"""Absolute tolerance of the equalities checked on µ."""
CONTROL_TOLERANCE = 1e-9
"""Absolute tolerance on the control at a switch [m/s, rad/s]."""


def hypotheses_prefix(variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step]) -> int:
    """Length of the prefix of a run on which the closed-loop hypothesis of the bypass holds.

    (H2) While the supervisor asks for pure avoidance (AVOID = 1, LEAVE = 0
    after a sample), the path follower keeps the robot within ξ+ of the
    obstacle it avoids (the nearest one when AVOID was set): at the next
    sample that distance is at most d+.  This is what case 3 of (2)
    presumes (its release band is [dL, d+], empty if LEAVE came beyond d+)
    and what ``visnav analyse`` bounds along a bypass; open-loop measurement
    sequences can break it, so the properties on hypothesis-respecting
    inputs are checked on the prefix before the first sample that does.
    (H1, obstacles more than 2 d+ apart, is enforced by
    :func:`~visnav.fuzzing.space.respect_hypotheses`.)
    """
    n = space.n_obstacles
    d_plus = space.envelopes.d_plus_m
    obstacle = -1
    avoiding = False
    prev_avoid = variant_flags(variant, variant.model.automaton.initial_mode)[0]
    for k, s in enumerate(steps):
        ds = _distances(s, n)
        if avoiding and ds[obstacle] > d_plus:
            return k
        avoid, leave, _ = variant_flags(variant, s.mode)
        if avoid and not prev_avoid:
            obstacle = min(range(n), key=ds.__getitem__)
        avoiding = bool(avoid and not leave and obstacle >= 0)
        prev_avoid = avoid
    return len(steps)


def _fail(prop: str, message: str, step: Step | None = None, **details: Any) -> PropertyViolation:
    if step is not None:
        details.setdefault("mode", step.mode)
        details.setdefault("mu", [step.mu_coll, step.mu_occ])
        details.setdefault("jumps", [j.transition for j in step.jumps])
    return PropertyViolation(prop, message, sample=None if step is None else step.index, details=details)


def _distances(step: Step, n: int) -> tuple[float, ...]:
    return step.measurement[:n]


def check_mu_range(variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer) -> None:
    """µ_coll and µ_occ lie in [0, 1] at every sample and in every mode visited at an instant.

    Inputs: adversarial sequences (jumps, ``inf``), hypotheses possibly broken.
    """
    for s in steps:
        values = [(s.mode, s.mu_coll, s.mu_occ)]
        for j in s.jumps:
            values.append((j.target, *variant.model.risk(j.target, s.signals, j.memory_after)))
        for mode, mu_c, mu_o in values:
            for name, mu in (("mu_coll", mu_c), ("mu_occ", mu_o)):
                if not 0.0 <= mu <= 1.0:
                    raise _fail("mu_range", f"{name} = {mu!r} outside [0, 1] in mode {mode}", s)


def check_mu_continuity(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """µ never jumps: equal on both sides of every transition, Lipschitz in the measurements between samples.

    At every jump, µ of the source mode (memory before the reset) equals µ
    of the target mode (memory after) at the same signals, to 1e-12; between
    samples ``|Δµ_coll| <= max_i |Δd_coll_i| / min(d0 − d−, d+ − d0)`` and
    ``|Δµ_occ| <= |Δd_occ| / min(D0 − D−, D+ − D0)`` (+1e-12).  The bound holds
    whatever the rates, so the inputs are adversarial (jumps, ``inf``) but
    respect the one-obstacle-at-a-time hypothesis.  The equality at a jump is
    required at samples reached by a plausible move (every channel within its
    rate bound, as in :func:`~visnav.fuzzing.space.signal_runs` with ``bounded=True``): after a jump
    of the measurements an intermediate mode of the instant may see them in
    the wrong phase (e.g. APPROACH → FAR when the latched obstacle jumped away
    while another jumped inside d0, or d_occ jumping to ∞ while OCCLUDED), and
    only the Lipschitz bound on the sample's µ is meaningful.  Guided search maximises
    the largest ratio ``|Δµ| / bound``.
    """
    n = space.n_obstacles
    lc, lo = space.lipschitz_mu_coll(), space.lipschitz_mu_occ()
    i_occ = space.index("d_occ_px")
    prev: Step | None = None
    worst = 0.0
    risk = variant.model.risk
    channels = cached_channels(space)
    for s in steps:
        plausible = prev is None or _plausible(channels, prev.measurement, s.measurement)
        for j in s.jumps if plausible else ():
            before = risk(j.source, s.signals, j.memory_before)
            after = risk(j.target, s.signals, j.memory_after)
            if abs(before[0] - after[0]) > TOLERANCE or abs(before[1] - after[1]) > TOLERANCE:
                raise _fail(
                    "mu_continuity",
                    f"(mu_coll, mu_occ) jumps from {before} to {after} at transition {j.transition}", s,
                    transition=j.transition,
                )
        if prev is not None:
            dd = max(_delta(a, b) for a, b in zip(_distances(prev, n), _distances(s, n)))
            docc = _delta(prev.measurement[i_occ], s.measurement[i_occ])
            for name, dmu, bound in (
                ("mu_coll", abs(s.mu_coll - prev.mu_coll), lc * dd),
                ("mu_occ", abs(s.mu_occ - prev.mu_occ), lo * docc),
            ):
                if dmu > bound + TOLERANCE:
                    raise _fail(
                        "mu_continuity",
                        f"|d{name}| = {dmu:.6g} between samples {prev.index} and {s.index} exceeds the bound "
                        f"{bound:.6g} from the measurement change ({prev.mode} -> {s.mode})", s,
                        delta=dmu, bound=bound,
                    )
                if dmu > 0.0:
                    worst = max(worst, dmu / bound if bound > 0.0 else math.inf)
        prev = s
    observe("largest |dmu| / Lipschitz bound", worst)


def _plausible(channels: Sequence[Channel], before: Sequence[float], after: Sequence[float]) -> bool:
    """Whether every continuous channel moved within its rate bound (finite values only)."""
    for ch, a, b in zip(channels, before, after):
        if ch.choices or a == b:
            continue
        if not (math.isfinite(a) and math.isfinite(b)) or abs(b - a) > ch.max_step * (1.0 + 1e-9):
            return False
    return True


def _delta(a: float, b: float) -> float:
    if a == b:
        return 0.0
    return abs(b - a) if math.isfinite(a) and math.isfinite(b) else math.inf


def check_determinism(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """Never two enabled transitions without a priority between them.

    At every jump, no other enabled transition has the winner's priority
    (the executor would raise; here the run goes on with the first declared).
    Inputs: adversarial sequences, hypotheses possibly broken.
    """
    for s in steps:
        for j in s.jumps:
            if j.tied:
                raise _fail(
                    "determinism",
                    f"transitions {[j.transition, *j.tied]} are enabled together in mode {j.source} with the "
                    "same priority", s, enabled=list(j.enabled),
                )


def check_no_chatter(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """No chatter under bounded-rate measurements.

    (a) No instantaneous Zeno: at most :data:`MAX_JUMPS_BOUNDED` = 4 jumps at
    one sample (never the executor's limit of 8).  (b) No component (collision
    or occlusion phase) undoes a switch sooner than
    :meth:`MeasurementSpace.min_reversal_gap` samples (2 with the defaults:
    the 2 cm detection hysteresis at 1 cm/sample), i.e. at most
    ``1 / (gap T)`` = 10 back-and-forth switches per second per component.
    A reversal is a *toggle*, and counts, when it restores the memory the
    first switch wrote (FAR → APPROACH latching obstacle A, then APPROACH →
    FAR forgetting it); when the latched values differ it is a *hand-over*
    and does not count (APPROACH → FAR → APPROACH as the robot leaves one
    obstacle's hysteresis band while entering the next one's detection
    range, which obstacles exactly 2 d+ apart allow).  Guided search
    maximises the number of switches within any 1 s window.
    """
    gap = space.min_reversal_gap()
    window = max(1, int(round(1.0 / space.period_s)))
    writes = {t.name: t.writes for t in variant.model.automaton.transitions}
    last: dict[tuple[int, str, str], tuple[int, Mapping[str, float], tuple[str, ...]]] = {}
    switch_samples: list[int] = []
    busiest = 0
    for s in steps:
        if s.zeno:
            chain = " -> ".join(j.transition for j in s.jumps)
            raise _fail("no_chatter", f"instantaneous Zeno: more than {MAX_JUMPS_PER_SAMPLE} jumps at one sample "
                        f"({chain} -> ...)", s)
        if len(s.jumps) > MAX_JUMPS_BOUNDED:
            raise _fail("no_chatter", f"{len(s.jumps)} jumps at one sample (bounded rates allow "
                        f"{MAX_JUMPS_BOUNDED})", s)
        for j in s.jumps:
            for component in (0, 1):
                a, b = split_mode(j.source)[component], split_mode(j.target)[component]
                if a == b:
                    continue
                back, memory_then, written = last.get((component, b, a), (None, {}, ()))
                handover = any(memory_then[name] != j.memory_after[name] for name in written)
                if back is not None and s.index - back < gap and not handover:
                    raise _fail(
                        "no_chatter",
                        f"{'collision' if component == 0 else 'occlusion'} phase {b} -> {a} at sample {back} undone "
                        f"by {a} -> {b} ({j.transition}) {s.index - back} sample(s) later; bounded rates need >= {gap}",
                        s, reversal_gap=s.index - back, min_gap=gap,
                    )
                last[(component, a, b)] = (s.index, j.memory_before, writes[j.transition])
                switch_samples.append(s.index)
        while switch_samples and switch_samples[0] <= s.index - window:
            switch_samples.pop(0)
        busiest = max(busiest, len(switch_samples))
    observe("switches within 1 s", float(busiest))


def check_flag_consistency(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """The flags and µ tell the same story (the unambiguous parts of (2), (3) and remark 3).

    At every sample: LEAVE ⇒ AVOID; OCCLU ⇒ µ_occ = 1; AVOID ∧ ¬LEAVE ⇒
    µ_coll = 1 ("otherwise" of (2)); ¬AVOID ∧ ¬LEAVE with every obstacle
    beyond d0 ⇒ µ_coll = 0 (case 1 of (2)); LEAVE is set only at a sample
    where µ_occ = 0 (section V.A).  Inputs: adversarial, hypotheses possibly broken.
    """
    d_zero = space.envelopes.d_zero_m
    n = space.n_obstacles
    prev_leave = variant_flags(variant, variant.model.automaton.initial_mode)[1]
    for s in steps:
        avoid, leave, occlu = variant_flags(variant, s.mode)
        if leave and not avoid:
            raise _fail("flag_consistency", f"LEAVE = 1 with AVOID = 0 in mode {s.mode}", s)
        if occlu and s.mu_occ != 1.0:
            raise _fail("flag_consistency", f"OCCLU = 1 but mu_occ = {s.mu_occ!r} in mode {s.mode}", s)
        if avoid and not leave and s.mu_coll != 1.0:
            raise _fail("flag_consistency", f"AVOID = 1, LEAVE = 0 but mu_coll = {s.mu_coll!r} in mode {s.mode}", s)
        if not avoid and not leave and min(_distances(s, n)) > d_zero and s.mu_coll != 0.0:
            raise _fail("flag_consistency", f"AVOID = LEAVE = 0, every obstacle beyond d0 but mu_coll = "
                        f"{s.mu_coll!r} in mode {s.mode}", s)
        if leave and not prev_leave and s.mu_occ != 0.0:
            raise _fail("flag_consistency", f"LEAVE set while mu_occ = {s.mu_occ!r} > 0", s)
        prev_leave = leave


def _abstract_control(
    variant: SupervisorVariant, space: MeasurementSpace, step: Step, mode: str, memory: Mapping[str, float]
) -> tuple[float, float, float]:
    """The global control (19) with fixed sub-controllers and the real blending and path following."""
    n = space.n_obstacles
    row = step.measurement
    alpha, visible = row[n + 4], row[n + 5]
    mu_c, mu_o = variant.model.risk(mode, step.signals, memory)
    view = variant.controller_memory(step.signals, memory)
    obstacle, side = int(view["obstacle"]), view["side"]
    d = row[obstacle]
    radius = 0.5
    v_coll, k = 0.2, 4.0
    q_vs = (0.3, 0.2 * math.sin(alpha), 0.1)
    q_occ = (0.1, -0.3, 0.4 * visible - 0.2)
    q_coll = None
    if mu_c > 0.0:
        omega = kinematics.path_following_omega(d - space.envelopes.d_zero_m, alpha, 1.0 / (max(d, 0.0) + radius),
                                                side, v_coll, k)
        q_coll = avoidance_control(v_coll, omega, -omega, -omega + 0.1, mu_o)
    return blend(mu_c, mu_o, q_vs, q_occ, q_coll)


def check_control_continuity(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """Switching never makes the control jump.

    The control (19) is evaluated with the real blending and path-following
    law on fixed sub-controllers (q̇_VS, q̇_occ constant, q̇_coll from (11)
    with the latched bypass side and the measured α).  At every sample after
    the first, the control of the mode *after* the sample's jumps equals the
    control of the mode *before* them at the same measurements
    (``|Δq̇|∞ <= 1e-9``): the supervisor's discrete update contributes nothing
    to ``q̇[k] − q̇[k−1]``.  Inputs: bounded-rate, hypotheses respected (a
    jump of the measurements may legitimately land inside a band).
    """
    worst = 0.0
    for s in steps[1:]:
        if not s.jumps:
            continue
        before = _abstract_control(variant, space, s, s.mode_before, s.memory_before)
        after = _abstract_control(variant, space, s, s.mode, s.memory)
        gap = max(abs(a - b) for a, b in zip(before, after))
        worst = max(worst, gap)
        if gap > CONTROL_TOLERANCE:
            raise _fail(
                "control_continuity",
                f"the control jumps by {gap:.6g} at the switch {s.mode_before} -> {s.mode}: {before} -> {after}", s,
                before=list(before), after=list(after),
            )
    observe("largest control jump at a switch", worst)


def check_leave_timing(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """LEAVE comes exactly when the obstacle is overcome, and not before.

    A monitor independent of the automaton follows section V.A with the
    answers of ``docs/supervisor.md``: once AVOID is set, the LEAVE test is
    *armed* when the wrapped pan angle ``w = wrap(ϑ)`` reaches the arming
    angle (its sign latched); it *fires* at the first later sample where
    ``w`` is back through zero on the other side with ``|w| <= π/2``.  If
    µ_occ = 0 there, LEAVE must be set at that sample; otherwise it must be
    set at the first sample where µ_occ = 0.  At every other sample of the
    avoidance phase LEAVE must stay 0.  Inputs: bounded-rate, hypotheses
    respected.  Guided search maximises the time from AVOID to LEAVE.
    """
    arm = space.settings.arm_angle_rad
    i_pan = space.index("pan_rad")
    p_avoid, p_leave, _ = variant_flags(variant, variant.model.automaton.initial_mode)
    armed = 0
    pending = False
    since = 0
    longest = 0
    for s in steps:
        avoid, leave, _ = variant_flags(variant, s.mode)
        w = wrap_angle(s.measurement[i_pan])
        fresh = (avoid and not p_avoid) or (p_leave and not leave and avoid)
        if fresh:
            armed, pending, since = 0, False, s.index
        if avoid and (p_avoid and not p_leave) and not fresh:
            crossing = armed != 0 and -armed * w >= 0.0 and abs(w) <= 0.5 * math.pi
            expect = False
            if crossing or pending:
                if s.mu_occ == 0.0:
                    expect = True
                else:
                    pending = True
            if bool(leave) != expect:
                why = ("the armed pan angle came back through zero with mu_occ = 0" if expect else
                       "the pan angle has not come back through zero since arming" if armed else
                       "the LEAVE test is not armed (|wrap(pan)| never reached the arming angle since AVOID)")
                raise _fail(
                    "leave_timing",
                    f"LEAVE = {leave}, expected {int(expect)}: {why} (wrap(pan) = {w:.6g}, armed sign {armed}, "
                    f"pending {pending}, mu_occ = {s.mu_occ:.6g})", s, wrapped_pan=w, armed=armed,
                )
            if expect:
                longest = max(longest, s.index - since)
        elif fresh and leave:
            raise _fail("leave_timing", "LEAVE set at the sample AVOID was (re)entered, before any arming", s)
        if avoid and not leave and armed == 0 and abs(w) >= arm:
            armed = 1 if w > 0.0 else -1
        p_avoid, p_leave = avoid, leave
    observe("samples from AVOID to LEAVE", float(longest))


def check_leave_release(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """LEAVE ends: µ_coll returns to 0 at the end of the release band.

    When LEAVE is set at distance dL from the obstacle being avoided (the
    nearest one when AVOID was set), AVOID and LEAVE must both be 0 and
    µ_coll = 0 at the latest at the first sample where that distance reaches
    ``max(dL + (d+ − d0), d+ + hysteresis)`` — unless the robot went back
    into ξ− (LEAVE → AVOID) before.  Inputs: bounded-rate, hypotheses
    respected.  Guided search maximises how far beyond that point LEAVE is held.
    """
    env, s_ = space.envelopes, space.settings
    n = space.n_obstacles
    p_avoid, p_leave, _ = variant_flags(variant, variant.model.automaton.initial_mode)
    obstacle = -1
    release_at: float | None = None
    overstay = 0.0
    for s in steps:
        avoid, leave, _ = variant_flags(variant, s.mode)
        ds = _distances(s, n)
        if avoid and not p_avoid:
            obstacle = min(range(n), key=ds.__getitem__)
        if leave and not p_leave and obstacle >= 0:
            d_leave = ds[obstacle]
            release_at = max(d_leave + (env.d_plus_m - env.d_zero_m), env.d_plus_m + s_.detection_hysteresis_m)
        if release_at is not None:
            d = ds[obstacle]
            if not leave and avoid:
                release_at = None
            elif not avoid and not leave:
                release_at = None
            elif d >= release_at + TOLERANCE:
                raise _fail(
                    "leave_release",
                    f"still AVOID = {avoid}, LEAVE = {leave}, mu_coll = {s.mu_coll:.6g} at d = {d:.6g} m >= "
                    f"{release_at:.6g} m (end of the release band)", s, distance=d, release_at=release_at,
                )
            else:
                overstay = max(overstay, d - release_at)
        p_avoid, p_leave = avoid, leave
    observe("distance beyond the release point with LEAVE held [m]", overstay)


def check_differential(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """The automaton agrees with a literal transcription of (2)–(3) wherever the paper is unambiguous.

    With the flags the automaton holds and dL, DL taken from the run (d_coll
    when LEAVE was set, d_occ when OCCLU was reset), every case of the
    printed (2) and (3) that holds is evaluated (:mod:`visnav.fuzzing.paper_logic`);
    where they agree, µ must equal them (1e-9).  Also literal: AVOID is set
    at a sample where the robot is inside ξ− (d_coll <= d−), and only there;
    OCCLU likewise with Ξ− (d_occ <= D−).  Not compared, because the paper
    is silent or deliberately resolved otherwise in ``docs/supervisor.md``:
    samples where two obstacles are within d+ + hysteresis (hypothesis
    broken; the sensors' "closest obstacle" is not unique); LEAVE = 1 beyond
    d+ (question 2: the printed "otherwise" keeps µ_coll = 1 for ever);
    LEAVE = 1 with dL > d0 inside the widened band [dL, dL + d+ − d0]
    (question 8's construction); OCCLU = 0 in the release phase after an
    OCCLU reset until µ_occ = 0 (question 8).  A sample with two obstacles
    within d+ + hysteresis taints the collision checks until the robot is
    again beyond that range with AVOID = LEAVE = 0 (the latched values stem
    from an ambiguous "closest obstacle").  Inputs: adversarial.
    """
    env, s_ = space.envelopes, space.settings
    n = space.n_obstacles
    crowd = env.d_plus_m + s_.detection_hysteresis_m
    p_avoid, p_leave, p_occlu = variant_flags(variant, variant.model.automaton.initial_mode)
    d_leave = D_leave = math.inf
    releasing = crowded = False
    compared = 0
    for s in steps:
        avoid, leave, occlu = variant_flags(variant, s.mode)
        ds = _distances(s, n)
        d = s.signals[I_D_NEAREST]
        d_occ, d_bord = s.signals[I_D_OCC], s.signals[I_D_BORD]
        if sum(1 for x in ds if x <= crowd) >= 2:
            crowded = True  # and stays so while the collision component holds an obstacle
        elif not avoid and not leave and min(ds) > crowd:
            crowded = False
        if leave and not p_leave:
            d_leave = d
        if p_occlu and not occlu:
            D_leave, releasing = d_occ, True
        if occlu or s.mu_occ == 0.0:
            releasing = False
        # flag rules
        if not crowded and not p_avoid and d <= env.d_minus_m and not avoid:
            raise _fail("differential", f"d_coll = {d!r} <= d- but AVOID was not set", s)
        if avoid and not p_avoid and d > env.d_minus_m:
            raise _fail("differential", f"AVOID set at d_coll = {d!r} > d- (outside xi-)", s)
        if not p_occlu and d_occ <= env.D_minus_px and not occlu:
            raise _fail("differential", f"d_occ = {d_occ!r} <= D- but OCCLU was not set", s)
        if occlu and not p_occlu and d_occ > env.D_minus_px:
            raise _fail("differential", f"OCCLU set at d_occ = {d_occ!r} > D-", s)
        # mu_coll
        skip = crowded or (leave and d > env.d_plus_m) or (
            leave and d_leave > env.d_zero_m and d < d_leave + (env.d_plus_m - env.d_zero_m))
        if not skip:
            cases = mu_coll_cases(d, avoid=avoid, leave=leave, d_leave=d_leave, envelopes=env)
            if _unanimous(cases):
                compared += 1
                if abs(s.mu_coll - cases[0][1]) > 1e-9:
                    raise _fail("differential", f"mu_coll = {s.mu_coll!r} but the printed (2) gives "
                                f"{cases[0][1]!r} (case {cases[0][0]}; AVOID={avoid} LEAVE={leave} d={d!r} "
                                f"dL={d_leave!r})", s, cases=[list(c) for c in cases])
        # mu_occ
        if not (releasing and not occlu):
            cases = mu_occ_cases(d_occ, d_bord, occlu=occlu, D_leave=D_leave, envelopes=env)
            if _unanimous(cases):
                compared += 1
                if abs(s.mu_occ - cases[0][1]) > 1e-9:
                    raise _fail("differential", f"mu_occ = {s.mu_occ!r} but the printed (3) gives "
                                f"{cases[0][1]!r} (case {cases[0][0]}; OCCLU={occlu} d_occ={d_occ!r} "
                                f"d_bord={d_bord!r} DL={D_leave!r})", s, cases=[list(c) for c in cases])
        p_avoid, p_leave, p_occlu = avoid, leave, occlu
    observe("samples compared with the printed equations", float(compared))


def _unanimous(cases: Sequence[tuple[int, float]]) -> bool:
    first = cases[0][1]
    return all(abs(value - first) <= TOLERANCE for _, value in cases[1:])


# ---- monitors written against slips (docs/fuzzing.md, "Slips") ---------------------------------


def check_occlu_timing(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """OCCLU is set and reset exactly at the samples the specification names, never earlier or later.

    An independent monitor of the flag (``docs/supervisor.md``, question 7):
    with OCCLU = 0 before a sample, OCCLU must be 1 after it exactly when
    ``d_occ <= D−``; with OCCLU = 1, it must be 0 after it exactly when
    ``d_occ >= D0``, or ``d_bord = 0`` and ``d_occ >= (D− + D0)/2``.  A change
    at a sample where it is not due is reported at once (with the thresholds
    it should have met); a due change that does not come is reported where
    the flag finally changes, or at the end of the run, with the sample and
    the ``d_occ`` at which it was due — a moved threshold shows as the two
    values.  Every jump inside a sample's instant is checked too: OCCLU
    toggling at one instant is a change that was not due.  Inputs:
    adversarial (the rule holds sample by sample, whatever the rates).
    Guided search brings ``d_occ`` close to the thresholds.
    """
    env = space.envelopes
    D_minus, D_zero = env.D_minus_px, env.D_zero_px
    mid = 0.5 * (D_minus + D_zero)

    def rule(flag: int) -> str:
        return (f"d_occ <= D- = {D_minus:g} px" if not flag else
                f"d_occ >= D0 = {D_zero:g} px, or d_bord = 0 and d_occ >= (D- + D0)/2 = {mid:g} px")

    def is_due(flag: int, d_occ: float, d_bord: float) -> bool:
        return d_occ <= D_minus if not flag else (d_occ >= D_zero or (d_bord <= 0.0 and d_occ >= mid))

    prev = variant_flags(variant, variant.model.automaton.initial_mode)[2]
    due_at: tuple[int, float, float] | None = None
    closest = math.inf
    for s in steps:
        occlu = variant_flags(variant, s.mode)[2]
        d_occ, d_bord = s.signals[I_D_OCC], s.signals[I_D_BORD]
        if math.isfinite(d_occ):
            closest = min(closest, abs(d_occ - D_minus), abs(d_occ - mid), abs(d_occ - D_zero))
        for j in s.jumps:  # every change of the flag, also inside an instant, must be due at this sample
            before, after = variant_flags(variant, j.source)[2], variant_flags(variant, j.target)[2]
            if before != after and not is_due(before, d_occ, d_bord):
                what = "set" if not before else "reset"
                again = " again within the instant" if before != prev else ""
                raise _fail("occlu_timing", f"OCCLU {what}{again} where it is not due: at d_occ = {d_occ:.6g} px, "
                            f"d_bord = {d_bord:.6g} px ({j.transition}); the specification {what}s it only when "
                            f"{rule(before)}", s, flag=what, d_occ_px=d_occ, d_bord_px=d_bord, due_sample=None,
                            transition=j.transition)
        what = "set" if not prev else "reset"
        due = is_due(prev, d_occ, d_bord)
        if due_at is not None:
            if occlu != prev:
                k, d_due, b_due = due_at
                raise _fail("occlu_timing", f"OCCLU {what} late: at d_occ = {d_occ:.6g} px (d_bord = {d_bord:.6g} px), "
                            f"due at sample {k} where d_occ = {d_due:.6g} px, d_bord = {b_due:.6g} px "
                            f"({rule(prev)})", s,
                            flag=what, d_occ_px=d_occ, due_sample=k, due_d_occ_px=d_due, due_d_bord_px=b_due)
        elif occlu == prev and due:
            due_at = (s.index, d_occ, d_bord)
        if occlu != prev:
            due_at = None
        prev = occlu
    if due_at is not None:
        k, d_due, b_due = due_at
        what = "set" if not prev else "reset"
        raise _fail("occlu_timing", f"OCCLU never {what}: due at sample {k} where d_occ = {d_due:.6g} px, "
                    f"d_bord = {b_due:.6g} px ({rule(prev)}), still {prev} at the end of the run", steps[-1],
                    flag=what, d_occ_px=None, due_sample=k, due_d_occ_px=d_due, due_d_bord_px=b_due)
    observe("-(closest d_occ to a threshold) [px]", -closest if math.isfinite(closest) else -1e3)


def _band_mu(d: float, start: float, end: float) -> float:
    """Case 3 of (2)/(3): ``clip((d − end)/(start − end))`` (0 for ``d = ∞``)."""
    if math.isinf(d):
        return 0.0
    x = (d - end) / (start - end)
    return 0.0 if x <= 0.0 else (1.0 if x >= 1.0 else x)


def _implied_end(d: float, start: float, mu: float) -> float | None:
    """End of the band ``[start, end]`` on which ``clip((d − end)/(start − end)) = mu`` (None unless 0 < mu < 1)."""
    if not (0.0 < mu < 1.0 and math.isfinite(d)):
        return None
    return (d - mu * start) / (1.0 - mu)


def check_release_band(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """µ follows case 3 of (2) and (3) along both release bands, and each band ends exactly at its end.

    LEAVE band (``docs/supervisor.md``, questions 2, 5, 8): when LEAVE is set
    at distance dL from the obstacle being avoided (the nearest when AVOID
    was set), with ``d_end = max(d+, dL + d+ − d0)``, while LEAVE = 1
    ``µ_coll = clip((d − d_end)/(dL − d_end))`` (1e-12), and LEAVE ends
    exactly at the first sample where ``d >= max(d_end, d+ + hysteresis)``
    (then AVOID = 0) or ``d <= min(d−, dL − 1 cm)`` (then AVOID = 1), not at
    another sample.  RELEASE band (question 8): when OCCLU is reset at
    d_occ = DL (D0 if d_occ = ∞), with ``D_end = max(D+, DL + D+ − D0)``,
    until OCCLU is set again: ``µ_occ = clip((d_occ − D_end)/(DL − D_end))``
    (0 at d_occ = ∞) at every sample before the first one with
    ``d_occ >= D_end``, and cases 1–2 of (3), ``clip((D0 − d_occ)/(D0 − D−))``,
    from that one on (the band is over).  dL and DL are the monitor's own
    readings of the measurements at the switch, not the automaton's memory,
    so a latch that follows the measurement, a moved band end and a dropped
    hysteresis all show.  Inputs: bounded-rate, hypotheses respected.
    Guided search brings the distance close to the end of the band.
    """
    env, settings = space.envelopes, space.settings
    n = space.n_obstacles
    d_minus, d_zero, d_plus = env.d_minus_m, env.d_zero_m, env.d_plus_m
    D_minus, D_zero, D_plus = env.D_minus_px, env.D_zero_px, env.D_plus_px
    p_avoid, p_leave, p_occlu = variant_flags(variant, variant.model.automaton.initial_mode)
    obstacle = -1
    leave: tuple[float, float, float, float] | None = None  # dL, d_end, release at, back to AVOID at
    late: tuple[int, float] | None = None
    release: tuple[float, float] | None = None  # DL, D_end
    release_over = False
    closest = closest_occ = math.inf
    for s in steps:
        avoid, leave_flag, occlu = variant_flags(variant, s.mode)
        ds = _distances(s, n)
        if avoid and not p_avoid:
            obstacle = min(range(n), key=ds.__getitem__)
        # ---- the LEAVE band
        if leave_flag and not p_leave and obstacle >= 0:
            d_l = ds[obstacle]
            d_end = max(d_plus, d_l + (d_plus - d_zero))
            leave, late = (d_l, d_end, max(d_end, d_plus + settings.detection_hysteresis_m),
                           min(d_minus, d_l - 0.01)), None
        elif leave is not None:
            d_l, d_end, out_at, back_at = leave
            d = ds[obstacle]
            closest = min(closest, abs(d - out_at))
            released, back = d >= out_at, d <= back_at
            where = (f"d = {d:.6g} m, dL = {d_l:.6g} m: LEAVE ends at d >= max(d_end, d+ + hysteresis) = "
                     f"{out_at:.6g} m or d <= min(d-, dL - 1 cm) = {back_at:.6g} m")
            if not leave_flag:
                if late is not None:
                    raise _fail("release_band", f"LEAVE ended late at {where}; it was due at sample {late[0]} "
                                f"(d = {late[1]:.6g} m)", s, distance=d, d_leave=d_l, release_at=out_at,
                                due_sample=late[0], due_distance=late[1])
                if not (released or back):
                    raise _fail("release_band", f"LEAVE ended early, inside its band, at {where}", s,
                                distance=d, d_leave=d_l, release_at=out_at, back_at=back_at, due_sample=None)
                if avoid != (not released):
                    raise _fail("release_band", f"LEAVE ended at {where} with AVOID = {avoid}, expected "
                                f"{int(not released)}", s, distance=d, d_leave=d_l, release_at=out_at)
                leave = late = None
            elif (released or back) and late is None:
                late = (s.index, d)
        if leave is not None and leave_flag:
            d_l, d_end = leave[0], leave[1]
            d = ds[obstacle]
            expected = _band_mu(d, d_l, d_end)
            if late is None and abs(s.mu_coll - expected) > TOLERANCE:
                seen = _implied_end(d, d_l, s.mu_coll)
                raise _fail("release_band", f"mu_coll = {s.mu_coll:.6g} at d = {d:.6g} m in the LEAVE band "
                            f"[dL = {d_l:.6g}, d_end = {d_end:.6g}] m: case 3 of (2) gives {expected:.6g}"
                            + ("" if seen is None else f" (the mu seen ends the band at {seen:.6g} m)"), s,
                            distance=d, d_leave=d_l, d_end=d_end, expected=expected, mu_coll=s.mu_coll,
                            implied_end=seen)
        # ---- the RELEASE band
        d_occ = s.signals[I_D_OCC]
        if occlu:
            release, release_over = None, False
        elif p_occlu:
            dl = d_occ if math.isfinite(d_occ) else D_zero
            release, release_over = (dl, max(D_plus, dl + (D_plus - D_zero))), False
        if release is not None and not occlu:
            dl, d_end = release
            release_over = release_over or d_occ >= d_end
            if release_over:
                expected = _band_mu(d_occ, D_minus, D_zero)  # cases 1-2 of (3): clip((D0 - d)/(D0 - D-))
                phase = f"after the release band [DL = {dl:.6g}, D_end = {d_end:.6g}] px ended: cases 1-2 of (3) give"
            else:
                expected = _band_mu(d_occ, dl, d_end)
                phase = f"in the release band [DL = {dl:.6g}, D_end = {d_end:.6g}] px: case 3 of (3) gives"
                if math.isfinite(d_occ):
                    closest_occ = min(closest_occ, abs(d_occ - d_end))
            if abs(s.mu_occ - expected) > TOLERANCE:
                seen = None if release_over else _implied_end(d_occ, dl, s.mu_occ)
                raise _fail("release_band", f"mu_occ = {s.mu_occ:.6g} at d_occ = {d_occ:.6g} px {phase} "
                            f"{expected:.6g}"
                            + ("" if seen is None else f" (the mu seen ends the band at {seen:.6g} px)"),
                            s, d_occ_px=d_occ, D_leave=dl, D_end=d_end, expected=expected,
                            mu_occ=s.mu_occ, band_over=release_over, implied_end=seen)
        p_avoid, p_leave, p_occlu = avoid, leave_flag, occlu
    if late is not None and leave is not None:
        raise _fail("release_band", f"LEAVE never ended: due at sample {late[0]} (d = {late[1]:.6g} m >= "
                    f"{leave[2]:.6g} m or <= {leave[3]:.6g} m), still set at the end of the run", steps[-1],
                    d_leave=leave[0], release_at=leave[2], due_sample=late[0], due_distance=late[1])
    observe("-(closest distance to the end of the LEAVE band) [m]", -closest if math.isfinite(closest) else -1e3)
    observe("-(closest d_occ to the end of the RELEASE band) [px]",
            -closest_occ if math.isfinite(closest_occ) else -1e3)


def check_side_latched(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """The controllers get the obstacle and bypass side latched when that obstacle was detected.

    An independent monitor of question 12 of ``docs/supervisor.md``: an
    obstacle is *detected* at the first sample where the nearest obstacle is
    within d+ while none is held; the monitor then holds that obstacle and
    the bypass side σ measured at that sample until it is forgotten: at a
    sample where the held obstacle is at d+ + hysteresis or beyond, if
    AVOID = LEAVE = 0 before the sample (only detected), or if LEAVE was set
    before it and is reset by it (the end of the release band); never during
    pure avoidance.  Another obstacle may be detected at the same sample.
    Whenever µ_coll > 0 (the avoidance controller is used) the obstacle and
    side the controllers read
    (:meth:`~visnav.fuzzing.mutants.SupervisorVariant.controller_memory`)
    must be the held ones: a side read at every sample, a side flipped or
    latched at another moment all show.  Inputs: adversarial (σ flips at
    will), hypotheses respected.  Guided search maximises the flips of the
    measured σ while an obstacle is held.
    """
    env, settings = space.envelopes, space.settings
    n = space.n_obstacles
    d_plus = env.d_plus_m
    forget = d_plus + settings.detection_hysteresis_m
    i_side = space.index("side")
    held: tuple[int, float, int] | None = None  # obstacle, side, sample of the detection
    flips = 0
    previous_side: float | None = None
    p_avoid, p_leave, _ = variant_flags(variant, variant.model.automaton.initial_mode)
    for s in steps:
        if s.zeno:  # the instant did not settle (no_chatter reports it); its mode says nothing about the latch
            continue
        avoid, leave, _ = variant_flags(variant, s.mode)
        ds = _distances(s, n)
        sigma = float(s.measurement[i_side])
        if held is not None and ds[held[0]] >= forget and ((not p_avoid and not p_leave) or (p_leave and not leave)):
            held = None
        if held is None:
            nearest = ds.index(min(ds))
            if ds[nearest] <= d_plus:
                held = (nearest, sigma, s.index)
        elif previous_side is not None and sigma != previous_side:
            flips += 1
        previous_side = sigma
        p_avoid, p_leave = avoid, leave
        if held is not None and s.mu_coll > 0.0:
            view = variant.controller_memory(s.signals, s.memory)
            obstacle, side = int(view["obstacle"]), float(view["side"])
            if obstacle != held[0] or side != held[1]:
                raise _fail(
                    "side_latched",
                    f"the controllers get obstacle {obstacle}, side {side:+g} (mu_coll = {s.mu_coll:.6g}, measured "
                    f"side now {sigma:+g}), but obstacle {held[0]} was detected at sample {held[2]} with bypass "
                    f"side {held[1]:+g} and is still held", s,
                    side=side, latched_side=held[1], measured_side=sigma, obstacle=obstacle,
                    latched_obstacle=held[0], detected_at=held[2],
                )
    observe("flips of the measured bypass side while an obstacle is held", float(flips))


# ---- the state machine's invariants ------------------------------------------------------------


def check_sample(variant: SupervisorVariant, space: MeasurementSpace, s: Step, prev: Step | None) -> None:
    """The invariants of the state machine at one sample (``prev``: the sample before)."""
    prop = "stateful"
    if s.zeno:
        raise _fail(prop, f"instantaneous Zeno: more than {MAX_JUMPS_PER_SAMPLE} jumps at one sample", s)
    plausible = prev is None or _plausible(cached_channels(space), prev.measurement, s.measurement)
    for j in s.jumps:
        if j.tied:
            raise _fail(prop, f"transitions {[j.transition, *j.tied]} enabled together with the same priority", s)
        if not plausible:
            continue
        before = variant.model.risk(j.source, s.signals, j.memory_before)
        after = variant.model.risk(j.target, s.signals, j.memory_after)
        if max(abs(before[0] - after[0]), abs(before[1] - after[1])) > TOLERANCE:
            raise _fail(prop, f"(mu_coll, mu_occ) jumps from {before} to {after} at {j.transition}", s)
    for name, mu in (("mu_coll", s.mu_coll), ("mu_occ", s.mu_occ)):
        if not 0.0 <= mu <= 1.0:
            raise _fail(prop, f"{name} = {mu!r} outside [0, 1]", s)
    avoid, leave, occlu = variant_flags(variant, s.mode)
    if leave and not avoid:
        raise _fail(prop, "LEAVE = 1 with AVOID = 0", s)
    if occlu and s.mu_occ != 1.0:
        raise _fail(prop, f"OCCLU = 1 but mu_occ = {s.mu_occ!r}", s)
    if prev is not None:
        n = space.n_obstacles
        i_occ = space.index("d_occ_px")
        dd = max(_delta(a, b) for a, b in zip(_distances(prev, n), _distances(s, n)))
        docc = _delta(prev.measurement[i_occ], s.measurement[i_occ])
        if abs(s.mu_coll - prev.mu_coll) > space.lipschitz_mu_coll() * dd + TOLERANCE:
            raise _fail(prop, f"|dmu_coll| = {abs(s.mu_coll - prev.mu_coll):.6g} exceeds the Lipschitz bound", s)
        if abs(s.mu_occ - prev.mu_occ) > space.lipschitz_mu_occ() * docc + TOLERANCE:
            raise _fail(prop, f"|dmu_occ| = {abs(s.mu_occ - prev.mu_occ):.6g} exceeds the Lipschitz bound", s)


def check_stateful(variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer) -> None:
    """The state machine's invariants hold at every sample of a sequence (replays its runs).

    µ in [0, 1], no µ jump at any transition reached by a plausible move,
    the Lipschitz bound between samples (as ``mu_continuity``), LEAVE ⇒ AVOID, OCCLU ⇒ µ_occ = 1, no tie of priorities, no
    instantaneous Zeno.
    """
    prev = None
    for s in steps:
        check_sample(variant, space, s, prev)
        prev = s
