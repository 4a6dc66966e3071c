"""Subset simulation (Au & Beck 2001, Probabilistic Engineering Mechanics 16: 263-277) of
P(g(U) <= 0) for U standard normal in d dimensions.

Level 0 draws N samples of U. Each level then sets the threshold b_j so that a fraction
p0 of its samples have g <= b_j (b_j between the p0 N-th and the next smallest g), and
grows 1 / p0 states of a Markov chain from each of those p0 N samples, conditional on
g <= b_j, by the *modified Metropolis* algorithm: every component proposes a Gaussian
step of sd ``spread`` and takes it with probability min(1, phi(new) / phi(old)), and the
moved point is kept only if it stays in g <= b_j. The last level has b <= 0 and counts
its own share of failures, so P = p0^(m) x P(g <= 0 | level m).

The spread is fixed within a level (so its chains keep the conditional distribution)
and adapted between levels toward the acceptance rate ACCEPTANCE (30-50 % is what Zuev
et al. 2012 recommend). The coefficient of variation is Au & Beck's: per level
delta_j^2 = (1 - p_j) / (p_j N) (1 + gamma_j), gamma_j from the correlation of the
level's indicator along its chains (0 for level 0's independent samples), summed over
the levels (their estimates' correlation neglected, as Au & Beck do).

``g`` takes a batch of points (n, d) and returns (n,) values: each chain step is one call
for all chains at once, so a drape limit state drapes a batch per call. ``calls`` counts
the points evaluated (a proposal that moves no component is not evaluated).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Target acceptance rate of the moved points (Zuev et al. 2012: 30-50 %).
ACCEPTANCE = 0.4


@dataclass(frozen=True)
class SubsetResult:
    """P(g <= 0), its estimated coefficient of variation, the points evaluated, and per
    level the threshold b_j (the last is 0), the conditional probability, gamma_j and the
    acceptance rate of its chains (NaN for level 0)."""

    probability: float
    cov: float
    calls: int
    thresholds: tuple[float, ...]
    level_probabilities: tuple[float, ...]
    gammas: tuple[float, ...]
    acceptance: tuple[float, ...]

    @property
    def reached(self) -> bool:
        """Whether the levels reached the failure domain (else ``probability`` is the
        estimate of P(g <= the last threshold), above P: the budget or the levels ran out)."""
        return self.thresholds[-1] == 0.0


def chain_gamma(indicator: np.ndarray) -> float:
    """Au & Beck's gamma (their Eqs 27-29) of a level's failure indicator (chain length Ns,
    chains Nc): 2 sum_k (1 - k / Ns) rho(k), rho the indicator's autocorrelation along the
    chains at lag k, estimated over all chains."""
    I = np.asarray(indicator, dtype=float)
    Ns, Nc = I.shape
    p = I.mean()
    r0 = p * (1 - p)
    if Ns == 1 or r0 == 0:
        return 0.0
    lags = np.arange(1, Ns)
    r = np.array([(I[:-k] * I[k:]).sum() / (Nc * (Ns - k)) for k in lags]) - p**2
    return float(2 * np.sum((1 - lags / Ns) * r / r0))


def _threshold(y: np.ndarray, n_seeds: int) -> float:
    """The level's threshold: midway between its n_seeds-th smallest g and the next."""
    part = np.partition(y, (n_seeds - 1, n_seeds))
    return float((part[n_seeds - 1] + part[n_seeds]) / 2)


def subset_simulation(g, d: int, *, n_per_level: int = 1000, p0: float = 0.1, seed: int, spread: float = 1.0,
                      max_levels: int = 30) -> SubsetResult:
    """P(g(U) <= 0), U ~ N(0, I_d), by subset simulation with ``n_per_level`` samples a
    level and conditional probability ``p0`` (p0 N and 1 / p0 integers); ``spread`` the
    first level's proposal sd. ValueError if failure is not reached in ``max_levels``."""
    result = subset_levels(g, d, n_per_level=n_per_level, p0=p0, rng=np.random.default_rng(seed), spread=spread,
                           max_levels=max_levels)[0]
    if not result.reached:
        raise ValueError(f"subset simulation reached no failure (g <= 0) in {max_levels} levels of p0 = {p0}: "
                         f"P < {p0 ** max_levels:.1e} or g has no failure domain")
    return result


def subset_levels(g, d: int, *, n_per_level: int, p0: float, rng, spread: float, max_levels: int,
                  max_calls: float = np.inf) -> tuple[SubsetResult, list[tuple[np.ndarray, np.ndarray]]]:
    """:func:`subset_simulation` drawing from ``rng``, also returning each level's samples
    and their g values, [(U (N, d), g (N,)), ...] (a chain's repeated states included).
    It stops before a level whose chains could take it past ``max_calls`` points, and
    after ``max_levels``: the result's ``reached`` is then False."""
    n = int(n_per_level)
    n_seeds, chain = round(p0 * n), round(1 / p0)
    if n_seeds < 1 or n_seeds * chain != n or abs(n_seeds - p0 * n) > 1e-9:
        raise ValueError(f"p0 * n_per_level and 1 / p0 must be whole numbers, got p0={p0}, n_per_level={n}")
    u = rng.standard_normal((n, d))
    y = np.asarray(g(u), dtype=float)
    calls, indicator_shape = n, (n, 1)  # level 0: n independent "chains" of one state
    probability, cov2 = 1.0, 0.0
    thresholds, levels, gammas, rates, samples = [], [], [], [np.nan], []
    for level in range(max_levels):
        samples.append((u, y))
        b = max(_threshold(y, n_seeds), 0.0)
        inside = (y <= b).reshape(indicator_shape)
        p = float(inside.mean())
        gamma = chain_gamma(inside.T if indicator_shape == (n, 1) else inside)
        probability *= p
        cov2 += (1 - p) / (p * n) * (1 + gamma)
        thresholds.append(b)
        levels.append(p)
        gammas.append(gamma)
        if b == 0.0 or level == max_levels - 1 or calls + (chain - 1) * n_seeds > max_calls:
            break  # failure reached, or no level left (then P(g <= b) is above P)
        seeds = np.argsort(y)[:n_seeds]
        x, yx = u[seeds].copy(), y[seeds].copy()
        states, values, accepted, moved_total = [x.copy()], [yx.copy()], 0, 0
        for _ in range(chain - 1):
            step = x + spread * rng.standard_normal(x.shape)
            take = rng.random(x.shape) < np.exp(-0.5 * (step**2 - x**2))
            candidate = np.where(take, step, x)
            moved = np.flatnonzero(take.any(axis=1))
            if moved.size:
                yc = np.asarray(g(candidate[moved]), dtype=float)
                calls += moved.size
                keep = moved[yc <= b]
                x[keep], yx[keep] = candidate[keep], yc[yc <= b]
                accepted += keep.size
                moved_total += moved.size
            states.append(x.copy())
            values.append(yx.copy())
        rate = accepted / max(moved_total, 1)
        rates.append(rate)
        spread = float(np.clip(spread * np.exp(rate - ACCEPTANCE), 0.05, 3.0))
        u = np.concatenate(states)  # (chain x n_seeds, d), state l of chain c at row l n_seeds + c
        y = np.concatenate(values)
        indicator_shape = (chain, n_seeds)
    return SubsetResult(probability, float(np.sqrt(cov2)), calls, tuple(thresholds), tuple(levels), tuple(gammas),
                        tuple(rates[:len(levels)])), samples
