"""The restricted likelihood of a Gaussian field measured at scattered points.

The measured values y_i (deg) at points (a_i, b_i) (mm along fibre 1 and fibre 2) are
y = μ 1 + f + e: f a zero-mean Gaussian field of sd σ and the separable correlation
c(Δa; L1) · c(Δb; L2) of ``uqdrape.stochastic.fields`` (the same function the study's
lattices use), e independent measurement errors of variance τ² + s_i² (τ the fitted
nugget, s_i the file's per-point sd). The mean μ is integrated out: the restricted
(REML) log-likelihood, the likelihood of the contrasts of y, is

    ℓ = −½ [log|Σ| + log(1ᵀΣ⁻¹1) + rᵀΣ⁻¹r + (n−1) log 2π],   r = y − μ̂ 1,

with μ̂ the generalised-least-squares mean. REML rather than the full likelihood
because its σ is unbiased where the full one is low by the mean's share (for iid data
it is the sample sd with n − 1), and both rank covariance models alike when the mean
model is the same. Parameters are optimised in logs (θ = log σ, log L1, log L2, log τ);
the gradient is the trace formula ∂ℓ/∂θ_k = ½ (αᵀΣ_kα − tr(PΣ_k)) with α = Py,
P = Σ⁻¹ − Σ⁻¹11ᵀΣ⁻¹ / 1ᵀΣ⁻¹1, one Cholesky factor and inverse (LAPACK potrf/potri) per
evaluation; ∂c/∂log L is a forward difference of the correlation function (relative
step 1e-6), so the correlation is written once, in ``fields``.

Points that fill a tensor grid along the fibres (every (a_i, b_j) once, as a study's
lattice) with one measurement sd are evaluated through the eigenpairs of the two 1-D
correlation matrices instead, as ``fields`` samples its lattices: Σ = (U1⊗U2)(σ² Λ1⊗Λ2
+ ν I)(U1⊗U2)ᵀ, so ℓ and its gradient cost O(na³ + nb³ + na nb (na + nb)) instead of
O(n³) (a 40 x 40 grid: milliseconds instead of a second); the two ways agree to
round-off (tested).

The iid family has no length and no nugget: without per-point sds a nugget cannot be
told from σ, so σ is then the sd of the measured values, measurement error included.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg.lapack as lapack
import scipy.optimize

from ..stochastic.fields import CORRELATIONS, correlation_function

FAMILIES = CORRELATIONS
#: Step of log L in the forward difference of the correlation function.
_LOG_STEP = 1e-6


def parameter_names(family: str) -> tuple[str, ...]:
    """The fitted parameters of ``family`` besides the mean, in θ order."""
    return ("sd",) if family == "iid" else ("sd", "length_1", "length_2", "nugget")


class Likelihood:
    """ℓ(θ) of ``family`` for values ``y`` (deg) at fibre coordinates ``a``, ``b`` (mm) with
    per-point measurement sds ``noise_sd`` (deg). Call it with θ (logs, see
    :func:`parameter_names`) for (ℓ, ∂ℓ/∂θ); :meth:`mean` gives μ̂ and its variance."""

    def __init__(self, a, b, y, noise_sd, family: str):
        if family not in FAMILIES:
            raise ValueError(f"family must be one of {', '.join(FAMILIES)}, got {family!r}")
        self.family = family
        self.names = parameter_names(family)
        self.y = np.asarray(y, dtype=float)
        self.n = len(self.y)
        self.noise_var = np.asarray(noise_sd, dtype=float) ** 2
        self.a, self.b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        self.lag_a = np.abs(np.subtract.outer(self.a, self.a))
        self.lag_b = np.abs(np.subtract.outer(self.b, self.b))
        self.grid = _tensor_grid(self.a, self.b, self.noise_var)
        distance = np.hypot(self.lag_a, self.lag_b)
        #: the largest distance between two points and the median distance from a point to
        #: its nearest neighbour (mm; the diameter if all points coincide)
        self.diameter = float(distance.max())
        distance[distance == 0.0] = np.inf
        nearest = float(np.median(distance.min(axis=1)))
        self.nearest = nearest if np.isfinite(nearest) else self.diameter

    def _correlations(self, theta):
        """The 1-D correlations (c1 along fibre 1, c2 along fibre 2) between the points."""
        lengths = (None, None) if self.family == "iid" else np.exp(theta[1:3])
        return (correlation_function(self.lag_a, self.family, lengths[0]),
                correlation_function(self.lag_b, self.family, lengths[1]))

    def covariance(self, theta, correlations=None):
        """Σ(θ) (deg²), from the 1-D ``correlations`` if already computed."""
        theta = np.asarray(theta, dtype=float)
        c1, c2 = self._correlations(theta) if correlations is None else correlations
        sigma = c1 * c2
        sigma *= np.exp(2.0 * theta[0])
        nugget2 = 0.0 if self.family == "iid" else np.exp(2.0 * theta[3])
        sigma[np.diag_indices(self.n)] += nugget2 + self.noise_var
        return sigma

    @staticmethod
    def _factor(sigma):
        """(lower Cholesky factor of Σ, log|Σ|), or None if Σ is not positive definite to
        working precision."""
        factor, info = lapack.dpotrf(sigma, lower=1, clean=1)
        if info != 0:
            return None
        return factor, 2.0 * np.sum(np.log(np.diag(factor)))

    def _inverse_of(self, factor):
        """Σ⁻¹ from its Cholesky factor (potri fills the lower triangle; the factor's upper
        one is clean, zeros)."""
        inverse, info = lapack.dpotri(factor, lower=1)
        if info != 0:
            raise np.linalg.LinAlgError("the covariance's Cholesky factor is singular")
        inverse += inverse.T
        inverse[np.diag_indices(self.n)] *= 0.5
        return inverse

    def _inverse(self, sigma):
        """(Σ⁻¹, log|Σ|), or None if Σ is not positive definite."""
        done = self._factor(sigma)
        return None if done is None else (self._inverse_of(done[0]), done[1])

    def __call__(self, theta, gradient: bool = True):
        """(ℓ, ∂ℓ/∂θ) at θ (∂ℓ/∂θ None unless ``gradient``: the value alone needs only the
        factor); (−inf, zeros) where Σ is not positive definite."""
        theta = np.asarray(theta, dtype=float)
        if self.grid is not None:
            return self._on_grid(theta, gradient)
        return self.dense(theta, gradient)

    def dense(self, theta, gradient: bool = True):
        """(ℓ, ∂ℓ/∂θ) from the full covariance (any points): see :meth:`__call__`."""
        theta = np.asarray(theta, dtype=float)
        c1, c2 = self._correlations(theta)
        done = self._factor(self.covariance(theta, (c1, c2)))
        if done is None:
            return -np.inf, np.zeros(len(theta))
        factor, logdet = done
        solved, _ = lapack.dpotrs(factor, np.column_stack([np.ones(self.n), self.y]), lower=1)
        w, v = solved[:, 0], solved[:, 1]
        total = w.sum()
        mu = w @ self.y / total
        alpha = v - w * mu
        loglik = -0.5 * (logdet + np.log(total) + alpha @ (self.y - mu) + (self.n - 1) * np.log(2.0 * np.pi))
        if not gradient:
            return loglik, None
        inverse = self._inverse_of(factor)
        # ∂ℓ/∂θ_k = −½ Σ_ij (∂Σ/∂θ_k)_ij G_ij with G = P − ααᵀ, P = Σ⁻¹ − wwᵀ/1ᵀw
        g = inverse
        g -= np.outer(alpha, alpha)
        g -= np.outer(w / total, w)
        sd2 = np.exp(2.0 * theta[0])
        h = c2 * g
        grad = [-sd2 * np.einsum("ij,ij->", c1, h)]
        if self.family != "iid":
            step = np.exp(_LOG_STEP)
            lengths = np.exp(theta[1:3])
            d1 = correlation_function(self.lag_a, self.family, lengths[0] * step) - c1
            d2 = correlation_function(self.lag_b, self.family, lengths[1] * step) - c2
            grad += [-0.5 * sd2 / _LOG_STEP * np.einsum("ij,ij->", d1, h),
                     -0.5 * sd2 / _LOG_STEP * np.einsum("ij,ij->", d2, c1 * g),
                     -np.exp(2.0 * theta[3]) * np.trace(g)]
        return loglik, np.array(grad)

    def _grid_parts(self, theta):
        """On a tensor grid: the 1-D correlations c1, c2, their eigenvectors u1, u2 and the
        eigenvalues d of Σ as an (na, nb) array (None if Σ is not positive definite)."""
        _, ua, ub = self.grid
        lengths = (None, None) if self.family == "iid" else np.exp(theta[1:3])
        c1 = correlation_function(np.subtract.outer(ua, ua), self.family, lengths[0])
        c2 = correlation_function(np.subtract.outer(ub, ub), self.family, lengths[1])
        (lam1, u1), (lam2, u2) = (np.linalg.eigh(c) for c in (c1, c2))
        nugget2 = 0.0 if self.family == "iid" else np.exp(2.0 * theta[3])
        d = (np.exp(2.0 * theta[0]) * np.outer(np.clip(lam1, 0.0, None), np.clip(lam2, 0.0, None))
             + nugget2 + self.noise_var[0])
        return c1, c2, u1, u2, (d if np.all(d > 0.0) else None)

    def _on_grid(self, theta, gradient: bool):
        """(ℓ, ∂ℓ/∂θ) through the 1-D eigenpairs (points on a tensor grid, one noise sd)."""
        order, ua, ub = self.grid
        na, nb = len(ua), len(ub)
        y = self.y[order].reshape(na, nb)
        c1, c2, u1, u2, d = self._grid_parts(theta)
        if d is None:
            return -np.inf, np.zeros(len(theta))
        sd2 = np.exp(2.0 * theta[0])
        nugget2 = 0.0 if self.family == "iid" else np.exp(2.0 * theta[3])
        lengths = (None, None) if self.family == "iid" else np.exp(theta[1:3])

        def solve(m):  # Σ⁻¹ m for an (na, nb) array m
            return u1 @ ((u1.T @ m @ u2) / d) @ u2.T

        w, v = solve(np.ones((na, nb))), solve(y)
        total = w.sum()
        mu = np.sum(w * y) / total
        alpha = v - mu * w
        loglik = -0.5 * (np.sum(np.log(d)) + np.log(total) + np.sum(alpha * (y - mu))
                         + (self.n - 1) * np.log(2.0 * np.pi))
        if not gradient:
            return loglik, None

        def term(scale, k1, k2):  # ∂ℓ/∂θ for ∂Σ/∂θ = scale (k1 ⊗ k2)
            trace = np.sum(np.outer(np.einsum("ji,jk,ki->i", u1, k1, u1), np.einsum("ji,jk,ki->i", u2, k2, u2)) / d)
            quad = lambda m: np.sum(m * (k1 @ m @ k2))  # noqa: E731
            return 0.5 * scale * (quad(alpha) - trace + quad(w) / total)

        grad = [term(2.0 * sd2, c1, c2)]
        if self.family != "iid":
            step = np.exp(_LOG_STEP)
            d1 = correlation_function(np.subtract.outer(ua, ua), self.family, lengths[0] * step) - c1
            d2 = correlation_function(np.subtract.outer(ub, ub), self.family, lengths[1] * step) - c2
            eye_a, eye_b = np.eye(na), np.eye(nb)
            grad += [term(sd2 / _LOG_STEP, d1, c2), term(sd2 / _LOG_STEP, c1, d2), term(2.0 * nugget2, eye_a, eye_b)]
        return loglik, np.array(grad)

    def mean(self, theta) -> tuple[float, float]:
        """μ̂ (deg) and its variance 1 / 1ᵀΣ⁻¹1 (deg²) at θ."""
        theta = np.asarray(theta, dtype=float)
        if self.grid is not None:
            order, ua, ub = self.grid
            _, _, u1, u2, d = self._grid_parts(theta)
            w = u1 @ ((u1.T @ np.ones((len(ua), len(ub))) @ u2) / d) @ u2.T
            return float(np.sum(w * self.y[order].reshape(d.shape)) / w.sum()), float(1.0 / w.sum())
        inverse, _ = self._inverse(self.covariance(theta))
        w = inverse.sum(axis=1)
        return float(w @ self.y / w.sum()), float(1.0 / w.sum())

    def leave_one_out(self, theta) -> tuple[np.ndarray, np.ndarray]:
        """Each point's prediction from all the others (mean re-estimated) and its sd, deg:
        y_i − (Py)_i / P_ii and 1 / sqrt(P_ii) (Dubrule 1983), measurement error included."""
        inverse, _ = self._inverse(self.covariance(theta))
        w = inverse.sum(axis=1)
        proj = inverse - np.outer(w, w) / w.sum()
        diag = np.diag(proj)
        return self.y - proj @ self.y / diag, 1.0 / np.sqrt(diag)

    def predict(self, theta, a, b) -> tuple[np.ndarray, np.ndarray]:
        """The field's conditional mean and sd (deg; the measurement error excluded) at the
        fibre coordinates ``a``, ``b`` (mm), the mean μ̂ plugged in."""
        theta = np.asarray(theta, dtype=float)
        inverse, _ = self._inverse(self.covariance(theta))
        w = inverse.sum(axis=1)
        mu = w @ self.y / w.sum()
        sd2 = np.exp(2.0 * theta[0])
        lengths = (None, None) if self.family == "iid" else np.exp(theta[1:3])
        cross = sd2 * (correlation_function(np.subtract.outer(a, self.a), self.family, lengths[0])
                       * correlation_function(np.subtract.outer(b, self.b), self.family, lengths[1]))
        field = mu + cross @ (inverse @ (self.y - mu))
        var = sd2 - np.sum((cross @ inverse) * cross, axis=1)
        return field, np.sqrt(np.clip(var, 0.0, None))


def _tensor_grid(a, b, noise_var):
    """(order, a values, b values) if the points are every node of a tensor grid in
    (a, b) exactly once, at least 2 x 2, with one noise variance (``order`` sorts them
    row-major, a slowest); else None. Coordinates are compared at 1e-9 mm."""
    if len(a) < 4 or np.ptp(noise_var) != 0.0:
        return None
    ua, ia = np.unique(np.round(a, 9), return_inverse=True)
    ub, ib = np.unique(np.round(b, 9), return_inverse=True)
    key = ia * len(ub) + ib
    if len(ua) < 2 or len(ub) < 2 or len(ua) * len(ub) != len(a) or len(np.unique(key)) != len(a):
        return None
    return np.argsort(key), ua, ub


def maximise(like: Likelihood, x0, bounds, fixed: dict | None = None):
    """θ maximising ℓ with the entries ``fixed`` {index: value} held, from ``x0`` within
    ``bounds`` (L-BFGS-B on the analytic gradient). Returns (θ, ℓ)."""
    fixed = fixed or {}
    free = [k for k in range(len(x0)) if k not in fixed]
    theta = np.asarray(x0, dtype=float).copy()
    for k, v in fixed.items():
        theta[k] = v

    def objective(x):
        theta[free] = x
        value, grad = like(theta)
        if not np.isfinite(value):
            return 1e30, np.zeros(len(free))
        return -value, -grad[free]

    if free:
        result = scipy.optimize.minimize(objective, theta[free], jac=True, method="L-BFGS-B",
                                         bounds=[bounds[k] for k in free],
                                         options={"maxiter": 500, "ftol": 1e-11, "gtol": 1e-6})
        theta[free] = result.x
    return theta, like(theta, gradient=False)[0]
