"""Building the pin-jointed net, batched over realisations.

Two orders of construction share the compiled node kernels:

* ``build_geodesic``: the four generator arms are traced as discrete geodesics to the
  last ring, then every other node is filled anti-diagonal by anti-diagonal
  (|i| + |j| = d), compiled per realisation (``ring.geodesic_block``).
* ``EnergyRings``: ring by ring (thesis Fig 5.1). At ring k each arm gets one segment
  whose turn angle about the surface normal minimises the energy of the pattern so
  far; the ring is filled from the arms towards the quadrant corners. The ring step is
  compiled per realisation (``ring``).

Node (i, j) is stored at array index (i + n, j + n). Arms are ordered +i, +j, -i, -j.
``net_quads`` gives the cells of a net's valid nodes, for meshes and maps.
"""

from __future__ import annotations

import functools

import numpy as np

from .._jit import on_threads
from ..geometry.compiled import new_memo
from . import ring
from .energy import MM_TO_M, bending_energy
from .status import Status


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
        #: the material of every realisation (one, or one per realisation), and the first
        #: (what they share: locking angles, phi0, bending stiffness); None for a geodesic net
        self.materials = None if material is None else list(material) if isinstance(material, (list, tuple)) \
            else [material]
        self.material = None if material is None else self.materials[0]
        self.tol = tol
        self.R = crossover.shape[0]
        # The flat blank at nominal spacing (thesis Fig 5.2), (R, 3, 2): node (i, j) lies at
        # blank[0] + i blank[1] + j blank[2] (``ring._flat``).
        self.blank = np.stack([crossover, spacing * flat_e1, spacing * flat_e2], axis=1)

    def kernel(self, r: int):
        """The compiled shear energy (``Material.kernel``) of realisation ``r``."""
        return self.materials[r if len(self.materials) > 1 else 0].kernel

    def same_material(self, rows: slice) -> list[slice]:
        """``rows`` cut into slices of realisations that share one material: ``rows`` itself,
        or one realisation each when every realisation has its own card."""
        if len(self.materials) == 1:
            return [rows]
        return [slice(r, r + 1) for r in range(rows.start, rows.stop)]

    @functools.cached_property
    def cell_s1(self):
        """Fibre-1 segment length of each cell (R, 2n, 2n) mm, for the shear energy (not
        computed for a geodesic net without a material)."""
        return 0.5 * (self.seg_i[:, :, :-1] + self.seg_i[:, :, 1:])

    @functools.cached_property
    def cell_s2(self):
        """Fibre-2 segment length of each cell (R, 2n, 2n) mm."""
        return 0.5 * (self.seg_j[:, :-1, :] + self.seg_j[:, 1:, :])

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


def net_quads(valid: np.ndarray):
    """Points and quads of the nodes ``valid`` (N, N) bool: (flat node indices of the kept
    points, quads (M, 4) into those points, counter-clockwise in (i, j))."""
    index = np.full(valid.shape, -1)
    kept = np.flatnonzero(valid.ravel())
    index.ravel()[kept] = np.arange(kept.size)
    corners = np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], axis=-1)
    quads = corners[(corners >= 0).all(-1)]
    return kept, quads.reshape(-1, 4)


def build_geodesic(prob: NetProblem, threads=1):
    """Geodesic net: arms first, then anti-diagonal fill (``ring.geodesic_block``), the
    realisations shared among ``threads`` threads. Returns P, status."""
    P, status = prob.start()
    first_dir = np.ascontiguousarray(prob.first_directions())
    on_threads(threads, prob.R, lambda r: ring.geodesic_block(
        prob.surface.kernel, new_memo(prob.surface.kernel[0]), prob.tol, prob.n, P[r], status[r], prob.seg_i[r], prob.seg_j[r], first_dir[r]))
    return P, status


