"""A run folder: a manifest and one netCDF file per chunk (a plain path's location).

Layout of ``<output_dir>``::

    run.json          manifest: the study (``Study.to_dict()``), chunk size, chunk file names
    run.lock          one run at a time (``lock.hold_lock``)
    chunks/*.nc       one finished chunk each (written whole, then renamed into place)
    chunks/*.nc.sha256  its checksum (``location.digest`` of the file's bytes), written
                      before the chunk is renamed into place and checked by every reader
    chunks/*.part     a file being written, or left by a killed run: never read
    rare.json, sensitivity.nc, design.nc, evaluations/, fixed/, report/, export/
                      the files beside the ensemble, each written whole

:meth:`Folder.open` opens the chunks lazily as one Dataset. There is no consolidated
single file: the chunk files already are the store (each a plain netCDF file), and
``open_ensemble(d).to_netcdf(path)`` makes one when a single file is wanted.
"""

from __future__ import annotations

import contextlib
import errno
import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: xarray is imported where a Dataset is made or read
    import xarray as xr

from ..errors import ParameterError, naming
from ..conventions import cf_decode, cf_encode
from ..files import check_unlinked, write_atomic, write_text_atomic
from ..schema import FORCE, REALIZATION
from .chunk import write_netcdf
from ..pool import orphaned
from .lock import run_lock
from .location import (MANIFEST, MAX_MANIFEST_BYTES, Location, changed, check_growth, check_same_study,
                       corrupt_manifest, digest, held, new_key, parse_manifest, plan_chunks)

CHUNKS = "chunks"


