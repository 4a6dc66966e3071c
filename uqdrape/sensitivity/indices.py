"""Sensitivity indices of evaluated sample matrices, per blank-holder force level, as xarray.

Given a :class:`SampleMatrix` and the outputs of its rows (dims blankholder_force, realization:
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

#: Outputs spanning less than this over the sample (degree, J or -) are constant: round-off,
#: e.g. the crossover node's shear when the fabric is rotated on a mould of revolution.
ROUNDOFF = 1e-9


@dataclass(frozen=True)
class SampleMatrix:
    """A SALib sample: ``X`` in the problem's variables (what SALib analyses) and
    ``standard``, the same rows in the evaluator's own variables (for a study: scalar
    factors as standard uniforms u, as ``uqdrape.ensemble.inputs_from_rows`` takes them).
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


def _per_level(sample: SampleMatrix, data, analyse):
    """``analyse(level)`` at each blank-holder level of ``data``, stacked along ``blankholder_force``."""
    rows = data[REALIZATION].values
    if not np.array_equal(rows, np.arange(sample.n_evaluations)) or FORCE not in data.dims:
        raise ValueError(f"the outputs must be the sample's {sample.n_evaluations} evaluations as realisations "
                         f"0..{sample.n_evaluations - 1} in order at each {FORCE!r} level; got dims {dict(data.sizes)}")
    forces = data[FORCE].values
    return indices_vs_levels([analyse(data.sel({FORCE: f})) for f in forces], forces, dim=FORCE, units="N")


def _describe_factors(sample: SampleMatrix, ds: xr.Dataset) -> xr.Dataset:
    """Add per-factor coordinates (number of SALib variables in each group, field or
    scalar) and the sample's metadata as attributes."""
    groups = sample.problem.get("groups") or sample.problem["names"]
    labels = list(ds["factor"].values)
    sizes = [groups.count(label) for label in labels]
    kinds = ["field" if any(name.startswith(f"{label}[") for name in sample.problem["names"]) else "scalar"
             for label in labels]
    return ds.assign_coords(
        n_variables=("factor", sizes, {"long_name": "SALib variables in the group (KL modes of a field)"}),
        factor_kind=("factor", kinds, {"long_name": "scalar factor or random field"})).assign_attrs(sample.meta)


def qoi_indices(sample: SampleMatrix, qois: xr.Dataset, *, seed: int, conf_level: float = 0.95,
                num_resamples: int = 100) -> xr.Dataset:
    """Indices of every variable of ``qois`` (dims blankholder_force, realization, the
    realisations being the sample's rows), per force level.

    Dims (factor, qoi, blankholder_force); variables of ``uqdrape.sensitivity.analyze``
    (Sobol' S1, S1_conf, ST, ST_conf or Morris mu, mu_star, mu_star_conf, sigma);
    coordinates qoi_units, n_variables, factor_kind; attributes of the analysis and the sample.
    """
    names = list(qois.data_vars)

    def analyse(level):
        Y = np.stack([level[q].transpose(REALIZATION).values for q in names], axis=1)
        return analyze(sample.problem, sample.X, Y, method=sample.method, qoi_names=names,
                       conf_level=conf_level, seed=seed, num_resamples=num_resamples, atol=ROUNDOFF)

    ds = _per_level(sample, qois, analyse)
    ds = ds.assign_coords(qoi_units=("qoi", [qois[q].attrs.get("units", "") for q in names],
                                     {"long_name": "units of the quantity of interest"}))
    return _describe_factors(sample, ds)


def map_indices(sample: SampleMatrix, field: xr.DataArray, *, seed: int, conf_level: float = 0.95,
                num_resamples: int = 100, progress=None) -> xr.Dataset:
    """Index maps of a per-node output, e.g. node shear (dims blankholder_force,
    realization, i, j): dims (factor, i, j, blankholder_force); NaN where a node is
    invalid in some evaluation (see ``analyze_map``). ``progress(n)``: called as n more
    node columns of a level are analysed."""
    def analyse(level):
        return analyze_map(sample.problem, sample.X, level, method=sample.method, conf_level=conf_level,
                           seed=seed, num_resamples=num_resamples, atol=ROUNDOFF, progress=progress)

    return _describe_factors(sample, _per_level(sample, field, analyse))
