"""The nose-cone profile meshes of ``tools/nosecone_profiles.py`` (issue 24): each revolved
mesh lies on its analytic surface within the chord error its edge lengths allow, has the
apex and base radius asked for, and is a mould uqdrape accepts. No drapes here."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from uqdrape.geometry import MeshSurface, NoseCone

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
import nosecone_profiles as npf  # tools/nosecone_profiles.py, a script of the checkout

R, H = 225.0, NoseCone().tip_height  # the default cone's base radius and height (mm)


def _sagitta_bound(meridian_radius: float) -> float:
    """Largest distance (mm) of a flat facet from a surface of revolution of base radius R
    meshed with meridian chords of STEP_MM on a meridian of curvature radius >=
    ``meridian_radius`` and SECTIONS chords around: the two chords' sagittae added."""
    return (npf.STEP_MM**2 / (8.0 * meridian_radius)
            + R * (1.0 - math.cos(math.pi / npf.SECTIONS)))


def _wall(mesh):
    v = np.asarray(mesh.vertices)
    return v[v[:, 2] > 1e-9]


def test_ogive_radius_of_its_arc():
    # the arc through the apex (0, H) and tangent to r = R at the base: centre (R - rho, 0)
    rho = npf.ogive_rho(R, H)
    assert math.hypot(0.0 - (R - rho), H) == pytest.approx(rho, rel=1e-14)
    meridian = npf.ogive_meridian(R, H, 50)
    assert np.hypot(meridian[:, 0] - (R - rho), meridian[:, 1]) == pytest.approx(rho, rel=1e-12)


@pytest.mark.parametrize("name", ["ogive", "ellipsoid"])
def test_profile_mesh_lies_on_its_surface(name):
    if name == "ogive":
        mesh, distance = npf.ogive_mesh(R, H), lambda p: npf.ogive_distance(p, R, H)
        bound = _sagitta_bound(npf.ogive_rho(R, H))
    else:  # the prolate meridian is least curved-radius at the apex: R^2 / H
        mesh, distance = npf.ellipsoid_mesh(R, H), lambda p: npf.ellipsoid_distance(p, R, H)
        bound = _sagitta_bound(R**2 / H)
    wall = _wall(mesh)
    # vertices on the analytic surface (resampled off a dense polyline: micrometre level)
    assert distance(wall).max() < 1e-4
    # facets off it by at most the chord sagittae, and by a measurable part of them
    error = npf.wall_error(mesh, distance)
    assert 0.25 * bound < error <= bound
    # apex on the axis at the height asked for, base radius R on z = 0, flange to 2 R
    v = np.asarray(mesh.vertices)
    top = v[np.argmax(v[:, 2])]
    assert top == pytest.approx([0.0, 0.0, H], abs=1e-9)
    r = np.hypot(v[:, 0], v[:, 1])
    assert r[v[:, 2] > 1e-9].max() < R <= r[np.abs(v[:, 2]) <= 1e-9].min() + 1e-9
    assert r.max() == pytest.approx(npf.FLANGE_FACTOR * R, rel=1e-9)
    # wall edges: meridian chords <= STEP_MM, around <= the base circle's chord; diagonals
    # (the longest) no longer than both together
    e = mesh.vertices[mesh.edges_unique]
    on_wall = e[:, :, 2].min(1) > 1e-9
    length = np.linalg.norm(e[:, 1] - e[:, 0], axis=1)[on_wall]
    around = 2.0 * R * math.sin(math.pi / npf.SECTIONS)
    assert length.max() <= math.hypot(npf.STEP_MM, around) + 1e-9


def test_meshed_default_cone_is_the_analytic_one():
    cone = NoseCone()
    mesh = npf.revolve(npf.nosecone_meridian(cone, 20000))
    v = _wall(mesh)
    assert np.abs(v[:, 2] - cone.height(v[:, 0], v[:, 1])).max() < 1e-4
    assert v[:, 2].max() == pytest.approx(cone.tip_height, abs=1e-9)


def test_profile_mesh_is_a_mould(tmp_path):
    # a coarse ogive, so the check is quick: read back as kind = "mesh", its top is the apex
    # (to the float32 an STL stores: 2^-24 relative, 2e-5 mm at 284 mm)
    path = tmp_path / "ogive.stl"
    npf.ogive_mesh(R, H, step=10.0, sections=90).export(path)
    surface = MeshSurface(path)
    assert surface.height(np.array([0.0]), np.array([0.0]))[0] == pytest.approx(H, abs=1e-4)
    assert surface.bounds == pytest.approx((-2 * R, 2 * R, -2 * R, 2 * R), rel=1e-3)
