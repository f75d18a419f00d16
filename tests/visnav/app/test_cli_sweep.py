"""``visnav sweep`` at its edges: a held folder, full disks, a summary that cannot be written, a peer that
is not a Dask scheduler, a cluster without workers, foreign and old results lines.

Each case ends with its documented exit code and a one-line message saying what is kept and how to
resume, never a traceback; the resumed campaign then ends byte-identical to an uninterrupted one.
Campaigns are 4 samples of a 6 s scenario run in this process (``--workers 1``), or on fake executors.
"""

import concurrent.futures as cf
import contextlib
import errno
import json
import os
import re
import socket
import threading
from pathlib import Path

import pytest

import analysis.campaigns
import visnav.app.campaign_store as campaign_store
from analysis.campaigns import CampaignBackend, InlineExecutor, WatchedExecutor
from hybrid.jsonable import canonical_json
from visnav.app.campaign_store import line_checksum
from visnav.app.cli import main
from visnav.app.cli_sweep import open_campaign_store
from visnav.scenario import load_scenario
from visnav.studies.campaign import CampaignSpec, run_sample, store_header

PAPER_TOML = Path(__file__).parents[3] / "visnav" / "scenarios" / "paper.toml"
N = 4
SEED = 4


@pytest.fixture(scope="module")
def short_toml(tmp_path_factory):
    text, count = re.subn(r"(?m)^duration_s = 120\.0.*$", "duration_s = 6.0", PAPER_TOML.read_text())
    assert count == 1
    text = text[:text.index("[[requirements]]")] if "[[requirements]]" in text else text
    path = tmp_path_factory.mktemp("scenario") / "short.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def spec(short_toml):
    return CampaignSpec(scenario=load_scenario(str(short_toml)), samples=N, seed=SEED)


def args(short_toml, out, *extra):
    return ["sweep", "--scenario", str(short_toml), "--samples", str(N), "--seed", str(SEED), "--out", str(out),
            "--workers", "1", *extra]


@pytest.fixture(scope="module")
def reference(short_toml, tmp_path_factory):
    out = tmp_path_factory.mktemp("reference")
    assert main(args(short_toml, out)) == 0
    return out


def same_as(reference, out):
    return all((out / name).read_bytes() == (reference / name).read_bytes() for name in ("results.jsonl",
                                                                                          "summary.json"))


def enospc(*_, **__):
    raise OSError(errno.ENOSPC, "No space left on device")


def replace_fails_for(monkeypatch, name, code=errno.ENOSPC):
    """``os.replace`` onto ``name`` fails with ``code`` (the last step of every atomic write)."""
    real = os.replace

    def replace(src, dst, *rest, **options):
        if Path(dst).name == name:
            raise OSError(code, os.strerror(code))
        return real(src, dst, *rest, **options)

    monkeypatch.setattr(os, "replace", replace)


def test_a_second_sweep_on_a_held_folder_exits_2_naming_the_holder(short_toml, spec, tmp_path, capsys):
    store, _ = open_campaign_store(tmp_path / "results.jsonl", spec)
    with store:
        (tmp_path / "campaign.lock").unlink()  # deleting the lock file does not free the folder
        assert main(args(short_toml, tmp_path)) == 2
        assert "another process (pid unknown: no readable lock file) is writing" in capsys.readouterr().err
        (tmp_path / "campaign.lock").write_text(canonical_json({"pid": os.getpid()}))
        assert main(args(short_toml, tmp_path)) == 2
        err = capsys.readouterr().err
    assert err.startswith("visnav: error: campaign file ") and err.count("\n") == 1
    assert f"another process (pid {os.getpid()}) is writing this campaign" in err
    assert "fix: wait for the other `visnav sweep` to finish" in err and "or choose another --out" in err
    assert store.done == set()


