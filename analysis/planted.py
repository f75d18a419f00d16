"""Planted-bug verification problems with known violating regions: the fixtures of the falsification tests
and of ``benchmarks/bench_fals.py``.

Each problem's violating share of the box is known in closed form (:data:`VIOLATING_FRACTION`), so a
search's simulations to its first violation can be judged against Monte-Carlo's exactly: Monte-Carlo's
count is geometric with that share as its parameter.

``line-corner``
    ``x(t) = a + b t`` on ``t ∈ [0, 1]``, ``a, b`` uniform on ``[-1, 1]`` (nominal ``a = 0.5``);
    ``always (x >= -0.9)`` fails where ``a + min(b, 0) < -0.9``.
``line-well``
    the same line, ``always (x > -1.97)``: fails in the narrow corner ``a + min(b, 0) < -1.97``.
``ramp-late``
    ``x(t) = p t`` with ``p`` the product of four parameters' departures: a violation that needs every
    coordinate at its upper end (``always (x < 0.7)`` fails where ``∏ u_i > 0.7`` with ``u_i`` uniform
    on [0, 1]).

The examples' planted bugs (``examples/acc.py``, ``examples/thermostat.py``'s zero band) are loaded by
the tests and the benchmark from their files.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verification import Parameter, VerificationProblem

__all__ = ["VIOLATING_FRACTION", "line_problem", "ramp_problem", "planted_problems"]

_T = np.linspace(0.0, 1.0, 21)


def _corner_share(c: float) -> float:
    """Share of ``(a, b) ∈ [-1, 1]²`` (uniform) with ``a + min(b, 0) < c``: ``b >= 0`` gives ``a < c``, ``b < 0``
    gives ``a + b < c``, integrated in closed form."""
    def pos(y: float) -> float:  # P(a < y) for a uniform on [-1, 1]
        return min(1.0, max(0.0, (y + 1.0) / 2.0))

    def neg(y: float) -> float:  # P(a + b < y) for a on [-1, 1], b on [-1, 0]: area / 2
        # a + b ranges over [-2, 1]; area of {a + b < y} in the rectangle [-1, 1] x [-1, 0]
        s = y + 2.0  # distance above the lowest corner
        if s <= 0:
            return 0.0
        if s <= 1:
            return s * s / 2.0 / 2.0
        if s <= 2:
            return (0.5 + (s - 1.0)) / 2.0
        return (2.0 - (3.0 - s) ** 2 / 2.0) / 2.0 if s < 3 else 1.0

    return 0.5 * pos(c) + 0.5 * neg(c)


def _ramp_share(c: float, k: int = 4) -> float:
    """``P(∏ u_i > c)`` for ``k`` independent uniforms on [0, 1]: ``1 - c Σ_{j<k} (-ln c)^j / j!``."""
    s = sum((-math.log(c)) ** j / math.factorial(j) for j in range(k))
    return 1.0 - c * s


VIOLATING_FRACTION: Mapping[str, float] = {"line-corner": _corner_share(-0.9), "line-well": _corner_share(-1.97),
                                           "ramp-late": 0.5 * _ramp_share(0.7)}
"""Violating share of each problem's box (Monte-Carlo's draws are uniform on it), closed form."""


class _Line:
    def __call__(self, p: Mapping[str, float]) -> SignalTrace:
        return SignalTrace(times=_T, signals={"x": p["a"] + p["b"] * _T})


class _Ramp:
    def __call__(self, p: Mapping[str, float]) -> SignalTrace:
        prod = p["u1"] * p["u2"] * p["u3"] * p["u4"]
        return SignalTrace(times=_T, signals={"x": prod * _T})


def line_problem(threshold: float, name: str) -> VerificationProblem:
    """``x = a + b t`` must stay ``>= threshold`` (``>`` for the well)."""
    params = (Parameter(name="a", low=-1.0, high=1.0, nominal=0.5), Parameter(name="b", low=-1.0, high=1.0, nominal=0.0))
    return VerificationProblem(name=name, simulate=_Line(), parameters=params, horizon=1.0, signals=("x",),
                               requirements=(Requirement(name="low", formula=f"always[0, 1] (x > {threshold!r})"),))


def ramp_problem() -> VerificationProblem:
    """``x = u1 u2 u3 u4 t`` with each ``u_i`` on ``[-1, 1]`` (nominal 0) must stay below 0.7: only the
    orthant where every ``u_i`` has one sign, near its vertex, fails (an odd count of negatives makes
    the product negative: half the orthants can fail, each only near its vertex)."""
    params = tuple(Parameter(name=f"u{i}", low=-1.0, high=1.0, nominal=0.0) for i in range(1, 5))
    return VerificationProblem(name="ramp-late", simulate=_Ramp(), parameters=params, horizon=1.0, signals=("x",),
                               requirements=(Requirement(name="below", formula="always[0, 1] (x < 0.7)"),))


def planted_problems() -> dict[str, VerificationProblem]:
    """The closed-form planted problems keyed by name."""
    return {"line-corner": line_problem(-0.9, "line-corner"), "line-well": line_problem(-1.97, "line-well"),
            "ramp-late": ramp_problem()}
