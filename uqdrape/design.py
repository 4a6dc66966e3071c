"""Blank-holder design under uncertainty: the force (total, or per sector) that keeps a
part inside its limits while the fabric and the process scatter.

A study's ``[design]`` section (``uqdrape.study.spec.Design``) names the decision
variables -- the total blank-holder force, or the forces of N equal angular sectors
(from +x, anticlockwise; the solver's ``sectors`` weights are the forces over their
sum), optionally the friction coefficient -- each with bounds, a total-force budget, and
an objective from :data:`~uqdrape.study.spec.DESIGN_OBJECTIVES`. The uncertain inputs
are the study's fields and factors. Plain-function flow::

    problem(study) -> optimise (evaluate batches of designs) -> validate -> write_design

Estimators (sample-average approximation with common random numbers). Every candidate
design drapes the same realisations 0..R-1 of the study (``sampled_inputs``: the same
seeds, fields and factors); only force, sectors and friction differ, so the objective is
a deterministic function of the design and two candidates differ by their effect, not
by sampling noise. A design's statistics, with ``confidence`` limits:

- ``p_locked``: P(any node of the net locked), Wilson score interval;
- ``q95_max_abs_shear``: the 95 % quantile of the largest |node shear| (deg),
  distribution-free order-statistic interval;
- ``abs_mean_asymmetry``: |mean asymmetry| (deg) of ``uqdrape.stats.line_means`` over
  line nodes 1..k_max, k_max fixed by the baseline design's realisations; Student-t
  interval of the mean, folded at 0;
- ``q95_max_draw_in``: the 95 % quantile of the largest :func:`draw_in` of the held edge
  (mm), order-statistic interval.

The design minimises the statistic's upper limit (``statistic = "upper"``, the default)
or its estimate, or with ``target`` the distance |value - target| (e.g. the force where
the upper limit of |mean asymmetry| falls to 1 deg).

Draw-in limit. With ``max_draw_in_mm`` a design is feasible when the same statistic
(upper limit or estimate) of ``q95_max_draw_in`` is at most the limit. Both optimisers
see an infeasible design's value as ``INFEASIBLE`` + its excess (mm), above every
feasible value, so they rank it after every feasible design and, among infeasible
ones, by how far they miss; the optimum is the best feasible design evaluated (the
least infeasible if none is). More force holds the edge, so the limit is a floor on the
force where the held edge would otherwise be pulled in too far.

Optimisers (deterministic: scipy, fixed seed, a deterministic objective):

- one variable (the total force): a grid of ``GRID`` forces over the bounds (one
  parallel batch), then ``scipy.optimize.minimize_scalar(method="bounded")`` between the
  grid neighbours of the best grid force, ``xatol = tolerance_N``;
- several (sector forces, or force and friction): ``scipy.optimize.differential_evolution``
  (population ``DE_POPSIZE`` x variables, latin hypercube start holding the equal split of
  the budget, no polishing, seed = study seed, a whole generation draped as one batch)
  with the budget as a linear constraint on the sum of the sector forces (candidates
  over budget are not draped); generations until ``max_evaluations`` designs have been
  draped. Its tolerance is that of a few generations: the optimum is the best design
  evaluated, not a converged point (the synthetic test finds a 200 N optimum of four
  sectors to 40 N in 60 designs).

Validation. The optimum and the baseline (the study's own force) are re-draped on an
independent sample: ``validation_realizations`` realisations of the study with seed
``validation_seed(study)`` (``numpy.random.SeedSequence([seed, VALIDATION_STREAM])``), so
the reported risk is not optimistically biased by the selection. A sector design also
drapes the uniform force at the optimum's total on both samples; the margin uniform -
sector has a paired bootstrap interval (the same realisations under both designs).

Force interval. The interval of the optimum force(s) is the 2.5-97.5 % range of the best
evaluated design (by the same objective) when the realisations are resampled
(``BOOTSTRAP`` resamples): how much the choice among the evaluated designs depends on
the sample. It cannot be wider than the designs evaluated around the optimum.

Files (in the output folder): ``evaluations/<key>.nc``, one per draped design and sample
(per-realisation quantities and node lock counts), written whole then renamed and keyed
by the study, the sample and the design vector, so a killed run replays the optimiser
from them and drapes only what is missing; ``design.nc``, every evaluated design with
its statistics, the history and the result.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import dask
import numpy as np
import xarray as xr
from scipy import optimize

from .drape import max_shear_lines
from .ensemble import Progress, compute_tasks, drape_inputs, local_pool, run_lock, sampled_inputs, write_atomic
from .export import flat_positions
from .stats import line_means, mean_statistics, wilson_interval
from .stats.summary import quantile_statistics
from .study.spec import DESIGN_OBJECTIVES

#: Output files and folder of a design run.
DESIGN_FILE = "design.nc"
EVALUATIONS = "evaluations"
#: Forces of the first batch of a one-variable design, evenly over the bounds.
GRID = 5
#: Differential evolution population per variable.
DE_POPSIZE = 3
#: Realisation resamples of the force interval and of the margin's interval.
BOOTSTRAP = 400
#: The validation sample's seed is SeedSequence([study seed, VALIDATION_STREAM]).
VALIDATION_STREAM = 13
#: Statistic of the draw-in limit, and the value of a design that breaks it before its
#: excess (mm) is added: above every feasible objective (probabilities, degrees, mm).
DRAW_IN = "q95_max_draw_in"
INFEASIBLE = 1.0e6
#: Version of the records in evaluations/, part of their key: a record of another
#: version (other per-drape quantities) is draped again, not read.
RECORD_VERSION = 2
STATISTICS = tuple(DESIGN_OBJECTIVES)


def validation_seed(study) -> int:
    """The seed of the independent validation sample of a design study."""
    return int(np.random.SeedSequence([study.seed, VALIDATION_STREAM]).generate_state(1)[0])


@dataclass(frozen=True)
class Problem:
    """A design problem: the study, its variable names and bounds, and the two samples."""

    study: object
    names: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    baseline: tuple[float, ...]
    validation: object

    @property
    def spec(self):
        return self.study.design

    @property
    def n_forces(self) -> int:
        return self.spec.sectors or 1

    def settings(self, x) -> tuple[float, tuple[float, ...] | None, float]:
        """(total force N, sector weights or None, friction) of design vector ``x``."""
        forces = np.asarray(x[: self.n_forces], dtype=float)
        friction = float(x[self.n_forces]) if len(x) > self.n_forces else self.study.process.friction
        total = float(forces.sum())
        if self.spec.sectors is None:
            return total, self.study.process.sectors, friction
        weights = tuple(forces / total) if total > 0 else None
        return total, weights, friction

    def uniform(self, total: float, x) -> np.ndarray:
        """The design with ``total`` spread evenly (sectors), friction as in ``x``."""
        forces = np.full(self.n_forces, total / self.n_forces)
        return np.concatenate([forces, np.asarray(x[self.n_forces:], dtype=float)])


def problem(study) -> Problem:
    """The design problem of a study with a [design] section."""
    spec = study.design
    if spec is None:
        raise ValueError(f"study {study.name!r} ({study.path}) has no [design] section")
    lo, hi = spec.force_bounds_N
    n = spec.sectors or 1
    if spec.budget_N is not None and n == 1:
        hi = min(hi, spec.budget_N)
    names = ("force",) if n == 1 else tuple(f"sector_{k}" for k in range(n))
    bounds = [(lo, hi)] * n
    f0, weights = study.force_levels[0], study.process.sectors
    if n > 1 and weights is not None and len(weights) == n:  # the study's own sectors
        baseline = list(f0 * np.asarray(weights) / np.sum(weights))
    else:
        baseline = [f0 / n] * n
    if spec.friction_bounds is not None:
        names += ("friction",)
        bounds.append(spec.friction_bounds)
        baseline.append(study.process.friction)
    n_val = spec.validation_realizations or study.realizations
    validation = dataclasses.replace(study, seed=validation_seed(study), realizations=n_val)
    return Problem(study, names, tuple(bounds), tuple(baseline), validation)


# ----------------------------------------------------------------------------- draping


def draw_in(ds: xr.Dataset) -> xr.DataArray:
    """Radial draw-in (mm) of the nodes of the net's outermost ring, the edge the
    blank-holder holds (NaN elsewhere): the plan distance of a node from the crossover in
    the realisation's flat blank (``uqdrape.export.flat_positions``) minus that on the
    mould, how far the fabric's edge is pulled in towards the first contact point."""
    n = int(ds.attrs["rings"])
    flat = flat_positions(ds)
    cx, cy = ds["crossover_x"], ds["crossover_y"]
    inwards = (np.hypot(ds["x"].copy(data=flat[..., 0]) - cx, ds["y"].copy(data=flat[..., 1]) - cy)
               - np.hypot(ds["x"] - cx, ds["y"] - cy))
    edge = (abs(ds["i"]) == n) | (abs(ds["j"]) == n)
    return inwards.where(edge).assign_attrs(units="mm", long_name="radial draw-in of the held edge")