def test_disk_full_while_appending_exits_3_and_resumes_identically(short_toml, reference, tmp_path, capsys,
                                                                   monkeypatch):
    calls = []
    real = campaign_store._write_all

    def fills_up(fd, data):
        calls.append(1)
        if len(calls) >= 3:
            os.write(fd, data[:17])  # a part of the line reaches the disk, then it is full
            enospc()
        real(fd, data)

    monkeypatch.setattr(campaign_store, "_write_all", fills_up)
    assert main(args(short_toml, tmp_path)) == 3
    err = capsys.readouterr().err
    results = tmp_path / "results.jsonl"
    assert err == (f"visnav: error: the campaign stopped: appending sample 2 to {results} failed (No space left on "
                   f"device); 2 of {N} samples are stored in {results}, valid; free some space and rerun the same "
                   "command to resume\n")  # one message, no second one from closing the file
    assert not (tmp_path / "summary.json").exists() and not (tmp_path / "campaign.lock").exists()
    monkeypatch.undo()
    assert main(args(short_toml, tmp_path)) == 0
    assert capsys.readouterr().err == ""  # the half line was undone: nothing to repair
    assert same_as(reference, tmp_path)


def test_disk_full_during_the_final_rewrite_keeps_the_complete_file(short_toml, spec, reference, tmp_path, capsys,
                                                                    monkeypatch):
    store, _ = open_campaign_store(tmp_path / "results.jsonl", spec)
    with store:  # samples 3 and 0 stored first: the file is not in index order at the end
        store.append(run_sample(spec, 3))
        store.append(run_sample(spec, 0))
    replace_fails_for(monkeypatch, "results.jsonl")
    assert main(args(short_toml, tmp_path)) == 3
    err = capsys.readouterr().err
    results = tmp_path / "results.jsonl"
    assert re.fullmatch(
        r"visnav: error: every sample is done, but rewriting it in index order failed \(No space left on device; "
        rf"it needs about \d+ bytes free\): {re.escape(str(results))} is kept as it was, complete and valid \(all "
        rf"{N} samples, in the order they finished\); free some space and rerun the same command: it runs nothing "
        r"again, puts the file in index order and writes summary.json\n", err), err
    indices = [json.loads(line)["result"]["index"] for line in results.read_text().splitlines()[1:]]
    assert indices == [3, 0, 1, 2]
    monkeypatch.undo()
    assert main(args(short_toml, tmp_path, "--json")) == 0
    assert json.loads(capsys.readouterr().out)["ran"] == 0
    assert same_as(reference, tmp_path)


def test_a_summary_that_cannot_be_replaced_exits_3_and_a_rerun_writes_it(short_toml, reference, tmp_path, capsys,
                                                                         monkeypatch):
    replace_fails_for(monkeypatch, "summary.json", errno.EACCES)
    assert main(args(short_toml, tmp_path)) == 3
    err = capsys.readouterr().err
    assert err == (f"visnav: error: every sample is done, but {tmp_path / 'summary.json'} could not be written "
                   f"(Permission denied): {tmp_path / 'results.jsonl'} is complete and valid (all {N} samples); fix "
                   "the cause and rerun the same command: it runs nothing again and writes summary.json\n")
    monkeypatch.undo()
    assert main(args(short_toml, tmp_path)) == 0
    assert same_as(reference, tmp_path)
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]  # no partial file left


def test_disk_full_writing_the_summary_says_to_free_space(short_toml, tmp_path, capsys, monkeypatch):
    replace_fails_for(monkeypatch, "summary.json")
    assert main(args(short_toml, tmp_path)) == 3
    err = capsys.readouterr().err
    assert "could not be written (No space left on device)" in err and "free some space and rerun" in err


def test_a_summary_path_that_is_a_folder_is_refused_before_running(short_toml, tmp_path, capsys):
    (tmp_path / "summary.json").mkdir()
    assert main(args(short_toml, tmp_path)) == 2
    err = capsys.readouterr().err
    assert "summary.json exists and is not a file" in err and "move" in err and "choose another --out" in err
    assert not (tmp_path / "results.jsonl").exists()  # nothing was run


