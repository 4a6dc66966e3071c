"""The on-disk ensemble: a run folder with a manifest and one netCDF file per chunk.

Layout of ``<output_dir>``::

    run.json          manifest: the study (``Study.to_dict()``), chunk size, chunk file names
    chunks/*.nc       one finished chunk each (written whole, then renamed into place)
    chunks/*.nc.part  a chunk being written, or left by a killed run: never read

:func:`open_ensemble` opens the chunks lazily as one Dataset. There is no consolidated
single file: the chunk files already are the store (each a plain netCDF file), and
``open_ensemble(d).to_netcdf(path)`` makes one when a single file is wanted.
"""

from __future__ import annotations

import errno
import json
import re
from pathlib import Path

import xarray as xr

from ..conventions import cf_decode
from ..files import is_url, write_text_atomic
from ..schema import FORCE

MANIFEST = "run.json"
CHUNKS = "chunks"


#: A chunk file's name: ``r<first>-<last>.nc``, prefixed ``f<level>-`` in a sweep (and never a path).
CHUNK_NAME = re.compile(r"^(f\d{3}-)?r\d{7}-\d{7}\.nc$")
#: Largest run manifest read (bytes): a million chunk names take about 30 MB.
MAX_MANIFEST_BYTES = 64 * 2**20


def read_manifest(output_dir) -> dict | None:
    """The run manifest of ``output_dir`` (a run folder, or a store's URL:
    ``uqdrape.ensemble.zarrstore``), or None if there is none. A manifest that is not one
    uqdrape wrote (hand-edited, truncated, another program's) raises OSError naming the
    file and what is wrong: its chunk names are paths uqdrape will open, so they must be
    plain chunk file names inside ``chunks/``."""
    from .zarrstore import read_store_manifest

    if is_url(output_dir):
        return read_store_manifest(output_dir)
    path = Path(output_dir) / MANIFEST
    if not path.is_file():
        return None
    if path.stat().st_size > MAX_MANIFEST_BYTES:
        raise corrupt_manifest(path, f"larger than {MAX_MANIFEST_BYTES // 2**20} MB")
    return parse_manifest(path.read_bytes(), path)


def corrupt_manifest(where, why: str) -> OSError:
    """The one-line error for a manifest at ``where`` (path or URL) that is not one uqdrape wrote."""
    return OSError(errno.EIO, f"not a uqdrape run manifest ({why}); run the study again with --no-resume, "
                              "or delete the folder", str(where))


def parse_manifest(text: bytes, where) -> dict:
    """The manifest in ``text`` (read from ``where``), checked as :func:`read_manifest` says."""
    try:
        manifest = json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as err:
        raise corrupt_manifest(where, f"not JSON text: {type(err).__name__}") from None
    if not isinstance(manifest, dict):
        raise corrupt_manifest(where, "not a JSON object")
    study, chunks, size = manifest.get("study"), manifest.get("chunks"), manifest.get("chunk_size")
    if not (isinstance(study, dict) and all(isinstance(v, dict) for v in study.values())
            and isinstance(study.get("study"), dict)):
        raise corrupt_manifest(where, '"study" must be the study record, a table of sections')
    if not (isinstance(chunks, list) and all(isinstance(c, str) and CHUNK_NAME.match(c) for c in chunks)):
        raise corrupt_manifest(where, '"chunks" must be a list of chunk file names such as r0000000-0000063.nc')
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise corrupt_manifest(where, '"chunk_size" must be a positive integer')
    wall = manifest.get("wall_time_s", 0.0)
    if isinstance(wall, bool) or not isinstance(wall, (int, float)) or not 0 <= wall < 1e9:
        raise corrupt_manifest(where, '"wall_time_s" must be a number of seconds')
    return manifest


def write_manifest(output_dir, manifest: dict) -> None:
    """Write the manifest atomically (uqdrape.files: temporary file + rename; a store's as
    one object put)."""
    from .zarrstore import write_store_manifest

    if is_url(output_dir):
        write_store_manifest(output_dir, manifest)
    else:
        write_text_atomic(Path(output_dir) / MANIFEST, json.dumps(manifest, indent=1))


def open_ensemble(output_dir) -> xr.Dataset:
    """All chunks of a finished run as one lazy (dask-backed) Dataset.

    Dims (blankholder_force, realization, i, j, ...), the force dimension of length 1
    without a sweep (``uqdrape.schema``); one dask chunk per chunk file. Raises
    FileNotFoundError if ``output_dir`` holds no run or some chunks are missing (naming
    them: resume the run to compute them), ValueError for a run written before the force
    was always a dimension.
    """
    from .zarrstore import open_store

    if is_url(output_dir):  # a zarr store by fsspec URL (uqdrape.ensemble.zarrstore)
        return open_store(output_dir)
    output_dir = Path(output_dir)
    manifest = read_manifest(output_dir)
    if manifest is None:
        raise FileNotFoundError(
            f"{output_dir} holds no uqdrape run (no {MANIFEST}); run the study first (uqdrape run STUDY)")
    paths = [output_dir / CHUNKS / name for name in manifest["chunks"]]  # in plan order
    missing = [p.name for p in paths if not p.is_file()]
    if missing:
        shown = ", ".join(missing[:5]) + (", ..." if len(missing) > 5 else "")
        raise FileNotFoundError(
            f"{output_dir} is an incomplete run: {len(missing)} of {len(paths)} chunk files missing "
            f"in {CHUNKS}/ ({shown}); resume it (uqdrape run STUDY) to compute them")
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
        raise OSError(errno.EIO, f"the chunk files do not combine into one ensemble ({err}); run the study "
                      "again with --no-resume", str(output_dir / CHUNKS)) from None
    if FORCE not in files.dims:
        files.close()
        raise ValueError(f"{output_dir} was written by an older uqdrape (no {FORCE!r} dimension); "
                         "run its study again with --no-resume")
    ds = cf_decode(files)
    ds.set_close(files.close)  # closing the result closes the chunk files
    if len(paths) > 1:  # an extended run: the study as its last call ran it (the plan's last chunk)
        with xr.open_dataset(paths[-1], engine="netcdf4", decode_cf=False) as last:
            ds.attrs.update({k: v for k, v in last.attrs.items() if k.startswith("study_")})
    # the run's own description, not its first chunk's ("realisations 0-15 at 126 N")
    levels = ", ".join(f"{f:g}" for f in ds[FORCE].values)
    ds.attrs["title"] = (f"uqdrape ensemble: study {ds.attrs.get('study_name', output_dir.name)}, "
                         f"{ds.sizes.get('realization', 0)} realisations at {levels} N")
    return ds
