"""uqdrape.sensitivity: SALib problem, sample matrices, indices, pipeline (Ishigami and toys)."""

import warnings

import numpy as np
import pytest
import xarray as xr
from SALib.analyze import morris as salib_morris_analyze
from SALib.analyze import sobol as salib_sobol_analyze
from SALib.sample import morris as salib_morris_sample
from SALib.sample import sobol as salib_sobol_sample
from SALib.test_functions import Ishigami
from scipy import stats

from uqdrape.sensitivity import (
    MORRIS_TAIL_QUANTILE,
    analyze,
    analyze_map,
    check_problem,
    field_group,
    indices_vs_levels,
    make_problem,
    sample,
)
from uqdrape.stochastic import constant, lognormal, normal, truncnormal, uniform

from golden import ISHIGAMI_S1, ISHIGAMI_ST


def run_sensitivity(problem, evaluate, *, base_samples, method="sobol", seed, qoi_names=None):
    """Sample the matrix, evaluate ``evaluate(X) -> Y`` once, analyse every QoI (SALib's own
    flow for a callable toy model); the sample metadata in the attributes."""
    X, meta = sample(problem, method, base_samples=base_samples, seed=seed)
    ds = analyze(problem, X, np.asarray(evaluate(X), dtype=float), method=method, qoi_names=qoi_names, seed=seed)
    ds.attrs.update(meta)
    return ds

PI = np.pi


def ishigami_problem(dummy=False):
    names = ["x1", "x2", "x3"] + (["x4"] if dummy else [])
    return make_problem({name: uniform(-PI, PI) for name in names})


def ishigami_with_dummy(X):
    """Ishigami of the first three columns; column 4 has no effect."""
    return Ishigami.evaluate(X[:, :3])


# --- problem ---------------------------------------------------------------------------


def test_problem_dists_follow_salib_conventions():
    factors = {
        "force": truncnormal(200.0, 50.0, 0.0, 400.0),
        "friction": uniform(0.15, 0.3),
        "pre_shear": constant(0.0),
        "orientation": normal(-45.0, 2.0),
        "spacing_cv": lognormal(0.01, 0.002),
    }
    p = make_problem(factors)
    assert p["names"] == ["force", "friction", "orientation", "spacing_cv"]  # constant left out
    assert p["dists"] == ["truncnorm", "unif", "norm", "lognorm"]
    assert p["bounds"][0] == [0.0, 400.0, 200.0, 50.0]
    assert "groups" not in p
    X, _ = sample(p, base_samples=1024, seed=5)
    # Sobol' A rows are a (scrambled) QMC sample of the joint distribution.
    A = X[:: 4 + 2]
    assert A[:, 1].min() >= 0.15 and A[:, 1].max() <= 0.3
    assert np.mean(A[:, 2]) == pytest.approx(-45.0, abs=0.05)
    assert np.std(A[:, 2]) == pytest.approx(2.0, rel=0.02)
    # SALib's lognorm bounds are ln-space; the stochastic factor is given by mean and sd
    assert np.mean(A[:, 3]) == pytest.approx(0.01, rel=0.01)
    assert np.std(A[:, 3]) == pytest.approx(0.002, rel=0.03)
    truncated = stats.truncnorm(-4.0, 4.0, loc=200.0, scale=50.0)
    assert np.std(A[:, 0]) == pytest.approx(truncated.std(), rel=0.02)


def test_fields_are_groups_of_standard_normals():
    assert field_group("zero_angle", 3) == ["zero_angle[0]", "zero_angle[1]", "zero_angle[2]"]
    p = make_problem({"friction": uniform(0.1, 0.3)}, fields={"zero_angle": 3, "spacing": 2})
    assert p["names"][:2] == ["friction", "zero_angle[0]"]
    assert p["groups"] == ["friction"] + ["zero_angle"] * 3 + ["spacing"] * 2
    assert p["dists"][1:] == ["norm"] * 5
    assert p["bounds"][1:] == [[0.0, 1.0]] * 5  # SALib norm: [mean, sd]


