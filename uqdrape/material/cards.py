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

Instead of the inline tables, `[shear] csv = "curves.csv"` names a CSV file (relative to the
card) in the CSV format below. A bare CSV can also be loaded on its own; the material is then
named after the file and every other property takes its default.

CSV format: optional `#` comment lines, a header `angle_deg,ns_positive[,ns_negative]`, then one
row per angle (deg, N/m, N/m; negative-branch forces as magnitudes). Without `ns_negative` the
fabric is symmetric.
"""

from __future__ import annotations

import csv
import io
import json
import math
import tomllib
from importlib import resources
from pathlib import Path

from .model import Material

_CARD_KEYS = {
    "name": str,
    "description": str,
    "note": str,
    "phi0_deg": float,
    "locking_angle_deg": float,
    "locking_angle_neg_deg": float,
    "bending_stiffness": float,
    "stitch_direction_deg": float,
    "shear": dict,
    "architecture": dict,
}
_CSV_COLUMNS = ("angle_deg", "ns_positive", "ns_negative")


def _cards_dir():
    return resources.files("uqdrape.material").joinpath("cards")


def available_materials() -> list[str]:
    """Names of the material cards shipped with uqdrape (sorted)."""
    return sorted(p.name[: -len(".toml")] for p in _cards_dir().iterdir() if p.name.endswith(".toml"))


def load_material(name_or_path) -> Material:
    """A `Material` from a shipped card name, or a path to a TOML card or a CSV curve file."""
    text = str(name_or_path)
    shipped = available_materials()
    if text in shipped:
        cards = _cards_dir()
        return _material_from_toml(cards.joinpath(text + ".toml").read_text(encoding="utf-8"),
                                   f"material card {text!r}", text, cards)
    path = Path(name_or_path)
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".csv"):
        raise ValueError(
            f"unknown material {text!r}: valid shipped cards are {', '.join(shipped)}; "
            "or give the path of a .toml card or a .csv curve file"
        )
    if not path.is_file():
        raise ValueError(f"{path}: material file not found")
    if suffix == ".csv":
        curves = _read_csv(path.read_text(encoding="utf-8"), str(path))
        return _build(str(path), {"name": path.stem, **curves})
    return _material_from_toml(path.read_text(encoding="utf-8"), str(path), path.stem, path.parent)


def card_material(text: str, label: str) -> Material:
    """A `Material` from the TOML text of a self-contained card (no [shear] csv); ``label``
    names it in errors and its stem is the default name."""
    return _material_from_toml(text, label, Path(label).stem, None)


def _material_from_toml(text, label, stem, base_dir):
    """Parse a TOML card; `base_dir` (Path or importlib Traversable) resolves a `[shear] csv`."""
    try:
        card = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{label}: not valid TOML ({exc})") from None
    unknown = sorted(set(card) - set(_CARD_KEYS))
    if unknown:
        raise ValueError(f"{label}: unknown key(s) {', '.join(unknown)}; valid keys are {', '.join(_CARD_KEYS)}")
    props = {}
    for key, value in card.items():
        kind = _CARD_KEYS[key]
        if kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{label}: {key} must be a number, got {value!r}")
            props[key] = float(value)
        elif not isinstance(value, kind):
            raise ValueError(f"{label}: {key} must be a {'table' if kind is dict else 'string'}, got {value!r}")
        elif key != "shear":
            props[key] = value  # "architecture": a derived card's record, kept as read
    props.setdefault("name", stem)
    if "shear" not in card:
        raise ValueError(f"{label}: missing the [shear] table (inline [shear.positive] points or csv = \"file.csv\")")
    props.update(_shear_curves(card["shear"], label, base_dir))
    return _build(label, props)


def _shear_curves(shear, label, base_dir):
    """The curve arguments of `Material` from a card's [shear] table."""
    keys = set(shear)
    if keys == {"csv"}:
        rel = shear["csv"]
        if not isinstance(rel, str):
            raise ValueError(f"{label}: shear.csv must be a file name, got {rel!r}")
        source = base_dir.joinpath(rel)
        if not source.is_file():
            raise ValueError(f"{label}: shear.csv file {rel!r} not found next to the card")
        return _read_csv(source.read_text(encoding="utf-8"), f"{label} -> {rel}")
    if "csv" in keys or not keys <= {"positive", "negative"} or "positive" not in keys:
        raise ValueError(
            f"{label}: [shear] must hold either csv = \"file.csv\" or a [shear.positive] table "
            f"(and optionally [shear.negative]), got keys {', '.join(sorted(keys)) or '(none)'}"
        )
    curves = {}
    for branch in ("positive", "negative"):
        if branch not in shear:
            continue
        table = shear[branch]
        if not isinstance(table, dict) or set(table) != {"angle_deg", "ns"}:
            got = ", ".join(sorted(table)) if isinstance(table, dict) else repr(table)
            raise ValueError(f"{label}: shear.{branch} must have exactly the keys angle_deg and ns, got {got}")
        for key in ("angle_deg", "ns"):
            values = table[key]
            if not isinstance(values, list) or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in values):
                raise ValueError(f"{label}: shear.{branch}.{key} must be a list of numbers, got {values!r}")
        suffix = "pos" if branch == "positive" else "neg"
        curves[f"angles_deg_{suffix}"] = table["angle_deg"]
        curves[f"ns_{suffix}"] = table["ns"]
    return curves


