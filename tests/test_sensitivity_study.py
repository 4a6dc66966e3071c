"""Sensitivity studies end to end (issue 6): a study's SALib sample draped by the ensemble
engine, QoIs per realisation, indices per blank-holder level, files, CLI and report.

Tiny energy drapes of the EBXhd-936-like NCF on the nose cone (6 rings, 30 mm from the
tip), friction and an iid zero-angle field (sd 5 deg) at F_BH = 0 and 378 N. Friction
enters the model only through the blank-holder term, so at 0 N it must do exactly
nothing and the zero-angle field must carry all the variance.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from SALib.analyze import sobol as salib_sobol_analyze
from SALib.sample import sobol as salib_sobol_sample
from SALib.test_functions import Ishigami
from scipy.stats import norm, qmc

from uqdrape.cli import main
from uqdrape.ensemble import inputs_from_rows, open_ensemble
from uqdrape.sensitivity import qoi_indices
from uqdrape.stats import SENSITIVITY_QOIS as QOIS, realization_qois
from uqdrape.study import StudyError, load_study
from uqdrape.sensitivity import (MORRIS_SCREENING_TRAJECTORIES, sensitivity_base_samples, sensitivity_sample,
                                 study_problem)
from uqdrape.workflow import open_sensitivity, run_study

from conftest import assert_one_line_error, write_study
from golden import ISHIGAMI_S1, ISHIGAMI_ST

FORCES = (0.0, 378.0)


#: The default inputs of the sensitivity studies: an iid zero-angle field and friction.
INPUTS = {"zero_angle": {"sd_deg": 5.0}, "friction": {"dist": "uniform", "bounds": [0.15, 0.3]}}


def study_file(tmp_path, name="sens", *, force=(0.0, 378.0), rings=6, base=128, method="sobol",
               uncertainty=INPUTS, mode="energy"):
    """Write a small nose-cone sensitivity study; its output folder is tmp_path/name."""
    return write_study(
        tmp_path, name,
        study={"realizations": 8, "chunk_size": 128},
        geometry={"kind": "nose_cone", "radius": None},
        fabric={"material": "ebxhd936_like"},
        process={"blankholder_force_N": list(force) if isinstance(force, tuple) else force},
        solver={"mode": mode, "rings": rings},
        uncertainty=uncertainty,
        sensitivity={"method": method, "base_samples": base},
    )


@pytest.fixture(scope="module")
def sweep_run(tmp_path_factory):
    """(study, output folder) of the friction + zero-angle Sobol' study at 0 and 378 N:
    1,024 energy drapes and their analysis, so the tests that use it are marked slow."""
    tmp = tmp_path_factory.mktemp("sweep")
    study = load_study(study_file(tmp))
    return study, run_study(study, scheduler="synchronous", progress=False)


# ----------------------------------------------------------------------------- physics


@pytest.mark.slow  # end to end: uses sweep_run
def test_friction_does_nothing_without_a_blankholder(sweep_run):
    _, out = sweep_run
    ind, maps = open_sensitivity(out)
    at0 = ind.sel(factor="friction", blankholder_force=0.0)
    for var in ("S1", "S1_conf", "ST", "ST_conf"):
        np.testing.assert_allclose(at0[var].values, 0.0, atol=1e-12)
        np.testing.assert_allclose(maps[var].sel(factor="friction", blankholder_force=0.0).fillna(0).values,
                                   0.0, atol=1e-12)
    # no blank-holder: no blank-holder energy at all
    assert bool(ind.output_constant.sel(qoi="blankholder_energy", blankholder_force=0.0))


@pytest.mark.slow  # end to end: uses sweep_run
def test_friction_drives_blankholder_energy_at_the_highest_force(sweep_run):
    _, out = sweep_run
    ind, _ = open_sensitivity(out)
    top = ind.sel(factor="friction", qoi="blankholder_energy", blankholder_force=max(FORCES))
    # U_BH is proportional to mu for a fixed net; the net barely moves with mu: ST near 1
    assert float(top.ST - top.ST_conf) > 0.7
    assert float(top.ST) == pytest.approx(1.0, abs=float(top.ST_conf))
    # and the zero-angle field's share of the line asymmetry drops as the force rises
    asym = ind.ST.sel(factor="zero_angle", qoi="asymmetry")
    assert float(asym.sel(blankholder_force=378.0)) < float(asym.sel(blankholder_force=0.0)) - 0.4


@pytest.mark.slow  # end to end: uses sweep_run
def test_zero_angle_field_alone_gives_total_index_one(sweep_run):
    """At 0 N only the zero-angle field acts (friction is inert, checked above): the group
    carries all the variance of the asymmetry, ST = 1 within its confidence interval."""
    _, out = sweep_run
    ind, _ = open_sensitivity(out)
    z = ind.sel(factor="zero_angle", blankholder_force=0.0, qoi="asymmetry")
    assert float(z.ST_conf) < 0.25
    assert abs(float(z.ST) - 1.0) < float(z.ST_conf)
    assert abs(float(z.S1) - 1.0) < float(z.S1_conf)
    assert int(ind.n_variables.sel(factor="zero_angle")) == (2 * 6) ** 2  # iid: every cell a KL mode
    assert str(ind.factor_kind.sel(factor="zero_angle").values) == "field"


@pytest.mark.slow  # end to end: uses sweep_run
def test_sample_rows_are_the_realisations_at_every_level(sweep_run):
    """Common random numbers: the same sample rows (friction, zero-angle field) at both forces."""
    study, out = sweep_run
    sample = sensitivity_sample(study)
    with open_ensemble(out) as ds:
        assert ds.sizes["realization"] == sample.n_evaluations == 128 * (2 + 2)
        friction = ds["friction"].transpose("blankholder_force", "realization").values
        gamma0 = ds["gamma0"].isel(realization=slice(0, 40)).transpose("blankholder_force", ...).values
    inputs = inputs_from_rows(study, sample.standard[:40])
    for level in range(len(FORCES)):
        np.testing.assert_array_equal(friction[level], inputs_from_rows(study, sample.standard)["friction"])
        # the drape stores gamma0 back from radians: equal to round-off
        np.testing.assert_allclose(gamma0[level], inputs["gamma0"], rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------- stored results


@pytest.mark.slow  # end to end: uses sweep_run
def test_stored_indices_have_intervals_sample_size_and_units(sweep_run):
    _, out = sweep_run
    ind, maps = open_sensitivity(out)
    assert ind["ST"].dims == ("factor", "qoi", "blankholder_force")
    assert list(ind.qoi.values) == list(QOIS)
    assert list(ind.blankholder_force.values) == list(FORCES) and ind.blankholder_force.attrs["units"] == "N"
    assert set(ind.factor.values) == {"friction", "zero_angle"}
    for var in ("S1", "S1_conf", "ST", "ST_conf"):
        assert var in ind and var in maps
    assert (ind.ST_conf.values >= 0).all() and (ind.ST_conf.values > 0).any()
    assert ind.attrs["base_samples"] == 128 and ind.attrs["n_evaluations"] == 512
    assert ind.attrs["method"] == "sobol" and ind.attrs["conf_level"] == 0.95
    assert dict(zip(ind.qoi.values, ind.qoi_units.values))["blankholder_energy"] == "J"
    assert maps["ST"].dims == ("factor", "i", "j", "blankholder_force")
    assert maps.sizes["i"] == maps.sizes["j"] == 13 and maps.attrs["output_units"] == "degree"
    # the crossover node's shear does not vary: flagged constant, not ranked on round-off
    assert bool(maps.output_constant.sel(i=0, j=0).all())


@pytest.mark.slow  # end to end: uses sweep_run
def test_stored_indices_round_trip_and_equal_a_recomputation(sweep_run, tmp_path):
    study, out = sweep_run
    ind, _ = open_sensitivity(out)
    ind.to_netcdf(tmp_path / "again.nc")
    xr.testing.assert_identical(xr.load_dataset(tmp_path / "again.nc"), ind)
    with open_ensemble(out) as ds:
        again = qoi_indices(sensitivity_sample(study), realization_qois(ds), seed=study.seed)
    xr.testing.assert_identical(again.drop_attrs(), ind.drop_attrs())


@pytest.mark.slow  # end to end: uses sweep_run
def test_qois_of_a_drape(sweep_run):
    _, out = sweep_run
    with open_ensemble(out) as ds:
        one = ds.isel(realization=slice(0, 5)).load()
    q = realization_qois(one)
    assert list(q.data_vars) == list(QOIS)
    np.testing.assert_array_equal(q.blankholder_energy.values, one.energy_blankholder.values)
    np.testing.assert_allclose(q.asymmetry, q.mean_shear_positive + q.mean_shear_negative, rtol=1e-12)
    np.testing.assert_allclose(q.max_abs_shear, np.nanmax(np.abs(one.shear.values), axis=(2, 3)))
    assert (q.mean_shear_negative < q.mean_shear_positive).all()  # compliant - quadrants (Fig 5.9)
    with pytest.raises(ValueError, match="must be distinct names from max_abs_shear"):
        realization_qois(one, ["max_shear"])


# ----------------------------------------------------------------------------- same path as SALib


def test_ishigami_through_the_study_sample_path_reproduces_salib(tmp_path):
    """Swap the drape for Ishigami: study factors -> standard sample -> inputs_from_rows
    (physical values) -> qoi_indices gives SALib's own indices and the analytic ones."""
    uncertainty = {name: {"dist": "uniform", "bounds": [-np.pi, np.pi]}
                   for name in ("orientation", "pre_shear", "skew")}
    study = load_study(study_file(tmp_path, force=0.0, base=1024, uncertainty=uncertainty))
    sample = sensitivity_sample(study)
    inputs = inputs_from_rows(study, sample.standard)
    x = np.stack([inputs["orientation"], inputs["pre_shear"], inputs["skew"]], axis=1)
    qois = xr.Dataset({"y": (("blankholder_force", "realization"), Ishigami.evaluate(x)[None])},
                      coords={"blankholder_force": [0.0], "realization": np.arange(sample.n_evaluations)})
    ours = qoi_indices(sample, qois, seed=study.seed).squeeze("blankholder_force")

    physical = {"num_vars": 3, "names": ["x1", "x2", "x3"], "bounds": [[-np.pi, np.pi]] * 3}
    X = salib_sobol_sample.sample(physical, 1024, calc_second_order=False, seed=study.seed)
    np.testing.assert_allclose(x, X, rtol=0, atol=1e-12)
    ref = salib_sobol_analyze.analyze(physical, Ishigami.evaluate(X), calc_second_order=False,
                                      seed=np.random.default_rng(study.seed))
    for var in ("S1", "S1_conf", "ST", "ST_conf"):
        np.testing.assert_allclose(ours[var].sel(qoi="y").values, ref[var], atol=1e-9)
    np.testing.assert_allclose(ours.S1.sel(qoi="y").values, ISHIGAMI_S1, atol=0.05)
    np.testing.assert_allclose(ours.ST.sel(qoi="y").values, ISHIGAMI_ST, atol=0.05)


