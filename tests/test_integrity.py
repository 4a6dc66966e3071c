"""Damaged data is detected (issue 40): every chunk of a run folder and every region of a
store carries a SHA-256 of its content, the run's checksum key and its name, recorded when
it is written. A chunk edited in place (shear + 1e6 deg, its attributes kept), two chunks
swapped with their checksums, a chunk copied in from another run of the same study, or a
store object overwritten, cut short or removed is named in one line by ``report`` and ``export``
(exit 3) and drawn again by a resumed run, which then equals the untouched run."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from conftest import assert_one_line_error, write_study
from uqdrape.cli import main as cli
from uqdrape.ensemble import open_ensemble

BACKENDS = ["folder", "file", "s3"]


def _run(study, out, *extra) -> int:
    return cli(["run", str(study), "--out", str(out), "--scheduler", "synchronous", "-q", "--no-report", *extra])


def _out(backend: str, folder: Path, request, name: str):
    if backend == "s3":
        request.getfixturevalue("s3")
        return f"s3://runs/{folder.name}-{name}"
    return folder / name if backend == "folder" else f"file://{folder}/{name}"


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The study (6 realisations, 3 chunks) and its untouched ensemble, loaded."""
    folder = tmp_path_factory.mktemp("reference")
    study = write_study(folder)
    assert _run(study, folder / "run") == 0
    with open_ensemble(folder / "run") as ds:
        return study, ds.load()


def _edit_folder(out: Path, damage: str, other: Path) -> str:
    chunks = sorted((out / "chunks").glob("*.nc"))
    victim = chunks[1]
    if damage == "values":
        with xr.open_dataset(victim, engine="netcdf4") as ds:
            edited = ds.load()
        edited["shear"] = edited["shear"] + 1e6
        edited.to_netcdf(victim, engine="netcdf4")
    elif damage == "swap":
        for suffix in ("", ".sha256"):
            a, b = Path(f"{chunks[0]}{suffix}"), Path(f"{chunks[1]}{suffix}")
            a.rename(a.with_name("tmp")), b.rename(a), a.with_name("tmp").rename(b)
    elif damage == "foreign":  # the same chunk of another run of the same study, with its own checksum
        for suffix in ("", ".sha256"):
            shutil.copy(other / "chunks" / f"{victim.name}{suffix}", Path(f"{victim}{suffix}"))
    else:  # cut short
        victim.write_bytes(victim.read_bytes()[:5000])
    return victim.name


def _edit_store(out: str, damage: str) -> str:
    """Damage the shear object of the second region (realisations 2-3 of 6)."""
    import fsspec

    fs, root = fsspec.core.url_to_fs(out)
    objects = sorted(p for p in fs.find(f"{root}/data/shear") if "/c/" in p)
    victim = next(p for p in objects if p.split("/c/")[1].split("/")[:2] == ["0", "1"])
    data = fs.cat_file(victim)
    if damage == "remove":  # zarr reads a missing object as the fill value
        fs.rm(victim)
    else:
        fs.pipe_file(victim, data[:len(data) // 2] if damage == "cut" else bytes(b ^ 0x5A for b in data))
    return json.loads(fs.cat_file(f"{root}/run.json"))["chunks"][1]


@pytest.mark.parametrize("damage", ["values", "swap", "foreign", "cut"])
def test_a_damaged_chunk_is_named_by_report_and_export_and_drawn_again_on_resume(reference, tmp_path, capsys,
                                                                                damage):
    study, expected = reference
    out, other = tmp_path / "run", tmp_path / "other"
    assert _run(study, out) == 0 and _run(study, other) == 0
    name = _edit_folder(out, damage, other)
    for argv in (["report", str(out)], ["export", str(out), "--to", "netcdf"]):
        assert cli(argv) == 3, argv
        assert_one_line_error(capsys.readouterr().err, file=out / "chunks", valid=["is not what the run wrote"])
    assert not (out / "report").exists() and not (out / "export").exists()
    assert cli(["run", str(study), "--out", str(out), "--scheduler", "synchronous", "--no-report"]) == 0
    err = capsys.readouterr().err
    assert f"{1 + (damage == 'swap')} chunk file(s) damaged or not this run's, draped again: " in err and name in err
    with open_ensemble(out) as ds:
        xr.testing.assert_identical(ds.load().drop_attrs(), expected.drop_attrs())


@pytest.mark.parametrize("backend, damage", [("file", "flip"), ("file", "cut"), ("file", "remove"), ("s3", "flip")])
def test_a_damaged_store_region_is_named_by_report_and_export_and_drawn_again_on_resume(reference, tmp_path, capsys,
                                                                                       request, backend, damage):
    study, expected = reference
    out = _out(backend, tmp_path, request, "store")
    assert _run(study, out) == 0
    name = _edit_store(out, damage)
    for argv in (["report", out], ["export", out, "--to", "netcdf"]):
        assert cli(argv) == 3, argv
        assert_one_line_error(capsys.readouterr().err, file=out, valid=[f"region {name}", "is not what the run wrote"])
    assert cli(["run", str(study), "--out", out, "--scheduler", "synchronous", "--no-report"]) == 0
    assert f"damaged or not this run's, draped again: {name}" in capsys.readouterr().err
    with open_ensemble(out) as ds:
        np.testing.assert_array_equal(ds["shear"].values, expected["shear"].values)
        xr.testing.assert_identical(ds.load().drop_attrs(), expected.drop_attrs())


def test_checksums_are_taken_of_what_was_written_and_a_resumed_run_keeps_its_key(reference, tmp_path):
    """Each chunk's recorded checksum is the digest of its file under the manifest's key and
    its name; resuming and extending keep the key (so the kept chunks still pass)."""
    from uqdrape.ensemble.location import digest

    study, _ = reference
    out = tmp_path / "run"
    assert _run(study, out) == 0
    key = json.loads((out / "run.json").read_text())["checksum_key"]
    for path in sorted((out / "chunks").glob("*.nc")):
        recorded = Path(f"{path}.sha256").read_text().strip()
        assert recorded == digest(key, path.name, [path.read_bytes()])
    assert _run(study, out) == 0
    assert json.loads((out / "run.json").read_text())["checksum_key"] == key
    assert _run(study, out, "--no-resume") == 0
    assert json.loads((out / "run.json").read_text())["checksum_key"] != key


def test_a_run_without_checksums_is_still_read(reference, tmp_path):
    """A run written before checksums (no key in its manifest, no .sha256 files) opens as
    before: old run folders are read, not refused."""
    study, expected = reference
    out = tmp_path / "run"
    assert _run(study, out) == 0
    manifest = json.loads((out / "run.json").read_text())
    del manifest["checksum_key"]
    (out / "run.json").write_text(json.dumps(manifest))
    for path in (out / "chunks").glob("*.sha256"):
        path.unlink()
    with open_ensemble(out) as ds:
        xr.testing.assert_identical(ds.load().drop_attrs(), expected.drop_attrs())
