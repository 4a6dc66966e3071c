"""The one choice of a run's storage: :func:`at` turns a path or URL into its location
(``uqdrape.ensemble.location``), and the readers everyone uses take either."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: xarray is imported where a Dataset is made or read
    import xarray as xr

from ..files import location
from .location import Location
from .store import Folder
from .zarrstore import ZarrStore


def at(target) -> Location:
    """The location of a run: ``target`` itself if it is one; a zarr store for an fsspec URL
    (``s3://bucket/prefix``, ``file:///abs/path``, ``memory://name``: ``files.location``
    tells them apart), else a run folder of netCDF chunks."""
    if isinstance(target, Location):
        return target
    place = location(target)
    return Folder(place) if isinstance(place, Path) else ZarrStore(place)


def open_ensemble(output_dir) -> xr.Dataset:
    """All chunks of the finished run in ``output_dir`` (a run folder or a store's URL) as
    one lazy (dask-backed) Dataset (``Folder.open``, ``ZarrStore.open``)."""
    return at(output_dir).open()


def read_manifest(output_dir) -> dict | None:
    """The run manifest of ``output_dir`` (a run folder or a store's URL), or None if there
    is none; OSError naming it for a manifest uqdrape did not write."""
    return at(output_dir).read_manifest()
