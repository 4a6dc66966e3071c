"""Where a run lives, for everything that reads one: a run folder (a plain path: netCDF
chunk files, ``uqdrape.ensemble.store``) or one zarr store (an fsspec URL:
``uqdrape.ensemble.zarrstore``).

``open_ensemble`` and ``read_manifest`` take either. The files made beside a run's
ensemble go through here: a run's own netCDF files (sensitivity indices, a design's
``design.nc``) by :func:`read_dataset` / :func:`write_dataset`, the folders of files made
from it (a report, exports) by :func:`made_from`. In a run folder they are files in it;
in a store, objects under its URL, each put whole (``zarrstore.publish``).
"""

from __future__ import annotations

import contextlib
import tempfile
from pathlib import Path

import xarray as xr

from .chunk import write_atomic
from ..files import is_url
from .zarrstore import fetch, publish


def run_name(run) -> str:
    """The last part of a run folder's path or a store's URL (``s3://b/runs/x`` -> ``x``)."""
    return str(run).rstrip("/").rsplit("/", 1)[-1] if is_url(run) else Path(run).name


def read_dataset(run, name: str) -> xr.Dataset | None:
    """The run's own netCDF file ``name`` (e.g. ``sensitivity.nc``), read into memory;
    None if the run has none. OSError / ValueError as xarray's for an unreadable file."""
    if not is_url(run):
        path = Path(run) / name
        return xr.load_dataset(path, engine="netcdf4") if path.is_file() else None
    with tempfile.TemporaryDirectory(prefix="uqdrape-") as tmp:
        local = Path(tmp) / name
        return xr.load_dataset(local, engine="netcdf4") if fetch(run, name, local) else None


def write_dataset(run, name: str, ds: xr.Dataset, encoding: dict | None = None) -> Path | str:
    """Write ``ds`` as the run's own netCDF file ``name``, whole (a run folder: written
    beside, then renamed; a store: uploaded, then moved); return its path or URL."""
    if not is_url(run):
        return write_atomic(ds, Path(run) / name, encoding)
    with tempfile.TemporaryDirectory(prefix="uqdrape-") as tmp:
        publish(write_atomic(ds, Path(tmp) / name, encoding), run, name)
    return f"{str(run).rstrip('/')}/{name}"


@contextlib.contextmanager
def made_from(run, sub: str):
    """A local folder for the files made from ``run`` into its subfolder ``sub`` (its
    report, its exports): ``run/sub`` of a run folder. For a store, a temporary folder
    whose files are put under ``URL/sub/`` when the block ends without error, in the
    order they were written (a report's index.html last), each whole; a failed block
    puts nothing. ``where(path)`` of the yielded folder names a file's final place."""
    if not is_url(run):
        yield Made(Path(run) / sub, None)
        return
    with tempfile.TemporaryDirectory(prefix="uqdrape-") as tmp:
        made = Made(Path(tmp) / sub, f"{str(run).rstrip('/')}/{sub}")
        yield made
        for path in sorted((p for p in made.folder.rglob("*") if p.is_file()), key=lambda p: p.stat().st_mtime_ns):
            publish(path, run, f"{sub}/{path.relative_to(made.folder).as_posix()}")


class Made:
    """The local ``folder`` of :func:`made_from` and, for a store, the URL it goes to."""

    def __init__(self, folder: Path, url: str | None):
        self.folder, self.url = folder, url

    def where(self, path) -> Path | str:
        """The final place of ``path`` written in the folder: itself, or its URL in the store."""
        path = Path(path)
        return path if self.url is None else f"{self.url}/{path.relative_to(self.folder).as_posix()}"
