"""Analytic moulds as height fields z = h(x, y) (lengths in mm, angles in degrees).

Every mould stands on the plane z = 0 (the flange or blank-holder level) unless it has
no rim (cylinder, saddle). Where a slope becomes vertical (hemisphere rim) the gradient
is clipped to a large finite value, so callers never see NaN or inf.

Each class has ``bounds`` = (xmin, xmax, ymin, ymax) in mm, the plan rectangle that
holds its domain; ``params()`` returns exactly the constructor arguments, so
``type(s)(**s.params())`` rebuilds the same mould.
"""

from __future__ import annotations

import math

import numpy as np

from .base import Surface

# Smallest radius used to form x / r on surfaces of revolution (mm); at r = 0 the
# in-plane direction is undefined and the gradient is reported as 0.
_R_EPS = 1e-12


#: Largest mould dimension accepted (mm): beyond any press, and far from float overflow.
MAX_LENGTH_MM = 1e5


def _length(name: str, value) -> float:
    """A strictly positive, finite length in mm, or a ValueError naming the argument."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive length in mm, got {value!r}") from None
    if not (math.isfinite(v) and 0 < v <= MAX_LENGTH_MM):
        raise ValueError(f"{name} must be a positive length in mm up to {MAX_LENGTH_MM:g} (a 100 m tool), "
                         f"got {value!r}")
    return v


def _angle(name: str, value, lo: float, hi: float) -> float:
    """An angle in degrees strictly inside (lo, hi), or a ValueError naming the argument."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an angle in degrees in ({lo}, {hi}), got {value!r}") from None
    if not (lo < v < hi):
        raise ValueError(f"{name} must be an angle in degrees in ({lo}, {hi}), got {value!r}")
    return v


def _flange(value, rim: float, default_factor: float = 2.0) -> float:
    """Flange half-width (mm): given, or ``default_factor`` times the rim radius; >= rim."""
    w = default_factor * rim if value is None else _length("flange_half_width", value)
    if w < rim:
        raise ValueError(
            f"flange_half_width must be >= the mould's rim radius {rim:g} mm, got {value!r}"
        )
    return w


class _SquareDomain(Surface):
    """A mould whose domain is the square |x|, |y| <= ``_half`` (mm)."""

    _half: float

    def inside(self, x, y):
        return (np.abs(x) <= self._half) & (np.abs(y) <= self._half)

    @property
    def bounds(self):
        return (-self._half, self._half, -self._half, self._half)


