"""Histogram of one node's ensemble values with a fitted Normal (thesis Fig 5.20)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr
from scipy import stats

from ._common import REALIZATION, get_variable, select_site


def node_histogram(ds: xr.Dataset, node: Sequence[int], var: str = "shear", bins: int | str | Sequence[float] = 20,
                   range: tuple[float, float] | None = None) -> xr.Dataset:
    """Counts of ``ds[var]`` at ``node`` = (i, j) (or (cell_i, cell_j)) and a fitted Normal.

    ``bins``/``range`` are as for ``numpy.histogram_bin_edges``; the edges are computed
    once from all valid values, so a leading ``blankholder_force`` dim gets one histogram
    per level on common edges. The Normal is the maximum-likelihood fit
    ``scipy.stats.norm.fit`` (its sd has ddof = 0). Returns dims (..., bin) with
    ``count``, ``density`` (counts / (n * width)), ``normal_pdf`` at the bin centres,
    ``bin_edges`` (dim ``bin_edge``), and per level ``normal_mean``, ``normal_sd``, ``n_valid``.
    """
    da = select_site(get_variable(ds, var), node).transpose(..., REALIZATION).compute()
    values = da.values
    flat = values.reshape(-1, values.shape[-1])
    valid_all = values[~np.isnan(values)]
    if valid_all.size == 0:
        raise ValueError(f"node {tuple(node)} of {var!r} has no valid realisation to make a histogram of")
    edges = np.histogram_bin_edges(valid_all, bins=bins, range=range)
    rows = [row[~np.isnan(row)] for row in flat]  # the valid values of each level
    fits = [stats.norm.fit(v) if v.size else (np.nan, np.nan) for v in rows]
    lead, shape = da.dims[:-1], values.shape[:-1]
    centres = 0.5 * (edges[:-1] + edges[1:])
    count = np.asarray([np.histogram(v, bins=edges)[0] for v in rows]).reshape(*shape, centres.size)
    n = np.asarray([v.size for v in rows]).reshape(shape)
    mu, sd = np.moveaxis(np.asarray(fits, dtype=float).reshape(*shape, 2), -1, 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        density = count / (n[..., None] * np.diff(edges))
    units = da.attrs.get("units")
    u = {"units": units} if units else {}
    coords = {d: da[d] for d in lead}
    coords.update({name: c for name, c in da.coords.items() if c.ndim == 0})
    coords["bin"] = ("bin", centres, {**u, "long_name": "bin centre"})
    return xr.Dataset({
        "count": ((*lead, "bin"), count, {"units": "1", "long_name": "number of realisations in the bin"}),
        "density": ((*lead, "bin"), density, {"long_name": "histogram density (integrates to 1)"}),
        "normal_pdf": ((*lead, "bin"), stats.norm.pdf(centres, mu[..., None], sd[..., None]),
                       {"long_name": "fitted Normal density at the bin centres"}),
        "bin_edges": (("bin_edge",), edges, {**u, "long_name": "bin edges"}),
        "normal_mean": (lead, mu, {**u, "long_name": "fitted Normal mean (maximum likelihood)"}),
        "normal_sd": (lead, sd, {**u, "long_name": "fitted Normal sd (maximum likelihood, ddof=0)"}),
        "n_valid": (lead, n, {"units": "1", "long_name": "number of valid realisations"})},
        coords=coords, attrs={**ds.attrs, "variable": var, "node": list(node)})
