"""Tests of uqdrape.stochastic: fields, inputs, factors, plans, seeding.

Statistical checks use R independent realisations and a tolerance of Z = 4 standard
errors: SE(mean) = sd/sqrt(R), SE(sd) ≈ sd/sqrt(2R), SE(Pearson r) ≈ (1 − ρ²)/sqrt(R).
Averages over cells or lattice pairs of such estimators have SE no larger than one
estimator's, so the same bound is conservative for them. Seeds are fixed.
"""

import numpy as np
import pytest
import scipy.stats
from SALib.util import scale_samples

from uqdrape.stochastic import (
    GaussianField, SpacingInput, ZeroAngleInput, constant, lognormal, make_factor, normal,
    realization_normals, realization_rng, sample_uniforms, truncnormal, uniform, uniforms_to_normals,
)

R = 4000
Z = 4.0
SPACING = 5.0


def draws(field, n=R, seed=0):
    rng = np.random.default_rng(seed)
    return field.sample(rng.standard_normal((n,) + field.xi_shape))


def corr_1d(n, step, correlation, length):
    """Independent construction of the 1-D correlation matrix from the formulas."""
    lag = np.abs(np.subtract.outer(np.arange(n), np.arange(n))) * step
    if correlation == "iid":
        return np.eye(n)
    if correlation == "exponential":
        return np.exp(-lag / length)
    return np.exp(-(lag / length) ** 2)


def linear_map(field):
    """Matrix A with flat(field.sample(xi)) = flat(xi) @ A, from unit inputs."""
    k = int(np.prod(field.xi_shape))
    return field.sample(np.eye(k).reshape((k,) + field.xi_shape)).reshape(k, -1)


def mean_pair_corr(x, lag, axis):
    """Mean over lattice pairs at ``lag`` along ``axis`` of the Pearson r across realisations."""
    a = np.moveaxis(x, axis + 1, 1)
    u, v = a[:, :-lag], a[:, lag:]
    u = (u - u.mean(0)) / u.std(0)
    v = (v - v.mean(0)) / v.std(0)
    return (u * v).mean(0).mean()


# ---------------------------------------------------------------- fields

@pytest.mark.parametrize("correlation, length", [
    ("iid", None), ("exponential", (15.0, 30.0)), ("squared_exponential", (12.0, 25.0)),
])
def test_exact_field_covariance_is_the_separable_model(correlation, length):
    na, nb = 7, 9
    f = GaussianField((na, nb), SPACING, correlation, length)
    A = linear_map(f)
    L1, L2 = length or (None, None)
    expected = np.kron(corr_1d(na, SPACING, correlation, L1), corr_1d(nb, SPACING, correlation, L2))
    np.testing.assert_allclose(A.T @ A, expected, atol=1e-10)


@pytest.mark.parametrize("correlation", ["iid", "exponential", "squared_exponential"])
def test_field_mean_zero_sd_one(correlation):
    x = draws(GaussianField((12, 15), SPACING, correlation, (20.0, 40.0)))
    for cell in [(0, 0), (6, 7), (11, 14), (0, 14)]:
        assert abs(x[(slice(None),) + cell].mean()) < Z / np.sqrt(R)
        assert abs(x[(slice(None),) + cell].std() - 1.0) < Z / np.sqrt(2 * R)
    assert abs(x.std(0).mean() - 1.0) < Z / np.sqrt(2 * R)


@pytest.mark.parametrize("correlation, rho", [
    ("exponential", lambda h, L: np.exp(-h / L)),
    ("squared_exponential", lambda h, L: np.exp(-(h / L) ** 2)),
])
def test_field_autocorrelation_along_each_fibre(correlation, rho):
    lengths = (15.0, 30.0)
    x = draws(GaussianField((16, 16), SPACING, correlation, lengths), seed=1)
    for axis, L in enumerate(lengths):
        for lag in (1, 2, 3):
            expected = rho(lag * SPACING, L)
            tol = Z * (1 - expected**2) / np.sqrt(R)
            assert abs(mean_pair_corr(x, lag, axis) - expected) < tol, (axis, lag)


def test_iid_field_uncorrelated_at_lag_one():
    x = draws(GaussianField((16, 16), SPACING, "iid", (15.0, 30.0)), seed=2)
    for axis in (0, 1):
        assert abs(mean_pair_corr(x, 1, axis)) < Z / np.sqrt(R)


