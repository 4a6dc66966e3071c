"""``run_ensemble``: a study's ensemble as dask tasks, one netCDF file per chunk, resumable.

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

Extension: ``realizations`` is not part of the resume identity. A finished (or
interrupted) run resumed with more realisations keeps every chunk of its plan as it is,
the last partial one included, and adds chunks of ``chunk_size`` from where it stopped;
realisation r's inputs depend only on the study and r (under the plans of
``uqdrape.stochastic.sampling.EXTENDABLE_PLANS``), so the result is bitwise that of the larger run from the start.
Fewer realisations than a run holds, or another number under a plan whose points depend
on N (latin_hypercube, sobol), are refused.

Given a design matrix (a sensitivity study's rows, ``uqdrape.workflow.study_design``),
its rows are draped as realisations 0..n-1 instead of the Monte Carlo sample, through
the same chunks; what the outputs mean is not this package's business.
"""

from __future__ import annotations

import contextlib
import functools
import json
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import dask
import errno
import numpy as np
import xarray as xr
from dask.callbacks import Callback

from .. import __version__
from .. import geometry as _geometry
from ..conventions import cf_encode
from ..files import is_url, read_text
from ..schema import FORCE, REALIZATION, at_level
from ..study import Study, identity
from ..stochastic.inputs import positive_int
from ..stochastic.sampling import extension_problem
from .chunk import drape_inputs, write_atomic
from .inputs import inputs_from_design, sampled_inputs
from .hygiene import local_pool, orphaned, run_lock
from .progress import Progress
from .store import CHUNKS, read_manifest, write_manifest

#: dask schedulers in this process: a pool of local processes (default) or no
#: parallelism at all (for debugging). Anything with "://" is a dask.distributed address.
LOCAL_SCHEDULERS = ("processes", "synchronous")
#: How long to try to reach a dask.distributed scheduler (s).
SCHEDULER_TIMEOUT = 10


@dataclass(frozen=True)
class Chunk:
    """Realisations start..stop-1 at blank-holder force ``force`` (N); ``name`` its file's."""

    start: int
    stop: int
    force: float
    name: str


_RANGE = re.compile(r"r(\d{7})-(\d{7})\.nc$")


def plan_chunks(study: Study, chunk_size: int, realizations: int | None = None, kept=()) -> list[Chunk]:
    """The chunks of a study: consecutive ranges of its realisations (default
    ``study.realizations``; a sensitivity design's row count) at each force level, named
    ``r<first>-<last>.nc``, prefixed ``f<level>-`` in a sweep. ``kept``: the chunk names of
    an earlier run of the same study, whose ranges stay as they are (an extension); the
    realisations after them are cut into ``chunk_size`` pieces."""
    n = study.realizations if realizations is None else realizations
    ranges = sorted({tuple(int(v) for v in _RANGE.search(name).groups()) for name in kept})
    ranges = [(a, b + 1) for a, b in ranges]
    start = ranges[-1][1] if ranges else 0
    ranges += [(a, min(a + chunk_size, n)) for a in range(start, n, chunk_size)]
    levels = study.force_levels
    chunks = []
    for k, force in enumerate(levels):
        prefix = f"f{k:03d}-" if len(levels) > 1 else ""
        chunks += [Chunk(a, b, force, f"{prefix}r{a:07d}-{b - 1:07d}.nc") for a, b in ranges]
    return chunks


def _kept_chunks(out: Path, provenance: dict, study: Study, chunk_size: int, n: int, resume: bool) -> list[str]:
    """The chunk names of an earlier run in ``out`` of the same study (by ``identity``)
    that this one keeps: all of them, or none without one (or with resume False). Raises
    ValueError for another chunk size, fewer realisations than the run holds, or more
    under a plan that does not extend."""
    old = read_manifest(out) if resume else None
    if old is None or identity(old["study"]) != identity(provenance):
        return []  # nothing to keep; another study's folder is refused by _prepare
    held = max((int(_RANGE.search(name).group(2)) + 1 for name in old["chunks"]), default=0)
    check_growth(out, study, old["chunk_size"], held, chunk_size, n)
    return old["chunks"]


def check_growth(where, study: Study, old_chunk_size: int, held: int, chunk_size: int, n: int) -> None:
    """Raise ValueError (naming ``where``, a folder or a store) unless a run of ``held``
    realisations in chunks of ``old_chunk_size`` can be resumed as ``n`` in chunks of
    ``chunk_size``: the same chunk size, no fewer realisations, more only under a plan
    that extends."""
    if old_chunk_size != chunk_size:
        raise ValueError(
            f"{where} was run with --chunk-size {old_chunk_size}; resume with --chunk-size {old_chunk_size} "
            "or run again with --no-resume")
    if n < held:
        raise ValueError(f"{where} holds {held} realisations, more than the {n} asked for: set "
                         f"realizations >= {held} in [study], or run again with --no-resume")
    why = extension_problem(study.sampling, held, n) if n > held else None
    if why:
        raise ValueError(f"{where} holds {held} realisations and cannot be extended to {n}: {why}; "
                         "run again with --no-resume")


