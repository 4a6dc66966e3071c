"""Material cards: shipped TOML cards, user TOML cards and CSV shear curves -> `Material`.

A TOML card (angles in degrees, N_s in N/m, bending stiffness in N·m²):

    name = "my_fabric"                 # optional, default: the file's stem
    description = "..."                # optional
    note = "..."                       # optional: where the curves come from
    phi0_deg = 45.0                    # optional, half the initial inter-tow angle
    locking_angle_deg = 60.0           # optional, default: end of the positive curve
    locking_angle_neg_deg = 65.0       # optional, magnitude
    bending_stiffness = 1e-6           # optional
    stitch_direction_deg = 45.0        # optional, NCFs only

    [shear.positive]                   # required
    angle_deg = [0, 5, 10, ...]
    ns = [0, 20.9, 42.1, ...]
    [shear.negative]                   # optional magnitudes; omitted = symmetric (woven)
    angle_deg = [...]
    ns = [...]
    [architecture]                     # cards derived from a fabric architecture only:
    ...                                # inputs, calibration, model version (see
                                       # uqdrape.material.architecture.derive_card)
    [scatter.positive]                 # cards fitted to shear tests only (see
    ...                                # uqdrape.material.sheartest.card): the
    [sheartest]                        # specimens' sd per angle, the fit's record
    ...

Instead of the inline tables, `[shear] csv = "curves.csv"` names a CSV file (relative to the
card) in the CSV format below. A bare CSV can also be loaded on its own; the material is then
named after the file and every other property takes its default.

CSV format: optional `#` comment lines, a header `angle_deg,ns_positive[,ns_negative]`, then one
row per angle (deg, N/m, N/m; negative-branch forces as magnitudes). Without `ns_negative` the
fabric is symmetric.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

from ..files import Document, Table, csv_number, csv_rows, parse_toml, read_text, toml_text
from .model import Material, MaterialError

_CARD_KEYS = {"name": str, "description": str, "note": str, "phi0_deg": float, "locking_angle_deg": float,
              "locking_angle_neg_deg": float, "bending_stiffness": float, "stitch_direction_deg": float,
              "shear": dict, "architecture": dict, "scatter": dict, "sheartest": dict}
#: Tables a card keeps for its readers, not for `Material`: [scatter] (the specimens' sd
#: per angle) and [sheartest] (how the curves were fitted: `uqdrape.material.sheartest`).
_RECORD_KEYS = ("shear", "scatter", "sheartest")
_CSV_COLUMNS = ("angle_deg", "ns_positive", "ns_negative")


def cards_dir():
    """The folder of the shipped cards (package data)."""
    return resources.files("uqdrape.material").joinpath("cards")


def available_materials() -> list[str]:
    """Names of the material cards shipped with uqdrape (sorted)."""
    return sorted(p.name[: -len(".toml")] for p in cards_dir().iterdir() if p.name.endswith(".toml"))


def load_material(name_or_path) -> Material:
    """A `Material` from a shipped card name, or a path to a TOML card or a CSV curve file."""
    text = str(name_or_path)
    shipped = available_materials()
    if text in shipped:
        path = Path(str(cards_dir().joinpath(text + ".toml")))
        return _material_from_toml(Document(path, "material card"), path.stem)
    path = Path(name_or_path)
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".csv"):
        raise ValueError(f"unknown material {text!r}: valid shipped cards are {', '.join(shipped)}; "
                         "or give the path of a .toml card or a .csv curve file")
    if not path.is_file():
        raise ValueError(f"{path}: material file not found")
    if suffix == ".csv":
        curves = _read_csv(read_text(path, "material CSV"), str(path))
        return _build(str(path), {"name": path.stem, **curves})
    return _material_from_toml(Document(path, "material card"), path.stem)


def card_material(text: str, label: str) -> Material:
    """A `Material` from the TOML text of a self-contained card (no [shear] csv); ``label``
    names it in errors and its stem is the default name."""
    source = Document(None, "material card", label=label)
    return _material_from_toml(source, Path(label).stem, parse_toml(text, label))


def _material_from_toml(source: Document, stem: str, card: dict | None = None) -> Material:
    """The card of ``source`` (``card``: its document, if already parsed) as a Material."""
    card = source.read() if card is None else card
    top = Table(source, "", card, tuple(_CARD_KEYS))
    props = {}
    for key, kind in _CARD_KEYS.items():
        if not top.has(key) or key in _RECORD_KEYS:
            continue
        if kind is float:
            props[key] = top.number(key)
        elif kind is str:
            props[key] = top.string(key)
        else:
            props[key] = top.table(key).data  # "architecture": a derived card's record, kept as read
    props.setdefault("name", stem)
    if not top.has("shear"):
        source.missing("shear", 'a card needs a [shear] table: [shear.positive] points or csv = "file.csv"')
    shear = top.table("shear", ("csv", "positive", "negative"))
    props.update(_shear_curves(shear, source))
    if top.has("scatter"):
        _check_scatter(top.table("scatter", tuple(b for b in ("positive", "negative") if shear.has(b))), shear)
    return _build(source, props, top)


def _check_scatter(scatter: Table, shear: Table) -> None:
    """A [scatter.<branch>] table (cards fitted to shear tests): the specimens' sd of N_s
    (N/m, >= 0) at the angles of [shear.<branch>], from ``specimens`` >= 2 tests."""
    for branch in scatter.data:
        table = scatter.table(branch, ("angle_deg", "ns_sd", "specimens"))
        angles = table.numbers("angle_deg", hint="angle_deg must be a list of numbers (deg)")
        if list(angles) != [float(a) for a in shear.data.get(branch, {}).get("angle_deg", [])]:
            table.invalid("angle_deg", f"angle_deg must be the angles of [shear.{branch}]")
        sd = table.numbers("ns_sd", length=len(angles), hint=f"ns_sd must be {len(angles)} numbers >= 0 (N/m), "
                                                             "one per angle")
        if min(sd) < 0.0:
            table.invalid("ns_sd", "ns_sd must be >= 0 (N/m)")
        table.number("specimens", integer=True, ge=2)


def _shear_curves(shear: Table, source: Document) -> dict:
    """The curve arguments of `Material` from a card's [shear] table."""
    if shear.has("csv"):
        if len(shear.data) > 1:
            shear.invalid("csv", 'give either csv = "file.csv" or [shear.positive] points, not both')
        path = source.relative_file("shear.csv", shear.data["csv"])
        return _read_csv(read_text(path, "shear CSV"), f"{source.label} -> {shear.data['csv']}")
    if not shear.has("positive"):
        source.missing("shear.positive", 'the [shear] table needs [shear.positive] points, or csv = "file.csv"')
    curves = {}
    for branch, suffix in (("positive", "pos"), ("negative", "neg")):
        if shear.has(branch):
            points = shear.table(branch, ("angle_deg", "ns"))
            curves[f"angles_deg_{suffix}"] = points.numbers("angle_deg", hint="angle_deg must be a list of numbers (deg)")
            curves[f"ns_{suffix}"] = points.numbers("ns", hint="ns must be a list of numbers (N/m)")
    return curves


