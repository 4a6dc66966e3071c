"""The symmetrising blank-holder force: how much force makes an asymmetric NCF drape symmetric.

Thesis §5.2.4: with EBXhd-936 over the nose cone the − and + shear quadrants differ at
0 N, less at 126 N, "almost symmetric" at 252 N and "entirely symmetric" at 378 N.
:func:`symmetrising_force` measures that force for a material: the blank-holder force at
which the quadrant gap has fallen to ``fraction`` of its 0 N value.

The gap (deg) is −``asymmetry`` of :func:`uqdrape.stats.line_scalars`: the mean
|shear| on the max-shear lines of the − quadrants (−+, +−) minus that of the +
quadrants (++, −−), averaged over nodes k = 1..k_max, with k_max fixed by the 0 N drape
so that every force averages the same nodes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .drape import drape
from .stats import line_scalars

#: Forces (N) of the first batch besides 0 N: the thesis's experimental levels.
THESIS_FORCES = (126.0, 252.0, 378.0)


@dataclass(frozen=True)
class SymmetrisingForce:
    """Result of :func:`symmetrising_force`. Forces in N, gaps in degrees.

    ``force`` is None when the gap did not fall to ``target`` at any force up to
    ``f_max``; then ``bracket`` is (largest force draped, None).
    """

    force: float | None
    fraction: float
    gap0: float
    target: float
    bracket: tuple[float, float | None]
    tolerance: float
    forces: tuple[float, ...]
    gaps: tuple[float, ...]
    k_max: int
    f_max: float

    @property
    def reached(self) -> bool:
        return self.force is not None

    def gap_at(self, force: float) -> float:
        """The gap (deg) measured at a force that was draped."""
        return self.gaps[self.forces.index(float(force))]

    def describe(self) -> str:
        """One line for reports."""
        if not self.reached:
            return (f"gap {self.gap0:.2f} deg at 0 N; not reached below F_max = {self.f_max:g} N "
                    f"(gap still {self.gaps[-1]:.2f} deg there, target {self.target:.2f} deg = "
                    f"{self.fraction:g} x gap(0))")
        return (f"gap {self.gap0:.2f} deg at 0 N falls to {self.fraction:g} x that ({self.target:.2f} deg) "
                f"at {self.force:.0f} N (bracket {self.bracket[0]:g}-{self.bracket[1]:g} N)")


def _gaps(surface, spacing, rings, material, forces, k_max, drape_kwargs):
    ds = drape(surface, spacing, rings, mode="energy", material=material, blankholder_force=list(forces),
               **drape_kwargs)
    scalars = line_scalars(ds, k_max) if k_max else line_scalars(ds)
    gaps = -scalars["asymmetry"].values
    if not np.all(np.isfinite(gaps)):
        bad = [f for f, g in zip(forces, gaps) if not np.isfinite(g)]
        raise ValueError(f"the max-shear lines are not valid to node k_max = {scalars.attrs['k_max']} at "
                         f"{', '.join(f'{f:g}' for f in bad)} N; use fewer rings")
    return [float(g) for g in gaps], int(scalars.attrs["k_max"])


def symmetrising_force(surface, spacing, rings, material, *, fraction=0.1, forces=THESIS_FORCES,
                       f_max=1e4, rtol=0.05, batch=3, **drape_kwargs) -> SymmetrisingForce:
    """The blank-holder force (N) at which the −/+ quadrant gap falls to ``fraction`` × gap(0 N).

    Energy drapes of ``material`` over ``surface`` (spacing mm, rings as for
    :func:`uqdrape.drape.drape`; ``drape_kwargs`` go to it unchanged, e.g. ``friction``,
    ``orientation`` or a blank-holder model). Each round is one batched drape:

    1. 0 N and ``forces``; then, until the target is bracketed, ``batch`` forces doubling
       from the largest so far, up to ``f_max`` (not reached: ``force`` None);
    2. the bracket [lo, hi] (gap(lo) > target >= gap(hi)) is cut by ``batch`` interior
       forces, evenly spaced in log force (linear when lo = 0), until hi/lo − 1 <= ``rtol``;
    3. ``force`` interpolates the gap linearly in log force between lo and hi (in force
       when lo = 0).

    The gap is assumed to fall monotonically with force (as the thesis reports and the
    shipped NCF cards show); the first bracketed crossing is returned. A fabric without
    a gap at 0 N (gap(0) <= 0) is symmetric already: force 0.
    """
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"fraction must lie in (0, 1), got {fraction!r}")
    if batch < 1 or rtol <= 0.0:
        raise ValueError(f"batch must be >= 1 and rtol > 0, got batch={batch!r}, rtol={rtol!r}")
    forces = sorted({float(f) for f in forces if 0.0 < f <= f_max})
    first = [0.0, *forces]
    gaps, k_max = _gaps(surface, spacing, rings, material, first, None, drape_kwargs)
    seen = dict(zip(first, gaps))
    gap0 = seen[0.0]
    target = fraction * gap0

    def result(force, lo, hi):
        keys = sorted(seen)
        return SymmetrisingForce(force, fraction, gap0, target, (lo, hi), rtol, tuple(keys),
                                 tuple(seen[f] for f in keys), k_max, float(f_max))

    if gap0 <= 0.0:
        return result(0.0, 0.0, 0.0)

    def bracket():
        keys = sorted(seen)
        for lo, hi in zip(keys, keys[1:]):
            if seen[lo] > target >= seen[hi]:
                return lo, hi
        return None

    while bracket() is None:
        top = max(seen)
        if top >= f_max:
            return result(None, top, None)
        more = [min(top * 2.0 ** (k + 1), f_max) for k in range(batch)] if top > 0 else [min(126.0, f_max)]
        more = sorted(set(more))
        seen.update(zip(more, _gaps(surface, spacing, rings, material, more, k_max, drape_kwargs)[0]))
    lo, hi = bracket()
    while hi / max(lo, 1e-300) - 1.0 > rtol:
        if lo == 0.0:
            inner = [hi * (k + 1) / (batch + 1) for k in range(batch)]
        else:
            inner = [lo * (hi / lo) ** ((k + 1) / (batch + 1)) for k in range(batch)]
        seen.update(zip(inner, _gaps(surface, spacing, rings, material, inner, k_max, drape_kwargs)[0]))
        lo, hi = bracket()
    g_lo, g_hi = seen[lo], seen[hi]
    w = (g_lo - target) / (g_lo - g_hi)
    force = lo + w * (hi - lo) if lo == 0.0 else math.exp(math.log(lo) + w * math.log(hi / lo))
    return result(float(force), lo, hi)
