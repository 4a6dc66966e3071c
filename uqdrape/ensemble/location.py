"""Where a run lives: the one storage interface of uqdrape's ensembles.

A run's *location* is chosen once, from a path or a URL, by ``uqdrape.ensemble.storage.at``:
a run folder of netCDF chunk files (a plain path: ``store.Folder``) or one zarr store on
any fsspec URL (``zarrstore.ZarrStore``). Each offers what the run loop
(``uqdrape.ensemble.run``) and every reader need: plan what an earlier run keeps,
prepare a run under its lock, write one chunk, check the chunks, read and write the
manifest, read and write the files beside the ensemble (rare and design records,
sensitivity indices, reports, exports: each whole), name the twin's location inside it,
and open the ensemble lazily. This module holds what both share: the chunk plan and the
checks of a resumed run.
"""

from __future__ import annotations

import errno
import hashlib
import re
import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: xarray is imported where a Dataset is made or read
    import xarray as xr

from ..errors import ParameterError, naming
from ..files import json_object, write_text_atomic
from ..stochastic.sampling import extension_problem
from ..study import Study, identity
from .chunk import HDF5_LOCK, write_atomic

#: The manifest of a run, in a folder or a store alike (its lock: ``lock.LOCK``).
MANIFEST = "run.json"

#: A chunk file's name: ``r<first>-<last>.nc``, prefixed ``f<level>-`` in a sweep (and never a path).
CHUNK_NAME = re.compile(r"^(f\d{3}-)?r\d{7}-\d{7}\.nc$")
#: Largest run manifest read (bytes): a million chunk names take about 30 MB.
MAX_MANIFEST_BYTES = 64 * 2**20


def corrupt_manifest(where, why: str) -> OSError:
    """The one-line error for a manifest at ``where`` (path or URL) that is not one uqdrape wrote."""
    return naming(OSError(errno.EIO, f"not a uqdrape run manifest ({why}); run the study again without "
                                     "resuming, or delete the folder", str(where)), "resume")


def parse_manifest(text: bytes, where) -> dict:
    """The manifest in ``text`` (read from ``where``), checked as :func:`read_manifest` says."""
    manifest = json_object(text, lambda why: corrupt_manifest(where, why))
    study, chunks, size = manifest.get("study"), manifest.get("chunks"), manifest.get("chunk_size")
    if not (isinstance(study, dict) and all(isinstance(v, dict) or (isinstance(v, list) and all(
            isinstance(p, dict) for p in v)) for v in study.values())
            and isinstance(study.get("study"), dict)):
        raise corrupt_manifest(where, '"study" must be the study record, a table of sections (the ply book an array of them)')
    if not (isinstance(chunks, list) and all(isinstance(c, str) and CHUNK_NAME.match(c) for c in chunks)):
        raise corrupt_manifest(where, '"chunks" must be a list of chunk file names such as r0000000-0000063.nc')
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise corrupt_manifest(where, '"chunk_size" must be a positive integer')
    key = manifest.get("checksum_key")
    if key is not None and not (isinstance(key, str) and re.fullmatch(r"[0-9a-f]{32}", key)):
        raise corrupt_manifest(where, '"checksum_key" must be 32 hexadecimal digits')
    wall = manifest.get("wall_time_s", 0.0)
    if isinstance(wall, bool) or not isinstance(wall, (int, float)) or not 0 <= wall < 1e9:
        raise corrupt_manifest(where, '"wall_time_s" must be a number of seconds')
    return manifest


def new_key() -> str:
    """A run's checksum key (``run.json`` ``"checksum_key"``), drawn once per run and kept
    by its resumptions and extensions: a chunk's digest covers it, so a chunk copied in
    from another run of the same study does not pass as this run's."""
    return secrets.token_hex(16)


def digest(key: str, name: str, parts) -> str:
    """The SHA-256 (hex) a chunk is checked by: the run's ``key``, the chunk's ``name``,
    then its content ``parts`` (bytes, in order). The name is in it, so two chunks
    swapped, or one copied under another's name, do not pass."""
    sha = hashlib.sha256(f"{key}\0{name}\0".encode())
    for part in parts:
        sha.update(part)
    return sha.hexdigest()


def changed(where, what: str) -> OSError:
    """The one-line error for a chunk or region at ``where`` whose content is not what the
    run wrote (edited, swapped, copied in from another run, or damaged)."""
    return naming(OSError(errno.EIO, f"{what} is not what the run wrote (its SHA-256 differs from the one recorded "
                                     "with it: changed, swapped or damaged since); run the study again to resume, "
                                     "which draws it again", str(where)), "resume")


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
    ``study.realizations``; a sensitivity sample's row count) at each force level, named
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


def region_of(name: str) -> tuple[int, int, int]:
    """(force level index, first realisation, stop) of the chunk named ``name``."""
    start, last = (int(v) for v in _RANGE.search(name).groups())
    return (int(name[1:4]) if name.startswith("f") else 0), start, last + 1


