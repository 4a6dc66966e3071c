"""Forming energies of a (partly) draped net, in J.

Shear energy lives on cells (material card, zero-energy offset per cell), bending is the
generator-path penalty, and the blank-holder energy is friction work on the boundary
polygon of the outermost ring: thesis Eq 5.1-5.5 (radial draw-in only) or the full plan
slip of the held fabric. All functions are batched over leading axes.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit
from ..schema import BLANKHOLDER_MODELS

MM_TO_M = 1e-3


def bending_energy(turn, stiffness, spacing):
    """Generator-path penalty (B / s) * turn^2 (J): turn in rad, B in N m^2, s in mm."""
    return stiffness / (spacing * MM_TO_M) * turn**2


@jit
def _angle2(a0, a1, b0, b1):
    """Unsigned angle (rad) between plan vectors a and b."""
    return abs(math.atan2(a0 * b1 - a1 * b0, a0 * b0 + a1 * b1))


@jit
def _cumulative_share(weights, cumulative, theta):
    """Fraction of the total force between angle 0 and ``theta`` (rad, unwrapped)."""
    s = weights.size
    pos = theta / (2 * np.pi) * s
    turns = math.floor(pos / s)
    pos = pos - turns * s
    k = min(int(math.floor(pos)), s - 1)
    return turns + cumulative[k] + (pos - k) * weights[k]


@jit
def segment_energy(bh, p1, p2, f1, f2, centre, force, friction):
    """Energy (J) of one boundary segment under blank-holder kernel ``bh`` (``BlankHolder.kernel``):
    draped ends p1, p2 (3,), flat ends f1, f2 (2,), crossover ``centre`` (2,), all mm."""
    radial, weights, cumulative = bh
    d10, d11 = p1[0] - centre[0], p1[1] - centre[1]
    d20, d21 = p2[0] - centre[0], p2[1] - centre[1]
    u10, u11 = f1[0] - centre[0], f1[1] - centre[1]
    u20, u21 = f2[0] - centre[0], f2[1] - centre[1]
    md0, md1 = 0.5 * (d10 + d20), 0.5 * (d11 + d21)
    mu0, mu1 = 0.5 * (u10 + u20), 0.5 * (u11 + u21)
    if radial:  # plan lengths by sqrt, not hypot: nothing here can overflow, and it is 3x faster
        slip = abs(math.sqrt(mu0 * mu0 + mu1 * mu1) - math.sqrt(md0 * md0 + md1 * md1))
    else:
        slip = math.sqrt((md0 - mu0) ** 2 + (md1 - mu1) ** 2)
    phi = 0.5 * (_angle2(d10, d11, d20, d21) + _angle2(u10, u11, u20, u21))
    if weights.size == 0:
        share = phi / (2 * np.pi)
    else:
        nd, nu = math.sqrt(md0 * md0 + md1 * md1), math.sqrt(mu0 * mu0 + mu1 * mu1)
        theta = math.atan2(md1 / nd + mu1 / nu, md0 / nd + mu0 / nu)
        share = (_cumulative_share(weights, cumulative, theta + 0.5 * phi)
                 - _cumulative_share(weights, cumulative, theta - 0.5 * phi))
    return 2.0 * friction * share * force * slip * MM_TO_M


@jit
def _segment_energy_many(bh, p1, p2, f1, f2, centre, force, friction, out):
    for m in range(out.size):
        out[m] = segment_energy(bh, p1[m], p2[m], f1[m], f2[m], centre[m], force[m], friction[m])


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
            self.weights = np.zeros(0)
            self.cumulative = np.zeros(1)
        else:
            w = np.asarray(sectors, dtype=float)
            if w.ndim != 1 or w.size < 1 or np.any(w < 0) or not np.isfinite(w).all() or w.sum() <= 0:
                raise ValueError(f"sectors must be a non-empty list of non-negative weights, got {sectors!r}")
            self.weights = w / w.sum()
            self.cumulative = np.concatenate([[0.0], np.cumsum(self.weights)])
        #: compiled form: (radial?, sector weights (empty: uniform), their cumulative sums)
        self.kernel = (model == "radial", self.weights, self.cumulative)

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
        p1, p2, f1, f2, centre = (np.asarray(a, float) for a in (p1, p2, f1, f2, centre))
        force, friction = np.asarray(force, float), np.asarray(friction, float)
        shape = np.broadcast_shapes(p1.shape[:-1], p2.shape[:-1], f1.shape[:-1], f2.shape[:-1], centre.shape[:-1],
                                    force.shape, friction.shape)
        args = [np.ascontiguousarray(np.broadcast_to(a, shape + a.shape[-1:])).reshape(-1, a.shape[-1])
                for a in (p1, p2, f1, f2, centre)]
        args += [np.ascontiguousarray(np.broadcast_to(a, shape)).ravel() for a in (force, friction)]
        out = np.empty(args[-1].size)
        _segment_energy_many(self.kernel, *args, out)
        return out.reshape(shape)
