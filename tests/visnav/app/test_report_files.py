"""Writing a report's folder: swapped in whole (an interruption anywhere leaves the old report or the new one),
partial files named and cleaned, the umask's modes, every OSError an OutputError with the path and the fix."""

from __future__ import annotations

import errno
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from visnav.app import files, report_files
from visnav.app.files import OutputError, write_text_atomic
from visnav.app.report_files import check_report_folder, write_report
from visnav.app.verification_report import Report

COUNTEREXAMPLE = '{\n "format": "visnav-verification-counterexample",\n "run": %d\n}\n'


@pytest.fixture(autouse=True)
def _images():
    """The figures as given bytes (matplotlib's rendering is the CLI tests' business): each "figure" is its PNG.

    A patch of its own: the tests' ``monkeypatch.undo()`` ends their planted faults, not this."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(report_files, "figures_png", lambda figures: {stem: figures[stem] for stem in sorted(figures)})
        yield


def _report(run: int, stems: tuple[str, ...], counterexamples: tuple[str, ...]) -> Report:
    """A small report (no study run): its figures, counterexample files and documents differ by ``run``."""
    data = {"meta": {"quick": True, "problem": f"run{run}", "versions": {"python": "3"}, "seeds": {"report": run},
                     "budgets": {"verify_budget": 1}, "command": f"visnav report --seed {run}"},
            "sections": [], "claims": [], "claim_counts": {"proven": 0, "measured": 0, "sampled": 0}, "verdict": None}
    return Report(data=data, figures={stem: b"\x89PNG %s %d" % (stem.encode(), run) for stem in stems},
                  files={f"counterexamples/{name}.json": COUNTEREXAMPLE % run for name in counterexamples})


def _old() -> Report:
    return _report(1, ("a", "b"), ("x",))


def _new() -> Report:
    return _report(2, ("a",), ("y",))


NEW_FILES = [".visnav-manifest.json", "counterexamples/y.json", "figures/a.png", "report.html", "report.json",
             "report.md"]
WRITES = len(NEW_FILES) - 1  # write_bytes_atomic / write_text_atomic calls of the new report (the manifest: its own)


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture()
def old_folder(tmp_path):
    """``tmp_path/out`` holding the old report; its bytes (the parent holds nothing else)."""
    out = tmp_path / "out"
    write_report(_old(), out)
    before = _snapshot(out)
    assert sorted(before) == [".visnav-manifest.json", "counterexamples/x.json", "figures/a.png", "figures/b.png",
                              "report.html", "report.json", "report.md"]
    return out, before


def _siblings(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.parent.iterdir() if p != folder)


def test_a_new_report_replaces_the_folder_with_exactly_its_files(old_folder):
    out, before = old_folder
    written = write_report(_new(), out)
    after = _snapshot(out)
    assert sorted(after) == NEW_FILES  # the old x.json and b.png are gone: a git-tracked folder ends exact
    assert sorted(str(p.relative_to(out)) for p in written) == NEW_FILES[1:]  # the manifest lists them
    assert after["figures/a.png"] != before["figures/a.png"] and b'"run": 2' in after["counterexamples/y.json"]
    assert b"--seed 2" in after["report.md"]
    assert _siblings(out) == []  # nothing left beside it


def _interrupt_at(monkeypatch, call: int, error: BaseException) -> None:
    """Make the ``call``-th file write of report_files raise ``error``."""
    count = [0]
    real_bytes, real_text = report_files.write_bytes_atomic, report_files.write_text_atomic

    def counted(real):
        def write(path, data):
            if count[0] == call:
                raise error
            count[0] += 1
            real(path, data)
        return write

    monkeypatch.setattr(report_files, "write_bytes_atomic", counted(real_bytes))
    monkeypatch.setattr(report_files, "write_text_atomic", counted(real_text))


@pytest.mark.parametrize("call", range(WRITES))
def test_an_interruption_at_any_write_leaves_the_old_report_byte_identical(old_folder, monkeypatch, call):
    out, before = old_folder
    _interrupt_at(monkeypatch, call, KeyboardInterrupt())
    with pytest.raises(KeyboardInterrupt):
        write_report(_new(), out)
    assert _snapshot(out) == before
    assert _siblings(out) == []  # the partial folder is removed
    monkeypatch.undo()
    write_report(_new(), out)  # and the next run completes
    assert sorted(_snapshot(out)) == NEW_FILES


@pytest.mark.parametrize("where", ["render", "exchange", "fallback-rename", "fallback-signal"])
def test_an_interruption_while_rendering_or_swapping_leaves_the_old_report(old_folder, monkeypatch, where):
    out, before = old_folder
    if where == "render":
        monkeypatch.setattr(report_files, "render_html", lambda *a: (_ for _ in ()).throw(KeyboardInterrupt()))
    elif where == "exchange":
        monkeypatch.setattr(report_files, "_exchange", lambda a, b: (_ for _ in ()).throw(KeyboardInterrupt()))
    else:  # a file system without an atomic exchange: two renames, the second interrupted
        monkeypatch.setattr(report_files, "_exchange", lambda a, b: False)
        renames = []
        real_rename = os.rename

        def rename(src, dst):
            renames.append((Path(src).name, Path(dst).name))
            if len(renames) == 2:
                if where == "fallback-rename":
                    raise KeyboardInterrupt
                os.kill(os.getpid(), 2)  # a real SIGINT between the renames: held back until both are done
            real_rename(src, dst)

        monkeypatch.setattr(os, "rename", rename)
    with pytest.raises(KeyboardInterrupt):
        write_report(_new(), out)
    monkeypatch.undo()
    if where == "fallback-signal":  # the SIGINT came after the swap: the new report is complete
        assert sorted(_snapshot(out)) == NEW_FILES
    else:
        assert _snapshot(out) == before
    assert _siblings(out) == []


def test_without_an_atomic_exchange_the_two_renames_give_the_new_report(old_folder, monkeypatch):
    out, _ = old_folder
    monkeypatch.setattr(report_files, "_exchange", lambda a, b: False)
    write_report(_new(), out)
    assert sorted(_snapshot(out)) == NEW_FILES and _siblings(out) == []


def test_an_interruption_while_deleting_the_old_report_leaves_the_new_one(old_folder, monkeypatch):
    out, _ = old_folder
    real_rmtree = shutil.rmtree
    calls = []

    def rmtree(path, *args, **kwargs):
        calls.append(path)
        if len(calls) == 1:
            raise KeyboardInterrupt
        real_rmtree(path, *args, **kwargs)

    monkeypatch.setattr(shutil, "rmtree", rmtree)
    with pytest.raises(KeyboardInterrupt):
        write_report(_new(), out)
    monkeypatch.undo()
    assert sorted(_snapshot(out)) == NEW_FILES and _siblings(out) == []


def _dead_pid() -> int:
    """The process id of a process that has ended."""
    child = subprocess.Popen([sys.executable, "-c", ""])
    child.wait()
    return child.pid


def _age(path: Path) -> None:
    past = time.time() - 3600
    os.utime(path, (past, past))


def test_stale_partial_files_are_cleaned_and_new_ones_say_partial(tmp_path, monkeypatch):
    dead = _dead_pid()
    stale = [tmp_path / f".summary.json.partial-{dead}-abcd1234", tmp_path / ".summary.json.k2j3h4l5"]
    kept = [tmp_path / f".summary.json.partial-{os.getpid()}-abcd1234",  # a write in progress (this process)
            tmp_path / f".other.json.partial-{dead}-zzzz9999",  # written during this run: maybe a concurrent one
            tmp_path / ".notes.txt.abcd1234"]  # looks like an old temporary, but of no file being written
    for path in stale + kept:
        path.write_text("{}")
    for path in stale + kept[:1] + kept[2:]:
        _age(path)
    names = []
    real_replace = os.replace

    def replace(src, dst):
        names.append(Path(src).name)
        real_replace(src, dst)

    monkeypatch.setattr(files.os, "replace", replace)
    write_text_atomic(tmp_path / "summary.json", "{}\n")
    assert [p.exists() for p in stale] == [False, False]
    assert [p.exists() for p in kept] == [True, True, True]
    assert re.fullmatch(rf"\.summary\.json\.partial-{os.getpid()}-[a-z0-9_]{{8}}", names[0])
    assert (tmp_path / "summary.json").read_text() == "{}\n"


def test_a_stale_partial_report_folder_beside_the_report_is_cleaned(old_folder):
    out, _ = old_folder
    dead = _dead_pid()
    leftover = out.parent / f".out.partial-{dead}-abcd1234"  # a hard kill while writing: the marker came first
    (leftover / "figures").mkdir(parents=True)
    (leftover / ".visnav-partial").write_text(f'{{"format": "visnav-partial-folder", "name": "out", "pid": {dead}}}\n')
    (leftover / "report.md").write_text("half")
    _age(leftover)
    previous = out.parent / f".out.previous-{dead}-0123abcd"  # a kill -9 between the fallback's renames
    shutil.copytree(out, previous)  # the old report, its manifest with it
    look_alike = out.parent / f".out.partial-{dead}-0000aaaa"  # the same kind of name, no marker: not ours
    look_alike.mkdir()
    (look_alike / "notes.txt").write_text("mine")
    _age(look_alike)
    write_report(_new(), out)
    assert not leftover.exists() and not previous.exists() and sorted(_snapshot(out)) == NEW_FILES
    assert (look_alike / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("mask, file_mode, dir_mode", [(0o022, 0o644, 0o755), (0o027, 0o640, 0o750)])
def test_files_get_the_mode_of_the_umask(tmp_path, mask, file_mode, dir_mode):
    previous = os.umask(mask)
    try:
        write_text_atomic(tmp_path / "a.json", "{}")
        out = tmp_path / "report"
        write_report(_new(), out)
    finally:
        os.umask(previous)
    assert oct(os.stat(tmp_path / "a.json").st_mode & 0o777) == oct(file_mode)
    for name in NEW_FILES:
        assert oct(os.stat(out / name).st_mode & 0o777) == oct(file_mode), name
    for folder in (out, out / "figures", out / "counterexamples"):
        assert oct(os.stat(folder).st_mode & 0o777) == oct(dir_mode), folder


def test_a_replaced_folder_keeps_its_mode(old_folder):
    out, _ = old_folder
    os.chmod(out, 0o750)
    write_report(_new(), out)
    assert oct(os.stat(out).st_mode & 0o777) == oct(0o750)


def test_a_disk_full_is_an_output_error_with_the_path_and_the_folder_is_kept(old_folder, monkeypatch):
    out, before = old_folder
    real_fsync = os.fsync
    calls = [0]

    def fsync(fd):
        calls[0] += 1
        if calls[0] == 4:  # after the partial folder's marker, a.png and y.json
            raise OSError(errno.ENOSPC, "No space left on device")
        real_fsync(fd)

    monkeypatch.setattr(files.os, "fsync", fsync)
    with pytest.raises(OutputError, match="No space left on device; free space") as error:
        write_report(_new(), out)
    monkeypatch.undo()
    assert error.value.errno == errno.ENOSPC and ".partial-" not in str(error.value)
    assert f"cannot write {str(out / 'report.md')!r}" in str(error.value)  # the third file: after a.png, y.json
    assert str(error.value).endswith("; the folder is left as it was")
    assert _snapshot(out) == before and _siblings(out) == []


def test_a_path_component_that_is_a_file_is_an_output_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OutputError, match="a component of the path is a file") as error:
        write_text_atomic(blocker / "summary.json", "{}")
    assert str(blocker / "summary.json") in str(error.value)
    with pytest.raises(OutputError, match="not a folder"):
        write_report(_new(), blocker)
    assert blocker.read_text() == "x"


def test_a_folder_holding_other_files_is_refused_untouched(old_folder, monkeypatch):
    out, before = old_folder
    (out / "notes.txt").write_text("mine")
    (out / "figures" / ".DS_Store").write_text("")  # a file browser's: not refused
    (out / "counterexamples" / "fuzz.json").write_text('{"format": "visnav-fuzz-counterexample"}')
    with pytest.raises(OutputError, match=r"holds 2 file\(s\) that are not part of a visnav report "
                                          r"\(counterexamples/fuzz.json, notes.txt\)"):
        write_report(_new(), out)
    assert _snapshot(out) == {**before, "notes.txt": b"mine", "figures/.DS_Store": b"",
                              "counterexamples/fuzz.json": b'{"format": "visnav-fuzz-counterexample"}'}
    monkeypatch.chdir(tmp := out / "figures")
    with pytest.raises(OutputError, match="is the current folder or holds it"):
        check_report_folder(out)
    assert tmp.is_dir()