class EnergyRings:
    """Ring-by-ring construction with the per-step energy minimisation (thesis Fig 5.1),
    compiled per realisation in ``ring``; ``sides`` and ``corners`` expose the step
    energy's two kinds of term for a whole batch."""

    def __init__(self, prob: NetProblem, bending_stiffness, tolerance, max_iterations, max_turn, threads=1):
        self.prob = prob
        self.threads = threads
        self.B = bending_stiffness
        self.tol = tolerance
        self.max_iterations = max_iterations
        self.max_turn = max_turn
        self.first_dir = np.ascontiguousarray(prob.first_directions())
        self.bend = bending_stiffness / (prob.s * MM_TO_M)  # J/rad^2, as bending_energy

    def _realisation(self, P, r, k):
        """The leading arguments of the compiled ring functions at ring k, realisation r."""
        p = self.prob
        return (p.surface.kernel, new_memo(p.surface.kernel[0]), p.tol, p.n, k, np.ascontiguousarray(P[r]), p.blank[r],
                p.seg_i[r], p.seg_j[r], p.cell_s1[r], p.cell_s2[r], p.gamma0[r], p.crossover[r], p.blankholder.force[r],
                p.blankholder.friction[r])

    def sides(self, P, k, turn):
        """Arm nodes and side chains of ring k for turn angles (R, M, 4) rad: chain nodes
        S (R, M, 4, 2, k, 3), their status and the energy per arm (R, M, 4) J (bending +
        side cells + side blank-holder segments), as ``ring.sides``."""
        R, M = turn.shape[:2]
        S = np.empty((R, M, 4, 2, k, 3))
        St = np.empty((R, M, 4, 2, k), np.int8)
        energy = np.empty((R, M, 4))
        for r in range(R):
            ring.sides(*self._realisation(P, r, k), self.first_dir[r], self.bend, self.prob.kernel(r),
                       self.prob.blankholder.kernel, np.ascontiguousarray(turn[r], float), S[r], St[r], energy[r])
        return S, St, energy

    def corners(self, P, k, S, combos):
        """Quadrant corner nodes (R, C, 4, 3), status and energy (R, C, 4) J for candidate
        pairs ``combos`` [(candidate of the i-arm, of the j-arm)] of ``sides``' chains S."""
        R, C = S.shape[0], len(combos)
        X = np.empty((R, C, 4, 3))
        Xs = np.empty((R, C, 4), np.int8)
        energy = np.empty((R, C, 4))
        pairs = np.array(combos, np.int64).reshape(C, 2)
        for r in range(R):
            ring.corners(*self._realisation(P, r, k), self.prob.kernel(r), self.prob.blankholder.kernel,
                         np.ascontiguousarray(S[r]), pairs, X[r], Xs[r], energy[r])
        return X, Xs, energy

    def step_energy(self, P, k, turn):
        """The minimiser's objective at ring k for turn angles (R, 4) rad: the step energy
        (R,) J (arm terms plus corner terms, unplaced-node penalty included), with the ring's
        chain nodes (R, 4, 2, k, 3), their status, corner nodes (R, 4, 3) and their status."""
        S, St, arm = self.sides(P, k, turn[:, None, :])
        X, Xs, corner = self.corners(P, k, S, [(0, 0)])
        return arm[:, 0].sum(-1) + corner[:, 0].sum(-1), S[:, 0], St[:, 0], X[:, 0], Xs[:, 0]

    def place_at(self, P, status, k, turn):
        """Place ring k of every realisation at the given turn angles (R, 4) rad, not searched:
        P (R, N, N, 3) and status (R, N, N), with rings < k placed, are filled in place."""
        _, S, St, X, Xs = self.step_energy(P, k, turn)
        for r in range(self.prob.R):
            ring.put_ring(self.prob.n, k, P[r], status[r], S[r], St[r], X[r], Xs[r])

    def run(self, progress=None):
        """Drape ring by ring (one compiled call per ring for the whole block, the block's
        realisations shared among ``threads`` threads; ``progress``,
        if given, is called with the number of rings placed after each). Returns P, status,
        turn angles (R, n, 4) rad, bending energy (R,) J, total iterations (R,) and converged (R,)."""
        prob = self.prob
        P, status = prob.start()
        turns = np.zeros((prob.R, prob.n, 4))
        iterations = np.zeros(prob.R, np.int32)
        converged = np.ones(prob.R, bool)
        for k in range(1, prob.n + 1):
            self.place_ring(k, P, status, turns, iterations, converged)
            if progress is not None:
                progress(k)
        bending = bending_energy(turns, self.B, prob.s).sum(axis=(1, 2))
        return P, status, turns, bending, iterations, converged

    def place_ring(self, k, P, status, turns, iterations, converged):
        """Ring k of every realisation from its rings < k in P, status and turns (rad), all
        filled in place (``ring.drape_ring``), the realisations shared among ``threads``."""
        prob = self.prob

        def place(rows):
            for r in prob.same_material(rows):  # a compiled call takes one card
                ring.drape_ring(
                    prob.surface.kernel, new_memo(prob.surface.kernel[0]), prob.tol, prob.n, k, P[r], status[r], prob.blank[r], prob.seg_i[r],
                    prob.seg_j[r], prob.cell_s1[r], prob.cell_s2[r], prob.gamma0[r], prob.crossover[r],
                    prob.blankholder.force[r], prob.blankholder.friction[r], self.first_dir[r], self.bend,
                    prob.kernel(r.start), prob.blankholder.kernel, self.tol, self.max_iterations, self.max_turn,
                    turns[r], iterations[r], converged[r])

        on_threads(self.threads, prob.R, place)
