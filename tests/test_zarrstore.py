"""Tests of uqdrape.ensemble.zarrstore: an ensemble as one zarr store on an fsspec URL.

The same tiny sweep (hemisphere, 5 rings, 20 realisations in chunks of 7, two force
levels) as a run folder is the reference; "bitwise equal" is xarray's assert_identical
of every variable, coordinate and variable attribute. S3 runs against moto's server on
127.0.0.1, started by the test.
"""

import errno
import os

import pytest
import xarray as xr

from uqdrape.ensemble import open_ensemble, run_ensemble
from uqdrape.ensemble.zarrstore import DATA, DONE, LOCK, MANIFEST, PROBE, ZARR_FORMAT, ZarrStore, check_store
from uqdrape.stats import node_statistics
from uqdrape.study import load_study

from conftest import write_study


def tiny(tmp_path):
    return load_study(write_study(
        tmp_path, "tiny", study={"seed": 11, "realizations": 20, "chunk_size": 7},
        process={"blankholder_force_N": [0.0, 100.0], "friction": 0.2}, solver={"mode": "geodesic", "rings": 5},
        uncertainty={"spacing": {"cv": 0.01}, "zero_angle": {"sd_deg": 3.0},
                     "friction": {"dist": "uniform", "bounds": [0.1, 0.3]}},
        output={"directory": tmp_path / "folder"}))


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ref")
    study = tiny(tmp)
    run_ensemble(study, scheduler="synchronous", progress=False)
    return study, open_ensemble(tmp / "folder").load()


def same(a, b):
    xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))


def test_store_from_two_workers_equals_folder(reference, tmp_path):
    study, ref = reference
    url = f"file://{tmp_path}/store"
    assert run_ensemble(study, output_dir=url, workers=2, progress=False) == url
    assert (tmp_path / "store" / DATA / "zarr.json").is_file()  # zarr format 3
    assert ZARR_FORMAT == 3
    ds = open_ensemble(url)
    assert ds["shear"].chunks[1] == (7, 7, 6)  # lazy, one dask chunk per region
    same(ref, ds.load())
    assert ZarrStore(url).done() == {f"f{k:03d}-r{a:07d}-{min(a + 6, 19):07d}.nc" for k in (0, 1) for a in (0, 7, 14)}
    assert not (tmp_path / "store" / LOCK).exists()


def test_statistics_read_store_lazily(reference, tmp_path):
    study, ref = reference
    url = "memory://zarr28-stats"
    run_ensemble(study, output_dir=url, scheduler="synchronous", progress=False)
    lazy = open_ensemble(url)
    assert lazy["shear"].data.__class__.__module__.startswith("dask")
    with open_ensemble(study.output_dir) as folder:  # the same dask chunks, so the same sums
        same(node_statistics(folder), node_statistics(lazy))


def test_resume_redoes_only_unmarked_regions(reference, tmp_path, capsys):
    study, ref = reference
    url = f"file://{tmp_path}/store"
    run_ensemble(study, output_dir=url, scheduler="synchronous", progress=False)
    lost = "f001-r0000007-0000013.nc"
    (tmp_path / "store" / DONE / lost).unlink()  # a killed writer: its region half-written, no marker
    z = xr.open_zarr(f"{tmp_path}/store/{DATA}")
    part = z[["shear"]].isel(blankholder_force=[1], realization=slice(7, 14)).load() * 0 + 99.0
    part.drop_vars([v for v in part.variables if v not in ("shear",)]).to_zarr(
        f"{tmp_path}/store/{DATA}", region={"blankholder_force": slice(1, 2), "realization": slice(7, 14)})
    kept = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "store" / DONE).iterdir()}
    with pytest.raises(FileNotFoundError, match="1 of 6 regions not done"):
        open_ensemble(url)
    run_ensemble(study, output_dir=url, scheduler="synchronous", progress=True)
    assert "5 of 6 regions already done" in capsys.readouterr().err
    assert {p.name: p.stat().st_mtime_ns for p in (tmp_path / "store" / DONE).iterdir() if p.name in kept} == kept
    same(ref, open_ensemble(url).load())


def test_bad_url_is_one_line_oserror(reference):
    study, _ = reference
    with pytest.raises(OSError, match="not a store URL fsspec can open") as err:
        run_ensemble(study, output_dir="nosuchproto://x/y", scheduler="synchronous", progress=False)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("url", ["file://{tmp}/store", "memory://zarr28-manifest"])
