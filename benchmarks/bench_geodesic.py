"""Geodesic drape speed (issue 2): hemisphere R = 100 mm, spacing 5 mm, 41 x 41 net.

Prints the median single-drape time, the time of one batched call of N different drapes
(random orientation, crossover and segment lengths) on one thread per core (the default
from a main process) and on one thread, and the throughput ratio batched / looped-single
measured in the same run, with the load average before and after.
Run: python benchmarks/bench_geodesic.py [N]
"""

import os
import statistics
from concurrent.futures import ProcessPoolExecutor
import sys
import time

import dask
import numpy as np

from uqdrape.drape import drape
from uqdrape.drape.solver import default_threads
from uqdrape.geometry import Hemisphere


def inputs(rng, n_real, rings, spacing):
    return dict(
        orientation=rng.uniform(-10, 10, n_real),
        crossover=rng.uniform(-5, 5, (n_real, 2)),
        seg_i=spacing * (1 + 0.01 * rng.standard_normal((n_real, 2 * rings, 2 * rings + 1))),
        seg_j=spacing * (1 + 0.01 * rng.standard_normal((n_real, 2 * rings + 1, 2 * rings))),
    )


def _half_batch(mould, spacing, rings, n_real, seed):
    """A task that draws its own inputs, as an ensemble chunk does, and returns a scalar."""
    args = inputs(np.random.default_rng(seed), n_real, rings, spacing)
    return float(drape(mould, spacing, rings, **args).energy_total.sum())


def main(n_batch=1000, n_single=30):
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    mould, spacing, rings = Hemisphere(100.0), 5.0, 20
    rng = np.random.default_rng(1)
    drape(mould, spacing, rings)  # warm up
    singles = []
    args = inputs(rng, n_single, rings, spacing)
    for r in range(n_single):
        one = {k: v[r] for k, v in args.items()}
        t = time.perf_counter()
        drape(mould, spacing, rings, **one)
        singles.append(time.perf_counter() - t)
    single = statistics.median(singles)
    batches, one_thread, cpu = [], [], []
    for _ in range(3):
        args = inputs(rng, n_batch, rings, spacing)
        t, c = time.perf_counter(), time.process_time()
        ds = drape(mould, spacing, rings, **args)
        batches.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
        t = time.perf_counter()
        drape(mould, spacing, rings, threads=1, **args)
        one_thread.append(time.perf_counter() - t)
    batch = statistics.median(batches)
    valid = float((ds.status == 0).mean())
    # the same batch split over the machine's two cores with dask's local process scheduler
    tasks = [dask.delayed(_half_batch)(mould, spacing, rings, n_batch // 2, seed) for seed in (2, 3)]
    parallel = []
    with ProcessPoolExecutor(2) as pool:
        dask.compute(*tasks, scheduler="processes", pool=pool, chunksize=1)  # start the workers
        for _ in range(3):
            t = time.perf_counter()
            dask.compute(*tasks, scheduler="processes", pool=pool, chunksize=1)
            parallel.append(time.perf_counter() - t)
    par = statistics.median(parallel)
    print(f"load average before {load}, after {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"hemisphere R=100 mm, s=5 mm, {2 * rings + 1}x{2 * rings + 1} net, geodesic")
    print(f"single drape: median {single * 1e3:.1f} ms over {n_single} runs")
    print(f"batch of {n_batch}: median {batch:.2f} s over 3 runs ({n_batch / batch:.0f} drapes/s, valid nodes {valid:.3f})")
    print(f"batch of {n_batch} on one thread: median {statistics.median(one_thread):.2f} s "
          f"({statistics.median(one_thread) / batch:.2f}x the threaded call, {default_threads()} threads; "
          f"its CPU time {statistics.median(cpu):.2f} s: the threads got {statistics.median(cpu) / batch:.2f} CPUs)")
    print(f"throughput ratio batched / looped-single: {single * n_batch / batch:.1f}x (one process)")
    print(f"batch of {n_batch} over 2 dask processes: median {par:.2f} s; ratio to looped-single "
          f"{single * n_batch / par:.1f}x")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1000)
