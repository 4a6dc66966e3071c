"""Ensemble speed and memory (issue 4). Run: python benchmarks/bench_ensemble.py [--skip-nosecone]

(a) The thesis's Fig 5.19 study, ``studies/nosecone-zero-angle.toml`` (127 energy drapes
    of the nose cone), end to end as a user runs it: ``uqdrape run --workers 2
    --no-resume`` in a fresh process (imports, ensemble, report). Median wall time of
    3 runs; target < 30 s.
(b) 10,000 geodesic drapes of a hemisphere (R = 100 mm, spacing 5 mm, 20 rings: a 41 x 41
    net, iid spacing cv 0.5 %) streamed to disk chunk by chunk with ``run_study``, once
    with 1 and once with 2 local workers: realisations/s, the speed-up, and the peak
    resident memory of the whole process tree (this process + every worker, RSS summed,
    sampled every 0.2 s); target < 1.5 GB and a speed-up >= 1.7.

Every run writes into a temporary folder that is deleted afterwards. The machine is
shared: the load average (1 min) is printed before and after each part.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parent.parent
NOSECONE = ROOT / "studies" / "nosecone-zero-angle.toml"
HEMISPHERE_STUDY = """\
[study]
name = "bench-hemisphere-10k"
seed = 4004
realizations = {n}
chunk_size = {chunk}
description = "issue 4 benchmark: geodesic hemisphere ensemble streamed to disk"

[geometry]
kind = "hemisphere"
radius = 100.0

[fabric]
material = "generic_woven"
spacing_mm = 5.0

[process]
blankholder_force_N = 0.0

[solver]
mode = "geodesic"
rings = 20

[uncertainty.spacing]
cv = 0.005
correlation = "iid"
"""


class PeakRSS:
    """Peak of the summed resident set size (bytes) of this process and all its
    descendants, sampled every ``interval`` seconds in a daemon thread (use as a context)."""

    def __init__(self, interval: float = 0.2):
        self.interval = interval
        self.peak = 0
        self._stop = threading.Event()
        self._me = psutil.Process()

    def sample(self) -> int:
        total = 0
        for proc in [self._me, *self._me.children(recursive=True)]:
            try:
                total += proc.memory_info().rss
            except psutil.Error:  # a worker that exited between listing and reading
                pass
        self.peak = max(self.peak, total)
        return total

    def _run(self):
        while not self._stop.is_set():
            self.sample()
            self._stop.wait(self.interval)

    def __enter__(self):
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.sample()


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min)"


def bench_nosecone(runs: int = 3) -> None:
    print(f"(a) {NOSECONE.relative_to(ROOT)}: uqdrape run --workers 2 --no-resume (ensemble + report), "
          f"{runs} runs; {load()}", flush=True)
    times, peaks = [], []
    with tempfile.TemporaryDirectory(prefix="bench-nosecone-") as tmp:
        for k in range(runs):
            cmd = [sys.executable, "-m", "uqdrape.cli", "run", str(NOSECONE), "--workers", "2", "--no-resume",
                   "--quiet"]
            with PeakRSS() as mem:
                t = time.perf_counter()
                subprocess.run(cmd, cwd=tmp, check=True, stdout=subprocess.DEVNULL)
                times.append(time.perf_counter() - t)
            peaks.append(mem.peak)
            print(f"    run {k + 1}: {times[-1]:.1f} s, peak RSS {mem.peak / 2**20:.0f} MiB; {load()}", flush=True)
    print(f"    median {statistics.median(times):.1f} s (target < 30 s); peak RSS of the process tree "
          f"{max(peaks) / 2**20:.0f} MiB", flush=True)


def bench_hemisphere(n: int, chunk: int) -> None:
    from uqdrape.workflow import run_study

    print(f"(b) {n} geodesic hemisphere drapes (R 100 mm, s 5 mm, 41 x 41 net, spacing cv 0.5 %), "
          f"chunks of {chunk}, streamed to disk; {load()}", flush=True)
    rates = {}
    with tempfile.TemporaryDirectory(prefix="bench-hemisphere-") as tmp:
        study = Path(tmp) / "bench-hemisphere-10k.toml"
        study.write_text(HEMISPHERE_STUDY.format(n=n, chunk=chunk), encoding="utf-8")
        for workers in (1, 2):
            cwd = os.getcwd()
            os.chdir(tmp)  # the study's output folder is relative to the working directory
            try:
                with PeakRSS() as mem:
                    t = time.perf_counter()
                    out = run_study(study, workers=workers, resume=False, progress=False)
                    elapsed = time.perf_counter() - t
            finally:
                os.chdir(cwd)
            size = sum(p.stat().st_size for p in (out / "chunks").glob("*.nc"))
            rates[workers] = n / elapsed
            print(f"    {workers} worker{'s' if workers > 1 else ''}: {elapsed:.1f} s, {rates[workers]:.0f} "
                  f"realisations/s, peak RSS of the process tree {mem.peak / 2**20:.0f} MiB (target < 1536), "
                  f"{size / 2**30:.2f} GiB on disk; {load()}", flush=True)
            shutil.rmtree(out)
    print(f"    speed-up 2 workers / 1 worker: {rates[2] / rates[1]:.2f}x (target >= 1.7x)", flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--skip-nosecone", action="store_true", help="only part (b)")
    p.add_argument("--skip-hemisphere", action="store_true", help="only part (a)")
    p.add_argument("--realizations", type=int, default=10_000, help="part (b) ensemble size (default 10000)")
    p.add_argument("--chunk-size", type=int, default=250, help="part (b) realisations per chunk (default 250)")
    args = p.parse_args(argv)
    print(f"{psutil.cpu_count()} CPUs, {psutil.virtual_memory().total / 2**30:.1f} GiB RAM, "
          f"python {sys.version.split()[0]}")
    if not args.skip_nosecone:
        bench_nosecone()
    if not args.skip_hemisphere:
        bench_hemisphere(args.realizations, args.chunk_size)
    return 0


if __name__ == "__main__":
    sys.exit(main())
