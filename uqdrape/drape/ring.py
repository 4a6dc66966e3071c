"""The net's construction loops, compiled per realisation: the geodesic net and the
energy drape's ring step (thesis Fig 5.1).

``geodesic_block`` traces the four generator arms as discrete geodesics and fills the
rest of the net anti-diagonal by anti-diagonal (|i| + |j| = d).

At ring k each arm gets one segment whose turn angle about the surface normal (rad)
minimises the energy of the pattern so far. That energy splits into one term per arm
(its bending penalty, the cells and blank-holder segments along its two side chains)
and one per quadrant corner (the corner cell and its two blank-holder segments, coupling
the quadrant's two arms). ``sides`` and ``corners`` evaluate them for candidate turn
angles of one realisation, ``minimise`` finds the four angles by trust-region Newton
on finite-difference stencils (placed only around accepted trials), and ``drape_ring``
places one ring of every realisation of a block, each realisation to its own iteration
count (a straggler holds no other).

Arrays of one realisation r (mm unless stated): P (N, N, 3) the net, NaN where unplaced;
blank (3, 2) the flat blank, whose node (i, j) lies at blank[0] + i blank[1] + j blank[2]
(the crossover and the fibre steps s e1, s e2); seg_i (2n, 2n+1), seg_j (2n+1, 2n) segment lengths;
s1, s2 (2n, 2n) cell segment lengths and g0 (2n, 2n) zero-energy angles (rad);
centre (2,) the crossover. ``surf`` is the mould's ``(kind, params)`` and ``memo`` its query
memo (``compiled.new_memo``, one per thread: a mesh's answers to nearby points, None
for a closed form), ``mat`` the
material's and ``bh`` the blank-holder's compiled form. Energies in J.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit
from ..material.model import cell_energy
from .energy import segment_energy
from .kernels import OK, arm_node, fill, shear

#: Arm steps (di, dj), ordered +i, +j, -i, -j.
ARMS = ((1, 0), (0, 1), (-1, 0), (0, -1))
#: Per quadrant ++, -+, --, +-: i-family arm and side, j-family arm and side, signs si, sj.
CORNERS = ((0, 0, 1, 0, 1, 1), (2, 0, 1, 1, -1, 1), (2, 1, 3, 1, -1, -1), (0, 1, 3, 0, 1, -1))
#: Energy (J) charged to the minimiser per node a candidate fails to place: invalid nodes
#: carry no shear energy, so without it the minimiser would prefer turns that lose nodes.
#: Equal counts cancel in the stencils; it never enters the reported energies.
INVALID_NODE_ENERGY = 1e3
#: Finite-difference step (rad) of the turn angles.
STENCIL = 1e-3
#: Stencil candidates of the minimiser: (i-arm candidate, j-arm candidate) per corner
#: evaluation, candidates 0, 1, 2 being turn - h, turn, turn + h.
_PAIRS = ((0, 1), (1, 1), (2, 1), (1, 0), (1, 2), (2, 2))


@jit
def _arm_length(seg_i, seg_j, n, k, a):
    """Length (mm) of the k-th segment of arm a."""
    di, dj = ARMS[a]
    if a % 2 == 0:  # fibre-1 arm: segment (k di, 0)-((k-1) di, 0)
        return seg_i[min(k * di, (k - 1) * di) + n, n]
    return seg_j[n, min(k * dj, (k - 1) * dj) + n]


@jit
def _arm_direction(P, n, k, a, first_dir):
    """Direction of arm a's last segment before ring k (the first one's for k = 1)."""
    di, dj = ARMS[a]
    if k == 1:
        return (first_dir[a, 0], first_dir[a, 1], first_dir[a, 2])
    last = _node(P, n, (k - 1) * di, (k - 1) * dj)
    before = _node(P, n, (k - 2) * di, (k - 2) * dj)
    return (last[0] - before[0], last[1] - before[1], last[2] - before[2])


@jit
def _put(P, status, n, i, j, q, st):
    P[i + n, j + n, 0], P[i + n, j + n, 1], P[i + n, j + n, 2] = q
    status[i + n, j + n] = st


@jit
def _geodesic_net(surf, memo, tol, n, P, status, seg_i, seg_j, first_dir):
    """Geodesic net of one realisation: P (N, N, 3) mm and status (N, N), with the
    crossover placed, are filled in place; seg_i, seg_j, first_dir (4, 3); ``memo`` the
    mould's query memo (``compiled.new_memo``)."""
    kind, par = surf
    for k in range(1, n + 1):
        for a in range(4):
            di, dj = ARMS[a]
            q, st = arm_node(kind, par, memo, _node(P, n, (k - 1) * di, (k - 1) * dj),
                             _arm_direction(P, n, k, a, first_dir), 0.0, _arm_length(seg_i, seg_j, n, k, a), tol)
            _put(P, status, n, k * di, k * dj, q, st)
    for d in range(2, 2 * n + 1):
        for a in range(max(1, d - n), min(n, d - 1) + 1):
            for si, sj in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
                i, j = si * a, sj * (d - a)
                q, st = fill(kind, par, memo, _node(P, n, i - si, j), _node(P, n, i, j - sj), _node(P, n, i - si, j - sj),
                             seg_i[min(i, i - si) + n, j + n], seg_j[i + n, min(j, j - sj) + n], si * sj, tol)
                _put(P, status, n, i, j, q, st)


