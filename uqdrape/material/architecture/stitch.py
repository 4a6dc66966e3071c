"""The stitch's energy terms: thread tension (Eq 4.1-4.13) and its friction through the
pass-through points (Eq 4.24-4.33), J/m² per unit initial fabric area."""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

from .fabric import Architecture
from .geometry import pass_through_lengths, stitch_length, stitch_strain
from .grid import branchwise, outward


def _tension(arch: Architecture, strain):
    """Thread tension S(ε) (N), 0 when slack; and the stored energy per free length ∫_0^ε S dε (N)."""
    e = np.maximum(strain, 0.0)
    if arch.tension_curve is None:
        k = arch.stitch_stiffness_N
        return k * e, 0.5 * k * e * e
    x, t = (np.asarray(v, dtype=float) for v in arch.tension_curve)
    slope = (t[-1] - t[-2]) / (x[-1] - x[-2])
    cum = cumulative_trapezoid(t, x, initial=0.0)
    inside = np.minimum(e, x[-1])
    tension = np.interp(inside, x, t) + slope * (e - inside)
    k = np.clip(np.searchsorted(x, inside, side="right") - 1, 0, x.size - 2)
    tk = t[k] + (inside - x[k]) * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    energy = cum[k] + 0.5 * (t[k] + tk) * (inside - x[k])
    energy = energy + (e - inside) * (t[-1] + 0.5 * slope * (e - inside))
    return tension, energy


def stitch_terms(arch: Architecture, theta):
    """(W_tension, W_friction, tension S) on the grid θ (rad, containing 0): J/m², J/m², N."""
    free = stitch_length(arch, 0.0) / (1.0 + arch.prestrain)
    strain = stitch_strain(arch, theta)
    tension, stored = _tension(arch, strain)
    # failure: from the first grid point (walking out from 0) at or past the failure strain
    # the thread carries nothing and its stored energy stays where it was
    for idx in outward(theta):
        broken = np.maximum.accumulate(strain[idx] >= arch.failure_strain)
        if broken.any():
            first = idx[int(np.argmax(broken))]
            stored[idx[broken]] = stored[first]
            tension[idx[broken]] = 0.0
    to_j_per_m2 = 1e3 / arch.unit_area_mm2  # N·mm per mm² -> J/m²
    zero = outward(theta)[0][0]
    w_tension = (stored - stored[zero]) * free * to_j_per_m2
    # friction, Eq 4.30-4.33: slip through every pass-through point against the uniform strain
    lengths = pass_through_lengths(arch, theta)
    geometric = stitch_length(arch, theta) / stitch_length(arch, 0.0) - 1.0
    slip = np.abs(lengths - (1.0 + geometric)[:, None, None] * lengths[zero]).sum(axis=(-1, -2))
    friction = branchwise(theta, lambda idx: cumulative_trapezoid(tension[idx], slip[idx], initial=0.0))
    w_friction = arch.stitch_friction * friction * to_j_per_m2
    return w_tension, w_friction, tension

