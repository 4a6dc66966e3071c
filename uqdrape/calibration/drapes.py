"""Measured drapes -> the posterior of chosen study parameters, through an emulator of the
ensemble statistics (emcee and scikit-learn; optional extra ``calibrate``).

Data: parts, each a set of measured shears (deg) at points of its max-shear lines
(``uqdrape.experimental``). Model: at parameters θ (a point of the prior box) the study's
ensemble gives, at the union of the parts' points, the shear's mean μ(θ) and sd s(θ) over
its realisations (``uqdrape.stats.shear_at_points``); space-filling training points θ are
draped (``uqdrape.workflow.calibrate``) and :class:`.emulator.Emulator` interpolates μ and
log s between the training points, with predictive variances v_μ and v_l.

Likelihood (decided here): the parts are independent realisations of the study; one part's
shears y are Gaussian, y ~ N(μ, D R D + diag(v_μ) + σ_m² I) over its points, where D =
diag(s) with s² = exp(2 l + 2 v_l) (the mean of s² when log s is N(l, v_l): the
emulator's error in the sd widens the likelihood rather than being ignored), R is the
correlation of the ensemble's shears between the points (pooled over the training points'
standardised residuals, shrunk by Ledoit-Wolf; taken as not depending on θ), v_μ the
emulator's variance of the mean, and σ_m the measurement's own sd. The prior is uniform
in the box. The posterior is sampled with emcee's affine-invariant ensemble.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .emulator import Emulator
from .posterior import Posterior, run_chains

#: Smallest ensemble sd (deg) kept: a point no input moves has sd 0, whose log would be -inf.
SD_FLOOR_DEG = 1e-6


@dataclass(frozen=True)
class TrainingRuns:
    """The draped training points: ``points`` (training point, parameter), ``shear`` (training point,
    draw, measured point) in deg, the draws being ``copies`` line copies of each
    realisation (``uqdrape.stats.shear_at_points``)."""

    points: np.ndarray
    shear: np.ndarray
    copies: int = 2

    def statistics(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per training point and measured point: mean, log sd and their Monte Carlo variances
        (as of one draw per realisation: a realisation's copies share its ring turns)."""
        n = np.isfinite(self.shear).sum(axis=1) / self.copies
        if (n < 2).any():
            raise ValueError("a training point has fewer than 2 realisations reaching a measured point: the points lie "
                             "beyond the study's net (more rings, or nearer points)")
        mean = np.nanmean(self.shear, axis=1)
        sd = np.maximum(np.nanstd(self.shear, axis=1, ddof=1), SD_FLOOR_DEG)
        return mean, np.log(sd), sd ** 2 / n, 1.0 / (2.0 * np.maximum(n - 1, 1))

    def correlation(self) -> np.ndarray:
        """The pooled correlation of the shears between measured points (Ledoit-Wolf)."""
        from sklearn.covariance import LedoitWolf

        mean, log_sd, _, _ = self.statistics()
        z = (self.shear - mean[:, None, :]) / np.exp(log_sd)[:, None, :]
        z = z.reshape(-1, z.shape[-1])
        z = z[np.isfinite(z).all(axis=1)]
        cov = LedoitWolf(assume_centered=True).fit(z).covariance_
        d = np.sqrt(np.diag(cov))
        return cov / np.outer(d, d)


@dataclass(frozen=True)
class Parts:
    """Measured parts: ``index[j]`` the measured points (into the union) of part j,
    ``shear[j]`` its shears (deg); ``measurement_sd`` σ_m (deg)."""

    index: tuple
    shear: tuple
    measurement_sd: float


class PartsLikelihood:
    """The log posterior of the module docstring, vectorised over rows of θ."""

    def __init__(self, emulator: Emulator, correlation: np.ndarray, parts: Parts, lower, upper):
        self.emulator, self.correlation, self.parts = emulator, correlation, parts
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.n_points = correlation.shape[0]

    def moments(self, theta) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Emulated mean μ, sd s (with the emulator's log-sd variance folded in) and the
        emulator's variance of μ at rows of θ, each (row, measured point)."""
        mean, var = self.emulator.predict(theta)
        p = self.n_points
        return mean[:, :p], np.exp(mean[:, p:] + var[:, p:]), var[:, :p]

    def __call__(self, theta) -> np.ndarray:
        theta = np.atleast_2d(theta)
        out = np.full(len(theta), -np.inf)
        inside = np.all((theta > self.lower) & (theta < self.upper), axis=1)
        if not inside.any():
            return out
        mu, sd, v_mu = self.moments(theta[inside])
        total = np.zeros(len(mu))
        m2 = self.parts.measurement_sd ** 2
        for idx, y in zip(self.parts.index, self.parts.shear):
            s = sd[:, idx]
            cov = self.correlation[np.ix_(idx, idx)] * s[:, :, None] * s[:, None, :]
            cov[:, np.arange(len(idx)), np.arange(len(idx))] += v_mu[:, idx] + m2
            chol = np.linalg.cholesky(cov)
            z = np.linalg.solve(chol, (y - mu[:, idx])[..., None])[..., 0]
            total += -0.5 * ((z ** 2).sum(axis=1) + len(idx) * np.log(2 * np.pi)) \
                - np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1)
        out[inside] = total
        return out


def sample_posterior(likelihood: PartsLikelihood, names, *, walkers: int = 24, steps: int = 1500, burn: int = 500,
                     seed: int = 0) -> Posterior:
    """An emcee sample of θ (names as given), walkers started uniformly in the box."""
    lower, upper = likelihood.lower, likelihood.upper
    walkers = max(int(walkers), 2 * lower.size + 2)
    rng = np.random.default_rng(seed)
    start = lower + (upper - lower) * rng.uniform(0.02, 0.98, (walkers, lower.size))
    return run_chains(likelihood, start, list(names), steps=steps, burn=burn, rng=rng, vectorize=True)


def predictive_bands(likelihood: PartsLikelihood, posterior: Posterior, level: float, *, draws: int = 400,
                     seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The posterior-predictive ``level`` band (lower, upper; deg) of a new part's shear at
    each measured point: θ from the sample, then the shear from the likelihood's Gaussian."""
    rng = np.random.default_rng(seed)
    theta = np.column_stack(list(posterior.samples.values()))
    theta = theta[rng.integers(len(theta), size=draws)]
    mu, sd, v_mu = likelihood.moments(theta)
    spread = np.sqrt(sd ** 2 + v_mu + likelihood.parts.measurement_sd ** 2)
    y = mu + spread * rng.standard_normal(mu.shape)
    alpha = 1.0 - level
    return np.quantile(y, alpha / 2, axis=0), np.quantile(y, 1 - alpha / 2, axis=0)
