"""``run_study``: a study's ensemble as dask tasks, one netCDF file per chunk, resumable.

Realisations 0..N-1 are cut into consecutive chunks of ``chunk_size``; a sweep repeats
the same chunks at every blank-holder-force level with the same random inputs (common
random numbers, so differences between levels are not sampling noise). A chunk is one
batched drape run as one dask task, which writes its own file and returns only its path,
so memory stays bounded by a chunk per worker. Realisation r's inputs depend only on the
study (see ``inputs``), so results are identical for any chunk size, worker count and
scheduler.

Resume: the run folder's manifest records the study (and, once the run is done, its wall
time in s, summed over resumed calls); a rerun of the same study skips
chunks whose final file exists (a ``.part`` file is an unfinished chunk and is redone).

A sensitivity study (``[sensitivity] method`` sobol/morris) drapes the rows of its SALib
design (``uqdrape.sensitivity.study_design``) as realisations 0..n-1 instead of the
Monte Carlo sample, through the same chunks, and is analysed once all chunks exist
(``uqdrape.sensitivity.write_sensitivity``).
"""

from __future__ import annotations

import contextlib
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import dask
import numpy as np
from dask.diagnostics import ProgressBar
from tqdm import tqdm

from .. import __version__
from ..study import SENSITIVITY_METHODS, Study, load_study
from .chunk import drape_inputs, write_atomic
from .inputs import inputs_from_design, sampled_inputs
from .store import CHUNKS, read_manifest, write_manifest

#: dask schedulers in this process: a pool of local processes (default) or no
#: parallelism at all (for debugging). Anything with "://" is a dask.distributed address.
LOCAL_SCHEDULERS = ("processes", "synchronous")


@dataclass(frozen=True)
class Chunk:
    """Realisations start..stop-1 at force level ``level`` (index into the sweep, else None)."""

    start: int
    stop: int
    level: int | None = None
    force: float | None = None

    @property
    def name(self) -> str:
        prefix = "" if self.level is None else f"f{self.level:03d}-"
        return f"{prefix}r{self.start:07d}-{self.stop - 1:07d}.nc"


def plan_chunks(study: Study, chunk_size: int, realizations: int | None = None) -> list[Chunk]:
    """The chunks of a study: consecutive ranges of its realisations (default
    ``study.realizations``; a sensitivity design's row count), for each force level of a sweep."""
    n = study.realizations if realizations is None else realizations
    ranges = [(a, min(a + chunk_size, n)) for a in range(0, n, chunk_size)]
    if not study.is_sweep:
        return [Chunk(a, b) for a, b in ranges]
    return [Chunk(a, b, k, f) for k, f in enumerate(study.force_levels) for a, b in ranges]


def _run_chunk(study: Study, chunk: Chunk, folder: str, attrs: dict, design_rows=None) -> str:
    """Dask task: drape one chunk (its Monte Carlo realisations, or the given rows of a
    sensitivity design), write its file, return the file's path."""
    r = np.arange(chunk.start, chunk.stop)
    inputs = sampled_inputs(study, r) if design_rows is None else inputs_from_design(study, design_rows)
    ds = drape_inputs(study, r, inputs, force=chunk.force)
    ds.attrs.update(attrs)
    return str(write_atomic(ds, Path(folder) / chunk.name))


def _positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def _identity(manifest: dict) -> dict:
    """What must match for chunks to be reused: the study without its chunk size."""
    study = json.loads(json.dumps(manifest["study"]))
    study["study"].pop("chunk_size", None)
    return study


def _prepare(out: Path, manifest: dict, resume: bool) -> None:
    """Check a previous run in ``out`` can be resumed, or clear it; then record this run."""
    folder = out / CHUNKS
    old = read_manifest(out)
    if not resume:
        for pattern in ("*.nc", "*.nc.part"):
            for path in folder.glob(pattern):
                path.unlink()
    elif old is None:
        if any(folder.glob("*.nc")):
            raise ValueError(f"{folder} holds chunk files but {out} has no run manifest; "
                             "they cannot be checked against this study: run with resume=False (--no-resume)")
    else:
        before, now = _identity(old), _identity(manifest)
        if before != now:
            changed = sorted(f"{section}.{key}" for section in set(before) | set(now)
                             for key in set(before.get(section, {})) | set(now.get(section, {}))
                             if before.get(section, {}).get(key) != now.get(section, {}).get(key))
            raise ValueError(
                f"{out} holds a run of a different study definition (changed: {', '.join(changed)}); "
                "run with resume=False (--no-resume) to replace it, or set another [output] directory")
        if old["chunks"] != manifest["chunks"]:
            raise ValueError(
                f"{out} was run with chunk_size={old['chunk_size']}; resume with chunk_size={old['chunk_size']} "
                "or run with resume=False (--no-resume)")
    folder.mkdir(parents=True, exist_ok=True)
    write_manifest(out, manifest)


