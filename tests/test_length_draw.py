"""The hierarchical ensemble's correlation lengths (issue 25): a zero-angle field's lengths
drawn per realisation (``[uncertainty.zero_angle] length_log_sd``), and ``uqdrape
calibrate`` writing the key only for lengths the data identify."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.stats

from conftest import assert_one_line_error, write_study
from uqdrape.cli import main
from uqdrape.ensemble import sampled_inputs
from uqdrape.ensemble.inputs import realization_length_mm, realization_sd_deg
from uqdrape.study import load_study

LENGTH = [12.0, 30.0]


def _study(tmp_path, name="l", realizations=4000, plan="monte_carlo", **field):
    zero = {"mean_deg": -2.3, "sd_deg": 5.6, "correlation": "exponential", "length_mm": LENGTH, **field}
    return load_study(write_study(tmp_path, name, study={"realizations": realizations},
                                  uncertainty={"zero_angle": zero}, sampling={"plan": plan}))


@pytest.mark.parametrize("plan", ["monte_carlo", "latin_hypercube"])
def test_drawn_log_lengths_are_normal_about_the_study_length(tmp_path, plan):
    """ln L_r over 4000 realisations is Normal(ln L, s) (Kolmogorov-Smirnov), both lengths
    moved by the same factor."""
    study = _study(tmp_path, plan=plan, length_log_sd=0.3)
    lengths = realization_length_mm(study, np.arange(4000))
    z = np.log(lengths / LENGTH) / 0.3
    np.testing.assert_allclose(z[:, 0], z[:, 1], rtol=0, atol=1e-12)
    assert scipy.stats.kstest(z[:, 0], "norm").pvalue > 1e-3
    fixed = realization_length_mm(_study(tmp_path, name="f", plan=plan), np.arange(3))
    assert np.all(fixed == LENGTH)


@pytest.mark.parametrize("extra", [{}, {"sd_dof": 37.0}])
def test_every_other_number_is_unchanged_bitwise(tmp_path, extra):
    """The lengths' normal comes last: the drawn sds and every factor are bitwise those of
    the run without length_log_sd."""
    factors = {"friction": {"dist": "normal", "mean": 0.2, "sd": 0.01}}
    path = write_study(tmp_path, "a", study={"realizations": 64},
                       uncertainty={"zero_angle": {"sd_deg": 2.0, "correlation": "exponential",
                                                   "length_mm": LENGTH, **extra}, **factors})
    drawn = write_study(tmp_path, "b", study={"realizations": 64},
                        uncertainty={"zero_angle": {"sd_deg": 2.0, "correlation": "exponential", "length_mm": LENGTH,
                                                    "length_log_sd": 0.5, **extra}, **factors})
    base, hier = load_study(path), load_study(drawn)
    r = np.arange(64)
    assert np.array_equal(sampled_inputs(base, r)["friction"], sampled_inputs(hier, r)["friction"])
    assert np.array_equal(realization_sd_deg(base, r), realization_sd_deg(hier, r))
    assert not np.array_equal(sampled_inputs(base, r)["gamma0"], sampled_inputs(hier, r)["gamma0"])


@pytest.mark.parametrize("extra", [{}, {"sd_dof": 37.0}])
def test_a_tiny_log_sd_gives_the_fixed_length_fields(tmp_path, extra):
    """s = 1e-12: each realisation's field, rebuilt for its own L_r, is the fixed-length
    (and, with sd_dof, the same drawn-sd) run's to round-off."""
    r = np.arange(24)
    base = sampled_inputs(_study(tmp_path, name="f", realizations=24, **extra), r)["gamma0"]
    tiny = sampled_inputs(_study(tmp_path, realizations=24, length_log_sd=1e-12, **extra), r)["gamma0"]
    np.testing.assert_allclose(tiny, base, rtol=0, atol=1e-9)
    assert np.max(np.abs(base + 2.3)) > 5.0  # the fields are not flat


def test_a_drawn_length_changes_the_field_s_correlation(tmp_path):
    """Neighbour correlation of γ0 along fibre 1 follows each realisation's own L_r: over
    realisations whose L_r is short it is lower than over those whose L_r is long."""
    study = _study(tmp_path, realizations=400, length_log_sd=0.8)
    r = np.arange(400)
    g = sampled_inputs(study, r)["gamma0"] + 2.3
    lengths = realization_length_mm(study, r)[:, 0]
    rho = np.mean(g[:, 1:, :] * g[:, :-1, :], axis=(1, 2)) / np.mean(g ** 2, axis=(1, 2))
    short, long = lengths < np.quantile(lengths, 0.25), lengths > np.quantile(lengths, 0.75)
    assert rho[short].mean() < rho[long].mean() - 0.1


