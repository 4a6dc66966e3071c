"""Stationary Gaussian random fields on the regular 2-D lattice of the net.

Axis 0 of a field runs along fibre 1 (net index i), axis 1 along fibre 2 (index j);
lattice points are ``spacing_mm`` apart. Fields have zero mean and unit variance, and a
separable correlation C(Δa, Δb) = c1(Δa) · c2(Δb):

- ``"iid"``: no correlation between lattice points;
- ``"exponential"``: c(Δ) = exp(-|Δ|/L), the Ornstein–Uhlenbeck sheet (Skordos & Sutcliffe
  2008 for tow angles);
- ``"squared_exponential"``: c(Δ) = exp(-Δ²/L²), smooth fields.

The lattice covariance is the Kronecker product C1 ⊗ C2 of the 1-D matrices, so its
eigenpairs are products of the 1-D eigenpairs. With C1 = Φ1 Λ1 Φ1ᵀ and C2 = Φ2 Λ2 Φ2ᵀ,
a field is ``Φ1 (S ∘ Z) Φ2ᵀ`` with S_ij = sqrt(λ1_i λ2_j): exact sampling fills Z with
na·nb standard normals (:meth:`GaussianField.sample`); the truncated Karhunen–Loève
expansion keeps only the largest modes (:class:`KLField`), so a sensitivity design needs
a small, known number of standard variables. Eigendecomposition (not Cholesky) is used
because the squared-exponential matrix is numerically singular for long lengths; its
round-off negative eigenvalues are set to zero.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError

CORRELATIONS = ("iid", "exponential", "squared_exponential")

# Relative gap below which two KL eigenvalues count as equal (kept or dropped together).
_TIE_RTOL = 1e-9


def _pair(value, name: str) -> tuple[float, float]:
    """A positive finite number or pair of numbers as a (along fibre 1, along fibre 2) pair."""
    try:
        arr = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        arr = np.array([np.nan])
    if arr.shape not in ((1,), (2,)) or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ParameterError(name, f"{name} must be a positive number or a pair of positive numbers (mm), "
                                   f"got {value!r}")
    return (float(arr[0]), float(arr[-1]))


def correlation_function(lag_mm, correlation: str, length_mm: float | None) -> np.ndarray:
    """The 1-D correlation c(Δ) of family ``correlation`` at lags ``lag_mm`` (any shape, mm)
    for the correlation length ``length_mm`` (mm; ignored for "iid"). The lattice fields
    here and the calibration's scattered points (``uqdrape.calibration``) both use it."""
    lag = np.abs(np.asarray(lag_mm, dtype=float))
    if correlation == "iid":
        return (lag == 0).astype(float)
    if correlation == "exponential":
        return np.exp(-lag / length_mm)
    return np.exp(-((lag / length_mm) ** 2))


def _correlation_matrix(n: int, step_mm: float, correlation: str, length_mm: float | None):
    """1-D correlation matrix of n lattice points ``step_mm`` apart."""
    import scipy.linalg

    return scipy.linalg.toeplitz(correlation_function(step_mm * np.arange(n), correlation, length_mm))


def _eigenpairs(matrix):
    """Eigenvalues (descending, negatives from round-off set to 0) and eigenvectors."""
    import scipy.linalg

    lam, phi = scipy.linalg.eigh(matrix)
    return np.clip(lam[::-1], 0.0, None), phi[:, ::-1]


