"""Start-up and a run's fixed overhead (issue 41). Run: python benchmarks/bench_startup.py [--repeats 5]

Measured in one run, the commands interleaved (one of each per repeat, medians printed):

- wall time of ``python -c "import numpy"`` (the floor any numerical command pays),
  ``python -c "import uqdrape"``, ``uqdrape --help`` and ``uqdrape validate STUDY``;
- a run's fixed overhead at 1 and 2 local workers: ``uqdrape run`` of STUDY cut to two
  chunks (``--no-report -v``, into a temporary folder), the time from starting the
  command to its first "finished" chunk line, minus one chunk's drape time measured
  in this process with the kernels already loaded (median of 3). That difference is what
  the run pays before its workers drape: interpreter and imports, the pre-run checks,
  the pool's start, each worker's imports and kernel loading.

The numba cache is warm (a first run after an edit of the kernels compiles them once,
which this benchmark does before timing). The machine's load average is printed.
"""

from __future__ import annotations

import argparse
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
CLI = [sys.executable, "-m", "uqdrape.cli"]


def wall(cmd: list[str]) -> float:
    """Wall time (s) of ``cmd`` run to its end; it must succeed."""
    start = time.perf_counter()
    subprocess.run(cmd, env=ENV, cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def first_chunk(study: Path, workers: int, out: Path) -> float:
    """Seconds from starting ``uqdrape run`` to its first finished chunk's line."""
    cmd = CLI + ["run", str(study), "--out", str(out), "--workers", str(workers), "--no-report", "--no-resume",
                 "-v"]
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, env=ENV, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    first = None
    for line in proc.stderr:
        if first is None and line.startswith("finished"):
            first = time.perf_counter() - start
    if proc.wait() != 0 or first is None:
        raise RuntimeError(f"{' '.join(cmd)} failed (exit {proc.returncode})")
    return first


def two_chunks(folder: Path, chunk: int) -> Path:
    """STUDY with two chunks of ``chunk`` realisations, written into ``folder``."""
    text = STUDY.read_text(encoding="utf-8")
    text = re.sub(r"(?m)^realizations = \d+", f"realizations = {2 * chunk}", text)
    text = re.sub(r"(?m)^chunk_size = \d+", f"chunk_size = {chunk}", text)
    path = folder / STUDY.name
    path.write_text(text, encoding="utf-8")
    return path


def chunk_drape_time(study: Path, chunk: int, repeats: int = 3) -> float:
    """Median seconds of one chunk's drape in this process, the kernels loaded first."""
    import numpy as np

    from uqdrape.ensemble import drape_inputs, sampled_inputs
    from uqdrape.study import load_study

    s = load_study(study)
    r = np.arange(chunk)
    inputs = sampled_inputs(s, r)
    drape_inputs(s, r[:1], sampled_inputs(s, r[:1]))  # load (or compile) the kernels
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        drape_inputs(s, r, inputs)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="interleaved repeats (default 5)")
    parser.add_argument("--chunk", type=int, default=16, help="realisations per chunk of the run (default 16)")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    print(f"load average before: {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        study = two_chunks(tmp, args.chunk)
        drape = chunk_drape_time(study, args.chunk)
        first_chunk(study, 1, tmp / "warm")  # a first run compiles the kernels if the cache is cold
        commands = {
            'python -c "import numpy"': lambda: wall([sys.executable, "-c", "import numpy"]),
            'python -c "import uqdrape"': lambda: wall([sys.executable, "-c", "import uqdrape"]),
            "uqdrape --help": lambda: wall(CLI + ["--help"]),
            f"uqdrape validate {STUDY.relative_to(ROOT)}": lambda: wall(CLI + ["validate", str(STUDY)]),
            "run, 1 worker: first chunk": lambda: first_chunk(study, 1, tmp / "w1"),
            "run, 2 workers: first chunk": lambda: first_chunk(study, 2, tmp / "w2"),
        }
        times = {name: [] for name in commands}
        for _ in range(args.repeats):
            for name, measure in commands.items():
                times[name].append(measure())
    numpy = statistics.median(times['python -c "import numpy"'])
    print(f"\nmedians of {args.repeats} interleaved repeats (s); ratio to `import numpy`")
    for name, values in times.items():
        med = statistics.median(values)
        print(f"  {name:48s} {med:7.3f}  x{med / numpy:5.1f}   (min {min(values):.3f}, max {max(values):.3f})")
    print(f"\none chunk's drape ({args.chunk} realisations, kernels loaded): {drape:.3f} s")
    for workers in (1, 2):
        first = statistics.median(times[f"run, {workers} worker{'s' if workers > 1 else ''}: first chunk"])
        print(f"  run's fixed overhead at {workers} worker{'s' if workers > 1 else ' '}: {first - drape:6.2f} s"
              f"  (first chunk {first:.2f} s - drape {drape:.2f} s)")
    print(f"load average after: {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
