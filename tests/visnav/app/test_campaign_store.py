"""The campaign results file: durable appends, corruption detection, resume, spec hash, lock, full disks.

Most tests use the store as ``visnav sweep`` does (:func:`visnav.app.cli_sweep.open_campaign_store`,
results :class:`visnav.studies.campaign.SampleResult`); the last ones use it with another kind of
result, through a header mapping and a :class:`ResultCodec` only.
"""

import dataclasses
import errno
import json
import os
import subprocess
import sys

import pytest

import visnav.app.campaign_store as campaign_store
from hybrid.jsonable import canonical_json
from visnav.app.campaign_store import (
    MAX_JSON_DEPTH,
    STORE_VERSION,
    CampaignStoreError,
    CampaignStoreWriteError,
    ResultCodec,
    StoreHints,
    line_checksum,
    lock_path,
    open_store,
)
from visnav.app.cli_sweep import open_campaign_store
from visnav.scenario import load_scenario
from visnav.studies.campaign import CampaignSpec, SampleResult, store_header


@pytest.fixture(scope="module")
def spec():
    return CampaignSpec(scenario=load_scenario("paper"), samples=10, seed=3)


def result(index, outcome="timeout", clearance=0.25):
    return SampleResult(index=index, outcome=outcome, parameters=(("gains.k_path", 4.0 + index / 7),),
                        attempts=1, scenario_digest="ab" * 32, min_clearance_m=clearance + index / 1000,
                        final_feature_error_px=300.0 + index / 3, max_reconstruction_error_px=None,
                        max_depth_error_mm=None, occlusion_duration_s=0.0, sim_time_s=6.0, transitions=2,
                        chatter_count=0, steps=121, within_actuator_limits=True)


def record(data, spec_hash):
    """A results line as the store writes it (canonical JSON, checksum, spec hash)."""
    return canonical_json({"result": data, "sha256": line_checksum(data), "spec_hash": spec_hash})


def write(tmp_path, spec, indices):
    path = tmp_path / "results.jsonl"
    store, report = open_campaign_store(path, spec)
    with store:
        for i in indices:
            store.append(result(i))
    return path, report


def test_new_file_has_header_then_one_line_per_result(tmp_path, spec):
    path, report = write(tmp_path, spec, [4, 1, 7])
    assert report.created and report.results == 0 and report.bad_lines == ()
    lines = path.read_text().splitlines()
    header = json.loads(lines[0])
    assert header["format"] == "visnav-campaign" and header["spec_hash"] == spec.spec_hash()
    assert header["spec"]["seed"] == 3 and header["spec"]["samples"] == 10
    assert header["store_version"] == STORE_VERSION == 2
    records = [json.loads(line) for line in lines[1:]]
    assert [r["result"]["index"] for r in records] == [4, 1, 7]  # in arrival order
    assert all(r["sha256"] == line_checksum(r["result"]) for r in records)
    assert all(r["spec_hash"] == spec.spec_hash() for r in records)  # every line bound to its campaign


def test_reopen_reads_back_equal_results(tmp_path, spec):
    path, _ = write(tmp_path, spec, [4, 1, 7])
    before = path.read_bytes()
    store, report = open_campaign_store(path, spec)
    with store:
        assert store.done == {1, 4, 7}
        assert store.results() == (result(1), result(4), result(7))
        assert report.results == 3 and not report.created and not report.rewritten
    assert path.read_bytes() == before  # a clean file is left untouched


def test_truncated_last_line_is_dropped_and_the_rest_kept(tmp_path, spec):
    path, _ = write(tmp_path, spec, [0, 1, 2])
    text = path.read_text()
    path.write_text(text + text.splitlines()[2][:40])  # a write cut by SIGKILL: no end of line
    store, report = open_campaign_store(path, spec)
    with store:
        assert store.done == {0, 1, 2}
    assert [b.line for b in report.bad_lines] == [5]
    assert "not valid JSON" in report.bad_lines[0].reason and "cut" in report.bad_lines[0].reason
    assert report.rewritten and path.read_text() == text  # rewritten without the cut line


