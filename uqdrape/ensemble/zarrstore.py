"""An ensemble as one chunked zarr store on any fsspec URL (issue 28).

Selected by a URL (anything with ``://``: ``file:///abs/path``, ``memory://name``,
``s3://bucket/prefix``), as ``--out`` or ``[output] directory``. Decided: a plain path
stays a run folder of netCDF chunks (``uqdrape.ensemble.store``), the default, and old
run folders are read, not refused: every reader takes either
(``uqdrape.ensemble.location``: the interface both offer). Layout under the URL::

    run.json        the manifest: study record, chunk size, chunk names, realisations;
                    written as run.json.part, then moved over the old one
    run.lock        one writer at a time (``lock.hold_lock``): created with exclusive
                    create ("xb": on S3 a conditional put, If-None-Match: *)
    data/           the zarr store (zarr format 3), the ensemble in the layout of
                    ``open_ensemble``: (blankholder_force, realization, ...), zarr
                    chunks of (1, chunk_size, full node grid)
    done/<chunk>    a region's "done" marker, written after its data: the region's
                    checksum (``location.digest`` of its stored bytes), checked by every
                    reader
    rare.json, sensitivity.nc, design.nc, evaluations/, fixed/, report/, export/
                    as in a run folder, each file put whole (``ZarrStore._put``)

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
import itertools
import json
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # annotations only: xarray is imported where a Dataset is made or read
    import xarray as xr

from ..conventions import cf_decode, cf_encode
from ..files import check_unlinked, claim, url_problem
from ..schema import FORCE, REALIZATION
from .chunk import drape_chunk
from .lock import LOCK, hold_lock
from .location import (MANIFEST, MAX_MANIFEST_BYTES, Location, changed, check_growth, check_same_study,
                       corrupt_manifest, digest, new_key, parse_manifest, plan_chunks, region_of)

#: the object ``check_store`` puts and removes to learn that a store takes writes
PROBE = ".uqdrape-probe"
DATA = "data"
DONE = "done"
#: zarr on-disk format written (zarr-python >= 3 writes format 3).
ZARR_FORMAT = 3
#: encoding keys of ``cf_encode`` that mean the same in zarr (netCDF's zlib/complevel do not).
_KEPT = ("dtype", "_FillValue", "units", "calendar")
#: regions checked at once when a store is opened: their objects are read in one call
#: (concurrent on an object store) and held in memory together
CHECK_BATCH = 4


class ZarrStore(Location):
    """One zarr store at the fsspec URL ``target``."""

    parts = "regions"

    def __init__(self, target: str):
        why = url_problem(target)
        if why:
            raise ValueError(f"{target}: {why}")
        super().__init__(target)

    def absolute(self) -> ZarrStore:
        return self

    def refused_with(self, scheduler) -> str | None:
        """A memory:// store lives in one process. Decided: only scheduler "synchronous" (this
        process, as the Python API's tests run) writes one; any other scheduler's worker
        processes would each see an empty store of their own (zarr's GroupNotFoundError at
        the first chunk), and a command's store would be gone when it exits anyway."""
        if self.target.startswith("memory://") and scheduler != "synchronous":
            return ("a memory:// store lives in one process, where the run's worker processes cannot write it; use "
                    "file:///abs/path or s3://bucket/prefix (in Python, scheduler='synchronous' can use memory://)")
        return None

    def path_of(self, name: str) -> str:
        return f"{self.target.rstrip('/')}/{name}"

    @contextlib.contextmanager
    def reading(self, name: str):
        """A local copy of the store's file ``name``, in a temporary folder."""
        fs, root = _fs(self.target)
        _check_reachable(fs, root, self.target)
        with tempfile.TemporaryDirectory(prefix="uqdrape-") as tmp:
            local = Path(tmp) / name
            local.parent.mkdir(parents=True, exist_ok=True)  # else a missing folder here reads as no such file
            try:
                fs.get_file(f"{root}/{name}", str(local))
            except FileNotFoundError:
                local = None
            yield local

    @contextlib.contextmanager
    def writing(self, name: str):
        """A temporary local path whose file, or whose folder's files, are put in the store."""
        with tempfile.TemporaryDirectory(prefix="uqdrape-") as tmp:
            local = Path(tmp) / name
            yield local
            if local.is_file():
                self._put(name, local)
            for path in sorted((p for p in local.rglob("*") if p.is_file()), key=lambda p: p.stat().st_mtime_ns):
                self._put(f"{name}/{path.relative_to(local).as_posix()}", path)

    def _put(self, name: str, data) -> None:
        """Put ``data`` (bytes, or a local file's path) as the store's object ``name``, whole:
        uploaded as ``name.part``, then moved (a rename on a local disk, a server-side copy
        on S3), so a reader never sees it half-written and a failed or killed upload leaves
        the old object; a failure that returns removes the part. On a local disk the part is
        made by ``files.claim`` and renamed by os.replace, so a symbolic link planted at
        either name is replaced, never written through."""
        fs, root = _fs(self.target)
        part, final = f"{root}/{name}.part", f"{root}/{name}"
        local = "file" in (fs.protocol if isinstance(fs.protocol, tuple) else (fs.protocol,))
        if local:
            check_unlinked(root, str(Path(name).parent))  # a link at the name itself is replaced below
            fs.makedirs(fs._parent(part), exist_ok=True)
            claim(part)
        try:
            fs.pipe_file(part, data) if isinstance(data, bytes) else fs.put_file(str(data), part)
        except BaseException:
            with contextlib.suppress(OSError):
                fs.rm(part)
            raise
        if local:
            os.replace(part, final)
        else:
            fs.mv(part, final)

    def local_folder(self) -> Path | None:
        """The local folder of a file:// store (its disk the run fills), else None."""
        return Path(self.target.removeprefix("file://")) if self.target.startswith("file://") else None

    def child(self, sub: str) -> ZarrStore:
        """The store ``sub`` inside this one (a fixed twin's); in a local store, refused if it
        is a link (``files.check_unlinked``)."""
        if self.local_folder() is not None:
            check_unlinked(self.local_folder(), sub)
        return ZarrStore(self.path_of(sub))

    def probe(self) -> None:
        """OSError unless a run can write here (:func:`check_store`)."""
        check_store(self.target)

    def lock(self):
        """Hold ``run.lock`` of the store (``lock.hold_lock``, with exclusive create)."""
        fs, root = _fs(self.target)
        _check_reachable(fs, root, self.target)
        path = f"{root}/{LOCK}"
        fs.makedirs(root, exist_ok=True)  # a no-op on object stores

        def create(record: bytes):
            with fs.open(path, "xb") as f:
                f.write(record)

        return hold_lock(self.target, "store", create, lambda: fs.cat_file(path), lambda: fs.rm(path))

    def read_manifest(self) -> dict | None:
        """The manifest, or None if there is none (checked as ``Folder.read_manifest``
        checks a folder's, and its ``realizations`` a count); OSError (one line) for a
        missing bucket or an unreachable store (``_check_reachable``)."""
        fs, root = _fs(self.target)
        _check_reachable(fs, root, self.target)
        where = self.path_of(MANIFEST)
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

    def write_manifest(self, manifest: dict) -> None:
        """Write the manifest whole (:meth:`_put`)."""
        self._put(MANIFEST, json.dumps(manifest, indent=1).encode())

    def done(self) -> set[str]:
        """The chunk names whose region is marked done (a marker's ``.part``, being put or
        left by a killed writer, is not one)."""
        fs, root = _fs(self.target)
        try:
            names = {p.rstrip("/").rsplit("/", 1)[-1] for p in fs.ls(f"{root}/{DONE}", detail=False)}
        except FileNotFoundError:
            return set()
        return {name for name in names if not name.endswith(".part")}

    # -- the run loop's operations (``uqdrape.ensemble.run``)

    def plan(self, study, provenance: dict, chunk_size: int, n: int, resume: bool):
        """(chunks, names of the regions done) of a run of ``n`` realisations here: always
        the whole-chunk plan (module docstring), keeping the regions done of an earlier run
        of the same study. ValueError for another study's run, or as ``check_growth``;
        OSError (one line naming the URL) unless the store takes writes."""
        check_store(self.target)
        chunks = plan_chunks(study, chunk_size, n)
        return chunks, self._kept(study, provenance, chunk_size, n, chunks, resume)[1]

    def _kept(self, study, provenance, chunk_size, n, chunks, resume) -> tuple[dict | None, set[str]]:
        """(manifest, done region names) of an earlier run here that this one keeps."""
        old = self.read_manifest() if resume else None
        if old is None:
            return None, set()
        check_same_study(self.target, old, provenance)
        check_growth(self.target, study, old["chunk_size"], old["realizations"], chunk_size, n)
        return old, self.done() & {c.name for c in chunks}

    def prepare(self, study, chunks, manifest: dict, resume: bool, attrs: dict, sample_rows):
        """Under the run's lock: write the template afresh (no run to keep), or grow the
        kept run's arrays to this one's realisations; record this run. Returns (manifest,
        earlier wall time in s, chunks to drape, damaged chunks: none, a marker is written
        after its region)."""
        n = manifest["realizations"] = max(c.stop for c in chunks)
        manifest["zarr_format"] = ZARR_FORMAT
        fs, root = _fs(self.target)
        old, done = self._kept(study, manifest["study"], manifest["chunk_size"], n, chunks, resume)  # as it is now
        key = new_key() if old is None else old.get("checksum_key")  # a run of an older uqdrape has none
        if key:
            manifest["checksum_key"] = key
        title = (f"uqdrape ensemble: study {study.name}, {n} realisations at "
                 + ", ".join(f"{f:g}" for f in study.force_levels) + " N")
        damaged = []
        if self.local_folder() is not None:
            for name in (DATA, DONE):
                check_unlinked(self.local_folder(), name)
        with _writing(self.target, "the store's template"):
            if old is None:
                if fs.exists(f"{root}/{DONE}"):
                    fs.rm(f"{root}/{DONE}", recursive=True)
                _write_template(study, self.target, chunks, n, manifest["chunk_size"], attrs, title, sample_rows)
                self.write_manifest(manifest)
            else:
                bad = set(self.damaged(sorted(done), key))  # one pass over the kept regions
                damaged = [c for c in chunks if c.name in bad]
                for name in self.done() - done | {c.name for c in damaged}:  # regions cut anew, or to draw again
                    fs.rm(f"{root}/{DONE}/{name}")
                # the manifest first: a store killed while it grows reads as incomplete, not as the smaller run
                self.write_manifest({**manifest, "wall_time_s": old.get("wall_time_s", 0.0)})
                _resize(self.target, n, {**attrs, "title": title})
        done -= {c.name for c in damaged}
        return manifest, (old or {}).get("wall_time_s", 0.0), [c for c in chunks if c.name not in done], damaged

    def write_chunk(self, study, ds: xr.Dataset, chunk, level: int, attrs: dict, key: str | None) -> str:
        """In the worker: write the draped chunk ``ds`` into its region of the store, then
        the region's marker, its checksum under the run's ``key`` read back from the store
        (a bare marker without a key: a resumed run of an older uqdrape); return its name.
        A failed write is one-line OSError naming the store (a full or read-only bucket).
        The run's attributes are the template's."""
        ds = _encoded(ds, study, title="")
        region = {FORCE: slice(level, level + 1), REALIZATION: slice(chunk.start, chunk.stop)}
        ds = ds.drop_vars([v for v, var in ds.variables.items() if not set(region) & set(var.dims)])
        ds.attrs = {}
        with _writing(self.target, f"region {chunk.name}"):
            ds.to_zarr(f"{self.target}/{DATA}", region=region, mode="r+", zarr_format=ZARR_FORMAT,
                       consolidated=False, storage_options=_options(self.target))
            # after the data: a marker means the region is whole
            mark = self._digests(self._layout(), [chunk.name], key)[0] if key else "done"
            self._put(f"{DONE}/{chunk.name}", f"{mark}\n".encode())
        return chunk.name

    def _layout(self) -> list[tuple]:
        """(name, dims, shape, chunk shape, chunk-key encoder) of each array a region writes:
        all with a realisation or force dimension but the index coordinates (the run's,
        written whole with the template). OSError naming the store if its data cannot be
        opened (damaged metadata)."""
        import zarr

        try:
            group = zarr.open_group(f"{self.target}/{DATA}", mode="r", zarr_format=ZARR_FORMAT,
                                    storage_options=_options(self.target) or None)
            arrays = sorted(group.arrays(), key=lambda item: item[0])
            return [(var, list(a.metadata.dimension_names or ()), a.shape, a.chunks, a.metadata.encode_chunk_key)
                    for var, a in arrays if var not in (FORCE, REALIZATION)
                    and {FORCE, REALIZATION} & set(a.metadata.dimension_names or ())]
        except Exception as err:  # zarr's, JSON's or the filesystem's error, whichever damaged metadata raises
            raise OSError(errno.EIO, f"the store's data cannot be opened ({type(err).__name__}: {err}); run the "
                          "study again without resuming", self.path_of(DATA)) from None

    @staticmethod
    def _objects(layout, name: str) -> list[str]:
        """The keys (under ``data/``) of the stored objects region ``name`` writes."""
        level, start, stop = region_of(name)
        keys = []
        for var, dims, shape, chunks, encode in layout:
            ranges = [range(level // c, level // c + 1) if d == FORCE else range(start // c, (stop - 1) // c + 1)
                      if d == REALIZATION else range(-(-size // c)) for d, size, c in zip(dims, shape, chunks)]
            keys += [f"{var}/{encode(index)}" for index in itertools.product(*ranges)]
        return keys

    def _digests(self, layout, names, key: str) -> list[str]:
        """``location.digest`` of each region in ``names``: the stored objects it writes, by
        key, their bytes as stored (compressed; none for one zarr left unwritten or that
        cannot be read)."""
        fs, root = _fs(self.target)
        keys = [self._objects(layout, name) for name in names]
        objects = fs.cat([f"{root}/{DATA}/{k}" for ks in keys for k in ks], on_error="return")
        return [digest(key, name, (part for k in ks for part in (k.encode() + b"\0",
                                                                 _bytes(objects, f"{root}/{DATA}/{k}"))))
                for name, ks in zip(names, keys)]

    def damaged(self, names, key: str | None) -> list[str]:
        """The regions among ``names`` (marked done) whose stored objects are not those their
        marker's checksum was taken of (edited, swapped, cut short, removed); none without
        a ``key``. OSError naming the store if its data cannot be opened at all."""
        if not key or not names:
            return []
        fs, root = _fs(self.target)
        layout, bad = self._layout(), []
        for at in range(0, len(names), CHECK_BATCH):
            batch = list(names[at:at + CHECK_BATCH])
            marks = fs.cat([f"{root}/{DONE}/{name}" for name in batch], on_error="return")
            bad += [name for name, sha in zip(batch, self._digests(layout, batch, key))
                    if _bytes(marks, f"{root}/{DONE}/{name}").strip() != sha.encode()]
        return bad

    def finish(self) -> None:
        """Nothing to clear: a region without its marker is drawn again by the next run."""

    def open(self) -> xr.Dataset:
        """The ensemble as a lazy (dask) Dataset, one dask chunk per region;
        FileNotFoundError naming the regions not yet done."""
        import xarray as xr

        manifest = self.read_manifest()
        if manifest is None:
            raise FileNotFoundError(f"{self.target} holds no uqdrape run (no {MANIFEST}); run the study first")
        missing = [c for c in manifest["chunks"] if c not in self.done()]
        if missing:
            raise FileNotFoundError(f"{self.target} is an incomplete run: {len(missing)} of {len(manifest['chunks'])} "
                                    f"regions not done ({', '.join(missing[:5])}); resume it to compute them")
        damaged = self.damaged(manifest["chunks"], manifest.get("checksum_key"))
        if damaged:
            raise changed(self.target, f"region {damaged[0]}" + (f" (and {len(damaged) - 1} more)" if damaged[1:] else ""))
        raw = xr.open_zarr(f"{self.target}/{DATA}", consolidated=False, zarr_format=ZARR_FORMAT,
                           storage_options=_options(self.target))
        return cf_decode(raw)


def _bytes(objects: dict, path: str) -> bytes:
    """The object ``path`` from ``fs.cat``'s answer: its bytes, none if it could not be read."""
    data = objects.get(path)
    return data if isinstance(data, bytes) else b""


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


def _encoded(ds: xr.Dataset, study, title: str) -> xr.Dataset:
    """``ds`` with its CF attributes and the zarr-valid part of ``cf_encode``'s encoding."""
    ds, encoding = cf_encode(ds, title=title, history=f"uqdrape run {study.path.name}", float32=study.float32)
    for name, var in ds.variables.items():
        kept = {k: v for k, v in var.encoding.items() if k in _KEPT}
        kept.update({k: v for k, v in encoding.get(name, {}).items() if k in _KEPT})
        var.encoding = kept
    return ds


@contextlib.contextmanager
def _writing(url: str, what: str):
    """An OSError raised writing ``what`` to the store at ``url`` (a read-only or full
    bucket, a lost connection) as one line naming both."""
    try:
        yield
    except OSError as err:
        cause = " ".join(str(err.strerror or err).split())
        raise OSError(err.errno or errno.EIO, f"cannot write {what} ({type(err).__name__}: {cause})", url) from None


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


def _write_template(study, url, chunks, n, chunk_size, attrs, title, sample_rows) -> None:
    """Write the store's metadata and index coordinates once (``compute=False``): every
    variable of a chunk, widened to all force levels and ``n`` realisations, no data.
    The structure is that of one realisation draped here."""
    import dask.array
    import xarray as xr

    first = chunks[0]
    one = drape_chunk(study, [first.start], first.force, None if sample_rows is None else sample_rows[:1])
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