def test_unbounded_factors_are_coded_as_standard_normals(tmp_path):
    uncertainty = {"orientation": {"dist": "normal", "mean": 0.0, "sd": 2.0},
                   "crossover_x": {"dist": "uniform", "bounds": [-3.0, 3.0]}}
    study = load_study(study_file(tmp_path, force=0.0, base=64, uncertainty=uncertainty))
    problem = study_problem(study)
    assert problem["names"] == ["orientation", "crossover_x"] and problem["dists"] == ["norm", "unif"]
    morris = sensitivity_sample(study, "morris")
    values = inputs_from_rows(study, morris.standard)["orientation"]
    # Morris end levels at the 0.5 % / 99.5 % quantiles (+-2.58 sd), not u = 0 / 1 (+-7 sd)
    assert np.abs(values).max() == pytest.approx(2.0 * norm.ppf(0.995), rel=1e-9)
    assert morris.meta["base_samples"] == MORRIS_SCREENING_TRAJECTORIES == sensitivity_base_samples(study, "morris")


# ----------------------------------------------------------------------------- refusals


@pytest.mark.parametrize("method, base, minimum", [("sobol", 32, "the minimum is 64"),
                                                   ("morris", 4, "the minimum is 10 trajectories")])
def test_too_small_base_sample_is_refused_with_the_minimum(tmp_path, method, base, minimum):
    path = study_file(tmp_path, base=base, method=method)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key="sensitivity.base_samples", value=str(base), valid=[minimum])


