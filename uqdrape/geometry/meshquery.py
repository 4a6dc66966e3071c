"""Compiled queries of a triangle-mesh mould (lengths mm): closest point on a bounding-volume
hierarchy, the signed distance that is the mesh's implicit function, its smooth normal and
the vertical ray that finds the top surface.

The whole mesh travels as one float64 array (the ``params`` of ``compiled``'s kind MESH),
built by ``uqdrape.geometry.mesh``: a header, then

TRI  the faces' corners (nf, 3, 3), in BVH order: a face's coordinates in one place
F    vertex indices per face (nf, 3), in BVH order; a corner whose vertex normal strays
     from its face's normal by more than the crease angle is stored as -(index + 1) and
     takes the face normal (a sharp edge keeps its two normals)
NB   the face across edge k = (corner k, corner k + 1) per face (nf, 3); -1 on a boundary
VN   angle-weighted unit vertex normals (nv, 3): pseudo-normals for the sign and the
     smooth normal at corners that are not creased
VB   1.0 for a vertex on a boundary edge (nv,)
BOX  node boxes (2 L - 1, 6) [xmin, ymin, zmin, xmax, ymax, zmax] of a complete binary tree
     in heap order (children of node i: 2 i + 1, 2 i + 2); leaf l (node L - 1 + l) holds
     faces LEAF l .. LEAF (l + 1) - 1; padding leaves are empty (+inf, -inf)
HASH a cell grid's hash table (rows, 3) [cell key, first, end] (key -1: an empty slot),
     open addressing with linear probing from a home slot below GRID_SLOTS (a power of 2)
     onwards, no wrap-around (the table ends with an empty slot), for the cells of size
     GRID_CELL (from GRID_X0, GRID_Y0, GRID_Z0) that some face's box, widened by
     GRID_MARGIN, overlaps
LIST the faces of those cells, cell by cell

Indices are stored as floats (exact below 2**53). The signed distance is phi = (p - c) . n
inside a face's region (c the closest point, n the face normal), +-|p - c| with the sign of
the angle-weighted pseudo-normal at an edge or vertex (Baerentzen & Aanaes 2005), and the
height over the face's plane where the closest point lies on the mesh's open boundary, so
a sheet is continued by its tangent plane past its edge (nodes placed there are off the
mould, as past an analytic mould's domain).

The closest face is the one of least squared distance, ties to the lower face index, so the
answer does not depend on the order of the search. A node solve queries points that lie
close together (its Newton steps, the energy minimiser's stencil candidates), so a query
takes a ``memo`` (``new_memo``, one per thread): a table, hashed by a point's cell of size
REACH, of earlier answers, each with a radius rho within which it is proven to be the
answer: the search went on to REACH beyond the closest face and found no other face nearer
than 2 rho beyond it, so for a point moved by less than rho the same face is still strictly
closest, and the query only recomputes the point on that face. A memoised query equals a
query with a fresh memo to the last bit (tests/test_mesh_query.py).

A query the memo does not answer looks in the cell grid first: every face that comes within
GRID_MARGIN of the point's cell is in the cell's list, so when the closest of them lies
nearer than the margin (plus the point's distance to the cell's sides) it is the closest
face of the mesh, found by testing one list (8 faces a cell on average on the bench
hemisphere's meshes, most rejected by their box) instead of walking the hierarchy down
from its root. Farther points (and points outside
the grid) are searched in the hierarchy. Both searches give the same answer, the least
squared distance with ties to the lower face index.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit

#: Header slots of the packed mesh array: counts, offsets, the on-mesh tolerance (mm), the
#: mesh's size (mm), cos(crease angle), the edge blend half-width (mm), the memo's reach (mm),
#: and the cell grid: its cell size and margin (mm), origin (mm), hash slots and offsets;
#: last the offset (mm) of the surface the queries describe from the mesh (``OFFSET``).
(NV, NF, LEAVES, OFF_TRI, OFF_F, OFF_NB, OFF_VN, OFF_VB, OFF_BOX, ON_TOL, SCALE, COS_CREASE, EDGE_BLEND, REACH,
 GRID_CELL, GRID_MARGIN, GRID_X0, GRID_Y0, GRID_Z0, GRID_SLOTS, OFF_HASH, OFF_LIST, OFFSET) = range(23)
HEADER = 23
#: Cells of the grid per axis (a cell's key, ix + GRID_AXIS (iy + GRID_AXIS iz), is exact in a float).
GRID_AXIS = 1 << 17
#: Entries of a query memo (a power of 2), each (x, y, z, rho, face).
MEMO_SLOTS = 4096
#: Faces per BVH leaf.
LEAF = 4
#: Bound on the BVH depth (a complete tree of up to 2**40 leaves).
_STACK = 96
#: Where a memo keeps the search's stack, after its table.
_STACK_AT = 5 * MEMO_SLOTS


@jit
def _corner(p, f, k):
    """Vertex index of corner k of face f, and whether that corner is creased."""
    c = int(p[int(p[OFF_F]) + 3 * f + k])
    return (-c - 1, True) if c < 0 else (c, False)


@jit
def _face(p, f):
    o = int(p[OFF_TRI]) + 9 * f
    return (p[o], p[o + 1], p[o + 2]), (p[o + 3], p[o + 4], p[o + 5]), (p[o + 6], p[o + 7], p[o + 8])


@jit
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@jit
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@jit
def _face_normal(p, f):
    a, b, c = _face(p, f)
    e1, e2 = _sub(b, a), _sub(c, a)
    n = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
    s = math.sqrt(_dot(n, n))
    return (n[0] / s, n[1] / s, n[2] / s)


@jit
def _closest_on_triangle(q, a, b, c):
    """Closest point of triangle abc to q (Ericson, Real-Time Collision Detection 5.1.5):
    (point, barycentric weights of a, b, c, region) with region 0 the face, 1 + k corner k,
    4 + k edge k (corner k to corner k + 1)."""
    ab, ac, ap = _sub(b, a), _sub(c, a), _sub(q, a)
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return a, (1.0, 0.0, 0.0), 1
    bp = _sub(q, b)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return b, (0.0, 1.0, 0.0), 2
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return (a[0] + v * ab[0], a[1] + v * ab[1], a[2] + v * ab[2]), (1.0 - v, v, 0.0), 4
    cp = _sub(q, c)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return c, (0.0, 0.0, 1.0), 3
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return (a[0] + w * ac[0], a[1] + w * ac[1], a[2] + w * ac[2]), (1.0 - w, 0.0, w), 6
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return (b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2])), (0.0, 1.0 - w, w), 5
    denom = 1.0 / (va + vb + vc)
    v, w = vb * denom, vc * denom
    return ((a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w),
            (1.0 - v - w, v, w), 0)


@jit
def _box_distance2(p, node, q):
    o = int(p[OFF_BOX]) + 6 * node
    s = 0.0
    for k in range(3):
        d = max(p[o + k] - q[k], 0.0, q[k] - p[o + 3 + k])
        s += d * d
    return s


@jit
def new_memo():
    """An empty query memo (``closest``): its table (no entry matches: NaN radii) and the
    search's stack."""
    return np.full(_STACK_AT + 2 * _STACK, math.nan)


