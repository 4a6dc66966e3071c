"""Architecture files: the TOML layout of an Architecture, read and checked with
uqdrape.files (one error style: file, dotted key, value, what is valid)."""

from __future__ import annotations

from dataclasses import replace
from importlib import resources
from pathlib import Path

from ...files import Document, FileFormatError, Table
from .calibrate import calibrate
from .fabric import Architecture, ArchitectureError

#: File layout: (table, key) -> Architecture field. Top-level keys have table None.
_LAYOUT = {
    (None, "name"): "name", (None, "description"): "description", (None, "source"): "source",
    (None, "phi0_deg"): "phi0_deg", (None, "thickness_mm"): "thickness_mm",
    ("stitch", "length_mm"): "stitch_length_mm", ("stitch", "gauge"): "gauge",
    ("stitch", "lapping"): "lapping", ("stitch", "stiffness_N"): "stitch_stiffness_N",
    ("stitch", "tension_curve"): "tension_curve", ("stitch", "failure_strain"): "failure_strain",
    ("stitch", "friction"): "stitch_friction", ("stitch", "prestrain"): "prestrain",
    ("compaction", "vf0"): "vf0", ("compaction", "v0"): "v0", ("compaction", "va"): "va",
    ("compaction", "fibre_modulus_GPa"): "fibre_modulus_GPa", ("compaction", "beta"): "beta",
    ("crossover", "side_mm"): "crossover_side_mm", ("crossover", "friction"): "crossover_friction",
    ("crossover", "tow_shear_ratio"): "tow_shear_ratio",
}
_FILE_KEY = {f: (k if t is None else f"{t}.{k}") for (t, k), f in _LAYOUT.items()}
_CALIBRATION_KEYS = ("zero_force_angle_deg", "negative_ns", "from")
_STRINGS = ("name", "description", "source")
#: Fields a file may set to "calibrate" (fitted to [calibration]).
_CALIBRATED = ("prestrain", "beta")
#: Fields without a default, and what each is.
_REQUIRED = {"name": "the architecture's name", "stitch_length_mm": "the stitch length s_l (mm)",
             "gauge": "the needles per inch", "prestrain": 'the stitch pre-strain (a fraction) or "calibrate"',
             "beta": "McBride's arch span/height ratio or \"calibrate\""}


def architecture_document(arch: Architecture) -> dict:
    """The architecture in its file layout (all values resolved, no [calibration] table)."""
    doc = {}
    for (table, key), fname in _LAYOUT.items():
        value = getattr(arch, fname)
        if value is None or (fname in _STRINGS and not value):
            continue
        if fname == "lapping":
            value = list(value)
        elif fname == "tension_curve":
            value = {"strain": list(value[0]), "tension_N": list(value[1])}
        (doc if table is None else doc.setdefault(table, {}))[key] = value
    return doc


