"""Tests of uqdrape.stats against numpy/scipy references, chunked vs in memory, and coverage."""

from __future__ import annotations

import warnings

import dask
import numpy as np
import pytest
import xarray as xr
from dask.callbacks import Callback
from scipy import stats

from uqdrape.stats import (
    clopper_pearson_interval,
    convergence,
    exceedance_probability,
    line_scalars,
    line_statistics,
    mean_statistics,
    node_histogram,
    node_statistics,
    quantile_statistics,
    samples_needed,
    wilson_interval,
)

SHEAR_ATTRS = {"units": "degree", "long_name": "node shear angle"}


def ensemble(n_real=40, ni=5, nj=6, seed=0, nan_frac=0.1, forces=None):
    """Skewed synthetic shear (gamma, deg) on (realization, i, j) with random invalid nodes."""
    rng = np.random.default_rng(seed)
    lead = () if forces is None else (len(forces),)
    a = rng.gamma(2.0, 3.0, size=(*lead, n_real, ni, nj)) - 4.0
    a[rng.random(a.shape) < nan_frac] = np.nan
    dims = ("realization", "i", "j") if forces is None else ("blankholder_force", "realization", "i", "j")
    coords = {"realization": np.arange(n_real), "i": np.arange(ni) - ni // 2, "j": np.arange(nj) - nj // 2}
    if forces is not None:
        coords["blankholder_force"] = ("blankholder_force", np.asarray(forces, float), {"units": "N"})
    return xr.Dataset({"shear": (dims, a, SHEAR_ATTRS)}, coords=coords, attrs={"locking_angle_deg": 8.0})


def as_numpy(da):
    return da.transpose("realization", ...).values


@pytest.mark.parametrize("chunked", [False, True])
def test_node_statistics_matches_numpy_scipy(chunked):
    ds = ensemble()
    a = as_numpy(ds.shear)
    st = node_statistics(ds.chunk({"realization": 7}) if chunked else ds, quantiles=(0.1, 0.5, 0.9))
    n = np.sum(~np.isnan(a), axis=0)
    np.testing.assert_array_equal(st["count"].values, n)
    np.testing.assert_allclose(st["mean"].values, np.nanmean(a, axis=0), rtol=1e-12)
    np.testing.assert_allclose(st["sd"].values, np.nanstd(a, axis=0, ddof=1), rtol=1e-11)
    skew = stats.skew(a, axis=0, bias=False, nan_policy="omit")
    np.testing.assert_allclose(st["skewness"].values, np.asarray(skew), rtol=1e-10)
    q = np.moveaxis(np.nanquantile(a, [0.1, 0.5, 0.9], axis=0), 0, -1)
    np.testing.assert_allclose(st["quantile_value"].transpose("i", "j", "quantile").values, q, rtol=1e-12)
    for ii in range(a.shape[1]):
        for jj in range(a.shape[2]):
            v = a[:, ii, jj][~np.isnan(a[:, ii, jj])]
            lo, hi = stats.t.interval(0.95, v.size - 1, loc=v.mean(), scale=stats.sem(v))
            assert st["mean_lower"].values[ii, jj] == pytest.approx(lo, rel=1e-10)
            assert st["mean_upper"].values[ii, jj] == pytest.approx(hi, rel=1e-10)
    assert st["mean"].attrs["units"] == "degree" and "long_name" in st["quantile_lower"].attrs
    assert st["skewness"].attrs["units"] == "1"
    assert st.attrs["locking_angle_deg"] == 8.0


def sorted_reference(x, probs, confidence):
    """(np.nanquantile, lower, upper limits) of ``x`` along its last axis, the limits as
    the l-th and u-th of the sorted valid values (QUANTILE_INTERVAL), NaN where absent."""
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows
        q = np.moveaxis(np.nanquantile(x, probs, axis=-1), 0, -1)
    xs = np.sort(x, axis=-1)
    n = np.count_nonzero(~np.isnan(x), axis=-1)[..., None]
    alpha = 1 - confidence
    with np.errstate(invalid="ignore"):
        ranks = stats.binom.ppf(alpha / 2, n, probs), stats.binom.ppf(1 - alpha / 2, n, probs) + 1
    limits = [np.where(ok, np.take_along_axis(xs, np.where(ok, r - 1, 0).astype(int), axis=-1), np.nan)
              for r, ok in ((ranks[0], (ranks[0] >= 1) & (n > 0)), (ranks[1], (ranks[1] <= n) & (n > 0)))]
    return q, *limits


@pytest.mark.parametrize("chunk_size", ["128MiB", "8KiB"])  # gathered at once, or narrowed in passes first
def test_quantiles_and_limits_are_numpys_bit_for_bit(chunk_size):
    """Quantiles equal np.nanquantile exactly and their limits the sorted values' l-th
    and u-th, over magnitudes 1e-3..1e3, nodes with no, one or some valid values, ties,
    a constant node, signed zeros, infinities and subnormals, in any chunking."""
    rng = np.random.default_rng(3)
    probs = np.array([0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99, 1 / 3])
    for trial in range(24):
        x = rng.normal(size=(5, 7, rng.integers(1, 300))) * 10 ** rng.uniform(-3, 3)
        if trial % 4 == 0:
            x = np.round(x, 1)  # ties, and 0.0 with -0.0
        x[rng.random(x.shape) < rng.uniform(0, 0.9)] = np.nan
        x[0, 0] = np.nan
        x[0, 1, 1:] = np.nan
        x[1, 1] = 2.5
        x[2, 2, ::3] = (np.inf, -np.inf, 5e-324)[trial % 3]
        expected = sorted_reference(x, probs, 0.9)
        da = xr.DataArray(x, dims=("i", "j", "realization"))
        for data in (da, da.chunk({"realization": int(rng.integers(1, 40)), "i": 2})):
            with dask.config.set({"array.chunk-size": chunk_size}):
                got = quantile_statistics(data, probs, 0.9)
            for name, want in zip(("quantile_value", "quantile_lower", "quantile_upper"), expected):
                assert got[name].dims == ("i", "j", "quantile")
                np.testing.assert_array_equal(got[name].values, want, err_msg=f"{name}, trial {trial}")


def test_quantiles_take_a_few_passes():
    """A dask ensemble is read in a few passes (dask graph runs): its moments and
    range, histogram passes narrowing the ranks' regions while the values left in them
    exceed a quarter of dask's array.chunk-size, then one gathering them: 2 passes
    when everything fits at once; with a 64 KiB chunk-size (histograms of 16 bins,
    4 bits a pass) an ensemble 8 times larger (3 bits) needs at most one more pass."""
    class Count(Callback):
        runs = 0

        def _start(self, dsk):
            Count.runs += 1

    def passes(n, chunk_size):
        ds = ensemble(n_real=n, ni=6, nj=6, seed=n, nan_frac=0.05).chunk({"realization": 250})
        Count.runs = 0
        with Count(), dask.config.set({"array.chunk-size": chunk_size}):
            st = node_statistics(ds)
        q, lower, upper = sorted_reference(np.moveaxis(ds.shear.values, 0, -1), st["quantile"].values, 0.95)
        np.testing.assert_array_equal(st["quantile_value"].values, q)
        np.testing.assert_array_equal(st["quantile_upper"].values, upper)
        return Count.runs

    assert passes(1000, "128MiB") == 2
    few = passes(1000, "64KiB")
    assert 2 < few <= passes(8000, "64KiB") <= few + 1


def test_chunked_equals_in_memory_with_force_sweep():
    ds = ensemble(n_real=30, forces=[0.0, 126.0, 252.0])
    lazy = ds.chunk({"realization": 7})
    xr.testing.assert_allclose(node_statistics(ds), node_statistics(lazy), rtol=1e-12)
    for method in ("wilson", "clopper-pearson"):
        xr.testing.assert_allclose(
            exceedance_probability(ds, method=method), exceedance_probability(lazy, method=method), rtol=1e-12
        )
    st = node_statistics(lazy)
    assert st["mean"].dims == ("blankholder_force", "i", "j")
    np.testing.assert_allclose(st["mean"].values, np.nanmean(ds.shear.values, axis=1), rtol=1e-12)


def test_out_of_core_from_netcdf_chunk_files_in_two_passes(tmp_path):
    ds = ensemble(n_real=28)
    for k in range(4):
        ds.isel(realization=slice(7 * k, 7 * k + 7)).to_netcdf(tmp_path / f"chunk{k}.nc")
    with xr.open_mfdataset(sorted(tmp_path.glob("chunk*.nc")), combine="nested", concat_dim="realization") as lazy:
        assert lazy.shear.chunks is not None

        class Count(Callback):
            runs = 0

            def _start(self, dsk):
                Count.runs += 1

        with Count():
            st = node_statistics(lazy)
        assert Count.runs == 2  # the moments and each node's range, then the order statistics gathered
        xr.testing.assert_allclose(st, node_statistics(ds), rtol=1e-12)


def test_cell_variable_statistics_and_histogram():
    rng = np.random.default_rng(9)
    a = rng.normal(2.0, 1.0, size=(30, 4, 4))
    centres = np.arange(-2, 2) + 0.5
    ds = xr.Dataset(
        {"cell_shear": (("realization", "cell_i", "cell_j"), a, SHEAR_ATTRS)},
        coords={"cell_i": centres, "cell_j": centres},
    )
    st = node_statistics(ds.chunk({"realization": 7}), var="cell_shear")
    assert st["mean"].dims == ("cell_i", "cell_j")
    np.testing.assert_allclose(st["mean"].values, a.mean(axis=0), rtol=1e-12)
    h = node_histogram(ds, (0.5, -1.5), var="cell_shear", bins=5)
    assert h["count"].sum().item() == 30 and h["normal_mean"].item() == pytest.approx(a[:, 2, 0].mean())


def test_order_statistic_interval_of_the_median_known_ranks():
    # n = 20: the distribution-free 95 % interval of the median is [X_(6), X_(15)] (coverage 95.86 %).
    rng = np.random.default_rng(3)
    v = rng.permutation(np.arange(1.0, 21.0))
    ds = xr.Dataset({"shear": (("realization", "i", "j"), v[:, None, None], SHEAR_ATTRS)})
    st = node_statistics(ds, quantiles=(0.05, 0.5))
    assert st["quantile_lower"].sel(quantile=0.5).item() == 6.0
    assert st["quantile_upper"].sel(quantile=0.5).item() == 15.0
    assert st["quantile_value"].sel(quantile=0.5).item() == 10.5
    # 20 samples cannot bound the 5 % quantile from below at 95 %: (0.95)^20 > 0.025.
    assert np.isnan(st["quantile_lower"].sel(quantile=0.05).item())


def test_t_interval_and_quantile_interval_coverage():
    # 1000 repeats laid out as nodes, 20 realisations each, N(3, 2^2).
    rng = np.random.default_rng(11)
    a = rng.normal(3.0, 2.0, size=(20, 25, 40))
    ds = xr.Dataset({"shear": (("realization", "i", "j"), a, SHEAR_ATTRS)})
    st = node_statistics(ds.chunk({"realization": 7}), quantiles=(0.5,))
    cover = ((st.mean_lower <= 3.0) & (st.mean_upper >= 3.0)).mean().item()
    assert abs(cover - 0.95) < 0.025
    med = st.sel(quantile=0.5)
    cover_q = ((med.quantile_lower <= 3.0) & (med.quantile_upper >= 3.0)).mean().item()
    exact = stats.binom.cdf(14, 20, 0.5) - stats.binom.cdf(5, 20, 0.5)  # ranks 6 and 15
    assert exact >= 0.95 and abs(cover_q - exact) < 0.025


def test_wilson_and_clopper_pearson_coverage():
    # P(|X| > 1) for X ~ N(0, 1) = 0.3173; 1000 repeats of 50 realisations.
    rng = np.random.default_rng(5)
    ds = xr.Dataset({"shear": (("realization", "i", "j"), rng.normal(size=(50, 25, 40)), SHEAR_ATTRS)})
    p_true = 2.0 * stats.norm.sf(1.0)
    lazy = ds.chunk({"realization": 7})
    wilson = exceedance_probability(lazy, 1.0, method="wilson")
    exact = exceedance_probability(lazy, 1.0, method="clopper-pearson")
    cover = {}
    for name, ex in (("wilson", wilson), ("cp", exact)):
        cover[name] = ((ex.probability_lower <= p_true) & (ex.probability_upper >= p_true)).mean().item()
    assert abs(cover["wilson"] - 0.95) < 0.025
    assert cover["cp"] >= 0.95 - 0.015  # exact method: coverage >= nominal up to sampling error
    # Clopper-Pearson is the more conservative: wider on average
    cp_width = (exact.probability_upper - exact.probability_lower).mean().item()
    assert cp_width > (wilson.probability_upper - wilson.probability_lower).mean().item()
    assert abs(wilson.probability.mean().item() - p_true) < 0.01


def test_binomial_intervals_known_values():
    # 0 of 10: Wilson upper z^2 / (n + z^2); Clopper-Pearson upper 1 - (alpha/2)^(1/n).
    z = stats.norm.ppf(0.975)
    lo, hi = wilson_interval(np.array(0.0), np.array(10.0), 0.95)
    assert lo == 0.0 and hi == pytest.approx(z**2 / (10 + z**2), rel=1e-12)
    for n in (10, 48, 127):  # all of n: the upper limit is 1 itself, the lower 1 - (0 of n's upper)
        lo, hi = wilson_interval(n, n, 0.95)
        assert hi == 1.0 and lo == pytest.approx(1 - z**2 / (n + z**2), rel=1e-12)
    lo, hi = clopper_pearson_interval(0, 10, 0.95)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / 10), rel=1e-10)
    lo, hi = clopper_pearson_interval(10, 10, 0.95)
    assert hi == 1.0 and lo == pytest.approx(0.025 ** (1 / 10), rel=1e-10)


