"""Picture-frame (PF) test: kinematics (thesis Eq 3.1-3.5) and normalisation (Eq 3.16).

A square frame of side L (hinge centre to hinge centre) is set at the inter-tow angle 2φ0
and pulled along a diagonal by the crosshead: displacement d (mm), force F (N). With φ
half the current frame angle about the pulled diagonal:

    θ = 2(φ0 − φ),   d = 2L[cos(φ0 − θ/2) − cos φ0]                      (Eq 3.2-3.5)
    F_s = F / (2 cos φ)            the force along each frame side     (Eq 3.1)

Two normalised forces are in use and this module keeps them apart:

    F/L            crosshead form, the thesis's "ψ/k2" (Eq 3.16), N/m
    N_s = F_s/L    shear force per unit side length = F / (2 L cos φ), N/m

A card holds N_s (Material's W(θ) = ∫ N_s sin(2φ0 − t)/sin 2φ0 dt); the two agree in
the energy balance F·ḋ = L² sin 2φ0 · W'(θ) θ̇ (thesis-notes §1.6). `shear_per_crosshead`
is the factor between them: N_s = F/L · 1/(2 cos(φ0 − θ/2)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def shear_per_crosshead(theta, phi0):
    """N_s / (F/L) = 1/(2 cos(φ0 − θ/2)) (-) at shear θ (rad) of a start φ0 (rad): Eq 3.1.

    Multiply a crosshead form F/L (N/m, Eq 3.16) by it for the shear force per unit side
    length N_s = F_s/L (N/m); divide N_s by it for F/L."""
    return 1.0 / (2.0 * np.cos(phi0 - np.asarray(theta, dtype=float) / 2.0))


@dataclass(frozen=True)
class PictureFrame:
    """A picture-frame rig: ``side_mm`` L (mm), ``phi0_deg`` φ0 (deg), half the frame's
    initial angle (45 for a square start; otherwise a non-orthogonal start)."""

    side_mm: float
    phi0_deg: float

    @property
    def phi0(self) -> float:
        return np.deg2rad(self.phi0_deg)

    def shear_angle(self, d_mm):
        """θ (rad) from crosshead displacement d (mm), Eq 3.5; NaN where the frame would
        pass straight (cos φ0 + d/2L > 1)."""
        c = np.cos(self.phi0) + np.asarray(d_mm, dtype=float) / (2.0 * self.side_mm)
        with np.errstate(invalid="ignore"):
            return np.where(c <= 1.0, 2.0 * (self.phi0 - np.arccos(np.clip(c, -1.0, 1.0))), np.nan)

    def displacement(self, theta):
        """Crosshead displacement d (mm) at shear θ (rad), Eq 3.4."""
        return 2.0 * self.side_mm * (np.cos(self.phi0 - np.asarray(theta) / 2.0) - np.cos(self.phi0))

    def max_angle(self) -> float:
        """The shear (rad) at which the frame closes to a straight line (φ = 0): 2φ0."""
        return 2.0 * self.phi0

    def crosshead_force(self, ns, theta):
        """Crosshead force F (N) that shear force N_s (N/m) at θ (rad) needs: 2 L cos φ N_s."""
        theta = np.asarray(theta, dtype=float)
        return 2.0 * self.side_mm * 1e-3 * np.cos(self.phi0 - theta / 2.0) * ns(theta)

    def shear_force(self, force, theta):
        """N_s (N/m) from crosshead force ``force(θ)`` (N, a callable) at θ (rad): Eq 3.1 over L."""
        theta = np.asarray(theta, dtype=float)
        return force(theta) / (self.side_mm * 1e-3) * shear_per_crosshead(theta, self.phi0)

    def pointwise_shear_force(self, force_n, theta, force=None):
        """N_s (N/m) of each measured point (θ rad, F N); ``force`` (the fit) is not
        needed for a picture frame and only keeps the bias-extension signature."""
        return self.shear_force(lambda t: np.asarray(force_n, dtype=float), theta)

    def normalised_force(self, force_n):
        """The crosshead form F/L (N/m) of Eq 3.16."""
        return np.asarray(force_n, dtype=float) / (self.side_mm * 1e-3)

    def describe(self) -> str:
        return f"picture frame, side {self.side_mm:g} mm, phi0 {self.phi0_deg:g} deg"