def drape_design(study, realizations, force: float, sectors, friction: float) -> xr.Dataset:
    """Dask task: drape ``realizations`` of ``study`` under one design (total force N,
    sector weights, friction) and keep what the statistics need: per realisation
    ``any_locked``, ``max_abs_shear`` (deg), ``max_draw_in`` (mm), the max-shear-line
    shear (deg), and per node the lock count, the valid count and the summed plan
    position (mm)."""
    variant = dataclasses.replace(study, process=dataclasses.replace(
        study.process, blankholder_force_N=(float(force),), sectors=sectors, friction=float(friction)))
    r = np.asarray(realizations)
    ds = drape_inputs(variant, r, sampled_inputs(variant, r))
    locked = ds["locked"] > 0
    valid = ds["shear"].notnull()
    return xr.Dataset({
        "any_locked": locked.any(["i", "j"]).astype(float),
        "max_abs_shear": abs(ds["shear"]).max(["i", "j"]),
        "max_draw_in": draw_in(ds).max(["i", "j"]),
        "line_shear": max_shear_lines(ds)["shear"],
        "node_locked": locked.sum("realization"),
        "node_valid": valid.sum("realization"),
        "node_x": ds["x"].where(valid).sum("realization"),
        "node_y": ds["y"].where(valid).sum("realization"),
    }).drop_vars([c for c in ("i", "j") if c in ds.coords]).load()


