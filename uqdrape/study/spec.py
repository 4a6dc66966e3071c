"""The study specification: what a validated study file says, as frozen dataclasses.

A section's dataclass fields are named as its study-file keys, so one walk over
``dataclasses.fields`` writes a study back in its file layout (:meth:`Study.to_dict`, the
provenance stored with every ensemble) and reads it again (:func:`from_dict`) without a
second list of keys. Values are validated where a study file is read
(``uqdrape.study.validate``), never here.
"""

from __future__ import annotations

import dataclasses
import functools
import json
from dataclasses import dataclass
from pathlib import Path

from ..files import location
from .. import geometry as _geometry
from .. import material as _material
from .. import stochastic as _stochastic
from ..schema import QOI_ATTRS, SOLVER_INPUTS

#: Where a study file fixes each scalar solver input (``uqdrape.schema.SOLVER_INPUTS``,
#: the solver's names): (section, key, index of the element of a list key or None).
SETTING_KEYS = {
    "blankholder_force": ("process", "blankholder_force_N", None),
    "friction": ("process", "friction", None),
    "orientation": ("fabric", "orientation_deg", None),
    "crossover_x": ("fabric", "crossover", 0),
    "crossover_y": ("fabric", "crossover", 1),
    "pre_shear": ("fabric", "pre_shear_deg", None),
    "skew": ("fabric", "skew_deg", None),
}
assert set(SETTING_KEYS) == set(SOLVER_INPUTS), "every solver input has its study-file setting"
#: Scalar factors of [uncertainty.<factor>] -> the dotted study-file setting each one overrides.
FACTOR_SETTINGS = {name: f"{section}.{key}" + ("" if index is None else f"[{index}]")
                   for name, (section, key, index) in SETTING_KEYS.items()}
#: Random fields of [uncertainty.<field>] and the study-file keys of their own parameters.
FIELD_KEYS = {"spacing": ("cv",), "zero_angle": ("mean_deg", "sd_deg"), "stitch_prestrain": ("mean", "sd")}
FIELDS = tuple(FIELD_KEYS)
SENSITIVITY_METHODS = ("sobol", "morris", "none")
SECTIONS = (
    "study", "geometry", "fabric", "process", "solver",
    "uncertainty", "sampling", "sensitivity", "design", "report", "ply", "output",
)
#: Decision variables of a [design]: one total blank-holder force, or one force per sector.
DESIGN_VARIABLES = ("force", "sectors")
#: Design objectives by name -> (the per-drape quantity, the statistic of it):
#: P(any node locked) (binomial, Wilson limits), the 95 % quantile of the largest |node
#: shear| (order-statistic limits), |mean asymmetry| (Student-t limits of the mean), the
#: 95 % quantile of the largest draw-in of the held edge (mm; also the draw-in limit's).
DESIGN_OBJECTIVES = {"p_locked": ("any_locked", "probability"),
                     "q95_max_abs_shear": ("max_abs_shear", "quantile95"),
                     "abs_mean_asymmetry": ("asymmetry", "abs_mean"),
                     "q95_max_draw_in": ("max_draw_in", "quantile95")}
#: What a design minimises of its objective: the upper confidence limit or the estimate.
DESIGN_STATISTICS = ("upper", "estimate")
#: Statistics a [study] target can be about -> the QoIs (``uqdrape.schema.QOI_ATTRS``) they
#: apply to (None: any): the mean (Student-t interval; across randomisations under rqmc)
#: and the probability of a 0/1 quantity (Wilson score interval).
TARGET_STATISTICS = {"mean": None, "probability": ("any_locked",)}
#: QoIs a [study] rare probability can be about: those with a continuous value, which the
#: subset levels rank (a 0/1 quantity or a fraction that is 0 in nearly every drape gives
#: them nothing to rank; P(any cell locked) is P(lock_margin >= 1)).
RARE_QOIS = tuple(q for q in QOI_ATTRS if q not in ("any_locked", "locked_fraction"))
#: Study-file parameter names of each factor distribution; "bounds" = [lower, upper].
DIST_KEYS = {"normal": ("mean", "sd"), "truncnormal": ("mean", "sd", "bounds"),
             "uniform": ("bounds",), "lognormal": ("mean", "sd")}