@jit
def geodesic_block(surf, memo, tol, n, P, status, seg_i, seg_j, first_dir):
    """Geodesic nets of a block, one after the other: P (R, N, N, 3), status (R, N, N),
    seg_i, seg_j, first_dir (R, 4, 3) as ``_geodesic_net`` per realisation."""
    for r in range(P.shape[0]):
        _geodesic_net(surf, memo, tol, n, P[r], status[r], seg_i[r], seg_j[r], first_dir[r])


@jit
def boundary_blankholder(n, k, P, blank, centre, force, mu, bh, out):
    """Blank-holder energy (J) of ring k's boundary polygon per quadrant, out (R, 4), for the
    nets P (R, N, N, 3) of a block: per quadrant (si, sj) its fibre-2 segments
    (si k, j)-(si k, j + 1) and fibre-1 segments (i, sj k)-(i + 1, sj k); unplaced ends
    add nothing. blank (R, 3, 2), centre (R, 2), force and mu (R,) as in ``sides``. Without
    force every segment's energy is 0, so it is not evaluated (a geodesic drape's case)."""
    for r in range(P.shape[0]):
        if force[r] == 0.0:
            out[r] = 0.0
            continue
        for q in range(4):
            si, sj = CORNERS[q][4], CORNERS[q][5]
            total = 0.0
            for t in range(k):
                lo = t if sj > 0 else t - k  # fibre-2 segment (si k, lo)-(si k, lo + 1)
                a, b = si * k + n, lo + n
                e = segment_energy(bh, P[r, a, b], P[r, a, b + 1], _flat(blank[r], si * k, lo),
                                   _flat(blank[r], si * k, lo + 1), centre[r], force[r], mu[r])
                if not math.isnan(e):
                    total += e
                lo = t if si > 0 else t - k  # fibre-1 segment (lo, sj k)-(lo + 1, sj k)
                a, b = lo + n, sj * k + n
                e = segment_energy(bh, P[r, a, b], P[r, a + 1, b], _flat(blank[r], lo, sj * k),
                                   _flat(blank[r], lo + 1, sj * k), centre[r], force[r], mu[r])
                if not math.isnan(e):
                    total += e
            out[r, q] = total


@jit
def _node(P, n, i, j):
    return (P[i + n, j + n, 0], P[i + n, j + n, 1], P[i + n, j + n, 2])


@jit
def _flat(blank, i, j):
    """Plan position (mm) of node (i, j) in the flat blank."""
    return (blank[0, 0] + i * blank[1, 0] + j * blank[2, 0], blank[0, 1] + i * blank[1, 1] + j * blank[2, 1])


@jit
def _finite0(e):
    """NaN -> 0 and +-inf -> the largest finite number, as numpy.nan_to_num."""
    if math.isnan(e):
        return 0.0
    return min(max(e, -1.7976931348623157e308), 1.7976931348623157e308)