def test_bad_middle_lines_are_reported_by_number_and_reason(tmp_path, spec):
    path, _ = write(tmp_path, spec, [0, 1, 2, 3])
    lines = path.read_text().splitlines()
    altered = json.loads(lines[2])
    altered["result"]["min_clearance_m"] = 9.0  # valid JSON, wrong checksum
    lines[2] = json.dumps(altered, sort_keys=True, separators=(",", ":"))
    lines[3] = "{garbage"
    lines.insert(4, "")
    lines.append(lines[1])  # sample 0 again
    path.write_text("\n".join(lines) + "\n")
    store, report = open_campaign_store(path, spec)
    with store:
        assert store.done == {0, 3}
        assert store.results() == (result(0), result(3))
    reasons = {b.line: b.reason for b in report.bad_lines}
    assert set(reasons) == {3, 4, 5, 7}
    assert "checksum mismatch" in reasons[3]
    assert "not valid JSON" in reasons[4]
    assert reasons[5] == "empty line"
    assert "sample 0 again (already on line 2, identical)" == reasons[7]
    assert len(path.read_text().splitlines()) == 3  # header + the two valid lines


def test_malformed_field_and_out_of_range_index(tmp_path, spec):
    path, _ = write(tmp_path, spec, [0])
    bad = result(1).as_dict()
    bad["outcome"] = "exploded"
    far = result(2).as_dict()
    far["index"] = 10
    with path.open("a") as handle:
        for data in (bad, far):
            handle.write(record(data, spec.spec_hash()) + "\n")
    store, report = open_campaign_store(path, spec)
    store.close()
    reasons = [b.reason for b in report.bad_lines]
    assert "malformed result (field 'outcome' = 'exploded': expected one of success" in reasons[0]
    assert reasons[1] == "index 10 outside the campaign's [0, 10)"


def test_other_campaign_is_refused_naming_the_difference(tmp_path, spec):
    path, _ = write(tmp_path, spec, [0])
    other = CampaignSpec(scenario=spec.scenario, samples=10, seed=4)
    with pytest.raises(CampaignStoreError, match=r"belongs to another campaign .*seed 3 in the file, 4 now.*"
                                                  r"fix: rerun with the options of the interrupted campaign"):
        open_campaign_store(path, other)


@pytest.mark.parametrize("content, problem", [
    ("", "the file is empty"),
    ("hello\n", "line 1 is not a campaign header"),
    ('{"format": "something-else"}\n', "line 1 is not a visnav-campaign header"),
])
def test_not_a_campaign_file(tmp_path, spec, content, problem):
    path = tmp_path / "results.jsonl"
    path.write_text(content)
    with pytest.raises(CampaignStoreError, match=problem + ".*fix: choose another --out"):
        open_campaign_store(path, spec)
    assert path.read_text() == content  # never overwritten


def test_compact_orders_by_index_whatever_the_arrival_order(tmp_path, spec):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, _ = write(tmp_path / "a", spec, [3, 0, 2, 1])
    b, _ = write(tmp_path / "b", spec, [1, 2, 0, 3])
    for path in (a, b):
        store, _ = open_campaign_store(path, spec)
        with store:
            store.compact()
            store.append(result(5))  # still appendable after compaction
    assert a.read_bytes() == b.read_bytes()
    indices = [json.loads(line)["result"]["index"] for line in a.read_text().splitlines()[1:]]
    assert indices == [0, 1, 2, 3, 5]


def test_append_refuses_a_stored_or_foreign_index(tmp_path, spec):
    store, _ = open_campaign_store(tmp_path / "results.jsonl", spec)
    with store:
        store.append(result(2))
        with pytest.raises(ValueError, match=r"sample 2: expected a new index in \[0, 10\)"):
            store.append(result(2))
        with pytest.raises(ValueError, match=r"sample 10: expected a new index"):
            store.append(result(10))


def test_second_writer_is_refused_while_the_first_is_open(tmp_path, spec):
    path = tmp_path / "results.jsonl"
    store, _ = open_campaign_store(path, spec)
    with store:
        assert json.loads(lock_path(path).read_text())["pid"] == os.getpid()
        with pytest.raises(CampaignStoreError, match=rf"another process \(pid {os.getpid()}\) is writing this "
                                                     rf"campaign.*fix: wait for the other `visnav sweep` to finish "
                                                     rf"\(or stop it: kill {os.getpid()}\), or choose another --out"):
            open_campaign_store(path, spec)
    assert not lock_path(path).exists()  # removed on close
    store2, _ = open_campaign_store(path, spec)  # released on close
    store2.close()


