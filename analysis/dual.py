"""Forward-mode automatic differentiation with dual numbers: a model's own float code, run on :class:`Dual`
values, computes the derivatives of its results alongside them.

A :class:`Dual` is ``value + grad · ε`` (``ε² = 0``): ``value`` a float, ``grad`` a numpy vector of the
derivatives with respect to ``k`` seeded variables (:func:`variables`).  Arithmetic (``+ - * /``, ``**`` by a
constant, unary ``-``, :func:`abs`) propagates the gradient by the chain rule; comparisons compare the values
only, so a model's discrete decisions (a table segment chosen by :func:`bisect.bisect_right`, a ``min``/``max``
clamp, a mode switch) follow the float run, and the derivative is that of the branch taken (exact for a fixed
discrete path; at a tie, the one-sided derivative of the branch the float code takes).  The values are
bit-identical to the float run: each operation performs the same IEEE operation on the values (``a * b`` and
``b * a`` alike, both commutative).

``float(dual)`` raises :class:`TypeError`: a library call that would silently drop the derivative (``math.exp``
on a dual) fails loudly; use :func:`exp`, :func:`expm1`, :func:`sqrt` of this module, which take floats too.

Examples
--------
>>> x, y = variables([2.0, 3.0])
>>> z = x * y + x ** 2
>>> z.value, z.grad.tolist()
(10.0, [7.0, 2.0])
>>> values, grads = split([z, 1.5], 2)
>>> values.tolist(), grads.tolist()
([10.0, 1.5], [[7.0, 2.0], [0.0, 0.0]])
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["Dual", "variables", "seeded", "split", "value_of", "exp", "expm1", "sqrt"]


class Dual:
    """A value and its gradient with respect to the seeded variables.

    Attributes
    ----------
    value : float
    grad : numpy.ndarray, shape (k,)
        Derivatives of ``value`` with respect to the ``k`` variables.
    """

    __slots__ = ("value", "grad")

    def __init__(self, value: float, grad: np.ndarray) -> None:
        self.value = value
        self.grad = grad

    def __repr__(self) -> str:
        return f"Dual({self.value!r}, {self.grad.tolist()!r})"

    def __add__(self, other: object) -> Dual:
        if isinstance(other, Dual):
            return Dual(self.value + other.value, self.grad + other.grad)
        return Dual(self.value + other, self.grad)

    def __radd__(self, other: object) -> Dual:
        return Dual(other + self.value, self.grad)

    def __sub__(self, other: object) -> Dual:
        if isinstance(other, Dual):
            return Dual(self.value - other.value, self.grad - other.grad)
        return Dual(self.value - other, self.grad)

    def __rsub__(self, other: object) -> Dual:
        return Dual(other - self.value, -self.grad)

    def __mul__(self, other: object) -> Dual:
        if isinstance(other, Dual):
            return Dual(self.value * other.value, other.value * self.grad + self.value * other.grad)
        return Dual(self.value * other, other * self.grad)

    def __rmul__(self, other: object) -> Dual:
        return Dual(other * self.value, other * self.grad)

    def __truediv__(self, other: object) -> Dual:
        if isinstance(other, Dual):
            q = self.value / other.value
            return Dual(q, (self.grad - q * other.grad) / other.value)
        return Dual(self.value / other, self.grad / other)

    def __rtruediv__(self, other: object) -> Dual:
        q = other / self.value
        return Dual(q, (-q / self.value) * self.grad)

    def __pow__(self, exponent: object) -> Dual:
        if isinstance(exponent, Dual):
            raise TypeError("Dual ** Dual is not supported: write exp(b * log(a)) explicitly")
        return Dual(self.value ** exponent, (exponent * self.value ** (exponent - 1)) * self.grad)

    def __neg__(self) -> Dual:
        return Dual(-self.value, -self.grad)

    def __pos__(self) -> Dual:
        return self

    def __abs__(self) -> Dual:
        return Dual(abs(self.value), (1.0 if self.value >= 0 else -1.0) * self.grad)

    def __lt__(self, other: object) -> bool:
        return self.value < value_of(other)

    def __le__(self, other: object) -> bool:
        return self.value <= value_of(other)

    def __gt__(self, other: object) -> bool:
        return self.value > value_of(other)

    def __ge__(self, other: object) -> bool:
        return self.value >= value_of(other)

    def __bool__(self) -> bool:
        return self.value != 0

    def __float__(self) -> float:
        raise TypeError("float() of a Dual would drop its derivative: use analysis.dual.value_of(x) for the value, "
                        "or analysis.dual.exp/expm1/sqrt in place of math's")

    __hash__ = None  # type: ignore[assignment]


def value_of(x: object) -> float:
    """The value of a dual, or ``x`` itself."""
    return x.value if isinstance(x, Dual) else x  # type: ignore[return-value]


def variables(values: Sequence[float], k: int | None = None, offset: int = 0) -> list[Dual]:
    """Duals for ``values``, the ``i``-th seeded with the unit vector ``offset + i`` of length ``k`` (default
    ``len(values)``)."""
    k = len(values) if k is None else k
    out = []
    for i, v in enumerate(values):
        grad = np.zeros(k)
        grad[offset + i] = 1.0
        out.append(Dual(float(v), grad))
    return out


def seeded(value: float, index: int, k: int) -> Dual:
    """One dual: ``value`` with the unit gradient ``index`` of length ``k``."""
    grad = np.zeros(k)
    grad[index] = 1.0
    return Dual(float(value), grad)


def split(items: Sequence[object] | np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Values, shape ``(n,)``, and gradients, shape ``(n, k)``, of a sequence of duals and floats (a float has a
    zero gradient)."""
    n = len(items)
    values, grads = np.empty(n), np.zeros((n, k))
    for i, x in enumerate(items):
        if isinstance(x, Dual):
            values[i], grads[i] = x.value, x.grad
        else:
            values[i] = x
    return values, grads


def exp(x: object) -> object:
    """``e**x`` of a float or a dual."""
    if isinstance(x, Dual):
        e = math.exp(x.value)
        return Dual(e, e * x.grad)
    return math.exp(x)  # type: ignore[arg-type]


def expm1(x: object) -> object:
    """``e**x - 1`` of a float or a dual (accurate for small ``x``)."""
    if isinstance(x, Dual):
        return Dual(math.expm1(x.value), math.exp(x.value) * x.grad)
    return math.expm1(x)  # type: ignore[arg-type]


def sqrt(x: object) -> object:
    """Square root of a float or a dual."""
    if isinstance(x, Dual):
        r = math.sqrt(x.value)
        return Dual(r, x.grad / (2.0 * r))
    return math.sqrt(x)  # type: ignore[arg-type]
