"""A study's sensitivity analysis: its SALib design, and the indices of its ensemble.

``uqdrape run`` of a study with ``[sensitivity] method = "sobol" | "morris"`` drapes the
rows of :func:`study_design` as its realisations (same chunked, resumable engine, the
same rows at every blank-holder level: common random numbers), then
:func:`write_sensitivity` computes the scalar quantities of interest (``qoi``) of every
drape and the indices per force level, into ``<output_dir>/sensitivity.nc`` (dims factor,
qoi[, blankholder_force]) and the per-node shear index maps into
``<output_dir>/sensitivity_maps.nc`` (dims factor, i, j[, blankholder_force]).

Variables. Sobol' indices are unchanged by a monotone map of each input, and the Morris
screening order is too, so the SALib problem is posed in the standard variables the
ensemble consumes (``uqdrape.ensemble.design_variables``) and one design path,
``inputs_from_design``, turns rows into solver inputs:

- a random field is one group: its truncated Karhunen-Loeve standard normals ("norm"
  [0, 1]), the modes keeping ``kl_retained`` of the variance;
- a scalar factor is its own group, coded as a standard uniform u ("unif" [0, 1]) when
  its distribution is bounded (uniform, truncnormal), and as a standard normal
  z = Phi^-1(u) ("norm" [0, 1]) when unbounded (normal, lognormal), so that Morris's end
  levels become the MORRIS_TAIL_QUANTILE quantiles rather than u = 0 or 1 (about +-7 sd).
  The physical value is ``Factor.ppf(u)`` either way.

Morris mu/mu_star are therefore per unit step in u or z, not in the factor's own unit.

Not offered as factors in this release: spacing cv, offset sigma0 and correlation length.
They are parameters of the random fields' distributions, not per-realisation inputs; a
design row could only vary them through a different field map per row. The fields
themselves (spacing, zero angle) are the groups.

Method override: a run with another method than the study's (``uqdrape run --method``)
writes to ``<output_dir>-<method>``; Morris then uses the study's base_samples as
trajectories if the study is a Morris study, else ``MORRIS_SCREENING_TRAJECTORIES``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.special import ndtr
from scipy.stats import qmc

from ..ensemble.inputs import design_variables
from ..stochastic import normal, uniform
from .analysis import analyze, analyze_map, indices_vs_levels
from .design import _UNBOUNDED, check_base_samples, check_method, sample
from .problem import make_problem
from .qoi import QOI_ATTRS, realization_qois

#: Files a sensitivity run writes into its output folder.
INDICES_FILE = "sensitivity.nc"
MAPS_FILE = "sensitivity_maps.nc"
#: Morris trajectories of a screening run (``--method morris``) of a study that is not a
#: Morris study: 20, the top of Campolongo et al.'s 10-20, at (groups + 1) drapes each.
MORRIS_SCREENING_TRAJECTORIES = 20
#: Outputs spanning less than this over the design (degree, J or -) are constant: round-off,
#: e.g. the crossover node's shear when the fabric is rotated on a mould of revolution.
ROUNDOFF = 1e-9
FORCE = "blankholder_force"
REALIZATION = "realization"


@dataclass(frozen=True)
class StudyDesign:
    """A study's SALib design: ``X`` in the problem's variables (what SALib analyses) and
    ``standard``, the same rows as ``inputs_from_design`` takes them (scalar factors as u).
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


def study_problem(study) -> dict:
    """The SALib problem of a study in standard variables (see the module docstring);
    its names are ``design_variables(study)``. Fields are groups of their KL modes."""
    factors = {name: normal(0.0, 1.0) if factor.salib_dist in _UNBOUNDED else uniform(0.0, 1.0)
               for name, factor in study.uncertainty.factors.items()}
    fields = {name: spec.build_input(study.solver.rings, study.fabric.spacing_mm).kl(spec.kl_retained).n_variables
              for name, spec in study.uncertainty.fields.items()}
    try:
        problem = make_problem(factors, fields)
    except ValueError as err:
        raise ValueError(f"study {study.name!r} ({study.path}): {err}; add [uncertainty.*] inputs") from None
    assert problem["names"] == design_variables(study), "problem and ensemble disagree on the variable order"
    return problem


def design_base_samples(study, method: str) -> int:
    """Base samples (Sobol') or trajectories (Morris) of ``study`` run with ``method``."""
    method = check_method(method)
    base = study.sensitivity.base_samples
    if method == "morris" and study.sensitivity.method != "morris":
        return MORRIS_SCREENING_TRAJECTORIES
    if base is None:
        raise ValueError(f"method={method!r}: study {study.name!r} ({study.path}) has no [sensitivity] "
                         f"base_samples; set it (Sobol': a power of 2 >= 64)")
    return check_base_samples(method, base)


