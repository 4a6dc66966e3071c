"""Batched node kernels of the pin-jointed net.

Every function works on arrays with arbitrary leading axes (realisation, candidate,
node, ...) and a trailing axis of 3 for points (x, y, z in mm). Radians inside.

Both ways of placing a node reduce to one problem: find where a circle in space meets
the mould surface. A generator-arm node lies on the circle of radius s around the last
arm node in the normal plane of the steered direction; a filled node lies on the circle
where the two spheres around its placed neighbours meet. ``solve_on_circle`` finds the
root nearest the circle's reference direction by safeguarded Newton, falling back to a
bracketing search where Newton does not settle (kinks, steep walls).
"""

from __future__ import annotations

import numpy as np

from .status import Status

#: Largest circle angle (rad) searched either side of the reference direction.
THETA_MAX = np.deg2rad(89.0)
_NEWTON_ITERS = 12
_BRACKET_SAMPLES = 90
_BRACKET_ITERS = 60


def _point(c, u, v, rho, theta):
    ct = np.cos(theta)[..., None]
    st = np.sin(theta)[..., None]
    return c + rho[..., None] * (ct * u + st * v)


def _gap(surface, c, u, v, rho, theta):
    """Vertical gap z - h(x, y) of the circle point at ``theta`` and its theta-derivative."""
    q = _point(c, u, v, rho, theta)
    ct = np.cos(theta)[..., None]
    st = np.sin(theta)[..., None]
    dq = rho[..., None] * (-st * u + ct * v)
    h, hx, hy = surface.height_gradient(q[..., 0], q[..., 1])
    return q, q[..., 2] - h, dq[..., 2] - hx * dq[..., 0] - hy * dq[..., 1]


def solve_on_circle(surface, c, u, v, rho, tol):
    """Point of the circle ``c + rho (cos t u + sin t v)`` on the surface, |t| < THETA_MAX.

    Returns ``(q, ok)``: q (..., 3) with NaN where no root was found, and ok (bool).
    The root nearest t = 0 is taken. ``tol`` is the vertical gap accepted (mm).
    Newton iterates only on the entries that have not yet converged.
    """
    shape = np.broadcast_shapes(c.shape, u.shape, v.shape, rho.shape + (3,))[:-1]
    c, u, v = (np.broadcast_to(a, shape + (3,)).reshape(-1, 3) for a in (c, u, v))
    rho = np.broadcast_to(rho, shape).reshape(-1)
    with np.errstate(invalid="ignore"):
        finite = np.isfinite(c.sum(-1) + u.sum(-1) + v.sum(-1) + rho) & (rho > 0)
    if not finite.all():  # keep NaN out of the surface (an STL spline would refuse it)
        c, u, v = (np.where(finite[:, None], a, 0.0) for a in (c, u, v))
        rho = np.where(finite, rho, 1.0)
    theta = np.zeros(rho.shape)
    active = None  # first sweeps over every entry; then only the unconverged are gathered
    with np.errstate(divide="ignore", invalid="ignore"):
        for sweep in range(_NEWTON_ITERS):
            if active is None:
                _, g, dg = _gap(surface, c, u, v, rho, theta)
                done = ~finite | (np.abs(g) < tol)
            else:
                _, g, dg = _gap(surface, c[active], u[active], v[active], rho[active], theta[active])
                done = np.abs(g) < tol
            step = np.clip(-g / dg, -0.2, 0.2)
            moving = np.isfinite(step) & ~done
            if active is None:
                theta += np.where(moving, step, 0.0)
                if sweep == 1:
                    active = np.flatnonzero(moving)
            else:
                theta[active] += np.where(moving, step, 0.0)
                active = active[moving]
            if active is not None and active.size == 0:
                break
    q = _point(c, u, v, rho, theta)
    g = q[:, 2] - surface.height(q[:, 0], q[:, 1])
    ok = finite & (np.abs(g) < tol) & (np.abs(theta) < THETA_MAX)
    retry = finite & ~ok
    if retry.any():
        q_r, ok_r = _bracket(surface, c[retry], u[retry], v[retry], rho[retry], tol)
        q[retry] = q_r
        ok[retry] = ok_r
    q[~ok] = np.nan
    return q.reshape(shape + (3,)), ok.reshape(shape)


