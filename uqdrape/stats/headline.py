"""What kind of ensemble a study made, and its headline numbers (the report's table and
``summary.json``).

The kind decides which statistics mean anything (decisions):

- ``"sensitivity sample"``: the rows of a SALib sample matrix (``sample_method`` attribute). Not
  independent draws, so no confidence intervals, convergence or N-needed; the mean and
  sd over the sample are descriptive.
- ``"deterministic"``: one drape per blank-holder level (a single drape or a force sweep).
- ``"swept factor"``: exactly one uncertain input, a scalar factor with a uniform
  distribution (e.g. ``skew`` over 0-55 deg, however the plan spreads it): a
  deterministic sweep over that factor, so no Normal fit, risk interval or N-needed.
  An ensemble without a study record counts as one when exactly one scalar factor varies.
- ``"random sample"``: anything else with N >= 2 per level, a Monte Carlo or LHS sample;
  every statistic applies.
"""

from __future__ import annotations

import json
import math

import numpy as np
import xarray as xr

from ..drape.status import Status
from ..files import to_float
from ..schema import FORCE, REALIZATION, SOLVER_INPUTS, by_force
from .convergence import samples_needed
from .exceedance import exceedance_probability
from .summary import node_statistics

RANDOM, DETERMINISTIC, SWEPT, SENSITIVITY = "random sample", "deterministic", "swept factor", "sensitivity sample"
STUDY_KINDS = (RANDOM, DETERMINISTIC, SWEPT, SENSITIVITY)


def varying_factors(ds: xr.Dataset) -> list[str]:
    """Scalar solver inputs (``uqdrape.schema.SOLVER_INPUTS``) that take more than one
    value over the realisations of ``ds`` (a drape or an ensemble), in the table's order."""
    ds = by_force(ds)
    out = []
    for name, inp in SOLVER_INPUTS.items():
        if inp.variable in ds.data_vars and set(ds[inp.variable].dims) == {FORCE, REALIZATION}:
            values = ds[inp.variable].values
            if np.nanmin(values, initial=np.inf) < np.nanmax(values, initial=-np.inf):
                out.append(name)
    return out


def study_kind(ds: xr.Dataset) -> str:
    """One of :data:`STUDY_KINDS` for ``ds`` in the ensemble layout (``uqdrape.schema.by_force``;
    see the module docstring for the rules)."""
    ds = by_force(ds)
    if ds.attrs.get("sample_method"):
        return SENSITIVITY
    if ds.sizes[REALIZATION] < 2:
        return DETERMINISTIC
    factors = varying_factors(ds)
    if "study_json" not in ds.attrs:
        return SWEPT if len(factors) == 1 else RANDOM
    uncertain = json.loads(ds.attrs["study_json"]).get("uncertainty", {})
    if len(uncertain) == 1 and factors == list(uncertain) and uncertain[factors[0]].get("dist") == "uniform":
        return SWEPT
    return RANDOM


def argmax_site(da: xr.DataArray) -> dict | None:
    """Coordinates {dim: value} of the largest finite entry of ``da`` (None if there is none)."""
    values = da.values
    if not np.isfinite(values).any():
        return None
    idx = np.unravel_index(int(np.nanargmax(values)), values.shape)
    return {d: da[d].values[k].item() for d, k in zip(da.dims, idx)}


def _site(da: xr.DataArray) -> dict:
    """{value, node [i, j], blankholder_force_N} of the largest finite entry of ``da`` (value None if none)."""
    at = argmax_site(da)
    if at is None:
        return {"value": None, "node": None, "blankholder_force_N": None}
    return {"value": float(da.sel(at)), "node": [int(at["i"]), int(at["j"])], "blankholder_force_N": float(at[FORCE])}


def wrinkle_risk(ds: xr.Dataset, confidence: float = 0.95) -> xr.Dataset | None:
    """Per-node wrinkle risk with its binomial interval, or None when nothing can lock.

    From the drape's ``locked`` flag (a node next to a cell sheared past its own branch's
    locking angle, zero-energy offset included): the asymmetric locking of an NCF counts.
    An ensemble without it (a file written before the flag existed) falls back to
    P(|node shear| > ``locking_angle_deg``); a geodesic drape without a material has
    neither. ``attrs["risk"]`` names what was measured.
    """
    if "locked" in ds.data_vars and bool(np.isfinite(ds["locked"]).any()):
        ex = exceedance_probability(ds, 0.5, var="locked", confidence=confidence)
        ex.attrs["risk"] = "P(next to a locked cell)"
        return ex
    threshold = to_float(ds.attrs.get("locking_angle_deg"))
    if not math.isfinite(threshold):
        return None
    ex = exceedance_probability(ds, threshold, confidence=confidence)
    ex.attrs["risk"] = f"P(|shear| > {threshold:g}°)"
    return ex


