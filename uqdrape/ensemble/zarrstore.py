"""An ensemble as one chunked zarr store on any fsspec URL (issue 28).

Selected by a URL (anything with ``://``: ``file:///abs/path``, ``memory://name``,
``s3://bucket/prefix``). Decided: a plain path stays a run folder of netCDF chunks
(``uqdrape.ensemble.store``), the default, and old run folders are read, not refused:
every reader takes either (``uqdrape.ensemble.location``). Layout under the URL::

    run.json        the manifest: study record, chunk size, chunk names, realisations
    run.lock        one writer at a time: created with exclusive create ("xb": on S3 a
                    conditional put, If-None-Match: *), removed when the run ends
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
read as done). Credentials and endpoints come from the environment / fsspec config
(for S3: ``AWS_ACCESS_KEY_ID``, ``AWS_SECRET_ACCESS_KEY``, ``AWS_ENDPOINT_URL``), never
from the study file.
"""

from __future__ import annotations

import errno
import json
import sys
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
from .inputs import inputs_from_design, sampled_inputs
from .progress import Progress

MANIFEST = "run.json"
LOCK = "run.lock"
DATA = "data"
DONE = "done"
#: zarr on-disk format written (zarr-python >= 3 writes format 3).
ZARR_FORMAT = 3
#: encoding keys of ``cf_encode`` that mean the same in zarr (netCDF's zlib/complevel do not).
_KEPT = ("dtype", "_FillValue", "units", "calendar")


def is_url(target) -> bool:
    """Whether ``target`` names a store by fsspec URL (a plain path is a run folder)."""
    return isinstance(target, str) and "://" in target


def _fs(url: str):
    """(filesystem, root path) of ``url``; OSError (one line, exit 3) for a URL fsspec
    cannot open (an unknown protocol, a missing optional package)."""
    import fsspec

    try:
        fs, root = fsspec.core.url_to_fs(url, **_options(url))
    except (ValueError, ImportError) as err:
        raise OSError(errno.EINVAL, f"not a store URL fsspec can open ({err}); use file:///path, memory://name "
                                    "or s3://bucket/prefix", url) from None
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
            raise OSError(errno.ENOENT, f"bucket {bucket!r} does not exist; create it first", url) from None
        except PermissionError as err:
            raise OSError(errno.EACCES, f"access refused ({err}); set AWS_ACCESS_KEY_ID / AWS_SECRET_ACCESS_KEY",
                          url) from None
        except Exception as err:  # botocore's NoCredentialsError, an unreachable endpoint
            raise OSError(errno.EIO, f"cannot reach the store ({type(err).__name__}: {err}); check "
                          "AWS_ENDPOINT_URL and the credentials in the environment", url) from None


def read_store_manifest(url: str) -> dict | None:
    """The manifest of the store at ``url``, or None if there is none; OSError (one line)
    for a missing bucket or an unreachable store (``_check_reachable``)."""
    fs, root = _fs(url)
    _check_reachable(fs, root, url)
    try:
        with fs.open(f"{root}/{MANIFEST}", "rb") as f:
            text = f.read()
    except FileNotFoundError:
        return None
    try:
        manifest = json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        manifest = None
    if not (isinstance(manifest, dict) and isinstance(manifest.get("chunks"), list)
            and isinstance(manifest.get("study"), dict)):
        raise OSError(errno.EIO, "not a uqdrape run manifest; run again with resume=False", f"{url}/{MANIFEST}")
    return manifest


class _StoreLock:
    """``run.lock`` of a store, created with exclusive create: ``FileExistsError`` is
    another writer. There is no stale-lock takeover on a store (its writer may be on
    any host): a lock left by a killed run is deleted by hand."""

    def __init__(self, fs, root: str, url: str):
        self.fs, self.path, self.url = fs, f"{root}/{LOCK}", url

    def __enter__(self):
        import os
        import socket
        import time

        me = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S %Z")}
        self.fs.makedirs(self.path.rsplit("/", 1)[0], exist_ok=True)  # a no-op on object stores
        try:
            with self.fs.open(self.path, "xb") as f:
                f.write(json.dumps(me).encode())
        except FileExistsError:
            raise OSError(errno.EBUSY, f"another run holds {LOCK} of this store; wait for it, or delete "
                          f"{self.url}/{LOCK} if that run is certainly gone", self.url) from None
        return self

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
                 attrs: dict, design_rows) -> str:
    """Dask task: drape realisations start..stop-1 at force level ``level`` (N ``force``),
    write them into their region of the store from this worker, then the region's marker."""
    ds = at_level(_drape(study, np.arange(start, stop), force, design_rows), force)
    ds.attrs.update(attrs)
    ds = _encoded(ds, study, title="")
    region = {FORCE: slice(level, level + 1), REALIZATION: slice(start, stop)}
    ds = ds.drop_vars([v for v, var in ds.variables.items() if not set(region) & set(var.dims)])
    ds.attrs = {}
    ds.to_zarr(f"{url}/{DATA}", region=region, mode="r+", zarr_format=ZARR_FORMAT, consolidated=False, storage_options=_options(url))
    fs, root = _fs(url)
    fs.pipe_file(f"{root}/{DONE}/{name}", b"done\n")  # after the data: a marker means the region is whole
    return name


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


