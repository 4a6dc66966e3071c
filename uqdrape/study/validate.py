"""The study file: read a study TOML, validate it, explain what is wrong.

``load_study(path)`` reads a study file (TOML, via ``tomllib``) into a frozen
:class:`~uqdrape.study.spec.Study`.

Sections and keys: ``KEYS`` below, in the order they are checked. What each key means,
with its units and default, is the study-file reference of the documentation, rendered
from ``KEYS`` and the other tables here by ``docs/_ext/studyref.py``.

Factor distributions (values in the units of the setting they override): normal
(mean, sd), truncnormal (mean, sd, bounds = [lo, hi]; mean/sd of the parent normal),
uniform (bounds = [lo, hi]), lognormal (mean, sd of the value itself, as in
uqdrape.stochastic). A factor overrides its fixed setting in the ensemble; the fixed
value stays the nominal one.

Paths in the file (a mesh mould's ``path``, a material card, ``experimental_csv``) are relative to
the study file and must stay in its folder or below (absolute paths and '..' are refused:
a study read as data reads nothing its folder does not hold). ``output.directory`` is
relative to the current working directory, as ``results/<study name>`` is meant to be, and
a relative one must stay inside it ('..' climbing out is refused); an absolute directory is
taken as written and shown by ``uqdrape validate``; ``--out DIR`` on the command line
replaces it and may be anywhere. A directory with ``://`` is an fsspec URL
(``s3://bucket/prefix``, ``file:///abs/path``): the run writes one zarr store there
(``uqdrape.ensemble.zarrstore``). A ``file://`` URL's path is held to the rule of a path
(``file://../x`` is refused as ``../x`` is), and a URL must name something after ``://``.

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

import dataclasses
import inspect
import math
import re
from pathlib import Path

import numpy as np

from .. import geometry as _geometry
from .. import material as _material
from .. import stochastic as _stochastic
from ..experimental import read_experimental
from ..geometry.outline import read_trim
from ..files import (REQUIRED, Document, FileFormatError, Table, fmt, inside, is_int, is_number, location,
                     url_problem)
from ..stochastic.sampling import EXTENDABLE_PLANS, RQMC, STUDY_PLANS, rqmc_points
from ..schema import (BLANKHOLDER_MODELS, MAX_RINGS, MAX_TOLERANCE_DEG, MODES, QOI_ATTRS, SENSITIVITY_QOIS,
                      SOLVER_INPUTS, SPACING_RANGE_MM)
from ..material.scatter import card_scatter
from .spec import (CARD, DESIGN_OBJECTIVES, DESIGN_STATISTICS, DESIGN_VARIABLES, DIST_KEYS, FACTOR_SETTINGS, FIELD_KEYS,
                   FIELDS, RARE_QOIS, SECTIONS, SENSITIVITY_METHODS, TARGET_STATISTICS, Design, Fabric, Geometry,
                   Ply, Process, RandomField, Rare, RareLimit, Report, Sampling, Sensitivity, Solver, Study,
                   Target, Uncertainty, fields_table, prestrain_map)


class StudyError(FileFormatError):
    """A problem in a study file; the message names the file, the key, the value and what
    is valid, ``path`` is the file and ``key`` the dotted key (None for the file as a whole)."""


def study_error(path, key: str, value, why: str) -> StudyError:
    """The error for ``key = value`` of study file ``path``: ``<file>: <key> = <value> is invalid: <why>``."""
    return StudyError(f"{path}: {key} = {fmt(value)} is invalid: {why}", path, key)


# factor distributions offered in a study file (a constant is the fixed setting itself)
_DISTS = tuple(d for d in _stochastic.DISTRIBUTIONS if d != "constant")
_NAME_RE = re.compile(r"^[A-Za-z0-9_-]+$")

#: The keys of each table of a study file, in the order they are checked. The mould's keys
#: are its kind's shape parameters (``uqdrape.geometry.KINDS``), a scalar factor's its
#: distribution's (``DIST_KEYS``). The study-file reference of the documentation is
#: generated from this table (``docs/_ext/studyref.py``), so a key added here needs its
#: entry there (a test holds the two equal).
_FIELD_COMMON = ("correlation", "length_mm", "kl_retained")
KEYS = {
    "study": ("name", "seed", "realizations", "chunk_size", "description", "target", "max_realizations", "rare"),
    "study.target": ("qoi", "statistic", "half_width", "confidence"),
    "study.rare": ("qoi", "threshold", "cov", "max_drapes"),
    "fabric": ("material", "spacing_mm", "orientation_deg", "pre_shear_deg", "skew_deg", "crossover", "imbalance_Nm"),
    "process": ("blankholder_force_N", "friction", "sectors", "blankholder_model"),
    "solver": ("mode", "rings", "tolerance_deg", "max_iterations", "failure_budget"),
    **{f"uncertainty.{name}": (*keys, *_FIELD_COMMON, *(("sd_dof", "length_log_sd") if name == "zero_angle" else ()))
       for name, keys in FIELD_KEYS.items()},
    "sampling": ("plan", "randomizations"),
    "sensitivity": ("method", "base_samples", "qoi"),
    "design": ("variables", "sectors", "force_bounds_N", "friction_bounds", "budget_N", "objective", "statistic",
               "target", "confidence", "max_evaluations", "tolerance_N", "validation_realizations",
               "max_draw_in_mm", "rare"),
    "design.rare": ("qoi", "threshold", "max_probability", "cov", "max_drapes"),
    "report": ("histogram_nodes", "experimental_csv", "fixed_twin"),
    "ply": ("name", "angle_deg", "material", "spacing_mm", "crossover", "misalignment_sd_deg", "trim", "thickness_mm",
            "uncertainty"),
    "output": ("directory", "float32"),
}

#: How far a random input's values reach, in standard deviations: a few million draws of a
#: standard normal (a large ensemble's cells) stay within 7 with all but 1e-5 probability.
REACH_SD = 7.0
#: Largest sd of ln length a study may draw its lengths with: a factor e^7 ~ 1,100 at the
#: reach, past which a drawn field is constant over any net or iid on its lattice.
MAX_LENGTH_LOG_SD = 1.0
#: Most blank-holder sectors a [design] optimises: one force each, every candidate a
#: whole ensemble of drapes (36: 10 degrees of the rim a sector).
MAX_DESIGN_SECTORS = 36
#: Most candidate designs a [design] may evaluate, each a whole ensemble of drapes (the
#: shipped designs take 40-52), and most realisations of its validation ensembles (the
#: largest ensemble run into one store, 10^6).
MAX_DESIGN_EVALUATIONS = 10_000
MAX_VALIDATION_REALIZATIONS = 1_000_000
#: Thickness a ply may add to the stack (mm): a dry ply is a fraction of a millimetre to a
#: few millimetres (an NCF's 2 mm); 10 mm is a typing error.
MAX_PLY_THICKNESS_MM = 10.0


class _Source(Document):
    """The study file being read (``uqdrape.files.Document``), which also says which study
    key another module's ParameterError is about."""

    def __init__(self, path: Path):
        super().__init__(path, "study file", error=StudyError)

    def wrap(self, err: ValueError, section: str, given: dict, required: dict | None = None):
        """Re-raise another module's ValueError with file and key context.

        ``given`` maps an argument name as the other module spells it to (dotted study key,
        value) for keys present in the file; ``required`` maps names of absent required keys
        to their dotted keys. The error's own ``names`` (``uqdrape.errors.ParameterError``)
        decide which key is blamed: a missing required key first, else every present key
        it names, else ``[section]``.
        """
        msg, names = str(err), getattr(err, "names", ())
        for name in names:
            if name in (required or {}):
                self.missing(required[name], msg)
        blamed = {}
        for name in names:
            if name in given:
                blamed.setdefault(*given[name])
        if blamed:
            lhs = ", ".join(f"{k} = {fmt(v)}" for k, v in blamed.items())
            self.fail(f"{lhs} is invalid: {msg}", next(iter(blamed)))
        self.fail(f"[{section}] is invalid: {msg}", section)


