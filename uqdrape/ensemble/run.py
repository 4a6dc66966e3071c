"""``run_ensemble``: a study's ensemble as dask tasks, one netCDF file per chunk, resumable.

Realisations 0..N-1 are cut into consecutive chunks of ``chunk_size``; a sweep repeats
the same chunks at every blank-holder-force level with the same random inputs (common
random numbers, so differences between levels are not sampling noise). A chunk is one
batched drape run as one dask task, which writes its own file and returns only its path,
so memory stays bounded by a chunk per worker. Realisation r's inputs depend only on the
study (see ``inputs``), so results are identical for any chunk size, worker count and
scheduler.

The run is written to a location (``uqdrape.ensemble.location``: a run folder of netCDF
chunk files, or a zarr store on an fsspec URL), chosen once from the output path or URL
(``storage.at``); this one loop plans, locks, prepares and drapes it on either.

Resume: the run's manifest records the study (and, once the run is done, its wall time in
s, summed over resumed calls); a rerun of the same study skips chunks already written
(a folder's finished files, a store's regions marked done).

Extension: ``realizations`` is not part of the resume identity. A finished (or
interrupted) run resumed with more realisations keeps every chunk of its plan as it is,
the last partial one included, and adds chunks of ``chunk_size`` from where it stopped;
realisation r's inputs depend only on the study and r (under the plans of
``uqdrape.stochastic.sampling.EXTENDABLE_PLANS``), so the result is bitwise that of the larger run from the start.
Fewer realisations than a run holds, or another number under a plan whose points depend
on N (latin_hypercube, sobol), are refused.

Given a sample matrix (a sensitivity study's rows, ``uqdrape.sensitivity.sensitivity_sample``),
its rows are draped as realisations 0..n-1 instead of the Monte Carlo sample, through
the same chunks; what the outputs mean is not this package's business.
"""

from __future__ import annotations

import contextlib
import errno
import json
import sys
import time
from pathlib import Path

import dask
from dask.callbacks import Callback

from .._version import __version__
from ..files import read_text
from ..study import Study
from ..stochastic.inputs import positive_int
from .chunk import drape_chunk
from ..pool import local_pool
from .progress import Progress, announce_compiling
from .storage import at

#: dask schedulers in this process: a pool of local processes (default) or no
#: parallelism at all (for debugging). Anything with "://" is a dask.distributed address.
LOCAL_SCHEDULERS = ("processes", "synchronous")
#: How long to try to reach a dask.distributed scheduler (s).
SCHEDULER_TIMEOUT = 10


def _run_chunk(study: Study, where, chunk, level: int, attrs: dict, key: str | None, sample_rows=None) -> str:
    """Dask task: drape one chunk (its Monte Carlo realisations, or the given rows of a
    sensitivity sample) and write it to the run's location ``where`` with its checksum
    under the run's ``key``; return its name."""
    ds = drape_chunk(study, range(chunk.start, chunk.stop), chunk.force, sample_rows)
    return where.write_chunk(study, ds, chunk, level, attrs, key)


def reach_scheduler(scheduler: str | None) -> None:
    """Raise a one-line OSError unless ``scheduler`` is local or answers as a dask
    scheduler within ``SCHEDULER_TIMEOUT`` s. Runs call it before they touch their output
    folder, so a wrong address leaves nothing behind (distributed itself trusts a
    non-dask server's first bytes)."""
    if scheduler is None or scheduler in LOCAL_SCHEDULERS:
        return
    from .handshake import check_scheduler

    check_scheduler(scheduler, SCHEDULER_TIMEOUT)


def compute_tasks(tasks: list, sizes: list, scheduler: str | None, workers: int | None, progress: Progress,
                  pool=None) -> list:
    """Run dask tasks locally or on a dask.distributed cluster, counting each finished
    task's realisations (``sizes``) in ``progress``; return their results in task order and
    re-raise a failure. ``scheduler`` and ``workers`` as for :func:`run_ensemble`; ``pool``
    (a ``pool.local_pool``) keeps local workers alive across calls. A cluster address must
    have passed :func:`reach_scheduler` (a design calls this once per batch: one handshake a run)."""
    if not tasks:
        return []
    count = {task.key: size for task, size in zip(tasks, sizes)}
    if scheduler is None or scheduler in LOCAL_SCHEDULERS:
        def finished(key, result, dsk, state, worker_id):
            if key in count:
                progress.update(count[key], Path(result).name if isinstance(result, str) else None)

        with Callback(posttask=finished):
            if scheduler == "synchronous":
                return list(dask.compute(*tasks, scheduler="synchronous"))
            # dask batches local tasks (6 per dispatch by default); a chunk is already a
            # big batch, so dispatch one at a time or two chunks share one process
            with local_pool(workers) if pool is None else contextlib.nullcontext(pool) as pool:
                return list(dask.compute(*tasks, scheduler="processes", pool=pool, chunksize=1))
    from distributed import Client, as_completed

    try:  # the caller has run reach_scheduler before touching its folder (run_ensemble, run_design)
        client = Client(scheduler, timeout=SCHEDULER_TIMEOUT)
    except (OSError, TimeoutError) as err:
        raise OSError(errno.EHOSTUNREACH, f"cannot reach the dask scheduler within {SCHEDULER_TIMEOUT} s "
                      f"({type(err).__name__})", scheduler) from None
    with client:
        futures = client.compute(tasks)
        for future in as_completed(futures):
            result = future.result()
            progress.update(count[future.key], Path(result).name if isinstance(result, str) else None)
        return [future.result() for future in futures]


