"""The application layer: run a study, analyse it, design it, report it.

This is the one place where the stages meet (``uqdrape.cli`` calls nothing else for a
study): the study file (``uqdrape.study``) is drawn and draped by the ensemble engine
(``uqdrape.ensemble``), its outputs reduced by ``uqdrape.stats`` and, for a sensitivity
study, ranked by ``uqdrape.sensitivity``; ``uqdrape.report`` renders the result.

Sensitivity studies. ``uqdrape run`` of a study with ``[sensitivity] method = "sobol" |
"morris"`` drapes the rows of :func:`study_design` as its realisations (same chunked,
resumable engine, the same rows at every blank-holder level: common random numbers),
then computes the scalar quantities of interest of every drape and their indices per
force level into ``<output_dir>/sensitivity.nc`` (dims factor, qoi, blankholder_force)
and the per-node shear index maps into ``<output_dir>/sensitivity_maps.nc`` (dims
factor, i, j, blankholder_force).

Sobol' indices are unchanged by a monotone map of each input, and the Morris screening
order is too, so the SALib problem is posed in the standard variables the ensemble
consumes (``uqdrape.ensemble.design_variables``) and one design path,
``inputs_from_design``, turns rows into solver inputs:

- a random field is one group: its truncated Karhunen-Loeve standard normals ("norm"
  [0, 1]), the modes keeping ``kl_retained`` of the variance;
- a scalar factor is its own group, coded as a standard uniform u ("unif" [0, 1]) when
  its distribution is bounded (uniform, truncnormal), and as a standard normal
  z = Phi^-1(u) ("norm" [0, 1]) when unbounded (normal, lognormal), so that Morris's end
  levels become the MORRIS_TAIL_QUANTILE quantiles rather than u = 0 or 1 (about +-7 sd).
  The physical value is ``Factor.ppf(u)`` either way.

Morris mu/mu_star are therefore per unit step in u or z, not in the factor's own unit.
Spacing cv, offset sigma0 and correlation length are not factors: they are parameters of
the random fields' distributions, not per-realisation inputs.

Design studies. A study with a ``[design]`` section is run by ``uqdrape.design`` (its
candidate designs drape the study's realisations with common random numbers) into
``<output_dir>/design.nc``, and reported by ``uqdrape.report.write_design_report``.

Method override: a run with another method than the study's (``uqdrape run --method``)
writes to ``<output_dir>-<method>``; Morris then uses the study's base_samples as
trajectories if the study is a Morris study, else ``MORRIS_SCREENING_TRAJECTORIES``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import xarray as xr
from scipy.special import ndtr
from scipy.stats import qmc

from . import design as _design
from .ensemble import design_variables, open_ensemble, read_manifest, run_ensemble, write_atomic
from .report import write_design_report, write_report
from .sensitivity import Design, check_base_samples, map_indices, make_problem, qoi_indices, sample
from .sensitivity.design import UNBOUNDED, check_method
from .stats import QOIS, realization_qois
from .stochastic import normal, uniform
from .study import SENSITIVITY_METHODS, Study, from_dict, load_study

#: Files a sensitivity run writes into its output folder.
INDICES_FILE = "sensitivity.nc"
MAPS_FILE = "sensitivity_maps.nc"
#: Morris trajectories of a screening run (``--method morris``) of a study that is not a
#: Morris study: 20, the top of Campolongo et al.'s 10-20, at (groups + 1) drapes each.
MORRIS_SCREENING_TRAJECTORIES = 20


def run_study(study, *, scheduler: str | None = None, workers: int | None = None,
              chunk_size: int | None = None, resume: bool = True, progress: bool = True,
              method: str | None = None, verbose: bool = False) -> Path:
    """Run a study (a ``Study`` or a study file's path); return its output folder.

    ``method`` None: the study's [sensitivity] method; "sobol" / "morris": drape that
    SALib design and write sensitivity.nc; "none": the Monte Carlo sample. Another method
    than the study's writes to ``<output_dir>-<method>``. The other arguments are those of
    ``uqdrape.ensemble.run_ensemble``. A study with a [design] section runs its design
    (:func:`run_design`); ``method`` must then be None.
    """
    study = study if isinstance(study, Study) else load_study(study)
    if study.design is not None:
        if method is not None:
            raise ValueError(f"study {study.name!r} is a [design] study; it takes no sensitivity method")
        return run_design(study, scheduler=scheduler, workers=workers, progress=progress)
    method = study.sensitivity.method if method is None else method
    if method not in SENSITIVITY_METHODS:
        raise ValueError(f"method must be None or one of {SENSITIVITY_METHODS}, got {method!r}")
    design = None if method == "none" else study_design(study, method)
    out = study.output_dir
    provenance = study.to_dict()
    if method != study.sensitivity.method:
        out = out.with_name(f"{out.name}-{method}")
        provenance["sensitivity"]["method"] = method
        provenance["sensitivity"].pop("base_samples", None)
    attrs = {}
    if design is not None:
        provenance["sensitivity"]["base_samples"] = design.meta["base_samples"]
        attrs = dict(design_method=design.method, design_base_samples=design.meta["base_samples"],
                     design_evaluations=design.n_evaluations)
    out = run_ensemble(study, design_rows=None if design is None else design.standard, output_dir=out,
                       provenance=provenance, attrs=attrs, scheduler=scheduler, workers=workers,
                       chunk_size=chunk_size, resume=resume, progress=progress, verbose=verbose)
    if design is not None:
        if progress:
            print(f"{study.name}: analysing {design.method} indices of {design.n_evaluations} evaluations"
                  + (f" at {len(study.force_levels)} force levels" if study.is_sweep else ""), file=sys.stderr)
        write_sensitivity(out, design, qoi=study.sensitivity.qoi, seed=study.seed)
    return out


def study_problem(study) -> dict:
    """The SALib problem of a study in standard variables (see "Sensitivity studies" above);
    its names are ``design_variables(study)``. Fields are groups of their KL modes."""
    factors = {name: normal(0.0, 1.0) if factor.salib_dist in UNBOUNDED else uniform(0.0, 1.0)
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


def study_design(study, method: str | None = None) -> Design:
    """The design of ``study`` with ``method`` (default: the study's own), seeded by the
    study seed. Rows are evaluations (drapes); see :class:`Design`."""
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
    return Design(problem, X, standard, meta)


def write_sensitivity(output_dir, design: Design, *, qoi=None, seed: int) -> tuple[Path, Path]:
    """Analyse a finished sensitivity run in ``output_dir`` (its realisations are the
    design's rows): QoI indices to ``sensitivity.nc``, node-shear index maps to
    ``sensitivity_maps.nc`` (both written whole, then renamed). ``qoi``: names (default all
    of QOIS). Returns the two paths."""
    out = Path(output_dir)
    with open_ensemble(out) as ds:
        qois = realization_qois(ds, QOIS if qoi is None else qoi)
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


def run_design(study, *, scheduler: str | None = None, workers: int | None = None, progress: bool = True) -> Path:
    """Run the [design] of a study (a ``Study`` or a study file's path) into its output
    folder (``design.nc`` and the per-design records; resumes from them); return the folder."""
    study = study if isinstance(study, Study) else load_study(study)
    if study.design is None:
        raise ValueError(f"study {study.name!r} ({study.path}) has no [design] section; run it with `uqdrape run`")
    return _design.run_design(study, scheduler=scheduler, workers=workers, progress=progress)


def run_report(output_dir, out_dir=None) -> Path:
    """Report of a finished run: the ensemble under ``output_dir`` with the title
    (the study's name), description, study text, histogram nodes and experimental CSV of
    the study stored in its attributes, the wall time from its manifest, and its
    sensitivity results if it has them; of a design run, its design page. Writes into
    ``out_dir`` (default ``output_dir/report``); returns the index.html path."""
    design = Path(output_dir) / _design.DESIGN_FILE
    ds = xr.load_dataset(design) if design.is_file() else open_ensemble(output_dir)
    study = from_dict(json.loads(ds.attrs["study_json"]), Path(output_dir))
    report = Path(out_dir) if out_dir else Path(output_dir) / "report"
    if design.is_file():
        return write_design_report(ds, report, surface=study.geometry.build_mould())
    sensitivity = open_sensitivity(output_dir)
    return write_report(ds, report, title=study.name,
                        description=study.description or None, study_text=ds.attrs.get("study_toml"),
                        histogram_nodes=list(study.report.histogram_nodes) or None,
                        experimental_csv=study.report.experimental_csv,
                        wall_time_s=read_manifest(output_dir).get("wall_time_s"),
                        **({} if sensitivity is None else dict(zip(("sensitivity", "sensitivity_maps"), sensitivity))))