# ----------------------------------------------------------------------------- sections


def _study(src: _Source, doc: dict) -> dict:
    t = Table(src, "study", doc.get("study", {}), KEYS["study"])
    name = t.string("name", hint="name must be a non-empty string of letters, digits, '-' and '_'",
                    valid=_NAME_RE.match)
    head = {
        "name": name,
        "seed": t.number("seed", integer=True, ge=0, lt=2**63),
        "realizations": t.number("realizations", integer=True, ge=1),
        "chunk_size": t.number("chunk_size", 64, integer=True, ge=1),
        "description": t.string("description", ""),
    }
    if t.has("target") != t.has("max_realizations"):
        given, absent = ("target", "max_realizations") if t.has("target") else ("max_realizations", "target")
        t.invalid(given, f"a run to a target needs both study.target and study.max_realizations (its budget): "
                         f"add {absent} or remove {given}")
    if t.has("target"):
        head["target"] = _target(t.table("target", KEYS["study.target"]))
        head["max_realizations"] = t.number("max_realizations", integer=True, ge=head["realizations"])
    if t.has("rare"):
        r = t.table("rare", KEYS["study.rare"])
        head["rare"] = Rare(*_rare(r))
    return head


def _rare(r: Table) -> tuple:
    """(qoi, threshold, cov, max_drapes) of a rare probability's table."""
    return (r.string("qoi", choices=RARE_QOIS), r.number("threshold"), r.number("cov", 0.1, gt=0, lt=1),
            r.number("max_drapes", 20_000, integer=True, ge=1000))


