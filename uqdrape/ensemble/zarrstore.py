"""An ensemble as one chunked zarr store on any fsspec URL (issue 28).

Selected by a URL (anything with ``://``: ``file:///abs/path``, ``memory://name``,
``s3://bucket/prefix``), as ``--out`` or ``[output] directory``. Decided: a plain path
stays a run folder of netCDF chunks (``uqdrape.ensemble.store``), the default, and old
run folders are read, not refused: every reader takes either
(``uqdrape.ensemble.location``). Layout under the URL::

    run.json        the manifest: study record, chunk size, chunk names, realisations;
                    written as run.json.part, then moved over the old one
    run.lock        one writer at a time: created with exclusive create ("xb": on S3 a
                    conditional put, If-None-Match: *), removed when the run ends; a
                    lock whose process is gone from this host is taken over
    data/           the zarr store (zarr format 3), the ensemble in the layout of
                    ``open_ensemble``: (blankholder_force, realization, ...), zarr
                    chunks of (1, chunk_size, full node grid)
    done/<chunk>    a region's "done" marker, written after its data
    sensitivity.nc, sensitivity_maps.nc, report/, export/
                    as in a run folder, each file put whole (:func:`publish`)

The template (every variable's shape, dtype and attributes, no data) is written once
with ``compute=False``; each dask task drapes its chunk and writes its region of
``data/`` from the worker, then its marker; only the marker's name comes back. Resume
redoes the regions without a marker (a killed writer's half-written region is never
read as done; a retried task writes the same bytes again).

Regions are always the whole-chunk plan of the run's realisations (r0-r(c-1), rc-...,
the last one partial), so every zarr chunk has one writer. Extension (more
realisations, a target round) resizes every array along ``realization`` and keeps the
done regions of that plan; a last region that was partial is drawn again whole with the
realisations that fill its zarr chunk (two writers of one zarr chunk could lose each
other's bytes). Credentials and endpoints come from the environment / fsspec config
(for S3: ``AWS_ACCESS_KEY_ID``, ``AWS_SECRET_ACCESS_KEY``, ``AWS_ENDPOINT_URL``), never
from the study file.
"""

from __future__ import annotations

import contextlib
import errno
import json
import sys
import time
from pathlib import Path

import dask
import dask.array
import numpy as np
import xarray as xr

from .. import __version__
from ..conventions import cf_decode, cf_encode
from ..files import read_text
from ..schema import FORCE, REALIZATION, at_level
from ..study import Study, identity
from ..stochastic.inputs import positive_int
from .chunk import drape_inputs
from .hygiene import lock_owner, lock_record, stale
from .inputs import inputs_from_design, sampled_inputs
from .progress import Progress
from .store import MAX_MANIFEST_BYTES, corrupt_manifest, parse_manifest

MANIFEST = "run.json"
LOCK = "run.lock"
#: the object ``check_store`` puts and removes to learn that a store takes writes
PROBE = ".uqdrape-probe"
DATA = "data"
DONE = "done"
#: zarr on-disk format written (zarr-python >= 3 writes format 3).
ZARR_FORMAT = 3
#: encoding keys of ``cf_encode`` that mean the same in zarr (netCDF's zlib/complevel do not).
_KEPT = ("dtype", "_FillValue", "units", "calendar")


def _fs(url: str):
    """(filesystem, root path) of ``url``; OSError (one line, exit 3) for a URL fsspec
    cannot open (an unknown protocol, a missing optional package)."""
    import fsspec

    try:
        fs, root = fsspec.core.url_to_fs(url, **_options(url))
    except (ValueError, ImportError) as err:
        raise OSError(errno.EINVAL, f"not a store URL fsspec can open ({err}); use file:///path, memory://name "
                                    "or s3://bucket/prefix", url) from None
    fs.invalidate_cache()  # fsspec instances are shared and cache listings; other processes write the store
    return fs, root.rstrip("/")


def _options(url: str) -> dict:
    """fsspec storage options of ``url``: a local folder makes its subfolders as needed."""
    return {"auto_mkdir": True} if url.startswith("file://") else {}


