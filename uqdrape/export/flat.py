"""The flat pattern: where each draped node sits in the flat blank, and the blank outline.

A realisation's flat blank is ``uqdrape.drape.flat_positions``. An ensemble's flat pattern is the mean flat position over the realisations that placed
the node on the mould, with the fraction that did (``p_valid``).
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import ezdxf
import numpy as np

from ..drape import flat_positions
from ..files import write_all
from .result import Level


def flat_pattern(level: Level) -> tuple[np.ndarray, np.ndarray]:
    """(flat positions (N, N, 2) mm, fraction of realisations placing each node (N, N));
    positions are NaN where no realisation placed the node on the mould."""
    flat = flat_positions(level.data)
    placed = (level.data.status.values == 0).reshape(flat.shape[:-1])
    count = placed.sum(0)
    with np.errstate(invalid="ignore"):
        mean = np.where(placed[..., None], flat, 0.0).sum(0) / count[..., None]
    mean[count == 0] = np.nan
    return mean, count / placed.shape[0]


def outline(valid: np.ndarray) -> list[np.ndarray]:
    """Closed boundary loops of the cells whose four nodes are ``valid`` (N, N): each an
    array (K, 2) of node indices (array positions), counter-clockwise in (i, j)."""
    cells = valid[:-1, :-1] & valid[1:, :-1] & valid[1:, 1:] & valid[:-1, 1:]
    nxt = {}
    for a, b in zip(*np.nonzero(cells)):
        ring = [(a, b), (a + 1, b), (a + 1, b + 1), (a, b + 1)]
        for p, q in zip(ring, ring[1:] + ring[:1]):
            nxt.setdefault((int(p[0]), int(p[1])), []).append((int(q[0]), int(q[1])))
    edges = {(p, q) for p, qs in nxt.items() for q in qs}
    boundary = {}
    for p, q in sorted(edges):
        if (q, p) not in edges:
            boundary.setdefault(p, []).append(q)
    loops = []
    while boundary:
        start = min(boundary)
        loop, p = [start], start
        while True:
            q = boundary[p].pop()
            if not boundary[p]:
                del boundary[p]
            if q == start:
                break
            loop.append(q)
            p = q
        loops.append(np.array(loop))
    return loops


def _csv(tmp: Path, header: str, rows: np.ndarray, fmt: str) -> None:
    np.savetxt(tmp, rows, fmt=fmt, delimiter=",", header=header, comments="")


def _dxf(tmp: Path, nodes: np.ndarray, loops: list[np.ndarray]) -> None:
    doc = ezdxf.new("R2010", units=ezdxf.units.MM)
    doc.header["$MEASUREMENT"] = 1  # metric
    doc.layers.add("NODES", color=8)
    doc.layers.add("OUTLINE", color=1)
    msp = doc.modelspace()
    for x, y in nodes:
        msp.add_point((x, y), dxfattribs={"layer": "NODES"})
    for loop in loops:
        msp.add_lwpolyline([tuple(p) for p in loop], close=True, dxfattribs={"layer": "OUTLINE"})
    doc.saveas(tmp)


def flat_files(levels: list[Level], stem) -> dict:
    """Writers (for ``write_all``) of, per level, ``STEM[-LEVEL]-flat-nodes.csv`` (i, j, x_mm, y_mm[, p_valid]),
    ``-flat-outline.csv`` (loop, i, j, x_mm, y_mm) and ``-flat.dxf`` (layers NODES:
    points, OUTLINE: closed polylines; units mm)."""
    stem = Path(stem)
    writers = {}
    for level in levels:
        base = f"{stem.name}-{level.label}" if level.label else stem.name
        flat, p_valid = flat_pattern(level)
        N = flat.shape[0]
        n = (N - 1) // 2
        valid = np.isfinite(flat).all(-1)
        ai, aj = np.nonzero(valid)
        nodes = flat[ai, aj]
        loops = outline(valid)
        extra = [p_valid[ai, aj]] if level.is_ensemble else []  # an ensemble adds the share of drapes placing a node
        rows = np.column_stack([ai - n, aj - n, nodes, *extra])
        header = "i,j,x_mm,y_mm" + (",p_valid" if extra else "")
        fmt = ["%d", "%d"] + ["%.17g"] * (rows.shape[1] - 2)
        lines = [np.column_stack([np.full(len(loop), k), loop - n, flat[loop[:, 0], loop[:, 1]]])
                 for k, loop in enumerate(loops)]
        writers[stem.with_name(f"{base}-flat-nodes.csv")] = partial(_csv, header=header, rows=rows, fmt=fmt)
        writers[stem.with_name(f"{base}-flat-outline.csv")] = partial(
            _csv, header="loop,i,j,x_mm,y_mm", rows=np.concatenate(lines) if lines else np.zeros((0, 5)),
            fmt=["%d", "%d", "%d", "%.17g", "%.17g"])
        writers[stem.with_name(f"{base}-flat.dxf")] = partial(_dxf, nodes=nodes, loops=[flat[lp[:, 0], lp[:, 1]]
                                                                                       for lp in loops])
    return writers


def export_flat(levels: list[Level], stem) -> list[Path]:
    """Write the files of :func:`flat_files`; returns their paths."""
    return write_all(flat_files(levels, stem))