def _target(t: Table) -> Target:
    qoi = t.string("qoi", choices=tuple(QOI_ATTRS))
    statistic = t.string("statistic", choices=tuple(TARGET_STATISTICS))
    applies = TARGET_STATISTICS[statistic]
    if applies is not None and qoi not in applies:
        t.invalid("statistic", f"statistic {statistic!r} is of a 0/1 quantity: qoi must be one of {', '.join(applies)}")
    return Target(qoi, statistic, t.number("half_width", gt=0), t.number("confidence", 0.95, gt=0, lt=1))


def _target_rules(src: _Source, head: dict, sampling: Sampling, sensitivity: Sensitivity, design) -> None:
    """A target run extends its own Monte Carlo (or randomised QMC) sample: refuse it
    with a plan that does not extend, a sensitivity design or a [design]."""
    if "target" not in head:
        return
    if sampling.plan not in EXTENDABLE_PLANS:
        src.invalid("sampling.plan", sampling.plan, f"a [study] target run adds realisations in rounds: the plan "
                                                    f"must be one of {', '.join(EXTENDABLE_PLANS)}")
    if sensitivity.method != "none" or design is not None:
        src.invalid("study.target", dataclasses.asdict(head["target"]),
                    'a [study] target is for a sample of the study (sensitivity method = "none", no [design]): '
                    'remove it')


def _rare_rules(src: _Source, head: dict, uncertainty: Uncertainty, design) -> None:
    """A rare probability is of the study's own inputs as standard normals: refuse it with
    a [design] (whose force is what varies) or a sd drawn per realisation (no column)."""
    if "rare" not in head:
        return
    if design is not None:
        src.invalid("study.rare", dataclasses.asdict(head["rare"]),
                    "a [study] rare probability is estimated for a study without [design]: remove it (a "
                    "design takes one as its constraint: [design] rare)")
    _fixed_sd(src, uncertainty, "a [study] rare probability")


def _geometry_section(src: _Source, doc: dict):
    """The mould spec and the built mould (needed for the crossover checks)."""
    t = Table(src, "geometry", doc["geometry"])
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
    t = Table(src, "fabric", doc.get("fabric", {}), KEYS["fabric"])
    material, card = _material_card(t, REQUIRED)
    spacing = t.number("spacing_mm", ge=SPACING_RANGE_MM[0], lt=SPACING_RANGE_MM[1])
    orientation = t.number("orientation_deg", 0.0)
    if not SOLVER_INPUTS["orientation"].admits(orientation):
        t.invalid("orientation_deg", f"orientation_deg {SOLVER_INPUTS['orientation'].describe_range()}")
    pre_shear = t.number("pre_shear_deg", 0.0, gt=-90, lt=90)
    skew = t.number("skew_deg", 0.0, gt=-90, lt=90)
    if abs(pre_shear + skew) >= 90:
        t.invalid("skew_deg", f"pre_shear_deg + skew_deg must lie in (-90, 90) degrees, got {pre_shear + skew:g}")
    locked = card.blank_shear_error(pre_shear)
    if locked:
        t.invalid("pre_shear_deg", f"a blank pre-sheared {pre_shear:g} deg is {locked}")
    crossover = t.numbers("crossover", (0.0, 0.0), length=2,
                          hint="crossover must be two numbers [x, y] in mm")
    off = mould.crossover_error(*crossover)
    if off:
        src.invalid("fabric.crossover", list(crossover), off)
    imbalance = t.number("imbalance_Nm", None, gt=0)
    if imbalance is not None:
        from ..material.imbalance import with_imbalance

        try:
            with_imbalance(card, imbalance)
        except ValueError as err:
            t.invalid("imbalance_Nm", str(err))
    return Fabric(material, spacing, orientation, pre_shear, crossover, skew, imbalance)


def _material_card(t: Table, default) -> tuple:
    """(material as a Study holds it, its loaded card) of ``t``'s ``material`` key: a
    shipped card's name or a card file relative to the study file."""
    shipped = _material.available_materials()
    hint = (f"material must be a shipped card ({', '.join(shipped)}) "
            "or the path of a .toml/.csv card relative to the study file")
    name = t.string("material", default, hint=hint)
    if name in shipped:
        material = name
    elif Path(name).suffix.lower() in (".toml", ".csv") and t.has("material"):
        material = str(t.doc.relative_file(t.dotted("material"), name))
    elif not t.has("material"):
        material = name  # the fabric's, checked there
    else:
        t.invalid("material", hint)
    try:
        return material, _material.load_material(material)
    except ValueError as err:
        t.invalid("material", str(err))