def _read_csv(text, label):
    """Curve arguments of `Material` from CSV text (header angle_deg,ns_positive[,ns_negative])."""
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    rows = list(csv.reader(io.StringIO("\n".join(lines))))
    if not rows:
        raise ValueError(f"{label}: empty CSV; expected a header {','.join(_CSV_COLUMNS)}")
    header = [h.strip() for h in rows[0]]
    if header not in (list(_CSV_COLUMNS[:2]), list(_CSV_COLUMNS)):
        raise ValueError(
            f"{label}: CSV header must be angle_deg,ns_positive or angle_deg,ns_positive,ns_negative, "
            f"got {','.join(header)}"
        )
    columns = {name: [] for name in header}
    for lineno, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise ValueError(f"{label}: data row {lineno} has {len(row)} values, expected {len(header)} ({','.join(header)})")
        for name, cell in zip(header, row):
            try:
                columns[name].append(float(cell))
            except ValueError:
                raise ValueError(f"{label}: data row {lineno}, column {name}: {cell.strip()!r} is not a number") from None
    curves = {"angles_deg_pos": columns["angle_deg"], "ns_pos": columns["ns_positive"]}
    if "ns_negative" in columns:
        curves.update(angles_deg_neg=columns["angle_deg"], ns_neg=columns["ns_negative"])
    return curves


def _build(label, props):
    """`Material(**props)` with any validation error prefixed by the file it came from."""
    try:
        return Material.from_curves(**props)
    except ValueError as exc:
        raise ValueError(f"{label}: {exc}") from None


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


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (int, float)):
        if isinstance(value, float) and not math.isfinite(value):
            raise ValueError(f"cannot write the non-finite number {value!r} to a card")
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {value!r} to TOML")


def card_text(doc: dict, header: str = "") -> str:
    """TOML text of a card document (plain keys first, then each table in order)."""
    lines = [f"# {line}" for line in header.splitlines()]

    def emit(table: dict, prefix: str):
        for key, value in table.items():
            if not isinstance(value, dict):
                lines.append(f"{key} = {_toml_value(value)}")
        for key, value in table.items():
            if isinstance(value, dict):
                name = f"{prefix}{key}"
                if any(not isinstance(v, dict) for v in value.values()) or not value:
                    lines.extend(["", f"[{name}]"])
                emit(value, name + ".")

    emit(doc, "")
    return "\n".join(lines) + "\n"
