"""The batched pin-jointed-net drape solver (geodesic and energy-minimising modes)."""

from .energy import BLANKHOLDER_MODELS
from .lines import max_shear_lines, min_shear_lines
from .solver import MODES, drape
from .status import Status, placement_failures

__all__ = ["drape", "MODES", "BLANKHOLDER_MODELS", "placement_failures", "Status", "max_shear_lines", "min_shear_lines"]
