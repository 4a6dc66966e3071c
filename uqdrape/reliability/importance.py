"""Importance sampling around a design point found by subset simulation, for P(g(U) <= 0)
with U standard normal in d dimensions, run until a target coefficient of variation.

1. Subset simulation (``subset.subset_levels``) to the failure level: its samples, from
   the standard normal to the conditional ones near the failure domain, are where g has
   been looked at.
2. The design point (the most likely failure point, FORM's beta alpha) from them without
   gradients: a linear response surface g ~ a0 + a . u, fitted by least squares to every
   distinct sample of the levels, gives the direction alpha = -a / |a|; a root search of
   g along it (``scipy.optimize.brentq`` on g(c alpha)) gives beta. The fit's R^2 is kept:
   near 1 where failure is a half-space (the design point then carries the probability).
3. Importance sampling with the density N(u*, I) (the standard normal moved to the design
   point: Au & Beck 2003 show a moved mean, not a fitted covariance, is what keeps the
   weights bounded in high dimension), in rounds: P = mean(1[g(V) <= 0] w(V)),
   w(v) = phi(v) / phi(v - u*) = exp(-u* . v + |u*|^2 / 2), its CoV the sample sd of the
   terms over sqrt(n) P, the samples being independent. The next round aims at the
   n (cov / target)^2 that 1/sqrt(n) needs, at most doubling n, until the target CoV or the
   call budget.

The estimate is the importance sampling one alone (unbiased whatever the design point;
the design point only sets its variance, and which failures it sees in practice). Two
checks decide whether the design point carries the probability, since where it does
not, the weights are so heavy-tailed that the sample CoV of a few hundred of them means
nothing (the estimate comes out low by orders of magnitude, or by the share it misses):

- the subset simulation's last-level failure samples (draws of U given failure) must lie
  on the design point's side: at most ``OPPOSITE`` of them with u . alpha <= 0, where
  N(u*, I) puts only Phi(-beta) of its samples. The exterior of a sphere (every direction
  fails at the same radius) and a failure at both signs of a factor (max |shear| under a
  skew of either sign: two design points) fail it;
- the first round's estimate must agree with the subset simulation's own, independent
  one: their log ratio within ``AGREE`` sd (from the two CoVs).

Otherwise subset simulation is run again with the samples a level that its first run's
CoV says the target needs (within the budget), and that is the estimate; ``method`` says
which.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from .subset import SubsetResult, subset_levels

#: Log ratio of the first importance round's estimate to the subset levels', in sd, past
#: which the design point is taken not to carry the probability.
AGREE = 3.0
#: Share of the subset's failure samples on the far side of the origin from the design
#: point (u . alpha <= 0) past which it is taken not to carry the probability: about the
#: relative bias of an estimate that missed them, a tenth of a 10 % CoV.
OPPOSITE = 0.01
#: Samples of the first importance-sampling round.
FIRST_ROUND = 200


@dataclass(frozen=True)
class RareResult:
    """P(g <= 0) with its CoV and the model calls it took in all (``calls``: the subset
    levels', the root search's and the importance samples'); ``method`` "importance" or
    "subset" (the estimate's); ``beta`` |u*|, ``r2`` the response surface's fit;
    ``opposite`` the share of the subset's failure samples on the far side (u . alpha <= 0);
    ``importance_calls`` the importance samples; ``subset`` the subset simulation (the
    second one where its estimate is returned)."""

    probability: float
    cov: float
    calls: int
    method: str
    beta: float
    r2: float
    opposite: float
    importance_calls: int
    subset: SubsetResult


def design_point(g, samples) -> tuple[np.ndarray, float, int]:
    """(u*, R^2, calls): the design point from the subset levels' ``samples`` [(U, g)]
    (module docstring, step 2) and the model calls its root search took."""
    U = np.concatenate([u for u, _ in samples])
    y = np.concatenate([v for _, v in samples])
    U, first = np.unique(U, axis=0, return_index=True)
    y = y[first]
    A = np.column_stack([np.ones(len(U)), U])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    r2 = 1 - np.sum((y - A @ coef) ** 2) / np.sum((y - y.mean()) ** 2)
    a0, a = coef[0], coef[1:]
    alpha = -a / np.linalg.norm(a)

    calls = []

    def along(c):
        calls.append(c)
        return float(np.asarray(g(c * alpha[None, :]), dtype=float)[0])

    # g(0) > 0 (failure is rare); bracket the root from the fitted beta, at most 8 steps
    c = max(a0 / np.linalg.norm(a), 0.5)
    low, high = 0.0, c
    for _ in range(8):
        if along(high) <= 0:
            beta = optimize.brentq(along, low, high, xtol=1e-3)
            return beta * alpha, float(r2), len(calls)
        low, high = high, 1.5 * high
    return c * alpha, float(r2), len(calls)  # no root along alpha: the fitted point; sampling stays unbiased


def agree(p: float, delta: float, sus: SubsetResult) -> bool:
    """Whether an importance estimate ``p`` (CoV ``delta``) agrees with the subset
    simulation's: |ln(p / P_sus)| within AGREE sd of the log-normal approximations."""
    if not (p > 0 and math.isfinite(delta)):
        return False
    sd = math.sqrt(math.log1p(delta**2) + math.log1p(sus.cov**2))
    return abs(math.log(p / sus.probability)) <= AGREE * sd


def importance_sampling(g, d: int, *, seed: int, cov: float = 0.1, max_calls: int = 100_000,
                        n_per_level: int = 500, p0: float = 0.1, max_levels: int = 30) -> RareResult:
    """P(g(U) <= 0), U ~ N(0, I_d), to coefficient of variation ``cov`` or ``max_calls``
    model calls in all (the module docstring); the subset levels have ``n_per_level``
    samples and conditional probability ``p0``. ValueError if subset simulation reaches no
    failure in ``max_levels``."""
    rng = np.random.default_rng(seed)
    sus, samples = subset_levels(g, d, n_per_level=n_per_level, p0=p0, rng=rng, spread=1.0, max_levels=max_levels)
    u_star, r2, search = design_point(g, samples)
    spent = sus.calls + search
    beta = float(np.linalg.norm(u_star))
    u_last, y_last = samples[-1]
    opposite = float(np.mean(u_last[y_last <= 0] @ u_star <= 0))

    def subset_again(importance_calls: int) -> RareResult:
        used = spent + importance_calls
        n = n_per_level * max(1, math.ceil((sus.cov / cov) ** 2))
        n = min(n, max(n_per_level, round((max_calls - used) / (1 + (len(sus.thresholds) - 1) * (1 - p0)))))
        n -= n % round(1 / p0)
        again = subset_levels(g, d, n_per_level=n, p0=p0, rng=rng, spread=1.0, max_levels=max_levels)[0]
        return RareResult(again.probability, again.cov, used + again.calls, "subset", beta, r2, opposite,
                          importance_calls, again)

    if opposite > OPPOSITE:
        return subset_again(0)
    terms = np.empty(0)
    n = FIRST_ROUND
    while True:
        take = max(min(n - terms.size, max_calls - spent - terms.size), 0)
        v = u_star + rng.standard_normal((take, d))
        fails = np.asarray(g(v), dtype=float) <= 0 if take else np.zeros(0, bool)
        weights = np.exp(-v @ u_star + beta**2 / 2)
        terms = np.concatenate([terms, np.where(fails, weights, 0.0)])
        p = float(terms.mean()) if terms.size else 0.0
        delta = float(terms.std(ddof=1) / math.sqrt(terms.size) / p) if p > 0 else math.inf
        if terms.size == FIRST_ROUND and not agree(p, delta, sus):
            return subset_again(terms.size)
        if delta <= cov or take == 0 or spent + terms.size >= max_calls:
            return RareResult(p, delta, spent + terms.size, "importance", beta, r2, opposite, int(terms.size), sus)
        n = min(max(math.ceil(terms.size * (delta / cov) ** 2), terms.size + FIRST_ROUND), 2 * terms.size)