def _check_reachable(fs, root: str, url: str) -> None:
    """OSError naming ``url`` if its bucket (the first path part) is missing or the
    credentials are refused, before anything is written."""
    bucket = root.split("/")[0]
    if fs.protocol in ("s3", "s3a") or "s3" in (fs.protocol if isinstance(fs.protocol, tuple) else ()):
        try:
            fs.ls(bucket, refresh=True)
        except FileNotFoundError:
            # not ENOENT: that is a FileNotFoundError, a user's missing input (exit 2); a store fault is exit 3
            raise OSError(errno.EIO, f"bucket {bucket!r} does not exist; create it first", url) from None
        except PermissionError as err:
            raise OSError(errno.EACCES, f"access refused ({err}); set AWS_ACCESS_KEY_ID / AWS_SECRET_ACCESS_KEY",
                          url) from None
        except Exception as err:  # botocore's NoCredentialsError, an unreachable endpoint
            raise OSError(errno.EIO, f"cannot reach the store ({type(err).__name__}: {err}); check "
                          "AWS_ENDPOINT_URL and the credentials in the environment", url) from None


def check_store(url: str) -> None:
    """Raise a one-line OSError naming ``url`` unless a run can write there: fsspec opens
    the URL, an S3 bucket exists and takes the credentials, and a probe object can be
    written and removed (a read-only or full bucket). The probe has one name for every
    process (``PROBE``), so one left by a process killed while probing is overwritten
    and removed by the next probe, never piled up. A file:// store is a local folder:
    the preflight checks it as one (``uqdrape.workflow.preflight``)."""
    fs, root = _fs(url)
    _check_reachable(fs, root, url)
    if url.startswith("file://"):
        return
    with _writing(url, "a probe object"):
        fs.pipe_file(f"{root}/{PROBE}", b"probe\n")
        with contextlib.suppress(FileNotFoundError):  # another process's probe removed it
            fs.rm(f"{root}/{PROBE}")


def read_store_manifest(url: str) -> dict | None:
    """The manifest of the store at ``url``, or None if there is none (checked as
    ``store.read_manifest`` checks a folder's, and its ``realizations`` a count); OSError
    (one line) for a missing bucket or an unreachable store (``_check_reachable``)."""
    fs, root = _fs(url)
    _check_reachable(fs, root, url)
    where = f"{url}/{MANIFEST}"
    try:  # its size first: a read of the limit's length would allocate the limit (64 MB) every time
        if fs.size(f"{root}/{MANIFEST}") > MAX_MANIFEST_BYTES:
            raise corrupt_manifest(where, f"larger than {MAX_MANIFEST_BYTES // 2**20} MB")
        text = fs.cat_file(f"{root}/{MANIFEST}")
    except FileNotFoundError:
        return None
    manifest = parse_manifest(text, where)
    held = manifest.get("realizations")
    if isinstance(held, bool) or not isinstance(held, int) or held < 1:
        raise corrupt_manifest(where, '"realizations" must be a positive integer')
    return manifest


def write_store_manifest(url: str, manifest: dict) -> None:
    """Write the manifest of the store at ``url`` whole: put as ``run.json.part``, then
    moved over the old one (a rename on a local disk; on an object store a put is whole
    anyway), so a failed or killed write leaves the old manifest (the part is removed
    on a failure that returns)."""
    fs, root = _fs(url)
    part = f"{root}/{MANIFEST}.part"
    try:
        fs.pipe_file(part, json.dumps(manifest, indent=1).encode())
    except BaseException:
        with contextlib.suppress(OSError):
            fs.rm(part)
        raise
    fs.mv(part, f"{root}/{MANIFEST}")


class _StoreLock:
    """``run.lock`` of a store, created with exclusive create: ``FileExistsError`` is
    another writer. A lock whose run was on this host and is gone (a SIGKILLed client) is
    taken over, as a run folder's (``hygiene.run_lock``); one from another host is
    never guessed about: the message says to delete it by hand."""

    def __init__(self, fs, root: str, url: str):
        self.fs, self.path, self.url = fs, f"{root}/{LOCK}", url

    def __enter__(self):
        self.fs.makedirs(self.path.rsplit("/", 1)[0], exist_ok=True)  # a no-op on object stores
        taken = False
        while True:
            try:
                with self.fs.open(self.path, "xb") as f:
                    f.write(json.dumps(lock_record()).encode())
                return self
            except FileExistsError:
                owner = self._owner()
            if owner is None or taken or not stale(owner):
                held = ("it is not a lock uqdrape wrote" if owner is None else
                        f"pid {owner['pid']} on {owner['host']}, started {owner['started']}")
                raise OSError(errno.EBUSY, f"another run holds {LOCK} of this store ({held}); wait for it, or "
                              f"delete {self.url}/{LOCK} if that run is certainly gone", self.url)
            self.fs.rm(self.path)  # its run on this host is gone
            taken = True

    def _owner(self) -> dict | None:
        try:
            return lock_owner(self.fs.cat_file(self.path))
        except OSError:
            return None

    def __exit__(self, *exc):
        self.fs.rm(self.path)


