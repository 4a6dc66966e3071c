"""Tests of uqdrape.ensemble: deterministic inputs, chunked dask runs, the chunk store, resume.

Tiny studies (hemisphere, 4-5 rings, up to 20 realisations) with random spacing, a
random zero angle and one scalar factor. "Same numbers" means bitwise: every variable,
coordinate and variable attribute identical (global attributes hold the provenance,
which names the output folder, so they are compared separately).
"""

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from uqdrape.ensemble import (
    drape_inputs, inputs_from_rows, open_ensemble, sample_columns, sampled_inputs,
)
from uqdrape.ensemble import read_manifest
from uqdrape.schema import SOLVER_INPUTS
from uqdrape.stats import varying_factors
from uqdrape.study import FACTOR_SETTINGS, load_study
from uqdrape.workflow import run_study

from conftest import write_study

N = 20


def study_file(tmp_path, name="tiny", *, realizations=N, chunk_size=7, mode="geodesic", rings=5,
               force=100.0, plan="monte_carlo", seed=11, out=None, blankholder_model="slip"):
    """Write a tiny hemisphere study; its output folder is tmp_path/out (or ``out``)."""
    return write_study(
        tmp_path, name,
        study={"seed": seed, "realizations": realizations, "chunk_size": chunk_size},
        process={"blankholder_force_N": force, "friction": 0.2, "blankholder_model": blankholder_model},
        solver={"mode": mode, "rings": rings},
        uncertainty={"spacing": {"cv": 0.01}, "zero_angle": {"sd_deg": 3.0},
                     "friction": {"dist": "uniform", "bounds": [0.1, 0.3]}},
        sampling={"plan": plan},
        output={"directory": out or tmp_path / "out"},
    )


def moved(study, folder):
    """The same study writing to another folder."""
    return dataclasses.replace(study, output_dir=Path(folder))


