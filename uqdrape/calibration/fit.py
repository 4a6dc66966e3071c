"""Fit a Gaussian field to measured values: families, the chosen one, intervals.

Each correlation family (iid, exponential, squared exponential) is fitted by restricted
maximum likelihood (:mod:`.likelihood`); the family kept is the one of least AIC
(−2ℓ + 2k) or, on request, BIC (−2ℓ + k log n), k the fitted parameters, mean included.

Intervals at ``level`` (default 90 %), all from the profile likelihood of the chosen
family, the other parameters re-maximised at every profile point:

- correlation lengths L1, L2: {L : 2(ℓ̂ − ℓ_p(L)) ≤ χ²₁(level)} (Wilks);
- sd σ: the same profile, its two ends cut at the deviances the restricted likelihood of
  n iid values has at the equal-tailed χ²_{n−1} limits, m (Q − 1 − log Q) with
  Q = χ²_{n−1}(α/2)/m below σ̂ and χ²_{n−1}(1 − α/2)/m above it (m = n − 1). For iid
  values that *is* the closed-form interval s √(m / χ²_{n−1}); for a correlated field it
  is the profile likelihood interval with the skew of a variance's likelihood corrected
  at small n, tending to Wilks as n grows;
- mean μ: μ̂ ± t_{n−1} √(1/1ᵀΣ⁻¹1) (the generalised-least-squares variance);
- nugget τ: its estimate only.

A profile that has not fallen to the cut at a parameter's search bound (lengths: a tenth
of the points' median nearest-neighbour distance to ten times the sample's diameter)
leaves that end open: the data do not bound it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
import scipy.stats

from .likelihood import FAMILIES, Likelihood, maximise, parameter_names

CRITERIA = ("aic", "bic")
#: Fewest points for a correlated family (4 covariance parameters and the mean).
MIN_CORRELATED_POINTS = 8
#: Fewest points for any fit.
MIN_POINTS = 3
#: Profile end-point tolerance: |√deviance − √cut|.
_ROOT_TOL = 1e-4
#: Times a profile may restart from a higher optimum it found.
_RESTARTS = 3


@dataclass(frozen=True)
class Estimate:
    """A fitted value and its interval at the calibration's level; an open end means the
    profile had not reached its cut at the search bound (the end given is that bound)."""

    value: float
    lower: float
    upper: float
    lower_open: bool = False
    upper_open: bool = False


@dataclass(frozen=True)
class FamilyFit:
    """One family's fit: θ (logs of sd, L1, L2, nugget; :func:`parameter_names`), the
    restricted log-likelihood, its parameter count (mean included) and criteria."""

    family: str
    theta: np.ndarray
    loglik: float
    n_params: int
    aic: float
    bic: float

    @property
    def sd_deg(self) -> float:
        return float(math.exp(self.theta[0]))

    @property
    def length_mm(self) -> tuple[float, float] | None:
        return None if self.family == "iid" else (float(math.exp(self.theta[1])), float(math.exp(self.theta[2])))

    @property
    def nugget_deg(self) -> float:
        return 0.0 if self.family == "iid" else float(math.exp(self.theta[3]))


@dataclass
class Profile:
    """Profile deviance 2(ℓ̂ − ℓ_p) (``deviance``) of one parameter at ``values`` (natural
    units) and the cut each side (lower, upper)."""

    values: list = field(default_factory=list)
    deviance: list = field(default_factory=list)
    cut: tuple[float, float] = (math.nan, math.nan)


@dataclass
class FieldFit:
    """The fits of every family tried, the chosen one and its estimates and profiles
    (names: mean_deg, sd_deg, length_1_mm, length_2_mm, nugget_deg)."""

    fits: dict
    family: str
    criterion: str
    level: float
    estimates: dict
    profiles: dict
    likelihood: Likelihood

    @property
    def chosen(self) -> FamilyFit:
        return self.fits[self.family]


def fit_field(a, b, y, noise_sd=None, *, family: str = "auto", criterion: str = "aic", level: float = 0.9,
              intervals: bool = True) -> FieldFit:
    """Fit values ``y`` (deg) at fibre coordinates ``a``, ``b`` (mm) with per-point
    measurement sds ``noise_sd`` (deg; None: none known). ``family`` "auto" fits every
    family the points allow and keeps the best by ``criterion``; ``intervals`` False skips
    the profiles (estimates then have their value as both ends)."""
    y = np.asarray(y, dtype=float)
    n = len(y)
    noise_sd = np.zeros(n) if noise_sd is None else np.asarray(noise_sd, dtype=float)
    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {', '.join(CRITERIA)}, got {criterion!r}")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be a probability in (0, 1), got {level!r}")
    if family != "auto" and family not in FAMILIES:
        raise ValueError(f"family must be auto or one of {', '.join(FAMILIES)}, got {family!r}")
    if n < MIN_POINTS:
        raise ValueError(f"{n} measured points: a fit needs at least {MIN_POINTS}")
    if np.ptp(y) == 0.0:
        raise ValueError(f"all {n} measured angles are equal ({y[0]:g} deg): there is no scatter to fit")
    places, index, count = np.unique(np.round(np.column_stack([a, b]), 9), axis=0, return_inverse=True,
                                     return_counts=True)
    shared = (count[index.ravel()] > 1) & (noise_sd == 0.0)
    if shared.any():
        raise ValueError(f"{int(shared.sum())} of the {n} points share their place with another and have no "
                         "measurement sd: the field has one value per place; give each place once (the mean of "
                         "its readings) or each reading its sd_deg")
    if len(places) == 1:
        raise ValueError(f"all {n} points are at one place: the field's scatter cannot be told from its mean")
    if family in ("exponential", "squared_exponential") and n < MIN_CORRELATED_POINTS:
        raise ValueError(f"{n} measured points: a correlated family needs at least {MIN_CORRELATED_POINTS}")
    families = ((FAMILIES if n >= MIN_CORRELATED_POINTS else ("iid",)) if family == "auto" else (family,))
    likes = {f: Likelihood(a, b, y, noise_sd, f) for f in families}
    scale = float(np.std(y, ddof=1))
    fits = {f: _fit_family(likes[f], scale) for f in families}
    chosen = min(fits, key=lambda f: getattr(fits[f], criterion))
    like = likes[chosen]
    fit = fits[chosen]
    estimates, profiles, theta = _estimates(like, fit, scale, level, intervals)
    if theta is not fit.theta:  # a profile found a higher optimum: keep it
        fits[chosen] = _family_fit(like, theta, like(theta, gradient=False)[0])
    return FieldFit(fits, chosen, criterion, level, estimates, profiles, like)


def bounds(like: Likelihood, scale: float) -> list[tuple[float, float]]:
    """Search bounds of θ (logs): sd and nugget from 1e-3 to 1e3 and 10 times the values'
    sd ``scale``; lengths from a tenth of the median nearest-neighbour distance to ten
    times the diameter of the point set."""
    sd = (math.log(1e-3 * scale), math.log(1e3 * scale))
    if like.family == "iid":
        return [sd]
    length = (math.log(0.1 * like.nearest), math.log(10.0 * like.diameter))
    return [sd, length, length, (math.log(1e-3 * scale), math.log(10.0 * scale))]


def _fit_family(like: Likelihood, scale: float) -> FamilyFit:
    """The restricted ML fit of ``like``'s family from the best of a few starting points."""
    box = bounds(like, scale)
    if like.family == "iid":
        starts = [np.array([math.log(scale)])]
    else:
        lo, hi = box[1]
        starts = [np.array([math.log(scale), L, L, math.log(t * scale)])
                  for L in np.linspace(lo + 0.3 * (hi - lo), lo + 0.7 * (hi - lo), 3) for t in (0.1, 0.5)]
    start = max(starts, key=lambda th: like(th, gradient=False)[0])
    theta, loglik = maximise(like, start, box)
    return _family_fit(like, theta, loglik)


