"""Friction between the two tow layers over each crossover (Eq 4.37-4.42)."""

from __future__ import annotations

import functools
import math

import numpy as np

from .compaction import bulk_stress, fibre_volume_fraction
from .fabric import Architecture
from .grid import outward

#: Elements per side of the crossover grid (the thesis needed 40 to converge, L7335).
CROSSOVER_ELEMENTS = 40
#: Step of the crossover path-line integration (deg of fabric shear; the thesis used 0.5).
CROSSOVER_STEP_DEG = 0.5


@functools.lru_cache(maxsize=64)
def crossover_slip(a: float, tow_shear_ratio: float, phi0_deg: float, theta_end_rad: float):
    """Slip-area of one crossover: Σ_j A_j l_ij per path step (mm³) and the step ends θ (rad);
    cached, as it depends only on the crossover's geometry.

    Relative velocity of the two tow layers, Eq 4.37: v = Ω(θ)·(−Y, X) with
    Ω = (1 − γ_t/ω)(1 − sin|θ|) per unit fabric shear rate (the field is a rotation about
    the crossover centre; |θ| keeps the two shear directions alike). Path lines start at
    the centres of a 40 × 40 grid over the initial square crossover of side a and are
    integrated by RK4; a step's increment counts only if the point lies inside the
    crossover (two tow strips of width a·sin(2φ0−θ)/sin 2φ0 crossing at 2φ0 − θ) at both
    ends of the step (thesis L7335-7355).
    """
    m = CROSSOVER_ELEMENTS
    centres = (np.arange(m) + 0.5) / m * a - a / 2.0
    x, y = (v.ravel() for v in np.meshgrid(centres, centres))
    # fixed steps from 0 (the last one shorter), so that every grid shares the same path
    step = math.copysign(math.radians(CROSSOVER_STEP_DEG), theta_end_rad)
    whole = int(theta_end_rad / step + 1e-9)
    ts = step * np.arange(whole + 1)
    if abs(theta_end_rad - ts[-1]) > 1e-12:
        ts = np.append(ts, theta_end_rad)
    steps = ts.size - 1
    ratio = 1.0 - tow_shear_ratio
    phi0 = math.radians(phi0_deg)

    def rate(t, px, py):
        om = ratio * (1.0 - math.sin(abs(t))) * math.copysign(1.0, theta_end_rad)
        return -om * py, om * px

    def inside(t, px, py):
        half = 0.5 * a * math.sin(2.0 * phi0 - t) / math.sin(2.0 * phi0)
        # layer 1 along x; layer 2 along the direction at the current inter-tow angle 2φ0 − t
        alpha = 2.0 * phi0 - t
        return (np.abs(py) <= half) & (np.abs(px * math.sin(alpha) - py * math.cos(alpha)) <= half)

    area = a * a / (m * m)
    out = np.zeros(steps)
    was_in = inside(0.0, x, y)
    for k in range(steps):
        t, h = ts[k], ts[k + 1] - ts[k]
        k1 = rate(t, x, y)
        k2 = rate(t + h / 2, x + abs(h) / 2 * k1[0], y + abs(h) / 2 * k1[1])
        k3 = rate(t + h / 2, x + abs(h) / 2 * k2[0], y + abs(h) / 2 * k2[1])
        k4 = rate(t + h, x + abs(h) * k3[0], y + abs(h) * k3[1])
        nx = x + abs(h) / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        ny = y + abs(h) / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        now_in = inside(ts[k + 1], nx, ny)
        both = was_in & now_in
        out[k] = area * np.hypot(nx - x, ny - y)[both].sum()
        x, y, was_in = nx, ny, now_in
    ts.flags.writeable = out.flags.writeable = False  # shared by the cache
    return ts, out


def crossover_energy(arch: Architecture, theta):
    """W_X(θ) = μ Σ P·(slip area) / a² per unit initial area, P = σ_b at the step (J/m²)."""
    w = np.zeros_like(theta)
    a2 = arch.crossover_side_mm**2
    for idx in outward(theta):
        end = theta[idx[-1]]
        if end == 0.0:
            continue
        ts, slip = crossover_slip(arch.crossover_side_mm, arch.tow_shear_ratio, arch.phi0_deg, float(end))
        mid = 0.5 * (ts[1:] + ts[:-1])
        pressure = bulk_stress(arch, fibre_volume_fraction(arch, mid))
        cum = np.concatenate([[0.0], np.cumsum(pressure * slip)])  # Pa·mm³
        w[idx] = arch.crossover_friction * np.interp(np.abs(theta[idx]), np.abs(ts), cum) * 1e-9 / (a2 * 1e-6)
    return w