def test_a_peer_that_is_not_a_dask_scheduler_exits_2(short_toml, tmp_path, capsys):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    clients = []

    def serve():
        with contextlib.suppress(OSError):
            while True:
                client, _ = server.accept()
                clients.append(client)
                client.sendall(b"SSH-2.0-OpenSSH_9.2p1\r\n")

    threading.Thread(target=serve, daemon=True).start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    try:
        code = main(["sweep", "--scenario", str(short_toml), "--samples", "2", "--out", str(tmp_path), "--scheduler",
                     address, "--connect-timeout", "2"])
    finally:
        server.close()
        for client in clients:
            client.close()
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith(f"visnav: error: --scheduler '{address}': not a Dask scheduler at {address} (it sent "
                          "b'SSH-2.0-OpenSSH_9.2p1\\r\\n'; reading its first message as the Dask protocol failed: "
                          "MemoryError: ")
    assert err.endswith("fix: give the --scheduler of a Dask scheduler (`dask scheduler` prints it), not another "
                        "service's port\n") and err.count("\n") == 1


def test_an_ipv6_scheduler_address_is_accepted(short_toml, tmp_path, capsys):
    code = main(["sweep", "--scenario", str(short_toml), "--samples", "2", "--out", str(tmp_path), "--scheduler",
                 "tcp://[::1]:1", "--connect-timeout", "0.5"])
    err = capsys.readouterr().err
    assert code == 2 and "--scheduler 'tcp://[::1]:1': no Dask scheduler answered (" in err  # reached, not refused
    assert "expected an address" not in err


class Stalling(cf.Executor):
    """Runs the first ``runs`` tasks, then leaves every task pending forever (a cluster without workers)."""

    def __init__(self, runs):
        self.runs = runs

    def submit(self, fn, /, *args, **kwargs):
        if self.runs > 0:
            self.runs -= 1
            return InlineExecutor().submit(fn, *args, **kwargs)
        return cf.Future()


def test_no_worker_alive_exits_3_and_resumes_identically(short_toml, reference, tmp_path, capsys, monkeypatch):
    given = {}

    @contextlib.contextmanager
    def no_workers_after_two(**options):
        given.update(options)
        executor = WatchedExecutor(Stalling(2), lambda: 0, options["no_worker_timeout_s"], where="the test cluster",
                                   poll_s=0.05)
        yield CampaignBackend(executor=executor, kind="dask", workers=1, description="the test cluster", window=1)
        executor.shutdown(wait=False)

    monkeypatch.setattr(analysis.campaigns, "campaign_executor", no_workers_after_two)
    assert main(args(short_toml, tmp_path, "--no-worker-timeout", "0.3")) == 3
    assert given["no_worker_timeout_s"] == 0.3
    err = capsys.readouterr().err
    results = tmp_path / "results.jsonl"
    assert err == ("visnav: error: the campaign stopped: no Dask worker alive for 0.3 s (the limit of "
                   f"--no-worker-timeout) on the test cluster; 2 of {N} samples are stored in {results}; start Dask "
                   "workers (`dask worker ADDRESS`) or raise --no-worker-timeout, and rerun the same command to "
                   "resume\n")
    monkeypatch.undo()
    assert main(args(short_toml, tmp_path)) == 0
    assert same_as(reference, tmp_path)


def test_an_executor_failure_exits_3_with_what_is_kept(short_toml, tmp_path, capsys, monkeypatch):
    class Broken(cf.Executor):
        def submit(self, fn, /, *args, **kwargs):
            future = cf.Future()
            future.set_exception(cf.process.BrokenProcessPool("a worker died"))
            return future

    @contextlib.contextmanager
    def broken(**options):
        yield CampaignBackend(executor=Broken(), kind="process", workers=2, description="broken", window=2)

    monkeypatch.setattr(analysis.campaigns, "campaign_executor", broken)
    assert main(args(short_toml, tmp_path)) == 3
    assert capsys.readouterr().err == (f"visnav: error: the campaign stopped (BrokenProcessPool: a worker died); 0 of "
                                       f"{N} samples are stored in {tmp_path / 'results.jsonl'}; rerun the same "
                                       "command to resume\n")