def store_lock(url: str) -> _StoreLock:
    """The run lock of the store at ``url`` (a context manager; OSError EBUSY if another
    run holds it), for runs that write there other than ``run_store`` (a design)."""
    fs, root = _fs(url)
    _check_reachable(fs, root, url)
    return _StoreLock(fs, root, url)


def _encoded(ds: xr.Dataset, study: Study, title: str) -> xr.Dataset:
    """``ds`` with its CF attributes and the zarr-valid part of ``cf_encode``'s encoding."""
    ds, encoding = cf_encode(ds, title=title, history=f"uqdrape run {study.path.name}", float32=study.float32)
    for name, var in ds.variables.items():
        kept = {k: v for k, v in var.encoding.items() if k in _KEPT}
        kept.update({k: v for k, v in encoding.get(name, {}).items() if k in _KEPT})
        var.encoding = kept
    return ds


def _drape(study: Study, r, force: float, design_rows) -> xr.Dataset:
    """Drape realisations ``r`` of the study's sample, or the design rows ``design_rows``."""
    inputs = sampled_inputs(study, r) if design_rows is None else inputs_from_design(study, design_rows)
    return drape_inputs(study, r, inputs, force=force)


def _region_task(study: Study, url: str, name: str, start: int, stop: int, level: int, force: float,
                 design_rows) -> str:
    """Dask task: drape realisations start..stop-1 at force level ``level`` (N ``force``),
    write them into their region of the store from this worker, then the region's marker.
    A failed write is one-line OSError naming the store (a full or read-only bucket)."""
    ds = at_level(_drape(study, np.arange(start, stop), force, design_rows), force)
    ds = _encoded(ds, study, title="")
    region = {FORCE: slice(level, level + 1), REALIZATION: slice(start, stop)}
    ds = ds.drop_vars([v for v, var in ds.variables.items() if not set(region) & set(var.dims)])
    ds.attrs = {}
    with _writing(url, f"region {name}"):
        ds.to_zarr(f"{url}/{DATA}", region=region, mode="r+", zarr_format=ZARR_FORMAT, consolidated=False,
                   storage_options=_options(url))
        fs, root = _fs(url)
        fs.pipe_file(f"{root}/{DONE}/{name}", b"done\n")  # after the data: a marker means the region is whole
    return name


@contextlib.contextmanager
def _writing(url: str, what: str):
    """An OSError raised writing ``what`` to the store at ``url`` (a read-only or full
    bucket, a lost connection) as one line naming both."""
    try:
        yield
    except OSError as err:
        cause = " ".join(str(err.strerror or err).split())
        raise OSError(err.errno or errno.EIO, f"cannot write {what} ({type(err).__name__}: {cause})", url) from None


def done_regions(url: str) -> set[str]:
    """The chunk names whose region of the store at ``url`` is marked done."""
    fs, root = _fs(url)
    try:
        return {p.rstrip("/").rsplit("/", 1)[-1] for p in fs.ls(f"{root}/{DONE}", detail=False)}
    except FileNotFoundError:
        return set()


def fetch(url: str, name: str, local) -> bool:
    """Copy the file ``name`` under the store at ``url`` to the local path ``local``;
    False if the store has no such file."""
    fs, root = _fs(url)
    _check_reachable(fs, root, url)
    Path(local).parent.mkdir(parents=True, exist_ok=True)  # else a missing folder here reads as no such file
    try:
        fs.get_file(f"{root}/{name}", str(local))
    except FileNotFoundError:
        return False
    return True


def publish(local, url: str, name: str) -> None:
    """Put the local file ``local`` under the store at ``url`` as ``name``, whole: it is
    uploaded as ``name.part`` and then moved (a rename on a local disk, a server-side
    copy on S3), so a reader never sees it half-written."""
    fs, root = _fs(url)
    fs.put_file(str(local), f"{root}/{name}.part")
    fs.mv(f"{root}/{name}.part", f"{root}/{name}")


