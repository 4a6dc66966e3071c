"""Ten small studies through one Python process against ten ``uqdrape run`` commands (issue 41).

Run: python benchmarks/bench_warm_pool.py [--count 10] [--workers 2]

A small study (the Fig 5.19 energy study cut to 32 realisations in chunks of 16, each
study its own seed) is run ``--count`` times, alternately:

- warm: ``uqdrape.workflow.run_study`` in this process, whose workers' forkserver (with
  the drape engine imported) is started by the first run and kept for the others;
- cold: ``uqdrape run STUDY --no-report -q`` in a fresh process each time.

Printed: the median and total wall time of each, and their ratio; the warm runs' first
(which starts the forkserver) is shown apart. Both write into a temporary folder, and
the ensembles of the two ways are checked equal (same seeds, same numbers). The load
average is printed before and after.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STUDY = ROOT / "studies" / "nosecone-zero-angle.toml"
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}


def small_study(folder: Path, seed: int) -> Path:
    """The Fig 5.19 study with 32 realisations in chunks of 16 and seed ``seed``."""
    text = STUDY.read_text(encoding="utf-8")
    text = re.sub(r"(?m)^realizations = \d+", "realizations = 32", text)
    text = re.sub(r"(?m)^seed = \d+", f"seed = {seed}", text)
    path = folder / f"seed-{seed}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=10, help="studies each way (default 10)")
    parser.add_argument("--workers", type=int, default=2, help="local workers (default 2)")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    import xarray as xr

    from uqdrape.ensemble import open_ensemble
    from uqdrape.study import load_study
    from uqdrape.workflow import run_study

    print(f"load average before: {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} CPUs")
    warm, cold = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for k in range(args.count):
            path = small_study(tmp, 1000 + k)
            start = time.perf_counter()
            mine = run_study(dataclasses.replace(load_study(path), output_dir=tmp / f"warm-{k}"), workers=args.workers,
                             progress=False)
            warm.append(time.perf_counter() - start)
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "uqdrape.cli", "run", str(path), "--out", str(tmp / f"cold-{k}"),
                            "--workers", str(args.workers), "--no-report", "-q"], env=ENV, cwd=ROOT, check=True,
                           stdout=subprocess.DEVNULL)
            cold.append(time.perf_counter() - start)
            with open_ensemble(mine) as a, open_ensemble(tmp / f"cold-{k}") as b:
                xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))
            print(f"  study {k}: warm {warm[-1]:6.1f} s, cold {cold[-1]:6.1f} s", flush=True)
    print(f"\n{args.count} studies of 32 energy drapes, {args.workers} workers (s):")
    print(f"  warm, one process: first {warm[0]:.1f}, median of the rest {statistics.median(warm[1:]):.1f}, "
          f"total {sum(warm):.1f}")
    print(f"  cold, a command each: median {statistics.median(cold):.1f}, total {sum(cold):.1f}")
    print(f"  cold / warm: {sum(cold) / sum(warm):.2f}x in total, "
          f"{statistics.median(cold) / statistics.median(warm[1:]):.2f}x a study once warm")
    print(f"load average after: {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
