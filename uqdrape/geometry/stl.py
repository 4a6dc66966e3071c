"""Moulds from triangle meshes (STL), resampled to a smooth height field (mm).

``StlSurface`` reads a mesh with trimesh, finds the top surface on a regular plan grid
(the highest triangle over each grid node: a z-buffer, the same answer as casting a ray
downwards and keeping the first hit) and interpolates it with a cubic
``scipy.interpolate.RectBivariateSpline``, so height and gradient are smooth and the
node solver's Newton steps converge. The spline is fitted by scipy and evaluated by the
compiled mould kernel (``compiled.height_gradient``, kind STL) like every other mould. trimesh's own ray casting needs the optional
``rtree`` package, so the z-buffer uses trimesh's barycentric coordinates instead.
trimesh is imported where a mesh is read or written: its second of import time is not
paid by every process that drapes (ensemble workers, the CLI) for the analytic moulds.

``export_stl`` writes any Surface's height field as a binary STL. The test mesh
``tests/data/hemisphere_r50.stl`` is regenerated from the repository root with::

    python -c "from uqdrape.geometry import Hemisphere, export_stl; export_stl(Hemisphere(50, 60), 'tests/data/hemisphere_r50.stl', resolution_mm=2.5)"
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.ndimage import distance_transform_edt

from ..errors import ParameterError
from . import compiled
from .base import Surface

# Largest number of (triangle, grid node) candidate pairs tested at once (memory bound).
_PAIRS_PER_CHUNK = 2_000_000

#: Largest height grid an STL mould is sampled on (points): 4,000 x 4,000, 128 MB per array.
MAX_GRID_POINTS = 16_000_000


def _grid(lo: float, hi: float, step: float) -> np.ndarray:
    """Nodes from lo to hi inclusive, evenly spaced at most ``step`` apart (at least 4)."""
    n = max(int(math.ceil((hi - lo) / step - 1e-9)) + 1, 4)
    return np.linspace(lo, hi, n)


def _top_heights(triangles: np.ndarray, xg: np.ndarray, yg: np.ndarray) -> np.ndarray:
    """Highest z of the triangles (n, 3, 3) above each node of the plan grid; NaN = no hit.

    Returns an array of shape (len(xg), len(yg)). Triangles that are vertical in plan
    (zero plan area) are skipped: their edges belong to neighbouring triangles.
    """
    import trimesh

    top = np.full((xg.size, yg.size), -np.inf)
    plan = triangles[:, :, :2]
    e1, e2 = plan[:, 1] - plan[:, 0], plan[:, 2] - plan[:, 0]
    area2 = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    scale = np.ptp(plan.reshape(-1, 2), axis=0).max()
    triangles = triangles[area2 > 1e-12 * scale**2]
    plan = triangles[:, :, :2]
    x0, dx = xg[0], xg[1] - xg[0]
    y0, dy = yg[0], yg[1] - yg[0]
    # grid index ranges covered by each triangle's plan bounding box
    ix0 = np.clip(np.ceil((plan[:, :, 0].min(1) - x0) / dx - 1e-9), 0, xg.size).astype(np.int64)
    ix1 = np.clip(np.floor((plan[:, :, 0].max(1) - x0) / dx + 1e-9), -1, xg.size - 1).astype(np.int64)
    iy0 = np.clip(np.ceil((plan[:, :, 1].min(1) - y0) / dy - 1e-9), 0, yg.size).astype(np.int64)
    iy1 = np.clip(np.floor((plan[:, :, 1].max(1) - y0) / dy + 1e-9), -1, yg.size - 1).astype(np.int64)
    nx = np.maximum(ix1 - ix0 + 1, 0)
    ny = np.maximum(iy1 - iy0 + 1, 0)
    count = nx * ny
    ends = np.cumsum(count)
    start = 0
    while start < triangles.shape[0]:
        # take triangles until the chunk holds enough candidate pairs (at least one)
        base = ends[start - 1] if start else 0
        stop = max(int(np.searchsorted(ends, base + _PAIRS_PER_CHUNK, side="right")), start + 1)
        sl = slice(start, stop)
        start = stop
        c = count[sl]
        if c.sum() == 0:
            continue
        tri = np.repeat(np.arange(sl.start, sl.stop), c)
        local = np.arange(c.sum()) - np.repeat(np.cumsum(c) - c, c)
        ix = ix0[tri] + local % nx[tri]
        iy = iy0[tri] + local // nx[tri]
        pts = np.stack([xg[ix], yg[iy]], axis=1)
        bary = trimesh.triangles.points_to_barycentric(plan[tri], pts)
        hit = (bary >= -1e-9).all(axis=1)
        z = np.einsum("nk,nk->n", bary[hit], triangles[tri[hit], :, 2])
        np.maximum.at(top, (ix[hit], iy[hit]), z)
    top[np.isneginf(top)] = np.nan
    return top


class StlSurface(Surface):
    """Top surface of a triangle mesh (STL, mm) as a smooth height field.

    The mesh is sampled on a plan grid of spacing ``resolution_mm`` (mm) spanning its
    bounding box; the highest triangle over each node gives the height. A bicubic
    interpolating spline through these heights gives ``height`` and ``gradient``
    (continuous slope; it rings slightly, about a grid step wide, at creases such as a
    rim meeting a flange). ``inside`` is the mesh's plan footprint: True inside the
    mesh's plan bounding box where the nearest grid node lies under the mesh. Nodes outside the footprint take the height
    of the nearest covered node so the spline stays tame near the edge.
    """

    name = "stl"

    def __init__(self, path, resolution_mm: float = 2.0):
        self.path = Path(path)
        if not self.path.is_file():
            raise ParameterError("path", f"path: STL file {str(self.path)!r} does not exist")
        try:
            res = float(resolution_mm)
        except (TypeError, ValueError):
            res = float("nan")
        if not (math.isfinite(res) and res > 0):
            raise ParameterError("resolution_mm", f"resolution_mm must be a positive length (mm), got {resolution_mm!r}")
        self.resolution_mm = res
        import trimesh

        try:
            mesh = trimesh.load_mesh(self.path, file_type="stl")
        except Exception as err:  # trimesh raises assorted types on unreadable files
            # (on a file that is neither binary nor ASCII STL, even a missing optional module)
            why = "not a binary or ASCII STL file" if isinstance(err, ImportError) else str(err)
            raise ParameterError("path", f"path: cannot read {str(self.path)!r} as STL: {why}") from err
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise ParameterError("path", f"path: {str(self.path)!r} holds no triangles")
        (xmin, ymin, _), (xmax, ymax, _) = mesh.bounds
        if not (xmax - xmin > 0 and ymax - ymin > 0):
            raise ParameterError("path", f"path: mesh {str(self.path)!r} has no extent in plan")
        points = math.ceil((xmax - xmin) / res + 1) * math.ceil((ymax - ymin) / res + 1)
        if points > MAX_GRID_POINTS:
            raise ParameterError("resolution_mm",
                                 f"resolution_mm = {res:g} mm makes a height grid of {points:,} points over the "
                             f"mesh's {xmax - xmin:.4g} x {ymax - ymin:.4g} mm plan, more than {MAX_GRID_POINTS:,}; "
                             "use a coarser resolution")
        self._x = _grid(xmin, xmax, res)
        self._y = _grid(ymin, ymax, res)
        top = _top_heights(np.asarray(mesh.triangles, dtype=float), self._x, self._y)
        self._hit = np.isfinite(top)
        if not self._hit.any():
            raise ParameterError("path", f"path: mesh {str(self.path)!r} covers no grid node at {res} mm")
        # fill uncovered nodes with their nearest covered node's height
        idx = distance_transform_edt(~self._hit, return_distances=False, return_indices=True)
        filled = top[idx[0], idx[1]]
        tx, ty, coef = RectBivariateSpline(self._x, self._y, filled, kx=3, ky=3, s=0).tck
        self.bounds = (float(xmin), float(xmax), float(ymin), float(ymax))
        self.size = 0.5 * max(xmax - xmin, ymax - ymin)
        header = [self._x[0], self._x[1] - self._x[0], self._x.size, self._y[0], self._y[1] - self._y[0],
                  self._y.size, *self.bounds, tx.size, ty.size]
        self.kernel = (compiled.STL, np.concatenate([header, tx, ty, coef, self._hit.ravel()]).astype(float))

    def params(self):
        return {"path": str(self.path), "resolution_mm": self.resolution_mm}


def export_stl(surface: Surface, path, half_width: float | None = None, resolution_mm: float = 2.0) -> Path:
    """Write ``surface``'s height field as a binary STL (mm); returns the path.

    The field is triangulated on a regular plan grid (spacing at most ``resolution_mm``)
    over the square |x|, |y| <= ``half_width`` if given, else over ``surface.bounds``;
    two triangles per grid cell, kept where all three corners are ``inside`` the
    domain, facing up. Only the top surface is written (an open sheet, not a solid).
    """
    res = float(resolution_mm)
    if not (math.isfinite(res) and res > 0):
        raise ParameterError("resolution_mm", f"resolution_mm must be a positive length (mm), got {resolution_mm!r}")
    if half_width is not None:
        w = float(half_width)
        if not (math.isfinite(w) and w > 0):
            raise ValueError(f"half_width must be a positive length in mm, got {half_width!r}")
        xmin, xmax, ymin, ymax = -w, w, -w, w
    else:
        try:
            xmin, xmax, ymin, ymax = surface.bounds
        except AttributeError:
            raise ValueError(
                f"half_width is required: {type(surface).__name__} has no bounds"
            ) from None
    xg, yg = _grid(xmin, xmax, res), _grid(ymin, ymax, res)
    X, Y = np.meshgrid(xg, yg, indexing="ij")
    vertices = np.stack([X, Y, surface.height(X, Y)], axis=-1).reshape(-1, 3)
    ok = np.asarray(surface.inside(X, Y)).ravel()
    node = np.arange(X.size).reshape(X.shape)
    a, b = node[:-1, :-1].ravel(), node[1:, :-1].ravel()  # (i, j), (i+1, j)
    c, d = node[1:, 1:].ravel(), node[:-1, 1:].ravel()  # (i+1, j+1), (i, j+1)
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    faces = faces[ok[faces].all(axis=1)]
    if faces.size == 0:
        raise ValueError("no triangle lies inside the surface's domain; check half_width")
    import trimesh

    out = Path(path)
    trimesh.Trimesh(vertices=vertices, faces=faces, process=False).export(out, file_type="stl")
    return out
