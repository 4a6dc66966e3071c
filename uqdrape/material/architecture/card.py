"""Derived material cards: architecture -> card (derive_card), and a derived card back to
its architecture's pre-strain -> γ0 table (material_zero_force_table)."""

from __future__ import annotations

import math

import numpy as np

from ...files import Document
from ..model import DEFAULT_BENDING_STIFFNESS
from .fabric import Architecture
from .model import MODEL_VERSION, TERMS, branch_forces, summed
from .reader import architecture_document, architecture_from_document
from .zero_force import ZeroForceTable, zero_force_angle, zero_force_table

#: Angles (deg) of the derived card's curve points: 0, 1, 2, ... up to the branch end.
CARD_STEP_DEG = 1.0
#: N_s (N/m) at which a derived card's branch ends and locks: the top of the thesis's
#: positive-shear picture-frame axes for these fabrics (Figs 3.10, 3.12: 0-1000 N/m).
#: Beyond it the constant-thickness compaction is the near-vertical wall that the thesis
#: itself calls unrealistic (L7655-7663).
LOCK_FORCE_N_PER_M = 1000.0
#: Angles (deg, absolute θ) at which a card records each term's N_s (Fig 4.18); 0 is left
#: out because the friction terms jump there.
CONTRIBUTION_STEP_DEG = 5.0


def _card_branch(arch, sides, gamma0, sense, x_max):
    """Card points (x deg from γ0, N_s magnitudes as the Material weights them) of one branch,
    the branch's locking angle and the largest negative N_s clipped to 0 on it."""
    g0 = math.radians(gamma0)
    phi0 = math.radians(arch.phi0_deg)
    xs, ns = [], []
    clipped = 0.0
    for x in np.arange(0.0, x_max + 1e-9, CARD_STEP_DEG):
        t = g0 + sense * math.radians(x)
        on_plus = t > 0.0 or (t == 0.0 and sense > 0)
        grid, force = sides[0] if on_plus else sides[1]
        value = sense * float(np.interp(abs(t), np.abs(grid), force))
        # the Material integrates N_s · sin(2φ0 − sense·x)/sin 2φ0; the architecture's
        # work weight at θ = γ0 + sense·x is sin(2φ0 − θ)/sin 2φ0
        value *= math.sin(2.0 * phi0 - t) / math.sin(2.0 * phi0 - sense * math.radians(x))
        if value < 0.0:
            clipped = max(clipped, -value)
            value = 0.0
        xs.append(float(x))
        ns.append(round(value, 3) + 0.0)
        if value >= LOCK_FORCE_N_PER_M:
            break
    return xs, ns, xs[-1], clipped


def derive_card(arch: Architecture, *, name: str | None = None, source: str = "", terms=None) -> dict:
    """A material card document (TOML layout of uqdrape.material.cards) from the architecture.

    The branches start at the zero-force angle γ0 (x = θ − γ0, magnitudes), 1° apart, and
    end where N_s reaches LOCK_FORCE_N_PER_M, which is the locking angle of that branch.
    The summed energy of the thesis can fall briefly along a branch (stitch friction
    counted from θ = 0 outweighing a slackening stitch); there N_s is clipped to 0 and the
    largest clipped value is recorded (``terms``: ``summed(arch)`` if already computed).
    ``[architecture]`` records the inputs, the
    calibration, the model version, γ0 and each term's N_s every 5° (thesis Fig 4.18).
    """
    gamma0 = zero_force_angle(arch)
    terms = summed(arch) if terms is None else terms
    theta = terms["theta"]
    sides = branch_forces(arch, theta, terms["total"])
    end = float(np.rad2deg(theta[-1]))
    pos = _card_branch(arch, sides, gamma0, +1, end - gamma0)
    neg = _card_branch(arch, sides, gamma0, -1, end + gamma0)
    top = CONTRIBUTION_STEP_DEG * math.floor(end / CONTRIBUTION_STEP_DEG)
    angles = [float(a) for a in np.arange(-top, top + 1e-9, CONTRIBUTION_STEP_DEG)
              if a != 0.0 and gamma0 - neg[2] <= a <= gamma0 + pos[2]]
    at = np.deg2rad(angles)
    contributions = {"angle_deg": [float(a) for a in angles]}
    for term in (*TERMS, "total"):
        contributions[term] = [round(float(v), 3) + 0.0 for v in np.interp(at, theta, terms[f"ns_{term}"])]
    description = (f"derived from the fabric architecture {arch.name!r} (thesis ch. 4 model): "
                   f"{arch.description}").rstrip(": ")
    note = (f"Derived by uqdrape {MODEL_VERSION} from {source or arch.name}: stitch tension, stitch friction, "
            "lateral tow compaction and crossover friction summed at the energy level and differentiated "
            f"(Wiggers 2007, §4.3). Branches are measured from the zero-force angle {gamma0:.3f} deg; they end "
            f"where N_s reaches {LOCK_FORCE_N_PER_M:g} N/m (locking). Calibrated constants and their targets are "
            "under [architecture.calibration]. A model prediction, not measured data.")
    return {
        "name": name or f"{arch.name}_derived",
        "description": description,
        "note": note,
        "phi0_deg": float(arch.phi0_deg),
        "locking_angle_deg": pos[2],
        "locking_angle_neg_deg": neg[2],
        "bending_stiffness": DEFAULT_BENDING_STIFFNESS,
        "stitch_direction_deg": float(arch.phi0_deg),
        "shear": {"positive": {"angle_deg": pos[0], "ns": pos[1]},
                  "negative": {"angle_deg": neg[0], "ns": neg[1]}},
        "architecture": {
            "model": MODEL_VERSION,
            "source": source or arch.name,
            "zero_force_angle_deg": round(gamma0, 6),
            "clipped_ns_N_per_m": round(max(pos[3], neg[3]), 6),
            "inputs": architecture_document(arch),
            "calibration": dict(arch.calibration),
            "contributions": contributions,
        },
    }


def material_zero_force_table(material) -> ZeroForceTable:
    """The pre-strain -> γ0 map of a card derived from an architecture (its [architecture.inputs]).

    Range of validity: the card is the architecture's curve at its own pre-strain ε*,
    measured from its γ0*; a cell at ε0 is given that card shifted to γ0(ε0), i.e. the
    change of shape with ε0 is left out. For the FGE 106hd card (ε* = 0.384 %) the
    shifted card's energy stays within 5 % of the architecture's own (over ±45° from γ0,
    relative to W there) for 0.2 % <= ε0 <= 0.6 % and within 10 % for 0.1-0.8 %
    (γ0 -0.6 to -4.6°); at 1 % it is 14 %, at 2 % 28 %.
    """
    if material.architecture is None:
        raise ValueError(f"material {material.name!r} has no [architecture] record; derive its card from a fabric "
                         "architecture (uqdrape materials derive) to vary the stitch pre-strain")
    source = Document(None, "material card", label=f"material {material.name!r} [architecture.inputs]")
    arch = architecture_from_document(material.architecture["inputs"], source)
    return zero_force_table(arch)