def _merge(parts: list) -> xr.Dataset:
    """One design's record from its chunks: realisations concatenated, node sums summed."""
    per = [p[["any_locked", "max_abs_shear", "max_draw_in", "line_shear"]] for p in parts]
    nodes = sum(p[["node_locked", "node_valid", "node_x", "node_y"]] for p in parts)
    return xr.merge([xr.concat(per, "realization"), nodes])


class Evaluator:
    """Drapes batches of designs on the design or the validation sample, each design once:
    records are cached in ``folder`` (None: in memory only) under a key of the study, the
    sample and the design vector. ``drape`` is the task that drapes one chunk
    (:func:`drape_design`; a test passes a synthetic one through the same pipeline)."""

    def __init__(self, prob: Problem, folder=None, *, scheduler=None, workers=None, progress=True,
                 drape=drape_design, pool=None):
        self.prob, self.scheduler, self.workers, self.progress = prob, scheduler, workers, progress
        self.pool = pool
        self.folder = None if folder is None else Path(folder) / EVALUATIONS
        self.drape = drape
        self.records: dict[str, xr.Dataset] = {}
        self.order: list[tuple[str, str, tuple[float, ...]]] = []  # (sample, key, x) as first asked for
        identity = prob.study.to_dict()
        for section in ("design", "output"):
            identity.pop(section, None)
        identity["study"].pop("chunk_size", None)
        self.identity = json.dumps(identity, sort_keys=True)
        self.drapes = 0
        self.k_max = None  # line nodes of the asymmetry, set from the baseline design
        self.cache: dict[str, tuple[dict, dict]] = {}

    def statistics(self, X, sample: str = "design") -> list[dict]:
        """:func:`statistics` of the designs (rows of X), each computed once."""
        out = []
        for x, record in zip(X, self(X, sample)):
            key = self.key(sample, x)
            if key not in self.cache:
                values = per_realization(record, self.k_max)
                self.cache[key] = (values, statistics(values, self.prob.spec.confidence))
            out.append(self.cache[key][1])
        return out

    def values(self, X, sample: str = "design") -> np.ndarray:
        """Per-drape quantities (design, statistic name -> (R,)) of the designs, cached."""
        self.statistics(X, sample)
        return [self.cache[self.key(sample, x)][0] for x in X]

    def key(self, sample: str, x) -> str:
        study = self.prob.study if sample == "design" else self.prob.validation
        text = (f"{RECORD_VERSION}|{self.identity}|{sample}|{study.seed}|{study.realizations}|"
                f"{np.asarray(x, float).tobytes().hex()}")
        return hashlib.sha1(text.encode()).hexdigest()[:16]

    def __call__(self, X, sample: str = "design") -> list[xr.Dataset]:
        """Records of the designs (rows of X), draping those not yet evaluated as one batch."""
        X = [tuple(float(v) for v in np.atleast_1d(x)) for x in X]
        study = self.prob.study if sample == "design" else self.prob.validation
        keys = [self.key(sample, x) for x in X]
        todo = {}
        for key, x in zip(keys, X):
            if all(key != k for _, k, _ in self.order):
                self.order.append((sample, key, x))
            if key in self.records or key in todo:
                continue
            path = None if self.folder is None else self.folder / f"{key}.nc"
            if path is not None and path.is_file():
                self.records[key] = xr.load_dataset(path)
            else:
                todo[key] = x
        if todo:
            self._drape(study, sample, todo)
        return [self.records[k] for k in keys]

    def _drape(self, study, sample: str, todo: dict) -> None:
        size = study.chunk_size
        ranges = [(a, min(a + size, study.realizations)) for a in range(0, study.realizations, size)]
        task = dask.delayed(self.drape, pure=False)
        tasks, owners = [], []
        for key, x in todo.items():
            force, sectors, friction = self.prob.settings(x)
            for a, b in ranges:
                tasks.append(task(study, np.arange(a, b), force, sectors, friction))
                owners.append(key)
        n = len(todo) * study.realizations
        bar = Progress(n, enabled=self.progress, desc=f"{study.name}: {len(todo)} designs ({sample})")
        try:
            parts = compute_tasks(tasks, [b - a for a, b in ranges] * len(todo), self.scheduler, self.workers, bar,
                                  self.pool)
        finally:
            bar.close()
        self.drapes += n
        for key, x in todo.items():
            record = _merge([p for p, owner in zip(parts, owners) if owner == key])
            record.attrs.update(sample=sample, seed=study.seed, x=list(x), names=list(self.prob.names))
            if self.folder is not None:
                self.folder.mkdir(parents=True, exist_ok=True)
                write_atomic(record, self.folder / f"{key}.nc")
            self.records[key] = record