@jit
def sides(surf, memo, tol, n, k, P, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, first_dir, bend,
          mat, bh, turns, S, St, energy):
    """Arm nodes and side chains of ring k for candidate turn angles ``turns`` (M, 4) rad.

    Writes the chain nodes S (M, 4, 2, >= k, 3) (chain node m of arm a, side s at index
    [c, a, s, m]), their status St and the energy per arm ``energy`` (M, 4): bending
    (``bend`` = B / s in J/rad²) + side cells + side blank-holder segments + the penalty
    for unplaced nodes.
    """
    kind, par = surf
    for c in range(turns.shape[0]):
        for a in range(4):
            di, dj = ARMS[a]
            turn = turns[c, a]
            q, st = arm_node(kind, par, memo, _node(P, n, (k - 1) * di, (k - 1) * dj), _arm_direction(P, n, k, a, first_dir),
                             turn, _arm_length(seg_i, seg_j, n, k, a), tol)
            invalid = 0
            cells = 0.0
            held = 0.0
            ifam = di != 0
            for side in range(2):
                sgn = 1 - 2 * side
                ei, ej = (0, sgn) if ifam else (sgn, 0)
                S[c, a, side, 0, 0], S[c, a, side, 0, 1], S[c, a, side, 0, 2] = q
                St[c, a, side, 0] = st
                invalid += st != OK
                prev = q
                for m in range(1, k):
                    xi, xj = k * di + m * ei, k * dj + m * ej
                    fi, fj = xi - di, xj - dj  # fixed neighbour, ring k - 1
                    fixed = _node(P, n, fi, fj)
                    if ifam:
                        ai, bj = fi, xj - ej
                        na, nb = fixed, prev
                    else:
                        ai, bj = xi - ei, fj
                        na, nb = prev, fixed
                    x, xs = fill(kind, par, memo, na, nb, _node(P, n, fi - ei, fj - ej),
                                 seg_i[min(xi, ai) + n, xj + n], seg_j[xi + n, min(xj, bj) + n],
                                 (xi - ai) * (xj - bj), tol)
                    S[c, a, side, m, 0], S[c, a, side, m, 1], S[c, a, side, m, 2] = x
                    St[c, a, side, m] = xs
                    invalid += xs != OK
                    inner = _node(P, n, (k - 1) * di + m * ei, (k - 1) * dj + m * ej)
                    inner_prev = _node(P, n, (k - 1) * di + (m - 1) * ei, (k - 1) * dj + (m - 1) * ej)
                    eps0 = 1.0 if (di + ei) * (dj + ej) > 0 else -1.0
                    gamma = shear(inner_prev, prev, x, inner, eps0)
                    ci = min(k * di, (k - 1) * di) + min((m - 1) * ei, m * ei) + n
                    cj = min(k * dj, (k - 1) * dj) + min((m - 1) * ej, m * ej) + n
                    e = cell_energy(mat, gamma, s1[ci, cj], s2[ci, cj], g0[ci, cj])
                    if not math.isnan(e):
                        cells += e
                    e = segment_energy(bh, prev, x, _flat(blank, xi - ei, xj - ej), _flat(blank, xi, xj),
                                       centre, force, mu)
                    if not math.isnan(e):
                        held += e
                    prev = x
            energy[c, a] = bend * turn**2 + INVALID_NODE_ENERGY * invalid + cells + held


