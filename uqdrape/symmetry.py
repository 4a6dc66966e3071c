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


def quadrant_gaps(surface, spacing, rings, material, forces, k_max, drape_kwargs):
    """The −/+ gap (deg) of one energy drape of ``material`` at each blank-holder force of
    ``forces`` (N), averaged over nodes 1..``k_max`` (None: the largest valid in every
    drape), and that k_max. ``drape_kwargs`` (a dict) go to :func:`uqdrape.drape.drape`."""
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
    gaps, k_max = quadrant_gaps(surface, spacing, rings, material, first, None, drape_kwargs)
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
        seen.update(zip(more, quadrant_gaps(surface, spacing, rings, material, more, k_max, drape_kwargs)[0]))
    lo, hi = bracket()
    while hi / max(lo, 1e-300) - 1.0 > rtol:
        inner = ([hi * (k + 1) / (batch + 1) for k in range(batch)] if lo == 0.0 else
                 [lo * (hi / lo) ** ((k + 1) / (batch + 1)) for k in range(batch)])
        seen.update(zip(inner, quadrant_gaps(surface, spacing, rings, material, inner, k_max, drape_kwargs)[0]))
        lo, hi = bracket()
    g_lo, g_hi = seen[lo], seen[hi]
    w = (g_lo - target) / (g_lo - g_hi)
    force = lo + w * (hi - lo) if lo == 0.0 else math.exp(math.log(lo) + w * math.log(hi / lo))
    return result(float(force), lo, hi)


# ----------------------------------------------------------------------------- the card's imbalance from a trial


def _family(material):
    from .material.imbalance import with_imbalance

    return lambda value: with_imbalance(material, value)


@dataclass(frozen=True)
class ImbalanceBounds:
    """Result of :func:`imbalance_bounds`: the ΔN(30°) (N/m, F_s/L) range of the card
    family in which the drape is symmetric at every force of ``symmetric_at`` and not at
    any of ``asymmetric_at``, as ``lower < ΔN <= upper``. A side with no statement, or
    whose root lies outside ``bounds``, is None (open)."""

    lower: float | None
    upper: float | None
    symmetric_at: tuple[float, ...]
    asymmetric_at: tuple[float, ...]
    fraction: float
    bounds: tuple[float, float]
    drapes: int


