"""The study file: read a study TOML, validate it, explain what is wrong.

``load_study(path)`` reads a study file (TOML, via ``tomllib``) into a frozen
:class:`~uqdrape.study.spec.Study`.

Sections and keys (units: mm, N, degrees)::

    [study]        name, seed, realizations, chunk_size = 64, description = ""
    [geometry]     kind + that kind's shape parameters (see uqdrape.geometry.KINDS)
    [fabric]       material, spacing_mm, orientation_deg = 0, pre_shear_deg = 0, skew_deg = 0, crossover = [0, 0]
    [process]      blankholder_force_N (a number, or a list: a sweep), friction = 0.2, sectors,
                   blankholder_model = "slip" ("radial": thesis Eq 5.1-5.5)
    [solver]       mode = "energy", rings, tolerance_deg = 1e-3, max_iterations = 30,
                   failure_budget = 0.5 (a run stops before draping if more of the first
                   realisation's nodes cannot be placed)
    [uncertainty.spacing]     cv, correlation = "iid", length_mm, kl_retained = 0.95
    [uncertainty.zero_angle]  mean_deg = 0, sd_deg, correlation = "iid", length_mm, kl_retained = 0.95
    [uncertainty.stitch_prestrain]  mean, sd (fractions), correlation = "iid", length_mm, kl_retained = 0.95:
                   each cell's stitch pre-strain, mapped to its zero-energy angle gamma0 through the
                   material card's [architecture] (uqdrape.material.architecture.material_zero_force_table);
                   needs a card derived from an architecture; not together with zero_angle
    [uncertainty.<factor>]    dist + parameters, factor in FACTOR_SETTINGS
    [sampling]     plan = "monte_carlo"
    [sensitivity]  method = "none", base_samples, qoi = all of QOIS
    [design]       variables ("force" | "sectors"), sectors (>= 2, for "sectors"), force_bounds_N = [lo, hi]
                   (the total force, or each sector's), friction_bounds = [lo, hi], budget_N (total force),
                   objective (DESIGN_OBJECTIVES), statistic = "upper" | "estimate", target, confidence = 0.95,
                   max_evaluations = 40, tolerance_N = 5, validation_realizations = study.realizations,
                   max_draw_in_mm (a draw-in limit: the statistic of q95_max_draw_in at most this):
                   a blank-holder design (uqdrape.design); the study's own force is the baseline design
    [report]       histogram_nodes = [], experimental_csv
    [output]       directory = "results/<study name>", float32 = false (true: chunks store floats as
                   float32 with zlib, about a third of the size, rounded to 7 significant digits)

Factor distributions (values in the units of the setting they override): normal
(mean, sd), truncnormal (mean, sd, bounds = [lo, hi]; mean/sd of the parent normal),
uniform (bounds = [lo, hi]), lognormal (mean, sd of the value itself, as in
uqdrape.stochastic). A factor overrides its fixed setting in the ensemble; the fixed
value stays the nominal one.

Paths in the file (a mesh mould's ``path``, a material card, ``experimental_csv``) are relative to
the study file; ``output.directory`` is relative to the current working directory.

Errors. Every problem raises :class:`StudyError` naming the file, the dotted key, the
bad value and what is valid, in one line, e.g. ``studies/x.toml:
uncertainty.spacing.cv = 1.2 is invalid: cv (spacing coefficient of variation) must be
in [0, 1), got 1.2``. Only the **first** problem is reported, in a fixed order: unknown
sections; then the sections in the order above; within a section unknown keys, then the
keys in the order above (``geometry.kind`` and a factor's ``dist`` first: they decide
which keys are valid). Stopping at the first is deliberate: later checks need earlier
values (the crossover check builds the mould, histogram nodes need ``rings``, random
fields need ``spacing_mm``). Range checks of moulds, materials, distributions, random
fields, sampling plans and sensitivity designs are those of uqdrape.geometry, .material,
.stochastic and .sensitivity; this module checks TOML types and keys and the rules that
tie sections together. A key that would be silently ignored (``length_mm`` of an iid
field, ``base_samples`` without a sensitivity method) is an
error too, because it usually means another key was forgotten.
"""
from __future__ import annotations

import inspect
import os
import shutil
import json
import math
import re
import tomllib
from pathlib import Path

import numpy as np

