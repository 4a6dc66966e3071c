"""Fibre directions and shear of a drape on the elements of an FE surface mesh.

Each element's centroid (mean of its corner nodes) is moved along the mould normal onto
the mould, located in a cell of the draped net in plan (each quad split into two
triangles along its (i, j)-(i+1, j+1) diagonal) and given the net's node values by
linear barycentric interpolation: exact for fields linear in plan position, error
O(s^2) for smooth fields at spacing s. On a mesh mould, whose walls have no plan
position, the centroid goes to its closest point on the mesh and is located on the
nearest net triangle in space (within half the tolerance; farther is off the net). The fibre directions are interpolated, laid on
the mould's tangent plane and opened to 90 deg - the interpolated shear
(``fibre_frame``). Elements are never dropped: ``map_status`` says why one has no values.
Both yarns are then given in each element's own frame (``elements``) and written in the
cards of each FE solver flavour asked for (``cards``); an ensemble adds the P5/P50/P95
of each yarn angle over its drapes, each drape mapped as the nominal net is.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path

import meshio
import numpy as np
from scipy.spatial import cKDTree

from ..drape.net import net_quads
from .cards import FLAVOURS, WRITERS, Cards
from .directions import dot, fibre_directions, fibre_frame
from .elements import ANGLE_QUANTILES, axial_quantiles, corner_nodes, element_frames, with_defaults, yarn_angles
from ..files import check_input_file, write_all
from ..geometry.mesh import MAX_MESH_BYTES, UnreadableMesh, read_meshio
from .keyword import LABELS, SUFFIXES as KEYWORD_SUFFIXES, read_keyword
from .result import Level, surface_of

SURFACE_CELLS = {"triangle": 3, "triangle6": 3, "triangle7": 3, "quad": 4, "quad8": 4, "quad9": 4}
VOLUME_CELLS = ("tetra", "hexahedron", "wedge", "pyramid")
#: map_status codes of an element
ON_NET, OFF_NET, OFF_MOULD = 0, 1, 2
#: Net cells tried per element (nearest by plan centroid) when locating it.
CANDIDATES = 16


def read_surface_mesh(path) -> tuple[meshio.Mesh, list]:
    """The mesh at ``path`` (any format meshio reads, or an LS-DYNA keyword file: ``keyword``)
    and its surface cell blocks; raises FileNotFoundError / ValueError naming the path for a
    missing, unreadable or volume mesh."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such mesh file")
    check_input_file(path, "mesh file", MAX_MESH_BYTES, error=ValueError)
    try:
        mesh = read_keyword(path) if path.suffix.lower() in KEYWORD_SUFFIXES else read_meshio(path)
    except UnreadableMesh as err:
        raise ValueError(f"{path}: cannot read it as a mesh ({err})") from None
    volume = sorted({b.type for b in mesh.cells if b.type.startswith(VOLUME_CELLS)})
    if volume:
        raise ValueError(f"{path}: a volume mesh ({', '.join(volume)} cells); fibre directions map onto "
                         "a surface (shell) mesh of triangles or quads")
    blocks = [b for b in mesh.cells if b.type in SURFACE_CELLS]
    if not blocks:
        raise ValueError(f"{path}: no triangle or quad cells (found: "
                         f"{', '.join(sorted({b.type for b in mesh.cells})) or 'none'})")
    return mesh, blocks


def element_labels(path, mesh: meshio.Mesh, blocks) -> np.ndarray:
    """Labels (M,) of the elements of the surface ``blocks``: an Abaqus input's own element
    numbers (its ``*ELEMENT`` data lines, which meshio reads in order, one cell block per
    keyword, but does not keep), an LS-DYNA keyword file's EIDs, else 1-based positions in
    the mesh file's order."""
    path = Path(path)
    if LABELS in mesh.cell_data:
        return np.concatenate([ids for ids, b in zip(mesh.cell_data[LABELS], mesh.cells) if b.type in SURFACE_CELLS])
    if path.suffix.lower() != ".inp":
        return np.arange(1, sum(len(b.data) for b in blocks) + 1)
    numbers, current = [], None
    for lineno, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        if line.startswith("*"):
            keyword = line.partition(",")[0].strip().lstrip("*").upper()
            current = [] if keyword == "ELEMENT" else None
            if current is not None:
                numbers.append(current)
        elif current is not None and line.strip():
            try:
                current += [int(k) for k in line.split(",") if k.strip()]
            except ValueError:
                raise ValueError(f"{path}: line {lineno}: expected an *ELEMENT data line, integers "
                                 "label,node,node,...") from None
    if len(numbers) != len(mesh.cells):
        raise ValueError(f"{path}: {len(numbers)} *ELEMENT blocks but meshio read {len(mesh.cells)} cell blocks; "
                         "cannot tell the element labels")
    return np.concatenate([np.reshape(ints, (-1, b.data.shape[1] + 1))[:, 0]
                           for ints, b in zip(numbers, mesh.cells) if b.type in SURFACE_CELLS])


