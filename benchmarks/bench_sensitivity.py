"""Sensitivity-study speed (issue 6): studies/sensitivity-vs-blankholder.toml, Sobol' with
5 factors/groups at 4 blank-holder levels on the nose cone (EBXhd-936-like, energy mode,
20 rings), run from scratch with local dask processes, then its report.

Prints the wall time of the design + drapes + analysis (``run_study``), of the design +
analysis alone (a resumed run: every chunk already exists), hence of the drapes, the
drapes per second, and the report time. ``--base-samples 64`` runs a quarter of the
design and extrapolates linearly to 256 (drapes and per-column SALib analyses both scale
with the base sample; the design's Sobol' sequence does not, so it is a slight
over-estimate). Target: the full study in under 15 minutes on 2 cores.

``--rings 30`` runs the same study at the thesis's 30 rings (a copy of the study file
with its ``rings`` changed, written to a temporary folder). ``--study PATH`` times another
sensitivity study, e.g. studies/sensitivity-vs-blankholder-30rings.toml. The design alone
(``sensitivity_sample``) is timed too, so design and analysis are stated apart.

Run: python benchmarks/bench_sensitivity.py [--study PATH] [--base-samples N] [--workers W] [--out DIR] [--rings R]
"""

import argparse
import dataclasses
import re
import tempfile
import time
from pathlib import Path

from uqdrape.workflow import run_report, run_study, sensitivity_sample
from uqdrape.study import load_study

STUDY = Path(__file__).resolve().parents[1] / "studies" / "sensitivity-vs-blankholder.toml"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--study", type=Path, default=STUDY, help="study file (default: %(default)s)")
    parser.add_argument("--base-samples", type=int, default=None, help="Sobol' base samples (default: the study's 256)")
    parser.add_argument("--workers", type=int, default=2, help="local worker processes (default 2)")
    parser.add_argument("--out", default=None, help="output folder (default: the study's)")
    parser.add_argument("--rings", type=int, default=None, help="rings of the net (default: the study's 20)")
    args = parser.parse_args()

    path = args.study
    if args.rings:
        text, count = re.subn(r"(?m)^rings = \d+", f"rings = {args.rings}", path.read_text())
        assert count == 1, "the study file should set rings once"
        path = Path(tempfile.mkdtemp()) / path.name
        path.write_text(text)
    study = load_study(path)
    full = study.sensitivity.base_samples
    base = args.base_samples or full
    study = dataclasses.replace(
        study, sensitivity=dataclasses.replace(study.sensitivity, base_samples=base),
        output_dir=Path(args.out) if args.out else study.output_dir)
    groups = len(study.uncertainty.factors) + len(study.uncertainty.fields)
    per_level = base * (groups + 2)
    drapes = per_level * len(study.force_levels)

    t0 = time.perf_counter()
    out = run_study(study, workers=args.workers, resume=False, progress=False)
    total = time.perf_counter() - t0
    t0 = time.perf_counter()
    run_study(study, workers=args.workers, resume=True, progress=False)  # design + analysis only
    overhead = time.perf_counter() - t0
    t0 = time.perf_counter()
    report = run_report(out)
    report_time = time.perf_counter() - t0

    t0 = time.perf_counter()
    sensitivity_sample(study)
    design_time = time.perf_counter() - t0
    drape_time = total - overhead
    print(f"{study.name}: sobol, {groups} factors/groups, base {base}: {per_level} drapes per level x "
          f"{len(study.force_levels)} levels = {drapes} drapes, {study.solver.rings} rings, {args.workers} workers")
    print(f"run (design + drapes + analysis): {total:.0f} s = {total / 60:.1f} min")
    print(f"  design + analysis alone: {overhead:.0f} s (design {design_time:.0f} s, analysis and its files "
          f"{overhead - design_time:.0f} s); drapes: {drape_time:.0f} s = {drapes / drape_time:.1f} drapes/s")
    print(f"report: {report_time:.0f} s ({report})")
    if base != full:
        scale = full / base
        print(f"extrapolated to base {full} ({drapes * scale:.0f} drapes): {total * scale / 60:.1f} min run "
              f"+ {report_time / 60:.1f} min report (linear in the base sample)")


if __name__ == "__main__":
    main()
