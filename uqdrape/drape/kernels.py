"""Node kernels of the pin-jointed net, compiled (numba) per node.

``arm_node`` and ``fill`` place one node (points are 3-tuples, x, y, z in mm; radians
inside) and are called from the compiled net loops (``ring``).

Both ways of placing a node reduce to one problem: find where a circle in space meets
the mould surface, the zero set of the mould's implicit function phi(p) (``compiled.gap``:
a height field is phi = z - h(x, y); a triangle mesh its signed distance). A generator-arm node lies on the circle of radius s around the last
arm node in the normal plane of the steered direction; a filled node lies on the circle
where the two spheres around its placed neighbours meet. ``_solve_on_circle`` finds the
root nearest the circle's reference direction by safeguarded Newton, falling back to a
bracketing search where Newton does not settle (kinks, steep walls).

Where the circle cuts the surface more than once (a fold, the far side of a thin flange or
wall, a sheet's other face), the root kept is the nearest one on the sheet the net is on:
the circle's parameter is oriented so that, on that sheet, phi increases with t (the circle
leaves the mould through its outer side), so a crossing where phi falls is the surface
seen from inside and is never taken. A node with no such root is NO_INTERSECTION, not
placed on another face.

``memo`` is the mould's query memo (``compiled.new_memo``): it makes a mesh's nearby queries
cheap and never changes an answer.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import inline, jit
from ..geometry.compiled import gap_on, surface_normal
from .status import Status

#: Largest circle angle (rad) searched either side of the reference direction.
THETA_MAX = np.deg2rad(89.0)
_NEWTON_ITERS = 12
_BRACKET_GRID = np.linspace(-THETA_MAX, THETA_MAX, 90)
#: Grid intervals in the order the bracket search tries them: nearest t = 0 first (ties to
#: the lower index), so the scan stops at the first sign change.
_BRACKET_ORDER = np.array(sorted(range(_BRACKET_GRID.size - 1), key=lambda s: (
    abs(0.5 * (_BRACKET_GRID[s] + _BRACKET_GRID[s + 1])), s)), np.int64)
_BRACKET_ITERS = 60
#: Status codes as plain ints, for the compiled kernels.
OK, NO_INTERSECTION, OFF_MOULD, DEPENDENT, FOLDED = (int(s) for s in (
    Status.OK, Status.NO_INTERSECTION, Status.OFF_MOULD, Status.DEPENDENT, Status.FOLDED))


NAN3 = (math.nan, math.nan, math.nan)


@inline
def _gap(kind, par, memo, c, u, v, rho, t):
    """Circle point q at angle t (mm), the mould function phi(q) (mm), its t-derivative, the
    gradient of phi at q (3-tuple) and whether q is on the mould (``compiled.gap_on``). For a
    height field, phi = z - h and the derivative (d2 - hx d0) - hy d1, the same arithmetic
    as the vertical gap it replaces."""
    ct, st = math.cos(t), math.sin(t)
    q = (c[0] + rho * (ct * u[0] + st * v[0]), c[1] + rho * (ct * u[1] + st * v[1]),
         c[2] + rho * (ct * u[2] + st * v[2]))
    d0, d1, d2 = rho * (-st * u[0] + ct * v[0]), rho * (-st * u[1] + ct * v[1]), rho * (-st * u[2] + ct * v[2])
    phi, gx, gy, gz, on = gap_on(kind, par, q[0], q[1], q[2], memo)
    return q, phi, (gz * d2 + gx * d0) + gy * d1, (gx, gy, gz), on


@jit
def _bracket(kind, par, memo, c, u, v, rho, tol, up):
    """Sign change nearest t = 0 on a grid of circle angles where phi rises with ``up`` * t
    (the sheet's outward crossing), then Illinois false position.

    The grid's gaps are evaluated lazily, interval by interval outwards from t = 0."""
    grid = _BRACKET_GRID
    g = np.empty(grid.size)
    seen = np.zeros(grid.size, np.bool_)
    pick, found = 0, False
    for s in _BRACKET_ORDER:
        for e in (s, s + 1):
            if not seen[e]:
                g[e] = _gap(kind, par, memo, c, u, v, rho, grid[e])[1]
                seen[e] = True
        if np.sign(g[s]) * np.sign(g[s + 1]) <= 0 and (g[s + 1] - g[s]) * up > 0:
            pick, found = s, True
            break
    a, b = grid[pick], grid[pick + 1]
    ga, gb = g[pick], g[pick + 1]
    side = 0
    t = 0.5 * (a + b)
    if found:
        for _ in range(_BRACKET_ITERS):
            t_new = b - gb * (b - a) / (gb - ga) if gb != ga else 0.5 * (a + b)
            if not (min(a, b) < t_new < max(a, b)):
                t_new = 0.5 * (a + b)
            g_new = _gap(kind, par, memo, c, u, v, rho, t_new)[1]
            t = t_new
            if abs(g_new) < tol:
                break
            left = np.sign(g_new) == np.sign(ga)
            # Illinois: halve the retained end's value when the same end is kept twice.
            if left and side == 1:
                gb = 0.5 * gb
            if not left and side == -1:
                ga = 0.5 * ga
            if left:
                a, ga = t_new, g_new
            else:
                b, gb = t_new, g_new
            side = 1 if left else -1
    q, g_t, _, grad, on = _gap(kind, par, memo, c, u, v, rho, t)
    return q, found and abs(g_t) < tol, grad, on


@jit
def _solve_on_circle(kind, par, memo, c, u, v, rho, tol, up):
    """Point of the circle ``c + rho (cos t u + sin t v)`` on the surface, |t| < THETA_MAX,
    where phi rises with ``up`` * t (+-1: the net's own sheet, see the module docstring).

    Returns (q, ok, gradient of phi at q, q on the mould): the root nearest t = 0 by safeguarded Newton
    (steps clipped to 0.2 rad), falling back to a bracketing search when Newton does not
    settle in _NEWTON_ITERS steps, starts to alternate or lands on a crossing of the wrong
    orientation; ``tol`` is the |phi| accepted (mm).
    """
    if not (math.isfinite(c[0] + c[1] + c[2] + u[0] + u[1] + u[2] + v[0] + v[1] + v[2] + rho) and rho > 0):
        return NAN3, False, NAN3, False
    theta, last, older = 0.0, math.nan, math.nan
    q, g, dg, grad, on = _gap(kind, par, memo, c, u, v, rho, theta)
    for _ in range(_NEWTON_ITERS):
        if abs(g) < tol:
            break
        step = -g / dg
        if math.isnan(step):
            break
        older, last, theta = last, theta, theta + min(max(step, -0.2), 0.2)
        if theta == older:  # a 2-cycle: Newton would alternate until it gives up
            return _bracket(kind, par, memo, c, u, v, rho, tol, up)
        q, g, dg, grad, on = _gap(kind, par, memo, c, u, v, rho, theta)
    if abs(g) < tol and abs(theta) < THETA_MAX and dg * up > 0:
        return q, True, grad, on
    return _bracket(kind, par, memo, c, u, v, rho, tol, up)


@jit
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@jit
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@jit
def _unit(a):
    s = math.sqrt(_dot(a, a))
    return (a[0] / s, a[1] / s, a[2] / s)


@jit
def _status(ok, on, parents_valid):
    """Status code of a node from its root (found, on the mould) and its parents (``Status``)."""
    if not parents_valid:
        return DEPENDENT
    if not ok:
        return NO_INTERSECTION
    if not on:
        return OFF_MOULD
    return OK


@jit
def arm_node(kind, par, memo, p, direction, turn, length, tol):
    """Next generator-arm node: distance ``length`` (mm) from ``p`` along the surface
    direction obtained by turning ``direction`` by ``turn`` (rad) about the normal at ``p``.

    ``turn = 0`` gives the discrete geodesic (straightest) path. Returns (q, status).
    """
    n = surface_normal(kind, par, p[0], p[1], p[2], memo)
    dn = _dot(direction, n)
    t = _unit((direction[0] - dn * n[0], direction[1] - dn * n[1], direction[2] - dn * n[2]))
    w = _cross(n, t)
    ct, st = math.cos(turn), math.sin(turn)
    t = (ct * t[0] + st * w[0], ct * t[1] + st * w[1], ct * t[2] + st * w[2])
    q, ok, _, on = _solve_on_circle(kind, par, memo, p, t, n, length, tol, 1.0)  # t rises along n: outwards
    parents = math.isfinite(p[0] + p[1] + p[2] + direction[0] + direction[1] + direction[2])
    status = _status(ok, on, parents)
    return (q if status == OK else NAN3), status


@jit
def fill(kind, par, memo, a, b, c, la, lb, sign_ij, tol):
    """Node at distance ``la`` (mm) from its fibre-1 neighbour ``a`` and ``lb`` from its
    fibre-2 neighbour ``b``, on the side away from the diagonal-opposite node ``c``.

    ``sign_ij`` is (i_node - i_a) * (j_node - j_b) = +-1: the orientation that a
    right-handed cell must keep (a node whose cell turns over is FOLDED). Neighbours closer
    than ``tol`` (mm) span no circle (a cell folded flat into a sharp corner, its two
    neighbours on one point): the node is NO_INTERSECTION, not placed wherever round-off
    points. Returns (q, status).
    """
    ab = (b[0] - a[0], b[1] - a[1], b[2] - a[2])
    d = math.sqrt(_dot(ab, ab))
    if d <= tol:
        parents = math.isfinite(a[0] + a[1] + a[2] + b[0] + b[1] + b[2] + c[0] + c[1] + c[2])
        return NAN3, _status(False, False, parents)
    e = (ab[0] / d, ab[1] / d, ab[2] / d)
    along = (la * la - lb * lb + d * d) / (2 * d)
    rho = math.sqrt(la * la - along * along)
    centre = (a[0] + along * e[0], a[1] + along * e[1], a[2] + along * e[2])
    guess = (a[0] + b[0] - c[0] - centre[0], a[1] + b[1] - c[1] - centre[1], a[2] + b[2] - c[2] - centre[2])
    ge = _dot(guess, e)
    u = _unit((guess[0] - ge * e[0], guess[1] - ge * e[1], guess[2] - ge * e[2]))
    v = _cross(e, u)
    # v = e x u points along sign_ij times the outward normal on a right-handed cell
    q, ok, grad, on = _solve_on_circle(kind, par, memo, centre, u, v, rho, tol, float(sign_ij))
    parents = math.isfinite(a[0] + a[1] + a[2] + b[0] + b[1] + b[2] + c[0] + c[1] + c[2])
    status = _status(ok, on, parents)
    if status == OK:
        s = math.sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2])
        n = (grad[0] / s, grad[1] / s, grad[2] / s)  # the normal at q, from the root's last gradient
        qa = (q[0] - a[0], q[1] - a[1], q[2] - a[2])
        qb = (q[0] - b[0], q[1] - b[1], q[2] - b[2])
        if sign_ij * _dot(_cross(qa, qb), n) <= 0:
            status = FOLDED
    return (q if status == OK else NAN3), status


