"""A smooth, non-decreasing fit of noisy force-angle data, and the rules that cut the
data to its valid range.

Method (recorded in every card): a cubic B-spline on [0, θ_end] with ``knots`` equally
spaced interior knots, fitted by least squares under the constraint that its
coefficients do not decrease, which makes the spline itself non-decreasing (a B-spline
is a convex combination of its coefficients). The constrained problem is linear in the
coefficient increments, bounded below by 0, and solved by scipy's `lsq_linear`. Unlike
a polynomial (thesis Eq 3.36) it neither oscillates nor turns down at the ends, and
unlike the point-by-point iteration it does not carry load-cell quantisation steps up
the curve (thesis Fig 3.23).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.ndimage import median_filter
from scipy.optimize import lsq_linear

METHOD = ("least-squares cubic B-spline with non-decreasing coefficients (monotone), "
          "{knots} equally spaced interior knots on [0, valid end], scipy.optimize.lsq_linear")

#: Points of the running median through which measured and kinematic angles are compared.
DIVERGENCE_WINDOW = 11


@dataclass(frozen=True)
class MonotoneFit:
    """A fitted non-decreasing curve y(x) on [0, x_end]; ``residual_rms`` is the RMS of
    the data's residuals (units of y), ``points`` how many points were fitted."""

    spline: BSpline
    x_end: float
    residual_rms: float
    points: int

    def __call__(self, x):
        return self.spline(np.clip(np.asarray(x, dtype=float), 0.0, self.x_end))


def monotone_fit(x, y, x_end: float, knots: int) -> MonotoneFit:
    """The least-squares non-decreasing cubic spline through points (x, y) on [0, x_end]."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    inner = np.linspace(0.0, x_end, knots + 2)[1:-1]
    t = np.concatenate([[0.0] * 4, inner, [x_end] * 4])
    n = len(t) - 4
    basis = BSpline.design_matrix(np.clip(x, 0.0, x_end), t, 3).toarray()
    scale = max(float(np.max(np.abs(y))), 1e-300)
    # coefficients c = T p: p[0] the first coefficient, p[1:] the increments (>= 0)
    steps = np.tril(np.ones((n, n)))
    lower = np.r_[-np.inf, np.zeros(n - 1)]
    p = lsq_linear(basis @ steps, y / scale, bounds=(lower, np.inf), method="bvls").x
    spline = BSpline(t, steps @ p * scale, 3)
    residual = y - spline(np.clip(x, 0.0, x_end))
    return MonotoneFit(spline, float(x_end), float(np.sqrt(np.mean(residual**2))), int(x.size))


def divergence_end(theta_measured, theta_kinematic, tolerance):
    """The first measured angle (rad, in row order) at which the running median (over
    DIVERGENCE_WINDOW points) of |θ_measured − θ_kinematic| exceeds ``tolerance`` (rad):
    where the sample stops shearing as the ideal kinematics say (a kinematic NaN, past
    the rig's geometric limit, counts as diverged). None if it never does."""
    gap = np.abs(np.asarray(theta_measured) - np.asarray(theta_kinematic))
    gap = median_filter(np.where(np.isnan(gap), np.inf, gap), size=DIVERGENCE_WINDOW, mode="nearest")
    over = np.nonzero(gap > tolerance)[0]
    return None if over.size == 0 else float(theta_measured[over[0]])
