"""Scalar process factors: a distribution that maps a standard uniform u to a value.

Each factor is a deterministic function of u ∈ [0, 1] (the inverse CDF, via scipy.stats,
imported when a factor is first evaluated: reading a study imports none of it), so Monte
Carlo, Latin hypercube, Sobol and SALib designs all drive it the same way. Values carry
the factor's own units (blank-holder force N, friction -, angles degree, offsets mm). u
is clipped to [1e-12, 1 − 1e-12] so the ends of a design stay finite (about ±7 sd for a
normal).

Parametrisations:
- ``normal(mean, sd)``;
- ``truncnormal(mean, sd, lower, upper)``: mean and sd of the parent normal, cut to
  [lower, upper];
- ``uniform(lower, upper)``;
- ``lognormal(mean, sd)``: mean and sd of the value itself (not of its logarithm), so it
  is specified like a normal but stays positive; median = mean / sqrt(1 + (sd/mean)²);
- ``constant(value)``: not random (left out of sensitivity problems).
"""

from __future__ import annotations

import functools
import inspect
import math
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..files import to_float

_EPS = 1e-12


def _finite(name: str, value) -> float:
    number = to_float(value)
    if not math.isfinite(number):
        raise ParameterError(name, f"{name} must be a finite number, got {value!r}")
    return number


def _positive(name: str, value) -> float:
    value = _finite(name, value)
    if value <= 0:
        raise ParameterError(name, f"{name} must be > 0, got {value!r}")
    return value


def _ordered(lower, upper) -> tuple[float, float]:
    lower, upper = _finite("lower", lower), _finite("upper", upper)
    if lower >= upper:
        raise ParameterError(("lower", "upper"), f"lower must be < upper, got lower={lower!r}, upper={upper!r}")
    return lower, upper


@dataclass(frozen=True)
class Factor:
    """A scalar uncertain input; build it with the functions of this module."""

    dist: str
    params: dict
    salib_dist: str | None = None
    salib_bounds: tuple | None = None

    @property
    def is_random(self) -> bool:
        return self.dist != "constant"

    @functools.cached_property
    def _rv(self):
        """The frozen scipy.stats distribution, built on first use from ``params``."""
        import scipy.stats

        p = self.params
        if self.dist == "normal":
            return scipy.stats.norm(p["mean"], p["sd"])
        if self.dist == "truncnormal":
            return scipy.stats.truncnorm((p["lower"] - p["mean"]) / p["sd"], (p["upper"] - p["mean"]) / p["sd"],
                                         loc=p["mean"], scale=p["sd"])
        if self.dist == "uniform":
            return scipy.stats.uniform(p["lower"], p["upper"] - p["lower"])
        mu, sigma = self.salib_bounds  # lognormal
        return scipy.stats.lognorm(sigma, scale=math.exp(mu))

    def ppf(self, u) -> np.ndarray:
        """Values at standard uniforms ``u`` (any shape, each in [0, 1])."""
        u = np.asarray(u, dtype=float)
        if np.any(~(u >= 0.0) | ~(u <= 1.0)):
            raise ValueError(f"u must lie in [0, 1] for factor {self.describe()}, got values outside")
        if not self.is_random:
            return np.full(u.shape, self.params["value"])
        return self._rv.ppf(np.clip(u, _EPS, 1.0 - _EPS))

    def salib(self) -> dict:
        """SALib ``{"bounds": [...], "dists": name}`` entry for this factor."""
        if not self.is_random:
            raise ValueError(f"{self.describe()} is not random and has no SALib distribution")
        return {"bounds": list(self.salib_bounds), "dists": self.salib_dist}

    def describe(self) -> str:
        p = ", ".join(f"{k}={v:g}" for k, v in self.params.items())
        return f"{self.dist}({p})"


def normal(mean, sd) -> Factor:
    mean, sd = _finite("mean", mean), _positive("sd", sd)
    return Factor("normal", {"mean": mean, "sd": sd}, "norm", (mean, sd))


def truncnormal(mean, sd, lower, upper) -> Factor:
    mean, sd = _finite("mean", mean), _positive("sd", sd)
    lower, upper = _ordered(lower, upper)
    params = {"mean": mean, "sd": sd, "lower": lower, "upper": upper}
    return Factor("truncnormal", params, "truncnorm", (lower, upper, mean, sd))


def uniform(lower, upper) -> Factor:
    lower, upper = _ordered(lower, upper)
    return Factor("uniform", {"lower": lower, "upper": upper}, "unif", (lower, upper))


def lognormal(mean, sd) -> Factor:
    mean, sd = _positive("mean", mean), _positive("sd", sd)
    sigma = math.sqrt(math.log1p((sd / mean) ** 2))
    mu = math.log(mean) - 0.5 * sigma**2
    return Factor("lognormal", {"mean": mean, "sd": sd}, "lognorm", (mu, sigma))


def constant(value) -> Factor:
    return Factor("constant", {"value": _finite("value", value)})


DISTRIBUTIONS = {f.__name__: f for f in (normal, truncnormal, uniform, lognormal, constant)}


def make_factor(dist: str, **params) -> Factor:
    """Factor from a distribution name and its parameters, e.g. ``make_factor("uniform", lower=0.15, upper=0.3)``."""
    if dist not in DISTRIBUTIONS:
        raise ValueError(f"dist must be one of {tuple(DISTRIBUTIONS)}, got {dist!r}")
    build = DISTRIBUTIONS[dist]
    expected = tuple(inspect.signature(build).parameters)
    if set(params) != set(expected):
        raise ValueError(f"dist {dist!r} takes parameters {expected}, got {tuple(params)}")
    return build(**params)