def test_exceedance_counts_only_valid_and_uses_locking_angle():
    ds = ensemble()
    a = as_numpy(ds.shear)
    ex = exceedance_probability(ds)  # threshold from attrs: 8 degree
    assert ex["threshold"].item() == 8.0
    n = np.sum(~np.isnan(a), axis=0)
    k = np.sum(np.abs(np.nan_to_num(a)) > 8.0, axis=0)
    np.testing.assert_array_equal(ex["exceed_count"].values, k)
    np.testing.assert_allclose(ex["probability"].values, k / n)
    multi = exceedance_probability(ds, [2.0, 8.0])
    xr.testing.assert_allclose(multi.sel(threshold=8.0).drop_vars("threshold"), ex.drop_vars("threshold"))
    with pytest.raises(ValueError, match="locking_angle_deg"):
        exceedance_probability(ds.drop_attrs())
    with pytest.raises(ValueError, match="method must be one of"):
        exceedance_probability(ds, 5.0, method="agresti")
    with pytest.raises(ValueError, match="threshold_deg"):
        exceedance_probability(ds, -1.0)


def test_bad_input_errors_name_the_argument():
    ds = ensemble()
    with pytest.raises(ValueError, match="var='cell_shear' is not a data variable"):
        node_statistics(ds, var="cell_shear")
    with pytest.raises(ValueError, match="confidence must be in"):
        node_statistics(ds, confidence=95)
    with pytest.raises(ValueError, match="quantiles must be"):
        node_statistics(ds, quantiles=(0.5, 1.0))
    with pytest.raises(ValueError, match="node i=9"):
        node_histogram(ds, (9, 0))
    with pytest.raises(ValueError, match="node=\\(i, j\\) is required"):
        convergence(ds)


