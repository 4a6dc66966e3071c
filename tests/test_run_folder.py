"""A run folder's own files are data, not a program: a hand-edited or corrupted manifest
or lock is refused in one line, a damaged chunk is draped again on resume, the lock has no
moment at which it exists empty, and a folder can be moved and resumed."""

from __future__ import annotations

import json
import shutil
import threading
import time

import pytest
import xarray as xr

from conftest import assert_one_line_error, write_study
from uqdrape.cli import main as cli
from uqdrape.ensemble import lock as lockmod, open_ensemble
from uqdrape.ensemble.lock import LOCK, RunLocked, run_lock


def _run(path, *extra):
    return cli(["run", str(path), "--scheduler", "synchronous", "-q", "--no-report", *extra])


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished 6-realisation run (3 chunks) and its study file."""
    folder = tmp_path_factory.mktemp("finished")
    path = write_study(folder)
    assert _run(path) == 0
    return path, folder / "tiny"


def _copy(finished, tmp_path):
    path, out = finished
    study = write_study(tmp_path)
    shutil.copytree(out, tmp_path / "tiny")
    return study, tmp_path / "tiny"


@pytest.mark.parametrize("text", [
    "{}", "[]", '"run"', "{not json", "\xff\xfe", '{"study": [1], "chunks": [], "chunk_size": 2}',
    '{"study": {"study": {}}, "chunks": 5, "chunk_size": 2}',
    '{"study": {"study": {}}, "chunks": ["../../other/chunks/r0000000-0000001.nc"], "chunk_size": 2}',
    '{"study": {"study": {}}, "chunks": ["r0000000-0000001.nc"], "chunk_size": 0}',
    '{"study": {"study": {}}, "chunks": ["r0000000-0000001.nc"], "chunk_size": 2, "wall_time_s": "long"}',
])
def test_a_corrupted_manifest_is_refused_in_one_line_by_report_and_resume(finished, tmp_path, capsys, text):
    study, out = _copy(finished, tmp_path)
    (out / "run.json").write_text(text, encoding="utf-8", errors="surrogateescape")
    for argv in (["report", str(out)], ["run", str(study), "--scheduler", "synchronous", "-q", "--no-report"]):
        assert cli(argv) == 3, argv
        assert_one_line_error(capsys.readouterr().err, file=out / "run.json", valid=["not a uqdrape run manifest"])
    assert _run(study, "--no-resume") == 0  # --no-resume replaces it


@pytest.mark.parametrize("text", [
    "", "5", "{}", '{"pid": 0, "host": "HOST", "started": "x"}', '{"pid": -1, "host": "HOST", "started": "x"}',
    '{"pid": 1e30, "host": "HOST", "started": "x"}', '{"pid": "12", "host": "HOST", "started": "x"}',
    '{"pid": 1, "host": "elsewhere", "started": "x"}',
])
def test_a_lock_that_is_not_a_live_local_run_of_uqdrape_is_refused_not_guessed_about(tmp_path, capsys, text):
    import socket

    path = write_study(tmp_path)
    (tmp_path / "tiny").mkdir()
    (tmp_path / "tiny" / LOCK).write_text(text.replace("HOST", socket.gethostname()))
    assert _run(path) == 3
    err = capsys.readouterr().err
    assert_one_line_error(err, file=tmp_path / "tiny", valid=[LOCK])
    assert "elsewhere" in err if "elsewhere" in text else "not a lock uqdrape wrote" in err


def test_a_stale_lock_of_a_dead_local_process_is_taken_over(tmp_path):
    import socket
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    out = tmp_path / "run"
    out.mkdir()
    (out / LOCK).write_text(json.dumps({"pid": int(dead.stdout), "host": socket.gethostname(), "started": "x"}))
    with run_lock(out):
        assert json.loads((out / LOCK).read_text())["pid"] != int(dead.stdout)
    assert not (out / LOCK).exists()


def test_two_runs_that_find_the_same_stale_lock_cannot_both_take_it(tmp_path, monkeypatch):
    """Both read the dead run's lock before either takes it over (held there by a barrier):
    the first removes it and makes its own; the second must then see a live lock, not
    remove the first's and take the folder too (before: both held it)."""
    import socket
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    out = tmp_path / "run"
    out.mkdir()
    (out / LOCK).write_text(json.dumps({"pid": int(dead.stdout), "host": socket.gethostname(), "started": "x"}))
    both_read, stale = threading.Barrier(2, timeout=10), lockmod.stale

    def stale_after_both_read(owner):
        both_read.wait()
        return stale(owner)

    monkeypatch.setattr(lockmod, "stale", stale_after_both_read)
    outcome, release = [], threading.Event()

    def run():
        try:
            with run_lock(out):
                outcome.append("held")
                release.wait(10)
        except RunLocked:
            outcome.append("refused")

    threads = [threading.Thread(target=run) for _ in range(2)]
    for t in threads:
        t.start()
    deadline = time.monotonic() + 10
    while len(outcome) < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    release.set()
    for t in threads:
        t.join(10)
    assert sorted(outcome) == ["held", "refused"]
    assert not (out / LOCK).exists()


def test_the_lock_never_exists_without_its_owner(tmp_path, monkeypatch):
    """A writer slowed between making its lock and linking it into place: a second run
    in that window takes the folder, and the slow one is then refused (the old lock, made
    empty and filled afterwards, let both through: an empty lock counted as stale)."""
    out = tmp_path / "run"
    link, entered, proceed = lockmod.os.link, threading.Event(), threading.Event()

    def slow_link(src, dst):
        if threading.current_thread().name == "slow":
            entered.set()
            proceed.wait(10)
        return link(src, dst)

    monkeypatch.setattr(lockmod.os, "link", slow_link)
    outcome = {}

    def slow():
        try:
            with run_lock(out):
                outcome["slow"] = "held"
        except RunLocked:
            outcome["slow"] = "refused"

    thread = threading.Thread(target=slow, name="slow")
    thread.start()
    assert entered.wait(10)
    assert not (out / LOCK).exists()  # in the window: no empty lock to be mistaken for a dead one
    with run_lock(out):
        proceed.set()
        thread.join(10)
        assert json.loads((out / LOCK).read_text())["pid"] > 0
    assert outcome == {"slow": "refused"}


@pytest.mark.parametrize("damage", ["truncate", "empty", "swap"])
def test_resume_drapes_a_damaged_chunk_again_and_says_so(finished, tmp_path, capsys, damage):
    study, out = _copy(finished, tmp_path)
    chunks = sorted((out / "chunks").glob("*.nc"))
    with open_ensemble(finished[1]) as ds:
        reference = ds.load()
    if damage == "truncate":
        chunks[1].write_bytes(chunks[1].read_bytes()[:3000])
    elif damage == "empty":
        chunks[1].write_bytes(b"")
    else:  # another chunk's (valid) file under this one's name
        shutil.copy(chunks[0], chunks[1])
    assert cli(["run", str(study), "--scheduler", "synchronous", "--no-report"]) == 0
    assert f"1 chunk file(s) damaged or not this run's, draped again: {chunks[1].name}" in capsys.readouterr().err
    with open_ensemble(out) as ds:
        xr.testing.assert_identical(ds.load().drop_attrs(), reference.drop_attrs())


def test_a_moved_run_folder_resumes_without_draping(finished, tmp_path, capsys):
    study, out = _copy(finished, tmp_path)
    started = time.perf_counter()
    assert cli(["run", str(study), "--scheduler", "synchronous", "--no-report"]) == 0
    assert "3 of 3 chunks already done" in capsys.readouterr().err
    assert time.perf_counter() - started < 30
