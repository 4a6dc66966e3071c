"""uqdrape: uncertainty quantification for kinematic drape of dry textile preforms.

Units at every interface: lengths mm, forces N, energies J, angles degrees.

The Python API (``uqdrape.__all__``), each name documented with its units, shapes and an
example (``help(uqdrape.run_study)``):

Studies
    load_study, validate_study, Study, StudyError, list_examples, copy_example
Runs
    run_study, open_ensemble, open_sensitivity, open_design, rare_probability
Statistics
    node_statistics, exceedance_probability, line_statistics, realization_qois
Reports and exports
    write_report, export_result
Single drapes, moulds and material cards
    mould, drape_mould, available_materials, load_material, derive_material, fit_material
Calibration
    calibrate_fibre_angles, calibrate_drapes

A first run (a small version of a shipped study; statistics per node as a Dataset)::

    import uqdrape as ud

    study = ud.load_study(ud.copy_example("nosecone-zero-angle", "studies"),
                          {"study.realizations": 16, "solver.rings": 12})
    run = ud.run_study(study, out="results/first-run")
    stats = ud.node_statistics(ud.open_ensemble(run), "shear")
    stats["sd"].isel(blankholder_force=0).plot()

The names are imported on first use (PEP 562), so ``import uqdrape`` and ``uqdrape
--help`` do not pay for numba, xarray, dask, SciPy or matplotlib.
"""

from typing import TYPE_CHECKING

from ._lazy import lazy_exports
from ._version import __version__  # noqa: F401  (the package's version, written once in _version)

#: The public API: the names of the module docstring, in its order (a test holds them equal).
__all__ = [
    "load_study", "validate_study", "Study", "StudyError", "list_examples", "copy_example",
    "run_study", "open_ensemble", "open_sensitivity", "open_design", "rare_probability",
    "node_statistics", "exceedance_probability", "line_statistics", "realization_qois",
    "write_report", "export_result",
    "mould", "drape_mould", "available_materials", "load_material", "derive_material", "fit_material",
    "calibrate_fibre_angles", "calibrate_drapes",
]

if TYPE_CHECKING:  # what IDEs and type checkers follow; at run time __getattr__ imports on first use
    from .api import (available_materials, calibrate_drapes, calibrate_fibre_angles, derive_material, drape_mould,
                      exceedance_probability, export_result, fit_material, line_statistics, load_material,
                      load_study, mould, node_statistics, open_design, open_ensemble, open_sensitivity,
                      rare_probability, realization_qois, run_study, validate_study, write_report)
    from .study import Study, StudyError
    from .workflow.examples import copy_example, list_examples

#: Where the names live: uqdrape.api, but for four.
__getattr__, __dir__ = lazy_exports(__name__, {".api": __all__, ".study": ("Study", "StudyError"),
                                               ".workflow.examples": ("list_examples", "copy_example")})
