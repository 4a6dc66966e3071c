"""uqdrape.sensitivity: SALib problems (stochastic factors + random-field groups), sample matrices,
Sobol'/Morris indices as xarray Datasets, and indices versus blank-holder force.

Flow (as SALib's): ``make_problem`` -> ``sample`` -> evaluate -> ``analyze``;
``qoi_indices`` and ``map_indices`` analyse the outputs of a sample matrix's rows per blank-holder force level. The
study's own problem and sample matrix are ``study``; running it (its drapes, the files) is
``uqdrape.workflow``.
"""

from .analysis import CONSTANT_RTOL, VARIABLES, analyze, analyze_map, indices_vs_levels
from ..stochastic.sampling import METHODS, MORRIS_MIN_TRAJECTORIES, SOBOL_MIN_BASE_SAMPLES, check_base_samples
from .sample import MORRIS_NUM_LEVELS, MORRIS_TAIL_QUANTILE, sample
from .problem import check_problem, field_group, make_problem
from .indices import ROUNDOFF, SampleMatrix, map_indices, qoi_indices
from .study import MORRIS_SCREENING_TRAJECTORIES, sensitivity_base_samples, sensitivity_sample, study_problem

__all__ = [
    "CONSTANT_RTOL", "METHODS", "MORRIS_MIN_TRAJECTORIES", "MORRIS_NUM_LEVELS",
    "MORRIS_TAIL_QUANTILE", "SOBOL_MIN_BASE_SAMPLES", "VARIABLES", "analyze",
    "analyze_map", "check_base_samples", "check_problem", "field_group", "indices_vs_levels",
    "make_problem", "sample",
    "ROUNDOFF", "SampleMatrix", "map_indices", "qoi_indices",
    "MORRIS_SCREENING_TRAJECTORIES", "sensitivity_base_samples", "sensitivity_sample", "study_problem",
]