def _family_fit(like: Likelihood, theta, loglik) -> FamilyFit:
    k = len(theta) + 1
    return FamilyFit(like.family, theta, float(loglik), k, -2.0 * loglik + 2.0 * k, -2.0 * loglik + k * math.log(like.n))


def sd_cuts(n: int, level: float) -> tuple[float, float]:
    """The deviance cuts of σ's profile below and above σ̂ (see the module docstring)."""
    m = n - 1
    alpha = 1.0 - level
    q = np.array([scipy.stats.chi2.ppf(1.0 - alpha / 2, m), scipy.stats.chi2.ppf(alpha / 2, m)]) / m
    cut = m * (q - 1.0 - np.log(q))
    return float(cut[0]), float(cut[1])


def _estimates(like: Likelihood, fit: FamilyFit, scale: float, level: float, intervals: bool):
    """Estimates with intervals, the profiles of the chosen family's fit, and θ at the
    optimum (``fit.theta`` itself unless a profile found a higher one)."""
    names = parameter_names(fit.family)
    box = bounds(like, scale)
    theta, best = fit.theta.copy(), fit.loglik
    estimates, profiles = {}, {}
    for k, name in enumerate(names[:3]):
        cuts = sd_cuts(like.n, level) if name == "sd" else (scipy.stats.chi2.ppf(level, 1),) * 2
        value = math.exp(theta[k])
        if not intervals:
            estimates[name] = Estimate(value, value, value)
            continue
        for _ in range(_RESTARTS + 1):
            search = _ProfileSearch(like, theta, best, k, box)
            ends = [search.end(side, cut) for side, cut in zip((-1, 1), cuts)]
            if search.better is None:
                break
            theta, best = search.better  # a higher optimum than the fit's: start again from it
        (lo, lo_open), (hi, hi_open) = ends
        estimates[name] = Estimate(math.exp(theta[k]), math.exp(lo), math.exp(hi), lo_open, hi_open)
        order = np.argsort(search.values)
        profiles[name] = Profile(list(np.exp(np.asarray(search.values)[order])),
                                 list(np.asarray(search.deviance)[order]), cuts)
    mean, var = like.mean(theta)
    half = scipy.stats.t.ppf(0.5 + level / 2, like.n - 1) * math.sqrt(var)
    estimates = {"mean_deg": Estimate(mean, mean - half, mean + half),
                 "sd_deg": estimates["sd"],
                 **({} if fit.family == "iid" else
                    {"length_1_mm": estimates["length_1"], "length_2_mm": estimates["length_2"],
                     "nugget_deg": Estimate(math.exp(theta[3]), math.exp(theta[3]), math.exp(theta[3]))})}
    profiles = {{"sd": "sd_deg", "length_1": "length_1_mm", "length_2": "length_2_mm"}[k]: v
                for k, v in profiles.items()}
    return estimates, profiles, theta


