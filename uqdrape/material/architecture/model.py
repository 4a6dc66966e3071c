"""The summed model: every term's energy on the θ grid, and N_s from the energy (Eq 4.14-4.15)."""

from __future__ import annotations

import numpy as np

from .compaction import compaction_energy
from .crossover import crossover_energy
from .fabric import Architecture
from .geometry import area_ratio
from .grid import GRID_LIMIT_DEG, branchwise, outward, theta_grid
from .stitch import stitch_terms

#: Version of this model, recorded in every derived card.
MODEL_VERSION = "wiggers2007-ch4/1"
#: The energy terms of thesis §4.3, in the order cards record them.
TERMS = ("stitch_tension", "stitch_friction", "compaction", "crossover")


def energy_terms(arch: Architecture, theta_rad=None) -> dict:
    """Each term's energy per unit initial area W (J/m²) on the grid θ (rad, must hold 0).

    Returns {"theta": θ, term: W for term in TERMS}; +inf where the tows are locked.
    """
    theta = theta_grid(min(GRID_LIMIT_DEG, arch.locking_angle_deg)) if theta_rad is None else np.asarray(theta_rad)
    if not np.any(theta == 0.0):
        raise ValueError("the θ grid must contain 0 (energies are integrated outward from it)")
    w_t, w_f, _ = stitch_terms(arch, theta)
    return {"theta": theta, "stitch_tension": w_t, "stitch_friction": w_f,
            "compaction": compaction_energy(arch, theta), "crossover": crossover_energy(arch, theta)}


def branch_forces(arch: Architecture, theta, energy):
    """N_s = (dW/dθ) sin 2φ0 / sin(2φ0 − θ) (Eq 4.14-4.15), N/m, by np.gradient within each
    branch (one-sided at θ = 0, so a term with a kink at 0, friction, keeps its jump).

    Returns ((θ ≥ 0, N_s), (θ ≤ 0, N_s)), both starting at θ = 0 and running outward.
    """
    return tuple((theta[idx], _branch_force(arch, theta, energy, idx)) for idx in outward(theta))


def _branch_force(arch: Architecture, theta, energy, idx):
    """N_s (N/m) along one branch ``idx`` of the grid (see branch_forces)."""
    return np.gradient(energy[idx], theta[idx]) / area_ratio(arch, theta[idx])


def shear_force(arch: Architecture, theta, energy):
    """N_s (N/m) on the grid θ (see branch_forces); at θ = 0 the negative side's value."""
    return branchwise(theta, lambda idx: _branch_force(arch, theta, energy, idx))


def summed(arch: Architecture, theta_rad=None) -> dict:
    """energy_terms plus "total" W (J/m²) and N_s per term and in total (N/m): keys
    ``ns_<term>`` and ``ns_total``."""
    terms = energy_terms(arch, theta_rad)
    theta = terms["theta"]
    terms["total"] = sum(terms[t] for t in TERMS)
    for t in (*TERMS, "total"):
        terms[f"ns_{t}"] = shear_force(arch, theta, terms[t])
    return terms