@jit
def corners(surf, memo, tol, n, k, P, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, mat, bh, S, pairs,
            X, Xs, energy):
    """Quadrant corner nodes of ring k for candidate pairs ``pairs`` (C, 2): (candidate of
    the i-family arm, candidate of the j-family arm) of the side chains S.

    Writes nodes X (C, 4, 3), status Xs (C, 4) and energy (C, 4): the corner cell and the
    two blank-holder segments that end at the corner, plus the unplaced-node penalty.
    """
    kind, par = surf
    for c in range(pairs.shape[0]):
        ca, cb = pairs[c, 0], pairs[c, 1]
        for q in range(4):
            qa, sa, qb, sb, si, sj = CORNERS[q]
            a = (S[cb, qb, sb, k - 1, 0], S[cb, qb, sb, k - 1, 1], S[cb, qb, sb, k - 1, 2])  # (si(k-1), sj k)
            b = (S[ca, qa, sa, k - 1, 0], S[ca, qa, sa, k - 1, 1], S[ca, qa, sa, k - 1, 2])  # (si k, sj(k-1))
            diag = _node(P, n, si * (k - 1), sj * (k - 1))
            x, xs = fill(kind, par, memo, a, b, diag, seg_i[min(si * k, si * (k - 1)) + n, sj * k + n],
                         seg_j[si * k + n, min(sj * k, sj * (k - 1)) + n], si * sj, tol)
            X[c, q, 0], X[c, q, 1], X[c, q, 2] = x
            Xs[c, q] = xs
            gamma = shear(diag, a, x, b, float(si * sj))
            ci, cj = min(si * k, si * (k - 1)) + n, min(sj * k, sj * (k - 1)) + n
            cell = cell_energy(mat, gamma, s1[ci, cj], s2[ci, cj], g0[ci, cj])
            fx = _flat(blank, si * k, sj * k)
            held = (segment_energy(bh, a, x, _flat(blank, si * (k - 1), sj * k), fx, centre, force, mu)
                    + segment_energy(bh, b, x, _flat(blank, si * k, sj * (k - 1)), fx, centre, force, mu))
            energy[c, q] = _finite0(cell) + _finite0(held) + INVALID_NODE_ENERGY * (xs != OK)


@jit
def _stencil(e_arm, e_corner, h, grad, hess):
    """Gradient (4,) and Hessian (4, 4) of the step energy from the stencil energies: per arm
    e_arm (3, 4) at turn - h, turn, turn + h, per corner e_corner (6, 4) at the ``_PAIRS``
    (NaN energies count as +inf; non-finite results are clamped by ``_finite0``)."""
    per_arm = np.empty((3, 4))
    for a in range(4):
        for c in range(3):
            if math.isnan(e_arm[c, a]):
                e_arm[c, a] = math.inf
            per_arm[c, a] = e_arm[c, a]
    hess[:] = 0.0
    for q in range(4):
        qa, _, qb, _, _, _ = CORNERS[q]
        for c in range(3):
            per_arm[c, qa] += e_corner[c, q]
            per_arm[c, qb] += e_corner[(3, 1, 4)[c], q]
        hess[qa, qb] = hess[qb, qa] = _finite0((e_corner[5, q] - e_corner[2, q] - e_corner[4, q] + e_corner[1, q])
                                               / h**2)
    for a in range(4):
        grad[a] = _finite0((per_arm[2, a] - per_arm[0, a]) / (2 * h))
        hess[a, a] = _finite0((per_arm[2, a] - 2 * per_arm[1, a] + per_arm[0, a]) / h**2)


@jit
def _forward(e_arm, e_corner, h, grad, hess):
    """Gradient (4,) of the step energy from the forward half of the stencil (candidates 1
    and 2, corner pairs (1, 1), (2, 1), (1, 2), (2, 2)), the curvature along each arm taken
    from ``hess``'s diagonal (J/rad²); the corner couplings, which the forward half gives in
    full, are written into ``hess``."""
    per_arm = np.empty((2, 4))
    for a in range(4):
        for c in range(2):
            per_arm[c, a] = math.inf if math.isnan(e_arm[c + 1, a]) else e_arm[c + 1, a]
    for q in range(4):
        qa, _, qb, _, _, _ = CORNERS[q]
        per_arm[0, qa] += e_corner[1, q]
        per_arm[1, qa] += e_corner[2, q]
        per_arm[0, qb] += e_corner[1, q]
        per_arm[1, qb] += e_corner[4, q]
        hess[qa, qb] = hess[qb, qa] = _finite0((e_corner[5, q] - e_corner[2, q] - e_corner[4, q] + e_corner[1, q])
                                               / h**2)
    for a in range(4):
        grad[a] = _finite0((per_arm[1, a] - per_arm[0, a]) / h - 0.5 * h * hess[a, a])


