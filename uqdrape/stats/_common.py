"""Shared argument checks and small helpers for ``uqdrape.stats``."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr
from scipy import stats

from ..schema import REALIZATION, site_dims


def check_confidence(confidence: float) -> float:
    """Return ``confidence`` as a float, or raise if it is not strictly between 0 and 1."""
    try:
        c = float(confidence)
    except (TypeError, ValueError):
        raise ValueError(f"confidence must be a number in (0, 1), got {confidence!r}") from None
    if not 0.0 < c < 1.0:
        raise ValueError(f"confidence must be in (0, 1) (e.g. 0.95), got {confidence!r}")
    return c


def get_variable(ds: xr.Dataset, var: str) -> xr.DataArray:
    """``ds[var]`` as float, checked to exist and to carry the ``realization`` dim."""
    if var not in ds.data_vars:
        raise ValueError(f"var={var!r} is not a data variable of the Dataset; valid: {sorted(map(str, ds.data_vars))}")
    da = ds[var]
    if REALIZATION not in da.dims:
        raise ValueError(f"var={var!r} has dims {da.dims}; statistics need a {REALIZATION!r} dim")
    return da.astype(float) if da.dtype != float else da


def select_site(da: xr.DataArray, node: Sequence) -> xr.DataArray:
    """Select one node (i, j) -- or one cell (cell_i, cell_j) for a cell variable."""
    names = site_dims(da)
    if len(node) != 2:
        raise ValueError(f"node must be a pair {names}, got {node!r}")
    for name, value in zip(names, node):
        coord = da[name].values
        if value not in coord:
            raise ValueError(f"node {name}={value!r} is not in the net; valid {name}: {coord.min()} .. {coord.max()}")
    return da.sel({names[0]: node[0], names[1]: node[1]})


def lazy_map(func, *args, n_out: int = 1):
    """Apply an elementwise numpy/scipy function to (possibly dask-backed) DataArrays, lazily."""
    return xr.apply_ufunc(func, *args, dask="parallelized", output_dtypes=[float] * n_out,
                          output_core_dims=[[]] * n_out)


def t_quantile(confidence: float, dof: xr.DataArray) -> xr.DataArray:
    """Two-sided Student-t critical value t_{(1+c)/2, dof}; NaN where dof < 1."""
    def crit(d):
        return stats.t.ppf(0.5 + confidence / 2.0, np.where(d >= 1, d, np.nan))

    return lazy_map(crit, dof)