# ----------------------------------------------------------------------------- statistics


def per_realization(record: xr.Dataset, k_max: int) -> dict[str, np.ndarray]:
    """The per-drape quantity of each statistic (name -> (R,) array)."""
    asym = line_means(record["line_shear"], k_max)["asymmetry"]
    return {"p_locked": record["any_locked"].values, "q95_max_abs_shear": record["max_abs_shear"].values,
            "abs_mean_asymmetry": asym.values, DRAW_IN: record["max_draw_in"].values}


def statistics(values: dict, confidence: float) -> dict[str, tuple]:
    """(estimate, lower, upper) of every statistic of per-drape quantities ``values``
    (name -> array (..., R)): floats for one design, arrays (...) for a stack of them
    (e.g. bootstrap resamples)."""
    out = {}
    for name, v in values.items():
        v = np.asarray(v, dtype=float)
        kind = DESIGN_OBJECTIVES[name][1]
        drapes = xr.DataArray(v).rename({f"dim_{v.ndim - 1}": "realization"})
        if kind == "probability":
            n = np.count_nonzero(~np.isnan(v), axis=-1)
            k = np.nansum(v, axis=-1)
            lo, hi = wilson_interval(k, n, confidence)
            triple = (k / n, lo, hi)
        elif kind == "quantile95":
            q = quantile_statistics(drapes, [0.95], confidence).isel(quantile=0)
            triple = tuple(q[f"quantile_{s}"].values for s in ("value", "lower", "upper"))
        else:
            m = mean_statistics(drapes, confidence)
            mean, lo, hi = (m[s].values for s in ("mean", "mean_lower", "mean_upper"))
            straddles = (lo <= 0) & (hi >= 0)  # |mean| folded at 0
            triple = (np.abs(mean), np.where(straddles, 0.0, np.minimum(np.abs(lo), np.abs(hi))),
                      np.maximum(np.abs(lo), np.abs(hi)))
        out[name] = tuple(float(t) if np.ndim(t) == 0 else np.asarray(t, dtype=float) for t in triple)
    return out