def _status_counts(ds: xr.Dataset) -> dict[str, int]:
    """Node values per placement status over the whole ensemble, statuses that occur only;
    counted lazily, a chunk at a time, for an ensemble opened from its store."""
    if "status" not in ds:
        return {}
    counts = xr.Dataset({s.name.lower(): (ds["status"] == s).sum() for s in Status}).compute()
    return {name: int(k) for name, k in counts.items() if k > 0}


def headline_numbers(ds: xr.Dataset, *, node_stats: xr.Dataset | None = None,
                     exceedance: xr.Dataset | None = None, half_width_deg: float = 1.0,
                     confidence: float = 0.95) -> dict:
    """The headline numbers of ensemble ``ds`` as a JSON-ready dict (angles in deg).

    ``ds`` is taken in the ensemble layout (``uqdrape.schema.by_force``). Always: ``kind``
    (:func:`study_kind`), ``realizations`` (N per level),
    ``blankholder_force_levels_N``, ``blankholder_model`` (ensembles written before the
    choice existed used "radial"), ``valid_fraction`` (valid node values / all node
    values), ``node_status`` (count of node values per status name, e.g. ``off_mould``) and ``max_abs_mean_shear_deg`` (value, node, level; the shear itself for one
    drape per level). A random sample or a sensitivity sample adds ``max_sd_deg``; a
    random sample adds ``max_wrinkle_probability`` (the largest ``wrinkle_risk`` with its
    interval and ``measure``) and ``samples_needed`` (N for a ``confidence`` interval of
    the mean of half-width ``half_width_deg`` at the node of largest sd). Numbers that
    do not apply to the kind, or cannot be computed, are None.
    """
    ds = by_force(ds)
    kind = study_kind(ds)
    node_stats = node_statistics(ds, confidence=confidence) if node_stats is None else node_stats
    count = node_stats["count"]
    n = int(ds.sizes[REALIZATION])
    out = {
        "kind": kind,
        "realizations": n,
        "blankholder_force_levels_N": [float(f) for f in ds[FORCE].values],
        "blankholder_model": ds.attrs.get("blankholder_model", "radial"),
        "valid_fraction": float(count.sum()) / (n * count.size),
        "node_status": _status_counts(ds),
        "max_abs_mean_shear_deg": _site(abs(node_stats["mean"])),
        "max_sd_deg": _site(node_stats["sd"]) if kind in (RANDOM, SENSITIVITY) else None,
        "max_wrinkle_probability": None,
        "samples_needed": None,
    }
    if kind != RANDOM:
        return out
    exceedance = wrinkle_risk(ds, confidence) if exceedance is None else exceedance
    if exceedance is not None:
        site = _site(exceedance["probability"])
        if site["value"] is not None:
            at = exceedance.sel({"i": site["node"][0], "j": site["node"][1], FORCE: site["blankholder_force_N"]})
            site.update(lower=float(at["probability_lower"]), upper=float(at["probability_upper"]),
                        measure=exceedance.attrs["risk"],
                        interval=f"{exceedance.attrs['confidence']:.0%} {exceedance.attrs['interval']}")
        out["max_wrinkle_probability"] = site
    sd = out["max_sd_deg"]
    if sd["value"] is not None and sd["value"] > 0:
        out["samples_needed"] = {
            "value": int(samples_needed(sd["value"], half_width_deg, confidence)),
            "half_width_deg": float(half_width_deg), "confidence": float(confidence),
            "node": sd["node"], "blankholder_force_N": sd["blankholder_force_N"], "sd_deg": sd["value"],
        }
    return out


def dominant_factors(indices: xr.Dataset) -> list[dict]:
    """Per blank-holder level, the factor with the largest total-order Sobol' index ST over
    every quantity of interest: [{blankholder_force_N, factor, qoi, ST, ST_conf}].
    ``indices`` is a Sobol' indices Dataset (factor, qoi, blankholder_force)."""
    out = []
    for force in indices[FORCE].values:
        st = indices.sel({FORCE: force})
        at = argmax_site(st["ST"].transpose("factor", "qoi"))
        out.append({"blankholder_force_N": float(force), "factor": str(at["factor"]),
                    "qoi": str(at["qoi"]), "ST": float(st["ST"].sel(at)), "ST_conf": float(st["ST_conf"].sel(at))})
    return out
