"""The hierarchical ensemble (issue 25): a zero-angle sd drawn per realisation from its
calibration's uncertainty (``[uncertainty.zero_angle] sd_dof``), and ``uqdrape calibrate``
writing that uncertainty into the block."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from conftest import assert_one_line_error, write_study
from test_calibration import TABLE_5_1, table_5_1_points
from uqdrape.calibration import calibrate_points, read_points, study_block
from uqdrape.calibration.block import sd_dof
from uqdrape.cli import main
from uqdrape.ensemble import sampled_inputs
from uqdrape.ensemble.inputs import realization_sd_deg
from uqdrape.study import load_study


def _study(tmp_path, name="h", realizations=4000, plan="monte_carlo", **field):
    zero = {"mean_deg": -2.3, "sd_deg": 5.6, **field}
    return load_study(write_study(tmp_path, name, study={"realizations": realizations},
                                  uncertainty={"zero_angle": zero}, sampling={"plan": plan}))


def test_table_5_1_block_carries_n_minus_1_degrees_of_freedom(tmp_path):
    """iid: the sd interval is the chi-square one, so the matched m is n - 1 = 37."""
    cal = calibrate_points(read_points(table_5_1_points(tmp_path)), family="iid")
    table = study_block(cal)["uncertainty"]["zero_angle"]
    assert table["sd_dof"] == pytest.approx(TABLE_5_1["n"] - 1, rel=1e-3)
    assert sd_dof(cal.fit.estimates["sd_deg"], 0.9) == pytest.approx(37.0, rel=1e-3)


@pytest.mark.parametrize("plan", ["monte_carlo", "latin_hypercube"])
def test_sampled_sd_per_realisation_is_the_stated_distribution(tmp_path, plan):
    """m s² / sd_r² over 4000 realisations is χ²_m (Kolmogorov-Smirnov), and each
    realisation's γ0 is the fixed-sd study's, rescaled to its own sd_r."""
    study = _study(tmp_path, plan=plan, sd_dof=37.0)
    sd = realization_sd_deg(study, np.arange(4000))
    ks = scipy.stats.kstest(37.0 * 5.6 ** 2 / sd ** 2, scipy.stats.chi2(37.0).cdf)
    assert ks.pvalue > 1e-3
    fixed = _study(tmp_path, name="f", plan=plan)
    assert np.all(realization_sd_deg(fixed, np.arange(10)) == 5.6)
    r = np.arange(40)
    gamma0 = sampled_inputs(study, r)["gamma0"]
    # the fixed-sd study's noise is the same: the hierarchy only rescales each realisation
    # (and the other standard variables keep their values)
    base = sampled_inputs(fixed, r)["gamma0"]
    np.testing.assert_allclose((gamma0 + 2.3) * 5.6 / sd[:40, None, None], base + 2.3, atol=1e-9)


def test_sd_dof_with_rqmc_or_a_bad_value_is_one_line(tmp_path, capsys):
    for field, sampling, key in (({"sd_dof": 0}, {}, "uncertainty.zero_angle.sd_dof"),
                                 ({"sd_dof": 1.4}, {}, "uncertainty.zero_angle.sd_dof"),  # 99.9 %: sd 29 deg
                                 ({"sd_dof": 37}, {"plan": "rqmc", "randomizations": 4},
                                  "uncertainty.zero_angle.sd_dof")):
        path = write_study(tmp_path, "bad", study={"realizations": 64},
                           uncertainty={"zero_angle": {"sd_deg": 2.0, **field}}, sampling=sampling)
        assert main(["validate", str(path)]) != 0
        assert_one_line_error(capsys.readouterr().err, file=path.name, key=key)


# -- the posterior sample (emcee) ---------------------------------------------------------


def test_posterior_of_table_5_1_is_the_chi_square_interval(tmp_path):
    """iid with p(σ) ∝ 1/σ: σ² | y is scaled-inverse-χ²_37, so the sample's 90 % interval is
    the profile's (closed-form) one to Monte Carlo error (about 1 % here), and sd_dof from
    it is near 37."""
    pytest.importorskip("emcee")
    cal = calibrate_points(read_points(table_5_1_points(tmp_path)), family="iid", posterior=True)
    post, est = cal.posterior, cal.fit.estimates["sd_deg"]
    assert post.interval("sd_deg", 0.9) == pytest.approx((est.lower, est.upper), rel=0.02)
    assert 0.2 < post.acceptance < 0.95
    assert study_block(cal)["uncertainty"]["zero_angle"]["sd_dof"] == pytest.approx(37, rel=0.15)


def test_posterior_agrees_with_the_profile_intervals_of_a_correlated_field(tmp_path):
    """A squared-exponential 8 x 8 grid: each posterior 90 % interval end within 10 % of
    the profile likelihood's (measured: within 3 %)."""
    pytest.importorskip("emcee")
    from test_calibration import _grid_csv

    cal = calibrate_points(read_points(_grid_csv(tmp_path, "squared_exponential")), family="squared_exponential",
                           posterior=True)
    for name in ("sd_deg", "length_1_mm", "length_2_mm"):
        est = cal.fit.estimates[name]
        assert cal.posterior.interval(name, 0.9) == pytest.approx((est.lower, est.upper), rel=0.1), name


def test_calibrate_posterior_flag_writes_its_intervals(tmp_path, capsys):
    pytest.importorskip("emcee")
    out = tmp_path / "z.toml"
    assert main(["calibrate", str(table_5_1_points(tmp_path)), "--out", str(out), "--posterior", "-q"]) == 0
    text = out.read_text(encoding="utf-8")
    assert "posterior (emcee" in text and "sd_dof = " in text and "posterior interval" in text


def test_posterior_without_emcee_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "emcee", None)  # import emcee raises ImportError
    out = tmp_path / "z.toml"
    assert main(["calibrate", str(table_5_1_points(tmp_path)), "--out", str(out), "--posterior", "-q"]) != 0
    assert_one_line_error(capsys.readouterr().err, valid=("uqdrape[calibrate]",))
    assert not out.exists()