#: The card-scatter factor: a realisation's score z on its card's specimen scatter,
#: N_s = mean + z sd at every angle (``uqdrape.material.scatter``); it varies the
#: fabric's material, as the other factors vary the setting they name.
CARD = "card"
FACTOR_SETTINGS[CARD] = "fabric.material"


@dataclass(frozen=True)
class Geometry:
    """The mould: ``kind`` (a key of uqdrape.geometry.KINDS) and its full shape parameters."""

    kind: str
    params: dict

    def build_mould(self):
        """A new Surface for this mould (an STL mould is re-read: keep the result)."""
        return _geometry.build(self.kind, **self.params)


@dataclass(frozen=True)
class Fabric:
    """Fabric and blank: material (shipped card name or absolute card path), mm, degrees."""

    material: str
    spacing_mm: float
    orientation_deg: float
    pre_shear_deg: float
    crossover: tuple[float, float]
    #: extra angle closed between the generator paths at the crossover (thesis Fig 5.5)
    skew_deg: float = 0.0
    #: the card's mid-angle imbalance ΔN(30°) moved to this value (N/m, F_s/L;
    #: ``uqdrape.material.imbalance``); None: the card as it is
    imbalance_Nm: float | None = None

    def card(self):
        """The Material this fabric drapes with: the card, its imbalance moved if asked."""
        card = _material.load_material(self.material)
        if self.imbalance_Nm is None:
            return card
        from ..material.imbalance import with_imbalance

        return with_imbalance(card, self.imbalance_Nm)


@dataclass(frozen=True)
class Process:
    """Blank-holder force levels (N; one level unless a sweep), friction (-), sector weights,
    and which slip the friction works on (``uqdrape.drape.energy.BlankHolder``)."""

    blankholder_force_N: tuple[float, ...]
    friction: float
    sectors: tuple[float, ...] | None
    blankholder_model: str = "slip"


@dataclass(frozen=True)
class Solver:
    """The drape solver's settings: ``mode`` (schema.MODES), ``rings`` n of the
    (2n + 1)^2-node net, the minimiser's tolerance (deg) and iteration cap per step."""

    mode: str
    rings: int
    tolerance_deg: float
    max_iterations: int
    #: largest fraction of a realisation's nodes that may fail to be placed before a run stops
    failure_budget: float = 0.5


@dataclass(frozen=True)
class RandomField:
    """A random fabric field (``name`` in FIELDS) and its correlation model.

    ``params`` is ``{"cv": ...}`` for spacing, ``{"mean_deg": ..., "sd_deg": ...}`` for the
    zero-energy angle, ``{"mean": ..., "sd": ...}`` for the stitch pre-strain (whose map to
    gamma0 comes from ``material``, the fabric's card); ``length_mm`` (along fibre 1,
    fibre 2) is None for iid. ``sd_dof`` (zero angle only; None: the sd is known) makes
    the ensemble hierarchical: each realisation draws its own sd, ``sd_deg`` √(m / χ²_m)
    with m = ``sd_dof``, the sd's uncertainty from a calibration on few points
    (:func:`uqdrape.ensemble.inputs.realization_sd_deg`). ``length_log_sd`` (zero angle,
    correlated; None: the lengths are known) draws each realisation's lengths too,
    ``length_mm`` · exp(s z), s = ``length_log_sd``, one z for both lengths
    (:func:`uqdrape.ensemble.inputs.realization_length_mm`).
    """

    name: str
    params: dict
    correlation: str
    length_mm: tuple[float, float] | None
    kl_retained: float
    material: str | None = None
    sd_dof: float | None = None
    length_log_sd: float | None = None

    def build_input(self, rings: int, spacing_mm: float):
        """The exact-sampling input map (uqdrape.stochastic SpacingInput / ZeroAngleInput /
        PrestrainInput); call ``.kl(self.kl_retained)`` on it for a sample matrix that needs a
        finite variable set."""
        common = dict(correlation=self.correlation, length_mm=self.length_mm, **self.params)
        if self.name == "stitch_prestrain":
            return _stochastic.PrestrainInput(rings, spacing_mm, to_gamma0=prestrain_map(self.material), **common)
        cls = _stochastic.SpacingInput if self.name == "spacing" else _stochastic.ZeroAngleInput
        return cls(rings, spacing_mm, **common)