def held(chunk_names) -> int:
    """The realisations an earlier plan's chunk names cover."""
    return max((int(_RANGE.search(name).group(2)) + 1 for name in chunk_names), default=0)


def check_growth(where, study: Study, old_chunk_size: int, held: int, chunk_size: int, n: int) -> None:
    """Raise ValueError (naming ``where``, a folder or a store) unless a run of ``held``
    realisations in chunks of ``old_chunk_size`` can be resumed as ``n`` in chunks of
    ``chunk_size``: the same chunk size, no fewer realisations, more only under a plan
    that extends."""
    if old_chunk_size != chunk_size:
        raise ParameterError(("chunk_size", "resume"), f"{where} was run in chunks of {old_chunk_size}; resume "
                             f"with that chunk size or run again without resuming")
    if n < held:
        raise ParameterError("resume", f"{where} holds {held} realisations, more than the {n} asked for: set "
                             f"realizations >= {held} in [study], or run again without resuming")
    why = extension_problem(study.sampling, held, n) if n > held else None
    if why:
        raise ParameterError("resume", f"{where} holds {held} realisations and cannot be extended to {n}: "
                             f"{why}; run again without resuming")


def check_same_study(where, old: dict, provenance: dict) -> None:
    """Raise ValueError naming the changed keys unless the run manifest ``old`` in ``where``
    is of the study ``provenance`` describes (by ``identity``)."""
    before, now = identity(old["study"]), identity(provenance)
    if before != now:
        changed = sorted(f"{section}.{key}" for section in set(before) | set(now)
                         for key in set(before.get(section, {})) | set(now.get(section, {}))
                         if before.get(section, {}).get(key) != now.get(section, {}).get(key))
        raise ParameterError("resume", f"{where} holds a run of a different study definition (changed: "
                             f"{', '.join(changed)}); run again without resuming to replace it, or set "
                             "another [output] directory")


class Location:
    """A run's place (``target``: a Path, or a store's URL). The backends define the
    abstract operations; the side-file readers and writers here are built on
    :meth:`reading` and :meth:`writing`."""

    #: what the run's pieces are called in messages ("chunks" of a folder, "regions" of a store)
    parts = "chunks"

    def __init__(self, target):
        self.target = target

    def __str__(self) -> str:
        return str(self.target)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({str(self.target)!r})"

    @property
    def name(self) -> str:
        """The last part of the folder's path or the store's URL (``s3://b/runs/x`` -> ``x``)."""
        return str(self.target).rstrip("/").rsplit("/", 1)[-1]

    def child(self, sub: str) -> Location:
        """The location ``sub`` inside this one (a fixed twin's)."""
        raise NotImplementedError

    def sibling(self, suffix: str) -> Location:
        """The location beside this one, its name with ``suffix`` appended (another method's run)."""
        return type(self)(str(self.target).rstrip("/") + suffix)

    def refused_with(self, scheduler) -> str | None:
        """Why a run here cannot use ``scheduler`` (as ``run_ensemble`` takes it), or None."""
        return None

    def path_of(self, name: str) -> Path | str:
        """Where the file or folder ``name`` of the run lives: a path, or a URL in a store."""
        raise NotImplementedError

    def reading(self, name: str):
        """Context manager: a local path holding the run's file ``name``, or None if it has none."""
        raise NotImplementedError

    def writing(self, name: str):
        """Context manager: a local path to write the run's file or folder ``name`` at; in
        place when the block ends without error, each file whole (a folder's files in the
        order they were written, so a report's index.html is last)."""
        raise NotImplementedError

    def read_dataset(self, name: str) -> xr.Dataset | None:
        """The run's own netCDF file ``name`` (e.g. ``sensitivity.nc``), loaded; None if the
        run has none. OSError / ValueError as xarray's for an unreadable file."""
        import xarray as xr

        with self.reading(name) as path, HDF5_LOCK:
            return None if path is None else xr.load_dataset(path, engine="netcdf4")

    def write_dataset(self, name: str, ds: xr.Dataset, encoding: dict | None = None) -> Path | str:
        """Write ``ds`` as the run's netCDF file ``name``, whole; return its path or URL."""
        with self.writing(name) as path:
            write_atomic(ds, path, encoding)
        return self.path_of(name)

    def read_text(self, name: str) -> str | None:
        """The run's UTF-8 text file ``name`` (e.g. ``rare.json``), or None if it has none."""
        with self.reading(name) as path:
            return None if path is None else Path(path).read_text(encoding="utf-8")

    def write_text(self, name: str, text: str) -> Path | str:
        """Write ``text`` as the run's file ``name``, whole; return its path or URL."""
        with self.writing(name) as path:
            write_text_atomic(path, text)
        return self.path_of(name)
