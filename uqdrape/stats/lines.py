"""Ensemble summaries along the lines of maximum (and minimum) shear.

The lines themselves -- per realisation shear (deg) against distance from the
crossover along the surface (mm) -- come from ``uqdrape.drape.lines``; this module
reduces them over the ensemble and derives the per-realisation line scalars used by
the sensitivity analysis (mean shear per quadrant and the +/- quadrant asymmetry).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from uqdrape.drape.lines import max_shear_lines, min_shear_lines

from ..schema import MINUS_QUADRANTS, PLUS_QUADRANTS
from ._common import REALIZATION, check_confidence
from .summary import moment_statistics

_KINDS = {"max": max_shear_lines, "min": min_shear_lines}


def _lines(ds: xr.Dataset, kind: str) -> xr.Dataset:
    if kind not in _KINDS:
        raise ValueError(f"kind must be one of {tuple(_KINDS)}, got {kind!r}")
    missing = [v for v in ("x", "y", "z", "shear") if v not in ds.data_vars]
    if missing:
        raise ValueError(f"line statistics need data variables x, y, z, shear; missing {missing}")
    if REALIZATION not in ds["shear"].dims:
        raise ValueError(f"'shear' has dims {ds['shear'].dims}; line statistics need a {REALIZATION!r} dim")
    return _KINDS[kind](ds)


def line_statistics(ds: xr.Dataset, kind: str = "max", confidence: float = 0.95) -> xr.Dataset:
    """Ensemble mean, sd and Student-t band of the mean of shear and distance per node k.

    ``kind`` "max" gives the quadrant diagonals (dims ..., quadrant, k), "min" the
    generator arms (dims ..., arm, k). Variables ``shear_mean, shear_sd, shear_skewness,
    shear_mean_lower, shear_mean_upper`` (degree), the same with prefix ``distance_``
    (mm), and ``count`` (valid realisations at that node). Computed in one pass.
    """
    c = check_confidence(confidence)
    lines = _lines(ds, kind)
    parts = []
    for name in ("shear", "distance"):
        st = moment_statistics(lines[name], c)
        parts.append(st.drop_vars("count").rename({v: f"{name}_{v}" for v in st.data_vars if v != "count"}))
    count = lines["shear"].notnull().sum(REALIZATION)
    count.attrs = {"units": "1", "long_name": "number of valid realisations at this node of the line"}
    out = xr.merge([*parts, count.to_dataset(name="count")], combine_attrs="override")
    out.attrs = {**ds.attrs, "lines": f"{kind}-shear lines", "confidence": c}
    return out.compute()


def line_scalars(ds: xr.Dataset, k_max: int | None = None) -> xr.Dataset:
    """Per-realisation scalars along the max-shear lines, for sensitivity and summaries:
    :func:`line_means` of the max-shear lines of the drapes in ``ds``."""
    out = line_means(_lines(ds, "max")["shear"], k_max)
    out.attrs = {**ds.attrs, "k_max": out.attrs["k_max"]}
    return out


def line_means(shear: xr.DataArray, k_max: int | None = None) -> xr.Dataset:
    """Line scalars of max-shear-line shear (degree, dims ..., realization, quadrant, k;
    ``uqdrape.drape.max_shear_lines``), e.g. lines kept from drapes no longer at hand.

    ``line_mean_shear`` (..., realization, quadrant): signed shear averaged over nodes
    k = 1..k_max of a diagonal (the crossover k = 0 is common to all four and left out);
    ``plus_mean_shear`` / ``minus_mean_shear``: its average over the i*j > 0 quadrants
    ("++", "--") and the i*j < 0 ones ("-+", "+-"); ``asymmetry`` = plus + minus
    (degree): zero for a mirrored pattern, negative when the negative quadrants shear more
    in magnitude. ``k_max`` defaults to the largest k valid in every realisation and
    quadrant, so every scalar averages the same nodes; a line invalid within 1..k_max
    gives NaN.
    """
    n_k = shear.sizes["k"] - 1
    if k_max is None:
        valid = shear.notnull().all([d for d in shear.dims if d != "k"]).compute().values
        k_max = int(valid.argmin()) - 1 if not valid.all() else n_k
        if k_max < 1:
            raise ValueError("no node k >= 1 of the max-shear lines is valid in every realisation; pass k_max")
    elif not isinstance(k_max, int) or not 1 <= k_max <= n_k:
        raise ValueError(f"k_max must be an integer in 1..{n_k}, got {k_max!r}")
    line_mean = shear.sel(k=slice(1, k_max)).mean("k", skipna=False)
    plus = line_mean.sel(quadrant=list(PLUS_QUADRANTS)).mean("quadrant", skipna=False)
    minus = line_mean.sel(quadrant=list(MINUS_QUADRANTS)).mean("quadrant", skipna=False)
    scalars = {
        "line_mean_shear": (line_mean, f"mean signed shear over nodes k = 1..{k_max} of the max-shear line"),
        "plus_mean_shear": (plus, "line mean shear averaged over the i*j > 0 quadrants (++, --)"),
        "minus_mean_shear": (minus, "line mean shear averaged over the i*j < 0 quadrants (-+, +-)"),
        "asymmetry": (plus + minus,
                      "plus_mean_shear + minus_mean_shear (0 when mirrored; < 0 when the - quadrants shear more)")}
    out = xr.Dataset({name: value.assign_attrs(units="degree", long_name=text)
                      for name, (value, text) in scalars.items()})
    out.attrs = {"k_max": k_max}
    return out.compute()


def shear_at_points(ds: xr.Dataset, distance_mm, quadrant_sign) -> np.ndarray:
    """Each drape's shear (deg) at measured points along its max-shear lines, for comparing
    measured parts with an ensemble (``uqdrape.calibration.drapes``): point p lies at
    ``distance_mm[p]`` from the crossover on a line of sign ``quadrant_sign[p]`` (+1: the
    i*j > 0 quadrants, as ``uqdrape.experimental``), shear interpolated linearly in each
    drape's own line distance (NaN past its end). The two lines of a sign are read as two
    copies of the part (a mould symmetric under a half turn about the crossover): copy 0
    puts + points on "++" and - points on "-+", copy 1 on "--" and "+-". Returns an array
    (copy, realization, point); ``ds`` has dims realization, i, j (one force level)."""
    lines = _lines(ds, "max").transpose(REALIZATION, "quadrant", "k")
    distance, sign = np.asarray(distance_mm, float), np.asarray(quadrant_sign, float)
    out = np.full((2, lines.sizes[REALIZATION], distance.size), np.nan)
    for copy, quadrants in enumerate((("++", "-+"), ("--", "+-"))):
        for s, q in zip((1.0, -1.0), quadrants):
            at = np.flatnonzero(sign == s)
            d, g = lines["distance"].sel(quadrant=q).values, lines["shear"].sel(quadrant=q).values
            for r in range(d.shape[0]):
                ok = np.isfinite(d[r]) & np.isfinite(g[r])
                if ok.any():
                    out[copy, r, at] = np.interp(distance[at], d[r][ok], g[r][ok], right=np.nan)
    return out
