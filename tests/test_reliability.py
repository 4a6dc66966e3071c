"""Rare events by subset simulation (issue 29): analytic limit states with known P in >= 100
dimensions, the estimates' coverage over repeated runs against their stated coefficient
of variation, and the bookkeeping (levels, thresholds, model calls)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from uqdrape.reliability import linear_limit_state, sphere_limit_state, subset_simulation
from uqdrape.reliability.subset import chain_gamma

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