def _process(src: _Source, doc: dict) -> Process:
    t = Table(src, "process", doc.get("process", {}), KEYS["process"])
    hint = ("blankholder_force_N must be a number >= 0 (N), "
            "or a non-empty list of distinct numbers >= 0 (a sweep)")
    force = t.raw("blankholder_force_N", REQUIRED, hint)
    if is_number(force):
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
    t = Table(src, "solver", doc.get("solver", {}), KEYS["solver"])
    solver = Solver(
        mode=t.string("mode", "energy", choices=MODES),
        rings=t.number("rings", integer=True, ge=1),
        tolerance_deg=t.number("tolerance_deg", 1e-3, gt=0),
        max_iterations=t.number("max_iterations", 30, integer=True, ge=1),
        failure_budget=t.number("failure_budget", 0.5, ge=0),
    )
    if solver.rings > MAX_RINGS:
        t.invalid("rings", f"rings must be an integer in [1, {MAX_RINGS}]: (2 rings + 1)^2 nodes, "
                           f"{(2 * MAX_RINGS + 1) ** 2:,} at most")
    if solver.failure_budget > 1:
        t.invalid("failure_budget", "failure_budget is a fraction of the nodes, in [0, 1]")
    if solver.tolerance_deg > MAX_TOLERANCE_DEG:
        t.invalid("tolerance_deg", f"the minimiser's tolerance on turn angles must lie in (0, {MAX_TOLERANCE_DEG:g}] "
                                   "degrees")
    return solver


def _field(src: _Source, name: str, data, rings: int, spacing_mm: float, material: str,
           section: str | None = None) -> RandomField:
    section = section or f"uncertainty.{name}"
    t = Table(src, section, data, KEYS[f"uncertainty.{name}"])
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
        top = params["mean"] + REACH_SD * params["sd"]
        if top > table.max_prestrain:
            src.invalid(section, data, f"mean + {REACH_SD:g} sd = {top:g} passes the largest mapped pre-strain "
                                       f"{table.max_prestrain:g}; use a smaller mean or sd")
    correlation = t.string("correlation", "iid", choices=_stochastic.CORRELATIONS)
    length = None
    if t.has("length_mm"):
        if correlation == "iid":
            t.invalid("length_mm", 'length_mm is only used by a correlated field: set correlation = '
                      '"exponential" or "squared_exponential", or remove length_mm')
        length = t.numbers("length_mm", length=2, hint="length_mm must be two numbers [L1, L2] in mm, > 0")
    retained = t.number("kl_retained", 0.95)
    sd_dof = t.number("sd_dof", gt=0) if t.has("sd_dof") else None
    if sd_dof is not None and name == "zero_angle":
        # the sd a realisation may draw (its 99.9 % quantile) must keep the field's reach inside (-90, 90)
        from scipy.stats import chi2

        top = params["sd_deg"] * math.sqrt(sd_dof / chi2.ppf(1e-3, sd_dof))
        if abs(params["mean_deg"]) + REACH_SD * top >= 90:
            t.invalid("sd_dof", f"a realisation's sd reaches {top:.3g} deg (99.9 % quantile of sd_deg sqrt(m / chi2_m)), "
                                f"and |mean_deg| + {REACH_SD:g} x that passes 90 deg: the measurement bounds the sd too "
                                "loosely for a hierarchical run; use a larger sd_dof (more points) or remove it")
    length_log_sd = _length_log_sd(t, correlation) if t.has("length_log_sd") else None
    _reach(src, name, t, params)
    spec = RandomField(name, params, correlation, length, retained,
                       material if name == "stitch_prestrain" else None, sd_dof, length_log_sd)
    given = {k: (t.dotted(k), v) for k, v in t.data.items()}
    given["retained"] = (t.dotted("kl_retained"), retained)
    required = {"length_mm": t.dotted("length_mm")} if length is None and correlation != "iid" else {}
    try:
        spec.build_input(rings, spacing_mm).kl(retained)
    except ValueError as err:
        src.wrap(err, section, given, required)
    return spec


def _length_log_sd(t: Table, correlation: str) -> float:
    """The sd s of ln L of lengths drawn per realisation, in (0, MAX_LENGTH_LOG_SD]: out to the
    field's reach (REACH_SD sd) L exp(+-s z) stays within a factor e^REACH_SD of L."""
    if correlation == "iid":
        t.invalid("length_log_sd", 'length_log_sd draws a correlated field\'s lengths: set correlation = '
                                   '"exponential" or "squared_exponential", or remove length_log_sd')
    s = t.number("length_log_sd", gt=0)
    if s > MAX_LENGTH_LOG_SD:
        t.invalid("length_log_sd", f"length_log_sd (the sd of ln length) must lie in (0, {MAX_LENGTH_LOG_SD:g}]: "
                                   f"at {REACH_SD:g} sd a length would move by a factor e^{REACH_SD * s:.3g}, "
                                   "too loose a length for a hierarchical run; remove length_log_sd")
    return s