def run_ensemble(study: Study, *, sample_rows=None, output_dir=None, provenance: dict | None = None,
                 attrs: dict | None = None, scheduler: str | None = None, workers: int | None = None,
                 chunk_size: int | None = None, resume: bool = True, progress: bool = True,
                 verbose: bool = False, preflight=None) -> Path | str:
    """Drape a study's realisations into chunk files; return the output folder (open it
    with ``open_ensemble``). An fsspec URL as ``output_dir`` (or the study's) writes one
    zarr store there instead (``uqdrape.ensemble.zarrstore``) and returns the URL; a
    location (``storage.at``) is taken as it is.

    sample_rows  None: the study's own sample (``sampled_inputs``); else a sample matrix
                 of standard variables (``inputs_from_rows``), row k draped as realisation k
    output_dir   default: the study's [output] directory; a folder, or a store's URL
    provenance   the study record kept in the manifest and every chunk (default ``study.to_dict()``)
    attrs        further attributes of every chunk
    scheduler    None or "processes": a pool of local processes; "synchronous": in this
                 process; "tcp://host:port" (any "://" address): that dask.distributed cluster
    workers      local processes (default: one per CPU); not allowed with a cluster address
    chunk_size   realisations per chunk (one batched drape call); default: the study's
    resume       skip chunks already written by an earlier run of the same study, extending
                 it to more realisations; False deletes its chunks first
    progress     show progress on stderr: realisations done, rate and ETA (a bar on a
                 terminal, a plain line every 30 s elsewhere); ``verbose`` adds a line per chunk
    preflight    ``preflight(drapes, first, force)``, called before the output folder is
                 touched with the number of drapes still to write and the first of them
                 (realisation, force level): the application layer's checks of memory,
                 disk and placement (``uqdrape.workflow.preflight``); it raises to stop
                 the run

    Local worker processes are spawned and import the calling script, so a script needs
    the usual ``if __name__ == "__main__":`` guard. Cluster workers need uqdrape installed
    and must see the output folder (a shared file system).
    """
    start = time.perf_counter()
    chunk_size = study.chunk_size if chunk_size is None else positive_int("chunk_size", chunk_size)
    if scheduler is not None and not (isinstance(scheduler, str) and (scheduler in LOCAL_SCHEDULERS or "://" in scheduler)):
        raise ValueError(f"scheduler must be None, one of {LOCAL_SCHEDULERS} or a dask.distributed "
                         f"address such as 'tcp://host:8786', got {scheduler!r}")
    if workers is not None:
        workers = positive_int("workers", workers)
        if scheduler is not None and scheduler not in LOCAL_SCHEDULERS:
            raise ValueError(f"workers={workers} sets local processes; the cluster at {scheduler} has its own workers")
    where = at(study.output_dir if output_dir is None else output_dir).absolute()
    if where.refused_with(scheduler):
        raise ValueError(f"{where}: {where.refused_with(scheduler)}")
    provenance = study.to_dict() if provenance is None else provenance
    n = study.realizations if sample_rows is None else len(sample_rows)
    chunks, done = where.plan(study, provenance, chunk_size, n, resume)
    reach_scheduler(scheduler)
    todo = [c for c in chunks if c.name not in done]
    if preflight is not None and todo:
        preflight(sum(c.stop - c.start for c in todo), todo[0].start, todo[0].force)
    attrs = {"study_name": study.name, "study_seed": study.seed, "study_realizations": study.realizations,
             "sampling_plan": study.sampling.plan, "study_toml": read_text(study.path, "study file"),
             "study_json": json.dumps(provenance), **(attrs or {})}
    manifest = {"study": provenance, "chunk_size": chunk_size, "chunks": [c.name for c in chunks],
                "uqdrape_version": __version__}
    with where.lock():
        manifest, earlier, todo, damaged = where.prepare(study, chunks, manifest, resume, attrs, sample_rows)
        if damaged and progress:
            print(f"{study.name}: {len(damaged)} chunk file(s) damaged or not this run's, draped again: "
                  + ", ".join(c.name for c in damaged[:5]) + (", ..." if len(damaged) > 5 else ""), file=sys.stderr)
        if progress and len(todo) < len(chunks):
            print(f"{study.name}: {len(chunks) - len(todo)} of {len(chunks)} {where.parts} already done in {where}",
                  file=sys.stderr)
        announce_compiling(study.solver.mode, progress and bool(todo), prefix=f"{study.name}: ")
        levels = list(study.force_levels)
        run = dask.delayed(_run_chunk, pure=False)
        sizes = [c.stop - c.start for c in todo]
        total = sum(c.stop - c.start for c in chunks)
        bar = Progress(total, total - sum(sizes), enabled=progress, verbose=verbose, desc=study.name)
        try:
            compute_tasks([run(study, where, c, levels.index(c.force), attrs, manifest.get("checksum_key"),
                               None if sample_rows is None else sample_rows[c.start:c.stop]) for c in todo],
                          sizes, scheduler, workers, bar)
        finally:  # an interrupted or failed run's workers are gone: their unfinished files too
            bar.close()
            where.finish()
        # for the report's provenance: the time of the finished calls that made this run (an
        # interrupted call records nothing)
        where.write_manifest({**manifest, "wall_time_s": round(earlier + time.perf_counter() - start, 1),
                              "last_call": {"chunks": len(chunks), "drawn": len(todo), "damaged": len(damaged)}})
    return where.target
