"""Compile cost of the numba kernels, cold and warm (issue 12).

Each figure is a fresh process that imports uqdrape and runs a first small drape of each
kind (a 5-ring geodesic hemisphere drape, then a 3-ring energy nose-cone drape over an
STL-free analytic mould, then a 3-ring geodesic drape over the test STL), with
``NUMBA_CACHE_DIR`` pointing at a new empty folder (cold: everything is compiled and
written to the cache) and then again at the same folder (warm: the machine code is
loaded from disk). Prints the median of ``--repeats`` runs of each, in seconds.

Run: python benchmarks/bench_compile.py [--repeats 3]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

CHILD = r'''
import json, time
t0 = time.perf_counter()
from uqdrape.drape import drape
from uqdrape.geometry import MeshSurface, build
from uqdrape.material import load_material
t1 = time.perf_counter()
drape(build("hemisphere"), 5.0, 5)
t2 = time.perf_counter()
drape(build("nose_cone"), 5.0, 3, mode="energy", material=load_material("ebxhd936_like"), blankholder_force=126.0)
t3 = time.perf_counter()
drape(MeshSurface("tests/data/hemisphere_r50.stl"), 5.0, 3)
t4 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "geodesic": t2 - t1, "energy": t3 - t2, "mesh": t4 - t3, "total": t4 - t0}))
'''


def run(cache):
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, cwd=root, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    cold, warm = [], []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as cache:
            cold.append(run(cache))
            warm.append(run(cache))
    for name, runs in (("cold", cold), ("warm", warm)):
        print(name, "  ".join(f"{k} {statistics.median(r[k] for r in runs):.2f} s" for k in runs[0]))


if __name__ == "__main__":
    main()
