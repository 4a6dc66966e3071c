"""Probe for issue 23 (measured once, not shipped): would a per-face clearance that proves the
closest face from ONE face test answer the geodesic drape's mesh searches, and how much would
it save?

The query streams are recorded, not synthesised: ``record`` copies the package to a temporary
folder, logs every ``meshquery.closest`` call (numba object mode) and runs
``bench_mesh.py --drape``'s geodesic nets (64 nets x 18 rings) and energy drapes (4 forces x 18
rings) on the bench's two meshes of Hemisphere(100). The replays below use the worktree's
shipped query on those streams, one memo a recorded memo.

The proof. Face f, query q whose closest point c on f lies inside f (region 0), at distance d,
on side s of f's plane (s = +1 outward); D = d + eps (eps = 1e-12 x the mesh size, the
round-off margin of the shipped searches). Every point x of the ball B(q, D) has height
h = s (x - c).n >= -eps above f's plane and lateral distance rho from c with
rho^2 <= 2 D (eps + max(h, 0)), and |x - c| <= d + D. Per face and side, stored at build:
T  the 1-ring's fold: every point of a face sharing a corner with f has
   h <= T * lambda + tau, lambda its plan distance outside f (lower-bounded by the largest
   signed distance beyond f's three edge lines), tau = 1e-11 x the mesh size (taken at the
   neighbours' corners only: a probe's approximation, a point between corners need not keep
   the ratio)
R  the distance from f to the nearest face outside the 1-ring with a corner at h >= -tau,
   searched to RCAP (its corners' distances to f and f's to it: a probe's approximation of
   the triangle-triangle distance; every proven answer is checked against the shipped one)
Then no 1-ring face meets B when m >= D T and m^2 > 2 D (eps + tau) (m: c's distance to f's
edges, since rho >= m + lambda), and no other face when d + D < R: f is strictly closest, by
more than the round-off margin, so it is the shipped answer to the last bit.

``python benchmarks/probe_mesh_oneface.py --drape`` runs ``bench_mesh.py --drape`` on two
patched copies of the package (the clearance stored after each face's corners, 16 floats a
face instead of 9, with and without the proof from the previous answer tried before the cell
grid) and on the shipped one, in turn.

``python benchmarks/probe_mesh_oneface.py`` (about 2 minutes) prints, per mesh and drape: the
searched queries, how many a one-face proof from the cheap candidates answers (the previous
query's answer; the memo slot's face), the q1/q2 pattern of the geodesic net, and the CPU time
a query of the shipped path against shipped + one-face proof from the previous answer
(medians of interleaved repeats).
"""

import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

from uqdrape.geometry import meshquery as mq

HERE = Path(__file__).resolve().parent
#: The far faces' search radius, in median edges (REACH is 0.1 median edge).
RCAP = 2.0

_RECORDER = '''
import sys, numpy as np
sys.path.insert(0, {bench!r})
from bench_mesh import _icosphere_cap
from uqdrape.drape import drape
from uqdrape.geometry import Hemisphere, MeshSurface, export_stl
from uqdrape.geometry import meshquery as mq
from uqdrape.material import load_material
from pathlib import Path
out = Path({out!r})
analytic = Hemisphere(100.0)
_icosphere_cap(100.0, 7).export(out / "cap.stl")
meshes = {{"plan grid": MeshSurface(export_stl(analytic, out / "grid.stl", half_width=150.0, resolution_mm=1.0)),
          "cap": MeshSurface(out / "cap.stl")}}
for name, s in meshes.items():
    np.save(out / f"{{name}}.npy", s.kernel[1])
    rng = np.random.default_rng(4)
    cases = {{"geodesic": dict(orientation=rng.uniform(-20, 20, 64), crossover=rng.uniform(-5, 5, (64, 2))),
             "energy": dict(mode="energy", material=load_material("ebxhd936_like"),
                            blankholder_force=[0.0, 126.0, 252.0, 378.0], friction=0.2)}}
    for label, kw in cases.items():
        mq.LOG.clear()
        drape(s, 5.0, 18, threads=1, **kw)
        np.save(out / f"{{name}} {{label}}.npy", np.array(mq.LOG))
'''


