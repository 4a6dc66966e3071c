"""Probe for issue 23 (measured once, not shipped): would a walk over face neighbours from a
face already in cache, proved by a per-face clearance over its 1-ring, answer a geodesic
net's mesh queries faster than the cell grid?

Replays the analytic geodesic nets' nodes (``bench_mesh.py --drape``'s 64 nets x 18 rings on
Hemisphere(100)) in the net's fill order, three queries a node as a node solve makes them
(the circle's t = 0 point, the node moved 1e-3 mm along its radius, the node), on the bench's
two meshes, one memo per run, and times per node (CPU time, medians of interleaved repeats):

A  ``meshquery.closest`` as shipped (memo, cell grid, hierarchy)
B  memo, then a walk from the last answer's face, A's search where the proof fails
C  memo, then a walk from the parent node's face (its fibre-1 neighbour's answer: the best
   hint a node kernel could pass), A's search where the proof fails
R  as C, every walk starting at A's answer (an oracle: the 1-ring proof alone, the floor of
   any walk)
D  A, with the cells of the next anti-diagonal's nodes (hash slot, list, corners) loaded
   before it is filled, so that their cache misses overlap
T  D's loading alone
G1, G2  the cell grid's search of each node's three points, once and twice in a row (the
   second pass: the same search with its data and branches warm)

The walk: greedy descent over the edge neighbours (NB) on the squared distance, then the
faces sharing a corner with the face reached (the 1-ring, lists built here in numpy); the
answer is proven when the reached face's clearance (the distance from it to every face
outside its 1-ring) exceeds its distance plus the ring's best distance. The clearance here is
a stand-in of 0.5 median edge (a real one is about 0.87 edge on these meshes): timing only,
and every walked answer is checked equal to A's. ``python benchmarks/probe_mesh_walk.py``.
"""

import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

from uqdrape.geometry import meshquery as mq

sys.path.insert(0, str(Path(__file__).resolve().parent))


def ring_lists(f):
    """The faces sharing a corner with each face (itself included) of faces ``f`` (nf, 3):
    (row pointers (nf + 1,), faces)."""
    nf = len(f)
    face_of = np.repeat(np.arange(nf), 3)
    vert = f.ravel()
    order = np.argsort(vert, kind="stable")
    vs, fs = vert[order], face_of[order]
    start = np.searchsorted(vs, np.arange(f.max() + 2))
    pairs = []
    for k in range(3):
        v = f[:, k]
        cnt = start[v + 1] - start[v]
        rows = np.repeat(np.arange(nf), cnt)
        idx = np.repeat(start[v] - np.r_[0, np.cumsum(cnt)[:-1]], cnt) + np.arange(cnt.sum())
        pairs.append(np.stack([rows, fs[idx]], 1))
    pr = np.unique(np.concatenate(pairs), axis=0)
    return np.searchsorted(pr[:, 0], np.arange(nf + 1)), pr[:, 1].copy()


@njit
def walk(p, ptr, ring, clear, q, start):
    """(face, squared distance, proven squared bound of every other face, steps) from face
    ``start`` towards q, face -1 where the clearance cannot prove the answer."""
    nbo = int(p[mq.OFF_NB])
    f = start
    pt, w, region, d2 = mq._distance2(p, f, q)
    steps = 0
    for _ in range(64):
        if region == 0:
            break
        c1, c2 = (region - 4, region - 4) if region >= 4 else (region - 1, (region + 1) % 3)
        moved = False
        for g in (int(p[nbo + 3 * f + c1]), int(p[nbo + 3 * f + c2])):
            if g >= 0:
                pt2, w2, r2, e2 = mq._distance2(p, g, q)
                if e2 < d2:
                    f, region, d2, moved = g, r2, e2, True
        if not moved:
            break
        steps += 1
    df = np.sqrt(d2)
    best, best_f, second = d2, f, np.inf
    r = df + 1e-12 * p[mq.SCALE]
    limit = r * r
    for e in range(ptr[f], ptr[f + 1]):
        g = ring[e]
        if g == f:
            continue
        a, b, c = mq._face(p, g)
        lb = 0.0
        for k in range(3):
            dd = max(min(a[k], b[k], c[k]) - q[k], 0.0, q[k] - max(a[k], b[k], c[k]))
            lb += dd * dd
        if lb > limit:
            second = min(second, lb)
            continue
        pt2, w2, r2 = mq._closest_on_triangle(q, a, b, c)
        dv = mq._sub(q, pt2)
        e2 = mq._dot(dv, dv)
        if e2 < best or (e2 == best and g < best_f):
            second, best, best_f = min(second, best), e2, g
        else:
            second = min(second, e2)
    outside = clear[f] - df
    if not np.sqrt(best) + 1e-12 * p[mq.SCALE] < outside:
        return -1, best, 0.0, steps
    return best_f, best, min(second, outside * outside), steps


