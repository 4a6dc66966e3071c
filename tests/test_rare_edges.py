"""Rare-event estimates that keep their promise (issue 39), on analytic limit states: the
edges (certain failure is P = 1, no failure is an upper bound, the budget is a hard limit
however small), a stated CoV that is true over repeated runs (importance sampling, and
subset simulation in independent rounds where no most probable point carries the probability),
and a bounded factor (a standard uniform's Phi(u) saturating in u) whose most probable point
the response surface finds when it is fitted in the factor's own value."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import optimize, stats
from scipy.special import ndtr

from uqdrape.reliability import bounded_limit_state, importance_sampling, linear_limit_state
from uqdrape.reliability.importance import NONE_SEEN

REPEATS = 30


def counted(g):
    """``g`` and the list of the batch sizes it was called with."""
    calls = []

    def wrapped(u):
        calls.append(len(u))
        return g(u)

    return wrapped, calls


def test_certain_failure_is_p_one_from_one_level_of_plain_samples():
    g, calls = counted(lambda u: -np.ones(len(u)))
    r = importance_sampling(g, 20, seed=0, cov=0.1, max_calls=5000)
    assert (r.probability, r.cov, r.method, r.note) == (1.0, 0.0, "montecarlo", "")
    assert r.calls == sum(calls) == 500


def test_a_failure_that_is_not_rare_is_plain_monte_carlo_to_the_target():
    g, exact = linear_limit_state(20, 0.2)
    g, calls = counted(g)
    r = importance_sampling(g, 20, seed=1, cov=0.05, max_calls=5000)
    assert r.method == "montecarlo" and r.note == "" and r.cov <= 0.05
    assert r.cov == pytest.approx(np.sqrt((1 - r.probability) / (r.probability * r.calls)), rel=1e-12)
    assert abs(r.probability / exact - 1) <= 3 * r.cov
    assert r.calls == sum(calls) <= (1 - exact) / (exact * 0.05**2) * 1.3  # what binomial sampling needs


def test_no_failure_is_an_upper_bound_that_says_so():
    g, calls = counted(lambda u: np.ones(len(u)))
    r = importance_sampling(g, 20, seed=0, cov=0.1, max_calls=5000, max_levels=4)
    assert r.method == "below" and r.cov == 0.0 and r.calls == sum(calls) <= 5000
    # no failure among level 0's 500 independent samples: 95 % bound -ln(0.05) / 500
    assert r.probability == pytest.approx(NONE_SEEN / 500, rel=1e-12)
    assert r.note == "no failure reached before the levels ran out"


@pytest.mark.parametrize("budget", [300, 1000, 2000])
def test_the_budget_is_a_hard_limit_even_below_the_levels_it_needs(budget):
    # 1e-6 needs 6 levels of 500 (about 2,750 calls) before any importance sample
    g, exact = linear_limit_state(50, 1e-6)
    g, calls = counted(g)
    r = importance_sampling(g, 50, seed=2, cov=0.1, max_calls=budget)
    assert r.calls == sum(calls) <= budget
    assert r.method == "below" and r.note == "no failure reached before the budget ran out"
    assert exact < r.probability <= NONE_SEEN / min(budget, 500)  # a bound above the truth


@pytest.mark.parametrize("budget", [2500, 4000, 9000])
def test_the_budget_is_a_hard_limit_when_it_runs_out_on_the_way(budget):
    # two half-spaces: the checks send it to subset rounds, which the budget cuts short
    d, beta = 20, 3.2
    a = np.ones(d) / np.sqrt(d)
    g, calls = counted(lambda u: beta - np.abs(np.asarray(u) @ a))
    r = importance_sampling(g, d, seed=3, cov=0.05, max_calls=budget)
    assert r.calls == sum(calls) <= budget
    assert r.method == "subset" and r.cov > 0.05 and r.note.endswith("ran out") and r.note


def spread(runs, exact):
    """(observed CoV of the estimates about the exact P, mean stated CoV, mean estimate / P)."""
    estimate = np.array([r.probability for r in runs])
    return estimate.std(ddof=1) / exact, np.mean([r.cov for r in runs]), estimate.mean() / exact


def test_the_stated_cov_of_importance_sampling_is_true_on_a_hyperplane_at_1e3():
    g, exact = linear_limit_state(100, 1e-3)
    runs = [importance_sampling(g, 100, seed=seed, cov=0.1, max_calls=20_000) for seed in range(REPEATS)]
    observed, stated, bias = spread(runs, exact)
    assert 1 / 1.5 <= observed / stated <= 1.5
    assert abs(bias - 1) <= 3 * observed / np.sqrt(REPEATS)


def test_the_stated_cov_of_subset_rounds_is_true_where_no_design_point_carries_it():
    # |u . a| >= beta: failure at both signs, P = 2 Phi(-beta) = 1e-3; every run answers by
    # subset simulation in rounds, whose CoV comes from their spread
    d = 10
    beta = -stats.norm.ppf(5e-4)
    a = np.ones(d) / np.sqrt(d)

    def g(u):
        return beta - np.abs(np.asarray(u) @ a)

    runs = [importance_sampling(g, d, seed=seed, cov=0.2, max_calls=20_000) for seed in range(REPEATS)]
    assert all(r.method == "subset" and r.calls <= 20_000 for r in runs)
    observed, stated, bias = spread(runs, 1e-3)
    assert 1 / 1.5 <= observed / stated <= 1.5
    assert abs(bias - 1) <= 3 * observed / np.sqrt(REPEATS)


def test_a_bounded_factor_fitted_in_its_own_value_gets_its_design_point_and_a_true_cov():
    d, p = 50, 1e-3
    g, exact, uniform_value = bounded_limit_state(d, p)
    t = g(np.zeros(d))[()] + 0.5  # g(0) = t - Phi(0)
    # FORM's most probable point: least |u| with Phi(u0) + sigma |z| = t, z along the noise's direction
    u0 = optimize.minimize_scalar(lambda v: v**2 + ((t - ndtr(v)) / 0.05) ** 2, bounds=(0, 5), method="bounded").x
    form = np.hypot(u0, (t - ndtr(u0)) / 0.05)
    runs = [importance_sampling(g, d, seed=seed, cov=0.1, max_calls=20_000, features=uniform_value)
            for seed in range(REPEATS)]
    importance = [r for r in runs if r.method == "importance"]
    assert len(importance) >= 0.9 * REPEATS
    assert all(abs(r.beta - form) < 0.05 and r.r2 == pytest.approx(1.0, abs=1e-9) for r in importance)
    assert exact == pytest.approx(p, rel=1e-9)
    observed, stated, bias = spread(runs, p)
    assert 1 / 1.5 <= observed / stated <= 1.5 and abs(bias - 1) <= 3 * observed / np.sqrt(REPEATS)
    # >= 10x fewer calls than plain Monte Carlo at the observed accuracy: (1 - p) / (p CoV^2)
    assert np.mean([r.calls for r in runs]) * 10 <= (1 - p) / (p * observed**2)
    assert all(r.calls <= 20_000 for r in runs)


@pytest.mark.slow  # ten estimates in 1,203 dimensions, about 10 s each (REPEATS would take 5 min)
def test_a_bounded_factor_among_a_thousand_noise_columns_is_screened_to_its_design_point():
    # as many columns as the energy drapes' (friction and a 1,202-mode field): a surface
    # through all of them interpolates the pilot's ~2,000 samples (beta 0.7, refused); the
    # one on the correlated columns, the rest as noise, finds FORM's point
    d, p = 1203, 1e-3
    g, _, uniform_value = bounded_limit_state(d, p)
    t = g(np.zeros(d))[()] + 0.5
    u0 = optimize.minimize_scalar(lambda v: v**2 + ((t - ndtr(v)) / 0.05) ** 2, bounds=(0, 5), method="bounded").x
    form = np.hypot(u0, (t - ndtr(u0)) / 0.05)
    runs = [importance_sampling(g, d, seed=seed, cov=0.1, max_calls=20_000, features=uniform_value)
            for seed in range(10)]
    assert sum(r.method == "importance" for r in runs) >= 9
    assert all(abs(r.beta - form) < 0.2 and r.calls <= 20_000 for r in runs)
    observed, stated, bias = spread(runs, p)
    assert 1 / 1.5 <= observed / stated <= 1.5 and abs(bias - 1) <= 3 * observed / np.sqrt(10)


def test_a_bounded_factor_fitted_in_u_is_caught_by_the_beta_check_and_says_its_cov():
    # the surface linear in u finds the noise's direction only (beta about 9, not 2.9): the
    # beta check refuses it, subset rounds answer, and their stated CoV is their spread's
    d, p = 50, 1e-3
    g, _, _ = bounded_limit_state(d, p)
    runs = [importance_sampling(g, d, seed=seed, cov=0.1, max_calls=20_000) for seed in range(REPEATS)]
    assert all(r.method == "subset" and "most probable point beta" in r.note for r in runs if r.beta > 5)
    assert sum(r.beta > 5 for r in runs) >= 0.9 * REPEATS
    observed, stated, bias = spread(runs, p)
    assert 1 / 1.5 <= observed / stated <= 1.5 and abs(bias - 1) <= 3 * observed / np.sqrt(REPEATS)


@pytest.mark.parametrize("budget", [1000, 1900, 1960, 2000])
def test_the_root_search_fits_in_the_budget(budget):
    # 1e-3 reaches failure in about 1,850 calls: the root search must fit in what is left
    g, _ = linear_limit_state(20, 1e-3)
    g, calls = counted(g)
    r = importance_sampling(g, 20, seed=4, cov=0.01, max_calls=budget)
    assert r.calls == sum(calls) <= budget and r.note


@pytest.mark.parametrize("budget", [1500, 2200, 3000, 3500])
def test_subset_rounds_stay_in_the_budget(budget):
    # two half-spaces at 1e-2 and a 1 % target: the pilot, then subset rounds that the
    # budget cuts; none of them may start a level it cannot pay for
    d, beta = 10, -stats.norm.ppf(5e-3)
    a = np.ones(d) / np.sqrt(d)
    g, calls = counted(lambda u: beta - np.abs(np.asarray(u) @ a))
    for seed in range(5):
        calls.clear()
        r = importance_sampling(g, d, seed=seed, cov=0.01, max_calls=budget)
        assert r.calls == sum(calls) <= budget and r.method == "subset" and r.note


def test_where_plain_sampling_is_no_dearer_than_subset_rounds_it_is_used():
    # two half-spaces at P = 0.05: no most probable point carries it, and plain sampling on from the
    # pilot's 500 independent samples needs fewer calls than subset rounds to 10 %
    d = 10
    beta, a = -stats.norm.ppf(0.025), np.ones(d) / np.sqrt(d)
    g, calls = counted(lambda u: beta - np.abs(np.asarray(u) @ a))
    for seed in range(5):
        calls.clear()
        r = importance_sampling(g, d, seed=seed, cov=0.1, max_calls=20_000)
        assert r.method == "montecarlo" and r.cov <= 0.1 and r.note == "" and r.calls == sum(calls)
        assert abs(r.probability / 0.05 - 1) <= 3 * r.cov
        # the pilot's levels above level 0 and the root search, plus what plain MC needs
        assert r.calls <= r.subset.calls + 40 + (1 - 0.05) / (0.05 * 0.1**2) * 1.1
