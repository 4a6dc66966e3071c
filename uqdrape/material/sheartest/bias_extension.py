"""Bias-extension (BE) test: kinematics (thesis Eq 3.17-3.19) and the energy
normalisation of §3.4.4.1, solved exactly and by the thesis's two approximate routes.

A sample of free height h0 and width w0 (mm), tows at ±φ0 to the pulling axis, has the
generalised aspect ratio κ = (h0/w0) tan φ0 (Eq 3.17) and the tow-direction side of its
regions A and C, L3 = w0 / (2 sin φ0). Region A (initial area (2κ−3) L3² sin 2φ0) shears
by θ, region B (2 L3² sin 2φ0) by θ/2, region C not at all:

    d = 2(κ − 1) L3 [cos(φ0 − θ/2) − cos φ0]                              (Eq 3.18-3.19)

Energy balance, W(θ) the shear energy per unit initial area (J/m², θ in rad) and
W' = dW/dθ = N_s sin(2φ0 − θ)/sin 2φ0 (the picture-frame relation, thesis-notes §1.6):

    (2κ − 3) W'(θ) + W'(θ/2) = g(θ),   g = (κ − 1)(F/L3) sin(φ0 − θ/2) / sin 2φ0

`shear_force` solves it exactly. The thesis (Eq 3.33-3.39) writes the same balance for
the crosshead form X = ψ_A/k2 as (2κ − 3) X(θ) + X(θ/2) = (κ − 1) F/L3, which treats
ψ_A(θ/2)/k2(θ) as X(θ/2) although k2 ∝ sin(φ0 − θ/2) changes between θ/2 and θ; as
k2(θ) < k2(θ/2) it subtracts too little and over-predicts N_s (errata item 6). Both of
its routes are here for comparison: `thesis_iterative` (Eq 3.34-3.35) and
`thesis_polynomial` (Eq 3.36-3.39); X is turned into N_s by Eq 3.1, N_s = X / (2 cos φ).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Halvings of θ summed by `halving_solve`: θ/2^HALVINGS < 1e-6 rad for any θ < 1.05 rad.
HALVINGS = 20


def halving_solve(g, theta, a: float):
    """y(θ) solving a·y(θ) + y(θ/2) = g(θ) for a > 0, ``g`` a callable of θ (rad).

    y(θ) = Σ_{m<M} (−1)^m g(θ/2^m)/a^(m+1) + (−1)^M y(θ/2^M)/a^M, M = HALVINGS, with the
    fixed point y(x) = g(x)/(a + 1) for the tail, exact as x -> 0. Its partial sums are
    the iterates of thesis Eq 3.35 started from Eq 3.34 (y_0 = g/a), so this is that
    iteration carried to convergence; started at θ -> 0 it also converges at a = 1
    (κ = 2) when g(0) ≠ 0, where the plain iteration oscillates. For a < 1 (κ < 2)
    errors in g near 0 grow by (1/a)^M: the problem itself is ill-conditioned there.
    """
    theta = np.asarray(theta, dtype=float)
    total = np.zeros_like(theta)
    for m in range(HALVINGS):
        total += (-1.0) ** m * g(theta / 2.0**m) / a ** (m + 1)
    tail = theta / 2.0**HALVINGS
    return total + (-1.0) ** HALVINGS * g(tail) / ((a + 1.0) * a**HALVINGS)


@dataclass(frozen=True)
class BiasExtension:
    """A bias-extension sample: free ``height_mm`` h0 and ``width_mm`` w0 (mm), tows at
    ±``phi0_deg`` φ0 (deg) to the pulling axis."""

    height_mm: float
    width_mm: float
    phi0_deg: float

    @property
    def phi0(self) -> float:
        return np.deg2rad(self.phi0_deg)

    @property
    def kappa(self) -> float:
        """κ = (h0/w0) tan φ0 (Eq 3.17)."""
        return self.height_mm / self.width_mm * np.tan(self.phi0)

    @property
    def side_mm(self) -> float:
        """L3 = w0 / (2 sin φ0) (mm), the tow-direction side of regions A and C."""
        return self.width_mm / (2.0 * np.sin(self.phi0))

    def shear_angle(self, d_mm):
        """Kinematic θ (rad) of region A from crosshead displacement d (mm), Eq 3.19; NaN
        past the geometric limit."""
        c = np.cos(self.phi0) + np.asarray(d_mm, dtype=float) / (2.0 * (self.kappa - 1.0) * self.side_mm)
        with np.errstate(invalid="ignore"):
            return np.where(c <= 1.0, 2.0 * (self.phi0 - np.arccos(np.clip(c, -1.0, 1.0))), np.nan)

    def displacement(self, theta):
        """Crosshead displacement d (mm) at region-A shear θ (rad), Eq 3.18."""
        theta = np.asarray(theta, dtype=float)
        return 2.0 * (self.kappa - 1.0) * self.side_mm * (np.cos(self.phi0 - theta / 2.0) - np.cos(self.phi0))

    def max_angle(self) -> float:
        """The shear (rad) at which region A's tows become parallel: 2φ0."""
        return 2.0 * self.phi0

    def _dw(self, ns):
        """W'(θ) (J/m²/rad) of a shear force callable N_s(θ) (N/m)."""
        s = np.sin(2.0 * self.phi0)
        return lambda t: ns(t) * np.sin(2.0 * self.phi0 - t) / s

    def crosshead_force(self, ns, theta):
        """The exact forward balance: crosshead force F (N) at θ (rad) of a fabric whose
        shear force is the callable N_s(θ) (N/m)."""
        theta = np.asarray(theta, dtype=float)
        dw, k, l3 = self._dw(ns), self.kappa, self.side_mm * 1e-3
        balance = (2.0 * k - 3.0) * dw(theta) + dw(theta / 2.0)
        return l3 * np.sin(2.0 * self.phi0) * balance / ((k - 1.0) * np.sin(self.phi0 - theta / 2.0))

    def shear_force(self, force, theta):
        """N_s (N/m) at θ (rad) from crosshead force ``force(θ)`` (N, a callable): the
        exact W' form of the energy balance."""
        theta = np.asarray(theta, dtype=float)
        k, l3, s = self.kappa, self.side_mm * 1e-3, np.sin(2.0 * self.phi0)
        g = lambda t: (k - 1.0) * force(t) / l3 * np.sin(self.phi0 - t / 2.0) / s  # noqa: E731
        dw = halving_solve(g, theta, 2.0 * k - 3.0)
        return dw * s / np.sin(2.0 * self.phi0 - theta)

    def pointwise_shear_force(self, force_n, theta, force):
        """N_s (N/m) of each measured point (θ (rad), F (N)): the balance solved for
        W'(θ) with the region-B term W'(θ/2) taken from the fitted ``force`` callable."""
        theta = np.asarray(theta, dtype=float)
        k, l3, s = self.kappa, self.side_mm * 1e-3, np.sin(2.0 * self.phi0)
        g = (k - 1.0) * np.asarray(force_n) / l3 * np.sin(self.phi0 - theta / 2.0) / s
        half = self.shear_force(force, theta / 2.0) * np.sin(2.0 * self.phi0 - theta / 2.0) / s
        return (g - half) / (2.0 * k - 3.0) * s / np.sin(2.0 * self.phi0 - theta)

    def _thesis_ns(self, x, theta):
        """N_s from the thesis's crosshead form X = ψ_A/k2 (N/m) by Eq 3.1."""
        return x / (2.0 * np.cos(self.phi0 - np.asarray(theta) / 2.0))

    def thesis_iterative(self, force, theta):
        """N_s (N/m) by the thesis's iteration Eq 3.34-3.35 on F/L3, converged."""
        k, l3 = self.kappa, self.side_mm * 1e-3
        x = halving_solve(lambda t: (k - 1.0) * force(t) / l3, theta, 2.0 * k - 3.0)
        return self._thesis_ns(x, theta)

    def thesis_polynomial(self, theta_data, force_n, theta, order: int = 6):
        """N_s (N/m) by Eq 3.36-3.39: a least-squares polynomial of ``order`` (the thesis's
        6, not through the origin) fitted to F/L3 of the points (θ rad, F N), then
        X = (κ−1) Σ a_i θ^i / (2κ − 3 + 2^−i)."""
        k, l3 = self.kappa, self.side_mm * 1e-3
        a = np.polynomial.polynomial.polyfit(theta_data, np.asarray(force_n) / l3, order)
        b = (k - 1.0) * a / (2.0 * k - 3.0 + 2.0 ** -np.arange(order + 1))
        return self._thesis_ns(np.polynomial.polynomial.polyval(theta, b), theta)

    def describe(self) -> str:
        return (f"bias extension, {self.height_mm:g} x {self.width_mm:g} mm, phi0 {self.phi0_deg:g} deg, "
                f"kappa {self.kappa:.4g}")
