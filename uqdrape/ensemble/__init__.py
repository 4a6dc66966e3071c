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
"""

from .chunk import drape_inputs, study_mould, write_atomic, write_netcdf
from .inputs import inputs_from_rows, sample_columns, sampled_inputs
from ..pool import local_pool
from .progress import Progress, ring_progress
from .run import compute_tasks, reach_scheduler, run_ensemble
from .storage import at, open_ensemble, read_manifest


__all__ = ["run_ensemble", "open_ensemble", "sampled_inputs", "inputs_from_rows", "sample_columns",
           "drape_inputs", "study_mould", "write_atomic", "write_netcdf", "read_manifest",
           "compute_tasks", "reach_scheduler", "Progress", "ring_progress", "local_pool", "at"]
