"""The campaign results file: durable appends, corruption detection, resume, spec hash.

Most tests use the store as ``visnav sweep`` does (:func:`visnav.app.cli_sweep.open_campaign_store`,
results :class:`visnav.studies.campaign.SampleResult`); the last ones use it with another kind of
result, through a header mapping and a :class:`ResultCodec` only.
"""

import dataclasses
import json

import pytest

from hybrid.jsonable import canonical_json
from visnav.app.campaign_store import CampaignStoreError, ResultCodec, StoreHints, line_checksum, open_store
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
    records = [json.loads(line) for line in lines[1:]]
    assert [r["result"]["index"] for r in records] == [4, 1, 7]  # in arrival order
    assert all(r["sha256"] == line_checksum(r["result"]) for r in records)


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
            handle.write(json.dumps({"result": data, "sha256": line_checksum(data)}) + "\n")
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
        with pytest.raises(CampaignStoreError, match="another process is writing this campaign"):
            open_campaign_store(path, spec)
    store2, _ = open_campaign_store(path, spec)  # released on close
    store2.close()


def test_header_line_is_the_canonical_json_of_the_campaign_header(tmp_path, spec):
    path, _ = write(tmp_path, spec, [2])
    header, line = path.read_text().splitlines()
    assert header == canonical_json(store_header(spec))
    assert line == canonical_json({"result": result(2).as_dict(), "sha256": line_checksum(result(2).as_dict())})


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
    assert json.loads(lines[0]) == HEADER and lines[0] == canonical_json(HEADER)
    assert json.loads(lines[1]) == {"result": {"case": 3, "falsified": True, "robustness": -0.25},
                                    "sha256": line_checksum({"case": 3, "falsified": True, "robustness": -0.25})}
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
            handle.write(json.dumps({"result": data, "sha256": line_checksum(data)}) + "\n")
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
    assert not (tmp_path / "x.jsonl").exists()
