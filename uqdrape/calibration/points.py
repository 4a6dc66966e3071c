"""Measured local fibre angles on a flat fabric sample, read from a CSV.

Format (a header row after any ``#`` comment lines, columns in any order, extra columns refused so a misspelt
optional column is not silently ignored)::

    x_mm,y_mm,angle_deg,fibre_set[,sd_deg]
    12.5,40.0,42.1,1
    37.5,40.0,136.2,2

``x_mm``, ``y_mm``: the point on the sample (mm, any origin). ``angle_deg``: the plan
direction of the measured fibre, degrees anticlockwise from the sample's x axis (the
weft datum of the thesis's Table 5.1); a fibre is a line, so 42 and 222 are the same.
``fibre_set``: 1 or 2, which of the two tow sets was measured. ``sd_deg`` (optional): the
measurement's own standard deviation (deg, >= 0), e.g. the scatter of repeated readings.

Every problem raises :class:`PointsError`, one line naming the file, the row (the
file's line number) and the column.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..files import QUOTED_CELL, FileFormatError, csv_number, csv_rows, read_text

REQUIRED_COLUMNS = ("x_mm", "y_mm", "angle_deg", "fibre_set")
SD_COLUMN = "sd_deg"
FIBRE_SETS = (1, 2)
#: Most points fitted: the likelihood of scattered points factors their n x n covariance,
#: O(n^3) a step over hundreds of steps and a dozen n x n arrays (2,500 points: 50 MB
#: each, minutes of fitting).
MAX_POINTS = 2500
#: Largest |x_mm|, |y_mm| (mm: a 100 m sample) and measurement sd (deg: a fibre's whole
#: deviation may be 45 deg) accepted.
MAX_COORDINATE_MM = 1e5
MAX_SD_DEG = 45.0


def check_point_count(n: int, source: str, hint: str) -> None:
    """Refuse more than MAX_POINTS points before any n x n array is made; ``hint`` says
    how to have fewer."""
    if n > MAX_POINTS:
        raise PointsError(f"{source}: {n} points would need {n * n * 8 * 12 / 2**30:.1f} GB and O(n^3) steps to fit; "
                          f"at most {MAX_POINTS} are fitted: {hint}", source)


#: Least spread (mm) of points not all at one spot: a fibre angle is told over a tow, not a
#: micrometre, so a smaller spread is coordinates in the wrong unit (and its figure's axes
#: overflow FreeType's rasteriser).
MIN_SPREAD_MM = 1e-3


def check_spread(points) -> None:
    """Refuse points spread over less than MIN_SPREAD_MM but not all at one spot."""
    spread = max(np.ptp(points.x_mm), np.ptp(points.y_mm)) if len(points) else 0.0
    if 0 < spread < MIN_SPREAD_MM:
        raise PointsError(f"{points.source}: the points lie within {spread:.3g} mm of each other; points not at one "
                          f"spot must spread over at least {MIN_SPREAD_MM:g} mm: are x_mm and y_mm in mm?",
                          points.source)


class PointsError(FileFormatError):
    """A problem in a fibre-angle CSV; ``key`` is the column at fault (None: the file)."""


@dataclass(frozen=True)
class AnglePoints:
    """Measured fibre angles: position (mm), plan angle (deg from x), fibre set (1 or 2),
    the measurement sd (deg; 0 where the file gives none), each point's line in the file
    (``rows``, for messages) and the file as it was named (``source``)."""

    x_mm: np.ndarray
    y_mm: np.ndarray
    angle_deg: np.ndarray
    fibre_set: np.ndarray
    sd_deg: np.ndarray
    rows: np.ndarray
    source: str

    def __len__(self) -> int:
        return len(self.x_mm)


def read_points(path) -> AnglePoints:
    """The fibre-angle points of the CSV ``path`` (see the module docstring). A header that
    names none of the required columns is not quoted: the file may be any file named by
    mistake."""
    path = Path(path)
    (top, header), *rows = csv_rows(read_text(path, "fibre-angle CSV", error=PointsError), str(path),
                                    error=PointsError, path=path)

    def fail(why, column=None):
        raise PointsError(f"{path}: {why}", path, column)

    valid = f"columns {', '.join(REQUIRED_COLUMNS)} (optional: {SD_COLUMN})"
    if not set(header) & set(REQUIRED_COLUMNS):
        fail(f"row {top} (the header) names none of the required columns; "
             f"valid: {valid}")
    for name in header:
        if name not in (*REQUIRED_COLUMNS, SD_COLUMN):
            fail(f"row {top}: column {name[:QUOTED_CELL]!r} is unknown; valid: {valid}", name)
        if header.count(name) > 1:
            fail(f"row {top}: column {name!r} is repeated; valid: {valid}", name)
    for name in REQUIRED_COLUMNS:
        if name not in header:
            fail(f"row {top}: column {name!r} is missing; valid: {valid}", name)
    values = {name: [] for name in header}
    check_point_count(len(rows), str(path), "thin them (every k-th row) or average them into cells")
    for line, row in rows:
        if len(row) != len(header):
            fail(f"row {line}: {len(row)} values for {len(header)} columns")
        for name, cell in zip(header, row):
            values[name].append(_value(name, cell, lambda why, n=name, at=line: fail(f"row {at}: {why}", n)))
    if not rows:
        fail("no data rows after the header")
    columns = {name: np.asarray(v, dtype=float) for name, v in values.items()}
    sd = columns.get(SD_COLUMN, np.zeros(len(rows)))
    return AnglePoints(columns["x_mm"], columns["y_mm"], columns["angle_deg"], columns["fibre_set"].astype(int),
                       sd, np.asarray([line for line, _ in rows]), str(path))


def _value(name: str, text: str, fail) -> float:
    """The number in cell ``text`` of column ``name``, checked for that column."""
    try:
        value = csv_number(text)
    except ValueError as err:
        fail(f"column {name!r}: {err}")
    if name == "fibre_set" and value not in FIBRE_SETS:
        fail(f"column 'fibre_set' = {text[:QUOTED_CELL]!r}; valid: 1 or 2")
    if name == SD_COLUMN and not 0 <= value <= MAX_SD_DEG:
        fail(f"column {SD_COLUMN!r} = {text[:QUOTED_CELL]!r}; valid: a measurement sd from 0 to {MAX_SD_DEG:g} deg")
    if name in ("x_mm", "y_mm") and not abs(value) <= MAX_COORDINATE_MM:
        fail(f"column {name!r} = {text[:QUOTED_CELL]!r}; valid: within +-{MAX_COORDINATE_MM:g} mm")
    return value
