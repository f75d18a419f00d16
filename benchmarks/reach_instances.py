"""The instances of ``bench_reach.py``: symbolic hybrid systems, initial boxes, requirements, published results.

Each builder returns an :class:`Instance`: the system (a symbolic :class:`hybrid.system.HybridSystem`), the
initial box and mode, the options of :func:`analysis.reach.reach`, the safety requirement (STL, in the fragment of
``docs/reachability.md``), the same unsafe states as :class:`analysis.reach.UnsafeSet` objects (for the peers,
which take unsafe polyhedra), and *planted* sets for the soundness benchmark:

* ``planted_inside``: unsafe sets that reach just inside the true reach set (by 0.01 in the units of the row),
  placed with a closed form: reachable, so a flowpipe that "proves" one of them is unsound;
* ``planted_outside``: the same, just outside: unreachable (closed form), proving them measures precision.

The spacecraft instances (SRNA01, SRA01, SRA02) are read from ``tests/data/spaceex/visnav/`` and the building (BLDC01)
from the ARCH-COMP 2017 file in ``tests/data/spaceex/arch2017/``, through hybrid's SpaceEx import.

``PUBLISHED``: the verdicts the ARCH-COMP AFF category reports give for CORA and JuliaReach (both verify
SRNA01, SRA01, SRA02 and BLDC01-BDS01 safe in the ARCH-COMP19 report, M. Althoff et al., "ARCH-COMP19 Category Report:
Continuous and Hybrid Systems with Linear Continuous Dynamics", EPiC Series in Computing 61, and in the later
editions).  Their runtimes were measured on other machines; they are given only where this project has them
verbatim, otherwise ``None`` (see ``docs/reachability.md``, "Benchmarks").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SPACEEX = ROOT / "tests" / "data" / "spaceex"
GRAVITY = 9.81


@dataclass(frozen=True, kw_only=True, slots=True)
class Instance:
    """One benchmark instance (see the module docstring)."""

    name: str
    system: Any
    box: dict[str, tuple[float, float]]
    initial_mode: str | None
    options: dict[str, Any]
    requirement: str
    unsafe: tuple[Any, ...]
    planted_inside: tuple[Any, ...] = ()
    planted_outside: tuple[Any, ...] = ()
    simulation: dict[str, Any] = field(default_factory=dict)
    hylaa_step: float | None = None
    note: str = ""


@dataclass(frozen=True, kw_only=True, slots=True)
class Published:
    """A verdict published for another tool (``"safe"``), the report, and the runtime if known [s]."""

    tool: str
    verdict: str
    report: str
    seconds: float | None = None


ARCH19 = "ARCH-COMP19 AFF report (Althoff et al., EPiC 61, 2019)"


def _unsafe(name: str, condition: Any, states: tuple[str, ...], modes: Any = None) -> Any:
    from analysis.reach import unsafe_set

    return unsafe_set(name, condition, states, modes=modes)


def bouncing_ball() -> Instance:
    """The ball of ``hybrid.examples`` (restitution 0.8), ``h0 ∈ [0.9, 1]``, ``v0 ∈ [-0.1, 0.1]``, 2.5 s.

    Closed form: no height exceeds the initial energy height ``h0 + v0²/(2g) <= 1 + 0.01/(2g)``; the corner
    ``(1, ±0.1)`` reaches it exactly.
    """
    from hybrid.examples import bouncing_ball as ball
    from hybrid.symbolic import coordinates

    model = ball()
    states = model.system.state_names
    h = coordinates(*states).h
    apex = 1.0 + 0.1 ** 2 / (2 * GRAVITY)
    return Instance(
        name="bouncing ball", system=model.system, box={"h": (0.9, 1.0), "v": (-0.1, 0.1)}, initial_mode=None,
        options=dict(horizon=2.5, time_step=0.005, max_jumps=10), requirement=f"always[0, 2.5] h <= {apex + 0.02!r}",
        unsafe=(_unsafe("too high", h >= apex + 0.02, states),),
        planted_inside=(_unsafe("apex - 0.01", h >= apex - 0.01, states),),
        planted_outside=(_unsafe("apex + 0.01", h >= apex + 0.01, states),),
        simulation=dict(duration=2.5, max_jumps=10))


def thermostat() -> Instance:
    """The thermostat of ``hybrid.examples``, ``T0 ∈ [19.5, 20.5]``, 12 s: it switches at exactly 19 and 21."""
    from hybrid.examples import thermostat as room
    from hybrid.symbolic import coordinates

    model = room()
    T = coordinates("T").T
    return Instance(
        name="thermostat", system=model.system, box={"T": (19.5, 20.5)}, initial_mode=None,
        options=dict(horizon=12.0, time_step=0.01, max_jumps=20),
        requirement="always[0, 12] (T >= 18.95 and T <= 21.05)",
        unsafe=(_unsafe("cold", T <= 18.95, ("T",)), _unsafe("hot", T >= 21.05, ("T",))),
        planted_inside=(_unsafe("T <= 19.01", T <= 19.01, ("T",)), _unsafe("T >= 20.99", T >= 20.99, ("T",))),
        planted_outside=(_unsafe("T <= 18.99", T <= 18.99, ("T",)), _unsafe("T >= 21.01", T >= 21.01, ("T",))),
        simulation=dict(duration=12.0))


SWITCHED_A1 = np.array([[-1.0, 0.5], [-0.5, -1.0]])
SWITCHED_A2 = np.array([[-2.0, 1.0], [0.3, -1.0]])


def switched_pair() -> Instance:
    """Two stable linear modes with the common quadratic Lyapunov function ``|x|²`` (``A + Aᵀ ≺ 0`` in both).

    Mode ``a`` for ``x <= 0.1``, ``b`` for ``x >= -0.1`` (hysteresis).  From ``[-0.5, -0.3] × [2, 2.5]``,
    ``|x(t)| <= |x(0)| <= sqrt(0.5² + 2.5²)``: the box ``±2.6`` is safe; the start corner ``y = 2.5`` is reached.
    """
    from hybrid import HybridAutomaton, Mode, Transition
    from hybrid.symbolic import coordinates, flow_map
    from hybrid.system import HybridSystem

    for a in (SWITCHED_A1, SWITCHED_A2):
        if np.max(np.linalg.eigvalsh(a + a.T)) >= 0:
            raise AssertionError("the switched pair lost its common Lyapunov function")
    v = coordinates("x", "y")
    automaton = HybridAutomaton(
        name="pair", modes=(Mode(name="a", invariant=v.x <= 0.1), Mode(name="b", invariant=v.x >= -0.1)),
        transitions=(Transition(name="ab", source="a", target="b", guard=v.x >= 0.1),
                     Transition(name="ba", source="b", target="a", guard=v.x <= -0.1)),
        variables=("x", "y"), initial_mode="a")
    a1, a2 = SWITCHED_A1, SWITCHED_A2
    system = HybridSystem(automaton=automaton, state_names=("x", "y"), flows={
        "a": flow_map(a1[0, 0] * v.x + a1[0, 1] * v.y, a1[1, 0] * v.x + a1[1, 1] * v.y),
        "b": flow_map(a2[0, 0] * v.x + a2[0, 1] * v.y, a2[1, 0] * v.x + a2[1, 1] * v.y)})
    r = math.hypot(0.5, 2.5)
    states = ("x", "y")
    return Instance(
        name="switched pair", system=system, box={"x": (-0.5, -0.3), "y": (2.0, 2.5)}, initial_mode="a",
        options=dict(horizon=5.0, time_step=0.005, max_jumps=20),
        requirement="always[0, 5] (x <= 2.6 and x >= -2.6 and y <= 2.6 and y >= -2.6)",
        unsafe=tuple(_unsafe(n, c, states) for n, c in (("x high", v.x >= 2.6), ("x low", v.x <= -2.6),
                                                         ("y high", v.y >= 2.6), ("y low", v.y <= -2.6))),
        planted_inside=(_unsafe("y >= 2.49", v.y >= 2.49, states),),
        planted_outside=tuple(_unsafe(f"|x| >= r + 0.01 ({d})", c, states) for d, c in (
            ("x", v.x >= r + 0.01), ("-x", v.x <= -r - 0.01), ("y", v.y >= r + 0.01), ("-y", v.y <= -r - 0.01))),
        simulation=dict(duration=5.0))


def two_tanks() -> Instance:
    """The two tanks of ``hybrid.examples`` with inflow 1 = outflow1 + outflow2 (no Zeno), 10 s.

    Closed form: the total volume ``x1 + x2`` is constant (the inflow always goes to one tank), so it stays in
    ``[1.8, 2.2]``; a tank is refilled when it reaches 0, so no level goes below 0.
    """
    from hybrid.examples import water_tanks
    from hybrid.symbolic import coordinates

    model = water_tanks(inflow=1.0, outflow1=0.5, outflow2=0.5, x1_0=1.0, x2_0=1.0)
    states = model.system.state_names
    v = coordinates(*states)
    return Instance(
        name="two tanks", system=model.system, box={"x1": (0.9, 1.1), "x2": (0.9, 1.1)}, initial_mode=None,
        options=dict(horizon=10.0, time_step=0.01, max_jumps=20),
        requirement="always[0, 10] (x1 + x2 <= 2.25 and x1 >= -0.05 and x2 >= -0.05)",
        unsafe=(_unsafe("overflow", v.x1 + v.x2 >= 2.25, states), _unsafe("x1 empty", v.x1 <= -0.05, states),
                _unsafe("x2 empty", v.x2 <= -0.05, states)),
        planted_inside=(_unsafe("volume >= 2.19", v.x1 + v.x2 >= 2.19, states),
                        _unsafe("volume <= 1.81", v.x1 + v.x2 <= 1.81, states)),
        planted_outside=(_unsafe("volume >= 2.21", v.x1 + v.x2 >= 2.21, states),
                         _unsafe("volume <= 1.79", v.x1 + v.x2 <= 1.79, states)),
        simulation=dict(duration=10.0))


def _spaceex(xml: Path, cfg: Path) -> tuple[Any, dict[str, tuple[float, float]], str, str, float]:
    from hybrid.spaceex_config import forbidden_formula, initial_box, parse_config
    from hybrid.spaceex_import import load_spaceex, read_bytes

    model = load_spaceex(xml)
    config = parse_config(read_bytes(cfg, "SpaceEx configuration").decode("utf-8"), str(cfg))
    box, modes = initial_box(model, config)
    return model.system, box, modes[0], forbidden_formula(model, config, config.horizon), float(config.horizon)


def _spacecraft(name: str, abort: bool) -> Instance:
    from hybrid.symbolic import coordinates

    folder = SPACEEX / "visnav"
    system, box, mode, requirement, horizon = _spaceex(folder / f"{name}.xml", folder / f"{name}.cfg")
    states = system.state_names
    v = coordinates(*states)
    tan30 = 0.5773502691896258
    unsafe = [_unsafe(f"P3 {label}", cond, states, modes=("P3",)) for label, cond in (
        ("LOS y", v.y <= tan30 * v.x), ("LOS -y", -v.y <= tan30 * v.x), ("vx", v.vx >= 3), ("-vx", v.vx <= -3),
        ("vy", v.vy >= 3), ("-vy", v.vy <= -3), ("vx+vy", v.vx + v.vy >= 4.2), ("-vx-vy", v.vx + v.vy <= -4.2),
        ("vx-vy", v.vx - v.vy >= 4.2), ("vy-vx", v.vx - v.vy <= -4.2))]
    # P3's step: the first segment's bloating (about a quarter of (‖A‖δ)²/2 times |x|, |x| ~ 100 m at entry) must stay
    # below the requirement's slack; 0.03 min keeps the margin above the one 0.02 gave with the older, 4x larger bound
    steps = {"P3": 0.03}
    options: dict[str, Any] = dict(horizon=horizon, time_step=0.5, max_jumps=5, mode_time_steps=steps)
    if abort:
        unsafe.append(_unsafe("target hit", (v.x >= -0.1) & (v.x <= 0.1) & (v.y >= -0.1) & (v.y <= 0.1), states,
                              modes=("passive",)))
        steps["passive"] = 1.0  # the drifting passive mode (‖A‖ ~ 0.07 /min): the target box is far from its sets
        options["jump_cluster"] = 25
    return Instance(
        name=name, system=system, box=box, initial_mode=mode, options=options, requirement=requirement,
        unsafe=tuple(unsafe), simulation=dict(duration=horizon), hylaa_step=0.1,
        planted_inside=(_unsafe("start corner x <= -924.99", v.x <= -924.99, states),),
        note="ARCH-COMP spacecraft rendezvous (linearised), tests/data/spaceex/visnav/ (SOURCE.md)")


def srna01() -> Instance:
    """SRNA01: approach and rendezvous attempt, no abort (300 min)."""
    return _spacecraft("SRNA01", abort=False)


def sra01() -> Instance:
    """SRA01: abort at t = 120 min into the passive (uncontrolled) mode (300 min)."""
    return _spacecraft("SRA01", abort=True)


def sra02() -> Instance:
    """SRA02: abort at a time in [120, 125] min (CORA's ``rendezvous_SRA01.m`` model file has this window)."""
    return _spacecraft("SRA02", abort=True)


def bldc01() -> Instance:
    """BLDC01-BDS01: the 48-state building with a constant uncertain input, ``x25 <= 0.0051`` over 20 s."""
    from hybrid.symbolic import coordinates

    folder = SPACEEX / "arch2017" / "Building" / "SpaceEx"
    system, box, mode, requirement, horizon = _spaceex(folder / "BLDC01.xml", folder / "BLDC01-BDS01.cfg")
    states = system.state_names
    x25 = getattr(coordinates(*states), "x25")
    return Instance(
        name="BLDC01-BDS01", system=system, box=box, initial_mode=mode,
        options=dict(horizon=horizon, time_step=3.3e-4, max_jumps=0, merge_segments=200, max_segments=400_000),
        requirement=requirement, unsafe=(_unsafe("x25 >= 0.0051", x25 >= 0.0051, states),),
        planted_inside=(_unsafe("start corner x25 >= 0.000099", x25 >= 0.000099, states),),
        simulation=dict(duration=horizon), hylaa_step=0.01,
        note="ARCH-COMP17 building, tests/data/spaceex/arch2017/ (SOURCE.md)")


BUILDERS: dict[str, Callable[[], Instance]] = {
    "bouncing ball": bouncing_ball, "thermostat": thermostat, "switched pair": switched_pair,
    "two tanks": two_tanks, "SRNA01": srna01, "SRA01": sra01, "SRA02": sra02, "BLDC01-BDS01": bldc01}
"""Every instance by name, in the table's order."""

QUICK = ("bouncing ball", "thermostat", "switched pair", "two tanks")
"""The ``--quick`` subset (CI): the small instances."""

PUBLISHED: dict[str, tuple[Published, ...]] = {
    "SRNA01": (Published(tool="CORA", verdict="safe", report=ARCH19),
               Published(tool="JuliaReach", verdict="safe", report=ARCH19)),
    "SRA01": (Published(tool="CORA", verdict="safe", report=ARCH19),
              Published(tool="JuliaReach", verdict="safe", report=ARCH19)),
    "SRA02": (Published(tool="CORA", verdict="safe", report=ARCH19),
              Published(tool="JuliaReach", verdict="safe", report=ARCH19)),
    "BLDC01-BDS01": (Published(tool="CORA", verdict="safe", report=ARCH19),
                     Published(tool="JuliaReach", verdict="safe", report=ARCH19)),
}
"""Published verdicts (ARCH-COMP AFF).  The small instances are not ARCH-COMP benchmarks: their expected verdict
is the closed form's (``EXPECTED``)."""

EXPECTED = {"bouncing ball": "safe", "thermostat": "safe", "switched pair": "safe", "two tanks": "safe",
            "SRNA01": "safe", "SRA01": "safe", "SRA02": "safe", "BLDC01-BDS01": "safe"}
"""The verdict every instance should get: the closed form's (small instances) or the published one (ARCH)."""