@pytest.mark.parametrize("build, message", [
    (lambda: field_group("g", 0), "n_modes=0"),
    (lambda: make_problem({"a": uniform(0, 1), "b": (0, 1)}), "'b' must be a uqdrape.stochastic Factor"),
    (lambda: make_problem({"spacing": uniform(0, 1)}, fields={"spacing": 2}),
     "'spacing' is both a scalar factor and a field name"),
    (lambda: make_problem({"f[0]": uniform(0, 1)}, fields={"f": 2}), "clash with field 'f'"),
    (lambda: make_problem({}, fields={"g": 4}), "at least 2 random factors or groups"),
    (lambda: make_problem({"a": uniform(0, 1), "b": constant(2.0)}), "at least 2 random factors"),
    (lambda: check_problem({"num_vars": 2, "names": ["a", "a"], "bounds": [[0, 1]] * 2}),
     "repeated: \\['a'\\]"),
    (lambda: check_problem({"num_vars": 2, "names": ["a", "b"]}), "missing key 'bounds'"),
    (lambda: check_problem({"num_vars": 2, "names": ["a", "b"], "bounds": [[0, 1]] * 2,
                            "dists": ["unif", "weibull"]}), "dist 'weibull' is not supported"),
])
def test_problem_rejects_bad_input(build, message):
    with pytest.raises(ValueError, match=message):
        build()


# --- sample ----------------------------------------------------------------------------


@pytest.mark.parametrize("method, n, message", [
    ("sobol", 32, "minimum is 64"),
    ("sobol", 100, "must be a power of 2 for Sobol' \\(e.g. 64 or 128\\)"),
    ("morris", 5, "minimum is 10 trajectories"),
    ("fast", 64, "method='fast' is not supported"),
])
def test_too_small_or_bad_sample_refused(method, n, message):
    with pytest.raises(ValueError, match=message):
        sample(ishigami_problem(), method, base_samples=n, seed=1)


def test_seed_must_be_non_negative_int():
    with pytest.raises(ValueError, match="seed=-1"):
        sample(ishigami_problem(), base_samples=64, seed=-1)


def test_morris_moves_unbounded_levels_to_tail_quantiles():
    p = make_problem({"friction": uniform(0.1, 0.3)}, fields={"f": 2})
    X, meta = sample(p, "morris", base_samples=10, seed=3)
    assert meta["n_evaluations"] == 10 * 3 == X.shape[0]
    assert np.isfinite(X).all()
    q = MORRIS_TAIL_QUANTILE
    levels = q + (1 - 2 * q) * np.array([0, 1 / 3, 2 / 3, 1])
    assert np.isin(np.round(X[:, 1:], 12), np.round(stats.norm.ppf(levels), 12)).all()
    # uniform factors keep SALib's own levels, including the bounds
    assert np.isin(np.round(X[:, 0], 12), np.round(np.linspace(0.1, 0.3, 4), 12)).all()
    ds = analyze(p, X, 3.0 * X[:, 1] - X[:, 2], method="morris", seed=3).sel(qoi="y0")
    assert list(ds.factor.values) == ["friction", "f"]
    assert ds.mu_star.sel(factor="friction") == 0.0 and ds.mu_star.sel(factor="f") > 1.0
    assert np.isnan(ds.sigma.sel(factor="f")) and ds.sigma.sel(factor="friction") == 0.0


# --- Sobol' ----------------------------------------------------------------------------


def test_pipeline_reproduces_salib_bitwise():
    p = ishigami_problem()
    ds = run_sensitivity(p, Ishigami.evaluate, base_samples=1024, seed=11, qoi_names=["f"])
    X = salib_sobol_sample.sample(dict(p), 1024, calc_second_order=False, seed=11)
    np.testing.assert_array_equal(sample(p, base_samples=1024, seed=11)[0], X)
    S = salib_sobol_analyze.analyze(p, Ishigami.evaluate(X), calc_second_order=False, seed=11)
    for name in ("S1", "S1_conf", "ST", "ST_conf"):
        np.testing.assert_array_equal(ds[name].sel(qoi="f").values, S[name])
    assert ds.attrs["base_samples"] == 1024 and ds.attrs["n_evaluations"] == 1024 * 5
    assert ds.attrs["method"] == "sobol" and ds.attrs["conf_level"] == 0.95


def test_many_columns_at_once_give_salib_per_column():
    """The Sobol' indices of 40 outputs at once (a node map) equal SALib's analyze on each
    column with the same seed, to round-off (measured 2e-12 relative)."""
    p = make_problem({"a": uniform(0.0, 1.0), "b": normal(0.0, 1.0)}, fields={"f": 3})
    X, _ = sample(p, base_samples=128, seed=3)
    Y = np.sin(X @ np.random.default_rng(0).normal(size=(X.shape[1], 40))) + X[:, :1] ** 2
    ds = analyze(p, X, Y, seed=7)
    for c in range(Y.shape[1]):
        S = salib_sobol_analyze.analyze(p, Y[:, c].copy(), calc_second_order=False, seed=7)
        for name in ("S1", "S1_conf", "ST", "ST_conf"):
            np.testing.assert_allclose(ds[name].values[:, c], S[name], rtol=1e-11, atol=1e-14)