def test_deleting_the_lock_file_does_not_let_a_second_writer_in(tmp_path, spec):
    path = tmp_path / "results.jsonl"
    store, _ = open_campaign_store(path, spec)
    with store:
        lock_path(path).unlink()  # the lock is the flock held by the open folder, not this file
        with pytest.raises(CampaignStoreError, match=r"another process \(pid unknown: no readable lock file\) is "
                                                     r"writing this campaign"):
            open_campaign_store(path, spec)
        store.append(result(1))  # the holder carries on
    store, _ = open_campaign_store(path, spec)
    with store:
        assert store.done == {1}


def test_a_lock_held_by_another_process_names_its_pid_and_dies_with_it(tmp_path, spec):
    path = tmp_path / "results.jsonl"
    write(tmp_path, spec, [0])
    code = ("import sys, time; from visnav.app.campaign_store import ResultCodec, open_store; "
            "codec = ResultCodec(to_dict=dict, from_dict=dict, index=lambda r: r['i']); "
            "s, _ = open_store(sys.argv[1], {'format': 'f', 'version': 1, 'spec_hash': 'h'}, codec, samples=1); "
            "print('held', flush=True); time.sleep(60)")
    # another campaign file in the same folder: the lock covers the folder
    holder = subprocess.Popen([sys.executable, "-c", code, str(tmp_path / "other.jsonl")], stdout=subprocess.PIPE,
                              text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        with pytest.raises(CampaignStoreError, match=rf"another process \(pid {holder.pid}\) is writing"):
            open_campaign_store(path, spec)
    finally:
        holder.kill()  # SIGKILL: no clean-up, its lock file stays behind
        holder.wait(timeout=30)
    assert json.loads(lock_path(tmp_path / "other.jsonl").read_text())["pid"] == holder.pid  # stale
    store, _ = open_campaign_store(path, spec)  # the lock died with its process
    with store:
        assert store.done == {0}
    lock_path(path).write_text(json.dumps({"pid": holder.pid}))  # a stale lock file of this very campaign
    store, _ = open_campaign_store(path, spec)  # never blocks
    store.close()


def test_without_folder_locks_the_lock_file_itself_is_locked(tmp_path, spec, monkeypatch):
    real_open = os.open

    def no_folder(path, flags, *args):
        if os.path.isdir(path):
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return real_open(path, flags, *args)

    monkeypatch.setattr(campaign_store.os, "open", no_folder)
    path = tmp_path / "results.jsonl"
    store, _ = open_campaign_store(path, spec)
    with store:
        with pytest.raises(CampaignStoreError, match=rf"another process \(pid {os.getpid()}\) is writing"):
            open_campaign_store(path, spec)
    assert lock_path(path).exists()  # kept: removing a locked file would let a waiting opener in
    open_campaign_store(path, spec)[0].close()


def test_header_line_is_the_canonical_json_of_the_campaign_header(tmp_path, spec):
    path, _ = write(tmp_path, spec, [2])
    header, line = path.read_text().splitlines()
    assert header == canonical_json({**store_header(spec), "store_version": 2})
    assert line == record(result(2).as_dict(), spec.spec_hash())


# ---------------------------------------------------------------------------------------------
# Lines of another campaign, files of an older visnav, nesting
# ---------------------------------------------------------------------------------------------


def test_a_line_of_another_campaign_is_dropped_not_counted(tmp_path, spec):
    path, _ = write(tmp_path, spec, [0, 1])
    other = CampaignSpec(scenario=spec.scenario, samples=10, seed=4)
    foreign = result(2, outcome="success").as_dict()  # same index range, valid checksum, other campaign
    with path.open("a") as handle:
        handle.write(record(foreign, other.spec_hash()) + "\n")
        handle.write(record(result(3).as_dict(), spec.spec_hash()) + "\n")
    store, report = open_campaign_store(path, spec)
    with store:
        assert store.done == {0, 1, 3}
        assert all(r.outcome == "timeout" for r in store.results())
    assert [b.line for b in report.bad_lines] == [4]
    assert report.bad_lines[0].reason == (f"a result of another campaign (spec hash {other.spec_hash()[:12]}..., "
                                          f"this campaign {spec.spec_hash()[:12]}...): not counted")
    assert report.rewritten and len(path.read_text().splitlines()) == 4  # header + 0, 1, 3


def test_a_line_without_spec_hash_in_a_current_file_is_dropped(tmp_path, spec):
    path, _ = write(tmp_path, spec, [0])
    data = result(1).as_dict()
    with path.open("a") as handle:
        handle.write(json.dumps({"result": data, "sha256": line_checksum(data)}) + "\n")
    store, report = open_campaign_store(path, spec)
    store.close()
    assert store.done == {0}
    assert report.bad_lines[0].reason.startswith("not bound to a campaign (no 'spec_hash')")


def test_a_file_of_the_previous_store_version_is_migrated(tmp_path, spec):
    """Written before lines carried the spec hash: the header has no store_version, lines no spec_hash."""
    path = tmp_path / "results.jsonl"
    old = [canonical_json(store_header(spec))] + [
        canonical_json({"result": result(i).as_dict(), "sha256": line_checksum(result(i).as_dict())}) for i in (2, 0)]
    path.write_text("\n".join(old) + "\n")
    store, report = open_campaign_store(path, spec)
    with store:
        assert report.migrated and report.rewritten and report.results == 2 and report.bad_lines == ()
        assert store.done == {0, 2}
        store.append(result(1))
        store.compact()
    (tmp_path / "fresh").mkdir()
    fresh, _ = write(tmp_path / "fresh", spec, [0, 1, 2])
    assert path.read_bytes() == fresh.read_bytes()  # the same bytes as a campaign run with this visnav


def test_a_newer_store_version_is_refused(tmp_path, spec):
    path = tmp_path / "results.jsonl"
    path.write_text(canonical_json({**store_header(spec), "store_version": 3}) + "\n")
    with pytest.raises(CampaignStoreError, match=r"store version 3, this visnav reads 1 and 2.*fix: choose another "
                                                  r"--out, or move this file away to start afresh"):
        open_campaign_store(path, spec)


def test_deeply_nested_lines_are_corrupt_lines_not_a_recursion_error(tmp_path, spec):
    path, _ = write(tmp_path, spec, [0])
    with path.open("a") as handle:
        handle.write("[" * 1000 + "]" * 1000 + "\n")
        handle.write('{"result":' + '{"a":' * 5000 + "1" + "}" * 5000 + ',"sha256":"x","spec_hash":"y"}\n')
        handle.write(record(result(1).as_dict(), spec.spec_hash()) + "\n")
    store, report = open_campaign_store(path, spec)
    store.close()
    assert store.done == {0, 1}
    assert [str(b) for b in report.bad_lines] == [
        f"line 3: JSON nested 1000 levels deep (at most {MAX_JSON_DEPTH}): corrupt or not a record",
        f"line 4: JSON nested 5001 levels deep (at most {MAX_JSON_DEPTH}): corrupt or not a record"]


def test_a_deeply_nested_header_is_not_a_campaign_header(tmp_path, spec):
    path = tmp_path / "results.jsonl"
    path.write_text("[" * 1000 + "]" * 1000 + "\n")
    with pytest.raises(CampaignStoreError, match=r"line 1 is not a campaign header \(JSON nested 1000 levels deep.*"
                                                  r"fix: choose another --out"):
        open_campaign_store(path, spec)


def test_brackets_inside_strings_do_not_count_as_nesting():
    text = json.dumps({"toml": "[[obstacles]]\n" * 200, "q": '\\"[' * 100, "list": [[1]]})
    assert campaign_store._too_deep(text) is None
    assert campaign_store._too_deep("[" * 65 + "]" * 65) == 65
    assert campaign_store._too_deep("[" * 64 + "]" * 64) is None


# ---------------------------------------------------------------------------------------------
# Full disks: every failed write leaves a file to resume from, and says so
# ---------------------------------------------------------------------------------------------


def enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_cut_last_line_is_truncated_in_place_without_free_space(tmp_path, spec, monkeypatch):
    path, _ = write(tmp_path, spec, [0, 1])
    text = path.read_text()
    path.write_text(text + text.splitlines()[1][:30])
    monkeypatch.setattr(campaign_store, "write_text_atomic", enospc)  # no room for a rewrite
    store, report = open_campaign_store(path, spec)
    with store:
        assert report.rewritten and [b.line for b in report.bad_lines] == [4] and store.done == {0, 1}
    assert path.read_text() == text


def test_a_last_line_without_its_end_of_line_is_completed(tmp_path, spec):
    path, _ = write(tmp_path, spec, [0, 1])
    text = path.read_text()
    path.write_text(text[:-1])
    store, report = open_campaign_store(path, spec)
    store.close()
    assert report.rewritten and report.bad_lines == () and store.done == {0, 1} and path.read_text() == text


def test_a_repair_that_cannot_be_written_leaves_the_file_unchanged(tmp_path, spec, monkeypatch):
    path, _ = write(tmp_path, spec, [0, 1, 2])
    lines = path.read_text().splitlines()
    lines[2] = "{garbage"  # a bad middle line: needs a rewrite
    damaged = "\n".join(lines) + "\n"
    path.write_text(damaged)
    monkeypatch.setattr(campaign_store, "write_text_atomic", enospc)
    with pytest.raises(CampaignStoreWriteError, match=r"rewriting it without its 1 bad line\(s\) failed \(No space "
                                                       r"left on device; it needs about \d+ bytes free\); the file is "
                                                       r"unchanged") as info:
        open_campaign_store(path, spec)
    assert info.value.errno == errno.ENOSPC and info.value.resource
    assert path.read_text() == damaged
    monkeypatch.undo()
    open_campaign_store(path, spec)[0].close()  # the lock was released


def test_a_failed_append_is_undone_and_close_does_not_raise(tmp_path, spec, monkeypatch):
    path, _ = write(tmp_path, spec, [0])
    before = path.read_bytes()

    def half_then_full(fd, data):
        os.write(fd, data[:len(data) // 2])
        raise OSError(errno.ENOSPC, "No space left on device")

    store, _ = open_campaign_store(path, spec)
    monkeypatch.setattr(campaign_store, "_write_all", half_then_full)
    with store:
        with pytest.raises(CampaignStoreWriteError, match=r"appending sample 1 failed \(No space left on device\); "
                                                           r"the 1 results stored before are kept and valid"):
            store.append(result(1))
        assert store.done == {0}
    store.close()  # again: idempotent, never raises
    assert path.read_bytes() == before  # the half line was cut away
    monkeypatch.undo()
    store, report = open_campaign_store(path, spec)
    with store:
        assert report.bad_lines == () and not report.rewritten
        store.append(result(1))


def test_compact_writes_nothing_when_the_file_is_in_index_order(tmp_path, spec, monkeypatch):
    path = tmp_path / "results.jsonl"
    store, _ = open_campaign_store(path, spec)
    monkeypatch.setattr(campaign_store, "write_text_atomic", enospc)  # a rewrite would fail
    with store:
        for i in (0, 1, 4):
            store.append(result(i))
        assert store.in_index_order
        store.compact()  # nothing to do, nothing written
        store.append(result(2))
        assert not store.in_index_order
        with pytest.raises(CampaignStoreWriteError, match=r"rewriting it in index order failed \(No space left on "
                                                           r"device; it needs about \d+ bytes free\); the file is "
                                                           r"unchanged: its 4 results are valid, in the order they "
                                                           r"arrived"):
            store.compact()
        store.append(result(3))  # still appendable after a failed compaction
    monkeypatch.undo()
    store, report = open_campaign_store(path, spec)
    with store:
        assert report.bad_lines == () and store.done == {0, 1, 2, 3, 4}
        store.compact()
    assert [json.loads(line)["result"]["index"] for line in path.read_text().splitlines()[1:]] == [0, 1, 2, 3, 4]
    store, _ = open_campaign_store(path, spec)
    with store:
        assert store.in_index_order  # read back as such: a resumed campaign is not rewritten at its end either
    lines = path.read_text().splitlines()
    lines[2] = json.dumps(json.loads(lines[2]), sort_keys=True)  # the same record, not in the store's spelling
    path.write_text("\n".join(lines) + "\n")
    store, report = open_campaign_store(path, spec)
    with store:
        assert report.bad_lines == () and not store.in_index_order
        store.compact()
    assert path.read_text().splitlines()[2] == record(result(1).as_dict(), spec.spec_hash())


def test_the_line_rebuilt_on_reading_is_the_line_written():
    data = result(3).as_dict()
    assert campaign_store._line_of(canonical_json(data), line_checksum(data), "ab" * 32) == record(data, "ab" * 32)



# ---------------------------------------------------------------------------------------------
# Another kind of campaign: a header mapping and a codec, nothing of the robot
# ---------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Trial:
    case: int
    falsified: bool
    robustness: float


TRIALS = ResultCodec(
    to_dict=dataclasses.asdict,
    from_dict=lambda data: Trial(**data),
    index=lambda trial: trial.case,
)
HEADER = {"format": "falsification", "version": 3, "spec_hash": "f" * 64, "spec": {"budget": 5, "property": "p"}}
HINTS = StoreHints(writer="visnav falsify", out_option="--results", same_campaign="the same --budget")


def test_any_result_kind_round_trips_and_resumes(tmp_path):
    path = tmp_path / "trials.jsonl"
    store, report = open_store(path, HEADER, TRIALS, samples=5, hints=HINTS)
    with store:
        assert report.created
        store.append(Trial(case=3, falsified=True, robustness=-0.25))
        store.append(Trial(case=0, falsified=False, robustness=1.5))
    lines = path.read_text().splitlines()
    assert lines[0] == canonical_json({**HEADER, "store_version": 2})
    assert json.loads(lines[1]) == {"result": {"case": 3, "falsified": True, "robustness": -0.25},
                                    "sha256": line_checksum({"case": 3, "falsified": True, "robustness": -0.25}),
                                    "spec_hash": "f" * 64}
    store, report = open_store(path, HEADER, TRIALS, samples=5, hints=HINTS)
    with store:
        assert store.done == {0, 3} and report.results == 2
        assert store.results() == (Trial(case=0, falsified=False, robustness=1.5),
                                   Trial(case=3, falsified=True, robustness=-0.25))
        with pytest.raises(ValueError, match=r"sample 5: expected a new index in \[0, 5\)"):
            store.append(Trial(case=5, falsified=False, robustness=0.0))


def test_another_kind_reports_malformed_lines_and_names_its_own_program(tmp_path):
    path = tmp_path / "trials.jsonl"
    store, _ = open_store(path, HEADER, TRIALS, samples=5, hints=HINTS)
    store.close()
    with path.open("a") as handle:
        for data in ({"case": 1, "falsified": True}, {"case": 9, "falsified": True, "robustness": 0.0}):
            handle.write(record(data, HEADER["spec_hash"]) + "\n")
    store, report = open_store(path, HEADER, TRIALS, samples=5, hints=HINTS)
    store.close()
    reasons = [b.reason for b in report.bad_lines]
    assert reasons[0].startswith("malformed result (") and "robustness" in reasons[0]
    assert reasons[1] == "index 9 outside the campaign's [0, 5)"
    other = {**HEADER, "spec_hash": "0" * 64, "spec": {"budget": 6, "property": "p"}}
    with pytest.raises(CampaignStoreError, match=r"budget 5 in the file, 6 now.*expected the same --budget to resume; "
                                                  r"fix: .*choose another --results"):
        open_store(path, other, TRIALS, samples=5, hints=HINTS)
    with pytest.raises(CampaignStoreError, match=r"format version 3, this visnav writes 4.*written by visnav falsify"):
        open_store(path, {**HEADER, "version": 4}, TRIALS, samples=5, hints=HINTS)


def test_header_must_name_format_version_and_spec_hash(tmp_path):
    with pytest.raises(ValueError, match=r"header\['spec_hash'\] = None: expected a non-empty str"):
        open_store(tmp_path / "x.jsonl", {"format": "f", "version": 1}, TRIALS, samples=1)
    with pytest.raises(ValueError, match=r"header\['store_version'\] = 2: expected no such key \(the store writes "
                                         r"it\); fix: remove 'store_version'"):
        open_store(tmp_path / "x.jsonl", {**HEADER, "store_version": 2}, TRIALS, samples=1)
    assert not (tmp_path / "x.jsonl").exists()


def test_a_codec_failing_in_any_way_marks_the_line_malformed(tmp_path):
    def fussy(data):
        if data["case"] == 1:
            raise KeyError("robustness")  # not the ValueError/TypeError of the contract
        return Trial(**data)

    codec = ResultCodec(to_dict=dataclasses.asdict, from_dict=fussy, index=lambda trial: trial.case)
    path = tmp_path / "trials.jsonl"
    store, _ = open_store(path, HEADER, codec, samples=5, hints=HINTS)
    with store:
        store.append(Trial(case=0, falsified=False, robustness=1.0))
        store.append(Trial(case=1, falsified=False, robustness=1.0))
    store, report = open_store(path, HEADER, codec, samples=5, hints=HINTS)
    store.close()
    assert store.done == {0} and report.bad_lines[0].reason == "malformed result ('robustness')"