def test_kl_retained_variance_matches_trace_of_full_covariance():
    na, nb, lengths = 8, 10, (15.0, 30.0)
    f = GaussianField((na, nb), SPACING, "exponential", lengths)
    lam = np.sort(np.linalg.eigvalsh(np.kron(corr_1d(na, SPACING, "exponential", lengths[0]),
                                             corr_1d(nb, SPACING, "exponential", lengths[1]))))[::-1]
    share = np.cumsum(lam) / (na * nb)  # trace of a correlation matrix = number of points
    kl = f.kl(0.95)
    n = int(np.argmax(share >= 0.95)) + 1
    assert kl.n_modes == n and share[n - 2] < 0.95 <= kl.retained_variance
    assert kl.retained_variance == pytest.approx(share[n - 1], abs=1e-12)
    # the expansion's covariance has exactly that trace
    A = linear_map(kl)
    assert np.trace(A.T @ A) / (na * nb) == pytest.approx(kl.retained_variance, abs=1e-12)
    # a given mode count
    kl5 = f.kl(n_modes=5)
    assert kl5.xi_shape == (5,) and kl5.retained_variance == pytest.approx(share[4], abs=1e-12)
    # sampled KL field variance ≈ retained fraction
    x = draws(kl, seed=3)
    assert abs(x.var(0).mean() - kl.retained_variance) < Z * np.sqrt(2 / R)


def test_kl_complete_and_iid_keep_everything():
    f = GaussianField((6, 5), SPACING, "squared_exponential", (10.0, 10.0))
    full = f.kl(1.0)
    assert full.retained_variance == pytest.approx(1.0, abs=1e-12)
    A = linear_map(full)
    np.testing.assert_allclose(A.T @ A, f.covariance(), atol=1e-10)
    iid = GaussianField((6, 5), SPACING).kl(0.5)  # all eigenvalues tie: no arbitrary subset
    assert iid.n_modes == 30 and iid.retained_variance == pytest.approx(1.0)


def test_independent_realisations_uncorrelated():
    f = GaussianField((10, 10), SPACING, "exponential", (25.0, 25.0))
    (xi,) = realization_normals(11, range(2 * R), [f.n_modes])
    x = f.sample(xi.reshape((-1,) + f.shape))
    for cell in [(0, 0), (5, 5), (9, 3)]:
        r = np.corrcoef(x[0::2][(slice(None),) + cell], x[1::2][(slice(None),) + cell])[0, 1]
        assert abs(r) < Z / np.sqrt(R)


