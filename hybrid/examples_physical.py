"""The physical reference models of :mod:`hybrid.examples`, with closed forms: the record
(:class:`ReferenceModel`), the bouncing ball, the thermostat and the two water tanks, and the parameter checks
the other reference models share.

:mod:`hybrid.examples` re-exports every public name (import them from there); see its docstring for the
conventions (affine, symbolic guards and flows; planted defects).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from numbers import Integral, Real

from .errors import ModelDefinitionError
from .model import Conjunction, HybridAutomaton, Mode, Transition, all_of, jump_text
from .region import Box
from .symbolic import Apply, Expr, SymbolicVector, as_expr, coordinates, exactly, flow_map, is_symbolic, jump_map
from .system import HybridSystem

# Helpers shared with hybrid.examples have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = [
    "FINDING_KINDS",
    "ReferenceModel",
    "bouncing_ball",
    "bouncing_ball_impact_times",
    "bouncing_ball_apex_heights",
    "bouncing_ball_zeno_time",
    "thermostat",
    "thermostat_switch_times",
    "water_tanks",
    "water_tanks_switch_times",
    "water_tanks_zeno_time",
    "thermostat_parameters",
]


FINDING_KINDS: tuple[str, ...] = (
    "unreachable_mode",
    "unreachable_transition",
    "sink_mode",
    "nondeterminism",
    "deadlock",
    "reset_outside_invariant",
    "reset_retriggers",
)
"""Kinds of structural findings a model may plant (the vocabulary of the checks)."""

HORIZON_EVENT = 8
"""The physical models' ``duration`` lies halfway between this event and the next.

