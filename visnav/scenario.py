"""Scenario files: load, validate and write the TOML description of one run.

A scenario file has one table per parameter record of :mod:`visnav.parameters`
(keys are the dataclass field names), plus the start and goal poses, the target
and a list of obstacles.  ``docs/scenarios.md`` describes the format, every key
with its unit and default, and every validation rule.

Validation happens here, before any dataclass is built, so that every problem is
reported as a :class:`ScenarioError` naming the file, the dotted key, the value
found, what was expected and how to fix it::

    scenario 'my.toml': envelopes.d_zero_m = 0.7: expected d_minus_m < d_zero_m
    < d_plus_m (0.3 < 0.7 < 0.6 is false); fix: choose d_zero_m between d_minus_m
    and d_plus_m

Obstacle indices in keys (``obstacles[1].radius_m``) count from 0, in file order.

Hostile input is refused the same way, never with a traceback or a hang: a file
that is a directory, not UTF-8, starts with a byte-order mark, is larger than
:data:`MAX_SCENARIO_BYTES`, nests deeper than the TOML parser can follow or holds
an integer it cannot read; arrays longer than :data:`MAX_OBSTACLES`,
:data:`MAX_TARGET_POINTS`, :data:`MAX_REQUIREMENTS`; and a run longer than the
resource bounds of :mod:`visnav.simulation` (samples and trace memory, derived
from the scenario before anything runs).

Examples
--------
>>> scenario = load_scenario("paper")
>>> scenario.envelopes.d_plus_m
0.6
>>> scenario_from_toml(scenario_to_toml(scenario), "copy") == scenario
True
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import hashlib
import importlib.resources
import math
import os
import re
import sys
import tomllib
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from analysis.bdf import MAX_ORDER, MIN_ORDER, BdfOrderError
from analysis.verify.requirements import Requirement, RequirementError, parse_requirements, requirement_from_mapping

from visnav import geometry
from visnav.estimator import SCREW_MODELS, EstimatorSettingsError, validate_settings
from visnav.parameters import (
    K_PATH_RANGE,
    PATH_CLEARANCE_M,
    ActuatorLimits,
    CameraModel,
    Envelopes,
    EstimatorSettings,
    Gains,
    Obstacle,
    Pose,
    RobotGeometry,
    Scenario,
    SupervisorSettings,
    Target,
)
from visnav.scenario_errors import (
    MAX_KEY_PARTS,
    MISSING_VALUE,
    ScenarioError,
    deepest_line,
    long_dotted_key,
    short_key,
    syntax_hint,
)

__all__ = [
    "ScenarioError",
    "SCREW_MODELS",
    "ESTIMATOR_ORDERS",
    "builtin_scenario_names",
    "load_scenario",
    "scenario_from_toml",
    "scenario_from_mapping",
    "validate_scenario",
    "validate_gains",
    "scenario_to_toml",
    "scenario_digest",
    "target_square",
    "point_in_camera",
    "MIN_TARGET_POINTS",
    "MAX_TARGET_POINTS",
    "MAX_OBSTACLES",
    "MAX_REQUIREMENTS",
    "MAX_SCENARIO_BYTES",
    "MAX_KEY_PARTS",
]

#: Zero-stable BDF orders accepted for ``estimator.order`` (for reference: the check itself is
#: :func:`visnav.estimator.validate_settings`).
ESTIMATOR_ORDERS = range(MIN_ORDER, MAX_ORDER + 1)
#: Minimum number of target points (``C = (LᵀL)⁻¹Lᵀ`` needs ``2N >= 3`` independent rows; the
#: paper uses 4).
MIN_TARGET_POINTS = 3
#: Most target points (the paper uses 4; every sample projects, estimates and records each one).
MAX_TARGET_POINTS = 100
#: Most obstacles (the paper has 2; the separation rule compares every pair, the supervisor's
#: checks take one coordinate per obstacle).
MAX_OBSTACLES = 100
#: Most ``[[requirements]]`` (the paper has 33; each formula is parsed at load).
MAX_REQUIREMENTS = 1000
#: Largest scenario file or text [bytes] (the commented paper scenario is about 20 kB).
MAX_SCENARIO_BYTES = 1_048_576

# Tables holding one dataclass each, in canonical order.
_SECTIONS: dict[str, type] = {
    "robot": RobotGeometry,
    "camera": CameraModel,
    "envelopes": Envelopes,
    "gains": Gains,
    "limits": ActuatorLimits,
    "estimator": EstimatorSettings,
    "supervisor": SupervisorSettings,
}
_POSES = ("start", "goal")
_TOP_SCALARS = ("name", "description", "sampling_period_s", "duration_s", "success_tolerance_px")
_TOP_KEYS = (*_TOP_SCALARS, *_SECTIONS, *_POSES, "target", "obstacles", "requirements")
_REQUIRED_TOP = ("name", "target", "start", "goal")
_OBSTACLE_KEYS = ("name", "center_m", "radius_m", "height_m")
_REQUIREMENT_KEYS = ("name", "formula", "description")
_TARGET_POINTS_KEYS = ("points_m",)
_TARGET_SQUARE_KEYS = ("center_m", "normal_rad", "side_m", "n_points")
_TARGET_KEYS = (*_TARGET_POINTS_KEYS, *_TARGET_SQUARE_KEYS)


def _num(x: float) -> str:
    """Short human form of a number for messages."""
    return f"{x:.4g}"


def _mm_up(x: float) -> str:
    """A distance rounded *up* to the millimetre, so that a suggested move is sufficient."""
    return f"{math.ceil(x * 1000.0 - 1e-9) / 1000.0:g}"


# ---------------------------------------------------------------------------------------------
# Geometry shared by the validator (and usable by tests and plots)
# ---------------------------------------------------------------------------------------------


def target_square(
    center: Sequence[float], normal_rad: float, side_m: float
) -> tuple[tuple[float, float, float], ...]:
    """Corners of a vertical square target, each ``(x, y, height)`` [m].

    Parameters
    ----------
    center : (x, y, height)
        Centre of the square [m].
    normal_rad : float
        Direction the target faces, i.e. towards the robot that looks at it [rad]:
        ``pi`` is a target on the robot's +x axis, seen by a robot heading along +x.
    side_m : float
        Side length [m].

    Returns
    -------
    tuple of 4 points
        Ordered as seen by a camera facing the target: top-left, top-right,
        bottom-right, bottom-left.  "Left" is the viewer's left,
        ``(sin normal, -cos normal)``; in the camera frame point 1 has
        ``Y > 0`` (left) and ``X < 0`` (up).

    Examples
    --------
    >>> target_square((9.0, 0.0, 0.5), math.pi, 0.3)
    ((9.0, 0.15, 0.65), (9.0, -0.15, 0.65), (9.0, -0.15, 0.35), (9.0, 0.15, 0.35))
    """
    cx, cy, ch = (float(c) for c in center)
    half = 0.5 * float(side_m)
    lx, ly = math.sin(normal_rad), -math.cos(normal_rad)  # viewer's left
    corners = ((+1, +1), (-1, +1), (-1, -1), (+1, -1))  # (left sign, up sign)
    return tuple(
        (cx + sl * half * lx, cy + sl * half * ly, ch + su * half) for sl, su in corners
    )


def point_in_camera(
    point: Sequence[float], pose: Pose, robot: RobotGeometry
) -> tuple[float, float, float]:
    """Camera-frame coordinates ``(x_c, y_c, z)`` [m] of a world point ``(x, y, height)``.

    ``z`` is the depth along the optical axis, ``y_c`` points left and
    ``x_c = camera_height − height`` points down (the same frame as
    :func:`visnav.geometry.project_point`, which divides by ``z``).
    """
    cx, cy, phi = geometry.camera_pose(pose.x_m, pose.y_m, pose.theta_rad, pose.pan_rad, robot)
    dx, dy = point[0] - cx, point[1] - cy
    c, s = math.cos(phi), math.sin(phi)
    return (robot.camera_height_m - point[2], -s * dx + c * dy, c * dx + s * dy)


# ---------------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------------


def _builtin_dir():
    return importlib.resources.files("visnav").joinpath("scenarios")


def builtin_scenario_names() -> tuple[str, ...]:
    """Names of the scenario files shipped in ``visnav/scenarios/`` (sorted, without ``.toml``)."""
    return tuple(
        sorted(
            entry.name[: -len(".toml")]
            for entry in _builtin_dir().iterdir()
            if entry.name.endswith(".toml") and entry.is_file()
        )
    )


def load_scenario(name_or_path: str | os.PathLike[str]) -> Scenario:
    """Load and validate a built-in scenario by name, or a ``.toml`` file by path.

    A string without a path separator and without the ``.toml`` suffix is looked
    up among :func:`builtin_scenario_names` first; anything else is a path.

    Raises
    ------
    ScenarioError
        Unknown name or missing file (the message lists the built-in names),
        TOML syntax error (with line and column), or any validation failure.
    """
    text_name = os.fspath(name_or_path)
    names = builtin_scenario_names()
    available = ", ".join(names) if names else "(none)"
    looks_like_path = (
        isinstance(name_or_path, os.PathLike)
        or text_name.endswith(".toml")
        or "/" in text_name
        or os.sep in text_name
    )
    if not looks_like_path and text_name in names:
        text = _builtin_dir().joinpath(f"{text_name}.toml").read_text(encoding="utf-8")
        return scenario_from_toml(text, text_name)
    path = Path(text_name)
    if path.is_dir():
        inside = sorted(entry.name for entry in path.glob("*.toml"))[:5]
        hint = f" (it holds {', '.join(inside)})" if inside else ""
        raise ScenarioError(
            text_name, None, text_name,
            f"the path of a scenario file, found a directory at {str(path.resolve())!r}{hint}",
            "give the path of a .toml file, e.g. " + (f"{str(path / inside[0])!r}" if inside else "'DIR/my.toml'"),
        )
    if not path.is_file():
        if looks_like_path:
            expected = f"an existing scenario file (no file at {str(path.resolve())!r})"
        else:
            expected = (
                f"a built-in scenario name (one of: {available}) or the path of a .toml file, "
                f"found neither for {text_name!r}"
            )
        raise ScenarioError(
            text_name,
            None,
            text_name,
            expected,
            f"use one of the built-in names {available}, or check the path",
        )
    try:
        size = path.stat().st_size
        if size > MAX_SCENARIO_BYTES:
            raise ScenarioError(
                text_name, None, None,
                f"a scenario file of at most {MAX_SCENARIO_BYTES:,} bytes (visnav.scenario.MAX_SCENARIO_BYTES), "
                f"found {size:,} bytes",
                "check that this is the scenario file; a scenario needs a few kilobytes (the commented paper "
                "scenario is about 20 kB)",
            )
        with path.open("rb") as handle:
            data = handle.read(MAX_SCENARIO_BYTES + 1)  # the file may grow between stat and read
    except OSError as err:
        raise ScenarioError(
            text_name, None, text_name, f"a readable file ({err.strerror or err})",
            "check the file's permissions and that it is a regular file",
        ) from err
    return scenario_from_toml(_decode(data, text_name), text_name)


def _decode(data: bytes, source: str) -> str:
    """UTF-8 text of a scenario file; a byte that is not UTF-8 is named by its offset, line and column."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        column = err.start - (data.rfind(b"\n", 0, err.start) + 1) + 1
        bad = data[err.start:err.end].hex(" ")
        raise ScenarioError(
            source, None, None,
            f"UTF-8 text (the byte{'s' if err.end - err.start > 1 else ''} 0x{bad} at byte offset {err.start}, "
            f"line {line}, column {column}, {'are' if err.end - err.start > 1 else 'is'} not valid UTF-8: "
            f"{err.reason})",
            f"save the file as UTF-8 (it may be in Latin-1 or Windows-1252: re-encode it, e.g. "
            f"iconv -f latin1 -t utf-8), or retype the character at line {line}, column {column}",
            line=line, column=column,
        ) from err


