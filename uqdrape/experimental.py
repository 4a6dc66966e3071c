"""Measured shear along the max-shear lines, read from a CSV, for overlay on line plots.

Format (a header row after any ``#`` comment lines, extra columns ignored)::

    distance_mm,shear_deg,quadrant_sign[,blankholder_force_N]
    12.5,8.1,1
    12.5,-10.4,-1

``quadrant_sign`` is +1 for the i*j > 0 (positive-shear) quadrants and -1 for the
others; the optional ``blankholder_force_N`` assigns a point to one panel of a
blank-holder force sweep (without it every point is shown on every panel).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .files import QUOTED_CELL, csv_number, csv_rows, read_text

REQUIRED_COLUMNS = ("distance_mm", "shear_deg", "quadrant_sign")
FORCE_COLUMN = "blankholder_force_N"


@dataclass(frozen=True)
class ExperimentalPoints:
    """Measured points: distance from the crossover (mm), shear (deg), quadrant sign (+1/-1), force (N or NaN)."""

    distance_mm: np.ndarray
    shear_deg: np.ndarray
    quadrant_sign: np.ndarray
    blankholder_force_N: np.ndarray
    source: str

    def at_force(self, force: float) -> "ExperimentalPoints":
        """The points measured at blank-holder force ``force`` (N) plus those with no force given."""
        keep = np.isnan(self.blankholder_force_N) | np.isclose(self.blankholder_force_N, force)
        return ExperimentalPoints(self.distance_mm[keep], self.shear_deg[keep], self.quadrant_sign[keep],
                                  self.blankholder_force_N[keep], self.source)


def read_experimental(path) -> ExperimentalPoints:
    """Read and check an experimental CSV (see module docstring); ValueError naming file, row
    and column. A file without the required header is not echoed (it may be any file named
    by mistake); past the header a bad cell is quoted (``csv_number``)."""
    path = Path(path)
    label = f"experimental CSV {str(path)!r}"
    if not path.is_file():
        raise ValueError(f"{label} does not exist")
    (_, header), *rows = csv_rows(read_text(path, "experimental CSV"), label)
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise ValueError(f"{label}: missing column(s) {missing} in its header (the first line that is not a "
                         f"# comment); required: {', '.join(REQUIRED_COLUMNS)} (optional: {FORCE_COLUMN})")
    index = {name: header.index(name) for name in (*REQUIRED_COLUMNS, FORCE_COLUMN) if name in header}
    columns = {c: [] for c in (*REQUIRED_COLUMNS, FORCE_COLUMN)}
    for line, row in rows:
        for name in columns:
            cell = row[index[name]] if name in index and index[name] < len(row) else ""
            if name == FORCE_COLUMN and not cell:
                columns[name].append(np.nan)
                continue
            try:
                value = csv_number(cell)
            except ValueError as err:
                raise ValueError(f"{label} row {line}: column {name!r}: {err}") from None
            text = cell[:QUOTED_CELL]
            why = (f"quadrant_sign = {text!r}; valid: +1 (i*j > 0 quadrants) or -1"
                   if name == "quadrant_sign" and value not in (1.0, -1.0)
                   else f"distance_mm = {text!r} must be >= 0 (mm)" if name == "distance_mm" and value < 0
                   else f"shear_deg = {text!r}; valid: a shear angle within +-90 deg"
                   if name == "shear_deg" and abs(value) > 90.0
                   else None)
            if why is not None:
                raise ValueError(f"{label} row {line}: {why}")
            columns[name].append(value)
    if not rows:
        raise ValueError(f"{label} has a header but no data rows")
    return ExperimentalPoints(*(np.asarray(columns[c], dtype=float) for c in (*REQUIRED_COLUMNS, FORCE_COLUMN)),
                              source=path.name)


def as_experimental(experimental) -> ExperimentalPoints | None:
    """``None``, an ``ExperimentalPoints`` or a CSV path -> ``ExperimentalPoints`` (or None)."""
    if experimental is None or isinstance(experimental, ExperimentalPoints):
        return experimental
    if isinstance(experimental, (str, Path)):
        return read_experimental(experimental)
    raise ValueError(
        f"experimental must be None, a CSV path or ExperimentalPoints, got {type(experimental).__name__}"
    )
