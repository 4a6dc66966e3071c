"""An ensemble as one zarr store against the folder of netCDF chunks (issue 28): wall
time, peak memory of the client and of the workers, size and object count on disk, and
the per-node statistics read back lazily.

Studies: (g) geodesic drapes of a hemisphere (R 100 mm, spacing 5 mm, 21 x 21 net,
iid spacing cv 0.5 %, zero-energy angle sd 3 deg), chunks of 2,000; (e) energy drapes of
the same net (EBXhd-936-like card, 100 N, mu 0.2), chunks of 250. Both float32 (a third
of the bytes). Each case is ``uqdrape run STUDY --out OUT --workers 2 --no-resume
--no-report -q`` in a fresh process, OUT a run folder or a ``file://`` store under
--root, then ``node_statistics(open_ensemble(OUT))`` (mean, sd, skewness, 3 quantiles
with their limits: a few lazy dask passes) in another fresh process. Memory: the peak RSS of
the client process and the peak RSS of the largest single worker process, sampled every
0.2 s with psutil. Each output is deleted after it is measured.

Run: ``nice -n 10 python benchmarks/bench_store.py --geodesic 100000 1000000 --energy
10000 --root /tmp/bench-store`` (check the disk first: 10^6 geodesic drapes take about
11 GiB). Cases run once each, energy first, store then folder (``--layouts``).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import psutil

sys.path.insert(0, str(Path(__file__).parent))
from bench_ensemble import PeakRSS, load  # noqa: E402

STUDY = """
[study]
name = "{name}"
seed = 28
realizations = {n}
chunk_size = {chunk}

[geometry]
kind = "hemisphere"
radius = 100.0

[fabric]
material = "ebxhd936_like"
spacing_mm = 5.0

[process]
blankholder_force_N = 100.0
friction = 0.2

[solver]
mode = "{mode}"
rings = 10

[uncertainty.spacing]
cv = 0.005
correlation = "iid"

[uncertainty.zero_angle]
sd_deg = 3.0
correlation = "iid"

[output]
float32 = true
"""

#: argv: the run, then "all" (node_statistics) or "moments" (its mean, sd, skewness part alone); prints
#: the mean and sd averaged over the nodes and the number of dask graph runs (passes)
STATISTICS = """
import sys
from dask.callbacks import Callback
from uqdrape.ensemble import open_ensemble
from uqdrape.stats import node_statistics
from uqdrape.stats.summary import moment_statistics
class Passes(Callback):  # dask graph runs: passes over the ensemble
    runs = 0
    def _start(self, dsk):
        Passes.runs += 1
with open_ensemble(sys.argv[1]) as ds, Passes():
    stats = node_statistics(ds) if sys.argv[2] == "all" else moment_statistics(ds["shear"], 0.95).compute()
print(float(stats["mean"].mean()), float(stats["sd"].mean()), Passes.runs)
"""


class ClientAndWorkers(PeakRSS):
    """Peak RSS (bytes) of the direct child process (the client) and of the largest of
    its descendants (a worker), sampled as ``PeakRSS`` samples the tree."""

    def __init__(self, interval: float = 0.2):
        super().__init__(interval)
        self.client = self.worker = 0

    def sample(self) -> int:
        for child in self._me.children():
            try:
                self.client = max(self.client, child.memory_info().rss)
                for worker in child.children(recursive=True):
                    self.worker = max(self.worker, worker.memory_info().rss)
            except psutil.Error:  # a process that exited between listing and reading
                pass
        return self.client


def measured(cmd: list[str], cwd: Path) -> tuple[float, ClientAndWorkers, str]:
    """Run ``cmd`` in ``cwd``: (wall time s, its memory peaks, its stdout)."""
    with ClientAndWorkers() as mem:
        t = time.perf_counter()
        done = subprocess.run(cmd, cwd=cwd, check=True, capture_output=True, text=True)
        wall = time.perf_counter() - t
    return wall, mem, done.stdout


def on_disk(folder: Path) -> tuple[int, int]:
    """(bytes, files) under ``folder``."""
    size = files = 0
    for parent, _, names in os.walk(folder):
        for name in names:
            size += (Path(parent) / name).stat().st_size
            files += 1
    return size, files


def case(root: Path, mode: str, n: int, chunk: int, layout: str) -> dict:
    """One run and its statistics; the output deleted after."""
    name = f"bench-store-{mode}-{n}-{layout}"
    study = root / f"{name}.toml"
    study.write_text(STUDY.format(name=name, n=n, chunk=chunk, mode=mode), encoding="utf-8")
    folder = root / name
    out = f"file://{folder}" if layout == "store" else str(folder)
    try:
        wall, run, _ = measured([sys.executable, "-m", "uqdrape.cli", "run", str(study), "--out", out,
                                 "--workers", "2", "--no-resume", "--no-report", "-q"], root)
        size, files = on_disk(folder)
        stats_wall, stats, values = measured([sys.executable, "-c", STATISTICS, out, "all"], root)
        moments_wall, moments, _ = measured([sys.executable, "-c", STATISTICS, out, "moments"], root)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
        study.unlink()
    row = {"mode": mode, "realizations": n, "chunk_size": chunk, "layout": layout, "wall_s": round(wall, 1),
           "drapes_per_s": round(n / wall), "client_MiB": round(run.client / 2**20),
           "worker_MiB": round(run.worker / 2**20), "GiB": round(size / 2**30, 3), "objects": files,
           "stats_s": round(stats_wall, 1), "stats_MiB": round(stats.client / 2**20),
           "moments_s": round(moments_wall, 1), "moments_MiB": round(moments.client / 2**20),
           "mean_sd": values.split()[:2], "stats_passes": int(values.split()[2]), "load": load()}
    print(json.dumps(row), flush=True)
    return row


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--geodesic", type=int, nargs="*", default=[100_000, 1_000_000], help="ensemble sizes")
    p.add_argument("--energy", type=int, nargs="*", default=[10_000], help="ensemble sizes")
    p.add_argument("--layouts", nargs="+", choices=("store", "folder"), default=["store", "folder"])
    p.add_argument("--root", type=Path, default=Path("/tmp/bench-store"), help="where the outputs go")
    args = p.parse_args(argv)
    args.root.mkdir(parents=True, exist_ok=True)
    print(f"{psutil.cpu_count()} CPUs, {psutil.virtual_memory().total / 2**30:.1f} GiB RAM, "
          f"{shutil.disk_usage(args.root).free / 2**30:.0f} GiB free under {args.root}; {load()}", flush=True)
    for mode, sizes, chunk in (("energy", args.energy, 250), ("geodesic", args.geodesic, 2000)):
        for n in sizes:
            for layout in args.layouts:
                case(args.root, mode, n, chunk, layout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
