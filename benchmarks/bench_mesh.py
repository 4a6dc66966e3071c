"""Mesh moulds: build time, memory and accuracy of the compiled closest-point query (cell grid
and hierarchy) for about 1e4, 1e5 and 1e6 triangles, and drape time on a meshed against the analytic
hemisphere (issue 23).

``python benchmarks/bench_mesh.py [--sizes 1e4 1e5 1e6]`` writes a closed tool (a
triangulated torus, the same shape at every size) as a binary STL per size and prints per size: faces, the time to read the file, to check and pack it (hierarchy included),
the packed array's size, the compiled signed-distance query time per point, and the
accuracy: |phi| at points sampled on the faces (should be round-off) and the largest
difference of |phi| from a brute-force distance at 200 points off the surface (trimesh's
point-triangle closest points over every face whose box lies within |phi| of the point:
the same distance computed another way).

``python benchmarks/bench_mesh.py --drape [--repeats 7]`` times geodesic and energy drapes
on four meshes of the hemisphere against the analytic one (``drapes``).
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from uqdrape.geometry import MeshSurface
from uqdrape.geometry import mesh as meshmod


def _torus(faces: float) -> trimesh.Trimesh:
    """A torus (R = 200, r = 60 mm) of about ``faces`` triangles."""
    sections = max(int(round(np.sqrt(faces / 2 / 3))), 4)
    return trimesh.creation.torus(200.0, 60.0, major_sections=3 * sections, minor_sections=sections)


def _brute_distance(tri, point, bound):
    """Distance (mm) of ``point`` from the triangles (n, 3, 3), searching the faces whose
    bounding box lies within ``bound`` (an upper bound of the distance) of it."""
    gap = np.maximum(np.maximum(tri.min(1) - point, point - tri.max(1)), 0.0)
    near = np.flatnonzero((gap**2).sum(1) <= bound**2 * (1 + 1e-9) + 1e-18)
    closest = trimesh.triangles.closest_point(tri[near], np.broadcast_to(point, (near.size, 3)))
    return np.linalg.norm(closest - point, axis=1).min()


def _icosphere_cap(radius: float, subdivisions: int) -> trimesh.Trimesh:
    """The faces of an icosphere of ``radius`` whose corners all lie at z >= 0: a mesh of the
    hemisphere with near-equal edges along the surface (as a CAD export by chord length
    gives), an open sheet whose edge zig-zags within one edge of the equator."""
    ball = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    cap = trimesh.Trimesh(ball.vertices, ball.faces[(ball.vertices[ball.faces][..., 2] >= 0).all(1)], process=False)
    cap.remove_unreferenced_vertices()
    return cap


def _query_costs(surfaces, nodes, repeats):
    """CPU time per query (us) of ``compiled.gap`` at the analytic net's nodes (5 mm apart,
    so a mesh's memo never answers: a search, of the cell grid near the mesh) and at each node followed by the same node moved
    1e-6 mm (the memo answers the second: its cost is the difference), medians of
    ``repeats``."""
    from uqdrape.geometry import compiled

    nodes = nodes[np.isfinite(nodes).all(1)]
    pairs = np.repeat(nodes, 2, axis=0)
    pairs[1::2] += 1e-6
    for name, surface in surfaces.items():
        cost = []
        for points in (nodes, pairs):
            compiled.evaluate_gap(surface.kernel, *points[:10].T)  # compile outside the timing
            runs = []
            for _ in range(repeats):
                t = time.process_time()
                compiled.evaluate_gap(surface.kernel, *points.T)
                runs.append(time.process_time() - t)
            cost.append(np.median(runs))
        memo = f", memo answer {(cost[1] - cost[0]) / len(nodes) * 1e6:.3f} us" if name != "analytic" else ""
        print(f"query {name}: {cost[0] / len(nodes) * 1e6:.3f} us{memo}")


def drapes(repeats):
    """Drape time on four meshes of Hemisphere(100) against the closed form, the same nets,
    interleaved ``repeats`` times in one run (CPU time of one thread; medians): its height
    field exported on a 1 mm plan grid (whose facets near the vertical rim are up to 14 mm
    long down the slope) and an icosphere's cap at three refinements, edges 3.6, 1.8 and
    0.9 mm (the nets' nodes all lie on the dome, at plan radii below 99.7 mm, so the ground
    plane the cap lacks is never reached): the mesh's size sets how often a node's first
    search misses the cache."""
    from uqdrape.drape import drape
    from uqdrape.geometry import Hemisphere, export_stl
    from uqdrape.material import load_material

    analytic = Hemisphere(100.0)
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        meshes = {"plan grid 1 mm": MeshSurface(export_stl(analytic, folder / "grid.stl", half_width=150.0,
                                                             resolution_mm=1.0))}
        for subdivisions in (5, 6, 7):  # caps of about 10,000, 41,000 and 164,000 faces
            cap = _icosphere_cap(100.0, subdivisions)
            cap.export(folder / f"cap{subdivisions}.stl")
            edge = np.median(cap.edges_unique_length)
            meshes[f"icosphere cap, edges {edge:.2f} mm"] = MeshSurface(folder / f"cap{subdivisions}.stl")
    surfaces = {"analytic": analytic, **meshes}
    rng = np.random.default_rng(4)
    cases = {
        "geodesic 64 x 18 rings": dict(spacing=5.0, rings=18, orientation=rng.uniform(-20, 20, 64),
                                       crossover=rng.uniform(-5, 5, (64, 2))),
        "energy 4 x 18 rings": dict(spacing=5.0, rings=18, mode="energy", material=load_material("ebxhd936_like"),
                                    blankholder_force=[0.0, 126.0, 252.0, 378.0], friction=0.2),
    }
    for label, kw in cases.items():
        spacing, rings = kw.pop("spacing"), kw.pop("rings")
        if label.startswith("geodesic"):
            ds = drape(analytic, spacing, rings, threads=1, **kw)
            _query_costs(surfaces, np.stack([ds.x.values, ds.y.values, ds.z.values], -1).reshape(-1, 3), repeats)
        times = {name: [] for name in surfaces}
        out = {}
        for surface in surfaces.values():
            drape(surface, spacing, 3, threads=1, **kw)  # compile (and load) every kernel the timed call uses
        for _ in range(repeats):
            for name, surface in surfaces.items():
                t = time.process_time()  # CPU time of one thread: less swayed by a loaded machine than wall time
                out[name] = drape(surface, spacing, rings, threads=1, **kw)
                times[name].append(time.process_time() - t)
        base = np.median(times["analytic"])
        nets = {name: np.stack([ds.x.values, ds.y.values, ds.z.values], -1) for name, ds in out.items()}
        print(f"{label}: analytic {base:.3f} s, iterations {int(out['analytic'].iterations.sum())}")
        for name, surface in meshes.items():
            ratios = np.array(times[name]) / np.array(times["analytic"])
            gap = np.nanmax(np.linalg.norm(nets[name] - nets["analytic"], axis=-1))
            print(f"  {name} ({surface.faces_count:,} faces): {np.median(times[name]):.3f} s  ratio of medians "
                  f"{np.median(times[name]) / base:.2f} (per repeat {ratios.min():.2f}-{ratios.max():.2f})  "
                  f"iterations {int(out[name].iterations.sum())}  max node gap {gap:.3f} mm")


def main(sizes):
    rng = np.random.default_rng(1)
    with tempfile.TemporaryDirectory() as folder:
        for n in sizes:
            mesh = _torus(n)
            path = Path(folder) / "tool.stl"
            mesh.export(path)
            t0 = time.perf_counter()
            vertices, faces = meshmod._read(path)
            t1 = time.perf_counter()
            surface = MeshSurface(path)
            t2 = time.perf_counter()
            pack_s = (t2 - t1) - (t1 - t0)  # MeshSurface reads again: its time minus one read
            read = trimesh.Trimesh(vertices, faces, process=False)  # float32 coordinates, as in the file
            on, _ = trimesh.sample.sample_surface(read, 20_000, seed=2)
            surface.gap(on[:10, 0], on[:10, 1], on[:10, 2])  # compile outside the timing
            t3 = time.perf_counter()
            phi_on = surface.gap(on[:, 0], on[:, 1], on[:, 2])[0]
            query_us = (time.perf_counter() - t3) / on.shape[0] * 1e6
            off = on[:200] + rng.normal(0.0, 5.0, (200, 3))
            phi = surface.gap(off[:, 0], off[:, 1], off[:, 2])[0]
            tri = vertices[faces]
            ref = np.array([_brute_distance(tri, p, abs(f)) for p, f in zip(off, phi)])
            print(f"faces {faces.shape[0]:>9,}  read {t1 - t0:6.2f} s  check+pack {pack_s:6.2f} s  "
                  f"array {surface.kernel[1].nbytes / 2**20:7.1f} MiB  query {query_us:5.2f} us/point  "
                  f"max|phi| on faces {np.abs(phi_on).max():.1e} mm  max||phi| - brute| {np.abs(np.abs(phi) - ref).max():.1e} mm")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1e4, 1e5, 1e6])
    parser.add_argument("--drape", action="store_true", help="time drapes on a meshed vs the analytic hemisphere")
    parser.add_argument("--repeats", type=int, default=7, help="interleaved repeats of the drape timings")
    args = parser.parse_args()
    drapes(args.repeats) if args.drape else main(args.sizes)
