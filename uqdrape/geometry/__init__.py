"""Moulds as height fields z = h(x, y) (mm)."""

from .analytic import Hemisphere, Plate
from .base import Surface

__all__ = ["Surface", "Plate", "Hemisphere"]
