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

import importlib
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


    def at_bounds(self, name: str, lower: float, upper: float, *, log: bool = False) -> list[float]:
        """The bounds of the prior range [lower, upper] (uniform in ``name``, or in its log
        with ``log``) that the draws pile against: more than ``EDGE_SHARE`` of them within
        ``EDGE`` of the range's width from it. A posterior that the data bound has next to no
        draws there; one that does, would reach further with a wider prior: the data do not
        identify the parameter and its interval is the prior's."""
        x, lo, hi = self.samples[name], lower, upper
        if log:
            x, lo, hi = np.log(x), math.log(lo), math.log(hi)
        t = (x - lo) / (hi - lo)
        return [b for b, share in ((lower, np.mean(t < EDGE)), (upper, np.mean(t > 1 - EDGE))) if share > EDGE_SHARE]


#: See :meth:`Posterior.at_bounds`: the outer share of a prior range, and the share of the
#: draws there that marks a parameter as not identified.
EDGE, EDGE_SHARE = 0.05, 0.01


class MissingExtraError(ImportError, ValueError):
    """A package of the optional extra ``calibrate`` is not installed (a ValueError too, so
    the command line says it in one line)."""


def extra(module: str, needs: str):
    """The module ``module`` of the optional extra ``calibrate``; MissingExtraError saying
    what ``needs`` it (e.g. "a posterior sample needs emcee") where it is not installed."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(f"{needs}, the optional extra: pip install 'uqdrape[calibrate]'") from None


def prior_box(field_fit) -> dict:
    """The prior's range of each sampled parameter (name -> (lower, upper), deg or mm):
    the fit's search box (:func:`.fit.bounds`), the prior flat in the logs inside it."""
    like = field_fit.likelihood
    box = bounds(like, float(np.std(like.y, ddof=1)))
    return {_NAMES[n]: (math.exp(lo), math.exp(hi)) for n, (lo, hi) in zip(parameter_names(like.family), box)}


def posterior_sample(field_fit, *, walkers: int = 16, steps: int = 1500, burn: int = 300,
                     seed: int = 0) -> Posterior:
    """Sample the chosen family's parameters of ``field_fit`` (see the module docstring)."""
    like = field_fit.likelihood
    theta0 = np.asarray(field_fit.chosen.theta, dtype=float)
    ndim = theta0.size
    walkers = max(int(walkers), 2 * ndim + 2)
    if not 0 <= burn < steps:
        raise ValueError(f"burn must be in [0, steps), got burn={burn!r}, steps={steps!r}")
    box = np.log(np.array(list(prior_box(field_fit).values())))

    def log_post(theta):
        if np.any(theta <= box[:, 0]) or np.any(theta >= box[:, 1]):
            return -np.inf
        value = like(theta, gradient=False)[0]
        return value if np.isfinite(value) else -np.inf

    rng = np.random.default_rng(seed)
    start = theta0 + 1e-3 * rng.standard_normal((walkers, ndim))
    start = np.clip(start, box[:, 0] + 1e-9, box[:, 1] - 1e-9)
    names = list(prior_box(field_fit))
    post = run_chains(log_post, start, names, steps=steps, burn=burn, rng=rng)
    return Posterior({n: np.exp(v) for n, v in post.samples.items()}, post.acceptance, post.autocorrelation,
                     post.seconds)


def run_chains(log_post, start, names, *, steps: int, burn: int, rng, vectorize: bool = False) -> Posterior:
    """emcee's affine-invariant ensemble from ``start`` (walker, parameter), ``burn`` of
    ``steps`` steps dropped; the sample of θ under ``names``, reproducible from ``rng``."""
    emcee = extra("emcee", "a posterior sample needs emcee")
    clock = time.perf_counter()
    sampler = emcee.EnsembleSampler(len(start), start.shape[1], log_post, vectorize=vectorize)
    sampler.random_state = np.random.RandomState(int(rng.integers(2 ** 31))).get_state()  # reproducible
    sampler.run_mcmc(start, steps, progress=False)
    seconds = time.perf_counter() - clock
    chain = sampler.get_chain(discard=burn, flat=True)
    quiet = logging.getLogger("emcee")
    level, quiet.level = quiet.level, logging.ERROR  # a short chain's warning: the times are reported as they are
    try:
        tau = sampler.get_autocorr_time(discard=burn, quiet=True) if steps - burn >= 50 else [math.nan] * len(names)
    finally:
        quiet.level = level
    return Posterior({n: chain[:, k] for k, n in enumerate(names)}, float(np.mean(sampler.acceptance_fraction)),
                     {n: float(t) for n, t in zip(names, tau)}, seconds)
