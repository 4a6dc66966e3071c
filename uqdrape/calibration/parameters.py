"""The study parameters a calibration from measured drapes estimates: each a dotted study
key with a uniform prior box (``KEY=LOW:HIGH``, ``uqdrape calibrate --drapes
--parameter``), and the study document with them at their posterior medians."""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import date
from pathlib import Path

import numpy as np

from .._version import __version__
from ..errors import ParameterError
from ..files import is_number
from .block import sd_dof
from .fit import Estimate


@dataclass(frozen=True)
class Parameter:
    """A calibrated study parameter: its dotted study key and uniform prior box (its units)."""

    key: str
    lower: float
    upper: float


def parse_parameters(texts, study) -> list[Parameter]:
    """``KEY=LOW:HIGH`` texts (``--parameter``) as Parameters: KEY a number of ``study``
    (defaults filled, e.g. ``process.friction``, ``uncertainty.zero_angle.sd_deg``)."""
    params = []
    doc = study.to_dict()
    for text in texts:
        key, _, box = text.partition("=")
        lo, _, hi = box.partition(":")
        value = doc
        for name in key.split("."):
            value = value.get(name) if isinstance(value, dict) else None
        if not is_number(value):
            raise ParameterError("parameters", f"{text!r}: {key!r} is not a number of {study.path} (with defaults "
                             "filled); give a dotted study key such as process.friction or "
                             "uncertainty.zero_angle.sd_deg, as KEY=LOW:HIGH (a key without a default, "
                             "such as fabric.imbalance_Nm, must be set in the study file first)")
        try:
            lower, upper = float(lo), float(hi)
        except ValueError:
            lower = upper = math.nan
        if not (math.isfinite(lower) and math.isfinite(upper) and lower < upper):
            raise ParameterError("parameters", f"{text!r}: the prior box must be LOW:HIGH, two numbers with "
                                 "LOW < HIGH")
        if key in (p.key for p in params):
            raise ParameterError("parameters", f"{key} is given twice")
        params.append(Parameter(key, lower, upper))
    if not params:
        raise ParameterError("parameters", "a calibration from drapes needs at least one parameter KEY=LOW:HIGH")
    return params


def calibrated_study(doc: dict, cal, command: str, fraction: float) -> tuple[dict, str]:
    """The study document ``doc`` (the study file's own) with each parameter of ``cal``
    (a ``drapes.DrapeCalibration``) at its posterior median (and, for the zero-angle sd,
    sd_dof from its interval), renamed "-calibrated"; the fit as comments, ``fraction``
    the share of measured points inside the predictive band."""
    name = f"{doc['study']['name']}-calibrated"
    overrides = {"study.name": name}
    if "directory" in doc.get("output", {}):
        overrides["output.directory"] = str(Path(doc["output"]["directory"]).parent / name)
    level = 100 * cal.level
    post = cal.posterior
    lines = [f"{name}: calibrated by `{command}` (uqdrape {__version__}, {date.today().isoformat()})",
             f"from {len(cal.parts)} measured part(s): " + ", ".join(Path(p.source).name for p in cal.parts)
             + f"; {len(cal.distance_mm)} distinct points, measurement sd {cal.likelihood.parts.measurement_sd:g} deg",
             f"emulator: a GP per point's ensemble mean and log sd over {len(cal.runs.points)} training points of "
             f"{cal.runs.shear.shape[1] // 2} realisations (uqdrape.calibration.drapes)",
             f"posterior (emcee, {len(next(iter(post.samples.values())))} draws, acceptance {post.acceptance:.2f}, "
             f"{post.seconds:.1f} s): median and {level:g} % interval, uniform prior in the box"]
    for p in cal.params:
        lo, hi = cal.interval(p)
        value = float(f"{np.median(post.samples[p.key]):.4g}")
        overrides[p.key] = value
        lines.append(f"  {p.key} = {value:.4g}  [{lo:.4g}, {hi:.4g}]  prior [{p.lower:g}, {p.upper:g}]  "
                     f"autocorrelation {post.autocorrelation[p.key]:.0f} steps")
        if p.key == "uncertainty.zero_angle.sd_deg":
            m = None if post.at_bounds(p.key, p.lower, p.upper) else sd_dof(Estimate(value, lo, hi), cal.level)
            if m is not None:
                overrides["uncertainty.zero_angle.sd_dof"] = float(f"{m:.4g}")
                lines.append(f"  sd_dof = {m:.4g}: the sd's interval as a scaled-inverse-chi-square one "
                             "(a hierarchical ensemble; delete it for a fixed sd)")
    lines += [f"WARNING: {u}" for u in cal.unidentified()]
    lines.append(f"posterior-predictive check: {100 * fraction:.0f} % of the measured points inside the "
                 f"{level:g} % predictive band")
    for key, value in overrides.items():
        *tables, leaf = key.split(".")
        table = doc
        for t in tables:
            table = table.setdefault(t, {})
        table[leaf] = value
    return doc, "\n".join(lines)