def _kept_regions(url: str, study: Study, provenance: dict, chunk_size: int, n: int, chunks,
                  resume: bool) -> tuple[dict | None, set[str]]:
    """(manifest, done region names) of an earlier run at ``url`` of the same study that
    this one keeps: (None, empty) without one or with resume False. Raises ValueError for
    another study, or as ``run.check_growth``."""
    old = read_store_manifest(url) if resume else None
    if old is None:
        return None, set()
    if identity(old["study"]) != identity(provenance):
        raise ValueError(f"{url} holds a run of a different study definition; run again with --no-resume to "
                         "replace it, or set another --out")
    from .run import check_growth

    check_growth(url, study, old["chunk_size"], old["realizations"], chunk_size, n)
    return old, done_regions(url) & {c.name for c in chunks}


def run_store(study: Study, url: str, *, design_rows=None, provenance: dict | None = None, attrs: dict | None = None,
              scheduler: str | None = None, workers: int | None = None, chunk_size: int | None = None,
              resume: bool = True, progress: bool = True, preflight=None) -> str:
    """Drape a study's realisations into one zarr store at ``url``; return ``url``.

    Arguments as for ``run_ensemble``. ``resume`` keeps the regions marked done of an
    earlier run of the same study and chunk size, extending it to more realisations (see
    the module docstring), and drapes only the others; False writes the template afresh.
    Raises OSError (one line naming the URL) for a URL fsspec cannot open, a missing
    bucket, refused or missing credentials, another writer, a failed write."""
    from .run import compute_tasks, plan_chunks, reach_scheduler

    start = time.perf_counter()
    chunk_size = positive_int("chunk_size", study.chunk_size if chunk_size is None else chunk_size)
    provenance = study.to_dict() if provenance is None else provenance
    n = study.realizations if design_rows is None else len(design_rows)
    chunks = plan_chunks(study, chunk_size, n)
    check_store(url)
    fs, root = _fs(url)
    _, done = _kept_regions(url, study, provenance, chunk_size, n, chunks, resume)
    reach_scheduler(scheduler)
    todo = [c for c in chunks if c.name not in done]
    if preflight is not None and todo:
        preflight(sum(c.stop - c.start for c in todo), todo[0].start, todo[0].force)
    attrs_all = _run_attrs(study, provenance, attrs)
    title = (f"uqdrape ensemble: study {study.name}, {n} realisations at "
             + ", ".join(f"{f:g}" for f in study.force_levels) + " N")
    with _StoreLock(fs, root, url):
        old, done = _kept_regions(url, study, provenance, chunk_size, n, chunks, resume)  # as it is now
        manifest = {"study": provenance, "chunk_size": chunk_size, "chunks": [c.name for c in chunks],
                    "realizations": n, "zarr_format": ZARR_FORMAT, "uqdrape_version": __version__}
        with _writing(url, "the store's template"):
            if old is None:
                if fs.exists(f"{root}/{DONE}"):
                    fs.rm(f"{root}/{DONE}", recursive=True)
                _write_template(study, url, chunks, n, chunk_size, attrs_all, title, design_rows)
                write_store_manifest(url, manifest)
            else:
                for name in done_regions(url) - done:  # regions of the earlier plan that this one cuts anew
                    fs.rm(f"{root}/{DONE}/{name}")
                # the manifest first: a store killed while it grows reads as incomplete, not as the smaller run
                write_store_manifest(url, {**manifest, "wall_time_s": old.get("wall_time_s", 0.0)})
                _resize(url, n, {**attrs_all, "title": title})
        todo = [c for c in chunks if c.name not in done]
        if progress and done:
            print(f"{study.name}: {len(chunks) - len(todo)} of {len(chunks)} regions already done in {url}",
                  file=sys.stderr)
        levels = list(study.force_levels)
        run = dask.delayed(_region_task, pure=False)
        bar = Progress(n * len(levels), n * len(levels) - sum(c.stop - c.start for c in todo), enabled=progress,
                       desc=study.name)
        try:
            compute_tasks([run(study, url, c.name, c.start, c.stop, levels.index(c.force), c.force,
                               None if design_rows is None else design_rows[c.start:c.stop]) for c in todo],
                          [c.stop - c.start for c in todo], scheduler, workers, bar)
        finally:
            bar.close()
        earlier = old.get("wall_time_s", 0.0) if old else 0.0
        write_store_manifest(url, {**manifest, "wall_time_s": round(earlier + time.perf_counter() - start, 1),
                                   "last_call": {"chunks": len(chunks), "drawn": len(todo), "damaged": 0}})
    return url