@pytest.mark.parametrize("call, match", [
    (lambda: GaussianField((5, 5), SPACING, "gaussian", 10.0), "correlation must be one of"),
    (lambda: GaussianField((5, 5), SPACING, "exponential"), "length_mm .* required"),
    (lambda: GaussianField((5, 5), SPACING, "exponential", (10.0, -1.0)), "length_mm must be a positive"),
    (lambda: GaussianField((5, 5), 0.0), "spacing_mm must be a positive"),
    (lambda: GaussianField((5, 0), SPACING), "shape must be two positive integers"),
    (lambda: GaussianField((5, 5), SPACING).sample(np.zeros((2, 5, 4))), r"trailing shape \(5, 5\)"),
    (lambda: GaussianField((5, 5), SPACING, "exponential", 9.0).kl(1.5), r"retained must be .* \(0, 1\]"),
    (lambda: GaussianField((5, 5), SPACING, "exponential", 9.0).kl(n_modes=26), r"n_modes must be .* \[1, 25\]"),
    (lambda: GaussianField((5, 5), SPACING, "exponential", 9.0).kl().sample(np.zeros(99)), "trailing shape"),
])
def test_field_bad_parameters(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ---------------------------------------------------------------- inputs

def test_spacing_input_mean_and_sd():
    s, cv, n = SPACING, 0.05, 6
    lengths = (10.0, 40.0)
    sp = SpacingInput(n, s, cv, "exponential", lengths)
    rng = np.random.default_rng(4)
    s1, s2 = sp(rng.standard_normal((R, sp.n_variables)))
    assert s1.shape == (R, 2 * n, 2 * n + 1) and s2.shape == (R, 2 * n + 1, 2 * n)
    for seg in (s1, s2):
        assert abs(seg.mean(0).mean() - s) < Z * s * cv / np.sqrt(R)
        assert abs(seg.std(0).mean() - s * cv) < Z * s * cv / np.sqrt(2 * R)
    # both lattices correlate as exp(-5/L1) along fibre 1 (axis 0) and exp(-5/L2) along fibre 2
    for seg in (s1, s2):
        for axis, L in enumerate(lengths):
            expected = np.exp(-SPACING / L)
            assert abs(mean_pair_corr(seg, 1, axis) - expected) < Z * (1 - expected**2) / np.sqrt(R)
    # the KL version needs fewer variables and gives the same shapes
    kl = sp.kl(0.95)
    assert kl.n_variables < sp.n_variables
    t1, t2 = kl(np.zeros((3, kl.n_variables)))
    assert t1.shape == (3, 2 * n, 2 * n + 1) and np.all(t2 == s)


def test_zero_angle_input_mean_and_sd():
    za = ZeroAngleInput(5, SPACING, mean_deg=-2.3, sd_deg=5.0)
    g = za(np.random.default_rng(5).standard_normal((R, za.n_variables)))
    assert g.shape == (R, 10, 10)
    assert abs(g.mean(0).mean() + 2.3) < Z * 5.0 / np.sqrt(R)
    assert abs(g.std(0).mean() - 5.0) < Z * 5.0 / np.sqrt(2 * R)
    assert abs(mean_pair_corr(g, 1, 1)) < Z / np.sqrt(R)


@pytest.mark.parametrize("call, match", [
    (lambda: SpacingInput(4, SPACING, 1.0), r"cv .* must be in \[0, 1\)"),
    (lambda: SpacingInput(4, SPACING, -0.1), r"cv .* must be in \[0, 1\)"),
    (lambda: SpacingInput(0, SPACING, 0.01), "rings must be a positive integer"),
    (lambda: SpacingInput(4, -5.0, 0.01), "spacing_mm must be a positive number"),
    (lambda: SpacingInput(4, SPACING, 0.01)(np.zeros(7)), "trailing length n_variables=144"),
    (lambda: ZeroAngleInput(4, SPACING, 0.0, -1.0), "sd_deg >= 0"),
    (lambda: ZeroAngleInput(4, SPACING, 95.0, 1.0), r"\|mean_deg\| < 90"),
])
def test_input_bad_parameters(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_inputs_refuse_impossible_realisations():
    sp = SpacingInput(2, SPACING, 0.5)
    xi = np.zeros((3, sp.n_variables))
    xi[2, 7] = -2.5  # s = 5 (1 - 1.25) < 0 in realisation 2
    with pytest.raises(ValueError, match=r"non-positive segment length \(batch index \(2,\)\).*smaller cv"):
        sp(xi)
    za = ZeroAngleInput(2, SPACING, 0.0, 30.0)
    with pytest.raises(ValueError, match=r"\|gamma0\| >= 90"):
        za(np.full(za.n_variables, 3.1))


# ---------------------------------------------------------------- factors

def test_factor_ppf_maps():
    u = np.linspace(0.0, 1.0, 101)
    f = uniform(0.15, 0.3)
    np.testing.assert_allclose(f.ppf([0.0, 0.5, 1.0]), [0.15, 0.225, 0.3], atol=1e-9)
    assert normal(126.0, 10.0).ppf(scipy.stats.norm.cdf(1.0)) == pytest.approx(136.0)
    t = truncnormal(0.0, 2.0, -1.0, 3.0).ppf(u)
    assert np.all((t >= -1.0) & (t <= 3.0)) and np.all(np.diff(t) > 0)
    assert t[0] == pytest.approx(-1.0, abs=1e-9) and t[-1] == pytest.approx(3.0, abs=1e-9)
    assert truncnormal(1.0, 2.0, -1.0, 3.0).ppf(0.5) == pytest.approx(1.0)
    assert np.all(constant(0.2).ppf(u) == 0.2) and not constant(0.2).is_random
    assert np.all(np.isfinite(normal(0.0, 1.0).ppf([0.0, 1.0])))


def test_lognormal_median_and_mean():
    mean, sd = 0.2, 0.05
    f = lognormal(mean, sd)
    assert f.ppf(0.5) == pytest.approx(mean / np.sqrt(1 + (sd / mean) ** 2), rel=1e-12)
    x = f.ppf(sample_uniforms("latin_hypercube", 20000, 1, 6)[:, 0])
    assert abs(x.mean() - mean) < Z * sd / np.sqrt(20000)
    assert abs(x.std() - sd) < Z * sd * 3 / np.sqrt(2 * 20000)  # lognormal kurtosis widens SE(sd)
    assert x.min() > 0


@pytest.mark.parametrize("factor", [
    uniform(0.15, 0.3), normal(126.0, 12.0), truncnormal(0.0, 2.0, -1.0, 3.0), lognormal(0.2, 0.05),
])
def test_factor_salib_description_agrees_with_ppf(factor):
    u = sample_uniforms("sobol", 64, 1, 8)
    desc = factor.salib()
    theirs = scale_samples(u.copy(), {"num_vars": 1, "bounds": [desc["bounds"]], "dists": [desc["dists"]]})
    np.testing.assert_allclose(factor.ppf(u[:, 0]), theirs[:, 0], rtol=1e-10)


@pytest.mark.parametrize("call, match", [
    (lambda: normal(0.0, 0.0), "sd must be > 0"),
    (lambda: uniform(0.3, 0.15), "lower must be < upper"),
    (lambda: truncnormal(0.0, 1.0, 2.0, 2.0), "lower must be < upper"),
    (lambda: lognormal(-0.2, 0.05), "mean must be > 0"),
    (lambda: constant(float("nan")), "value must be a finite number"),
    (lambda: make_factor("beta", a=1), "dist must be one of"),
    (lambda: make_factor("uniform", lower=0.1, high=0.3), r"takes parameters \('lower', 'upper'\)"),
    (lambda: normal(0.0, 1.0).ppf([0.5, 1.2]), r"u must lie in \[0, 1\]"),
    (lambda: constant(1.0).salib(), "not random"),
])
def test_factor_bad_parameters(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_make_factor_builds_the_named_distribution():
    f = make_factor("truncnormal", mean=0.2, sd=0.05, lower=0.1, upper=0.3)
    assert f == truncnormal(0.2, 0.05, 0.1, 0.3) and f.salib()["dists"] == "truncnorm"


# ---------------------------------------------------------------- plans and seeding

@pytest.mark.parametrize("plan", ["latin_hypercube", "sobol"])
def test_plan_stratification(plan):
    n = 64
    u = sample_uniforms(plan, n, 5, 9)
    assert u.shape == (n, 5) and np.all((u > 0) & (u < 1))
    for col in u.T:  # each of the n equal strata is hit exactly once per dimension
        np.testing.assert_array_equal(np.sort(np.floor(col * n)), np.arange(n))


def test_plans_are_seeded():
    for plan in ("monte_carlo", "latin_hypercube", "sobol"):
        a, b = sample_uniforms(plan, 32, 3, 1), sample_uniforms(plan, 32, 3, 2)
        np.testing.assert_array_equal(a, sample_uniforms(plan, 32, 3, 1))
        assert not np.allclose(a, b)
    # Monte Carlo rows do not depend on the number of realisations
    np.testing.assert_array_equal(sample_uniforms("monte_carlo", 5, 3, 1),
                                  sample_uniforms("monte_carlo", 50, 3, 1)[:5])
    assert sample_uniforms("monte_carlo", 4, 0, 1).shape == (4, 0)


@pytest.mark.parametrize("args, match", [
    (("stratified", 8, 2, 1), "plan must be one of"),
    (("sobol", 100, 2, 1), r"power-of-two n .* got n=100 \(nearest: 64, 128\)"),
    (("monte_carlo", 0, 2, 1), "n .* must be >= 1"),
    (("monte_carlo", 8, 2, -3), "seed must be a non-negative integer"),
])
def test_plan_bad_parameters(args, match):
    with pytest.raises(ValueError, match=match):
        sample_uniforms(*args)


def test_uniforms_to_normals():
    np.testing.assert_allclose(uniforms_to_normals([0.5, scipy.stats.norm.cdf(1.5)]), [0.0, 1.5])


def test_realization_rng_independent_of_chunking():
    seed = 20071
    alone = realization_rng(seed, 5).standard_normal(7)
    in_loop = [realization_rng(seed, r).standard_normal(7) for r in range(10)]
    np.testing.assert_array_equal(alone, in_loop[5])
    spawned = np.random.default_rng(np.random.SeedSequence(seed).spawn(10)[5]).standard_normal(7)
    np.testing.assert_array_equal(alone, spawned)
    assert not np.allclose(in_loop[4], in_loop[5])
    # a chunk's draws equal the same rows of the whole study's draws
    whole = realization_normals(seed, range(10), [6, 3])
    chunk = realization_normals(seed, [4, 5, 6], [6, 3])
    for w, c in zip(whole, chunk):
        assert c.shape == (3, w.shape[1])
        np.testing.assert_array_equal(c, w[4:7])
    with pytest.raises(ValueError, match="r must be a non-negative integer"):
        realization_rng(seed, -1)
