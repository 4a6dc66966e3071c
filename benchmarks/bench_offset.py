"""What draping on a mould's offset surface costs against the mould itself (issue 37: a
laminate's upper plies lie on the tool offset by the plies below them).

For a hemisphere (offset in closed form: a sphere), the double dome (offset point by point)
and an icosphere mesh of the hemisphere (offset as a level set of its distance), the CPU
time of a batch of drapes on the mould and on its offset, interleaved, medians of
--repeats; the ratio is offset / mould.

Run: ``python benchmarks/bench_offset.py --offset 1.5 --repeats 5``.
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--offset", type=float, default=1.5, help="offset (mm)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)

    import trimesh

    from uqdrape.drape import drape
    from uqdrape.geometry import MeshSurface, build
    from uqdrape.material import load_material

    card = load_material("twintex3_like")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "dome.stl"
        trimesh.creation.icosphere(subdivisions=6, radius=100.0).export(path)
        cases = {"hemisphere R 100": (build("hemisphere", radius=100.0), 12),
                 "double dome": (build("double_dome"), 36),
                 "icosphere mesh R 100 (1 mm edges)": (MeshSurface(path), 12)}
        print(f"offset {args.offset:g} mm; {load()}; CPU seconds, medians of {args.repeats}")
        for name, (mould, rings) in cases.items():
            for mode in ("geodesic", "energy"):
                kw = (dict(mode="energy", material=card, blankholder_force=np.full(4, 100.0)) if mode == "energy"
                      else dict(blankholder_force=np.zeros(16)))
                surfaces = {"mould": mould, "offset": mould.offset(args.offset)}
                for s in surfaces.values():  # compiled and warm
                    drape(s, 5.0, rings, **kw)
                times = {k: [] for k in surfaces}
                for _ in range(args.repeats):
                    for k, s in surfaces.items():
                        t = time.process_time()
                        drape(s, 5.0, rings, **kw)
                        times[k].append(time.process_time() - t)
                med = {k: statistics.median(v) for k, v in times.items()}
                print(f"  {name}, {mode} ({len(kw['blankholder_force'])} drapes, {rings} rings): "
                      f"mould {med['mould']:.3f} s, offset {med['offset']:.3f} s, ratio {med['offset'] / med['mould']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
