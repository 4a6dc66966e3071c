"""Write the C-spar tool of studies/cspar-misalignment.toml as a binary STL (mm).

The spar runs along x (400 mm); its outer surface is a web z = 0 across |y| <= 40, two
fillets of radius 10 mm and two flanges y = +-50 falling to z = -60: plane + cylinder +
plane, a developable no height field z = h(x, y) can hold (the flanges are vertical). An
open sheet, facing outward; 5 mm steps along x, web and flanges, 12 facets per fillet.
Run from the repository root: ``python tools/make_cspar.py`` (rewrites studies/meshes/cspar.stl).
"""

from pathlib import Path

import numpy as np
import trimesh

LENGTH, HALF_WEB, FILLET, DEPTH = 400.0, 50.0, 10.0, 60.0


def profile() -> np.ndarray:
    """The cross-section (y, z) from the -y flange's foot to the +y flange's foot."""
    inner = HALF_WEB - FILLET
    flange = np.linspace(-DEPTH, -FILLET, 11)  # 5 mm steps
    arc = np.linspace(np.pi, np.pi / 2, 13)[1:]  # the -y fillet, centre (-inner, -FILLET)
    web = np.linspace(-inner, inner, 17)[1:-1]
    left = np.concatenate([np.stack([np.full(11, -HALF_WEB), flange], 1),
                           np.stack([-inner + FILLET * np.cos(arc), -FILLET + FILLET * np.sin(arc)], 1)])
    right = left[::-1] * [-1.0, 1.0]
    return np.concatenate([left, np.stack([web, np.zeros_like(web)], 1), right])


def cspar() -> trimesh.Trimesh:
    yz = profile()
    xs = np.linspace(-LENGTH / 2, LENGTH / 2, int(LENGTH / 5) + 1)
    X = np.repeat(xs, len(yz))
    v = np.column_stack([X, np.tile(yz[:, 0], len(xs)), np.tile(yz[:, 1], len(xs))])
    node = np.arange(v.shape[0]).reshape(len(xs), len(yz))
    a, b, c, d = node[:-1, :-1].ravel(), node[1:, :-1].ravel(), node[1:, 1:].ravel(), node[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return trimesh.Trimesh(v, faces, process=False)


if __name__ == "__main__":
    out = Path(__file__).resolve().parent.parent / "studies" / "meshes" / "cspar.stl"
    cspar().export(out)
    print(out)
