"""The θ grid on which every energy term is evaluated, and the walk outward from θ = 0
along each branch (the terms are path integrals from the knitted state)."""

from __future__ import annotations

import numpy as np

#: Step of the θ grid on which the energies are summed and differentiated (deg).
GRID_STEP_DEG = 0.05
#: Half-range of the θ grid (deg): thesis Fig 4.18 plots -75..75.
GRID_LIMIT_DEG = 75.0


def outward(theta):
    """Index arrays walking the grid from θ = 0 outward: (positive branch, negative branch)."""
    zero = int(np.argmin(np.abs(theta)))
    return np.arange(zero, theta.size), np.arange(zero, -1, -1)


def branchwise(theta, fn):
    """Apply fn(indices) -> values along both branches from θ = 0 and merge."""
    out = np.empty_like(theta)
    for idx in outward(theta):
        out[idx] = fn(idx)
    return out


def theta_grid(limit_deg: float | None = None) -> np.ndarray:
    """The symmetric θ grid (rad), GRID_STEP_DEG apart, through 0, up to ±limit_deg."""
    limit = GRID_LIMIT_DEG if limit_deg is None else limit_deg
    n = int(round(limit / GRID_STEP_DEG))
    return np.deg2rad(np.arange(-n, n + 1) * GRID_STEP_DEG)

