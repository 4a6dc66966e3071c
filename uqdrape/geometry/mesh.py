"""Moulds from triangle meshes (STL, OBJ, PLY and any surface mesh meshio reads), walls,
undercuts and sharp edges included, and ``export_stl`` of any mould's height field.

``MeshSurface`` reads the file (trimesh for the formats it knows, else meshio), scales it to
mm, turns it so that its press direction points +z (the solver's frame: tool moving along
z, blank-holder in x-y; results stay in that frame), checks it and packs it with a
bounding-volume hierarchy into the array that ``meshquery`` evaluates compiled, like every
other mould. The node solver sees the mesh's signed distance, so nodes lie on the mesh
itself (to the root tolerance), not on a resampled height field.

The hierarchy is a complete binary tree, four faces per leaf, each node's faces split at
their median along the longest axis of their centroids; the split and the boxes are done
level by level in numpy, with no per-node Python (``bench_mesh.py`` times it). Beside it, a
hashed grid of cells lists the faces near each cell, which answers most queries near the
mesh from one list (``meshquery``); it is built in numpy too (a sort of the cell keys and a
linear-probing hash filled in rounds).
trimesh is imported where a mesh is read or written: its second of import time is not paid
by processes that drape only analytic moulds.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .._lazy import lazy_module
from ..errors import ParameterError
from ..files import FileFormatError, check_input_file
from .analytic import MAX_LENGTH_MM
from .base import Surface

# numba: loaded when a mesh is packed or queried
compiled = lazy_module("uqdrape.geometry.compiled")
mq = lazy_module("uqdrape.geometry.meshquery")

#: Length units a mesh file may be in, and their size in mm.
UNITS = {"mm": 1.0, "m": 1000.0, "in": 25.4}
#: The default round-off (mm) of the mesh's open edges.
EDGE_BLEND_MM = 2.0
#: A corner whose angle-weighted vertex normal strays more than this from its face's normal
#: (deg) keeps the face normal: a sharp edge is not rounded by the interpolated normal.
CREASE_DEG = 30.0
#: A node is on the mesh within this fraction of the mould's size (mm per mm).
ON_TOLERANCE = 1e-7
#: A query's memo reach (``meshquery``) as a fraction of the median edge length: a query
#: searches this far beyond its closest face to prove its answer for nearby points (0.1:
#: on the bench hemisphere 77 % of an energy drape's queries are answered from the memo,
#: 68 % at 0.5, whose searches test twice the faces).
MEMO_REACH = 0.1
#: The cell grid of a query's first look (``meshquery``): its cell size and margin as
#: fractions of the median edge length. A cell lists the faces within the margin of it: on
#: the bench hemisphere's meshes about 10 entries a face and 8 faces a cell, 25 MiB for
#: 170,000 faces; cells of 1.5 edges with a 0.3 margin (half the memory, 13 faces a cell)
#: gave 3-9 % slower drapes (one interleaved run).
GRID_CELL, GRID_MARGIN = 1.0, 0.2
#: Most list entries a face on average: a mesh whose faces would fill more cells (a few faces
#: far larger than the median edge, e.g. a CAD export's flat sides beside fine fillets) gets
#: no grid, and every query searches the hierarchy.
GRID_BUDGET = 32
#: Largest mesh file read, bytes (a binary STL of about 1.3 million triangles).
MAX_MESH_BYTES = 64 * 2**20
#: Formats read by trimesh; others go to meshio.
_TRIMESH_FORMATS = {".stl", ".obj", ".ply", ".off", ".glb", ".gltf"}


class MeshError(ParameterError):
    """A mesh file that cannot be a mould; the message is one line naming the file, and the
    argument at fault is the mould's ``path``."""

    def __init__(self, message: str):
        super().__init__("path", message)


class UnreadableMesh(ValueError):
    """A file meshio cannot read; the message says why without quoting the file."""


