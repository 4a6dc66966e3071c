"""uqdrape.ensemble: run a study's realisations as dask tasks into a netCDF chunk store.

``run_ensemble(study)`` drapes every realisation (or the rows of a design) (locally or on a dask.distributed cluster,
resumable) and returns the output folder; ``open_ensemble(folder)`` opens it lazily as
one xarray Dataset; a plain path is a run folder of netCDF chunks, an fsspec URL one zarr
store, and every reader takes either (``location``: a run's own files, and the files made
from it, in either). ``sampled_inputs`` / ``inputs_from_design`` give the solver inputs of
realisations as deterministic functions of standard variables, and ``drape_inputs``
drapes them (e.g. for a sensitivity design); ``compute_tasks`` runs any such batches as
dask tasks on the same schedulers (e.g. the candidate designs of ``uqdrape.design``).
"""

from .chunk import drape_inputs, write_atomic, write_netcdf
from .inputs import design_variables, inputs_from_design, sampled_inputs
from .hygiene import local_pool, run_lock
from .location import made_from, read_dataset, run_name, write_dataset
from .progress import Progress
from .run import compute_tasks, reach_scheduler, run_ensemble
from .store import open_ensemble, read_manifest
from ..files import is_url
from .zarrstore import store_lock

__all__ = ["run_ensemble", "open_ensemble", "sampled_inputs", "inputs_from_design", "design_variables",
           "drape_inputs", "write_atomic", "write_netcdf", "read_manifest", "compute_tasks", "reach_scheduler", "Progress", "local_pool", "run_lock",
           "made_from", "read_dataset", "write_dataset", "run_name", "is_url",
           "store_lock"]