@functools.lru_cache(maxsize=8)
def prestrain_map(material: str):
    """The stitch pre-strain -> gamma0 table of a material card (built once per process)."""
    from ..material.architecture import material_zero_force_table

    return material_zero_force_table(_material.load_material(material))


@dataclass(frozen=True)
class Uncertainty:
    """Random fields by name (FIELDS) and scalar factors by name (FACTOR_SETTINGS)."""

    fields: dict
    factors: dict

    @property
    def varying(self) -> tuple[str, ...]:
        return tuple(self.fields) + tuple(self.factors)


@dataclass(frozen=True)
class Ply:
    """One ply of a laminate's ply book (``[[ply]]``): its ``name``; ``angle_deg``, its
    fibre-1 angle from the rosette's 0 deg direction (``fabric.orientation_deg``); its card,
    fibre spacing (mm) and seed point ``crossover`` (plan mm, the ply's first contact);
    ``misalignment_sd_deg``, the sd of its own normal misalignment (deg; 0: none); and its
    random fields by name (``RandomField``; a ply without its own takes the study's);
    ``trim``, its edge in plan (nodes outside it are the ply's offcut); ``thickness_mm``,
    what it adds to the stack (mm): the plies above it lie on the tool's offset surface
    (``Study.ply_offset``). Each ply draws its own fields and misalignment."""

    name: str
    angle_deg: float
    material: str
    spacing_mm: float
    crossover: tuple[float, float]
    misalignment_sd_deg: float
    fields: dict
    #: the ply's edge: a plan polyline CSV (x_mm,y_mm); None: the whole net
    trim: str | None = None
    #: the ply's thickness in the stack (mm); 0: the plies above lie where it does
    thickness_mm: float = 0.0


def ply_seed(seed: int, k: int) -> int:
    """The seed ply ``k`` (0-based) of a study seeded ``seed`` draws its fields and its
    misalignment with: a single-ply study with this seed, the ply's fabric and variability
    drapes the ply's realisations bitwise (:meth:`Study.ply_study`)."""
    import numpy as np

    return int(np.random.SeedSequence([seed, k]).generate_state(1, np.uint64)[0] >> np.uint64(1))


@dataclass(frozen=True)
class Sampling:
    """The plan (``uqdrape.stochastic.sampling.STUDY_PLANS``); ``randomizations`` K of an
    rqmc plan (its realisations are K scramblings of one Sobol' net), else None."""

    plan: str
    randomizations: int | None = None


@dataclass(frozen=True)
class Sensitivity:
    method: str
    base_samples: int | None
    qoi: tuple[str, ...]


@dataclass(frozen=True)
class Design:
    """A blank-holder design problem (``uqdrape.design``): forces in N.

    ``variables`` "force": the total force in ``force_bounds_N``; "sectors": the force of
    each of ``sectors`` equal angular sectors (from +x, anticlockwise), each in
    ``force_bounds_N``, their sum at most ``budget_N``. ``friction_bounds`` (optional) adds
    the friction coefficient as a variable. The design minimises ``statistic`` ("upper"
    confidence limit at ``confidence``, or the "estimate") of ``objective`` (a key of
    DESIGN_OBJECTIVES), or with ``target`` its distance from the target value, among the
    designs whose ``q95_max_draw_in`` (same statistic) is at most ``max_draw_in_mm`` and
    whose rare probability ``rare`` (same statistic, :class:`RareLimit`) is at most its
    ``max_probability``. At most
    ``max_evaluations`` designs of the study's realisations each (common random numbers);
    the optimum is re-evaluated on ``validation_realizations`` fresh ones.
    """

    variables: str
    force_bounds_N: tuple[float, float]
    objective: str
    sectors: int | None = None
    friction_bounds: tuple[float, float] | None = None
    budget_N: float | None = None
    statistic: str = "upper"
    target: float | None = None
    confidence: float = 0.95
    max_evaluations: int = 40
    tolerance_N: float = 5.0
    validation_realizations: int | None = None
    max_draw_in_mm: float | None = None
    rare: RareLimit | None = None