def _binary_stl(path: Path):
    """The triangles (n, 3, 3) float32 of a binary STL file, or None if it is not one (its
    size is not 84 + 50 n bytes for the n triangles its header states)."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(84)
        if len(head) < 84 or size != 84 + 50 * int(np.frombuffer(head[80:], "<u4")[0]):
            return None
        rec = np.fromfile(f, np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")]))
    return rec["corners"]


def _read(path: Path):
    """Vertices (nv, 3) and triangles (nf, 3) of a mesh file, duplicate vertices merged."""
    name = str(path)
    if not path.exists():
        raise MeshError(f"path: mesh file {name!r} does not exist")
    try:
        size = check_input_file(path, "mesh file", MAX_MESH_BYTES)
    except FileFormatError as err:  # a pipe, a folder, too large
        raise MeshError(f"path: {err}") from None
    if size == 0:
        raise MeshError(f"path: mesh file {name!r} is empty")
    suffix = path.suffix.lower()
    try:
        binary = _binary_stl(path) if suffix == ".stl" else None
        if binary is not None:
            vertices = binary.reshape(-1, 3).astype(float)
            faces = np.arange(vertices.shape[0]).reshape(-1, 3)
        elif suffix in _TRIMESH_FORMATS:
            import trimesh

            mesh = trimesh.load_mesh(path, process=False)
            if isinstance(mesh, trimesh.Scene):  # several bodies: one mesh
                mesh = trimesh.util.concatenate(list(mesh.dump()))
            vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
        else:
            m = read_meshio(path)
            vertices = np.asarray(m.points, float)[:, :3] if m.points.ndim == 2 else np.zeros((0, 3))
            tris = [c.data for c in m.cells if c.type == "triangle"]
            tris += [q[:, idx] for q in (c.data for c in m.cells if c.type == "quad") for idx in ([0, 1, 2], [0, 2, 3])]
            faces = np.concatenate(tris).astype(np.int64) if tris else np.zeros((0, 3), np.int64)
    except MeshError:
        raise
    except Exception as err:  # the readers raise assorted types on unreadable files, their words may quote it
        why = str(err) if isinstance(err, UnreadableMesh) else type(err).__name__
        raise MeshError(f"path: cannot read {name!r} as a triangle mesh ({why})") from None
    if faces.ndim != 2 or faces.shape[0] == 0 or faces.shape[1] != 3:
        raise MeshError(f"path: {name!r} holds no triangles")
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError(f"path: {name!r} has faces that refer to missing vertices")
    used = np.zeros(len(vertices), bool)
    used[faces] = True
    vertices, faces = vertices[used], (np.cumsum(used) - 1)[faces]  # only the vertices of faces
    if not np.isfinite(vertices).all():
        raise MeshError(f"path: {name!r} has non-finite vertex coordinates")
    # merge coincident vertices (STL stores every corner): equal bits (-0.0 made 0.0), found
    # by sorting a hash of them; a hash collision between different points is checked for
    v = vertices + 0.0
    bits = v.view(np.uint64)
    key = _mix(_mix(_mix(bits[:, 0]) ^ bits[:, 1]) ^ bits[:, 2])
    order = np.argsort(key, kind="stable")
    ks, vs = key[order], v[order]
    new = np.r_[True, ks[1:] != ks[:-1]]
    if (vs[1:][~new[1:]] != vs[:-1][~new[1:]]).any():  # a collision: sort the coordinates themselves
        order = np.lexsort(v.T[::-1])
        vs = v[order]
        new = np.r_[True, (vs[1:] != vs[:-1]).any(1)]
    index = np.empty(len(v), np.int64)
    index[order] = np.cumsum(new) - 1
    return vs[new], index[faces]


def read_meshio(path):
    """``meshio.read(path)`` with what its readers print kept off the terminal, and its
    exit when none can read the file raised as UnreadableMesh saying so, or naming the
    failing reader's error type: never its words, which may quote the file."""
    import contextlib
    import io

    import meshio

    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            return meshio.read(path)
    except (Exception, SystemExit) as err:  # its readers raise anything from ReadError to IndexError, or exit
        raise UnreadableMesh("no meshio reader understands it" if isinstance(err, SystemExit) else
                             f"meshio: {type(err).__name__}") from None


