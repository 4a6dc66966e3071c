"""Forming energies of a (partly) draped net, in J.

Shear energy lives on cells (material card, zero-energy offset per cell), bending is the
generator-path penalty, and the blank-holder energy is friction work on the boundary
polygon of the outermost ring: thesis Eq 5.1-5.5 (radial draw-in only) or the full plan
slip of the held fabric. All functions are batched over leading axes.
"""

from __future__ import annotations

import numpy as np

MM_TO_M = 1e-3


def bending_energy(turn, stiffness, spacing):
    """Generator-path penalty (B / s) * turn^2 (J): turn in rad, B in N m^2, s in mm."""
    return stiffness / (spacing * MM_TO_M) * turn**2


def _angle2(a, b):
    """Unsigned angle (rad) between 2-D vectors."""
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return np.abs(np.arctan2(cross, np.sum(a * b, axis=-1)))


#: Blank-holder friction models: what the friction work of a held boundary segment acts on.
BLANKHOLDER_MODELS = ("slip", "radial")


class BlankHolder:
    """Blank-holder friction, optionally with a segmented pressure.

    ``force`` (N) and ``friction`` (-) are per realisation, shape (R,). ``sectors`` are
    relative weights of equal angular sectors starting at the +x axis and running
    anticlockwise (None: uniform). A boundary segment takes the share of the total force
    that its angular span receives; with uniform weights that share is phi_seg / 2 pi
    exactly, the thesis formula.

    ``model`` says which slip of the held fabric the friction works on:

    * ``"radial"``: thesis Eq 5.1-5.5, the radial draw-in |dD| of the segment midpoint
      (plan distance to the crossover, flat minus draped). A sideways slide is free.
    * ``"slip"``: Coulomb friction on the whole plan slip |m_draped - m_flat| of the
      segment midpoint, radial and circumferential. It equals ``"radial"`` where the
      midpoint moves along its ray and charges a sideways slide to first order.

    Both are end-state measures recomputed in full at every ring (Eq 5.5): at step k the
    held fabric is the flat blank outside ring k's boundary polygon, which has slid by
    the displacement of that polygon from its flat position. Friction work is taken on
    the displacement, not on an accumulated path, because the ring-by-ring construction
    has no physical time between steps. |slip| has a kink at zero slip, as |dD| has; the
    minimiser's trust region handles it (no smoothing), and on a drape the held boundary
    is always drawn in, so the kink is met only on a flat tool.
    """

    def __init__(self, force, friction, sectors=None, model="slip"):
        if model not in BLANKHOLDER_MODELS:
            raise ValueError(f"blankholder_model must be one of {BLANKHOLDER_MODELS}, got {model!r}")
        self.model = model
        self.force = np.asarray(force, dtype=float)
        self.friction = np.asarray(friction, dtype=float)
        if sectors is None:
            self.weights = None
        else:
            w = np.asarray(sectors, dtype=float)
            if w.ndim != 1 or w.size < 1 or np.any(w < 0) or not np.isfinite(w).all() or w.sum() <= 0:
                raise ValueError(f"sectors must be a non-empty list of non-negative weights, got {sectors!r}")
            self.weights = w / w.sum()
            self.cumulative = np.concatenate([[0.0], np.cumsum(self.weights)])

    def _cumulative_share(self, theta):
        """Fraction of the total force between angle 0 and ``theta`` (rad, unwrapped)."""
        s = self.weights.size
        pos = theta / (2 * np.pi) * s
        turns = np.floor(pos / s)
        pos = pos - turns * s
        k = np.minimum(np.floor(pos).astype(int), s - 1)
        return turns + self.cumulative[k] + (pos - k) * self.weights[k]

    def segment_energy(self, p1, p2, f1, f2, centre, force, friction):
        """Energy (J) of boundary segments: draped ends p1, p2 (..., 3), flat-blank ends
        f1, f2 (..., 2), crossover (..., 2) in plan; force and friction broadcast.

        phi_seg = mean of the angles the draped and the flat segment subtend at the
        crossover; dU = 2 mu (share) F |slip| with both fabric faces rubbing. Under
        ``"radial"`` slip is dD = D_undraped - D_draped of the segment midpoints (plan
        distance to the crossover); friction work does not change sign with the sliding
        direction, so |dD| is used where the thesis writes dD: the same on convex moulds
        (material is only drawn in), and no negative energy for the minimiser to exploit
        when a segment moves outwards. Under ``"slip"`` it is the plan displacement of the
        midpoint from its flat position.
        """
        d1 = p1[..., :2] - centre
        d2 = p2[..., :2] - centre
        u1 = f1 - centre
        u2 = f2 - centre
        mid_d = 0.5 * (d1 + d2)
        mid_u = 0.5 * (u1 + u2)
        if self.model == "radial":
            slip = np.abs(np.hypot(mid_u[..., 0], mid_u[..., 1]) - np.hypot(mid_d[..., 0], mid_d[..., 1]))
        else:
            slip = np.hypot(mid_d[..., 0] - mid_u[..., 0], mid_d[..., 1] - mid_u[..., 1])
        phi = 0.5 * (_angle2(d1, d2) + _angle2(u1, u2))
        if self.weights is None:
            share = phi / (2 * np.pi)
        else:
            direction = mid_d / np.linalg.norm(mid_d, axis=-1, keepdims=True)
            direction = direction + mid_u / np.linalg.norm(mid_u, axis=-1, keepdims=True)
            theta = np.arctan2(direction[..., 1], direction[..., 0])
            share = self._cumulative_share(theta + 0.5 * phi) - self._cumulative_share(theta - 0.5 * phi)
        return 2.0 * friction * share * force * slip * MM_TO_M
