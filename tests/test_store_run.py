"""The producer side of the zarr store (issue 28): ``uqdrape run --out URL`` and
``[output] directory = URL``, the preflight and ``validate`` on a URL, a store extended
to more realisations (and by target rounds) bitwise equal to the larger run from the
start, a lock left by a killed run on this host taken over, and every store fault one
line with exit 3. S3 runs against moto's server on 127.0.0.1 (conftest ``s3``)."""

from __future__ import annotations

import dataclasses
import errno
import json
import os
import socket

import pytest
import xarray as xr

from uqdrape.cli import main
from uqdrape.ensemble import open_ensemble, read_manifest, run_ensemble
from uqdrape.ensemble.zarrstore import DONE, LOCK
from uqdrape.study import load_study
from uqdrape.workflow import run_study

from conftest import assert_one_line_error, write_study


def sweep_file(folder, realizations, out):
    """The test_zarrstore sweep (hemisphere, 5 rings, chunks of 7, two force levels) with
    ``realizations`` and ``[output] directory = out``."""
    folder.mkdir(exist_ok=True)
    return write_study(folder, "tiny", study={"seed": 11, "realizations": realizations, "chunk_size": 7},
                       process={"blankholder_force_N": [0.0, 100.0], "friction": 0.2},
                       solver={"mode": "geodesic", "rings": 5},
                       uncertainty={"spacing": {"cv": 0.01}, "zero_angle": {"sd_deg": 3.0},
                                    "friction": {"dist": "uniform", "bounds": [0.1, 0.3]}},
                       output={"directory": out})


def same(a, b):
    xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))


@pytest.fixture(scope="module")
def folder30(tmp_path_factory):
    """The sweep of 30 realisations run into a folder, from the start."""
    tmp = tmp_path_factory.mktemp("ref30")
    out = run_ensemble(load_study(sweep_file(tmp / "s", 30, tmp / "folder")), scheduler="synchronous",
                       progress=False)
    return open_ensemble(out).load()


def test_extended_store_equals_the_larger_run(tmp_path, folder30):
    url = f"file://{tmp_path}/store"
    small = load_study(sweep_file(tmp_path / "s", 20, url))
    run_ensemble(small, scheduler="synchronous", progress=False)
    marks = tmp_path / "store" / DONE
    full = {"r0000000-0000006.nc", "r0000007-0000013.nc"}
    kept = {p.name: p.stat().st_mtime_ns for p in marks.iterdir() if p.name[5:] in full}
    assert len(kept) == 4 and (marks / "f001-r0000014-0000019.nc").is_file()
    run_ensemble(dataclasses.replace(small, realizations=30), scheduler="synchronous", progress=False)
    assert {p.name: p.stat().st_mtime_ns for p in marks.iterdir() if p.name in kept} == kept  # kept as they were
    # the partial region 14-19 is cut anew as 14-20 (its zarr chunk has one writer), then 21-27, 28-29
    assert sorted(p.name for p in marks.iterdir() if p.name.startswith("f001")) == [
        "f001-r0000000-0000006.nc", "f001-r0000007-0000013.nc", "f001-r0000014-0000020.nc",
        "f001-r0000021-0000027.nc", "f001-r0000028-0000029.nc"]
    grown = open_ensemble(url)
    assert grown["shear"].chunks[1] == (7, 7, 7, 7, 2)
    same(folder30, grown.load())
    assert grown.attrs["study_realizations"] == 30 and "30 realisations" in grown.attrs["title"]
    assert read_manifest(url)["realizations"] == 30
    with pytest.raises(ValueError, match=r"holds 30 realisations, more than the 20 asked for"):
        run_ensemble(small, scheduler="synchronous", progress=False)


def test_a_killed_extension_reads_as_incomplete_and_resumes(tmp_path, folder30, monkeypatch):
    import uqdrape.ensemble.run

    url = "memory://store-run-killed-extension"
    small = load_study(sweep_file(tmp_path / "s", 20, url))
    run_ensemble(small, scheduler="synchronous", progress=False)
    large = dataclasses.replace(small, realizations=30)

    def killed(*args):
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:  # killed once the arrays grew, before any new region is written
        patch.setattr(uqdrape.ensemble.run, "compute_tasks", killed)
        with pytest.raises(KeyboardInterrupt):
            run_ensemble(large, scheduler="synchronous", progress=False)
    with pytest.raises(FileNotFoundError, match="6 of 10 regions not done"):
        open_ensemble(url)
    run_ensemble(large, scheduler="synchronous", progress=False)
    same(folder30, open_ensemble(url).load())