def _reach(src: _Source, name: str, t: Table, params: dict) -> None:
    """Refuse a spacing or zero-angle field whose values, out to REACH_SD standard
    deviations, leave the physical range: a segment length must stay > 0, a cell's
    zero-energy angle inside (-90, 90) degrees. (The runtime check would otherwise stop a
    run at the first realisation that goes there.)"""
    if name == "spacing" and 0 <= params["cv"] < 1 and params["cv"] * REACH_SD >= 1:
        t.invalid("cv", f"a segment s (1 + cv z) must stay > 0 out to z = -{REACH_SD:g} (the field's reach): "
                        f"cv must be < {1 / REACH_SD:.3g}")
    if name == "zero_angle" and abs(params["mean_deg"]) + REACH_SD * abs(params["sd_deg"]) >= 90:
        t.invalid("sd_deg" if t.has("sd_deg") else "mean_deg",
                  f"|mean_deg| + {REACH_SD:g} sd_deg = {abs(params['mean_deg']) + REACH_SD * abs(params['sd_deg']):g} "
                  "degrees: a cell's zero-energy angle must stay inside (-90, 90) degrees out to the field's reach")


def _factor(src: _Source, name: str, data):
    section = f"uncertainty.{name}"
    t = Table(src, section, data)
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
    t = Table(src, "uncertainty", doc.get("uncertainty", {}), names)
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
    if CARD in factors:
        _card(src, t.data[CARD], fabric, solver)
    for name, factor in factors.items():
        if name == CARD:
            continue
        inp = SOLVER_INPUTS[name]
        lo, hi = _extent(factor)
        if not (inp.admits(lo) and inp.admits(hi)):
            src.invalid(f"uncertainty.{name}", t.data[name],
                        f"its values reach [{lo:g}, {hi:g}] but {name} {inp.describe_range()}; "
                        "use bounds (uniform/truncnormal) or a smaller sd")
    if "pre_shear" in factors:  # the blank must not start locked anywhere in its reach
        card = _material.load_material(fabric.material)
        for pre in _extent(factors["pre_shear"]):
            locked = card.blank_shear_error(pre)
            if locked:
                src.invalid("uncertainty.pre_shear", t.data["pre_shear"], f"its values reach a pre-shear of "
                            f"{pre:.4g} deg, {locked}; use bounds (uniform/truncnormal) or a smaller sd")
    if {"crossover_x", "crossover_y"} & set(factors):
        xs = _extent(factors["crossover_x"]) if "crossover_x" in factors else (fabric.crossover[0],) * 2
        ys = _extent(factors["crossover_y"]) if "crossover_y" in factors else (fabric.crossover[1],) * 2
        corners = [(x, y) for x in xs for y in ys]
        if not all(mould.contains(x, y) for x, y in corners):
            key = "crossover_x" if "crossover_x" in factors else "crossover_y"
            src.invalid(f"uncertainty.{key}", t.data[key],
                        f"crossovers up to x in [{xs[0]:g}, {xs[1]:g}], y in [{ys[0]:g}, {ys[1]:g}] mm "
                        f"leave the mould's domain ({mould.domain()})")
    return Uncertainty(fields, factors)


def _card(src: _Source, data, fabric: Fabric, solver: Solver) -> None:
    """[uncertainty.card] needs an energy drape (a geodesic one reads no card) and a card
    that records its specimens' scatter."""
    if solver.mode != "energy":
        src.invalid("uncertainty.card", data, 'the card scatter acts on the shear energy: it needs [solver] mode = '
                                              '"energy"')
    if not card_scatter(fabric.material):
        src.invalid("uncertainty.card", data, f"the card {fabric.material} has no [scatter] table (the specimens' sd "
                                              "of N_s): fit it from several specimens with `uqdrape materials fit`")


def _extent(factor) -> tuple[float, float]:
    """The range of values a design can give (u = 0 and 1; about ±7 sd for a normal)."""
    lo, hi = factor.ppf(np.array([0.0, 1.0]))
    return float(lo), float(hi)


def _sampling(src: _Source, doc: dict, realizations: int, seed: int, uncertainty: Uncertainty,
              solver: Solver, fabric: Fabric) -> Sampling:
    t = Table(src, "sampling", doc.get("sampling", {}), KEYS["sampling"])
    plan = t.string("plan", "monte_carlo", choices=STUDY_PLANS)
    given = {"plan": ("sampling.plan", plan), "n": ("study.realizations", realizations)}
    if plan != RQMC:
        if t.has("randomizations"):
            t.invalid("randomizations", f'randomizations is only used by plan = "{RQMC}": set it, or remove '
                                        "randomizations")
        try:
            _stochastic.sample_uniforms(plan, realizations, 0, seed)  # checks the plan, draws nothing
        except ValueError as err:
            src.wrap(err, "sampling", given)
        return Sampling(plan)
    _fixed_sd(src, uncertainty, f'sampling plan = "{RQMC}"')
    k = t.number("randomizations", integer=True)
    given["randomizations"] = ("sampling.randomizations", k)
    d = len(uncertainty.factors) + sum(f.build_input(solver.rings, fabric.spacing_mm).kl(f.kl_retained).n_variables
                                       for f in uncertainty.fields.values())
    try:
        rqmc_points(realizations, k)
    except ValueError as err:
        src.wrap(err, "sampling", given)
    from scipy.stats import qmc

    if d > qmc.Sobol.MAXDIM:
        src.invalid("sampling.plan", plan, f"an rqmc plan of {d} variables (factors and KL modes) needs more "
                                           f"Sobol' dimensions than scipy's {qmc.Sobol.MAXDIM}: use a correlated "
                                           "field or a lower kl_retained")
    return Sampling(plan, k)


