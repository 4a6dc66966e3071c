"""Calibration of the constants the thesis does not print: McBride's β and the stitch pre-strain."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.optimize import brentq

from .compaction import compaction_energy
from .crossover import crossover_energy
from .fabric import Architecture
from .grid import theta_grid
from .model import shear_force
from .stitch import stitch_terms
from .zero_force import TABLE_PRESTRAINS, FixedTerms


def calibrate(arch: Architecture, *, zero_force_angle_deg=None, negative_ns=None, iterations=6) -> Architecture:
    """The architecture with ``beta`` and/or ``prestrain`` fitted to thesis targets.

    ``negative_ns`` = (angle deg > 0, N_s N/m): β such that the summed negative-branch
    N_s at −angle equals the value. σ_b (so the compaction and crossover terms) scales
    exactly as β⁻⁴ (see bulk_stress), so β = (K/(N − N_stitch))^¼ with K their N_s at
    β = 1. ``zero_force_angle_deg`` (< 0): the pre-strain whose γ0 equals it (brentq).
    The two fits are alternated until both hold (β barely moves γ0). The result's
    ``calibration`` records the targets and the fitted values.
    """
    record = dict(arch.calibration)
    for _ in range(iterations):
        before = (arch.beta, arch.prestrain)
        if negative_ns is not None:
            angle, target = (float(v) for v in negative_ns)
            theta = theta_grid(angle + 1.0)  # central differences at -angle, as in summed()
            at = int(np.argmin(np.abs(theta + math.radians(angle))))
            unit = replace(arch, beta=1.0)
            k_ns = -shear_force(unit, theta, compaction_energy(unit, theta) + crossover_energy(unit, theta))[at]
            w_t, w_f, _ = stitch_terms(arch, theta)
            stitch = -shear_force(arch, theta, w_t + w_f)[at]
            if not target > stitch:
                raise ValueError(f"negative_ns target {target:g} N/m at -{angle:g} deg is not above the stitch "
                                 f"terms' {stitch:.3g} N/m there")
            arch = replace(arch, beta=float((k_ns / (target - stitch)) ** 0.25))
        if zero_force_angle_deg is not None:
            target = float(zero_force_angle_deg)
            fixed = FixedTerms(arch)
            top = float(TABLE_PRESTRAINS[-1])
            if not fixed.zero_force_angle(top) < target < 0.0:
                raise ValueError(f"zero_force_angle_deg = {target:g} must lie in "
                                 f"({fixed.zero_force_angle(top):.3g}, 0) deg for this architecture")
            eps = brentq(lambda e: fixed.zero_force_angle(e) - target, 0.0, top, xtol=1e-9)
            arch = replace(arch, prestrain=float(eps))
        if negative_ns is None or zero_force_angle_deg is None:
            break
        if np.allclose((arch.beta, arch.prestrain), before, rtol=1e-10, atol=0.0):
            break
    if negative_ns is not None:
        record.update(beta=arch.beta, negative_ns_angle_deg=float(negative_ns[0]),
                      negative_ns_N_per_m=float(negative_ns[1]))
    if zero_force_angle_deg is not None:
        record.update(prestrain=arch.prestrain, zero_force_angle_deg=float(zero_force_angle_deg))
    return replace(arch, calibration=record)

