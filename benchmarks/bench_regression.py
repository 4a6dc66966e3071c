"""Drape speed against a reference commit, in one run (issue 41): so the analytic drape
cannot slow down unseen again.

The reference commit is checked out as a git worktree under the temporary folder, and two
worker processes are started, one importing this checkout's package and one the
reference's. Each compiles (or loads) its kernels and runs every workload once as a
warm-up; then the workloads are timed in rounds, the two workers taking turns within each
round, so load changes hit both alike. Workloads, all on one thread:

- ``energy32``: a batch of 32 energy drapes of the nose cone (EBXhd-936-like, 5 mm, 30
  rings, 126 N, mu 0.2), each with its own iid zero-energy-angle field (sd 5 deg);
- ``energy1``: a single such drape with no zero-angle field;
- ``geodesic256``: 256 geodesic drapes of a hemisphere (R 100 mm, 5 mm, 20 rings) with
  random orientation, crossover and segment lengths (cv 1 %);
- ``geodesic1``: one such drape;
- with ``--mesh`` (a reference that has mesh moulds): ``mesh64``, the 256 geodesic drapes'
  first 64 on that hemisphere exported as a triangle mesh on a 1 mm plan grid.

Prints per workload the median wall time and CPU time of each commit, their ratio (this
checkout / reference), whether the node coordinates agree bitwise, and ``uptime`` before
and after. Run: ``python benchmarks/bench_regression.py [--rounds 7] [--ref 38a9b35] [--mesh]``.
"""

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORKLOADS = ("energy32", "energy1", "geodesic256", "geodesic1")


def _inputs(name):
    """The drape call (mould, spacing, rings, keyword arguments) of workload ``name``."""
    import numpy as np

    from uqdrape.geometry import Hemisphere, build
    from uqdrape.material import load_material

    if name == "mesh64":
        from uqdrape.geometry import MeshSurface, export_stl

        _, s, rings, kwargs = _inputs("geodesic256")
        with tempfile.TemporaryDirectory() as folder:
            path = export_stl(Hemisphere(100.0), Path(folder) / "dome.stl", half_width=150.0, resolution_mm=1.0)
            mould = MeshSurface(path)
        return mould, s, rings, {k: v[:64] for k, v in kwargs.items()}
    if name.startswith("energy"):
        rings, n = 30, int(name.removeprefix("energy"))
        kwargs = dict(mode="energy", material=load_material("ebxhd936_like"), blankholder_force=126.0,
                      friction=0.2)
        if n > 1:
            kwargs["gamma0"] = np.random.default_rng(7).normal(0.0, 5.0, (n, 2 * rings, 2 * rings))
        return build("nose_cone"), 5.0, rings, kwargs
    rings, n, s = 20, int(name.removeprefix("geodesic")), 5.0
    rng = np.random.default_rng(1)
    kwargs = dict(orientation=rng.uniform(-10, 10, n), crossover=rng.uniform(-5, 5, (n, 2)),
                  seg_i=s * (1 + 0.01 * rng.standard_normal((n, 2 * rings, 2 * rings + 1))),
                  seg_j=s * (1 + 0.01 * rng.standard_normal((n, 2 * rings + 1, 2 * rings))))
    if n == 1:
        kwargs = {k: v[0] for k, v in kwargs.items()}
    return Hemisphere(100.0), s, rings, kwargs


def worker(names):
    """Serve the workloads ``names`` as they are named on stdin, one JSON line each on stdout:
    wall and CPU seconds of one drape call and a SHA-256 of its node coordinates."""
    import uqdrape
    from uqdrape.drape import drape

    calls = {name: _inputs(name) for name in names}

    def run(name):
        mould, spacing, rings, kwargs = calls[name]
        t, c = time.perf_counter(), time.process_time()
        ds = drape(mould, spacing, rings, threads=1, **kwargs)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        digest = hashlib.sha256(b"".join(ds[v].values.tobytes() for v in ("x", "y", "z"))).hexdigest()
        return dict(wall=wall, cpu=cpu, digest=digest)

    for name in names:  # warm-up: compiling or loading the kernels is not timed
        run(name)
    print(json.dumps(dict(ready=uqdrape.__file__)), flush=True)
    for line in sys.stdin:
        print(json.dumps(run(line.strip())), flush=True)


def reference_tree(commit):
    """A worktree of ``commit`` under the temporary folder (made once, then reused)."""
    sha = subprocess.run(["git", "-C", str(ROOT), "rev-parse", commit], capture_output=True, text=True,
                         check=True).stdout.strip()
    tree = Path(tempfile.gettempdir()) / f"uqdrape-ref-{sha[:12]}"
    if not (tree / "uqdrape").is_dir():
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), sha], check=True,
                       capture_output=True)
    return tree


class Worker:
    """A worker process importing the package of checkout ``tree``."""

    def __init__(self, tree, names):
        env = dict(os.environ, PYTHONPATH=str(tree))
        self.proc = subprocess.Popen([sys.executable, __file__, "--worker", *names], cwd=tree, env=env, text=True,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self.package = json.loads(self.proc.stdout.readline())["ready"]

    def __call__(self, name):
        self.proc.stdin.write(name + "\n")
        self.proc.stdin.flush()
        return json.loads(self.proc.stdout.readline())

    def close(self):
        self.proc.stdin.close()
        self.proc.wait()


def uptime():
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def main(rounds, ref, names):
    t0 = time.perf_counter()
    workers = {"this": Worker(ROOT, names), ref: Worker(reference_tree(ref), names)}
    for label, w in workers.items():
        print(f"{label}: {w.package}")
    print(f"start-up and warm-up {time.perf_counter() - t0:.0f} s; {uptime()}")
    results = {label: {name: [] for name in names} for label in workers}
    for r in range(rounds):
        for name in names:
            for label in (list(workers) if r % 2 == 0 else list(workers)[::-1]):
                results[label][name].append(workers[label](name))
    for w in workers.values():
        w.close()
    print(f"{rounds} rounds, threads=1, medians; {uptime()}")
    print(f"{'workload':12} {'this wall':>10} {'ref wall':>10} {'ratio':>6} {'this cpu':>10} {'ref cpu':>10} "
          f"{'ratio':>6}  bitwise equal")
    for name in names:
        this, other = results["this"][name], results[ref][name]
        med = {k: (statistics.median(x[k] for x in this), statistics.median(x[k] for x in other))
               for k in ("wall", "cpu")}
        equal = {x["digest"] for x in this} == {x["digest"] for x in other} and len({x["digest"] for x in this}) == 1
        print(f"{name:12} {med['wall'][0] * 1e3:8.1f}ms {med['wall'][1] * 1e3:8.1f}ms {med['wall'][0] / med['wall'][1]:6.3f}"
              f" {med['cpu'][0] * 1e3:8.1f}ms {med['cpu'][1] * 1e3:8.1f}ms {med['cpu'][0] / med['cpu'][1]:6.3f}  {equal}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=7, help="timed rounds (each workload once per commit)")
    parser.add_argument("--ref", default="38a9b35", help="the reference commit")
    parser.add_argument("--mesh", action="store_true", help="add the meshed hemisphere (mesh64)")
    parser.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    worker(args.worker) if args.worker else main(args.rounds, args.ref, WORKLOADS + ("mesh64",) * args.mesh)