def _fixed_sd(src: _Source, uncertainty: Uncertainty, what: str) -> None:
    """Refuse a hierarchical zero-angle sd or length (``sd_dof``, ``length_log_sd``) under a
    design of standard variables (rqmc, a sensitivity design) or a rare estimate: its
    columns hold no variable for them."""
    field = uncertainty.fields.get("zero_angle")
    for key, what_drawn in (("sd_dof", "a sd"), ("length_log_sd", "a correlation length")):
        value = getattr(field, key, None)
        if value is not None:
            src.invalid(f"uncertainty.zero_angle.{key}", value,
                        f"{what_drawn} drawn per realisation is not supported with {what}: use plan = "
                        f"\"monte_carlo\", \"latin_hypercube\" or \"sobol\" without a sensitivity design, or remove {key}")


def _sensitivity(src: _Source, doc: dict, uncertainty: Uncertainty) -> Sensitivity:
    t = Table(src, "sensitivity", doc.get("sensitivity", {}), KEYS["sensitivity"])
    method = t.string("method", "none", choices=SENSITIVITY_METHODS)
    base = None
    if method == "none":
        if t.has("base_samples"):
            t.invalid("base_samples", 'base_samples is only used by a sensitivity method: set method = '
                      '"sobol" or "morris", or remove base_samples')
    else:
        _fixed_sd(src, uncertainty, f'sensitivity method = "{method}"')
        base = t.number("base_samples", integer=True, ge=1)
        try:
            _stochastic.check_base_samples(method, base)
        except ValueError as err:
            src.wrap(err, "sensitivity", {"base_samples": ("sensitivity.base_samples", base)})
        if len(uncertainty.varying) < 2:
            found = ", ".join(uncertainty.varying) or "none"
            src.invalid("sensitivity.method", method,
                        f"a sensitivity analysis needs at least two [uncertainty.*] inputs (found: {found}); "
                        "indices of a single input are 1 by construction")
    hint = f"qoi must be a non-empty list of distinct names from {', '.join(QOI_ATTRS)}"
    qoi = t.raw("qoi", list(SENSITIVITY_QOIS), hint)
    if (not isinstance(qoi, list) or not qoi or len(set(map(repr, qoi))) != len(qoi)
            or any(q not in QOI_ATTRS for q in qoi)):
        t.invalid("qoi", hint)
    return Sensitivity(method, base, tuple(qoi))


def _bounds(t: Table, key: str, unit: str):
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
    t = Table(src, "design", doc["design"], KEYS["design"])
    variables = t.string("variables", choices=DESIGN_VARIABLES)
    sectors = None
    if variables == "sectors":
        sectors = t.number("sectors", integer=True, ge=2, lt=MAX_DESIGN_SECTORS + 1)
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
    evaluations = t.number("max_evaluations", 40, integer=True, ge=4, lt=MAX_DESIGN_EVALUATIONS + 1)
    tolerance = t.number("tolerance_N", 5.0, gt=0)
    validation = t.number("validation_realizations", None, integer=True, ge=2, lt=MAX_VALIDATION_REALIZATIONS + 1)
    draw_in = t.number("max_draw_in_mm", None, gt=0)
    rare = None
    if t.has("rare"):
        r = t.table("rare", KEYS["design.rare"])
        qoi, threshold, cov, drapes = _rare(r)
        rare = RareLimit(qoi, threshold, r.number("max_probability", gt=0, lt=1), cov, drapes)
        _fixed_sd(src, uncertainty, "a [design] rare constraint")
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
                  evaluations, tolerance, validation, draw_in, rare)


def _report(src: _Source, doc: dict, rings: int, uncertainty: Uncertainty, design: Design | None) -> Report:
    t = Table(src, "report", doc.get("report", {}), KEYS["report"])
    hint = f"histogram_nodes must be a list of [i, j] integer pairs with |i|, |j| <= rings = {rings}"
    nodes = t.raw("histogram_nodes", [], hint)
    ok = isinstance(nodes, list) and all(
        isinstance(n, list) and len(n) == 2 and all(is_int(v) and abs(v) <= rings for v in n) for n in nodes)
    if not ok:
        t.invalid("histogram_nodes", hint)
    csv = None
    if t.has("experimental_csv"):
        csv = src.relative_file("report.experimental_csv", t.data["experimental_csv"])
        try:
            read_experimental(csv)  # a run must not find a bad CSV only when it writes the report
        except ValueError as err:
            src.invalid("report.experimental_csv", t.data["experimental_csv"], str(err))
    return Report(tuple((int(i), int(j)) for i, j in nodes), csv, _fixed_twin(t, uncertainty, design))


