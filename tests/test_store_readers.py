"""Everything that reads an ensemble reads a zarr store as it reads a run folder (issue 28):
statistics, the report, the sensitivity analysis and every export, from a file:// store
and from an S3 store on moto's server on 127.0.0.1, against the same study's run folder.

The run is test_zarrstore's tiny sweep (hemisphere, 5 rings, 20 realisations in chunks
of 7, 0 and 100 N). A store's drapes are bitwise the folder's (test_zarrstore), so
everything computed from them is asserted identical (xarray's assert_identical, or the
same bytes), not close.
"""

from __future__ import annotations

import dataclasses
import json

import fsspec
import meshio
import numpy as np
import pytest
import xarray as xr

from uqdrape.cli import main
from uqdrape.conventions import cf_decode
from uqdrape.ensemble import open_ensemble, run_ensemble
from uqdrape.stats import SENSITIVITY_QOIS, node_statistics, realization_qois
from uqdrape.study import load_study
from uqdrape.workflow import open_sensitivity, run_report, run_study
from uqdrape.workflow.run import analysed

from conftest import write_study
from test_export import hemisphere_mesh
from test_zarrstore import tiny

STORES = ("file", "s3")


@pytest.fixture(scope="module")
def runs(tmp_path_factory, s3):  # noqa: F811
    """(study, tmp folder, {kind: URL}): the tiny sweep as a run folder, a file:// store and an S3 store."""
    tmp = tmp_path_factory.mktemp("readers")
    study = tiny(tmp)
    run_ensemble(study, scheduler="synchronous", progress=False)
    urls = {"file": f"file://{tmp}/store", "s3": "s3://runs/readers"}
    for url in urls.values():
        run_ensemble(study, output_dir=url, scheduler="synchronous", progress=False)
    return study, tmp, urls


def same(a, b):
    xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))


def read(url: str) -> bytes:
    with fsspec.open(url, "rb") as f:
        return f.read()


@pytest.mark.parametrize("kind", STORES)
def test_statistics_and_qois_of_a_store_equal_the_folder(runs, kind):
    study, _, urls = runs
    with open_ensemble(study.output_dir) as folder, open_ensemble(urls[kind]) as store:
        assert store["shear"].chunks[1] == (7, 7, 6)  # lazy, a region a dask chunk
        same(node_statistics(folder), node_statistics(store))
        same(realization_qois(folder, SENSITIVITY_QOIS), realization_qois(store, SENSITIVITY_QOIS))


@pytest.fixture(scope="module")
def folder_report(runs):
    study, tmp, _ = runs
    return run_report(study.output_dir, tmp / "folder-report")


@pytest.mark.parametrize("kind", STORES)
def test_report_of_a_store_is_put_under_its_url_and_equals_the_folders(runs, folder_report, kind, capsys):
    study, tmp, urls = runs
    url = urls[kind]
    assert main(["report", url, "-q"]) == 0
    assert capsys.readouterr().out == f"report: {url}/report/index.html\n"
    assert b"</html>" in read(f"{url}/report/index.html")
    folder = json.loads(folder_report.with_name("summary.json").read_text())
    store = json.loads(read(f"{url}/report/summary.json"))
    # the same page but for the provenance (a store records no wall time) and the run's own dates
    for page in (folder, store):
        del page["provenance"], page["attrs"]["date_created"], page["attrs"]["history"]
    assert store == folder
    local = tmp / f"{kind}-statistics.nc"
    local.write_bytes(read(f"{url}/report/statistics.nc"))
    same(xr.load_dataset(folder_report.with_name("statistics.nc")), xr.load_dataset(local))
    names = {p.rsplit("/", 1)[-1] for p in fsspec.core.url_to_fs(url)[0].ls(f"{url.split('://')[1]}/report")}
    assert names == {p.name for p in folder_report.parent.iterdir()}  # every figure, nothing half-written


@pytest.fixture(scope="module")
def part(runs):
    """(trim CSV, FE mesh) inside the tiny net: a circle of radius 8 mm and a hemisphere cap mesh."""
    study, tmp, _ = runs
    t = np.linspace(0.0, 2 * np.pi, 40, endpoint=False)
    edge = tmp / "edge.csv"
    edge.write_text("x_mm,y_mm\n" + "".join(f"{8 * np.cos(a):.6f},{8 * np.sin(a):.6f}\n" for a in t))
    return edge, hemisphere_mesh(study.geometry.build_mould(), tmp / "cap.msh", radius_mm=12.0, rings=6)


@pytest.fixture(scope="module")
def folder_exports(runs, part):
    study, tmp, _ = runs
    edge, mesh = part
    out = tmp / "folder-export" / "tiny"
    assert main(["export", str(study.output_dir), "--to", "vtk", "fe", "flat", "cut", "netcdf", "--mesh", str(mesh),
                 "--trim", str(edge), "--ply", "P1", "--out", str(out), "-q"]) == 0
    return out.parent