def test_one_group_and_huge_sobol_samples_are_refused(tmp_path):
    # the validator refuses it before anything runs
    alone = study_file(tmp_path, name="alone", uncertainty={"zero_angle": {"sd_deg": 5.0}})
    with pytest.raises(StudyError) as err:
        load_study(alone)
    assert_one_line_error(str(err.value), file=alone, key="sensitivity.method",
                          valid=["at least two [uncertainty.*] inputs", "(found: zero_angle)"])
    big = {"spacing": {"cv": 0.001}, "zero_angle": {"sd_deg": 5.0}}
    huge = load_study(study_file(tmp_path, name="huge", rings=30, uncertainty=big))
    with pytest.raises(ValueError, match=r"more than scipy's 21201 .*'spacing': 7320, 'zero_angle': 3600"):
        sensitivity_sample(huge)


# ----------------------------------------------------------------------------- command line


@pytest.mark.slow  # ~25 s: 640 energy drapes in a worker process, two analyses and a report
def test_uqdrape_run_writes_indices_and_a_report_with_the_sensitivity_figures(tmp_path, capsys):
    path = study_file(tmp_path, name="cli", rings=4, base=64)
    assert main(["run", str(path), "--quiet", "--workers", "1"]) == 0
    out = tmp_path / "cli"
    assert (out / "sensitivity.nc").is_file() and (out / "sensitivity_maps.nc").is_file()
    page = (out / "report" / "index.html").read_text()
    figures = ["sensitivity_bars.png", "sensitivity_vs_force.png", "sensitivity_map_S1.png", "sensitivity_map_ST.png"]
    for name in figures:
        assert f'src="{name}"' in page and (out / "report" / name).is_file()
    assert "<h2>Sensitivity</h2>" in page and "F_BH = 378 N" in page

    # a Morris screening run of the same study goes to its own folder
    assert main(["run", str(path), "--quiet", "--workers", "1", "--method", "morris", "--no-report"]) == 0
    morris = xr.load_dataset(tmp_path / "cli-morris" / "sensitivity.nc")
    assert morris.attrs["method"] == "morris" and "mu_star_conf" in morris
    assert morris.attrs["n_evaluations"] == MORRIS_SCREENING_TRAJECTORIES * 3
    np.testing.assert_allclose(morris.mu_star.sel(factor="friction", blankholder_force=0.0), 0.0, atol=1e-12)
    assert capsys.readouterr().err == ""


def test_shipped_study_is_five_groups_within_the_sobol_dimension_limit():
    study = load_study(Path(__file__).resolve().parents[1] / "studies" / "sensitivity-vs-blankholder.toml")
    problem = study_problem(study)
    groups = list(dict.fromkeys(problem["groups"]))
    assert groups == ["friction", "orientation", "crossover_x", "spacing", "zero_angle"]
    assert problem["groups"].count("spacing") == 2 * 40 * 41 and problem["groups"].count("zero_angle") == 40 * 40
    assert 2 * problem["num_vars"] <= qmc.Sobol.MAXDIM
    assert study.force_levels == (0.0, 126.0, 252.0, 378.0)
    assert (study.sensitivity.method, sensitivity_base_samples(study, "sobol")) == ("sobol", 256)
