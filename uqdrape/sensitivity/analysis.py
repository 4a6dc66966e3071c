"""Sensitivity indices from a sample matrix and its model outputs, as xarray Datasets.

Sobol' indices of all output columns (scalar QoIs, net nodes) are computed at once by
SALib's estimators (``first_order``, ``total_order``) on 2-D arrays, with the steps of
``SALib.analyze.sobol.analyze`` (per-column standardisation, the same bootstrap rows for
every column): equal to a call of that function per column to round-off, without a
Python call per node. Morris indices of all columns are computed at once too
(:func:`_morris_columns`: the elementary effects from SALib's trajectory layout, the
bootstrap of mu_star through each variable's resample counts), equal to a call of
``SALib.analyze.morris.analyze`` per column to round-off. The
``factor`` dimension holds SALib's labels: group names when the problem has groups (a
random field is one label), otherwise variable names.

Outputs that are constant over the sample (range <= max(``atol``, ``CONSTANT_RTOL`` x
max |y|), e.g. blank-holder energy at F_BH = 0) have zero variance to apportion: their
indices and confidence half-widths are set to 0 and ``output_constant`` is True. ``atol``
(default 0, in the output's unit) lets a caller declare round-off-level variation
constant, e.g. the crossover node's shear of a rotated fabric.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from importlib.metadata import version

import numpy as np
import pandas as pd
import xarray as xr
from scipy.stats import norm
from SALib.analyze import sobol as sobol_analyze
from SALib.util import compute_groups_matrix

from ..schema import REALIZATION
from .problem import check_problem
from .sample import MORRIS_NUM_LEVELS, check_method, check_seed

CONSTANT_RTOL = 1e-12

VARIABLES = {
    "sobol": ("S1", "S1_conf", "ST", "ST_conf"),
    "morris": ("mu", "mu_star", "mu_star_conf", "sigma"),
}


def _long_names(conf_level: float) -> dict[str, str]:
    ci = f"half-width of the {100 * conf_level:g} % bootstrap confidence interval of"
    return {
        "S1": "first-order Sobol' index",
        "S1_conf": f"{ci} S1",
        "ST": "total-order Sobol' index",
        "ST_conf": f"{ci} ST",
        "mu": "mean elementary effect per unit step in the factor's quantile",
        "mu_star": "mean absolute elementary effect per unit step in the factor's quantile",
        "mu_star_conf": f"{ci} mu_star",
        "sigma": "standard deviation of the elementary effects (NaN for groups of several variables)",
    }


def _sobol_columns(problem, Y, conf_level, seed, num_resamples, progress=None):
    """Sobol' S1, S1_conf, ST, ST_conf of every column of Y (n_evaluations, n_columns) of a
    Saltelli sample without second order: {variable: (n_labels, n_columns)}.

    As ``sobol_analyze.analyze`` per column: each column standardised, A, B and AB_j
    rows split from the sample matrix, bootstrap rows drawn once from ``seed`` (SALib draws the
    same ones for every column), half-widths Z * sd of the bootstrap estimates (0 where
    the resampled outputs do not vary). Columns go in cache-sized blocks (about 2 MB of
    resamples each). ``progress(n)`` is called as n more columns are finished.
    """
    D = len(set(problem.get("groups") or problem["names"]))
    step = D + 2
    N = Y.shape[0] // step
    Y = (Y - Y.mean(axis=0)) / Y.std(axis=0)
    r = np.random.default_rng(seed).integers(N, size=(N, num_resamples))
    Z = norm.ppf(0.5 + conf_level / 2)
    out = {name: np.empty((D, Y.shape[1])) for name in VARIABLES["sobol"]}
    width = max(1, 250_000 // (N * num_resamples))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # SALib's constant-output note: handled by the caller
        for c in range(0, Y.shape[1], width):
            cols = slice(c, c + width)
            A, B = Y[0::step, cols], Y[step - 1::step, cols]
            Ar, Br = A[r], B[r]
            varies = np.ptp(np.concatenate([Ar, Br]), axis=(0, 1)) != 0.0
            for j in range(D):
                AB = Y[j + 1::step, cols]
                out["S1"][j, cols] = sobol_analyze.first_order(A, AB, B)
                out["ST"][j, cols] = sobol_analyze.total_order(A, AB, B)
                out["S1_conf"][j, cols] = np.where(
                    varies, Z * sobol_analyze.first_order(Ar, AB[r], Br).std(axis=0, ddof=1), 0.0)
                out["ST_conf"][j, cols] = np.where(
                    varies, Z * sobol_analyze.total_order(Ar, AB[r], Br).std(axis=0, ddof=1), 0.0)
            if progress is not None:
                progress(A.shape[1])
    return out


def _morris_steps(X, n_groups):
    """Where each variable moves in a Morris sample X (T (G + 1), n_vars): the step
    (T, n_vars; 0..G-1, or -1 if it does not move) and the direction (+1, -1 or 0). A
    variable moving more than once in a trajectory is not a Morris sample: ValueError."""
    T = X.shape[0] // (n_groups + 1)
    sign = np.sign(np.diff(X.reshape(T, n_groups + 1, X.shape[1]), axis=1))  # (T, G, n_vars)
    if np.any(np.abs(sign).sum(axis=1) > 1):
        raise ValueError("X is not a Morris trajectory sample: a variable moves more than once in a trajectory")
    moves = sign != 0
    return np.where(moves.any(axis=1), moves.argmax(axis=1), -1), sign.sum(axis=1)


def _resample_covariance(n_vars, T, num_resamples, seed):
    """Covariance (n_vars, T, T) over SALib's bootstrap resamples of how often each
    trajectory is drawn: SALib draws ``integers(T, size=(num_resamples, T))`` per variable
    in order from one generator seeded with ``seed``, the same draws for every column."""
    rng = np.random.default_rng(seed)
    index = np.stack([rng.integers(T, size=(num_resamples, T)) for _ in range(n_vars)])
    flat = (np.arange(n_vars * num_resamples)[:, None] * T + index.reshape(-1, T)).ravel()
    counts = np.bincount(flat, minlength=n_vars * num_resamples * T).reshape(n_vars, num_resamples, T)
    centred = counts - counts.mean(axis=1, keepdims=True)
    return np.einsum("jrs,jrt->jst", centred, centred) / (num_resamples - 1)


def _morris_columns(problem, X, Y, conf_level, seed, num_resamples, progress=None):
    """Morris mu, mu_star, mu_star_conf, sigma of every column of Y (n_evaluations,
    n_columns): {variable: (n_labels, n_columns)}, as ``SALib.analyze.morris.analyze`` per column.

    Elementary effect of variable j in trajectory t: its direction times the output
    difference over the step where it moves, divided by SALib's delta. mu and mu_star
    are per-variable means over t, then group means (SALib's); sigma is defined for
    single-variable groups only. mu_star_conf: the bootstrap mean of |EE| over a resample
    with counts w is w . |EE| / T, so its variance over the resamples is
    |EE|^T Cov(w) |EE| / T^2 (Cov per variable, shared by all columns; |EE| centred over
    t first, which leaves it unchanged since w sums to T, so that round-off is relative
    to the spread of |EE| and not to its mean); the group's
    value is the mean of its variables' Z sd, as SALib's. ``progress(n)`` is called with
    the number of columns finished.
    """
    groups, _ = compute_groups_matrix(problem.get("groups") or problem["names"])  # (n_vars, G)
    n_vars, G = groups.shape
    T = X.shape[0] // (G + 1)
    delta = MORRIS_NUM_LEVELS / (2.0 * (MORRIS_NUM_LEVELS - 1))  # SALib's _compute_delta
    step, direction = _morris_steps(X, G)
    cov = _resample_covariance(n_vars, T, num_resamples, seed)
    Z = norm.ppf(0.5 + conf_level / 2)
    size = groups.sum(axis=0)
    single = np.flatnonzero(size[groups.argmax(axis=1)] == 1)  # variables that are a group alone
    # mu and mu_star as matrix products: row j picks (with its direction) the step where j moves
    pick = np.zeros((n_vars, T, G + 1))
    moves = step >= 0
    t, j = np.nonzero(moves)
    pick[j, t, step[t, j]] = direction[t, j]
    pick = pick.reshape(n_vars, -1) / T
    # the variables moving at the same steps share |EE|: one pattern per group, typically
    patterns, pattern_of = np.unique(step.T, axis=0, return_inverse=True)
    block = 256  # variables per bootstrap product
    width = max(1, 8_000_000 // (block * T))
    out = {name: np.full((G, Y.shape[1]), np.nan) for name in VARIABLES["morris"]}
    for c in range(0, Y.shape[1], width):
        cols = slice(c, c + width)
        D = np.diff(Y[:, cols].reshape(T, G + 1, -1), axis=1) / delta    # (T, G, columns)
        taken = np.concatenate([D, np.zeros_like(D[:, :1])], axis=1)    # step -1 -> an effect of 0
        flat = taken.reshape(T * (G + 1), -1)
        out["mu"][:, cols] = groups.T @ (pick @ flat) / size[:, None]
        out["mu_star"][:, cols] = groups.T @ (np.abs(pick) @ np.abs(flat)) / size[:, None]
        conf = np.empty((n_vars, flat.shape[1]))
        for p, pattern in enumerate(patterns):
            A = np.abs(taken[np.arange(T), pattern])                     # (T, columns)
            A -= A.mean(axis=0)  # w . 1 = T in every resample: no change, less round-off
            members = np.flatnonzero(pattern_of == p)
            for part in np.array_split(members, -(-members.size // block)):
                var = np.einsum("jst,sc,tc->jc", cov[part], A, A, optimize=True) / T**2
                conf[part] = Z * np.sqrt(np.maximum(var, 0.0))
        out["mu_star_conf"][:, cols] = groups.T @ conf / size[:, None]
        ee = taken[np.arange(T)[:, None], step[:, single]] * direction[:, single, None]
        out["sigma"][groups[single].argmax(axis=1), cols] = ee.std(axis=0, ddof=1)
        if progress is not None:
            progress(flat.shape[1])
    return out


def _indices(problem, X, Y, method, conf_level, seed, num_resamples, atol=0.0, progress=None):
    """Indices of every column of Y (n_evaluations, n_columns).

    Returns ({variable: (n_labels, n_columns)}, constant (n_columns,) bool, attrs).
    Columns with any NaN/inf get NaN indices (the estimators need every evaluation).
    ``progress(n)``: called as n more columns are analysed (the constant and non-finite
    ones first, at once).
    """
    labels = check_problem(problem)
    method = check_method(method)
    seed = check_seed(seed)
    if not 0 < conf_level < 1:
        raise ValueError(f"conf_level={conf_level!r} must lie strictly between 0 and 1")
    if not (np.isfinite(atol) and atol >= 0):
        raise ValueError(f"atol={atol!r} must be a finite number >= 0 (in the output's unit)")
    if isinstance(num_resamples, bool) or not isinstance(num_resamples, (int, np.integer)) or num_resamples < 2:
        raise ValueError(f"num_resamples={num_resamples!r} must be an integer >= 2")
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[1] != problem["num_vars"]:
        raise ValueError(f"X has shape {X.shape}, expected (n_evaluations, {problem['num_vars']})")
    if Y.shape[0] != X.shape[0]:
        raise ValueError(f"Y has {Y.shape[0]} rows but X has {X.shape[0]} (one per evaluation)")
    per_sample = len(labels) + (2 if method == "sobol" else 1)
    if X.shape[0] % per_sample:
        raise ValueError(f"{X.shape[0]} evaluations do not form a {method} sample for {len(labels)} "
                         f"factors/groups (need a multiple of {per_sample})")

    n_cols = Y.shape[1]
    out = {name: np.full((len(labels), n_cols), np.nan) for name in VARIABLES[method]}
    finite = np.isfinite(Y).all(axis=0)
    span = np.ptp(np.where(finite, Y, 0.0), axis=0)
    scale = np.max(np.abs(np.where(finite, Y, 0.0)), axis=0)
    constant = finite & (span <= np.maximum(atol, CONSTANT_RTOL * scale))
    for name in out:
        out[name][:, constant] = 0.0
    if method == "morris":
        # SALib leaves sigma undefined for groups of several variables.
        group_sizes = compute_groups_matrix(problem.get("groups") or problem["names"])[0].sum(axis=0)
        out["sigma"][group_sizes > 1, :] = np.nan
    varying = np.flatnonzero(finite & ~constant)
    if progress is not None:
        progress(n_cols - varying.size)
    if varying.size:
        columns = (_sobol_columns(problem, Y[:, varying], conf_level, seed, num_resamples, progress)
                   if method == "sobol" else
                   _morris_columns(problem, X, Y[:, varying], conf_level, seed, num_resamples, progress))
        for name, values in columns.items():
            out[name][:, varying] = values

    attrs = {"method": method, "base_samples": X.shape[0] // per_sample, "n_evaluations": X.shape[0],
             "conf_level": float(conf_level), "num_resamples": int(num_resamples), "analysis_seed": seed,
             "constant_atol": float(atol), "salib_version": version("SALib")}
    if method == "morris":
        attrs["num_levels"] = MORRIS_NUM_LEVELS
    return labels, out, constant, attrs


def _dataset(labels, out, constant, attrs, dims, shape, coords) -> xr.Dataset:
    """Assemble the indices Dataset with dims ("factor", *dims)."""
    names = _long_names(attrs["conf_level"])
    data_vars = {
        name: (("factor", *dims), values.reshape(len(labels), *shape),
               {"long_name": names[name], **({"units": "1"} if name.startswith("S") else {})})
        for name, values in out.items()
    }
    data_vars["output_constant"] = (dims, constant.reshape(shape),
                                    {"long_name": "output constant over the sample (indices set to 0)"})
    return xr.Dataset(data_vars, coords={"factor": ("factor", labels, {
        "long_name": "factor, or factor group (a random field is one group)"}), **coords}, attrs=attrs)


def analyze(problem: Mapping, X, Y, *, method: str = "sobol",
            qoi_names: Sequence[str] | None = None, conf_level: float = 0.95,
            seed: int, num_resamples: int = 100, atol: float = 0.0) -> xr.Dataset:
    """Indices of scalar outputs Y (n_evaluations,) or (n_evaluations, n_qoi).

    Returns a Dataset with dims (factor, qoi): Sobol' S1, S1_conf, ST, ST_conf, or
    Morris mu, mu_star, mu_star_conf, sigma; output_constant (qoi). Attributes: method,
    base_samples, n_evaluations, conf_level, num_resamples, analysis_seed, constant_atol,
    salib_version (+ num_levels for Morris). NaN or inf in Y is an error. ``atol``: see
    the module docstring.
    """
    Y = np.asarray(Y, dtype=float)
    Y = Y[:, None] if Y.ndim == 1 else Y
    if Y.ndim != 2:
        raise ValueError(f"Y has shape {Y.shape}, expected (n_evaluations,) or (n_evaluations, n_qoi)")
    qoi_names = [f"y{k}" for k in range(Y.shape[1])] if qoi_names is None else qoi_names
    qoi_names = [str(q) for q in qoi_names]
    if len(qoi_names) != Y.shape[1] or len(set(qoi_names)) != len(qoi_names):
        raise ValueError(f"qoi_names={qoi_names} must be {Y.shape[1]} unique names (one per column of Y)")
    bad = (~np.isfinite(Y)).sum(axis=0)
    if bad.any():
        which = {q: int(b) for q, b in zip(qoi_names, bad) if b}
        raise ValueError(f"Y contains NaN/inf (count per QoI: {which}); every evaluation must succeed")
    labels, out, constant, attrs = _indices(problem, X, Y, method, conf_level, seed, num_resamples, atol)
    return _dataset(labels, out, constant, attrs, ("qoi",), (Y.shape[1],), {"qoi": ("qoi", qoi_names)})


def analyze_map(problem: Mapping, X, Y: xr.DataArray, *, method: str = "sobol",
                sample_dim: str = REALIZATION, conf_level: float = 0.95,
                seed: int, num_resamples: int = 100, atol: float = 0.0, progress=None) -> xr.Dataset:
    """Index maps of a field output, e.g. node shear (realization, i, j).

    Every position along Y's other dims is analysed separately; the result has dims
    (factor, *other dims) with Y's coordinates, the variables of ``analyze``, and
    NaN indices where any evaluation of that position is NaN/inf (e.g. a node outside the
    mould in some realisations). Y's name and units are kept as attributes. ``progress(n)``
    is called as positions are finished, n of them at a time.
    """
    if not isinstance(Y, xr.DataArray) or sample_dim not in Y.dims:
        raise ValueError(f"Y must be an xarray DataArray with dimension sample_dim={sample_dim!r}")
    Y = Y.transpose(sample_dim, ...)
    dims, shape = Y.dims[1:], Y.shape[1:]
    values = np.asarray(Y.values, dtype=float).reshape(Y.shape[0], -1)
    labels, out, constant, attrs = _indices(problem, X, values, method, conf_level, seed, num_resamples, atol,
                                            progress)
    coords = {name: coord for name, coord in Y.coords.items() if sample_dim not in coord.dims}
    ds = _dataset(labels, out, constant, attrs, dims, shape, coords)
    ds.attrs["output"] = str(Y.name)
    if "units" in Y.attrs:
        ds.attrs["output_units"] = Y.attrs["units"]
    return ds


def indices_vs_levels(datasets: Sequence[xr.Dataset], level_values, *,
                      dim: str = "blankholder_force", units: str = "N") -> xr.Dataset:
    """Stack per-level index Datasets along a new last dim ``dim`` (e.g. F_BH in N).

    All datasets must have the same coordinates (factors, outputs) and attributes.
    The result round-trips through netCDF (``ds.to_netcdf`` / ``xr.load_dataset``).
    """
    datasets = list(datasets)
    levels = np.asarray(level_values, dtype=float)
    if levels.ndim != 1 or len(levels) != len(datasets) or len(datasets) == 0:
        raise ValueError(f"level_values has {levels.size} values for {len(datasets)} datasets; "
                         "give one level per dataset (at least one)")
    if len(np.unique(levels)) != len(levels):
        raise ValueError(f"level_values={levels.tolist()} must be unique")
    first = datasets[0]
    for k, ds in enumerate(datasets[1:], start=1):
        for name in set(first.indexes) | set(ds.indexes):
            if name not in first.indexes or not first.indexes[name].equals(ds.indexes.get(name)):
                raise ValueError(f"dataset {k} differs from dataset 0 in coordinate {name!r}")
        differing = sorted(key for key in set(first.attrs) | set(ds.attrs)
                           if not np.array_equal(first.attrs.get(key), ds.attrs.get(key)))
        if differing:
            raise ValueError(f"dataset {k} differs from dataset 0 in attributes {differing}")
    index = pd.Index(levels, name=dim)
    stacked = xr.concat(datasets, dim=index, join="exact", combine_attrs="override")
    stacked[dim].attrs.update(units=units, long_name=dim.replace("_", " "))
    return stacked.transpose(..., dim)
