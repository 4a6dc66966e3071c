"""Exceedance probability P(|var| > threshold) per node: the wrinkle-risk map.

With the locking angle as threshold this is the probability that a node's shear is
beyond locking (where wrinkles start), with a binomial confidence interval.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from scipy import stats

from ._common import REALIZATION, check_confidence, get_variable, lazy_map

METHODS = ("wilson", "clopper-pearson")
_METHOD_TEXT = {"wilson": "Wilson score interval",
                "clopper-pearson": "Clopper-Pearson exact interval (beta quantiles)"}


def wilson_interval(k, n, confidence: float):
    """Wilson score interval of a binomial proportion k/n (NaN where n = 0); exactly
    [0, ...] at k = 0 and [..., 1] at k = n, where the formula gives 0 and 1 up to rounding.

    Works on numbers, numpy arrays or (dask-backed) DataArrays.
    """
    z = stats.norm.ppf(0.5 + confidence / 2.0)
    nn = n.where(n > 0) if isinstance(n, xr.DataArray) else np.where(np.asarray(n) > 0, n, np.nan)
    p = k / nn
    centre = (p + z**2 / (2.0 * nn)) / (1.0 + z**2 / nn)
    half = z / (1.0 + z**2 / nn) * np.sqrt(p * (1.0 - p) / nn + z**2 / (4.0 * nn**2))
    lower, upper = np.maximum(centre - half, 0.0), np.minimum(centre + half, 1.0)
    return lower * (p != 0.0), upper + (p == 1.0) * (1.0 - upper)  # arithmetic: DataArrays stay DataArrays


def _clopper_pearson(k, n, confidence):
    alpha = 1.0 - confidence
    k = np.asarray(k, dtype=float)
    n = np.where(np.asarray(n) > 0, n, np.nan)
    with np.errstate(invalid="ignore"):
        lo = np.where(k > 0, stats.beta.ppf(alpha / 2.0, k, n - k + 1.0), 0.0)
        hi = np.where(k < n, stats.beta.ppf(1.0 - alpha / 2.0, k + 1.0, n - k), 1.0)
    bad = np.isnan(n)
    return np.where(bad, np.nan, lo), np.where(bad, np.nan, hi)


def clopper_pearson_interval(k, n, confidence: float):
    """Clopper-Pearson (exact, conservative) interval of k/n via scipy.stats.beta quantiles."""
    if isinstance(k, xr.DataArray) or isinstance(n, xr.DataArray):
        return lazy_map(lambda a, b: _clopper_pearson(a, b, confidence), k, n, n_out=2)
    return _clopper_pearson(k, n, confidence)


def exceedance_probability(ds: xr.Dataset, threshold_deg=None, var: str = "shear", confidence: float = 0.95,
                           method: str = "wilson") -> xr.Dataset:
    """P(|ds[var]| > threshold_deg) per node over the valid realisations, with an interval.

    ``threshold_deg`` (degree; a scalar, or a 1-D sequence giving a ``threshold`` dim)
    defaults to ``ds.attrs["locking_angle_deg"]``. ``method`` is "wilson" or
    "clopper-pearson". Returns the computed Dataset with ``probability``,
    ``probability_lower``, ``probability_upper`` (units 1), ``exceed_count`` and
    ``count`` (valid realisations); a scalar threshold is kept as a scalar coordinate.
    """
    c = check_confidence(confidence)
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    da = get_variable(ds, var)
    if threshold_deg is None:
        if "locking_angle_deg" not in ds.attrs:
            raise ValueError("threshold_deg is None and the Dataset has no 'locking_angle_deg' attr; pass "
                             "threshold_deg (degree)")
        threshold_deg = ds.attrs["locking_angle_deg"]
    thr = np.asarray(threshold_deg, dtype=float)
    if thr.ndim > 1 or thr.size == 0 or not np.all(np.isfinite(thr)) or np.any(thr < 0):
        raise ValueError(f"threshold_deg must be a finite angle >= 0 (degree) or a 1-D sequence of them, got "
                         f"{threshold_deg!r}")
    t = xr.DataArray(np.atleast_1d(thr), dims="threshold", name="threshold",
                     attrs={"units": da.attrs.get("units", "degree"), "long_name": f"threshold on |{var}|"})
    t = t.assign_coords(threshold=t)
    n = da.notnull().sum(REALIZATION)
    k = (np.abs(da) > t).sum(REALIZATION)
    if thr.ndim == 0:
        k = k.squeeze("threshold")
    p = k / n.where(n > 0)
    lo, hi = (wilson_interval if method == "wilson" else clopper_pearson_interval)(k, n, c)
    interval = {"method": _METHOD_TEXT[method], "confidence": c}
    out = xr.Dataset({
        "probability": p.assign_attrs(units="1", long_name=f"probability that |{var}| exceeds the threshold"),
        **{f"probability_{side}": limit.assign_attrs(units="1", long_name=f"{side} confidence limit of the probability",
                                                     **interval) for side, limit in (("lower", lo), ("upper", hi))},
        "exceed_count": k.assign_attrs(units="1", long_name=f"number of valid realisations with |{var}| > threshold"),
        "count": n.assign_attrs(units="1", long_name="number of valid (non-NaN) realisations")})
    out.attrs = {**ds.attrs, "variable": var, "confidence": c, "interval": _METHOD_TEXT[method]}
    return out.compute()
