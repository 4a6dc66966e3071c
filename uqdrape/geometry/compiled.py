"""Compiled mould evaluation: every shipped mould as a kind code and a parameter array.

A ``Surface`` carries ``kernel = (kind, params)``; ``height_gradient(kind, params, x, y)``
(one point, mm) dispatches on the kind, so the node solver's compiled loops call the
mould without Python in between, and the Python ``Surface`` methods are thin vectorised
wrappers of the same functions (one implementation of each shape). Kinds and their
parameter layouts (all mm unless stated):

PLATE        [half, height]
HEMISPHERE   [half, R, flange height]           the sphere's radius R + flange height
CYLINDER     [R, length, axis (0: x, 1: y), width fraction, offset]
CONE         [half, H, cot(half-angle), base radius]
NOSE_CONE    [half, base radius, cot(half-angle), tip radius, blend radius, sphere centre z,
              flange height]
DOUBLE_DOME  [half, dome R, base radius, centre distance, blend, depth, rim slope, offset]
SADDLE       [half, R, offset]
MESH         a triangle mesh with its bounding-volume hierarchy (``meshquery``)

The offset and flange-height slots describe a mould's outward offset surface
(``Surface.offset``; 0 for the mould itself): a sphere's radius grows by the offset about
the same centre, a cone is shifted along its normal, a flange is raised; a cone's offset
is a nose cone with a tip of the offset's radius. A double dome's domes and a saddle,
whose offsets are of no closed form, are offset point by point (``_offset_of``).

Every kind is also an implicit surface for the node solver (``gap_on``, ``surface_normal``): a height field through its closed form, a mesh through its signed distance.
These take a query memo (``new_memo``): a mesh's table of proven nearby answers
(``meshquery.closest``), None for the closed forms, which need none. numba compiles a
kernel once per argument type and drops the branch a None rules out, so a height field's
node solver carries no mesh code.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import inline, jit
from . import meshquery

PLATE, HEMISPHERE, CYLINDER, CONE, NOSE_CONE, DOUBLE_DOME, SADDLE, MESH = range(8)

#: Smallest radius used to form x / r on surfaces of revolution (mm).
R_EPS = 1e-12


@jit
def _revolution(kind, p, r):
    """Profile f(r) (mm) and slope df/dr of a cone or nose cone."""
    if kind == CONE:
        f = max(p[1] - r * p[2], 0.0)
        return f, (-p[2] if r < p[3] else 0.0)
    # NOSE_CONE
    base, cot, tip, blend, zc, floor = p[1], p[2], p[3], p[4], p[5], p[6]
    if r <= blend:
        rs = min(r, blend)
        return zc + math.sqrt(max(tip * tip - r * r, 0.0)), -rs / math.sqrt(tip * tip - rs * rs)
    f = (base - r) * cot
    return (f, -cot) if f > floor else (floor, 0.0)


@jit
def _cap(p, x, y, xc):
    """One double-dome cap continued by its tangent cone: (f, df/dx, df/dy)."""
    dome, base, depth, rim = p[1], p[2], p[5], p[6]
    dx = x - xc
    r = math.sqrt(dx * dx + y * y)
    if r <= base:
        root = math.sqrt(max(dome * dome - r * r, 0.0))
        k = -1.0 / root
        return root - depth, k * dx, k * y
    k = -rim / max(r, R_EPS)
    return (base - r) * rim, k * dx, k * y


@jit
def height_gradient(kind, p, x, y):
    """(h, dh/dx, dh/dy) of mould ``kind`` at plan point (x, y) (mm); NaN in, NaN out."""
    if kind == MESH:
        if not (math.isfinite(x) and math.isfinite(y)):
            return math.nan, math.nan, math.nan
        return meshquery.offset_top(p, x, y)
    return _closed_form(kind, p, x, y)


@inline
def _closed_form(kind, p, x, y):
    """``height_gradient`` of a height field given in closed form (every kind but MESH),
    kept apart so the node solver's loops over them hold no mesh code."""
    if not (math.isfinite(x) and math.isfinite(y)):
        return math.nan, math.nan, math.nan
    if kind == PLATE:
        return p[1], 0.0, 0.0
    if kind == HEMISPHERE:  # h = sqrt(R^2 - x^2 - y^2), dh/dx = -x / h: no plan radius needed
        R, floor = p[1] + p[2], p[2]
        q = R * R - (x * x + y * y)
        if q <= floor * floor:
            return floor, 0.0, 0.0
        f = math.sqrt(q)
        k = -1.0 / max(f, 1e-9 * R)
        return f, k * x, k * y
    if kind == CONE or kind == NOSE_CONE:
        r = math.sqrt(x * x + y * y)  # not hypot: no overflow to guard against, and 3x faster
        f, slope = _revolution(kind, p, r)
        k = slope / max(r, R_EPS)
        return f, k * x, k * y
    if kind == CYLINDER:
        R = p[0] + p[4]
        c = y if p[2] == 0.0 else x
        q = R * R - c * c
        root = max(math.sqrt(max(q, 0.0)), 1e-9 * R)
        across = -c / root if q > 0 else 0.0
        h = math.sqrt(max(q, 0.0))
        return (h, 0.0, across) if p[2] == 0.0 else (h, across, 0.0)
    if kind == DOUBLE_DOME:  # the domes' surface, or its offset, on the flange raised by the offset
        floor = p[7]
        f, gx, gy = _smooth(kind, p, x, y) if floor == 0.0 else _offset_of(kind, p, x, y, floor)
        if f > floor:
            return f, gx, gy
        return floor, 0.0, 0.0
    # SADDLE
    if p[2] == 0.0:
        return _smooth(kind, p, x, y)
    return _offset_of(kind, p, x, y, p[2])


