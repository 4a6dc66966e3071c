"""P(g(U) <= 0) with U standard normal in d dimensions, to a target coefficient of
variation within a hard budget of model calls: importance sampling around a most probable point
found by subset simulation where that point carries the probability, subset simulation
in independent rounds where it does not, plain Monte Carlo where failure is not rare.

1. Pilot: subset simulation (``subset.subset_levels``) at ``n_per_level`` samples a
   level, stopped before a level that could pass the budget. Its samples, from the
   standard normal to the conditional ones near the failure domain, are where g has been
   looked at. Two outcomes end here:

   - no failure reached (the levels or the budget ran out): ``method = "below"`` and the
     probability is an upper bound, the smaller of the 95 % one-sided bound
     -ln(0.05) / N of level 0's N independent samples (none of which failed) and the
     levels' estimate of P(g <= their last threshold);
   - failure reached at level 0 (P of the order of p0 or more: not rare):
     ``method = "montecarlo"``, level 0's independent samples and more of them until the
     binomial CoV sqrt((1 - P) / (P n)) meets the target; P = 1 (CoV 0) where every one
     failed.

2. The most probable point u* (the most likely failure point, FORM's beta alpha) from the pilot's
   samples without gradients: a linear response surface g ~ a0 + a . u, fitted by least
   squares to every distinct sample, gives the direction alpha = -a / |a|; a root search
   of g along it (``scipy.optimize.brentq`` on g(c alpha)) gives beta. The fit's R^2 is
   kept (near 1 where failure is a half-space). With more columns than the pilot can fit
   (a random field's thousand modes: the surface interpolates, R^2 1) and beta refused
   by the check below, a second surface is fitted on the columns that correlate with g,
   the rest one noise term (:func:`screened_point`), and its point is checked instead.
3. Importance sampling with the density N(u*, I) (Au & Beck 2003: a moved mean, not a
   fitted covariance, keeps the weights bounded in high dimension), in rounds:
   P = mean(1[g(V) <= 0] w(V)), w(v) = phi(v) / phi(v - u*) = exp(-u* . v + |u*|^2 / 2),
   its CoV the sample sd of the independent terms over sqrt(n) P. The next round aims at
   the n (cov / target)^2 that 1/sqrt(n) needs, at most doubling n.

The importance estimate is unbiased whatever the most probable point, but where the point does
not carry the probability the weights are so heavy-tailed that the sample CoV of a few
hundred of them means nothing. Four checks decide that it does:

- the pilot's last-level failure samples (draws of U given failure) lie on the most probable
  point's side: at most ``OPPOSITE`` of them with u . alpha <= 0 (a sphere's exterior,
  or failure at both signs of a factor, fail it);
- beta agrees with the pilot's generalised index Phi^-1(1 - P_sus): within ``BETA_GAP``
  plus ``AGREE`` sd of the latter (a curved failure surface, e.g. a bounded factor's
  Phi(u) saturating, puts the linear fit's point far out);
- the first round's estimate agrees with the pilot's independent one: their log ratio
  within ``AGREE`` sd;
- each further round's CoV falls below the previous one's (heavy weights do not).

Otherwise subset simulation runs again in ``ROUNDS`` independent rounds, each sized so
that their mean meets the target (within the budget), and more rounds of that size while
the budget allows one and the rounds' CoV is above the target; their mean is the estimate
(``method = "subset"``). Its CoV is the larger of the rounds' spread, sd / (sqrt(R) P),
true whatever the correlation of the chains and levels, and Au & Beck's formula (which
leaves that correlation out). A result's ``note`` says why its CoV is above the target.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize
from scipy.special import ndtri

from .subset import SubsetResult, subset_levels

#: Log ratio of the first importance-sampling round's estimate to the pilot's, in sd (and
#: sd of the pilot's generalised index in the beta check), past which the most probable point is
#: taken not to carry the probability.
AGREE = 3.0
#: Share of the pilot's failure samples on the far side of the origin from the most
#: probable point (u . alpha <= 0) past which it is taken not to carry the probability: about the
#: relative bias of an estimate that missed them, a tenth of a 10 % CoV.
OPPOSITE = 0.01
#: |beta - Phi^-1(1 - P_sus)| allowed beyond the pilot's own scatter: FORM's index of a
#: moderately curved surface differs by a few tenths; more puts the point out of place.
BETA_GAP = 0.5
#: A response surface takes at most one column per SCREEN pilot samples before the
#: screened one is tried; that one keeps the columns whose correlation with g over
#: level 0's n independent samples passes SCREENED / sqrt(n) (3.5 sd of a zero one).
SCREEN, SCREENED = 4, 3.5
#: Samples of the first importance-sampling round.
FIRST_ROUND = 200
#: Independent subset-simulation rounds where no most probable point carries the probability,
#: and the least samples a level that one may have.
ROUNDS, LEAST_LEVEL = 5, 100
#: Model calls the most probable point's root search may take at most (the origin, 9 bracket
#: steps, brentq's ends and SEARCH - 12 iterations): kept back from the pilot's budget.
SEARCH = 40
#: Failures in none of N independent samples: P < -ln(1 - 0.95) / N with 95 % confidence.
NONE_SEEN = -math.log(0.05)


@dataclass(frozen=True)
class RareResult:
    """P(g <= 0) with its CoV and the model calls it took in all (``calls``: the pilot's,
    the root search's, the importance samples' and the rounds'); ``method`` "importance",
    "subset", "montecarlo" (failure not rare) or "below" (no failure reached:
    ``probability`` is an upper bound, ``cov`` 0); ``beta`` |u*| and ``r2`` the response
    surface's fit (NaN where no most probable point was sought); ``opposite`` the share of the
    pilot's failure samples on the far side (u . alpha <= 0); ``importance_calls`` the
    importance samples; ``subset`` the pilot subset simulation; ``note`` why the CoV is
    above the target or the result is a bound ("" when it is neither)."""

    probability: float
    cov: float
    calls: int
    method: str
    beta: float
    r2: float
    opposite: float
    importance_calls: int
    subset: SubsetResult
    note: str = ""


def most_probable_point(g, samples, features=None) -> tuple[np.ndarray | None, float, int]:
    """(u*, R^2, calls): the most probable failure point (FORM's design point) from the
    pilot's ``samples`` [(U, g)] (module docstring, step 2) and the model calls its root
    search took; u* the surface's own point
    where g has no root along its direction within 8 steps out, None where g(0) <= 0.
    ``features`` maps each column of U on its own (e.g. a bounded factor's u to its own
    value); the response surface is linear in them (default: in U)."""
    U = np.concatenate([u for u, _ in samples])
    y = np.concatenate([v for _, v in samples])
    U, first = np.unique(U, axis=0, return_index=True)
    y = y[first]
    coef, r2 = _fit(U if features is None else features(U), y)
    u_fit = surface_point(coef[0], coef[1:], features, U.shape[1])
    c = max(float(np.linalg.norm(u_fit)), 0.5)
    alpha = u_fit / np.linalg.norm(u_fit)

    calls = []

    def along(c):
        calls.append(c)
        return float(np.asarray(g(c * alpha[None, :]), dtype=float)[0])

    # bracket the root from the surface's beta, at most 8 steps out; g(0) > 0 (failure is
    # rare where this is called), but the origin is not assumed safe
    low, high = 0.0, c
    if along(low) <= 0:
        return None, float(r2), len(calls)
    for _ in range(8):
        if along(high) <= 0:
            beta = optimize.brentq(along, low, high, xtol=1e-3, maxiter=SEARCH - 12, disp=False)
            return beta * alpha, float(r2), len(calls)
        low, high = high, 1.5 * high
    return c * alpha, float(r2), len(calls)  # no root along alpha: the surface's point (the checks judge it)


def screened_point(samples, features=None) -> tuple[np.ndarray, float, float]:
    """(u*, beta, R^2) of a response surface fitted where the columns outnumber what the
    pilot's ``samples`` can fit: over the independent level-0 samples (n of them), on
    the columns that correlate with g (|r| > SCREENED / sqrt(n); the strongest one at
    least), the other columns one normal noise term of the residuals' sd, a standard
    variable e of its own. FORM on that surface (:func:`surface_point`) gives (u_kept*,
    e*): u* moves the kept columns only (zero elsewhere) and beta is |(u_kept*, e*)|. No
    root search: along the kept columns alone g may never reach 0."""
    U0, y0 = samples[0]
    d = U0.shape[1]
    X0 = U0 if features is None else features(U0)
    r = np.nan_to_num([np.corrcoef(x, y0)[0, 1] if x.std() > 0 else 0.0 for x in X0.T])
    keep = np.flatnonzero(np.abs(r) > SCREENED / math.sqrt(len(y0)))
    keep = keep if keep.size else np.array([int(np.argmax(np.abs(r)))])
    coef, r2 = _fit(X0[:, keep], y0)
    noise = float(np.std(y0 - np.column_stack([np.ones(len(y0)), X0[:, keep]]) @ coef))

    def kept(u_e):  # the features of (u_kept, e): the kept columns' own, then e as it is
        full = np.zeros((len(u_e), d))
        full[:, keep] = u_e[:, :-1]
        return np.column_stack([(full if features is None else features(full))[:, keep], u_e[:, -1]])

    point = surface_point(coef[0], np.append(coef[1:], noise), kept, keep.size + 1)
    u_star = np.zeros(d)
    u_star[keep] = point[:-1]
    return u_star, float(np.linalg.norm(point)), r2


def _fit(X, y) -> tuple[np.ndarray, float]:
    """(coefficients [a0, a...], R^2) of the least-squares fit y ~ a0 + X a."""
    A = np.column_stack([np.ones(len(X)), X])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return coef, float(1 - np.sum((y - A @ coef) ** 2) / np.sum((y - y.mean()) ** 2))


def surface_point(a0: float, a: np.ndarray, features, d: int) -> np.ndarray:
    """The most probable point of the response surface q(u) = a0 + a . features(u): the u of least
    |u| with q(u) = 0 (FORM on the surface; ``scipy.optimize.minimize``'s SLSQP from the
    linear surface's point, the features' slopes by central differences). In U itself
    (``features`` None) it is -a0 a / |a|^2."""
    if features is None:
        return -a0 * a / float(a @ a)
    h = 1e-6

    def q(u):
        return float(a0 + a @ features(u[None, :])[0])

    def slope(u):
        return a * (features((u + h)[None, :])[0] - features((u - h)[None, :])[0]) / (2 * h)

    start = -q(np.zeros(d)) * slope(np.zeros(d)) / max(float(slope(np.zeros(d)) @ slope(np.zeros(d))), 1e-300)
    found = optimize.minimize(lambda u: 0.5 * u @ u, start, jac=lambda u: u, method="SLSQP",
                              constraints=[{"type": "eq", "fun": q, "jac": slope}], options={"maxiter": 200})
    return found.x if found.success and np.linalg.norm(found.x) > 0 else start


def agree(p: float, delta: float, sus: SubsetResult) -> bool:
    """Whether an importance estimate ``p`` (CoV ``delta``) agrees with the subset
    simulation's: |ln(p / P_sus)| within AGREE sd of the log-normal approximations."""
    if not (p > 0 and math.isfinite(delta)):
        return False
    sd = math.sqrt(math.log1p(delta**2) + math.log1p(sus.cov**2))
    return abs(math.log(p / sus.probability)) <= AGREE * sd


def beta_agrees(beta: float, sus: SubsetResult) -> bool:
    """Whether the most probable point's ``beta`` agrees with the pilot's generalised index
    -Phi^-1(P_sus): within BETA_GAP plus AGREE sd of the index (its sd from the pilot's
    CoV: P cov / phi(index))."""
    index = -float(ndtri(sus.probability))
    sd = sus.probability * sus.cov / (math.exp(-index**2 / 2) / math.sqrt(2 * math.pi))
    return abs(beta - index) <= BETA_GAP + AGREE * sd


def importance_sampling(g, d: int, *, seed: int, cov: float = 0.1, max_calls: int = 100_000,
                        n_per_level: int = 500, p0: float = 0.1, max_levels: int = 30,
                        features=None) -> RareResult:
    """P(g(U) <= 0), U ~ N(0, I_d), to coefficient of variation ``cov`` within
    ``max_calls`` model calls in all, a hard limit (the module docstring); the pilot's
    subset levels have ``n_per_level`` samples (fewer if the budget is smaller), at most
    ``max_levels`` of them, and conditional probability ``p0``. ``features``: what the
    response surface is linear in (:func:`most_probable_point`; default U)."""
    chain = round(1 / p0)
    n_per_level = min(n_per_level, int(max_calls) // chain * chain)
    if n_per_level < chain:
        raise ValueError(f"max_calls={max_calls} must allow one level of at least 1 / p0 = {chain} samples")
    rng = np.random.default_rng(seed)
    sus, samples = subset_levels(g, d, n_per_level=n_per_level, p0=p0, rng=rng, spread=1.0, max_levels=max_levels,
                                 max_calls=(pilot := max(max_calls - SEARCH, n_per_level)))

    def result(p, delta, calls, method, beta=math.nan, r2=math.nan, opposite=math.nan, importance=0, why=""):
        note = why if delta > cov or method == "below" else ""
        return RareResult(float(p), float(delta), int(calls), method, float(beta), float(r2), float(opposite),
                          int(importance), sus, note)

    if not sus.reached:
        bound = min(NONE_SEEN / n_per_level, sus.probability)
        why = "the budget" if sus.calls + (chain - 1) * round(p0 * n_per_level) > pilot else "the levels"
        return result(bound, 0.0, sus.calls, "below", why=f"no failure reached before {why} ran out")
    if len(sus.thresholds) == 1:
        return _monte_carlo(g, d, samples[0][1], cov, max_calls, rng, result)
    if sus.calls + SEARCH > max_calls:  # no budget for the root search: the pilot is the answer
        return result(sus.probability, sus.cov, sus.calls, "subset", why="the budget ran out")
    u_star, r2, search = most_probable_point(g, samples, features)
    spent = sus.calls + search
    u_last, y_last = samples[-1]
    if u_star is None:
        return _subset_rounds(g, d, sus, samples[0][1], spent, cov, max_calls, p0, max_levels, rng,
                              lambda *a, **k: result(*a, **k, r2=r2), "the origin fails")
    beta = float(np.linalg.norm(u_star))
    if not beta_agrees(beta, sus) and d + 1 > sum(len(u) for u, _ in samples) / SCREEN:
        screened, form, fit = screened_point(samples, features)
        if beta_agrees(form, sus):  # FORM's index of the screened surface; the shift is u* alone
            u_star, beta, r2 = screened, form, fit
    shift = float(np.linalg.norm(u_star))
    opposite = float(np.mean(u_last[y_last <= 0] @ u_star <= 0))

    def subset_again(importance_calls: int, why: str) -> RareResult:
        return _subset_rounds(g, d, sus, samples[0][1], spent + importance_calls, cov, max_calls, p0, max_levels, rng,
                              lambda *a, **k: result(*a, **k, beta=beta, r2=r2, opposite=opposite,
                                                     importance=importance_calls), why)

    if opposite > OPPOSITE:
        return subset_again(0, "failures on both sides of the most probable point")
    if not beta_agrees(beta, sus):
        return subset_again(0, f"most probable point beta {beta:.2f} against the subset estimate's "
                               f"{-float(ndtri(sus.probability)):.2f}")
    terms, previous = np.empty(0), math.inf
    n = FIRST_ROUND
    while True:
        take = max(min(n - terms.size, max_calls - spent - terms.size), 0)
        v = u_star + rng.standard_normal((take, d))
        fails = np.asarray(g(v), dtype=float) <= 0 if take else np.zeros(0, bool)
        weights = np.exp(-v @ u_star + shift**2 / 2)
        terms = np.concatenate([terms, np.where(fails, weights, 0.0)])
        p = float(terms.mean()) if terms.size else 0.0
        delta = float(terms.std(ddof=1) / math.sqrt(terms.size) / p) if p > 0 and terms.size > 1 else math.inf
        if terms.size <= FIRST_ROUND and not agree(p, delta, sus):
            return subset_again(int(terms.size), "the first importance round disagreed with the subset estimate")
        if terms.size > FIRST_ROUND and take and delta >= previous:
            return subset_again(int(terms.size), "the importance rounds' CoV stopped falling")
        if delta <= cov or take == 0 or spent + terms.size >= max_calls:
            return result(p, delta, spent + terms.size, "importance", beta, r2, opposite, terms.size,
                          "the budget ran out")
        previous = delta
        n = min(max(math.ceil(terms.size * (delta / cov) ** 2), terms.size + FIRST_ROUND), 2 * terms.size)


def _monte_carlo(g, d, y0, cov, max_calls, rng, result, other: int = 0, why: str = "") -> RareResult:
    """Plain Monte Carlo from the pilot's level-0 values ``y0`` on, to CoV ``cov`` within
    ``max_calls`` with ``other`` calls spent besides level 0's: where failure is not rare,
    or plain sampling costs no more than subset rounds, n (1 - P) / P samples are all it
    needs (sized from one failure while none is seen; none at the end is a bound)."""
    fails, n, batch = int(np.sum(y0 <= 0)), len(y0), len(y0)
    while True:
        p = max(fails, 1) / n
        delta = math.sqrt((1 - p) / (p * n))
        more = min(math.ceil((1 - p) / (p * cov**2)) - n, int(max_calls) - other - n, batch)
        if not fails and more <= 0:
            return result(NONE_SEEN / n, 0.0, other + n, "below", why=f"{why}; no failure in the plain samples")
        if (delta <= cov and fails) or more <= 0:
            return result(p, delta, other + n, "montecarlo",
                          why=f"{why}; the budget ran out" if why else "the budget ran out")
        fails += int(np.sum(np.asarray(g(rng.standard_normal((more, d))), dtype=float) <= 0))
        n += more


def _subset_rounds(g, d, sus, y0, spent, cov, max_calls, p0, max_levels, rng, result, why) -> RareResult:
    """Subset simulation in ROUNDS independent rounds after the pilot ``sus`` (level-0
    values ``y0``) and ``spent`` calls (module docstring), each with the samples a level
    that the pilot's CoV says the target needs, within what the budget leaves; the pilot's
    estimate where not even two rounds of LEAST_LEVEL samples a level fit; plain Monte
    Carlo on from level 0 where that needs no more calls than the rounds would."""
    chain, n0 = round(1 / p0), len(y0)
    per_sample = sus.calls / n0 * 1.1  # calls a round per sample a level, with a level's margin
    need = n0 * (sus.cov / cov) ** 2 / ROUNDS
    p = sus.probability
    if (1 - p) / (p * cov**2) - n0 <= need * ROUNDS * per_sample:
        return _monte_carlo(g, d, y0, cov, max_calls, rng, result, other=spent - n0,
                            why=f"{why}; plain sampling no dearer than subset rounds")
    rounds = min(ROUNDS, int((max_calls - spent) / (per_sample * LEAST_LEVEL)))
    if rounds < 2:
        return result(sus.probability, sus.cov, spent, "subset", why=f"{why}; no budget left for subset rounds")
    n = int(min(need, (max_calls - spent) / (rounds * per_sample))) // chain * chain
    n = max(n, LEAST_LEVEL // chain * chain)
    estimates, covs, delta = [], [], math.inf
    while max_calls - spent >= n and (len(estimates) < rounds or delta > cov):  # a round's level 0 left
        r = subset_levels(g, d, n_per_level=n, p0=p0, rng=rng, spread=1.0, max_levels=max_levels,
                          max_calls=max_calls - spent)[0]
        spent += r.calls
        if r.reached:
            estimates.append(r.probability)
            covs.append(r.cov)
        if len(estimates) >= 2:
            p = float(np.mean(estimates))
            spread = float(np.std(estimates, ddof=1)) / math.sqrt(len(estimates)) / p
            delta = max(spread, math.sqrt(float(np.sum((np.array(covs) * estimates) ** 2))) / len(estimates) / p)
    if len(estimates) < 2:
        return result(sus.probability, sus.cov, spent, "subset", why=f"{why}; the subset rounds did not reach failure")
    return result(p, delta, spent, "subset", why=f"{why}; the budget ran out")