def _mix(u: np.ndarray) -> np.ndarray:
    """The splitmix64 finaliser of uint64 array ``u``: every input bit moves every output bit
    (float bits end in zeros, which a bare multiply would keep)."""
    u = (u ^ (u >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    u = (u ^ (u >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return u ^ (u >> np.uint64(31))


def _rotation_to_z(d) -> np.ndarray:
    """The rotation (3, 3) taking unit vector ``d`` onto +z by the shortest arc."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(d @ z)
    if c < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])  # half a turn about x
    v = np.cross(d, z)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1 + c)


def _edges(faces: np.ndarray, name: str):
    """Per face and edge k (corner k to k + 1) the face across it (-1 on a boundary); raises
    on edges shared by more than two faces or wound the same way by both."""
    nf = faces.shape[0]
    a = faces.reshape(-1)
    b = faces[:, [1, 2, 0]].reshape(-1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * (faces.max() + 1) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    count = np.diff(np.r_[start, ks.size])
    if (count > 2).any():
        raise MeshError(f"path: {name!r} is not manifold: {int((count > 2).sum())} edges are shared by more "
                        "than two faces")
    pairs = start[count == 2]
    h1, h2 = order[pairs], order[pairs + 1]  # half-edges (face * 3 + k)
    same = a[h1] == a[h2]
    if same.any():
        raise MeshError(f"path: {name!r} has inconsistent normals: {int(same.sum())} edges are wound the same "
                        "way by both their faces (fix the winding, e.g. trimesh.repair.fix_normals)")
    nb = np.full(3 * nf, -1, np.int64)
    nb[h1], nb[h2] = h2 // 3, h1 // 3
    return nb.reshape(nf, 3)


def _order(centroids: np.ndarray, leaves: int) -> np.ndarray:
    """Face order of the hierarchy: the faces (centroids (nf, 3)) padded to ``leaves`` *
    LEAF slots, each node's slots split at their middle along the longest axis of its
    centroids' box (a median split, level by level in numpy); padding sorts last."""
    nf = centroids.shape[0]
    total = leaves * mq.LEAF
    # per slot: the centroid for minima (padding +inf: never a minimum, sorts last), then
    # its negative for maxima (padding +inf again), in float32 to halve the traffic
    c = np.full((total, 6), np.inf, np.float32)
    c[:nf, :3], c[:nf, 3:] = centroids, -centroids
    idx = np.arange(total)
    span = total
    while span > mq.LEAF:
        rows = total // span
        c, idx = c.reshape(rows, span, 6), idx.reshape(rows, span)
        m = c.min(1)
        axis = np.argmax(-m[:, 3:] - m[:, :3], axis=1)
        key = np.take_along_axis(c, axis[:, None, None], axis=2)[..., 0]
        part = np.argpartition(key, span // 2 - 1, axis=1)
        c = np.take_along_axis(c, part[..., None], axis=1).reshape(total, 6)
        idx = np.take_along_axis(idx, part, axis=1).ravel()
        span //= 2
    return idx[:nf]


def _boxes(tri: np.ndarray, leaves: int) -> np.ndarray:
    """Node boxes (2 L - 1, 6) of the complete tree of L = ``leaves`` leaves over faces ``tri``
    (nf, 3, 3) in order, ``LEAF`` per leaf."""
    nf = tri.shape[0]
    fb = np.empty((leaves * mq.LEAF, 6))
    fb[:, :3], fb[:, 3:] = np.inf, -np.inf
    fb[:nf, :3], fb[:nf, 3:] = tri.min(1), tri.max(1)
    fb = fb.reshape(leaves, mq.LEAF, 6)
    level = np.concatenate([fb[:, :, :3].min(1), fb[:, :, 3:].max(1)], axis=1)
    boxes = np.empty((2 * leaves - 1, 6))
    width = leaves
    while True:
        boxes[width - 1:2 * width - 1] = level
        if width == 1:
            return boxes
        pair = level.reshape(width // 2, 2, 6)
        level = np.concatenate([pair[:, :, :3].min(1), pair[:, :, 3:].max(1)], axis=1)
        width //= 2


def _cell_grid(tri: np.ndarray, cell: float, margin: float, origin: np.ndarray):
    """The cell grid of faces ``tri`` (nf, 3, 3) mm: the hash table's size (a power of 2, for
    the home slots), the table (at least that many rows, 3) [key, first, end] and the face
    lists of ``meshquery`` (in no particular order within a cell). A face is listed in every
    cell its box, widened by 1.01 ``margin`` (a margin over the round-off of the cells'
    bounds), overlaps; no cell at all beyond GRID_BUDGET entries a face."""
    wide = 1.01 * margin
    lo = np.floor((tri.min(1) - wide - origin) / cell).astype(np.int64)
    hi = np.floor((tri.max(1) + wide - origin) / cell).astype(np.int64)
    n = hi - lo + 1
    if n.prod(1).sum() > GRID_BUDGET * tri.shape[0]:
        return 1, np.full((2, 3), -1.0), np.zeros(0)  # no cell: one home slot, empty
    keys, faces = [], []
    # the cells of every face by offset (dx, dy, dz) from its lowest one: each offset takes the
    # faces that reach that far (most faces span 1-3 cells an axis), so the work is the entries
    every = np.arange(tri.shape[0])
    for dz in range(int(n[:, 2].max())):
        fz = every[n[every, 2] > dz]
        for dy in range(int(n[fz, 1].max(initial=0))):
            fy = fz[n[fz, 1] > dy]
            for dx in range(int(n[fy, 0].max(initial=0))):
                f = fy[n[fy, 0] > dx]
                keys.append((lo[f, 0] + dx) + mq.GRID_AXIS * ((lo[f, 1] + dy) + mq.GRID_AXIS * (lo[f, 2] + dz)))
                faces.append(f)
    key, face = np.concatenate(keys), np.concatenate(faces)
    del keys, faces
    order = np.argsort(key)
    key, face = key[order], face[order]
    del order
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    end = np.r_[first[1:], key.size]
    cx, cy, cz = key[first] % mq.GRID_AXIS, key[first] // mq.GRID_AXIS % mq.GRID_AXIS, key[first] // mq.GRID_AXIS**2
    slots = 1 << int(math.ceil(math.log2(1.25 * first.size)))
    home = ((cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)) & (slots - 1)  # meshquery._cell_hash
    # linear probing without wrap-around: in the order of their home slots, each cell takes the
    # first free slot from its home on (slot i = i + the running max of home - i), so the slots
    # from a cell's home to its own are all taken; the table ends with an empty slot
    by_home = np.argsort(home, kind="stable")
    rank = np.arange(first.size)
    slot = rank + np.maximum.accumulate(home[by_home] - rank)
    table = np.full((int(slot[-1]) + 2, 3), -1.0)
    table[slot] = np.stack([key[first[by_home]], first[by_home], end[by_home]], 1)
    return slots, table, face


def pack(vertices: np.ndarray, faces: np.ndarray, name: str = "mesh", edge_blend_mm: float = EDGE_BLEND_MM,
         offset_mm: float = 0.0) -> np.ndarray:
    """The packed array of ``meshquery`` for a checked mesh (mm, outward-wound faces):
    faces sorted into the hierarchy's order, vertices into their faces', neighbours, vertex
    normals, crease flags; its queries describe the surface ``offset_mm`` outside it (the
    cell grid's margin widened by as much, so that a query there is answered from its cell)."""
    tri = vertices[faces]
    leaves = 1 << max(int(math.ceil(math.log2(max(math.ceil(faces.shape[0] / mq.LEAF), 1)))), 0)
    order = _order(tri.mean(1), leaves)
    faces, tri = faces[order], tri[order]
    # vertices numbered in the order the hierarchy's faces first use them, so that a query's
    # faces find their corners close together in memory
    _, first = np.unique(faces, return_index=True)
    used = np.argsort(first)
    number = np.empty(vertices.shape[0], np.int64)
    number[used] = np.arange(used.size)
    vertices, faces = vertices[used], number[faces]
    nf, nv = faces.shape[0], vertices.shape[0]
    nb = _edges(faces, name)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    fn = cross / np.linalg.norm(cross, axis=1, keepdims=True)
    # angle at each corner, weighting the face normal into the vertex normal
    e_next = tri[:, [1, 2, 0]] - tri
    e_prev = tri[:, [2, 0, 1]] - tri
    cosang = np.einsum("fki,fki->fk", e_next, e_prev) / (
        np.linalg.norm(e_next, axis=2) * np.linalg.norm(e_prev, axis=2))
    angle = np.arccos(np.clip(cosang, -1.0, 1.0))
    vn = np.stack([np.bincount(faces.ravel(), (angle[..., None] * fn[:, None, :])[..., c].ravel(), nv)
                   for c in range(3)], axis=1)
    length = np.linalg.norm(vn, axis=1, keepdims=True)
    vn = vn / np.where(length > 0, length, 1.0)
    creased = np.einsum("fi,fki->fk", fn, vn[faces]) < math.cos(math.radians(CREASE_DEG))
    vb = np.zeros(nv)
    boundary = nb < 0
    vb[faces[boundary]] = 1.0
    vb[faces[:, [1, 2, 0]][boundary]] = 1.0
    boxes = _boxes(tri, leaves)
    size = 0.5 * float(np.ptp(vertices, 0).max())
    edge = float(np.median(np.linalg.norm(e_next, axis=2)))
    cell = max(GRID_CELL * edge, 2 * size / (mq.GRID_AXIS - 8))  # a cell no smaller than the grid allows
    margin = GRID_MARGIN * edge + offset_mm
    origin = vertices.min(0) - 2 * margin - cell
    slots, table, lists = _cell_grid(tri, cell, margin, origin)
    parts = [tri, np.where(creased, -faces - 1, faces), nb, vn, vb, boxes, table, lists]
    head = np.zeros(mq.HEADER)
    head[[mq.NV, mq.NF, mq.LEAVES]] = nv, nf, leaves
    offsets = np.cumsum([mq.HEADER] + [p.size for p in parts[:-1]])
    head[[mq.OFF_TRI, mq.OFF_F, mq.OFF_NB, mq.OFF_VN, mq.OFF_VB, mq.OFF_BOX, mq.OFF_HASH, mq.OFF_LIST]] = offsets
    head[mq.ON_TOL] = ON_TOLERANCE * size
    head[mq.SCALE] = size
    head[mq.COS_CREASE] = math.cos(math.radians(CREASE_DEG))
    head[mq.EDGE_BLEND] = edge_blend_mm
    head[mq.REACH] = MEMO_REACH * edge
    head[mq.OFFSET] = offset_mm
    head[[mq.GRID_CELL, mq.GRID_MARGIN, mq.GRID_X0, mq.GRID_Y0, mq.GRID_Z0, mq.GRID_SLOTS]] = (
        cell, margin, *origin, slots)
    return np.concatenate([head] + [np.asarray(p, float).ravel() for p in parts])


def _oriented(vertices, faces, nb):
    """``faces`` wound so their normals point out of a closed mesh (positive volume) or, for an
    open sheet, up (+z, towards the blank) on average."""
    tri = vertices[faces]
    if (nb >= 0).all():
        turned = np.einsum("fi,fi->f", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() < 0
    else:
        turned = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2].sum() < 0
    return faces[:, ::-1].copy() if turned else faces


class MeshSurface(Surface):
    """A mould from a triangle-mesh file: any surface, vertical walls and undercuts included.

    ``path``            the mesh file (STL, OBJ, PLY, OFF; any surface meshio reads)
    ``units``           the file's length unit: "mm", "m" or "in"
    ``press_direction`` the direction (in the file's frame) that becomes +z: the tool's "up",
                        towards the incoming blank; the mesh is turned by the shortest arc
                        onto it. The solver, its result files and the report's plots work in
                        this frame; VTK and FE exports are turned back into the file's
                        frame (``to_tool``; mm, whatever ``units``)
    ``edge_blend_mm``   half-width (mm) of the band either side of a sharp edge (faces meeting
                        beyond CREASE_DEG) where a node's tangent plane turns from one face's
                        to the other's, as over a rounded edge; nodes stay on the sharp mesh.
                        At least a fifth of the fibre spacing, so that a node next to a right-
                        angled edge finds the next one over it (within 89 deg of its tangent)

    A closed mesh is wound outward, an open sheet so that it faces +z. The crossover is
    placed at the top of the mesh over its plan position (the blank's first contact);
    ``height``, ``inside`` and ``normal`` describe that top surface for plots and exports.
    """

    name = "mesh"

    def __init__(self, path, units: str = "mm", press_direction=(0.0, 0.0, 1.0), edge_blend_mm: float = EDGE_BLEND_MM):
        self.path = Path(path)
        name = str(self.path)
        if not isinstance(units, str) or units not in UNITS:
            raise ParameterError("units", f"units must be one of {', '.join(UNITS)}, got {units!r}")
        self.units = units
        if isinstance(press_direction, str):  # "x,y,z", as a command-line --param gives it
            press_direction = press_direction.split(",")
        try:
            d = np.asarray(press_direction, float).reshape(3)
        except (TypeError, ValueError):
            d = np.full(3, np.nan)
        if not (np.isfinite(d).all() and np.linalg.norm(d) > 0):
            raise ParameterError("press_direction", f"press_direction must be a non-zero 3-vector, got {press_direction!r}")
        self.press_direction = [float(c) for c in d]
        try:
            blend = float(edge_blend_mm)
        except (TypeError, ValueError):
            blend = math.nan
        if not (math.isfinite(blend) and 0 <= blend <= MAX_LENGTH_MM):
            raise ParameterError("edge_blend_mm", f"edge_blend_mm must be a length >= 0 in mm, got {edge_blend_mm!r}")
        self.edge_blend_mm = blend
        vertices, faces = _read(self.path)
        R = _rotation_to_z(d / np.linalg.norm(d))
        self.tool_rotation = None if (R == np.eye(3)).all() else R
        vertices = vertices * UNITS[units] @ R.T
        extent = float(np.ptp(vertices, 0).max())
        if not extent <= MAX_LENGTH_MM:
            raise MeshError(f"path: {name!r} is {extent:.3g} mm across in {units}, more than "
                            f"{MAX_LENGTH_MM:g} mm (a 100 m tool): check units")
        if not extent >= 1e-3:
            raise MeshError(f"path: {name!r} is {extent:.3g} mm across: no extent (check units)")
        tri = vertices[faces]
        area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        bad = area2 <= 1e-12 * extent**2
        if bad.any():
            raise MeshError(f"path: {name!r} has {int(bad.sum())} degenerate (zero-area) triangles, the first "
                            f"face {int(np.flatnonzero(bad)[0])}")
        faces = _oriented(vertices, faces, _edges(faces, name))
        self.faces_count = int(faces.shape[0])
        self.kernel = (compiled.MESH, pack(vertices, faces, name, blend))
        lo, hi = vertices.min(0), vertices.max(0)
        self.bounds = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
        self.size = 0.5 * extent

    def _kernel(self, d):
        v, f, _ = self.triangles()
        return compiled.MESH, pack(v, f, str(self.path), self.edge_blend_mm, d)

    def params(self):
        return self._with_offset({"path": str(self.path), "units": self.units, "press_direction": self.press_direction,
                                  "edge_blend_mm": self.edge_blend_mm})

    def describe(self) -> str:
        """The mould in words: its file, units and press direction (and a blend other than
        the default), e.g. "mesh pan.stl (mm, press +z)"."""
        d = self.press_direction
        axis = [k for k in range(3) if d[k] != 0]
        press = (("+" if d[axis[0]] > 0 else "-") + "xyz"[axis[0]] if len(axis) == 1
                 else "(" + ", ".join(f"{c:g}" for c in d) + ")")
        blend = "" if self.edge_blend_mm == EDGE_BLEND_MM else f", edge blend {self.edge_blend_mm:g} mm"
        offset = f", offset {self.offset_mm:g} mm" if self.offset_mm else ""
        return f"mesh {self.path.name} ({self.units}, press {press}{blend}{offset})"

    def normal_at(self, points):
        """The solver's unit normal (..., 3) at points (..., 3) mm on the mesh (NaN in, NaN out)."""
        return compiled.evaluate_normal(self.kernel, points)

    def project(self, points):
        """Foot points (M, 3) on the mesh of points (M, 3) mm, their signed distances (M,) mm
        and whether each has one (finite), the mesh's closest points: the way to carry
        points onto a mould whose walls have no plan position."""
        points = np.ascontiguousarray(points, float).reshape(-1, 3)
        foot, phi = np.empty_like(points), np.empty(len(points))
        mq.closest_many(self.kernel[1], points, foot, phi)
        return foot, phi, np.isfinite(phi)

    def triangles(self):
        """The mesh in the solver frame: vertices (nv, 3) mm, faces (nf, 3) in the hierarchy's
        order and the vertex normals (nv, 3), read back from the packed array."""
        p = self.kernel[1]
        nv, nf = int(p[mq.NV]), int(p[mq.NF])
        f = p[int(p[mq.OFF_F]):int(p[mq.OFF_F]) + 3 * nf].reshape(nf, 3).astype(np.int64)
        f = np.where(f < 0, -f - 1, f)
        v = np.empty((nv, 3))
        v[f.ravel()] = p[int(p[mq.OFF_TRI]):int(p[mq.OFF_TRI]) + 9 * nf].reshape(-1, 3)  # every vertex is a corner
        vn = p[int(p[mq.OFF_VN]):int(p[mq.OFF_VN]) + 3 * nv].reshape(nv, 3)
        return v, f, vn

    def distance(self, points):
        """Unsigned distance (mm) of points (..., 3) from the mesh."""
        return np.abs(self.gap(points[..., 0], points[..., 1], points[..., 2])[0])


def _grid(lo: float, hi: float, step: float) -> np.ndarray:
    """Nodes from lo to hi inclusive, evenly spaced at most ``step`` apart (at least 4)."""
    n = max(int(math.ceil((hi - lo) / step - 1e-9)) + 1, 4)
    return np.linspace(lo, hi, n)


def export_stl(surface: Surface, path, half_width: float | None = None, resolution_mm: float = 2.0) -> Path:
    """Write ``surface``'s height field as a binary STL (mm); returns the path.

    The field is triangulated on a regular plan grid (spacing at most ``resolution_mm``)
    over the square |x|, |y| <= ``half_width`` if given, else over ``surface.bounds``;
    two triangles per grid cell, kept where all three corners are ``inside`` the
    domain, facing up. Only the top surface is written (an open sheet, not a solid).
    """
    res = float(resolution_mm)
    if not (math.isfinite(res) and res > 0):
        raise ValueError(f"resolution_mm must be a positive length in mm, got {resolution_mm!r}")
    if half_width is not None:
        w = float(half_width)
        if not (math.isfinite(w) and w > 0):
            raise ValueError(f"half_width must be a positive length in mm, got {half_width!r}")
        xmin, xmax, ymin, ymax = -w, w, -w, w
    else:
        try:
            xmin, xmax, ymin, ymax = surface.bounds
        except AttributeError:
            raise ValueError(
                f"half_width is required: {type(surface).__name__} has no bounds"
            ) from None
    xg, yg = _grid(xmin, xmax, res), _grid(ymin, ymax, res)
    X, Y = np.meshgrid(xg, yg, indexing="ij")
    vertices = np.stack([X, Y, surface.height(X, Y)], axis=-1).reshape(-1, 3)
    ok = np.asarray(surface.inside(X, Y)).ravel()
    node = np.arange(X.size).reshape(X.shape)
    a, b = node[:-1, :-1].ravel(), node[1:, :-1].ravel()  # (i, j), (i+1, j)
    c, d = node[1:, 1:].ravel(), node[:-1, 1:].ravel()  # (i+1, j+1), (i, j+1)
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    faces = faces[ok[faces].all(axis=1)]
    if faces.size == 0:
        raise ValueError("no triangle lies inside the surface's domain; check half_width")
    import trimesh

    out = Path(path)
    trimesh.Trimesh(vertices=vertices, faces=faces, process=False).export(out, file_type="stl")
    return out