@inline
def _smooth(kind, p, x, y):
    """(f, df/dx, df/dy) of the smooth height fields whose offsets have no closed form: the
    saddle, and the double dome's caps joined by the valley's blend (continued below its
    flange by their tangent cones)."""
    if kind == SADDLE:
        return (x * x - y * y) / (2 * p[1]), x / p[1], -y / p[1]
    d = 0.5 * p[3]
    f1, g1x, g1y = _cap(p, x, y, -d)
    f2, g2x, g2y = _cap(p, x, y, d)
    k = p[4]
    gap = max(k - abs(f1 - f2), 0.0)
    f = max(f1, f2) + gap * gap / (4 * k)
    w = min(max(0.5 + (f1 - f2) / (2 * k), 0.0), 1.0)
    return f, w * g1x + (1 - w) * g2x, w * g1y + (1 - w) * g2y


@jit
def _offset_of(kind, p, x, y, d):
    """(h, dh/dx, dh/dy) at plan point (x, y) of the surface d mm outside ``_smooth``: the
    foot (u, v) whose point moved by d along its unit normal n lies over (x, y), found by the
    fixed-point iteration (u, v) <- (x, y) - d n_xy(u, v) (it contracts by about d times
    the curvature), then h = f(u, v) + d n_z and the foot's slope. NaN where it does not
    settle in 100 steps (an offset past a concave curvature radius folds)."""
    u, v = x, y
    for _ in range(100):
        f, fx, fy = _smooth(kind, p, u, v)
        s = d / math.sqrt(1.0 + fx * fx + fy * fy)
        un, vn = x + fx * s, y + fy * s
        done = abs(un - u) + abs(vn - v) <= 1e-13 * (abs(x) + abs(y) + d)
        u, v = un, vn
        if done:
            f, fx, fy = _smooth(kind, p, u, v)
            return f + d / math.sqrt(1.0 + fx * fx + fy * fy), fx, fy
    return math.nan, math.nan, math.nan


@jit
def inside(kind, p, x, y):
    """True where plan point (x, y) (mm) lies in the mould's domain (a mesh: under its top)."""
    if kind == MESH:
        return math.isfinite(meshquery.top(p, x, y)[0])
    return _in_domain(kind, p, x, y)


@inline
def _in_domain(kind, p, x, y):
    """``inside`` for a closed-form kind: the plan domain's rectangle."""
    if kind == CYLINDER:
        a, c = (x, y) if p[2] == 0.0 else (y, x)
        return abs(a) <= 0.5 * p[1] and abs(c) <= p[3] * p[0]
    return abs(x) <= p[0] and abs(y) <= p[0]


def new_memo(kind):
    """A query memo for ``gap_on`` and ``surface_normal`` on a mould of ``kind``: a mesh's
    (``meshquery.new_memo``), else None. One per thread: it is written by every query."""
    return meshquery.new_memo() if kind == MESH else None