def _read_csv(text, label):
    """Curve arguments of `Material` from CSV text (header angle_deg,ns_positive[,ns_negative]).
    A file whose header is not that is not echoed (it may be any file named by mistake, or
    by someone else's card); past the header a bad cell is quoted (``csv_number``)."""
    (_, header), *rows = csv_rows(text, label)
    if header not in (list(_CSV_COLUMNS[:2]), list(_CSV_COLUMNS)):
        raise ValueError(f"{label}: not a curve CSV: its first line that is not a # comment must be the header "
                         "angle_deg,ns_positive or angle_deg,ns_positive,ns_negative")
    columns = {name: [] for name in header}
    for lineno, row in rows:
        if len(row) != len(header):
            raise ValueError(f"{label}: data row {lineno} has {len(row)} values, expected {len(header)} ({','.join(header)})")
        for name, cell in zip(header, row):
            try:
                columns[name].append(csv_number(cell))
            except ValueError as err:
                raise ValueError(f"{label}: data row {lineno}, column {name}: {err}") from None
    curves = {"angles_deg_pos": columns["angle_deg"], "ns_pos": columns["ns_positive"]}
    if "ns_negative" in columns:
        curves.update(angles_deg_neg=columns["angle_deg"], ns_neg=columns["ns_negative"])
    return curves


def _build(source, props, top: Table | None = None) -> Material:
    """`Material(**props)`. A refused property is blamed on ``source``: the label of a CSV
    file, or the Document of a TOML card (``top`` its top level) naming the key at fault
    (``shear.csv`` for curves read from a CSV)."""
    try:
        material = Material.from_curves(**props)
        for branch in ("positive", "negative"):
            if not np.any(material.curve(branch)[1] > 0.0):
                raise MaterialError(f"shear.{branch}", f"{branch} shear curve: N_s is 0 at every angle: a fabric "
                                    "with no shear resistance cannot steer an energy drape (use the geodesic "
                                    "mode, which needs no card, or give the measured curve)")
        return material
    except MaterialError as err:
        if isinstance(source, str):
            raise ValueError(f"{source}: {err}") from None
        if err.key.startswith("shear."):
            shear = top.table("shear")
            shear.invalid("csv" if shear.has("csv") else err.key.partition(".")[2], str(err))
        if top.has(err.key):
            top.invalid(err.key, str(err))
        source.fail(str(err), err.key)


def material_document(material: Material) -> dict:
    """The card of a `Material` as a TOML-layout dict (inverse of loading a TOML card)."""
    doc = {"name": material.name}
    for key in ("description", "note"):
        if getattr(material, key):
            doc[key] = getattr(material, key)
    doc.update(phi0_deg=material.phi0_deg, locking_angle_deg=material.locking_angle_deg,
               locking_angle_neg_deg=material.locking_angle_neg_deg,
               bending_stiffness=material.bending_stiffness)
    if material.stitch_direction_deg is not None:
        doc["stitch_direction_deg"] = material.stitch_direction_deg
    branches = ("positive",) if material.symmetric else ("positive", "negative")
    doc["shear"] = {}
    for branch in branches:
        angles, ns = material.curve(branch)
        doc["shear"][branch] = {"angle_deg": angles.tolist(), "ns": ns.tolist()}
    if material.architecture is not None:
        doc["architecture"] = material.architecture
    return doc


def card_text(doc: dict, header: str = "") -> str:
    """TOML text of a card document (``uqdrape.files.toml_text``: plain keys first, then each table)."""
    return toml_text(doc, header)
