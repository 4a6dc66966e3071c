"""A study's rare exceedance probabilities: P(QoI >= threshold) of its drapes, as limit
states in standard normal space for ``uqdrape.reliability``, and the estimates a
``[study] rare`` asks for, kept in the run folder (``rare.json``) and shown in its report.

U's columns are the study's sample columns (``uqdrape.ensemble.sample_columns``): a
scalar factor's u = Phi(U) (then its own ``ppf``), a random field's truncated KL modes
as they are (``kl_retained`` of its variance). A batch of rows is one batched drape.

A ``[study] rare = {qoi, threshold, cov, max_drapes}`` is estimated after the run's
sample, at every force level, by ``uqdrape.reliability.importance_sampling`` (importance
sampling at the most probable point the subset levels give, its response surface linear in the
factors' own values; subset simulation in independent rounds where no most probable point
carries the probability; plain Monte Carlo where failure is not rare, P = 1 where every
drape fails; an upper bound where no drape reaches the threshold) to CoV ``cov`` within
``max_drapes`` drapes, a hard limit, with the seed ``SeedSequence([study seed,
RARE_STREAM, level])``. A level whose CoV is above the target, or that is a bound, is
said on stderr in one line whether the run is quiet or not, and its report row says why. Its drapes are the
estimator's own (their nets are not stored). A resumed run keeps ``rare.json`` if it was
written for the same study and request.
"""

from __future__ import annotations

import dataclasses
import errno
import hashlib
import json
import math
import sys
from pathlib import Path

import numpy as np
from scipy.special import ndtr

from ..ensemble import at, drape_inputs, inputs_from_rows, sample_columns, study_mould
from ..files import check_input_file, json_object
from ..reliability import importance_sampling
from ..report import rare_rows
from ..report.html import RARE_METHODS
from ..schema import QOI_ATTRS
from ..stats import realization_qois
from ..study import identity

#: The rare-event estimates of a run, in its output folder.
RARE_FILE = "rare.json"
#: The estimator's seeds are SeedSequence([study seed, RARE_STREAM, force level index]).
RARE_STREAM = 29
#: Conditional probability of the subset levels.
P0 = 0.1
#: A [design] rare candidate's subset levels stop at P below BELOW x its bound.
BELOW = 0.01


def drape_limit_state(study, qoi: str, threshold: float, force: float | None = None):
    """(g, d) for P(``qoi`` >= ``threshold``) of ``study``'s drapes at blank-holder level
    ``force`` (N; None: the only one): g(U) = threshold - qoi of the drapes of the rows
    of U (n, d), so failure is g <= 0. A line QoI averages the max-shear line nodes valid
    in the nominal drape (U = 0), the same nodes in every batch."""
    names = sample_columns(study)
    factors = len(study.uncertainty.factors)
    surface, material = study_mould(study), study.fabric.card()

    def values(U, k_max=None):
        X = np.array(U, dtype=float, ndmin=2)
        X[:, :factors] = ndtr(X[:, :factors])
        ds = drape_inputs(study, np.arange(len(X)), inputs_from_rows(study, X), force=force, surface=surface,
                          material=material)
        return realization_qois(ds, [qoi], k_max)

    k_max = values(np.zeros((1, len(names)))).attrs.get("k_max")

    def g(U):
        return threshold - values(U, k_max)[qoi].values

    return g, len(names)


def factor_values(study):
    """The map of U's columns (n, d) to what a response surface of the drapes is fitted in:
    a scalar factor's own value (its ``ppf`` of Phi(u): a bounded factor saturates in u),
    the random fields' KL modes as they are (``uqdrape.reliability.importance.most_probable_point``)."""
    factors = list(study.uncertainty.factors.values())

    def features(U):
        X = np.array(U, dtype=float)
        for k, factor in enumerate(factors):
            X[:, k] = factor.ppf(ndtr(np.clip(X[:, k], -8.0, 8.0)))
        return X

    return features


