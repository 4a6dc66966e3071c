"""What a laminate costs against its plies draped one by one (issue 37).

An 8-ply laminate ([0/45/90/-45]s, one card, one spacing: one batched drape of 8 N
members) of N realisations, ``uqdrape.ensemble.drape_laminate``, against the same 8 plies
draped as 8 single-ply studies of N realisations (``drape_inputs`` of each
``Study.ply_study``), interleaved in one process, medians of --repeats. Both give the
same drapes bit for bit (tests/test_laminate.py); the ratio is what batching the plies
saves or costs. Also the memory of one realisation of the laminate: the in-memory
Dataset's bytes per realisation (all plies), and a float64 chunk file's bytes per
realisation. With ``--thickness T`` the same laminate with plies of T mm, each on the tool
offset by the plies below it (8 offsets: 8 batches), is timed beside the others.

Run: ``python benchmarks/bench_laminate.py --mode energy --n 16 --rings 10 --repeats 5 --thickness 0.5``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_ensemble import load  # noqa: E402

ANGLES = (0, 45, 90, -45, -45, 90, 45, 0)


def study_text(mode: str, n: int, rings: int, out: Path, thickness: float = 0.0) -> str:
    plies = "".join(f'\n[[ply]]\nname = "p{k}"\nangle_deg = {a}\nmisalignment_sd_deg = 1.0\nthickness_mm = {thickness}\n'
                    for k, a in enumerate(ANGLES))
    return f"""[study]
name = "bench-laminate"
seed = 37
realizations = {n}
chunk_size = {n}

[geometry]
kind = "hemisphere"
radius = 100.0

[fabric]
material = "ebxhd936_like"
spacing_mm = 5.0

[process]
blankholder_force_N = 100.0

[solver]
mode = "{mode}"
rings = {rings}

[uncertainty.zero_angle]
mean_deg = 0.0
sd_deg = 1.0

[output]
directory = "{out}"
{plies}"""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mode", choices=("geodesic", "energy"), default="energy")
    parser.add_argument("--n", type=int, default=16, help="realisations")
    parser.add_argument("--rings", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--thickness", type=float, default=0.0, help="ply thickness (mm) of a third, offset laminate")
    args = parser.parse_args(argv)

    from uqdrape.ensemble import drape_inputs, drape_laminate, sampled_inputs
    from uqdrape.ensemble.chunk import ply_inputs, write_atomic
    from uqdrape.schema import at_level
    from uqdrape.study import load_study

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "lam.toml"
        path.write_text(study_text(args.mode, args.n, args.rings, Path(tmp) / "out"))
        study = load_study(path)
        thick_path = Path(tmp) / "thick.toml"
        thick_path.write_text(study_text(args.mode, args.n, args.rings, Path(tmp) / "thick", args.thickness))
        thick = load_study(thick_path)
        r = np.arange(args.n)
        shared = sampled_inputs(study.shared, r)
        plies = [(study.ply_study(k), ply_inputs(study, k, r, shared)) for k in range(len(study.plies))]

        def laminate():
            return drape_laminate(study, r)

        def one_by_one():
            return [drape_inputs(ply, r, inputs) for ply, inputs in plies]

        def offset():
            return drape_laminate(thick, r)

        runs = {"laminate_s": laminate, "plies_one_by_one_s": one_by_one}
        if args.thickness:
            runs["offset_laminate_s"] = offset
        for run in runs.values():  # compiled and warm
            run()
        times = {label: [] for label in runs}
        for _ in range(args.repeats):
            for label, run in runs.items():
                t = time.perf_counter()
                ds = run()
                times[label].append(time.perf_counter() - t)
        ds = at_level(laminate(), 100.0)
        chunk = write_atomic(ds, Path(tmp) / "chunk.nc")
        med = {k: statistics.median(v) for k, v in times.items()}
        print(f"{args.mode} hemisphere, {len(ANGLES)} plies x {args.n} realisations, {args.rings} rings "
              f"({(2 * args.rings + 1) ** 2} nodes a ply); {load()}; medians of {args.repeats}")
        print(f"  laminate (one batch of {len(ANGLES) * args.n}):  {med['laminate_s']:.3f} s")
        print(f"  8 plies one by one (8 batches of {args.n}):  {med['plies_one_by_one_s']:.3f} s")
        print(f"  ratio laminate / one by one: {med['laminate_s'] / med['plies_one_by_one_s']:.3f}")
        if args.thickness:
            print(f"  laminate of {args.thickness:g} mm plies, each on its offset (8 batches of {args.n}): "
                  f"{med['offset_laminate_s']:.3f} s, {med['offset_laminate_s'] / med['laminate_s']:.3f} x the laminate")
        print(f"  memory per realisation (all {len(ANGLES)} plies): {ds.nbytes / args.n / 1e3:.1f} kB in memory, "
              f"{chunk.stat().st_size / args.n / 1e3:.1f} kB in a float64 chunk file")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