def _bracket(surface, c, u, v, rho, tol):
    """Sign-change search on a grid of circle angles, then Illinois false position."""
    grid = np.linspace(-THETA_MAX, THETA_MAX, _BRACKET_SAMPLES)
    m = rho.shape[0]
    t = np.broadcast_to(grid, (m, grid.size))
    _, g, _ = _gap(surface, c[:, None], u[:, None], v[:, None], rho[:, None], t)
    change = np.sign(g[:, :-1]) * np.sign(g[:, 1:]) <= 0
    centre = np.abs(0.5 * (grid[:-1] + grid[1:]))
    score = np.where(change, centre, np.inf)
    pick = np.argmin(score, axis=1)
    found = np.isfinite(score[np.arange(m), pick])
    a = grid[pick]
    b = grid[pick + 1]
    ga = g[np.arange(m), pick]
    gb = g[np.arange(m), pick + 1]
    side = np.zeros(m)
    t = 0.5 * (a + b)
    settled = ~found  # entries stop once converged, so a batch equals single calls
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(_BRACKET_ITERS):
            t_new = np.where(gb != ga, b - gb * (b - a) / (gb - ga), 0.5 * (a + b))
            t_new = np.where((t_new > np.minimum(a, b)) & (t_new < np.maximum(a, b)), t_new, 0.5 * (a + b))
            _, g_new, _ = _gap(surface, c, u, v, rho, t_new)
            t = np.where(settled, t, t_new)
            settled |= np.abs(g_new) < tol
            left = np.sign(g_new) == np.sign(ga)
            # Illinois: halve the retained end's value when the same end is kept twice.
            gb = np.where(left & (side == 1), 0.5 * gb, gb)
            ga = np.where(~left & (side == -1), 0.5 * ga, ga)
            a = np.where(left, t_new, a)
            ga = np.where(left, g_new, ga)
            b = np.where(left, b, t_new)
            gb = np.where(left, gb, g_new)
            side = np.where(left, 1, -1)
            if settled.all():
                break
    q, g, _ = _gap(surface, c, u, v, rho, t)
    return q, found & (np.abs(g) < tol)


def unit(a):
    return a / norm(a)[..., None]


def norm(a):
    """Euclidean length over the last axis (faster than np.linalg.norm for (..., 3))."""
    return np.sqrt(dot(a, a))


def dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def cross(a, b):
    """Cross product over the last axis, written out (np.cross is slow on small axes)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def arm_step(surface, p, direction, turn, length, tol):
    """Next generator-arm node: distance ``length`` from ``p`` along the surface direction
    obtained by turning ``direction`` by ``turn`` (rad) about the surface normal at ``p``.

    ``turn = 0`` gives the discrete geodesic (straightest) path. Returns (q, status).
    """
    n = surface.normal(p[..., 0], p[..., 1])
    t = unit(direction - dot(direction, n)[..., None] * n)
    w = cross(n, t)
    t = np.cos(turn)[..., None] * t + np.sin(turn)[..., None] * w
    q, ok = solve_on_circle(surface, p, t, n, length, tol)
    return q, _status(surface, q, ok, np.isfinite(p.sum(-1) + direction.sum(-1)))


def fill_node(surface, a, b, c, la, lb, sign_ij, tol):
    """Node at distance ``la`` from its fibre-1 neighbour ``a`` and ``lb`` from its fibre-2
    neighbour ``b``, on the side away from the diagonal-opposite node ``c``.

    ``sign_ij`` is (i_node - i_a) * (j_node - j_b) = +-1: the orientation that a right-handed
    cell must keep (a node whose cell turns over is flagged FOLDED). Returns (q, status).
    """
    ab = b - a
    d = norm(ab)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = ab / d[..., None]
        along = (la**2 - lb**2 + d**2) / (2 * d)
        rho = np.sqrt(la**2 - along**2)
        centre = a + along[..., None] * e
        guess = a + b - c - centre
        u = unit(guess - dot(guess, e)[..., None] * e)
    v = cross(e, u)
    q, ok = solve_on_circle(surface, centre, u, v, rho, tol)
    parents = np.isfinite(a.sum(-1) + b.sum(-1) + c.sum(-1))  # NaN marks an invalid node
    status = _status(surface, q, ok, parents)
    n = surface.normal(q[..., 0], q[..., 1])
    with np.errstate(invalid="ignore"):
        turned = sign_ij * dot(cross(q - a, q - b), n) <= 0
    status = np.where((status == Status.OK) & turned, Status.FOLDED, status).astype(np.int8)
    q[status != Status.OK] = np.nan
    return q, status


def _status(surface, q, ok, parents_valid):
    parents_valid = np.broadcast_to(parents_valid, ok.shape)
    inside = np.zeros(ok.shape, bool)
    inside[ok] = surface.inside(q[ok][:, 0], q[ok][:, 1])
    status = np.full(ok.shape, Status.OK, np.int8)
    status[~ok] = Status.NO_INTERSECTION
    status[ok & ~inside] = Status.OFF_MOULD
    status[~parents_valid] = Status.DEPENDENT
    q[status != Status.OK] = np.nan
    return status


def quad_shear(q0, q1, q2, q3, eps0):
    """Signed shear (rad) of the cell with corners q0..q3 in cyclic order.

    ``eps0`` is +1 when q0 is the cell's (min i, min j) or (max i, max j) corner and -1
    otherwise. At each corner the shear is 90 deg minus the angle between the +i and +j
    edges, i.e. arcsin of the cosine of that angle, with the sign alternating round the
    cell; the cell value is the mean of the four.
    """
    e01, e12, e23, e30 = (unit(b - a) for a, b in ((q0, q1), (q1, q2), (q2, q3), (q3, q0)))
    s = (
        np.arcsin(np.clip(-dot(e30, e01), -1.0, 1.0))
        - np.arcsin(np.clip(-dot(e01, e12), -1.0, 1.0))
        + np.arcsin(np.clip(-dot(e12, e23), -1.0, 1.0))
        - np.arcsin(np.clip(-dot(e23, e30), -1.0, 1.0))
    )
    return 0.25 * eps0 * s
