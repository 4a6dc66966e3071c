"""Analytic moulds as height fields z = h(x, y) (lengths in mm, angles in degrees).

Every mould stands on the plane z = 0 (the flange or blank-holder level) unless it has
no rim (cylinder, saddle). Where a slope becomes vertical (hemisphere rim) the gradient
is clipped to a large finite value, so callers never see NaN or inf. Each class sets
``kernel``, its kind code and parameters for ``compiled.height_gradient``, which holds
the shape formulas.

Each class has ``bounds`` = (xmin, xmax, ymin, ymax) in mm, the plan rectangle that
holds its domain, and keeps each constructor argument as the attribute of the same name
(the cone's ``height`` excepted), so ``params()`` returns exactly the constructor
arguments and ``type(s)(**s.params())`` rebuilds the same mould.
"""

from __future__ import annotations

import math

import numpy as np

from .._lazy import lazy_module
from ..errors import ParameterError
from .base import Surface

compiled = lazy_module("uqdrape.geometry.compiled")  # numba: loaded when a mould is made


#: Largest mould dimension accepted (mm): beyond any press, and far from float overflow.
MAX_LENGTH_MM = 1e5


def _length(name: str, value) -> float:
    """A strictly positive, finite length in mm, or a ValueError naming the argument."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, f"{name} must be a positive length in mm, got {value!r}") from None
    if not (math.isfinite(v) and 0 < v <= MAX_LENGTH_MM):
        raise ParameterError(name, f"{name} must be a positive length in mm up to {MAX_LENGTH_MM:g} (a 100 m tool), "
                         f"got {value!r}")
    return v


def _angle(name: str, value, lo: float, hi: float) -> float:
    """An angle in degrees strictly inside (lo, hi), or a ValueError naming the argument."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, f"{name} must be an angle in degrees in ({lo}, {hi}), got {value!r}") from None
    if not (lo < v < hi):
        raise ParameterError(name, f"{name} must be an angle in degrees in ({lo}, {hi}), got {value!r}")
    return v


def _flange(value, rim: float, default_factor: float = 2.0) -> float:
    """Flange half-width (mm): given, or ``default_factor`` times the rim radius; >= rim."""
    w = default_factor * rim if value is None else _length("flange_half_width", value)
    if w < rim:
        raise ParameterError(
            "flange_half_width", f"flange_half_width must be >= the mould's rim radius {rim:g} mm, got {value!r}"
        )
    return w


class _SquareDomain(Surface):
    """A mould whose domain is the square |x|, |y| <= ``_half`` (mm)."""

    _half: float

    @property
    def bounds(self):
        return (-self._half, self._half, -self._half, self._half)


class Plate(_SquareDomain):
    """Flat plate z = 0 over the square |x|, |y| <= half_width (mm). Developable: drapes without shear."""

    name = "plate"

    def __init__(self, half_width: float = 300.0):
        self.half_width = _length("half_width", half_width)
        self._half = self.half_width
        self.size = self.half_width
        self.kernel = self._kernel(0.0)

    def _kernel(self, d):
        return compiled.PLATE, np.array([self._half, d])


class Hemisphere(_SquareDomain):
    """Hemisphere of radius R (mm) centred at the origin, standing on a flat flange z = 0.

    The flange is the square |x|, |y| <= flange_half_width (default 2R). The slope is
    vertical at the rim r = R (clipped to about 1e9) and jumps to zero on the flange;
    the node solver brackets its roots, so the kink costs iterations, not robustness.
    """

    name = "hemisphere"

    def __init__(self, radius: float = 100.0, flange_half_width: float | None = None):
        self.radius = _length("radius", radius)
        self.flange_half_width = _flange(flange_half_width, self.radius)
        self._half = self.flange_half_width
        self.size = self.radius
        self.kernel = self._kernel(0.0)

    def _kernel(self, d):
        return compiled.HEMISPHERE, np.array([self._half, self.radius, d])


class Cylinder(Surface):
    """Upper half of a circular cylinder of radius R (mm) lying along ``axis`` ("x" or "y").

    For axis "x": z = sqrt(R^2 - y^2) over |x| <= length/2 and |y| <= 0.95 R. The
    cross-section is cut at 0.95 R (slope about 3, 72 deg) so the slope stays finite
    everywhere in the domain. Developable: a drape with one fibre along the axis has no
    shear, which makes it the solver's shear-free check on a curved mould.
    """

    name = "cylinder"
    #: fraction of R at which the cross-section is cut (keeps the slope finite)
    WIDTH_FRACTION = 0.95

    def __init__(self, radius: float = 100.0, length: float = 400.0, axis: str = "x"):
        self.radius = _length("radius", radius)
        self.length = _length("length", length)
        if axis not in ("x", "y"):
            raise ParameterError("axis", f"axis must be 'x' or 'y', got {axis!r}")
        self.axis = axis
        self.size = self.radius
        self.kernel = self._kernel(0.0)

    def _kernel(self, d):
        return compiled.CYLINDER, np.array([self.radius, self.length, 0.0 if self.axis == "x" else 1.0,
                                            self.WIDTH_FRACTION, d])

    @property
    def bounds(self):
        a, c = 0.5 * self.length, self.WIDTH_FRACTION * self.radius
        return (-a, a, -c, c) if self.axis == "x" else (-c, c, -a, a)