def imbalance_bounds(surface, spacing, rings, material, *, symmetric_at=(), asymmetric_at=(), fraction=0.1,
                     bounds=(0.5, 2000.0), rtol=1e-3, **drape_kwargs) -> ImbalanceBounds:
    """The mid-angle imbalances ΔN(30°) of ``material``'s family
    (``uqdrape.material.imbalance.with_imbalance``) that agree with a forming trial's
    statements: symmetric (gap <= ``fraction`` × gap(0 N), as :func:`symmetrising_force`)
    at each force (N) of ``symmetric_at``, not symmetric at each of ``asymmetric_at``.

    The thesis's nose cone, "almost symmetric at 252 N, entirely symmetric at 378 N", is
    ``asymmetric_at=(252,), symmetric_at=(378,)``. Deterministic energy drapes (arguments
    as :func:`symmetrising_force`); for each stated force F the ΔN at which gap(F) /
    gap(0 N) = ``fraction`` is found by Brent's method in log ΔN within ``bounds`` to
    ``rtol``, the gap ratio being taken to rise with ΔN (more imbalance, more force to
    symmetrise). Raises ValueError when the statements admit no ΔN in ``bounds``."""
    from scipy.optimize import brentq

    symmetric = tuple(sorted({float(f) for f in symmetric_at}))
    asymmetric = tuple(sorted({float(f) for f in asymmetric_at}))
    if not symmetric and not asymmetric:
        raise ValueError("give at least one force in symmetric_at or asymmetric_at (N)")
    if min((*symmetric, *asymmetric)) <= 0.0:
        raise ValueError("the stated forces must be > 0 N (the gap is measured against 0 N)")
    if not 0.0 < fraction < 1.0 or not 0.0 < bounds[0] < bounds[1]:
        raise ValueError(f"fraction must lie in (0, 1) and bounds be 0 < low < high N/m, got {fraction!r}, {bounds!r}")
    card = _family(material)
    forces = [0.0, *sorted({*symmetric, *asymmetric})]
    k_max = quadrant_gaps(surface, spacing, rings, material, [0.0], None, drape_kwargs)[1]
    ratios = {}

    def ratio(log_value: float, force: float) -> float:
        if log_value not in ratios:
            gaps = quadrant_gaps(surface, spacing, rings, card(math.exp(log_value)), forces, k_max, drape_kwargs)[0]
            ratios[log_value] = dict(zip(forces, np.divide(gaps, gaps[0])))
        return ratios[log_value][force] - fraction

    lo, hi = math.log(bounds[0]), math.log(bounds[1])

    def root(force: float) -> float | None:
        """ΔN at which the gap at ``force`` is ``fraction`` of gap(0); None outside bounds."""
        if ratio(lo, force) >= 0.0 or ratio(hi, force) <= 0.0:
            return None
        return math.exp(brentq(ratio, lo, hi, args=(force,), xtol=rtol / 2, rtol=rtol / 2))

    def edge(force: float, below: bool) -> float | None:
        value = root(force)
        if value is None and (ratio(lo, force) >= 0.0) == below:  # the whole range on the wrong side
            raise ValueError(f"no dN(30 deg) in {bounds[0]:g}-{bounds[1]:g} N/m is "
                             f"{'symmetric' if below else 'asymmetric'} at {force:g} N")
        return value

    uppers = [v for v in (edge(f, True) for f in symmetric) if v is not None]
    lowers = [v for v in (edge(f, False) for f in asymmetric) if v is not None]
    upper, lower = (min(uppers) if uppers else None), (max(lowers) if lowers else None)
    if upper is not None and lower is not None and lower >= upper:
        raise ValueError(f"the statements contradict each other in this card family: asymmetric at "
                         f"{asymmetric} N needs dN(30 deg) > {lower:.4g} N/m, symmetric at {symmetric} N "
                         f"needs <= {upper:.4g} N/m")
    return ImbalanceBounds(lower, upper, symmetric, asymmetric, float(fraction), tuple(map(float, bounds)),
                           (len(ratios) + 1) * len(forces))


@dataclass(frozen=True)
class ImbalancePosterior:
    """Result of :meth:`GapModel.posterior`: ``grid`` ΔN(30°) (N/m, F_s/L, log-spaced),
    ``density`` the posterior per unit ln ΔN on it, its equal-tailed ``level``
    ``interval`` and ``median``; ``gaps`` (deg) the trial, read to ``sd_deg``."""

    grid: np.ndarray
    density: np.ndarray
    level: float
    interval: tuple[float, float]
    median: float
    gaps: tuple[float, ...]
    sd_deg: float


@dataclass(frozen=True)
class GapModel:
    """Result of :func:`gap_model`: at each ΔN(30°) of ``values`` (N/m) and each force of
    ``forces`` (N), the mean ``mean`` (deg) and variance ``variance`` (deg², with the
    mean's own Monte Carlo error) of one part's −/+ gap over ``realizations`` drapes."""

    values: np.ndarray
    forces: tuple[float, ...]
    mean: np.ndarray
    variance: np.ndarray
    realizations: int
    zero_angle_sd_deg: float

    def posterior(self, gaps_deg, sd_deg: float, level: float = 0.95) -> ImbalancePosterior:
        """The posterior of ΔN(30°) from one part's gap ``gaps_deg`` (deg) at each of the
        model's forces, each read to ``sd_deg`` (deg): gap ~ N(mean, variance + sd_deg²),
        the parts independent, the prior flat in ln ΔN over the model's range; mean and
        ln of the variance interpolated in ln ΔN (PCHIP) onto a grid 20 times finer."""
        gaps = np.asarray(gaps_deg, dtype=float)
        if gaps.shape != (len(self.forces),) or not np.all(np.isfinite(gaps)):
            raise ValueError(f"gaps_deg must be one finite gap (deg) per force {self.forces}, got {gaps_deg!r}")
        if not 0.0 < level < 1.0 or not sd_deg >= 0.0 or (sd_deg == 0.0 and not np.all(self.variance > 0.0)):
            raise ValueError("0 < level < 1 and sd_deg >= 0 (deg) are needed, sd_deg > 0 for a model without "
                             "part-to-part scatter (zero_angle_sd_deg = 0)")
        from scipy.interpolate import PchipInterpolator

        logs = np.log(self.values)
        fine = np.linspace(logs[0], logs[-1], 20 * (len(logs) - 1) + 1)
        mean = PchipInterpolator(logs, self.mean)(fine)
        var = np.exp(PchipInterpolator(logs, np.log(self.variance + sd_deg**2))(fine))
        log_like = -0.5 * np.sum((gaps - mean) ** 2 / var + np.log(var), axis=1)
        weight = np.exp(log_like - log_like.max())
        cdf = np.concatenate([[0.0], np.cumsum(0.5 * (weight[1:] + weight[:-1]) * np.diff(fine))])
        density = weight / cdf[-1]
        lo, med, hi = np.exp(np.interp([(1 - level) / 2, 0.5, (1 + level) / 2], cdf / cdf[-1], fine))
        return ImbalancePosterior(np.exp(fine), density, float(level), (float(lo), float(hi)), float(med),
                                  tuple(gaps.tolist()), float(sd_deg))