def _statistic(stats: dict, name: str, spec):
    """The spec's statistic (upper limit or estimate) of statistic ``name``."""
    estimate, _, upper = stats[name]
    value = upper if spec.statistic == "upper" else estimate
    if not np.all(np.isfinite(value)):
        raise ValueError(f"the {spec.statistic} of {name} is undefined (no valid realisation, or too few "
                         "for its confidence limit)")
    return value


def excess(stats: dict, spec):
    """How far (mm) a design breaks the draw-in limit, 0 if it keeps it or there is none."""
    if spec.max_draw_in_mm is None:
        return np.zeros(np.shape(stats[DRAW_IN][0]))
    return np.maximum(_statistic(stats, DRAW_IN, spec) - spec.max_draw_in_mm, 0.0)


def objective_value(stats: dict, spec):
    """What the design minimises of its statistics (a float, or an array for a stack)."""
    value = _statistic(stats, spec.objective, spec)
    return np.abs(value - spec.target) if spec.target is not None else value


def penalised(stats: dict, spec):
    """The objective, or ``INFEASIBLE`` + the excess (mm) of a design over the draw-in limit."""
    over = excess(stats, spec)
    return np.where(over > 0, INFEASIBLE + over, objective_value(stats, spec))


# ----------------------------------------------------------------------------- optimise


@dataclass
class Result:
    """A finished design: the optimum and the designs draped on the validation sample
    (the history is the evaluator's ``order``)."""

    prob: Problem
    k_max: int
    optimum: tuple
    message: str
    validation: dict  # role -> x, draped on the validation sample


