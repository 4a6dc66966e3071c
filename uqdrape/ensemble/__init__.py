"""uqdrape.ensemble: run a study's realisations as dask tasks into a run's storage.

``run_ensemble(study)`` drapes every realisation (or the rows of a sample matrix) (locally or on
a dask.distributed cluster, resumable) and returns where it wrote them;
``open_ensemble(where)`` opens them lazily as one xarray Dataset. Where a run lives is
chosen once by ``at(path or URL)`` (``location``: the one storage interface; a plain path
is a run folder of netCDF chunks, an fsspec URL one zarr store), and every reader takes
either. ``sampled_inputs`` / ``inputs_from_rows`` give the solver inputs of
realisations as deterministic functions of standard variables, and ``drape_inputs``
drapes them (e.g. for a sensitivity sample); ``compute_tasks`` runs any such batches as
dask tasks on the same schedulers (e.g. the candidate designs of ``uqdrape.design``).

The names below are imported on first use (PEP 562), so that ``uqdrape validate``, which
drapes one realisation (``inputs``, ``chunk``) and checks the output folder (``storage``),
does not load dask, the run loop or the progress bar.
"""

from __future__ import annotations

from .._lazy import lazy_exports

_EXPORTS = {
    ".chunk": ("drape_inputs", "drape_laminate", "placement_status", "ply_inputs", "study_mould", "write_atomic",
               "write_netcdf"),
    ".inputs": ("inputs_from_rows", "sample_columns", "sampled_inputs"),
    ".progress": ("Progress", "ring_progress"),
    ".run": ("compute_tasks", "reach_scheduler", "run_ensemble"),
    ".storage": ("at", "open_ensemble", "read_manifest"),
    "..pool": ("local_pool",),  # the worker pool's, re-exported
}

__all__ = ["run_ensemble", "open_ensemble", "sampled_inputs", "inputs_from_rows", "sample_columns",
           "drape_inputs", "drape_laminate", "placement_status", "ply_inputs", "study_mould", "write_atomic", "write_netcdf", "read_manifest",
           "compute_tasks", "reach_scheduler", "Progress", "ring_progress", "local_pool", "at"]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
