"""Per-node (or per-cell) ensemble statistics with confidence limits.

Reductions run along ``realization`` only, so a dask-backed ensemble (a run folder's
chunk files or a zarr store, ``uqdrape.ensemble.open_ensemble``) is processed chunk by
chunk: moments in one pass of shifted power sums, quantiles per block of nodes holding
every realisation of that block, one block at a time (:func:`node_statistics`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import dask
import numpy as np
import xarray as xr
from scipy import stats

from ._common import REALIZATION, check_confidence, get_variable, t_quantile

MEAN_INTERVAL = "Student t: mean +- t_{(1+c)/2, n-1} * sd / sqrt(n) over the n valid realisations"
#: The interval of the mean of a randomised QMC sample: its points are not independent,
#: its K randomisations are.
REPLICATE_INTERVAL = ("Student t over randomisations: mean of the K randomisations' means +- "
                      "t_{(1+c)/2, K-1} * sd(means) / sqrt(K)")
QUANTILE_INTERVAL = (
    "distribution-free order statistics: [X_(l), X_(u)] with l = binom.ppf((1-c)/2, n, p), "
    "u = binom.ppf((1+c)/2, n, p) + 1 (1-based ranks, coverage >= c); NaN when n is too small"
)
QUANTILE_METHOD = "numpy 'linear' (Hyndman-Fan type 7) over the valid realisations"


def _attrs(units, long_name: str, **extra) -> dict:
    out = {"long_name": long_name}
    if units is not None:
        out["units"] = units
    out.update(extra)
    return out


def _limits(prefix: str, lower, upper, units, what: str, confidence: float, method: str) -> dict:
    """``<prefix>_lower`` and ``<prefix>_upper``: the confidence limits of ``what`` with their attributes."""
    return {f"{prefix}_{side}": limit.assign_attrs(_attrs(units, f"{side} {confidence:.0%} confidence limit of {what}",
                                                          method=method))
            for side, limit in (("lower", lower), ("upper", upper))}


def moment_statistics(da: xr.DataArray, confidence: float, dim: str = REALIZATION) -> xr.Dataset:
    """Lazy mean, sd, skewness, count and t interval of the mean of ``da`` along ``dim``.

    NaN entries are invalid realisations and are left out. Values are shifted by the
    first realisation (per node) before the power sums, which keeps the one-pass
    variance accurate when the mean is large against the spread (e.g. coordinates in mm).
    sd uses ddof = 1; skewness is the adjusted Fisher-Pearson G1 (scipy ``bias=False``),
    NaN for n < 3 or zero spread.
    """
    units = da.attrs.get("units")
    name = da.attrs.get("long_name", da.name)
    valid = da.notnull()
    shift = da.isel({dim: 0}, drop=True).fillna(0.0)
    d = da - shift
    n = valid.sum(dim)
    nn = n.where(n > 0).astype(float)
    a1 = d.sum(dim) / nn
    a2 = (d**2).sum(dim) / nn
    a3 = (d**3).sum(dim) / nn
    m2 = (a2 - a1**2).clip(min=0.0)
    m3 = a3 - 3.0 * a1 * a2 + 2.0 * a1**3
    mean = shift + a1
    sd = np.sqrt((m2 * nn / (nn - 1.0)).where(n > 1))
    spread = (m2 > (np.finfo(float).resolution * mean) ** 2) & (n > 2)
    m2s = m2.where(spread)
    skew = (m3 / m2s**1.5 * np.sqrt(nn * (nn - 1.0)) / (nn - 2.0)).where(spread)
    half = t_quantile(confidence, n - 1) * sd / np.sqrt(nn)
    return xr.Dataset(
        {
            "mean": mean.assign_attrs(_attrs(units, f"ensemble mean of {name}")),
            "sd": sd.assign_attrs(_attrs(units, f"ensemble standard deviation (ddof=1) of {name}")),
            "skewness": skew.assign_attrs(_attrs("1", f"adjusted sample skewness G1 of {name}")),
            "count": n.assign_attrs(_attrs("1", "number of valid (non-NaN) realisations")),
            **_limits("mean", mean - half, mean + half, units, "the mean", confidence, MEAN_INTERVAL),
        }
    )


def _linear_quantiles(xs: np.ndarray, n: np.ndarray, probs: np.ndarray) -> np.ndarray:
    """numpy's default ("linear") quantiles of rows sorted with NaN last, ``n`` (..., 1)
    valid values each, by the same arithmetic as ``np.nanquantile`` (so the same numbers)
    but in whole arrays: ``np.nanquantile`` along an axis loops over the rows in Python,
    which made it most of a design study's statistics. NaN where a row has no valid value."""
    virtual = (n - 1) * probs
    below = np.floor(virtual)
    top = virtual >= n - 1  # at or past the largest valid value: take it
    lo = np.clip(np.where(top, n - 1, below), 0, None).astype(np.intp)
    hi = np.clip(np.where(top, n - 1, below + 1), 0, None).astype(np.intp)
    a, b = np.take_along_axis(xs, lo, axis=-1), np.take_along_axis(xs, hi, axis=-1)
    t = virtual - below
    diff = b - a
    q = np.where(t >= 0.5, b - diff * (1 - t), a + diff * t)
    return np.where(n > 0, q, np.nan)