class Cone(_SquareDomain):
    """Right circular cone, apex up on the z axis, on a flat flange z = 0.

    z = H - r / tan(half_angle) for r <= R_base = H tan(half_angle), else 0; the slope
    on the cone is 1 / tan(half_angle). The gradient is undefined at the apex and is
    reported as 0 there; a drape whose nodes avoid the apex is developable (no shear
    on the cone away from its apex and base). Flange half-width defaults to 2 R_base.
    """

    name = "cone"

    def __init__(
        self,
        half_angle_deg: float = 30.0,
        height: float = 100.0,
        flange_half_width: float | None = None,
    ):
        self.half_angle_deg = _angle("half_angle_deg", half_angle_deg, 0.0, 90.0)
        self.cone_height = _length("height", height)
        self._cot = 1.0 / math.tan(math.radians(self.half_angle_deg))
        self.base_radius = self.cone_height / self._cot
        self.flange_half_width = _flange(flange_half_width, self.base_radius)
        self._half = self.flange_half_width
        self.size = self.base_radius
        self.kernel = self._kernel(0.0)

    def _kernel(self, d):
        if d == 0.0:
            return compiled.CONE, np.array([self._half, self.cone_height, self._cot, self.base_radius])
        # the offset of the apex is a sphere of radius d about it: a nose cone's tip
        cos = math.cos(math.radians(self.half_angle_deg))
        return compiled.NOSE_CONE, np.array([self._half, self.base_radius + d / cos, self._cot, d, d * cos,
                                             self.cone_height, d])

    def params(self):
        # ``height`` is the constructor's name, but Surface.height is the height field
        return self._with_offset({"half_angle_deg": self.half_angle_deg, "height": self.cone_height,
                                  "flange_half_width": self.flange_half_width})


class NoseCone(_SquareDomain):
    """Nose cone: a cone with a spherical tip blended tangentially, tip up at (0, 0).

    Profile (r = plan distance from the axis): a sphere of radius ``tip_radius`` for
    r <= r_t = tip_radius * cos(half_angle), then the tangent cone of slope
    1 / tan(half_angle) down to z = 0 at r = ``base_radius``, then the flat flange. The
    profile and its slope are continuous at the tip/cone blend; the cone meets the
    flange with a kink.

    The defaults approximate the Rolls-Royce Tay nose cone of Wiggers (2007) ch. 5; the
    thesis gives no dimensions, only plan outlines reaching about +-225 mm, hence
    base_radius = 225 mm. Far from the tip a geodesic pin-jointed net on a cone of
    half-angle a shears by 90 (1 - sin a) degrees on its diagonals (the angle deficit
    split over four quadrants); half_angle_deg = 35 gives about 38 deg, inside the
    30-60 deg that the thesis's max-shear lines reach by 200 mm. tip_radius = 50 mm.
    These are an approximation to be tuned against the thesis figures.
    """

    name = "nose_cone"

    def __init__(self, base_radius: float = 225.0, half_angle_deg: float = 35.0, tip_radius: float = 50.0,
                 flange_half_width: float | None = None):
        self.base_radius = _length("base_radius", base_radius)
        self.half_angle_deg = _angle("half_angle_deg", half_angle_deg, 0.0, 90.0)
        self.tip_radius = _length("tip_radius", tip_radius)
        a = math.radians(self.half_angle_deg)
        self._cot = 1.0 / math.tan(a)
        self.blend_radius = self.tip_radius * math.cos(a)  # r_t, plan radius of the blend
        if self.blend_radius >= self.base_radius:
            raise ParameterError(
                "tip_radius", f"tip_radius must satisfy tip_radius * cos(half_angle) < base_radius "
                f"({self.base_radius:g} mm), got tip_radius={tip_radius!r}"
            )
        z_blend = (self.base_radius - self.blend_radius) * self._cot
        self._z_centre = z_blend - self.tip_radius * math.sin(a)  # sphere centre height
        self.tip_height = self._z_centre + self.tip_radius
        self.flange_half_width = _flange(flange_half_width, self.base_radius)
        self._half = self.flange_half_width
        self.size = self.base_radius
        self.kernel = self._kernel(0.0)

    def _kernel(self, d):
        cos = math.cos(math.radians(self.half_angle_deg))
        tip = self.tip_radius + d
        return compiled.NOSE_CONE, np.array([self._half, self.base_radius + d / cos, self._cot, tip, tip * cos,
                                             self._z_centre, d])


