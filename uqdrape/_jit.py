"""The compilation setting of uqdrape's kernels: numba ``njit`` cached to disk (the
``__pycache__`` next to each module, or ``NUMBA_CACHE_DIR``), with numpy's floating-point
error model (x / 0 gives inf or NaN, as in the array code, instead of raising).
``jit_threads`` is the same with ``prange`` loops run on numba's threads."""

from numba import njit

jit = njit(cache=True, error_model="numpy")
jit_threads = njit(cache=True, error_model="numpy", parallel=True)
