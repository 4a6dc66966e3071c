"""Shear-energy material models and material cards."""