def record(out: Path):
    """Every query point of the bench's drapes, in order (a NaN row where a memo is made),
    saved in ``out`` with the packed meshes."""
    copy = out / "pkg"
    shutil.copytree(Path(mq.__file__).resolve().parents[1], copy / "uqdrape",
                    ignore=shutil.ignore_patterns("__pycache__"))
    src = copy / "uqdrape" / "geometry" / "meshquery.py"
    s = src.read_text()
    s = s.replace("from .._jit import jit\n", "from .._jit import jit\nimport numba\nLOG = []\n\n\n"
                  "def _log(x, y, z):\n    LOG.append((x, y, z))\n")
    s = s.replace("    return np.full(_STACK_AT", "    with numba.objmode():\n        _log(math.nan, math.nan, math.nan)\n"
                  "    return np.full(_STACK_AT")
    s = s.replace("    if not math.isfinite(x + y + z):\n        return -1, (math.nan",
                  "    with numba.objmode():\n        _log(x, y, z)\n    if not math.isfinite(x + y + z):\n"
                  "        return -1, (math.nan")
    src.write_text(s)
    jit = copy / "uqdrape" / "_jit.py"
    jit.write_text(jit.read_text().replace("njit(cache=True, **_OPTIONS)", "njit(**_OPTIONS)"))
    env = dict(os.environ, PYTHONPATH=str(copy))
    subprocess.run([sys.executable, "-c", _RECORDER.format(bench=str(HERE), out=str(out))], env=env, cwd=copy, check=True)


_QUERY_PATCH = [  # meshquery: faces stored as corners + clearance (16 floats); the previous answer proved first
    ("HEADER = 22\n", "HEADER = 22\nSTRIDE = 16\n_LAST = 5 * 4096 + 2 * 96\n"),
    ("    o = int(p[OFF_TRI]) + 9 * f\n", "    o = int(p[OFF_TRI]) + STRIDE * f\n"),
    ("        o = tri + 9 * int(p[lists + e])\n", "        o = tri + STRIDE * int(p[lists + e])\n"),
    ("    return np.full(_STACK_AT + 2 * _STACK, math.nan)", "    return np.full(_STACK_AT + 2 * _STACK + 1, math.nan)"),
    ("    f, pt, w, region, d2, second = _grid_search(p, q)\n    if f >= 0:\n",
     "    last = memo[_LAST]\n    if PROVE and last == last:\n        ok, pt, w, region, d2 = _prove(p, int(last), q)\n"
     "        if ok:\n            return int(last), pt, w, region, d2\n"
     "    f, pt, w, region, d2, second = _grid_search(p, q)\n    if f >= 0:\n        memo[_LAST] = f\n"),
    ("    _keep(memo, slot, q, best_f, best, second, reach, eps)  # no face",
     "    memo[_LAST] = best_f\n    _keep(memo, slot, q, best_f, best, second, reach, eps)  # no face"),
    ("@jit\ndef closest(p, x, y, z, memo):", """@jit
def _prove(p, f, q):
    o = int(p[OFF_TRI]) + STRIDE * f
    a, b, c = _face(p, f)
    pt, w, region = _closest_on_triangle(q, a, b, c)
    dv = _sub(q, pt)
    d2 = _dot(dv, dv)
    if region != 0:
        return False, pt, w, region, d2
    eps, tau = 1e-12 * p[SCALE], 1e-11 * p[SCALE]
    e1, e2 = _sub(b, a), _sub(c, a)
    n = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
    side = 0 if _dot(dv, n) >= 0.0 else 1
    d = math.sqrt(d2)
    big = d + eps
    m = min(w[2] * p[o + 13], w[0] * p[o + 14], w[1] * p[o + 15])
    return (m >= big * p[o + 9 + side] and m * m > 2.0 * big * (eps + tau) and d + big < p[o + 11 + side],
            pt, w, region, d2)


@jit
def closest(p, x, y, z, memo):"""),
]
_PACK_PATCH = [  # mesh.pack: the clearance (``clearance``) after each face's corners
    ("    parts = [tri, np.where(creased", "    parts = [np.concatenate([tri.reshape(nf, 9), np.zeros((nf, 7))], 1), "
     "np.where(creased"),
    ("    return np.concatenate([head] + [np.asarray(p, float).ravel() for p in parts])\n",
     "    packed = np.concatenate([head] + [np.asarray(p, float).ravel() for p in parts])\n"
     "    import sys\n    sys.path.insert(0, {here!r})\n    from probe_mesh_oneface import clearance, RCAP\n"
     "    packed[mq.HEADER:mq.HEADER + 16 * nf].reshape(nf, 16)[:, 9:] = clearance(packed, RCAP * edge)\n"
     "    return packed\n"),
]


