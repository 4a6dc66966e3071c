"""Lateral tow compaction at constant thickness (Eq 4.35) with the Cai-Gutowski/McBride
bulk-stress law (Eq 2.23-2.29)."""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import cumulative_trapezoid

from .fabric import Architecture
from .geometry import area_ratio
from .grid import branchwise


def fibre_volume_fraction(arch: Architecture, theta_rad):
    """Tow V_f(θ) at constant thickness, Eq 4.35."""
    return arch.vf0 / area_ratio(arch, np.asarray(theta_rad, dtype=float))


def bulk_stress(arch: Architecture, vf):
    """Cai-Gutowski/McBride lateral bulk stress σ_b (Pa, compression > 0) at tow V_f, Eq 2.23-2.29.

    ε_b = sqrt(V_f/V0) − 1 (compression positive), ζ = sqrt(V_a/V_f);
    B_ll = 4ζ²[1 + 2(ζ−1)²]/(πE_f), B_bl = −16β²ζ(ζ−1)³/(π³E_f),
    B_bb = β⁴(ζ−1)⁴/(3πE_f) and σ_b = ε_b B_ll/(B_bb B_ll − B_bl²) (zero axial strain).
    B_bb is read with β⁴ where the extracted Eq 2.27 shows ζ⁴: only then is the
    determinant positive for any β (B_bl²/(B_bb B_ll) ≤ 192/π⁴·½ < 1) and Eq 2.29
    reduces to Gutowski's σ_b = (3πE_f/β⁴)(sqrt(V_f/V0) − 1)/(ζ − 1)⁴ without coupling.
    σ_b = 0 below V0, +inf at or beyond V_a.
    """
    vf = np.asarray(vf, dtype=float)
    e_f = arch.fibre_modulus_GPa * 1e9
    with np.errstate(divide="ignore", invalid="ignore"):
        zeta = np.sqrt(arch.va / vf)
        b_ll = 4.0 * zeta**2 * (1.0 + 2.0 * (zeta - 1.0) ** 2) / (math.pi * e_f)
        b_bl = -16.0 * arch.beta**2 * zeta * (zeta - 1.0) ** 3 / (math.pi**3 * e_f)
        b_bb = arch.beta**4 * (zeta - 1.0) ** 4 / (3.0 * math.pi * e_f)
        sigma = (np.sqrt(vf / arch.v0) - 1.0) * b_ll / (b_bb * b_ll - b_bl**2)
    return np.where(vf >= arch.va, np.inf, np.where(vf <= arch.v0, 0.0, sigma))


def compaction_energy(arch: Architecture, theta):
    """W_c(θ) = −∫ σ_b dV, V = t0 · area ratio (both tow layers, per unit initial area), J/m²."""
    sigma = bulk_stress(arch, fibre_volume_fraction(arch, theta))
    t0 = arch.thickness_mm * 1e-3
    dvol = t0 * np.gradient(area_ratio(arch, theta), theta)  # m per rad
    return branchwise(theta, lambda idx: cumulative_trapezoid(-sigma[idx] * dvol[idx], theta[idx], initial=0.0))

