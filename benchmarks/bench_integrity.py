"""What checking the chunks' checksums costs a reader (issue 40): ``open_ensemble`` of a
run folder and of a ``file://`` store with the checks (every chunk file hashed, every
region's stored bytes read and hashed) against the same open without them (the run's
``checksum_key`` removed from its manifest, as a run of an older uqdrape has none), and
against ``node_statistics`` of the opened ensemble, the first thing ``report`` does.

The run: bench_store.py's geodesic hemisphere study (21 x 21 net, float32), N
realisations in chunks of C, written once per layout with ``uqdrape run --workers 2``.
Each timing is the median of --repeats, the three measurements interleaved in one
process (the files in the page cache after the first).

Run: ``python benchmarks/bench_integrity.py --n 20000 --chunk 500 --repeats 5``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from bench_ensemble import load  # noqa: E402
from bench_store import STUDY  # noqa: E402


def _manifest(out: str) -> Path:
    return Path(out.removeprefix("file://")) / "run.json"


def timed(out: str, repeats: int) -> dict:
    """Median seconds of open with checks, open without, and node_statistics."""
    from uqdrape.ensemble import open_ensemble
    from uqdrape.stats import node_statistics

    path = _manifest(out)
    checked = path.read_text()
    unchecked = json.dumps({k: v for k, v in json.loads(checked).items() if k != "checksum_key"})
    times = {"open_checked_s": [], "open_unchecked_s": [], "statistics_s": []}
    for _ in range(repeats):
        for label, text in (("open_checked_s", checked), ("open_unchecked_s", unchecked)):
            path.write_text(text)
            t = time.perf_counter()
            open_ensemble(out).close()
            times[label].append(time.perf_counter() - t)
        path.write_text(checked)
        with open_ensemble(out) as ds:
            t = time.perf_counter()
            node_statistics(ds)
            times["statistics_s"].append(time.perf_counter() - t)
    return {k: round(statistics.median(v), 3) for k, v in times.items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=20000)
    parser.add_argument("--chunk", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-integrity-") as tmp:
        root = Path(tmp)
        study = root / "study.toml"
        study.write_text(STUDY.format(name="bench-integrity", n=args.n, chunk=args.chunk, mode="geodesic"))
        for layout in ("folder", "store"):
            out = str(root / layout) if layout == "folder" else f"file://{root}/{layout}"
            subprocess.run([sys.executable, "-m", "uqdrape.cli", "run", str(study), "--out", out, "--workers", "2",
                            "--no-resume", "--no-report", "-q"], check=True)
            row = {"layout": layout, "realizations": args.n, "chunk_size": args.chunk, **timed(out, args.repeats)}
            row["check_over_statistics"] = round((row["open_checked_s"] - row["open_unchecked_s"])
                                                 / row["statistics_s"], 3)
            print(json.dumps({**row, "load": load()}), flush=True)
            shutil.rmtree(out.removeprefix("file://"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
