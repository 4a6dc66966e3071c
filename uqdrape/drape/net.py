"""Building the pin-jointed net, batched over realisations.

Two orders of construction share the node kernels:

* ``build_geodesic``: the four generator arms are traced as discrete geodesics to the
  last ring, then every other node is filled anti-diagonal by anti-diagonal
  (|i| + |j| = d), so a drape costs about 3n Python steps whatever the batch size.
* ``build_energy``: ring by ring (thesis Fig 5.1). At ring k each arm gets one segment
  whose turn angle about the surface normal minimises the energy of the pattern so
  far; the ring is filled from the arms towards the quadrant corners.

Node (i, j) is stored at array index (i + n, j + n). Arms are ordered +i, +j, -i, -j.
"""

from __future__ import annotations

import copy

import numpy as np

from .energy import BlankHolder, bending_energy
from .kernels import arm_step, fill_node, quad_shear, unit
from .status import Status

ARM_STEPS = np.array([(1, 0), (0, 1), (-1, 0), (0, -1)])
#: Per quadrant (sign i, sign j): its i-family arm and side, its j-family arm and side.
QUADRANTS = {"++": (0, 0, 1, 0), "-+": (2, 0, 1, 1), "--": (2, 1, 3, 1), "+-": (0, 1, 3, 0)}
QUADRANT_SIGNS = {"++": (1, 1), "-+": (-1, 1), "--": (-1, -1), "+-": (1, -1)}
SIDES = np.array([1, -1])
#: Energy (J) charged to the minimiser per node a candidate fails to place: invalid nodes
#: carry no shear energy, so without it the minimiser would prefer turns that lose nodes.
#: Equal counts cancel in the stencils; it never enters the reported energies.
INVALID_NODE_ENERGY = 1e3


