"""Estimators of a design's statistics from its per-drape quantities, with confidence
limits, and what the optimiser minimises of them (see ``uqdrape.design``)."""

from __future__ import annotations

import numpy as np
import xarray as xr
from scipy.special import ndtri

from ..schema import DRAW_IN, REALIZATION
from ..stats import line_means, mean_statistics, quantile_statistics, wilson_interval
from ..study.spec import DESIGN_OBJECTIVES

#: The value of a design that breaks the draw-in limit before its excess (mm) is added:
#: above every feasible objective (probabilities, degrees, mm).
INFEASIBLE = 1.0e6
STATISTICS = tuple(DESIGN_OBJECTIVES)
#: Statistic of a ``[design] rare`` constraint: the candidate's rare probability estimate.
RARE = "p_rare"


def per_realization(record: xr.Dataset, k_max: int) -> dict[str, np.ndarray]:
    """The per-drape quantity of each statistic (name -> (R,) array)."""
    asym = line_means(record["line_shear"], k_max)["asymmetry"]
    return {"p_locked": record["any_locked"].values, "q95_max_abs_shear": record["max_abs_shear"].values,
            "abs_mean_asymmetry": asym.values, DRAW_IN: record["max_draw_in"].values}


def statistics(values: dict, confidence: float) -> dict[str, tuple]:
    """(estimate, lower, upper) of every statistic of per-drape quantities ``values``
    (name -> array (..., R)): floats for one design, arrays (...) for a stack of them
    (e.g. bootstrap resamples)."""
    out = {}
    for name, v in values.items():
        v = np.asarray(v, dtype=float)
        kind = DESIGN_OBJECTIVES[name][1]
        drapes = xr.DataArray(v).rename({f"dim_{v.ndim - 1}": REALIZATION})
        if kind == "probability":
            n = np.count_nonzero(~np.isnan(v), axis=-1)
            k = np.nansum(v, axis=-1)
            lo, hi = wilson_interval(k, n, confidence)
            triple = (k / n, lo, hi)
        elif kind == "quantile95":
            q = quantile_statistics(drapes, [0.95], confidence).isel(quantile=0)
            triple = tuple(q[f"quantile_{s}"].values for s in ("value", "lower", "upper"))
        else:
            m = mean_statistics(drapes, confidence)
            mean, lo, hi = (m[s].values for s in ("mean", "mean_lower", "mean_upper"))
            straddles = (lo <= 0) & (hi >= 0)  # |mean| folded at 0
            triple = (np.abs(mean), np.where(straddles, 0.0, np.minimum(np.abs(lo), np.abs(hi))),
                      np.maximum(np.abs(lo), np.abs(hi)))
        out[name] = tuple(float(t) if np.ndim(t) == 0 else np.asarray(t, dtype=float) for t in triple)
    return out


def rare_interval(probability: float, cov: float, confidence: float) -> tuple[float, float, float]:
    """(estimate, lower, upper) of a rare probability estimate of coefficient of variation
    ``cov``: the two-sided ``confidence`` interval of its log-normal approximation,
    P exp(-+z sqrt(ln(1 + cov^2))) (positive, and the usual reading of a CoV at small P)."""
    z = ndtri((1 + confidence) / 2) * np.sqrt(np.log1p(cov**2))
    return float(probability), float(probability * np.exp(-z)), float(probability * np.exp(z))


def rare_statistic(attrs, spec, confidence: float) -> tuple[float, float, float]:
    """(estimate, lower, upper) of a design's rare estimate (its record's ``rare_*``
    ``attrs``): :func:`rare_interval`, but with upper 1 where the estimate's CoV is above the
    constraint's target (nothing bounds it: :func:`excess` then keeps no bound). A bound
    (method "below", CoV 0) is its own interval."""
    p, lower, upper = rare_interval(attrs["rare_probability"], attrs["rare_cov"], confidence)
    trusted = attrs["rare_method"] == "below" or attrs["rare_cov"] <= spec.rare.cov
    return p, lower, upper if trusted else 1.0


def _statistic(stats: dict, name: str, spec):
    """The spec's statistic (upper limit or estimate) of statistic ``name``."""
    estimate, _, upper = stats[name]
    value = upper if spec.statistic == "upper" else estimate
    if not np.all(np.isfinite(value)):
        raise ValueError(f"the {spec.statistic} of {name} is undefined (no valid realisation, or too few "
                         "for its confidence limit)")
    return value


def excess(stats: dict, spec):
    """How far a design breaks its limits, 0 if it keeps them: the draw-in limit's excess
    (mm) plus the rare constraint's (decades: log10 of P over max_probability, P taken as 1
    where its upper limit is 1: certain failure, or an estimate above its target CoV), a
    ranking of infeasible designs by how far they miss, not a physical quantity."""
    over = np.zeros(np.shape(stats[DRAW_IN][0]))
    if spec.max_draw_in_mm is not None:
        over = over + np.maximum(_statistic(stats, DRAW_IN, spec) - spec.max_draw_in_mm, 0.0)
    if spec.rare is not None:
        with np.errstate(divide="ignore"):  # P = 0: keeps it
            p = np.where(stats[RARE][2] >= 1.0, 1.0, _statistic(stats, RARE, spec))
            over = over + np.maximum(np.log10(p / spec.rare.max_probability), 0.0)
    return over


def objective_value(stats: dict, spec):
    """What the design minimises of its statistics (a float, or an array for a stack)."""
    value = _statistic(stats, spec.objective, spec)
    return np.abs(value - spec.target) if spec.target is not None else value


def penalised(stats: dict, spec):
    """The objective, or ``INFEASIBLE`` + the excess (:func:`excess`) of a design over its limits."""
    over = excess(stats, spec)
    return np.where(over > 0, INFEASIBLE + over, objective_value(stats, spec))
