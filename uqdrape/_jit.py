"""The compilation setting of uqdrape's kernels: numba ``njit`` cached to disk (the
``__pycache__`` next to each module, or ``NUMBA_CACHE_DIR``), with numpy's floating-point
error model (x / 0 gives inf or NaN, as in the array code, instead of raising), and
without the GIL, so ``on_threads`` can share a batch's realisations among Python threads."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit

jit = njit(cache=True, error_model="numpy", nogil=True)


def on_threads(threads, R, call):
    """Call ``call(rows)`` for ``threads`` contiguous slices ``rows`` of range(R), each on
    its own thread (one slice, on this thread, for threads <= 1). Every realisation is
    computed by the same compiled code whatever the split, so results do not depend on it."""
    bounds = np.linspace(0, R, max(min(threads, R), 1) + 1).round().astype(int)
    rows = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]
    if len(rows) == 1:
        call(rows[0])
        return
    with ThreadPoolExecutor(len(rows)) as pool:
        for done in [pool.submit(call, r) for r in rows]:
            done.result()