def _resize(url: str, n: int, attrs: dict) -> None:
    """Grow (or, after a killed extension run again, set) every array of the store along
    ``realization`` to ``n``, write the realisation coordinate and the run's attributes.
    The new zarr chunks hold nothing until their regions are written."""
    import zarr

    group = zarr.open_group(f"{url}/{DATA}", mode="r+", zarr_format=ZARR_FORMAT,
                            storage_options=_options(url) or None)
    for _, array in group.arrays():
        dims = list(array.metadata.dimension_names or ())
        if REALIZATION in dims:
            shape = list(array.shape)
            shape[dims.index(REALIZATION)] = n
            if tuple(shape) != array.shape:
                array.resize(shape)
    coordinate = group[REALIZATION]
    coordinate[:] = np.arange(n, dtype=coordinate.dtype)
    group.attrs.update(attrs)


def _run_attrs(study: Study, provenance: dict, attrs: dict | None) -> dict:
    """The global attributes of a run (as ``run._drape_chunks`` gives every chunk)."""
    return {"study_name": study.name, "study_seed": study.seed, "study_realizations": study.realizations,
            "sampling_plan": study.sampling.plan, "study_toml": read_text(study.path, "study file"),
            "study_json": json.dumps(provenance), **(attrs or {})}


def _write_template(study, url, chunks, n, chunk_size, attrs, title, design_rows) -> None:
    """Write the store's metadata and index coordinates once (``compute=False``): every
    variable of a chunk, widened to all force levels and ``n`` realisations, no data.
    The structure is that of one realisation draped here."""
    first = chunks[0]
    one = at_level(_drape(study, np.arange(first.start, first.start + 1), first.force,
                          None if design_rows is None else design_rows[:1]), first.force)
    levels = np.asarray(study.force_levels, dtype=float)
    one.attrs.update(attrs)
    ds = _encoded(one, study, title=title)
    sizes = {**ds.sizes, FORCE: len(levels), REALIZATION: n}
    variables = {d: xr.Variable(d, values, ds[d].attrs, encoding=ds[d].encoding) for d, values in
                 ((FORCE, levels), (REALIZATION, np.arange(n, dtype=ds[REALIZATION].dtype)))}
    for name, var in ds.variables.items():
        if name in variables:
            continue
        if not {FORCE, REALIZATION} & set(var.dims):
            variables[name] = var
            continue
        chunks_ = tuple(1 if d == FORCE else chunk_size if d == REALIZATION else sizes[d] for d in var.dims)
        data = dask.array.zeros(tuple(sizes[d] for d in var.dims), dtype=var.dtype, chunks=chunks_)
        variables[name] = xr.Variable(var.dims, data, var.attrs, encoding={**var.encoding, "chunks": chunks_})
    template = xr.Dataset({k: v for k, v in variables.items() if k not in ds.coords},
                          coords={k: v for k, v in variables.items() if k in ds.coords}, attrs=ds.attrs)
    template.to_zarr(f"{url}/{DATA}", mode="w", compute=False, zarr_format=ZARR_FORMAT, consolidated=False,
                     storage_options=_options(url))


def open_store(url: str) -> xr.Dataset:
    """The ensemble in the store at ``url`` as a lazy (dask) Dataset, one dask chunk per
    region; FileNotFoundError naming the regions not yet done."""
    manifest = read_store_manifest(url)
    if manifest is None:
        raise FileNotFoundError(f"{url} holds no uqdrape run (no {MANIFEST}); run the study first")
    missing = [c for c in manifest["chunks"] if c not in done_regions(url)]
    if missing:
        raise FileNotFoundError(f"{url} is an incomplete run: {len(missing)} of {len(manifest['chunks'])} regions "
                                f"not done ({', '.join(missing[:5])}); resume it to compute them")
    raw = xr.open_zarr(f"{url}/{DATA}", consolidated=False, zarr_format=ZARR_FORMAT,
                       storage_options=_options(url))
    return cf_decode(raw)
