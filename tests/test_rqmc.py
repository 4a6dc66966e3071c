"""Randomised quasi-Monte Carlo (issue 29): ``[sampling] plan = "rqmc"`` with K
randomisations of one scrambled Sobol' net; intervals from the spread between
randomisations, checked for coverage on an integrand with a known mean; a realisation
depends on the points per randomisation only, so a run extends by randomisations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ndtri

from uqdrape.ensemble import open_ensemble, read_manifest, sampled_inputs
from uqdrape.ensemble.inputs import sample_columns
from uqdrape.stats import realization_qois
from uqdrape.study import StudyError, identity, load_study
from uqdrape.stochastic.sampling import rqmc_uniforms
from uqdrape.workflow import run_study
from uqdrape.workflow.target import replicate_interval

from conftest import assert_one_line_error, write_study

#: The integrand: exp(a . z) of d = 8 standard normals z = Phi^-1(u), whose mean is
#: exp(|a|^2 / 2) (the normal's moment generating function), smooth and unbounded.
A = np.array([0.4, -0.3, 0.25, 0.2, -0.15, 0.1, 0.05, 0.02])
EXACT = np.exp(A @ A / 2)


def rqmc_values(seed, randomizations, points):
    u = np.concatenate([rqmc_uniforms(seed, k, points, A.size) for k in range(randomizations)])
    return np.exp(ndtri(u) @ A)


def test_rqmc_intervals_cover_a_known_mean_and_beat_monte_carlo():
    runs, K, M = 300, 8, 64
    covered, errors = 0, []
    for seed in range(runs):
        estimate, half = replicate_interval(rqmc_values(seed, K, M), K, 0.95)
        covered += abs(estimate - EXACT) <= half
        errors.append(estimate - EXACT)
    # 95 % nominal: the count of 300 is binomial, sd 3.8; 4 sd below and the top allowed
    assert covered >= 0.95 * runs - 4 * np.sqrt(runs * 0.95 * 0.05)
    # against plain MC of the same K M = 512 drapes: its variance is Var f / 512, Var f known in
    # closed form (E f^2 = exp(2 |a|^2)); RQMC's mean square error is far below it
    mc_variance = (np.exp(2 * A @ A) - EXACT**2) / (K * M)
    assert np.mean(np.square(errors)) < mc_variance / 10  # 25x lower at these seeds


def test_a_randomisation_is_a_balanced_net_and_randomisations_are_independent():
    u = rqmc_uniforms(3, 0, 32, 4)
    for column in u.T:  # every 1-D projection hits each of the 32 strata once
        np.testing.assert_array_equal(np.sort(np.floor(column * 32)), np.arange(32))
    other = rqmc_uniforms(3, 1, 32, 4)
    assert not np.any(np.isclose(u, other))
    np.testing.assert_array_equal(u, rqmc_uniforms(3, 0, 32, 4))


def rqmc_file(tmp_path, name="q", realizations=16, randomizations=2, **study):
    folder = tmp_path / name
    folder.mkdir(exist_ok=True)
    return write_study(folder, "q", study={"seed": 4, "realizations": realizations, "chunk_size": 8, **study},
                       solver={"mode": "geodesic", "rings": 4},
                       uncertainty={"spacing": {"cv": 0.02}, "friction": {"dist": "uniform", "bounds": [0.1, 0.3]}},
                       sampling={"plan": "rqmc", "randomizations": randomizations},
                       output={"directory": tmp_path / "out"})


def test_study_rqmc_realisations_depend_on_the_points_per_randomisation_only(tmp_path):
    two, four = load_study(rqmc_file(tmp_path, "two")), load_study(rqmc_file(tmp_path, "four", 32, 4))
    assert identity(two.to_dict()) == identity(four.to_dict())  # an extension of the same study
    a, b = sampled_inputs(two, range(16)), sampled_inputs(four, range(16))
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])
    # the friction factor takes the first Sobol' dimension: each randomisation is balanced
    u = (sampled_inputs(four, range(32))["friction"] - 0.1) / 0.2
    for k in range(4):
        np.testing.assert_array_equal(np.sort(np.floor(u[8 * k:8 * k + 8] * 8)), np.arange(8))
    assert len(sample_columns(two)) == 1 + a["seg_i"][0].size + a["seg_j"][0].size  # iid: every segment a mode
    other = load_study(rqmc_file(tmp_path, "eight", 32, 2))  # 16 points per randomisation: another point set
    assert identity(other.to_dict()) != identity(two.to_dict())


@pytest.mark.parametrize("realizations, randomizations, key, valid", [
    (24, 2, "sampling.randomizations", ("power of two",)),
    (16, 1, "sampling.randomizations", (">= 2",)),
])
def test_rqmc_keys_are_checked(tmp_path, realizations, randomizations, key, valid):
    path = rqmc_file(tmp_path, realizations=realizations, randomizations=randomizations)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key=key, valid=valid)


def test_randomizations_without_rqmc_are_refused(tmp_path):
    path = rqmc_file(tmp_path)
    path.write_text(path.read_text().replace('plan = "rqmc"', 'plan = "monte_carlo"'))
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key="sampling.randomizations", valid=("rqmc",))


def test_an_rqmc_target_run_adds_whole_randomisations(tmp_path):
    target = {"qoi": "max_abs_shear", "statistic": "mean", "half_width": 1e-9}
    out = run_study(rqmc_file(tmp_path, target=target, max_realizations=44), scheduler="synchronous",
                    progress=False)
    record = read_manifest(out)["target"]
    assert [r["realizations"] for r in record["rounds"]] == [16, 32, 40] and record["stopped_by"] == "budget"
    assert read_manifest(out)["study"]["sampling"]["randomizations"] == 5
    with open_ensemble(out) as ds:
        values = realization_qois(ds, ["max_abs_shear"])["max_abs_shear"].isel(blankholder_force=0).values
    assert record["half_width_reached"] == pytest.approx(replicate_interval(values, 5, 0.95)[1], rel=1e-12)
