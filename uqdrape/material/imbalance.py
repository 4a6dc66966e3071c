"""A card family with the mid-angle imbalance of an NCF as its parameter.

What sets the blank-holder force that makes an asymmetric NCF drape symmetric is the
difference of its two shear branches at mid angles, about ΔN(30°) = N_s⁺(30°) − N_s⁻(30°)
(N/m, N_s = F_s/L), while the ends of the curves (zero at 0°, the rise to locking) are
what shear tests measure best. :func:`with_imbalance` keeps a card's negative branch and
the ends of its positive one and moves the mid range to a chosen ΔN(30°):

    N⁺(θ) = N⁻(θ) + D(θ) · ρ^w(θ),      D = N⁺_card − N⁻_card,  ρ = ΔN / D(30°)

with w = 1 up to 30° and w = cos²(π/2 · (θ − 30°) / (θ_L − 30°)) from there to the
positive locking angle θ_L, or the end of the negative curve where that comes first (w = 0
there and beyond): below 30° the card's imbalance is
scaled by ρ, at locking it is the card's. ρ = 1 gives the card back exactly. The family
is evaluated at the card's own angle points (30° inserted if the card has no point
there), so a card with coarse points keeps its PCHIP shape.
"""

from __future__ import annotations

import math

import numpy as np

from .model import Material, MaterialError

#: The angle (deg) the imbalance is stated at.
IMBALANCE_ANGLE_DEG = 30.0


def _negative_at(material: Material, angles_deg: np.ndarray) -> np.ndarray:
    """N⁻ (N/m, magnitude) at ``angles_deg`` (deg >= 0), by the card's own interpolation."""
    ns = -material.shear_force(-np.deg2rad(angles_deg))
    ns[np.asarray(angles_deg) == 0.0] = material.curve("negative")[1][0]  # shear_force(-0.0) is the positive branch
    if not np.all(np.isfinite(ns)):
        raise MaterialError("shear.negative", f"the negative curve of {material.name} ends at "
                            f"{material.curve('negative')[0][-1]:g} deg, before the positive locking angle: "
                            "the imbalance needs both branches up to it")
    return ns


def imbalance(material: Material) -> float:
    """ΔN(30°) = N⁺(30°) − N⁻(30°) of a card (N/m, F_s/L)."""
    theta = np.array([IMBALANCE_ANGLE_DEG])
    return float(material.shear_force(np.deg2rad(theta))[0] - _negative_at(material, theta)[0])


def with_imbalance(material: Material, imbalance_Nm: float) -> Material:
    """The card ``material`` with its mid-angle imbalance ΔN(30°) moved to ``imbalance_Nm``
    (N/m, F_s/L; see the module docstring). Refused (MaterialError naming the branch) for
    a card without a positive imbalance at 30° to scale, or a value that is not > 0."""
    value = float(imbalance_Nm)
    base = imbalance(material)
    if not (math.isfinite(value) and value > 0.0):
        raise MaterialError("imbalance_Nm", f"imbalance_Nm must be a number > 0 (N/m), got {imbalance_Nm!r}")
    if not base > 0.0:
        raise MaterialError("imbalance_Nm", f"the card {material.name} has no positive imbalance at 30 deg to "
                            f"scale (N+ - N- = {base:.3g} N/m): the family keeps the card's shape and needs "
                            "a stiffer positive branch (an asymmetric NCF card)")
    if value == base:
        return material
    angles, ns = material.curve("positive")
    if IMBALANCE_ANGLE_DEG not in angles:
        if not angles[-1] > IMBALANCE_ANGLE_DEG:
            raise MaterialError("shear.positive", f"the positive curve of {material.name} ends at {angles[-1]:g} "
                                "deg, before 30 deg")
        ns = np.insert(ns, np.searchsorted(angles, IMBALANCE_ANGLE_DEG),
                       material.shear_force(np.deg2rad([IMBALANCE_ANGLE_DEG]))[0])
        angles = np.insert(angles, np.searchsorted(angles, IMBALANCE_ANGLE_DEG), IMBALANCE_ANGLE_DEG)
    lock = min(material.locking_angle_deg, float(material.curve("negative")[0][-1]))
    span = np.clip((angles - IMBALANCE_ANGLE_DEG) / (lock - IMBALANCE_ANGLE_DEG), 0.0, 1.0)
    weight = np.cos(0.5 * np.pi * span) ** 2
    inside = angles < lock  # from θ_L on the card's own points
    negative = _negative_at(material, angles[inside])
    positive = ns.copy()
    positive[inside] = np.maximum(negative + (ns[inside] - negative) * (value / base) ** weight[inside], 0.0)
    neg_angles, neg_ns = material.curve("negative")
    return Material(f"{material.name} (dN30 = {value:.4g} N/m)", angles, positive, neg_angles, neg_ns,
                    phi0_deg=material.phi0_deg, locking_angle_deg=material.locking_angle_deg,
                    locking_angle_neg_deg=material.locking_angle_neg_deg,
                    bending_stiffness=material.bending_stiffness, stitch_direction_deg=material.stitch_direction_deg,
                    description=material.description,
                    note=f"{material.note}\nMid-angle imbalance moved to dN(30 deg) = {value:.6g} N/m "
                         f"(card: {base:.6g} N/m) by uqdrape.material.imbalance.with_imbalance.".strip())
