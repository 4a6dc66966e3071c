"""Write the pan tool of studies/pan-corner-lock.toml as a binary STL (mm).

A male pan, 120 x 80 mm on top, 40 mm deep, vertical walls (no draft), every edge and
corner rounded with a radius of 8 mm: the top face z = 0, the walls falling to z = -40,
open at the foot. Made by rounding a box: each vertex v of a finely triangulated box
(about 3 mm edges) goes to c + r (v - c) / |v - c|, c the nearest point of the box shrunk
by r, which keeps faces and walls and turns every edge into a cylinder and every corner
into a sphere octant (the corners are what a net cannot cover without shear). Run from
the repository root: ``python tools/make_pan.py`` (rewrites studies/meshes/pan.stl).
"""

from pathlib import Path

import numpy as np
import trimesh

TOP_X, TOP_Y, DEPTH, RADIUS = 120.0, 80.0, 40.0, 8.0


def pan(max_edge: float = 3.0) -> trimesh.Trimesh:
    """The pan of the module doc, its box triangulated to edges of at most ``max_edge`` mm."""
    box = trimesh.creation.box(extents=(TOP_X, TOP_Y, DEPTH))
    box.apply_translation((0.0, 0.0, -DEPTH / 2))
    vertices, faces = trimesh.remesh.subdivide_to_size(box.vertices, box.faces, max_edge=max_edge)
    keep = ~(vertices[faces][:, :, 2] <= -DEPTH + 1e-9).all(1)  # the foot stays open
    lo = np.array([-TOP_X / 2 + RADIUS, -TOP_Y / 2 + RADIUS, -DEPTH])
    hi = np.array([TOP_X / 2 - RADIUS, TOP_Y / 2 - RADIUS, -RADIUS])
    c = np.clip(vertices, lo, hi)
    d = vertices - c
    with np.errstate(invalid="ignore"):  # the foot's own vertices (d = 0) go with its faces
        rounded = c + RADIUS * d / np.linalg.norm(d, axis=1, keepdims=True)
    mesh = trimesh.Trimesh(rounded, faces[keep], process=False)
    mesh.remove_unreferenced_vertices()
    return mesh


if __name__ == "__main__":
    out = Path(__file__).resolve().parent.parent / "studies" / "meshes" / "pan.stl"
    pan().export(out)
    print(out)