def _fixed_twin(t: Table, uncertainty: Uncertainty, design: Design | None) -> bool | None:
    """``report.fixed_twin``: true by default for a hierarchical ensemble (a zero-angle sd
    or length drawn per realisation), refused where no twin would be draped."""
    field = uncertainty.fields.get("zero_angle")
    drawn = field is not None and (field.sd_dof is not None or field.length_log_sd is not None)
    if not t.has("fixed_twin"):
        return True if drawn and design is None else None
    value = t.data["fixed_twin"]
    if not isinstance(value, bool):
        t.invalid("fixed_twin", "fixed_twin must be true or false")
    if not drawn:
        t.invalid("fixed_twin", "fixed_twin applies to a hierarchical study (sd_dof or length_log_sd in "
                                "[uncertainty.zero_angle]); remove it")
    if design is not None:
        t.invalid("fixed_twin", "a [design] study drapes no fixed twin; remove fixed_twin")
    return value


def _output(src: _Source, doc: dict, name: str) -> tuple[Path | str, bool]:
    t = Table(src, "output", doc.get("output", {}), KEYS["output"])
    directory = t.string("directory", f"results/{name}", hint="directory must be a non-empty path without NUL",
                         valid=lambda d: bool(d) and "\0" not in d)
    place = location(directory)
    if isinstance(place, str) and url_problem(place):
        t.invalid("directory", url_problem(place))
    local = isinstance(place, Path) or place.startswith("file://")
    path = directory.removeprefix("file://")  # file://../x is the path ../x
    if local and not Path(path).is_absolute() and not inside(path):
        t.invalid("directory", "a relative directory is taken from the current folder and must stay in it "
                               "('..' climbing out is refused); write the absolute path")
    float32 = t.raw("float32", False, "float32 must be true or false")
    if not isinstance(float32, bool):
        t.invalid("float32", "float32 must be true or false")
    return location(directory), float32


#: Study-level factors a laminate's plies share in each realisation: the process, and the
#: rosette's angle (``orientation``, a common rosette error); a ply's own misalignment is
#: its ``misalignment_sd_deg``.
SHARED_FACTORS = ("blankholder_force", "friction", "orientation")


def _plies(src: _Source, doc: dict, fabric: Fabric, solver: Solver, uncertainty: Uncertainty, mould,
           refused: dict) -> tuple[Ply, ...]:
    """The ply book ``[[ply]]`` (empty for a single-ply study). ``refused`` maps dotted keys
    present in the file to what a laminate does not combine with (checked first)."""
    if "ply" not in doc:
        return ()
    data = doc["ply"]
    if not isinstance(data, list) or not data or not all(isinstance(p, dict) for p in data):
        src.invalid("ply", data, "the ply book is an array of tables: one [[ply]] per ply, in stacking order "
                                 "(the first on the tool)")
    for key, why in refused.items():
        src.fail(f"{key} is not supported in a laminate (a study with [[ply]]): {why}", key)
    for name in uncertainty.factors:
        if name not in SHARED_FACTORS:
            src.fail(f"uncertainty.{name} is not supported in a laminate: its plies share only "
                     f"{', '.join(SHARED_FACTORS)} (orientation: the rosette's angle); give each ply its own "
                     "misalignment_sd_deg or fields", f"uncertainty.{name}")
    plies, seen = [], {}
    for k, entry in enumerate(data):
        name = Table(src, f"ply[{k}]", entry).string(
            "name", hint="name must be a non-empty string of letters, digits, '-' and '_'", valid=_NAME_RE.match)
        if name in seen:
            src.invalid(f"ply[{k}].name", name, f"ply[{seen[name]}] has the same name; ply names must differ")
        seen[name] = k
        plies.append(_ply(src, Table(src, f"ply.{name}", entry, KEYS["ply"]), name, fabric, solver, uncertainty,
                          mould))
    below = 0.0
    for ply in plies[:-1]:
        below += ply.thickness_mm
        if below:
            try:
                mould.offset(below)
            except ValueError as err:
                src.invalid(f"ply.{ply.name}.thickness_mm", ply.thickness_mm,
                            f"the plies above it lie on the tool offset by {below:g} mm: {err}")
    return tuple(plies)


