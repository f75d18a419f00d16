"""Generated inputs, valid, subtly wrong and hostile, against the CLI's contract (docs/failure_modes.md).

Every case runs a ``visnav`` command in-process and asserts the contract:

* the exit code is one the command documents for that kind of input (never 4, "internal error");
* nothing on stdout or stderr is a Python traceback;
* it ends within a bound (a hang is a failure, never a wait);
* an accepted input gives the same answer twice (nothing changes silently).

Five generators: scenario files (``mode-graph --scenario FILE``: loading, validation, the
supervisor's construction), counterexample files (``replay FILE``), argument lists of every
subcommand (hostile values of every option), raw bytes (BOM, invalid UTF-8, truncation, deep
nesting, huge numbers), and campaign results files (read back by the store ``visnav sweep``
resumes from: refused with its message, or every result kept is one the campaign wrote).  The CI budget (``CI`` set) runs {CI_CASES} cases in all; locally a tenth.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import signal
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import visnav.app.cli as cli
from visnav.app.cli_types import EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_OK, EXIT_TASK_FAILED

CI_CASES = 2000
SHARE = {"scenario": 0.3, "counterexample": 0.2, "argv": 0.2, "bytes": 0.15, "results": 0.15}
CASE_BOUND_S = 30.0
"""No case may run longer: the cheapest commands are used, and a refusal must come before any run."""

PAPER = Path(cli.__file__).resolve().parents[1] / "scenarios" / "paper.toml"
PAPER_DATA = tomllib.loads(PAPER.read_text(encoding="utf-8"))


def _examples(kind: str) -> int:
    total = CI_CASES if os.environ.get("CI") else CI_CASES // 10
    return max(10, int(total * SHARE[kind]))


def _settings(kind: str) -> settings:
    return settings(max_examples=_examples(kind), deadline=None, database=None, derandomize=True,
                    suppress_health_check=list(HealthCheck))


class _Hang(Exception):
    pass


def run(argv: list[str]) -> tuple[int, str]:
    """``visnav ARGV`` in-process: (exit code, stdout + stderr), within :data:`CASE_BOUND_S`."""
    out, err = io.StringIO(), io.StringIO()

    def alarm(signum, frame):
        raise _Hang(f"visnav {' '.join(argv)} ran over {CASE_BOUND_S} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, CASE_BOUND_S)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = cli.main(argv)
            except SystemExit as exit_:  # argparse's usage errors and --help
                code = exit_.code if isinstance(exit_.code, int) else EXIT_BAD_INPUT
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    text = out.getvalue() + err.getvalue()
    assert "_Hang" not in text, f"hang: {text[-500:]}"
    return code, text


def assert_contract(argv: list[str], allowed: set[int]) -> tuple[int, str]:
    code, text = run(argv)
    assert "Traceback (most recent call last)" not in text, text[-2000:]
    assert code != EXIT_INTERNAL, f"internal error on visnav {' '.join(argv)}: {text[-800:]}"
    assert code in allowed, f"exit {code} on visnav {' '.join(argv)} (allowed {sorted(allowed)}): {text[-800:]}"
    if code == EXIT_BAD_INPUT:
        assert "error" in text.lower() or "usage" in text.lower(), text[-800:]
    return code, text


# --------------------------------------------------------------------------- TOML writing
def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        text = repr(v)
        return text if any(c in text for c in ".eE") else text + ".0"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(data: dict[str, Any]) -> str:
    """A TOML text of ``data`` (scalars, arrays, tables, arrays of tables; keys quoted)."""
    lines = [f"{json.dumps(k)} = {_toml_value(v)}" for k, v in data.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v))]
    for k, v in data.items():
        if isinstance(v, dict):
            lines.append(f"\n[{json.dumps(k)}]")
            lines += [f"{json.dumps(kk)} = {_toml_value(vv)}" for kk, vv in v.items()]
    for k, v in data.items():
        if isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for item in v:
                lines.append(f"\n[[{json.dumps(k)}]]")
                lines += [f"{json.dumps(kk)} = {_toml_value(vv)}" for kk, vv in item.items()]
    return "\n".join(lines) + "\n"


def _leaves(data: Any, path: tuple = ()) -> list[tuple]:
    out = []
    if isinstance(data, dict):
        for k, v in data.items():
            out += _leaves(v, path + (k,)) or [path + (k,)]
    elif isinstance(data, list) and data and all(isinstance(x, dict) for x in data):
        for i, v in enumerate(data):
            out += _leaves(v, path + (i,))
    else:
        return [path] if path else []
    return out


SCENARIO_LEAVES = _leaves(PAPER_DATA)
HOSTILE = st.sampled_from([
    math.nan, math.inf, -math.inf, 0.0, -0.0, -1.0, 5e-324, 1e-12, 1.7976931348623157e308, 1e12, 1e300,
    10 ** 30, -(10 ** 18), 0, 1, True, False, "", "text", "nan", [], [1.0], [1.0, 2.0, 3.0, 4.0], {"x": 1.0},
]) | st.floats(allow_nan=True, allow_infinity=True) | st.integers(min_value=-(10 ** 20), max_value=10 ** 20) \
    | st.text(max_size=8)
HOSTILE = HOSTILE.map(lambda v: json.loads(json.dumps(v)) if isinstance(v, (list, dict)) else v)  # fresh containers


def _set(data: Any, path: tuple, value: Any) -> None:
    for p in path[:-1]:
        data = data[p]
    data[path[-1]] = value


def _delete(data: Any, path: tuple) -> None:
    for p in path[:-1]:
        data = data[p]
    del data[path[-1]]


@st.composite
def scenario_data(draw) -> dict[str, Any]:
    data = json.loads(json.dumps(PAPER_DATA))  # a deep copy
    for _ in range(draw(st.integers(1, 3))):
        action = draw(st.sampled_from(["set", "set", "set", "delete", "unknown", "obstacles"]))
        leaves = _leaves(data)
        if action == "set" and leaves:
            _set(data, draw(st.sampled_from(leaves)), draw(HOSTILE))
        elif action == "delete" and leaves:
            _delete(data, draw(st.sampled_from(leaves)))
        elif action == "unknown":
            table = draw(st.sampled_from([None] + [k for k, v in data.items() if isinstance(v, dict)]))
            key = draw(st.sampled_from(["spurious", "duration", "d_minus", "Obstacles", "é"]))
            (data if table is None else data[table])[key] = draw(HOSTILE)
        elif action == "obstacles":
            data["obstacles"] = draw(st.sampled_from([[], data.get("obstacles", [])[:1],
                                                      (data.get("obstacles") or [{}]) * 3]))
    return data


# --------------------------------------------------------------------------- scenario files
@_settings("scenario")
@given(data=scenario_data())
def test_generated_scenario_files(tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("scenario")
    path = folder / "s.toml"
    path.write_text(to_toml(data), encoding="utf-8")
    code, text = assert_contract(["mode-graph", "--scenario", str(path), "--format", "json"], {EXIT_OK, EXIT_BAD_INPUT})
    if code == EXIT_OK:
        again, text2 = run(["mode-graph", "--scenario", str(path), "--format", "json"])
        assert (again, text2) == (code, text)


# --------------------------------------------------------------------------- raw bytes
BYTE_KINDS = st.one_of(
    st.just(("bom", 0)), st.tuples(st.just("utf8"), st.integers(0, 4000), st.sampled_from([b"\xff", b"\xc3", b"\xed\xa0\x80", b"\x00"])),
    st.tuples(st.just("truncate"), st.integers(0, 20000)), st.tuples(st.just("nest"), st.sampled_from([50, 500, 5000, 20000])),
    st.tuples(st.just("digits"), st.sampled_from([20, 400, 5000, 50000])), st.just(("duplicate", 0)),
    st.tuples(st.just("binary"), st.binary(max_size=200)), st.just(("empty", 0)), st.just(("nonascii_key", 0)),
    st.just(("inline", 0)))
"""A short description of each hostile file (the falsifying example stays readable); :func:`hostile_bytes` builds it."""


def hostile_bytes(case: tuple) -> bytes:
    base = PAPER.read_bytes()
    kind = case[0]
    if kind == "bom":
        return b"\xef\xbb\xbf" + base
    if kind == "utf8":
        at = min(case[1], len(base))
        return base[:at] + case[2] + base[at:]
    if kind == "truncate":
        return base[:case[1]]
    if kind == "nest":
        return b"x = " + b"[" * case[1] + b"]" * case[1] + b"\n" + base
    if kind == "digits":
        return base.replace(b"duration_s = 120.0", b"duration_s = " + b"9" * case[1])
    if kind == "duplicate":
        return base.replace(b"duration_s = 120.0", b"duration_s = 120.0\nduration_s = 60.0")
    if kind == "binary":
        return case[1]
    if kind == "empty":
        return b""
    if kind == "nonascii_key":
        return "durée = 1.0\n".encode() + base
    return base.replace(b"[limits]", b"limits = {v_max_mps = 0.6}\n[limits]")


@_settings("bytes")
@given(case=BYTE_KINDS)
def test_hostile_scenario_bytes(tmp_path_factory, case):
    path = tmp_path_factory.mktemp("bytes") / "s.toml"
    path.write_bytes(hostile_bytes(case))
    assert_contract(["mode-graph", "--scenario", str(path)], {EXIT_OK, EXIT_BAD_INPUT})


@pytest.mark.parametrize("where", ["directory", "missing", "fifo_like"])
def test_scenario_paths_that_are_not_files(tmp_path, where):
    path = tmp_path / "s.toml"
    if where == "directory":
        path.mkdir()
    elif where == "fifo_like":
        path = Path("/dev/null")
    assert_contract(["mode-graph", "--scenario", str(path)], {EXIT_BAD_INPUT})


# --------------------------------------------------------------------------- counterexample files
def _valid_counterexample() -> dict[str, Any]:
    from visnav.fuzzing.counterexamples import Counterexample, counterexample_to_json

    row = (1.0, 1.6, 1.0, 160.0, 320.0, 0.0, 0.0, 1.0)
    cx = Counterexample(property="mu_range", variant="resolved", kind="signals", message="m",
                        measurements=(row, row))
    return json.loads(counterexample_to_json(cx))


VALID_CX = _valid_counterexample()
CX_HOSTILE = HOSTILE | st.just(None) | st.lists(st.lists(st.floats(), max_size=3), max_size=3)
"""(``HOSTILE`` draws fresh lists and tables: a drawn container is never shared between examples.)"""


@st.composite
def counterexample_data(draw) -> Any:
    data = json.loads(json.dumps(VALID_CX))
    for _ in range(draw(st.integers(1, 3))):
        action = draw(st.sampled_from(["set", "set", "delete", "unknown", "top"]))
        leaves = [p for p in _json_leaves(data)]
        if action == "set" and leaves:
            _set(data, draw(st.sampled_from(leaves)), draw(CX_HOSTILE))
        elif action == "delete" and leaves:
            _delete(data, draw(st.sampled_from(leaves)))
        elif action == "unknown" and isinstance(data, dict):
            data[draw(st.sampled_from(["extra", "Property", "versions"]))] = draw(CX_HOSTILE)
        elif action == "top":
            return draw(CX_HOSTILE)
    return data


def _json_leaves(data: Any, path: tuple = ()) -> list[tuple]:
    if isinstance(data, dict) and data:
        return [q for k, v in data.items() for q in _json_leaves(v, path + (k,))] + ([path] if path else [])
    if isinstance(data, list) and data:
        return [q for i, v in enumerate(data) for q in _json_leaves(v, path + (i,))] + ([path] if path else [])
    return [path] if path else []


@_settings("counterexample")
@given(data=counterexample_data())
def test_generated_counterexample_files(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("cx") / "cx.json"
    path.write_text(json.dumps(data, allow_nan=True), encoding="utf-8")
    code, text = assert_contract(["replay", str(path)], {EXIT_OK, EXIT_TASK_FAILED, EXIT_BAD_INPUT})
    if code != EXIT_BAD_INPUT:
        assert run(["replay", str(path)]) == (code, text)


# --------------------------------------------------------------------------- argument lists
def _subcommands() -> dict[str, list[str]]:
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return {name: [o for a in p._actions for o in a.option_strings if o.startswith("--") and o != "--help"]
            for name, p in sub.choices.items()}


SUBCOMMANDS = _subcommands()
ARG_HOSTILE = st.sampled_from(["-1", "0", "nan", "inf", "-inf", "1e309", "5e-324", "", " ", "x", "1.5", "10**9",
                               "99999999999999999999999", "/", "/dev/null", "/proc/visnav-nope/x", "--json", "é",
                               "paper:nope", "no_such_module:obj", "../../etc/passwd"])


@st.composite
def argv_lists(draw) -> list[str]:
    name = draw(st.sampled_from(sorted(SUBCOMMANDS)))
    options = SUBCOMMANDS[name]
    argv = [name]
    hostile = draw(st.sampled_from(options)) if options else None
    for opt in draw(st.lists(st.sampled_from(options), max_size=3, unique=True)) if options else []:
        argv += [opt, draw(ARG_HOSTILE)]
    if hostile is not None:
        argv += [hostile, draw(st.sampled_from(["-1", "nan", "/proc/visnav-nope/x", "x", "1e309", ""]))]
    argv.append(draw(st.sampled_from(["--no-such-option", "--scenario=/proc/visnav-nope.toml"])))
    return argv


@_settings("argv")
@given(argv=argv_lists())
def test_generated_argument_lists(argv):
    # every list carries an unknown option or an unreadable scenario: it must be refused before anything runs
    assert_contract(argv, {EXIT_BAD_INPUT})


# --------------------------------------------------------------------------- results files of a campaign
RESULT_MUTATIONS = st.lists(st.one_of(
    st.tuples(st.just("cut"), st.integers(0, 400)),
    st.tuples(st.just("garbage"), st.integers(0, 6), st.sampled_from([b"{", b"nul\x00", b"\xff\xfe", b"[]", b"{}",
                                                                      b'{"result": 1}', b"1e999", b"-" * 300])),
    st.tuples(st.just("nest"), st.integers(0, 6), st.sampled_from([70, 1000, 20000])),
    st.tuples(st.just("foreign"), st.integers(1, 5)),
    st.tuples(st.just("value"), st.integers(1, 5), HOSTILE),
    st.tuples(st.just("duplicate"), st.integers(1, 5)),
    st.tuples(st.just("header"), HOSTILE),
), min_size=1, max_size=3)
"""Edits of a valid results file: cut bytes, garbage or deeply nested lines, a line of another campaign (its own
valid checksum), a changed value, a duplicated line, a changed header."""


def _mutated_results(lines: list[bytes], edits: list[tuple], other: list[bytes]) -> bytes:
    import copy

    out = list(lines)
    for edit in edits:
        kind = edit[0]
        if kind == "garbage":
            out.insert(min(edit[1], len(out)), edit[2])
        elif kind == "nest":
            out.insert(min(edit[1], len(out)), b"[" * edit[2] + b"]" * edit[2])
        elif kind == "foreign" and edit[1] < len(out):
            out[edit[1]] = other[min(edit[1], len(other) - 1)]
        elif kind == "value" and edit[1] < len(out):
            try:
                line = json.loads(out[edit[1]])
                line["result"]["value"] = copy.deepcopy(edit[2])
                out[edit[1]] = json.dumps(line, allow_nan=True).encode()
            except (ValueError, TypeError, KeyError):
                pass
        elif kind == "duplicate" and edit[1] < len(out):
            out.insert(edit[1], out[edit[1]])
        elif kind == "header":
            try:
                header = json.loads(out[0])
                header["spec_hash"] = copy.deepcopy(edit[1])
                out[0] = json.dumps(header, allow_nan=True).encode()
            except (ValueError, TypeError, KeyError, IndexError):
                pass
    data = b"\n".join(out) + b"\n"
    cut = next((e[1] for e in edits if e[0] == "cut"), None)
    return data if cut is None else data[:max(0, len(data) - cut)]


def _results_file(folder: Path, spec_hash: str, offset: float = 0.0) -> tuple[list[bytes], list[dict]]:
    from visnav.app.campaign_store import ResultCodec, open_store

    codec = ResultCodec(to_dict=dict, from_dict=dict, index=lambda r: r["i"])
    results = [{"i": i, "value": offset + 0.25 * i, "outcome": "success"} for i in range(5)]
    store, _ = open_store(folder / "results.jsonl", {"format": "harness", "version": 1, "spec_hash": spec_hash},
                          codec, samples=5)
    try:
        for r in results:
            store.append(r)
    finally:
        store.close()
    return (folder / "results.jsonl").read_bytes().splitlines(), results


_STORES: dict[str, Any] = {}


@_settings("results")
@given(edits=RESULT_MUTATIONS)
def test_generated_results_files(tmp_path_factory, edits):
    from visnav.app.campaign_store import CampaignStoreError, ResultCodec, open_store

    if not _STORES:  # one valid file of each campaign, copied into every case
        _STORES["other"] = _results_file(tmp_path_factory.mktemp("other"), "another-campaign", offset=100.0)[0]
        _STORES["this"] = _results_file(tmp_path_factory.mktemp("this"), "this-campaign")
    other = _STORES["other"]  # its results differ from ours
    lines, written = _STORES["this"]
    folder = tmp_path_factory.mktemp("results")
    (folder / "results.jsonl").write_bytes(_mutated_results(lines, edits, other))
    codec = ResultCodec(to_dict=dict, from_dict=dict, index=lambda r: r["i"])
    header = {"format": "harness", "version": 1, "spec_hash": "this-campaign"}
    try:
        store, report = open_store(folder / "results.jsonl", header, codec, samples=5)
    except CampaignStoreError as err:  # the documented refusal: names the file and the fix
        assert "results.jsonl" in str(err) and "Traceback" not in str(err)
        return
    try:
        kept = list(store.results())
    finally:
        store.close()
    for result in kept:  # nothing changes silently: every result read back is one this campaign wrote
        assert result in written, (result, report)
    assert len({r["i"] for r in kept}) == len(kept)
    again_store, again = open_store(folder / "results.jsonl", header, codec, samples=5)  # repaired: clean now
    try:
        assert list(again_store.results()) == kept and again.bad_lines == ()
    finally:
        again_store.close()