def gap_model(surface, spacing, rings, material, forces, *, zero_angle_sd_deg=0.0, realizations=16,
              grid=(1.0, 100.0), points=25, seed=0, **drape_kwargs) -> GapModel:
    """One part's −/+ gap (deg, as :func:`symmetrising_force` measures it) at each
    blank-holder force of ``forces`` (N) across the mid-angle imbalances ΔN(30°) of
    ``material``'s family (``uqdrape.material.imbalance.with_imbalance``): ``points``
    values log-spaced over ``grid`` (N/m), ``realizations`` energy drapes per force and
    value whose cells carry an iid zero-energy angle of sd ``zero_angle_sd_deg`` (deg; the
    part-to-part scatter, the same draws at every value; 0 gives one drape per force).
    ``drape_kwargs`` go to :func:`uqdrape.drape.drape` (e.g. ``friction``,
    ``blankholder_model``). :meth:`GapModel.posterior` turns a trial into ΔN."""
    forces = tuple(float(f) for f in forces)
    if not forces or min(forces) < 0.0:
        raise ValueError(f"forces must be one or more blank-holder forces >= 0 N, got {forces!r}")
    if not (zero_angle_sd_deg >= 0.0 and 0.0 < grid[0] < grid[1] and points >= 2):
        raise ValueError("zero_angle_sd_deg >= 0 (deg), 0 < grid low < high (N/m) and points >= 2 are needed")
    R = int(realizations) if zero_angle_sd_deg > 0.0 else 1
    if R < 2 and zero_angle_sd_deg > 0.0:
        raise ValueError(f"realizations must be >= 2 to estimate the scatter, got {realizations!r}")
    n = int(rings)
    draws = np.random.default_rng(seed).normal(0.0, zero_angle_sd_deg, (R, 2 * n, 2 * n))
    gamma0 = np.tile(draws, (len(forces), 1, 1))
    k_max = quadrant_gaps(surface, spacing, rings, material, [0.0], None, drape_kwargs)[1]
    card = _family(material)
    values = np.geomspace(grid[0], grid[1], points)
    mean = np.empty((points, len(forces)))
    variance = np.zeros((points, len(forces)))
    for p, value in enumerate(values):
        ds = drape(surface, spacing, rings, mode="energy", material=card(value), blankholder_force=np.repeat(forces, R),
                   gamma0=gamma0, **drape_kwargs)
        gap = -line_scalars(ds, k_max)["asymmetry"].values.reshape(len(forces), R)
        if not np.all(np.isfinite(gap)):
            raise ValueError(f"the max-shear lines are not valid to node k_max = {k_max} in every drape at "
                             f"dN(30 deg) = {value:.4g} N/m; use fewer rings")
        mean[p] = gap.mean(axis=1)
        if R > 1:
            variance[p] = gap.var(axis=1, ddof=1) * (1.0 + 1.0 / R)
    return GapModel(values, forces, mean, variance, R, float(zero_angle_sd_deg))