def assert_same_numbers(a, b):
    xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The tiny geodesic study run in this process in one chunk: (study, loaded ensemble)."""
    tmp = tmp_path_factory.mktemp("reference")
    study = load_study(study_file(tmp))
    out = run_study(study, scheduler="synchronous", chunk_size=64, progress=False)
    with open_ensemble(out) as ds:
        return study, ds.load()


# ----------------------------------------------------------------------------- inputs


@pytest.mark.parametrize("plan", ["monte_carlo", "latin_hypercube"])
def test_inputs_of_a_realisation_do_not_depend_on_its_chunk(tmp_path, plan):
    study = load_study(study_file(tmp_path, plan=plan))
    whole = sampled_inputs(study, range(N))
    parts = [sampled_inputs(study, r) for r in ([0, 1, 2, 3, 4, 5, 6], [13, 7, 8, 9, 10, 11, 12], [14, 19, 15, 16, 17, 18])]
    order = np.r_[0:7, 13, 7:13, 14, 19, 15:19]
    assert set(whole) == {"seg_i", "seg_j", "gamma0", "friction"}
    for key, value in whole.items():
        np.testing.assert_array_equal(np.concatenate([p[key] for p in parts]), value[order])
    assert whole["seg_i"].shape == (N, 10, 11) and whole["seg_j"].shape == (N, 11, 10)
    assert whole["gamma0"].shape == (N, 10, 10)


def test_latin_hypercube_factor_hits_every_stratum_once(tmp_path):
    study = load_study(study_file(tmp_path, plan="latin_hypercube"))
    u = (sampled_inputs(study, range(N))["friction"] - 0.1) / 0.2
    np.testing.assert_array_equal(np.sort(np.floor(u * N)), np.arange(N))


def test_monte_carlo_realisation_does_not_depend_on_ensemble_size(tmp_path):
    small = load_study(study_file(tmp_path, name="small"))
    big = load_study(study_file(tmp_path, name="big", realizations=3 * N))
    a, b = sampled_inputs(small, range(N)), sampled_inputs(big, range(N))
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])
    # the inputs are random: spacing scatter near cv = 1 %, friction spread over its bounds;
    # the sd of n iid segments has standard error cv / sqrt(2 n), so 4 of them bound it
    cv, n = 0.01, a["seg_i"].size
    assert np.std(a["seg_i"] / 5.0) == pytest.approx(cv, abs=4 * cv / np.sqrt(2 * n))
    assert a["friction"].min() < 0.15 and a["friction"].max() > 0.25


def test_inputs_from_rows_maps_standard_variables(tmp_path):
    study = load_study(study_file(tmp_path))
    names = sample_columns(study)
    assert names[0] == "friction"
    n_spacing = sum(name.startswith("spacing[") for name in names)
    n_zero = sum(name.startswith("zero_angle[") for name in names)
    assert n_spacing >= 1 and n_zero >= 1 and len(names) == 1 + n_spacing + n_zero
    assert names[1:] == [f"spacing[{k}]" for k in range(n_spacing)] + [f"zero_angle[{k}]" for k in range(n_zero)]
    X = np.zeros((3, len(names)))
    X[:, 0] = [0.0, 0.5, 1.0]
    X[2, 1] = 2.0          # one KL mode of the spacing in the last row
    X[1, 1 + n_spacing] = -1.5  # one KL mode of the zero angle in the middle row
    inp = inputs_from_rows(study, X)
    np.testing.assert_allclose(inp["friction"], [0.1, 0.2, 0.3], rtol=1e-9)
    # zero KL variables: the mean fields
    np.testing.assert_array_equal(inp["seg_i"][:2], 5.0)
    np.testing.assert_array_equal(inp["gamma0"][[0, 2]], 0.0)
    assert np.ptp(inp["seg_i"][2]) > 0 and np.ptp(inp["gamma0"][1]) > 0
    with pytest.raises(ValueError, match=r"X must have shape \(R >= 1, %d\)" % len(names)):
        inputs_from_rows(study, X[:, :-1])
    X[0, 0] = 1.5
    with pytest.raises(ValueError, match=r"\['friction'\] are standard uniforms"):
        inputs_from_rows(study, X)


def test_every_study_factor_reaches_the_solver(tmp_path):
    study = load_study(study_file(tmp_path))
    values = {"orientation": [10.0, -5.0], "pre_shear": [5.0, 0.0], "skew": [0.0, 20.0],
              "crossover_x": [1.0, 0.0], "crossover_y": [0.0, -2.0], "friction": [0.25, 0.1],
              "blankholder_force": [50.0, 80.0]}
    # the card factor reaches the solver as each realisation's material (tests/test_card_scatter.py)
    assert set(values) | {"card"} == set(FACTOR_SETTINGS)
    ds = drape_inputs(study, [3, 4], {k: np.array(v) for k, v in values.items()})
    np.testing.assert_array_equal(ds.realization, [3, 4])
    for name, value in values.items():
        np.testing.assert_array_equal(ds[SOLVER_INPUTS[name].variable], value)  # the force: as applied
    np.testing.assert_allclose(ds.x.sel(i=0, j=0), [1.0, 0.0], atol=1e-9)  # the crossover node
    # fibre 1 leaves the crossover at the orientation + half the skew (in plan; off the
    # pole of the hemisphere the plan angle of the first segment drifts a little)
    angle = np.degrees(np.arctan2(ds.y.sel(i=1, j=0) - ds.y.sel(i=0, j=0), ds.x.sel(i=1, j=0) - ds.x.sel(i=0, j=0)))
    np.testing.assert_allclose(angle, [10.0, 5.0], atol=0.5)
    with pytest.raises(ValueError, match=r"inputs \['spacing_cv'\] are not solver inputs"):
        drape_inputs(study, [0], {"spacing_cv": np.array([0.1])})


def test_realisation_indices_are_checked(tmp_path):
    study = load_study(study_file(tmp_path))
    with pytest.raises(ValueError, match="realization index 20 is outside the study's 0..19"):
        sampled_inputs(study, [3, 20])


# ----------------------------------------------------------------------------- runs


@pytest.mark.slow  # ~8 s: starts two worker processes
def test_same_numbers_for_another_chunk_size_and_two_local_processes(tmp_path, reference):
    # the reference ran in one chunk of 64 in this process; one worker process and
    # chunks of 1 are covered by test_interrupted_run_resumes_to_the_same_ensemble
    study, ref = reference
    assert ref.sizes["realization"] == N
    np.testing.assert_array_equal(ref.realization, np.arange(N))
    out = run_study(moved(study, tmp_path), chunk_size=7, workers=2, progress=False)
    with open_ensemble(out) as ds:
        assert ds.x.chunks[1] == (7, 7, 6)  # lazily opened, one dask chunk per file (along realization)
        assert_same_numbers(ds, ref)


@pytest.mark.slow  # ~6 s: starts a two-process dask cluster
def test_same_numbers_on_a_distributed_cluster(tmp_path, reference):
    from distributed import LocalCluster

    study, ref = reference
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        out = run_study(moved(study, tmp_path), scheduler=cluster.scheduler_address, chunk_size=7, progress=False)
    with open_ensemble(out) as ds:
        assert_same_numbers(ds, ref)


def test_ensemble_holds_inputs_provenance_and_units(reference):
    study, ensemble = reference
    # the force is a dimension of length 1 without a sweep; each drape keeps the force it was run with
    assert ensemble.x.dims == ("blankholder_force", "realization", "i", "j")
    np.testing.assert_array_equal(ensemble.blankholder_force, study.force_levels)
    np.testing.assert_array_equal(ensemble.applied_blankholder_force, np.full((1, N), study.force_levels[0]))
    ds = ensemble.isel(blankholder_force=0)
    inputs = sampled_inputs(study, range(N))
    np.testing.assert_array_equal(ds.seg_i, inputs["seg_i"])
    np.testing.assert_array_equal(ds.seg_j, inputs["seg_j"])
    # the solver stores gamma0 after a degree -> radian -> degree round trip (1 ulp)
    np.testing.assert_allclose(ds.gamma0, inputs["gamma0"], rtol=1e-15, atol=1e-15)
    np.testing.assert_array_equal(ds.friction, inputs["friction"])
    assert ds.seg_i.dims == ("realization", "cell_i", "j") and ds.seg_j.dims == ("realization", "i", "cell_j")
    assert ds.attrs["study_name"] == "tiny" and ds.attrs["study_seed"] == 11
    assert ds.attrs["study_realizations"] == N and ds.attrs["sampling_plan"] == "monte_carlo"
    assert json.loads(ds.attrs["study_json"]) == study.to_dict()
    assert ds.attrs["study_toml"] == study.path.read_text()
    assert ds.attrs["material"] == "generic_woven" and ds.attrs["mould"].startswith("hemisphere (radius 50 mm")
    assert ds.attrs["uqdrape_version"]
    assert (ds.status == 0).all() and bool(ds.converged.all())


def test_chunk_file_opens_with_plain_xarray(tmp_path, reference):
    study, ref = reference
    out = run_study(moved(study, tmp_path), scheduler="synchronous", progress=False)  # chunks of 7
    names = sorted(p.name for p in (out / "chunks").glob("*.nc"))
    assert names == ["r0000000-0000006.nc", "r0000007-0000013.nc", "r0000014-0000019.nc"]
    assert sorted(p.name for p in (out / "chunks").iterdir()) == sorted(names + [f"{n}.sha256" for n in names])
    with xr.open_dataset(out / "chunks" / names[1]) as ds:
        np.testing.assert_array_equal(ds.realization, np.arange(7, 14))
        units = {v: ds[v].attrs.get("units") for v in ("x", "z", "shear", "cell_shear", "energy_total",
                                                       "friction", "seg_i", "gamma0")}
        assert units == {"x": "mm", "z": "mm", "shear": "degree", "cell_shear": "degree",
                         "energy_total": "J", "friction": "1", "seg_i": "mm", "gamma0": "degree"}
        assert {"x", "y", "z"} <= set(ds.coords)  # CF 'coordinates': plain xarray places the nodes
        xr.testing.assert_identical(ds.x.reset_coords(drop=True), ref.x.sel(realization=slice(7, 13)))


def test_chunks_with_the_old_design_attribute_names_still_read(tmp_path, reference):
    """Issue 35: an older uqdrape named a sensitivity run's sample matrix design_method,
    design_base_samples and design_evaluations in every chunk; such a run opens with the
    current names (``conventions.RENAMED_ATTRS``) and is still a sensitivity sample."""
    import netCDF4

    from uqdrape.ensemble.store import _file_digest
    from uqdrape.stats import study_kind

    study, ref = reference
    out = run_study(moved(study, tmp_path), scheduler="synchronous", progress=False)  # chunks of 7
    old = {"design_method": "sobol", "design_base_samples": 4, "design_evaluations": N}
    key = read_manifest(out)["checksum_key"]
    for path in sorted((out / "chunks").glob("*.nc")):  # as the older uqdrape wrote them, checksums too
        with netCDF4.Dataset(path, "a") as nc:
            nc.setncatts(old)
        path.with_name(path.name + ".sha256").write_text(_file_digest(path, key, path.name) + "\n", encoding="ascii")
    with open_ensemble(out) as ds:
        assert not {name for name in ds.attrs if name.startswith("design")}
        assert (ds.attrs["sample_method"], int(ds.attrs["sample_base_samples"]),
                int(ds.attrs["sample_evaluations"])) == ("sobol", 4, N)
        assert study_kind(ds) == "sensitivity sample"
        assert_same_numbers(ds, ref)


def test_a_sampled_force_is_stored_per_drape_beside_its_nominal_level(tmp_path):
    path = study_file(tmp_path, name="sampled")
    path.write_text(path.read_text() + '\n[uncertainty.blankholder_force]\ndist = "uniform"\nbounds = [50.0, 150.0]\n')
    study = load_study(path)
    out = run_study(study, scheduler="synchronous", progress=False)
    with open_ensemble(out) as ds:
        ds = ds.load()
    # the dimension holds the study's fixed setting (the nominal force the factor replaces) ...
    np.testing.assert_array_equal(ds.blankholder_force, [100.0])
    assert ds.applied_blankholder_force.dims == ("blankholder_force", "realization")
    # ... and each drape the force it was run with: the sampled one
    applied = ds.applied_blankholder_force.isel(blankholder_force=0).values
    np.testing.assert_array_equal(applied, sampled_inputs(study, range(N))["blankholder_force"])
    assert 50.0 <= applied.min() < applied.max() <= 150.0
    assert varying_factors(ds) == ["blankholder_force", "friction"]


@pytest.mark.slow  # end to end: an energy sweep run
def test_energy_sweep_uses_common_random_numbers(tmp_path):
    path = study_file(tmp_path, name="sweep", mode="energy", rings=4, realizations=6, chunk_size=4,
                      force=[0.0, 300.0])
    out = run_study(path, scheduler="synchronous", progress=False)
    assert sorted(p.name for p in (out / "chunks").glob("*.nc")) == [
        "f000-r0000000-0000003.nc", "f000-r0000004-0000005.nc",
        "f001-r0000000-0000003.nc", "f001-r0000004-0000005.nc"]
    with open_ensemble(out) as ds:
        ds = ds.load()
    assert ds.x.dims == ("blankholder_force", "realization", "i", "j")
    np.testing.assert_array_equal(ds.blankholder_force, [0.0, 300.0])
    assert ds.blankholder_force.attrs["units"] == "N"
    for name in ("seg_i", "seg_j", "gamma0", "friction"):
        a, b = ds[name].sel(blankholder_force=0.0), ds[name].sel(blankholder_force=300.0)
        np.testing.assert_array_equal(a, b)
        assert float(a.std("realization").max()) > 0  # random, yet shared by the levels
    energy = ds.energy_blankholder
    assert (energy.sel(blankholder_force=0.0) == 0).all() and (energy.sel(blankholder_force=300.0) > 0).all()
    assert ds.mode == "energy" and int(ds.iterations.sum()) > 0
    # an energy drape too is the same for another chunking
    again = run_study(moved(load_study(path), tmp_path / "again"), scheduler="synchronous",
                      chunk_size=64, progress=False)
    with open_ensemble(again) as other:
        assert_same_numbers(other, ds)


def test_the_studys_blankholder_model_reaches_every_drape(tmp_path, reference):
    """The same tiny geodesic study under the radial model: the same nets (geodesic), a
    blank-holder energy recomputed with the radial model, and the model recorded."""
    study, slip = reference
    radial = run_study(load_study(study_file(tmp_path, blankholder_model="radial")), scheduler="synchronous",
                       progress=False)
    with open_ensemble(radial) as ds:
        ds = ds.load()
    assert (slip.attrs["blankholder_model"], ds.attrs["blankholder_model"]) == ("slip", "radial")
    np.testing.assert_array_equal(ds.x, slip.x)
    assert (ds.energy_blankholder < slip.energy_blankholder).all()  # the slip exceeds its radial part


# ----------------------------------------------------------------------------- store and resume


@pytest.mark.slow  # ~14 s: a run in a child process, killed, then resumed
def test_interrupted_run_resumes_to_the_same_ensemble(tmp_path, reference):
    study, ref = reference
    path = study_file(tmp_path, chunk_size=1)
    chunks = tmp_path / "out" / "chunks"
    code = (f"from uqdrape.workflow import run_study; "
            f"run_study({str(path)!r}, workers=1, progress=False)")
    proc = subprocess.Popen([sys.executable, "-c", code], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while not (chunks.is_dir() and any(chunks.glob("*.nc"))):
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline, "no chunk written within 60 s"
            time.sleep(0.005)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the run and its worker process
        proc.wait()
        proc.stderr.close()
    done = len(list(chunks.glob("*.nc")))
    assert 1 <= done < N
    with pytest.raises(FileNotFoundError, match=rf"incomplete run: {N - done} of {N} chunk files missing"):
        open_ensemble(tmp_path / "out")
    run_study(path, scheduler="synchronous", progress=False)
    assert len(list(chunks.glob("*.nc"))) == N
    with open_ensemble(tmp_path / "out") as ds:
        assert_same_numbers(ds, ref)


@pytest.mark.slow  # end to end: two resumed runs
def test_half_written_part_file_is_never_a_finished_chunk(tmp_path, reference):
    study, ref = reference
    study = moved(study, tmp_path)
    chunks = tmp_path / "chunks"
    chunks.mkdir()
    (chunks / "r0000007-0000013.nc.part").write_bytes(b"\x89HDF\r\n\x1a\n half a chunk")
    run_study(study, scheduler="synchronous", progress=False)
    assert not list(chunks.glob("*.part"))  # overwritten, then renamed into place
    with open_ensemble(tmp_path) as ds:
        assert_same_numbers(ds, ref)
    # a chunk lost after a part file was left: the part file is not taken for it
    (chunks / "r0000014-0000019.nc").rename(chunks / "r0000014-0000019.nc.part")
    with pytest.raises(FileNotFoundError, match=r"1 of 3 chunk files missing in chunks/ \(r0000014-0000019.nc\)"):
        open_ensemble(tmp_path)
    before = (chunks / "r0000000-0000006.nc").stat().st_mtime_ns
    run_study(study, scheduler="synchronous", progress=False)
    assert (chunks / "r0000000-0000006.nc").stat().st_mtime_ns == before  # finished chunks are skipped
    with open_ensemble(tmp_path) as ds:
        assert_same_numbers(ds, ref)


def test_resume_refuses_another_study_or_chunking(tmp_path, reference):
    study, _ = reference
    study = moved(study, tmp_path)
    run_study(study, scheduler="synchronous", progress=False)
    other = dataclasses.replace(study, seed=12, solver=dataclasses.replace(study.solver, rings=4))
    with pytest.raises(ValueError, match=r"different study definition \(changed: solver.rings, study.seed\)"):
        run_study(other, scheduler="synchronous", progress=False)
    with pytest.raises(ValueError, match=r"was run in chunks of 7; resume with that chunk size or run again "
                                         r"without resuming") as refused:
        run_study(study, scheduler="synchronous", chunk_size=5, progress=False)
    assert refused.value.names == ("chunk_size", "resume")  # the arguments that get past it
    out = run_study(other, scheduler="synchronous", chunk_size=5, resume=False, progress=False)
    assert len(list((out / "chunks").glob("*.nc"))) == 4
    with open_ensemble(out) as ds:
        assert ds.attrs["study_seed"] == 12


def test_open_ensemble_without_a_run(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"holds no uqdrape run \(no run.json\)"):
        open_ensemble(tmp_path)


def test_bad_run_arguments(tmp_path, reference):
    study = moved(reference[0], tmp_path)
    with pytest.raises(ValueError, match=r"scheduler must be None, one of \('processes', 'synchronous'\)"):
        run_study(study, scheduler="threads")
    with pytest.raises(ValueError, match="workers=2 sets local processes; the cluster at tcp://"):
        run_study(study, scheduler="tcp://127.0.0.1:1", workers=2)
    with pytest.raises(ValueError, match="chunk_size must be a positive integer, got 0"):
        run_study(study, chunk_size=0)
    with pytest.raises(ValueError, match=r"force=10.0: pass one of study .tiny.'s blank-holder levels \[100.0\] N"):
        drape_inputs(study, [0], sampled_inputs(study, [0]), force=10.0)
    assert not tmp_path.joinpath("run.json").exists()  # nothing written for bad arguments


def test_a_finished_run_records_its_wall_time(tmp_path, reference):
    study, _ = reference
    start = time.perf_counter()
    out = run_study(moved(study, tmp_path / "timed"), scheduler="synchronous", chunk_size=64, progress=False)
    elapsed = time.perf_counter() - start
    wall = read_manifest(out)["wall_time_s"]
    assert 0.0 <= wall <= round(elapsed, 1) + 0.05  # s, rounded to 0.1 s
    # resuming the finished run adds its own (short) time to the recorded one
    run_study(moved(study, tmp_path / "timed"), scheduler="synchronous", chunk_size=64, progress=False)
    assert wall <= read_manifest(out)["wall_time_s"] <= wall + 0.5 * elapsed + 0.1
