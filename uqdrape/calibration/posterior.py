"""A posterior sample of the field parameters by MCMC (emcee; optional extra ``calibrate``).

The target is the restricted likelihood of :mod:`.likelihood` (the mean integrated out
under a flat prior) times a prior flat in θ = (log σ, log L1, log L2, log τ) inside the
fit's search box (:func:`.fit.bounds`): scale-free, p(σ) ∝ 1/σ. For iid values σ² is then
exactly a scaled inverse χ²_{n−1} around the sample variance, so its equal-tailed
interval is the chi-square interval the profile gives (tested on Table 5.1); for a
correlated field the two differ where the likelihood is not yet quadratic.

Sampler: emcee's affine-invariant ensemble, ``walkers`` started in a small ball around
the maximum, ``burn`` steps dropped, the rest kept (``steps`` per walker). The sample is
in natural units (deg, mm) under the names of :attr:`.fit.FieldFit.estimates`.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from .fit import bounds
from .likelihood import parameter_names

#: The names of the sampled parameters by θ entry (natural units: exp θ).
_NAMES = {"sd": "sd_deg", "length_1": "length_1_mm", "length_2": "length_2_mm", "nugget": "nugget_deg"}


@dataclass(frozen=True)
class Posterior:
    """A posterior sample: ``samples[name]`` (deg or mm), emcee's mean acceptance
    fraction, the integrated autocorrelation time per parameter (steps; NaN where the
    chain is too short to tell) and the wall time (s)."""

    samples: dict
    acceptance: float
    autocorrelation: dict
    seconds: float

    def interval(self, name: str, level: float) -> tuple[float, float]:
        """The equal-tailed ``level`` interval of ``name``."""
        alpha = 1.0 - level
        lo, hi = np.quantile(self.samples[name], [alpha / 2, 1.0 - alpha / 2])
        return float(lo), float(hi)


class MissingExtraError(ImportError, ValueError):
    """emcee is not installed (a ValueError too, so the command line says it in one line)."""


def _emcee():
    try:
        import emcee
    except ImportError:
        raise MissingExtraError("a posterior sample needs emcee, the optional extra: pip install 'uqdrape[calibrate]'") \
            from None
    return emcee


def posterior_sample(field_fit, *, walkers: int = 16, steps: int = 1500, burn: int = 300,
                     seed: int = 0) -> Posterior:
    """Sample the chosen family's parameters of ``field_fit`` (see the module docstring)."""
    emcee = _emcee()
    like = field_fit.likelihood
    theta0 = np.asarray(field_fit.chosen.theta, dtype=float)
    ndim = theta0.size
    walkers = max(int(walkers), 2 * ndim + 2)
    if not 0 <= burn < steps:
        raise ValueError(f"burn must be in [0, steps), got burn={burn!r}, steps={steps!r}")
    box = np.array(bounds(like, float(np.std(like.y, ddof=1))))

    def log_post(theta):
        if np.any(theta <= box[:, 0]) or np.any(theta >= box[:, 1]):
            return -np.inf
        value = like(theta, gradient=False)[0]
        return value if np.isfinite(value) else -np.inf

    rng = np.random.default_rng(seed)
    start = theta0 + 1e-3 * rng.standard_normal((walkers, ndim))
    start = np.clip(start, box[:, 0] + 1e-9, box[:, 1] - 1e-9)
    clock = time.perf_counter()
    sampler = emcee.EnsembleSampler(walkers, ndim, log_post)
    sampler.random_state = np.random.RandomState(int(rng.integers(2 ** 31))).get_state()  # reproducible
    sampler.run_mcmc(start, steps, progress=False)
    seconds = time.perf_counter() - clock
    chain = sampler.get_chain(discard=burn, flat=True)
    names = [_NAMES[n] for n in parameter_names(like.family)]
    quiet = logging.getLogger("emcee")
    level, quiet.level = quiet.level, logging.ERROR  # a short chain's warning: the times are reported as they are
    try:
        tau = sampler.get_autocorr_time(discard=burn, quiet=True) if steps - burn >= 50 else [math.nan] * ndim
    finally:
        quiet.level = level
    return Posterior({n: np.exp(chain[:, k]) for k, n in enumerate(names)},
                     float(np.mean(sampler.acceptance_fraction)),
                     {n: float(t) for n, t in zip(names, tau)}, seconds)
