"""Analytic limit states g(U) of standard normal U (failure: g <= 0) with known P, to check
a rare-event estimator in high dimension."""

from __future__ import annotations

import numpy as np
from scipy import integrate, optimize, stats
from scipy.special import ndtr


def _check(d, p):
    if isinstance(d, bool) or not isinstance(d, (int, np.integer)) or d < 1:
        raise ValueError(f"d must be an integer >= 1, got {d!r}")
    if not 0 < p < 0.5:
        raise ValueError(f"p must lie in (0, 0.5), got {p!r}")


def linear_limit_state(d: int, p: float):
    """(g, P) of the hyperplane g(u) = beta - sum(u) / sqrt(d) with beta = -Phi^-1(p):
    sum(u) / sqrt(d) is standard normal, so P(g <= 0) = Phi(-beta) = p exactly."""
    _check(d, p)
    beta = -stats.norm.ppf(p)

    def g(u):
        return beta - np.asarray(u).sum(axis=-1) / np.sqrt(d)

    return g, float(stats.norm.cdf(-beta))


def sphere_limit_state(d: int, p: float):
    """(g, P) of the exterior of a sphere, g(u) = r^2 - |u|^2 with r^2 the chi-square (d dof)
    upper p-quantile: P(|U|^2 >= r^2) = p exactly. Every direction fails at the same radius,
    the hard case for methods that look for one most probable point."""
    _check(d, p)
    r2 = stats.chi2.isf(p, d)

    def g(u):
        return r2 - np.square(np.asarray(u)).sum(axis=-1)

    return g, float(stats.chi2.sf(r2, d))


def bounded_limit_state(d: int, p: float, sigma: float = 0.05):
    """(g, P, features) of failure x + sigma z >= t: x = Phi(u_0) a standard uniform (a
    bounded factor, as a friction U[a, b] is in a study), z = sum(u_1..u_{d-1}) / sqrt(d - 1)
    a standard normal (a field's noise), t such that P = int_0^1 Phi((x - t) / sigma) dx = p
    (to 1e-12). Phi(u_0) saturates, so the failure surface curves in U and a response
    surface linear in U puts its most probable point far out; ``features`` maps U to the factor's
    own value (column 0 to Phi(u_0)), where g is linear."""
    _check(d, p)
    if d < 2:
        raise ValueError(f"d must be >= 2 (a factor and the noise), got {d!r}")

    def prob(t):
        return integrate.quad(lambda x: ndtr((x - t) / sigma), 0, 1, epsabs=1e-15)[0]

    t = optimize.brentq(lambda t: prob(t) - p, 0.0, 1.0 + 10 * sigma, xtol=1e-14)

    def g(u):
        u = np.asarray(u)
        return t - ndtr(u[..., 0]) - sigma * u[..., 1:].sum(axis=-1) / np.sqrt(d - 1)

    def features(u):
        x = np.array(u, dtype=float)
        x[..., 0] = ndtr(x[..., 0])
        return x

    return g, prob(t), features