@jit
def _slot(p, q):
    """Offset in a memo of the entry for point q: its cell of size REACH, hashed."""
    c = p[REACH]
    h = (int(math.floor(q[0] / c)) * 73856093) ^ (int(math.floor(q[1] / c)) * 19349663) ^ (
        int(math.floor(q[2] / c)) * 83492791)
    return 5 * (h & (MEMO_SLOTS - 1))


@jit
def _distance2(p, f, q):
    """(point, barycentric weights, region, squared distance) of face f's closest point to q."""
    a, b, c = _face(p, f)
    pt, w, region = _closest_on_triangle(q, a, b, c)
    d = _sub(q, pt)
    return pt, w, region, _dot(d, d)


@jit
def _cell_hash(ix, iy, iz, slots):
    """Home slot of cell (ix, iy, iz) in a hash table of ``slots`` (a power of 2) home slots."""
    return ((ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791)) & (slots - 1)


@jit
def _grid_search(p, q):
    """The closest face to q among its grid cell's list, when it is proven the mesh's closest:
    (face, point, weights, region, squared distance, squared lower bound of every other face's
    distance, or nothing beyond the certificate's radius); face -1 when the cell cannot prove
    it (q outside the grid, in an empty cell, or farther from the list's closest face than the
    list's margin reaches)."""
    none = (-1, (math.nan, math.nan, math.nan), (0.0, 0.0, 0.0), 0, math.nan, math.nan)
    g = p[GRID_CELL]
    ux, uy, uz = (q[0] - p[GRID_X0]) / g, (q[1] - p[GRID_Y0]) / g, (q[2] - p[GRID_Z0]) / g
    if not (0.0 <= ux < GRID_AXIS and 0.0 <= uy < GRID_AXIS and 0.0 <= uz < GRID_AXIS):
        return none
    ix, iy, iz = int(ux), int(uy), int(uz)
    key = float(ix + GRID_AXIS * (iy + GRID_AXIS * iz))
    slots = int(p[GRID_SLOTS])
    table = int(p[OFF_HASH])
    s = _cell_hash(ix, iy, iz, slots)
    while p[table + 3 * s] != key:  # the table ends with an empty slot: no wrap-around
        if p[table + 3 * s] < 0.0:
            return none
        s += 1
    # q lies in its cell: every face within the margin plus q's distance to the cell's sides is listed
    inner = min(ux - ix, ix + 1 - ux, uy - iy, iy + 1 - uy, uz - iz, iz + 1 - uz) * g
    certain = p[GRID_MARGIN] + inner
    eps = 1e-12 * p[SCALE]
    lists = int(p[OFF_LIST])
    best, best_f, best_c, best_w, best_r = math.inf, -1, (math.nan, math.nan, math.nan), (0.0, 0.0, 0.0), 0
    second, limit = math.inf, math.inf
    first, end = int(p[table + 3 * s + 1]), int(p[table + 3 * s + 2])
    tri = int(p[OFF_TRI])
    touch = 0.0
    for e in range(first, end):  # fetch the faces' corners all at once, so their cache misses overlap
        o = tri + 9 * int(p[lists + e])
        touch += p[o] + p[o + 8]
    if math.isnan(touch):  # never (the corners are finite): it keeps the loads
        return none
    for e in range(first, end):
        f = int(p[lists + e])
        a, b, c = _face(p, f)
        lb = 0.0
        for k in range(3):
            d = max(min(a[k], b[k], c[k]) - q[k], 0.0, q[k] - max(a[k], b[k], c[k]))
            lb += d * d
        if lb > limit:
            second = min(second, lb)
            continue
        pt, w, region = _closest_on_triangle(q, a, b, c)
        dv = _sub(q, pt)
        d2 = _dot(dv, dv)
        if d2 < best or (d2 == best and f < best_f):
            second = min(second, best)
            best, best_f, best_c, best_w, best_r = d2, f, pt, w, region
            r = math.sqrt(best) + eps  # a face whose box lies farther is farther than round-off can hide
            limit = r * r
        else:
            second = min(second, d2)
    if not math.sqrt(best) + eps < certain:
        return none
    return best_f, best_c, best_w, best_r, best, min(second, certain * certain)