def optimise(prob: Problem, evaluate: Evaluator) -> Result:
    """Run the optimiser of ``prob`` (see the module notes); deterministic for a given
    study, so a rerun over the cached records replays it exactly."""
    spec, study = prob.spec, prob.study
    # the asymmetry averages line nodes 1..k_max, those valid in every realisation of the baseline design
    k_max = evaluate.k_max = int(line_means(evaluate([prob.baseline])[0]["line_shear"]).attrs["k_max"])

    def values(X):
        # to 12 significant digits: numpy's sums can differ in the last bit with the memory
        # alignment of an array (a record just draped, or read back from its file), and the
        # optimiser's next design must not, or a resumed run would leave the cached path
        return np.array([float(f"{penalised(s, spec):.12g}") for s in evaluate.statistics(X)])

    if len(prob.names) == 1:
        lo, hi = prob.bounds[0]
        grid = np.linspace(lo, hi, GRID)
        f = values(grid[:, None])
        b = int(np.argmin(f))
        left, right = grid[max(b - 1, 0)], grid[min(b + 1, GRID - 1)]
        left_over = spec.max_evaluations - GRID - 1
        res = optimize.minimize_scalar(lambda F: values([[F]])[0], bounds=(left, right), method="bounded",
                                       options={"xatol": spec.tolerance_N, "maxiter": max(left_over, 1)})
        message = f"grid of {GRID} forces, then bounded Brent on [{left:.1f}, {right:.1f}] N: {res.message}"
    else:
        n = prob.n_forces
        constraints = ()
        if spec.budget_N is not None and n > 1:
            a = np.zeros((1, len(prob.names)))
            a[0, :n] = 1.0
            constraints = (optimize.LinearConstraint(a, -np.inf, spec.budget_N),)
        population = DE_POPSIZE * len(prob.names)
        total = min(spec.budget_N or np.inf, n * prob.bounds[0][1])
        x0 = prob.uniform(total, prob.baseline)

        def spent(intermediate_result):  # infeasible candidates are never draped: count the designs that were
            return sum(sample == "design" for sample, _, _ in evaluate.order) >= spec.max_evaluations

        res = optimize.differential_evolution(
            lambda X: values(np.asarray(X).T), prob.bounds, constraints=constraints, seed=study.seed,
            popsize=DE_POPSIZE, maxiter=spec.max_evaluations, init="latinhypercube", polish=False,
            vectorized=True, updating="deferred", x0=x0, tol=0.0, callback=spent)
        message = f"differential evolution, population {population}, {res.nit} generations: {res.message}"
    history = [x for sample, _, x in evaluate.order if sample == "design"]
    f = values(history)
    optimum = history[int(np.argmin(f))]
    roles = {"baseline": prob.baseline, "optimum": optimum}
    if prob.n_forces > 1:
        roles["uniform"] = tuple(prob.uniform(sum(optimum[: prob.n_forces]), optimum))
        evaluate([roles["uniform"]])
    evaluate(list(roles.values()), "validation")
    return Result(prob, k_max, tuple(optimum), message, roles)


# ----------------------------------------------------------------------------- results


def _resampled(values: list, n: int, seed: int) -> dict:
    """Per-drape quantities of designs (a list of per-design dicts, the same realisations)
    under ``n`` common realisation resamples: name -> (n, design, R)."""
    R = len(next(iter(values[0].values())))
    idx = np.random.default_rng(seed).integers(0, R, size=(n, 1, R))
    return {name: np.stack([v[name] for v in values])[np.arange(len(values))[None, :, None], idx]
            for name in values[0]}


