"""Analytic limit states g(U) of standard normal U (failure: g <= 0) with known P, to check
a rare-event estimator in high dimension."""

from __future__ import annotations

import numpy as np
from scipy import stats


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
    the hard case for methods that look for one design point."""
    _check(d, p)
    r2 = stats.chi2.isf(p, d)

    def g(u):
        return r2 - np.square(np.asarray(u)).sum(axis=-1)

    return g, float(stats.chi2.sf(r2, d))