@jit
def _asin1(c):
    return math.asin(min(max(c, -1.0), 1.0))


@jit
def net_shear(P, out):
    """Signed cell shear (rad) of nets P (R, N, N, 3) into out (R, N-1, N-1): the value of
    ``shear`` per cell, with each unit edge computed once per net (the corner shear is
    arcsin of the dot product of the cell's +i and +j unit edges)."""
    N = P.shape[1]
    ei = np.empty((N - 1, N, 3))  # +i edges
    ej = np.empty((N, N - 1, 3))  # +j edges
    for r in range(P.shape[0]):
        for a in range(N):
            for b in range(N):
                p = (P[r, a, b, 0], P[r, a, b, 1], P[r, a, b, 2])
                if a + 1 < N:
                    ei[a, b, 0], ei[a, b, 1], ei[a, b, 2] = _unit(
                        (P[r, a + 1, b, 0] - p[0], P[r, a + 1, b, 1] - p[1], P[r, a + 1, b, 2] - p[2]))
                if b + 1 < N:
                    ej[a, b, 0], ej[a, b, 1], ej[a, b, 2] = _unit(
                        (P[r, a, b + 1, 0] - p[0], P[r, a, b + 1, 1] - p[1], P[r, a, b + 1, 2] - p[2]))
        for a in range(N - 1):
            for b in range(N - 1):
                lo, hi, left, right = ei[a, b], ei[a, b + 1], ej[a, b], ej[a + 1, b]
                out[r, a, b] = 0.25 * (_asin1(_dot(lo, left)) + _asin1(_dot(lo, right)) + _asin1(_dot(hi, left))
                                       + _asin1(_dot(hi, right)))