@jit
def _keep(memo, slot, q, f, d2, second, reach, eps):
    """Store face f, at squared distance d2 from q, in the memo's ``slot`` with the radius it
    is proven for: every other face lies at least min(sqrt(second), sqrt(d2) + reach) away."""
    d = math.sqrt(d2)
    rho = 0.5 * (min(math.sqrt(second), d + reach) - d) - eps
    if rho > 0:
        memo[slot], memo[slot + 1], memo[slot + 2], memo[slot + 3], memo[slot + 4] = q[0], q[1], q[2], rho, f


@jit
def closest(p, x, y, z, memo):
    """Closest point of the mesh to (x, y, z): (face, point, barycentric weights, region,
    squared distance), the face of least squared distance (ties to the lower index); face -1
    for a non-finite point. ``memo`` (``new_memo``) answers a point within a proven radius
    of an earlier one, and keeps this answer, as the module docstring says."""
    if not math.isfinite(x + y + z):
        return -1, (math.nan, math.nan, math.nan), (0.0, 0.0, 0.0), 0, math.nan
    q = (x, y, z)
    slot = _slot(p, q)
    dx, dy, dz = x - memo[slot], y - memo[slot + 1], z - memo[slot + 2]
    if dx * dx + dy * dy + dz * dz < memo[slot + 3] * memo[slot + 3]:
        f = int(memo[slot + 4])
        pt, w, region, d2 = _distance2(p, f, q)
        return f, pt, w, region, d2
    reach = p[REACH]
    eps = 1e-12 * p[SCALE]  # far above the round-off of a distance, far below any rho of use
    f, pt, w, region, d2, second = _grid_search(p, q)
    if f >= 0:
        _keep(memo, slot, q, f, d2, second, reach, eps)
        return f, pt, w, region, d2
    leaves = int(p[LEAVES])
    nf = int(p[NF])
    best, best_f, best_c, best_w, best_r = math.inf, -1, (math.nan, math.nan, math.nan), (0.0, 0.0, 0.0), 0
    second, limit = math.inf, math.inf  # nearest other face; boxes farther (squared) are left
    stack, bound = _STACK_AT, _STACK_AT + _STACK  # the memo's node stack, their squared box distances
    memo[stack], memo[bound] = 0.0, 0.0
    top = 1
    while top > 0:
        top -= 1
        node = int(memo[stack + top])
        if memo[bound + top] > limit:
            continue
        if node >= leaves - 1:
            first = (node - (leaves - 1)) * LEAF
            for f in range(first, min(first + LEAF, nf)):
                pt, w, region, d2 = _distance2(p, f, q)
                if d2 < best or (d2 == best and f < best_f):
                    second = min(second, best)
                    best, best_f, best_c, best_w, best_r = d2, f, pt, w, region
                    r = math.sqrt(best) + reach + eps
                    limit = r * r
                else:
                    second = min(second, d2)
            continue
        left, right = 2 * node + 1, 2 * node + 2
        dl, dr = _box_distance2(p, left, q), _box_distance2(p, right, q)
        if dl > dr:  # the nearer child is popped first
            left, right, dl, dr = right, left, dr, dl
        memo[stack + top], memo[bound + top], memo[stack + top + 1], memo[bound + top + 1] = right, dr, left, dl
        top += 2
    _keep(memo, slot, q, best_f, best, second, reach, eps)  # no face lies nearer than second, or beyond reach
    return best_f, best_c, best_w, best_r, best