class GaussianField:
    """Zero-mean, unit-variance Gaussian field on an ``shape`` = (na, nb) lattice.

    ``spacing_mm`` is the lattice step (mm), one value or (along fibre 1, along fibre 2);
    ``length_mm`` the correlation length (mm) likewise, required unless ``"iid"`` (where
    it is ignored). :meth:`sample` is exact; :meth:`kl` gives a truncated expansion.
    """

    def __init__(self, shape, spacing_mm, correlation: str = "iid", length_mm=None):
        shape = tuple(int(n) for n in np.atleast_1d(shape))
        if len(shape) != 2 or min(shape) < 1:
            raise ValueError(f"shape must be two positive integers (na, nb), got {shape!r}")
        if correlation not in CORRELATIONS:
            raise ParameterError("correlation", f"correlation must be one of {CORRELATIONS}, got {correlation!r}")
        self.shape = shape
        self.spacing_mm = _pair(spacing_mm, "spacing_mm")
        self.correlation = correlation
        if correlation == "iid":
            self.length_mm = None
        elif length_mm is None:
            raise ParameterError("length_mm", "length_mm (correlation length, mm) is required for "
                                              f"correlation={correlation!r}")
        else:
            self.length_mm = _pair(length_mm, "length_mm")
        lengths = self.length_mm or (None, None)
        self.matrices = tuple(_correlation_matrix(n, d, correlation, L)
                              for n, d, L in zip(shape, self.spacing_mm, lengths))
        (lam1, self._phi1), (lam2, self._phi2) = (_eigenpairs(m) for m in self.matrices)
        self._scale = np.sqrt(np.outer(lam1, lam2))

    @property
    def n_modes(self) -> int:
        """Standard normals per realisation (na · nb for exact sampling)."""
        return self.shape[0] * self.shape[1]

    @property
    def xi_shape(self) -> tuple[int, int]:
        """Trailing shape of the standard-normal input of :meth:`sample`."""
        return self.shape

    def covariance(self) -> np.ndarray:
        """Full lattice covariance C1 ⊗ C2, shape (na·nb, na·nb), row-major cell order."""
        return np.kron(*self.matrices)

    def _synthesise(self, z):
        """Φ1 (S ∘ Z) Φ2ᵀ for mode coefficients Z of shape (..., na, nb)."""
        return self._phi1 @ (self._scale * z) @ self._phi2.T

    def sample(self, xi) -> np.ndarray:
        """Exact field realisations from standard normals ``xi`` of shape (..., na, nb)."""
        xi = np.asarray(xi, dtype=float)
        if xi.shape[-2:] != self.shape:
            raise ValueError(f"xi must have trailing shape {self.shape}, got {xi.shape}")
        return self._synthesise(xi)

    def align_to(self, other: GaussianField) -> None:
        """Flip the sign of each eigenvector that points against ``other``'s of the same
        rank (same lattice, another length), in place: eigenvectors are defined up to sign,
        so without this the same noise could give an unrelated field for a nearby length.
        With it, a field rebuilt for a length drawn near ``other``'s maps the same noise to
        a nearby field."""
        for mine, theirs in ((self._phi1, other._phi1), (self._phi2, other._phi2)):
            mine *= np.where(np.sum(mine * theirs, axis=0) < 0, -1.0, 1.0)

    def kl(self, retained: float | None = 0.95, n_modes: int | None = None) -> KLField:
        """Truncated Karhunen–Loève expansion; see :class:`KLField`."""
        return KLField(self, retained=retained, n_modes=n_modes)


class KLField:
    """Truncated Karhunen–Loève expansion of a :class:`GaussianField`.

    Keeps the modes with the largest eigenvalues λ_k: exactly ``n_modes`` of them if given
    (``retained`` is then ignored), else the fewest whose share of the total variance (trace of the covariance = na·nb)
    reaches ``retained`` — plus any modes tied with the last one, so no arbitrary choice
    is made among equal eigenvalues (an iid field therefore keeps every mode).
    ``retained_variance`` is the exact kept share. The field is Σ_k sqrt(λ_k) φ_k ξ_k.
    """

    def __init__(self, field: GaussianField, retained: float | None = 0.95, n_modes: int | None = None):
        total = field.n_modes
        lam = (field._scale**2).ravel()
        order = np.argsort(-lam, kind="stable")
        share = np.cumsum(lam[order]) / lam.sum()
        if n_modes is not None:
            if int(n_modes) != n_modes or not 1 <= n_modes <= total:
                raise ValueError(f"n_modes must be an integer in [1, {total}], got {n_modes!r}")
            keep = int(n_modes)
        else:
            if retained is None or not 0.0 < retained <= 1.0:
                raise ParameterError("retained", f"retained must be a variance fraction in (0, 1], got {retained!r}")
            keep = int(np.searchsorted(share, retained - 1e-12)) + 1
            last = lam[order[keep - 1]]
            keep += int(np.count_nonzero(lam[order[keep:]] >= last * (1.0 - _TIE_RTOL)))
        self.field = field
        self.shape = field.shape
        self.n_modes = keep
        self.eigenvalues = lam[order[:keep]]
        self.retained_variance = float(share[keep - 1])
        self._index = np.unravel_index(order[:keep], field.shape)

    @property
    def xi_shape(self) -> tuple[int]:
        """Trailing shape of the standard-normal input of :meth:`sample`."""
        return (self.n_modes,)

    def sample(self, xi) -> np.ndarray:
        """Field realisations (..., na, nb) from mode variables ``xi`` of shape (..., n_modes)."""
        xi = np.asarray(xi, dtype=float)
        if xi.shape[-1:] != self.xi_shape:
            raise ValueError(f"xi must have trailing shape {self.xi_shape}, got {xi.shape}")
        z = np.zeros(xi.shape[:-1] + self.shape)
        z[..., self._index[0], self._index[1]] = xi
        return self.field._synthesise(z)