def test_ishigami_indices_within_ci_and_dummy_is_zero():
    ds = run_sensitivity(ishigami_problem(dummy=True), ishigami_with_dummy,
                         base_samples=1024, seed=2, qoi_names=["f"]).sel(qoi="f")
    assert list(ds.factor.values) == ["x1", "x2", "x3", "x4"]
    S1, ST = ds.S1.values, ds.ST.values
    assert (np.abs(S1[:3] - ISHIGAMI_S1) <= ds.S1_conf.values[:3]).all()
    assert (np.abs(ST[:3] - ISHIGAMI_ST) <= ds.ST_conf.values[:3]).all()
    assert ds.S1_conf.values[:3].max() < 0.08  # the interval is informative
    # the no-effect factor: A and AB_x4 rows give identical outputs, so ST is exactly 0
    assert ST[3] == 0.0 and abs(S1[3]) <= ds.S1_conf.values[3]


def test_groups_only_the_active_group_matters():
    p = make_problem({"a": uniform(0.0, 1.0)}, fields={"f": 4, "g": 3})
    cols_f = [p["names"].index(f"f[{k}]") for k in range(4)]
    X, meta = sample(p, base_samples=256, seed=4)
    assert meta["n_evaluations"] == 256 * (3 + 2)
    # rows A and AB_f (second cross-sample: group order a, f, g) differ only in f's columns
    differs = X[0] != X[2]
    assert differs[cols_f].all() and differs.sum() == 4
    ds = run_sensitivity(p, lambda X: (X[:, cols_f] ** 2).sum(axis=1), base_samples=256, seed=4)
    st = ds.ST.sel(qoi="y0")
    assert list(ds.factor.values) == ["a", "f", "g"]
    assert st.sel(factor="f") == pytest.approx(1.0, abs=float(ds.ST_conf.sel(factor="f", qoi="y0")))
    assert st.sel(factor="a") == 0.0 and st.sel(factor="g") == 0.0
    assert ds.S1.sel(factor="f", qoi="y0") == pytest.approx(1.0, abs=0.1)


def test_zero_variance_output_gives_zero_indices_without_warnings():
    def two_outputs(X):
        return np.column_stack([Ishigami.evaluate(X), np.full(len(X), 3.5)])

    for method, n in (("sobol", 64), ("morris", 10)):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            ds = run_sensitivity(ishigami_problem(), two_outputs, base_samples=n, method=method,
                                 seed=1, qoi_names=["ishigami", "blankholder_energy"])
        flat = ds.sel(qoi="blankholder_energy")
        assert bool(flat.output_constant) and not bool(ds.output_constant.sel(qoi="ishigami"))
        for name in ds.data_vars:
            if name != "output_constant":
                assert (flat[name].values == 0.0).all(), name
                assert np.isfinite(ds[name].sel(qoi="ishigami")).all(), name


def test_analyze_rejects_nan_and_wrong_shapes():
    p = ishigami_problem()
    X, _ = sample(p, base_samples=64, seed=1)
    Y = Ishigami.evaluate(X)
    Y[7] = np.nan
    with pytest.raises(ValueError, match="NaN/inf \\(count per QoI: \\{'y0': 1\\}\\)"):
        analyze(p, X, Y, seed=1)
    Y = Ishigami.evaluate(X)
    with pytest.raises(ValueError, match="need a multiple of 5"):
        analyze(p, X[:-1], Y[:-1], seed=1)
    with pytest.raises(ValueError, match="Y has 319 rows but X has 320"):
        analyze(p, X, Y[:-1], seed=1)
    with pytest.raises(ValueError, match="conf_level=1.5"):
        analyze(p, X, Y, conf_level=1.5, seed=1)


# --- Morris ----------------------------------------------------------------------------


def test_morris_matches_salib_and_ranks_ishigami():
    p = ishigami_problem()
    ds = run_sensitivity(p, Ishigami.evaluate, base_samples=50, method="morris", seed=8)
    X = salib_morris_sample.sample(dict(p), 50, num_levels=4, seed=8)
    S = salib_morris_analyze.analyze(dict(p), X, Ishigami.evaluate(X), num_levels=4, seed=8)
    for name in ("mu", "mu_star", "mu_star_conf", "sigma"):
        # one vectorised computation for every column: SALib's values to round-off (a zero
        # bootstrap sd, x2's constant |EE|, is round-off of order 1e-15 either way)
        expected = np.asarray(S[name])
        np.testing.assert_allclose(ds[name].sel(qoi="y0").values, expected, rtol=1e-12,
                                   atol=1e-12 * np.abs(expected).max())
    mu_star = ds.mu_star.sel(qoi="y0")
    assert mu_star.sel(factor="x3") < min(mu_star.sel(factor="x1"), mu_star.sel(factor="x2"))
    assert ds.attrs["n_evaluations"] == 50 * 4 and ds.attrs["num_levels"] == 4


