"""Writes on multi-threaded dask workers (issue 40): the Fig 5.19 study
(``studies/nosecone-zero-angle.toml``, 127 energy drapes in chunks of 16) run --runs times
on each of two clusters whose workers write several chunks at once, every run compared
bitwise with the local run:

- ``dask scheduler`` and one ``dask worker --nthreads 4`` (separate processes, as a user's
  cluster or dask-jobqueue starts them);
- a ``distributed.LocalCluster`` of 2 worker processes with 2 threads each.

Each run is ``uqdrape run STUDY --scheduler ADDRESS --out OUT --no-resume --no-report
-q`` in a fresh process; a failed run (non-zero exit) is counted with its last stderr
line. Prints one JSON line per cluster: runs, failures, runs equal to the local run,
median wall time per run.

Run: ``python benchmarks/check_threaded_workers.py --runs 20``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import xarray as xr

sys.path.insert(0, str(Path(__file__).parent))
from bench_ensemble import load  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
STUDY = ROOT / "studies" / "nosecone-zero-angle.toml"


def run(out: Path, *extra: str) -> tuple[float, str]:
    """(wall s, last stderr line, empty on success) of one ``uqdrape run`` into ``out``."""
    t = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "uqdrape.cli", "run", str(STUDY), "--out", str(out), "--no-resume",
                           "--no-report", "-q", *extra], capture_output=True, text=True)
    lines = done.stderr.strip().splitlines()
    return time.perf_counter() - t, "" if done.returncode == 0 else (lines[-1] if lines else f"exit {done.returncode}")


def equal(out: Path, reference: xr.Dataset) -> bool:
    from uqdrape.ensemble import open_ensemble

    with open_ensemble(out) as ds:
        return ds.load().drop_attrs().identical(reference)


def check(name: str, address: str, runs: int, root: Path, reference: xr.Dataset) -> dict:
    walls, failures, same = [], [], 0
    for k in range(runs):
        out = root / f"{name}-{k}"
        wall, why = run(out, "--scheduler", address)
        walls.append(wall)
        if why:
            failures.append(why)
        else:
            same += equal(out, reference)
    row = {"cluster": name, "runs": runs, "failures": len(failures), "equal_to_local": same,
           "median_wall_s": round(statistics.median(walls), 1), "failed_with": sorted(set(failures)), "load": load()}
    print(json.dumps(row), flush=True)
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args(argv)
    from distributed import LocalCluster
    from uqdrape.ensemble import open_ensemble

    with tempfile.TemporaryDirectory(prefix="threaded-workers-") as tmp:
        root = Path(tmp)
        wall, why = run(root / "local", "--workers", "2")
        if why:
            raise SystemExit(f"the local run failed: {why}")
        with open_ensemble(root / "local") as ds:
            reference = ds.load().drop_attrs()
        print(json.dumps({"cluster": "local processes (reference)", "wall_s": round(wall, 1)}), flush=True)
        port = 8786 + 17
        scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                      "--port", str(port), "--no-dashboard"], stderr=subprocess.DEVNULL)
        worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", f"tcp://127.0.0.1:{port}",
                                   "--nthreads", "4", "--no-dashboard"], stderr=subprocess.DEVNULL)
        try:
            time.sleep(5)
            rows = [check("dask worker --nthreads 4", f"tcp://127.0.0.1:{port}", args.runs, root, reference)]
        finally:
            worker.terminate(), scheduler.terminate()
            worker.wait(30), scheduler.wait(30)
        with LocalCluster(n_workers=2, threads_per_worker=2, host="127.0.0.1", dashboard_address=None) as cluster:
            rows.append(check("LocalCluster 2 workers x 2 threads", cluster.scheduler_address, args.runs, root,
                              reference))
    return 0 if all(r["failures"] == 0 and r["equal_to_local"] == r["runs"] for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