@njit
def run_a(p, pts, out):
    memo = mq.new_memo()
    for m in range(pts.shape[0]):
        out[m] = mq.closest(p, pts[m, 0], pts[m, 1], pts[m, 2], memo)[0]


@njit
def _walked(p, ptr, ring, clear, q, start, memo, count):
    """The memo's answer, else the walk's, else A's search; count: walked, fell back, steps."""
    slot = mq._slot(p, q)
    dx, dy, dz = q[0] - memo[slot], q[1] - memo[slot + 1], q[2] - memo[slot + 2]
    if dx * dx + dy * dy + dz * dz < memo[slot + 3] * memo[slot + 3]:
        return int(memo[slot + 4])
    f, d2, second, steps = walk(p, ptr, ring, clear, q, start)
    count[2] += steps
    if f >= 0:
        count[0] += 1
        mq._keep(memo, slot, q, f, d2, second, p[mq.REACH], 1e-12 * p[mq.SCALE])
        return f
    count[1] += 1
    return mq.closest(p, q[0], q[1], q[2], memo)[0]


@njit
def run_walk(p, ptr, ring, clear, pts, parent, oracle, out, count):
    """B (parent and oracle empty: start at the last answer), C (a node's first query starts
    at its parent node's last answer) or R (every walk starts at A's answer, ``oracle``)."""
    memo = mq.new_memo()
    last = 0
    for m in range(pts.shape[0]):
        start = oracle[m] if oracle.size else last
        if parent.size and m % 3 == 0 and parent[m // 3] >= 0:
            start = out[3 * parent[m // 3] + 2]
        last = out[m] = _walked(p, ptr, ring, clear, (pts[m, 0], pts[m, 1], pts[m, 2]), start, memo, count)


@njit
def _load_cell(p, q):
    """Loads q's cell: its hash slots, list and listed faces' corners (their sum)."""
    g = p[mq.GRID_CELL]
    ux, uy, uz = (q[0] - p[mq.GRID_X0]) / g, (q[1] - p[mq.GRID_Y0]) / g, (q[2] - p[mq.GRID_Z0]) / g
    if not (0.0 <= ux < mq.GRID_AXIS and 0.0 <= uy < mq.GRID_AXIS and 0.0 <= uz < mq.GRID_AXIS):
        return 0.0
    ix, iy, iz = int(ux), int(uy), int(uz)
    key = float(ix + mq.GRID_AXIS * (iy + mq.GRID_AXIS * iz))
    table = int(p[mq.OFF_HASH])
    s = mq._cell_hash(ix, iy, iz, int(p[mq.GRID_SLOTS]))
    while p[table + 3 * s] != key:
        if p[table + 3 * s] < 0.0:
            return 0.0
        s += 1
    lists, tri = int(p[mq.OFF_LIST]), int(p[mq.OFF_TRI])
    t = 0.0
    for e in range(int(p[table + 3 * s + 1]), int(p[table + 3 * s + 2])):
        o = tri + 9 * int(p[lists + e])
        t += p[o] + p[o + 8]
    return t


@njit
def run_d(p, pts, batch, out, query):
    """D (query True) or T (False): batch[b] .. batch[b + 1] the nodes of one arm ring or
    anti-diagonal, whose first points' cells are loaded before its queries."""
    memo = mq.new_memo()
    t = 0.0
    for b in range(batch.size - 1):
        for node in range(batch[b], batch[b + 1]):
            t += _load_cell(p, (pts[3 * node, 0], pts[3 * node, 1], pts[3 * node, 2]))
        if query:
            for m in range(3 * batch[b], 3 * batch[b + 1]):
                out[m] = mq.closest(p, pts[m, 0], pts[m, 1], pts[m, 2], memo)[0]
    return t


@njit
def run_g(p, pts, passes, out):
    for node in range(pts.shape[0] // 3):
        for _ in range(passes):
            for m in range(3 * node, 3 * node + 3):
                out[m] = mq._grid_search(p, (pts[m, 0], pts[m, 1], pts[m, 2]))[0]


def fill_order(n):
    """(i, j) of every node in geodesic fill order, its parent (the fibre-1 neighbour it grows
    from, for arms the previous arm node), the diagonal parent and batch boundaries."""
    order, parent, diag, batch = [], [], [], [0]
    arms = ((1, 0), (0, 1), (-1, 0), (0, -1))
    for k in range(1, n + 1):
        for di, dj in arms:
            order.append((k * di, k * dj))
            parent.append(((k - 1) * di, (k - 1) * dj))
            diag.append(None)
        batch.append(len(order))
    for d in range(2, 2 * n + 1):
        for a in range(max(1, d - n), min(n, d - 1) + 1):
            for si, sj in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
                i, j = si * a, sj * (d - a)
                order.append((i, j))
                parent.append(((i - si, j), (i, j - sj)))
                diag.append((i - si, j - sj))
        batch.append(len(order))
    return order, parent, diag, batch


def points(P, n):
    """Query points (3 a node) of every net in fill order, parent node index per node, batches."""
    order, parent, diag, batch = fill_order(n)
    pos = {ij: m for m, ij in enumerate(order)}
    pts, par, bat = [], [], [0]
    base = 0
    for r in range(P.shape[0]):
        X = P[r]
        for m, ij in enumerate(order):
            x = X[ij[0] + n, ij[1] + n]
            if diag[m] is None:
                a = X[parent[m][0] + n, parent[m][1] + n]
                q0 = x + 0.15 * (x - a) / np.linalg.norm(x - a)  # an arm's circle start, about as far off
                par.append(base + pos[parent[m]] if parent[m] in pos else -1)
            else:
                a, b, c = (X[ij[0] + n, ij[1] + n] for ij in (parent[m][0], parent[m][1], diag[m]))
                ab = b - a
                dd = np.linalg.norm(ab)
                e = ab / dd
                la, lb = np.linalg.norm(x - a), np.linalg.norm(x - b)
                along = (la * la - lb * lb + dd * dd) / (2 * dd)
                rho = np.sqrt(la * la - along * along)
                centre = a + along * e
                g = a + b - c - centre
                u = g - (g @ e) * e
                q0 = centre + rho * u / np.linalg.norm(u)  # fill's t = 0 point
                par.append(base + pos[parent[m][0]])
            rad = x / np.linalg.norm(x)
            pts += [q0, x + 1e-3 * rad, x]
        bat += [base + b for b in batch[1:]]
        base += len(order)
    return np.array(pts), np.array(par), np.array(bat)


def main(repeats=7):
    from bench_mesh import _icosphere_cap
    from uqdrape.drape import drape
    from uqdrape.geometry import Hemisphere, MeshSurface, export_stl

    analytic = Hemisphere(100.0)
    rng = np.random.default_rng(4)
    ds = drape(analytic, 5.0, 18, threads=1, orientation=rng.uniform(-20, 20, 64), crossover=rng.uniform(-5, 5, (64, 2)))
    pts, parent, batch = points(np.stack([ds.x.values, ds.y.values, ds.z.values], -1), 18)
    pts = np.where(np.isfinite(pts).all(1)[:, None], pts, 0.0)
    nodes = len(pts) // 3
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        _icosphere_cap(100.0, 7).export(folder / "cap.stl")
        meshes = {"plan grid 1 mm": MeshSurface(export_stl(analytic, folder / "grid.stl", half_width=150.0,
                                                             resolution_mm=1.0)),
                  "icosphere cap": MeshSurface(folder / "cap.stl")}
    print(f"{nodes:,} nodes, {len(pts):,} queries")
    for name, s in meshes.items():
        p = s.kernel[1]
        t = time.perf_counter()
        ptr, ring = ring_lists(s.triangles()[1])
        built = time.perf_counter() - t
        clear = np.full(s.faces_count, 0.5 * p[mq.REACH] / 0.1)  # REACH is 0.1 median edge
        none = np.zeros(0, np.int64)
        runs = {"A": lambda o, c: run_a(p, pts, o),
                "B": lambda o, c: run_walk(p, ptr, ring, clear, pts, none, none, o, c),
                "C": lambda o, c: run_walk(p, ptr, ring, clear, pts, parent, none, o, c),
                "R": lambda o, c: run_walk(p, ptr, ring, clear, pts, none, outs["A"], o, c),
                "D": lambda o, c: run_d(p, pts, batch, o, True),
                "T": lambda o, c: run_d(p, pts, batch, o, False),
                "G1": lambda o, c: run_g(p, pts, 1, o),
                "G2": lambda o, c: run_g(p, pts, 2, o)}
        times = {k: [] for k in runs}
        outs, counts = {}, {}
        for k in range(repeats + 1):  # the first round compiles
            for key, fn in runs.items():
                out, count = np.full(len(pts), -2, np.int64), np.zeros(3, np.int64)
                t = time.process_time()
                fn(out, count)
                if k:
                    times[key].append(time.process_time() - t)
                outs[key], counts[key] = out, count
        for key in "BCRD":
            assert (outs[key] == outs["A"]).all(), key
        assert (outs["G1"] == outs["G2"]).all()
        print(f"{name} ({s.faces_count:,} faces): 1-ring lists {ring.size / s.faces_count:.1f} a face, "
              f"built in {built:.2f} s")
        for key, v in times.items():
            v = np.array(v) / nodes * 1e6
            extra = ""
            if key in "BCR":
                walked, fell, steps = counts[key]
                extra = f"  walks {walked + fell:,} ({steps / (walked + fell):.1f} steps), failed proofs {fell:,}"
            print(f"  {key:>2}: {np.median(v):.3f} us a node ({v.min():.3f}-{v.max():.3f}){extra}")


if __name__ == "__main__":
    main()