def test_node_histogram_recovers_normal():
    rng = np.random.default_rng(2)
    a = rng.normal(10.0, 3.0, size=(2000, 3, 3))
    a[:50, 1, 1] = np.nan
    ds = xr.Dataset({"shear": (("realization", "i", "j"), a, SHEAR_ATTRS)}, coords={"i": [-1, 0, 1], "j": [-1, 0, 1]})
    h = node_histogram(ds.chunk({"realization": 300}), (0, 0), bins=25)
    assert h["n_valid"].item() == 1950 and h["count"].sum().item() == 1950
    assert h["normal_mean"].item() == pytest.approx(10.0, abs=3 * 3.0 / np.sqrt(1950))
    assert h["normal_sd"].item() == pytest.approx(3.0, rel=0.05)
    edges = h["bin_edges"].values
    assert edges.size == 26 and h["density"].values @ np.diff(edges) == pytest.approx(1.0)
    np.testing.assert_array_equal(h["count"].values, np.histogram(a[~np.isnan(a[:, 1, 1]), 1, 1], bins=edges)[0])
    # fitted pdf and histogram density agree to sampling error
    assert np.max(np.abs(h["density"] - h["normal_pdf"])).item() < 0.02


def test_node_histogram_per_force_level_on_common_edges():
    ds = ensemble(n_real=60, forces=[0.0, 378.0])
    h = node_histogram(ds, (0, 1), bins=8)
    assert h["count"].dims == ("blankholder_force", "bin")
    for f in range(2):
        v = ds.shear.isel(blankholder_force=f).sel(i=0, j=1).values
        assert h["n_valid"].values[f] == np.sum(~np.isnan(v))
        mu, sd = stats.norm.fit(v[~np.isnan(v)])
        assert h["normal_mean"].values[f] == pytest.approx(mu) and h["normal_sd"].values[f] == pytest.approx(sd)


