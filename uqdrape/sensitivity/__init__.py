"""uqdrape.sensitivity: SALib problems (stochastic factors + random-field groups), designs,
Sobol'/Morris indices as xarray Datasets, and indices versus blank-holder force.

Flow (as SALib's): ``make_problem`` -> ``sample`` -> evaluate -> ``analyze``;
``run_sensitivity`` does all three for any callable model. For a study,
``study_design`` gives the design whose rows ``uqdrape run`` drapes, and
``write_sensitivity`` analyses the run's quantities of interest (``realization_qois``)
and node shear per blank-holder level (``open_sensitivity`` reads the result).
"""

from .analysis import CONSTANT_RTOL, VARIABLES, analyze, analyze_map, indices_vs_levels
from .design import (
    METHODS,
    MORRIS_MIN_TRAJECTORIES,
    MORRIS_NUM_LEVELS,
    MORRIS_TAIL_QUANTILE,
    SOBOL_MIN_BASE_SAMPLES,
    check_base_samples,
    sample,
)
from .pipeline import run_sensitivity
from .problem import check_problem, field_group, make_problem
from .qoi import QOI_ATTRS, realization_qois
from .study import (
    INDICES_FILE,
    MAPS_FILE,
    MORRIS_SCREENING_TRAJECTORIES,
    StudyDesign,
    design_base_samples,
    map_indices,
    open_sensitivity,
    qoi_indices,
    study_design,
    study_problem,
    write_sensitivity,
)

__all__ = [
    "CONSTANT_RTOL", "METHODS", "MORRIS_MIN_TRAJECTORIES", "MORRIS_NUM_LEVELS",
    "MORRIS_TAIL_QUANTILE", "SOBOL_MIN_BASE_SAMPLES", "VARIABLES", "analyze",
    "analyze_map", "check_base_samples", "check_problem", "field_group", "indices_vs_levels",
    "make_problem", "run_sensitivity", "sample",
    "QOI_ATTRS", "realization_qois",
    "INDICES_FILE", "MAPS_FILE", "MORRIS_SCREENING_TRAJECTORIES", "StudyDesign", "design_base_samples",
    "map_indices", "open_sensitivity", "qoi_indices", "study_design", "study_problem", "write_sensitivity",
]