@dataclass(frozen=True)
class Target:
    """Run until the ``confidence`` interval of ``statistic`` (TARGET_STATISTICS) of the QoI
    ``qoi`` has a half-width of at most ``half_width`` (the QoI's unit) at every force level."""

    qoi: str
    statistic: str
    half_width: float
    confidence: float = 0.95


@dataclass(frozen=True)
class Rare:
    """P(``qoi`` >= ``threshold``) (the QoI's unit) at every force level, estimated to
    coefficient of variation ``cov`` within ``max_drapes`` drapes a level
    (``uqdrape.workflow.rare``; the budget stops the importance rounds and a second subset
    run, not the first subset run's levels of 500 drapes, about 450 more a decade of P)."""

    qoi: str
    threshold: float
    cov: float = 0.1
    max_drapes: int = 20_000


@dataclass(frozen=True)
class RareLimit:
    """A design's constraint P(``qoi`` >= ``threshold``) <= ``max_probability``, the
    probability estimated per candidate as a [study] :class:`Rare` is (to CoV ``cov``
    within ``max_drapes`` drapes, ``uqdrape.workflow.rare``)."""

    qoi: str
    threshold: float
    max_probability: float
    cov: float = 0.1
    max_drapes: int = 20_000


@dataclass(frozen=True)
class Report:
    """What the report shows. ``fixed_twin`` (a hierarchical study only, else None): the
    run also drapes the study with the drawn sd and lengths removed, the same realisations
    (``uqdrape.workflow.twin``), and the report measures the widening against it."""

    histogram_nodes: tuple[tuple[int, int], ...]
    experimental_csv: Path | None
    fixed_twin: bool | None = None