@jit
def _on_boundary(p, f, region):
    """Whether the closest feature (region of face f) lies on the mesh's open boundary."""
    if region >= 4:
        return p[int(p[OFF_NB]) + 3 * f + region - 4] < 0.0
    if region >= 1:
        return p[int(p[OFF_VB]) + _corner(p, f, region - 1)[0]] > 0.5
    return False


@jit
def signed_distance(p, x, y, z, memo):
    """(phi, gradient 3-tuple, on the mesh) at (x, y, z): the signed distance (> 0 outside, on
    the normals' side) less the mesh's OFFSET, its gradient, as set out in the module
    docstring, and whether the point lies on the mesh (its offset surface) within the stored tolerance (not on the tangent plane that
    continues it past an open edge), from the one closest-point query (``memo`` as in
    ``closest``)."""
    f, c, _, region, d2 = closest(p, x, y, z, memo)
    if f < 0:
        return math.nan, (math.nan, math.nan, math.nan), False
    off = p[OFFSET]
    on = d2 <= p[ON_TOL] * p[ON_TOL] if off == 0.0 else abs(math.sqrt(d2) - off) <= p[ON_TOL]
    n = _face_normal(p, f)
    diff = (x - c[0], y - c[1], z - c[2])
    if region == 0 or _on_boundary(p, f, region):
        return _dot(diff, n) - off, n, on
    if region >= 4:
        g = int(p[int(p[OFF_NB]) + 3 * f + region - 4])
        m = _face_normal(p, g)
        pseudo = (n[0] + m[0], n[1] + m[1], n[2] + m[2])
    else:
        o = int(p[OFF_VN]) + 3 * _corner(p, f, region - 1)[0]
        pseudo = (p[o], p[o + 1], p[o + 2])
    sign = 1.0 if _dot(diff, pseudo) >= 0.0 else -1.0
    d = math.sqrt(d2)
    if d > 1e-9 * p[SCALE]:
        return sign * d - off, (sign * diff[0] / d, sign * diff[1] / d, sign * diff[2] / d), on
    s = math.sqrt(_dot(pseudo, pseudo))
    return sign * d - off, (pseudo[0] / s, pseudo[1] / s, pseudo[2] / s), on