@pytest.mark.parametrize("kind", STORES)
def test_exports_of_a_store_equal_the_folders(runs, part, folder_exports, kind, capsys):
    study, tmp, urls = runs
    url, (edge, mesh) = urls[kind], part
    capsys.readouterr()
    assert main(["export", url, "--to", "vtk", "fe", "flat", "cut", "netcdf", "--mesh", str(mesh), "--trim",
                 str(edge), "--ply", "P1", "-q"]) == 0
    name = url.rsplit("/", 1)[-1]
    written = capsys.readouterr().out.splitlines()[-1].removeprefix("wrote ").split(", ")
    expected = sorted(p.name.replace("tiny", name, 1) for p in folder_exports.iterdir())
    assert sorted(w.rsplit("/", 1)[-1] for w in written) == expected
    assert all(w.startswith(f"{url}/export/") for w in written)
    for path in folder_exports.iterdir():
        got = read(f"{url}/export/{path.name.replace('tiny', name, 1)}")
        if path.suffix in (".csv", ".vtu", ".inp"):  # no date in them: the same bytes
            assert got == path.read_bytes(), path.name
        elif path.suffix == ".nc":
            local = tmp / f"{kind}.nc"
            local.write_bytes(got)
            with xr.open_dataset(local) as mine, xr.open_dataset(path) as theirs:
                same(theirs, mine)
                assert mine.attrs["Conventions"] == "CF-1.8" and mine.attrs["history"].split(" ", 2)[1:2] == ["uqdrape"]
    fe = meshio.read(folder_exports / "tiny-0N-fe.vtu").cell_data["theta1"][0]
    assert np.isfinite(fe).sum() > 10  # the FE mapping compared above is not empty


def test_netcdf_export_is_the_ensemble_with_its_cf_attributes(runs, tmp_path):
    study, _, urls = runs
    out = tmp_path / "one.nc"
    assert main(["export", urls["file"], "--to", "netcdf", "--out", str(out), "-q"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["one.nc"]  # STEM.nc itself, nothing else left
    with xr.open_dataset(out) as nc, open_ensemble(study.output_dir) as folder:
        assert nc.attrs["Conventions"] == "CF-1.8"
        assert nc.attrs["title"] == "uqdrape ensemble: study tiny, 20 realisations at 0, 100 N"
        assert nc["shear"].attrs["units"] == "degree" and nc["shear"].encoding["coordinates"] == "x y z"
        assert nc["x"].attrs["units"] == "mm"
        same(folder.load(), cf_decode(nc).load())  # CF-aware readers make x y z coordinates


@pytest.fixture(scope="module")
def morris(tmp_path_factory):
    """(study, run folder) of a Morris screening of the tiny net's orientation and skew: 30 drapes a level."""
    tmp = tmp_path_factory.mktemp("morris")
    study = load_study(write_study(tmp, "morris", study={"realizations": 8, "chunk_size": 9},
                                   process={"blankholder_force_N": [0.0, 100.0]},
                                   solver={"mode": "geodesic", "rings": 5},
                                   uncertainty={"orientation": {"dist": "normal", "mean": 0.0, "sd": 2.0},
                                                "skew": {"dist": "uniform", "bounds": [-2.0, 2.0]}},
                                   sensitivity={"method": "morris", "base_samples": 10}))
    return study, run_study(study, scheduler="synchronous", progress=False)


@pytest.mark.parametrize("kind", STORES)
def test_sensitivity_of_a_store_equals_the_folders(runs, morris, kind):
    _, _, urls = runs
    study, folder = morris
    url = urls[kind].replace("readers", "morris")
    assert run_study(dataclasses.replace(study, output_dir=url), scheduler="synchronous", progress=False) == url
    assert analysed(url)
    (ind_f, maps_f), (ind_s, maps_s) = open_sensitivity(folder), open_sensitivity(url)
    same(ind_f, ind_s)
    same(maps_f, maps_s)
    assert ind_s.attrs["run_key"] == ind_f.attrs["run_key"] and np.isfinite(ind_s["mu_star"]).all()


def test_a_store_out_of_reach_is_one_line_exit_3_for_every_reader(runs, no_s3_credentials, capsys):  # noqa: F811
    for command in (["report", "s3://runs/readers"], ["export", "s3://runs/readers", "--to", "netcdf"]):
        assert main(command) == 3
        err = capsys.readouterr().err
        assert err.startswith(f"uqdrape {command[0]}: error: s3://runs/readers: cannot reach the store (NoCredentials")
        assert err.count("\n") == 1 and "AWS_ENDPOINT_URL" in err
