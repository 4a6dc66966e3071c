"""uqdrape.stochastic: every uncertain input as a deterministic function of standard variables.

Random fields (exact and Karhunen–Loève), the maps to the solver's spacing and zero-angle
arrays, scalar process factors, sampling plans and per-realisation seeding.
"""

from .factors import DISTRIBUTIONS, Factor, constant, lognormal, make_factor, normal, truncnormal, uniform
from .fields import CORRELATIONS, GaussianField, KLField
from .inputs import PrestrainInput, SpacingInput, ZeroAngleInput
from .sampling import (METHODS, PLANS, check_base_samples, check_method, realization_normals, realization_rng,
                       sample_uniforms, uniforms_to_normals)

__all__ = [
    "CORRELATIONS", "GaussianField", "KLField",
    "PrestrainInput", "SpacingInput", "ZeroAngleInput",
    "DISTRIBUTIONS", "Factor", "constant", "lognormal", "make_factor", "normal", "truncnormal", "uniform",
    "METHODS", "PLANS", "check_base_samples", "check_method", "realization_normals", "realization_rng", "sample_uniforms", "uniforms_to_normals",
]