def result_dataset(result: Result, evaluate: Evaluator) -> xr.Dataset:
    """Every evaluated design with its statistics, and the result, as one Dataset."""
    prob, spec = result.prob, result.prob.spec
    confidence = spec.confidence
    rows = list(evaluate.order)
    stats = [evaluate.statistics([x], s)[0] for s, _, x in rows]
    X = np.array([x for _, _, x in rows])
    settings = [prob.settings(x) for x in X]
    data = {
        "x": (("evaluation", "variable"), X, {"long_name": "design vector (N; friction -)"}),
        "total_force": ("evaluation", [s[0] for s in settings], {"units": "N", "long_name": "total blank-holder force"}),
        "friction": ("evaluation", [s[2] for s in settings], {"units": "1", "long_name": "blank-holder friction"}),
        "sample": ("evaluation", [s for s, _, _ in rows], {"long_name": "design (common random numbers) or validation"}),
        "key": ("evaluation", [k for _, k, _ in rows], {"long_name": f"record in {EVALUATIONS}/"}),
        "objective": ("evaluation", [objective_value(s, spec) for s in stats],
                      {"long_name": f"objective: {spec.statistic} of {spec.objective}"
                                    + (f", distance from {spec.target:g}" if spec.target is not None else "")}),
        "feasible": ("evaluation", [int(excess(s, spec) == 0) for s in stats],
                     {"units": "1", "long_name": "keeps the draw-in limit (1) or not (0)"}),
    }
    units_of = {"p_locked": "1", DRAW_IN: "mm"}
    for name in STATISTICS:
        units = units_of.get(name, "degree")
        for i, part in enumerate(("", "_lower", "_upper")):
            data[name + part] = ("evaluation", [s[name][i] for s in stats],
                                 {"units": units, "long_name": f"{name}{part or ' estimate'} ({confidence:.0%})"})
    ds = xr.Dataset(data, coords={"variable": list(prob.names)})
    val = {role: evaluate([x], "validation")[0] for role, x in result.validation.items()}
    for role in val:
        rec = val[role]
        nv = rec["node_valid"].where(rec["node_valid"] > 0)
        ds[f"{role}_node_p_locked"] = (rec["node_locked"] / nv).assign_attrs(
            units="1", long_name=f"P(node locked), {role} design, validation sample")
        ds[f"{role}_node_x"] = (rec["node_x"] / nv).assign_attrs(units="mm")
        ds[f"{role}_node_y"] = (rec["node_y"] / nv).assign_attrs(units="mm")
    design_X = np.array([x for s, _, x in rows if s == "design"])
    resampled = _resampled(evaluate.values(design_X), BOOTSTRAP, prob.study.seed)
    boot = penalised(statistics({k: resampled[k] for k in {spec.objective, DRAW_IN}}, confidence), spec)
    best = design_X[np.argmin(boot, axis=1)]
    opt_stats = evaluate.statistics([result.optimum])[0][spec.objective]
    val_stats = {role: evaluate.statistics([x], "validation")[0] for role, x in result.validation.items()}
    inside = opt_stats[1] <= val_stats["optimum"][spec.objective][0] <= opt_stats[2]
    ds.attrs.update(
        study_name=prob.study.name, objective=spec.objective, statistic=spec.statistic,
        target=spec.target if spec.target is not None else "none", confidence=confidence,
        max_draw_in_mm=spec.max_draw_in_mm or "none",
        variables=list(prob.names), bounds=json.dumps(prob.bounds), budget_N=spec.budget_N or "none",
        k_max=result.k_max, optimiser=result.message, design_seed=prob.study.seed,
        design_realizations=prob.study.realizations, validation_seed=prob.validation.seed,
        validation_realizations=prob.validation.realizations, drapes_this_run=int(evaluate.drapes),
        drapes_total=int(sum(prob.study.realizations if s == "design" else prob.validation.realizations
                             for s, _, _ in rows)),
        optimum=list(result.optimum), optimum_lower=list(np.quantile(best, 0.025, axis=0)),
        optimum_upper=list(np.quantile(best, 0.975, axis=0)), optimum_interval=(
            f"2.5-97.5 % of the best evaluated design over {BOOTSTRAP} realisation resamples"),
        optimum_estimate=list(opt_stats), baseline=list(prob.baseline),
        validation=json.dumps({role: {"x": list(x), "estimate": list(val_stats[role][spec.objective]),
                                      "draw_in": list(val_stats[role][DRAW_IN])}
                               for role, x in result.validation.items()}),
        validated=int(inside), study_json=json.dumps(prob.study.to_dict()),
    )
    if "uniform" in result.validation:
        ds.attrs["margin"] = json.dumps(_margin(result, evaluate))
    ds.attrs["summary"] = summary_text(ds)
    return ds


def _margin(result: Result, evaluate: Evaluator) -> dict:
    """Uniform minus sector objective estimate at equal total, on both samples, with a
    paired bootstrap interval (the same realisations under both designs)."""
    spec = result.prob.spec
    out = {}
    for sample in ("design", "validation"):
        values = evaluate.values([result.validation["uniform"], result.optimum], sample)
        resampled = _resampled(values, BOOTSTRAP, result.prob.study.seed + 1)
        boot = statistics({spec.objective: resampled[spec.objective]}, spec.confidence)[spec.objective][0]
        d = boot[:, 0] - boot[:, 1]
        est = [statistics(v, spec.confidence)[spec.objective][0] for v in values]
        c = spec.confidence
        out[sample] = [float(est[0] - est[1]), float(np.quantile(d, (1 - c) / 2)), float(np.quantile(d, (1 + c) / 2))]
    return out


