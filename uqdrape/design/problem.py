"""A blank-holder design problem: the decision variables of a study's ``[design]``, their
bounds and baseline, and the independent validation sample (seed
``SeedSequence([study seed, VALIDATION_STREAM])``)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

#: The validation sample's seed is SeedSequence([study seed, VALIDATION_STREAM]).
VALIDATION_STREAM = 13


def validation_seed(study) -> int:
    """The seed of the independent validation sample of a design study."""
    return int(np.random.SeedSequence([study.seed, VALIDATION_STREAM]).generate_state(1)[0])


@dataclass(frozen=True)
class Problem:
    """A design problem: the study, its variable names and bounds, and the two samples."""

    study: object
    names: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    baseline: tuple[float, ...]
    validation: object

    @property
    def spec(self):
        return self.study.design

    @property
    def n_forces(self) -> int:
        return self.spec.sectors or 1

    def settings(self, x) -> tuple[float, tuple[float, ...] | None, float]:
        """(total force N, sector weights or None, friction) of design vector ``x``."""
        forces = np.asarray(x[: self.n_forces], dtype=float)
        friction = float(x[self.n_forces]) if len(x) > self.n_forces else self.study.process.friction
        total = float(forces.sum())
        if self.spec.sectors is None:
            return total, self.study.process.sectors, friction
        weights = tuple(forces / total) if total > 0 else None
        return total, weights, friction

    def uniform(self, total: float, x) -> np.ndarray:
        """The design with ``total`` spread evenly (sectors), friction as in ``x``."""
        forces = np.full(self.n_forces, total / self.n_forces)
        return np.concatenate([forces, np.asarray(x[self.n_forces:], dtype=float)])


def problem(study) -> Problem:
    """The design problem of a study with a [design] section."""
    spec = study.design
    if spec is None:
        raise ValueError(f"study {study.name!r} ({study.path}) has no [design] section")
    lo, hi = spec.force_bounds_N
    n = spec.sectors or 1
    if spec.budget_N is not None and n == 1:
        hi = min(hi, spec.budget_N)
    names = ("force",) if n == 1 else tuple(f"sector_{k}" for k in range(n))
    bounds = [(lo, hi)] * n
    f0, weights = study.force_levels[0], study.process.sectors
    if n > 1 and weights is not None and len(weights) == n:  # the study's own sectors
        baseline = list(f0 * np.asarray(weights) / np.sum(weights))
    else:
        baseline = [f0 / n] * n
    if spec.friction_bounds is not None:
        names += ("friction",)
        bounds.append(spec.friction_bounds)
        baseline.append(study.process.friction)
    n_val = spec.validation_realizations or study.realizations
    validation = dataclasses.replace(study, seed=validation_seed(study), realizations=n_val)
    return Problem(study, names, tuple(bounds), tuple(baseline), validation)
