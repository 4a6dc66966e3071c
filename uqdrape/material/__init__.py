"""Shear-energy material models and material cards.

`Material` turns normalised shear force curves N_s(γ) (N/m) into the shear energy per
unit area W(γ) (J/m²) and per net cell (J); `load_material` reads a shipped card, a
TOML card or a CSV curve file; `plot_material` draws N_s and W; `with_imbalance` moves a
card's mid-angle imbalance ΔN(30°) (`imbalance`) and keeps its ends.
"""

from .cards import available_materials, load_material
from .imbalance import imbalance, with_imbalance
from .model import Material
from .plot import plot_material

__all__ = ["Material", "available_materials", "imbalance", "load_material", "plot_material", "with_imbalance"]