class NetProblem:
    """Validated, broadcast inputs of a batch of R drapes (see ``uqdrape.drape.drape``)."""

    def __init__(self, surface, spacing, rings, crossover, arm_angles, seg_i, seg_j, gamma0,
                 flat_e1, flat_e2, blankholder, material, tol):
        self.surface = surface
        self.s = spacing
        self.n = rings
        self.size = 2 * rings + 1
        self.crossover = crossover  # (R, 2) mm
        self.arm_angles = arm_angles  # (R, 4) rad, plan angles of the first arm segments
        self.seg_i = seg_i  # (R, 2n, 2n+1) mm
        self.seg_j = seg_j  # (R, 2n+1, 2n) mm
        self.gamma0 = gamma0  # (R, 2n, 2n) rad
        self.blankholder = blankholder
        self.material = material
        self.tol = tol
        self.R = crossover.shape[0]
        idx = np.arange(-rings, rings + 1)
        # Flat-blank node positions at nominal spacing (thesis Fig 5.2), (R, N, N, 2).
        self.flat = (crossover[:, None, None, :]
                     + spacing * idx[None, :, None, None] * flat_e1[:, None, None, :]
                     + spacing * idx[None, None, :, None] * flat_e2[:, None, None, :])
        self.cell_s1 = 0.5 * (seg_i[:, :, :-1] + seg_i[:, :, 1:])
        self.cell_s2 = 0.5 * (seg_j[:, :-1, :] + seg_j[:, 1:, :])

    def subset(self, rows):
        """The same problem restricted to realisations ``rows`` (a shallow copy).

        Per-realisation nets and fields are not copied: the index helpers gather the
        few entries a step needs through ``rows``.
        """
        sub = copy.copy(self)
        for name in ("crossover", "arm_angles"):
            setattr(sub, name, getattr(self, name)[rows])
        sub.blankholder = copy.copy(self.blankholder)
        sub.blankholder.force = self.blankholder.force[rows]
        sub.blankholder.friction = self.blankholder.friction[rows]
        sub.rows = rows if self.rows is None else self.rows[rows]
        sub.R = len(rows)
        return sub

    rows = None  # realisations of the full batch this problem covers (None: all)

    # -- index helpers -----------------------------------------------------------------
    def take(self, field, a, b):
        """field[r, a, b] for this problem's realisations r; a, b broadcast -> (R, ...)."""
        if self.rows is None:
            return field[:, a, b]
        shape = (-1,) + (1,) * np.broadcast(a, b).ndim
        return field[self.rows.reshape(shape), a, b]

    def seg1(self, i_a, i_b, j):
        """Lengths (R, ...) of fibre-1 segments between nodes (i_a, j) and (i_b, j)."""
        return self.take(self.seg_i, np.minimum(i_a, i_b) + self.n, j + self.n)

    def seg2(self, i, j_a, j_b):
        return self.take(self.seg_j, i + self.n, np.minimum(j_a, j_b) + self.n)

    def node(self, P, i, j):
        """Positions (R, ..., 3) of nodes (i, j) in the batch's net P (or flat blank)."""
        return self.take(P, i + self.n, j + self.n)

    # -- shared stages -----------------------------------------------------------------
    def start(self):
        """Arrays with the crossover placed: P (R, N, N, 3) mm, status (R, N, N)."""
        P = np.full((self.R, self.size, self.size, 3), np.nan)
        status = np.full((self.R, self.size, self.size), Status.DEPENDENT, np.int8)
        x, y = self.crossover[:, 0], self.crossover[:, 1]
        ok = np.isfinite(x) & np.isfinite(y) & self.surface.inside(x, y)
        P[:, self.n, self.n] = np.stack([x, y, self.surface.height(x, y)], axis=-1)
        P[~ok, self.n, self.n] = np.nan
        status[:, self.n, self.n] = np.where(ok, Status.OK, Status.OFF_MOULD)
        return P, status

    def arm_nodes(self, P, k, turn):
        """Arm nodes of ring k for turn angles ``turn`` (R, M, 4) rad -> (R, M, 4, 3), status."""
        di, dj = ARM_STEPS[:, 0], ARM_STEPS[:, 1]
        last = self.node(P, (k - 1) * di, (k - 1) * dj)[:, None]  # (R, 1, 4, 3)
        if k == 1:
            direction = self.first_directions()[:, None]
        else:
            direction = last - self.node(P, (k - 2) * di, (k - 2) * dj)[:, None]
        return arm_step(self.surface, last, direction, turn, self.arm_lengths(k)[:, None], self.tol)

    def first_directions(self):
        """Unit directions (R, 4, 3) of the first arm segments on the surface.

        The flat blank touches the tool at the crossover and is laid onto the tangent
        plane there by the rotation that takes z onto the surface normal n, so the plan
        angles between the fibres are kept (a vertical projection would shear a blank
        that lands on a slope). For v = (vx, vy, 0) and w = -(n . v) the rotated vector
        is (vx + nx w / (1 + nz), vy + ny w / (1 + nz), w).
        """
        a = self.arm_angles
        n = self.surface.normal(self.crossover[:, 0:1], self.crossover[:, 1:2])  # (R, 1, 3)
        vx, vy = np.cos(a), np.sin(a)
        w = -(n[..., 0] * vx + n[..., 1] * vy)
        return np.stack([vx + n[..., 0] * w / (1 + n[..., 2]), vy + n[..., 1] * w / (1 + n[..., 2]), w], axis=-1)

    def arm_lengths(self, k):
        """Lengths (R, 4) of the k-th segment of each arm."""
        return np.stack([
            self.seg1(k, k - 1, 0), self.seg2(0, k, k - 1),
            self.seg1(-k, -k + 1, 0), self.seg2(0, -k, -k + 1),
        ], axis=-1)

    def cell_energy(self, gamma, ci, cj):
        """Shear energy (J) of cells whose lower-left node is (ci, cj), shear ``gamma`` (rad)."""
        a, b = np.broadcast_arrays(ci + self.n, cj + self.n)
        lead = (self.R,) + (1,) * (gamma.ndim - 1 - a.ndim)  # candidate axes between R and the cells

        def pick(field):
            return self.take(field, a, b).reshape(lead + a.shape)

        return self.material.cell_energy(gamma, pick(self.cell_s1), pick(self.cell_s2), pick(self.gamma0))

    def ring_blankholder(self, P, k):
        """Blank-holder energy (R, 4 quadrants) of the boundary polygon of ring k (J)."""
        out = np.zeros((self.R, 4))
        t = np.arange(-k, k)
        centre = self.crossover[:, None, :]
        force = self.blankholder.force[:, None]
        mu = self.blankholder.friction[:, None]
        for q, (si, sj) in enumerate(QUADRANT_SIGNS.values()):
            jj = t[(t >= 0) == (sj > 0)]  # fibre-2 segments (si k, j)-(si k, j+1)
            ii = t[(t >= 0) == (si > 0)]  # fibre-1 segments (i, sj k)-(i+1, sj k)
            e = self.blankholder.segment_energy(
                self.node(P, si * k, jj), self.node(P, si * k, jj + 1),
                self.node(self.flat, si * k, jj), self.node(self.flat, si * k, jj + 1),
                centre, force, mu)
            e2 = self.blankholder.segment_energy(
                self.node(P, ii, sj * k), self.node(P, ii + 1, sj * k),
                self.node(self.flat, ii, sj * k), self.node(self.flat, ii + 1, sj * k),
                centre, force, mu)
            out[:, q] = np.nansum(e, axis=-1) + np.nansum(e2, axis=-1)
        return out


