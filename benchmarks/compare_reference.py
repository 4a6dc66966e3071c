"""Equality check of the drape solver against saved reference outputs (issue 12).

``python benchmarks/compare_reference.py save DIR`` drapes a fixed set of cases and writes
one .npz per case into DIR; ``python benchmarks/compare_reference.py compare DIR`` drapes
them again and prints, per case, the largest node difference (mm), the largest node-shear
difference (deg), the largest turn-angle difference (deg) and whether the converged flags
and node statuses are equal. Cases: geodesic hemisphere / nose cone / double dome / mesh (the shipped STL)
(random orientation, crossover, segment lengths), energy nose-cone drapes (ebxhd936_like,
20 rings, random gamma0 sd 5 deg) at 0 / 126 / 378 N under both blank-holder models, and energy hemisphere and double-dome
drapes (15 rings) at the same three forces.
"""

import sys
from pathlib import Path

import numpy as np

from uqdrape.drape import drape
from uqdrape.geometry import MeshSurface, build
from uqdrape.material import load_material

STL = Path(__file__).resolve().parent.parent / "tests" / "data" / "hemisphere_r50.stl"


def _geodesic(surface, rings, R, seed):
    rng = np.random.default_rng(seed)
    n = rings
    return drape(surface, 5.0, rings, orientation=rng.uniform(-20, 20, R), crossover=rng.uniform(-5, 5, (R, 2)),
                 seg_i=5.0 * (1 + 0.01 * rng.standard_normal((R, 2 * n, 2 * n + 1))),
                 seg_j=5.0 * (1 + 0.01 * rng.standard_normal((R, 2 * n + 1, 2 * n))))


def _energy(model, R=6, rings=20, seed=5, surface=None):
    rng = np.random.default_rng(seed)
    force = np.repeat([0.0, 126.0, 378.0], R // 3)
    return drape(surface or build("nose_cone"), 5.0, rings, mode="energy", material=load_material("ebxhd936_like"),
                 gamma0=rng.normal(0.0, 5.0, (R, 2 * rings, 2 * rings)), blankholder_force=force,
                 friction=0.2, blankholder_model=model)


CASES = {
    "geodesic_hemisphere": lambda: _geodesic(build("hemisphere", radius=100.0), 20, 16, 1),
    "geodesic_nose_cone": lambda: _geodesic(build("nose_cone"), 30, 8, 2),
    "geodesic_double_dome": lambda: _geodesic(build("double_dome"), 20, 8, 3),
    "geodesic_mesh": lambda: _geodesic(MeshSurface(STL), 10, 8, 4),
    "energy_nose_cone_slip": lambda: _energy("slip"),
    "energy_nose_cone_radial": lambda: _energy("radial"),
    "energy_hemisphere": lambda: _energy("slip", 3, 15, 6, build("hemisphere", radius=100.0)),
    "energy_double_dome": lambda: _energy("slip", 3, 15, 7, build("double_dome")),
}


def _arrays(ds):
    return dict(P=np.stack([ds.x.values, ds.y.values, ds.z.values], -1), shear=ds.shear.values,
                status=ds.status.values, turn=ds.turn.values, converged=ds.converged.values)


def main(action, folder):
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, case in CASES.items():
        new = _arrays(case())
        if action == "save":
            np.savez(folder / f"{name}.npz", **new)
            continue
        if not (folder / f"{name}.npz").is_file():
            print(f"{name:26s} no reference saved")
            continue
        ref = np.load(folder / f"{name}.npz")
        both = np.isfinite(ref["P"]) & np.isfinite(new["P"])
        dP = float(np.abs(ref["P"] - new["P"])[both].max())
        sh = np.isfinite(ref["shear"]) & np.isfinite(new["shear"])
        dS = float(np.abs(ref["shear"] - new["shear"])[sh].max())
        dT = float(np.abs(ref["turn"] - new["turn"]).max())
        print(f"{name:26s} max|dnode| {dP:.2e} mm  max|dshear| {dS:.2e} deg  max|dturn| {dT:.2e} deg  "
              f"status equal {np.array_equal(ref['status'], new['status'])}  "
              f"converged equal {np.array_equal(ref['converged'], new['converged'])} "
              f"({int(new['converged'].sum())}/{new['converged'].size})")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
