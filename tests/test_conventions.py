"""CF-1.8 conventions of the netCDF files uqdrape writes (uqdrape.conventions), rule by
rule on a drape file and on ensemble chunks, plus the CF checker where it installs."""

import datetime
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr

from uqdrape import __version__
from uqdrape.conventions import cf_decode, cf_encode
from uqdrape.drape import drape
from uqdrape.ensemble import open_ensemble
from uqdrape.workflow import run_report, run_study
from uqdrape.geometry import build
from uqdrape.material import load_material
from uqdrape.study import StudyError, load_study

from conftest import assert_cf_compliant, write_study


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """A two-force drape with a material (so it has locking flags), in memory and written
    through cf_encode."""
    ds = drape(build("hemisphere", radius=50.0), 5.0, 4, material=load_material("generic_woven"),
               blankholder_force=[0.0, 100.0])
    path = tmp_path_factory.mktemp("cf") / "drape.nc"
    encoded, encoding = cf_encode(ds, title="a test drape", history="pytest")
    encoded.to_netcdf(path, encoding=encoding)
    return ds, path


def test_node_variables_name_their_positions(written):
    ds, path = written
    with netCDF4.Dataset(path) as nc:
        for name in ("shear", "status", "locked"):
            assert nc[name].getncattr("coordinates") == "x y z"
        assert "coordinates" not in nc["x"].ncattrs() and "coordinates" not in nc["energy_total"].ncattrs()
        assert nc["turn"].getncattr("coordinates") == "arm_label"
    with xr.open_dataset(path) as plain:  # a CF-aware reader places the nodes
        assert {"x", "y", "z"} <= set(plain.shear.coords)


def test_coordinates_are_numeric_described_and_without_fill_value(written):
    _, path = written
    with netCDF4.Dataset(path) as nc:
        for dim in nc.dimensions:
            if dim not in nc.variables:
                continue
            var = nc[dim]
            assert var.dtype.kind in "iuf", dim
            assert "_FillValue" not in var.ncattrs(), dim
            assert var.getncattr("long_name") and var.getncattr("units"), dim
        assert nc["arm_label"].dimensions == ("arm", "string2")  # a char array, CF-1.8 style
        assert list(nc["arm_label"][:]) == ["+i", "+j", "-i", "-j"]


def test_flags_have_the_variables_type_and_booleans_are_cf_bytes(written):
    _, path = written
    with netCDF4.Dataset(path) as nc:
        status = nc["status"]
        assert status.dtype == np.int8 and status.getncattr("flag_values").dtype == np.int8
        assert status.getncattr("flag_meanings").split()[0] == "ok"
        for name in ("converged", "cell_locked"):
            var = nc[name]
            assert var.dtype == np.int8
            assert var.getncattr("flag_values").dtype == np.int8
            np.testing.assert_array_equal(var.getncattr("flag_values"), [0, 1])
            assert var.getncattr("flag_meanings") == "false true"


def test_global_attributes_and_both_locking_angles(written):
    _, path = written
    with netCDF4.Dataset(path) as nc:
        attrs = {k: nc.getncattr(k) for k in nc.ncattrs()}
    assert attrs["Conventions"] == "CF-1.8" and attrs["title"] == "a test drape"
    assert attrs["source"].startswith(f"uqdrape {__version__}")
    created = datetime.datetime.fromisoformat(attrs["date_created"])
    assert abs(datetime.datetime.now(datetime.UTC) - created) < datetime.timedelta(minutes=10)
    assert attrs["history"] == f"{attrs['date_created']} pytest"
    assert attrs["locking_angle_deg"] == 50.0 and attrs["locking_angle_neg_deg"] == 50.0


def test_numbers_and_layout_survive_the_encoding(written):
    ds, path = written
    back = cf_decode(xr.load_dataset(path))
    assert sorted(back.variables) == sorted(ds.variables)
    for name in ds.variables:
        assert back[name].dtype == ds[name].dtype, name
        np.testing.assert_array_equal(back[name].values, ds[name].values)
        assert back[name].dims == ds[name].dims
    assert not ds.shear.encoding and isinstance(ds.status.attrs["flag_values"], list)  # input untouched


def _study(tmp_path, name, float32=None):
    """A 16-realisation geodesic sweep with random spacing (output.float32 = ``float32`` if given)."""
    return write_study(tmp_path, name, study={"realizations": 16, "chunk_size": 16},
                       process={"blankholder_force_N": [0.0, 100.0]}, solver={"rings": 12},
                       uncertainty={"spacing": {"cv": 0.01}}, output={"float32": float32})


def test_float32_chunks_are_smaller_and_rounded_only(tmp_path):
    full = run_study(_study(tmp_path, "full"), scheduler="synchronous", progress=False)
    small = run_study(_study(tmp_path, "small", True), scheduler="synchronous", progress=False)
    size = {p: sum(f.stat().st_size for f in (p / "chunks").glob("*.nc")) for p in (full, small)}
    assert size[small] < 0.6 * size[full]  # HDF5's per-variable overhead weighs on so small a run
    with open_ensemble(full) as a, open_ensemble(small) as b:
        assert a.shear.dtype == np.float64 and b.shear.dtype == np.float32
        for name in ("x", "shear", "seg_i", "energy_total"):
            np.testing.assert_array_equal(b[name].values, a[name].values.astype(np.float32))
        np.testing.assert_array_equal(a.status.values, b.status.values)
    with netCDF4.Dataset(next((small / "chunks").glob("*.nc"))) as nc:
        assert nc["shear"].filters()["zlib"] and nc["shear"].dtype == np.float32
        assert nc["blankholder_force"].dtype == np.float64  # coordinates keep their precision
        assert nc.getncattr("title").startswith("uqdrape ensemble chunk: study small")
    with pytest.raises(StudyError, match="output.float32"):
        load_study(_study(tmp_path, "bad", "yes"))


@pytest.mark.slow
def test_cf_checker_finds_no_errors_or_warnings(written, tmp_path):
    study = run_study(_study(tmp_path, "chunks"), scheduler="synchronous", progress=False)
    statistics = Path(run_report(study)).parent / "statistics.nc"  # the report's per-node statistics
    for path in (written[1], next((study / "chunks").glob("*.nc")), statistics):
        assert_cf_compliant(path, tmp_path)
