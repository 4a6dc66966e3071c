"""Readers of shear-test files: a specimen's CSV and the rig file that names them.

Test CSV: optional ``#`` comment lines, a header naming the columns, then one row per
sample: crosshead force (N), crosshead displacement (mm) and optionally the optically
measured shear angle of the central region (deg, the thesis's recommendation for BE).
Which header names these are is the rig file's ``[columns]`` table; other columns are
ignored.

Rig file (TOML), lengths in mm, angles in deg::

    name = "ebx936_pf"              # optional: the card's name (default: the card's stem)
    description = "..."             # optional
    test = "picture_frame"          # or "bias_extension"
    phi0_deg = 45.0                 # the card's φ0; negative-branch specimens are tested
                                    # at 90 − φ0 (the other bisector)
    side_mm = 145.0                 # picture frame: side L (hinge to hinge)
    height_mm = 180.0               # bias extension: free height h0 ...
    width_mm = 90.0                 # ... and width w0 (κ = h0/w0 · tan φ0)
    force_convention = "crosshead"  # what the force column holds (default "crosshead"):
                                    # "crosshead": crosshead force F (N), normalised here;
                                    # "F/L": F over side length (N/m, Eq 3.16; BE: the
                                    # PF-equivalent ψ_A/k2 of Eq 3.33), turned into
                                    # N_s = F/L · 1/(2 cos(φ0 − θ/2)) (Eq 3.1);
                                    # "F_s/L": N_s = F_s/L itself (N/m), used as it is

    [columns]                       # optional; these are the defaults
    force = "force_n"
    displacement = "displacement_mm"
    angle = "angle_deg"             # used where the header has it

    [fit]                           # optional; these are the defaults
    knots = 5                       # interior knots of the monotone spline (1 to 100)
    jump_deg = 1.0                  # rows below this shear are the friction jump: not fitted
    friction = "keep"               # or "subtract": the fit's value at 0 (the jump) removed
    max_angle_deg = 60.0            # the valid range ends here at the latest ...
    max_divergence_deg = 2.0        # ... or where measured and kinematic θ differ by more
    step_deg = 1.0                  # the card's angle spacing (at least 0.01)

    [[specimen]]                    # one per test
    file = "pf1.csv"                # relative to the rig file
    branch = "positive"             # or "negative" (NCFs: tested the other way)
    # height_mm / width_mm / side_mm here override the rig's for this specimen

The default ``force_convention`` is "crosshead", the only reading before the key existed,
so an older rig file means what it meant. A card always holds N_s = F_s/L (N/m).

Every problem raises `ShearTestError`, one line naming the file and the key, or the line
and column of the CSV, at fault.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...files import Document, FileFormatError, Table, csv_number, csv_rows, read_text
from .bias_extension import BiasExtension
from .picture_frame import PictureFrame, shear_per_crosshead

#: Fewest data rows a specimen's CSV may have: a spline of 5 knots wants many more points.
MIN_ROWS = 20
#: Most interior knots of a specimen's spline: its dense design matrix has a column per
#: knot and a row per data row, and a test's curve has a few bends, not hundreds.
MAX_KNOTS = 100
#: Finest angle spacing of a card's curve, deg (a 90 deg curve: 9,000 points).
MIN_STEP_DEG = 0.01
TESTS = ("picture_frame", "bias_extension")
#: What a specimen's force column holds: raw crosshead force (N), or already normalised
#: (N/m) as F/L (Eq 3.16) or as N_s = F_s/L (Eq 3.1 over L).
CONVENTIONS = ("crosshead", "F/L", "F_s/L")
BRANCHES = ("positive", "negative")
_COLUMNS = {"force": "force_n", "displacement": "displacement_mm", "angle": "angle_deg"}
_FIT = {"knots": 5, "jump_deg": 1.0, "friction": "keep", "max_angle_deg": 60.0, "max_divergence_deg": 2.0,
        "step_deg": 1.0}
_DIMENSIONS = {"picture_frame": ("side_mm",), "bias_extension": ("height_mm", "width_mm")}
_TOP = ("name", "description", "test", "phi0_deg", "force_convention", "side_mm", "height_mm", "width_mm", "columns", "fit", "specimen")


class ShearTestError(FileFormatError):
    """A problem in a shear-test rig file or test CSV (one line naming file and place)."""


@dataclass(frozen=True)
class TestData:
    """One specimen's rows: force (N), displacement (mm), measured angle (deg) or None,
    and the file line of each row."""

    path: Path
    force_n: np.ndarray
    displacement_mm: np.ndarray
    angle_deg: np.ndarray | None
    lines: np.ndarray
    columns: dict

    def fail(self, row: int, column: str, why: str):
        """Raise the error of data row ``row`` (index), column ``column`` (a [columns] key)."""
        raise ShearTestError(f"{self.path}: line {self.lines[row]}, column {self.columns[column]}: {why}", self.path)


@dataclass(frozen=True)
class Specimen:
    """A specimen of the rig file: its data, branch, rig geometry (a PictureFrame or a
    BiasExtension at the φ0 it was tested at) and force convention (`CONVENTIONS`)."""

    data: TestData
    branch: str
    rig: PictureFrame | BiasExtension
    convention: str = "crosshead"

    @property
    def force_unit(self) -> str:
        return "N" if self.convention == "crosshead" else "N/m"

    def shear_force(self, force, theta):
        """N_s (N/m) at θ (rad) of the force column's fit ``force(θ)`` (a callable)."""
        if self.convention == "crosshead":
            return self.rig.shear_force(force, theta)
        factor = shear_per_crosshead(theta, self.rig.phi0) if self.convention == "F/L" else 1.0
        return force(np.asarray(theta, dtype=float)) * factor

    def pointwise_shear_force(self, force_n, theta, force):
        """N_s (N/m) of each row (θ rad, force column value), ``force`` the fit."""
        if self.convention == "crosshead":
            return self.rig.pointwise_shear_force(force_n, theta, force)
        return self.shear_force(lambda t: np.asarray(force_n, dtype=float), theta)