def test_cli_run_out_url_writes_and_resumes_the_store(tmp_path, folder30, capsys):
    url = f"file://{tmp_path}/cli-store"
    study = sweep_file(tmp_path / "s", 30, tmp_path / "unused")
    assert main(["run", str(study), "--out", url, "--workers", "1", "--no-report", "-q"]) == 0
    assert capsys.readouterr().out == f"ensemble written to {url}: 10 chunks drawn\n"
    same(folder30, open_ensemble(url).load())
    assert not (tmp_path / "unused").exists()
    assert main(["run", str(study), "--out", url, "--workers", "1", "--no-report", "-q"]) == 0
    assert capsys.readouterr().out == f"resumed: 10 of 10 chunks kept, 0 drawn; ensemble in {url}\n"


def test_study_output_directory_url_is_kept_and_validated(tmp_path, capsys):
    url = f"file://{tmp_path}/store-run-validate/a//b"  # a Path would fold the '//'
    study = load_study(sweep_file(tmp_path / "s", 20, url))
    assert study.output_dir == url and study.to_dict()["output"]["directory"] == url
    assert main(["validate", str(study.path)]) == 0
    assert f"output: {url}" in capsys.readouterr().out


def test_target_rounds_on_a_store_equal_the_folders(tmp_path):
    def target(out):
        (tmp_path / "t").mkdir(exist_ok=True)
        return write_study(tmp_path / "t", "goal", study={
            "seed": 5, "realizations": 16, "chunk_size": 8, "max_realizations": 40,
            "target": {"qoi": "max_abs_shear", "statistic": "mean", "half_width": 1e-9}},
            solver={"mode": "geodesic", "rings": 4}, uncertainty={"spacing": {"cv": 0.02}},
            output={"directory": out})

    url = "memory://store-run-target"
    folder = run_study(target(tmp_path / "folder"), scheduler="synchronous", progress=False)
    assert run_study(target(url), scheduler="synchronous", progress=False) == url
    store, held = read_manifest(url)["target"], read_manifest(folder)["target"]
    assert [r["realizations"] for r in store["rounds"]] == [16, 32, 40] and store == held
    same(open_ensemble(folder).load(), open_ensemble(url).load())


def test_a_lock_left_by_a_killed_run_on_this_host_is_taken_over(tmp_path):
    url = f"file://{tmp_path}/store"
    study = load_study(sweep_file(tmp_path / "s", 20, url))
    gone = os.fork()
    if gone == 0:
        os._exit(0)
    os.waitpid(gone, 0)  # a pid that is certainly not running
    (tmp_path / "store").mkdir()
    (tmp_path / "store" / LOCK).write_text(json.dumps({"pid": gone, "host": socket.gethostname(),
                                                       "started": "earlier"}))
    run_ensemble(study, output_dir=url, scheduler="synchronous", progress=False)
    assert not (tmp_path / "store" / LOCK).exists() and open_ensemble(url).sizes["realization"] == 20
    (tmp_path / "store" / LOCK).write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                                                       "started": "now"}))
    with pytest.raises(OSError, match=rf"another run holds run.lock of this store \(pid {os.getpid()} on "
                                      rf"{socket.gethostname()}, started now\)") as err:
        run_ensemble(study, output_dir=url, scheduler="synchronous", progress=False)
    assert err.value.errno == errno.EBUSY


# -- store faults from the command line: one line, exit 3, nothing written --------------

@pytest.mark.parametrize("command", ["run", "validate"])
@pytest.mark.parametrize("url, valid", [
    ("nosuchproto://x/y", ["not a store URL fsspec can open"]),
    ("s3://nosuchbucket/x", ["bucket 'nosuchbucket' does not exist"]),
    ("s3://readonly/x", ["cannot write a probe object (PermissionError", "Forbidden"]),
])
def test_store_faults_are_one_line_exit_3(tmp_path, s3, capsys, command, url, valid):
    study = sweep_file(tmp_path / "s", 20, url)
    argv = [command, str(study)] + (["--workers", "1", "--no-report", "-q"] if command == "run" else [])
    assert main(argv) == 3
    assert_one_line_error(capsys.readouterr().err, file=url, valid=valid)
    assert not s3.exists("readonly/x")


def test_no_credentials_is_one_line_exit_3(tmp_path, no_s3_credentials, capsys):
    assert main(["run", str(sweep_file(tmp_path / "s", 20, "s3://runs/nocreds")), "--no-report", "-q"]) == 3
    assert_one_line_error(capsys.readouterr().err, file="s3://runs/nocreds",
                          valid=["Unable to locate credentials", "AWS_ENDPOINT_URL"])
