"""A card's specimen scatter as an uncertain input: the curve of one realisation.

A card fitted to several shear-test specimens (``uqdrape.material.sheartest``) records
per branch the specimens' sd of N_s at each angle of its mean curve (``[scatter.<branch>]
ns_sd``). A realisation with score z drapes the card

    N_s(γ; z) = max(mean(γ) + z · sd(γ), 0)          (N/m)

so that over realisations with z ~ Normal(0, 1) the curve has the specimens' mean and sd
at every angle (exactly, where the clip at 0 is not reached; ``tests/test_card_scatter.py``
measures it), perfectly correlated along the curve: a specimen stiffer at 10° is stiffer
at 40° too, as the thesis's PF specimens are. The locking angles, phi0 and bending
stiffness are the card's, so every realisation locks where the card says.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..files import read_toml
from .cards import available_materials, cards_dir
from .model import Material


def card_scatter(name_or_path) -> dict[str, np.ndarray]:
    """The specimens' sd of N_s (N/m) per branch ("positive", "negative") at the angles of
    the card's curve; empty for a card without a [scatter] table (a shipped shape, a
    derived card, a CSV). The card is read as ``load_material`` reads it."""
    text = str(name_or_path)
    path = cards_dir().joinpath(text + ".toml") if text in available_materials() else Path(text)
    if Path(path).suffix.lower() != ".toml":
        return {}
    scatter = read_toml(path, "material card").get("scatter", {})
    return {branch: np.asarray(table["ns_sd"], dtype=float) for branch, table in scatter.items()}


def scattered(material: Material, scatter: dict[str, np.ndarray], z: float) -> Material:
    """The card ``material`` at scatter score ``z``: each branch's N_s moved by z sd (clipped
    at 0), everything else as the card."""
    curves = {}
    for branch in ("positive", "negative"):
        angles, ns = material.curve(branch)
        sd = scatter.get(branch, scatter.get("positive") if material.symmetric else None)
        curves[branch] = (angles, ns if sd is None else np.maximum(ns + float(z) * sd, 0.0))
    negative = {} if material.symmetric else dict(angles_deg_neg=curves["negative"][0], ns_neg=curves["negative"][1])
    return Material(f"{material.name} (z = {float(z):+.3f})", *curves["positive"], **negative,
                    phi0_deg=material.phi0_deg, locking_angle_deg=material.locking_angle_deg,
                    locking_angle_neg_deg=material.locking_angle_neg_deg,
                    bending_stiffness=material.bending_stiffness, stitch_direction_deg=material.stitch_direction_deg,
                    description=material.description, note=material.note)
