"""One ensemble on every storage backend (issue 35): a run folder, a file:// store, a
memory:// store and an S3 store (moto's server, conftest ``s3``) take the same run
through the one run loop, a run stopped by a failing worker and resumed, extended to
more realisations, with a ``[study] rare`` probability and a report, and a hierarchical
run with its fixed-parameter twin, and give bitwise-equal numbers and the same side
files (the blank-holder design on every backend: test_store_design.py). The rare study on a file:// URL
reproduces issue 35's bug (``rare.json`` written into ``./file:/...``, the report from
elsewhere silently without the rare probability)."""

from __future__ import annotations

import dataclasses
import json
import os
import re
from pathlib import Path

import fsspec
import pytest
import xarray as xr

import uqdrape.ensemble.run as engine
from uqdrape.cli import main
from uqdrape.ensemble import at, open_ensemble, read_manifest
from uqdrape.files import location
from uqdrape.study import load_study
from uqdrape.workflow import run_report, run_study
from uqdrape.workflow.rare import RARE_FILE
from uqdrape.workflow.twin import MEASURED, twin_location

from conftest import write_study

#: A geodesic 4-ring dome with iid spacing and a skew factor; its P(mean line shear >= 5
#: deg) is about 0.16, estimated to CoV 0.3 in about 700 drapes.
RARE = {"qoi": "mean_shear_positive", "threshold": 5.0, "cov": 0.3, "max_drapes": 1000}
UNCERTAIN = {"spacing": {"cv": 0.02}, "skew": {"dist": "normal", "mean": 0.0, "sd": 1.0}}
BACKENDS = ["folder", "file", "memory", "s3"]


def rare_study(folder: Path, realizations: int):
    return load_study(write_study(folder, "rare", study={"seed": 1, "realizations": realizations, "chunk_size": 2,
                                                         "rare": RARE},
                                  solver={"mode": "geodesic", "rings": 4}, uncertainty=UNCERTAIN))


def target(backend: str, tmp_path: Path, request) -> Path | str:
    if backend == "s3":
        request.getfixturevalue("s3")
        return f"s3://runs/{tmp_path.name}"
    return {"folder": tmp_path / "run", "file": f"file://{tmp_path}/store",
            "memory": f"memory://{tmp_path.name}/store"}[backend]


