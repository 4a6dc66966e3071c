"""Write the example FE mesh and ply edge of README's "Results where engineers use them":

    python tools/make_part_mesh.py        # -> studies/meshes/nosecone-part.inp, nosecone-ply-edge.csv

A quad shell mesh (Abaqus .inp, mm) of the default nose cone's surface out to a plan
radius of 120 mm: 4 mm plan squares whose corners are lifted onto the mould, the mesh a
user would bring from their own pre-processor for `uqdrape export --to fe`. The ply edge
is a trim curve for `uqdrape export --to cut --trim`: a plan circle of 80 mm radius (720
vertices, x_mm,y_mm), inside what the 30-ring, 5 mm net of studies/nosecone-zero-angle.toml
covers (about 86 mm along the fibre axes; the base circle, 225 mm, is far beyond it).
"""

from pathlib import Path

import meshio
import numpy as np

from uqdrape.geometry import build

OUT = Path(__file__).resolve().parents[1] / "studies" / "meshes" / "nosecone-part.inp"
EDGE = OUT.with_name("nosecone-ply-edge.csv")
EDGE_RADIUS, EDGE_VERTICES = 80.0, 720


def main() -> None:
    mould = build("nose_cone")
    x = np.arange(-120.0, 120.0 + 1e-9, 4.0)
    X, Y = np.meshgrid(x, x, indexing="ij")
    Z = np.asarray(mould.height(X, Y), dtype=float)
    n = x.size
    index = np.arange(n * n).reshape(n, n)
    inside = np.hypot(X, Y) <= 120.0
    quads = np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], axis=-1).reshape(-1, 4)
    keep = inside.ravel()[quads].all(axis=1)
    quads = quads[keep]
    used = np.unique(quads)
    renumber = np.full(n * n, -1)
    renumber[used] = np.arange(used.size)
    points = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=-1)[used]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    meshio.write(OUT, meshio.Mesh(points, [("quad", renumber[quads])]), file_format="abaqus")
    print(f"wrote {OUT}: {len(quads)} quads, {len(points)} nodes")
    t = 2 * np.pi * np.arange(EDGE_VERTICES) / EDGE_VERTICES
    np.savetxt(EDGE, EDGE_RADIUS * np.column_stack([np.cos(t), np.sin(t)]), delimiter=",", header="x_mm,y_mm",
               comments="", fmt="%.12g")
    print(f"wrote {EDGE}: a plan circle of {EDGE_RADIUS:g} mm radius")


if __name__ == "__main__":
    main()