@jit
def closest_many(p, points, foot, phi):
    """Closest points ``foot`` (M, 3) on the mesh and the signed distances ``phi`` (M,) of
    ``points`` (M, 3) mm, filled in place (NaN for a non-finite point)."""
    memo = new_memo()
    for m in range(points.shape[0]):
        x, y, z = points[m, 0], points[m, 1], points[m, 2]
        c = closest(p, x, y, z, memo)[1]
        foot[m, 0], foot[m, 1], foot[m, 2] = c
        phi[m] = signed_distance(p, x, y, z, memo)[0]


@jit
def _smooth_normal(p, f, w):
    """Unit normal at barycentric weights w of face f: the corners' normals (vertex normal,
    or the face normal at a creased corner) interpolated."""
    nf = _face_normal(p, f)
    s0 = s1 = s2 = 0.0
    for k in range(3):
        v, creased = _corner(p, f, k)
        if creased:
            m = nf
        else:
            o = int(p[OFF_VN]) + 3 * v
            m = (p[o], p[o + 1], p[o + 2])
        s0 += w[k] * m[0]
        s1 += w[k] * m[1]
        s2 += w[k] * m[2]
    s = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    return (s0 / s, s1 / s, s2 / s)


@jit
def normal(p, x, y, z, memo):
    """Unit normal of the mesh at its point closest to (x, y, z): the interpolated normal,
    turned within EDGE_BLEND of a sharp edge (faces meeting beyond the crease angle) towards
    the edge's bisector, as if the edge were rounded for the tangent plane alone, so that a
    node on or next to the edge steps over it (the next node may lie a right angle round);
    ``memo`` as in ``closest``. A face that meets a sharp edge at one corner only (a creased
    corner, no creased edge there) turns towards that vertex's normal, by the distance to
    the vertex, so that which face wins a tie at a vertex on the edge does not matter."""
    f, q, w, _, _ = closest(p, x, y, z, memo)
    if f < 0:
        return (math.nan, math.nan, math.nan)
    n = _smooth_normal(p, f, w)
    nf = _face_normal(p, f)
    a, b, c = _face(p, f)
    e1, e2 = _sub(b, a), _sub(c, a)
    cr = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
    area2 = math.sqrt(_dot(cr, cr))
    corners = (a, b, c)
    best, target = math.inf, nf
    for k in range(3):  # edge k runs from corner k to k + 1; its distance is w[k + 2] times its height
        g = int(p[int(p[OFF_NB]) + 3 * f + k])
        if g < 0 or _dot(nf, _face_normal(p, g)) >= p[COS_CREASE]:
            continue
        e = _sub(corners[(k + 1) % 3], corners[k])
        d = w[(k + 2) % 3] * area2 / math.sqrt(_dot(e, e))
        if d < best:
            m = _face_normal(p, g)
            best, target = d, (0.5 * (nf[0] + m[0]), 0.5 * (nf[1] + m[1]), 0.5 * (nf[2] + m[2]))
    for k in range(3):
        v, creased = _corner(p, f, k)
        if not creased:
            continue
        r = _sub(q, corners[k])
        d = math.sqrt(_dot(r, r))
        if d <= best:  # at the vertex itself its normal, whichever face won the tie
            o = int(p[OFF_VN]) + 3 * v
            best, target = d, (p[o], p[o + 1], p[o + 2])
    if best >= p[EDGE_BLEND]:
        return n
    u = best / p[EDGE_BLEND]
    s0, s1, s2 = (1 - u) * target[0] + u * n[0], (1 - u) * target[1] + u * n[1], (1 - u) * target[2] + u * n[2]
    s = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    return (s0 / s, s1 / s, s2 / s)


