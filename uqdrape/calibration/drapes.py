"""Measured drapes -> the posterior of chosen study parameters, through an emulator of the
ensemble statistics (emcee and scikit-learn; optional extra ``calibrate``).

Data: parts, each a set of measured shears (deg) at points of its max-shear lines
(``uqdrape.experimental``). Model: at parameters θ (a point of the prior box) the study's
ensemble gives, at the union of the parts' points, the shear's mean μ(θ) and sd s(θ) over
its realisations (``uqdrape.stats.shear_at_points``); space-filling training points θ are
draped (by the caller: ``uqdrape.workflow.calibrate`` runs the drapes) and
:class:`.emulator.Emulator` interpolates μ and log s between the training points, with
predictive variances v_μ and v_l.

Likelihood (decided here): the parts are independent realisations of the study; one part's
shears y are Gaussian, y ~ N(μ, D R D + diag(v_μ) + σ_m² I) over its points, where D =
diag(s) with s² = exp(2 l + 2 v_l) (the mean of s² when log s is N(l, v_l): the
emulator's error in the sd widens the likelihood rather than being ignored), R is the
correlation of the ensemble's shears between the points (pooled over the training points'
standardised residuals, shrunk by Ledoit-Wolf; taken as not depending on θ), v_μ the
emulator's variance of the mean, and σ_m the measurement's own sd. The prior is uniform
in the box. The posterior is sampled with emcee's affine-invariant ensemble.

Design (:func:`drape_posterior`): Latin-hypercube training points in the prior box, the
posterior, then a second round of half as many points drawn from that posterior, the
emulator refitted on all and the posterior sampled again.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from .emulator import Emulator, latin_hypercube
from .posterior import Posterior, run_chains

#: Smallest ensemble sd (deg) kept: a point no input moves has sd 0, whose log would be -inf.
SD_FLOOR_DEG = 1e-6
#: Training points of the emulator per calibrated parameter when ``training_points`` is not given.
TRAINING_POINTS_PER_PARAMETER = 10
#: Most training points (each an ensemble; the emulator's GPs factor an n x n matrix per
#: measured point) and drapes per training point of a calibration.
MAX_TRAINING_POINTS = 1000
MAX_REALIZATIONS = 10000


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


def union_points(parts) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The measured points of all ``parts`` (``uqdrape.experimental`` points): distance (mm),
    quadrant sign, and each part's index into them."""
    keys = sorted({(s, round(float(d), 6)) for p in parts for d, s in zip(p.distance_mm, p.quadrant_sign)})
    where = {k: n for n, k in enumerate(keys)}
    index = []
    for p in parts:
        idx = [where[(s, round(float(d), 6))] for d, s in zip(p.distance_mm, p.quadrant_sign)]
        if len(set(idx)) < len(idx):
            raise ValueError(f"{p.source}: a point is measured twice (same distance_mm and quadrant_sign); a part "
                             "gives one line of each sign")
        index.append(np.array(idx))
    sign, distance = (np.array(c, float) for c in zip(*keys))
    return distance, sign, tuple(index)


