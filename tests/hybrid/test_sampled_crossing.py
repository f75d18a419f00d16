"""One event per crossing in the sampled executor: a sample exactly on a crossing guard's zero, then one beyond it,
is one crossing (hybrid/instant.py, docs/hybrid.md), counted against the closed form of the signal's zeros.

The signals are exact in binary floating point (slopes ±1, a period of 0.5 s): the samples land *exactly* on the
zeros, which is the case the rule is about.
"""

from __future__ import annotations

import pytest

from hybrid import HybridAutomaton, MemoryVariable, Mode, Plant, Transition, coordinates, memory, reset, simulate_sampled

PERIOD = 0.5


def _triangle(t: float) -> float:
    """-1 at t = 0, slope +1 up to 1 at t = 2, slope -1 down to -1 at t = 4, and so on (exact on dyadic times)."""
    return abs(((t + 2.0) % 4.0) - 2.0) - 1.0


class _Measured:
    """The controller: measures ``signal(t)`` (the plant is the clock ``x' = 1``), no input."""

    record_names = ()

    def __init__(self, signal):
        self.signal = signal

    def initial_state(self, t, x):
        return None

    def measure(self, t, x, c):
        return (self.signal(x[0]),), c

    def control(self, t, x, c, v, mode, memory_values):
        return (), c, ()


CLOCK = Plant(state_names=("t",), input_names=(), derivative=lambda x, u: (1.0,),
              exact_flow=lambda x, u, dt: (x[0] + dt,))


def _counter(direction: int) -> HybridAutomaton:
    """One mode, a self-loop on the crossing of ``x = 0`` (``direction``) that counts its firings."""
    v, m = coordinates("x"), memory("n")
    crossing = Transition(name="cross", source="m", target="m", guard=v.x >= 0.0, direction=direction,
                          reset=reset(n=m.n + 1.0))
    return HybridAutomaton(name="counter", modes=(Mode(name="m"),), transitions=(crossing,), variables=("x",),
                           memory=(MemoryVariable(name="n", initial=0.0),), initial_mode="m")


def _zeros(first: float, every: float, duration: float) -> list[float]:
    """Closed form: the crossings at ``first + k * every`` in ``[0, duration]``."""
    return [first + k * every for k in range(int(duration // every) + 2) if first + k * every <= duration]


def test_a_ramp_sampled_exactly_on_its_zero_fires_once():
    """x(t) = t - 1 from x = -1: samples -1, -0.5, 0 (t = 1), 0.5, ...: one crossing, at t = 1."""
    run = simulate_sampled(_counter(+1), CLOCK, _Measured(lambda t: t - 1.0), (0.0,), period=PERIOD, duration=3.0)
    assert [e.time for e in run.events] == [1.0] == _zeros(1.0, 10.0, 3.0)
    assert run.final_memory["n"] == 1.0


@pytest.mark.parametrize("direction, first", [(+1, 1.0), (-1, 3.0)])
def test_a_triangle_wave_fires_once_per_crossing_and_rearms(direction, first):
    """The triangle wave crosses 0 upwards at t = 1 + 4k and downwards at 3 + 4k, each time sampled exactly on the
    zero, then beyond it; between two crossings it goes strictly to the other side (the guard re-arms).  Before
    the fix the sample after each zero fired again: twice the closed form's count."""
    duration = 12.0
    run = simulate_sampled(_counter(direction), CLOCK, _Measured(_triangle), (0.0,), period=PERIOD,
                           duration=duration)
    expected = _zeros(first, 4.0, duration)
    assert [e.time for e in run.events] == expected and len(expected) == 3
    assert run.final_memory["n"] == float(len(expected))