class _ProfileSearch:
    """The profile of θ_k about the optimum ``theta`` (ℓ = ``best``), searched for the
    points where √deviance reaches √cut on either side; ``better`` is set to (θ, ℓ) if a
    profile point beats the optimum."""

    def __init__(self, like, theta, best, k, box):
        self.like, self.theta, self.best, self.k, self.box = like, theta, best, k, box
        self.values, self.deviance, self.thetas = [theta[k]], [0.0], [theta]
        self.better = None

    def _root_deviance(self, value):
        """√deviance at θ_k = value, the others re-maximised from the straight-line
        extrapolation of the two nearest profile points."""
        values = np.asarray(self.values)
        near = np.argsort(np.abs(values - value))[:2]
        start = self.thetas[near[0]]
        if len(near) == 2 and values[near[0]] != values[near[1]]:
            slope = (self.thetas[near[0]] - self.thetas[near[1]]) / (values[near[0]] - values[near[1]])
            start = np.clip(start + (value - values[near[0]]) * slope, *np.transpose(self.box))
        theta, loglik = maximise(self.like, start, self.box, fixed={self.k: value})
        deviance = 2.0 * (self.best - loglik)
        if deviance < -1e-6 and (self.better is None or loglik > self.better[1]):
            self.better = (theta, loglik)
        self.values.append(value)
        self.deviance.append(max(deviance, 0.0))
        self.thetas.append(theta)
        return math.sqrt(max(deviance, 0.0))

    def end(self, side: int, cut: float) -> tuple[float, bool]:
        """(θ_k where the deviance reaches ``cut`` on ``side`` (−1 below, +1 above), open):
        steps out along √deviance, nearly straight in θ_k, by secant steps until the cut is
        passed, then the Illinois variant of regula falsi inside the bracket."""
        centre = self.theta[self.k]
        reach = (self.box[self.k][1] - centre) if side > 0 else (centre - self.box[self.k][0])
        target = math.sqrt(cut)
        f = lambda u: self._root_deviance(centre + side * u) - target  # noqa: E731
        u_in, f_in = 0.0, -target
        u = min(0.2, reach)
        for _ in range(60):
            fu = f(u)
            if abs(fu) < _ROOT_TOL:
                return centre + side * u, False
            if fu > 0.0:
                break
            if u >= reach:
                return centre + side * reach, True
            slope = (fu - f_in) / (u - u_in)
            step = -fu / slope if slope > 0 else u
            u_in, f_in = u, fu
            u = min(reach, u + min(max(step * 1.05, 1e-3), 3.0 * u))
        else:
            return centre + side * u, True
        u_out, f_out, kept = u, fu, None
        for _ in range(60):  # Illinois: the end kept twice in a row has its value halved
            u = u_out - f_out * (u_out - u_in) / (f_out - f_in)
            fu = f(u)
            if abs(fu) < _ROOT_TOL or u_out - u_in < 1e-9:
                break
            if fu > 0.0:
                u_out, f_out, f_in = u, fu, f_in / 2 if kept == "in" else f_in
                kept = "in"
            else:
                u_in, f_in, f_out = u, fu, f_out / 2 if kept == "out" else f_out
                kept = "out"
        return centre + side * u, False


def profile_curve(field_fit: FieldFit, name: str, points: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """The profile deviance of parameter ``name`` (sd_deg, length_1_mm, length_2_mm) of
    the chosen family at ``points`` values each side of the estimate, out past its
    interval, for a figure: (values, deviance), sorted."""
    k = {"sd_deg": 0, "length_1_mm": 1, "length_2_mm": 2}[name]
    like, fit = field_fit.likelihood, field_fit.chosen
    estimate = field_fit.estimates[name]
    box = bounds(like, float(np.std(like.y, ddof=1)))
    search = _ProfileSearch(like, fit.theta, fit.loglik, k, box)
    centre = fit.theta[k]
    for end in (math.log(estimate.lower), math.log(estimate.upper)):
        far = centre + 1.25 * (end - centre)
        far = min(max(far, box[k][0]), box[k][1])
        for value in np.linspace(centre, far, points + 1)[1:]:
            search._root_deviance(value)
    order = np.argsort(search.values)
    return np.exp(np.asarray(search.values)[order]), np.asarray(search.deviance)[order]