def _quantile_block(x: np.ndarray, probs: np.ndarray, confidence: float):
    """Quantiles and their order-statistic limits along the last axis of ``x`` (NaN = invalid)."""
    xs = np.sort(x, axis=-1)  # NaN sorts last, so ranks 1..n are the valid values
    n = np.count_nonzero(~np.isnan(x), axis=-1)[..., None]
    q = _linear_quantiles(xs, n, probs)
    alpha = 1.0 - confidence
    with np.errstate(invalid="ignore"):
        lo = stats.binom.ppf(alpha / 2.0, n, probs)
        hi = stats.binom.ppf(1.0 - alpha / 2.0, n, probs) + 1.0
    limits = []
    for rank, ok in ((lo, (lo >= 1) & (n > 0)), (hi, (hi <= n) & (n > 0))):
        idx = np.where(ok, rank - 1, 0).astype(np.intp)
        limits.append(np.where(ok, np.take_along_axis(xs, idx, axis=-1), np.nan))
    return q, limits[0], limits[1]


def quantile_statistics(
    da: xr.DataArray, quantiles: Sequence[float], confidence: float, dim: str = REALIZATION
) -> xr.Dataset:
    """Lazy quantiles of ``da`` along ``dim`` with distribution-free confidence limits.

    A dask-backed input is rechunked to hold the whole ``dim`` per block and "auto"
    (memory-bounded) blocks along the other dims, so memory stays at one block.
    """
    probs = np.asarray(quantiles, dtype=float)
    if probs.ndim != 1 or probs.size == 0 or np.any(~(probs > 0) | ~(probs < 1)):
        raise ValueError(f"quantiles must be a non-empty sequence of probabilities in (0, 1), got {quantiles!r}")
    if da.chunks is not None:
        da = da.chunk({d: (-1 if d == dim else "auto") for d in da.dims})
    q, lo, hi = xr.apply_ufunc(
        _quantile_block, da,
        kwargs={"probs": probs, "confidence": confidence},
        input_core_dims=[[dim]], output_core_dims=[["quantile"]] * 3,
        dask="parallelized", output_dtypes=[float] * 3,
        dask_gufunc_kwargs={"output_sizes": {"quantile": probs.size}},
    )
    units = da.attrs.get("units")
    name = da.attrs.get("long_name", da.name)
    out = xr.Dataset(
        {
            "quantile_value": q.assign_attrs(_attrs(units, f"ensemble quantile of {name}", method=QUANTILE_METHOD)),
            **_limits("quantile", lo, hi, units, "the quantile", confidence, QUANTILE_INTERVAL),
        },
        coords={"quantile": ("quantile", probs, {"long_name": "probability level", "units": "1"})},
    )
    return out