def _ply(src: _Source, t: Table, name: str, fabric: Fabric, solver: Solver, uncertainty: Uncertainty,
         mould) -> Ply:
    """One [[ply]]: its keys default to the [fabric]'s, its fields to the study's."""
    angle = t.number("angle_deg")
    material, card = _material_card(t, fabric.material)
    locked = card.blank_shear_error(fabric.pre_shear_deg)
    if locked:
        t.invalid("material", f"the blank's pre-shear fabric.pre_shear_deg = {fabric.pre_shear_deg:g} deg is {locked}")
    spacing = t.number("spacing_mm", fabric.spacing_mm, ge=SPACING_RANGE_MM[0], lt=SPACING_RANGE_MM[1])
    crossover = t.numbers("crossover", fabric.crossover, length=2,
                          hint="crossover (the ply's seed point) must be two numbers [x, y] in mm")
    off = mould.crossover_error(*crossover)
    if off:
        src.invalid(t.dotted("crossover"), list(crossover), f"the ply's seed point is off the tool: {off}")
    sd = t.number("misalignment_sd_deg", 0.0, ge=0)
    reach = [fabric.orientation_deg + angle + s * REACH_SD * sd for s in (-1, 1)]
    if not all(SOLVER_INPUTS["orientation"].admits(a) for a in reach):
        t.invalid("misalignment_sd_deg", f"the ply's angle reaches [{reach[0]:g}, {reach[1]:g}] deg at {REACH_SD:g} sd; "
                                         f"orientation {SOLVER_INPUTS['orientation'].describe_range()}")
    trim = None
    if t.has("trim"):
        trim = str(src.relative_file(t.dotted("trim"), t.data["trim"]))
        try:
            read_trim(trim)
        except ValueError as err:
            t.invalid("trim", str(err))
    own = t.table("uncertainty", FIELDS)
    if "stitch_prestrain" in own.data and "zero_angle" in own.data:
        own.invalid("stitch_prestrain", "the stitch pre-strain sets each cell's zero-energy angle itself: give one "
                                        "of zero_angle and stitch_prestrain")
    given = own.data or {f: _plain_field(uncertainty.fields[f]) for f in uncertainty.fields}
    fields = {f: _field(src, f, entry, solver.rings, spacing, material,
                        own.dotted(f) if own.data else f"uncertainty.{f}") for f, entry in given.items()}
    for field in fields.values():
        if field.sd_dof is not None or field.length_log_sd is not None:
            src.fail(f"{field.name}: a sd or length drawn per realisation (sd_dof, length_log_sd) is not supported "
                     "in a laminate; remove it", f"uncertainty.{field.name}")
    thickness = t.number("thickness_mm", 0.0, ge=0, lt=MAX_PLY_THICKNESS_MM)
    return Ply(name, angle, material, spacing, crossover, sd, fields, trim, thickness)


def _plain_field(field: RandomField) -> dict:
    """A validated field as its study-file table (to check it again for a ply's card and spacing)."""
    return next(iter(fields_table({field.name: field}).values()))


# ----------------------------------------------------------------------------- public API


def load_study(path, overrides: dict | None = None) -> Study:
    """Read and validate a study file; raises StudyError (first problem found).
    ``overrides`` maps dotted keys ("process.friction") to values set in the file's
    document first, so each is checked as if the file held it (a calibration's design)."""
    path = Path(path)
    src = _Source(path)
    doc = src.read()
    for key, value in (overrides or {}).items():
        *tables, leaf = key.split(".")
        table = doc
        for name in tables:
            table = table.setdefault(name, {})
            if not isinstance(table, dict):
                src.fail(f"{name} in {key} is not a table", key)
        table[leaf] = value
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
    sampling = _sampling(src, doc, head["realizations"], head["seed"], uncertainty, solver, fabric)
    sensitivity = _sensitivity(src, doc, uncertainty)
    design = _design(src, doc, process, uncertainty, sensitivity, head["realizations"])
    _target_rules(src, head, sampling, sensitivity, design)
    _rare_rules(src, head, uncertainty, design)
    report = _report(src, doc, solver.rings, uncertainty, design)
    refused = {key: why for key, present, why in (
        ("sensitivity.method", sensitivity.method != "none", "a sensitivity sample is of one ply; remove it"),
        ("design", design is not None, "a blank-holder design is of one ply; remove [design]"),
        ("study.target", "target" in head, "give a number of realizations"),
        ("study.rare", "rare" in head, "a rare probability is of one ply; remove it"),
        ("fabric.imbalance_Nm", fabric.imbalance_Nm is not None, "each ply's card is used as it is; remove it"),
        ("uncertainty", any(f.sd_dof is not None or f.length_log_sd is not None
                            for f in uncertainty.fields.values()),
         "a sd or length drawn per realisation (sd_dof, length_log_sd) is of one ply; remove it")) if present}
    plies = _plies(src, doc, fabric, solver, uncertainty, mould, refused)
    output_dir, float32 = _output(src, doc, head["name"])  # checked last, as the sections are ordered
    return Study(path=path, **head, geometry=geometry, fabric=fabric, process=process, solver=solver,
                 uncertainty=uncertainty, sampling=sampling, sensitivity=sensitivity, report=report,
                 output_dir=output_dir, design=design, float32=float32, plies=plies)