def architecture_from_document(data: dict, source: Document, _chain=()) -> Architecture:
    """An Architecture from a file-layout document ``data`` read from ``source`` (which
    names the file in errors and resolves ``calibration.from``).

    ``"calibrate"`` for stitch.prestrain or compaction.beta fits it to the targets of
    ``[calibration]`` (zero_force_angle_deg, negative_ns = [angle, N_s]), or takes the
    fitted value of the architecture file named by ``calibration.from`` (relative to
    this one).
    """
    top = Table(source, "", data, (*(k for t, k in _LAYOUT if t is None), "stitch", "compaction", "crossover",
                                   "calibration"))
    kwargs, pending = {}, []
    for name in (None, "stitch", "compaction", "crossover"):
        keys = [k for t, k in _LAYOUT if t == name]
        table = top if name is None else top.table(name, keys)
        for key in keys:
            if table.has(key):
                fname = _LAYOUT[(name, key)]
                value = _value(table, key, fname)
                if fname in _CALIBRATED and value == "calibrate":
                    pending.append(fname)
                else:
                    kwargs[fname] = value
    for fname, what in _REQUIRED.items():
        if fname not in kwargs and fname not in pending:
            source.missing(_FILE_KEY[fname], f"{_FILE_KEY[fname]} is {what}")
    if "tension_curve" in kwargs:
        kwargs.setdefault("stitch_stiffness_N", None)
    cal = top.table("calibration", _CALIBRATION_KEYS)
    if pending and not cal.data:
        source.missing("calibration", f'{_FILE_KEY[pending[0]]} = "calibrate" needs a [calibration] table')
    try:
        arch = Architecture(**kwargs, **{f: (0.0 if f == "prestrain" else 1.0) for f in pending})
    except ArchitectureError as err:
        _blame(source, data, err)
    if not pending:
        return arch
    if cal.has("from"):
        ref = cal.data["from"]
        donor_path = source.relative_file("calibration.from", ref).resolve()
        if donor_path in _chain:
            source.invalid("calibration.from", ref, "the files' calibration.from entries form a cycle")
        donor = _load(donor_path, _chain)
        fitted = {f: getattr(donor, f) for f in pending}
        try:
            return replace(arch, **fitted, calibration=fitted | {"from": ref})
        except ArchitectureError as err:
            source.invalid("calibration.from", ref, f"its fitted {err}")
    targets = {}
    if "prestrain" in pending:
        if not cal.has("zero_force_angle_deg"):
            source.missing("calibration.zero_force_angle_deg",
                           'stitch.prestrain = "calibrate" needs the zero-force angle to fit it to (deg)')
        targets["zero_force_angle_deg"] = cal.number("zero_force_angle_deg")
    if "beta" in pending:
        hint = "negative_ns must be [angle_deg, N_s N/m]"
        if not cal.has("negative_ns"):
            source.missing("calibration.negative_ns", f'compaction.beta = "calibrate" needs it: {hint}')
        targets["negative_ns"] = cal.numbers("negative_ns", length=2, hint=hint)
        angle, ns = targets["negative_ns"]
        if not (0.0 < angle < 90.0 and 0.0 < ns <= 1e6):
            cal.invalid("negative_ns", f"{hint} with 0 < angle_deg < 90 and 0 < N_s <= 1e6 N/m")
    try:
        return calibrate(arch, **targets)
    except ValueError as err:
        source.invalid("calibration", cal.data, f"the fit failed: {err}")


def _value(table: Table, key: str, fname: str):
    """One value of the file, as the Architecture field ``fname`` takes it ("calibrate" kept)."""
    if fname in _STRINGS:
        return table.string(key)
    if fname == "lapping":
        return table.numbers(key, integer=True, hint="lapping must be a non-empty list of integer needle shifts "
                                                     "summing to 0, e.g. [1, -1] (tricot)")
    if fname == "tension_curve":
        curve = table.table(key, ("strain", "tension_N"))
        return tuple(curve.numbers(k, hint=f"{k} must be a non-empty list of numbers") for k in ("strain", "tension_N"))
    if fname in _CALIBRATED and isinstance(table.data[key], str):
        if table.data[key] != "calibrate":
            table.invalid(key, f'{key} must be a number or "calibrate"')
        return "calibrate"
    return table.number(key)


def _blame(source: Document, data: dict, err: ArchitectureError):
    """Re-raise an Architecture's check as an error of the file key holding that field."""
    key = _FILE_KEY[err.key]
    name, _, leaf = key.rpartition(".")
    value = (data.get(name, {}) if name else data).get(leaf, err.value)
    source.invalid(key, value, err.why)


def _architectures_dir() -> Path:
    return Path(str(resources.files("uqdrape.material").joinpath("architectures")))


def available_architectures() -> list[str]:
    """Names of the architecture files shipped with uqdrape (sorted)."""
    return sorted(p.stem for p in _architectures_dir().glob("*.toml"))


def load_architecture(name_or_path) -> Architecture:
    """Read an architecture TOML file, or a shipped one by name (``fge106hd``, ...)."""
    text = str(name_or_path)
    path = _architectures_dir() / f"{text}.toml" if text in available_architectures() else Path(text)
    if not path.is_file():
        raise FileFormatError(f"{path}: architecture file not found (shipped: {', '.join(available_architectures())})",
                              path)
    return _load(path, ())


def _load(path: Path, chain) -> Architecture:
    source = Document(path, "architecture file")
    return architecture_from_document(source.read(), source, (*chain, path.resolve()))
