"""Statistics of a laminate: its plies (``uqdrape.schema.PLY``) taken together.

- ``fibre_deviation``: each node's fibre-1 direction against its ply's nominal angle. The
  direction is the central difference of the node positions along i (one-sided at the
  net's edge and beside a missing node), measured as an angle in plan (the x-y projection,
  which is how a ply book and a rosette give angles); the nominal angle is
  ``rosette_deg + ply_angle``. Fibres are axes, so the deviation is wrapped into
  [-90, 90) deg. It holds the misalignment, a drawn rosette error and what forming turns.
  On a wall seen edge-on in plan the plan angle means nothing: read it on the flat blank.
- ``laminate_lock``: P(any ply locked) per force level, a node of any ply past its
  locking angle in a drape, with its Wilson score interval.
- ``tool_lock_map``: the probability that the tool is covered by a locked node of any
  ply, on a plan raster over all the nets (step: half the finest ply spacing). A raster
  point takes, in each ply, the locked state of the ply's node nearest to it in plan (at
  its ensemble-mean position, within that ply's spacing); a point no ply reaches is NaN.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from scipy.spatial import cKDTree

from ..schema import FORCE, PLY, PLY_ANGLE, PLY_ATTR, REALIZATION
from .exceedance import wilson_interval


def fibre_deviation(ds: xr.Dataset) -> xr.DataArray:
    """Plan angle of each node's fibre-1 direction minus its ply's nominal angle (deg,
    wrapped into [-90, 90)), dims as ``ds["x"]``; NaN where the node is not placed."""
    dx, dy = ds["x"].differentiate("i"), ds["y"].differentiate("i")
    nominal = ds.attrs.get("rosette_deg", 0.0) + ds[PLY_ANGLE]
    dev = (np.degrees(np.arctan2(dy, dx)) - nominal + 90.0) % 180.0 - 90.0
    return dev.where(ds["x"].notnull()).rename("fibre_deviation").assign_attrs(
        units="degree", long_name="fibre-1 plan angle minus the ply's nominal angle")


def laminate_lock(ds: xr.Dataset, confidence: float = 0.95) -> xr.Dataset:
    """P(any ply locked): per force level, the share of drapes in which a node of any ply
    is locked, ``count`` of them out of ``n`` valid realisations, and its Wilson
    ``lower``/``upper`` limits at ``confidence``; per ply the same as ``p_ply``."""
    locked = (ds["locked"] > 0).any(["i", "j"])
    any_ply = locked.any(PLY)
    n = ds.sizes[REALIZATION]
    k = any_ply.sum(REALIZATION)
    lo, hi = wilson_interval(k.values, n, confidence)
    return xr.Dataset({"p_any": k / n, "count": k, "lower": (k.dims, np.asarray(lo)),
                       "upper": (k.dims, np.asarray(hi)), "p_ply": locked.mean(REALIZATION)},
                      attrs={"n": n, "confidence": confidence})


def tool_lock_map(ds: xr.Dataset) -> xr.DataArray:
    """P(a locked node of any ply) on a plan raster (dims blankholder_force, y, x; mm
    coordinates), as in the module docstring."""
    pos = ds[["x", "y"]].mean(REALIZATION).compute()
    own = f"{PLY_ATTR}spacing_mm"
    spacing = np.broadcast_to(ds[own].values if own in ds.coords else float(ds.attrs["spacing_mm"]), (ds.sizes[PLY],))
    step = 0.5 * float(np.min(spacing))
    x, y = pos["x"].values, pos["y"].values
    grid_x = np.arange(np.nanmin(x), np.nanmax(x) + step, step)
    grid_y = np.arange(np.nanmin(y), np.nanmax(y) + step, step)
    gx, gy = np.meshgrid(grid_x, grid_y)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    locked = (ds["locked"] > 0).transpose(FORCE, PLY, REALIZATION, "i", "j").values
    out = np.full((ds.sizes[FORCE], points.shape[0]), np.nan)
    for f in range(ds.sizes[FORCE]):
        hit = np.zeros((ds.sizes[REALIZATION], points.shape[0]), bool)
        reached = np.zeros(points.shape[0], bool)
        for p in range(ds.sizes[PLY]):
            xy = np.column_stack([pos["x"].values[f, p].ravel(), pos["y"].values[f, p].ravel()])
            valid = np.flatnonzero(np.isfinite(xy).all(1))
            dist, idx = cKDTree(xy[valid]).query(points, distance_upper_bound=spacing[p])
            near = np.isfinite(dist)
            reached |= near
            hit[:, near] |= locked[f, p].reshape(locked.shape[2], -1)[:, valid[idx[near]]]
        out[f] = np.where(reached, hit.mean(0), np.nan)
    return xr.DataArray(out.reshape(-1, grid_y.size, grid_x.size), dims=(FORCE, "y", "x"),
                        coords={FORCE: ds[FORCE].values, "y": grid_y, "x": grid_x}, name="p_any_ply_locked",
                        attrs={"units": "1", "long_name": "probability of a locked node of any ply"})