Before the Zeno time, so that an executor without Zeno handling can run the
whole horizon, and never on an event, so that the last event is unambiguous.
"""


# ---------------------------------------------------------------------- the record
@dataclass(frozen=True, kw_only=True, slots=True)
class ReferenceModel:
    """A hybrid system with an initial condition, a search box and its planted defects.

    Attributes
    ----------
    name : str
        Name of the model (the automaton's name, the key in :func:`reference_models`).
    system : HybridSystem
        The automaton with its flows and jump maps.
    x0 : tuple of float
        Initial continuous state, in ``system.state_names`` order.
    initial_mode : str
        Initial mode (the automaton's ``initial_mode``).
    box : Box
        Declared region over exactly the state names, within which structural
        checks search; it contains ``x0``.
    duration : float
        Simulation horizon [s].
    description : str
        What the model is and what it is for.
    planted : tuple of str
        Kinds of defect (from :data:`FINDING_KINDS`) deliberately planted, that
        a correct structural checker must report at error or warning level;
        empty for a clean model.

    Raises
    ------
    ModelDefinitionError
        An unknown planted kind, an initial mode that is not the automaton's,
        an ``x0`` of the wrong length, outside the box or outside the initial
        mode's invariant, a box over other coordinates, or a non-positive
        duration.
    """

    name: str
    system: HybridSystem
    x0: tuple[float, ...]
    initial_mode: str
    box: Box
    duration: float
    description: str
    planted: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        where = f"reference model {self.name!r}"
        if not isinstance(self.system, HybridSystem):
            raise ModelDefinitionError(f"{where}: system = {self.system!r}; expected a HybridSystem")
        planted = tuple(self.planted)
        unknown = [k for k in planted if k not in FINDING_KINDS]
        if unknown or len(set(planted)) != len(planted):
            raise ModelDefinitionError(
                f"{where}: planted = {planted!r}; expected distinct kinds from {list(FINDING_KINDS)}"
            )
        object.__setattr__(self, "planted", planted)
        automaton = self.system.automaton
        if self.initial_mode != automaton.initial_mode:
            raise ModelDefinitionError(
                f"{where}: initial_mode = {self.initial_mode!r} but the automaton starts in "
                f"{automaton.initial_mode!r}; expected the automaton's initial mode"
            )
        try:
            x0 = tuple(float(c) for c in self.x0)
        except (TypeError, ValueError):
            raise ModelDefinitionError(f"{where}: x0 = {self.x0!r}; expected a sequence of real numbers") from None
        if len(x0) != self.system.dimension:
            raise ModelDefinitionError(
                f"{where}: x0 has {len(x0)} values; expected {self.system.dimension} "
                f"({', '.join(self.system.state_names)})"
            )
        object.__setattr__(self, "x0", x0)
        self.box.require(self.system.state_names, where)
        index = {n: i for i, n in enumerate(self.system.state_names)}
        if not self.box.contains([x0[index[n]] for n in self.box.names]):
            raise ModelDefinitionError(f"{where}: x0 = {x0} lies outside the box {self.box.describe()}")
        invariant = automaton.mode(self.initial_mode).invariant
        if invariant is not None and invariant(self.system.signals(0.0, x0), automaton.initial_memory()) < 0.0:
            raise ModelDefinitionError(
                f"{where}: x0 = {x0} violates the invariant of the initial mode {self.initial_mode!r} "
                f"({automaton.mode(self.initial_mode).invariant_text})"
            )
        if not (isinstance(self.duration, Real) and math.isfinite(self.duration) and self.duration > 0.0):
            raise ModelDefinitionError(f"{where}: duration = {self.duration!r}; expected a finite time > 0 s")
        object.__setattr__(self, "duration", float(self.duration))


# ---------------------------------------------------------------------- validation
def real_parameter(where: str, name: str, value: object, ok: Callable[[float], bool], expected: str) -> float:
    """``value`` as a float, or :class:`ModelDefinitionError` naming it and what was expected."""
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value) or not ok(float(value)):
        raise ModelDefinitionError(f"{where}: {name} = {value!r}; expected {expected}")
    return float(value)


def event_count(where: str, count: object) -> int:
    """``count`` as a number of events (an integer >= 0), or :class:`ModelDefinitionError`."""
    if isinstance(count, bool) or not isinstance(count, Integral) or count < 0:
        raise ModelDefinitionError(f"{where}: count = {count!r}; expected an integer >= 0 (number of events)")
    return int(count)


def positive_parameter(where: str, name: str, value: object, what: str) -> float:
    """``value`` as a finite float > 0, or :class:`ModelDefinitionError` naming it and ``what`` it is."""
    return real_parameter(where, name, value, lambda c: c > 0.0, f"a finite {what} > 0")


def event_horizon(times: tuple[float, ...]) -> float:
    """Halfway between the last two event times."""
    return 0.5 * (times[-2] + times[-1])


def exact_minus(a: Expr | float, b: Expr | float) -> Expr:
    """The symbolic difference ``a - b`` exactly as written, for a parameter that may be ``0.0``.

    The ``-`` operator of :mod:`hybrid.symbolic` simplifies ``0 - e`` to
    ``-e`` and ``e - 0`` to ``e``; the first turns the ``+0.0`` of
    ``0.0 - 0.0`` into ``-0.0`` (and the second an integer signal into an
    integer result), so a threshold ``r2 = 0`` would no longer evaluate bit for
    bit like the float formula on the face ``x2 = 0``.  This node keeps the
    subtraction.
    """
    return Apply("sub", (as_expr(a), as_expr(b)))

# ---------------------------------------------------------------------- bouncing ball
GRAVITY = 9.81
"""Default gravitational acceleration [m/s²]."""


def _ball(
    where: str, gravity: object, restitution: object, h0: object, v0: object
) -> tuple[float, float, float, float]:
    g = positive_parameter(where, "gravity", gravity, "acceleration [m/s²]")
    e = real_parameter(where, "restitution", restitution, lambda c: 0.0 < c <= 1.0,
              "a coefficient of restitution in (0, 1] (1 is elastic)")
    h = real_parameter(where, "h0", h0, lambda c: c >= 0.0, "an initial height >= 0 m (the ground is h = 0)")
    v = real_parameter(where, "v0", v0, lambda c: True, "a finite initial velocity [m/s]")
    if h == 0.0 and v == 0.0:
        raise ModelDefinitionError(
            f"{where}: h0 = {h0!r}, v0 = {v0!r} is the ball at rest on the ground (the Zeno point); "
            "expected h0 > 0 or v0 != 0"
        )
    return g, e, h, v


def _first_impact(g: float, h0: float, v0: float) -> tuple[float, float]:
    """Time and speed of the first impact (see :func:`bouncing_ball_impact_times`)."""
    v1 = math.sqrt(v0 * v0 + 2.0 * g * h0)
    # (v0 + v1)/g cancels when v0 < 0; (v0 + v1)(v1 - v0) = 2 g h0 gives the stable form.
    t1 = (v0 + v1) / g if v0 >= 0.0 else 2.0 * h0 / (v1 - v0)
    return t1, v1


def bouncing_ball(
    *, gravity: float = GRAVITY, restitution: float = 0.8, h0: float = 1.0, v0: float = 0.0
) -> ReferenceModel:
    """A ball falling under gravity and bouncing on the ground ``h = 0``.

    One mode ``fly`` (flow ``ḣ = v, v̇ = -g``, invariant ``h >= 0``) and one
    level-triggered self-loop ``bounce`` enabled when ``h <= 0 and v <= 0``,
    with jump map ``(h, v) -> (h, -e v)`` (the height is kept, not clamped).
    The ball is Zeno for ``e < 1``: see :func:`bouncing_ball_zeno_time`.

    Parameters
    ----------
    gravity : float
        ``g > 0`` [m/s²].
    restitution : float
        ``e`` in ``(0, 1]``.
    h0 : float
        Initial height ``>= 0`` [m].
    v0 : float
        Initial velocity [m/s] (upwards positive); ``h0 = v0 = 0`` is refused.

    Returns
    -------
    ReferenceModel
        Clean (``planted == ()``).  The box is ``h ∈ [0, 2 H]``,
        ``v ∈ [-2 v1, 2 v1]`` with ``H = h0 + v0²/(2 g)`` the height of the
        initial energy (no apex is higher) and ``v1 = sqrt(2 g H)`` the first
        impact speed (no speed is larger); the duration lies halfway between
        the 8th and 9th impacts.

    Raises
    ------
    ModelDefinitionError
        A parameter out of range, naming it, its value and the expected range.

    Examples
    --------
    >>> ball = bouncing_ball(restitution=0.5)
    >>> bounce = ball.system.automaton.transitions[0]
    >>> bounce.guard((0.0, -3.0), {}) >= 0, bounce.guard((0.1, -3.0), {}) >= 0
    (True, False)
    >>> ball.system.jump("bounce", 0.0, (0.0, -3.0), {})
    (0.0, 1.5)
    """
    g, e, h0, v0 = _ball("bouncing_ball", gravity, restitution, h0, v0)
    _, v1 = _first_impact(g, h0, v0)
    top = v1 * v1 / (2.0 * g)  # h0 + v0²/(2 g): no point of the motion is higher
    v = coordinates("h", "v")  # the signals read by the guards and invariants (v = x)
    x = coordinates("h", "v")  # the continuous state
    fly = Mode(
        name="fly",
        description="ball in the air (or on the ground), accelerated downwards by gravity",
        invariant=all_of(v.h >= 0.0),
    )
    bounce = Transition(
        name="bounce",
        source="fly",
        target="fly",
        guard=all_of(v.h <= 0.0, v.v <= 0.0),
        reads=("h", "v"),
    )
    flows = {"fly": flow_map(x.v, -g)}
    jumps = {"bounce": jump_map(x.h, -e * x.v)}
    automaton = HybridAutomaton(
        name="bouncing_ball",
        modes=(fly,),
        transitions=with_jump_texts((bounce,), jumps, ("h", "v")),
        variables=("h", "v"),
        initial_mode="fly",
        description=f"bouncing ball, g = {g:g} m/s², e = {e:g}",
    )
    require_symbolic("bouncing_ball", automaton.modes, automaton.transitions, flows, jumps)
    system = HybridSystem(automaton=automaton, state_names=("h", "v"), flows=flows, jumps=jumps)
    impacts = bouncing_ball_impact_times(gravity=g, restitution=e, h0=h0, v0=v0, count=HORIZON_EVENT + 1)
    return ReferenceModel(
        name="bouncing_ball",
        system=system,
        x0=(h0, v0),
        initial_mode="fly",
        box=Box(bounds={"h": (0.0, 2.0 * top), "v": (-2.0 * v1, 2.0 * v1)}),
        duration=event_horizon(impacts),
        description=(
            f"Bouncing ball (g = {g:g} m/s², e = {e:g}) from h0 = {h0:g} m, v0 = {v0:g} m/s: impact times, "
            "apex heights and the Zeno time have closed forms; the horizon stops between the 8th and 9th "
            "impacts, before the Zeno time. Clean; its self-loop lands back on its guard only at the Zeno "
            "point (h, v) = (0, 0)."
        ),
        planted=(),
    )


def bouncing_ball_impact_times(
    *, gravity: float = GRAVITY, restitution: float = 0.8, h0: float = 1.0, v0: float = 0.0, count: int
) -> tuple[float, ...]:
    """Times of the first ``count`` impacts of :func:`bouncing_ball`.

    Parameters
    ----------
    gravity, restitution, h0, v0 : float
        As in :func:`bouncing_ball`.
    count : int
        Number of impacts, ``>= 0``.

    Returns
    -------
    tuple of float
        ``(t_1, ..., t_count)`` [s].

    Notes
    -----
    Until the first impact ``h(t) = h0 + v0 t - g t²/2``.  Its positive root is
    ``t_1 = (v0 + v_1)/g`` with ``v_1 = sqrt(v0² + 2 g h0)``, and energy
    conservation gives the impact speed ``|v(t_1)| = v_1``.  (For ``v0 < 0``
    the equivalent ``t_1 = 2 h0/(v_1 - v0)``, from
    ``(v0 + v_1)(v_1 - v0) = 2 g h0``, avoids cancellation.)

    The ``k``-th bounce leaves the ground at speed ``e^k v_1``; the ballistic
    flight that follows returns to the ground after ``2 e^k v_1 / g``, at the
    same speed, so ``t_{k+1} = t_k + 2 e^k v_1 / g``.

    Examples
    --------
    >>> [round(t, 6) for t in bouncing_ball_impact_times(h0=4.905, gravity=9.81, restitution=0.5, count=3)]
    [1.0, 2.0, 2.5]
    """
    where = "bouncing_ball_impact_times"
    g, e, h0, v0 = _ball(where, gravity, restitution, h0, v0)
    n = event_count(where, count)
    t, v1 = _first_impact(g, h0, v0)
    times = []
    speed = v1
    for _ in range(n):
        times.append(t)
        speed *= e
        t += 2.0 * speed / g
    return tuple(times)


def bouncing_ball_apex_heights(
    *, gravity: float = GRAVITY, restitution: float = 0.8, h0: float = 1.0, v0: float = 0.0, count: int
) -> tuple[float, ...]:
    """Heights of the apexes after the first ``count`` bounces of :func:`bouncing_ball`.

    Returns
    -------
    tuple of float
        ``(H_1, ..., H_count)`` [m], ``H_k`` the highest point between the
        ``k``-th and the ``(k+1)``-th impacts.

    Notes
    -----
    The ``k``-th bounce leaves the ground at speed ``e^k v_1`` (``v_1`` as in
    :func:`bouncing_ball_impact_times`); kinetic energy turns into potential
    energy, ``(e^k v_1)²/2 = g H_k``, so ``H_k = (e^k v_1)² / (2 g)``.

    Examples
    --------
    >>> [round(h, 6) for h in bouncing_ball_apex_heights(restitution=0.5, count=2)]
    [0.25, 0.0625]
    """
    where = "bouncing_ball_apex_heights"
    g, e, h0, v0 = _ball(where, gravity, restitution, h0, v0)
    n = event_count(where, count)
    _, v1 = _first_impact(g, h0, v0)
    heights = []
    speed = v1
    for _ in range(n):
        speed *= e
        heights.append(speed * speed / (2.0 * g))
    return tuple(heights)


def bouncing_ball_zeno_time(
    *, gravity: float = GRAVITY, restitution: float = 0.8, h0: float = 1.0, v0: float = 0.0
) -> float:
    """Time at which the impacts of :func:`bouncing_ball` accumulate.

    Returns
    -------
    float
        ``t_Z = t_1 + 2 e v_1 / (g (1 - e))`` [s]; ``inf`` for an elastic ball
        (``e = 1``), whose impacts never accumulate.

    Notes
    -----
    Summing the flight times of :func:`bouncing_ball_impact_times`,
    ``t_Z = t_1 + Σ_{k>=1} 2 e^k v_1 / g``, a geometric series of ratio
    ``e < 1`` and first term ``2 e v_1 / g``.  At ``t_Z`` the ball rests at
    ``(h, v) = (0, 0)``.

    Examples
    --------
    >>> round(bouncing_ball_zeno_time(h0=4.905, restitution=0.5), 9)
    3.0
    """
    g, e, h0, v0 = _ball("bouncing_ball_zeno_time", gravity, restitution, h0, v0)
    t1, v1 = _first_impact(g, h0, v0)
    if e == 1.0:
        return math.inf
    return t1 + 2.0 * e * v1 / (g * (1.0 - e))


# ---------------------------------------------------------------------- thermostat
def thermostat_parameters(
    where: str,
    ambient: object,
    heater: object,
    rate: object,
    low: object,
    high: object,
    T0: object,
    initially_on: object,
) -> tuple[float, float, float, float, float, float, bool]:
    """The checked parameters of the thermostat ``(ambient, heater, rate, low, high, T0, initially_on)``."""
    a = real_parameter(where, "ambient", ambient, lambda c: True, "a finite temperature")
    u = real_parameter(where, "heater", heater, lambda c: True, "a finite temperature")
    k = positive_parameter(where, "rate", rate, "rate [1/s]")
    lo = real_parameter(where, "low", low, lambda c: True, "a finite temperature")
    hi = real_parameter(where, "high", high, lambda c: True, "a finite temperature")
    if not a < lo < hi < u:
        raise ModelDefinitionError(
            f"{where}: ambient = {ambient!r}, low = {low!r}, high = {high!r}, heater = {heater!r}; "
            "expected ambient < low < high < heater (otherwise a mode never reaches its switching threshold)"
        )
    if not isinstance(initially_on, bool):
        raise ModelDefinitionError(f"{where}: initially_on = {initially_on!r}; expected True or False")
    if initially_on:
        T = real_parameter(where, "T0", T0, lambda c: a < c <= hi,
                  f"a temperature in (ambient, high] = ({a:g}, {hi:g}] (invariant of mode 'on': T <= high)")
    else:
        T = real_parameter(where, "T0", T0, lambda c: lo <= c < u,
                  f"a temperature in [low, heater) = [{lo:g}, {u:g}) (invariant of mode 'off': T >= low)")
    return a, u, k, lo, hi, T, initially_on


def thermostat(
    *,
    ambient: float = 10.0,
    heater: float = 30.0,
    rate: float = 0.1,
    low: float = 19.0,
    high: float = 21.0,
    T0: float = 20.0,
    initially_on: bool = False,
) -> ReferenceModel:
    """A room heated by an on/off thermostat with hysteresis.

    Mode ``off``: ``Ṫ = -rate (T - ambient)``, invariant ``T >= low``; mode
    ``on``: ``Ṫ = -rate (T - heater)``, invariant ``T <= high``.  Transition
    ``heat_on`` (off → on) is enabled when ``T <= low``, ``heat_off``
    (on → off) when ``T >= high``; both are level-triggered and keep ``T``.

    Parameters
    ----------
    ambient, heater : float
        Temperatures approached without and with heating, ``ambient < low < high < heater``.
    rate : float
        Inverse time constant ``> 0`` [1/s].
    low, high : float
        Switching thresholds.
    T0 : float
        Initial temperature, inside ``(ambient, heater)`` and the initial mode's invariant.
    initially_on : bool
        Start in ``on`` rather than ``off``.

    Returns
    -------
    ReferenceModel
        Clean; box ``T ∈ [ambient, heater]``; the duration lies halfway
        between the 8th and 9th switches.

    Raises
    ------
    ModelDefinitionError
        A parameter out of range or an ordering ``ambient < low < high < heater`` violated.

    Examples
    --------
    >>> room = thermostat()
    >>> room.system.flow("on", 0.0, (20.0,), {})
    (1.0,)
    >>> [t.name for t in room.system.automaton.enabled("off", (18.5,), {})]
    ['heat_on']
    """
    a, u, k, lo, hi, T, on = thermostat_parameters("thermostat", ambient, heater, rate, low, high, T0, initially_on)
    v = coordinates("T")  # signal
    x = coordinates("T")  # state
    # The thresholds and temperatures may be 0.0: exactly() and exact_minus keep each subtraction as written.
    modes = (
        Mode(
            name="off",
            description="heater off: the room cools towards the ambient temperature",
            invariant=all_of(exactly(v.T >= lo)),
        ),
        Mode(
            name="on",
            description="heater on: the room warms towards the heater temperature",
            invariant=all_of(exactly(v.T <= hi)),
        ),
    )
    transitions = (
        Transition(
            name="heat_on", source="off", target="on", guard=exactly(v.T <= lo), reads=("T",),
        ),
        Transition(
            name="heat_off", source="on", target="off", guard=exactly(v.T >= hi), reads=("T",),
        ),
    )
    initial = "on" if on else "off"
    automaton = HybridAutomaton(
        name="thermostat",
        modes=modes,
        transitions=transitions,
        variables=("T",),
        initial_mode=initial,
        description=f"on/off thermostat with hysteresis band [{lo:g}, {hi:g}]",
    )
    flows = {
        "off": flow_map(-k * exact_minus(x.T, a)),
        "on": flow_map(-k * exact_minus(x.T, u)),
    }
    require_symbolic("thermostat", automaton.modes, automaton.transitions, flows, {})
    system = HybridSystem(automaton=automaton, state_names=("T",), flows=flows)
    switches = thermostat_switch_times(
        ambient=a, heater=u, rate=k, low=lo, high=hi, T0=T, initially_on=on, count=HORIZON_EVENT + 1
    )
    return ReferenceModel(
        name="thermostat",
        system=system,
        x0=(T,),
        initial_mode=initial,
        box=Box(bounds={"T": (a, u)}),
        duration=event_horizon(switches),
        description=(
            f"Thermostat (ambient {a:g}, heater {u:g}, rate {k:g}/s, band [{lo:g}, {hi:g}]) from T0 = {T:g} "
            f"in mode {initial!r}: switching times follow from the exponential decay; no Zeno behaviour. Clean."
        ),
        planted=(),
    )


def thermostat_switch_times(
    *,
    ambient: float = 10.0,
    heater: float = 30.0,
    rate: float = 0.1,
    low: float = 19.0,
    high: float = 21.0,
    T0: float = 20.0,
    initially_on: bool = False,
    count: int,
) -> tuple[float, ...]:
    """Times of the first ``count`` switches of :func:`thermostat`.

    Returns
    -------
    tuple of float
        Switch times [s]; they alternate ``heat_on``/``heat_off`` starting
        with the transition out of the initial mode.  A start on the threshold
        (``T0 = low`` in ``off``) switches at ``t = 0``.

    Notes
    -----
    In ``off``, ``T(t) = ambient + (T_a - ambient) e^{-rate t}`` from ``T_a``,
    so ``T`` reaches ``low`` after ``ln((T_a - ambient)/(low - ambient))/rate``;
    in ``on``, ``T(t) = heater - (heater - T_a) e^{-rate t}`` reaches ``high``
    after ``ln((heater - T_a)/(heater - high))/rate``.  After the first switch
    ``T_a`` is the other threshold, so the off and on phases then last
    ``ln((high - ambient)/(low - ambient))/rate`` and
    ``ln((heater - low)/(heater - high))/rate``.  The logarithms are evaluated
    as ``log1p`` of the relative distance to the threshold.

    Examples
    --------
    >>> [round(t, 4) for t in thermostat_switch_times(count=3)]
    [1.0536, 3.0603, 5.067]
    """
    where = "thermostat_switch_times"
    a, u, k, lo, hi, T, on = thermostat_parameters(where, ambient, heater, rate, low, high, T0, initially_on)
    n = event_count(where, count)
    times = []
    t = 0.0
    for _ in range(n):
        if on:
            t += math.log1p((hi - T) / (u - hi)) / k
            T = hi
        else:
            t += math.log1p((T - lo) / (lo - a)) / k
            T = lo
        times.append(t)
        on = not on
    return tuple(times)


# ---------------------------------------------------------------------- water tanks
def _tanks(
    where: str,
    inflow: object,
    outflow1: object,
    outflow2: object,
    r1: object,
    r2: object,
    x1_0: object,
    x2_0: object,
) -> tuple[float, float, float, float, float, float, float]:
    w = positive_parameter(where, "inflow", inflow, "flow rate")
    v1 = positive_parameter(where, "outflow1", outflow1, "flow rate")
    v2 = positive_parameter(where, "outflow2", outflow2, "flow rate")
    if not w > max(v1, v2):
        raise ModelDefinitionError(
            f"{where}: inflow = {inflow!r} with outflow1 = {outflow1!r}, outflow2 = {outflow2!r}; expected "
            "inflow > max(outflow1, outflow2), otherwise the tank being filled still drains below its "
            "threshold and the model jumps back and forth infinitely often at one instant"
        )
    a = real_parameter(where, "r1", r1, lambda c: c >= 0.0, "a threshold level >= 0")
    b = real_parameter(where, "r2", r2, lambda c: c >= 0.0, "a threshold level >= 0")
    x1 = real_parameter(where, "x1_0", x1_0, lambda c: c >= a, f"an initial level >= r1 = {a:g}")
    x2 = real_parameter(where, "x2_0", x2_0, lambda c: c > b,
               f"an initial level > r2 = {b:g} (the model starts in 'fill1', invariant x2 >= r2)")
    return w, v1, v2, a, b, x1, x2


def water_tanks(
    *,
    inflow: float = 0.75,
    outflow1: float = 0.5,
    outflow2: float = 0.5,
    r1: float = 0.0,
    r2: float = 0.0,
    x1_0: float = 1.0,
    x2_0: float = 1.0,
) -> ReferenceModel:
    """The two water tanks of Johansson, Egerstedt, Lygeros and Sastry (1999).

    Two tanks drain at constant rates ``v1``, ``v2``; an inflow ``w`` goes to
    one tank at a time and is switched to the other tank as soon as that one
    falls to its threshold.  Mode ``fill1``: ``ẋ1 = w - v1, ẋ2 = -v2``,
    invariant ``x2 >= r2``; mode ``fill2``: ``ẋ1 = -v1, ẋ2 = w - v2``,
    invariant ``x1 >= r1``.  Transition ``to_fill2`` (fill1 → fill2) is
    enabled when ``x2 <= r2``, ``to_fill1`` (fill2 → fill1) when
    ``x1 <= r1``; both keep the levels.  The model starts in ``fill1``.

    Regimes (all with ``w > max(v1, v2)``, which is required):

    * ``w < v1 + v2``: the total volume decreases, the switches accumulate at
      the Zeno time of :func:`water_tanks_zeno_time` (the classic example);
    * ``w >= v1 + v2``: the total volume does not decrease and the switches do
      not accumulate (no Zeno behaviour).

    Parameters
    ----------
    inflow : float
        ``w > max(v1, v2)``.
    outflow1, outflow2 : float
        ``v1, v2 > 0``.
    r1, r2 : float
        Thresholds ``>= 0``.
    x1_0, x2_0 : float
        Initial levels, ``x1_0 >= r1`` and ``x2_0 > r2``.

    Returns
    -------
    ReferenceModel
        Clean.  Box ``x_i ∈ [r_i, r_i + E0 + 1]`` with ``E0 = x1_0 - r1 + x2_0 - r2``
        the initial excess volume (in the Zeno regime no level exceeds its
        threshold by more than ``E0``); the duration lies halfway between the
        8th and 9th switches.

    Raises
    ------
    ModelDefinitionError
        A parameter out of range, naming it, its value and the expected range.

    Examples
    --------
    >>> tanks = water_tanks()
    >>> tanks.system.flow("fill1", 0.0, (1.0, 1.0), {})
    (0.25, -0.5)
    >>> round(water_tanks_zeno_time(), 12)
    8.0
    """
    w, v1, v2, a, b, x1, x2 = _tanks("water_tanks", inflow, outflow1, outflow2, r1, r2, x1_0, x2_0)
    v = coordinates("x1", "x2")  # signals (the levels)
    # The thresholds are 0.0 by default: exactly() keeps each subtraction as written (+0.0 on the face).
    modes = (
        Mode(
            name="fill1",
            description="inflow into tank 1; tank 2 drains",
            invariant=all_of(exactly(v.x2 >= b)),
        ),
        Mode(
            name="fill2",
            description="inflow into tank 2; tank 1 drains",
            invariant=all_of(exactly(v.x1 >= a)),
        ),
    )
    transitions = (
        Transition(
            name="to_fill2", source="fill1", target="fill2", guard=exactly(v.x2 <= b), reads=("x2",),
        ),
        Transition(
            name="to_fill1", source="fill2", target="fill1", guard=exactly(v.x1 <= a), reads=("x1",),
        ),
    )
    automaton = HybridAutomaton(
        name="water_tanks",
        modes=modes,
        transitions=transitions,
        variables=("x1", "x2"),
        initial_mode="fill1",
        description=f"two water tanks, inflow {w:g}, outflows {v1:g} and {v2:g}",
    )
    flows = {  # constant in each mode (the float differences are taken once, here)
        "fill1": flow_map(w - v1, -v2),
        "fill2": flow_map(-v1, w - v2),
    }
    require_symbolic("water_tanks", automaton.modes, automaton.transitions, flows, {})
    system = HybridSystem(automaton=automaton, state_names=("x1", "x2"), flows=flows)
    excess = x1 - a + x2 - b
    switches = water_tanks_switch_times(
        inflow=w, outflow1=v1, outflow2=v2, r1=a, r2=b, x1_0=x1, x2_0=x2, count=HORIZON_EVENT + 1
    )
    zeno = w < v1 + v2
    return ReferenceModel(
        name="water_tanks",
        system=system,
        x0=(x1, x2),
        initial_mode="fill1",
        box=Box(bounds={"x1": (a, a + excess + 1.0), "x2": (b, b + excess + 1.0)}),
        duration=event_horizon(switches),
        description=(
            f"Two water tanks (Johansson et al. 1999; inflow {w:g}, outflows {v1:g}, {v2:g}, thresholds "
            f"{a:g}, {b:g}) from ({x1:g}, {x2:g}) in 'fill1': "
            + (
                "Zeno, the switches accumulate when both tanks reach their thresholds; "
                if zeno
                else "not Zeno (inflow >= outflow1 + outflow2); "
            )
            + "switching times by exact recursion on the piecewise-constant flow. Clean."
        ),
        planted=(),
    )


def water_tanks_switch_times(
    *,
    inflow: float = 0.75,
    outflow1: float = 0.5,
    outflow2: float = 0.5,
    r1: float = 0.0,
    r2: float = 0.0,
    x1_0: float = 1.0,
    x2_0: float = 1.0,
    count: int,
) -> tuple[float, ...]:
    """Times of the first ``count`` switches of :func:`water_tanks`.

    Returns
    -------
    tuple of float
        Switch times [s], alternating ``to_fill2``, ``to_fill1``, ...

    Notes
    -----
    The flow is constant in each mode, so each phase is exact.  In ``fill1``
    tank 2 drains from ``x2`` to ``r2`` in ``(x2 - r2)/v2`` while tank 1
    gains ``(w - v1)`` per second; in ``fill2`` tank 1 drains from ``x1`` to
    ``r1`` in ``(x1 - r1)/v1`` while tank 2 gains ``(w - v2)`` per second.
    With ``w > max(v1, v2)`` the tank being filled rises, so every phase
    after the first starts strictly above the threshold of the tank that
    drains and lasts a positive time.

    Examples
    --------
    >>> water_tanks_switch_times(count=4)
    (2.0, 5.0, 6.5, 7.25)
    """
    where = "water_tanks_switch_times"
    w, v1, v2, a, b, x1, x2 = _tanks(where, inflow, outflow1, outflow2, r1, r2, x1_0, x2_0)
    n = event_count(where, count)
    e1, e2 = x1 - a, x2 - b  # excess over the thresholds
    times = []
    t = 0.0
    fill1 = True
    for _ in range(n):
        if fill1:
            dt = e2 / v2
            e1, e2 = e1 + (w - v1) * dt, 0.0
        else:
            dt = e1 / v1
            e1, e2 = 0.0, e2 + (w - v2) * dt
        t += dt
        times.append(t)
        fill1 = not fill1
    return tuple(times)


def water_tanks_zeno_time(
    *,
    inflow: float = 0.75,
    outflow1: float = 0.5,
    outflow2: float = 0.5,
    r1: float = 0.0,
    r2: float = 0.0,
    x1_0: float = 1.0,
    x2_0: float = 1.0,
) -> float:
    """Time at which the switches of :func:`water_tanks` accumulate.

    Returns
    -------
    float
        ``t_Z = (x1_0 + x2_0 - r1 - r2) / (v1 + v2 - w)`` [s] when
        ``w < v1 + v2``; ``inf`` otherwise (the switches do not accumulate).

    Notes
    -----
    Let ``E = (x1 - r1) + (x2 - r2)`` be the excess volume.  In both modes
    ``Ė = w - v1 - v2``, a constant, so ``E(t) = E_0 - (v1 + v2 - w) t``
    across the jumps (they keep the levels).  At the ``k``-th switch the tank
    that has just drained sits at its threshold, so ``E(t_k)`` is the excess
    of the other tank, which is ``v_i`` times the duration of the next phase.
    When the switches accumulate the phase durations tend to zero, hence
    ``E(t_Z) = 0``: both tanks sit at their thresholds, and
    ``t_Z = E_0 / (v1 + v2 - w)``.  They do accumulate for ``w < v1 + v2``:
    two consecutive phases scale the duration by
    ``(w - v1)(w - v2)/(v1 v2) < 1``, which is equivalent to
    ``w (w - v1 - v2) < 0``.  For ``w >= v1 + v2`` the product is ``>= 1``.

    Examples
    --------
    >>> round(water_tanks_zeno_time(inflow=0.9), 9)
    20.0
    """
    w, v1, v2, a, b, x1, x2 = _tanks("water_tanks_zeno_time", inflow, outflow1, outflow2, r1, r2, x1_0, x2_0)
    if w >= v1 + v2:
        return math.inf
    return (x1 - a + x2 - b) / (v1 + v2 - w)


def with_jump_texts(transitions: tuple[Transition, ...], jumps: dict[str, SymbolicVector],
                    state_names: tuple[str, ...]) -> tuple[Transition, ...]:
    """``transitions`` with the ``reset_text`` of each one that has a jump map derived from it (:func:`jump_text`)."""
    return tuple(dataclasses.replace(t, reset_text=jump_text(jumps[t.name], state_names))
                 if t.name in jumps and not t.reset_text else t for t in transitions)


def require_symbolic(
    name: str,
    modes: tuple[Mode, ...],
    transitions: tuple[Transition, ...],
    flows: dict[str, SymbolicVector],
    jumps: dict[str, SymbolicVector],
) -> None:
    """:class:`ModelDefinitionError` unless every guard, invariant (term), flow and jump map is symbolic."""
    parts: list[tuple[str, object]] = []
    for mode in modes:
        if mode.invariant is not None:
            parts.append((f"invariant of mode {mode.name!r}", mode.invariant))
    parts += [(f"guard of transition {t.name!r}", t.guard) for t in transitions]
    parts += [(f"flow of mode {k!r}", f) for k, f in flows.items()]
    parts += [(f"jump map of transition {k!r}", r) for k, r in jumps.items()]
    for what, function in parts:
        terms = function.terms if isinstance(function, Conjunction) else (function,)
        if not all(is_symbolic(term) for term in terms):
            raise ModelDefinitionError(
                f"reference model {name!r}: the {what} is {function!r}; expected a symbolic expression of "
                "hybrid.symbolic (coordinates(), flow_map(), jump_map()) so that a checker can decide it"
            )