def estimate(study, spec, seed: int, force: float, *, below: float | None = None) -> tuple[dict, int]:
    """({probability, cov, drapes, method, beta, subset_probability, subset_cov, note},
    standard variables) of P(``spec.qoi`` >= ``spec.threshold``) of ``study``'s drapes at
    ``force`` (N) by ``importance_sampling`` to CoV ``spec.cov`` within ``spec.max_drapes``
    drapes (a hard limit), with ``seed``. ``method`` "below": no drape reached the
    threshold, and ``probability`` is an upper bound (CoV 0); with ``below``, the subset
    levels stop at the first level of P under it (p0 = 0.1 each). ``note``: why the
    estimate is above the target CoV or a bound ("" otherwise)."""
    g, d = drape_limit_state(study, spec.qoi, spec.threshold, force)
    levels = 30 if below is None else math.ceil(round(math.log(below) / math.log(P0), 9))
    r = importance_sampling(g, d, seed=seed, cov=spec.cov, max_calls=spec.max_drapes, p0=P0, max_levels=levels,
                            features=factor_values(study))
    return {"probability": r.probability, "cov": r.cov, "drapes": r.calls, "method": r.method, "beta": r.beta,
            "subset_probability": r.subset.probability, "subset_cov": r.subset.cov, "note": r.note}, d


def untrusted(record: dict, level: dict) -> str:
    """One line saying why a force level's estimate of rare-event record ``record`` is not
    to be trusted ("" if it is): P below a bound, or its CoV above the target."""
    what = f"P({record['qoi']} >= {record['threshold']:g}) at {level['force']:g} N"
    if level["method"] == "below":
        return (f"{what}: no drape reached the threshold in {level['drapes']:,} drapes: P < "
                f"{level['probability']:.2g}, an upper bound, not an estimate")
    if level["cov"] > record["cov"]:
        why = f" ({level['note']})" if level.get("note") else ""  # a record of an older run has none
        return (f"{what} = {level['probability']:.3g} is not to be trusted: CoV {level['cov']:.2f} above the target "
                f"{record['cov']:g}{why}")
    return ""


def design_rare(variant) -> dict:
    """The ``[design] rare`` estimate of one candidate design (``variant``: the study with
    the candidate's force, sectors and friction, and the seed of its sample): :func:`estimate`
    with the seed ``SeedSequence([sample seed, RARE_STREAM])``, the same for every candidate
    of a sample (common random numbers, as its drapes), so a resumed design is bitwise the
    same. Subset levels stop at P below BELOW x the bound: a design that safe is feasible
    whatever its P, and is not estimated further (``method = "below"``)."""
    spec = variant.design.rare
    seed = int(np.random.SeedSequence([variant.seed, RARE_STREAM]).generate_state(1)[0])
    return estimate(variant, spec, seed, variant.force_levels[0], below=BELOW * spec.max_probability)[0]


def rare_key(study) -> str:
    """What a ``rare.json`` is of: a digest of the study's drapes (``identity``), its seed and
    its ``[study] rare``."""
    what = {"study": identity(study.to_dict()), "seed": study.seed, "rare": dataclasses.asdict(study.rare)}
    return hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()


def read_rare(study, output_dir) -> dict | None:
    """The rare-event record in ``output_dir`` (``RARE_FILE``; a run folder or a
    store's URL) if it is of ``study``'s ``[study] rare`` (:func:`rare_key`), else None;
    one uqdrape did not write raises as :func:`parse_rare`."""
    if study.rare is None:
        return None
    where = at(output_dir)
    with where.reading(RARE_FILE) as path:
        if path is None:
            return None
        check_input_file(path, "rare-event record", MAX_RARE_BYTES)  # a FIFO or a huge file: one line
        record = parse_rare(Path(path).read_bytes(), where.path_of(RARE_FILE))
    return record if record["key"] == rare_key(study) else None