def test_a_failed_manifest_write_leaves_the_old_manifest(tmp_path, monkeypatch, url):
    """The manifest is put beside and moved over: a write that fails half-way (a full
    disk) leaves the old manifest whole and no part behind."""
    import fsspec

    url = url.format(tmp=tmp_path)
    old, new = ({"study": {"study": {"name": name}}, "chunk_size": 10, "realizations": n,
                 "chunks": [f"r{k:07d}-{k + 9:07d}.nc" for k in range(0, n, 10)]} for name, n in (("old", 10), ("new", 20)))
    ZarrStore(url).write_manifest(old)
    fs, root = fsspec.core.url_to_fs(url)
    put = type(fs).pipe_file

    def half_then_full(self, path, value, **kwargs):
        put(self, path, value[:len(value) // 2], **kwargs)
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(type(fs), "pipe_file", half_then_full)
    with pytest.raises(OSError, match="No space left"):
        ZarrStore(url).write_manifest(new)
    monkeypatch.undo()
    assert ZarrStore(url).read_manifest() == old
    assert not fs.exists(f"{root}/{MANIFEST}.part")
    ZarrStore(url).write_manifest(new)
    assert ZarrStore(url).read_manifest() == new and not fs.exists(f"{root}/{MANIFEST}.part")


def test_a_probe_left_by_a_killed_process_is_removed_by_the_next(monkeypatch):
    """check_store's probe object has one name: one left behind (its process killed
    between the put and the removal) is overwritten and removed by the next probe, and
    a probe removed by another process meanwhile is no error."""
    import fsspec

    url = "memory://zarr28-probe/runs"
    fs, root = fsspec.core.url_to_fs(url)
    remove = type(fs).rm

    def killed(self, path, *args, **kwargs):
        raise KeyboardInterrupt  # SIGINT or a kill between the put and the removal

    monkeypatch.setattr(type(fs), "rm", killed)
    monkeypatch.setattr(os, "getpid", lambda pid=os.getpid(): pid + 1)  # the killed probe was another process's
    with pytest.raises(KeyboardInterrupt):
        check_store(url)
    assert fs.exists(f"{root}/{PROBE}")  # the litter of a killed probe
    monkeypatch.undo()
    check_store(url)
    assert fs.find(root) == []

    def raced(self, path, *args, **kwargs):
        remove(self, path, *args, **kwargs)  # another process's probe removed ours first
        remove(self, path, *args, **kwargs)

    monkeypatch.setattr(type(fs), "rm", raced)
    check_store(url)
    assert fs.find(root) == []


# -- S3 against moto's server on 127.0.0.1 ---------------------------------------------

def test_s3_store_equals_folder(reference, s3):
    study, ref = reference
    url = "s3://runs/tiny"
    run_ensemble(study, output_dir=url, scheduler="synchronous", progress=False)
    assert s3.exists(f"runs/tiny/{DATA}/zarr.json") and not s3.exists(f"runs/tiny/{LOCK}")
    same(ref, open_ensemble(url).load())


def test_s3_second_writer_refused(reference, s3):
    study, _ = reference
    s3.pipe_file(f"runs/busy/{LOCK}", b'{"pid": 1, "host": "elsewhere", "started": "now"}')
    with pytest.raises(OSError, match="another run holds run.lock") as err:
        run_ensemble(study, output_dir="s3://runs/busy", scheduler="synchronous", progress=False)
    assert err.value.errno == errno.EBUSY and "\n" not in str(err.value)
    assert not s3.exists(f"runs/busy/{DATA}")  # nothing written past the lock


def test_s3_missing_bucket(reference, s3):
    study, _ = reference
    with pytest.raises(OSError, match="bucket 'nosuchbucket' does not exist") as err:
        run_ensemble(study, output_dir="s3://nosuchbucket/x", scheduler="synchronous", progress=False)
    assert "\n" not in str(err.value)


def test_s3_no_credentials(reference, no_s3_credentials):
    study, _ = reference
    with pytest.raises(OSError, match="Unable to locate credentials.*credentials in the environment") as err:
        run_ensemble(study, output_dir="s3://runs/nocreds", scheduler="synchronous", progress=False)
    assert err.value.errno == errno.EIO and "\n" not in str(err.value)
