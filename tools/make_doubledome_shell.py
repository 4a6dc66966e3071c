"""Write the shell mesh of studies/doubledome-laminate.toml's part for its FE handoff:

    python tools/make_doubledome_shell.py   # -> studies/meshes/doubledome-shell.inp

A quad shell mesh (Abaqus .inp, mm, S4R) of the default double dome (the study's
``[geometry] kind = "double_dome"`` with no further keys) and a 10 mm strip of its
flange: the plan rectangle |x| <= 140, |y| <= 80 around the domes' footprint (260 x 140
mm) cut into 5 mm squares whose corners are lifted onto the mould with its height field
``h(x, y)``, the mesh a user would bring from their own pre-processor for
``uqdrape export --to fe``. Elements on the steep rim (slope up to 61 deg) are stretched
up the slope, about 2:1; node 1 -> 2 runs along +x, so the elements' normals point up,
away from the tool. Run from the repository root (rewrites the file).
"""

from pathlib import Path

import numpy as np

from uqdrape.geometry import build

OUT = Path(__file__).resolve().parents[1] / "studies" / "meshes" / "doubledome-shell.inp"
HALF_X, HALF_Y, STEP = 140.0, 80.0, 5.0


def shell() -> tuple[np.ndarray, np.ndarray]:
    """Nodes (n, 3) and quads (m, 4, zero-based, counter-clockwise seen from +z)."""
    mould = build("double_dome")
    x = np.linspace(-HALF_X, HALF_X, int(round(2 * HALF_X / STEP)) + 1)
    y = np.linspace(-HALF_Y, HALF_Y, int(round(2 * HALF_Y / STEP)) + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    Z = np.asarray(mould.height(X, Y), dtype=float)
    node = np.arange(X.size).reshape(X.shape)
    quads = np.stack([node[:-1, :-1], node[1:, :-1], node[1:, 1:], node[:-1, 1:]], axis=-1).reshape(-1, 4)
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=-1), quads


def write_inp(path: Path, points: np.ndarray, quads: np.ndarray) -> None:
    lines = ["*HEADING", "uqdrape double dome shell (tools/make_doubledome_shell.py), mm", "*NODE"]
    lines += [f"{k},{p[0]:.3f},{p[1]:.3f},{p[2]:.4f}" for k, p in enumerate(points, start=1)]
    lines.append("*ELEMENT, TYPE=S4R, ELSET=PART")
    lines += [f"{k}," + ",".join(str(n + 1) for n in q) for k, q in enumerate(quads, start=1)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="ascii")


if __name__ == "__main__":
    points, quads = shell()
    write_inp(OUT, points, quads)
    print(f"wrote {OUT}: {len(quads)} quads, {len(points)} nodes, {OUT.stat().st_size / 1024:.0f} kB")
