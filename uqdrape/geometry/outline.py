"""Closed plan polylines (mm): a part's edge for its cutting pattern, a ply's trim boundary."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..files import csv_number, csv_rows, read_text


def read_trim(path) -> np.ndarray:
    """The closed plan polyline (K, 2) mm of the trim CSV ``path`` (an optional header, then
    x_mm,y_mm a row), closing vertex dropped; FileNotFoundError / ValueError naming the file
    and line, never quoting it (it may be any file named by mistake)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such trim-curve file")
    (top, header), *lines = csv_rows(read_text(path, "trim CSV"), str(path), path=path)
    rows = []
    for k, cells in lines if _header(header) else [(top, header), *lines]:
        try:
            x, y = (csv_number(c) for c in cells[:2]) if len(cells) >= 2 else (None, None)
        except ValueError:
            x = None
        if x is None:
            raise ValueError(f"{path}: line {k}: expected two finite numbers x_mm,y_mm (a header line first "
                             "at most)")
        rows.append((x, y))
    P = np.array(rows, dtype=float).reshape(-1, 2)
    if len(P) > 1 and np.array_equal(P[0], P[-1]):
        P = P[:-1]
    if len(P) < 3:
        raise ValueError(f"{path}: a trim curve needs at least 3 finite vertices x_mm,y_mm, got {len(P)}")
    if abs(polygon_area(P)) == 0.0:
        raise ValueError(f"{path}: the trim curve encloses no area")
    return P


def _header(cells: list[str]) -> bool:
    """Whether the first line ``cells`` of a trim CSV is a header: not two numbers."""
    try:
        return len(cells) < 2 or not all(math.isfinite(float(c)) for c in cells[:2])
    except ValueError:
        return True


def polygon_area(P: np.ndarray) -> float:
    """Signed area (mm^2, positive counter-clockwise) of the closed polygon ``P`` (K, 2)."""
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def contains(P: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Whether each plan point (x, y) (any shape, mm) lies inside the closed polygon ``P``
    (K, 2), by the even-odd rule (a point exactly on an edge may go either way); NaN
    points are outside."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    inside = np.zeros(np.broadcast(x, y).shape, bool)
    for (x0, y0), (x1, y1) in zip(P, np.roll(P, -1, axis=0)):
        crosses = (y0 > y) != (y1 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        inside ^= crosses & (x < at)
    return inside