def _patched(folder: Path, prove: bool) -> Path:
    """A copy of the package with the one-face proof (``prove``) or only its layout."""
    copy = folder / ("proof" if prove else "layout")
    shutil.copytree(Path(mq.__file__).resolve().parents[1], copy / "uqdrape",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for name, patch in (("meshquery.py", _QUERY_PATCH + [("STRIDE = 16\n", f"STRIDE = 16\nPROVE = {prove}\n")]),
                        ("mesh.py", _PACK_PATCH)):
        src = copy / "uqdrape" / "geometry" / name
        s = src.read_text()
        for old, new in patch:
            assert s.count(old) == 1, old
            s = s.replace(old, new.replace("{here!r}", repr(str(HERE))))
        src.write_text(s)
    return copy


def drapes(rounds=2, repeats=5):
    """``bench_mesh.py --drape`` with the proof, with its layout alone and as shipped, in turn."""
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        copies = {"proof": _patched(folder, True), "layout only": _patched(folder, False),
                  "shipped": Path(mq.__file__).resolve().parents[2]}
        for _ in range(rounds):
            for name, root in copies.items():
                env = dict(os.environ, PYTHONPATH=str(root), NUMBA_CACHE_DIR=str(folder / "cache" / name))
                run = subprocess.run([sys.executable, str(HERE / "bench_mesh.py"), "--drape", "--repeats", str(repeats)],
                                     env=env, cwd=root, capture_output=True, text=True, check=True)
                print(name, os.getloadavg())
                print("\n".join(line for line in run.stdout.splitlines() if "ratio" in line))


@njit
def _face_vertices(p, f):
    o = int(p[mq.OFF_F]) + 3 * f
    out = np.empty(3, np.int64)
    for k in range(3):
        c = int(p[o + k])
        out[k] = -c - 1 if c < 0 else c
    return out


@njit
def _point_triangle(p, g, x):
    a, b, c = mq._face(p, g)
    pt = mq._closest_on_triangle(x, a, b, c)[0]
    d = mq._sub(x, pt)
    return math.sqrt(mq._dot(d, d))


@njit
def clearance(p, rcap):
    """(nf, 7): T+, T-, R+, R-, and the three altitudes (edge k: distance of corner k + 2 from it)."""
    nf, leaves = int(p[mq.NF]), int(p[mq.LEAVES])
    tau = 1e-11 * p[mq.SCALE]
    out = np.empty((nf, 7))
    stack = np.empty(96, np.int64)
    for f in range(nf):
        a, b, c = mq._face(p, f)
        n = mq._face_normal(p, f)
        corners = (a, b, c)
        vf = _face_vertices(p, f)
        e = (mq._sub(b, a), mq._sub(c, b), mq._sub(a, c))
        cr = (e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
              e[0][0] * e[1][1] - e[0][1] * e[1][0])
        area2 = math.sqrt(mq._dot(cr, cr))
        outward = np.empty((3, 3))
        for k in range(3):
            ek = e[k]
            o = (ek[1] * n[2] - ek[2] * n[1], ek[2] * n[0] - ek[0] * n[2], ek[0] * n[1] - ek[1] * n[0])
            s = math.sqrt(mq._dot(o, o))
            outward[k, 0], outward[k, 1], outward[k, 2] = o[0] / s, o[1] / s, o[2] / s
            out[f, 4 + k] = area2 / math.sqrt(mq._dot(ek, ek))
        lo = (min(a[0], b[0], c[0]) - rcap, min(a[1], b[1], c[1]) - rcap, min(a[2], b[2], c[2]) - rcap)
        hi = (max(a[0], b[0], c[0]) + rcap, max(a[1], b[1], c[1]) + rcap, max(a[2], b[2], c[2]) + rcap)
        t = np.zeros(2)
        r = np.full(2, rcap)
        stack[0] = 0
        top = 1
        while top > 0:
            top -= 1
            node = stack[top]
            ob = int(p[mq.OFF_BOX]) + 6 * node
            if (p[ob] > hi[0] or p[ob + 1] > hi[1] or p[ob + 2] > hi[2] or p[ob + 3] < lo[0] or p[ob + 4] < lo[1]
                    or p[ob + 5] < lo[2]):
                continue
            if node < leaves - 1:
                stack[top], stack[top + 1] = 2 * node + 1, 2 * node + 2
                top += 2
                continue
            first = (node - (leaves - 1)) * mq.LEAF
            for g in range(first, min(first + mq.LEAF, nf)):
                if g == f:
                    continue
                vg = _face_vertices(p, g)
                ga, gb, gc = mq._face(p, g)
                gcorners = (ga, gb, gc)
                shared = 0
                for i in range(3):
                    for j in range(3):
                        if vg[i] == vf[j]:
                            shared += 1
                for si in range(2):
                    sign = 1.0 if si == 0 else -1.0
                    if shared > 0:
                        for i in range(3):
                            if vg[i] == vf[0] or vg[i] == vf[1] or vg[i] == vf[2]:
                                continue
                            v = gcorners[i]
                            h = sign * mq._dot(mq._sub(v, a), n)
                            if h <= tau:
                                continue
                            lam = -math.inf
                            for k in range(3):
                                lam = max(lam, mq._dot(mq._sub(v, corners[k]), (outward[k, 0], outward[k, 1], outward[k, 2])))
                            t[si] = math.inf if lam <= 0.0 else max(t[si], (h - tau) / lam)
                    else:
                        up = False
                        for i in range(3):
                            up = up or sign * mq._dot(mq._sub(gcorners[i], a), n) >= -tau
                        if up:
                            dist = math.inf
                            for i in range(3):
                                dist = min(dist, _point_triangle(p, f, gcorners[i]), _point_triangle(p, g, corners[i]))
                            r[si] = min(r[si], dist)
        out[f, 0], out[f, 1], out[f, 2], out[f, 3] = t[0], t[1], r[0], r[1]
    return out


@njit
def prove(p, cl, f, q):
    """(proven, point, weights, region, squared distance) of face f for q by the one-face proof."""
    pt, w, region, d2 = mq._distance2(p, f, q)
    if region != 0:
        return False, pt, w, region, d2
    eps = 1e-12 * p[mq.SCALE]
    tau = 1e-11 * p[mq.SCALE]
    n = mq._face_normal(p, f)
    side = 0 if (q[0] - pt[0]) * n[0] + (q[1] - pt[1]) * n[1] + (q[2] - pt[2]) * n[2] >= 0.0 else 1
    d = math.sqrt(d2)
    big = d + eps
    m = min(w[2] * cl[f, 4], w[0] * cl[f, 5], w[1] * cl[f, 6])
    ok = m >= big * cl[f, side] and m * m > 2.0 * big * (eps + tau) and d + big < cl[f, 2 + side]
    return ok, pt, w, region, d2


@njit
def count(p, cl, pts, out):
    """out[m]: -1 memo marker, 0 memo answer, else 1 | 2 (the previous answer proves it) |
    4 (the memo slot's face proves it) | 8 (the previous answer is the answer, region 0)."""
    memo = mq.new_memo()
    last = -1
    for m in range(pts.shape[0]):
        x, y, z = pts[m, 0], pts[m, 1], pts[m, 2]
        if math.isnan(x):
            memo, last, out[m] = mq.new_memo(), -1, -1
            continue
        q = (x, y, z)
        slot = mq._slot(p, q)
        dx, dy, dz = x - memo[slot], y - memo[slot + 1], z - memo[slot + 2]
        hit = dx * dx + dy * dy + dz * dz < memo[slot + 3] * memo[slot + 3]
        cand = -1 if math.isnan(memo[slot + 4]) else int(memo[slot + 4])
        f, c, w, region, d2 = mq.closest(p, x, y, z, memo)
        flags = 0
        if not hit:
            flags = 1
            if last >= 0:
                ok, pt, w2, r2, e2 = prove(p, cl, last, q)
                if ok:
                    flags |= 2
                    if last != f or e2 != d2:
                        raise AssertionError("a proof gave another answer")
                if last == f and region == 0:
                    flags |= 8
            if cand >= 0:
                ok, pt, w2, r2, e2 = prove(p, cl, cand, q)
                if ok:
                    flags |= 4
                    if cand != f or e2 != d2:
                        raise AssertionError("a proof gave another answer")
        out[m] = flags
        last = f


@njit
def run(p, cl, pts, use, out):
    """The shipped query (use False) or the one-face proof from the previous answer first."""
    memo = mq.new_memo()
    last = -1
    for m in range(pts.shape[0]):
        x, y, z = pts[m, 0], pts[m, 1], pts[m, 2]
        if math.isnan(x):
            memo, last = mq.new_memo(), -1
            continue
        if use and last >= 0:
            q = (x, y, z)
            slot = mq._slot(p, q)
            dx, dy, dz = x - memo[slot], y - memo[slot + 1], z - memo[slot + 2]
            if not dx * dx + dy * dy + dz * dz < memo[slot + 3] * memo[slot + 3]:
                if prove(p, cl, last, q)[0]:
                    out[m] = last
                    continue
        last = out[m] = mq.closest(p, x, y, z, memo)[0]


def main(repeats=7):
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        t = time.perf_counter()
        record(folder)
        print(f"recorded in {time.perf_counter() - t:.0f} s")
        for mesh in ("plan grid", "cap"):
            p = np.load(folder / f"{mesh}.npy")
            edge = p[mq.REACH] / 0.1
            t = time.perf_counter()
            cl = clearance(p, RCAP * edge)
            t1 = time.perf_counter()
            cl = clearance(p, RCAP * edge)
            built = time.perf_counter() - t1
            print(f"{mesh} ({int(p[mq.NF]):,} faces): clearance {built:.2f} s (first call, compile included, "
                  f"{t1 - t:.1f} s); T+ median {np.median(cl[:, 0]):.3g}, T- {np.median(cl[:, 1]):.3g}, "
                  f"R+ median {np.median(cl[:, 2]) / edge:.2f} edge, R- {np.median(cl[:, 3]) / edge:.2f} edge")
            for case in ("geodesic", "energy"):
                pts = np.load(folder / f"{mesh} {case}.npy")
                out = np.zeros(len(pts), np.int64)
                count(p, cl, pts, out)
                s = out[out > 0]
                n = (out >= 0).sum()
                print(f"  {case}: {n:,} queries, {s.size:,} searched ({s.size / n:.1%}); of those the previous "
                      f"answer proves {((s & 2) > 0).mean():.1%} (is the answer in its interior: "
                      f"{((s & 8) > 0).mean():.1%}), the memo slot's face {((s & 4) > 0).mean():.1%}, "
                      f"either {((s & 6) > 0).mean():.1%}")
                if case == "geodesic":
                    step = np.r_[np.nan, np.linalg.norm(np.diff(pts, axis=0), axis=1)]
                    q1 = (step > 1.0) & (out > 0)
                    print(f"    first query of a node (> 1 mm from the last): {q1.sum():,}, proven from the "
                          f"previous answer {((out[q1] & 2) > 0).mean():.1%}; the other searches "
                          f"{((out > 0) & ~q1).sum():,}, proven {((out[(out > 0) & ~q1] & 2) > 0).mean():.1%}")
                times = {False: [], True: []}
                res = {}
                for k in range(repeats + 1):
                    for use in (False, True):
                        o = np.full(len(pts), -2, np.int64)
                        t = time.process_time()
                        run(p, cl, pts, use, o)
                        if k:
                            times[use].append(time.process_time() - t)
                        res[use] = o
                assert (res[True] == res[False]).all()
                a, b = np.array(times[False]) / n * 1e6, np.array(times[True]) / n * 1e6
                print(f"    CPU a query: shipped {np.median(a):.3f} us ({a.min():.3f}-{a.max():.3f}), with the "
                      f"one-face proof {np.median(b):.3f} us ({b.min():.3f}-{b.max():.3f}); ratio {np.median(b / a):.2f}")


if __name__ == "__main__":
    drapes() if "--drape" in sys.argv else main()