_POSITION = re.compile(r"line (\d+), column (\d+)")


def scenario_from_toml(text: str, source: str = "<string>") -> Scenario:
    """Parse TOML ``text`` and validate it with :func:`scenario_from_mapping`.

    Raises
    ------
    ScenarioError
        Text over :data:`MAX_SCENARIO_BYTES`, a byte-order mark, a TOML syntax error
        (with its line and column and, for the common mistakes, what to change: a
        non-ASCII bare key, a key defined twice), nesting too deep or an integer too
        long for the parser, or any validation failure.
    """
    if not isinstance(text, str):
        raise ScenarioError(source, None, None, f"TOML text (a str), found {type(text).__name__}",
                            "decode the file as UTF-8 first, or call load_scenario with its path")
    if len(text) > MAX_SCENARIO_BYTES:
        raise ScenarioError(
            source, None, None,
            f"a scenario of at most {MAX_SCENARIO_BYTES:,} characters (visnav.scenario.MAX_SCENARIO_BYTES), "
            f"found {len(text):,}", "a scenario needs a few kilobytes; check what is being loaded")
    if text.startswith("\ufeff"):
        raise ScenarioError(
            source, None, None,
            "TOML text without a byte-order mark (the file starts with a UTF-8 byte-order mark, U+FEFF, "
            "which TOML does not allow)",
            "save the file as UTF-8 without BOM (most editors offer 'UTF-8' next to 'UTF-8 with BOM')",
            line=1, column=1,
        )
    long_dotted_key(text, source)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        message = str(err)
        found = _POSITION.search(message)
        line, column = (int(found[1]), int(found[2])) if found else (None, None)
        if found is None and "end of document" in message:
            last = text.rsplit("\n", 1)[-1]
            line, column = text.count("\n") + 1, len(last) + 1
        at = f"line {line}, column {column}" if line is not None else "an unknown position"
        expected, fix = syntax_hint(text, message, line, column)
        raise ScenarioError(
            source,
            None,
            None,
            expected or f"valid TOML (syntax error at {at}: {message})",
            fix or f"correct the TOML syntax at {at}",
            line=line,
            column=column,
        ) from err
    except RecursionError as err:
        where = deepest_line(text)
        raise ScenarioError(
            source, None, None,
            f"TOML nested at most a few hundred levels deep: arrays or inline tables are nested too deep for "
            f"the parser{where}",
            "a scenario nests arrays at most 2 levels deep (target.points_m = [[x, y, h], ...]): remove the "
            "extra brackets",
        ) from err
    except ValueError as err:  # an integer longer than Python's int-to-str digit limit (4300 digits)
        long_number = re.search(r"\d{500,}", text)
        where = f" at line {text.count(chr(10), 0, long_number.start()) + 1}" if long_number else ""
        digits = re.search(r"value has (\d+) digits", str(err))
        found = f"found an integer of {digits[1]} digits" if digits else " ".join(str(err).split())
        raise ScenarioError(
            source, None, None,
            f"numbers the TOML parser can read: an integer has at most {sys.get_int_max_str_digits()} digits "
            f"({found}{where})",
            "write the number as a float with an exponent (1e300) or shorten it; no value of a scenario needs "
            "more than 17 significant digits",
        ) from err
    return scenario_from_mapping(data, source)


