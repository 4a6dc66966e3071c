"""Drape candidate designs: batches of designs on the design or the validation sample,
each design's realisations as chunks on the ensemble engine's schedulers
(``uqdrape.ensemble.compute_tasks``), each design's record kept in ``evaluations/`` so
a killed run replays the optimiser from them and drapes only what is missing."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys

import dask
import numpy as np
import xarray as xr

from ..drape import max_shear_lines
from ..ensemble import Progress, at, compute_tasks, drape_inputs, sampled_inputs
from ..schema import REALIZATION
from ..stats import realization_qois
from ..study import identity
from .estimators import RARE, per_realization, rare_statistic, statistics
from .problem import Problem

#: Folder of the per-design records in a design run's output folder.
EVALUATIONS = "evaluations"
#: Version of the records in evaluations/, part of their key: a record of another
#: version (other per-drape quantities) is draped again, not read.
RECORD_VERSION = 2
#: The per-drape quantities of interest a record keeps (``uqdrape.stats.qoi``).
RECORD_QOIS = ("any_locked", "max_abs_shear", "max_draw_in")


def variant(study, force: float, sectors, friction: float):
    """``study`` under one design: total force (N), sector weights, friction."""
    return dataclasses.replace(study, process=dataclasses.replace(
        study.process, blankholder_force_N=(float(force),), sectors=sectors, friction=float(friction)))


def drape_design(study, realizations, force: float, sectors, friction: float) -> xr.Dataset:
    """Dask task: drape ``realizations`` of ``study`` under one design (total force N,
    sector weights, friction) and keep what the statistics need: per realisation
    ``any_locked``, ``max_abs_shear`` (deg), ``max_draw_in`` (mm), the max-shear-line
    shear (deg), and per node the lock count, the valid count and the summed plan
    position (mm)."""
    variant_study = variant(study, force, sectors, friction)
    r = np.asarray(realizations)
    ds = drape_inputs(variant_study, r, sampled_inputs(variant_study, r))
    locked = ds["locked"] > 0
    valid = ds["shear"].notnull()
    return xr.Dataset({
        **realization_qois(ds, RECORD_QOIS).drop_attrs().data_vars,
        "line_shear": max_shear_lines(ds)["shear"],
        "node_locked": locked.sum(REALIZATION),
        "node_valid": valid.sum(REALIZATION),
        "node_x": ds["x"].where(valid).sum(REALIZATION),
        "node_y": ds["y"].where(valid).sum(REALIZATION),
    }).drop_vars([c for c in ("i", "j") if c in ds.coords]).load()


def _merge(parts: list) -> xr.Dataset:
    """One design's record from its chunks: realisations concatenated, node sums summed."""
    per = [p[[*RECORD_QOIS, "line_shear"]] for p in parts]
    nodes = sum(p[["node_locked", "node_valid", "node_x", "node_y"]] for p in parts)
    return xr.merge([xr.concat(per, REALIZATION), nodes])


class Evaluator:
    """Drapes batches of designs on the design or the validation sample, each design once:
    records are cached in ``folder`` (None: in memory only) under a key of the study, the
    sample and the design vector, in the run folder or store URL ``folder``'s
    ``evaluations/`` (``uqdrape.ensemble.at``). ``drape`` is the task that drapes one chunk
    (:func:`drape_design`; a test passes a synthetic one through the same pipeline). With a
    ``[design] rare`` constraint, ``rare`` estimates it for one design (its :func:`variant` of
    the sample's study -> {probability, cov, drapes, method, ...}:
    ``uqdrape.workflow.rare.design_rare``), kept in the design's record as ``rare_*`` attributes."""

    def __init__(self, prob: Problem, folder=None, *, scheduler=None, workers=None, progress=True,
                 drape=drape_design, pool=None, rare=None):
        self.prob, self.scheduler, self.workers, self.progress = prob, scheduler, workers, progress
        self.pool = pool
        self.folder = None if folder is None else at(folder)
        self.drape = drape
        if prob.spec.rare is not None and rare is None:
            raise ValueError("a [design] rare constraint needs its estimator (rare=)")
        self.rare = rare if prob.spec.rare is not None else None
        self.records: dict[str, xr.Dataset] = {}
        self.order: list[tuple[str, str, tuple[float, ...]]] = []  # (sample, key, x) as first asked for
        self.identity = json.dumps(identity(prob.study.to_dict()), sort_keys=True)
        self.drapes = 0
        self.kept = self.draped = 0  # designs read back from an earlier run's records / draped here
        self.k_max = None  # line nodes of the asymmetry, set from the baseline design
        self.cache: dict[str, tuple[dict, dict]] = {}

    def statistics(self, X, sample: str = "design") -> list[dict]:
        """:func:`statistics` of the designs (rows of X), each computed once."""
        out = []
        for x, record in zip(X, self(X, sample)):
            key = self.key(sample, x)
            if key not in self.cache:
                values = per_realization(record, self.k_max)
                stats = statistics(values, self.prob.spec.confidence)
                if self.rare is not None:
                    stats[RARE] = rare_statistic(record.attrs, self.prob.spec, self.prob.spec.confidence)
                self.cache[key] = (values, stats)
            out.append(self.cache[key][1])
        return out

    def values(self, X, sample: str = "design") -> np.ndarray:
        """Per-drape quantities (design, statistic name -> (R,)) of the designs, cached."""
        self.statistics(X, sample)
        return [self.cache[self.key(sample, x)][0] for x in X]

    def key(self, sample: str, x) -> str:
        study = self.prob.study if sample == "design" else self.prob.validation
        rare = self.prob.spec.rare
        asked = "" if rare is None else json.dumps([rare.qoi, rare.threshold, rare.cov, rare.max_drapes])
        text = (f"{RECORD_VERSION}|{self.identity}|{sample}|{study.seed}|{study.realizations}|"
                f"{np.asarray(x, float).tobytes().hex()}{asked}")
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
            record = None if self.folder is None else self.folder.read_dataset(f"{EVALUATIONS}/{key}.nc")
            if record is not None:
                self.records[key] = record
                self.kept += 1
            else:
                todo[key] = x
        if todo:
            self._drape(study, sample, todo)
            self.draped += len(todo)
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
        with Progress(n, enabled=self.progress, desc=f"{study.name}: {len(todo)} designs ({sample})") as bar:
            parts = compute_tasks(tasks, [b - a for a, b in ranges] * len(todo), self.scheduler, self.workers, bar,
                                  self.pool)
        self.drapes += n
        for key, x in todo.items():
            record = _merge([p for p, owner in zip(parts, owners) if owner == key])
            record.attrs.update(sample=sample, seed=study.seed, x=list(x), names=list(self.prob.names))
            if self.rare is not None:
                force = self.prob.settings(x)[0]
                estimate = self.rare(variant(study, *self.prob.settings(x)))
                record.attrs.update({f"rare_{k}": v for k, v in estimate.items()})
                self.drapes += estimate["drapes"]
                if self.progress:
                    print(f"{study.name}: rare estimate at {force:.1f} N ({sample}): P = {estimate['probability']:.3g}"
                          f" (CoV {estimate['cov']:.2f}, {estimate['drapes']:,} drapes, {estimate['method']})",
                          file=sys.stderr)
            if self.folder is not None:
                self.folder.write_dataset(f"{EVALUATIONS}/{key}.nc", record)
            self.records[key] = record
