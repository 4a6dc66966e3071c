"""Maps from standard normals to the solver's stochastic fabric inputs (thesis §5.3.3).

An input owns one or more :class:`~uqdrape.stochastic.fields.GaussianField` lattices
and is called with a flat vector of standard normals of length ``n_variables`` (batched
over leading axes): exact white noise for Monte Carlo, or KL mode variables after
:meth:`kl` for a design. Lattice points are segment midpoints / cell centres of the flat
blank, ``spacing_mm`` apart along each fibre; axis 0 runs along fibre 1 (i), axis 1
along fibre 2 (j), as in the net arrays.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from ..errors import ParameterError
from ..files import to_float
from .fields import GaussianField


def positive_int(name: str, value) -> int:
    """``value`` as an int, or ValueError naming ``name`` unless it is an integer >= 1."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def _spacing(spacing_mm) -> float:
    s = to_float(spacing_mm)
    if not (math.isfinite(s) and s > 0):
        raise ValueError(f"spacing_mm must be a positive number (mm), got {spacing_mm!r}")
    return s


class _FieldInput:
    """Lattice fields driven by one flat vector of standard normals."""

    def __init__(self, shapes, spacing_mm: float, correlation: str, length_mm):
        self._exact = tuple(GaussianField(sh, spacing_mm, correlation, length_mm) for sh in shapes)
        self.fields = self._exact

    @property
    def n_variables(self) -> int:
        """Standard normals per realisation."""
        return sum(math.prod(f.xi_shape) for f in self.fields)

    def kl(self, retained: float | None = 0.95, n_modes: int | None = None):
        """Copy driven by truncated KL expansions (per field) instead of exact white noise."""
        new = copy.copy(self)
        new.fields = tuple(f.kl(retained=retained, n_modes=n_modes) for f in self._exact)
        return new

    def aligned_to(self, other: _FieldInput) -> _FieldInput:
        """This input with its exact fields' eigenvector signs matched to ``other``'s (the
        same lattices, other lengths; :meth:`GaussianField.align_to`)."""
        for mine, theirs in zip(self._exact, other._exact):
            mine.align_to(theirs)
        return self

    def _field_values(self, xi) -> list[np.ndarray]:
        xi = np.asarray(xi, dtype=float)
        if xi.ndim < 1 or xi.shape[-1] != self.n_variables:
            raise ValueError(f"xi must have trailing length n_variables={self.n_variables}, got shape {xi.shape}")
        cuts = np.cumsum([math.prod(f.xi_shape) for f in self.fields])[:-1]
        return [f.sample(part.reshape(xi.shape[:-1] + f.xi_shape))
                for f, part in zip(self.fields, np.split(xi, cuts, axis=-1))]


def _first_bad(bad: np.ndarray, lead: int) -> str:
    """Leading (realisation) index of the first True in ``bad``, as text."""
    where = np.argwhere(bad)[0][:lead]
    return f" (batch index {tuple(int(k) for k in where)})" if lead else ""


class SpacingInput(_FieldInput):
    """Random segment lengths s_e = s (1 + cv ξ_e) (thesis §5.3.3.1), in mm.

    Fibre-1 segments form a (2n, 2n+1) lattice and fibre-2 segments a (2n+1, 2n) one;
    they are independent fields (different tow sets) with the same correlation model
    and lengths ``length_mm`` = (along fibre 1, along fibre 2). ``cv`` ∈ [0, 1).
    A realisation with a non-positive length (ξ ≤ −1/cv) is refused, not clipped:
    clipping would bias the distribution, and such a cv is outside the Gaussian model.
    """

    def __init__(self, rings: int, spacing_mm: float, cv: float, correlation: str = "iid", length_mm=None):
        n = positive_int("rings", rings)
        self.spacing_mm = _spacing(spacing_mm)
        if not isinstance(cv, (int, float, np.number)) or not 0.0 <= cv < 1.0:
            raise ParameterError("cv", f"cv (spacing coefficient of variation) must be in [0, 1), got {cv!r}")
        self.cv = float(cv)
        super().__init__([(2 * n, 2 * n + 1), (2 * n + 1, 2 * n)], self.spacing_mm, correlation, length_mm)

    def __call__(self, xi) -> tuple[np.ndarray, np.ndarray]:
        """(fibre-1 lengths (..., 2n, 2n+1), fibre-2 lengths (..., 2n+1, 2n)), mm."""
        lead = np.ndim(xi) - 1
        out = []
        for z in self._field_values(xi):
            s = self.spacing_mm * (1.0 + self.cv * z)
            if np.any(s <= 0):
                raise ValueError(f"spacing cv={self.cv:g} gave a non-positive segment length"
                                 f"{_first_bad(s <= 0, lead)}: a standard normal of {z.min():.2f} <= -1/cv; use a "
                                 "smaller cv")
            out.append(s)
        return tuple(out)


