"""Benchmark: the shipped double-dome blank-holder design study end to end.

``python benchmarks/bench_design.py`` runs ``studies/design-doubledome-sectors.toml``
as shipped (8 sector forces, 64 realisations per design, its ``max_evaluations``
designs, 64 validation drapes for each of 3 roles) from scratch with 2 local workers,
writes its report, and ends with one summary line: designs, drapes, wall time of the
design run (the report not included), drapes/s, workers and the load average.
``--evaluations N`` and ``--realizations R`` shrink it (a smaller run of the same study,
into ``<output>-N-R``); ``--keep`` resumes an earlier run instead of starting over.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shutil
import sys
import time
from pathlib import Path

import xarray as xr

from uqdrape.design import DESIGN_FILE
from uqdrape.study import load_study
from uqdrape.workflow import run_design, run_report

STUDY = Path(__file__).resolve().parents[1] / "studies" / "design-doubledome-sectors.toml"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--evaluations", type=int, help="max_evaluations (default: the study's)")
    p.add_argument("--realizations", type=int, help="realisations per design and validation role (default: the study's)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--keep", action="store_true", help="resume an earlier run of the same size")
    args = p.parse_args()
    study = load_study(STUDY)
    if args.evaluations or args.realizations:
        spec = study.design
        n = args.realizations or study.realizations
        e = args.evaluations or spec.max_evaluations
        study = dataclasses.replace(
            study, realizations=n, output_dir=study.output_dir.with_name(f"{study.output_dir.name}-{e}-{n}"),
            design=dataclasses.replace(spec, max_evaluations=e, validation_realizations=n))
    if not args.keep and study.output_dir.exists():
        shutil.rmtree(study.output_dir)
    load = os.getloadavg()[0]
    start = time.perf_counter()
    out = run_design(study, workers=args.workers)
    elapsed = time.perf_counter() - start
    report = run_report(out)
    ds = xr.load_dataset(out / DESIGN_FILE)
    designs = int((ds["sample"] == "design").sum())
    done = int(ds.attrs["drapes_this_run"])
    print(ds.attrs["summary"])
    print(f"report: {report}")
    print(f"bench_design: {study.name}: {designs} designs x {study.realizations} realisations "
          f"+ {ds.attrs['drapes_total'] - designs * study.realizations} validation drapes; {done} drapes "
          f"(of {ds.attrs['drapes_total']}) in {elapsed:.0f} s = {elapsed / 60:.1f} min, {done / elapsed:.2f} drapes/s; "
          f"{args.workers} workers; load average {load:.1f} at the start, {os.getloadavg()[0]:.1f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
