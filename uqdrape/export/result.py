"""Opening a result (a drape file, a run folder or a store URL) and cutting it into force levels.

A :class:`Level` is what every exporter draws: node positions (mm) and point fields on
the (i, j) grid of one drape, or of one force level of an ensemble summarised per node.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from ..conventions import cf_decode, cf_encode
from ..geometry import Surface, build
from ..schema import APPLIED_FORCE, FORCE, REALIZATION

#: Quantiles of the node shear exported for an ensemble.
QUANTILES = (0.05, 0.5, 0.95)


@dataclass
class Level:
    """One drape, or one force level of an ensemble, ready to export.

    label        "" for a single level, else e.g. "126N" (a suffix of file names)
    positions    node positions (N, N, 3) mm; NaN where no realisation placed the node
                 (an ensemble: the mean position over the realisations that placed it)
    shear        node shear (N, N) deg (an ensemble: its mean), opening the fibre angle
    fields       point fields by name, each (N, N): the drape's shear, status, locked, or
                 an ensemble's shear_mean, shear_sd, shear_qXX, p_locked, p_valid
    orientation  nominal plan angle of fibre 1 (deg), the reference of the deviation
    data         the drape Dataset of this level (realisations along ``realization``)
    """

    label: str
    positions: np.ndarray
    shear: np.ndarray
    fields: dict
    orientation: float
    data: xr.Dataset

    @property
    def is_ensemble(self) -> bool:
        return "p_valid" in self.fields


def open_result(path) -> tuple[xr.Dataset, bool]:
    """(Dataset, is_ensemble) of a ``uqdrape drape`` netCDF file, or of a ``uqdrape run``
    folder or store URL (lazy: ``uqdrape.ensemble.open_ensemble``).

    Raises FileNotFoundError for a missing path and ValueError for a file that is not a
    drape result, naming the path."""
    from ..ensemble import at
    from ..files import location

    if not isinstance(location(path), Path) or Path(path).is_dir():  # a store's URL, a run folder
        return at(path).open(), True
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file or run folder")
    try:
        ds = cf_decode(xr.load_dataset(path, engine="netcdf4"))
    except (OSError, ValueError) as err:
        raise ValueError(f"{path}: not a netCDF file ({str(err).splitlines()[0]})") from None
    missing = {"x", "y", "z", "shear", "status"} - set(ds.variables)
    if missing:
        raise ValueError(f"{path}: not a uqdrape drape result (no {', '.join(sorted(missing))})")
    return ds, False


def netcdf_file(ds: xr.Dataset, stem, history: str) -> dict:
    """The writer (for ``write_all``) of result ``ds`` as one CF netCDF file, ``STEM.nc``
    (``STEM`` itself if it ends in .nc), ``history`` the command that made it. A lazy
    ensemble is streamed: dask reads and writes it a chunk at a time."""
    from ..ensemble import write_netcdf

    stem = Path(stem)
    path = stem if stem.suffix == ".nc" else stem.with_name(stem.name + ".nc")
    encoded, encoding = cf_encode(ds, title=ds.attrs.get("title", f"uqdrape result {stem.name}"), history=history)
    return {path: lambda tmp: write_netcdf(encoded, tmp, encoding, target=path)}


def surface_of(ds: xr.Dataset) -> Surface:
    """The mould a result was draped on, rebuilt from its ``geometry_json`` record."""
    record = ds.attrs.get("geometry_json")
    if record is None:
        raise ValueError(f"the result ({ds.attrs.get('geometry', 'unknown mould')}) has no geometry_json "
                         "record of its mould; drape or run it again with this uqdrape version")
    params = json.loads(record)
    return build(params.pop("kind"), **params)


def _drape_level(ds: xr.Dataset, label: str) -> Level:
    one = ds.isel(realization=0)
    P = np.stack([one[c].values for c in ("x", "y", "z")], axis=-1)
    fields = {"shear": one.shear.values, "status": one.status.values.astype(np.int8)}
    if "locked" in one:
        fields["locked"] = one.locked.values.astype(float)
    return Level(label, P, fields["shear"], fields, float(one.orientation), ds)


def _ensemble_level(ds: xr.Dataset, label: str) -> Level:
    from ..stats import node_statistics

    st = node_statistics(ds, "shear", quantiles=QUANTILES)
    placed = (ds.status == 0)
    P = np.stack([ds[c].where(placed).mean(REALIZATION).values for c in ("x", "y", "z")], axis=-1)
    fields = {"shear_mean": st["mean"].values, "shear_sd": st["sd"].values}
    for q in QUANTILES:
        fields[f"shear_q{round(100 * q):02d}"] = st["quantile_value"].sel(quantile=q).values
    if "locked" in ds:
        fields["p_locked"] = ds.locked.mean(REALIZATION, skipna=True).values
    fields["p_valid"] = placed.mean(REALIZATION).values.astype(float)
    return Level(label, P, fields["shear_mean"], fields, float(ds.orientation.mean()), ds)


def levels(ds: xr.Dataset, is_ensemble: bool) -> list[Level]:
    """The levels to export: each force level of an ensemble sweep, each realisation of a
    drape file (a ``drape --blankholder-force`` list gives several), else one."""
    if is_ensemble:
        named = ds.sizes[FORCE] > 1
        return [_ensemble_level(ds.sel({FORCE: f}), f"{float(f):g}N" if named else "") for f in ds[FORCE].values]
    R = ds.sizes[REALIZATION]
    if R == 1:
        return [_drape_level(ds, "")]
    forces = ds[APPLIED_FORCE].values
    named = len(set(forces.tolist())) == R
    return [_drape_level(ds.isel(realization=[r]), f"{forces[r]:g}N" if named else f"r{r}") for r in range(R)]