@jit
def net_node_mean(cells, out):
    """Mean of the finite cells around each node: cells (R, m, m) into out (R, m + 1, m + 1),
    NaN where a node has none. Cells are added in a fixed order (the cell at (a, b), then
    (a, b - 1), (a - 1, b), (a - 1, b - 1)), so the value does not depend on the batch."""
    m = cells.shape[1]
    for r in range(cells.shape[0]):
        for a in range(m + 1):
            for b in range(m + 1):
                total, count = 0.0, 0
                for ca in (a, a - 1):
                    for cb in (b, b - 1):
                        if 0 <= ca < m and 0 <= cb < m and math.isfinite(cells[r, ca, cb]):
                            total += cells[r, ca, cb]
                            count += 1
                out[r, a, b] = total / count if count > 0 else math.nan


def _flat(shape, *arrays):
    """(array, is_point) pairs broadcast to ``shape`` (+ (3,) for points), flattened, float64."""
    out = []
    for a, point in arrays:
        tail = (3,) if point else ()
        out.append(np.ascontiguousarray(np.broadcast_to(a, shape + tail)).reshape((-1,) + tail))
    return out


@jit
def shear(q0, q1, q2, q3, eps0):
    """Signed shear (rad) of the cell with corners q0..q3 (3-tuples, mm) in cyclic order.

    ``eps0`` is +1 when q0 is the cell's (min i, min j) or (max i, max j) corner and -1
    otherwise. At each corner the shear is 90 deg minus the angle between the +i and +j
    edges, i.e. arcsin of the cosine of that angle, with the sign alternating round the
    cell; the cell value is the mean of the four.
    """
    e01 = _unit((q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]))
    e12 = _unit((q2[0] - q1[0], q2[1] - q1[1], q2[2] - q1[2]))
    e23 = _unit((q3[0] - q2[0], q3[1] - q2[1], q3[2] - q2[2]))
    e30 = _unit((q0[0] - q3[0], q0[1] - q3[1], q0[2] - q3[2]))
    s = (math.asin(min(max(-_dot(e30, e01), -1.0), 1.0)) - math.asin(min(max(-_dot(e01, e12), -1.0), 1.0))
         + math.asin(min(max(-_dot(e12, e23), -1.0), 1.0)) - math.asin(min(max(-_dot(e23, e30), -1.0), 1.0)))
    return 0.25 * eps0 * s


@jit
def _shear_many(q0, q1, q2, q3, eps0, out):
    for m in range(out.size):
        out[m] = shear((q0[m, 0], q0[m, 1], q0[m, 2]), (q1[m, 0], q1[m, 1], q1[m, 2]),
                       (q2[m, 0], q2[m, 1], q2[m, 2]), (q3[m, 0], q3[m, 1], q3[m, 2]), eps0[m])


def quad_shear(q0, q1, q2, q3, eps0):
    """``shear`` over broadcast arrays: corners (..., 3) mm, eps0 (...) -> shear (...) rad."""
    q0, q1, q2, q3, eps0 = (np.asarray(a, float) for a in (q0, q1, q2, q3, eps0))
    shape = np.broadcast_shapes(q0.shape[:-1], q1.shape[:-1], q2.shape[:-1], q3.shape[:-1], eps0.shape)
    args = _flat(shape, (q0, True), (q1, True), (q2, True), (q3, True), (eps0, False))
    out = np.empty(args[-1].size)
    _shear_many(*args, out)
    return out.reshape(shape)
