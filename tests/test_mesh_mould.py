"""Moulds from triangle meshes (issue 23): the node solver on a mesh's signed distance, the
closed-form sphere net on triangulated spheres, developables, walls no height field holds,
the root kept where a circle cuts the surface twice, batching, and bad mesh files.
Lengths mm, angles degrees."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from uqdrape.drape import kernels
from uqdrape.geometry import MeshSurface


def _save(mesh: trimesh.Trimesh, path) -> str:
    mesh.export(path)
    return str(path)


# -- the root on the net's own sheet -------------------------------------------------------
@pytest.fixture(scope="module")
def thin_plate(tmp_path_factory):
    """A closed plate 100 x 100 x 1 mm, top face z = 0, bottom face z = -1."""
    box = trimesh.creation.box(extents=(100.0, 100.0, 1.0))
    box.apply_translation((0.0, 0.0, -0.5))
    return MeshSurface(_save(box, tmp_path_factory.mktemp("plate") / "plate.stl"))


def test_a_circle_through_a_thin_plate_keeps_the_crossing_on_the_net_s_side(thin_plate):
    """Circle q(t) = (0, 0, -1.5) + 2 (cos t (1, 0, 0) + sin t (0, 0, 1)): it enters the plate
    through the bottom face at t = asin(0.25) = 14.5 deg (phi falling: the plate seen from
    inside) and leaves through the top at t = asin(0.75) = 48.6 deg (phi rising). Facing +t
    the nearer crossing is skipped for the top; facing -t the bottom is the root."""
    kind, par = thin_plate.kernel
    args = (kind, par, (0.0, 0.0, -1.5), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), 2.0, 1e-10)
    q, ok, grad = kernels._solve_on_circle(*args, 1.0)
    assert ok and q == pytest.approx((2.0 * np.cos(np.arcsin(0.75)), 0.0, 0.0), abs=1e-9)
    assert grad == pytest.approx((0.0, 0.0, 1.0))
    q, ok, grad = kernels._solve_on_circle(*args, -1.0)
    assert ok and q == pytest.approx((2.0 * np.cos(np.arcsin(0.25)), 0.0, -1.0), abs=1e-9)
    assert grad == pytest.approx((0.0, 0.0, -1.0))


def test_a_circle_that_only_enters_the_plate_has_no_root(thin_plate):
    """Circle (0, 0, -3) + 2.5 (cos t (1, 0, 0) + sin t (0, 0, 1)) meets the plate only where it
    enters its bottom face from below (t = asin(0.8)): no root on a sheet facing +t."""
    kind, par = thin_plate.kernel
    args = (kind, par, (0.0, 0.0, -3.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), 2.5, 1e-10)
    q, ok, _ = kernels._solve_on_circle(*args, 1.0)
    assert not ok
    q, ok, _ = kernels._solve_on_circle(*args, -1.0)
    assert ok and q == pytest.approx((1.5, 0.0, -1.0), abs=1e-9)