from .. import geometry as _geometry
from .. import material as _material
from .. import stochastic as _stochastic
from ..drape import BLANKHOLDER_MODELS, MODES, drape, placement_failures
from ..experimental import read_experimental
from ..schema import SOLVER_INPUTS
from ..stats import QOIS
from .spec import (DESIGN_OBJECTIVES, DESIGN_STATISTICS, DESIGN_VARIABLES, DIST_KEYS, FACTOR_SETTINGS, FIELD_KEYS,
                   FIELDS, SECTIONS, SENSITIVITY_METHODS, Design, Fabric, Geometry, Process, RandomField, Report,
                   Sampling, Sensitivity, Solver, Study, Uncertainty, prestrain_map)


class StudyError(ValueError):
    """A problem in a study file; the message names the file, the key, the value and what is valid."""


# factor distributions offered in a study file (a constant is the fixed setting itself)
_DISTS = tuple(d for d in _stochastic.DISTRIBUTIONS if d != "constant")
_NAME_RE = re.compile(r"^[A-Za-z0-9_-]+$")
_REQUIRED = object()


# ----------------------------------------------------------------------------- messages


def _fmt(value) -> str:
    """A value as it would be written in TOML (shortened if long)."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, str):
        text = json.dumps(value)
    elif isinstance(value, dict):
        text = "{ " + ", ".join(f"{k} = {_fmt(v)}" for k, v in value.items()) + " }"
    elif isinstance(value, (list, tuple)):
        text = "[" + ", ".join(_fmt(v) for v in value) + "]"
    else:
        text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


class _Source:
    """The study file being read: its label for messages and its folder for relative paths."""

    def __init__(self, path: Path):
        self.path = path
        self.label = str(path)
        self.folder = path.resolve().parent

    def fail(self, text: str):
        raise StudyError(f"{self.label}: {text}")

    def invalid(self, key: str, value, why: str):
        self.fail(f"{key} = {_fmt(value)} is invalid: {why}")

    def missing(self, key: str, why: str):
        self.fail(f"{key} is missing: {why}")

    def relative_file(self, key: str, value) -> Path:
        """An existing file named relative to the study file."""
        if not isinstance(value, str) or not value:
            self.invalid(key, value, "must be a file name (relative to the study file)")
        path = self.folder / value
        if not path.is_file():
            self.invalid(key, value, f"file not found: {path}")
        return path

    def wrap(self, err: Exception, section: str, given: dict, required: dict | None = None):
        """Re-raise another module's ValueError with file and key context.

        ``given`` maps a name as the other module spells it to (dotted study key, value)
        for keys present in the file; ``required`` maps names of absent required keys to
        their dotted keys. The names in the message decide which study key is blamed: a
        missing required key first, else every present key it names, else ``[section]``.
        """
        msg = str(err)

        def named(name):
            return re.search(rf"(?<![\w.]){re.escape(name)}(?!\w)", msg) is not None

        for name, key in (required or {}).items():
            if named(name):
                self.missing(key, msg)
        blamed = {}
        for name, (key, value) in given.items():
            if named(name):
                blamed.setdefault(key, value)
        if blamed:
            lhs = ", ".join(f"{k} = {_fmt(v)}" for k, v in blamed.items())
            self.fail(f"{lhs} is invalid: {msg}")
        self.fail(f"[{section}] is invalid: {msg}")


class _Table:
    """One TOML table of the study: rejects unknown keys, reads typed values."""

    def __init__(self, src: _Source, name: str, data, keys=None):
        self.src, self.name = src, name
        if not isinstance(data, dict):
            src.invalid(name, data, f"{name} must be a table [{name}]")
        self.data = data
        if keys is not None:
            self.only(keys)

    def only(self, keys):
        """Reject keys not in ``keys`` (called later when the valid keys depend on a value)."""
        for key in self.data:
            if key not in keys:
                self.src.fail(f"unknown key {self.dotted(key)}; valid keys in [{self.name}]: {', '.join(keys)}")

    def dotted(self, key: str) -> str:
        return f"{self.name}.{key}"

    def has(self, key: str) -> bool:
        return key in self.data

    def invalid(self, key: str, why: str):
        self.src.invalid(self.dotted(key), self.data[key], why)

    def raw(self, key: str, default, hint: str):
        if key in self.data:
            return self.data[key]
        if default is _REQUIRED:
            self.src.missing(self.dotted(key), hint)
        return default

    def number(self, key, default=_REQUIRED, *, integer=False, ge=None, gt=None, lt=None):
        """A finite number (an int where ``integer``) with optional bounds."""
        kind = "an integer" if integer else "a number"
        low = f"{ge} <= " if ge is not None else f"{gt} < " if gt is not None else ""
        if lt is not None:
            hint = f"{key} must be {kind} with {low}{key} < {lt}"
        elif low:
            hint = f"{key} must be {kind} {'>=' if ge is not None else '>'} {ge if ge is not None else gt}"
        else:
            hint = f"{key} must be a finite number" if not integer else f"{key} must be an integer"
        value = self.raw(key, default, hint)
        if key not in self.data:
            return value
        if not (_is_int(value) if integer else _is_number(value)) or not math.isfinite(value):
            self.invalid(key, hint)
        if (ge is not None and value < ge) or (gt is not None and value <= gt) or (lt is not None and value >= lt):
            self.invalid(key, hint)
        return value if integer else float(value)

    def string(self, key, default=_REQUIRED, *, choices=None, hint=None, valid=lambda value: True):
        """A string, one of ``choices`` if given, for which ``valid(value)`` holds if given."""
        hint = hint or (f"{key} must be one of {', '.join(map(json.dumps, choices))}" if choices
                        else f"{key} must be a string")
        value = self.raw(key, default, hint)
        if not isinstance(value, str) or (choices is not None and value not in choices) or not valid(value):
            self.invalid(key, hint)
        return value

    def numbers(self, key, default=_REQUIRED, *, length=None, hint):
        """A list of finite numbers (of exactly ``length`` if given, else non-empty)."""
        value = self.raw(key, default, hint)
        if key not in self.data:
            return value
        ok = isinstance(value, list) and len(value) > 0 and (length is None or len(value) == length)
        if not ok or not all(_is_number(v) and math.isfinite(v) for v in value):
            self.invalid(key, hint)
        return tuple(float(v) for v in value)


# ----------------------------------------------------------------------------- sections


def _read_toml(path: Path, src: _Source) -> dict:
    """The study document. UTF-8 (a byte-order mark is allowed) or UTF-16 with its mark;
    anything else is refused naming the first byte that is not text."""
    try:
        data = path.read_bytes()
    except OSError as err:
        src.fail(f"cannot read the study file: {err.strerror or err}")
    try:
        if data.startswith((b"\xff\xfe", b"\xfe\xff")):
            text = data.decode("utf-16")
        else:
            text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        src.fail(f"not UTF-8 text: byte 0x{data[err.start]:02x} at offset {err.start} ({err.reason}); "
                 "save the study file as UTF-8")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        src.fail(f"not valid TOML: {err}")


def _study(src: _Source, doc: dict) -> dict:
    t = _Table(src, "study", doc.get("study", {}), ("name", "seed", "realizations", "chunk_size", "description"))
    name = t.string("name", hint="name must be a non-empty string of letters, digits, '-' and '_'",
                    valid=_NAME_RE.match)
    return {
        "name": name,
        "seed": t.number("seed", integer=True, ge=0, lt=2**63),
        "realizations": t.number("realizations", integer=True, ge=1),
        "chunk_size": t.number("chunk_size", 64, integer=True, ge=1),
        "description": t.string("description", ""),
    }


def _geometry_section(src: _Source, doc: dict):
    """The mould spec and the built mould (needed for the crossover checks)."""
    t = _Table(src, "geometry", doc["geometry"])
    kind = t.string("kind", choices=tuple(_geometry.KINDS))  # first: it decides the valid keys
    sig = inspect.signature(_geometry.KINDS[kind].__init__)
    shape_keys = [p for p in sig.parameters if p != "self"]
    t.only(("kind", *shape_keys))
    params = {k: v for k, v in t.data.items() if k != "kind"}
    if "path" in shape_keys and "path" in params:  # a mould read from a file (kind "mesh")
        params["path"] = str(src.relative_file("geometry.path", params["path"]))
    required = {p: f"geometry.{p}" for p in shape_keys
                if sig.parameters[p].default is inspect.Parameter.empty and p not in params}
    try:
        mould = _geometry.build(kind, **params)
    except ValueError as err:
        src.wrap(err, "geometry", {k: (f"geometry.{k}", t.data[k]) for k in params}, required)
    return Geometry(kind, mould.params()), mould


def _fabric(src: _Source, doc: dict, mould) -> Fabric:
    t = _Table(src, "fabric", doc.get("fabric", {}),
               ("material", "spacing_mm", "orientation_deg", "pre_shear_deg", "skew_deg", "crossover"))
    shipped = _material.available_materials()
    hint = (f"material must be a shipped card ({', '.join(shipped)}) "
            "or the path of a .toml/.csv card relative to the study file")
    name = t.string("material", hint=hint)
    if name in shipped:
        material = name
    elif Path(name).suffix.lower() in (".toml", ".csv"):
        material = str(src.relative_file("fabric.material", name))
    else:
        t.invalid("material", hint)
    try:
        _material.load_material(material)
    except ValueError as err:
        t.invalid("material", str(err))
    spacing = t.number("spacing_mm", gt=0)
    orientation = t.number("orientation_deg", 0.0)
    pre_shear = t.number("pre_shear_deg", 0.0, gt=-90, lt=90)
    skew = t.number("skew_deg", 0.0, gt=-90, lt=90)
    if abs(pre_shear + skew) >= 90:
        t.invalid("skew_deg", f"pre_shear_deg + skew_deg must lie in (-90, 90) degrees, got {pre_shear + skew:g}")
    crossover = t.numbers("crossover", (0.0, 0.0), length=2,
                          hint="crossover must be two numbers [x, y] in mm")
    if not _inside(mould, *crossover):
        src.invalid("fabric.crossover", list(crossover),
                    f"the crossover must lie inside the mould's domain ({_describe(mould)})")
    return Fabric(material, spacing, orientation, pre_shear, crossover, skew)


def _process(src: _Source, doc: dict) -> Process:
    t = _Table(src, "process", doc.get("process", {}), ("blankholder_force_N", "friction", "sectors",
                                                                    "blankholder_model"))
    hint = ("blankholder_force_N must be a number >= 0 (N), "
            "or a non-empty list of distinct numbers >= 0 (a sweep)")
    force = t.raw("blankholder_force_N", _REQUIRED, hint)
    if _is_number(force):
        levels = (float(force),)
    else:
        levels = t.numbers("blankholder_force_N", hint=hint)
    if not all(math.isfinite(f) and f >= 0 for f in levels) or len(set(levels)) != len(levels):
        t.invalid("blankholder_force_N", hint)
    force = SOLVER_INPUTS["blankholder_force"]
    if not all(force.admits(f) for f in levels):
        t.invalid("blankholder_force_N", f"blankholder_force_N {force.describe_range()}")
    friction = t.number("friction", 0.2, ge=0)
    if not SOLVER_INPUTS["friction"].admits(friction):
        t.invalid("friction", f"friction {SOLVER_INPUTS['friction'].describe_range()}")
    sectors = None
    if t.has("sectors"):
        hint = "sectors must be a non-empty list of relative weights >= 0, not all zero"
        sectors = t.numbers("sectors", hint=hint)
        if any(w < 0 for w in sectors) or sum(sectors) <= 0:
            t.invalid("sectors", hint)
    model = t.string("blankholder_model", "slip", choices=BLANKHOLDER_MODELS)
    return Process(levels, friction, sectors, model)


def _solver(src: _Source, doc: dict) -> Solver:
    t = _Table(src, "solver", doc.get("solver", {}), ("mode", "rings", "tolerance_deg", "max_iterations",
                                                        "failure_budget"))
    solver = Solver(
        mode=t.string("mode", "energy", choices=MODES),
        rings=t.number("rings", integer=True, ge=1),
        tolerance_deg=t.number("tolerance_deg", 1e-3, gt=0),
        max_iterations=t.number("max_iterations", 30, integer=True, ge=1),
        failure_budget=t.number("failure_budget", 0.5, ge=0),
    )
    if solver.failure_budget > 1:
        t.invalid("failure_budget", "failure_budget is a fraction of the nodes, in [0, 1]")
    nodes = (2 * solver.rings + 1) ** 2
    if nodes * WORKING_BYTES_PER_NODE > _memory() / 2:
        t.invalid("rings", f"one drape of {nodes:,} nodes needs about {nodes * WORKING_BYTES_PER_NODE / 2**30:.3g} "
                  f"GiB, more than half of this machine's {_memory() / 2**30:.3g} GiB")
    return solver


def _field(src: _Source, name: str, data, rings: int, spacing_mm: float, material: str) -> RandomField:
    section = f"uncertainty.{name}"
    t = _Table(src, section, data, (*FIELD_KEYS[name], "correlation", "length_mm", "kl_retained"))
    if name == "spacing":
        params = {"cv": t.number("cv")}  # its range is checked by SpacingInput
    elif name == "zero_angle":
        params = {"mean_deg": t.number("mean_deg", 0.0), "sd_deg": t.number("sd_deg")}
    else:
        params = {"mean": t.number("mean"), "sd": t.number("sd", ge=0)}
        try:
            table = prestrain_map(material)
        except ValueError as err:
            src.invalid(section, data, str(err))
        if np.ptp(table.gamma0_deg) == 0.0:
            src.invalid(section, data, f"the zero-force angle of {Path(material).stem} is "
                                       f"{table.gamma0_deg[0]:g} deg at every pre-strain up to "
                                       f"{table.max_prestrain:g} (its stitch friction holds the fabric), "
                                       "so this field would change nothing")
        top = params["mean"] + 7.0 * params["sd"]
        if top > table.max_prestrain:
            src.invalid(section, data, f"mean + 7 sd = {top:g} passes the largest mapped pre-strain "
                                       f"{table.max_prestrain:g}; use a smaller mean or sd")
    correlation = t.string("correlation", "iid", choices=_stochastic.CORRELATIONS)
    length = None
    if t.has("length_mm"):
        if correlation == "iid":
            t.invalid("length_mm", 'length_mm is only used by a correlated field: set correlation = '
                      '"exponential" or "squared_exponential", or remove length_mm')
        length = t.numbers("length_mm", length=2, hint="length_mm must be two numbers [L1, L2] in mm, > 0")
    retained = t.number("kl_retained", 0.95)
    spec = RandomField(name, params, correlation, length, retained,
                       material if name == "stitch_prestrain" else None)
    given = {k: (t.dotted(k), v) for k, v in t.data.items()}
    given["retained"] = (t.dotted("kl_retained"), retained)
    required = {"length_mm": t.dotted("length_mm")} if length is None and correlation != "iid" else {}
    try:
        spec.build_input(rings, spacing_mm).kl(retained)
    except ValueError as err:
        src.wrap(err, section, given, required)
    return spec


def _factor(src: _Source, name: str, data):
    section = f"uncertainty.{name}"
    t = _Table(src, section, data)
    dist = t.string("dist", choices=_DISTS)  # first: it decides the valid keys
    keys = DIST_KEYS[dist]
    t.only(("dist", *keys))
    params = {}
    for key in keys:
        if key == "bounds":
            params["lower"], params["upper"] = t.numbers(
                "bounds", length=2, hint="bounds must be two numbers [lo, hi] with lo < hi")
        else:
            params[key] = t.number(key)
    try:
        return _stochastic.make_factor(dist, **params)
    except ValueError as err:
        given = {k: (t.dotted(k), t.data[k]) for k in keys}
        if "bounds" in keys:
            given["lower"] = given["upper"] = given["bounds"]
        src.wrap(err, section, given)


def _uncertainty(src: _Source, doc: dict, fabric: Fabric, process: Process, solver: Solver, mould) -> Uncertainty:
    names = (*FIELDS, *FACTOR_SETTINGS)
    t = _Table(src, "uncertainty", doc.get("uncertainty", {}), names)
    fields, factors = {}, {}
    for name in names:  # schema order, not file order: deterministic messages
        if not t.has(name):
            continue
        if name in FIELDS:
            if name == "stitch_prestrain" and "zero_angle" in fields:
                src.invalid("uncertainty.stitch_prestrain", t.data[name],
                            "the stitch pre-strain sets each cell's zero-energy angle itself: remove "
                            "[uncertainty.zero_angle] or this field")
            fields[name] = _field(src, name, t.data[name], solver.rings, fabric.spacing_mm, fabric.material)
        else:
            factors[name] = _factor(src, name, t.data[name])
    if "blankholder_force" in factors and len(process.blankholder_force_N) > 1:
        src.invalid("process.blankholder_force_N", list(process.blankholder_force_N),
                    "a sweep cannot be combined with [uncertainty.blankholder_force]; "
                    "give one nominal force or remove the factor")
    for name, factor in factors.items():
        inp = SOLVER_INPUTS[name]
        lo, hi = _extent(factor)
        if not (inp.admits(lo) and inp.admits(hi)):
            src.invalid(f"uncertainty.{name}", t.data[name],
                        f"its values reach [{lo:g}, {hi:g}] but {name} {inp.describe_range()}; "
                        "use bounds (uniform/truncnormal) or a smaller sd")
    if {"crossover_x", "crossover_y"} & set(factors):
        xs = _extent(factors["crossover_x"]) if "crossover_x" in factors else (fabric.crossover[0],) * 2
        ys = _extent(factors["crossover_y"]) if "crossover_y" in factors else (fabric.crossover[1],) * 2
        corners = [(x, y) for x in xs for y in ys]
        if not all(_inside(mould, x, y) for x, y in corners):
            key = "crossover_x" if "crossover_x" in factors else "crossover_y"
            src.invalid(f"uncertainty.{key}", t.data[key],
                        f"crossovers up to x in [{xs[0]:g}, {xs[1]:g}], y in [{ys[0]:g}, {ys[1]:g}] mm "
                        f"leave the mould's domain ({_describe(mould)})")
    return Uncertainty(fields, factors)


def _extent(factor) -> tuple[float, float]:
    """The range of values a design can give (u = 0 and 1; about ±7 sd for a normal)."""
    lo, hi = factor.ppf(np.array([0.0, 1.0]))
    return float(lo), float(hi)


def _inside(mould, x: float, y: float) -> bool:
    return bool(np.asarray(mould.inside(np.float64(x), np.float64(y))))


def _describe(mould) -> str:
    bounds = getattr(mould, "bounds", None)
    if bounds is None:
        return mould.describe()
    return f"{mould.name}, plan x in [{bounds[0]:g}, {bounds[1]:g}], y in [{bounds[2]:g}, {bounds[3]:g}] mm"


def _sampling(src: _Source, doc: dict, realizations: int, seed: int) -> Sampling:
    t = _Table(src, "sampling", doc.get("sampling", {}), ("plan",))
    plan = t.string("plan", "monte_carlo", choices=_stochastic.PLANS)
    try:
        _stochastic.sample_uniforms(plan, realizations, 0, seed)  # checks the plan, draws nothing
    except ValueError as err:
        src.wrap(err, "sampling", {"plan": ("sampling.plan", plan), "n": ("study.realizations", realizations)})
    return Sampling(plan)


def _sensitivity(src: _Source, doc: dict, uncertainty: Uncertainty) -> Sensitivity:
    t = _Table(src, "sensitivity", doc.get("sensitivity", {}), ("method", "base_samples", "qoi"))
    method = t.string("method", "none", choices=SENSITIVITY_METHODS)
    base = None
    if method == "none":
        if t.has("base_samples"):
            t.invalid("base_samples", 'base_samples is only used by a sensitivity method: set method = '
                      '"sobol" or "morris", or remove base_samples')
    else:
        # imported here: SALib is slow to import and only needed for a sensitivity study.
        # check_base_samples holds the design's minimum and power-of-two rules.
        from ..sensitivity import check_base_samples

        base = t.number("base_samples", integer=True, ge=1)
        try:
            check_base_samples(method, base)
        except ValueError as err:
            src.wrap(err, "sensitivity", {"base_samples": ("sensitivity.base_samples", base)})
        if len(uncertainty.varying) < 2:
            found = ", ".join(uncertainty.varying) or "none"
            src.invalid("sensitivity.method", method,
                        f"a sensitivity analysis needs at least two [uncertainty.*] inputs (found: {found}); "
                        "indices of a single input are 1 by construction")
    hint = f"qoi must be a non-empty list of distinct names from {', '.join(QOIS)}"
    qoi = t.raw("qoi", list(QOIS), hint)
    if not isinstance(qoi, list) or not qoi or len(set(map(repr, qoi))) != len(qoi) or any(q not in QOIS for q in qoi):
        t.invalid("qoi", hint)
    return Sensitivity(method, base, tuple(qoi))


def _bounds(t: _Table, key: str, unit: str):
    """Two numbers [lo, hi] with 0 <= lo < hi."""
    hint = f"{key} must be two numbers [lo, hi] with 0 <= lo < hi{unit}"
    lo, hi = t.numbers(key, length=2, hint=hint)
    if not 0 <= lo < hi:
        t.invalid(key, hint)
    return lo, hi


def _fewest_for_quantile_limit(p: float, confidence: float) -> int:
    """Fewest realisations whose order statistics give an upper confidence limit of the p-quantile."""
    from scipy import stats

    n = 2
    while stats.binom.ppf(0.5 + confidence / 2, n, p) + 1 > n:
        n += 1
    return n


def _design(src: _Source, doc: dict, process: Process, uncertainty: Uncertainty, sensitivity: Sensitivity,
            realizations: int):
    """The [design] section (None without one) and the rules tying it to the study."""
    if "design" not in doc:
        return None
    t = _Table(src, "design", doc["design"], ("variables", "sectors", "force_bounds_N", "friction_bounds",
                                              "budget_N", "objective", "statistic", "target", "confidence",
                                              "max_evaluations", "tolerance_N", "validation_realizations",
                                              "max_draw_in_mm"))
    variables = t.string("variables", choices=DESIGN_VARIABLES)
    sectors = None
    if variables == "sectors":
        sectors = t.number("sectors", integer=True, ge=2)
    elif t.has("sectors"):
        t.invalid("sectors", 'sectors is only used with variables = "sectors"')
    lo, hi = _bounds(t, "force_bounds_N", " (N" + (", each sector's force)" if sectors else ", total force)"))
    friction = _bounds(t, "friction_bounds", "") if t.has("friction_bounds") else None
    budget = t.number("budget_N", None, gt=0)
    floor = lo * (sectors or 1)
    if budget is not None and budget < floor:
        t.invalid("budget_N", f"budget_N must be >= the smallest total force the bounds allow, "
                              f"{sectors or 1} x {lo:g} = {floor:g} N")
    objective = t.string("objective", choices=tuple(DESIGN_OBJECTIVES))
    statistic = t.string("statistic", "upper", choices=DESIGN_STATISTICS)
    target = t.number("target", None, ge=0)
    confidence = t.number("confidence", 0.95, gt=0, lt=1)
    evaluations = t.number("max_evaluations", 40, integer=True, ge=4)
    tolerance = t.number("tolerance_N", 5.0, gt=0)
    validation = t.number("validation_realizations", None, integer=True, ge=2)
    draw_in = t.number("max_draw_in_mm", None, gt=0)
    quantiles = DESIGN_OBJECTIVES[objective][1] == "quantile95" or draw_in is not None
    if quantiles and statistic == "upper":
        fewest = _fewest_for_quantile_limit(0.95, confidence)
        for key, n in (("study.realizations", realizations), ("design.validation_realizations", validation)):
            if n is not None and n < fewest:
                src.invalid(key, n, f"the upper {confidence:g} confidence limit of a 95 % quantile needs at least "
                                    f"{fewest} realisations; use more, or statistic = \"estimate\"")
    if len(process.blankholder_force_N) > 1:
        src.invalid("process.blankholder_force_N", list(process.blankholder_force_N),
                    "a [design] study takes one force, its baseline design; remove the sweep")
    for name, varied in (("blankholder_force", True), ("friction", friction is not None)):
        if varied and name in uncertainty.factors:
            src.invalid(f"uncertainty.{name}", doc["uncertainty"][name],
                        f"{name} is a [design] variable here; remove [uncertainty.{name}]")
    if sensitivity.method != "none":
        src.invalid("sensitivity.method", sensitivity.method,
                    'a [design] study runs its own designs; set method = "none" or remove [design]')
    return Design(variables, (lo, hi), objective, sectors, friction, budget, statistic, target, confidence,
                  evaluations, tolerance, validation, draw_in)


def _report(src: _Source, doc: dict, rings: int) -> Report:
    t = _Table(src, "report", doc.get("report", {}), ("histogram_nodes", "experimental_csv"))
    hint = f"histogram_nodes must be a list of [i, j] integer pairs with |i|, |j| <= rings = {rings}"
    nodes = t.raw("histogram_nodes", [], hint)
    ok = isinstance(nodes, list) and all(
        isinstance(n, list) and len(n) == 2 and all(_is_int(v) and abs(v) <= rings for v in n) for n in nodes)
    if not ok:
        t.invalid("histogram_nodes", hint)
    csv = None
    if t.has("experimental_csv"):
        csv = src.relative_file("report.experimental_csv", t.data["experimental_csv"])
        try:
            read_experimental(csv)  # a run must not find a bad CSV only when it writes the report
        except ValueError as err:
            src.invalid("report.experimental_csv", t.data["experimental_csv"], str(err))
    return Report(tuple((int(i), int(j)) for i, j in nodes), csv)


def _output(src: _Source, doc: dict, name: str) -> tuple[Path, bool]:
    t = _Table(src, "output", doc.get("output", {}), ("directory", "float32"))
    directory = t.string("directory", f"results/{name}", hint="directory must be a non-empty path", valid=bool)
    float32 = t.raw("float32", False, "float32 must be true or false")
    if not isinstance(float32, bool):
        t.invalid("float32", "float32 must be true or false")
    existing = _nearest_existing(Path(directory))
    if not existing.is_dir():
        src.invalid("output.directory", directory, f"{existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        src.invalid("output.directory", directory, f"{existing} is not writable")
    return Path(directory), float32


#: Bytes a node costs in a chunk file (x, y, z, shear, locked, status and the cells' values)
#: and, about, in the solver's working arrays of an energy drape (candidate rings per step).
STORED_BYTES_PER_NODE = 64
WORKING_BYTES_PER_NODE = 600


def _nominal_placement(src: _Source, mould, fabric: Fabric, solver: Solver) -> None:
    """Refuse a study whose nominal net (a geodesic drape at the fixed settings) loses more
    than ``failure_budget`` of its nodes: every realisation would be mostly NaN."""
    ds = drape(mould, fabric.spacing_mm, solver.rings, orientation=fabric.orientation_deg,
               pre_shear=fabric.pre_shear_deg, skew=fabric.skew_deg, crossover=fabric.crossover)
    failed, why = placement_failures(ds["status"].values[0])
    if failed > solver.failure_budget:
        src.invalid("solver.rings", solver.rings, f"{failed:.0%} of the nominal net's nodes cannot be placed "
                    f"(geodesic drape at the fixed settings), more than solver.failure_budget = "
                    f"{solver.failure_budget:g} ({why}): use fewer rings, a smaller spacing or move the crossover")


def _nearest_existing(path: Path) -> Path:
    """``path`` (absolute) or its nearest ancestor that exists: where the output folder will be made."""
    path = path.absolute()
    while not path.exists():
        path = path.parent
    return path


def _memory() -> int:
    """This machine's physical memory (bytes)."""
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def _resources(src: _Source, realizations: int, chunk_size: int, rings: int, levels: int, output_dir: Path):
    """Refuse a study whose chunk would not fit in memory or whose ensemble would not fit on
    the disk of its output folder (estimates, stated in the message; one drape's own size
    is checked with [solver] rings)."""
    nodes = (2 * rings + 1) ** 2
    batch = min(chunk_size, realizations)
    need = batch * nodes * WORKING_BYTES_PER_NODE
    if need > _memory() / 2:
        src.invalid("study.chunk_size", chunk_size,
                    f"a chunk of {batch} drapes of {nodes:,} nodes needs about {need / 2**30:.3g} GiB, more than "
                    f"half of this machine's {_memory() / 2**30:.3g} GiB; use a smaller chunk_size")
    existing = _nearest_existing(output_dir)
    disk = realizations * levels * nodes * STORED_BYTES_PER_NODE
    free = shutil.disk_usage(existing).free
    if disk > free:
        src.invalid("study.realizations", realizations,
                    f"{realizations * levels:,} drapes of {nodes:,} nodes take about {disk / 2**30:.3g} GiB, "
                    f"more than the {free / 2**30:.3g} GiB free under {existing}")


