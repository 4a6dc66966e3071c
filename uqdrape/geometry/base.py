"""The mould interface: an implicit surface phi(x, y, z) = 0 seen by the node solver, and a
height field z = h(x, y) over a domain in the x-y plane (for a mesh: its top surface, the
first contact of a blank coming down -z) seen by the crossover, plots and exports.

Every method is vectorised over arrays of any (broadcastable) shape. Lengths are mm.
The tool moves along z and the blank-holder lies in an x-y plane (thesis assumption 3).
"""

from __future__ import annotations

import copy
import inspect
import math

import numpy as np

from .._lazy import lazy_module
from ..errors import ParameterError

compiled = lazy_module("uqdrape.geometry.compiled")  # numba: loaded when a mould is evaluated


class Surface:
    """Base class of every mould.

    Subclasses set ``kernel = (kind, params)``, the compiled description of their shape
    (``uqdrape.geometry.compiled``), and ``name`` and ``size`` (a characteristic length
    in mm, used for tolerances and plots). Height, gradient, domain and normal are the
    compiled functions evaluated point by point.
    """

    name: str = "surface"
    size: float = 100.0
    kernel: tuple
    #: The rotation R (3, 3) from the tool's CAD frame into the solver's (solver = R @ tool,
    #: both in mm); None where they are the same frame (every analytic mould).
    tool_rotation: np.ndarray | None = None
    #: How far (mm) this surface lies outside the mould it was made from (``offset``).
    offset_mm: float = 0.0

    def _kernel(self, d: float) -> tuple:
        """The compiled description of this mould's outward offset surface at d mm (0: the mould)."""
        raise NotImplementedError

    def offset(self, distance_mm: float) -> Surface:
        """The surface ``distance_mm`` (mm, >= 0) further out along the normal: where a ply
        lies over plies of that total thickness. Exact: for a mesh, a level set of its
        signed distance (rounded over convex edges, the offset faces meeting at concave
        ones); spheres, cylinders, cones and flanges offset to their own kind; a double
        dome's domes and a saddle point by point, up to their smallest concave radius of
        curvature (beyond it the offset folds: ParameterError ``offset_mm``). The crossover
        stays a plan position: the first contact is on the offset surface above it."""
        try:
            d = float(distance_mm)
        except (TypeError, ValueError):
            d = math.nan
        limit, what = self._largest_offset()
        if not (math.isfinite(d) and 0.0 <= self.offset_mm + d <= limit):
            raise ParameterError("offset_mm", f"offset_mm must be a length >= 0 and at most {what} ({limit:.4g} mm), "
                                 f"got {distance_mm!r}")
        out = copy.copy(self)
        out.offset_mm = self.offset_mm + d
        out.kernel = self._kernel(out.offset_mm)
        return out

    def _largest_offset(self) -> tuple[float, str]:
        """The largest offset (mm) this mould takes and what bounds it: its size, or where a
        concave curvature would fold the offset."""
        return self.size, "the mould's size"

    def _with_offset(self, params: dict) -> dict:
        """``params`` with this surface's ``offset_mm`` added where it is not 0."""
        return {**params, "offset_mm": self.offset_mm} if self.offset_mm else params

    def to_tool(self, a):
        """Points or vectors ``a`` (..., 3) of the solver frame in the tool's frame (mm);
        ``a`` itself where the frames are the same."""
        R = self.tool_rotation
        return a if R is None else np.asarray(a, float) @ R

    def to_solver(self, a):
        """Points or vectors ``a`` (..., 3) of the tool's frame in the solver's (mm)."""
        R = self.tool_rotation
        return a if R is None else np.asarray(a, float) @ R.T

    def height(self, x, y):
        """Surface height z (mm) at plan position (x, y) (mm)."""
        return compiled.evaluate(self.kernel, x, y)[0]

    def gradient(self, x, y):
        """Tuple (dh/dx, dh/dy), dimensionless, at (x, y)."""
        return compiled.evaluate(self.kernel, x, y)[1:]

    def inside(self, x, y):
        """Boolean array: True where (x, y) lies in the mould's domain."""
        return compiled.evaluate_inside(self.kernel, x, y)

    def contains(self, x: float, y: float) -> bool:
        """Whether the one plan point (x, y) (mm) lies in the mould's domain."""
        return bool(np.asarray(self.inside(np.float64(x), np.float64(y))))

    def domain(self) -> str:
        """The mould in words (``describe``) and, for one read from a file, its plan extent
        (mm): what a point outside its domain is told."""
        bounds = getattr(self, "bounds", None)
        if bounds is None:
            return self.describe()
        return f"{self.describe()}, plan x in [{bounds[0]:g}, {bounds[1]:g}], y in [{bounds[2]:g}, {bounds[3]:g}] mm"

    def crossover_error(self, x: float, y: float) -> str | None:
        """Why a drape cannot start at plan point (x, y) (mm) of this mould, None if it can:
        the blank's first contact must lie in the mould's domain (a mesh's plan extent has
        no area when the mesh is a wall seen edge-on from the press direction)."""
        return None if self.contains(x, y) else f"the crossover must lie inside the mould's domain ({self.domain()})"

    def height_gradient(self, x, y):
        """(h, dh/dx, dh/dy) in one call."""
        return compiled.evaluate(self.kernel, x, y)

    def gap(self, x, y, z):
        """The mould as an implicit surface at points (x, y, z) (mm): (phi, dphi/dx, dphi/dy,
        dphi/dz), phi = 0 on the mould and > 0 on the fabric's side (``compiled.gap``)."""
        return compiled.evaluate_gap(self.kernel, x, y, z)

    def params(self) -> dict:
        """Shape parameters (for netCDF attributes and reports): the constructor's
        arguments, read from the attributes of the same names, and ``offset_mm`` where not 0
        (``uqdrape.geometry.build`` takes them all)."""
        names = list(inspect.signature(type(self).__init__).parameters)[1:]
        return self._with_offset({name: getattr(self, name) for name in names})

    def normal(self, x, y):
        """Unit upward normal, shape (..., 3)."""
        hx, hy = self.gradient(x, y)
        n = np.stack([-hx, -hy, np.ones_like(hx)], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def normal_at(self, points):
        """Unit outward normal (..., 3) at points (..., 3) mm on the mould: a height field's
        normal at their plan position (a mesh overrides it: walls have no plan position)."""
        points = np.asarray(points, float)
        return self.normal(points[..., 0], points[..., 1])

    def describe(self) -> str:
        """The mould in words, for titles, tables and file attributes: its kind and its
        parameters with their units, e.g. "nose cone (base radius 225 mm, half angle 35°,
        tip radius 50 mm)" (lengths in mm, angles ``*_deg`` in degrees, unset ones left out)."""
        parts = []
        for key, value in self.params().items():
            if value is None:
                continue
            if isinstance(value, str):
                parts.append(f"{key.replace('_', ' ')} {value}")
            elif key.endswith("_deg"):
                parts.append(f"{key.removesuffix('_deg').replace('_', ' ')} {value:g}°")
            else:
                parts.append(f"{key.removesuffix('_mm').replace('_', ' ')} {value:g} mm")
        return f"{self.name.replace('_', ' ')} ({', '.join(parts)})"