@jit
def _newton(grad, hess, radius, best, max_turn):
    """The next trial (4,) rad from ``best``: the Newton step with the Hessian's eigenvalues
    clamped to positive, cut to the trust radius (rad) and bounded to |turn| <= max_turn."""
    lam, vec = np.linalg.eigh(hess)
    floor = max(1e-3 * np.abs(lam).max(), 1e-12)
    lam = np.maximum(np.abs(lam), floor)
    step = -(vec @ ((vec.T @ grad) / lam))
    size = np.abs(step).max()
    step *= min(1.0, radius / max(size, 1e-300))
    return np.minimum(np.maximum(best + step, -max_turn), max_turn)


@jit
def minimise(surf, memo, tol, n, k, P, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, first_dir, bend, mat, bh,
             turn, tolerance, max_iterations, max_turn, S, St, X, Xs, best_ring):
    """Trust-region Newton on the four turn angles (rad) of ring k, from ``turn``.

    Gradient and Hessian come from three-point stencils per arm plus one diagonal stencil
    point per quadrant corner (the only coupling between arms). Non-positive curvature is
    lifted by clamping the Hessian's eigenvalues. Each iteration places the trial's own
    ring; a trial that lowers the energy is accepted, gets its two stencil rings and
    widens the trust radius; one that raises it costs that one ring and shrinks the
    radius, so kinks in the energy (an asymmetric card's branch change at gamma0) cost
    iterations, not cycles. Converged when the next step, or the radius, is below
    ``tolerance`` (rad). An accepted trial's forward stencil ring comes first: if the step
    it gives (the gradient by forward differences, the curvature along the arms from the
    last stencil) is below a fifth of the tolerance, the search stops there without the
    backward ring, provided no arm's curvature changed by more than a quarter between the
    search's last two stencils (a stencil across a kink gives a curvature that does not
    hold beside it). Returns (turns, iterations, converged); ``best_ring`` (chain nodes, their
    status, corner nodes, their status; the buffers of one candidate) receives ring k at
    the returned turns, so it is not placed again.
    """
    S_best, St_best, X_best, Xs_best = best_ring
    h = STENCIL
    pairs = np.array(_PAIRS)
    cand = np.empty((3, 4))
    e_arm = np.empty((3, 4))
    e_corner = np.empty((6, 4))
    best = turn.copy()
    best_energy = math.inf
    grad_best = np.zeros(4)
    hess_best = np.zeros((4, 4))
    grad_fwd = np.zeros(4)
    hess_fwd = np.zeros((4, 4))
    curv_before = np.zeros(4)
    stencilled = False
    radius = 0.02
    last = 0.0
    its = 0
    for _ in range(max_iterations):
        for a in range(4):
            for c in range(3):
                cand[c, a] = turn[a] + (c - 1) * h
        # the trial's own ring first: its stencil neighbours only if it is accepted
        sides(surf, memo, tol, n, k, P, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, first_dir, bend, mat, bh,
              cand[1:2], S[1:2], St[1:2], e_arm[1:2])
        corners(surf, memo, tol, n, k, P, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, mat, bh, S, pairs[1:2],
                X[1:2], Xs[1:2], e_corner[1:2])
        total = 0.0
        for a in range(4):
            if math.isnan(e_arm[1, a]):
                e_arm[1, a] = math.inf
            total += e_arm[1, a]
        total += e_corner[1, 0] + e_corner[1, 1] + e_corner[1, 2] + e_corner[1, 3]
        its += 1
        if total <= best_energy:
            best[:] = turn
            best_energy = total
            S_best[0, :, :, :k] = S[1, :, :, :k]
            St_best[0, :, :, :k] = St[1, :, :, :k]
            X_best[0] = X[1]
            Xs_best[0] = Xs[1]
            radius = min(max(radius, 2 * last), 0.1)
            sides(surf, memo, tol, n, k, P, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, first_dir, bend, mat,
                  bh, cand[2:3], S[2:3], St[2:3], e_arm[2:3])
            for c in (2, 4, 5):
                corners(surf, memo, tol, n, k, P, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, mat, bh, S,
                        pairs[c:c + 1], X[c:c + 1], Xs[c:c + 1], e_corner[c:c + 1])
            steady = stencilled
            for a in range(4):
                steady &= abs(hess_best[a, a] - curv_before[a]) <= 0.25 * abs(curv_before[a])
            if steady:
                hess_fwd[:] = hess_best
                _forward(e_arm, e_corner, h, grad_fwd, hess_fwd)
                if np.abs(_newton(grad_fwd, hess_fwd, radius, best, max_turn) - best).max() < 0.2 * tolerance:
                    return best, its, True
            sides(surf, memo, tol, n, k, P, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, first_dir, bend, mat,
                  bh, cand[0:1], S[0:1], St[0:1], e_arm[0:1])
            for c in (0, 3):
                corners(surf, memo, tol, n, k, P, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, mat, bh, S,
                        pairs[c:c + 1], X[c:c + 1], Xs[c:c + 1], e_corner[c:c + 1])
            for a in range(4):
                curv_before[a] = hess_best[a, a]
            _stencil(e_arm, e_corner, h, grad_best, hess_best)
            if not stencilled:
                for a in range(4):
                    curv_before[a] = hess_best[a, a]
            stencilled = True
        else:
            radius = 0.25 * last
        nxt = _newton(grad_best, hess_best, radius, best, max_turn)
        last = np.abs(nxt - best).max()
        if last < tolerance or radius < tolerance:
            return best, its, True
        turn = nxt
    return best, its, False