# ----------------------------------------------------------------------------- public API


def load_study(path) -> Study:
    """Read and validate a study file; raises StudyError (first problem found)."""
    path = Path(path)
    src = _Source(path)
    doc = _read_toml(path, src)
    for key, value in doc.items():
        if key not in SECTIONS:
            what = f"section [{key}]" if isinstance(value, dict) else f"top-level key {key} (outside any section)"
            src.fail(f"unknown {what}; valid sections: {', '.join(SECTIONS)}")
    for key in ("study", "geometry", "fabric", "process", "solver"):
        if key not in doc:
            src.fail(f"section [{key}] is missing (required: study, geometry, fabric, process, solver)")
    head = _study(src, doc)
    geometry, mould = _geometry_section(src, doc)
    fabric = _fabric(src, doc, mould)
    process = _process(src, doc)
    solver = _solver(src, doc)
    uncertainty = _uncertainty(src, doc, fabric, process, solver, mould)
    sampling = _sampling(src, doc, head["realizations"], head["seed"])
    sensitivity = _sensitivity(src, doc, uncertainty)
    design = _design(src, doc, process, uncertainty, sensitivity, head["realizations"])
    report = _report(src, doc, solver.rings)
    output_dir, float32 = _output(src, doc, head["name"])  # checked last, as the sections are ordered
    _resources(src, head["realizations"], head["chunk_size"], solver.rings, len(process.blankholder_force_N),
               output_dir)
    _nominal_placement(src, mould, fabric, solver)
    return Study(
        path=path,
        **head,
        geometry=geometry,
        fabric=fabric,
        process=process,
        solver=solver,
        uncertainty=uncertainty,
        sampling=sampling,
        sensitivity=sensitivity,
        report=report,
        output_dir=output_dir,
        design=design,
        float32=float32,
    )