def test_convergence_half_width_shrinks_like_one_over_sqrt_n():
    rng = np.random.default_rng(8)
    x = rng.normal(5.0, 2.0, size=4000)
    x[rng.random(4000) < 0.05] = np.nan
    da = xr.DataArray(x, dims="realization", attrs=SHEAR_ATTRS)
    cv = convergence(da)
    assert cv.sizes["n"] == 4000 and cv["n"].values[0] == 1
    n = np.array([100, 200, 400, 800, 1600, 3200])
    slope = np.polyfit(np.log(n), np.log(cv.half_width.sel(n=n).values), 1)[0]
    assert slope == pytest.approx(-0.5, abs=0.05)
    m = 250
    v = x[:m][~np.isnan(x[:m])]
    lo, hi = stats.t.interval(0.95, v.size - 1, loc=v.mean(), scale=stats.sem(v))
    assert cv.running_mean.sel(n=m).item() == pytest.approx(v.mean(), rel=1e-12)
    assert cv.half_width.sel(n=m).item() == pytest.approx((hi - lo) / 2, rel=1e-10)
    assert cv["count"].sel(n=m).item() == v.size
    # the same through a Dataset and a node
    ds = ensemble(n_real=30)
    cn = convergence(ds, node=(0, 0))
    ref = ds.shear.sel(i=0, j=0).values
    assert cn.running_mean.isel(n=-1).item() == pytest.approx(np.nanmean(ref))


