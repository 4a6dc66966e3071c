"""Kill and retry of a run into a zarr store on S3 (issue 28, slow suite).

moto's S3 server runs on 127.0.0.1 in this process (conftest ``s3``); ``uqdrape run``
runs as its own process, its dask workers as two more (a dask.distributed scheduler and
two ``dask worker`` processes, or the run's own two local processes), each started in
its own empty working folder: nothing passes between them but the store and dask's
task messages. The study: an energy drape (6 rings, 169 nodes) of 1,200 realisations
in 4 chunks of 300, about 1.3 s a chunk, so that a kill lands inside a chunk; its run
folder, draped in this process, is the reference ("bitwise": xarray's
assert_identical of every variable, coordinate and variable attribute)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import xarray as xr

from uqdrape.ensemble import open_ensemble, run_ensemble
from uqdrape.ensemble.zarrstore import DONE, LOCK
from uqdrape.study import load_study

from conftest import assert_one_line_error, write_study

pytestmark = pytest.mark.slow

REGIONS = 4
#: How long a run of this study may take here (s), loaded machine included.
PATIENCE = 240


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """(study file, its folder run loaded)."""
    tmp = tmp_path_factory.mktemp("kill")
    path = write_study(tmp, "kill", study={"seed": 7, "realizations": 1200, "chunk_size": 300},
                       fabric={"material": "ebxhd936_like"},
                       process={"blankholder_force_N": 100.0, "friction": 0.2},
                       solver={"mode": "energy", "rings": 6},
                       uncertainty={"spacing": {"cv": 0.01}, "zero_angle": {"sd_deg": 3.0}},
                       output={"directory": tmp / "folder"})
    run_ensemble(load_study(path), scheduler="synchronous", progress=False)
    return path, open_ensemble(tmp / "folder").load()


def same(a, b):
    xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))


def own_folder(tmp_path, name) -> Path:
    folder = tmp_path / name
    folder.mkdir()
    return folder


def uqdrape(tmp_path, name, *args) -> subprocess.Popen:
    """``uqdrape ARGS`` started in its own working folder ``tmp_path/name``."""
    return subprocess.Popen([sys.executable, "-m", "uqdrape.cli", *args], cwd=own_folder(tmp_path, name),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for(condition, what: str, timeout: float = PATIENCE, every: float = 0.05):
    """The first true value of ``condition()``, polled every ``every`` s; fails after ``timeout``."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(every)
    pytest.fail(f"gave up waiting for {what}")


def markers(s3, prefix) -> set[str]:
    """The regions marked done (a marker's .part is one being put, as the store reads it)."""
    s3.invalidate_cache()
    try:
        return {p.rsplit("/", 1)[-1] for p in s3.ls(f"{prefix}/{DONE}", detail=False) if not p.endswith(".part")}
    except FileNotFoundError:
        return set()


@pytest.fixture()
def cluster(tmp_path):
    """A dask.distributed scheduler on 127.0.0.1 and two single-threaded workers (each
    under a nanny that restarts it), every process in its own working folder; yields
    (address, an observing Client)."""
    from distributed import Client

    dask = Path(sys.executable).with_name("dask")
    info = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([str(dask), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(info)], cwd=own_folder(tmp_path, "scheduler"),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    wait_for(info.is_file, "the scheduler", 60)
    with Client(scheduler_file=str(info), timeout=30) as client:
        address = client.scheduler.address
        for k in range(2):
            work = own_folder(tmp_path, f"worker{k}")
            procs.append(subprocess.Popen([str(dask), "worker", address, "--nthreads", "1", "--nworkers", "1",
                                           "--no-dashboard", "--local-directory", str(work)], cwd=work,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        client.wait_for_workers(2, timeout=60)
        try:
            yield address, client
        finally:
            for proc in procs[::-1]:
                proc.terminate()
            for proc in procs:
                proc.wait(timeout=30)


def test_a_worker_killed_mid_chunk_is_retried(reference, s3, cluster, tmp_path):
    path, ref = reference
    address, client = cluster
    url = "s3://runs/killed-worker"
    run = uqdrape(tmp_path, "client", "run", str(path), "--out", url, "--scheduler", address, "--no-report", "-q")

    def busy():  # a worker draping a region, and that worker's pid
        for worker, keys in client.processing().items():
            if any(str(key).startswith("_run_chunk") for key in keys):
                return worker, keys[0]
        return None

    worker, key = wait_for(busy, "a region task on a worker", every=0.02)
    pid = client.run(os.getpid, workers=[worker])[worker]
    before = markers(s3, "runs/killed-worker")
    os.kill(pid, signal.SIGKILL)  # mid-chunk: a task takes about 1.3 s, no marker is being written
    assert len(before) < REGIONS
    out, err = run.communicate(timeout=PATIENCE)
    assert (run.returncode, out, err) == (0, f"ensemble written to {url}: {REGIONS} chunks drawn\n", "")
    assert markers(s3, "runs/killed-worker") == {f"r{a:07d}-{a + 299:07d}.nc" for a in range(0, 1200, 300)}
    started = [t for t in client.story(key) if t[2] == "processing"]  # (key, from, to, ...) transitions
    assert len(started) >= 2, client.story(key)  # the killed task was given to a worker again
    same(ref, open_ensemble(url).load())
    assert not s3.exists(f"runs/killed-worker/{LOCK}")


def test_second_run_refused_and_resume_after_sigkill(reference, s3, tmp_path):
    path, ref = reference
    url = "s3://runs/sigkill"
    command = ("run", str(path), "--out", url, "--workers", "2", "--no-report", "-q")
    first = uqdrape(tmp_path, "first", *command)
    wait_for(lambda: s3.invalidate_cache() or s3.exists(f"runs/sigkill/{LOCK}"), "the first run's lock")
    second = uqdrape(tmp_path, "second", *command)
    out, err = second.communicate(timeout=PATIENCE)
    assert second.returncode == 3 and out == ""
    assert_one_line_error(err, file=url, valid=["another run holds run.lock of this store (pid "
                                                f"{first.pid} on "])
    done = wait_for(lambda: markers(s3, "runs/sigkill"), "a first region done")
    first.send_signal(signal.SIGKILL)  # the client; its local workers die with it (PR_SET_PDEATHSIG)
    first.communicate(timeout=60)
    kept = markers(s3, "runs/sigkill")
    assert done <= kept and 1 <= len(kept) < REGIONS and s3.exists(f"runs/sigkill/{LOCK}")
    with pytest.raises(FileNotFoundError, match=f"{REGIONS - len(kept)} of {REGIONS} regions not done"):
        open_ensemble(url)
    again = uqdrape(tmp_path, "again", *command)  # takes over the dead run's lock (same host, pid gone)
    out, err = again.communicate(timeout=PATIENCE)
    assert (again.returncode, err) == (0, "")
    assert out == (f"resumed: {len(kept)} of {REGIONS} chunks kept, {REGIONS - len(kept)} drawn; "
                   f"ensemble in {url}\n")
    same(ref, open_ensemble(url).load())


def test_a_full_bucket_is_one_line_exit_3(reference, s3, tmp_path):
    path, _ = reference
    url = "s3://full/run"  # the template fits in the bucket's quota, the first region does not
    run = uqdrape(tmp_path, "client", "run", str(path), "--out", url, "--workers", "1", "--no-report", "-q")
    out, err = run.communicate(timeout=PATIENCE)
    assert (run.returncode, out) == (3, "")
    assert_one_line_error(err, file=url, valid=["cannot write region r0000", "QuotaExceeded"])
    assert markers(s3, "full/run") == set() and not s3.exists(f"full/run/{LOCK}")
