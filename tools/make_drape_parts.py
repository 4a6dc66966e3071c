"""Write the example drape measurements of README's "your own drape measurements":

    python tools/make_drape_parts.py     # -> studies/measurements/part-1.csv .. part-4.csv

Synthetic, not measurements: four parts made by uqdrape, realisations of
studies/calibration-hemisphere.toml at zero-angle sd 3 deg and blank-holder force 150 N
(seed 7), read at 10, 20, 30 and 40 mm along one max-shear line of each sign with
0.05 deg of measurement error (``uqdrape.workflow.synthetic_parts``).
"""

from pathlib import Path

from uqdrape.workflow.calibrate import synthetic_parts

ROOT = Path(__file__).resolve().parents[1]
TRUTH = {"uncertainty.zero_angle.sd_deg": 3.0, "process.blankholder_force_N": 150.0}


def main() -> None:
    parts = synthetic_parts(ROOT / "studies" / "calibration-hemisphere.toml", TRUTH, 4,
                            [10.0, 20.0, 30.0, 40.0], seed=7, measurement_sd=0.05)
    for k, part in enumerate(parts, start=1):
        rows = "\n".join(f"{d:g},{s:.3f},{q:+.0f}" for d, s, q in zip(part.distance_mm, part.shear_deg,
                                                                       part.quadrant_sign))
        out = ROOT / "studies" / "measurements" / f"part-{k}.csv"
        out.write_text("# synthetic: tools/make_drape_parts.py\ndistance_mm,shear_deg,quadrant_sign\n" + rows + "\n",
                       encoding="utf-8")
        print(f"wrote {out}")


if __name__ == "__main__":
    main()
