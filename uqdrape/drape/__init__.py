"""The batched pin-jointed-net drape solver (geodesic and energy-minimising modes)."""

from .energy import BLANKHOLDER_MODELS
from .lines import max_shear_lines, min_shear_lines
from .solver import MODES, drape
from .status import Status

__all__ = ["drape", "MODES", "BLANKHOLDER_MODELS", "Status", "max_shear_lines", "min_shear_lines"]