def _compute(tasks: list, scheduler: str | None, workers: int | None, progress: bool) -> None:
    """Run the chunk tasks locally or on a dask.distributed cluster; re-raise a failure."""
    if not tasks:
        return
    if scheduler is None or scheduler in LOCAL_SCHEDULERS:
        options = {"scheduler": scheduler or "processes"}
        if options["scheduler"] == "processes":
            # dask batches local tasks (6 per dispatch by default); a chunk is already a
            # big batch, so dispatch one at a time or two chunks share one process
            options["chunksize"] = 1
        if workers is not None:
            options["num_workers"] = workers
        bar = ProgressBar(minimum=1.0, dt=1.0, out=sys.stderr) if progress else contextlib.nullcontext()
        with bar:
            dask.compute(*tasks, **options)
        return
    from distributed import Client, as_completed

    with Client(scheduler) as client:
        futures = client.compute(tasks)
        for future in tqdm(as_completed(futures), total=len(futures), desc="chunks",
                           file=sys.stderr, disable=not progress):
            future.result()


def run_study(study, *, scheduler: str | None = None, workers: int | None = None,
              chunk_size: int | None = None, resume: bool = True, progress: bool = True,
              method: str | None = None) -> Path:
    """Run a study's ensemble; return its output folder (open it with ``open_ensemble``).

    study       a ``Study`` or the path of a study TOML file
    scheduler   None or "processes": a pool of local processes; "synchronous": in this
                process; "tcp://host:port" (any "://" address): that dask.distributed cluster
    workers     local processes (default: one per CPU); not allowed with a cluster address
    chunk_size  realisations per chunk (one batched drape call); default: the study's
    resume      skip chunks already written by an earlier run of the same study; False
                deletes the folder's chunk files first
    progress    show a progress bar (stderr)
    method      None: the study's [sensitivity] method; "sobol" / "morris": drape that SALib
                design and write sensitivity.nc; "none": the Monte Carlo sample. Another
                method than the study's writes to ``<output_dir>-<method>``.

    Local worker processes are spawned and import the calling script, so a script needs
    the usual ``if __name__ == "__main__":`` guard. Cluster workers need uqdrape installed
    and must see the output folder (a shared file system).
    """
    start = time.perf_counter()
    study = study if isinstance(study, Study) else load_study(study)
    chunk_size = study.chunk_size if chunk_size is None else _positive_int("chunk_size", chunk_size)
    if scheduler is not None and not (isinstance(scheduler, str) and (scheduler in LOCAL_SCHEDULERS or "://" in scheduler)):
        raise ValueError(f"scheduler must be None, one of {LOCAL_SCHEDULERS} or a dask.distributed "
                         f"address such as 'tcp://host:8786', got {scheduler!r}")
    if workers is not None:
        workers = _positive_int("workers", workers)
        if scheduler is not None and scheduler not in LOCAL_SCHEDULERS:
            raise ValueError(f"workers={workers} sets local processes; the cluster at {scheduler} has its own workers")

    method = study.sensitivity.method if method is None else method
    if method not in SENSITIVITY_METHODS:
        raise ValueError(f"method must be None or one of {SENSITIVITY_METHODS}, got {method!r}")
    design = None
    if method != "none":
        from ..sensitivity import study_design  # SALib: imported only for a sensitivity run

        design = study_design(study, method)

    out = study.output_dir.absolute()
    provenance = study.to_dict()
    if method != study.sensitivity.method:
        out = out.with_name(f"{out.name}-{method}")
        provenance["sensitivity"]["method"] = method
        provenance["sensitivity"].pop("base_samples", None)
    if design is not None:
        provenance["sensitivity"]["base_samples"] = design.meta["base_samples"]
    chunks = plan_chunks(study, chunk_size, None if design is None else design.n_evaluations)
    manifest = {"study": provenance, "chunk_size": chunk_size, "chunks": [c.name for c in chunks],
                "uqdrape_version": __version__}
    earlier = (read_manifest(out) or {}).get("wall_time_s", 0.0) if resume else 0.0
    _prepare(out, manifest, resume)

    folder = out / CHUNKS
    todo = [c for c in chunks if not (folder / c.name).is_file()]
    if progress and len(todo) < len(chunks):
        print(f"{study.name}: {len(chunks) - len(todo)} of {len(chunks)} chunks already done in {folder}",
              file=sys.stderr)
    attrs = {"study_name": study.name, "study_seed": study.seed, "study_realizations": study.realizations,
             "sampling_plan": study.sampling.plan, "study_toml": Path(study.path).read_text(encoding="utf-8"),
             "study_json": json.dumps(provenance)}
    if design is not None:
        attrs.update(design_method=design.method, design_base_samples=design.meta["base_samples"],
                     design_evaluations=design.n_evaluations)
    run = dask.delayed(_run_chunk, pure=False)
    _compute([run(study, c, str(folder), attrs, None if design is None else design.standard[c.start:c.stop])
              for c in todo], scheduler, workers, progress)
    if design is not None:
        from ..sensitivity import write_sensitivity

        if progress:
            print(f"{study.name}: analysing {design.method} indices of {design.n_evaluations} evaluations"
                  + (f" at {len(study.force_levels)} force levels" if study.is_sweep else ""), file=sys.stderr)
        write_sensitivity(out, design, qoi=study.sensitivity.qoi, seed=study.seed)
    # for the report's provenance: the time of the finished calls that made this run (an
    # interrupted call records nothing)
    write_manifest(out, {**manifest, "wall_time_s": round(earlier + time.perf_counter() - start, 1)})
    return out