@jit
def top(p, x, y):
    """The highest point of the mesh above plan point (x, y): (z, dz/dx, dz/dy) from the smooth
    normal there, NaN where no face covers (x, y) in plan (faces edge-on in plan are skipped)."""
    leaves = int(p[LEAVES])
    nf = int(p[NF])
    ob = int(p[OFF_BOX])
    stack = np.empty(_STACK, np.int64)
    stack[0] = 0
    n = 1
    best, best_f, best_w = -math.inf, -1, (0.0, 0.0, 0.0)
    while n > 0:
        n -= 1
        node = stack[n]
        o = ob + 6 * node
        if not (p[o] <= x <= p[o + 3] and p[o + 1] <= y <= p[o + 4] and p[o + 5] > best):
            continue
        if node < leaves - 1:
            stack[n], stack[n + 1] = 2 * node + 1, 2 * node + 2
            n += 2
            continue
        first = (node - (leaves - 1)) * LEAF
        for f in range(first, min(first + LEAF, nf)):
            a, b, c = _face(p, f)
            det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
            if abs(det) <= 1e-14 * p[SCALE] * p[SCALE]:
                continue
            wb = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (y - a[1])) / det
            wc = ((b[0] - a[0]) * (y - a[1]) - (x - a[0]) * (b[1] - a[1])) / det
            wa = 1.0 - wb - wc
            if wa >= -1e-12 and wb >= -1e-12 and wc >= -1e-12:
                zz = wa * a[2] + wb * b[2] + wc * c[2]
                if zz > best:
                    best, best_f, best_w = zz, f, (wa, wb, wc)
    if best_f < 0:
        return math.nan, math.nan, math.nan
    m = _smooth_normal(p, best_f, best_w)
    nz = max(m[2], 1e-9)
    return best, -m[0] / nz, -m[1] / nz


@jit
def offset_top(p, x, y):
    """``top`` of the surface at the mesh's OFFSET (mm) outside it: (z, dz/dx, dz/dy) where a
    vertical line at plan point (x, y) meets phi = OFFSET above the mesh's top, found by
    Newton steps kept inside a bracket (from the top, where phi = 0, to above the mesh's
    highest point); the mesh's own ``top`` where OFFSET is 0."""
    h, hx, hy = top(p, x, y)
    off = p[OFFSET]
    if off == 0.0 or not math.isfinite(h):
        return h, hx, hy
    memo = new_memo()
    lo, hi = h, p[int(p[OFF_BOX]) + 5] + off + 1.0  # below: phi <= 0; above: phi > off
    z = h + off
    tol = 1e-12 * p[SCALE]
    g = (0.0, 0.0, 1.0)
    for _ in range(100):
        phi, g, _ = signed_distance(p, x, y, z, memo)
        if phi < 0.0:
            lo = z
        else:
            hi = z
        if abs(phi) <= tol or hi - lo <= tol:
            break
        step = z - phi / g[2] if g[2] > 1e-3 else math.nan
        z = step if lo < step < hi else 0.5 * (lo + hi)
    nz = max(g[2], 1e-9)
    return z, -g[0] / nz, -g[1] / nz
