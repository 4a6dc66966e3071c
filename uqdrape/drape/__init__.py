"""The batched pin-jointed-net drape solver (geodesic and energy-minimising modes)."""

from ..schema import BLANKHOLDER_MODELS, MODES
from .flat import draw_in, flat_positions
from .lines import max_shear_lines, min_shear_lines
from .solver import drape, drape_status
from .status import Status, placement_failures, unplaced_error

__all__ = ["drape", "drape_status", "MODES", "BLANKHOLDER_MODELS", "placement_failures", "unplaced_error", "Status",
           "max_shear_lines", "min_shear_lines", "flat_positions", "draw_in"]