#: Largest rare-event record read (bytes): a level takes about 300.
MAX_RARE_BYTES = 2**20


def parse_rare(data: bytes, where) -> dict:
    """The rare-event record in ``data`` (the bytes of the file ``where``), checked to hold
    what a resume and the report read of it (:func:`untrusted`, ``report.rare_rows``); one
    that is not JSON, or is not such a record (hand-edited, truncated, another program's),
    raises a one-line OSError naming ``where``, as a damaged run manifest does."""
    def damaged(why: str) -> OSError:
        return OSError(errno.EIO, f"not a uqdrape rare-event record ({why}); delete it and run the study again to "
                                  "estimate it anew", str(where))

    def number(value, low=-math.inf, integer=False) -> bool:
        kind = int if integer else (int, float)
        return isinstance(value, kind) and not isinstance(value, bool) and low <= value < math.inf

    record = json_object(data, damaged)
    if not isinstance(record.get("key"), str):
        raise damaged('"key" must be the digest of the study and its request')
    if not (isinstance(record.get("qoi"), str) and record["qoi"] in QOI_ATTRS):
        raise damaged(f'"qoi" must be one of {", ".join(QOI_ATTRS)}')
    if not (number(record.get("threshold")) and number(record.get("cov"), 0.0) and record["cov"] > 0
            and number(record.get("variables"), 0, integer=True)):
        raise damaged('"threshold" must be a number, "cov" one > 0 and "variables" a count')
    levels = record.get("levels")
    if not (isinstance(levels, list) and all(isinstance(level, dict) for level in levels)):
        raise damaged('"levels" must be a list of force levels')
    for level in levels:
        if not (number(level.get("force")) and number(level.get("probability"), 0.0) and level["probability"] <= 1
                and number(level.get("cov"), 0.0) and number(level.get("drapes"), 0, integer=True)
                and isinstance(level.get("method"), str) and level["method"] in RARE_METHODS
                and isinstance(level.get("note", ""), str)):
            raise damaged("a level must hold its force, a probability in [0, 1], its cov >= 0, a count of drapes, "
                          f"the method ({', '.join(RARE_METHODS)}) and a note")
    return record


def rare_probabilities(study, output_dir, *, resume: bool = True, progress: bool = True) -> dict:
    """Estimate the study's ``[study] rare`` at every force level (module docstring) and
    write it to ``output_dir/rare.json``; a resumed run keeps a record of the same
    :func:`rare_key`. Returns the record."""
    spec, key = study.rare, rare_key(study)
    kept = read_rare(study, output_dir) if resume else None
    if kept is not None:
        if progress:
            print(f"{study.name}: rare probability already estimated in {output_dir}", file=sys.stderr)
        _warn(study, kept)
        return kept
    levels = []
    for level, force in enumerate(study.force_levels):
        seed = int(np.random.SeedSequence([study.seed, RARE_STREAM, level]).generate_state(1)[0])
        entry, d = estimate(study, spec, seed, force)
        levels.append({"force": force, **{k: None if isinstance(v, float) and not math.isfinite(v) else v
                                          for k, v in entry.items()}})  # strict JSON: no NaN (beta of a bound)
    record = {"key": key, **dataclasses.asdict(spec), "variables": d, "levels": levels}
    if progress:
        for quantity, value, how in rare_rows(record):
            print(f"{study.name}: {quantity} = {value} ({how})", file=sys.stderr)
    _warn(study, record)
    at(output_dir).write_text(RARE_FILE, json.dumps(record, indent=2) + "\n")
    return record


def _warn(study, record: dict) -> None:
    """Say on stderr, quiet or not, each force level of ``record`` not to be trusted (:func:`untrusted`)."""
    for level in record["levels"]:
        if line := untrusted(record, level):
            print(f"{study.name}: warning: {line}", file=sys.stderr)
