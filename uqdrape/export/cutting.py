"""Cutting patterns: the part's edge mapped into the flat blank, as a cutting table reads it.

The edge is a closed polyline in plan (mm): a trim-curve CSV (columns ``x_mm,y_mm``, one
vertex a row, a header line allowed, closing vertex optional) or the mould's own
outline where it has one (the rim of a hemisphere, the base circle of a cone or nose
cone). It is resampled to at most a quarter of the fibre spacing per segment; each point
is located in the draped net in plan (the triangles of ``fe.locate``) and carried into
the flat blank with the same barycentric weights, so it keeps its place among the
yarns.

The pattern is drawn in the fabric's own axes: origin at the seed point (the first
contact, the net's node (0, 0)), x along fibre 1 in the flat blank, mm. A cutter lays
the seed on the blank and the x axis along the roll's fibre-1 direction.

For an ensemble the pattern is the mean over the drapes of each edge point's fabric
position (CUT), and the envelope (ENVELOPE) the 2.5 % and 97.5 % quantiles over the
drapes of each point's offset from it along the outline's outward normal: the band in
which 95 % of the drapes put that point of the edge.

DXF layers (units mm): CUT (the closed outline), ENVELOPE (inner and outer limits, an
ensemble only), FIBRE (arrows along fibre 1 and fibre 2 from the seed), SEED (a point
and a cross at the seed), LABEL (the ply label and what the file is). The CSV has one
row per edge point.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import ezdxf
import numpy as np

from ..drape import flat_positions
from ..drape.net import net_quads
from ..errors import ParameterError
from ..files import write_all
from ..geometry.outline import polygon_area, read_trim
from ..schema import REALIZATION
from .fe import locate
from .result import Level, surface_of

#: Moulds with an outline of their own: kind -> the attribute holding its plan radius (mm).
OUTLINE_RADIUS = {"hemisphere": "radius", "cone": "base_radius", "nose_cone": "base_radius"}
#: Vertices of a mould's own (circular) outline; a multiple of 4, so the axes are vertices.
OUTLINE_VERTICES = 720
#: Longest segment of the resampled edge, in fibre spacings.
RESAMPLE = 0.25
#: Length of the fibre arrows, as a fraction of the pattern's size.
ARROW = 0.15


def mould_outline(surface) -> np.ndarray:
    """The mould's own outline (K, 2) mm in plan, counter-clockwise; ValueError if it has none."""
    attr = OUTLINE_RADIUS.get(surface.name)
    if attr is None:
        raise ParameterError("trim", f"the mould ({surface.name}) has no outline of its own; give the part's "
                             f"edge as a trim curve (a CSV of x_mm,y_mm), moulds with one: "
                             f"{', '.join(OUTLINE_RADIUS)}")
    t = 2 * np.pi * np.arange(OUTLINE_VERTICES) / OUTLINE_VERTICES
    return getattr(surface, attr) * np.column_stack([np.cos(t), np.sin(t)])


def perimeter(P: np.ndarray) -> float:
    """Length (mm) of the closed polygon ``P`` (K, 2)."""
    return float(np.linalg.norm(P - np.roll(P, -1, axis=0), axis=1).sum())


def resample(P: np.ndarray, step: float) -> np.ndarray:
    """The closed polygon ``P`` with every segment split into equal parts no longer than ``step``."""
    Q = np.roll(P, -1, axis=0)
    parts = np.maximum(1, np.ceil(np.linalg.norm(Q - P, axis=1) / step).astype(int))
    return np.concatenate([P[k] + np.arange(m)[:, None] / m * (Q[k] - P[k]) for k, m in enumerate(parts)])