def run_store(study: Study, url: str, *, design_rows=None, provenance: dict | None = None, attrs: dict | None = None,
              scheduler: str | None = None, workers: int | None = None, chunk_size: int | None = None,
              resume: bool = True, progress: bool = True) -> str:
    """Drape a study's realisations into one zarr store at ``url``; return ``url``.

    Arguments as for ``run_ensemble``. ``resume`` keeps the regions marked done of an
    earlier run of the same study (same identity, chunk size and realisations; extending
    a store is not built yet: raises ValueError) and drapes only the others; False
    writes the template afresh. Raises OSError (one line naming the URL) for a URL fsspec
    cannot open, a missing bucket, refused or missing credentials, another writer."""
    from .run import compute_tasks, plan_chunks

    chunk_size = positive_int("chunk_size", study.chunk_size if chunk_size is None else chunk_size)
    provenance = study.to_dict() if provenance is None else provenance
    n = study.realizations if design_rows is None else len(design_rows)
    chunks = plan_chunks(study, chunk_size, n)
    manifest = {"study": provenance, "chunk_size": chunk_size, "chunks": [c.name for c in chunks],
                "realizations": n, "zarr_format": ZARR_FORMAT, "uqdrape_version": __version__}
    fs, root = _fs(url)
    _check_reachable(fs, root, url)
    with _StoreLock(fs, root, url):
        old = read_store_manifest(url) if resume else None
        if old is not None:
            if identity(old["study"]) != identity(provenance):
                raise ValueError(f"{url} holds a run of a different study definition; run with resume=False "
                                 "(--no-resume) to replace it, or use another URL")
            if (old.get("chunk_size"), old.get("realizations")) != (chunk_size, n):
                raise ValueError(f"{url} was run with chunk_size={old.get('chunk_size')} and "
                                 f"{old.get('realizations')} realisations; a store cannot be resumed with others "
                                 "yet: run with resume=False (--no-resume)")
            done = done_regions(url)
        else:
            if fs.exists(f"{root}/{DONE}"):
                fs.rm(f"{root}/{DONE}", recursive=True)
            _write_template(study, url, chunks, n, chunk_size, provenance, attrs, design_rows)
            fs.pipe_file(f"{root}/{MANIFEST}", json.dumps(manifest, indent=1).encode())
            done = set()
        todo = [c for c in chunks if c.name not in done]
        if progress and done:
            print(f"{study.name}: {len(chunks) - len(todo)} of {len(chunks)} regions already done in {url}",
                  file=sys.stderr)
        levels = list(study.force_levels)
        run = dask.delayed(_region_task, pure=False)
        attrs_all = _run_attrs(study, provenance, attrs)
        sizes = [c.stop - c.start for c in chunks]
        bar = Progress(sum(sizes), sum(sizes) - sum(c.stop - c.start for c in todo), enabled=progress,
                       desc=study.name)
        try:
            compute_tasks([run(study, url, c.name, c.start, c.stop, levels.index(c.force), c.force, attrs_all,
                               None if design_rows is None else design_rows[c.start:c.stop]) for c in todo],
                          [c.stop - c.start for c in todo], scheduler, workers, bar)
        finally:
            bar.close()
    return url


def _run_attrs(study: Study, provenance: dict, attrs: dict | None) -> dict:
    """The global attributes every chunk of a run carries (as ``run._drape_chunks``)."""
    return {"study_name": study.name, "study_seed": study.seed, "study_realizations": study.realizations,
            "sampling_plan": study.sampling.plan, "study_toml": read_text(study.path, "study file"),
            "study_json": json.dumps(provenance), **(attrs or {})}


def _write_template(study, url, chunks, n, chunk_size, provenance, attrs, design_rows) -> None:
    """Write the store's metadata and index coordinates once (``compute=False``): every
    variable of a chunk, widened to all force levels and ``n`` realisations, no data.
    The structure is that of one realisation draped here."""
    first = chunks[0]
    one = at_level(_drape(study, np.arange(first.start, first.start + 1), first.force,
                          None if design_rows is None else design_rows[:1]), first.force)
    levels = np.asarray(study.force_levels, dtype=float)
    one.attrs.update(_run_attrs(study, provenance, attrs))
    ds = _encoded(one, study, title=f"uqdrape ensemble: study {study.name}, {n} realisations at "
                                    + ", ".join(f"{f:g}" for f in levels) + " N")
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
    template.to_zarr(f"{url}/{DATA}", mode="w", compute=False, zarr_format=ZARR_FORMAT, consolidated=False, storage_options=_options(url))


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