class _Revolution(_SquareDomain):
    """Surface of revolution about the z axis, z = f(r), on a square flange.

    Subclasses give the profile ``_profile(r)`` and its slope ``_slope(r)`` = df/dr
    (both vectorised, r >= 0); the slope must be 0 where the profile is the flange.
    """

    def _profile(self, r):
        raise NotImplementedError

    def _slope(self, r):
        raise NotImplementedError

    def height(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return self._profile(np.hypot(x, y))

    def gradient(self, x, y):
        return self.height_gradient(x, y)[1:]

    def height_gradient(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        r = np.hypot(x, y)
        k = self._slope(r) / np.maximum(r, _R_EPS)
        return self._profile(r), k * x, k * y


class Plate(_SquareDomain):
    """Flat plate z = 0 over the square |x|, |y| <= half_width (mm). Developable: drapes without shear."""

    name = "plate"

    def __init__(self, half_width: float = 300.0):
        self.half_width = _length("half_width", half_width)
        self._half = self.half_width
        self.size = self.half_width

    def height(self, x, y):
        return np.zeros(np.broadcast(x, y).shape)

    def gradient(self, x, y):
        z = np.zeros(np.broadcast(x, y).shape)
        return z, z.copy()

    def params(self):
        return {"half_width": self.half_width}


class Hemisphere(_Revolution):
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

    def _profile(self, r):
        return np.sqrt(np.maximum(self.radius**2 - r**2, 0.0))

    def _slope(self, r):
        q = self.radius**2 - r**2
        root = np.maximum(np.sqrt(np.maximum(q, 0.0)), 1e-9 * self.radius)
        return np.where(q > 0, -r / root, 0.0)

    def params(self):
        return {"radius": self.radius, "flange_half_width": self.flange_half_width}


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
            raise ValueError(f"axis must be 'x' or 'y', got {axis!r}")
        self.axis = axis
        self.size = self.radius

    def _across(self, x, y):
        """(along-axis, across-axis) coordinates, broadcast, float64."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return (x, y) if self.axis == "x" else (y, x)

    def height(self, x, y):
        _, c = self._across(x, y)
        return np.sqrt(np.maximum(self.radius**2 - c**2, 0.0))

    def gradient(self, x, y):
        _, c = self._across(x, y)
        q = self.radius**2 - c**2
        root = np.maximum(np.sqrt(np.maximum(q, 0.0)), 1e-9 * self.radius)
        across = np.where(q > 0, -c / root, 0.0)
        along = np.zeros_like(across)
        return (along, across) if self.axis == "x" else (across, along)

    def inside(self, x, y):
        a, c = self._across(x, y)
        return (np.abs(a) <= 0.5 * self.length) & (np.abs(c) <= self.WIDTH_FRACTION * self.radius)

    @property
    def bounds(self):
        a, c = 0.5 * self.length, self.WIDTH_FRACTION * self.radius
        return (-a, a, -c, c) if self.axis == "x" else (-c, c, -a, a)

    def params(self):
        return {"radius": self.radius, "length": self.length, "axis": self.axis}


class Cone(_Revolution):
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

    def _profile(self, r):
        return np.maximum(self.cone_height - r * self._cot, 0.0)

    def _slope(self, r):
        return np.where(r < self.base_radius, -self._cot, 0.0)

    def params(self):
        return {
            "half_angle_deg": self.half_angle_deg,
            "height": self.cone_height,
            "flange_half_width": self.flange_half_width,
        }


class NoseCone(_Revolution):
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

    def __init__(
        self,
        base_radius: float = 225.0,
        half_angle_deg: float = 35.0,
        tip_radius: float = 50.0,
        flange_half_width: float | None = None,
    ):
        self.base_radius = _length("base_radius", base_radius)
        self.half_angle_deg = _angle("half_angle_deg", half_angle_deg, 0.0, 90.0)
        self.tip_radius = _length("tip_radius", tip_radius)
        a = math.radians(self.half_angle_deg)
        self._cot = 1.0 / math.tan(a)
        self.blend_radius = self.tip_radius * math.cos(a)  # r_t, plan radius of the blend
        if self.blend_radius >= self.base_radius:
            raise ValueError(
                f"tip_radius must satisfy tip_radius * cos(half_angle) < base_radius "
                f"({self.base_radius:g} mm), got tip_radius={tip_radius!r}"
            )
        z_blend = (self.base_radius - self.blend_radius) * self._cot
        self._z_centre = z_blend - self.tip_radius * math.sin(a)  # sphere centre height
        self.tip_height = self._z_centre + self.tip_radius
        self.flange_half_width = _flange(flange_half_width, self.base_radius)
        self._half = self.flange_half_width
        self.size = self.base_radius

    def _profile(self, r):
        sphere = self._z_centre + np.sqrt(np.maximum(self.tip_radius**2 - r**2, 0.0))
        cone = np.maximum((self.base_radius - r) * self._cot, 0.0)
        return np.where(r <= self.blend_radius, sphere, cone)

    def _slope(self, r):
        rs = np.minimum(r, self.blend_radius)  # keeps the sphere branch finite
        sphere = -rs / np.sqrt(self.tip_radius**2 - rs**2)
        cone = np.where(r < self.base_radius, -self._cot, 0.0)
        return np.where(r <= self.blend_radius, sphere, cone)

    def params(self):
        return {
            "base_radius": self.base_radius,
            "half_angle_deg": self.half_angle_deg,
            "tip_radius": self.tip_radius,
            "flange_half_width": self.flange_half_width,
        }


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

    def __init__(
        self,
        dome_radius: float = 80.0,
        base_radius: float = 70.0,
        centre_distance: float = 120.0,
        blend: float = 20.0,
        flange_half_width: float = 200.0,
    ):
        self.dome_radius = _length("dome_radius", dome_radius)
        self.base_radius = _length("base_radius", base_radius)
        if self.base_radius >= self.dome_radius:
            raise ValueError(
                f"base_radius must be < dome_radius ({self.dome_radius:g} mm), got {base_radius!r}"
            )
        self.centre_distance = _length("centre_distance", centre_distance)
        if self.centre_distance >= 2 * self.base_radius:
            raise ValueError(
                f"centre_distance must be < 2 * base_radius ({2 * self.base_radius:g} mm) "
                f"so the domes overlap, got {centre_distance!r}"
            )
        self.blend = _length("blend", blend)
        self._depth = math.sqrt(self.dome_radius**2 - self.base_radius**2)  # centre below z=0
        self._rim_slope = self.base_radius / self._depth
        reach = 0.5 * self.centre_distance + self.base_radius
        self.flange_half_width = _length("flange_half_width", flange_half_width)
        if self.flange_half_width < reach:
            raise ValueError(
                f"flange_half_width must be >= {reach:g} mm (the domes' plan extent), "
                f"got {flange_half_width!r}"
            )
        self._half = self.flange_half_width
        self.size = reach

    def _cap(self, x, y, xc):
        """One cap continued by its tangent cone: (f, df/dx, df/dy), everywhere finite."""
        dx = x - xc
        r = np.hypot(dx, y)
        on = r <= self.base_radius
        root = np.sqrt(np.maximum(self.dome_radius**2 - r**2, 0.0))
        f = np.where(on, root - self._depth, (self.base_radius - r) * self._rim_slope)
        # df/dr / r on each branch; root >= depth > 0 where ``on``
        k = np.where(on, -1.0 / np.where(on, root, 1.0), -self._rim_slope / np.maximum(r, _R_EPS))
        return f, k * dx, k * y

    def _smooth(self, x, y):
        """Smooth maximum of the two caps and its gradient."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        d = 0.5 * self.centre_distance
        f1, g1x, g1y = self._cap(x, y, -d)
        f2, g2x, g2y = self._cap(x, y, d)
        k = self.blend
        gap = np.maximum(k - np.abs(f1 - f2), 0.0)
        f = np.maximum(f1, f2) + gap**2 / (4 * k)
        w = np.clip(0.5 + (f1 - f2) / (2 * k), 0.0, 1.0)  # weight of cap 1 in the gradient
        return f, w * g1x + (1 - w) * g2x, w * g1y + (1 - w) * g2y

    def height(self, x, y):
        return np.maximum(self._smooth(x, y)[0], 0.0)

    def gradient(self, x, y):
        f, gx, gy = self._smooth(x, y)
        up = f > 0
        return np.where(up, gx, 0.0), np.where(up, gy, 0.0)

    def params(self):
        return {
            "dome_radius": self.dome_radius,
            "base_radius": self.base_radius,
            "centre_distance": self.centre_distance,
            "blend": self.blend,
            "flange_half_width": self.flange_half_width,
        }


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

    def height(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return (x**2 - y**2) / (2 * self.radius)

    def gradient(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return x / self.radius, -y / self.radius

    def params(self):
        return {"radius": self.radius, "half_width": self.half_width}