def _run_chunk(study: Study, chunk: Chunk, folder: str, attrs: dict, design_rows=None) -> str:
    """Dask task: drape one chunk (its Monte Carlo realisations, or the given rows of a
    sensitivity design), write its file, return the file's path."""
    ds = at_level(_drape(study, np.arange(chunk.start, chunk.stop), chunk.force, design_rows), chunk.force)
    ds.attrs.update(attrs)
    ds, encoding = cf_encode(ds, title=f"uqdrape ensemble chunk: study {study.name}, realisations "
                                       f"{chunk.start}-{chunk.stop - 1} at {chunk.force:g} N",
                             history=f"uqdrape run {Path(study.path).name}", float32=study.float32)
    return str(write_atomic(ds, Path(folder) / chunk.name, encoding, keep=lambda: not orphaned()))


def chunk_intact(path: Path, chunk: Chunk) -> bool:
    """Whether ``path`` is the finished chunk ``chunk``: a netCDF file that opens, holds the
    node shear and exactly the chunk's realisations at its force level. Reads only the
    file's metadata and two coordinates."""
    try:
        with xr.open_dataset(path, engine="netcdf4", decode_cf=False) as ds:
            return ("shear" in ds.variables and FORCE in ds.variables and REALIZATION in ds.variables
                    and ds[FORCE].values.tolist() == [chunk.force]
                    and ds[REALIZATION].values.tolist() == list(range(chunk.start, chunk.stop)))
    except (OSError, ValueError, KeyError, RuntimeError, AttributeError):  # netCDF4's for an unreadable attribute
        return False


@functools.lru_cache(maxsize=2)
def _mould(kind: str, params: str, stamp):
    """A mould built once per process (``stamp``: the version of the file it reads), so a
    mesh tool is read and packed once, not for every chunk."""
    return _geometry.build(kind, **json.loads(params))


def _study_mould(study: Study):
    """The study's mould from the process's cache (``_mould``), keyed by its parameters and,
    for a mould read from a file, the file's modification time and size."""
    g = study.geometry
    path = g.params.get("path")
    stat = Path(path).stat() if path is not None else None
    return _mould(g.kind, json.dumps(g.params, sort_keys=True), stat and (stat.st_mtime_ns, stat.st_size))


def _drape(study: Study, r, force: float, design_rows):
    """Drape realisations ``r`` of the study's sample, or the design rows ``design_rows`` (one per r)."""
    inputs = sampled_inputs(study, r) if design_rows is None else inputs_from_design(study, design_rows)
    return drape_inputs(study, r, inputs, force=force, surface=_study_mould(study))


def _prepare(out: Path, manifest: dict, resume: bool) -> None:
    """Check a previous run in ``out`` can be resumed, or clear it; then record this run.
    Called under the folder's run lock, so a ``.part`` file here is a killed run's."""
    folder = out / CHUNKS
    old = read_manifest(out) if resume else None
    for path in folder.glob("*.nc.part"):
        path.unlink()
    if not resume:
        for path in folder.glob("*.nc"):
            path.unlink()
    elif old is None:
        if any(folder.glob("*.nc")):
            raise ValueError(f"{folder} holds chunk files but {out} has no run manifest; "
                             "they cannot be checked against this study: run again with --no-resume")
    else:
        before, now = identity(old["study"]), identity(manifest["study"])
        if before != now:
            changed = sorted(f"{section}.{key}" for section in set(before) | set(now)
                             for key in set(before.get(section, {})) | set(now.get(section, {}))
                             if before.get(section, {}).get(key) != now.get(section, {}).get(key))
            raise ValueError(
                f"{out} holds a run of a different study definition (changed: {', '.join(changed)}); "
                "run again with --no-resume to replace it, or set another [output] directory")
    folder.mkdir(parents=True, exist_ok=True)
    write_manifest(out, manifest)


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
    (a ``hygiene.local_pool``) keeps local workers alive across calls. A cluster address must
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


