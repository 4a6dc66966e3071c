"""Write the example fibre-angle measurements of README's "your own measurements":

    python tools/make_fibre_angles.py     # -> studies/measurements/fibre-angles.csv

Synthetic, not measurements: 38 points of a flat sample like the thesis's Table 5.1
(FGE 106hd), an exponentially correlated angle field of
mean 42.7 deg (gamma0 = -2.3 deg) and sd 5.6 deg, lengths 20 and 10 mm along fibre 1
and 2, read with 0.5 deg of measurement error, at 38 of the nodes of a 5 mm lattice.
"""

from pathlib import Path

import numpy as np

from uqdrape.calibration.synthetic import synthetic_set

OUT = Path(__file__).resolve().parents[1] / "studies" / "measurements" / "fibre-angles.csv"


def main() -> None:
    rng = np.random.default_rng(5101)
    a, b, gamma0 = synthetic_set(rng, "exponential", sd_deg=5.6, length_mm=(20.0, 10.0), nugget_deg=0.5,
                                 mean_deg=-2.3, lattice=(12, 12), points=38)
    # fibre set 1 nominally at 45 deg (the default --fibre1-deg), turned by gamma0 (uqdrape.calibration.mapping)
    rows = "\n".join(f"{x:.1f},{y:.1f},{45.0 + g:.2f},1,0.5" for x, y, g in zip(a, b, gamma0))
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(f"x_mm,y_mm,angle_deg,fibre_set,sd_deg\n{rows}\n", encoding="utf-8")
    (OUT.parent / "README.md").write_text(
        "`fibre-angles.csv` is synthetic, not a measurement: written by `tools/make_fibre_angles.py` "
        "(38 points like the thesis's Table 5.1) for README's calibration example.\n", encoding="utf-8")
    print(f"wrote {OUT}: {len(a)} points")


if __name__ == "__main__":
    main()
