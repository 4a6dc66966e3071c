"""Sensitivity indices of evaluated designs, per blank-holder force level, as xarray.

Given a :class:`Design` and the outputs of its rows (dims blankholder_force, realization:
realisations 0..n-1 in order, the same rows draped at every force level), :func:`qoi_indices` analyses scalar quantities of interest and
:func:`map_indices` a per-node output such as node shear. Arrays in, Datasets out: no
files are read or written here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr

from ..schema import FORCE, REALIZATION
from .analysis import analyze, analyze_map, indices_vs_levels

#: Outputs spanning less than this over the design (degree, J or -) are constant: round-off,
#: e.g. the crossover node's shear when the fabric is rotated on a mould of revolution.
ROUNDOFF = 1e-9


@dataclass(frozen=True)
class Design:
    """A SALib design: ``X`` in the problem's variables (what SALib analyses) and
    ``standard``, the same rows in the evaluator's own variables (for a study: scalar
    factors as standard uniforms u, as ``uqdrape.ensemble.inputs_from_design`` takes them).
    ``meta`` holds the sample metadata (method, base_samples, n_evaluations, sample_seed...)."""

    problem: dict
    X: np.ndarray
    standard: np.ndarray
    meta: dict

    @property
    def method(self) -> str:
        return self.meta["method"]

    @property
    def n_evaluations(self) -> int:
        return self.meta["n_evaluations"]


def _per_level(design: Design, data, analyse):
    """``analyse(level)`` at each blank-holder level of ``data``, stacked along ``blankholder_force``."""
    rows = data[REALIZATION].values
    if not np.array_equal(rows, np.arange(design.n_evaluations)) or FORCE not in data.dims:
        raise ValueError(f"the outputs must be the design's {design.n_evaluations} evaluations as realisations "
                         f"0..{design.n_evaluations - 1} in order at each {FORCE!r} level; got dims {dict(data.sizes)}")
    forces = data[FORCE].values
    return indices_vs_levels([analyse(data.sel({FORCE: f})) for f in forces], forces, dim=FORCE, units="N")


def _describe_factors(design: Design, ds: xr.Dataset) -> xr.Dataset:
    """Add per-factor coordinates: number of SALib variables in each group, field or scalar."""
    groups = design.problem.get("groups") or design.problem["names"]
    labels = list(ds["factor"].values)
    sizes = [groups.count(label) for label in labels]
    kinds = ["field" if any(name.startswith(f"{label}[") for name in design.problem["names"]) else "scalar"
             for label in labels]
    return ds.assign_coords(
        n_variables=("factor", sizes, {"long_name": "SALib variables in the group (KL modes of a field)"}),
        factor_kind=("factor", kinds, {"long_name": "scalar factor or random field"}),
    )


def qoi_indices(design: Design, qois: xr.Dataset, *, seed: int, conf_level: float = 0.95,
                num_resamples: int = 100) -> xr.Dataset:
    """Indices of every variable of ``qois`` (dims blankholder_force, realization, the
    realisations being the design's rows), per force level.

    Dims (factor, qoi, blankholder_force); variables of ``uqdrape.sensitivity.analyze``
    (Sobol' S1, S1_conf, ST, ST_conf or Morris mu, mu_star, mu_star_conf, sigma);
    coordinates qoi_units, n_variables, factor_kind; attributes of the analysis and the design.
    """
    names = list(qois.data_vars)

    def analyse(level):
        Y = np.stack([level[q].transpose(REALIZATION).values for q in names], axis=1)
        return analyze(design.problem, design.X, Y, method=design.method, qoi_names=names,
                       conf_level=conf_level, seed=seed, num_resamples=num_resamples, atol=ROUNDOFF)

    ds = _per_level(design, qois, analyse)
    ds = ds.assign_coords(qoi_units=("qoi", [qois[q].attrs.get("units", "") for q in names],
                                     {"long_name": "units of the quantity of interest"}))
    ds.attrs.update(design.meta)
    return _describe_factors(design, ds)


def map_indices(design: Design, field: xr.DataArray, *, seed: int, conf_level: float = 0.95,
                num_resamples: int = 100, progress=None) -> xr.Dataset:
    """Index maps of a per-node output, e.g. node shear (dims blankholder_force,
    realization, i, j): dims (factor, i, j, blankholder_force); NaN where a node is
    invalid in some evaluation (see ``analyze_map``). ``progress(n)``: called as n more
    node columns of a level are analysed."""
    def analyse(level):
        return analyze_map(design.problem, design.X, level, method=design.method, conf_level=conf_level,
                           seed=seed, num_resamples=num_resamples, atol=ROUNDOFF, progress=progress)

    ds = _per_level(design, field, analyse)
    ds.attrs.update(design.meta)
    return _describe_factors(design, ds)
