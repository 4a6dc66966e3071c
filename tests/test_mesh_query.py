"""The memoised closest-point query of a mesh mould gives the answer of a query with a fresh
memo to the last bit (``meshquery.closest``): on a curved mesh, on sharp 90-degree edges, on both faces of a
1 mm flange and on a fold, at points on, near and off the mesh, visited in walks whose steps
range from round-off to a few mm, as a node solve visits them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from uqdrape.geometry import MeshSurface
from uqdrape.geometry import meshquery as mq

STUDIES = Path(__file__).resolve().parent.parent / "studies"


def _fold(path: Path) -> Path:
    """A sheet folded back on itself: two 60 x 40 mm strips meeting at x = 0 at 10 degrees."""
    y = np.linspace(-20.0, 20.0, 9)
    x = np.linspace(0.0, 60.0, 13)
    top = np.stack(np.meshgrid(x, y, indexing="ij"), -1).reshape(-1, 2)
    lower = top[top[:, 0] > 0]
    angle = np.radians(10.0)
    v = np.r_[np.c_[top[:, 0], top[:, 1], np.zeros(len(top))],
              np.c_[lower[:, 0] * np.cos(angle), lower[:, 1], -lower[:, 0] * np.sin(angle)]]
    grid = np.arange(len(top)).reshape(len(x), len(y))
    low = np.r_[grid[:1], len(top) + np.arange(len(lower)).reshape(len(x) - 1, len(y))]  # shares the x = 0 edge
    faces = []
    for g, flip in ((grid, False), (low, True)):
        a, b, c, d = g[:-1, :-1].ravel(), g[1:, :-1].ravel(), g[1:, 1:].ravel(), g[:-1, 1:].ravel()
        f = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
        faces.append(f[:, ::-1] if flip else f)
    trimesh.Trimesh(v, np.concatenate(faces), process=False).export(path)
    return path


@pytest.fixture(scope="module")
def moulds(tmp_path_factory):
    folder = tmp_path_factory.mktemp("query")
    plate = trimesh.creation.box(extents=(100.0, 100.0, 1.0))
    trimesh.creation.icosphere(subdivisions=4, radius=100.0).export(folder / "sphere.stl")
    plate.export(folder / "plate.stl")
    return {"sphere": MeshSurface(folder / "sphere.stl"), "thin plate": MeshSurface(folder / "plate.stl"),
            "c-spar": MeshSurface(STUDIES / "meshes" / "cspar.stl"), "fold": MeshSurface(_fold(folder / "fold.stl"))}


def _walks(surface, rng, starts=150, steps=12):
    """Points in walks from points on the mesh, on its edges and off it: each step moves by a
    length drawn log-uniformly from 1e-12 to 3 mm in a random direction."""
    v, f, _ = surface.triangles()
    tri = v[f]
    pick = rng.integers(0, len(f), starts)
    w = rng.dirichlet(np.ones(3), starts)
    w[: starts // 3, 0] = 0.0  # on an edge
    w /= w.sum(1, keepdims=True)
    start = np.einsum("mk,mki->mi", w, tri[pick])
    start[2 * starts // 3:] += rng.normal(0.0, 1.0, (starts - 2 * starts // 3, 3))  # off the mesh
    length = 10.0 ** rng.uniform(-12, np.log10(3.0), (starts, steps, 1))
    step = rng.normal(size=(starts, steps, 3))
    step *= length / np.linalg.norm(step, axis=-1, keepdims=True)
    return (start[:, None, :] + np.cumsum(step, axis=1)).reshape(-1, 3)


@pytest.mark.parametrize("name", ["sphere", "thin plate", "c-spar", "fold"])
def test_memoised_queries_give_the_cold_answer_bitwise(moulds, name):
    surface = moulds[name]
    p = surface.kernel[1]
    points = _walks(surface, np.random.default_rng(7))
    memo = mq.new_memo()
    hits = 0
    for x, y, z in points:
        slot = mq._slot(p, (x, y, z))
        hits += np.sum((memo[slot:slot + 3] - (x, y, z)) ** 2) < memo[slot + 3] ** 2
        warm = mq.closest(p, x, y, z, memo)
        assert warm == mq.closest(p, x, y, z, mq.new_memo())
        assert mq.signed_distance(p, x, y, z, memo) == mq.signed_distance(p, x, y, z, mq.new_memo())
        assert mq.normal(p, x, y, z, memo) == mq.normal(p, x, y, z, mq.new_memo())
    # the walks reach the memo: a third of the queries or more are answered from it
    assert hits > len(points) / 3, hits


@pytest.mark.parametrize("name", ["sphere", "thin plate", "c-spar", "fold"])
def test_the_cell_grid_gives_the_hierarchy_answer_bitwise(moulds, name):
    """A query answered from its grid cell's face list equals the hierarchy's search (the same
    mesh with every grid cell emptied) to the last bit, and near the mesh the grid answers."""
    surface = moulds[name]
    p = surface.kernel[1]
    bare = p.copy()
    table = int(p[mq.OFF_HASH])
    bare[table:int(p[mq.OFF_LIST]):3] = -1.0  # no cell: every query searches the hierarchy
    points = _walks(surface, np.random.default_rng(11))
    answered = 0
    for x, y, z in points:
        grid = mq._grid_search(p, (x, y, z))
        assert mq._grid_search(bare, (x, y, z))[0] == -1
        tree = mq.closest(bare, x, y, z, mq.new_memo())
        if grid[0] >= 0:
            answered += 1
            assert grid[:5] == tree
            assert grid[5] >= grid[4]  # no other face nearer than the answer
        assert mq.closest(p, x, y, z, mq.new_memo()) == tree
        assert mq.signed_distance(p, x, y, z, mq.new_memo()) == mq.signed_distance(bare, x, y, z, mq.new_memo())
    # the walks start on the mesh, on its edges and about 1 mm off it: most points lie within a cell's margin
    assert answered > len(points) / 2, answered


def test_a_mesh_with_a_few_huge_faces_gets_no_grid_and_the_same_answers(tmp_path):
    """A 200 mm triangle standing askew beside a plate of 6 mm edges would fill some 40,000
    cells of the plate's edge length, against 32 a face allowed: the mesh gets no grid (its
    memory stays bounded) and every query searches the hierarchy."""
    plate = trimesh.creation.box(extents=(50.0, 50.0, 1.0)).subdivide().subdivide().subdivide()
    big = trimesh.Trimesh([[100.0, 0.0, 0.0], [300.0, 0.0, 100.0], [100.0, 200.0, 200.0]], [[0, 1, 2]],
                          process=False)
    trimesh.util.concatenate([plate, big]).export(tmp_path / "askew.stl")
    surface = MeshSurface(tmp_path / "askew.stl")
    p = surface.kernel[1]
    assert int(p[mq.OFF_LIST]) - int(p[mq.OFF_HASH]) == 6  # two empty rows
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("uqdrape.geometry.mesh.GRID_BUDGET", 10**9)
        # without the budget the big face fills its cells, and a point on it is answered there
        assert mq._grid_search(MeshSurface(tmp_path / "askew.stl").kernel[1], (160.0, 60.0, 90.0))[0] >= 0
    for x, y, z in _walks(surface, np.random.default_rng(3), starts=30):
        assert mq._grid_search(p, (x, y, z))[0] == -1
        assert mq.closest(p, x, y, z, mq.new_memo())[0] >= 0