def summary_text(ds: xr.Dataset) -> str:
    """The result in plain words, e.g. "F = 290 N [260, 330]: p_locked 0.02 [0.01, 0.04] vs 0.31 at 126 N"."""
    names = list(ds.attrs["variables"])
    opt, lo, hi = (np.atleast_1d(ds.attrs[k]) for k in ("optimum", "optimum_lower", "optimum_upper"))
    val = json.loads(ds.attrs["validation"])
    name = ds.attrs["objective"]
    fmt = "{:.3g}"

    def stat(e):
        return f"{fmt.format(e[0])} [{fmt.format(e[1])}, {fmt.format(e[2])}]"

    design = ", ".join(f"{'F' if n == 'force' else n} = {o:.0f}{'' if n == 'friction' else ' N'} [{a:.0f}, {b:.0f}]"
                       if n != "friction" else f"friction {o:.3f} [{a:.3f}, {b:.3f}]"
                       for n, o, a, b in zip(names, opt, lo, hi))
    base = val["baseline"]
    n_forces = sum(n != "friction" for n in names)
    base_total = sum(base["x"][:n_forces])
    text = (f"{design}: {name} {stat(val['optimum']['estimate'])} vs {stat(base['estimate'])} at the baseline "
            f"{base_total:.0f} N (validation sample, {ds.attrs['validation_realizations']} drapes, "
            f"{ds.attrs['confidence']:.0%} limits). ")
    opt_est = ds.attrs["optimum_estimate"]
    if np.all(np.isfinite(opt_est)):
        text += (f"The validation estimate {'lies within' if ds.attrs['validated'] else 'lies OUTSIDE'} the "
                 f"optimisation estimate's limits {stat(opt_est)}.")
    else:
        text += (f"The optimisation estimate {stat(opt_est)} has no limits at {ds.attrs['design_realizations']} "
                 "drapes to check the validation estimate against.")
    if "margin" in ds.attrs:
        m = json.loads(ds.attrs["margin"])["validation"]
        beats = m[1] > 0
        text += (f" Uniform minus sector {name} at the same total {sum(opt[:n_forces]):.0f} N: {stat(m)}: the sector "
                 f"design {'beats' if beats else 'does NOT beat'} the uniform force by more than its limits.")
    limit = ds.attrs["max_draw_in_mm"]
    if limit != "none":
        d = val["optimum"]["draw_in"]
        kept = (d[2] if ds.attrs["statistic"] == "upper" else d[0]) <= limit
        none_kept = not ds["feasible"].values[ds["sample"].values == "design"].any()
        text += (f" Draw-in at the optimum (95 % quantile of the largest, mm): {stat(d)}, limit {limit:g} mm on its "
                 f"{ds.attrs['statistic']}: {'kept' if kept else 'BROKEN'} on the validation sample"
                 + ("; no evaluated design keeps it." if none_kept else "."))
    return text


def run_design(study, *, output_dir=None, scheduler=None, workers=None, progress=True, drape=drape_design) -> Path:
    """Run the design of a study with a [design] section; write ``design.nc`` into the
    output folder (default the study's) and return the folder. Resumes from the records
    of an earlier run of the same study."""
    start = time.perf_counter()
    prob = problem(study)
    out = Path(study.output_dir if output_dir is None else output_dir)
    out.mkdir(parents=True, exist_ok=True)
    local = scheduler in (None, "processes")
    # one pool for the whole run: a design is many small batches, and starting worker
    # processes for each would cost more than draping it; one run at a time in the folder
    with run_lock(out), local_pool(workers) if local else contextlib.nullcontext() as pool:
        evaluate = Evaluator(prob, out, scheduler=scheduler, workers=workers, progress=progress, drape=drape,
                             pool=pool)
        result = optimise(prob, evaluate)
        ds = result_dataset(result, evaluate)
        # this run's own time: a resumed run replays earlier designs from their records
        ds.attrs["wall_time_s"] = round(time.perf_counter() - start, 1)
        write_atomic(ds, out / DESIGN_FILE)
    if progress:
        print(f"{study.name}: {ds.attrs['summary']}", file=sys.stderr)
    return out
