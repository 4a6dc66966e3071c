"""Rare events by subset simulation (issue 29): analytic limit states with known P in >= 100
dimensions, the estimates' coverage over repeated runs against their stated coefficient
of variation, and the bookkeeping (levels, thresholds, model calls); a drape exceedance
as a limit state, cross-checked against plain Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from uqdrape.ensemble import drape_inputs, inputs_from_rows
from uqdrape.reliability import linear_limit_state, sphere_limit_state, subset_simulation
from uqdrape.reliability.subset import chain_gamma
from uqdrape.stats import realization_qois
from uqdrape.study import load_study
from uqdrape.workflow.rare import drape_limit_state

from conftest import write_study

RUNS, N = 200, 1000


@pytest.mark.parametrize("limit_state, d, p", [
    (linear_limit_state, 100, 1e-3), (linear_limit_state, 100, 1e-4),
    pytest.param(linear_limit_state, 100, 1e-5, marks=pytest.mark.slow),  # ~7 s each
    pytest.param(sphere_limit_state, 200, 1e-4, marks=pytest.mark.slow),
])
def test_subset_simulation_recovers_known_probabilities_within_their_stated_cov(limit_state, d, p):
    g, exact = limit_state(d, p)
    assert exact == pytest.approx(p, rel=1e-9)
    runs = [subset_simulation(g, d, n_per_level=N, seed=seed) for seed in range(RUNS)]
    estimate = np.array([r.probability for r in runs])
    stated = np.array([r.cov for r in runs])
    observed = estimate.std(ddof=1) / exact
    # coverage: P within 2 stated CoV of the estimate in most runs (95 % for a normal
    # estimate whose CoV is right; 4 binomial sd below that allowed, as the estimate is
    # skewed and Au & Beck's CoV leaves out the correlation between levels)
    covered = np.mean(np.abs(estimate / exact - 1) <= 2 * stated)
    assert covered >= 0.95 - 4 * np.sqrt(0.95 * 0.05 / RUNS)
    assert observed <= 1.5 * stated.mean()
    # the O(1/N) bias of the product of level estimates stays well inside the spread
    assert abs(estimate.mean() / exact - 1) <= observed / 2
    # levels: log10(1/p) of p0 = 0.1 (or one more, p being exactly p0^m), each after the first
    # adding N (1 - p0) evaluated points at most
    m = round(-np.log10(p))
    assert all(len(r.thresholds) in (m, m + 1) and r.thresholds[-1] == 0.0 for r in runs)
    assert all(N < r.calls <= N + (len(r.thresholds) - 1) * N * 0.9 for r in runs)


def test_subset_simulation_is_reproducible_and_its_thresholds_decrease():
    g, _ = linear_limit_state(100, 1e-4)
    a, b = (subset_simulation(g, 100, n_per_level=500, seed=7) for _ in range(2))
    assert a == b
    assert np.all(np.diff(a.thresholds) < 0)
    # p0 of each intermediate level (more where a rejected chain repeats the threshold's state)
    assert all(0.1 <= p < 0.12 for p in a.level_probabilities[:-1]) and 0.1 <= a.level_probabilities[-1] <= 1


def test_chain_gamma_of_independent_and_of_frozen_chains():
    rng = np.random.default_rng(0)
    independent = rng.random((10, 20_000)) < 0.1   # chains whose states are independent: gamma 0
    assert abs(chain_gamma(independent)) < 4 * 2 * 9 / np.sqrt(20_000 * 10)  # a few sd of the lag sums
    frozen = np.repeat(rng.random((1, 20_000)) < 0.1, 10, axis=0)  # chains that never move: rho = 1
    assert chain_gamma(frozen) == pytest.approx(2 * sum(1 - k / 10 for k in range(1, 10)), rel=1e-12)


def test_bad_arguments_are_refused():
    g, _ = linear_limit_state(10, 1e-3)
    with pytest.raises(ValueError, match="p0 \\* n_per_level and 1 / p0 must be whole numbers"):
        subset_simulation(g, 10, n_per_level=1005, seed=0)
    with pytest.raises(ValueError, match="no failure"):
        subset_simulation(lambda u: np.ones(len(u)), 10, n_per_level=100, seed=0, max_levels=3)
    with pytest.raises(ValueError, match="p must lie in"):
        linear_limit_state(10, 0.7)
    assert stats.norm.cdf(-(-stats.norm.ppf(1e-3))) == pytest.approx(1e-3)


def rare_study(tmp_path):
    """Geodesic drapes of a 50 mm dome, 6 rings, iid spacing (cv 2 %) and a skew factor:
    313 standard variables, about 3,000 drapes a second."""
    return load_study(write_study(tmp_path, "rare", study={"seed": 1, "realizations": 8, "chunk_size": 8},
                                  solver={"mode": "geodesic", "rings": 6},
                                  uncertainty={"spacing": {"cv": 0.02},
                                               "skew": {"dist": "normal", "mean": 0.0, "sd": 1.0}}))


def test_a_drape_limit_state_is_the_drape_of_its_standard_variables(tmp_path):
    study = rare_study(tmp_path)
    g, d = drape_limit_state(study, "max_abs_shear", 30.0)
    U = np.random.default_rng(2).standard_normal((5, d))
    X = U.copy()
    X[:, 0] = stats.norm.cdf(U[:, 0])  # skew, the one factor, as a standard uniform
    ds = drape_inputs(study, np.arange(5), inputs_from_rows(study, X))
    np.testing.assert_array_equal(g(U), 30.0 - realization_qois(ds, ["max_abs_shear"])["max_abs_shear"].values)


@pytest.mark.slow  # ~25 s: 20,000 + ~2,000 geodesic drapes, five times over for subset simulation
def test_subset_simulation_of_a_drape_exceedance_agrees_with_plain_monte_carlo(tmp_path):
    study = rare_study(tmp_path)
    g, d = drape_limit_state(study, "max_abs_shear", 0.0)
    U = np.random.default_rng(5).standard_normal((20_000, d))
    shear = -np.concatenate([g(part) for part in np.array_split(U, 20)])
    threshold = np.quantile(shear, 0.99)
    p_mc = np.mean(shear >= threshold)  # 0.01, CoV sqrt(0.99 / 200) = 7 %
    g, d = drape_limit_state(study, "max_abs_shear", threshold)
    runs = [subset_simulation(g, d, n_per_level=500, seed=seed) for seed in range(5)]
    p_sus = np.mean([r.probability for r in runs])
    cov = np.sqrt(np.mean([r.cov for r in runs]) ** 2 / len(runs) + 0.99 / (p_mc * 20_000))
    assert abs(p_sus / p_mc - 1) <= 3 * cov
    assert all(r.calls < 2_000 for r in runs)
