"""Run a study: its Monte Carlo ensemble, its SALib sample and indices, or its
blank-holder design; and the report of a finished run.

Sensitivity studies. ``run_study`` of a study with ``[sensitivity] method = "sobol" |
"morris"`` drapes the rows of ``uqdrape.sensitivity.sensitivity_sample`` as its realisations
(same chunked, resumable engine, the same rows at every blank-holder level: common
random numbers), then computes the quantities of interest of every drape and their
indices per force level into ``<output_dir>/sensitivity.nc`` (dims factor, qoi,
blankholder_force) and the per-node shear index maps into
``<output_dir>/sensitivity_maps.nc`` (dims factor, i, j, blankholder_force).

Method override: a run with another method than the study's (``uqdrape run --method``)
writes to ``<output_dir>-<method>``; Morris then uses the study's base_samples as
trajectories if the study is a Morris study, else ``MORRIS_SCREENING_TRAJECTORIES``.

Design studies. A study with a ``[design]`` section is run by :func:`run_design`: its
candidate designs drape the study's realisations with common random numbers
(``uqdrape.design``) into ``<output_dir>/design.nc``, under the same run lock and on the
same worker pool as an ensemble.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from typing import TYPE_CHECKING

from ..ensemble import at, read_manifest
from ..schema import FORCE
from ..study import SENSITIVITY_METHODS, Study, from_dict, identity, load_study

if TYPE_CHECKING:
    import xarray as xr

# What a plain run does not use (the design, report, sensitivity, statistics, rare-event
# and target engines: seconds of imports before its first drape) is imported where used.

#: Files a sensitivity run writes into its output folder.
INDICES_FILE = "sensitivity.nc"
MAPS_FILE = "sensitivity_maps.nc"


def run_study(study, *, scheduler: str | None = None, workers: int | None = None,
              chunk_size: int | None = None, resume: bool = True, progress: bool = True,
              method: str | None = None, verbose: bool = False) -> Path:
    """Run a study (a ``Study`` or a study file's path); return its output folder.

    ``method`` None: the study's [sensitivity] method; "sobol" / "morris": drape that
    SALib sample matrix and write sensitivity.nc; "none": the Monte Carlo sample. Another method
    than the study's writes to ``<output_dir>-<method>``. The other arguments are those of
    ``uqdrape.ensemble.run_ensemble``. A study with a [design] section runs its design
    (:func:`run_design`); ``method`` must then be None. A study with a ``[study] target``
    (and no sensitivity method) runs in rounds until it is met (``uqdrape.workflow.target``).
    Then each of :data:`AFTER_SAMPLE` runs, each doing nothing where its study does not ask
    for it: a hierarchical study's fixed-parameter twin into ``<output_dir>/fixed``
    (``uqdrape.workflow.twin``; ``[report] fixed_twin = false`` skips it), a sensitivity
    run's indices, a ``[study] rare`` probability.
    """
    from ..ensemble import run_ensemble, sample_columns
    from .preflight import run_preflight

    study = study if isinstance(study, Study) else load_study(study)
    if study.design is not None:
        if method is not None:
            raise ValueError(f"study {study.name!r} is a [design] study; it takes no sensitivity method")
        return run_design(study, scheduler=scheduler, workers=workers, progress=progress)
    method = study.sensitivity.method if method is None else method
    if method != "none":
        study.single_ply("a sensitivity sample")
    if method not in SENSITIVITY_METHODS:
        raise ValueError(f"method must be one of {', '.join(SENSITIVITY_METHODS)}, got {method!r}")
    matrix = None
    if method != "none":
        from ..sensitivity import sensitivity_sample

        matrix = sensitivity_sample(study, method)
    if matrix is not None:
        assert matrix.problem["names"] == sample_columns(study), "problem and ensemble disagree on the variables"
    out, provenance, attrs = study.output_dir, study.to_dict(), {}
    if method != study.sensitivity.method:
        out = at(out).sibling(f"-{method}").target
        provenance["sensitivity"]["method"] = method
        provenance["sensitivity"].pop("base_samples", None)
    if matrix is not None:
        provenance["sensitivity"]["base_samples"] = matrix.meta["base_samples"]
        attrs = dict(sample_method=matrix.method, sample_base_samples=matrix.meta["base_samples"],
                     sample_evaluations=matrix.n_evaluations)
    rows = None if matrix is None else matrix.standard

    def run(sample, where, again, **kwargs):
        return run_ensemble(sample, output_dir=where, scheduler=scheduler, workers=workers, chunk_size=chunk_size,
                            resume=again, progress=progress, verbose=verbose, **kwargs,
                            preflight=run_preflight(sample, where, chunk_size=chunk_size, quiet=not progress,
                                                    sample_rows=kwargs.get("sample_rows")))
    if matrix is None and study.target is not None:
        from .target import run_to_target

        out = run_to_target(study, lambda sample, again: run(sample, out, again),
                            chunk_size=chunk_size or study.chunk_size, resume=resume, progress=progress)
    else:
        out = run(study, out, resume, sample_rows=rows, provenance=provenance, attrs=attrs)
    done = Sampled(study, out, matrix, run, resume, progress)
    for step in AFTER_SAMPLE:
        step(done)
    return out


@dataclass(frozen=True)
class Sampled:
    """A study's finished sample, as the steps after it see it: the study, its output
    folder, its sensitivity sample matrix (None: a Monte Carlo run), ``run(sample, where,
    resume)`` to drape another study the same way, and the run's resume and progress."""

    study: Study
    out: Path | str
    matrix: object
    run: Callable
    resume: bool
    progress: bool


def _twin(done: Sampled) -> None:
    """Drape the fixed-parameter twin of a hierarchical Monte Carlo run with as many
    realisations as the run holds (``uqdrape.workflow.twin``), if the study asks for it
    (``[report] fixed_twin``; ``fixed_twin`` is None for a study that is not hierarchical)."""
    if done.matrix is not None or not done.study.report.fixed_twin:
        return
    from .twin import fixed_twin

    twin = fixed_twin(done.study, read_manifest(done.out)["study"]["study"]["realizations"], done.out)
    if done.progress:
        print(f"{done.study.name}: draping its fixed-parameter twin into {twin.output_dir}: the same "
              f"{twin.realizations} realisations with sd and lengths at their estimates, to measure the widening "
              "(twice the drapes; [report] fixed_twin = false skips it)", file=sys.stderr)
    done.run(twin, twin.output_dir, done.resume)


def _indices(done: Sampled) -> None:
    """A sensitivity run's indices and maps (:func:`write_sensitivity`), unless a resumed
    run already holds them for the same drapes."""
    matrix, name = done.matrix, done.study.name
    if matrix is None:
        return
    if done.resume and analysed(done.out):
        if done.progress:
            print(f"{name}: {matrix.method} indices already analysed in {done.out}", file=sys.stderr)
        return
    if done.progress:
        print(f"{name}: analysing {matrix.method} indices of {matrix.n_evaluations} evaluations"
              + (f" at {len(done.study.force_levels)} force levels" if done.study.is_sweep else ""), file=sys.stderr)
    write_sensitivity(done.out, matrix, qoi=done.study.sensitivity.qoi, seed=done.study.seed, progress=done.progress)


def _rare(done: Sampled) -> None:
    """The study's ``[study] rare`` probability into its run folder, if it asks for one."""
    if done.study.rare is not None:
        from .rare import rare_probabilities

        rare_probabilities(done.study, done.out, resume=done.resume, progress=done.progress)


#: What follows a study's sample, in order; a feature that works on a finished run plugs in here.
AFTER_SAMPLE = (_twin, _indices, _rare)


def _run_key(output_dir) -> str:
    """What a run folder's analysis is of: a digest of its manifest's study identity and
    chunk names (the drapes are a function of these alone)."""
    manifest = read_manifest(output_dir) or {}
    what = {"study": identity(manifest["study"]) if "study" in manifest else None, "chunks": manifest.get("chunks")}
    return hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()


def analysed(output_dir) -> bool:
    """Whether ``output_dir`` (a run folder or store URL) holds the sensitivity files of
    its own finished run (both files, written for the run its manifest describes), so a
    resume need not redo them."""
    keys = []
    for name in (INDICES_FILE, MAPS_FILE):
        try:
            ds = at(output_dir).read_dataset(name)
        except (OSError, ValueError):
            return False
        keys.append(None if ds is None else ds.attrs.get("run_key"))
    return keys[0] is not None and keys[0] == keys[1] == _run_key(output_dir)


def write_sensitivity(output_dir, matrix, *, qoi=None, seed: int,
                      progress: bool = False) -> tuple[Path | str, Path | str]:
    """Analyse a finished sensitivity run in ``output_dir`` (a run folder or store URL; its realisations are the
    sample matrix's rows): QoI indices to ``sensitivity.nc``, node-shear index maps to
    ``sensitivity_maps.nc`` (both written whole, then renamed, with the attribute
    ``run_key`` naming the run they are of: see :func:`analysed`). ``qoi``: names (default
    ``SENSITIVITY_QOIS``); ``progress``: count the analysed nodes on stderr. Returns the
    two paths (URLs in a store)."""
    from ..ensemble import Progress
    from ..sensitivity import map_indices, qoi_indices
    from ..stats import SENSITIVITY_QOIS, realization_qois

    out = at(output_dir)
    with out.open() as ds:
        qois = realization_qois(ds, SENSITIVITY_QOIS if qoi is None else qoi)
        shear = ds["shear"].load()
        study_name = ds.attrs.get("study_name", out.name)
    indices = qoi_indices(matrix, qois, seed=seed)
    nodes = shear.isel({dim: 0 for dim in shear.dims if dim not in ("i", "j")}).size
    with Progress(nodes * shear.sizes.get(FORCE, 1), enabled=progress, desc="index maps", unit="node") as bar:
        maps = map_indices(matrix, shear, seed=seed, progress=bar.update)
    for result in (indices, maps):
        result.attrs.update(study_name=study_name, run_key=_run_key(out))
    if "k_max" in qois.attrs:
        indices.attrs["line_k_max"] = qois.attrs["k_max"]
    return out.write_dataset(INDICES_FILE, indices), out.write_dataset(MAPS_FILE, maps)


def open_sensitivity(output_dir) -> tuple[xr.Dataset, xr.Dataset] | None:
    """(QoI indices, node-shear index maps) of a sensitivity run in ``output_dir`` (a run
    folder or store URL), loaded; None if the run holds no sensitivity results."""
    indices = at(output_dir).read_dataset(INDICES_FILE)
    return None if indices is None else (indices, at(output_dir).read_dataset(MAPS_FILE))


def run_design(study, *, output_dir=None, scheduler: str | None = None, workers: int | None = None,
               progress: bool = True, drape=None, rare=None) -> Path:
    """Run the [design] of a study (a ``Study`` or a study file's path): write
    ``design.nc`` and the per-design records into the output folder or store URL (default
    the study's; resumes from the records of an earlier run of the same study) and return
    it. ``drape`` is the task that drapes one chunk of one design (default
    ``uqdrape.design.drape_design``), ``rare`` estimates a ``[design] rare`` constraint of one
    design (default ``uqdrape.workflow.rare.design_rare``; a test passes synthetic ones
    through the same pipeline)."""
    from ..design import DESIGN_FILE, Evaluator, drape_design, optimise, problem, result_dataset
    from ..ensemble import local_pool, reach_scheduler
    from .preflight import check_placement, check_resources
    from .rare import design_rare

    drape, rare = drape or drape_design, rare or design_rare
    start = time.perf_counter()
    study = study if isinstance(study, Study) else load_study(study)
    if study.design is None:
        raise ValueError(f"study {study.name!r} ({study.path}) has no [design] section; run it with `uqdrape run`")
    prob = problem(study)
    out = at(study.output_dir if output_dir is None else output_dir)
    check_resources(study, out, 0)  # a design's records are per-drape numbers and node sums, not nets
    check_placement(study, quiet=not progress)
    reach_scheduler(scheduler)
    local = scheduler in (None, "processes")
    # one pool for the whole run: a design is many small batches, and starting worker
    # processes for each would cost more than draping it; one run at a time in the folder
    with out.lock(), local_pool(workers) if local else contextlib.nullcontext() as pool:
        evaluate = Evaluator(prob, out, scheduler=scheduler, workers=workers, progress=progress, drape=drape,
                             pool=pool, rare=rare)
        result = optimise(prob, evaluate)
        ds = result_dataset(result, evaluate)
        # this run's own time: a resumed run replays earlier designs from their records
        ds.attrs["wall_time_s"] = round(time.perf_counter() - start, 1)
        ds.attrs["designs_kept"], ds.attrs["designs_draped"] = evaluate.kept, evaluate.draped
        out.write_dataset(DESIGN_FILE, ds)
    if progress:
        print(f"{study.name}: {ds.attrs['summary']}", file=sys.stderr)
    return out.target


def run_report(output_dir, out_dir=None, formats=()) -> Path | str:
    """Report of a finished run (a run folder or a store URL): the ensemble with the title
    (the study's name), description, study text, histogram nodes and experimental CSV of
    the study stored in its attributes, the wall time from its manifest, and its
    sensitivity results if it has them; of a design run, its design page. Writes into
    the local folder ``out_dir`` (default: the run's ``report/``, in a store put under its
    URL), its figures also in the vector ``formats`` (svg, pdf) beside the PNGs; returns
    the index.html path (a URL in a store)."""
    from ..design import DESIGN_FILE
    from ..ensemble import open_ensemble
    from ..report import write_design_report, write_laminate_report, write_report
    from .rare import read_rare
    from .twin import hierarchical_summary

    if out_dir is None:
        where = at(output_dir)
        with where.writing("report") as folder:
            index = run_report(output_dir, folder, formats)
        return where.path_of(f"report/{index.relative_to(folder).as_posix()}")
    design = at(output_dir).read_dataset(DESIGN_FILE)
    ds = open_ensemble(output_dir) if design is None else design
    study = from_dict(json.loads(ds.attrs["study_json"]), Path(at(output_dir).name))
    report = Path(out_dir)
    if design is not None:
        return write_design_report(ds, report, surface=study.geometry.build_mould(), formats=formats)
    manifest = read_manifest(output_dir)
    if study.plies:
        return write_laminate_report(ds, report, title=study.name, description=study.description or None,
                                     study_text=ds.attrs.get("study_toml"), wall_time_s=manifest.get("wall_time_s"),
                                     formats=formats)
    sensitivity = open_sensitivity(output_dir)
    target = manifest.get("target") or {}  # a target run: what stopped it, for the page's attributes
    ds.attrs.update({f"target_{k}": v for k, v in target.items() if k not in ("forces", "rounds")})
    if target:
        ds.attrs["target_rounds"] = [r["realizations"] for r in target["rounds"]]
    return write_report(ds, report, title=study.name, summary=hierarchical_summary(study, ds, output_dir),
                        description=study.description or None, study_text=ds.attrs.get("study_toml"),
                        histogram_nodes=list(study.report.histogram_nodes) or None,
                        experimental_csv=study.report.experimental_csv,
                        wall_time_s=manifest.get("wall_time_s"),
                        replicates=study.sampling.randomizations if study.sampling.plan == "rqmc" else None,
                        formats=formats,
                        rare=read_rare(from_dict(manifest["study"], Path(output_dir)), output_dir),
                        **({} if sensitivity is None else dict(zip(("sensitivity", "sensitivity_maps"), sensitivity))))


def design_outcome(out) -> str:
    """What ``uqdrape design`` did to ``out`` (a folder or store URL): designs draped, or how
    many a resume kept."""
    from ..design import DESIGN_FILE, EVALUATIONS

    attrs = at(out).read_dataset(DESIGN_FILE).attrs
    kept, draped = int(attrs.get("designs_kept", 0)), int(attrs.get("designs_draped", 0))
    if not kept:
        return f"designs written to {out}: {draped} designs draped"
    return (f"resumed: {kept} of {kept + draped} designs kept from {EVALUATIONS}/, {draped} draped; "
            f"designs in {out}")


def run_outcome(out: Path) -> str:
    """What ``uqdrape run`` did to ``out``: chunks drawn, or how many of them a resume kept;
    a second line for its fixed-parameter twin if it has one."""
    from .twin import twin_location

    twin = twin_location(out)
    if read_manifest(twin) is not None:
        return f"{_outcome(out)}\nfixed-parameter twin: {_outcome(twin)}"
    return _outcome(out)


def _outcome(out) -> str:
    """:func:`run_outcome` of one run folder or store."""
    call = (read_manifest(out) or {}).get("last_call")
    if not isinstance(call, dict):  # a target study's rounds or a sensitivity run without the record
        return f"ensemble written to {out}"
    total, drawn, damaged = call.get("chunks", 0), call.get("drawn", 0), call.get("damaged", 0)
    if drawn == total:
        return f"ensemble written to {out}: {total} chunks drawn"
    again = f" ({damaged} of them damaged, drawn again)" if damaged else ""
    return f"resumed: {total - drawn} of {total} chunks kept, {drawn} drawn{again}; ensemble in {out}"
