"""The mould interface: a height field z = h(x, y) over a domain in the x-y plane.

Every method is vectorised over arrays of any (broadcastable) shape. Lengths are mm.
The tool moves along z and the blank-holder lies in an x-y plane (thesis assumption 3).
"""

from __future__ import annotations

import numpy as np


class Surface:
    """Base class of every mould.

    Subclasses implement ``height``, ``gradient`` and ``inside`` and set ``name`` and
    ``size`` (a characteristic length in mm, used for tolerances and plots).
    """

    name: str = "surface"
    size: float = 100.0

    def height(self, x, y):
        """Surface height z (mm) at plan position (x, y) (mm)."""
        raise NotImplementedError

    def gradient(self, x, y):
        """Tuple (dh/dx, dh/dy), dimensionless, at (x, y)."""
        raise NotImplementedError

    def inside(self, x, y):
        """Boolean array: True where (x, y) lies in the mould's domain."""
        raise NotImplementedError

    def height_gradient(self, x, y):
        """(h, dh/dx, dh/dy) in one call; subclasses override it to share work."""
        return (self.height(x, y), *self.gradient(x, y))

    def params(self) -> dict:
        """Shape parameters (for netCDF attributes and reports)."""
        return {}

    def normal(self, x, y):
        """Unit upward normal, shape (..., 3)."""
        hx, hy = self.gradient(x, y)
        n = np.stack([-hx, -hy, np.ones_like(hx)], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def describe(self) -> str:
        p = ", ".join(f"{k}={v}" for k, v in self.params().items())
        return f"{self.name}({p})"