@jit
def drape_ring(surf, memo, tol, n, k, P, status, blank, seg_i, seg_j, s1, s2, g0, centre, force, mu, first_dir, bend, mat,
               bh, tolerance, max_iterations, max_turn, turns, iterations, converged):
    """Ring k of every realisation r of a block, each from its own ring k - 1 and to its own
    iteration count (a straggler holds no other): P (R, N, N, 3) and status (R, N, N), with
    rings < k placed, are filled in place, as are turns (R, n, 4) rad, iterations (R,) and
    converged (R,). The other arrays carry a leading axis R."""
    S = np.empty((3, 4, 2, n, 3))
    St = np.empty((3, 4, 2, n), np.int8)
    X = np.empty((6, 4, 3))
    Xs = np.empty((6, 4), np.int8)
    best_ring = (np.empty((1, 4, 2, n, 3)), np.empty((1, 4, 2, n), np.int8), np.empty((1, 4, 3)),
                 np.empty((1, 4), np.int8))
    S_best, St_best, X_best, Xs_best = best_ring
    for r in range(P.shape[0]):
        args = (P[r], blank[r], seg_i[r], seg_j[r], s1[r], s2[r], g0[r], centre[r], force[r], mu[r])
        if k > 1:
            turn, its, ok = minimise(surf, memo, tol, n, k, *args, first_dir[r], bend, mat, bh, turns[r, k - 2].copy(),
                                     tolerance, max_iterations, max_turn, S, St, X, Xs, best_ring)
            iterations[r] += its
            converged[r] &= ok
        else:  # ring 1 leaves at the fabric angles
            turn = np.zeros(4)
            sides(surf, memo, tol, n, k, *args, first_dir[r], bend, mat, bh, turn.reshape(1, 4), S_best, St_best,
                  np.empty((1, 4)))
            corners(surf, memo, tol, n, k, *args, mat, bh, S_best, np.zeros((1, 2), np.int64), X_best, Xs_best,
                    np.empty((1, 4)))
        turns[r, k - 1] = turn
        put_ring(n, k, P[r], status[r], S_best[0], St_best[0], X_best[0], Xs_best[0])


@jit
def put_ring(n, k, P, status, S, St, X, Xs):
    """Write ring k of one realisation into its net P (N, N, 3) and status (N, N): the chain
    nodes S (4, 2, >= k, 3) with status St and the corner nodes X (4, 3) with status Xs of
    one candidate of ``sides`` and ``corners``."""
    for a in range(4):
        di, dj = ARMS[a]
        for side in range(2):
            sgn = 1 - 2 * side
            ei, ej = (0, sgn) if di != 0 else (sgn, 0)
            for m in range(k):
                i, j = n + k * di + m * ei, n + k * dj + m * ej
                P[i, j] = S[a, side, m]
                status[i, j] = St[a, side, m]
    for q in range(4):
        si, sj = CORNERS[q][4], CORNERS[q][5]
        P[n + si * k, n + sj * k] = X[q]
        status[n + si * k, n + sj * k] = Xs[q]