def scenario(folder: Path, out, monkeypatch) -> dict:
    """Run the rare study into ``out``: 4 realisations with the second chunk's worker
    failing, resumed, then extended to 6 with a report; what each step left there."""
    study = dataclasses.replace(rare_study(folder, 4), output_dir=location(str(out)))
    real, calls = engine.drape_chunk, []

    def fails_second(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("worker killed")
        return real(*args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(engine, "drape_chunk", fails_second)
        with pytest.raises(RuntimeError, match="worker killed"):
            run_study(study, scheduler="synchronous", progress=False)
    with pytest.raises(FileNotFoundError, match="incomplete run"):
        open_ensemble(out)
    run_study(study, scheduler="synchronous", progress=False)
    resumed = read_manifest(out)["last_call"]
    run_study(dataclasses.replace(rare_study(folder, 6), output_dir=study.output_dir), scheduler="synchronous",
              progress=False)
    extended = read_manifest(out)["last_call"]
    index = run_report(out)
    where = at(out)
    summary = json.loads(where.read_text("report/summary.json"))
    fs, root = fsspec.core.url_to_fs(str(out))
    files = {p[len(root.rstrip("/")) + 1:] for p in fs.find(root)}
    return {"files": {f for f in files if f.split("/")[0] not in ("chunks", "data", "done")}, "resumed": resumed, "extended": extended, "index": index, "rare": json.loads(where.read_text(RARE_FILE)),
            "summary": summary, "ensemble": open_ensemble(out).load()}


#: What a report's summary.json says of where and when it was made, not of the ensemble:
#: the study file's text and record (its output path), the dates, the wall time.
PROVENANCE = ("study_toml", "study_json", "date_created", "history")


def numbers(summary: dict) -> dict:
    """``summary`` without its provenance (``PROVENANCE``)."""
    attrs = {k: v for k, v in summary["attrs"].items() if k not in PROVENANCE}
    return {**{k: v for k, v in summary.items() if k != "provenance"}, "attrs": attrs}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The scenario on a run folder."""
    tmp = tmp_path_factory.mktemp("folder")
    with pytest.MonkeyPatch.context() as monkeypatch:
        return scenario(tmp, tmp / "run", monkeypatch)


@pytest.mark.parametrize("backend", BACKENDS)
def test_every_backend_gives_the_same_run_resume_extension_rare_and_report(backend, tmp_path, monkeypatch,
                                                                           request, reference, unrasterised):
    got = reference if backend == "folder" else scenario(tmp_path, target(backend, tmp_path, request), monkeypatch)
    assert got["resumed"] == {"chunks": 2, "drawn": 1, "damaged": 0}  # the failed call kept its first chunk
    assert got["extended"] == {"chunks": 3, "drawn": 1, "damaged": 0}
    xr.testing.assert_identical(got["ensemble"].drop_attrs(deep=False),
                                reference["ensemble"].drop_attrs(deep=False))
    assert got["ensemble"].sizes["realization"] == 6
    assert got["rare"] == reference["rare"] and 0 < got["rare"]["levels"][0]["probability"] < 1
    assert got["summary"]["rare"]["levels"] == got["rare"]["levels"]
    assert numbers(got["summary"]) == numbers(reference["summary"])
    assert got["files"] == reference["files"] and {RARE_FILE, "run.json", "report/summary.json"} <= set(got["files"])
    assert str(got["index"]).endswith("report/index.html")


#: A hierarchical study (its zero-angle sd drawn per realisation, sd_dof 6): the run drapes
#: its fixed-parameter twin beside it and the report states the widening between the two.
HIERARCHICAL = dict(study={"seed": 3, "realizations": 8, "chunk_size": 4}, fabric={"material": "ebxhd936_like"},
                    process={"blankholder_force_N": 150.0}, solver={"mode": "energy", "rings": 4},
                    uncertainty={"zero_angle": {"mean_deg": 0.0, "sd_deg": 1.0, "correlation": "iid",
                                                "sd_dof": 6.0}})


def twin_scenario(folder: Path, out) -> dict:
    """The hierarchical study run into ``out`` and reported: its ensemble, its twin's and
    the report's numbers."""
    study = dataclasses.replace(load_study(write_study(folder, "hier", **HIERARCHICAL)),
                                output_dir=location(str(out)))
    run_study(study, scheduler="synchronous", progress=False)
    run_report(out)
    return {"summary": json.loads(at(out).read_text("report/summary.json")),
            "ensemble": open_ensemble(out).load(), "twin": open_ensemble(twin_location(out)).load()}


@pytest.fixture(scope="module")
def twin_reference(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("twin")
    return twin_scenario(tmp, tmp / "run")


@pytest.mark.parametrize("backend", BACKENDS[1:])
def test_a_hierarchical_run_drapes_and_states_its_twin_alike_on_every_backend(backend, tmp_path, request,
                                                                              twin_reference, unrasterised):
    got = twin_scenario(tmp_path, target(backend, tmp_path, request))
    for key in ("ensemble", "twin"):
        xr.testing.assert_identical(got[key].drop_attrs(deep=False), twin_reference[key].drop_attrs(deep=False))
    for summary in (got["summary"], twin_reference["summary"]):  # the twin's wall time aside
        summary["extra"][MEASURED]["how"] = re.sub(r"\([\d.]+ s of drapes\)", "", summary["extra"][MEASURED]["how"])
    assert numbers(got["summary"]) == numbers(twin_reference["summary"])


def test_a_rare_study_on_a_file_url_keeps_its_record_in_the_store(tmp_path, monkeypatch, capsys, unrasterised):
    """Issue 35's reproduction: ``uqdrape run RARE.toml --out file:///abs/store`` from one
    folder, ``uqdrape report`` from another: the store holds rare.json, nothing is written
    under ``./file:``, and the report's summary has the rare probability."""
    path = write_study(tmp_path, "rare", study={"seed": 1, "realizations": 4, "chunk_size": 2, "rare": RARE},
                       solver={"mode": "geodesic", "rings": 4}, uncertainty=UNCERTAIN)
    url = f"file://{tmp_path}/store"
    (tmp_path / "here").mkdir()
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "here")
    assert main(["run", str(path), "--out", url, "--scheduler", "synchronous", "--no-report", "-q"]) == 0
    assert list((tmp_path / "here").iterdir()) == []
    record = json.loads((tmp_path / "store" / RARE_FILE).read_text())
    monkeypatch.chdir(tmp_path / "elsewhere")
    assert main(["report", url]) == 0
    capsys.readouterr()
    summary = json.loads((tmp_path / "store" / "report" / "summary.json").read_text())
    assert summary["rare"]["levels"] == record["levels"] and summary["rare"]["threshold"] == RARE["threshold"]
    assert list((tmp_path / "elsewhere").iterdir()) == []


def test_a_mesh_mould_is_read_once_per_worker_on_a_store_and_in_a_design(tmp_path, monkeypatch):
    """The chunk task's mould cache (``ensemble.chunk.study_mould``) serves a store run's
    template and every region, and every candidate of a design: one worker (this process,
    the synchronous scheduler) reads the mesh once."""
    import trimesh

    import uqdrape.geometry.mesh as mesh
    from uqdrape.workflow import run_design

    trimesh.creation.icosphere(subdivisions=3, radius=50.0).export(tmp_path / "dome.stl")
    reads, real = [], mesh._read
    monkeypatch.setattr(mesh, "_read", lambda path: reads.append(path) or real(path))
    geometry = {"kind": "mesh", "path": "dome.stl", "radius": None}
    study = load_study(write_study(tmp_path, "dome", study={"seed": 2, "realizations": 6, "chunk_size": 2},
                                   geometry=geometry, solver={"mode": "geodesic", "rings": 4},
                                   uncertainty={"spacing": {"cv": 0.02}}))
    reads.clear()  # the study's own check of its mesh
    engine.run_ensemble(study, output_dir=f"memory://{tmp_path.name}/dome", scheduler="synchronous", progress=False)
    assert len(reads) == 1 and len(read_manifest(f"memory://{tmp_path.name}/dome")["chunks"]) == 3
    path = write_study(tmp_path, "designed", study={"seed": 2, "realizations": 4, "chunk_size": 2},
                       geometry=geometry, solver={"mode": "geodesic", "rings": 4}, process={"friction": 0.2},
                       design={"variables": "force", "force_bounds_N": [0.0, 1000.0],
                               "objective": "q95_max_abs_shear", "statistic": "estimate", "tolerance_N": 50.0,
                               "max_evaluations": 4})
    designed = load_study(path)
    reads.clear()
    run_design(designed, scheduler="synchronous", progress=False)
    assert reads == [] and xr.load_dataset(tmp_path / "designed" / "design.nc").sizes["evaluation"] >= 2


@pytest.mark.slow  # ~40-70 s on the loaded 2-core machine: a one-process cluster of two threads, 64 chunks
def test_two_threads_of_one_worker_write_chunks_without_killing_it(tmp_path):
    """Issue 40: a dask worker with two threads writes two netCDF chunks at once; the HDF5
    library under netCDF4 is not thread-safe, and without ``chunk.HDF5_LOCK`` the worker
    died mid-run (restarted by its nanny, its chunks drawn again) or a write failed with
    "NetCDF: HDF error". The run's worker is the same process from start to end, and its
    numbers are the synchronous run's."""
    from distributed import Client, LocalCluster

    study = load_study(write_study(tmp_path, "threads", study={"seed": 5, "realizations": 128, "chunk_size": 2},
                                   solver={"mode": "geodesic", "rings": 4}, uncertainty={"spacing": {"cv": 0.02}}))
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        before = client.run(os.getpid)
        out = engine.run_ensemble(study, output_dir=tmp_path / "threads", scheduler=cluster.scheduler_address,
                                  progress=False)
        assert client.run(os.getpid) == before  # one worker process throughout: none died
    alone = engine.run_ensemble(study, output_dir=tmp_path / "alone", scheduler="synchronous", progress=False)
    xr.testing.assert_identical(open_ensemble(out).load().drop_attrs(deep=False),
                                open_ensemble(alone).load().drop_attrs(deep=False))