# --- maps, levels, netCDF --------------------------------------------------------------


def test_analyze_map_per_node():
    p = ishigami_problem()
    X, _ = sample(p, base_samples=256, seed=6)
    n = X.shape[0]
    values = np.empty((n, 2, 3))
    values[:, 0, 0] = 0.0                       # node (0, -1): no factor reaches it
    values[:, 0, 1] = 2.0 * X[:, 1]             # node (0, 0): driven by x2 alone
    values[:, 0, 2] = Ishigami.evaluate(X)
    values[:, 1, :] = X[:, [0]]
    values[17, 1, 2] = np.nan                   # node (1, 1): invalid in one realisation
    shear = xr.DataArray(values, dims=("realization", "i", "j"),
                         coords={"i": [0, 1], "j": [-1, 0, 1]}, name="shear",
                         attrs={"units": "degree"})
    ds = analyze_map(p, X, shear, seed=6)
    assert ds.S1.dims == ("factor", "i", "j") and list(ds.j.values) == [-1, 0, 1]
    assert bool(ds.output_constant.sel(i=0, j=-1)) and (ds.ST.sel(i=0, j=-1) == 0).all()
    assert np.isnan(ds.S1.sel(i=1, j=1)).all() and np.isnan(ds.ST_conf.sel(i=1, j=1)).all()
    assert float(ds.ST.sel(factor="x2", i=0, j=0)) == pytest.approx(1.0, abs=0.05)
    assert float(ds.ST.sel(factor="x1", i=0, j=0)) == 0.0
    scalar = analyze(p, X, values[:, 0, 1], seed=6)
    np.testing.assert_array_equal(ds.S1.sel(i=0, j=0).values, scalar.S1.values[:, 0])
    np.testing.assert_allclose(ds.ST.sel(i=1, j=0).values, [1.0, 0.0, 0.0], atol=1e-9)
    assert ds.attrs["output"] == "shear" and ds.attrs["output_units"] == "degree"


def test_indices_vs_levels_and_netcdf_round_trip(tmp_path):
    p = make_problem({"friction": uniform(0.15, 0.3), "orientation": normal(0.0, 2.0)},
                     fields={"zero_angle": 2})
    forces = [0.0, 126.0, 252.0]

    def model(force):
        def evaluate(X):
            energy = force * X[:, 0] * (1 + 0.01 * X[:, 2] ** 2)
            shear = 40 + X[:, 1] + 0.2 * force * X[:, 0] + X[:, 3]
            return np.column_stack([energy, shear])
        return evaluate

    per_level = [run_sensitivity(p, model(f), base_samples=64, seed=3,
                                 qoi_names=["energy_blankholder", "max |shear|"]) for f in forces]
    ds = indices_vs_levels(per_level, forces)
    assert ds.S1.dims == ("factor", "qoi", "blankholder_force")
    assert ds.blankholder_force.attrs["units"] == "N"
    assert bool(ds.output_constant.sel(qoi="energy_blankholder", blankholder_force=0.0))
    assert (ds.ST.sel(qoi="energy_blankholder", blankholder_force=0.0) == 0).all()
    assert float(ds.ST.sel(qoi="max |shear|", factor="friction", blankholder_force=0.0)) == 0.0
    assert float(ds.ST.sel(qoi="max |shear|", factor="friction", blankholder_force=252.0)) > 0.05

    path = tmp_path / "indices.nc"
    ds.to_netcdf(path)
    back = xr.load_dataset(path)
    xr.testing.assert_identical(back, ds)
    assert list(back.factor.values) == ["friction", "orientation", "zero_angle"]
    assert list(back.qoi.values) == ["energy_blankholder", "max |shear|"]

    with pytest.raises(ValueError, match="2 values for 3 datasets"):
        indices_vs_levels(per_level, forces[:2])
    other = per_level[1].copy()
    other.attrs["base_samples"] = 128
    with pytest.raises(ValueError, match="attributes \\['base_samples'\\]"):
        indices_vs_levels([per_level[0], other], forces[:2])
    with pytest.raises(ValueError, match="coordinate 'qoi'"):
        indices_vs_levels([per_level[0], per_level[1].isel(qoi=[0])], forces[:2])
