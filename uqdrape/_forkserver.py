"""Imported by the local workers' forkserver (``uqdrape.pool.PRELOAD``), once for all the
workers it forks. First it asks the kernel to kill it when the thread that started it
dies (Linux), as it does the workers, instead of leaving it to exit once the run's pipe
closes (seconds, unloading the engine it imported). Then it imports what a chunk's task
uses, down to what its first drape and netCDF file import on the way (dask.array through
xarray's duck arrays, dask.distributed through xarray's choice of write lock, scipy.linalg
through numba's BLAS check), and sets up numba's CPU target (its typing and lowering
registries), which every worker otherwise builds before its first kernel: about 1.2 CPU-s
a worker, spent here while the run's own process reads the study. No kernel runs here, so
no thread pool is started before the fork."""

from .pool import die_with_parent

die_with_parent()

import dask.array  # noqa: E402,F401
import dask.distributed  # noqa: E402,F401
import dask.multiprocessing  # noqa: E402,F401
import netCDF4  # noqa: E402,F401
import scipy.linalg  # noqa: E402,F401
import xarray  # noqa: E402,F401
from numba.core.registry import cpu_target  # noqa: E402

from .ensemble import chunk, run  # noqa: E402,F401

cpu_target.target_context.refresh()
cpu_target.typing_context.refresh()
