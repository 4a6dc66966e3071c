"""Convergence of the Monte Carlo mean with the number of realisations N."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr
from scipy import stats

from ._common import REALIZATION, check_confidence, get_variable, select_site, t_quantile


def convergence(data: xr.Dataset | xr.DataArray, node: Sequence[int] | None = None, var: str = "shear",
                confidence: float = 0.95) -> xr.Dataset:
    """Running mean, sd and Student-t half-width of the mean against N, in realisation order.

    ``data`` is an ensemble Dataset with ``node`` = (i, j) (or (cell_i, cell_j)) picking
    ``data[var]`` at one site, or a DataArray already reduced to (..., realization), e.g. a
    per-realisation scalar. Invalid (NaN) realisations are skipped. Returns dims (..., n)
    where coord ``n`` = realisations drawn (1..N), with ``running_mean``, ``running_sd``
    (ddof = 1), ``half_width`` (t_{(1+c)/2, m-1} * sd / sqrt(m)) and ``count`` m (valid).
    """
    c = check_confidence(confidence)
    if isinstance(data, xr.Dataset):
        if node is None:
            raise ValueError("node=(i, j) is required when data is a Dataset")
        da = select_site(get_variable(data, var), node)
    elif isinstance(data, xr.DataArray):
        da = data if node is None else select_site(data, node)
        if REALIZATION not in da.dims:
            raise ValueError(f"data has dims {da.dims}; convergence needs a {REALIZATION!r} dim")
    else:
        raise ValueError(f"data must be an xarray Dataset or DataArray, got {type(data).__name__}")
    x = da.astype(float).transpose(..., REALIZATION).compute()
    x = x.drop_vars([name for name, co in x.coords.items() if REALIZATION in co.dims])
    shift = x.mean(REALIZATION).fillna(0.0)  # centring keeps the running sums accurate
    d = x - shift
    m = x.notnull().cumsum(REALIZATION)
    mm = m.where(m > 0).astype(float)
    s1 = d.fillna(0.0).cumsum(REALIZATION)
    s2 = (d**2).fillna(0.0).cumsum(REALIZATION)
    mean = shift + s1 / mm
    sd = np.sqrt(((s2 - s1**2 / mm) / (mm - 1.0)).where(m > 1).clip(min=0.0))
    half = t_quantile(c, m - 1) * sd / np.sqrt(mm)
    units = da.attrs.get("units")
    u = {"units": units} if units else {}
    out = xr.Dataset({
        "running_mean": mean.assign_attrs(u, long_name="mean of the valid realisations among the first n"),
        "running_sd": sd.assign_attrs(u, long_name="sd (ddof=1) of the valid realisations among the first n"),
        "half_width": half.assign_attrs(u, long_name=f"half-width of the {c:.0%} Student-t confidence interval of "
                                                     "the mean"),
        "count": m.assign_attrs(units="1", long_name="number of valid realisations among the first n")})
    out = out.rename({REALIZATION: "n"}).assign_coords(
        n=("n", np.arange(1, x.sizes[REALIZATION] + 1), {"long_name": "number of realisations drawn"}))
    out.attrs = {"variable": str(da.name), "confidence": c, **({"node": list(node)} if node is not None else {})}
    return out


def samples_needed(sd, half_width, confidence: float = 0.95, method: str = "t"):
    """Realisations N needed for a confidence interval of the mean of half-width ``half_width``.

    ``sd`` and ``half_width`` in the same units (scalars or arrays). "normal":
    N = ceil((z_{(1+c)/2} * sd / half_width)^2). "t": the smallest N >= 2 with
    t_{(1+c)/2, N-1} * sd / sqrt(N) <= half_width (the Normal value is its lower bound).
    Returns int (or an int array).
    """
    c = check_confidence(confidence)
    if method not in ("t", "normal"):
        raise ValueError(f"method must be 't' or 'normal', got {method!r}")
    sd_a, h_a = np.asarray(sd, dtype=float), np.asarray(half_width, dtype=float)
    for name, value, a in (("sd", sd, sd_a), ("half_width", half_width, h_a)):
        if np.any(~(a > 0)) or not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    z = stats.norm.ppf(0.5 + c / 2.0)
    n = np.ceil((z * sd_a / h_a) ** 2)
    if method == "t":
        n = np.maximum(n, 2.0)
        while np.any(short := stats.t.ppf(0.5 + c / 2.0, n - 1.0) * sd_a / np.sqrt(n) > h_a):
            n = np.where(short, n + 1.0, n)
    out = n.astype(np.int64)
    return int(out) if out.ndim == 0 else out