def blockwise_quantiles(da: xr.DataArray, quantiles: Sequence[float], confidence: float,
                        dim: str = REALIZATION) -> xr.Dataset:
    """``quantile_statistics`` of ``da`` computed one block of nodes at a time, each block
    every realisation of at most dask's ``array.chunk-size`` bytes of nodes (one node at
    least). Memory is then a block and the chunks being read, not the ensemble: one
    rechunk of a whole variable to columns would hold every piece of it at once. A
    dask-backed ensemble is read once per block. Returns the same numbers: lazily if
    one block holds every node (so that one pass computes it with the moments), else
    computed."""
    template = quantile_statistics(da, quantiles, confidence, dim)
    limit = dask.utils.parse_bytes(dask.config.get("array.chunk-size"))
    block = {d: n for d, n in da.sizes.items() if d != dim}
    while math.prod(block.values()) * da.sizes[dim] * da.dtype.itemsize > limit and max(block.values()) > 1:
        widest = max(block, key=block.get)
        block[widest] = -(-block[widest] // 2)
    if da.chunks is None or block == {d: n for d, n in da.sizes.items() if d != dim}:
        return template
    out = {name: np.empty(var.shape, var.dtype) for name, var in template.data_vars.items()}
    for starts in itertools.product(*(range(0, da.sizes[d], size) for d, size in block.items())):
        where = {d: slice(a, a + block[d]) for d, a in zip(block, starts)}
        part = quantile_statistics(da.isel(where), quantiles, confidence, dim).compute()
        for name, values in out.items():
            dims = template[name].dims
            values[tuple(where.get(d, slice(None)) for d in dims)] = part[name].transpose(*dims).values
    return template.copy(data=out)


def mean_statistics(da: xr.DataArray, confidence: float = 0.95, dim: str = REALIZATION) -> xr.Dataset:
    """Mean, sd, skewness, count and Student-t interval of the mean of any DataArray.

    For per-realisation scalars (energies, line means, asymmetry) as well as fields.
    Returns the computed Dataset (variables ``mean, sd, skewness, count, mean_lower,
    mean_upper``) in the units of ``da``.
    """
    c = check_confidence(confidence)
    if dim not in da.dims:
        raise ValueError(f"dim={dim!r} is not a dim of the DataArray; dims: {da.dims}")
    return moment_statistics(da.astype(float), c, dim).assign_attrs(confidence=c).compute()


def node_statistics(
    ds: xr.Dataset,
    var: str = "shear",
    quantiles: Sequence[float] = (0.05, 0.5, 0.95),
    confidence: float = 0.95,
    replicates: int | None = None,
) -> xr.Dataset:
    """Per-node (or per-cell, for a cell variable) ensemble statistics of ``ds[var]``.

    Reduces along ``realization``, keeping every other dim (i, j or cell_i, cell_j, and
    a leading ``blankholder_force``). Only valid (non-NaN) realisations count. Variables:
    ``mean, sd, skewness, count, mean_lower, mean_upper`` and, along dim ``quantile``,
    ``quantile_value, quantile_lower, quantile_upper``; units those of ``var``. The mean
    interval is Student t; quantile limits are distribution-free order statistics (see
    each variable's ``method`` attr). The moments are one dask pass, the quantiles one a
    block of nodes (``blockwise_quantiles``); returns in-memory data.
    ``replicates`` K: the realisations are K equal consecutive randomisations of one
    randomised-QMC point set (``[sampling] plan = "rqmc"``): the mean's interval is then
    Student t over the K randomisations' means (REPLICATE_INTERVAL), as the points within
    one are not independent; sd and quantiles stay those of all realisations.
    """
    c = check_confidence(confidence)
    da = get_variable(ds, var)
    out = xr.merge([moment_statistics(da, c), blockwise_quantiles(da, quantiles, c)], combine_attrs="override")
    if replicates is not None:
        out.update(_replicate_limits(da, int(replicates), c))
    out.attrs = {**ds.attrs, "variable": var, "confidence": c}
    return out.compute()


def _replicate_limits(da: xr.DataArray, replicates: int, confidence: float) -> dict:
    """The mean's limits from the spread of ``replicates`` consecutive groups' means."""
    n = da.sizes[REALIZATION]
    if replicates < 2 or n % replicates:
        raise ValueError(f"replicates={replicates} must be >= 2 and divide the {n} realisations")
    group = xr.DataArray(np.arange(n) // (n // replicates), dims=REALIZATION, name="randomization")
    means = da.groupby(group).mean(REALIZATION)  # a randomisation's mean over its valid points
    k = means.notnull().sum("randomization")
    half = t_quantile(confidence, k - 1) * means.std("randomization", ddof=1) / np.sqrt(k.where(k > 0))
    centre = means.mean("randomization")
    return _limits("mean", centre - half, centre + half, da.attrs.get("units"), "the mean", confidence,
                   REPLICATE_INTERVAL)


def ring_sd(ds: xr.Dataset, var: str = "shear") -> xr.DataArray:
    """Per-node ensemble sd of ``var`` (deg) averaged over each ring k = max(|i|, |j|) = 1..n.

    Rings are the net's distance from the crossover in segments; the result has dim
    ``ring`` (plus a leading ``blankholder_force`` of a sweep). Nodes with fewer than
    two valid realisations are left out of their ring's average.
    """
    sd = node_statistics(ds, var)["sd"]
    ring = np.maximum(abs(sd["i"]), abs(sd["j"]))
    n = int(ring.max())
    per_ring = [sd.where(ring == k).mean(("i", "j")) for k in range(1, n + 1)]
    out = xr.concat(per_ring, dim="ring").assign_coords(ring=np.arange(1, n + 1))
    return out.assign_attrs(units=sd.attrs.get("units", "degree"),
                            long_name=f"mean over the ring's nodes of the ensemble sd of {var}")


def inner_outer_sd(ds: xr.Dataset, var: str = "shear", band: int = 5) -> tuple[float, float]:
    """(inner, outer) ring-averaged sd of ``var`` (deg): rings 1..band and the ``band``
    rings just inside the boundary ring (n-band..n-1). The boundary ring is left out:
    its node shear averages fewer cells (one at a corner), which adds scatter of its own."""
    per_ring = ring_sd(ds, var)
    n = per_ring.sizes["ring"]
    if n < 2 * band + 1:
        raise ValueError(f"band={band} needs a net of at least {2 * band + 1} rings, got {n}")
    inner = float(per_ring.sel(ring=slice(1, band)).mean())
    outer = float(per_ring.sel(ring=slice(n - band, n - 1)).mean())
    return inner, outer
