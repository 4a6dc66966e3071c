"""Cost of a calibration from measured drapes (issue 25): README's example, four synthetic
parts of studies/calibration-hemisphere.toml, the zero-angle sd and the blank-holder force
calibrated (20 + 10 design points of 32 energy drapes each, two emcee runs).

Prints per repeat the wall time of the design's drapes (both rounds, the ensemble engine's
local processes), of the emulator fits (a GP per output, both rounds), of the two emcee
runs and of the whole ``calibrate_parts``, with the load average; then the medians.

Run: python benchmarks/bench_calibration_drapes.py [--repeats 3]
"""

import argparse
import os
import time
from pathlib import Path

import numpy as np

from uqdrape.experimental import read_experimental
from uqdrape.workflow import calibrate as workflow

ROOT = Path(__file__).resolve().parents[1]
PARAMS = [workflow.Parameter("uncertainty.zero_angle.sd_deg", 0.5, 8.0),
          workflow.Parameter("process.blankholder_force_N", 0.0, 400.0)]


def _timed(name, func, spent):
    def wrapper(*args, **kwargs):
        clock = time.perf_counter()
        try:
            return func(*args, **kwargs)
        finally:
            spent[name] = spent.get(name, 0.0) + time.perf_counter() - clock
    return wrapper


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    parts = [read_experimental(ROOT / "studies" / "measurements" / f"part-{k}.csv") for k in range(1, 5)]
    study = ROOT / "studies" / "calibration-hemisphere.toml"
    rows = []
    originals = {name: getattr(workflow, name) for name in ("_drape_batches", "Emulator", "sample_posterior")}
    for repeat in range(args.repeats):
        spent = {}
        for name, func in originals.items():
            setattr(workflow, name, _timed(name, func, spent))
        clock = time.perf_counter()
        cal = workflow.calibrate_parts(study, parts, PARAMS, measurement_sd=0.05)
        spent["total"] = time.perf_counter() - clock
        rows.append(spent)
        print(f"repeat {repeat + 1}: drapes {spent['_drape_batches']:.1f} s, emulator fits {spent['Emulator']:.1f} s, "
              f"emcee {spent['sample_posterior']:.1f} s, total {spent['total']:.1f} s; sd "
              f"{np.median(cal.posterior.samples[PARAMS[0].key]):.4g}; load {os.getloadavg()[0]:.1f}", flush=True)
    for name in ("_drape_batches", "Emulator", "sample_posterior", "total"):
        print(f"median {name}: {np.median([r[name] for r in rows]):.1f} s")


if __name__ == "__main__":
    main()
