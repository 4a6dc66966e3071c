"""Energy-mode drape speed (issue 3): nose cone, EBXhd-936-like, spacing 5 mm, 30 rings
(the max-shear lines reach ~200 mm from the tip), F_BH = 126 N, mu = 0.2.

Prints the median single energy drape time, the batched throughput with a different
iid zero-energy-angle field (sd 5 deg) per realisation, and the energy / geodesic cost
ratio measured in the same run. Run: python benchmarks/bench_energy.py [N]
"""

import statistics
import sys
import time

import numpy as np

from uqdrape.drape import drape, max_shear_lines
from uqdrape.geometry import build
from uqdrape.material import load_material


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


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 64)
