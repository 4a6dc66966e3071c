"""Lines of maximum and minimum shear through the crossover.

The max-shear lines are the quadrant diagonals i = +-j (thesis Figs 5.9-5.20); the
min-shear lines are the generator arms (i = 0 or j = 0). Distance from the tip is the
distance along the surface, approximated by the sum of chords between successive nodes
from the crossover (mm).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # annotations only: xarray is imported where a Dataset is made or read
    import xarray as xr

from ..schema import QUADRANTS

#: Steps (si, sj) of the max-shear lines: the signs in each quadrant's label.
_SIGNS = {q: tuple(1 if c == "+" else -1 for c in q) for q in QUADRANTS}
#: Arm labels of the min-shear lines.
ARMS = ("+i", "+j", "-i", "-j")
_ARM_STEP = {"+i": (1, 0), "+j": (0, 1), "-i": (-1, 0), "-j": (0, -1)}


def _walk(ds: xr.Dataset, steps: dict, label: str) -> xr.Dataset:
    import xarray as xr

    n = int(min(ds.sizes["i"], ds.sizes["j"]) // 2)
    k = np.arange(n + 1)
    pieces = []
    for name, (di, dj) in steps.items():
        sel = dict(i=xr.DataArray(di * k, dims="k"), j=xr.DataArray(dj * k, dims="k"))
        pts = ds[["x", "y", "z", "shear"]].sel(sel).drop_vars(["i", "j"])
        chord = np.sqrt(pts.x.diff("k") ** 2 + pts.y.diff("k") ** 2 + pts.z.diff("k") ** 2)
        dist = xr.concat([xr.zeros_like(chord.isel(k=0)), chord.cumsum("k", skipna=False)], dim="k")
        pieces.append(
            xr.Dataset(
                {"distance": dist.transpose(*pts.shear.dims), "shear": pts.shear},
                coords={"k": k},
            )
        )
    out = xr.concat(pieces, dim=xr.DataArray(list(steps), dims=label, name=label))
    out["distance"].attrs = {"units": "mm", "long_name": "distance from the crossover along the surface"}
    out["shear"].attrs = {"units": "degree", "long_name": "node shear angle"}
    out["k"].attrs = {"long_name": "node number along the line from the crossover"}
    return out


def max_shear_lines(ds: xr.Dataset) -> xr.Dataset:
    """Shear and distance from the tip along the four quadrant diagonals.

    ``ds`` is a drape Dataset (variables x, y, z, shear on dims i, j and any leading
    dims). Returns a Dataset with a new ``quadrant`` dim (labels ``QUADRANTS``) and
    ``k`` (node number along the line), holding ``distance`` (mm) and ``shear`` (deg).
    A line is NaN from its first invalid node on.
    """
    return _walk(ds, _SIGNS, "quadrant")


def min_shear_lines(ds: xr.Dataset) -> xr.Dataset:
    """The same along the four generator arms (dim ``arm``, labels ``ARMS``)."""
    return _walk(ds, _ARM_STEP, "arm")
