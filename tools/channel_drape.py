"""Why an energy drape shears a C-channel's flat web (issue 38): sharp against rounded edges.

``python tools/channel_drape.py`` builds two C-channel tools as triangle meshes, a flat web
200 x 300 mm (z = 0) with two flanges 50 mm deep at x = +-100 mm, once with sharp 90 deg
edges and once with the edges rounded to ``RADIUS`` mm, and drapes a +-45 deg net (5 mm
spacing, 40 rings, crossover at the web's centre) over each: geodesic, and energy with the
asymmetric ``ebxhd936_like`` and the symmetric ``generic_woven`` card at 0 and 200 N
(friction 0.2, "slip"). It prints per drape the cell shear of the web (cells whose four
corners lie on z = 0 with |x| < 95 mm: mean, extremes, share beyond 5 deg) and the largest
arm turn, and writes ``results/channel-drape/`` (table.csv and shear.png: cell shear on
the flat blank, i along x, j along y, of the geodesic and the 200 N ebxhd936_like energy
drape on each tool). Meshes go to a temporary folder. A script of the checkout, like
tools/gallery.py.
"""

from __future__ import annotations

import csv
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import trimesh  # noqa: E402

from uqdrape.drape import drape  # noqa: E402
from uqdrape.geometry import MeshSurface  # noqa: E402
from uqdrape.material import load_material  # noqa: E402

OUT = Path("results") / "channel-drape"
WEB_X, WEB_Y, FLANGE, RADIUS, EDGE = 200.0, 300.0, 50.0, 10.0, 3.0
SPACING, RINGS, ORIENTATION = 5.0, 40, 45.0
CASES = [("geodesic", None, 0.0), ("energy", "ebxhd936_like", 0.0), ("energy", "ebxhd936_like", 200.0),
         ("energy", "generic_woven", 0.0), ("energy", "generic_woven", 200.0)]


def channel(radius: float) -> trimesh.Trimesh:
    """The C-channel sheet (web on top, flanges down, ends and foot open), triangulated to
    edges of at most EDGE mm; with ``radius`` > 0 (mm) its two edges are rounded, each vertex
    moved to c + radius (v - c) / |v - c|, c its nearest point of the web shrunk by radius."""
    box = trimesh.creation.box(extents=(WEB_X, WEB_Y, FLANGE))
    box.apply_translation((0.0, 0.0, -FLANGE / 2))
    v, f = trimesh.remesh.subdivide_to_size(box.vertices, box.faces, max_edge=EDGE)
    tri = v[f]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    mesh = trimesh.Trimesh(v, f[(normal[:, 2] > 0.9) | (np.abs(normal[:, 0]) > 0.9)], process=False)
    mesh.remove_unreferenced_vertices()
    if radius > 0:
        lo = np.array([-WEB_X / 2 + radius, -np.inf, -FLANGE])
        hi = np.array([WEB_X / 2 - radius, np.inf, -radius])
        c = np.clip(mesh.vertices, lo, hi)
        d = mesh.vertices - c
        length = np.linalg.norm(d, axis=1, keepdims=True)
        moved = length[:, 0] > 0
        mesh.vertices[moved] = c[moved] + radius * d[moved] / length[moved]
    return mesh


def web_cells(ds) -> np.ndarray:
    """Cells (2n, 2n) whose four corners lie on the flat web away from its edges."""
    z, x = ds.z.values[0], ds.x.values[0]
    on = (np.abs(z) < 1e-6) & (np.abs(x) < WEB_X / 2 - 5.0)
    return on[:-1, :-1] & on[1:, :-1] & on[:-1, 1:] & on[1:, 1:]


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    rows, maps = [], {}
    with tempfile.TemporaryDirectory() as folder:
        for label, radius in (("sharp", 0.0), (f"r{RADIUS:g}", RADIUS)):
            path = Path(folder) / f"channel-{label}.stl"
            channel(radius).export(path)
            mould = MeshSurface(path)
            for mode, card, force in CASES:
                ds = drape(mould, SPACING, RINGS, orientation=ORIENTATION, mode=mode,
                           material=None if card is None else load_material(card), blankholder_force=force)
                gamma = ds.cell_shear.values[0]
                web = gamma[web_cells(ds)]
                row = dict(edges=label, mode=mode, card=card or "-", force_N=force, web_cells=web.size,
                           mean_deg=round(float(web.mean()), 2), min_deg=round(float(web.min()), 2),
                           max_deg=round(float(web.max()), 2),
                           beyond_5deg=round(float((np.abs(web) > 5).mean()), 3),
                           max_turn_deg=round(float(np.abs(ds.turn.values).max()), 2))
                rows.append(row)
                print(", ".join(f"{k} {v}" for k, v in row.items()), flush=True)
                if mode == "geodesic" or (card == "ebxhd936_like" and force > 0):
                    maps[(label, mode)] = np.where(np.isfinite(gamma), gamma, np.nan)
    with open(OUT / "table.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    fig, axes = plt.subplots(2, 2, figsize=(9.5, 8.5), constrained_layout=True)
    extent = (-RINGS, RINGS, -RINGS, RINGS)
    for ax, ((label, mode), gamma) in zip(axes.ravel(), maps.items()):
        image = ax.imshow(gamma.T, origin="lower", extent=extent, cmap="RdBu_r", vmin=-25, vmax=25)
        what = "geodesic" if mode == "geodesic" else "energy, ebxhd936_like, 200 N"
        ax.set_title(f"{'sharp edges' if label == 'sharp' else f'edges rounded to {RADIUS:g} mm'}: {what}",
                     fontsize=9)
        ax.set_xlabel("i (fibre 1, +45 deg)")
        ax.set_ylabel("j (fibre 2, +135 deg)")
    fig.colorbar(image, ax=axes, shrink=0.6, label="cell shear (deg)")
    fig.suptitle(f"C-channel {WEB_X:g} x {WEB_Y:g} mm web, {FLANGE:g} mm flanges, +-45 deg net, "
                 f"{SPACING:g} mm, {RINGS} rings: shear on the flat blank (white: unplaced)", fontsize=10)
    fig.savefig(OUT / "shear.png", dpi=120)
    print(f"wrote {OUT / 'table.csv'} and {OUT / 'shear.png'}")


if __name__ == "__main__":
    main()