class DoubleDome(_SquareDomain):
    """Two overlapping spherical caps on a flat flange, joined by a smooth valley.

    Each cap is cut from a sphere of radius ``dome_radius`` so that it meets z = 0 at
    plan radius ``base_radius`` (< dome_radius, so the rim slope a / sqrt(R^2 - a^2)
    is finite); the caps are centred at x = +-centre_distance / 2, y = 0. Beyond its
    rim each cap is continued by its tangent cone, and the two are combined with a
    quadratic smooth maximum of width ``blend`` (mm), so the valley between them has a
    continuous gradient; the result is clipped at the flange z = 0 (a kink at the rim).
    Defaults (mm): sphere radius 80, base radius 70 (cap height 41.3, rim slope 61 deg),
    centres 120 apart (plan footprint 260 x 140), blend 20, flange half-width 200.
    """

    name = "double_dome"

    def __init__(self, dome_radius: float = 80.0, base_radius: float = 70.0, centre_distance: float = 120.0,
                 blend: float = 20.0, flange_half_width: float = 200.0):
        self.dome_radius = _length("dome_radius", dome_radius)
        self.base_radius = _length("base_radius", base_radius)
        if self.base_radius >= self.dome_radius:
            raise ParameterError(
                "base_radius", f"base_radius must be < dome_radius ({self.dome_radius:g} mm), got {base_radius!r}"
            )
        self.centre_distance = _length("centre_distance", centre_distance)
        if self.centre_distance >= 2 * self.base_radius:
            raise ParameterError(
                "centre_distance", f"centre_distance must be < 2 * base_radius ({2 * self.base_radius:g} mm) "
                f"so the domes overlap, got {centre_distance!r}"
            )
        self.blend = _length("blend", blend)
        self._depth = math.sqrt(self.dome_radius**2 - self.base_radius**2)  # centre below z=0
        self._rim_slope = self.base_radius / self._depth
        reach = 0.5 * self.centre_distance + self.base_radius
        self.flange_half_width = _length("flange_half_width", flange_half_width)
        if self.flange_half_width < reach:
            raise ParameterError(
                "flange_half_width", f"flange_half_width must be >= {reach:g} mm (the domes' plan extent), "
                f"got {flange_half_width!r}"
            )
        self._half = self.flange_half_width
        self.size = reach
        self.kernel = self._kernel(0.0)

    def _kernel(self, d):
        return compiled.DOUBLE_DOME, np.array([self._half, self.dome_radius, self.base_radius, self.centre_distance,
                                               self.blend, self._depth, self._rim_slope, d])

    def _largest_offset(self):
        """The smallest concave radius of curvature (mm) of the domes and their valley above
        the flange: the largest principal curvature of the shape operator, from central
        differences of the slope on a 0.5 mm plan grid."""
        reach, h = self.size, 1e-4
        X, Y = np.meshgrid(np.arange(-reach, reach, 0.5), np.arange(-self.base_radius, self.base_radius, 0.5))
        f, fx, fy = self.height_gradient(X, Y)
        rows = [np.stack(self.height_gradient(X + dx, Y + dy)[1:], -1) - np.stack(self.height_gradient(X - dx, Y - dy)[1:], -1)
                for dx, dy in ((h, 0.0), (0.0, h))]
        hessian = np.stack(rows, -2) / (2 * h)
        g = np.stack([fx, fy], -1)
        metric = np.eye(2) + g[..., :, None] * g[..., None, :]
        shape = np.linalg.solve(metric, hessian) / np.sqrt(1.0 + (g * g).sum(-1))[..., None, None]
        concave = np.linalg.eigvals(shape[f > 0.5]).real.max()
        return float(1.0 / concave), "the smallest concave radius of curvature of its valley, past which its offset folds"


class Saddle(_SquareDomain):
    """Hyperbolic paraboloid z = (x^2 - y^2) / (2 R) over |x|, |y| <= half_width (mm).

    Principal curvatures at the origin are +-1/R (Gaussian curvature -1/R^2): the
    negative-curvature counterpart of the hemisphere. No flange.
    """

    name = "saddle"

    def __init__(self, radius: float = 200.0, half_width: float = 150.0):
        self.radius = _length("radius", radius)
        self.half_width = _length("half_width", half_width)
        self._half = self.half_width
        self.size = self.half_width
        self.kernel = self._kernel(0.0)

    def _kernel(self, d):
        return compiled.SADDLE, np.array([self._half, self.radius, d])

    def _largest_offset(self):
        # its principal curvatures are largest, +-1/R, at the origin
        return min(self.radius, self.size), "the saddle's radius and size"
