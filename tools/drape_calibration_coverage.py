"""How often the drape calibration's 90 % interval covers the truth, over synthetic data sets
(issue 25; one data set is what tests/test_calibration_drapes.py asserts):

    python tools/drape_calibration_coverage.py [--sets 12]

Each set: four parts made by uqdrape (the test's small energy study, zero-angle sd 3 deg,
150 N, measurement sd 0.02 deg, parts' seed 100 + set), the sd calibrated in [0.5, 8]
from the first part and from all four. Prints each set's intervals, then the coverage
and the median ratio of the four-part to the one-part width.
"""

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from conftest import write_study  # noqa: E402  (the tests' study builder)
from test_calibration_drapes import DISTANCES, SD_KEY, SMALL  # noqa: E402

from uqdrape.calibration.parameters import Parameter  # noqa: E402
from uqdrape.workflow.calibrate import calibrate_parts, synthetic_parts  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--sets", type=int, default=12)
    args = parser.parse_args()
    param = Parameter(SD_KEY, 0.5, 8.0)
    covered, ratios = {1: 0, 4: 0}, []
    with tempfile.TemporaryDirectory() as folder:
        path = write_study(folder, **SMALL)
        for k in range(args.sets):
            parts = synthetic_parts(path, {SD_KEY: 3.0}, 4, DISTANCES, seed=100 + k, measurement_sd=0.02)
            widths = {}
            for n in (1, 4):
                cal = calibrate_parts(path, parts[:n], [param], measurement_sd=0.02, scheduler="synchronous",
                                      steps=1000)
                lo, hi = cal.interval(param)
                covered[n] += lo < 3.0 < hi
                widths[n] = hi - lo
                print(f"set {k}: {n} part(s) [{lo:.3f}, {hi:.3f}]", flush=True)
            ratios.append(widths[4] / widths[1])
    for n in (1, 4):
        print(f"{n} part(s): the 90 % interval covered sd = 3 in {covered[n]} of {args.sets} sets")
    print(f"width with 4 parts / with 1: median {np.median(ratios):.2f} (range {min(ratios):.2f}-{max(ratios):.2f})")


if __name__ == "__main__":
    main()