@dataclass(frozen=True)
class RigFile:
    """A rig file read: the card's name, description, test, φ0, fit options and specimens."""

    path: Path
    name: str | None
    description: str
    test: str
    phi0_deg: float
    fit: dict
    specimens: list
    force_convention: str = "crosshead"


def read_test_csv(path, columns: dict) -> TestData:
    """The rows of the test CSV ``path``; ``columns`` maps force/displacement/angle to the
    header names (angle optional: used if the header has it). A header without the force
    and displacement columns is not quoted: the file may be any file named by mistake."""
    path = Path(path)
    named = {}
    for key, name in columns.items():
        if name in named:
            raise ShearTestError(f"{path}: [columns] {named[name]} and {key} both name column {name!r}; each "
                                 "quantity needs its own column", path)
        named[name] = key
    (_, header), *rows = csv_rows(read_text(path, "test CSV", error=ShearTestError), str(path),
                                  error=ShearTestError, path=path)

    def fail(why):
        raise ShearTestError(f"{path}: {why}", path)

    for key in ("force", "displacement"):
        if columns[key] not in header:
            fail(f"the header (the first line that is not a # comment) has no column {columns[key]!r} ({key}); "
                 f"expected columns {columns['force']}, {columns['displacement']}[, {columns['angle']}], or name "
                 f"yours in the rig file's [columns] {key}")
    if len(set(header)) != len(header):
        fail(f"the header names a column twice ({len(header)} names, {len(set(header))} different)")
    wanted = {key: header.index(name) for key, name in columns.items() if name in header}
    values = {key: [] for key in wanted}
    for lineno, row in rows:
        if len(row) != len(header):
            fail(f"line {lineno} has {len(row)} values, the header {len(header)}")
        for key, index in wanted.items():
            try:
                values[key].append(csv_number(row[index]))
            except ValueError as err:
                fail(f"line {lineno}, column {columns[key]}: {err}")
    if len(rows) < MIN_ROWS:
        fail(f"{len(rows)} data rows; a fit needs at least {MIN_ROWS}")
    arrays = {key: np.asarray(v) for key, v in values.items()}
    if "angle" in arrays and (np.abs(arrays["angle"]) >= 90.0).any():
        row = int(np.argmax(np.abs(arrays["angle"]) >= 90.0))
        fail(f"line {rows[row][0]}, column {columns['angle']}: a shear angle of 90 deg or more; the angle column "
             "holds degrees of shear (is [columns] angle the angle?)")
    return TestData(path, arrays["force"], arrays["displacement"], arrays.get("angle"),
                    np.array([n for n, _ in rows]), dict(columns))


