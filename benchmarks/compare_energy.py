"""Energy drapes against a reference commit's (issue 41): how far a change of the minimiser
moves them.

``python benchmarks/compare_energy.py save DIR`` drapes the cases with this checkout and
writes one netCDF per case into DIR (run it in the reference's checkout);
``python benchmarks/compare_energy.py compare DIR`` drapes them again and prints, per case,
the largest node distance (mm), node-shear and turn differences (deg), the relative
difference of each drape's total energy (new - reference), how many drapes differ at all,
the converged fractions and the mean minimiser iterations per drape of both.

Cases (EBXhd-936-like, 5 mm, one thread): the nose cone, 30 rings, mu 0.2, at 0, 126 and
378 N without a zero-angle field; the hemisphere (R 100 mm), 20 rings, 200 N, mu 0.3; and
stochastic batches of the nose cone at 126 N (128 drapes) and 0 / 378 N (32 each), each
drape with its own iid zero-energy-angle field (sd 5 deg).
"""

import sys
from pathlib import Path

import numpy as np
import xarray as xr

from uqdrape.drape import drape
from uqdrape.geometry import Hemisphere, build
from uqdrape.material import load_material


def _cases():
    material, nose = load_material("ebxhd936_like"), build("nose_cone")
    common = dict(mode="energy", material=material, threads=1)
    cases = {f"nose_{f:.0f}N": (nose, 30, dict(blankholder_force=f, friction=0.2)) for f in (0.0, 126.0, 378.0)}
    cases["hemisphere_200N"] = (Hemisphere(100.0), 20, dict(blankholder_force=200.0, friction=0.3))
    for f, R, seed in ((126.0, 128, 7), (0.0, 32, 8), (378.0, 32, 9)):
        gamma0 = np.random.default_rng(seed).normal(0.0, 5.0, (R, 60, 60))
        cases[f"nose_{f:.0f}N_gamma0x{R}"] = (nose, 30, dict(blankholder_force=f, friction=0.2, gamma0=gamma0))
    return {name: (mould, rings, dict(common, **kw)) for name, (mould, rings, kw) in cases.items()}


def _compare(ref, new):
    nodes = lambda ds: np.stack([ds.x.values, ds.y.values, ds.z.values], -1)  # noqa: E731
    dnode = np.nanmax(np.linalg.norm(nodes(new) - nodes(ref), axis=-1), axis=(1, 2))
    dshear = np.nanmax(np.abs(new.shear.values - ref.shear.values))
    dturn = np.abs(new.turn.values - ref.turn.values).max()
    rel = (new.energy_total.values - ref.energy_total.values) / np.abs(ref.energy_total.values)
    moved = int(((dnode > 0) | (new.status.values != ref.status.values).any(axis=(1, 2))).sum())
    return (f"drapes moved {moved}/{dnode.size}  max|dnode| {dnode.max():.2e} mm  max|dshear| {dshear:.2e} deg  "
            f"max|dturn| {dturn:.2e} deg  dE_total/E {rel.min():+.1e} .. {rel.max():+.1e} (mean {rel.mean():+.1e})  "
            f"converged {float(ref.converged.mean()):.3f} -> {float(new.converged.mean()):.3f}  "
            f"iterations {float(ref.iterations.mean()):.1f} -> {float(new.iterations.mean()):.1f}")


def main(action, folder):
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, (mould, rings, kwargs) in _cases().items():
        ds = drape(mould, 5.0, rings, **kwargs)
        if action == "save":
            ds.to_netcdf(folder / f"{name}.nc")
        else:
            print(f"{name:22s} {_compare(xr.load_dataset(folder / f'{name}.nc'), ds)}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("save", "compare"):
        sys.exit("usage: python benchmarks/compare_energy.py save|compare DIR")
    main(sys.argv[1], sys.argv[2])
