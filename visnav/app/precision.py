"""The report's rounding policy: every number printed with the digits its computation supports.

A report (``report.json``, ``report.md``, ``report.html``, the figures) must be the same bytes on
every x86-64 machine with the pinned dependency set.  The raw numbers are not: another CPU takes
other SIMD paths in numpy's transcendental functions and other OpenBLAS kernels, and an adaptive
integrator or an interior-point solver turns a last-bit difference into a difference at its own
tolerance.  So every number of a report is rounded, once, here, to what its computation can defend,
and the documents are rendered from the rounded data only.

The policy is a table of **kinds** (:data:`KINDS`: significant digits, an absolute resolution,
a floor and a direction, each with why) and of **rules** (:data:`RULES`: which leaves of the
report's data are of which kind, by their path ``section/key/key``; the first matching rule wins,
list positions are not part of the path).  ``docs/report.md`` lists the kinds and their reasons.

Rounding is decimal and deterministic (:func:`round_value`): the float's shortest representation
(``repr``, correctly rounded on every platform) is rounded in :mod:`decimal` with an explicit
direction, so the same float gives the same digits everywhere.  Bounds proven by interval
arithmetic are rounded **outward** (an upper bound up, a lower bound down): the printed bound is
never less safe than the proven one.  Round-off-level quantities (residuals, errors under the
reference's accuracy) are printed as their floor, read "at most".

Figures are drawn from rounded data too (:func:`quantise_for_figure`: values to
:data:`FIGURE_DIGITS` significant digits, far below a pixel), so that a last-bit difference does
not move an antialiased edge.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from decimal import ROUND_CEILING, ROUND_FLOOR, ROUND_HALF_EVEN, Decimal
from typing import Any

import numpy as np

__all__ = [
    "Precision",
    "KINDS",
    "RULES",
    "TEXT_RULES",
    "FIGURE_DIGITS",
    "ROUNDOFF_FLOOR",
    "ACCURACY_FLOOR",
    "kind_of",
    "precision_of",
    "round_value",
    "round_tree",
    "round_section",
    "number_text",
    "round_numbers_in_text",
    "quantise_for_figure",
]

_DIRECTIONS = {"nearest": ROUND_HALF_EVEN, "up": ROUND_CEILING, "down": ROUND_FLOOR}


@dataclass(frozen=True, kw_only=True, slots=True)
class Precision:
    """How one kind of number is printed.

    Attributes
    ----------
    kind : str
    digits : int or None
        Significant digits kept; ``None``: the value is kept bit for bit (a counterexample to replay).
    resolution : float
        Absolute resolution (same unit as the value): the rounding step is the larger of the
        significant-digit step and this; ``0``: none.
    floor : float
        A value of magnitude at most ``floor`` is printed as ``floor`` (read "at most ``floor``": a
        round-off-level residual or error); ``0``: none.
    direction : {"nearest", "up", "down"}
        ``up`` for a proven upper bound, ``down`` for a proven lower bound (outward), else ``nearest``
        (half to even).
    why : str
        What in the computation sets these digits.
    """

    kind: str
    digits: int | None
    why: str
    resolution: float = 0.0
    floor: float = 0.0
    direction: str = "nearest"

    def __post_init__(self) -> None:
        if self.direction not in _DIRECTIONS:
            raise ValueError(f"Precision.direction = {self.direction!r}; expected one of {', '.join(_DIRECTIONS)}")
        if self.digits is not None and (isinstance(self.digits, bool) or not isinstance(self.digits, int)
                                        or self.digits < 1):
            raise ValueError(f"Precision.digits = {self.digits!r}; expected a whole number >= 1 or None")
        if not (self.resolution >= 0.0 and self.floor >= 0.0):
            raise ValueError(f"Precision {self.kind}: resolution {self.resolution!r} and floor {self.floor!r} "
                             "must be >= 0")


ROUNDOFF_FLOOR = 1e-12
"""Residuals of exact identities computed in double precision (closure of a closed form, a Lyapunov
equation, an equilibrium): O(1e-16 × the matrices' norms, <= 100) — printed as at most this."""

ACCURACY_FLOOR = 1e-11
"""Errors of the stiffness study's integrations against its Radau reference, dimensionless
(``max(|dX|, |dY|, |dz|/z)``): the two references agree to 4e-13, and an adaptive reference moves by
its tolerance (1e-13) between machines; :data:`visnav.studies.stiffness.ORDER_FIT_FLOOR` (1e-11) is
where the study stops fitting orders.  Below it an error is round-off."""

FOCAL_PX = 1000.0
"""The camera's focal length [px] that turns a normalised error into pixels (the paper camera)."""
MAX_DEPTH_MM = 1.0e4
"""Largest depth of the reconstruction [mm] (10 m) that turns a relative depth error into millimetres."""

KINDS: dict[str, Precision] = {p.kind: p for p in (
    Precision(kind="replay", digits=None,
              why="a counterexample or witness that `visnav replay` re-runs: drawn by a seeded generator (no "
                  "round-off) and possibly shrunk onto a boundary, so kept bit for bit"),
    Precision(kind="input", digits=12,
              why="a value given to the computation (scenario parameters, settings, box bounds, points drawn from "
                  "the box, gain grids from np.logspace): at most a last-bit difference (measured 1.5e-16 relative "
                  "between SIMD paths); 12 digits print a given decimal exactly"),
    Precision(kind="search_point", digits=6,
              why="a point a guided search moved to (where the lowest robustness was): its moves follow robustness "
                  "values, so their round-off reaches the coordinates (measured 1.7e-10 relative between libm "
                  "variants); 6 digits (a counterexample file keeps its unit coordinates bit for bit for replay)"),
    Precision(kind="time", digits=15, resolution=1e-9,
              why="an instant [s]: sample instants are sums of T_e (error <= 1e-13 s) and events are located to "
                  "event_tol = 1e-12 s; printed to 1 ns"),
    Precision(kind="simulation", digits=6,
              why="a simulation output (state, clearance, robustness of a trace): exact arcs between samples and a "
                  "Newton estimator at 1e-12, so round-off accumulates to <= 1e-10 relative over a run; 6 digits "
                  "keep a factor 1e4 above it"),
    Precision(kind="error_px", digits=6, resolution=FOCAL_PX * ACCURACY_FLOOR,
              why="a reconstruction error [px]: the difference of two integrations, each accurate to ACCURACY_FLOOR "
                  "(1e-11) in normalised coordinates, i.e. 1e-8 px at f = 1000 px: printed to 1e-8 px"),
    Precision(kind="error_mm", digits=6, resolution=MAX_DEPTH_MM * ACCURACY_FLOOR,
              why="a depth reconstruction error [mm]: relative depth accurate to ACCURACY_FLOOR (1e-11) at depths "
                  "<= 10 m, i.e. 1e-7 mm: printed to 1e-7 mm"),
    Precision(kind="truncation_px", digits=2, resolution=FOCAL_PX * ACCURACY_FLOOR, floor=FOCAL_PX * ACCURACY_FLOOR,
              why="a truncation error [px] (scheme against the reference): 2 significant digits; below 1e-8 px it is "
                  "round-off of the reference (measured: up to 6 % between machines) and printed as 1e-8 (at most)"),
    Precision(kind="truncation_mm", digits=2, resolution=MAX_DEPTH_MM * ACCURACY_FLOOR,
              floor=MAX_DEPTH_MM * ACCURACY_FLOOR,
              why="a depth truncation error [mm]: 2 significant digits, 1e-7 mm (at most) below the reference's "
                  "accuracy"),
    Precision(kind="accuracy_error", digits=2, resolution=ACCURACY_FLOOR, floor=ACCURACY_FLOOR,
              why="an integration error against a reference (dimensionless): 2 significant digits; at most "
                  "ACCURACY_FLOOR (1e-11) below the references' agreement"),
    Precision(kind="order", digits=2,
              why="an observed order of convergence: the slope of log errors, errors accurate to ~1 % near the "
                  "fit floor, so the slope to ~0.01: 2 significant digits"),
    Precision(kind="linear_algebra", digits=8, resolution=1e-10,
              why="eigenvalues, eigenvectors, Jacobians and Lyapunov-equation solutions of matrices of norm <= 100 "
                  "from LAPACK (backward stable: absolute errors ~1e-14): 8 digits, and 1e-10 absolute (a zero "
                  "computed as 1e-15 prints as 0)"),
    Precision(kind="margin", digits=6, resolution=1e-12,
              why="a stability margin or crossover frequency: brentq to rtol 1e-15 on a frequency response whose "
                  "evaluation carries ~1e-14 relative round-off (measured: 3e-15 between machines); 6 digits"),
    Precision(kind="sdp", digits=4,
              why="a result of a semidefinite program (SOS or LMI: Clarabel/SCS at tolerances 1e-8 to 1e-9): "
                  "its solution is unique only to ~1e-8 relative (measured: 4e-8 on the SOS coefficients between "
                  "machines), and so is everything computed from it: 4 significant digits"),
    Precision(kind="bound_up", digits=4, direction="up",
              why="an upper bound proven by interval branch and bound on an SDP-derived function: 4 significant "
                  "digits (the SDP's), rounded up: never below the proven bound"),
    Precision(kind="bound_down", digits=4, direction="down",
              why="a lower bound proven by interval branch and bound on an SDP-derived function: 4 significant "
                  "digits, rounded down: never above the proven bound"),
    Precision(kind="certified_level", digits=6, direction="down",
              why="a number in the text of an SOS claim (the level of a certified sublevel set, a box bound): the "
                  "library writes 9 digits and the SDP decides the last three (measured 0.999999969 against "
                  "0.999999973); 6 digits rounded down: a smaller level of the same certified family, box bounds "
                  "(written with 6 digits) unchanged"),
    Precision(kind="roundoff", digits=1, floor=ROUNDOFF_FLOOR, direction="up",
              why="a residual of an exact identity evaluated in floating point: round-off only; printed as at most "
                  "ROUNDOFF_FLOOR (1e-12), or rounded up to 1 significant digit above it"),
    Precision(kind="computed", digits=6,
              why="any other deterministic numerics on the model (a ratio, an angle from a boundary locus, a "
                  "closed form, a quantile of simulated values): 6 significant digits"),
)}
"""Every kind of number of a report, by name."""

RULES: tuple[tuple[str, str], ...] = (
    # --- verification (any problem) ---
    ("verification/requirements/counterexample/point*", "search_point"),
    ("verification/requirements/counterexample/unit*", "search_point"),
    ("verification/requirements/lowest_at*", "search_point"),
    ("verification/requirements/counterexample/time", "time"),
    ("verification/nominal/decided/*/time", "time"),
    ("verification/requirements/*", "simulation"),
    ("verification/nominal/decided/*", "simulation"),
    ("verification/*", "input"),
    # --- structural checks ---
    ("model/parameters/*", "input"),
    ("model/structural_checks/rates/*", "input"),
    ("model/structural_checks/*", "computed"),
    ("structure/*", "computed"),
    # --- simulation ---
    ("simulation/*reconstruction_error_px*", "error_px"),
    ("simulation/*depth_error_mm*", "error_mm"),
    ("simulation/paper_comparison/paper", "input"),
    ("simulation/metrics/transitions*", "time"),
    ("simulation/*duration_s", "time"),
    ("simulation/*_s", "time"),
    ("simulation/*", "simulation"),
    # --- analysis ---
    ("analysis/sampling_period_s", "input"),
    ("analysis/*residual*", "roundoff"),
    ("analysis/*error_vs_*", "roundoff"),
    ("analysis/eigenvalues_vs_lambda/lambda", "input"),
    ("analysis/margins_vs_gains/*/k", "input"),
    ("analysis/margins_vs_gains/*/lambda_*", "input"),
    ("analysis/path_following/eigenvalues_vs_*/k", "input"),
    ("analysis/path_following/eigenvalues_vs_*/v_coll_mps", "input"),
    ("analysis/path_following/parameters/*", "input"),
    ("analysis/path_following/lyapunov/region*", "input"),
    ("analysis/path_following/sos/bypass/*hand_closed_form*", "computed"),
    ("analysis/path_following/sos/bypass/*alpha0_rad", "input"),
    ("analysis/path_following/sos/bypass/*delta0_m", "input"),
    ("analysis/path_following/sos/bypass/*delta_entry_m", "input"),
    ("analysis/path_following/sos/bypass/k", "input"),
    ("analysis/path_following/sos/*entry_time_bound*", "bound_up"),
    ("analysis/path_following/sos/bypass/*delta_max_m", "bound_up"),
    ("analysis/path_following/sos/bypass/*omega_max_radps", "bound_up"),
    ("analysis/path_following/sos/bypass/*_certificate/bound", "bound_up"),
    ("analysis/path_following/sos/bypass/*min_distance_m", "bound_down"),
    ("analysis/path_following/sos/*omega_bound*", "bound_up"),
    # the gains k at which a certificate was sought (grid points, bisection brackets): inputs of the checks
    ("analysis/path_following/sos/*k_searched*", "input"),
    ("analysis/path_following/sos/*/k", "input"),
    ("analysis/path_following/sos/k", "input"),
    ("analysis/path_following/sos/*_k", "input"),
    ("analysis/path_following/sos/admissible/interval", "input"),
    ("analysis/path_following/sos/admissible/proven_gains", "input"),
    ("analysis/path_following/sos/admissible/*bracket*", "input"),
    ("analysis/path_following/sos/*clearance_m", "input"),
    ("analysis/path_following/sos/*d_zero_m", "input"),
    ("analysis/path_following/sos/*delta_entry_m", "input"),
    ("analysis/path_following/sos/*delta0_m", "input"),
    ("analysis/path_following/sos/*entry_angles_rad", "input"),
    ("analysis/path_following/sos/*alpha0_rad", "input"),
    ("analysis/path_following/sos/*omega_max_radps", "input"),
    ("analysis/path_following/sos/*omega_limit_radps", "input"),
    ("analysis/path_following/sos/radii_m", "input"),
    ("analysis/path_following/sos/v_mps", "input"),
    ("analysis/path_following/sos/*hand_level", "input"),
    ("analysis/path_following/sos/*/level", "certified_level"),
    ("analysis/path_following/bypass_reach/delta_bound_m", "bound_up"),
    ("analysis/path_following/bypass_reach/margin_m", "bound_down"),
    ("analysis/path_following/bypass_reach/coverage/longest_bypass_s", "time"),
    ("analysis/path_following/bypass_reach/*", "input"),
    ("analysis/path_following/sos/*", "sdp"),
    ("analysis/path_following/switched/*", "sdp"),
    ("analysis/path_following/admissible/k_searched", "input"),
    ("analysis/path_following/admissible/clearance_m", "input"),
    ("analysis/path_following/admissible/delta0_m", "input"),
    ("analysis/path_following/admissible/omega_max_radps", "input"),
    ("analysis/path_following/entry_states*", "simulation"),
    ("analysis/*eigen*", "linear_algebra"),
    ("analysis/*jacobian*", "linear_algebra"),
    ("analysis/*modes*", "linear_algebra"),
    ("analysis/*zero_mode*", "linear_algebra"),
    ("analysis/*input_matrix*", "linear_algebra"),
    ("analysis/*spectral_abscissa*", "linear_algebra"),
    ("analysis/*quadratic_lyapunov*", "linear_algebra"),
    ("analysis/*point*", "input"),
    ("analysis/*closed_form*", "computed"),
    ("analysis/margins*", "margin"),
    ("analysis/frequency_responses/*", "margin"),
    ("analysis/*", "computed"),
    # --- stiffness ---
    ("stiffness/settings/*", "input"),
    ("stiffness/scenario*", "input"),
    ("stiffness/period_s", "input"),
    ("stiffness/*rtol*", "input"),
    ("stiffness/*atol*", "input"),
    ("stiffness/*spurious_growth_per_step*", "roundoff"),
    ("stiffness/*truncation_error_px*", "truncation_px"),
    ("stiffness/*truncation_error_mm*", "truncation_mm"),
    ("stiffness/*error_px*", "error_px"),
    ("stiffness/*_px", "error_px"),
    ("stiffness/*error_mm*", "error_mm"),
    ("stiffness/*_mm", "error_mm"),
    ("stiffness/*zoh_rk4*", "error_px"),
    ("stiffness/*reconstruction_components/estimator*", "error_px"),
    ("stiffness/*observed_order*", "order"),
    ("stiffness/accuracy/*steps_s*", "input"),
    ("stiffness/accuracy/*duration_s*", "input"),
    ("stiffness/accuracy/*t0_s*", "input"),
    ("stiffness/accuracy/*error*", "accuracy_error"),
    ("stiffness/accuracy/*agreement*", "accuracy_error"),
    ("stiffness/*window*", "time"),
    ("stiffness/*", "computed"),
    # --- fuzzing, campaign ---
    ("fuzzing/*counterexamples*", "replay"),
    ("fuzzing/*", "computed"),
    ("campaign/spec/*", "input"),
    ("campaign/summary/*success*", "input"),
    ("campaign/summary/*reconstruction_error*", "error_px"),
    ("campaign/*", "simulation"),
    # --- a problem's stability analysis ---
    ("stability/*residual*", "roundoff"),
    ("stability/*period*", "time"),
    ("stability/*", "computed"),
    ("*", "computed"),
)
"""``(pattern, kind)``: the first pattern (:func:`fnmatch.fnmatchcase`, ``*`` spans ``/``) matching a leaf's
path ``section/key/...`` gives its kind (:data:`KINDS`)."""

TEXT_RULES: tuple[tuple[str, str], ...] = (
    ("analysis/path_following/sos/*lyapunov", "sdp"),
    ("analysis/path_following/sos/*claim", "certified_level"),
)
"""``(pattern, kind)`` of the text leaves whose numbers are rounded (:func:`round_numbers_in_text`): an SOS
polynomial is printed with the digits the SDP supports (4 significant digits of its largest coefficient:
a coefficient the SDP leaves at 1e-5 beside one of 16 is noise; the polynomial the interval re-check
certified has the SDP's own floats: ``visnav analyse --json``); the levels in an SOS claim rounded down."""

FIGURE_DIGITS = 6
"""Significant digits of every value a report figure plots (1e-6 of an axis: a thousandth of a pixel)."""


def kind_of(path: str, rules: tuple[tuple[str, str], ...] = RULES) -> str | None:
    """The kind of the leaf at ``path`` (``section/key/...``), or ``None`` when no rule matches."""
    for pattern, kind in rules:
        if fnmatch.fnmatchcase(path, pattern):
            return kind
    return None


def precision_of(path: str) -> Precision:
    """The :class:`Precision` of the number at ``path`` (:data:`RULES`)."""
    return KINDS[kind_of(path) or "computed"]


def round_value(value: float, precision: Precision | str) -> float:
    """``value`` rounded as ``precision`` (or the kind of that name) says; deterministic on every machine.

    The float's shortest decimal (``repr``) is rounded in :mod:`decimal` to the larger of the
    significant-digit step and the resolution, in the kind's direction; ``-0.0`` becomes ``0.0``;
    non-finite values are returned as they are.
    """
    p = KINDS[precision] if isinstance(precision, str) else precision
    x = float(value)
    if p.digits is None or not math.isfinite(x):
        return x
    if p.floor and abs(x) <= p.floor:
        return float(p.floor)
    d = Decimal(repr(x))
    if d == 0:
        return 0.0
    step = Decimal(1).scaleb(d.adjusted() - p.digits + 1)
    if p.resolution:
        step = max(step, Decimal(repr(float(p.resolution))))
    out = (d / step).to_integral_value(rounding=_DIRECTIONS[p.direction]) * step
    return float(out) + 0.0


def number_text(value: float, precision: Precision | str) -> str:
    """``value`` rounded (:func:`round_value`) and written with no more digits than the kind keeps."""
    p = KINDS[precision] if isinstance(precision, str) else precision
    x = round_value(value, p)
    if not math.isfinite(x) or p.digits is None:
        return repr(x)
    return f"{x:.{p.digits}g}"


_NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?(?![\w.])")
"""A decimal number in a text (not part of a name such as ``x1`` or of a version)."""


def round_numbers_in_text(text: str, precision: Precision | str) -> str:
    """``text`` with every decimal number that has a fraction or exponent rounded (:func:`number_text`).

    For a ``nearest`` kind the numbers are coefficients of one expression: the step is that of the largest
    one (its significant digits), so a coefficient the solver left at noise level prints as 0.
    """
    p = KINDS[precision] if isinstance(precision, str) else precision
    tokens = [m.group(0) for m in _NUMBER.finditer(text) if any(c in m.group(0) for c in ".eE")]
    if p.digits is not None and p.direction == "nearest" and tokens:
        largest = max(abs(float(t)) for t in tokens)
        if math.isfinite(largest) and largest > 0:
            step = 10.0 ** (math.floor(math.log10(largest)) - p.digits + 1)
            p = dataclasses.replace(p, resolution=max(p.resolution, float(f"{step:.0e}")))

    def one(match: re.Match[str]) -> str:
        token = match.group(0)
        if not any(c in token for c in ".eE"):
            return token  # an integer (an exponent of a power, a count) is exact
        return number_text(float(token), p)

    return _NUMBER.sub(one, text)


def round_tree(data: Any, path: str = "", *, rules: tuple[tuple[str, str], ...] = RULES,
               text_rules: tuple[tuple[str, str], ...] = TEXT_RULES) -> Any:
    """A copy of JSON-ready ``data`` with every float rounded by its kind (:data:`RULES`) and the text leaves
    of :data:`TEXT_RULES` rounded; ``path`` is where ``data`` sits in the report (``"analysis"``...).

    Idempotent: rounding rounded data changes nothing.  Integers, booleans and other texts are kept.
    """
    if isinstance(data, Mapping):
        return {k: round_tree(v, f"{path}/{k}" if path else str(k), rules=rules, text_rules=text_rules)
                for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [round_tree(v, path, rules=rules, text_rules=text_rules) for v in data]
    if isinstance(data, float):
        return round_value(data, KINDS[kind_of(path, rules) or "computed"])
    if isinstance(data, str):
        kind = kind_of(path, text_rules)
        return data if kind is None else round_numbers_in_text(data, kind)
    return data


def round_section(name: str, data: Mapping[str, Any]) -> dict[str, Any]:
    """The data of the report section ``name`` rounded (:func:`round_tree` at path ``name``)."""
    return round_tree(data, name)


def _quantise_array(values: np.ndarray, digits: int) -> np.ndarray:
    """Float arrays to ``digits`` significant digits (vectorised; zeros and non-finite values kept)."""
    x = np.asarray(values)
    if x.dtype.kind == "c":
        return _quantise_array(x.real, digits) + 1j * _quantise_array(x.imag, digits)
    if x.dtype.kind != "f":
        return values
    out = x.astype(float, copy=True)
    finite = np.isfinite(out) & (out != 0.0)
    exponent = np.floor(np.log10(np.abs(out[finite])))
    scale = 10.0 ** (digits - 1 - exponent)
    out[finite] = np.round(out[finite] * scale) / scale
    return out


def quantise_for_figure(obj: Any, digits: int = FIGURE_DIGITS) -> Any:
    """A copy of what a figure plots with every float to ``digits`` significant digits.

    Walks mappings, lists, tuples, numpy arrays and dataclass instances (copied with
    :func:`dataclasses.replace` when their fields can be set at construction); anything else is kept.
    """
    if isinstance(obj, np.ndarray):
        return _quantise_array(obj, digits)
    if isinstance(obj, (float, np.floating)):
        return float(_quantise_array(np.array([float(obj)]), digits)[0])
    if isinstance(obj, Mapping):
        return {k: quantise_for_figure(v, digits) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(quantise_for_figure(v, digits) for v in obj) if not hasattr(obj, "_fields") else obj
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        changes = {f.name: quantise_for_figure(getattr(obj, f.name), digits)
                   for f in dataclasses.fields(obj) if f.init}
        return dataclasses.replace(obj, **changes)
    return obj