@dataclass
class DrapeCalibration:
    """A calibration from measured drapes: the parameters (``parameters.Parameter``), the
    parts, the draped training points, the likelihood (emulator inside), the posterior and
    its ``level``; the union of the measured points (mm, sign)."""

    params: list
    parts: list
    runs: TrainingRuns
    likelihood: PartsLikelihood
    posterior: object
    level: float
    distance_mm: np.ndarray
    quadrant_sign: np.ndarray

    def interval(self, param) -> tuple[float, float]:
        return self.posterior.interval(param.key, self.level)

    def unidentified(self) -> list[str]:
        """A sentence per parameter whose posterior reaches its prior bound."""
        out = []
        for p in self.params:
            ends = self.posterior.at_bounds(p.key, p.lower, p.upper)
            if ends:
                lo, hi = self.interval(p)
                out.append(f"{p.key} is not identified by the data: its posterior reaches the prior bound "
                           f"{' and '.join(f'{b:g}' for b in ends)} ({100 * self.level:g} % interval "
                           f"[{lo:.4g}, {hi:.4g}] is the prior's, not the measurements'); widen its prior box or "
                           "measure more")
        return out

    def predictive_check(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The ``level`` posterior-predictive band (lower, upper; deg) at each measured point
        and the fraction of the measured shears inside it."""
        lower, upper = predictive_bands(self.likelihood, self.posterior, self.level)
        parts = self.likelihood.parts
        inside = [(y >= lower[i]) & (y <= upper[i]) for i, y in zip(parts.index, parts.shear)]
        return lower, upper, float(np.concatenate(inside).mean())


def drape_posterior(params, parts, drape: Callable, *, training_points: int | None, measurement_sd: float,
                     level: float, seed: int, steps: int) -> DrapeCalibration:
    """The posterior of ``params`` (``parameters.Parameter``) given measured ``parts``, by
    the design of the module docstring; ``training_points`` default 10 per parameter.
    ``drape(points, seeds, distance_mm, quadrant_sign)`` drapes the study at each row of
    ``points`` (training point, parameter) with its own seed and returns the shear (deg)
    at the measured points, (training point, draw, measured point)."""
    if not 0 <= measurement_sd <= 90:
        raise ParameterError("measurement_sd", f"measurement_sd must be from 0 to 90 (deg), got {measurement_sd!r}")
    distance, sign, index = union_points(parts)
    n = TRAINING_POINTS_PER_PARAMETER * len(params) if training_points is None else training_points
    if not (isinstance(n, int) and len(params) + 2 <= n <= MAX_TRAINING_POINTS):
        raise ParameterError("training_points", f"training_points must be an integer from {len(params) + 2} to "
                             f"{MAX_TRAINING_POINTS}, got {n!r}")
    lower, upper = np.array([p.lower for p in params]), np.array([p.upper for p in params])
    keys = [p.key for p in params]
    measured = Parts(index, tuple(p.shear_deg for p in parts), measurement_sd)
    points = latin_hypercube(lower, upper, n, seed)
    runs = None
    for _ in range(2):
        done = 0 if runs is None else len(runs.points)
        shear = drape(points, seed + 1 + done + np.arange(len(points)), distance, sign)
        runs = TrainingRuns(points, shear) if runs is None else TrainingRuns(np.vstack([runs.points, points]),
                                                                             np.concatenate([runs.shear, shear]))
        mean, log_sd, var_mean, var_log_sd = runs.statistics()
        emulator = Emulator(runs.points, np.hstack([mean, log_sd]), np.hstack([var_mean, var_log_sd]), lower, upper,
                            seed=seed)
        likelihood = PartsLikelihood(emulator, runs.correlation(), measured, lower, upper)
        posterior = sample_posterior(likelihood, keys, steps=steps, seed=seed)
        # second round: half as many training points again, drawn from the first posterior, so
        # the emulator is refined where the posterior lies (its error there is what matters)
        draws = np.column_stack([posterior.samples[k] for k in keys])
        points = draws[np.random.default_rng(seed).choice(len(draws), size=max(n // 2, 2), replace=False)]
    return DrapeCalibration(params, parts, runs, likelihood, posterior, level, distance, sign)


def posterior_dataset(cal: DrapeCalibration, lower, upper):
    """The posterior sample, the draped training points, the measured parts and the
    predictive band (``lower``, ``upper``; deg) as one xarray Dataset."""
    import xarray as xr

    names = [p.key for p in cal.params]
    mean, log_sd, _, _ = cal.runs.statistics()
    measured = np.full((len(cal.parts), len(cal.distance_mm)), np.nan)
    for j, (idx, y) in enumerate(zip(cal.likelihood.parts.index, cal.likelihood.parts.shear)):
        measured[j, idx] = y
    deg = {"units": "degree"}
    return xr.Dataset(
        {"posterior": (("draw", "parameter"), np.column_stack([cal.posterior.samples[n] for n in names]),
                       {"long_name": "posterior sample (emcee), in each parameter's study units"}),
         "prior_lower": ("parameter", [p.lower for p in cal.params]),
         "prior_upper": ("parameter", [p.upper for p in cal.params]),
         "training_points": (("training_point", "parameter"), cal.runs.points),
         "training_mean": (("training_point", "point"), mean, {**deg, "long_name": "ensemble mean shear"}),
         "training_sd": (("training_point", "point"), np.exp(log_sd), {**deg, "long_name": "ensemble shear sd"}),
         "measured": (("part", "point"), measured, {**deg, "long_name": "measured shear (NaN: not measured)"}),
         "predictive_lower": ("point", lower, deg), "predictive_upper": ("point", upper, deg),
         "distance": ("point", cal.distance_mm, {"units": "mm", "long_name": "distance from the crossover"}),
         "quadrant_sign": ("point", cal.quadrant_sign)},
        coords={"parameter": names, "part": [Path(p.source).name for p in cal.parts]},
        attrs={"level": cal.level, "acceptance": cal.posterior.acceptance, "sampler_seconds": cal.posterior.seconds})
