"""The batched pin-jointed-net drape solver (geodesic and energy-minimising modes)."""

from .lines import max_shear_lines, min_shear_lines
from .solver import MODES, drape
from .status import Status

__all__ = ["drape", "MODES", "Status", "max_shear_lines", "min_shear_lines"]
