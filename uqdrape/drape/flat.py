"""The flat blank of a drape: where each draped node sits before forming, and how far the
held edge is drawn in.

The flat blank of a realisation is its pin-jointed net laid on a plane: the same solver
run on a plate with the realisation's segment lengths (``seg_i``, ``seg_j``, or the
nominal spacing), orientation, pre-shear and crossover (skew closes the generator paths
on the mould only, so it is left out). With equal segments this is the grid crossover +
s i e1 + s j e2; with random spacing every segment keeps its own length.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ..geometry import Plate
from .solver import drape


def flat_positions(ds: xr.Dataset) -> np.ndarray:
    """Flat-blank plan positions (R, N, N, 2) mm of the realisations of drape Dataset ``ds``."""
    n = int(ds.attrs["rings"])
    spacing = float(ds.attrs["spacing_mm"])
    crossover = np.stack([ds.crossover_x.values, ds.crossover_y.values], axis=-1).reshape(-1, 2)
    seg_i = ds.seg_i.values if "seg_i" in ds else None
    seg_j = ds.seg_j.values if "seg_j" in ds else None
    longest = max([spacing] + [float(np.max(s)) for s in (seg_i, seg_j) if s is not None])
    plate = Plate(float(np.abs(crossover).max()) + 4 * n * longest)
    flat = drape(plate, spacing, n, orientation=ds.orientation.values.ravel(),
                 pre_shear=ds.pre_shear.values.ravel(), crossover=crossover, seg_i=seg_i, seg_j=seg_j)
    return np.stack([flat.x.values, flat.y.values], axis=-1)


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