class Folder(Location):
    """A run folder at the path ``target``."""

    def __init__(self, target):
        super().__init__(Path(target))

    def absolute(self) -> Folder:
        """This folder by its absolute path (a run's workers may start elsewhere)."""
        return Folder(self.target.absolute())

    @property
    def name(self) -> str:
        return self.target.name

    def sibling(self, suffix: str) -> Folder:
        return Folder(self.target.with_name(self.target.name + suffix))

    def child(self, sub: str) -> Folder:
        """The run folder ``sub`` inside this one (a fixed twin's), refused if it is a link
        (``files.check_unlinked``)."""
        check_unlinked(self.target, sub)
        return Folder(self.target / sub)

    def path_of(self, name: str) -> Path:
        return self.target / name

    @contextlib.contextmanager
    def reading(self, name: str):
        path = self.target / name
        yield path if path.is_file() else None

    @contextlib.contextmanager
    def writing(self, name: str):
        check_unlinked(self.target, name)
        yield self.target / name

    def local_folder(self) -> Path:
        """The local folder whose disk the run fills."""
        return self.target

    def probe(self) -> None:
        """Nothing to ask beforehand: the preflight checks the folder (``local_folder``)."""

    def lock(self):
        """Hold ``run.lock`` for the run (``lock.run_lock``); RunLocked if a live run holds it."""
        return run_lock(self.target)

    def read_manifest(self) -> dict | None:
        """The run manifest, or None if there is none. A manifest that is not one uqdrape
        wrote (hand-edited, truncated, another program's) raises OSError naming the file
        and what is wrong: its chunk names are paths uqdrape will open, so they must be
        plain chunk file names inside ``chunks/``."""
        path = self.target / MANIFEST
        if not path.is_file():
            return None
        if path.stat().st_size > MAX_MANIFEST_BYTES:
            raise corrupt_manifest(path, f"larger than {MAX_MANIFEST_BYTES // 2**20} MB")
        return parse_manifest(path.read_bytes(), path)

    def write_manifest(self, manifest: dict) -> None:
        """Write the manifest whole (a temporary file, then renamed)."""
        write_text_atomic(self.target / MANIFEST, json.dumps(manifest, indent=1))

    # -- the run loop's operations (``uqdrape.ensemble.run``)

    def plan(self, study, provenance: dict, chunk_size: int, n: int, resume: bool):
        """(chunks, names of those already written) of a run of ``n`` realisations here:
        an earlier run of the same study keeps its chunks as they are (an extension adds
        chunks after them). ValueError for another study's run, or as ``check_growth``."""
        old = self.read_manifest() if resume else None
        kept = []
        if old is not None:
            check_same_study(self.target, old, provenance)
            check_growth(self.target, study, old["chunk_size"], held(old["chunks"]), chunk_size, n)
            kept = old["chunks"]
        done = {p.name for p in (self.target / CHUNKS).glob("*.nc")} if resume else set()
        return plan_chunks(study, chunk_size, n, kept), done

    def prepare(self, study, chunks, manifest: dict, resume: bool, attrs: dict, sample_rows):
        """Under the run's lock: check an earlier run can be resumed, or clear it; record
        this run; drop damaged chunk files. Returns (manifest, earlier wall time in s,
        chunks to drape, damaged chunks). A ``.part`` file here is a killed run's."""
        folder = self.target / CHUNKS
        check_unlinked(self.target, CHUNKS)
        old = self.read_manifest() if resume else None
        for path in folder.glob("*.part"):
            path.unlink()
        if not resume:
            for path in (*folder.glob("*.nc"), *folder.glob("*.nc.sha256")):
                path.unlink()
        elif old is None:
            if any(folder.glob("*.nc")):
                raise ParameterError("resume", f"{folder} holds chunk files but {self.target} has no run "
                                     "manifest; they cannot be checked against this study: run again without "
                                     "resuming")
        else:
            check_same_study(self.target, old, manifest["study"])
        folder.mkdir(parents=True, exist_ok=True)
        key = new_key() if old is None else old.get("checksum_key")  # a run of an older uqdrape has none
        manifest = {**manifest, "checksum_key": key} if key else manifest
        self.write_manifest(manifest)
        damaged = [c for c in chunks if (folder / c.name).is_file()
                   and not (chunk_intact(folder / c.name, c) and self._matches(c.name, key))]
        for c in damaged:  # a truncated, edited, swapped or foreign file: drape it again
            (folder / c.name).unlink()
        todo = [c for c in chunks if not (folder / c.name).is_file()]
        return manifest, (old or {}).get("wall_time_s", 0.0), todo, damaged

    def write_chunk(self, study, ds: xr.Dataset, chunk, level: int, attrs: dict, key: str | None) -> str:
        """In the worker: write the draped chunk ``ds`` as its file, its checksum under the
        run's ``key`` first (none without a key: a resumed run of an older uqdrape), and
        not after the run has died (``pool.orphaned``); return its name."""
        ds.attrs.update(attrs)
        ds, encoding = cf_encode(ds, title=f"uqdrape ensemble chunk: study {study.name}, realisations "
                                           f"{chunk.start}-{chunk.stop - 1} at {chunk.force:g} N",
                                 history=f"uqdrape run {Path(study.path).name}", float32=study.float32)
        path = self.target / CHUNKS / chunk.name

        def write(part):
            write_netcdf(ds, part, encoding, target=path)
            if key:
                write_atomic(_sum_of(path), lambda tmp: tmp.write_text(_file_digest(part, key, chunk.name) + "\n"),
                             keep_suffix=False)
            return not orphaned()

        write_atomic(path, write, keep_suffix=False)
        return chunk.name

    def _matches(self, name: str, key: str | None) -> bool:
        """Whether chunk ``name``'s file hashes to the checksum written with it (always, in a
        run without a ``key``)."""
        if not key:
            return True
        path = self.target / CHUNKS / name
        try:
            return _sum_of(path).read_text(encoding="ascii").strip() == _file_digest(path, key, name)
        except (OSError, UnicodeDecodeError):
            return False

    def finish(self) -> None:
        """After the run's tasks, done or failed: their workers are gone, so are unfinished files."""
        for part in (self.target / CHUNKS).glob("*.part"):
            part.unlink(missing_ok=True)

    def open(self) -> xr.Dataset:
        """All chunks of a finished run as one lazy (dask-backed) Dataset.

        Dims (blankholder_force, realization, i, j, ...), the force dimension of length 1
        without a sweep (``uqdrape.schema``); one dask chunk per chunk file. Raises
        FileNotFoundError if the folder holds no run or some chunks are missing (naming
        them: resume the run to compute them), ValueError for a run written before the force
        was always a dimension."""
        import xarray as xr

        manifest = self.read_manifest()
        if manifest is None:
            raise FileNotFoundError(
                f"{self.target} holds no uqdrape run (no {MANIFEST}); run the study first (uqdrape run STUDY)")
        paths = [self.target / CHUNKS / name for name in manifest["chunks"]]  # in plan order
        missing = [p.name for p in paths if not p.is_file()]
        if missing:
            shown = ", ".join(missing[:5]) + (", ..." if len(missing) > 5 else "")
            raise FileNotFoundError(
                f"{self.target} is an incomplete run: {len(missing)} of {len(paths)} chunk files missing "
                f"in {CHUNKS}/ ({shown}); resume it (uqdrape run STUDY) to compute them")
        for path in paths:
            if not self._matches(path.name, manifest.get("checksum_key")):
                raise changed(path, f"chunk {path.name}")
        try:
            files = xr.open_mfdataset(
                paths, engine="netcdf4", combine="by_coords", data_vars="minimal", coords="minimal",
                compat="override", join="exact", combine_attrs="override",
            )
        except (OSError, RuntimeError, AttributeError, ValueError) as err:  # a damaged chunk: netCDF4's errors (an
            # unreadable attribute: AttributeError), an undecodable text attribute, coordinates that no longer combine
            for path in paths:  # which one: a truncated or overwritten chunk
                try:
                    xr.open_dataset(path, engine="netcdf4").close()
                except (OSError, RuntimeError, AttributeError, ValueError):
                    raise OSError(errno.EIO, f"a corrupt chunk file ({err}); delete it and run the study again "
                                  "to resume", str(path)) from None
            raise naming(OSError(errno.EIO, f"the chunk files do not combine into one ensemble ({err}); run the "
                                 "study again without resuming", str(self.target / CHUNKS)), "resume") from None
        if FORCE not in files.dims:
            files.close()
            raise ParameterError("resume", f"{self.target} was written by an older uqdrape (no {FORCE!r} "
                                 "dimension); run its study again without resuming")
        ds = cf_decode(files)
        ds.set_close(files.close)  # closing the result closes the chunk files
        if len(paths) > 1:  # an extended run: the study as its last call ran it (the plan's last chunk)
            with xr.open_dataset(paths[-1], engine="netcdf4", decode_cf=False) as last:
                ds.attrs.update({k: v for k, v in last.attrs.items() if k.startswith("study_")})
        # the run's own description, not its first chunk's ("realisations 0-15 at 126 N")
        levels = ", ".join(f"{f:g}" for f in ds[FORCE].values)
        ds.attrs["title"] = (f"uqdrape ensemble: study {ds.attrs.get('study_name', self.target.name)}, "
                             f"{ds.sizes.get(REALIZATION, 0)} realisations at {levels} N")
        return ds


def _sum_of(path: Path) -> Path:
    """The checksum file of the chunk file ``path``."""
    return path.with_name(path.name + ".sha256")


def _file_digest(path: Path, key: str, name: str) -> str:
    """``location.digest`` of the file ``path``'s bytes as chunk ``name`` of the run ``key``."""
    with open(path, "rb") as f:
        return digest(key, name, iter(lambda: f.read(2**20), b""))


def chunk_intact(path: Path, chunk) -> bool:
    """Whether ``path`` is the finished chunk ``chunk``: a netCDF file that opens, holds the
    node shear and exactly the chunk's realisations at its force level. Reads only the
    file's metadata and two coordinates."""
    import xarray as xr

    try:
        with xr.open_dataset(path, engine="netcdf4", decode_cf=False) as ds:
            return ("shear" in ds.variables and FORCE in ds.variables and REALIZATION in ds.variables
                    and ds[FORCE].values.tolist() == [chunk.force]
                    and ds[REALIZATION].values.tolist() == list(range(chunk.start, chunk.stop)))
    except (OSError, ValueError, KeyError, RuntimeError, AttributeError):  # netCDF4's for an unreadable attribute
        return False
