"""The application layer: every command goes cli -> workflow -> the engines.

- ``run``: run a study (its Monte Carlo ensemble, its SALib sample and indices, or its
  blank-holder design) and report a finished run;
- ``preflight``: what a study needs of this machine and of its physics (memory, disk,
  writability, placement of the first realisation), checked at the start of every run
  and by ``uqdrape validate``;
- ``single_shot``: one drape to files, material cards (show, derive, fit to shear tests),
  exports;
- ``help_text``: the command line's descriptions of moulds, architectures and studies;
- ``serve``: a study as a UM-Bridge model (``uqdrape serve``);
- ``calibrate``: measured fibre angles -> a calibrated ``[uncertainty.zero_angle]`` block;
  measured drapes -> the posterior of chosen study parameters and the calibrated study.

The names below are imported on first use (PEP 562), so that ``uqdrape --help`` and the
light commands do not pay for dask, matplotlib and SALib.
"""

from __future__ import annotations

from .._lazy import lazy_exports

_EXPORTS = {
    ".run": ("run_study", "run_outcome", "design_outcome", "run_design", "run_report", "write_sensitivity",
             "open_sensitivity", "INDICES_FILE", "MAPS_FILE"),
    ".preflight": ("load_study", "validate_study", "check_resources", "check_placement", "run_preflight",
                   "check_workers"),
    ".single_shot": ("check_drape_inputs", "drape_to_files", "material_list", "material_text", "derive_material",
                     "fit_material", "export_result"),
    ".help_text": ("geometry_help", "architectures", "describe_study", "version_text"),
    ".serve": ("serve_study", "input_names", "nominal_input"),
    ".calibrate": ("calibrate_fibre_angles", "calibrate_drapes", "calibrate_parts", "synthetic_parts"),
}
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