def read_rig(path) -> RigFile:
    """The rig file ``path`` and the test CSVs it names, validated."""
    doc = Document(path, "rig file", error=ShearTestError)
    top = Table(doc, "", doc.read(), _TOP)
    test = top.string("test", choices=TESTS)
    phi0 = top.number("phi0_deg", 45.0, gt=0.0, lt=90.0)
    convention = top.string("force_convention", "crosshead", choices=CONVENTIONS)
    columns = top.table("columns", tuple(_COLUMNS))
    names = {key: columns.string(key, default) for key, default in _COLUMNS.items()}
    fit = top.table("fit", tuple(_FIT))
    options = {
        "knots": fit.number("knots", _FIT["knots"], integer=True, ge=1, lt=MAX_KNOTS + 1),
        "jump_deg": fit.number("jump_deg", _FIT["jump_deg"], ge=0.0),
        "friction": fit.string("friction", _FIT["friction"], choices=("keep", "subtract")),
        "max_angle_deg": fit.number("max_angle_deg", _FIT["max_angle_deg"], gt=0.0),
        "max_divergence_deg": fit.number("max_divergence_deg", _FIT["max_divergence_deg"], gt=0.0),
        "step_deg": fit.number("step_deg", _FIT["step_deg"], ge=MIN_STEP_DEG),
    }
    if options["jump_deg"] >= options["max_angle_deg"]:
        fit.invalid("jump_deg", f"jump_deg must be below max_angle_deg = {options['max_angle_deg']:g}")
    for other in set(_DIMENSIONS) - {test}:
        for key in _DIMENSIONS[other]:
            if top.has(key):
                top.invalid(key, f"{key} is a {other.replace('_', '-')} dimension; this rig's test is {test}")
    listed = top.raw("specimen", [], "")
    if not isinstance(listed, list) or not listed:
        doc.missing("specimen", "give one [[specimen]] table per test, with file = \"test.csv\"")
    specimens = []
    for i, item in enumerate(listed):
        entry = Table(doc, f"specimen[{i}]", item, ("file", "branch", *_DIMENSIONS[test]))
        branch = entry.string("branch", "positive", choices=BRANCHES)
        dims = {key: entry.number(key, gt=0.0) if entry.has(key) else top.number(key, gt=0.0)
                for key in _DIMENSIONS[test]}
        tested = phi0 if branch == "positive" else 90.0 - phi0
        rig = PictureFrame(dims["side_mm"], tested) if test == "picture_frame" else \
            BiasExtension(dims["height_mm"], dims["width_mm"], tested)
        if test == "bias_extension" and not rig.kappa > 1.5:
            entry.doc.fail(f"specimen[{i}]: kappa = (height_mm/width_mm) tan(phi0) = {rig.kappa:.4g} is invalid: "
                           "region A exists only for kappa > 1.5 (the normal requirement is kappa >= 2)",
                           f"specimen[{i}]")
        file = entry.string("file", hint="file must name the specimen's test CSV (relative to the rig file)")
        data = read_test_csv(doc.relative_file(f"specimen[{i}].file", file), names)
        specimens.append(Specimen(data, branch, rig, convention))
    if not any(s.branch == "positive" for s in specimens):
        doc.missing("specimen", "at least one [[specimen]] must test the positive branch (a card needs "
                                "[shear.positive])")
    return RigFile(Path(path), top.string("name") if top.has("name") else None,
                   top.string("description", ""), test, phi0, options, specimens, convention)