def build_geodesic(prob: NetProblem):
    """Geodesic net: arms first, then anti-diagonal fill. Returns P, status."""
    P, status = prob.start()
    n = prob.n
    di, dj = ARM_STEPS[:, 0], ARM_STEPS[:, 1]
    zero = np.zeros((prob.R, 1, 4))
    for k in range(1, n + 1):
        q, st = prob.arm_nodes(P, k, zero)
        P[:, n + k * di, n + k * dj] = q[:, 0]
        status[:, n + k * di, n + k * dj] = st[:, 0]
    for d in range(2, 2 * n + 1):
        a = np.arange(max(1, d - n), min(n, d - 1) + 1)
        i = np.concatenate([a, -a, -a, a])
        j = np.concatenate([d - a, d - a, -(d - a), -(d - a)])
        si, sj = np.sign(i), np.sign(j)
        q, st = fill_node(
            prob.surface, prob.node(P, i - si, j), prob.node(P, i, j - sj), prob.node(P, i - si, j - sj),
            prob.seg1(i, i - si, j), prob.seg2(i, j, j - sj), si * sj, prob.tol)
        P[:, i + n, j + n] = q
        status[:, i + n, j + n] = st
    return P, status


class EnergyRings:
    """Ring-by-ring construction with the per-step energy minimisation (thesis Fig 5.1).

    The energy of ring k's pattern splits into one term per arm (its bending penalty,
    the cells and blank-holder segments along its two sides) and one term per quadrant
    corner (coupling the two arms that bound the quadrant). The four turn angles are
    found by a batched trust-region Newton iteration (``_minimise``) whose gradient and
    Hessian come from finite-difference stencils of those terms.
    """

    STENCIL = 1e-3  # rad, finite-difference step of the turn angles

    def __init__(self, prob: NetProblem, bending_stiffness, tolerance, max_iterations, max_turn):
        self.prob = prob
        self.B = bending_stiffness
        self.tol = tolerance
        self.max_iterations = max_iterations
        self.max_turn = max_turn

    # -- geometry of ring k -------------------------------------------------------------
    def sides(self, P, k, turn, prob=None):
        """Arm nodes and the side chains of ring k for turn angles (R, M, 4).

        Returns chain nodes S (R, M, 4, 2, k, 3), their status, and the energy per arm
        (R, M, 4): bending + side cells + side blank-holder segments. ``prob`` is a
        subset of the batch's problem when only some realisations are evaluated.
        """
        prob = prob or self.prob
        R, M = turn.shape[:2]
        arm_q, arm_st = prob.arm_nodes(P, k, turn)
        S = np.empty((R, M, 4, 2, k, 3))
        St = np.empty((R, M, 4, 2, k), np.int8)
        S[..., 0, :] = arm_q[:, :, :, None, :]
        St[..., 0] = arm_st[:, :, :, None]
        di, dj = ARM_STEPS[:, 0, None], ARM_STEPS[:, 1, None]
        ifam = (di != 0)  # (4, 1): arms along fibre 1
        ei = np.where(ifam, 0, SIDES[None, :])  # (4, 2)
        ej = np.where(ifam, SIDES[None, :], 0)
        if k > 1:
            # indices (4, 2, k-1) of the chain nodes m = 1..k-1 and their neighbours,
            # gathered for the whole chain at once; the loop below only slices them
            m = np.arange(1, k)
            xi, xj = k * di[..., None] + m * ei[..., None], k * dj[..., None] + m * ej[..., None]
            fi, fj = xi - di[..., None], xj - dj[..., None]  # fixed neighbour, ring k-1
            pi, pj = xi - ei[..., None], xj - ej[..., None]  # predecessor in the chain
            ai = np.where(ifam[..., None], fi, pi)
            bj = np.where(ifam[..., None], pj, fj)
            fixed = prob.node(P, fi, fj)[:, None]
            diagonal = prob.node(P, fi - ei[..., None], fj - ej[..., None])[:, None]
            la = prob.seg1(xi, ai, xj)[:, None]
            lb = prob.seg2(xi, xj, bj)[:, None]
            orientation = (xi - ai) * (xj - bj)
        for m in range(1, k):
            F = fixed[..., m - 1, :]
            Q = S[..., m - 1, :]
            a = np.where(ifam[..., None], F, Q)
            b = np.where(ifam[..., None], Q, F)
            q, st = fill_node(prob.surface, a, b, diagonal[..., m - 1, :], la[..., m - 1], lb[..., m - 1],
                              orientation[..., m - 1], prob.tol)
            S[..., m, :] = q
            St[..., m] = st
        energy = bending_energy(turn, self.B, prob.s) + INVALID_NODE_ENERGY * (St != Status.OK).sum(axis=(-2, -1))
        if k > 1:
            m = np.arange(1, k)
            inner = prob.node(P, (k - 1) * di[..., None] + m * ei[..., None],
                              (k - 1) * dj[..., None] + m * ej[..., None])[:, None]
            inner_prev = prob.node(P, (k - 1) * di[..., None] + (m - 1) * ei[..., None],
                                   (k - 1) * dj[..., None] + (m - 1) * ej[..., None])[:, None]
            eps0 = np.sign((di + ei) * (dj + ej))[..., None]
            gamma = quad_shear(inner_prev, S[..., :-1, :], S[..., 1:, :], inner, eps0)
            # lower-left node of each side cell
            ci = np.minimum(k * di, (k - 1) * di)[..., None] + np.minimum((m - 1) * ei[..., None], m * ei[..., None])
            cj = np.minimum(k * dj, (k - 1) * dj)[..., None] + np.minimum((m - 1) * ej[..., None], m * ej[..., None])
            cells = prob.cell_energy(gamma, ci, cj)
            xi = k * di[..., None] + m * ei[..., None]
            xj = k * dj[..., None] + m * ej[..., None]
            bh = prob.blankholder.segment_energy(
                S[..., :-1, :], S[..., 1:, :],
                prob.node(prob.flat, xi - ei[..., None], xj - ej[..., None])[:, None],
                prob.node(prob.flat, xi, xj)[:, None],
                prob.crossover[:, None, None, None, None, :],
                prob.blankholder.force[:, None, None, None, None],
                prob.blankholder.friction[:, None, None, None, None])
            energy = energy + np.nansum(cells, axis=(-2, -1)) + np.nansum(bh, axis=(-2, -1))
        return S, St, energy

    def corners(self, P, k, S, combos, prob=None):
        """Quadrant corner nodes for candidate pairs ``combos`` [(cand of i-arm, cand of j-arm)].

        Returns nodes (R, C, 4, 3), status (R, C, 4) and energy (R, C, 4): the corner cell
        and the two blank-holder segments that end at the corner.
        """
        prob = prob or self.prob
        ca = np.array([c[0] for c in combos])
        cb = np.array([c[1] for c in combos])
        qa = np.array([QUADRANTS[q][0] for q in QUADRANTS])
        sa = np.array([QUADRANTS[q][1] for q in QUADRANTS])
        qb = np.array([QUADRANTS[q][2] for q in QUADRANTS])
        sb = np.array([QUADRANTS[q][3] for q in QUADRANTS])
        si = np.array([QUADRANT_SIGNS[q][0] for q in QUADRANTS])
        sj = np.array([QUADRANT_SIGNS[q][1] for q in QUADRANTS])
        a = S[:, cb[:, None], qb[None, :], sb[None, :], k - 1]  # fibre-1 neighbour (si(k-1), sj k)
        b = S[:, ca[:, None], qa[None, :], sa[None, :], k - 1]  # fibre-2 neighbour (si k, sj(k-1))
        c = prob.node(P, si * (k - 1), sj * (k - 1))[:, None]
        x, st = fill_node(prob.surface, a, b, c,
                          prob.seg1(si * k, si * (k - 1), sj * k)[:, None],
                          prob.seg2(si * k, sj * k, sj * (k - 1))[:, None], si * sj, prob.tol)
        gamma = quad_shear(c, a, x, b, si * sj)
        cells = prob.cell_energy(gamma, np.minimum(si * k, si * (k - 1)), np.minimum(sj * k, sj * (k - 1)))
        centre = prob.crossover[:, None, None, :]
        force = prob.blankholder.force[:, None, None]
        mu = prob.blankholder.friction[:, None, None]
        fx = prob.node(prob.flat, si * k, sj * k)[:, None]
        bh = (prob.blankholder.segment_energy(a, x, prob.node(prob.flat, si * (k - 1), sj * k)[:, None], fx,
                                              centre, force, mu)
              + prob.blankholder.segment_energy(b, x, prob.node(prob.flat, si * k, sj * (k - 1))[:, None], fx,
                                                centre, force, mu))
        return x, st, np.nan_to_num(cells) + np.nan_to_num(bh) + INVALID_NODE_ENERGY * (st != Status.OK)

    # -- the per-step minimisation --------------------------------------------------------
    def run(self):
        """Drape ring by ring. Returns P, status, turn angles (R, n, 4) rad, bending energy
        (R,) J, total iterations (R,) and converged (R,)."""
        prob = self.prob
        n, R = prob.n, prob.R
        P, status = prob.start()
        turns = np.zeros((R, n, 4))
        iterations = np.zeros(R, np.int32)
        converged = np.ones(R, bool)
        h = self.STENCIL
        offsets = np.array([-h, 0.0, h])
        stencil = [(0, 1), (1, 1), (2, 1), (1, 0), (1, 2), (2, 2)]  # (i-arm cand, j-arm cand) pairs
        turn = np.zeros((R, 4))
        for k in range(1, n + 1):
            if k > 1 and self.max_iterations > 0:
                turn, its, ok = self._minimise(P, k, turn, offsets, stencil)
                iterations += its
                converged &= ok
            turns[:, k - 1] = turn
            S, St, _ = self.sides(P, k, turn[:, None, :])
            x, xs, _ = self.corners(P, k, S, [(0, 0)])
            self._store(P, status, k, S[:, 0], St[:, 0], x[:, 0], xs[:, 0])
        bending = bending_energy(turns, self.B, prob.s).sum(axis=(1, 2))
        return P, status, turns, bending, iterations, converged

    def _minimise(self, P, k, turn, offsets, stencil):
        """Batched trust-region Newton on the four turn angles (rad) of step k.

        Gradient and Hessian come from three-point stencils per arm plus one diagonal
        stencil point per quadrant corner (the only coupling between arms), so each
        iteration costs three candidate rings. Non-positive curvature is lifted by
        clamping the Hessian's eigenvalues. A trial that lowers the energy is accepted
        and widens the trust radius; one that raises it shrinks the radius, so kinks in
        the energy (an asymmetric card's branch change at gamma0) cost iterations, not
        cycles. Converged when the next step, or the radius, is below the tolerance.
        """
        R = turn.shape[0]
        h = offsets[2]
        best = turn.copy()
        best_energy = np.full(R, np.inf)
        grad_best = np.zeros((R, 4))
        hess_best = np.zeros((R, 4, 4))
        radius = np.full(R, 0.02)
        last = np.zeros(R)
        active = np.ones(R, bool)
        done = np.zeros(R, bool)
        its = np.zeros(R, np.int32)
        idx = np.arange(4)
        total = np.full(R, np.inf)
        grad = np.zeros((R, 4))
        hess = np.zeros((R, 4, 4))
        for _ in range(self.max_iterations):
            rows = np.flatnonzero(active)  # converged realisations are not evaluated again
            sub = self.prob if rows.size == R else self.prob.subset(rows)
            cand = turn[rows, None, :] + offsets[None, :, None]
            S, _, e_arm = self.sides(P, k, cand, sub)
            _, _, e_corner = self.corners(P, k, S, stencil, sub)
            e_arm = np.nan_to_num(e_arm, nan=np.inf)
            total[rows] = e_arm[:, 1].sum(-1) + e_corner[:, 1].sum(-1)
            per_arm = e_arm.copy()
            h_rows = np.zeros((rows.size, 4, 4))
            for q, (a, _, b, _) in enumerate(QUADRANTS.values()):
                per_arm[:, :, a] += e_corner[:, [0, 1, 2], q]
                per_arm[:, :, b] += e_corner[:, [3, 1, 4], q]
                cross = (e_corner[:, 5, q] - e_corner[:, 2, q] - e_corner[:, 4, q] + e_corner[:, 1, q]) / h**2
                h_rows[:, a, b] = h_rows[:, b, a] = cross
            with np.errstate(invalid="ignore", divide="ignore"):
                grad[rows] = (per_arm[:, 2] - per_arm[:, 0]) / (2 * h)
                h_rows[:, idx, idx] = (per_arm[:, 2] - 2 * per_arm[:, 1] + per_arm[:, 0]) / h**2
            hess[rows] = h_rows
            its += active
            better = active & (total <= best_energy)
            best = np.where(better[:, None], turn, best)
            best_energy = np.where(better, total, best_energy)
            grad_best = np.where(better[:, None], np.nan_to_num(grad), grad_best)
            hess_best = np.where(better[:, None, None], np.nan_to_num(hess), hess_best)
            radius = np.where(better, np.minimum(np.maximum(radius, 2 * last), 0.1), 0.25 * last)
            lam, vec = np.linalg.eigh(hess_best)
            floor = np.maximum(1e-3 * np.abs(lam).max(-1, keepdims=True), 1e-12)
            lam = np.maximum(np.abs(lam), floor)
            step = -np.einsum("rij,rj->ri", vec, np.einsum("rji,rj->ri", vec, grad_best) / lam)
            size = np.abs(step).max(-1)
            step *= np.minimum(1.0, radius / np.maximum(size, 1e-300))[:, None]
            nxt = np.clip(best + step, -self.max_turn, self.max_turn)
            last = np.abs(nxt - best).max(-1)
            finished = active & ((last < self.tol) | (radius < self.tol))
            done |= finished
            active &= ~finished
            turn = np.where(active[:, None], nxt, best)
            if not active.any():
                break
        return best, its, done

    def _store(self, P, status, k, S, St, x, xs):
        """Write ring k (one candidate) into the net arrays."""
        n = self.prob.n
        di, dj = ARM_STEPS[:, 0, None, None], ARM_STEPS[:, 1, None, None]
        ifam = di != 0
        m = np.arange(k)
        ei = np.where(ifam, 0, SIDES[None, :, None] * m)
        ej = np.where(ifam, SIDES[None, :, None] * m, 0)
        P[:, n + k * di + ei, n + k * dj + ej] = S
        status[:, n + k * di + ei, n + k * dj + ej] = St
        for q, (si, sj) in enumerate(QUADRANT_SIGNS.values()):
            P[:, n + si * k, n + sj * k] = x[:, q]
            status[:, n + si * k, n + sj * k] = xs[:, q]
