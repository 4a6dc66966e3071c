"""Analytic moulds as height fields (lengths in mm)."""

from __future__ import annotations

import numpy as np

from .base import Surface


class Plate(Surface):
    """Flat plate z = 0 over the square |x|, |y| <= half_width. Developable: drapes without shear."""

    name = "plate"

    def __init__(self, half_width: float = 300.0):
        if not half_width > 0:
            raise ValueError(f"half_width must be > 0 mm, got {half_width!r}")
        self.half_width = float(half_width)
        self.size = self.half_width

    def height(self, x, y):
        return np.zeros(np.broadcast(x, y).shape)

    def gradient(self, x, y):
        z = np.zeros(np.broadcast(x, y).shape)
        return z, z.copy()

    def inside(self, x, y):
        return (np.abs(x) <= self.half_width) & (np.abs(y) <= self.half_width)

    def params(self):
        return {"half_width": self.half_width}


class Hemisphere(Surface):
    """Hemisphere of radius R (mm) centred at the origin, standing on a flat flange z = 0.

    The flange is the square |x|, |y| <= flange_half_width. The slope is vertical at
    the rim r = R and jumps to zero on the flange; the node solver brackets its roots,
    so the kink costs iterations, not robustness.
    """

    name = "hemisphere"

    def __init__(self, radius: float = 100.0, flange_half_width: float | None = None):
        if not radius > 0:
            raise ValueError(f"radius must be > 0 mm, got {radius!r}")
        self.radius = float(radius)
        self.flange_half_width = float(flange_half_width or 2.0 * radius)
        if self.flange_half_width < self.radius:
            raise ValueError("flange_half_width must be >= radius")
        self.size = self.radius

    def height(self, x, y):
        r2 = np.asarray(x) ** 2 + np.asarray(y) ** 2
        return np.sqrt(np.maximum(self.radius**2 - r2, 0.0))

    def gradient(self, x, y):
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        q = self.radius**2 - x**2 - y**2
        on = q > 0
        root = np.sqrt(np.where(on, q, 1.0))
        root = np.maximum(root, 1e-9 * self.radius)
        return np.where(on, -x / root, 0.0), np.where(on, -y / root, 0.0)

    def inside(self, x, y):
        w = self.flange_half_width
        return (np.abs(x) <= w) & (np.abs(y) <= w)

    def params(self):
        return {"radius": self.radius, "flange_half_width": self.flange_half_width}