class ZeroAngleInput(_FieldInput):
    """Zero-energy shear angle per cell, γ0 = μ0 + σ0 ξ_c (thesis §5.3.3.2), in degrees.

    One (2n, 2n) lattice of cell centres. A realisation with |γ0| ≥ 90° (a collapsed
    cell) is refused.
    """

    def __init__(self, rings: int, spacing_mm: float, mean_deg: float, sd_deg: float,
                 correlation: str = "iid", length_mm=None):
        n = positive_int("rings", rings)
        ok = all(isinstance(v, (int, float, np.number)) and math.isfinite(v) for v in (mean_deg, sd_deg))
        if not ok or not abs(mean_deg) < 90.0 or sd_deg < 0:
            raise ParameterError(("mean_deg", "sd_deg"), "zero angle needs |mean_deg| < 90 and sd_deg >= 0 (degrees), "
                                                         f"got mean_deg={mean_deg!r}, sd_deg={sd_deg!r}")
        self.mean_deg, self.sd_deg = float(mean_deg), float(sd_deg)
        super().__init__([(2 * n, 2 * n)], _spacing(spacing_mm), correlation, length_mm)

    def __call__(self, xi) -> np.ndarray:
        """Zero-energy angles (..., 2n, 2n), degrees."""
        (z,) = self._field_values(xi)
        gamma0 = self.mean_deg + self.sd_deg * z
        bad = np.abs(gamma0) >= 90.0
        if np.any(bad):
            raise ValueError(f"zero angle mean_deg={self.mean_deg:g}, sd_deg={self.sd_deg:g} gave |gamma0| >= 90 "
                             f"degrees{_first_bad(bad, np.ndim(xi) - 1)}; use a smaller sd_deg")
        return gamma0


class PrestrainInput(_FieldInput):
    """Stitch pre-strain per cell ε0 = mean + sd ξ_c (fractions), mapped to the cell's
    zero-energy angle γ0 (degrees) by ``to_gamma0`` (a vectorised map such as
    ``uqdrape.material.architecture.ZeroForceTable``): the thesis's explanation of the
    negative mean fibre angle (L9189-9195) applied cell by cell.

    One (2n, 2n) lattice of cell centres, like :class:`ZeroAngleInput`.
    """

    def __init__(self, rings: int, spacing_mm: float, mean: float, sd: float, to_gamma0,
                 correlation: str = "iid", length_mm=None):
        n = positive_int("rings", rings)
        ok = all(isinstance(v, (int, float, np.number)) and math.isfinite(v) for v in (mean, sd))
        if not ok or sd < 0:
            raise ParameterError(("mean", "sd"), "stitch pre-strain needs finite mean and sd >= 0 (fractions), "
                                                 f"got mean={mean!r}, sd={sd!r}")
        self.mean, self.sd = float(mean), float(sd)
        self.to_gamma0 = to_gamma0
        super().__init__([(2 * n, 2 * n)], _spacing(spacing_mm), correlation, length_mm)

    def __call__(self, xi) -> np.ndarray:
        """Zero-energy angles (..., 2n, 2n), degrees."""
        (z,) = self._field_values(xi)
        return self.to_gamma0(self.mean + self.sd * z)
