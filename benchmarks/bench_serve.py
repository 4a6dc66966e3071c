"""uqdrape as a UM-Bridge model driven by another UQ library: SALib's Sobol' indices of
the nose cone's asymmetry through ``uqdrape serve``, and what the HTTP round trip costs.

A small study (nose cone, EBXhd-936-like card, energy mode, 10 rings of 5 mm) with two
uncertain factors, the blank-holder force (uniform 0-400 N) and the friction (uniform
0.1-0.3), is served on a free loopback port; SALib samples its Saltelli design in the
factors' physical values (the model's input), the umbridge client evaluates every row,
SALib analyses. The same rows are also evaluated in-process (``workflow.serve.evaluate``)
to time the server's overhead and to check the outputs are equal. Run:
``python benchmarks/bench_serve.py`` (needs ``pip install uqdrape[serve]``; about 15 s).

Measured 2026-12-02, 2 CPUs shared, load average 5.1: 64 drapes, 52.9 ms an evaluation
through UM-Bridge against 48.5 ms in-process (the HTTP round trip and JSON: 4.4 ms),
outputs equal bit for bit; S1 / ST of the asymmetry 0.722 / 0.892 for the blank-holder
force, 0.043 / 0.077 for the friction (16 base samples: indicative only).
"""

from __future__ import annotations

import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np
import umbridge
from SALib.analyze import sobol
from SALib.sample import sobol as sobol_sample

from uqdrape.workflow import load_study
from uqdrape.workflow.serve import evaluate

STUDY = """
[study]
name = "serve-bench"
seed = 1
realizations = 1
[geometry]
kind = "nose_cone"
[fabric]
material = "ebxhd936_like"
spacing_mm = 5.0
[process]
blankholder_force_N = 126.0
friction = 0.2
[solver]
mode = "energy"
rings = 10
[uncertainty.blankholder_force]
dist = "uniform"
bounds = [0.0, 400.0]
[uncertainty.friction]
dist = "uniform"
bounds = [0.1, 0.3]
[output]
directory = "{out}"
"""
BASE = 16  # Saltelli base samples: 16 x (2 + 2) = 64 drapes


def main() -> None:
    folder = Path(tempfile.mkdtemp())
    path = folder / "study.toml"
    path.write_text(STUDY.format(out=folder / "run"))
    problem = {"num_vars": 2, "names": ["blankholder_force", "friction"], "bounds": [[0.0, 400.0], [0.1, 0.3]]}
    X = sobol_sample.sample(problem, BASE, calc_second_order=False, seed=3)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}"
    server = subprocess.Popen([sys.executable, "-m", "uqdrape.cli", "serve", str(path), "--port", str(port),
                               "--qoi", "asymmetry", "--max-requests", str(len(X)), "--timeout", "900"],
                              stdout=subprocess.DEVNULL)
    try:
        for _ in range(600):
            try:
                urllib.request.urlopen(f"{url}/Info", timeout=2)
                break
            except OSError:
                time.sleep(0.2)
        model = umbridge.HTTPModel(url, "forward")
        model([list(X[0])])  # compile and warm up (counts as one of the requests)
        t0 = time.perf_counter()
        served = np.array([model([list(x)])[0][0] for x in X[1:]])
        http = (time.perf_counter() - t0) / (len(X) - 1)
        server.wait(timeout=60)  # it stops by itself after the last row
    finally:
        if server.poll() is None:
            server.kill()
    study = load_study(path)
    t0 = time.perf_counter()
    direct = np.array([evaluate(study, x, ("asymmetry",))[0][0] for x in X[1:]])
    local = (time.perf_counter() - t0) / (len(X) - 1)
    assert np.array_equal(served, direct), "served and in-process evaluations differ"
    Y = np.concatenate([[evaluate(study, X[0], ("asymmetry",))[0][0]], direct])  # row 0: the warm-up
    S = sobol.analyze(problem, Y, calc_second_order=False, seed=3)
    print(f"{len(X)} drapes; per evaluation {1e3 * http:.1f} ms through UM-Bridge, {1e3 * local:.1f} ms in-process")
    for name, s1, st in zip(problem["names"], S["S1"], S["ST"]):
        print(f"  {name:18s} S1 {s1:6.3f}  ST {st:6.3f}")


if __name__ == "__main__":
    main()