# ---------------------------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------------------------


class _Checker:
    """Type checks for one source; every failure raises a :class:`ScenarioError`."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str | None, value: object, expected: str, fix: str) -> typing.NoReturn:
        raise ScenarioError(self.source, key, value, expected, fix)

    def table(self, key: str, value: object, required: bool = False) -> Mapping[str, Any]:
        if value is MISSING_VALUE:
            if required:
                self.fail(key, MISSING_VALUE, f"a [{key}] table", f"add a [{key}] table (see docs/scenarios.md)")
            return {}
        if not isinstance(value, Mapping):
            self.fail(key, value, f"a table [{key}]", f"write the entries under a [{key}] header")
        return value

    def unknown_keys(self, prefix: str, table: Mapping[str, Any], valid: Sequence[str]) -> None:
        for key in table:
            if key in valid:
                continue
            shown = short_key(key)
            where = f"{prefix}.{shown}" if prefix else shown
            if prefix and key in _TOP_KEYS:
                # a top-level key written below a [table] header: TOML puts it into that table
                header = f"[[{prefix.split('[', 1)[0]}]]" if prefix.endswith("]") else f"[{prefix}]"
                extra = (" (or delete it: a file without [[obstacles]] tables has no obstacles)"
                         if key == "obstacles" else "")
                self.fail(
                    where, table[key],
                    f"one of the keys {', '.join(valid)}: in TOML every key after a {header} header belongs to "
                    f"that table, up to the next header, so this top-level {key!r} was read as {where}",
                    f"move the line {shown} = ... above the first [table] header of the file{extra}",
                )
            close = difflib.get_close_matches(str(key), valid, n=1, cutoff=0.6)
            if close:
                fix = f"did you mean {close[0]!r}? rename {shown!r} to {close[0]!r}"
            else:
                fix = f"remove {shown!r} (valid keys: {', '.join(valid)})"
            self.fail(where, table[key], f"one of the keys {', '.join(valid)}", fix)

    def number(self, key: str, value: object, unit: str = "") -> float:
        unit_text = f" [{unit}]" if unit else ""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            hint = (
                "write the number without quotes"
                if isinstance(value, str)
                else "write a number such as 0.5 (true/false are not numbers)"
                if isinstance(value, bool)
                else "write a single number"
            )
            self.fail(key, value, f"a number{unit_text}, found {_toml_type(value)}", hint)
        try:
            number = float(value)
        except OverflowError:  # an integer beyond the float range (TOML integers have no bound)
            self.fail(key, value, f"a finite number{unit_text} (this integer is beyond the float range, "
                      "about 1.8e308)", "write a number of a sensible magnitude")
        if not math.isfinite(number):
            self.fail(key, value, f"a finite number{unit_text}", "replace inf/nan by a finite value")
        return number

    def integer(self, key: str, value: object) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            hint = (
                "write the number without quotes"
                if isinstance(value, str)
                else f"write a whole number without a decimal point (e.g. {int(value)})"
                if isinstance(value, float) and math.isfinite(value) and value == int(value)
                else "write a whole number"
            )
            self.fail(key, value, f"an integer, found {_toml_type(value)}", hint)
        if value.bit_length() > 63:  # TOML integers are 64-bit; a Python mapping may hold any int
            self.fail(key, value, "an integer of at most 64 bits (|value| < 2**63)", "write a small whole number")
        return value

    def string(self, key: str, value: object) -> str:
        if not isinstance(value, str):
            self.fail(
                key,
                value,
                f"a string, found {_toml_type(value)}",
                'write the text in double quotes, e.g. "name"',
            )
        return value

    def vector(self, key: str, value: object, length: int, form: str, unit: str) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != length:
            found = f"an array of {len(value)}" if isinstance(value, list) else _toml_type(value)
            self.fail(
                key,
                value,
                f"an array of {length} numbers {form} [{unit}], found {found}",
                f"write {key.rsplit('.', 1)[-1]} = {form}",
            )
        return tuple(self.number(f"{key}[{i}]", v, unit) for i, v in enumerate(value))

    def positive(self, key: str, value: float, why: str = "") -> None:
        if not value > 0:
            reason = f" ({why})" if why else ""
            self.fail(key, value, f"a value > 0{reason}", f"set {key.rsplit('.', 1)[-1]} to a positive value")


def _toml_type(value: object) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a float"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, Mapping):
        return "a table"
    return f"a {type(value).__name__}"


_UNITS = {"_m": "m", "_px": "px", "_s": "s", "_rad": "rad", "_mps": "m/s", "_radps": "rad/s"}


def _unit(field_name: str) -> str:
    for suffix, unit in _UNITS.items():
        if field_name.endswith(suffix):
            return unit
    return ""


def _fields(cls: type) -> dict[str, type]:
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls)}


def _section(check: _Checker, prefix: str, cls: type, table: Mapping[str, Any]) -> dict[str, Any]:
    """Type-check the scalar keys of a table against a dataclass; return kwargs."""
    types = _fields(cls)
    check.unknown_keys(prefix, table, tuple(types))
    values: dict[str, Any] = {}
    for name, value in table.items():
        key = f"{prefix}.{name}" if prefix else name
        kind = types[name]
        if kind is float:
            values[name] = check.number(key, value, _unit(name))
        elif kind is int:
            values[name] = check.integer(key, value)
        elif kind is str:
            values[name] = check.string(key, value)
        else:  # pragma: no cover - only scalar records are read by this helper
            raise TypeError(f"{cls.__name__}.{name}: unsupported field type {kind!r}")
    return values


def _ordered(check: _Checker, prefix: str, names: tuple[str, str, str], env: Envelopes) -> None:
    low, mid, high = (getattr(env, n) for n in names)
    for n in names:
        check.positive(f"{prefix}.{n}", getattr(env, n), "envelope distances are positive")
    if low < mid < high:
        return
    chain = f"{names[0]} < {names[1]} < {names[2]} ({low!r} < {mid!r} < {high!r} is false)"
    if not low < high:
        check.fail(
            f"{prefix}.{names[0]}",
            low,
            chain,
            f"choose {names[0]} below {names[2]} and {names[1]} between them",
        )
    check.fail(f"{prefix}.{names[1]}", mid, chain, f"choose {names[1]} between {names[0]} and {names[2]}")


def scenario_from_mapping(data: Mapping[str, Any], source: str) -> Scenario:
    """Validate a parsed scenario (e.g. the output of ``tomllib``) and build the :class:`Scenario`.

    Parameters
    ----------
    data : mapping
        Top-level keys and tables as described in ``docs/scenarios.md``.
    source : str
        Name used in error messages (file path or built-in name).

    Raises
    ------
    ScenarioError
        On the first problem found; the message names the key, the value, the
        expectation and the fix.
    """
    check = _Checker(source)
    if not isinstance(data, Mapping):
        check.fail(
            None, data, f"a mapping of tables, found {_toml_type(data)}", "pass the parsed TOML document"
        )
    check.unknown_keys("", data, _TOP_KEYS)
    for key in _REQUIRED_TOP:
        if key not in data:
            fix = 'add name = "..." at the top of the file' if key == "name" else f"add a [{key}] table"
            check.fail(key, MISSING_VALUE, "a value (name, target, start and goal are required)", fix)

    # -- top-level scalars
    top = _section(check, "", Scenario, {k: data[k] for k in _TOP_SCALARS if k in data})
    if not top["name"].strip():
        check.fail("name", top["name"], "a non-empty name", 'write a short name such as name = "paper"')
    for key in ("sampling_period_s", "duration_s", "success_tolerance_px"):
        if key in top:
            check.positive(key, top[key])
    period = top.get("sampling_period_s", _SCENARIO_DEFAULTS["sampling_period_s"])
    duration = top.get("duration_s", _SCENARIO_DEFAULTS["duration_s"])
    if not duration >= period:
        check.fail(
            "duration_s", duration,
            f"at least sampling_period_s = {period!r} s (a run of at least one sampling period)",
            "lengthen duration_s or shorten sampling_period_s",
        )

    # -- parameter records
    records: dict[str, Any] = {}
    for prefix, cls in _SECTIONS.items():
        table = check.table(prefix, data.get(prefix, MISSING_VALUE))
        records[prefix] = cls(**_section(check, prefix, cls, table))

    robot: RobotGeometry = records["robot"]
    check.positive(
        "robot.pan_offset_m", robot.pan_offset_m, "Dx must be > 0: J_r is singular otherwise, det J_r = Dx"
    )
    check.positive("robot.camera_height_m", robot.camera_height_m, "the camera is above the floor")

    for name in ("focal_px", "half_width_px", "half_height_px"):
        check.positive(f"camera.{name}", getattr(records["camera"], name))

    env: Envelopes = records["envelopes"]
    _ordered(check, "envelopes", ("d_minus_m", "d_zero_m", "d_plus_m"), env)
    _ordered(check, "envelopes", ("D_minus_px", "D_zero_px", "D_plus_px"), env)
    if not env.d_zero_m > PATH_CLEARANCE_M:
        check.fail(
            "envelopes.d_zero_m", env.d_zero_m,
            f"a value > {PATH_CLEARANCE_M!r} m (visnav.parameters.PATH_CLEARANCE_M): the path-following analysis "
            f"of visnav analyse and visnav report certifies gains that keep {PATH_CLEARANCE_M!r} m from the obstacle, "
            "a clearance inside the avoidance envelope d0",
            f"choose d_zero_m above {PATH_CLEARANCE_M!r} m (the paper uses 0.5), keeping d_minus_m < d_zero_m "
            "< d_plus_m",
        )

    _gains_and_limits(check, records["gains"], records["limits"])
    _estimator(check, records["estimator"])

    sup: SupervisorSettings = records["supervisor"]
    if not 0.0 < sup.arm_angle_rad < math.pi / 2:
        check.fail(
            "supervisor.arm_angle_rad",
            sup.arm_angle_rad,
            f"0 < arm_angle_rad < pi/2 = {math.pi / 2:.6g} (the pan angle must move away from 0 before "
            "its return to 0 can mean 'obstacle overcome')",
            "choose an angle such as 0.2 rad",
        )
    if not sup.detection_hysteresis_m > 0.0:
        check.fail(
            "supervisor.detection_hysteresis_m", sup.detection_hysteresis_m,
            "a value > 0 [m] (with 0 the supervisor can leave and re-enter the approach band at the same "
            "instant, d = d+, forever: finding R2 of docs/fuzzing.md)", "use 0.02"
        )

    # -- poses
    poses = {
        key: Pose(**_section(check, key, Pose, check.table(key, data[key], required=True))) for key in _POSES
    }

    # -- obstacles
    obstacles = _obstacles(check, data.get("obstacles", MISSING_VALUE), env, poses)

    # -- target
    target_table = check.table("target", data["target"], required=True)
    target = _target(check, target_table, robot, records["camera"], poses)

    _run_bounds(check, period, duration, len(target.points_m), len(obstacles))

    scenario = Scenario(
        **top, **records, obstacles=obstacles, target=target, start=poses["start"], goal=poses["goal"]
    )
    requirements = _requirements(check, data.get("requirements", MISSING_VALUE), scenario)
    return dataclasses.replace(scenario, requirements=requirements) if requirements else scenario


_SCENARIO_DEFAULTS = {f.name: f.default for f in dataclasses.fields(Scenario)}


def _at_most(check: _Checker, key: str, raw: list[Any], constant: str, what: str, why: str) -> None:
    """Refuse an array of more than ``globals()[constant]`` entries before any entry is looked at."""
    limit = globals()[constant]
    if len(raw) > limit:
        check.fail(key, raw, f"at most {limit:,} {what} (visnav.scenario.{constant}), found {len(raw):,}: {why}",
                   f"keep at most {limit:,} {what}")


def _run_bounds(check: _Checker, period: float, duration: float, n_points: int, n_obstacles: int) -> None:
    """Rule 25: the run's samples and trace memory within :mod:`visnav.simulation`'s resource bounds."""
    from visnav.simulation import MAX_RUN_SAMPLES, MAX_TRACE_BYTES, TRACE_BYTES_PER_VALUE, run_size

    size = run_size(period, duration, n_points, n_obstacles)
    fix = "lengthen sampling_period_s or shorten duration_s (docs/scenarios.md, 'Resource bounds')"
    count = (f"{int(size.samples):,} samples" if size.samples <= 1e9 else f"{size.samples:.3g} samples"
             if math.isfinite(size.samples) else "more samples than a float can count")
    if not size.samples <= MAX_RUN_SAMPLES:
        check.fail(
            "duration_s", duration,
            f"a run of at most {MAX_RUN_SAMPLES:,} samples (visnav.simulation.MAX_RUN_SAMPLES): "
            f"duration_s / sampling_period_s = {duration!r} / {period!r} gives {count}, over the limit",
            fix,
        )
    if not size.trace_bytes <= MAX_TRACE_BYTES:
        check.fail(
            "duration_s", duration,
            f"a trace of at most {MAX_TRACE_BYTES / 1e6:,.0f} MB (visnav.simulation.MAX_TRACE_BYTES), the memory "
            f"of the run kept until it ends: {count} of {size.row_values} values "
            f"({n_points} target points, {n_obstacles} obstacles) at {TRACE_BYTES_PER_VALUE} bytes each take "
            f"{size.trace_bytes / 1e6:,.0f} MB; at most {size.max_samples:,} samples fit",
            fix + ", or use fewer target points",
        )


def _target_determines_motion(check: _Checker, points: tuple[tuple[float, float, float], ...],
                              robot: RobotGeometry, goal: Pose) -> None:
    """Rule 21: ``L^T L`` non-singular at ``s*``, with the controller's own test (:mod:`visnav.controllers`).

    The closed loop evaluates the interaction matrix at the desired features, so this one
    matrix is the one every sample of the run inverts.
    """
    from hybrid.errors import NumericalFailure

    from visnav.controllers import visual_servoing_error

    cx, cy, phi = geometry.camera_pose(goal.x_m, goal.y_m, goal.theta_rad, goal.pan_rad, robot)
    desired = geometry.project_points(cx, cy, phi, robot.camera_height_m, points)
    try:
        visual_servoing_error(desired, tuple((x, y) for x, y, _ in desired), desired)
    except NumericalFailure as err:
        check.fail(
            "target.points_m", [list(p) for p in points],
            "target points whose image at the goal pose determines the camera motion (the visual-servoing "
            f"matrix L^T L at s* must be invertible; {err.cause.split('; ', 1)[0]})",
            "spread the points: no two of them coincident, not all on one line (the paper uses the 4 corners of a "
            "square)",
        )


def _requirement_key(i: int, error: RequirementError) -> str:
    """The dotted key of a :class:`RequirementError` raised for ``requirements[i]``."""
    for key in ("formula", "description", "name"):
        if error.parameter.endswith(key):
            return f"requirements[{i}].{key}"
    return f"requirements[{i}]"


@functools.lru_cache(maxsize=1024)
def _check_formula(
    requirement: Requirement, signals: tuple[str, ...], labels: tuple[tuple[str, tuple[str, ...]], ...], horizon: float
) -> None:
    """:func:`analysis.verify.requirements.parse_requirements` of one requirement (cached: every perturbed copy of a
    scenario is validated again, with the same formulas, catalogue and horizon)."""
    parse_requirements((requirement,), signals=signals, labels=dict(labels), horizon=horizon)


def _requirements(check: _Checker, raw: object, scenario: Scenario) -> tuple[Requirement, ...]:
    """The ``[[requirements]]`` tables: each parsed against the signal catalogue and ``duration_s``.

    Rule 24 of ``docs/scenarios.md``: keys ``name`` (an identifier, unique), ``formula``
    (STL over :func:`visnav.requirements.signal_catalogue`, no window beyond ``duration_s``)
    and ``description``.
    """
    from visnav.requirements import signal_catalogue

    if raw is MISSING_VALUE:
        return ()
    if isinstance(raw, list):
        _at_most(check, "requirements", raw, "MAX_REQUIREMENTS", "requirements", "each formula is parsed at load")
    if not isinstance(raw, list) or not all(isinstance(item, Mapping) for item in raw):
        check.fail("requirements", raw, "an array of tables [[requirements]]",
                   "write each requirement under its own [[requirements]] header")
    signals, labels = signal_catalogue(scenario)
    out: list[Requirement] = []
    seen: dict[str, int] = {}
    for i, table in enumerate(raw):
        prefix = f"requirements[{i}]"
        check.unknown_keys(prefix, table, _REQUIREMENT_KEYS)
        for key in ("name", "formula"):
            if key not in table:
                check.fail(f"{prefix}.{key}", MISSING_VALUE, "name and formula for every requirement",
                           f'add {key} = "..." to the requirement (see docs/requirements.md)')
        for key in _REQUIREMENT_KEYS:
            if key in table:
                check.string(f"{prefix}.{key}", table[key])
        try:
            requirement = requirement_from_mapping(table, f"{check.source}: {prefix}")
        except RequirementError as err:
            check.fail(_requirement_key(i, err), err.value, err.expected, err.fix)
        if requirement.name in seen:
            check.fail(f"{prefix}.name", requirement.name,
                       f"a unique name (requirements[{seen[requirement.name]}] is also {requirement.name!r})",
                       "rename one of the requirements")
        seen[requirement.name] = i
        try:
            _check_formula(requirement, signals, tuple(labels.items()), scenario.duration_s)
        except RequirementError as err:
            check.fail(
                f"{prefix}.formula", requirement.formula,
                f"a valid STL formula over the signals of docs/requirements.md with no window beyond "
                f"duration_s = {scenario.duration_s!r} s",
                f"correct the formula of {requirement.name!r}:{err.fix}",
            )
        out.append(requirement)
    return tuple(out)


def _gains_and_limits(check: _Checker, gains: Gains, limits: ActuatorLimits) -> None:
    """Rules 11-12 of ``docs/scenarios.md``: positive gains and limits, ``k`` certified, ``v_coll <= v_max``."""
    for f in dataclasses.fields(Gains):
        why = "v_coll is the constant avoidance speed" if f.name == "v_coll_mps" else "every gain is positive"
        check.positive(f"gains.{f.name}", getattr(gains, f.name), why)
    for f in dataclasses.fields(ActuatorLimits):
        check.positive(f"limits.{f.name}", getattr(limits, f.name), "limits are magnitudes")
    low, high = K_PATH_RANGE
    if not low <= gains.k_path <= high:
        check.fail(
            "gains.k_path",
            gains.k_path,
            f"a gain in [{low:g}, {high:g}] 1/m, the range the Lyapunov certificate and the admissible-gain "
            "search cover (visnav.parameters.K_PATH_RANGE)",
            f"choose k_path between {low:g} and {high:g} (the paper scenario uses 4)",
        )
    if not gains.v_coll_mps <= limits.v_max_mps:
        check.fail(
            "gains.v_coll_mps",
            gains.v_coll_mps,
            f"at most limits.v_max_mps = {limits.v_max_mps!r} m/s: the robot cannot follow the envelope faster "
            "than its speed limit, and the Lyapunov certificate covers v in [0, v_max]",
            "lower gains.v_coll_mps or raise limits.v_max_mps",
        )


#: Scenario-file advice per estimator key; the rule itself is :func:`visnav.estimator.validate_settings`.
_ESTIMATOR_FIXES = {
    "order": "use 4, as in the paper",
    "screw_model": f"use one of {', '.join(SCREW_MODELS)}",
    "newton_tol": "set newton_tol to a relative tolerance in [1e-15, 1), e.g. 1e-12",
    "newton_maxiter": "use 8 (at most 100)",
}


def _estimator(check: _Checker, est: EstimatorSettings) -> None:
    """Rule 13: :func:`visnav.estimator.validate_settings`, its error mapped to a :class:`ScenarioError`."""
    try:
        validate_settings(est)
    except (EstimatorSettingsError, BdfOrderError) as err:
        message = str(err)
        for f in dataclasses.fields(EstimatorSettings):
            value = getattr(est, f.name)
            prefix = f"EstimatorSettings.{f.name} = {value!r}"
            if not message.startswith(prefix):
                continue
            rest = message[len(prefix):]
            at = rest.find("expected ")
            # the estimator's text after "; " is its fix in Python terms; the scenario gives its own
            expected = (rest[at + len("expected "):] if at >= 0 else rest.lstrip(": ")).split("; ", 1)[0]
            fix = _ESTIMATOR_FIXES.get(f.name, "see docs/estimator.md")
            if f.name == "screw_model" and isinstance(value, str):
                close = difflib.get_close_matches(value, SCREW_MODELS, n=1)
                fix = (f"did you mean {close[0]!r}? " if close else "") + fix
            check.fail(f"estimator.{f.name}", value, expected, fix)
        check.fail("estimator", None, f"valid estimator settings ({message})", "see docs/estimator.md")


def validate_gains(gains: Gains, limits: ActuatorLimits, source: str = "<gains>") -> None:
    """Check ``gains`` against the scenario rules (rules 11-12 of ``docs/scenarios.md``).

    The check :func:`scenario_from_mapping` applies to the ``[gains]`` and ``[limits]``
    tables, for records built in Python (e.g. with :func:`dataclasses.replace`):
    every gain and limit > 0, ``k_path`` within :data:`visnav.parameters.K_PATH_RANGE`
    [1/m], ``v_coll_mps <= limits.v_max_mps`` [m/s].

    Raises
    ------
    ScenarioError
        Naming ``source``, the key, the value, the expectation and the fix.
    """
    _gains_and_limits(_Checker(source), gains, limits)


def validate_scenario(scenario: Scenario, source: str | None = None) -> Scenario:
    """Apply every rule of :func:`scenario_from_mapping` to a scenario built in Python.

    The scenario goes through its canonical TOML (floats written as ``repr``, so
    the round trip is exact) and back through the validator.

    Parameters
    ----------
    scenario : Scenario
        E.g. a perturbed copy of a loaded scenario.
    source : str, optional
        Label used in error messages (default: the scenario's name).

    Returns
    -------
    Scenario
        An equal, validated scenario.

    Raises
    ------
    ScenarioError
        The first rule the scenario breaks (a non-finite number included).
    """
    label = scenario.name if source is None else source
    try:
        text = scenario_to_toml(scenario)
    except (TypeError, ValueError) as err:
        raise ScenarioError(label, None, None, f"finite numbers and strings only ({err})",
                            "check the values computed for the scenario") from err
    return scenario_from_toml(text, label)


def _obstacles(
    check: _Checker, raw: object, env: Envelopes, poses: Mapping[str, Pose]
) -> tuple[Obstacle, ...]:
    if raw is MISSING_VALUE:
        return ()
    if isinstance(raw, list):
        _at_most(check, "obstacles", raw, "MAX_OBSTACLES", "obstacles",
                 "the separation rule compares every pair and every sample measures every obstacle")
    if not isinstance(raw, list) or not all(isinstance(item, Mapping) for item in raw):
        check.fail(
            "obstacles",
            raw,
            "an array of tables [[obstacles]]",
            "write each obstacle under its own [[obstacles]] header",
        )
    obstacles: list[Obstacle] = []
    seen: dict[str, int] = {}
    for i, table in enumerate(raw):
        prefix = f"obstacles[{i}]"
        check.unknown_keys(prefix, table, _OBSTACLE_KEYS)
        for key in _OBSTACLE_KEYS:
            if key not in table:
                check.fail(
                    f"{prefix}.{key}",
                    MISSING_VALUE,
                    "name, center_m, radius_m and height_m for every obstacle",
                    f"add {key} to the obstacle",
                )
        name = check.string(f"{prefix}.name", table["name"])
        if not name.strip():
            check.fail(f"{prefix}.name", name, "a non-empty name", "name the obstacle")
        if name in seen:
            check.fail(
                f"{prefix}.name",
                name,
                f"a unique name (obstacles[{seen[name]}] is also {name!r})",
                "rename one of the obstacles",
            )
        seen[name] = i
        center = check.vector(f"{prefix}.center_m", table["center_m"], 2, "[x, y]", "m")
        radius = check.number(f"{prefix}.radius_m", table["radius_m"], "m")
        height = check.number(f"{prefix}.height_m", table["height_m"], "m")
        check.positive(f"{prefix}.radius_m", radius)
        check.positive(f"{prefix}.height_m", height)
        obstacle = Obstacle(name=name, center_m=center, radius_m=radius, height_m=height)

        for j, other in enumerate(obstacles):
            gap = math.dist(center, other.center_m) - radius - other.radius_m
            if gap < 2 * env.d_plus_m:
                check.fail(
                    f"{prefix}.center_m",
                    center,
                    f"at least 2*d_plus_m = {_num(2 * env.d_plus_m)} m surface to surface from "
                    f"obstacles[{j}] {other.name!r} (found {_num(gap)} m): "
                    "the paper's hypothesis is that obstacles are separated by at least 2*d+ "
                    "so that the robot is within d+ of one obstacle at a time",
                    f"move {name!r} at least {_mm_up(2 * env.d_plus_m - gap)} m further from {other.name!r}, "
                    "or reduce envelopes.d_plus_m",
                )
        for where, verb in (("start", "start"), ("goal", "end")):
            pose = poses[where]
            distance = math.dist((pose.x_m, pose.y_m), center)
            limit = radius + env.d_minus_m
            if distance < limit:
                check.fail(
                    f"{prefix}.center_m",
                    center,
                    f"the {where} point M = ({_num(pose.x_m)}, {_num(pose.y_m)}) at least "
                    f"radius_m + d_minus_m = {_num(limit)} m from the centre (found {_num(distance)} m): "
                    f"the robot would {verb} inside the critical envelope",
                    f"move {name!r} or the {where} pose at least {_mm_up(limit - distance)} m further apart",
                )
        obstacles.append(obstacle)
    return tuple(obstacles)


def _target(
    check: _Checker,
    table: Mapping[str, Any],
    robot: RobotGeometry,
    camera: CameraModel,
    poses: Mapping[str, Pose],
) -> Target:
    check.unknown_keys("target", table, _TARGET_KEYS)
    square_keys = [k for k in _TARGET_SQUARE_KEYS if k in table]
    if "points_m" in table:
        if square_keys:
            check.fail(
                f"target.{square_keys[0]}",
                table[square_keys[0]],
                "either points_m or a generated square (center_m, normal_rad, side_m), not both",
                f"remove {square_keys[0]} or remove points_m",
            )
        raw = table["points_m"]
        if not isinstance(raw, list):
            check.fail(
                "target.points_m",
                raw,
                f"an array of [x, y, h] points [m], found {_toml_type(raw)}",
                "write points_m = [[x, y, h], ...]",
            )
        _at_most(check, "target.points_m", raw, "MAX_TARGET_POINTS", "target points",
                 "every sample projects, reconstructs and records each point")
        points = tuple(
            check.vector(f"target.points_m[{i}]", p, 3, "[x, y, h]", "m") for i, p in enumerate(raw)
        )
    else:
        for key in ("center_m", "normal_rad", "side_m"):
            if key not in table:
                check.fail(
                    f"target.{key}",
                    MISSING_VALUE,
                    "either points_m = [[x, y, h], ...] or center_m, normal_rad and side_m of a square",
                    f"add target.{key} (or give points_m)",
                )
        center = check.vector("target.center_m", table["center_m"], 3, "[x, y, h]", "m")
        normal = check.number("target.normal_rad", table["normal_rad"], "rad")
        side = check.number("target.side_m", table["side_m"], "m")
        check.positive("target.side_m", side)
        if "n_points" in table and check.integer("target.n_points", table["n_points"]) != 4:
            check.fail(
                "target.n_points",
                table["n_points"],
                "4 (a generated square has 4 corners)",
                "use n_points = 4, or list the points in points_m",
            )
        points = target_square(center, normal, side)

    if len(points) < MIN_TARGET_POINTS:
        check.fail(
            "target.points_m",
            [list(p) for p in points],
            f"at least {MIN_TARGET_POINTS} points (the paper uses 4)",
            "add points, e.g. the 4 corners of a square",
        )
    for where in ("goal", "start"):
        for i, point in enumerate(points):
            _, _, depth = point_in_camera(point, poses[where], robot)
            if not depth > 0:
                check.fail(
                    f"target.points_m[{i}]",
                    list(point),
                    f"a point in front of the camera at the {where} pose (depth {_num(depth)} m <= 0)",
                    f"place the target ahead of the {where} pose "
                    f"or turn {where}.theta_rad/{where}.pan_rad towards it",
                )
    goal = poses["goal"]
    for i, point in enumerate(points):
        x_c, y_c, z = point_in_camera(point, goal, robot)
        horizontal, vertical = abs(y_c / z) * camera.focal_px, abs(x_c / z) * camera.focal_px
        outside = []
        if horizontal > camera.half_width_px:
            outside.append(f"|Y|*f = {_num(horizontal)} px > half_width_px = {_num(camera.half_width_px)}")
        if vertical > camera.half_height_px:
            outside.append(f"|X|*f = {_num(vertical)} px > half_height_px = {_num(camera.half_height_px)}")
        if outside:
            check.fail(
                f"target.points_m[{i}]",
                list(point),
                f"a point inside the image at the goal pose, otherwise s* is unobservable "
                f"(found {' and '.join(outside)})",
                "move the goal pose further from the target, shrink the target, or widen the image",
            )
    _target_determines_motion(check, points, robot, goal)
    return Target(points_m=points)


# ---------------------------------------------------------------------------------------------
# Canonical TOML
# ---------------------------------------------------------------------------------------------


def _toml_string(text: str) -> str:
    out = ['"']
    escapes = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}
    for ch in text:
        if ch in escapes:
            out.append(escapes[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _toml_value(value: object, integer: bool = False) -> str:
    """One TOML value; numbers are written as floats unless ``integer`` (int-typed fields)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int) and integer:
        return str(value)
    if isinstance(value, (int, float)):
        value = float(value)  # an int in a float field (built in Python) gets the same text as the float
        if not math.isfinite(value):
            raise ValueError(f"cannot write non-finite float {value!r} to a scenario")
        return repr(value)
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_toml_value(v, integer) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to a scenario")