def run_ensemble(study: Study, *, design_rows=None, output_dir=None, provenance: dict | None = None,
                 attrs: dict | None = None, scheduler: str | None = None, workers: int | None = None,
                 chunk_size: int | None = None, resume: bool = True, progress: bool = True,
                 verbose: bool = False, preflight=None) -> Path | str:
    """Drape a study's realisations into chunk files; return the output folder (open it
    with ``open_ensemble``). An fsspec URL as ``output_dir`` (or the study's) writes one
    zarr store there instead (``uqdrape.ensemble.zarrstore``) and returns the URL.

    design_rows  None: the study's own sample (``sampled_inputs``); else a design matrix
                 of standard variables (``inputs_from_design``), row k draped as realisation k
    output_dir   default: the study's [output] directory; a folder, or a store's URL
    provenance   the study record kept in the manifest and every chunk (default ``study.to_dict()``)
    attrs        further attributes of every chunk
    scheduler    None or "processes": a pool of local processes; "synchronous": in this
                 process; "tcp://host:port" (any "://" address): that dask.distributed cluster
    workers      local processes (default: one per CPU); not allowed with a cluster address
    chunk_size   realisations per chunk (one batched drape call); default: the study's
    resume       skip chunks already written by an earlier run of the same study; False
                 deletes the folder's chunk files first
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
    from .zarrstore import run_store

    output_dir = study.output_dir if output_dir is None else output_dir
    if is_url(output_dir):  # one zarr store by fsspec URL (issue 28)
        return run_store(study, output_dir, design_rows=design_rows, provenance=provenance, attrs=attrs,
                         scheduler=scheduler, workers=workers, chunk_size=chunk_size, resume=resume,
                         progress=progress, preflight=preflight)
    out = Path(output_dir).absolute()
    provenance = study.to_dict() if provenance is None else provenance
    n = study.realizations if design_rows is None else len(design_rows)
    chunks = plan_chunks(study, chunk_size, n, _kept_chunks(out, provenance, study, chunk_size, n, resume))
    manifest = {"study": provenance, "chunk_size": chunk_size, "chunks": [c.name for c in chunks],
                "uqdrape_version": __version__}
    reach_scheduler(scheduler)
    if preflight is not None:
        done = {p.name for p in (out / CHUNKS).glob("*.nc")} if resume else set()
        todo = [c for c in chunks if c.name not in done]
        if todo:
            preflight(sum(c.stop - c.start for c in todo), todo[0].start, todo[0].force)
    with run_lock(out):
        earlier = (read_manifest(out) or {}).get("wall_time_s", 0.0) if resume else 0.0
        _prepare(out, manifest, resume)
        folder = out / CHUNKS
        damaged = [c for c in chunks if (folder / c.name).is_file() and not chunk_intact(folder / c.name, c)]
        for c in damaged:  # a truncated, swapped or foreign file: drape it again
            (folder / c.name).unlink()
        if damaged and progress:
            print(f"{study.name}: {len(damaged)} chunk file(s) damaged or not this run's, draped again: "
                  + ", ".join(c.name for c in damaged[:5]) + (", ..." if len(damaged) > 5 else ""), file=sys.stderr)
        todo = [c for c in chunks if not (folder / c.name).is_file()]
        try:
            _drape_chunks(study, chunks, todo, folder, provenance, attrs, design_rows, scheduler, workers,
                          progress, verbose)
        finally:  # an interrupted or failed run's workers are gone: their unfinished files too
            for part in folder.glob("*.nc.part"):
                part.unlink(missing_ok=True)
        # for the report's provenance: the time of the finished calls that made this run (an
        # interrupted call records nothing)
        write_manifest(out, {**manifest, "wall_time_s": round(earlier + time.perf_counter() - start, 1),
                             "last_call": {"chunks": len(chunks), "drawn": len(todo), "damaged": len(damaged)}})
    return out


def _drape_chunks(study, chunks, todo, folder, provenance, attrs, design_rows, scheduler, workers, progress,
                  verbose) -> None:
    """Drape the chunks ``todo`` of ``chunks`` into ``folder``, with a progress count."""
    if progress and len(todo) < len(chunks):
        print(f"{study.name}: {len(chunks) - len(todo)} of {len(chunks)} chunks already done in {folder}",
              file=sys.stderr)
    attrs = {"study_name": study.name, "study_seed": study.seed, "study_realizations": study.realizations,
             "sampling_plan": study.sampling.plan, "study_toml": read_text(study.path, "study file"),
             "study_json": json.dumps(provenance), **(attrs or {})}
    run = dask.delayed(_run_chunk, pure=False)
    sizes = [c.stop - c.start for c in chunks]
    bar = Progress(sum(sizes), sum(sizes) - sum(c.stop - c.start for c in todo), enabled=progress, verbose=verbose,
                   desc=study.name)
    try:
        compute_tasks([run(study, c, str(folder), attrs, None if design_rows is None else design_rows[c.start:c.stop])
                  for c in todo], [c.stop - c.start for c in todo], scheduler, workers, bar)
    finally:
        bar.close()
