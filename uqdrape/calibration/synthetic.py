"""Synthetic fibre-angle measurements drawn from a known field, to check a calibration.

The values come from the study's own sampler (``uqdrape.stochastic.fields.GaussianField``
on a lattice along fibre 1 and fibre 2), plus independent measurement error, so a fit
that gets the parameters back gets back what a study would draw.
"""

from __future__ import annotations

import numpy as np

from ..stochastic.fields import GaussianField


def synthetic_set(rng: np.random.Generator, family: str, *, sd_deg: float, length_mm=None, nugget_deg: float = 0.0,
                  mean_deg: float = 0.0, lattice: tuple[int, int] = (40, 40), spacing_mm: float = 5.0,
                  points: int | None = None):
    """(a, b, y): fibre coordinates (mm) and values (deg) of one measurement set: the
    field of ``family`` (sd ``sd_deg``, ``length_mm`` along fibre 1 and 2) on a ``lattice``
    of nodes ``spacing_mm`` apart, at every node (``points`` None) or at ``points`` nodes
    drawn without replacement (scattered points), plus N(0, ``nugget_deg``²) error."""
    field = GaussianField(lattice, spacing_mm, family, length_mm)
    values = mean_deg + sd_deg * field.sample(rng.standard_normal(lattice))
    a, b = np.meshgrid(spacing_mm * np.arange(lattice[0]), spacing_mm * np.arange(lattice[1]), indexing="ij")
    a, b, values = a.ravel(), b.ravel(), values.ravel()
    if points is not None:
        keep = rng.choice(len(values), size=points, replace=False)
        a, b, values = a[keep], b[keep], values[keep]
    return a, b, values + nugget_deg * rng.standard_normal(len(values))