def test_bad_length_log_sd_is_one_line(tmp_path, capsys):
    key = "uncertainty.zero_angle.length_log_sd"
    correlated = {"sd_deg": 2.0, "correlation": "exponential", "length_mm": LENGTH}
    drawn = {**correlated, "length_log_sd": 0.3}
    rare = {"rare": {"qoi": "mean_shear_positive", "threshold": 10.9}}
    for field, sections, valid in (({**correlated, "length_log_sd": 0}, {}, ("> 0",)),
                                   ({**correlated, "length_log_sd": -0.1}, {}, ("> 0",)),
                                   ({**correlated, "length_log_sd": 1.5}, {}, ("(0, 1]",)),
                                   ({**correlated, "length_log_sd": "wide"}, {}, ("a number",)),
                                   ({"sd_deg": 2.0, "length_log_sd": 0.3}, {}, ('"exponential"',)),
                                   (drawn, {"sampling": {"plan": "rqmc", "randomizations": 4}}, ('"rqmc"',)),
                                   (drawn, {"sensitivity": {"method": "sobol", "base_samples": 8}}, ('"sobol"',)),
                                   (drawn, {"study": {"realizations": 64, **rare}}, ("a [study] rare",))):
        sections = {"study": {"realizations": 64}, **sections}
        path = write_study(tmp_path, "bad", uncertainty={"zero_angle": field}, **sections)
        assert main(["validate", str(path)]) == 2, (field, sections)
        assert_one_line_error(capsys.readouterr().err, file=path.name, key=key, valid=valid)


# -- written by `uqdrape calibrate` --------------------------------------------------------


def test_calibrate_writes_the_lengths_log_sd_of_an_identified_field(tmp_path, capsys):
    """An exponential 8 x 8 grid: both profile intervals finite, so the block carries
    length_log_sd = the wider ln(upper / lower) / (2 x 1.645), and a study reads it back."""
    from test_calibration import _grid_csv

    out = tmp_path / "z.toml"
    points = _grid_csv(tmp_path, "exponential")
    assert main(["calibrate", str(points), "--family", "exponential", "--out", str(out), "-q"]) == 0
    from uqdrape.calibration import calibrate_points, read_points

    est = calibrate_points(read_points(points), family="exponential").fit.estimates
    widest = max(np.log(est[k].upper / est[k].lower) for k in ("length_1_mm", "length_2_mm"))
    expected = float(f"{widest / (2 * scipy.stats.norm.ppf(0.95)):.4g}")
    text = out.read_text(encoding="utf-8")
    assert f"length_log_sd = {expected}\n" in text and "# length_log_sd = " in text
    study = tmp_path / "s.toml"
    study.write_text(write_study(tmp_path, "s").read_text(encoding="utf-8") + "\n" + text, encoding="utf-8")
    assert load_study(study).uncertainty.fields["zero_angle"].length_log_sd == expected


def test_calibrate_leaves_the_shipped_points_lengths_fixed(tmp_path, capsys):
    """The shipped 38 points: the posterior piles both lengths against the prior's bound,
    so no length_log_sd, and a comment says why."""
    pytest.importorskip("emcee")
    shipped = Path(__file__).resolve().parents[1] / "studies" / "measurements" / "fibre-angles.csv"
    out = tmp_path / "z.toml"
    assert main(["calibrate", str(shipped), "--out", str(out), "--posterior", "-q"]) == 0
    text = out.read_text(encoding="utf-8")
    assert "length_log_sd =" not in text and "length_mm = [" in text
    assert "# no length_log_sd: a correlation length is not identified by the data" in text


def test_the_report_states_the_drawn_lengths_spread(tmp_path):
    """The hierarchical statement gives this run's quantiles of L_r / L (one factor for
    both lengths) and of sd_r, computed here from the drawn values themselves; with sd_dof
    too, the sd's lines are those of the sd-only run. No twin here: not measured."""
    import xarray as xr

    from uqdrape.workflow.twin import DRAWN_LENGTHS, DRAWN_SD, MEASURED, hierarchical_summary

    study = _study(tmp_path, realizations=200, length_log_sd=0.4, sd_dof=37.0)
    r = np.arange(200)
    ds, out = xr.Dataset(coords={"realization": r}), tmp_path / "no-run"
    said = hierarchical_summary(study, ds, out)
    low, mid, high = np.quantile(realization_length_mm(study, r)[:, 1] / LENGTH[1], [0.05, 0.5, 0.95])
    assert said[DRAWN_LENGTHS] == (f"x {mid:.3g}", f"median (5-95 %: x {low:.3g} to x {high:.3g}) of exp(s z), "
                                   "s = length_log_sd = 0.4, both lengths")
    assert 0.45 < low < 0.6 and 1.7 < high < 2.1  # exp(-+1.645 x 0.4) = 0.52, 1.93, to 200 draws' error
    low, mid, high = np.quantile(realization_sd_deg(study, r), [0.05, 0.5, 0.95])
    assert said[DRAWN_SD] == (f"{mid:.3g}", f"median (5-95 %: {low:.3g} to {high:.3g}) of sd_deg 5.6 x "
                              "sqrt(m / chi2_m), m = sd_dof = 37")
    assert said[MEASURED][0] == "not measured" and said[MEASURED][1].startswith("fixed/ holds no run; ")
    sd_only = hierarchical_summary(_study(tmp_path, name="s", realizations=200, sd_dof=37.0), ds, out)
    assert {k: v for k, v in said.items() if k != DRAWN_LENGTHS} == sd_only