def centroids(mesh: meshio.Mesh, blocks) -> np.ndarray:
    """Centroids (M, 3) mm of the corner nodes of every cell of ``blocks``, in order."""
    return np.concatenate([mesh.points[b.data[:, :SURFACE_CELLS[b.type]]].mean(1) for b in blocks])


def onto_mould(surface, c: np.ndarray, iterations: int = 30):
    """Foot points on the mould of the points ``c`` (M, 3) moved along the mould normal:
    (plan positions (M, 2) mm, signed distance along the normal (M,) mm, inside domain);
    on a mesh mould, whose walls have no plan position, the closest points (M, 3) instead."""
    if hasattr(surface, "project"):
        return surface.project(c)
    xy = c[:, :2].copy()
    for _ in range(iterations):
        n = surface.normal(xy[:, 0], xy[:, 1])
        h = surface.height(xy[:, 0], xy[:, 1])
        d = dot(c - np.column_stack([xy, h]), n)
        xy = c[:, :2] - d[:, None] * n[:, :2]
    return xy, d, surface.inside(xy[:, 0], xy[:, 1])


def foot_normal(surface, foot) -> np.ndarray:
    """The mould's unit normal (M, 3) at ``onto_mould``'s foot points."""
    xy = foot[0]
    return surface.normal_at(xy) if xy.shape[1] == 3 else surface.normal(xy[:, 0], xy[:, 1])


