"""Figures of a verification (:mod:`visnav.app.verification_report`): runs against their requirements.

:func:`run_figure`
    One run (an :class:`analysis.stl.SignalTrace`) with one panel per
    requirement: what the requirement compares, over time, with its thresholds
    (:func:`compared_quantities`: every comparison of the formula with a
    constant is a quantity and a dashed threshold line of the same colour; in
    a comparison of two expressions the right side is the bound, a dashed line
    where it is constant on the run, a dashed curve where not), a label the
    requirement reads as a step line when it compares no number, the modes
    shaded (one colour per mode, thin lines at the jumps), and the instant that
    decides the robustness marked (red and solid on a counterexample: the
    violation instant; grey and dotted on a run that satisfies it).
:func:`robustness_history_figure`
    The lowest robustness seen against the number of simulations, one line per
    requirement (symmetric-log axis when the values span decades or signs).

:func:`orbit_figure`
    A periodic orbit (:class:`analysis.periodic.PeriodicOrbit`): the states over one period with the
    modes shaded, the orbit in the plane of its first two states, and the Floquet multipliers against
    the unit circle.

Rendering code only (Agg backend, nothing shown); the caller writes the figures.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from analysis.stl import Formula, SignalTrace, TraceError  # noqa: E402
from analysis.stl.syntax import BinOp, Compare, Func, Neg, Num, canonical  # noqa: E402

__all__ = ["Quantity", "RequirementPanel", "compared_quantities", "expression_values", "run_figure",
           "robustness_history_figure", "orbit_figure"]

MAX_QUANTITIES = 6
"""Quantities drawn per panel (the deciding atom's first)."""
MAX_MODE_LEGEND = 8
"""Modes named in the legend (beyond it the shading stays, unnamed)."""
PANELS_PER_FIGURE = 8
"""Requirement panels per run figure (callers page longer lists)."""
SYMLOG_DECADES = 6
"""Decades a symmetric-log robustness axis spans at most."""
OFF_SCALE = 1e4
"""A value this many times beyond a panel's largest threshold (and 1) is off scale (a sentinel)."""
LEGEND_ROWS = 18
"""Legend rows of the robustness figure before a new column."""
_LABEL_CHARS = 48


@dataclass(frozen=True, slots=True)
class Quantity:
    """An expression a formula compares, and what it is compared with.

    Attributes
    ----------
    text : str
        Canonical text of the expression.
    expression : object
        Its syntax tree (:mod:`analysis.stl.syntax`).
    thresholds : tuple of float
        The constants it is compared with, sorted.
    bounds : tuple of object
        The expressions it is compared with (the right-hand sides of ``x <= limit``): a
        threshold line where they are constant on a run, a dashed curve where they vary.
    atoms : tuple of str
        Canonical text of the comparisons it comes from.
    """

    text: str
    expression: object
    thresholds: tuple[float, ...]
    bounds: tuple[object, ...]
    atoms: tuple[str, ...]


@dataclass(frozen=True, kw_only=True, slots=True)
class RequirementPanel:
    """One requirement to draw on a run: its formula and the instant that decides it.

    ``time`` and ``atom`` default to the formula's :meth:`~analysis.stl.Formula.explain` on the run.
    """

    name: str
    formula: Formula
    violated: bool
    time: float | None = None
    atom: str | None = None


def _constant(expr: object) -> float | None:
    """The value of an expression made of numbers only, else ``None``."""
    match expr:
        case Num(value):
            return float(value)
        case Neg(arg):
            value = _constant(arg)
            return None if value is None else -value
        case BinOp(op, left, right):
            a, b = _constant(left), _constant(right)
            if a is None or b is None or (op == "/" and b == 0):
                return None
            return {"+": a + b, "-": a - b, "*": a * b, "/": a / b if b else math.nan}[op]
        case Func(name, args) if name in ("abs", "min", "max"):
            values = [_constant(a) for a in args]
            if any(v is None for v in values):
                return None
            return {"abs": lambda v: abs(v[0]), "min": min, "max": max}[name](values)
    return None


def _compares(node: object) -> list[Compare]:
    """Every comparison atom of a syntax tree, in reading order."""
    if isinstance(node, Compare):
        return [node]
    out: list[Compare] = []
    for name in getattr(node, "__dataclass_fields__", ()):
        child = getattr(node, name)
        for item in child if isinstance(child, tuple) else (child,):
            if hasattr(item, "__dataclass_fields__"):
                out += _compares(item)
    return out


def compared_quantities(formula: Formula) -> tuple[Quantity, ...]:
    """What ``formula`` compares: one :class:`Quantity` per distinct expression, in reading order.

    ``abs(T - 20) <= 1.5`` gives ``abs((T - 20))`` with threshold 1.5; ``-1 <= x <= 1`` gives ``x``
    with thresholds -1 and 1; ``abs(v) <= v_max`` gives ``abs(v)`` bounded by the expression
    ``v_max`` (the left side is the quantity when neither side is a number); label atoms
    (``mode == "on"``) give none.
    """
    found: dict[str, tuple[object, set[float], dict[str, object], list[str]]] = {}
    for atom in _compares(formula.tree):
        left, right = _constant(atom.left), _constant(atom.right)
        if left is not None and right is not None:
            continue
        expr = atom.right if left is not None else atom.left
        entry = found.setdefault(canonical(expr), (expr, set(), {}, []))
        if left is not None or right is not None:
            entry[1].add(left if left is not None else right)
        else:
            entry[2].setdefault(canonical(atom.right), atom.right)
        entry[3].append(canonical(atom))
    return tuple(Quantity(text=text, expression=expr, thresholds=tuple(sorted(ts)), bounds=tuple(bounds.values()),
                          atoms=tuple(atoms))
                 for text, (expr, ts, bounds, atoms) in found.items())


def expression_values(expression: object, trace: SignalTrace) -> np.ndarray | None:
    """An expression's values on ``trace``, shape (n,); ``None`` where it is not finite (a division by zero)."""
    try:
        # the robustness of ``e >= 0`` is ``e`` itself: the formula's own evaluator, no second one here
        return Formula(Compare(">=", expression, Num(0.0))).robustness_signal(trace)
    except TraceError:
        return None


def _short(text: str) -> str:
    text = " ".join(text.split())
    return text if len(text) <= _LABEL_CHARS else text[:_LABEL_CHARS - 1] + "…"


def _mode_label(trace: SignalTrace, formula: Formula) -> str | None:
    if "mode" in trace.label_names:
        return "mode"
    read = sorted(formula.labels)
    return read[0] if read else (trace.label_names[0] if trace.label_names else None)


def _x_axis(trace: SignalTrace) -> tuple[np.ndarray, bool]:
    """The abscissa of every sample: its time, or its index when every sample is at one instant (a jump chain)."""
    if trace.n > 1 and float(trace.times[-1]) <= float(trace.times[0]):
        return np.arange(trace.n, dtype=float), True
    return trace.times, False


def _mode_colours(names: Sequence[str]) -> dict[str, tuple[float, ...]]:
    colours = plt.get_cmap("tab10").colors
    return {name: colours[i % len(colours)] for i, name in enumerate(names)}


def _shade_modes(ax: plt.Axes, trace: SignalTrace, x: np.ndarray, label: str | None) -> list[Patch]:
    """One background colour per value of ``label`` over its segments, thin lines at the jumps; legend patches."""
    for k in np.flatnonzero(np.diff(trace.jumps) > 0) + 1:
        ax.axvline(float(x[k]), color="0.55", lw=0.4, zorder=0)
    if label is None:
        return []
    values = trace.label(label)
    colours = _mode_colours(sorted(set(values)))
    start = 0
    for k in range(1, len(values) + 1):
        if k == len(values) or values[k] != values[start]:
            end = float(x[min(k, len(values) - 1)])
            if end > x[start]:
                ax.axvspan(float(x[start]), end, color=colours[values[start]], alpha=0.13, lw=0, zorder=0)
            start = k
    return [Patch(color=c, alpha=0.35, label=f"{label} {n}") for n, c in colours.items()]


def _label_step(ax: plt.Axes, trace: SignalTrace, x: np.ndarray, label: str) -> None:
    values = trace.label(label)
    names = sorted(set(values))
    ax.step(x, [names.index(v) for v in values], where="post", color="k", lw=1.0, label=label)
    if len(names) <= 12:
        ax.set_yticks(range(len(names)), names, fontsize=7)


def _limit_off_scale(ax: plt.Axes, values: list[np.ndarray], thresholds: list[float]) -> None:
    """Keep the y-axis on the thresholds' scale when some values are :data:`OFF_SCALE` times beyond it.

    A sentinel such as 1e9 for "no occluder in view" would otherwise flatten every other curve;
    the axis says what it leaves out.
    """
    scale = max([1.0, *(abs(t) for t in thresholds)])
    finite = np.concatenate([v[np.isfinite(v)] for v in values]) if values else np.empty(0)
    off = np.abs(finite) > OFF_SCALE * scale
    if not off.any():
        return
    kept = np.concatenate((finite[~off], np.asarray(thresholds, dtype=float)))
    low, high = (float(kept.min()), float(kept.max())) if kept.size else (-scale, scale)
    pad = 0.08 * (high - low or scale)
    ax.set_ylim(low - pad, high + pad)
    ax.text(0.01, 0.97, f"off scale, not drawn: values up to {float(np.abs(finite).max()):.3g}",
            transform=ax.transAxes, fontsize=6.5, va="top", color="0.3")


def _quantities(ax: plt.Axes, trace: SignalTrace, x: np.ndarray, formula: Formula, atom: str) -> int:
    """Draw what the formula compares (the deciding atom's quantity first) and its thresholds; how many."""
    quantities = sorted(compared_quantities(formula), key=lambda q: atom.strip() not in q.atoms)[:MAX_QUANTITIES]
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    drawn: list[np.ndarray] = []
    levels: list[float] = []
    for i, q in enumerate(quantities):
        values = expression_values(q.expression, trace)
        if values is None:
            continue
        colour = colours[i % len(colours)]
        ax.plot(x, values, color=colour, lw=1.1, label=_short(q.text))
        levels += q.thresholds
        for threshold in q.thresholds:
            ax.axhline(threshold, color=colour, lw=0.9, ls="--")
        for bound in q.bounds:
            limit = expression_values(bound, trace)
            if limit is None:
                continue
            if np.ptp(limit) == 0:
                ax.axhline(float(limit[0]), color=colour, lw=0.9, ls="--")
                levels.append(float(limit[0]))
            else:
                ax.plot(x, limit, color=colour, lw=0.9, ls="--", label=_short(canonical(bound)))
                drawn.append(limit)
        drawn.append(values)
    _limit_off_scale(ax, drawn, levels)
    return len(drawn)


def _panel(ax: plt.Axes, trace: SignalTrace, panel: RequirementPanel) -> list[Patch]:
    formula = panel.formula
    x, by_index = _x_axis(trace)
    why = formula.explain(trace)
    time = why.time if panel.time is None else panel.time
    atom = why.atom if panel.atom is None else panel.atom
    patches = _shade_modes(ax, trace, x, _mode_label(trace, formula))
    if not _quantities(ax, trace, x, formula, atom) and formula.labels:
        _label_step(ax, trace, x, sorted(formula.labels)[0])
    where = float(x[why.index]) if by_index else time
    text = f"at t = {time:.4g} s" + (f" (sample {why.index})" if by_index else "") + f": {_short(atom)}"
    if panel.violated:  # an eventually's instant is where it came closest, not where it is violated
        said = "violated" if why.window is None else (
            f"never reached within [{why.window[0]:.4g}, {why.window[1]:.4g}] s; closest")
        ax.axvline(where, color="tab:red", lw=1.6, label=f"{said} {text}")
    else:
        ax.axvline(where, color="0.35", lw=1.0, ls=":", label=f"decided {text}")
    rho = float(formula.robustness(trace)) + 0.0  # no "-0"
    ax.set_title(f"{panel.name}: robustness {rho:.4g}" + (" — VIOLATED" if panel.violated else ""), fontsize=9)
    ax.legend(fontsize=6.5, loc="upper right", framealpha=0.8)
    ax.grid(True, lw=0.3)
    return patches


def run_figure(trace: SignalTrace, panels: Sequence[RequirementPanel], *, title: str) -> Figure:
    """One run against requirements: a panel each (module docstring), in two columns beyond four."""
    columns = 2 if len(panels) > 4 else 1
    rows = -(-len(panels) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(8 * columns, 1.4 + 2.1 * rows), sharex=True, squeeze=False)
    patches: list[Patch] = []
    for ax, panel in zip(axes.flat, panels):
        patches = _panel(ax, trace, panel) or patches
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    by_index = _x_axis(trace)[1]
    for ax in axes[-1]:
        ax.set_xlabel((f"sample (all at t = {float(trace.times[0]):.4g} s: a chain of jumps)" if by_index
                       else "t [s]") + "  (shaded: modes; thin lines: jumps; dashed: thresholds)")
        ax.xaxis.set_tick_params(labelbottom=True)
    fig.suptitle(title, fontsize=10)
    height = fig.get_figheight()
    top = 1.0 - 0.3 / height  # room for the title
    if 0 < len(patches) <= MAX_MODE_LEGEND:
        fig.legend(handles=patches, loc="upper center", bbox_to_anchor=(0.5, 0.985 - 0.35 / height),
                   ncol=min(len(patches), 4), fontsize=6.5, frameon=False)
        top = 1.0 - 0.55 / height
    fig.tight_layout(rect=(0, 0, 1, top))
    return fig


def _needs_symlog(values: np.ndarray) -> float | None:
    """A linear threshold for a symmetric-log axis when finite ``values`` span decades or both signs.

    At most :data:`SYMLOG_DECADES` decades are drawn logarithmically (a robustness of 1e-18 next to
    one of 1 would otherwise take the whole axis).
    """
    finite = np.abs(values[np.isfinite(values)])
    nonzero = finite[finite > 0]
    if nonzero.size == 0:
        return None
    low, high = float(nonzero.min()), float(nonzero.max())
    if high / low < 100 and not (np.any(values[np.isfinite(values)] < 0) and high / low >= 10):
        return None
    return 10.0 ** math.floor(math.log10(max(low, high * 10.0 ** -SYMLOG_DECADES)))


def robustness_history_figure(histories: Mapping[str, Sequence[float]], *, title: str) -> Figure:
    """The running minimum of each requirement's robustness against the simulations (infinite values not drawn).

    Beyond ten requirements the legend goes to the right of the axes, in columns of :data:`LEGEND_ROWS`.
    """
    many = len(histories) > 10
    columns = -(-len(histories) // LEGEND_ROWS) if many else 1
    height = max(3.6, 0.17 * min(len(histories), LEGEND_ROWS) + 1.2) if many else 3.6
    fig, ax = plt.subplots(figsize=(8 + (2.8 * columns if many else 0), height))
    everything = []
    for name, history in histories.items():
        y = np.asarray([float(v) for v in history], dtype=float)
        x = np.arange(1, y.size + 1)
        note = ""
        if np.any(np.isneginf(y)):
            note = f" (−∞ from simulation {int(np.argmax(np.isneginf(y))) + 1})"
        elif y.size and np.all(np.isposinf(y)):
            note = " (+∞: only label atoms, never violated)"
        ax.step(x, np.where(np.isfinite(y), y, np.nan), where="post", lw=1.3, label=_short(name) + note)
        everything.append(y)
    ax.axhline(0.0, color="tab:red", lw=0.8, ls="--", label="0: violation below")
    linthresh = _needs_symlog(np.concatenate(everything)) if everything else None
    if linthresh is not None:
        ax.set_yscale("symlog", linthresh=linthresh)
    ax.set_xlabel("simulations")
    ax.set_ylabel("lowest robustness so far")
    ax.set_title(title, fontsize=10)
    if many:
        ax.legend(fontsize=6.5, loc="upper left", bbox_to_anchor=(1.01, 1.0), ncol=columns, frameon=False)
    else:
        ax.legend(fontsize=7, loc="best")
    ax.grid(True, lw=0.3)
    fig.tight_layout()
    return fig


def orbit_figure(orbit: object) -> Figure:
    """One revolution of a periodic orbit: states against time, phase plane, Floquet multipliers."""
    times = np.asarray(orbit.times, dtype=float)
    states = np.asarray(orbit.states, dtype=float).reshape(times.size, -1)
    names = tuple(orbit.state_names)
    modes = list(orbit.modes)
    plane = states.shape[1] >= 2
    fig, axes = plt.subplots(1, 3 if plane else 2, figsize=(12 if plane else 9, 3.6))
    ax = axes[0]
    colours = _mode_colours(sorted(set(modes)))
    start = 0
    for k in range(1, len(modes) + 1):
        if k == len(modes) or modes[k] != modes[start]:
            ax.axvspan(times[start], times[k - 1], color=colours[modes[start]], alpha=0.15, lw=0)
            start = k
    for j, name in enumerate(names):
        ax.plot(times, states[:, j], lw=1.2, label=name)
    ax.set_xlabel("time in the revolution [s]")
    ax.set_title(f"period {orbit.period:.6g} s")
    ax.legend(handles=[*ax.get_legend_handles_labels()[0],
                       *(Patch(color=c, alpha=0.3, label=m) for m, c in colours.items())], fontsize=7)
    if plane:
        axes[1].plot(states[:, 0], states[:, 1], lw=1.2)
        axes[1].plot(states[0, 0], states[0, 1], "ko", ms=4)
        axes[1].set_xlabel(names[0])
        axes[1].set_ylabel(names[1])
        axes[1].set_title("orbit (dot: on the section)")
    ax = axes[-1]
    circle = np.linspace(0.0, 2.0 * math.pi, 200)
    ax.plot(np.cos(circle), np.sin(circle), color="0.6", lw=0.8)
    mult = np.asarray([complex(*m) if isinstance(m, (tuple, list)) else complex(m) for m in orbit.multipliers])
    ax.plot(mult.real, mult.imag, "x", color="tab:red", ms=7)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"Floquet multipliers: {orbit.verdict}")
    fig.tight_layout()
    return fig
