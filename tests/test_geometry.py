"""Tests of the mould library: gradients, known shapes, domains, registry, STL round trip
through the mesh kind (its solver-side tests: tests/test_mesh_mould.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from uqdrape.geometry import (
    KINDS,
    Cone,
    Cylinder,
    DoubleDome,
    Hemisphere,
    NoseCone,
    Plate,
    MeshSurface,
    Saddle,
    build,
    export_stl,
)

DATA = Path(__file__).parent / "data"

# (mould, plan radii (mm) that the finite-difference check keeps 1 mm away from: the
# cone apex and steep rims; other kinks sit where the height reaches the flange z = 0)
ANALYTIC = {
    "plate": (Plate(), []),
    "hemisphere": (Hemisphere(100.0), [100.0]),
    "cylinder_x": (Cylinder(100.0, 400.0, "x"), []),
    "cylinder_y": (Cylinder(80.0, 300.0, "y"), []),
    "cone": (Cone(30.0, 100.0), [0.0]),
    "cone_steep": (Cone(60.0, 50.0), [0.0]),
    "nose_cone": (NoseCone(), []),
    "double_dome": (DoubleDome(), []),
    "saddle": (Saddle(), []),
}

H_FD = 1e-4  # finite-difference step (mm)


def _interior_points(surface, avoid, n=400, seed=0):
    """Random points inside the domain whose difference stencil does not cross a kink."""
    rng = np.random.default_rng(seed)
    xmin, xmax, ymin, ymax = surface.bounds
    x = rng.uniform(0.98 * xmin, 0.98 * xmax, 4 * n)
    y = rng.uniform(0.98 * ymin, 0.98 * ymax, 4 * n)
    keep = np.ones_like(x, dtype=bool)
    for r in avoid:
        keep &= np.abs(np.hypot(x, y) - r) > 1.0
    # stencil wholly on the mould or wholly on the flange
    on = [surface.height(x + dx, y + dy) > 0 for dx, dy in
          [(0, 0), (H_FD, 0), (-H_FD, 0), (0, H_FD), (0, -H_FD)]]
    keep &= np.all(on, axis=0) | ~np.any(on, axis=0)
    return x[keep][:n], y[keep][:n]


@pytest.mark.parametrize("key", ANALYTIC)
def test_gradient_matches_finite_difference(key):
    s, kinks = ANALYTIC[key]
    x, y = _interior_points(s, kinks)
    assert x.size >= 200
    h = H_FD
    fx = (s.height(x + h, y) - s.height(x - h, y)) / (2 * h)
    fy = (s.height(x, y + h) - s.height(x, y - h)) / (2 * h)
    gx, gy = s.gradient(x, y)
    scale = 1.0 + np.hypot(gx, gy)
    assert np.max(np.abs(fx - gx) / scale) < 1e-6
    assert np.max(np.abs(fy - gy) / scale) < 1e-6


@pytest.mark.parametrize("key", ANALYTIC)
def test_vectorised_shapes_and_unit_normals(key):
    s, _ = ANALYTIC[key]
    xmin, xmax, ymin, ymax = s.bounds
    x = np.linspace(xmin, xmax, 7)[:, None]  # includes rims and edges
    y = np.linspace(ymin, ymax, 5)[None, :]
    z = s.height(x, y)
    gx, gy = s.gradient(x, y)
    n = s.normal(x, y)
    assert z.shape == gx.shape == gy.shape == (7, 5)
    assert z.dtype == gx.dtype == np.float64
    assert n.shape == (7, 5, 3)
    assert np.all(np.isfinite(z)) and np.all(np.isfinite(gx)) and np.all(np.isfinite(gy))
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, rtol=1e-12)
    assert np.all(n[..., 2] > 0)
    assert s.inside(x, y).shape == (7, 5)


@pytest.mark.parametrize("key", ANALYTIC)
def test_params_rebuild_the_same_mould(key):
    s, kinks = ANALYTIC[key]
    t = build(s.name, **s.params())
    assert type(t) is type(s) and t.params() == s.params()
    x, y = _interior_points(s, kinks, n=50, seed=3)
    np.testing.assert_array_equal(t.height(x, y), s.height(x, y))


def test_plate_is_flat():
    s = Plate(100.0)
    x, y = np.meshgrid(np.linspace(-100, 100, 5), np.linspace(-100, 100, 5))
    assert np.all(s.height(x, y) == 0)
    assert all(np.all(g == 0) for g in s.gradient(x, y))
    assert list(s.inside([0, 100, 100.1, 0], [0, -100, 0, -101])) == [True, True, False, False]


def test_hemisphere_values_and_rim():
    s = Hemisphere(50.0)
    assert s.height(0.0, 0.0) == 50.0
    assert s.height(30.0, 40.0) == pytest.approx(0.0, abs=1e-12)
    assert s.height(-30.0, 0.0) == pytest.approx(40.0)
    assert s.height(70.0, 0.0) == 0.0
    gx, gy = s.gradient(np.array([50.0, 50.0 - 1e-13, 60.0]), np.zeros(3))
    assert np.all(np.isfinite(gx)) and gx[1] < -1e3 and gx[2] == 0.0
    assert s.flange_half_width == 100.0
    assert list(s.inside([0, 99, 101], [0, -99, 0])) == [True, True, False]


def test_cylinder_profile_and_domain():
    s = Cylinder(100.0, 400.0, "x")
    y = np.array([0.0, 60.0, -80.0])
    np.testing.assert_allclose(s.height(123.0, y), np.sqrt(100.0**2 - y**2))
    gx, gy = s.gradient(np.array([-150.0, 10.0, 150.0]), y)
    assert np.all(gx == 0)
    np.testing.assert_allclose(gy, -y / np.sqrt(100.0**2 - y**2))
    assert list(s.inside([0, 200, 201, 0, 0], [0, 0, 0, 94.9, 95.1])) == [True, True, False, True, False]
    t = Cylinder(100.0, 400.0, "y")  # the same mould turned by 90 degrees
    np.testing.assert_allclose(t.height(y, 123.0), s.height(123.0, y))
    assert list(t.inside([94.9, 95.1, 0], [0, 0, 201])) == [True, False, False]


def test_cone_slope_and_apex():
    s = Cone(half_angle_deg=30.0, height=100.0)
    rng = np.random.default_rng(1)
    r = rng.uniform(1.0, s.base_radius - 1.0, 200)
    t = rng.uniform(0, 2 * np.pi, 200)
    gx, gy = s.gradient(r * np.cos(t), r * np.sin(t))
    np.testing.assert_allclose(np.hypot(gx, gy), 1 / math.tan(math.radians(30.0)), rtol=1e-12)
    # the gradient points towards the axis (downhill outwards)
    assert np.all(gx * np.cos(t) + gy * np.sin(t) < 0)
    assert s.height(0.0, 0.0) == 100.0
    assert s.base_radius == pytest.approx(100.0 * math.tan(math.radians(30.0)))
    assert s.height(s.base_radius, 0.0) == pytest.approx(0.0, abs=1e-12)
    assert s.height(0.0, -s.base_radius - 5.0) == 0.0
    assert [float(g) for g in s.gradient(0.0, 0.0)] == [0.0, 0.0]  # undefined apex -> 0


def test_nose_cone_blend_is_smooth_and_base_radius_right():
    s = NoseCone(base_radius=225.0, half_angle_deg=40.0, tip_radius=60.0)
    rt = s.blend_radius
    assert rt == pytest.approx(60.0 * math.cos(math.radians(40.0)))
    eps = 1e-7
    r = np.array([rt - eps, rt + eps])
    z = s.height(r, 0.0)
    gx, _ = s.gradient(r, 0.0)
    assert abs(z[1] - z[0]) < 1e-5
    assert abs(gx[1] - gx[0]) < 1e-5  # slope continuous across the tip/cone blend
    assert gx[1] == pytest.approx(-1 / math.tan(math.radians(40.0)))
    # tip: highest point, horizontal tangent plane, spherical curvature 1 / tip_radius
    assert s.height(0.0, 0.0) == pytest.approx(s.tip_height)
    assert [float(g) for g in s.gradient(0.0, 0.0)] == [0.0, 0.0]
    hx, _ = s.gradient(1e-3, 0.0)
    assert hx / 1e-3 == pytest.approx(-1 / 60.0, rel=1e-6)
    # the cone reaches the flange exactly at the base radius
    assert s.height(0.0, 225.0) == pytest.approx(0.0, abs=1e-12)
    assert s.height(0.0, 225.0 - 1e-3) > 0
    assert s.height(0.0, 230.0) == 0.0
    assert list(s.inside([0, 450, 451], [0, 450, 0])) == [True, True, False]


def test_nose_cone_defaults_match_documented_approximation():
    s = NoseCone()
    assert (s.base_radius, s.half_angle_deg, s.tip_radius) == (225.0, 35.0, 50.0)
    # far-field diagonal shear of a geodesic net on the cone, 90 (1 - sin a), lies in 30-60 deg
    assert 30.0 < 90.0 * (1 - math.sin(math.radians(s.half_angle_deg))) < 60.0


def test_double_dome_shape():
    s = DoubleDome(dome_radius=80.0, base_radius=70.0, centre_distance=120.0, blend=20.0)
    depth = math.sqrt(80.0**2 - 70.0**2)
    assert s.height(60.0, 0.0) == pytest.approx(80.0 - depth)  # dome tops
    assert s.height(-60.0, 0.0) == pytest.approx(80.0 - depth)
    valley = math.sqrt(80.0**2 - 60.0**2) - depth + 20.0 / 4  # smooth max adds k/4 at a tie
    assert s.height(0.0, 0.0) == pytest.approx(valley)
    assert s.height(0.0, 0.0) < s.height(60.0, 0.0)
    # symmetric in x and y, gradient continuous across the valley
    rng = np.random.default_rng(2)
    x, y = rng.uniform(-150, 150, (2, 100))
    np.testing.assert_allclose(s.height(x, y), s.height(-x, y), atol=1e-12)
    np.testing.assert_allclose(s.height(x, y), s.height(x, -y), atol=1e-12)
    gx, gy = s.gradient(np.array([-1e-7, 1e-7]), np.array([20.0, 20.0]))
    assert abs(gx[1] - gx[0]) < 1e-5 and abs(gy[1] - gy[0]) < 1e-5
    # each dome meets the flange at its base radius; outside it is flat
    assert s.height(130.0, 0.0) == pytest.approx(0.0, abs=1e-9)
    assert s.height(129.0, 0.0) > 0 and s.height(131.0, 0.0) == 0.0
    assert list(s.inside([0, 200, 201], [0, -200, 0])) == [True, True, False]


def test_saddle_curvature():
    R = 250.0
    s = Saddle(radius=R, half_width=100.0)
    assert s.height(100.0, 0.0) == pytest.approx(100.0**2 / (2 * R))
    assert s.height(0.0, 100.0) == pytest.approx(-(100.0**2) / (2 * R))
    h = 1e-3
    gx_p, gy_p = s.gradient(h, 0.0)
    gx_m, gy_m = s.gradient(-h, 0.0)
    hxx = (gx_p - gx_m) / (2 * h)
    hxy = (gy_p - gy_m) / (2 * h)
    hyy = (s.gradient(0.0, h)[1] - s.gradient(0.0, -h)[1]) / (2 * h)
    assert hxx == pytest.approx(1 / R) and hyy == pytest.approx(-1 / R) and hxy == 0
    assert hxx * hyy - hxy**2 == pytest.approx(-1 / R**2)  # Gaussian curvature at the origin
    assert list(s.inside([100, 100.5], [-100, 0])) == [True, False]


def test_registry_names():
    assert set(KINDS) == {
        "plate", "cylinder", "hemisphere", "cone", "nose_cone", "double_dome", "saddle", "mesh"
    }
    for kind, cls in KINDS.items():
        assert cls.name == kind
    assert isinstance(build("hemisphere", radius=80), Hemisphere)
    assert build("saddle").params() == Saddle().params()


def test_build_rejects_bad_kind_and_parameters():
    with pytest.raises(ValueError, match=r"unknown geometry kind 'sphere'; valid: plate, .*saddle, mesh"):
        build("sphere")
    with pytest.raises(
        ValueError,
        match=r"unknown parameter 'radus' for geometry 'hemisphere'; valid: radius, flange_half_width, offset_mm$",
    ):
        build("hemisphere", radus=50)
    with pytest.raises(ValueError, match=r"geometry 'mesh' needs parameter 'path'"):
        build("mesh")


@pytest.mark.parametrize(
    "make, argument",
    [
        (lambda: Plate(half_width=0), "half_width"),
        (lambda: Plate(half_width="wide"), "half_width"),
        (lambda: Hemisphere(radius=-1), "radius"),
        (lambda: Hemisphere(radius=50, flange_half_width=40), "flange_half_width"),
        (lambda: Cylinder(length=float("nan")), "length"),
        (lambda: Cylinder(axis="z"), "axis"),
        (lambda: Cone(half_angle_deg=90), "half_angle_deg"),
        (lambda: Cone(height=0), "height"),
        (lambda: NoseCone(half_angle_deg=0), "half_angle_deg"),
        (lambda: NoseCone(tip_radius=400), "tip_radius"),
        (lambda: DoubleDome(base_radius=90), "base_radius"),
        (lambda: DoubleDome(centre_distance=150), "centre_distance"),
        (lambda: DoubleDome(flange_half_width=100), "flange_half_width"),
        (lambda: Saddle(radius=float("inf")), "radius"),
        (lambda: MeshSurface("no/such/file.stl"), "path"),
        (lambda: MeshSurface(DATA / "hemisphere_r50.stl", units="ft"), "units"),
        (lambda: MeshSurface(DATA / "hemisphere_r50.stl", press_direction=(0, 0, 0)), "press_direction"),
    ],
)
def test_constructors_name_the_bad_argument(make, argument):
    with pytest.raises(ValueError, match=rf"^{argument}\b"):
        make()


def test_mesh_rejects_a_file_that_is_not_a_mesh(tmp_path):
    bad = tmp_path / "bad.stl"
    bad.write_text("this is not a mesh\n")
    with pytest.raises(ValueError, match=r"^path"):
        MeshSurface(bad)


def _disc_points(radius, frac, n=600, seed=4):
    rng = np.random.default_rng(seed)
    r = frac * radius * np.sqrt(rng.uniform(0, 1, n))
    t = rng.uniform(0, 2 * np.pi, n)
    return r * np.cos(t), r * np.sin(t)


def test_stl_round_trip_of_a_hemisphere(tmp_path):
    """export_stl, read back as a mesh mould: its top surface is the piecewise-linear
    interpolant of the hemisphere on the 1 mm grid, its slopes from the interpolated normals."""
    R = 50.0
    h = Hemisphere(R, 60.0)
    path = export_stl(h, tmp_path / "h.stl", resolution_mm=1.0)
    # binary STL: 80-byte header, triangle count, 50 bytes per triangle
    n_tri = int(np.frombuffer(path.read_bytes()[80:84], dtype="<u4")[0])
    assert n_tri == 2 * 120 * 120
    assert path.stat().st_size == 84 + 50 * n_tri
    s = MeshSurface(path)
    assert s.bounds == pytest.approx((-60.0, 60.0, -60.0, 60.0))
    x, y = _disc_points(R, 0.9)
    assert np.max(np.abs(s.height(x, y) - h.height(x, y))) < 0.3  # away from the rim
    x, y = _disc_points(R, 0.8)
    assert np.max(np.abs(s.height(x, y) - h.height(x, y))) < 0.02
    gx, gy = s.gradient(x, y)
    ax, ay = h.gradient(x, y)
    assert np.max(np.hypot(gx - ax, gy - ay)) < 0.03  # analytic slopes reach 1.33 here
    assert list(s.inside([0, 59, 61], [0, -59, 0])) == [True, True, False]


def test_export_keeps_only_the_domain(tmp_path):
    c = Cylinder(40.0, 100.0, "y")
    mesh = trimesh.load_mesh(export_stl(c, tmp_path / "c.stl", resolution_mm=5.0))
    v = mesh.vertices
    assert np.all(c.inside(v[:, 0] * (1 - 1e-9), v[:, 1] * (1 - 1e-9)))
    np.testing.assert_allclose(v[:, 2], c.height(v[:, 0], v[:, 1]), atol=1e-4)
    assert np.all(mesh.face_normals[:, 2] > 0)  # facing up
    with pytest.raises(ValueError, match="half_width"):
        export_stl(c, tmp_path / "d.stl", half_width=-1.0)


def test_mesh_height_is_the_top_of_a_closed_solid(tmp_path):
    ball = trimesh.creation.icosphere(subdivisions=5, radius=30.0)
    ball.export(tmp_path / "ball.stl")
    s = MeshSurface(tmp_path / "ball.stl")
    x, y = _disc_points(30.0, 0.7)
    np.testing.assert_allclose(s.height(x, y), np.sqrt(30.0**2 - x**2 - y**2), atol=0.1)
    assert not s.inside(29.0, 29.0)  # outside the round footprint, inside the bounding box


def test_shipped_stl_loads():
    path = DATA / "hemisphere_r50.stl"
    assert path.stat().st_size < 300_000
    s = build("mesh", path=path)
    h = Hemisphere(50.0, 60.0)
    assert s.height(0.0, 0.0) == pytest.approx(50.0, abs=0.05)
    x, y = _disc_points(50.0, 0.8)
    assert np.max(np.abs(s.height(x, y) - h.height(x, y))) < 0.2
    gx, gy = s.gradient(x, y)
    ax, ay = h.gradient(x, y)
    assert np.max(np.hypot(gx - ax, gy - ay)) < 0.1


# -- offset surfaces (a laminate's plies over the plies below them) ----------------------

OFFSET_MOULDS = {"plate": Plate(), "hemisphere": Hemisphere(100.0), "cylinder": Cylinder(100.0),
                 "cone": Cone(30.0, 100.0), "nose_cone": NoseCone(), "double_dome": DoubleDome(), "saddle": Saddle()}


@pytest.mark.parametrize("key", OFFSET_MOULDS)
def test_an_offset_surface_lies_its_distance_out_along_the_mould_s_normal(key):
    """Every point q of the offset surface at d, moved back by d along its normal n, lands
    on the mould (phi = 0) where the mould's normal is n: the definition of the offset
    (below the smallest concave radius of curvature, where it is the parallel surface), on
    the flanges, the spheres, the cones, a cone's apex (whose offset is a sphere about it),
    the double dome's valley, the saddle, and the concave rims where an offset dome or
    cone meets the raised flange."""
    mould, d = OFFSET_MOULDS[key], 3.0
    out = mould.offset(d)
    xmin, xmax, ymin, ymax = mould.bounds
    rng = np.random.default_rng(7)
    x, y = rng.uniform(0.95 * xmin, 0.95 * xmax, 20_000), rng.uniform(0.95 * ymin, 0.95 * ymax, 20_000)
    n = out.normal(x, y)
    foot = np.stack([x, y, out.height(x, y)], -1) - d * n
    assert np.abs(mould.gap(foot[:, 0], foot[:, 1], foot[:, 2])[0]).max() < 1e-9
    smooth = np.linalg.norm(foot[:, :2], axis=1) > 1e-6  # a cone's apex has no normal of its own
    assert np.abs(mould.normal(foot[smooth, 0], foot[smooth, 1]) - n[smooth]).max() < 1e-6
    assert out.describe() == mould.describe()[:-1] + ", offset 3 mm)"


def test_offset_moulds_rebuild_from_their_params_and_add_up():
    """``build(kind, **params)`` of an offset mould gives its kernel back, an offset of an
    offset is the offset by the sum, and a hemisphere's offset is the sphere of radius
    R + d (to the last bit where both are the sphere, with the flange raised by d)."""
    for mould in OFFSET_MOULDS.values():
        out = mould.offset(2.5)
        again = build(out.name, **out.params())
        assert again.params() == out.params() and np.array_equal(again.kernel[1], out.kernel[1])
        assert np.array_equal(mould.offset(1.0).offset(1.5).kernel[1], out.kernel[1])
        assert np.array_equal(mould.offset(0.0).kernel[1], mould.kernel[1])
    r = np.linspace(0.0, 99.0, 500)
    np.testing.assert_array_equal(Hemisphere(100.0).offset(2.0).height(r, 0 * r), Hemisphere(102.0).height(r, 0 * r))
    assert Hemisphere(100.0).offset(2.0).height(150.0, 0.0) == 2.0


def test_an_offset_past_the_smallest_concave_radius_is_refused():
    """The double dome's valley is concave with radius 5.93 mm at its narrowest (a finite-
    difference estimate on a 0.5 mm grid): the parallel surface folds past it, so larger
    offsets are refused; the saddle's concave radius is R (its curvature +-1/R at the
    origin)."""
    limit = DoubleDome()._largest_offset()[0]
    assert 5.9 < limit < 5.95
    assert np.isfinite(DoubleDome().offset(0.99 * limit).height(0.0, 36.5))
    with pytest.raises(ValueError, match=r"at most the smallest concave radius of curvature of its valley.*5.9"):
        DoubleDome().offset(1.01 * limit)
    assert Saddle(radius=50.0, half_width=150.0)._largest_offset()[0] == 50.0


@pytest.mark.parametrize("bad", [-1.0, float("nan"), "thick", 101.0])
def test_a_bad_offset_names_its_argument(bad):
    with pytest.raises(ValueError, match=r"offset_mm must be a length >= 0 and at most the mould's size \(100 mm\)"):
        Hemisphere(100.0).offset(bad)


def test_a_mesh_offset_is_the_level_set_of_its_distance(tmp_path):
    """A mesh's offset surface lies at its distance from the mesh to the solver's precision
    (its top found on a vertical line, and a drape on it), a sphere of R + d to the mesh's own
    faceting error."""
    path = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=5, radius=100.0).export(path)
    mesh = MeshSurface(path)
    out = build("mesh", **{**mesh.params(), "offset_mm": 2.0})
    assert out.describe() == "mesh ball.stl (mm, press +z, offset 2 mm)"
    x, y = np.meshgrid(np.linspace(-70, 70, 15), np.linspace(-70, 70, 15))
    top = np.stack([x, y, out.height(x, y)], -1).reshape(-1, 3)
    _, phi, _ = mesh.project(top)
    assert np.abs(phi - 2.0).max() < 1e-9
    sag = np.abs(mesh.height(x, y) - np.sqrt(100.0**2 - x**2 - y**2)).max()  # the faceting error
    assert np.abs(top[:, 2] - np.sqrt(102.0**2 - x.ravel()**2 - y.ravel()**2)).max() < 1.5 * sag

    from uqdrape.drape import drape

    ds = drape(out, 5.0, 8)
    P = np.stack([ds[c].values.ravel() for c in "xyz"], -1)
    assert (ds["status"].values == 0).all()
    assert np.abs(mesh.project(P)[1] - 2.0).max() < 1e-8
