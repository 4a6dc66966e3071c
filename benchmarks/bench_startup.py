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

On a shared machine wall times stretch with the load; the CPU seconds the run's
processes (the command, its forkserver and workers, sampled every 0.05 s) had used by
that line, minus the chunk's own CPU seconds, are an overhead the load does not stretch.
``--before DIR`` times another checkout (e.g. a ``git worktree`` of the code before a
change) in the same run, each command run in both checkouts one after the other.

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
import threading
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parent.parent
STUDY = ROOT / "studies" / "nosecone-zero-angle.toml"
CLI = [sys.executable, "-m", "uqdrape.cli"]


def env(root: Path) -> dict:
    """The environment that imports uqdrape from the checkout ``root``."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}


def wall(cmd: list[str], root: Path) -> float:
    """Wall time (s) of ``cmd`` run to its end in checkout ``root``; it must succeed."""
    start = time.perf_counter()
    subprocess.run(cmd, env=env(root), cwd=root, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


class TreeCPU:
    """CPU seconds (user + system) of a process and all its descendants, each process's
    last reading kept (sampled every ``interval`` s in a thread, so processes that exit
    are counted up to their last sample)."""

    def __init__(self, pid: int, interval: float = 0.05):
        self.root, self.interval, self.seen = psutil.Process(pid), interval, {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()

    def _watch(self) -> None:
        while not self._stop.is_set():
            self.sample()
            time.sleep(self.interval)

    def sample(self) -> float:
        try:
            procs = [self.root, *self.root.children(recursive=True)]
        except psutil.Error:
            procs = []
        for proc in procs:
            try:
                times = proc.cpu_times()
                self.seen[proc.pid] = times.user + times.system
            except psutil.Error:
                pass
        return sum(self.seen.values())

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def first_chunk(study: Path, workers: int, out: Path, root: Path) -> tuple[float, float]:
    """Seconds from starting ``uqdrape run`` to its first finished chunk's line, and the
    CPU seconds its processes (the command, its workers, forkserver) had used by then."""
    cmd = CLI + ["run", str(study), "--out", str(out), "--workers", str(workers), "--no-report", "--no-resume",
                 "-v"]
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env(root), cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    tree = TreeCPU(proc.pid)
    first = cpu = None
    for line in proc.stderr:
        if first is None and line.startswith("finished"):
            first, cpu = time.perf_counter() - start, tree.sample()
    tree.stop()
    if proc.wait() != 0 or first is None:
        raise RuntimeError(f"{' '.join(cmd)} failed (exit {proc.returncode})")
    return first, cpu


def two_chunks(folder: Path, chunk: int) -> Path:
    """STUDY with two chunks of ``chunk`` realisations, written into ``folder``."""
    text = STUDY.read_text(encoding="utf-8")
    text = re.sub(r"(?m)^realizations = \d+", f"realizations = {2 * chunk}", text)
    text = re.sub(r"(?m)^chunk_size = \d+", f"chunk_size = {chunk}", text)
    path = folder / STUDY.name
    path.write_text(text, encoding="utf-8")
    return path


def chunk_drape_time(study: Path, chunk: int, repeats: int = 3) -> tuple[float, float]:
    """Median wall and CPU seconds of one chunk's drape in this process, the kernels loaded first."""
    import numpy as np

    from uqdrape.ensemble import drape_inputs, sampled_inputs
    from uqdrape.study import load_study

    s = load_study(study)
    r = np.arange(chunk)
    inputs = sampled_inputs(s, r)
    drape_inputs(s, r[:1], sampled_inputs(s, r[:1]))  # load (or compile) the kernels
    walls, cpus = [], []
    for _ in range(repeats):
        start, cpu = time.perf_counter(), time.process_time()
        drape_inputs(s, r, inputs)
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - cpu)
    return statistics.median(walls), statistics.median(cpus)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="interleaved repeats (default 5)")
    parser.add_argument("--chunk", type=int, default=16, help="realisations per chunk of the run (default 16)")
    parser.add_argument("--before", type=Path, help="another checkout to time in the same run")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    roots = {"": ROOT} if args.before is None else {"after": ROOT, "before": args.before.resolve()}
    print(f"load average before: {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        study = two_chunks(tmp, args.chunk)
        drape, drape_cpu = chunk_drape_time(study, args.chunk)
        for root in roots.values():  # a first run compiles the kernels if the cache is cold
            first_chunk(study, 1, tmp / "warm", root)
        commands = {
            'python -c "import numpy"': lambda root: wall([sys.executable, "-c", "import numpy"], root),
            'python -c "import uqdrape"': lambda root: wall([sys.executable, "-c", "import uqdrape"], root),
            "uqdrape --help": lambda root: wall(CLI + ["--help"], root),
            f"uqdrape validate {STUDY.relative_to(ROOT)}": lambda root: wall(CLI + ["validate", str(STUDY)], root),
            "run, 1 worker: first chunk": lambda root: first_chunk(study, 1, tmp / "w1", root),
            "run, 2 workers: first chunk": lambda root: first_chunk(study, 2, tmp / "w2", root),
        }
        times = {(name, label): [] for name in commands for label in roots}
        for _ in range(args.repeats):
            for name, measure in commands.items():
                for label, root in roots.items():
                    times[name, label].append(measure(root))
    runs = {key: times.pop(key) for key in list(times) if key[0].startswith("run")}
    numpy = statistics.median(times['python -c "import numpy"', next(iter(roots))])
    print(f"\nmedians of {args.repeats} interleaved repeats (s); ratio to `import numpy`")
    for (name, label), values in times.items():
        med = statistics.median(values)
        print(f"  {label:6s} {name:52s} {med:7.3f}  x{med / numpy:5.1f}   (min {min(values):.3f}, max {max(values):.3f})")
    print(f"\none chunk's drape ({args.chunk} realisations, kernels loaded): {drape:.3f} s, {drape_cpu:.3f} CPU-s")
    for (name, label), values in runs.items():
        first = statistics.median(w for w, _ in values)
        cpu = statistics.median(c for _, c in values)
        print(f"  {label:6s} {name}: {first:6.2f} s, {cpu:6.2f} CPU-s; fixed overhead {first - drape:6.2f} s, "
              f"{cpu - drape_cpu:6.2f} CPU-s")
    print(f"load average after: {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