def study_design(study, method: str | None = None) -> StudyDesign:
    """The design of ``study`` with ``method`` (default: the study's own), seeded by the
    study seed. Rows are evaluations (drapes); see :class:`StudyDesign`."""
    method = study.sensitivity.method if method is None else method
    if method == "none":
        raise ValueError(f"study {study.name!r} has [sensitivity] method = \"none\"; pass method='sobol' or 'morris'")
    base = design_base_samples(study, method)
    problem = study_problem(study)
    if method == "sobol" and 2 * problem["num_vars"] > qmc.Sobol.MAXDIM:
        sizes = {name: problem["groups"].count(name) for name in study.uncertainty.fields}
        raise ValueError(
            f"study {study.name!r}: a Sobol' design of {problem['num_vars']} variables needs a Sobol' sequence of "
            f"{2 * problem['num_vars']} dimensions, more than scipy's {qmc.Sobol.MAXDIM} (KL modes per field: "
            f"{sizes}); use fewer rings, a correlated field or a lower kl_retained")
    X, meta = sample(problem, method, base_samples=base, seed=study.seed)
    standard = X.copy()
    coded = [k for k in range(len(study.uncertainty.factors)) if problem["dists"][k] == "norm"]
    standard[:, coded] = ndtr(X[:, coded])
    return StudyDesign(problem, X, standard, meta)


def _per_level(design: StudyDesign, data, analyse):
    """``analyse(level)`` at each blank-holder level of ``data`` (stacked), or once."""
    rows = data[REALIZATION].values
    if not np.array_equal(rows, np.arange(design.n_evaluations)):
        raise ValueError(f"the outputs must be the design's {design.n_evaluations} evaluations as realisations "
                         f"0..{design.n_evaluations - 1} in order; got {rows.size} realisations")
    if FORCE not in data.dims:
        return analyse(data)
    forces = data[FORCE].values
    return indices_vs_levels([analyse(data.sel({FORCE: f})) for f in forces], forces, dim=FORCE, units="N")


def _describe_factors(design: StudyDesign, ds: xr.Dataset) -> xr.Dataset:
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


def qoi_indices(design: StudyDesign, qois: xr.Dataset, *, seed: int, conf_level: float = 0.95,
                num_resamples: int = 100) -> xr.Dataset:
    """Indices of every variable of ``qois`` (dims [blankholder_force,] realization, the
    realisations being the design's rows), per force level.

    Dims (factor, qoi[, blankholder_force]); variables of ``uqdrape.sensitivity.analyze``
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


def map_indices(design: StudyDesign, field: xr.DataArray, *, seed: int, conf_level: float = 0.95,
                num_resamples: int = 100) -> xr.Dataset:
    """Index maps of a per-node output, e.g. node shear (dims [blankholder_force,]
    realization, i, j): dims (factor, i, j[, blankholder_force]); NaN where a node is
    invalid in some evaluation (see ``analyze_map``)."""
    def analyse(level):
        return analyze_map(design.problem, design.X, level, method=design.method, conf_level=conf_level,
                           seed=seed, num_resamples=num_resamples, atol=ROUNDOFF)

    ds = _per_level(design, field, analyse)
    ds.attrs.update(design.meta)
    return _describe_factors(design, ds)


def write_sensitivity(output_dir, design: StudyDesign, *, qoi=None, seed: int) -> tuple[Path, Path]:
    """Analyse a finished sensitivity run in ``output_dir`` (its realisations are the
    design's rows): QoI indices to ``sensitivity.nc``, node-shear index maps to
    ``sensitivity_maps.nc`` (both written whole, then renamed). ``qoi``: names (default all
    of QOIS). Returns the two paths."""
    from ..ensemble import open_ensemble
    from ..ensemble.chunk import write_atomic

    out = Path(output_dir)
    with open_ensemble(out) as ds:
        qois = realization_qois(ds, qoi if qoi is not None else tuple(QOI_ATTRS))
        shear = ds["shear"].load()
        study_name = ds.attrs.get("study_name", out.name)
    indices = qoi_indices(design, qois, seed=seed)
    maps = map_indices(design, shear, seed=seed)
    for result in (indices, maps):
        result.attrs["study_name"] = study_name
    if "k_max" in qois.attrs:
        indices.attrs["line_k_max"] = qois.attrs["k_max"]
    return write_atomic(indices, out / INDICES_FILE), write_atomic(maps, out / MAPS_FILE)


def open_sensitivity(output_dir) -> tuple[xr.Dataset, xr.Dataset] | None:
    """(QoI indices, node-shear index maps) of a sensitivity run in ``output_dir``, loaded;
    None if the folder holds no sensitivity results."""
    out = Path(output_dir)
    if not (out / INDICES_FILE).is_file():
        return None
    return xr.load_dataset(out / INDICES_FILE), xr.load_dataset(out / MAPS_FILE)