def _candidates(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Indices (M, k) of the k = min(CANDIDATES, T) triangles of ``tri`` (T, 3, d) whose
    centroids lie nearest each of the points (M, d)."""
    k = min(CANDIDATES, len(tri))
    return cKDTree(tri.mean(1)).query(points, k=k)[1].reshape(len(points), k)


def locate_on(points: np.ndarray, tri: np.ndarray, reach: float):
    """Triangle index (M,) (-1: none within ``reach`` mm) and barycentric weights (M, 3) of
    the points (M, 3) on their nearest of the triangles ``tri`` (T, 3, 3) in space."""
    import trimesh

    cand = _candidates(points, tri)
    k = cand.shape[1]
    near = trimesh.triangles.closest_point(tri[cand.ravel()], np.repeat(points, k, axis=0)).reshape(-1, k, 3)
    dist = np.linalg.norm(near - points[:, None], axis=-1)
    best = np.argmin(dist, axis=1)
    rows = np.arange(len(points))
    pick = cand[rows, best]
    lam = trimesh.triangles.points_to_barycentric(tri[pick], near[rows, best])
    return np.where(dist[rows, best] <= reach, pick, -1), lam


def locate(points: np.ndarray, tri_xy: np.ndarray):
    """Triangle index (M,) (-1: none) and barycentric weights (M, 3) of plan ``points``
    (M, 2) in the triangles ``tri_xy`` (T, 3, 2)."""
    cand = _candidates(points, tri_xy)
    a, b, c = (tri_xy[cand, m] for m in range(3))
    v0, v1, v2 = b - a, c - a, points[:, None, :] - a
    det = v0[..., 0] * v1[..., 1] - v0[..., 1] * v1[..., 0]
    det[det == 0.0] = np.nan  # a triangle seen edge-on in plan (a vertical face) holds no point: nan weights
    l1 = (v2[..., 0] * v1[..., 1] - v2[..., 1] * v1[..., 0]) / det
    l2 = (v0[..., 0] * v2[..., 1] - v0[..., 1] * v2[..., 0]) / det
    lam = np.stack([1 - l1 - l2, l1, l2], axis=-1)
    inside = lam.min(-1) >= -1e-9
    first = np.argmax(inside, axis=1)
    found = inside[np.arange(len(points)), first]
    rows = np.arange(len(points))
    return np.where(found, cand[rows, first], -1), lam[rows, first]


def map_level(level: Level, surface, mesh_centroids: np.ndarray, tolerance_mm: float, foot=None) -> dict:
    """Element values of one level: fibre1, fibre2 (M, 3), shear (deg), the ensemble's
    shear_sd and p_locked, map_status and distance_mm (to the mould along its normal);
    ``foot``: the centroids' ``onto_mould`` if already known."""
    return _interpolate(level.positions, level.shear, surface, foot or onto_mould(surface, mesh_centroids),
                        tolerance_mm, level.fields)


def _interpolate(P: np.ndarray, shear: np.ndarray, surface, foot, tolerance_mm: float, fields=None) -> dict:
    """The net with node positions ``P`` (N, N, 3) mm and ``shear`` (N, N) deg interpolated
    at the elements' foot points ``foot`` (see ``map_level``)."""
    fields = fields or {}
    d1, d2, _ = fibre_directions(P, shear, surface)
    valid = np.isfinite(P).all(-1) & np.isfinite(shear)
    kept, quads = net_quads(valid)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    pts = P.reshape(-1, 3)[kept]
    xy, dist, on_mould = foot
    if xy.shape[1] == 3:  # a mesh mould's foot points, located on the net in space
        tri, lam = (locate_on(xy, pts[tris], 0.5 * tolerance_mm) if len(tris)
                    else (np.full(len(xy), -1), np.zeros((len(xy), 3))))
    else:
        tri, lam = locate(xy, pts[tris, :2]) if len(tris) else (np.full(len(xy), -1), np.zeros((len(xy), 3)))
    near = on_mould & (np.abs(dist) <= tolerance_mm)
    hit = near & (tri >= 0)
    status = np.where(~near, OFF_MOULD, np.where(hit, ON_NET, OFF_NET)).astype(np.int8)
    corner = tris[np.where(hit, tri, 0)]

    def interp(values):
        v = values.reshape(len(P) ** 2, *values.shape[2:])[kept][corner]
        w = lam.reshape(lam.shape + (1,) * (v.ndim - 2))
        out = (w * v).sum(1)
        out[~hit] = np.nan
        return out

    normal = foot_normal(surface, foot)
    shear_e = interp(shear)
    with np.errstate(invalid="ignore"):
        e1, e2 = fibre_frame(interp(d1), interp(d2), normal, shear_e)
    out = {"fibre1": e1, "fibre2": e2, "shear": shear_e}
    for name in ("shear_sd", "p_locked"):
        if name in fields:
            out[name] = interp(fields[name])
    out.update(map_status=status, distance_mm=dist)
    return out


def _vtu(tmp: Path, mesh: meshio.Mesh, blocks, values: dict) -> None:
    sizes = np.cumsum([0] + [len(b.data) for b in blocks])
    cell_data = {name: [v[a:b] for a, b in zip(sizes[:-1], sizes[1:])] for name, v in values.items()}
    meshio.write(tmp, meshio.Mesh(mesh.points, blocks, cell_data=cell_data), file_format="vtu")


def drape_angles(data, surface, foot, tolerance_mm: float, frame) -> dict:
    """Yarn angles ``theta1``, ``theta2`` (R, M) deg in the element ``frame`` (solver axes)
    of each drape of ``data`` (a drape Dataset, dims realization, i, j), each mapped onto
    the elements at their ``foot`` points as the nominal net is; NaN where a drape's net
    does not reach an element."""
    placed = data.status.values == 0
    P = np.stack([np.where(placed, data[c].values, np.nan) for c in ("x", "y", "z")], axis=-1)
    shear = np.where(placed, data.shear.values, np.nan)
    normal = foot_normal(surface, foot)
    rows = []
    for r in range(P.shape[0]):
        one = _interpolate(P[r], shear[r], surface, foot, tolerance_mm)
        rows.append(yarn_angles(one["fibre1"], one["fibre2"], normal, frame))
    return {name: np.array([row[name] for row in rows]) for name in ("theta1", "theta2")}


def _ensemble_angles(level: Level, surface, foot, tolerance_mm: float, frame, nominal: dict) -> dict:
    """P5/P50/P95 (``theta1_q05`` ...) of each yarn angle (deg, element frame) over the
    level's drapes (``drape_angles``)."""
    out = {}
    for name, rows in drape_angles(level.data, surface, foot, tolerance_mm, frame).items():
        q = axial_quantiles(rows, nominal[name])
        out.update({f"{name}_q{round(100 * p):02d}": q[k] for k, p in enumerate(ANGLE_QUANTILES)})
    return out


def check_flavours(flavours) -> None:
    """ValueError naming the argument unless ``flavours`` is a non-empty list of ``cards.FLAVOURS``."""
    unknown = [f for f in flavours if f not in FLAVOURS]
    if unknown or not flavours:
        raise ValueError(f"flavours: FE flavour {', '.join(map(str, unknown)) or '(none)'} is not one of "
                         f"{', '.join(FLAVOURS)}")


@dataclass
class MeshOnMould:
    """A surface mesh placed on the mould: the meshio ``mesh`` and its surface ``blocks``,
    element ``labels`` (M,) and ``corners`` (M, 4), the element ``frame`` (e1, e2, e3) in
    the tool's axes and ``solver_frame`` in the solver's, the centroids' ``foot`` points
    (``onto_mould``) and the mould's unit ``normal`` (M, 3) there (solver axes)."""

    mesh: meshio.Mesh
    blocks: list
    labels: np.ndarray
    corners: np.ndarray
    frame: tuple
    solver_frame: tuple
    foot: tuple
    normal: np.ndarray


def tolerance_of(ds, tolerance_mm: float | None) -> float:
    """How far (mm) from the mould an element may lie: ``tolerance_mm``, by default the
    fibre spacing of result ``ds``; ValueError unless a distance > 0."""
    tol = float(ds.attrs["spacing_mm"]) if tolerance_mm is None else float(tolerance_mm)
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tolerance must be a distance > 0 mm, got {tolerance_mm!r}")
    return tol


def mesh_on_mould(mesh_path, surface, tolerance_mm: float) -> MeshOnMould:
    """The surface mesh at ``mesh_path`` (tool frame, mm) on ``surface``; ValueError if its
    median element lies farther than ``tolerance_mm`` from the mould along its normal."""
    mesh, blocks = read_surface_mesh(mesh_path)
    corners = corner_nodes(blocks)
    frame = element_frames(mesh.points, corners)
    # the FE mesh is in the tool's frame; mapping runs in the solver's, results go back
    foot = onto_mould(surface, surface.to_solver(centroids(mesh, blocks)))
    far = np.median(np.abs(foot[1]))
    if not far <= tolerance_mm:
        raise ValueError(f"{mesh_path}: its elements lie {far:.4g} mm (median) from the mould along its "
                         f"normal, more than the tolerance {tolerance_mm:g} mm: is the mesh in mm and in the "
                         "mould's coordinates?")
    return MeshOnMould(mesh, blocks, element_labels(mesh_path, mesh, blocks), corners, frame,
                       tuple(surface.to_solver(e) for e in frame), foot, foot_normal(surface, foot))


def fe_files(levels: list[Level], ds, mesh_path, stem, tolerance_mm: float | None = None,
             flavours=("abaqus",)):
    """Map each level onto the surface mesh at ``mesh_path``: writers (for ``write_all``)
    of ``STEM[-LEVEL]-fe.vtu`` (cell data: fibre1, fibre2, shear, [shear_sd, p_locked],
    map_status, distance_mm, and the element-frame yarn1, yarn2, theta1, theta2,
    area_ratio, [theta1_q05 ...]) and of each of ``flavours`` (``cards.FLAVOURS``:
    ``STEM[-LEVEL]-orientations.inp``, ``-lsdyna.k``, ``-nastran.bdf``). ``tolerance_mm``
    (default: the fibre spacing) is how far from the mould an element may lie; a mesh
    whose median element lies farther (wrong units or placement) is an error. The mesh is
    in the tool's frame (a mesh mould's file frame, mm) and so are the vectors written. Returns
    (writers, map_status of each level)."""
    check_flavours(flavours)
    stem = Path(stem)
    surface = surface_of(ds)
    tol = tolerance_of(ds, tolerance_mm)
    on = mesh_on_mould(mesh_path, surface, tol)
    writers, statuses = {}, []
    for level in levels:
        values = map_level(level, surface, None, tol, on.foot)
        values.update(yarn_angles(values["fibre1"], values["fibre2"], on.normal, on.solver_frame))
        values["area_ratio"] = np.cos(np.radians(values["shear"]))
        if level.is_ensemble:
            values.update(_ensemble_angles(level, surface, on.foot, tol, on.solver_frame, values))
        for name in ("fibre1", "fibre2", "yarn1", "yarn2"):
            values[name] = surface.to_tool(values[name])
        base = f"{stem.name}-{level.label}" if level.label else stem.name
        writers[stem.with_name(f"{base}-fe.vtu")] = partial(_vtu, mesh=on.mesh, blocks=on.blocks, values=values)
        source = f"{ds.attrs.get('geometry', 'a drape')}{' at ' + level.label if level.label else ''}"
        cards = Cards(on.labels, on.corners, on.mesh.points, on.frame,
                      with_defaults(values, on.frame, values["map_status"] == ON_NET), source)
        for flavour in dict.fromkeys(flavours):
            writers[stem.with_name(base + FLAVOURS[flavour])] = partial(WRITERS[flavour], cards=cards)
        statuses.append(values["map_status"])
    return writers, statuses


def export_fe(levels: list[Level], ds, mesh_path, stem, tolerance_mm: float | None = None, flavours=("abaqus",)):
    """Write the files of :func:`fe_files`; returns (paths, map_status of each level)."""
    writers, statuses = fe_files(levels, ds, mesh_path, stem, tolerance_mm, flavours)
    return write_all(writers), statuses
