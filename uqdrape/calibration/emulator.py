"""A Gaussian-process emulator of ensemble statistics over a box of study parameters
(scikit-learn; optional extra ``calibrate``).

The training points are a space-filling Latin hypercube of the box (scipy's ``qmc``, optimised for
centred discrepancy). Each output column (e.g. the ensemble mean of one measured point's
shear) gets its own GP with a constant times anisotropic squared-exponential kernel on
the box scaled to the unit cube, its hyper-parameters by maximum marginal likelihood; the
known Monte Carlo variance of each training value (a finite ensemble's mean or log sd)
enters as that point's noise, so the emulator smooths it out and its predictive variance
(of the underlying function, noise not added) says what the training points have not pinned down.
"""

from __future__ import annotations

import numpy as np
import scipy.stats.qmc

from .posterior import extra

#: Restarts of each GP's hyper-parameter search (the first start is the kernel's own).
RESTARTS = 2


def latin_hypercube(lower, upper, n: int, seed: int) -> np.ndarray:
    """``n`` space-filling points (rows) in the box [lower, upper]: a Latin hypercube."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    sampler = scipy.stats.qmc.LatinHypercube(d=lower.size, optimization="random-cd", rng=np.random.default_rng(seed))
    return scipy.stats.qmc.scale(sampler.random(n), lower, upper)


class Emulator:
    """GPs of the columns of ``values`` (training point, output) at ``points`` (training point,
    parameter) in the box [lower, upper]; ``noise_var`` (same shape as ``values``) the
    Monte Carlo variance of each value."""

    def __init__(self, points, values, noise_var, lower, upper, *, seed: int = 0):
        gp = extra("sklearn.gaussian_process", "a calibration from measured drapes needs scikit-learn")
        regressor, kernels = gp.GaussianProcessRegressor, gp.kernels
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        x = self._unit(points)
        values, noise_var = np.asarray(values, float), np.asarray(noise_var, float)
        self.offset = values.mean(axis=0)
        self.scale = np.maximum(values.std(axis=0), np.sqrt(noise_var.mean(axis=0)))
        self.scale = np.where(self.scale > 0, self.scale, 1.0)
        kernel = (kernels.ConstantKernel(1.0, (1e-3, 1e3))
                  * kernels.RBF(np.full(x.shape[1], 0.5), (1e-2, 1e2)))
        fitted = []
        for col in range(values.shape[1]):
            gp = regressor(kernel, alpha=noise_var[:, col] / self.scale[col] ** 2 + 1e-10,
                           n_restarts_optimizer=RESTARTS, random_state=seed)
            fitted.append(gp.fit(x, (values[:, col] - self.offset[col]) / self.scale[col]))
        # the fitted GPs' predictive equations, all outputs at once (sklearn's predict per
        # output and call would be most of an MCMC's time)
        self.gps = fitted
        self.x_train = x
        self.constant = np.array([gp.kernel_.k1.constant_value for gp in fitted])
        self.length = np.array([np.broadcast_to(gp.kernel_.k2.length_scale, x.shape[1]) for gp in fitted])
        self.weights = np.array([gp.alpha_ for gp in fitted])
        self.whiten = np.array([np.linalg.inv(gp.L_) for gp in fitted])

    def _unit(self, points) -> np.ndarray:
        return (np.atleast_2d(np.asarray(points, float)) - self.lower) / (self.upper - self.lower)

    def predict(self, points) -> tuple[np.ndarray, np.ndarray]:
        """The emulated values and their predictive variances at ``points`` (rows), each
        (point, output)."""
        diff = self._unit(points)[None, :, None, :] - self.x_train[None, None, :, :]
        cross = self.constant[:, None, None] * np.exp(-0.5 * ((diff / self.length[:, None, None, :]) ** 2).sum(-1))
        mean = np.einsum("gnm,gm->ng", cross, self.weights)
        var = self.constant[None, :] - (np.einsum("gij,gnj->gni", self.whiten, cross) ** 2).sum(-1).T
        return self.offset + self.scale * mean, self.scale ** 2 * np.maximum(var, 0.0)