def fabric_axes(flat: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Origin (the seed's flat position) and the unit fibre-1 direction of a flat blank
    ``flat`` (N, N, 2) with centre index ``n``."""
    seed = flat[n, n]
    e = flat[n + 1, n] - seed
    return seed, e / np.linalg.norm(e)


def to_fabric(points: np.ndarray, seed: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Flat-blank ``points`` (..., 2) in the fabric axes (origin ``seed``, x along ``e1``)."""
    d = points - seed
    return np.stack([d[..., 0] * e1[0] + d[..., 1] * e1[1], -d[..., 0] * e1[1] + d[..., 1] * e1[0]], axis=-1)


def edge_in_blank(positions: np.ndarray, flat: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """Fabric-axes flat positions (K, 2) mm of the plan ``edge`` points (K, 2) on the draped
    net ``positions`` (N, N, 3) with flat blank ``flat`` (N, N, 2); NaN off the net."""
    n = (len(positions) - 1) // 2
    valid = np.isfinite(positions).all(-1)
    kept, quads = net_quads(valid)
    if not len(quads):
        return np.full(edge.shape, np.nan)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    plan = positions.reshape(-1, 3)[kept][:, :2]
    tri, lam = locate(edge, plan[tris])
    seed, e1 = fabric_axes(flat, n)
    corners = to_fabric(flat.reshape(-1, 2)[kept], seed, e1)[tris[np.maximum(tri, 0)]]
    out = (lam[..., None] * corners).sum(1)
    out[tri < 0] = np.nan
    return out


def _outward_normals(P: np.ndarray) -> np.ndarray:
    """Unit outward normals (K, 2) at the vertices of the closed polygon ``P`` (central differences)."""
    t = np.roll(P, -1, axis=0) - np.roll(P, 1, axis=0)
    n = np.column_stack([t[:, 1], -t[:, 0]]) / np.linalg.norm(t, axis=1, keepdims=True)
    return n if polygon_area(P) > 0 else -n


def cut_pattern(level: Level, edge: np.ndarray) -> dict:
    """The cutting pattern of ``level`` along the plan ``edge`` (K, 2): ``outline`` (K, 2)
    fabric-axes mm, the fibre directions ``fibre1``, ``fibre2`` (unit, fabric axes) and, for
    an ensemble, ``inner``, ``outer`` (K, 2), the normal offsets ``q025``, ``q975`` (K,) mm
    and ``drapes`` (K,), how many drapes placed each point. ValueError names the points
    off the net."""
    data = level.data
    n = int(data.attrs["rings"])
    flat = flat_positions(data)
    placed = data.status.values == 0
    P = np.stack([np.where(placed, data[c].values, np.nan) for c in ("x", "y", "z")], axis=-1)
    per = np.array([edge_in_blank(P[r], flat[r], edge) for r in range(len(P))])
    count = np.isfinite(per).all(-1).sum(0)
    missing = np.flatnonzero(count == 0 if level.is_ensemble else count < len(P))
    if missing.size:
        x, y = edge[missing[0]]
        raise ValueError(f"the part's edge leaves the draped net at {missing.size} of its {len(edge)} points "
                         f"(first at x = {x:.1f}, y = {y:.1f} mm): drape more rings, or check the edge's units "
                         "and placement")
    outline = np.nanmean(per, axis=0)
    d2 = np.array([to_fabric(f[n, n + 1], *fabric_axes(f, n)) for f in flat]).mean(0)  # pre-shear may vary
    out = {"outline": outline, "fibre1": np.array([1.0, 0.0]), "fibre2": d2 / np.linalg.norm(d2)}
    if level.is_ensemble:
        normal = _outward_normals(outline)
        offsets = np.einsum("rkc,kc->rk", per - outline, normal)
        q025, q975 = np.nanquantile(offsets, [0.025, 0.975], axis=0)
        out.update(inner=outline + q025[:, None] * normal, outer=outline + q975[:, None] * normal,
                   q025=q025, q975=q975, drapes=count)
    return out


def _csv(tmp: Path, edge: np.ndarray, pattern: dict, note: str) -> None:
    cols = [np.arange(len(edge)), edge, pattern["outline"]]
    header = "point,x_plan_mm,y_plan_mm,x_mm,y_mm"
    if "q025" in pattern:
        cols += [pattern["q025"], pattern["q975"], pattern["drapes"]]
        header += ",offset_q025_mm,offset_q975_mm,drapes"
    rows = np.column_stack(cols)
    fmt = ["%d"] + ["%.17g"] * (rows.shape[1] - 1 - ("q025" in pattern)) + (["%d"] if "q025" in pattern else [])
    np.savetxt(tmp, rows, fmt=fmt, delimiter=",", header=f"# {note}\n{header}", comments="")


def _dxf(tmp: Path, pattern: dict, ply: str, note: str) -> None:
    doc = ezdxf.new("R2010", units=ezdxf.units.MM)
    doc.header["$MEASUREMENT"] = 1  # metric
    for name, colour in (("CUT", 1), ("ENVELOPE", 3), ("FIBRE", 5), ("SEED", 6), ("LABEL", 7)):
        doc.layers.add(name, color=colour)
    msp = doc.modelspace()
    outline = pattern["outline"]
    msp.add_lwpolyline([tuple(p) for p in outline], close=True, dxfattribs={"layer": "CUT"})
    for side in ("inner", "outer"):
        if side in pattern:
            msp.add_lwpolyline([tuple(p) for p in pattern[side]], close=True, dxfattribs={"layer": "ENVELOPE"})
    size = float(np.ptp(outline, axis=0).max())
    for key in ("fibre1", "fibre2"):
        tip = ARROW * size * pattern[key]
        back = -0.2 * tip
        side = 0.1 * np.array([-tip[1], tip[0]])
        msp.add_line((0.0, 0.0), tuple(tip), dxfattribs={"layer": "FIBRE"})
        for wing in (tip + back + side, tip + back - side):
            msp.add_line(tuple(tip), tuple(wing), dxfattribs={"layer": "FIBRE"})
        msp.add_text(key.replace("fibre", "fibre "), height=0.02 * size,
                     dxfattribs={"layer": "FIBRE"}).set_placement(tuple(1.05 * tip))
    msp.add_point((0.0, 0.0), dxfattribs={"layer": "SEED"})
    c = 0.02 * size
    msp.add_line((-c, 0.0), (c, 0.0), dxfattribs={"layer": "SEED"})
    msp.add_line((0.0, -c), (0.0, c), dxfattribs={"layer": "SEED"})
    top = float(outline[:, 1].max())
    msp.add_text(ply, height=0.04 * size, dxfattribs={"layer": "LABEL"}).set_placement((0.0, top + 0.06 * size))
    msp.add_text(note, height=0.015 * size, dxfattribs={"layer": "LABEL"}).set_placement(
        (float(outline[:, 0].min()), top + 0.02 * size))
    doc.saveas(tmp)


def cut_files(levels: list[Level], ds, stem, *, trim=None, ply: str = "ply") -> dict:
    """Writers (for ``write_all``) of, per level, ``STEM[-LEVEL]-cut.dxf`` (the layers of the
    module doc) and ``-cut.csv`` (point, x_plan_mm, y_plan_mm, x_mm, y_mm[, offset_q025_mm,
    offset_q975_mm, drapes]); ``trim``: the trim-curve CSV (default: the mould's outline)."""
    stem = Path(stem)
    surface = surface_of(ds)
    plan = read_trim(trim) if trim is not None else mould_outline(surface)
    edge = resample(plan, RESAMPLE * float(ds.attrs["spacing_mm"]))
    source = f"trim curve {Path(trim).name}" if trim is not None else f"the {surface.name}'s outline"
    writers = {}
    for level in levels:
        base = f"{stem.name}-{level.label}" if level.label else stem.name
        label = f"{ply} {level.label}".strip()
        pattern = cut_pattern(level, edge)
        what = (f"mean over {level.data.sizes[REALIZATION]} drapes; ENVELOPE: 2.5-97.5 % of each edge point's "
                "normal offset" if level.is_ensemble else "one drape")
        note = (f"uqdrape cutting pattern {label}: CUT = {source} in the flat blank ({what}); mm, fabric axes: "
                "origin the seed point, x along fibre 1")
        writers[stem.with_name(f"{base}-cut.dxf")] = partial(_dxf, pattern=pattern, ply=label, note=note)
        writers[stem.with_name(f"{base}-cut.csv")] = partial(_csv, edge=edge, pattern=pattern, note=note)
    return writers


def export_cut(levels: list[Level], ds, stem, *, trim=None, ply: str = "ply") -> list[Path]:
    """Write the files of :func:`cut_files`; returns their paths."""
    return write_all(cut_files(levels, ds, stem, trim=trim, ply=ply))
