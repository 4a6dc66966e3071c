"""Sensitivity samples: the SALib sample matrix for Sobol' or Morris.

Rows of the returned matrix are model evaluations, columns the problem's variables in
physical units (the distributions' inverse CDFs are applied by SALib).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from SALib.sample import morris as morris_sample
from SALib.sample import sobol as sobol_sample
from SALib.util import scale_samples

from ..stochastic.sampling import check_base_samples, check_method
from .problem import check_problem

MORRIS_NUM_LEVELS = 4
# Morris puts points on the 0 and 1 quantiles, i.e. at +-inf for norm/lognorm. For
# those (and only those) distributions the levels are moved affinely into
# [q, 1 - q]: the extreme Morris levels become the 0.5 % and 99.5 % quantiles.
MORRIS_TAIL_QUANTILE = 0.005
UNBOUNDED = ("norm", "lognorm")


def check_seed(seed) -> int:
    """Seeds are non-negative ints (reproducibility is not optional here)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed={seed!r} must be a non-negative integer")
    return int(seed)


def sample(problem: Mapping, method: str = "sobol", *, base_samples: int, seed: int):
    """Sample matrix (n_evaluations, num_vars) and its metadata.

    sobol: SALib.sample.sobol with calc_second_order=False, n = N (G + 2) rows for G
    groups (or factors). morris: SALib.sample.morris with ``MORRIS_NUM_LEVELS`` levels,
    base_samples trajectories, n = N (G + 1) rows. Metadata keys: method, base_samples,
    n_evaluations, sample_seed (+ num_levels, tail_quantile for Morris).
    """
    labels = check_problem(problem)
    method = check_method(method)
    n = check_base_samples(method, base_samples)
    seed = check_seed(seed)
    meta = {"method": method, "base_samples": n, "sample_seed": seed}

    if method == "sobol":
        # SALib adds keys to the dict it is given: hand it a copy.
        X = sobol_sample.sample(dict(problem), n, calc_second_order=False, seed=seed)
    else:
        d = problem["num_vars"]
        unit = {"num_vars": d, "names": list(problem["names"]), "bounds": [[0.0, 1.0]] * d,
                "groups": problem.get("groups")}
        levels = morris_sample.sample(unit, n, num_levels=MORRIS_NUM_LEVELS, seed=seed)
        dists = problem.get("dists") or ["unif"] * d
        unbounded = np.array([dist in UNBOUNDED for dist in dists])
        q = MORRIS_TAIL_QUANTILE
        levels[:, unbounded] = q + (1.0 - 2.0 * q) * levels[:, unbounded]
        X = scale_samples(levels, dict(problem))
        meta.update(num_levels=MORRIS_NUM_LEVELS, tail_quantile=q)

    per_sample = len(labels) + (2 if method == "sobol" else 1)
    assert X.shape == (n * per_sample, problem["num_vars"])
    meta["n_evaluations"] = int(X.shape[0])
    return X, meta