@dataclass(frozen=True)
class Study:
    """A validated study; ``path`` is the study file, ``output_dir`` relative to the cwd."""

    path: Path
    name: str
    seed: int
    realizations: int
    chunk_size: int
    description: str
    geometry: Geometry
    fabric: Fabric
    process: Process
    solver: Solver
    uncertainty: Uncertainty
    sampling: Sampling
    sensitivity: Sensitivity
    report: Report
    #: a run folder (Path), or an fsspec URL (str) of a zarr store (``uqdrape.ensemble.zarrstore``)
    output_dir: Path | str
    #: the [design] section, None for a study without one
    design: Design | None = None
    #: chunks store floats as float32 with zlib (``uqdrape.conventions.cf_encode``)
    float32: bool = False
    #: [study] target: run in rounds until it is met or ``max_realizations`` are drawn
    target: Target | None = None
    max_realizations: int | None = None
    #: [study] rare: a rare exceedance probability estimated after the run
    rare: Rare | None = None
    #: the ply book of a laminate (``[[ply]]``, in stacking order, the first on the tool);
    #: empty for a single ply
    plies: tuple[Ply, ...] = ()

    @property
    def force_levels(self) -> tuple[float, ...]:
        """Blank-holder force levels (N); length 1 unless the study is a sweep."""
        return self.process.blankholder_force_N

    @property
    def is_sweep(self) -> bool:
        return len(self.force_levels) > 1

    def setting(self, name: str, force: float | None = None) -> float:
        """The fixed value of solver input ``name`` (``uqdrape.schema.SOLVER_INPUTS``); the
        blank-holder force is ``force`` for one level of a sweep, else the only level."""
        if name == "blankholder_force":
            return self.force_levels[0] if force is None else float(force)
        section, key, index = SETTING_KEYS[name]
        value = getattr(getattr(self, section), key)
        return value if index is None else value[index]

    def single_ply(self, what: str) -> None:
        """Raise ValueError naming the study file if it is a laminate: ``what`` drapes one ply."""
        if self.plies:
            raise ValueError(f"{self.path}: {what} drapes one ply; this study is a laminate of {len(self.plies)} "
                             "plies ([[ply]]): remove the ply book, or run it with `uqdrape run`")

    @property
    def shared(self) -> Study:
        """The laminate's process as a study of its own: the factors every ply of a
        realisation shares (blank-holder force, friction, the rosette's angle as
        ``orientation``), drawn from the study's seed; no fields, no plies."""
        return dataclasses.replace(self, uncertainty=Uncertainty({}, self.uncertainty.factors), plies=())

    def ply_offset(self, k: int) -> float:
        """How far (mm) ply ``k`` lies outside the tool: the thickness of the plies below it."""
        return float(sum(p.thickness_mm for p in self.plies[:k]))

    def ply_study(self, k: int) -> Study:
        """Ply ``k`` of a laminate as a single-ply study: the ply's card, spacing and seed
        point, fibre 1 at the rosette's angle + the ply's angle, the ply's fields and
        misalignment (a normal factor on ``orientation``) drawn with ``ply_seed``, and the
        mould offset by ``ply_offset(k)`` where that is not 0 (geometry key ``offset_mm``)."""
        ply = self.plies[k]
        offset = self.ply_offset(k)
        geometry = self.geometry if not offset else Geometry(
            self.geometry.kind, {**self.geometry.params, "offset_mm": self.geometry.params.get("offset_mm", 0.0) + offset})
        fabric = dataclasses.replace(self.fabric, material=ply.material, spacing_mm=ply.spacing_mm,
                                     orientation_deg=self.fabric.orientation_deg + ply.angle_deg,
                                     crossover=ply.crossover)
        factors = {}
        if ply.misalignment_sd_deg > 0:
            factors["orientation"] = _stochastic.make_factor("normal", mean=fabric.orientation_deg,
                                                             sd=ply.misalignment_sd_deg)
        return dataclasses.replace(self, seed=ply_seed(self.seed, k), fabric=fabric, geometry=geometry,
                                   uncertainty=Uncertainty(ply.fields, factors), plies=())

    def to_dict(self) -> dict:
        """The study with defaults filled, in the file's own layout, as plain JSON types
        (``json.dumps`` it for a netCDF attribute or a provenance record)."""
        doc = {"study": {f.name: _plain(getattr(self, f.name)) for f in _HEADER if getattr(self, f.name) is not None}}
        doc["geometry"] = {"kind": self.geometry.kind, **self.geometry.params}
        for section in _PLAIN:
            doc[section] = {f.name: _plain(getattr(getattr(self, section), f.name))
                            for f in dataclasses.fields(getattr(self, section))
                            if getattr(getattr(self, section), f.name) is not None}
        if not self.is_sweep:
            doc["process"]["blankholder_force_N"] = self.force_levels[0]
        doc["uncertainty"] = fields_table(self.uncertainty.fields)
        for name, factor in self.uncertainty.factors.items():
            p = dict(factor.params)
            if "lower" in p:
                p["bounds"] = [p.pop("lower"), p.pop("upper")]
            doc["uncertainty"][name] = {"dist": factor.dist, **p}
        if self.design is not None:
            doc["design"] = {f.name: _plain(getattr(self.design, f.name)) for f in dataclasses.fields(Design)
                             if getattr(self.design, f.name) is not None}
        if self.plies:
            doc["ply"] = [{**{f.name: _plain(getattr(ply, f.name)) for f in dataclasses.fields(Ply) if f.name != "fields"},
                           "uncertainty": fields_table(ply.fields)} for ply in self.plies]
        doc["output"] = {"directory": str(self.output_dir), **({"float32": True} if self.float32 else {})}
        return doc


#: Sections whose dataclass fields are exactly their study-file keys.
_PLAIN = ("fabric", "process", "solver", "sampling", "sensitivity", "report")
#: The [study] header: Study fields between ``path`` and ``geometry``.
_HEADER = tuple(f for f in dataclasses.fields(Study) if f.name in ("name", "seed", "realizations", "chunk_size",
                                                                    "description", "target", "max_realizations",
                                                                    "rare"))


def fields_table(fields: dict) -> dict:
    """Random fields by name in their study-file layout."""
    return {name: _plain({**dataclasses.asdict(f), "name": None, "params": None, "material": None, **f.params})
            for name, f in fields.items()}