@pytest.mark.parametrize("value", ["0", "-1", "soon"])
def test_no_worker_timeout_must_be_a_positive_time(short_toml, tmp_path, capsys, value):
    with pytest.raises(SystemExit) as info:
        main(args(short_toml, tmp_path, "--no-worker-timeout", value))
    assert info.value.code == 2 and "--no-worker-timeout" in capsys.readouterr().err


def test_a_foreign_line_is_dropped_and_the_summary_is_unchanged(short_toml, spec, reference, tmp_path, capsys):
    other = CampaignSpec(scenario=spec.scenario, samples=N, seed=SEED + 1)
    data = run_sample(other, 1).as_dict()
    foreign = canonical_json({"result": data, "sha256": line_checksum(data), "spec_hash": other.spec_hash()})
    lines = (reference / "results.jsonl").read_text().splitlines()
    lines[2] = foreign  # sample 1 of another campaign, in place of ours
    (tmp_path / "results.jsonl").write_text("\n".join(lines) + "\n")
    assert main(args(short_toml, tmp_path, "--json")) == 0
    captured = capsys.readouterr()
    assert "line 3: a result of another campaign (spec hash " in captured.err and "not counted; dropped" in captured.err
    assert json.loads(captured.out)["ran"] == 1
    assert same_as(reference, tmp_path)


def test_a_results_file_of_the_previous_format_is_migrated(short_toml, spec, reference, tmp_path, capsys):
    old = [canonical_json(store_header(spec))]
    for line in (reference / "results.jsonl").read_text().splitlines()[1:3]:
        data = json.loads(line)["result"]
        old.append(canonical_json({"result": data, "sha256": line_checksum(data)}))
    (tmp_path / "results.jsonl").write_text("\n".join(old) + "\n")
    assert main(args(short_toml, tmp_path, "--json")) == 0
    captured = capsys.readouterr()
    assert "written by an older visnav (lines without the campaign's spec hash); its 2 results were bound" in captured.err
    assert json.loads(captured.out)["resumed"] == 2
    assert same_as(reference, tmp_path)


def test_a_deeply_nested_header_exits_2(short_toml, tmp_path, capsys):
    (tmp_path / "results.jsonl").write_text("[" * 1000 + "]" * 1000 + "\n")
    assert main(args(short_toml, tmp_path)) == 2
    err = capsys.readouterr().err
    assert "line 1 is not a campaign header (JSON nested 1000 levels deep" in err and "RecursionError" not in err


def test_no_room_to_repair_the_file_exits_3_with_it_unchanged(short_toml, reference, tmp_path, capsys, monkeypatch):
    lines = (reference / "results.jsonl").read_text().splitlines()
    lines[1] = "{garbage"
    damaged = "\n".join(lines) + "\n"
    (tmp_path / "results.jsonl").write_text(damaged)
    replace_fails_for(monkeypatch, "results.jsonl")
    assert main(args(short_toml, tmp_path)) == 3
    err = capsys.readouterr().err
    assert "rewriting it without its 1 bad line(s) failed (No space left on device" in err
    assert "the file is unchanged" in err and "rerun the same command (nothing was run)" in err
    assert (tmp_path / "results.jsonl").read_text() == damaged
    monkeypatch.undo()
    assert main(args(short_toml, tmp_path)) == 0
    assert same_as(reference, tmp_path)


def test_help_documents_the_no_worker_timeout(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    with pytest.raises(SystemExit) as info:
        main(["sweep", "--help"])
    out = capsys.readouterr().out
    assert info.value.code == 0
    assert re.search(r"--no-worker-timeout S\s+with --dask-local or --scheduler: stop \(exit 3, resumable\) once no "
                     r"Dask worker has been alive for S seconds \(default: 60\)", out), out