def test_samples_needed():
    # sd 5, half-width 1, 95 %: Normal (1.96 * 5)^2 = 96.04 -> 97; Student t -> 99.
    assert samples_needed(5.0, 1.0, method="normal") == 97
    n = samples_needed(5.0, 1.0)
    assert n == 99
    assert stats.t.ppf(0.975, n - 1) * 5 / np.sqrt(n) <= 1.0 < stats.t.ppf(0.975, n - 2) * 5 / np.sqrt(n - 1)
    np.testing.assert_array_equal(samples_needed([5.0, 5.0], [1.0, 0.5], method="normal"), [97, 385])
    with pytest.raises(ValueError, match="half_width"):
        samples_needed(5.0, 0.0)


def flat_net(n_real=12, rings=4, s=5.0, seed=4):
    """Flat plate net: x = i s, y = j s; shear = c_r * k along + diagonals, -1.5 c_r * k along -."""
    rng = np.random.default_rng(seed)
    idx = np.arange(-rings, rings + 1)
    ii, jj = np.meshgrid(idx, idx, indexing="ij")
    c = 1.0 + 0.2 * rng.standard_normal(n_real)
    k = np.maximum(np.abs(ii), np.abs(jj))
    sign = np.where(ii * jj > 0, 1.0, np.where(ii * jj < 0, -1.5, 0.0))
    shear = c[:, None, None] * (k * sign)[None]
    x = np.broadcast_to(ii * s, shear.shape).copy()
    y = np.broadcast_to(jj * s, shear.shape).copy()
    z = np.zeros_like(x)
    for arr in (x, y, z, shear):  # realisation 0: the ++ corner beyond ring 2 is invalid
        arr[0, rings + 3:, rings + 3:] = np.nan
    dims = ("realization", "i", "j")
    ds = xr.Dataset(
        {"x": (dims, x, {"units": "mm"}), "y": (dims, y, {"units": "mm"}), "z": (dims, z, {"units": "mm"}),
         "shear": (dims, shear, SHEAR_ATTRS)},
        coords={"realization": np.arange(n_real), "i": idx, "j": idx},
        attrs={"spacing_mm": s, "rings": rings},
    )
    return ds, c