def _plain(value):
    """A spec value as JSON types: tuples -> lists, paths -> strings, dataclasses -> dicts,
    None entries dropped."""
    if dataclasses.is_dataclass(value):
        return _plain(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items() if v is not None}
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def identity(doc: dict) -> dict:
    """What must match for stored drapes to be reused (a resumed run's chunks, a design's
    records): the study record ``doc`` (:meth:`Study.to_dict`) without what does not
    change a drape: the chunk size, the number of realisations (realisation r is the same
    in a larger run, so a run extends; ``uqdrape.ensemble.run`` refuses plans where it is
    not), an rqmc plan's number of randomisations (its points per randomisation stay), the
    target that chose the size, the rare probability asked for, the output folder, the
    [design] section (its candidates are keyed by their own settings) and whether a fixed
    twin is draped beside the run (``report.fixed_twin``)."""
    doc = json.loads(json.dumps(doc))
    doc.get("report", {}).pop("fixed_twin", None)
    sampling = doc.get("sampling", {})
    if "randomizations" in sampling:  # rqmc: K randomisations of M points; M is what a drape depends on
        sampling["points"] = doc["study"]["realizations"] // sampling.pop("randomizations")
    for key in ("chunk_size", "realizations", "target", "max_realizations", "rare"):
        doc["study"].pop(key, None)
    for section in ("output", "design"):
        doc.pop(section, None)
    return doc


def from_dict(doc: dict, path) -> Study:
    """The Study that :meth:`Study.to_dict` wrote (e.g. an ensemble's provenance record),
    for the study file ``path``. Not a validator: read study files with ``load_study``."""
    def section(cls, data, **override):
        kwargs = {f.name: data.get(f.name) for f in dataclasses.fields(cls)}
        kwargs.update(override)
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in kwargs.items()})

    process = dict(doc["process"])
    force = process["blankholder_force_N"]
    process["blankholder_force_N"] = list(force) if isinstance(force, list) else [force]
    report = doc["report"]
    def random_fields(entries, material):
        out = {}
        for name, entry in entries.items():
            entry = dict(entry)
            params = {k: entry.pop(k) for k in FIELD_KEYS[name]}
            out[name] = section(RandomField, entry, name=name, params=params,
                                material=material if name == "stitch_prestrain" else None)
        return out

    fields = random_fields({k: v for k, v in doc["uncertainty"].items() if k in FIELDS}, doc["fabric"]["material"])
    factors = {}
    for name, entry in doc["uncertainty"].items():
        if name not in FIELDS:
            entry = dict(entry)
            dist = entry.pop("dist")
            if "bounds" in entry:
                entry["lower"], entry["upper"] = entry.pop("bounds")
            factors[name] = _stochastic.make_factor(dist, **entry)
    geometry = dict(doc["geometry"])
    head = dict(doc["study"])
    if "target" in head:
        head["target"] = Target(**head["target"])
    if "rare" in head:
        head["rare"] = Rare(**head["rare"])
    return Study(
        path=Path(path), **head,
        geometry=Geometry(geometry.pop("kind"), geometry),
        fabric=section(Fabric, doc["fabric"]),
        process=section(Process, process),
        solver=section(Solver, doc["solver"]),
        uncertainty=Uncertainty(fields, factors),
        sampling=section(Sampling, doc["sampling"]),
        sensitivity=section(Sensitivity, doc["sensitivity"]),
        report=section(Report, report, histogram_nodes=tuple(tuple(n) for n in report["histogram_nodes"]),
                       experimental_csv=Path(report["experimental_csv"]) if report.get("experimental_csv") else None),
        output_dir=location(doc["output"]["directory"]),
        design=section(Design, doc["design"], rare=RareLimit(**doc["design"]["rare"]) if "rare" in doc["design"]
                       else None) if "design" in doc else None,
        float32=doc["output"].get("float32", False),
        plies=tuple(section(Ply, p, fields=random_fields(p["uncertainty"], p["material"])) for p in doc.get("ply", ())),
    )
