"""uqdrape.stats: ensemble statistics of drape results.

Per-node mean, sd, skewness, quantiles and their confidence limits; exceedance
probability (wrinkle risk) with binomial intervals; summaries along the max/min-shear
lines; node histograms with a fitted Normal; convergence with N; the scalar quantities
of interest of each drape (the registry ``qoi``: what sensitivity studies rank and
designs' objectives are statistics of). Every function
reduces along ``realization`` (dask-friendly) and returns an in-memory xarray Dataset
with CF ``units`` / ``long_name`` attributes.
"""

from .convergence import convergence, samples_needed
from .exceedance import clopper_pearson_interval, exceedance_probability, wilson_interval
from .headline import STUDY_KINDS, dominant_factors, headline_numbers, study_kind, varying_factors, wrinkle_risk
from .histogram import node_histogram
from .laminate import fibre_deviation, laminate_lock, tool_lock_map
from .lines import line_means, line_scalars, line_statistics, shear_at_points
from .qoi import QOI_ATTRS, QOIS, SENSITIVITY_QOIS, check_qois, realization_qois
from .summary import inner_outer_sd, mean_statistics, node_statistics, quantile_statistics, ring_sd

__all__ = [
    "fibre_deviation", "laminate_lock", "tool_lock_map", "node_statistics", "mean_statistics", "quantile_statistics",
    "exceedance_probability", "wilson_interval", "clopper_pearson_interval", "line_statistics", "line_scalars",
    "shear_at_points", "line_means", "node_histogram", "convergence", "samples_needed", "QOIS", "QOI_ATTRS",
    "SENSITIVITY_QOIS", "check_qois", "realization_qois", "ring_sd", "inner_outer_sd", "STUDY_KINDS", "study_kind",
    "varying_factors", "wrinkle_risk", "headline_numbers", "dominant_factors",
]
