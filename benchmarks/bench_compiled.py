"""Compiled drape against the previous (numpy) implementation, measured in one run (issue 12).

Both implementations are timed by the same code in child processes, one after the other:
this checkout's (the Python running this script, with the checkout holding the script
first on its path) and a previous release installed in its own virtual environment, given
by ``--previous`` (its ``python``, run without PYTHONPATH). Set that up once,
outside the repository, from the last numpy commit::

    mkdir /tmp/uqdrape-prev && git archive 36beba2 | tar -x -C /tmp/uqdrape-prev
    python3 -m venv /tmp/uqdrape-prev/.venv && /tmp/uqdrape-prev/.venv/bin/pip install /tmp/uqdrape-prev

Figures: the single energy drape of the nose cone (EBXhd-936-like, 5 mm, 30 rings,
126 N, mu 0.2; median of 5); a batch of N energy drapes with iid zero-energy angles
(sd 5 deg) in one process, and its CPU time per drape; two processes of N each on the
machine's two cores (dask, local process pool, as ``bench_energy.py``), in realisations
per minute; the single
41 x 41 geodesic hemisphere drape (R = 100 mm, median of 20) and one call of 1,000
such drapes with random orientations (median of 3).

Run: python benchmarks/bench_compiled.py [--previous PYTHON] [--batch N] [--repeats K]
(K alternating runs of both, medians). A checkout put first by PYTHONPATH is what
"compiled" measures (the previous interpreter runs without it), so ``PYTHONPATH=$PWD
/work/main/.venv/bin/python benchmarks/bench_compiled.py --previous
/work/main/.venv/bin/python`` compares a worktree with the main checkout's install.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHILD = r'''
import json, statistics, sys, time
from concurrent.futures import ProcessPoolExecutor
import dask
import numpy as np
from uqdrape.drape import drape
from uqdrape.geometry import build
from uqdrape.material import load_material

N = int(sys.argv[1])


def chunk(n_real, seed):
    rings = 30
    gamma0 = np.random.default_rng(seed).normal(0.0, 5.0, (n_real, 2 * rings, 2 * rings))
    ds = drape(build("nose_cone"), 5.0, rings, mode="energy", material=load_material("ebxhd936_like"),
               gamma0=gamma0, blankholder_force=126.0, friction=0.2)
    return int(ds.converged.sum())


def median(fn, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


if __name__ == "__main__":
    nose, hemi, mat = build("nose_cone"), build("hemisphere", radius=100.0), load_material("ebxhd936_like")
    kw = dict(mode="energy", material=mat, blankholder_force=126.0, friction=0.2)
    chunk(2, 0)  # warm-up (and, for a compiled build, the load of the cached machine code)
    out = {"single_energy_s": median(lambda: drape(nose, 5.0, 30, **kw), 5)}
    t, cpu = time.perf_counter(), time.process_time()
    chunk(N, 11)
    out["batch_energy_per_min"] = 60 * N / (time.perf_counter() - t)
    out["batch_energy_cpu_ms"] = 1e3 * (time.process_time() - cpu) / N
    with ProcessPoolExecutor(2) as pool:
        dask.compute(dask.delayed(chunk)(2, 0), dask.delayed(chunk)(2, 1), scheduler="processes", pool=pool)
        t = time.perf_counter()
        dask.compute(dask.delayed(chunk)(N, 11), dask.delayed(chunk)(N, 12), scheduler="processes", pool=pool,
                     chunksize=1)
        out["two_cores_energy_per_min"] = 60 * 2 * N / (time.perf_counter() - t)
    drape(hemi, 5.0, 20)
    out["single_geodesic_s"] = median(lambda: drape(hemi, 5.0, 20), 20)
    orientation = np.random.default_rng(3).uniform(0.0, 90.0, 1000)
    out["geodesic_1000_s"] = median(lambda: drape(hemi, 5.0, 20, orientation=orientation), 3)
    print(json.dumps(out))
'''

LABELS = {
    "single_energy_s": ("single energy drape, nose cone 30 rings (s)", True),
    "batch_energy_per_min": ("batch of N energy drapes, one process (realisations/min)", False),
    "batch_energy_cpu_ms": ("the same batch: CPU time per drape (ms; less sensitive to load)", True),
    "two_cores_energy_per_min": ("2 processes x N energy drapes (realisations/min)", False),
    "single_geodesic_s": ("single geodesic drape, hemisphere 41 x 41 (s)", True),
    "geodesic_1000_s": ("one call of 1,000 geodesic drapes (s)", True),
}


def measure(python, batch, checkout=None):
    """The child's figures (dict) under interpreter ``python``, run outside the checkout:
    with ``checkout`` first on its path (this checkout's uqdrape), else with its own
    installed uqdrape (no PYTHONPATH)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    if checkout:
        env["PYTHONPATH"] = str(checkout)
    done = subprocess.run([python, "-c", CHILD, str(batch)], capture_output=True, text=True, check=True,
                          cwd=tempfile.gettempdir(), env=env)
    out = json.loads(done.stdout.strip().splitlines()[-1])
    print(python, json.dumps(out), flush=True)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--previous", default="/tmp/uqdrape-prev/.venv/bin/python",
                        help="python of the previous implementation's environment")
    parser.add_argument("--batch", type=int, default=128, help="energy drapes per batch and per process (N)")
    parser.add_argument("--repeats", type=int, default=1,
                        help="measure both this many times, alternating; each figure is the median")
    args = parser.parse_args()
    with open("/proc/loadavg") as f:
        load = f.read().split()[:3]
    t = time.perf_counter()
    runs = [(measure(sys.executable, args.batch, Path(__file__).resolve().parents[1]), measure(args.previous, args.batch))
            for _ in range(args.repeats)]
    new, old = ({key: statistics.median(run[side][key] for run in runs) for key in LABELS} for side in (0, 1))
    print(f"N = {args.batch}, {args.repeats} run(s) each; load average before the run {' '.join(load)}; "
          f"run took {time.perf_counter() - t:.0f} s")
    print(f"{'figure':62s} {'previous':>10s} {'compiled':>10s} {'speed-up':>9s}")
    for key, (label, is_time) in LABELS.items():
        ratio = old[key] / new[key] if is_time else new[key] / old[key]
        print(f"{label:62s} {old[key]:10.4g} {new[key]:10.4g} {ratio:8.2f}x")
    print(json.dumps({"previous": old, "compiled": new}))


if __name__ == "__main__":
    main()
