"""Headline numbers of an ensemble (the report's table and ``summary.json``).

Every number is read from a ``uqdrape.stats`` result, so the page, the JSON file and
the statistics functions agree exactly.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from uqdrape.stats import exceedance_probability, node_statistics, samples_needed

from .figures import FORCE, REALIZATION


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
    return {
        "value": float(da.sel(at)),
        "node": [int(at["i"]), int(at["j"])],
        "blankholder_force_N": float(at[FORCE]) if FORCE in at else None,
    }


def _sel(site: dict) -> dict:
    out = {"i": site["node"][0], "j": site["node"][1]}
    if site["blankholder_force_N"] is not None:
        out[FORCE] = site["blankholder_force_N"]
    return out


def locking_threshold(ds: xr.Dataset) -> float | None:
    """The locking angle (deg) from the Dataset attrs, or None when absent/NaN (geodesic drapes)."""
    value = ds.attrs.get("locking_angle_deg")
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def wrinkle_risk(ds: xr.Dataset, confidence: float = 0.95) -> xr.Dataset | None:
    """Per-node wrinkle risk with its binomial interval, or None when nothing locks.

    From the drape's ``locked`` flag (a node next to a cell sheared past its own branch's
    locking angle, zero-energy offset included): the asymmetric locking of an NCF counts.
    An ensemble without it (a file written before the flag existed) falls back to
    P(|node shear| > ``locking_angle_deg``). ``attrs["risk"]`` names what was measured.
    """
    if "locked" in ds.data_vars and bool(np.isfinite(ds["locked"]).any()):
        ex = exceedance_probability(ds, 0.5, var="locked", confidence=confidence)
        ex.attrs["risk"] = "P(next to a locked cell)"
        return ex
    threshold = locking_threshold(ds)
    if threshold is None:
        return None
    ex = exceedance_probability(ds, threshold, confidence=confidence)
    ex.attrs["risk"] = f"P(|shear| > {threshold:g}°)"
    return ex


def headline_numbers(ds: xr.Dataset, *, node_stats: xr.Dataset | None = None,
                     exceedance: xr.Dataset | None = None, half_width_deg: float = 1.0,
                     confidence: float = 0.95) -> dict:
    """The report's headline numbers as a JSON-ready dict (angles in deg).

    ``realizations`` (N per level), ``blankholder_force_levels_N``, ``blankholder_model``
    (which slip the blank-holder friction works on; ensembles written before the choice
    existed used the thesis's "radial" model), ``valid_fraction``
    (valid node values / all node values), ``max_abs_mean_shear_deg`` and ``max_sd_deg``
    (value, node, level), ``max_wrinkle_probability`` (the largest ``wrinkle_risk`` with
    its interval and ``measure``, or None without a locking angle) and ``samples_needed`` (N for a
    ``confidence`` interval of the mean of half-width ``half_width_deg`` at the node of
    largest sd; None when that sd is 0).
    """
    node_stats = node_statistics(ds, confidence=confidence) if node_stats is None else node_stats
    count = node_stats["count"]
    levels = [float(f) for f in ds[FORCE].values] if FORCE in ds.dims else None
    n = int(ds.sizes[REALIZATION])
    out = {
        "realizations": n,
        "blankholder_force_levels_N": levels,
        "blankholder_model": ds.attrs.get("blankholder_model", "radial"),
        "valid_fraction": float(count.sum()) / (n * count.size),
        "max_abs_mean_shear_deg": _site(abs(node_stats["mean"])),
        "max_sd_deg": _site(node_stats["sd"]),
        "max_wrinkle_probability": None,
        "samples_needed": None,
    }
    if exceedance is None:
        exceedance = wrinkle_risk(ds, confidence)
    if exceedance is not None:
        site = _site(exceedance["probability"])
        if site["value"] is not None:
            at = exceedance.sel(_sel(site))
            site.update(lower=float(at["probability_lower"]), upper=float(at["probability_upper"]),
                        measure=exceedance.attrs.get("risk", f"P(|shear| > {float(exceedance['threshold']):g}°)"),
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
