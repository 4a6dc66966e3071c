"""Write the example picture-frame test files of README's "Your own material" (synthetic):

    python tools/make_sheartests.py            # -> studies/sheartests/

Three specimens of a picture-frame rig (side 145 mm, square start) whose fabric has
N_s(θ) = s (1.2 θ + 600 (θ/60°)^4) N/m (θ in degrees; 672 N/m at 60°, the scale of the
thesis's EBXhd-936 picture-frame axes), specimen factors s = 0.92, 1.00, 1.08, forced
through the rig's exact balance F = 2 L cos(φ0 − θ/2) N_s, with a 2 N friction jump and
load-cell noise of sd 0.5 N. They stand in for a user's own tests; they are not
measurements.
"""

from pathlib import Path

import numpy as np

from uqdrape.material.sheartest.picture_frame import PictureFrame

OUT = Path(__file__).resolve().parents[1] / "studies" / "sheartests"
RIG = '''# Example picture-frame rig of README's "Your own material": synthetic specimens written by
# tools/make_sheartests.py (not measurements). uqdrape materials fit studies/sheartests/pf-rig.toml
name = "synthetic_pf"
description = "synthetic picture-frame tests (tools/make_sheartests.py), 3 specimens"
test = "picture_frame"
phi0_deg = 45.0
side_mm = 145.0

[fit]
friction = "subtract"
'''


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    rig, rng = PictureFrame(145.0, 45.0), np.random.default_rng(2007)
    theta = np.linspace(0.0, np.deg2rad(62.0), 400)
    deg = np.rad2deg(theta)
    text = RIG
    for k, scale in enumerate((0.92, 1.00, 1.08), start=1):
        force = rig.crosshead_force(lambda t: scale * (1.2 * np.rad2deg(t) + 600.0 * (np.rad2deg(t) / 60.0) ** 4),
                                    theta)
        force = force + 2.0 * (1.0 - np.exp(-deg / 0.2)) + rng.normal(0.0, 0.5, theta.size)
        rows = "\n".join(f"{f:.4f},{d:.5f}" for f, d in zip(force, rig.displacement(theta)))
        (OUT / f"pf{k}.csv").write_text(f"# synthetic picture-frame specimen {k} (s = {scale})\n"
                                        f"force_n,displacement_mm\n{rows}\n", encoding="utf-8")
        text += f'\n[[specimen]]\nfile = "pf{k}.csv"\nbranch = "positive"\n'
    (OUT / "pf-rig.toml").write_text(text, encoding="utf-8")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
