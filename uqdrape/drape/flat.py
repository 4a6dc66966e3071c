"""The flat blank of a drape: where each draped node sits before forming, and how far the
held edge is drawn in.

The flat blank of a realisation is its pin-jointed net laid on a plane: the same solver
run on a plate with the realisation's segment lengths (``seg_i``, ``seg_j``, or the
nominal spacing), orientation, pre-shear and crossover (skew closes the generator paths
on the mould only, so it is left out). With equal segments this is the grid crossover +
s i e1 + s j e2; with random spacing every segment keeps its own length.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # annotations only: xarray is imported where a Dataset is made or read
    import xarray as xr

from ..geometry import Plate
from .solver import drape


def flat_positions(ds: xr.Dataset) -> np.ndarray:
    """Flat-blank plan positions (..., N, N, 2) mm of the realisations of drape Dataset
    ``ds``, its leading dims those of its nodes' ``x`` (realization, or an ensemble's
    blankholder_force and realization): the realisations are draped flat as one batch."""
    n = int(ds.attrs["rings"])
    spacing = float(ds.attrs["spacing_mm"])
    lead = ds["x"].isel(i=0, j=0, drop=True)  # one value per realisation, in the nodes' order

    def batch(name, tail=()):
        return ds[name].broadcast_like(lead).transpose(*lead.dims, ...).values.reshape(lead.size, *tail)

    crossover = np.stack([batch("crossover_x"), batch("crossover_y")], axis=-1)
    seg_i, seg_j = (batch(s, ds[s].shape[-2:]) if s in ds else None for s in ("seg_i", "seg_j"))
    longest = max([spacing] + [float(np.max(s)) for s in (seg_i, seg_j) if s is not None])
    plate = Plate(float(np.abs(crossover).max()) + 4 * n * longest)
    flat = drape(plate, spacing, n, orientation=batch("orientation"),
                 pre_shear=batch("pre_shear"), crossover=crossover, seg_i=seg_i, seg_j=seg_j)
    return np.stack([flat.x.values, flat.y.values], axis=-1).reshape(*lead.shape, 2 * n + 1, 2 * n + 1, 2)


def draw_in(ds: xr.Dataset) -> xr.DataArray:
    """Radial draw-in (mm) of the nodes of the net's outermost ring, the edge the
    blank-holder holds (NaN elsewhere): the plan distance of a node from the crossover in
    the realisation's flat blank minus that on the mould, how far the fabric's edge is
    pulled in towards the first contact point."""
    n = int(ds.attrs["rings"])
    flat = flat_positions(ds)
    cx, cy = ds["crossover_x"], ds["crossover_y"]
    inwards = (np.hypot(ds["x"].copy(data=flat[..., 0]) - cx, ds["y"].copy(data=flat[..., 1]) - cy)
               - np.hypot(ds["x"] - cx, ds["y"] - cy))
    edge = (abs(ds["i"]) == n) | (abs(ds["j"]) == n)
    return inwards.where(edge).assign_attrs(units="mm", long_name="radial draw-in of the held edge")