def _toml_line(record: object, name: str) -> str:
    integer = _fields(type(record))[name] is int
    return f"{name} = {_toml_value(getattr(record, name), integer)}"


def _toml_table(record: object) -> list[str]:
    return [_toml_line(record, f.name) for f in dataclasses.fields(record)]


def scenario_to_toml(scenario: Scenario) -> str:
    """Canonical TOML text of ``scenario``: every key written, in dataclass order.

    The text is deterministic (floats as ``repr``, so they round-trip exactly)
    and loads back into an equal :class:`Scenario`.  The target is always
    written as explicit ``points_m``.
    """
    lines = ["# Canonical scenario written by visnav.scenario.scenario_to_toml", ""]
    lines += [_toml_line(scenario, key) for key in _TOP_SCALARS]
    for key in (*_SECTIONS, *_POSES):
        lines += ["", f"[{key}]", *_toml_table(getattr(scenario, key))]
    lines += ["", "[target]", "points_m = ["]
    lines += [f"    {_toml_value(point)}," for point in scenario.target.points_m]
    lines.append("]")
    for obstacle in scenario.obstacles:
        lines += ["", "[[obstacles]]", *_toml_table(obstacle)]
    for requirement in scenario.requirements:
        lines += ["", "[[requirements]]"]
        lines += [f"{key} = {_toml_string(getattr(requirement, key))}" for key in _REQUIREMENT_KEYS]
    return "\n".join(lines) + "\n"


def scenario_digest(scenario: Scenario) -> str:
    """SHA-256 (hex) of :func:`scenario_to_toml`: identifies the run parameters in reports."""
    return hashlib.sha256(scenario_to_toml(scenario).encode("utf-8")).hexdigest()
