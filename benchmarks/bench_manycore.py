"""Throughput against local workers on a many-core machine (issue 41).

Run (a 16-core machine, nothing else running; about 25 min):
    python benchmarks/bench_manycore.py
    python benchmarks/bench_manycore.py --workers 1 2 --drapes 32 64    # a quick check

The thesis's Fig 5.19 study (``studies/nosecone-zero-angle.toml``: energy drapes of the
nose cone, chunks of 16) is cut to each drape count and run as a user runs it, ``uqdrape
run STUDY --workers W --no-report --no-resume -q`` in a fresh process into a temporary
folder, for every worker count (one run a row). Printed per row:
wall time, drapes/min and parallel efficiency, T(1 worker) / (W x T(W workers)) at the
same drape count; per worker count, from the two largest drape counts, the rate the added
drapes go at and the fixed cost that rate leaves (wall time minus drapes / rate): the
seconds a run pays whatever its size. The kernels are loaded from a warm cache (a first
run compiles them, before timing). The load average is printed before and after.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STUDY = ROOT / "studies" / "nosecone-zero-angle.toml"
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}


def study_of(folder: Path, drapes: int, chunk: int) -> Path:
    """The Fig 5.19 study cut to ``drapes`` realisations in chunks of ``chunk``, written into ``folder``."""
    text = STUDY.read_text(encoding="utf-8")
    text = re.sub(r"(?m)^realizations = \d+", f"realizations = {drapes}", text)
    text = re.sub(r"(?m)^chunk_size = \d+", f"chunk_size = {chunk}", text)
    path = folder / f"drapes-{drapes}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def run(study: Path, workers: int, out: Path) -> float:
    """Wall time (s) of ``uqdrape run`` of ``study`` with ``workers`` local processes."""
    cmd = [sys.executable, "-m", "uqdrape.cli", "run", str(study), "--out", str(out), "--workers", str(workers),
           "--no-report", "--no-resume", "-q"]
    start = time.perf_counter()
    subprocess.run(cmd, env=ENV, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4, 8, 16], help="worker counts")
    parser.add_argument("--drapes", type=int, nargs="+", default=[512, 2048], help="drape counts")
    parser.add_argument("--chunk", type=int, default=16, help="realisations per chunk (default 16, the study's)")
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} CPUs")
    wall = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        studies = {n: study_of(tmp, n, args.chunk) for n in args.drapes}
        run(study_of(tmp, args.chunk, args.chunk), 1, tmp / "warm")  # compiles the kernels if the cache is cold
        for n in args.drapes:
            for w in args.workers:
                wall[n, w] = run(studies[n], w, tmp / f"out-{n}-{w}")
                print(f"  {n:5d} drapes, {w:2d} workers: {wall[n, w]:7.1f} s", flush=True)
    base = min(args.workers)
    print(f"\n{'drapes':>6s} {'workers':>7s} {'wall s':>8s} {'drapes/min':>10s} {'efficiency':>10s}")
    for n in args.drapes:
        for w in args.workers:
            efficiency = wall[n, base] * base / (w * wall[n, w])
            print(f"{n:6d} {w:7d} {wall[n, w]:8.1f} {60 * n / wall[n, w]:10.0f} {efficiency:10.0%}")
    if len(args.drapes) > 1:
        small, large = sorted(args.drapes)[-2:]
        print(f"\nfrom {small} to {large} drapes: rate of the added drapes, and the fixed cost it leaves")
        for w in args.workers:
            rate = (large - small) / (wall[large, w] - wall[small, w])
            print(f"  {w:2d} workers: {60 * rate:8.0f} drapes/min ({rate / w * 60:6.0f} a worker), "
                  f"fixed {wall[small, w] - small / rate:6.1f} s")
    print(f"load average after: {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