@jit
def gap_on(kind, p, x, y, z, memo):
    """The mould as an implicit surface at the point (x, y, z) (mm): (phi, dphi/dx, dphi/dy,
    dphi/dz, on), phi = 0 on the mould, > 0 on the side the fabric comes from, its gradient
    the outward normal (not unit), and whether a point of the surface there lies on the
    mould (a node placed where ``on`` is False is off the mould). A height field is
    phi = z - h(x, y), gradient (-hx, -hy, 1), on its plan domain; a mesh its signed
    distance, on it within its tolerance, not on the tangent plane continuing it past an
    open edge (``meshquery.signed_distance``, one closest-point query for all of it)."""
    if memo is None:  # a height field in closed form
        h, hx, hy = _closed_form(kind, p, x, y)
        return z - h, -hx, -hy, 1.0, _in_domain(kind, p, x, y)
    phi, g, on = meshquery.signed_distance(p, x, y, z, memo)
    return phi, g[0], g[1], g[2], on


@jit
def gap(kind, p, x, y, z, memo):
    """(phi, dphi/dx, dphi/dy, dphi/dz) of ``gap_on``."""
    phi, gx, gy, gz, _ = gap_on(kind, p, x, y, z, memo)
    return phi, gx, gy, gz


@jit
def surface_normal(kind, p, x, y, z, memo):
    """Unit outward normal (3-tuple) of the mould at the surface point (x, y, z) (mm): the
    tangent plane a node's arm step uses: the normalised gradient of a height field, a mesh's
    interpolated vertex normal (continuous, so an arm steps as over the smooth part)."""
    if memo is None:  # a height field
        _, gx, gy, gz = gap(kind, p, x, y, z, memo)
        s = math.sqrt(gx * gx + gy * gy + gz * gz)
        return (gx / s, gy / s, gz / s)
    return meshquery.normal(p, x, y, z, memo)


@jit
def _evaluate_many(kind, p, x, y, h, hx, hy):
    for m in range(x.size):
        h[m], hx[m], hy[m] = height_gradient(kind, p, x[m], y[m])


@jit
def _inside_many(kind, p, x, y, out):
    for m in range(x.size):
        out[m] = inside(kind, p, x[m], y[m])


def evaluate(kernel, x, y):
    """(h, dh/dx, dh/dy) arrays at broadcast plan points (mm) for ``kernel = (kind, params)``."""
    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    shape = x.shape
    x, y = np.ascontiguousarray(x).ravel(), np.ascontiguousarray(y).ravel()
    h, hx, hy = np.empty(x.size), np.empty(x.size), np.empty(x.size)
    _evaluate_many(kernel[0], kernel[1], x, y, h, hx, hy)
    return h.reshape(shape), hx.reshape(shape), hy.reshape(shape)


@jit
def _gap_many(kind, p, memo, x, y, z, out):
    for m in range(x.size):
        out[m, 0], out[m, 1], out[m, 2], out[m, 3] = gap(kind, p, x[m], y[m], z[m], memo)


def evaluate_gap(kernel, x, y, z):
    """(phi, dphi/dx, dphi/dy, dphi/dz) arrays at broadcast points (mm): ``gap`` per point."""
    x, y, z = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float), np.asarray(z, float))
    shape = x.shape
    out = np.empty((x.size, 4))
    _gap_many(kernel[0], kernel[1], new_memo(kernel[0]), *(np.ascontiguousarray(a).ravel() for a in (x, y, z)), out)
    return tuple(out[:, c].reshape(shape) for c in range(4))


@jit
def _normal_many(kind, p, memo, x, y, z, out):
    for m in range(x.size):
        out[m, 0], out[m, 1], out[m, 2] = surface_normal(kind, p, x[m], y[m], z[m], memo)


def evaluate_normal(kernel, points):
    """``surface_normal`` (..., 3) at points (..., 3) mm."""
    points = np.asarray(points, float)
    flat = np.ascontiguousarray(points.reshape(-1, 3))
    out = np.empty(flat.shape)
    _normal_many(kernel[0], kernel[1], new_memo(kernel[0]), flat[:, 0].copy(), flat[:, 1].copy(), flat[:, 2].copy(), out)
    return out.reshape(points.shape)


def evaluate_inside(kernel, x, y):
    """Boolean array: (x, y) inside the domain of ``kernel = (kind, params)``."""
    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    shape = x.shape
    out = np.empty(x.size, np.bool_)
    _inside_many(kernel[0], kernel[1], np.ascontiguousarray(x).ravel(), np.ascontiguousarray(y).ravel(), out)
    return out.reshape(shape)
