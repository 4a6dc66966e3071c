"""The zero-force angle γ0: the rest state of the summed energy next to the knitted state,
and its table over the stitch pre-strain (for random pre-strain fields)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .compaction import compaction_energy
from .crossover import crossover_energy
from .fabric import Architecture
from .grid import theta_grid
from .stitch import stitch_terms

#: Grid half-range (deg) on which zero-force angles are sought.
ZERO_SEARCH_DEG = 40.0


def _zero_force(theta, total):
    """γ0 (deg): walking downhill on the summed energy from θ = 0 (the knitted state) to
    the first local minimum, refined within the grid step (see below). A fabric whose
    stitch friction resists more than the stitch tension pulls stays at 0."""
    k = int(np.argmin(np.abs(theta)))
    step = -1 if total[k - 1] < total[k] else 1 if total[k + 1] < total[k] else 0
    if step == 0:
        return 0.0
    while 0 < k + step < theta.size - 1 and total[k + step] < total[k]:
        k += step
    if not 0 < k + step < theta.size - 1:
        raise ValueError(f"the zero-force angle lies beyond ±{np.rad2deg(abs(theta[k])):g} deg")
    # the slopes of the two grid steps next to the minimum (at their midpoints) change sign:
    # their zero, by linear interpolation, is the minimum to within one grid step
    down, up = total[k] - total[k - 1], total[k + 1] - total[k]
    if up - down <= 0.0:
        return float(np.rad2deg(theta[k]))
    h = theta[k + 1] - theta[k]
    return float(np.rad2deg(theta[k] - h / 2.0 + h * (-down) / (up - down)))


class FixedTerms:
    """The terms that do not depend on the stitch pre-strain, on the γ0 search grid."""

    def __init__(self, arch: Architecture):
        self.arch = arch
        self.theta = theta_grid(ZERO_SEARCH_DEG)
        self.w = compaction_energy(arch, self.theta) + crossover_energy(arch, self.theta)

    def zero_force_angle(self, prestrain: float) -> float:
        arch = replace(self.arch, prestrain=float(prestrain))
        w_t, w_f, _ = stitch_terms(arch, self.theta)
        return _zero_force(self.theta, self.w + w_t + w_f)


def zero_force_angle(arch: Architecture) -> float:
    """γ0 (deg): the rest state of the summed energy next to θ = 0 (< 0 when the
    pre-strained stitch pulls harder than its friction holds; see _zero_force)."""
    return FixedTerms(arch).zero_force_angle(arch.prestrain)


@dataclass(frozen=True)
class ZeroForceTable:
    """Pre-strain -> zero-force angle γ0 of one architecture, tabulated once, vectorised.

    ``prestrain`` (fractions, from 0 to ``max_prestrain``) and ``gamma0_deg`` are the
    nodes; between them a monotone cubic (PCHIP). A thread with ε0 <= 0 is slack at
    θ = 0, so γ0 = 0 there exactly (the remaining terms are least at 0); values above
    ``max_prestrain`` are refused.
    """

    prestrain: np.ndarray
    gamma0_deg: np.ndarray

    @property
    def max_prestrain(self) -> float:
        return float(self.prestrain[-1])

    def __call__(self, prestrain):
        """γ0 (deg) for any array of pre-strains (fractions)."""
        from scipy.interpolate import PchipInterpolator

        e = np.asarray(prestrain, dtype=float)
        if e.size and not np.nanmax(e) <= self.max_prestrain:
            raise ValueError(f"stitch pre-strain {np.nanmax(e):g} is beyond the mapped range "
                             f"[0, {self.max_prestrain:g}]")
        return PchipInterpolator(self.prestrain, self.gamma0_deg)(np.maximum(e, 0.0))


#: Pre-strains tabulated by zero_force_table: 0 to 3 % (γ0 to about -16 deg for the FGE
#: 106hd tricot), 0.1 % apart.
TABLE_PRESTRAINS = np.round(np.linspace(0.0, 0.03, 31), 6)


def zero_force_table(arch: Architecture, prestrains=TABLE_PRESTRAINS) -> ZeroForceTable:
    """Tabulate γ0(ε0) for the architecture (its own pre-strain is ignored)."""
    fixed = FixedTerms(arch)
    e = np.asarray(prestrains, dtype=float)
    return ZeroForceTable(e, np.array([fixed.zero_force_angle(v) for v in e]))

