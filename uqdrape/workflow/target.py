"""Runs to a target accuracy: a study's sample drawn in rounds until the confidence
interval of the statistic its ``[study] target`` names is narrow enough, or its budget
``max_realizations`` is spent.

A round extends the run (``uqdrape.ensemble``: the same random streams a larger run has,
so the result is the larger run's, bitwise). The first round is ``realizations``; after a
round of n drapes with half-width h (the widest over the force levels), the next aims at
the n (h / target)^2 that a 1/sqrt(n) interval needs, at most doubling n and at least one
step (``chunk_size`` realisations; one randomisation of a randomised QMC plan), capped by
the budget. The run's manifest records under ``target`` the rounds (realisations,
estimate and half-width per force level) and what stopped it: ``"target"`` (the last
round's half-width is at most the target at every level) or ``"budget"``.

Intervals: the mean of a QoI, Student t over the drapes; the probability of a 0/1 QoI,
Wilson score; under a randomised QMC plan, both Student t over the randomisations' own
estimates (``replicate_interval``), the points of one randomisation not being independent.
"""

from __future__ import annotations

import dataclasses
import math
import sys

import numpy as np
from scipy import stats as _stats

from ..ensemble import at, open_ensemble, read_manifest
from ..schema import FORCE
from ..stats import realization_qois, wilson_interval

#: What stopped a target run: the target met, or the budget spent.
STOPS = ("target", "budget")


def replicate_interval(values, replicates: int, confidence: float) -> tuple[float, float]:
    """(estimate, half-width) of the mean of ``values`` (R,) made of ``replicates`` equal
    consecutive groups (independent randomisations of one point set): the mean of the
    group means and the Student-t half-width of their spread (replicates - 1 dof)."""
    groups = np.asarray(values, dtype=float).reshape(replicates, -1).mean(axis=1)
    t = _stats.t.ppf(0.5 + confidence / 2, replicates - 1)
    return float(groups.mean()), float(t * groups.std(ddof=1) / math.sqrt(replicates))


def interval(values, target, replicates: int | None = None) -> tuple[float, float]:
    """(estimate, half-width) of the target's statistic from one force level's per-drape
    values (R,): see the module docstring; ``replicates`` the randomisations of an rqmc
    plan (None: independent drapes)."""
    values = np.asarray(values, dtype=float)
    if np.isnan(values).any():
        raise ValueError(f"target: {target.qoi} is undefined in {int(np.isnan(values).sum())} drapes")
    if replicates is None and target.statistic == "probability":
        lo, hi = wilson_interval(values.sum(), values.size, target.confidence)
        return float(values.mean()), float(hi - lo) / 2
    # independent drapes: the Student-t interval of groups of one
    return replicate_interval(values, values.size if replicates is None else replicates, target.confidence)


def next_realizations(n: int, half: float, goal: float, step: int, budget: int) -> int:
    """The size of the next round's run after ``n`` drapes gave half-width ``half`` >
    ``goal``: n (half / goal)^2 rounded up to a multiple of ``step``, between n + step and
    2 n (at least one step), at most ``budget``."""
    aim = n * (half / goal) ** 2
    aim = min(max(aim, n + step), max(2 * n, n + step))
    return min(budget, step * math.ceil(aim / step))


def level_intervals(out, target, replicates: int | None):
    """{force (N): (estimate, half-width)} of the run in ``out``."""
    with open_ensemble(out) as ds:
        values = realization_qois(ds, [target.qoi])[target.qoi]
    return {float(f): interval(values.sel({FORCE: f}).values, target, replicates) for f in values[FORCE].values}


def _resized(study, n: int, points: int | None):
    """The study with n realisations (n / points randomisations of an rqmc plan)."""
    sampling = study.sampling if points is None else dataclasses.replace(study.sampling, randomizations=n // points)
    return dataclasses.replace(study, realizations=n, sampling=sampling)


def run_to_target(study, run_round, *, chunk_size: int, resume: bool = True, progress: bool = True):
    """Run ``study`` (with a ``target``) in rounds: ``run_round(study_of_n, resume)`` drapes
    the study with n realisations into its output folder (resume True: extending what is
    there) and returns the folder. A round adds at least ``chunk_size`` realisations (one
    randomisation of an rqmc plan). ``resume`` False starts afresh, True from the size of
    the folder's last round (an earlier run's, finished or interrupted). Writes the
    ``target`` record into the manifest; returns the folder."""
    target, budget = study.target, study.max_realizations
    points = study.realizations // study.sampling.randomizations if study.sampling.randomizations else None
    step = points or chunk_size
    budget -= budget % points if points else 0  # whole randomisations
    n, rounds = study.realizations, []
    earlier = read_manifest(study.output_dir) if resume else None
    if earlier:  # the size of the folder's last round, finished or interrupted
        n = max(n, earlier["study"]["study"]["realizations"])
    while True:
        out = run_round(_resized(study, n, points), resume or bool(rounds))
        levels = level_intervals(out, target, None if points is None else n // points)
        half = max(h for _, h in levels.values())
        rounds.append({"realizations": n, "estimate": [e for e, _ in levels.values()],
                       "half_width": [h for _, h in levels.values()]})
        if progress:
            print(f"{study.name}: round {len(rounds)}, {n} realisations: {target.statistic} of {target.qoi} "
                  f"+- {half:.4g} (target {target.half_width:g})", file=sys.stderr)
        if half <= target.half_width or n >= budget:
            break
        n = next_realizations(n, half, target.half_width, step, budget)
    stop = STOPS[0] if half <= target.half_width else STOPS[1]
    manifest = read_manifest(out)
    at(out).write_manifest({**manifest, "target": {**dataclasses.asdict(target), "max_realizations": study.max_realizations,
                                                "stopped_by": stop, "realizations": n, "half_width_reached": half,
                                                "forces": list(levels), "rounds": rounds}})
    return out
