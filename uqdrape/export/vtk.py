"""The draped net and the mould as VTK unstructured grids (``.vtu``, written by meshio).

The net is one quad per cell whose four nodes are placed; its point data are the
level's fields (``Level.fields``), the fibre directions ``fibre1``, ``fibre2`` (unit),
``fibre_deviation`` (deg, from the nominal fibre-1 direction) and the node indices
``i``, ``j``. The mould is a quad grid of its height field with its unit ``normal`` (a
mesh mould: its own triangles near the net, with its vertex normals). Points and vectors
are in the tool's frame: a mesh mould with a ``press_direction`` is turned back from the
solver's (``Surface.to_tool``).
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import meshio
import numpy as np

from ..drape.net import net_quads
from .directions import fibre_deviation, fibre_directions
from ..files import write_all
from .result import Level, surface_of

#: Quads per side of the exported mould grid.
MOULD_GRID = 120
#: Margin (fraction of the net's plan extent) of the mould grid around the net.
MOULD_MARGIN = 0.15


def net_mesh(level: Level, surface) -> meshio.Mesh:
    """The level's net as a meshio quad mesh with its point data (see the module doc)."""
    P = level.positions
    d1, d2, normal = fibre_directions(P, level.shear, surface)
    valid = np.isfinite(P).all(-1)
    kept, quads = net_quads(valid)
    N = P.shape[0]
    n = (N - 1) // 2
    ii, jj = np.meshgrid(np.arange(-n, n + 1), np.arange(-n, n + 1), indexing="ij")
    data = {name: np.asarray(v).ravel()[kept] for name, v in level.fields.items()}
    tool = surface.to_tool
    data.update(fibre1=tool(d1.reshape(-1, 3)[kept]), fibre2=tool(d2.reshape(-1, 3)[kept]),
                fibre_deviation=fibre_deviation(d1, normal, level.orientation).ravel()[kept],
                i=ii.ravel()[kept].astype(np.int32), j=jj.ravel()[kept].astype(np.int32))
    return meshio.Mesh(tool(P.reshape(-1, 3)[kept]), [("quad", quads)], point_data=data)


def mould_mesh(surface, positions: np.ndarray) -> meshio.Mesh:
    """The mould's height field as a quad grid over the net's plan extent plus a margin
    (clipped to the mould's bounds), cells whose four corners lie on the mould; a mesh mould
    as its own triangles within the net's box plus the margin."""
    if hasattr(surface, "triangles"):
        return _mesh_mould(surface, positions)
    xy = positions[..., :2].reshape(-1, 2)
    xy = xy[np.isfinite(xy).all(-1)]
    lo, hi = xy.min(0), xy.max(0)
    pad = MOULD_MARGIN * (hi - lo).max()
    xmin, xmax, ymin, ymax = getattr(surface, "bounds", (-np.inf, np.inf, -np.inf, np.inf))
    xs = np.linspace(max(lo[0] - pad, xmin), min(hi[0] + pad, xmax), MOULD_GRID + 1)
    ys = np.linspace(max(lo[1] - pad, ymin), min(hi[1] + pad, ymax), MOULD_GRID + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    inside = surface.inside(X, Y)
    P = np.stack([X, Y, np.where(inside, surface.height(X, Y), np.nan)], axis=-1)
    P[~inside] = np.nan
    kept, quads = net_quads(inside)
    normal = surface.normal(X, Y).reshape(-1, 3)[kept]
    return meshio.Mesh(P.reshape(-1, 3)[kept], [("quad", quads)], point_data={"normal": normal})


def _mesh_mould(surface, positions: np.ndarray) -> meshio.Mesh:
    """A mesh mould's triangles with a vertex within the net's 3-D box plus the margin."""
    v, f, vn = surface.triangles()
    p = positions.reshape(-1, 3)
    p = p[np.isfinite(p).all(-1)]
    lo, hi = p.min(0), p.max(0)
    pad = MOULD_MARGIN * (hi - lo).max()
    near = ((v >= lo - pad) & (v <= hi + pad)).all(1)
    f = f[near[f].any(1)]
    used = np.unique(f)
    index = np.full(len(v), -1)
    index[used] = np.arange(used.size)
    return meshio.Mesh(surface.to_tool(v[used]), [("triangle", index[f])],
                       point_data={"normal": surface.to_tool(vn[used])})


def _write(mesh: meshio.Mesh, tmp: Path) -> None:
    meshio.write(tmp, mesh, file_format="vtu")


def vtk_files(levels: list[Level], ds, stem) -> dict:
    """Writers (for ``write_all``) of ``STEM[-LEVEL].vtu`` (the net of each level) and
    ``STEM-mould.vtu``; ``ds`` is the result the levels come from (it names the mould)."""
    stem = Path(stem)
    surface = surface_of(ds)
    writers = {}
    for level in levels:
        name = f"{stem.name}-{level.label}.vtu" if level.label else f"{stem.name}.vtu"
        writers[stem.with_name(name)] = partial(_write, net_mesh(level, surface))
    writers[stem.with_name(f"{stem.name}-mould.vtu")] = partial(_write, mould_mesh(surface, levels[0].positions))
    return writers


def export_vtk(levels: list[Level], ds, stem) -> list[Path]:
    """Write the files of :func:`vtk_files`; returns their paths."""
    return write_all(vtk_files(levels, ds, stem))
