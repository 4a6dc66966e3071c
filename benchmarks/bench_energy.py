"""Energy-mode drape speed (issue 3): nose cone, EBXhd-936-like, spacing 5 mm, 30 rings
(the max-shear lines reach ~200 mm from the tip), F_BH = 126 N, mu = 0.2.

Prints the median single energy drape time, the batched throughput with a different
iid zero-energy-angle field (sd 5 deg) per realisation, and the energy / geodesic cost
ratio measured in the same run. Run: python benchmarks/bench_energy.py [N]
"""

import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import dask
import numpy as np

from uqdrape.drape import drape, max_shear_lines
from uqdrape.geometry import build
from uqdrape.material import load_material


def _chunk(n_real, seed):
    """An ensemble-style task: draws its own zero-angle fields and drapes them in one call."""
    mould, material, rings = build("nose_cone"), load_material("ebxhd936_like"), 30
    gamma0 = np.random.default_rng(seed).normal(0.0, 5.0, (n_real, 2 * rings, 2 * rings))
    ds = drape(mould, 5.0, rings, mode="energy", material=material, gamma0=gamma0,
               blankholder_force=126.0, friction=0.2)
    return float(ds.converged.mean())


def main(n_batch=64, repeats=3):
    mould, material, spacing, rings = build("nose_cone"), load_material("ebxhd936_like"), 5.0, 30
    common = dict(material=material, blankholder_force=126.0, friction=0.2)
    rng = np.random.default_rng(7)

    def timed(fn):
        times = []
        for _ in range(repeats):
            t = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t)
        return statistics.median(times), out

    single_e, one = timed(lambda: drape(mould, spacing, rings, mode="energy", **common))
    single_g, _ = timed(lambda: drape(mould, spacing, rings, mode="geodesic", **common))
    gamma0 = rng.normal(0.0, 5.0, (n_batch, 2 * rings, 2 * rings))
    batch_e, ds = timed(lambda: drape(mould, spacing, rings, mode="energy", gamma0=gamma0, **common))
    batch_g, _ = timed(lambda: drape(mould, spacing, rings, mode="geodesic", gamma0=gamma0, **common))
    reach = float(max_shear_lines(one).distance.isel(realization=0).max())
    print(f"nose cone, s=5 mm, {rings} rings (max-shear lines reach {reach:.0f} mm), ebxhd936_like, 126 N")
    print(f"single energy drape: median {single_e:.2f} s; single geodesic drape {single_g * 1e3:.0f} ms")
    print(f"batch of {n_batch} energy drapes (different zero-angle fields): median {batch_e:.2f} s "
          f"= {60 * n_batch / batch_e:.0f} realisations/min on one process "
          f"(converged {float(ds.converged.mean()):.2f}, mean iterations {float(ds.iterations.mean()):.0f})")
    print(f"energy / geodesic cost ratio: single {single_e / single_g:.0f}x, batched {batch_e / batch_g:.0f}x")
    # both cores: two chunks of n_batch drapes as dask tasks on a pool of two processes
    tasks = [dask.delayed(_chunk)(n_batch, seed) for seed in (11, 12)]
    with ProcessPoolExecutor(2) as pool:
        dask.compute(dask.delayed(_chunk)(2, 0), dask.delayed(_chunk)(2, 1), scheduler="processes", pool=pool)
        both, _ = timed(lambda: dask.compute(*tasks, scheduler="processes", pool=pool, chunksize=1))
    print(f"2 processes, 2 x {n_batch} energy drapes: median {both:.2f} s = {60 * 2 * n_batch / both:.0f} "
          f"realisations/min on 2 cores ({batch_e * 2 / both:.2f}x one process)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 64)