@pytest.mark.parametrize("chunked", [False, True])
def test_line_statistics_on_flat_net(chunked):
    ds, c = flat_net()
    st = line_statistics(ds.chunk({"realization": 5}) if chunked else ds)
    k = st["k"].values
    for q, factor in (("++", 1.0), ("--", 1.0), ("-+", -1.5), ("+-", -1.5)):
        line = st.sel(quadrant=q)
        # distances along a flat diagonal are k s sqrt(2) in every valid realisation
        np.testing.assert_allclose(line.distance_mean.values, k * 5.0 * np.sqrt(2.0), rtol=1e-12)
        np.testing.assert_allclose(line.distance_sd.values, 0.0, atol=1e-9)
        for kk in range(1, 5):
            cc = c[1:] if (q == "++" and kk >= 3) else c  # realisation 0 is invalid there
            assert line.shear_mean.values[kk] == pytest.approx(factor * kk * cc.mean(), rel=1e-12)
            assert line.shear_sd.values[kk] == pytest.approx(abs(factor) * kk * cc.std(ddof=1), rel=1e-9)
            half = stats.t.ppf(0.975, cc.size - 1) * abs(factor) * kk * cc.std(ddof=1) / np.sqrt(cc.size)
            assert line.shear_mean_upper.values[kk] - line.shear_mean.values[kk] == pytest.approx(half, rel=1e-9)
    assert st["count"].sel(quadrant="++").values.tolist() == [12, 12, 12, 11, 11]
    assert st["distance_mean"].attrs["units"] == "mm" and st["shear_mean_upper"].attrs["units"] == "degree"
    arms = line_statistics(ds, kind="min")
    np.testing.assert_allclose(arms.distance_mean.sel(arm="+i").values, k * 5.0, rtol=1e-12)
    np.testing.assert_allclose(arms.shear_mean.values, 0.0, atol=1e-12)


def test_line_scalars_and_asymmetry():
    ds, c = flat_net()
    sc = line_scalars(ds.chunk({"realization": 5}))
    assert sc.attrs["k_max"] == 2  # ++ of realisation 0 is invalid from k = 3
    mean_k = (1 + 2) / 2
    np.testing.assert_allclose(sc.line_mean_shear.sel(quadrant="--").values, c * mean_k, rtol=1e-12)
    np.testing.assert_allclose(sc.minus_mean_shear.values, -1.5 * c * mean_k, rtol=1e-12)
    np.testing.assert_allclose(sc.asymmetry.values, -0.5 * c * mean_k, rtol=1e-12)
    full = line_scalars(ds, k_max=4)
    assert np.isnan(full.asymmetry.values[0]) and np.all(np.isfinite(full.asymmetry.values[1:]))
    ms = mean_statistics(sc.asymmetry)
    assert ms["mean"].item() == pytest.approx(-0.75 * c.mean(), rel=1e-12)
    with pytest.raises(ValueError, match="k_max must be an integer in 1..4"):
        line_scalars(ds, k_max=7)


def test_an_rqmc_sample_takes_the_interval_of_its_mean_from_its_randomisations():
    """K randomisations of one point set: Student t over the K group means (K - 1 dof),
    not over the K M points, which are not independent."""
    rng = np.random.default_rng(1)
    R, K = 64, 8
    x = rng.normal(size=(1, R, 2, 2))
    x[0, 3, 1, 1] = np.nan  # an invalid node in one realisation: its group's mean skips it
    ds = xr.Dataset({"shear": (("blankholder_force", "realization", "i", "j"), x, {"units": "degree"})},
                    coords={"blankholder_force": [0.0], "realization": np.arange(R), "i": [0, 1], "j": [0, 1]})
    st = node_statistics(ds, replicates=K)
    for i, j in ((0, 0), (1, 1)):
        means = np.nanmean(x[0, :, i, j].reshape(K, R // K), axis=1)
        half = stats.t.ppf(0.975, K - 1) * means.std(ddof=1) / np.sqrt(K)
        np.testing.assert_allclose([float(st.mean_lower[0, i, j]), float(st.mean_upper[0, i, j])],
                                   [means.mean() - half, means.mean() + half], rtol=1e-12)
    assert st.mean_lower.attrs["method"].startswith("Student t over randomisations")
    assert float(st["sd"][0, 0, 0]) == pytest.approx(np.std(x[0, :, 0, 0], ddof=1), rel=1e-12)  # sd of all points
    with pytest.raises(ValueError, match="replicates=5 must be >= 2 and divide the 64 realisations"):
        node_statistics(ds, replicates=5)
