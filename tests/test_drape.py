"""Acceptance tests of the pin-jointed-net drape (issue 2): geometry of the net, shear on
developable and doubly curved moulds, batching, failure flags, bad input, STL and netCDF
round trips, max-shear lines. Lengths mm, angles degrees.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from uqdrape.drape import Status, drape, max_shear_lines, min_shear_lines
from uqdrape.geometry import Cone, Cylinder, Hemisphere, MeshSurface, Plate, build
from uqdrape.material import load_material

from golden import (
    CONE_FLANK_MAX_CELL_SHEAR_DEG,
    HEMISPHERE_MAX_CELL_SHEAR_DEG,
    HEMISPHERE_NODE_DISTANCE_MM,
    HEMISPHERE_NODE_SHEAR_DEG,
    STL_HEMISPHERE_POSITION_GAP_MM,
    STL_HEMISPHERE_SHEAR_GAP_DEG,
)

DATA = Path(__file__).parent / "data"


# -- helpers ---------------------------------------------------------------------------
def positions(ds):
    """Node positions (R, N, N, 3) mm."""
    return np.stack([ds.x.values, ds.y.values, ds.z.values], axis=-1)


def segment_lengths(ds):
    """Chord lengths of the fibre-1 (R, 2n, 2n+1) and fibre-2 (R, 2n+1, 2n) segments (mm)."""
    P = positions(ds)
    return (np.linalg.norm(P[:, 1:] - P[:, :-1], axis=-1),
            np.linalg.norm(P[:, :, 1:] - P[:, :, :-1], axis=-1))


def random_segments(rng, s, n, R=None, cv=0.02):
    """Segment lengths s (1 + cv xi), xi standard normal, for fibre 1 and fibre 2."""
    lead = () if R is None else (R,)
    return (s * (1 + cv * rng.standard_normal(lead + (2 * n, 2 * n + 1))),
            s * (1 + cv * rng.standard_normal(lead + (2 * n + 1, 2 * n))))


def parents(i, j):
    """Nodes that node (i, j) is built from: the arm's previous two nodes, or the two inner
    neighbours along each fibre and the diagonal one."""
    if i == 0 or j == 0:
        k, di, dj = abs(i + j), np.sign(i), np.sign(j)
        return [((k - m) * di, (k - m) * dj) for m in (1, 2) if k - m >= 0]
    si, sj = np.sign(i), np.sign(j)
    return [(i - si, j), (i, j - sj), (i - si, j - sj)]


def check_status_rules(ds):
    """Status codes are those of Status; invalid <=> NaN; DEPENDENT <=> an invalid parent."""
    n = ds.attrs["rings"]
    codes = {s.value for s in Status}
    st = ds.status.values
    assert set(np.unique(st)) <= codes
    assert np.array_equal(st != Status.OK, np.isnan(ds.x.values))
    assert np.array_equal(np.isnan(ds.x.values), np.isnan(ds.z.values))
    for r in range(st.shape[0]):
        for i in range(-n, n + 1):
            for j in range(-n, n + 1):
                if i == 0 and j == 0:
                    assert st[r, n, n] in (Status.OK, Status.OFF_MOULD)
                    continue
                bad_parent = any(st[r, a + n, b + n] != Status.OK for a, b in parents(i, j))
                assert (st[r, i + n, j + n] == Status.DEPENDENT) == bad_parent, (r, i, j)


# -- net geometry ----------------------------------------------------------------------
MOULDS = [
    ("hemisphere", dict(radius=100.0), 5.0, 14, (3.0, -2.0)),
    ("saddle", {}, 8.0, 12, (10.0, 5.0)),
    ("nose_cone", {}, 10.0, 14, (0.0, 0.0)),
    ("double_dome", {}, 6.0, 12, (-60.0, 5.0)),
]


@pytest.mark.parametrize("kind, params, s, n, crossover", MOULDS, ids=[m[0] for m in MOULDS])
def test_segments_keep_their_length_and_nodes_lie_on_the_mould(kind, params, s, n, crossover):
    rng = np.random.default_rng(11)
    surf = build(kind, **params)
    seg_i, seg_j = random_segments(rng, s, n)
    ds = drape(surf, s, n, orientation=20.0, crossover=crossover, seg_i=seg_i, seg_j=seg_j)
    valid = ds.status.values[0] == Status.OK
    assert valid.mean() > 0.95
    l1, l2 = segment_lengths(ds)
    err1 = np.abs(l1[0] / seg_i - 1)
    err2 = np.abs(l2[0] / seg_j - 1)
    assert np.isfinite(err1).sum() > 0.9 * err1.size
    assert np.nanmax(err1) <= 1e-9 and np.nanmax(err2) <= 1e-9
    x, y, z = ds.x.values[0][valid], ds.y.values[0][valid], ds.z.values[0][valid]
    assert np.max(np.abs(z - surf.height(x, y))) <= 1e-9 * surf.size
    assert surf.inside(x, y).all()
    check_status_rules(ds)


def test_geodesic_arms_on_a_sphere_follow_great_circles():
    """Off the pole, a discrete geodesic on a sphere stays in a plane through the centre and
    advances by 2 asin(l / 2R) per chord l (known value of the straightest path)."""
    R, s, n = 100.0, 5.0, 10
    rng = np.random.default_rng(5)
    seg_i, seg_j = random_segments(rng, s, n)
    ds = drape(Hemisphere(R), s, n, orientation=17.0, crossover=(20.0, -10.0), seg_i=seg_i, seg_j=seg_j)
    P = positions(ds)[0]
    centre = np.array([0.0, 0.0, 0.0])
    arms = {
        "+i": ([(k, 0) for k in range(n + 1)], seg_i[n:, n]),
        "-i": ([(-k, 0) for k in range(n + 1)], seg_i[:n, n][::-1]),
        "+j": ([(0, k) for k in range(n + 1)], seg_j[n, n:]),
        "-j": ([(0, -k) for k in range(n + 1)], seg_j[n, :n][::-1]),
    }
    for name, (nodes, lengths) in arms.items():
        pts = np.array([P[i + n, j + n] for i, j in nodes]) - centre
        normal = np.cross(pts[0], pts[1])
        normal /= np.linalg.norm(normal)
        assert np.max(np.abs(pts @ normal)) <= 1e-9 * R, name
        angle = np.arccos(np.clip(np.sum(pts[:-1] * pts[1:], -1) / R**2, -1, 1))
        np.testing.assert_allclose(angle, 2 * np.arcsin(lengths / (2 * R)), rtol=1e-9, err_msg=name)
        # the arm keeps going the same way round the great circle
        assert np.all(np.cross(pts[:-1], pts[1:]) @ normal > 0), name


# -- developable moulds ----------------------------------------------------------------
def test_plate_is_shear_free_at_any_orientation_and_keeps_its_pre_shear():
    s, n = 5.0, 8
    orientation = np.array([0.0, 30.0, 30.0, -75.0])
    pre = np.array([0.0, 0.0, 12.0, -20.0])
    crossover = np.array([[0.0, 0.0], [10.0, -20.0], [0.0, 0.0], [-15.0, 5.0]])
    ds = drape(Plate(300.0), s, n, orientation=orientation, pre_shear=pre, crossover=crossover,
               blankholder_force=200.0, friction=0.3)
    assert (ds.status == Status.OK).all()
    assert np.abs(ds.shear - ds.pre_shear).max() <= 1e-9
    assert np.abs(ds.cell_shear - ds.pre_shear).max() <= 1e-9
    # nodes sit at their flat-blank positions, so nothing is drawn in under the blank-holder
    idx = np.arange(-n, n + 1)
    psi = np.deg2rad(orientation)[:, None, None]
    b = np.deg2rad(orientation + 90.0 - pre)[:, None, None]
    I, J = idx[None, :, None], idx[None, None, :]
    x = crossover[:, 0, None, None] + s * (I * np.cos(psi) + J * np.cos(b))
    y = crossover[:, 1, None, None] + s * (I * np.sin(psi) + J * np.sin(b))
    assert np.abs(ds.x.values - x).max() <= 1e-9 and np.abs(ds.y.values - y).max() <= 1e-9
    assert np.abs(ds.z).max() == 0.0
    assert np.abs(ds.energy_blankholder).max() <= 1e-12


def test_skew_on_a_plate_closes_every_cell_by_the_skew():
    ds = drape(Plate(300.0), 5.0, 6, skew=[10.0, -8.0], pre_shear=[0.0, 5.0], orientation=[0.0, 40.0])
    expected = (ds.skew + ds.pre_shear).values[:, None, None]
    assert np.abs(ds.cell_shear.values - expected).max() <= 1e-9


@pytest.mark.parametrize("axis, orientation", [("x", 0.0), ("x", 180.0), ("y", 90.0)])
def test_cylinder_with_the_net_along_its_axis_is_shear_free(axis, orientation):
    crossover = np.array([[0.0, 0.0], [20.0, 30.0], [-35.0, -40.0]])
    if axis == "y":
        crossover = crossover[:, ::-1]
    ds = drape(Cylinder(100.0, 400.0, axis), 5.0, 12, orientation=orientation, crossover=crossover)
    assert (ds.status == Status.OK).all()
    assert np.abs(ds.shear).max() <= 1e-9  # zero to round-off (measured 4.9e-13 deg)


def test_cylinder_at_45_deg():
    """The +-45 deg net is generated by screw motions about the cylinder's axis, so every
    cell is congruent and the corner-averaged shear cancels: measured 3.0e-10 deg on the
    crest and on the flank (crossover at y = 40 mm, where the blank lands on a 24 deg
    slope and is rotated, not projected, onto the tangent plane) for s = 10, 5, 2.5 mm."""
    cyl = Cylinder(100.0, 400.0, "x")
    for crossover in ((0.0, 0.0), (0.0, 40.0)):
        for s in (10.0, 5.0, 2.5):
            ds = drape(cyl, s, int(40 / s), orientation=45.0, crossover=crossover)
            assert (ds.status == Status.OK).all()
            assert np.abs(ds.cell_shear).max() <= 1e-9


def test_a_blank_landing_on_a_slope_keeps_its_fibre_angle():
    """First segments on a sloped crossover: the angle between the +i and +j arms equals
    the flat blank's 90 - pre_shear (to the chord's discretisation), whatever the slope."""
    for pre_shear in (0.0, 20.0):
        ds = drape(Cylinder(100.0, 400.0, "x"), 0.05, 1, orientation=30.0, pre_shear=pre_shear,
                   crossover=(0.0, 60.0))
        p0 = np.array([float(ds[v].sel(i=0, j=0)[0]) for v in "xyz"])
        e1 = np.array([float(ds[v].sel(i=1, j=0)[0]) for v in "xyz"]) - p0
        e2 = np.array([float(ds[v].sel(i=0, j=1)[0]) for v in "xyz"]) - p0
        angle = np.rad2deg(np.arccos(e1 @ e2 / np.linalg.norm(e1) / np.linalg.norm(e2)))
        assert abs(angle - (90.0 - pre_shear)) < 1e-3


def test_cone_flank_discretisation_shear_is_small_and_second_order():
    """Crossover on the flank of a 30 deg cone (plan r = 30 mm; apex and rim stay > 15 mm away),
    fibres along the parallel and the generator, net 30 mm along each arm. Max |cell shear|
    0.260, 0.0766, 0.0215, 0.00566 deg for s = 10, 5, 2.5, 1.25 mm (golden, regression)."""
    cone = Cone(30.0, 100.0)
    worst = []
    for s in (10.0, 5.0, 2.5, 1.25):
        ds = drape(cone, s, int(round(30 / s)), crossover=(0.0, 30.0))
        assert (ds.status == Status.OK).all()
        r = np.hypot(ds.x, ds.y)
        assert r.min() > 10.0 and r.max() < cone.base_radius - 5.0
        worst.append(float(np.abs(ds.cell_shear).max()))
    np.testing.assert_allclose(worst, CONE_FLANK_MAX_CELL_SHEAR_DEG, rtol=1e-6)
    ratios = np.array(worst[:-1]) / np.array(worst[1:])
    assert np.all((ratios > 3.0) & (ratios < 4.5)), ratios
    assert 3.5 < ratios[-1] < 4.5


# -- hemisphere ------------------------------------------------------------------------
def test_hemisphere_from_the_pole_mirrors_in_its_quadrants():
    n = 16
    ds = drape(Hemisphere(100.0), 5.0, n)
    assert (ds.status == Status.OK).all()
    S = ds.shear.values[0]
    X, Y, Z = ds.x.values[0], ds.y.values[0], ds.z.values[0]
    flip_i, flip_j = (slice(None, None, -1), slice(None)), (slice(None), slice(None, None, -1))
    assert np.abs(S + S[flip_i]).max() <= 1e-9  # shear(-i, j) = -shear(i, j)
    assert np.abs(S + S[flip_j]).max() <= 1e-9
    assert np.abs(S - S.T).max() <= 1e-9  # shear(j, i) = shear(i, j)
    assert np.abs(X + X[flip_i]).max() <= 1e-9 and np.abs(Y - Y[flip_i]).max() <= 1e-9
    assert np.abs(X - X[flip_j]).max() <= 1e-9 and np.abs(Y + Y[flip_j]).max() <= 1e-9
    assert np.abs(X - Y.T).max() <= 1e-9 and np.abs(Z - Z.T).max() <= 1e-9
    C = ds.cell_shear.values[0]
    assert (C[n:, n:] > 0).all() and (C[:n, :n] > 0).all()  # i*j > 0
    assert (C[n:, :n] < 0).all() and (C[:n, n:] < 0).all()  # i*j < 0
    assert C.max() == pytest.approx(HEMISPHERE_MAX_CELL_SHEAR_DEG, abs=1e-6)  # the outermost corner cell


def test_hemisphere_shear_converges_at_a_fixed_point_when_the_spacing_halves():
    """Node (35/s, 35/s), about 50.5 mm from the pole along the diagonal of a R = 100 mm
    hemisphere: 7.012555, 7.012806, 7.012867 deg for s = 5, 2.5, 1.25 mm (differences
    2.5e-4, 6.2e-5: second order)."""
    h = Hemisphere(100.0)
    values, distances = [], []
    for s in (5.0, 2.5, 1.25):
        n, k = int(round(40 / s)), int(round(35 / s))
        ds = drape(h, s, n)
        line = max_shear_lines(ds).sel(quadrant="++").isel(realization=0, k=k)
        distances.append(float(line.distance))
        values.append(float(ds.shear.isel(realization=0).sel(i=k, j=k)))
    d = np.abs(np.diff(values))
    np.testing.assert_allclose(values, HEMISPHERE_NODE_SHEAR_DEG, rtol=1e-6)
    np.testing.assert_allclose(distances, HEMISPHERE_NODE_DISTANCE_MM, rtol=1e-6)
    assert d[0] < 1e-3 and d[1] < d[0] / 3


# -- batching --------------------------------------------------------------------------
def _assert_batch_equals_singles(surf, s, n, mode, inputs, atol=0.0, threads=1):
    material = load_material("ebxhd936_like")
    batch = drape(surf, s, n, mode=mode, material=material, threads=threads, **inputs)
    R = batch.sizes["realization"]
    for r in range(R):
        one = drape(surf, s, n, mode=mode, material=material, **{k: v[r] for k, v in inputs.items()})
        for name in batch.data_vars:
            a = batch[name].isel(realization=r).values
            b = one[name].isel(realization=0).values
            if a.dtype.kind == "f":
                assert np.array_equal(np.isnan(a), np.isnan(b)), (name, r)
                assert np.nanmax(np.abs(a - b), initial=0.0) <= atol, (name, r)
            else:
                assert np.array_equal(a, b), (name, r)
    return batch


def _varied_inputs(rng, s, n, R):
    seg_i, seg_j = random_segments(rng, s, n, R)
    return dict(orientation=rng.uniform(-45, 45, R), crossover=rng.uniform(-15, 15, (R, 2)),
                pre_shear=rng.uniform(-10, 10, R), skew=rng.uniform(0, 20, R), seg_i=seg_i, seg_j=seg_j,
                blankholder_force=rng.uniform(0, 300, R), friction=rng.uniform(0.1, 0.3, R),
                gamma0=rng.normal(0.0, 3.0, (R, 2 * n, 2 * n)))


@pytest.mark.parametrize("mode", ["geodesic", "energy"])
def test_a_batch_gives_the_numbers_of_single_calls(mode):
    """Nose cone, 4 drapes with different orientation, crossover, pre-shear, skew, segment
    lengths, gamma0, force and friction (one with a folded corner): identical to single calls."""
    rng = np.random.default_rng(7)
    batch = _assert_batch_equals_singles(build("nose_cone"), 10.0, 10, mode, _varied_inputs(rng, 10.0, 10, 4))
    assert len(np.unique(batch.energy_total)) == 4


@pytest.mark.parametrize("threads", [1, 2])
def test_a_batch_gives_the_numbers_of_single_calls_near_the_rim(threads):
    """Nodes past the rim fall back from Newton to the bracket search; a batch on one or on
    two threads is bitwise the single calls."""
    rng = np.random.default_rng(7)
    _assert_batch_equals_singles(Hemisphere(50.0, 60.0), 5.0, 10, "geodesic", _varied_inputs(rng, 5.0, 10, 5),
                                 threads=threads)


def test_threads_by_default_only_from_the_main_thread_of_the_main_process():
    """Ensemble workers and thread-pool threads share the cores already: one thread each."""
    import threading

    import numba

    from uqdrape.drape.solver import default_threads

    assert default_threads() == numba.config.NUMBA_NUM_THREADS
    seen = []
    worker = threading.Thread(target=lambda: seen.append(default_threads()))
    worker.start()
    worker.join()
    assert seen == [1]


def test_the_drape_dataset_has_the_net_s_dimensions():
    ds = drape(Hemisphere(100.0), 5.0, 4, orientation=[0.0, 30.0], factors={"spacing_cv": 0.01})
    assert ds.sizes == {"realization": 2, "i": 9, "j": 9, "cell_i": 8, "cell_j": 8, "ring": 4, "arm": 4,
                        "quadrant": 4}


# -- failure is data -------------------------------------------------------------------
FAILURES = [
    ("crossover near the plate edge", Plate(50.0), 5.0, 6, (45.0, 0.0), Status.OFF_MOULD),
    # the circle meets the surface only past the small dome, off the mould's domain
    ("spacing beyond the curvature", Hemisphere(20.0), 15.0, 4, (0.0, 0.0), Status.OFF_MOULD),
    ("rings far off the mould", Hemisphere(50.0, 60.0), 10.0, 10, (0.0, 0.0), Status.OFF_MOULD),
    ("crossover off the mould", Plate(50.0), 5.0, 4, (60.0, 0.0), Status.OFF_MOULD),
]


@pytest.mark.parametrize("mode", ["geodesic", "energy"])
@pytest.mark.parametrize("label, surf, s, n, crossover, code", FAILURES, ids=[f[0] for f in FAILURES])
def test_failures_are_flagged_not_raised(label, surf, s, n, crossover, code, mode):
    ds = drape(surf, s, n, crossover=crossover, mode=mode, material=load_material("generic_woven"),
               blankholder_force=100.0)
    st = ds.status.values[0]
    assert (st == code).any()
    assert (st == Status.DEPENDENT).any()
    check_status_rules(ds)
    valid = st == Status.OK
    assert surf.inside(ds.x.values[0][valid], ds.y.values[0][valid]).all()
    assert np.isfinite(ds.energy_total).all()


def test_crossover_off_the_mould_invalidates_the_whole_net():
    ds = drape(Plate(50.0), 5.0, 4, crossover=[(60.0, 0.0), (0.0, 0.0)])
    assert ds.status.values[0, 4, 4] == Status.OFF_MOULD
    assert (ds.status.values[0] != Status.OK).all()
    assert (ds.status.values[1] == Status.OK).all()


BAD = [
    (dict(spacing=-5.0), "spacing"),
    (dict(spacing=0.0), "spacing"),
    (dict(spacing=float("nan")), "spacing"),
    (dict(crossover=(float("nan"), 0.0)), "crossover"),
    (dict(crossover=[(0.0, 0.0), (1.0, float("nan"))]), "crossover"),
    (dict(rings=0), "rings"),
    (dict(rings=2.5), "rings"),
    (dict(mode="kinematic"), "mode"),
    (dict(mode="energy"), "material"),
    (dict(orientation=[0.0, 10.0, 20.0], crossover=[(0.0, 0.0), (1.0, 1.0)]), "orientation"),
    (dict(seg_i=np.ones((3, 3))), "seg_i"),
    (dict(seg_j=np.full((9, 8), -1.0)), "seg_j"),
    (dict(orientation=float("nan")), "orientation"),
    (dict(blankholder_force=-1.0), "blankholder_force"),
    (dict(friction=float("nan")), "friction"),
    (dict(threads=0), "threads"),
    (dict(threads=1.5), "threads"),
]


@pytest.mark.parametrize("kwargs, name", BAD, ids=[f"{b[1]}-{i}" for i, b in enumerate(BAD)])
def test_impossible_arguments_raise_naming_the_argument(kwargs, name):
    args = dict(spacing=5.0, rings=4)
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        drape(Plate(100.0), args.pop("spacing"), args.pop("rings"), **args)


# -- STL, netCDF, lines ----------------------------------------------------------------
def test_drape_over_the_shipped_stl_matches_the_analytic_hemisphere():
    """tests/data/hemisphere_r50.stl is Hemisphere(50, 60) exported at 2.5 mm. Net within
    r < 42 mm of the axis (rim at 50), draped on the mesh itself (kind "mesh")."""
    kwargs = dict(orientation=[0.0, 25.0], crossover=[(0.0, 0.0), (3.0, -2.0)])
    analytic = drape(Hemisphere(50.0, 60.0), 5.0, 6, **kwargs)
    meshed = drape(MeshSurface(DATA / "hemisphere_r50.stl"), 5.0, 6, **kwargs)
    assert (analytic.status == Status.OK).all() and (meshed.status == Status.OK).all()
    assert float(np.hypot(analytic.x, analytic.y).max()) < 42.0
    gap = np.linalg.norm(positions(analytic) - positions(meshed), axis=-1)
    shear_gap = float(np.abs(analytic.shear - meshed.shear).max())
    assert gap.max() < 0.15 and shear_gap < 0.3
    assert gap.max() == pytest.approx(STL_HEMISPHERE_POSITION_GAP_MM, rel=1e-6)
    assert shear_gap == pytest.approx(STL_HEMISPHERE_SHEAR_GAP_DEG, rel=1e-6)
    assert float(np.abs(analytic.shear).max()) > 15.0


def test_netcdf_round_trip(tmp_path):
    ds = drape(Hemisphere(20.0, 25.0), 5.0, 6, mode="energy", material=load_material("twintex3_like"),
               blankholder_force=[0.0, 100.0], factors={"spacing_cv": [0.01, 0.02]})
    assert (ds.status != Status.OK).any()  # NaNs travel too
    path = tmp_path / "drape.nc"
    ds.to_netcdf(path)
    with xr.open_dataset(path) as back:
        back.load()
    xr.testing.assert_identical(ds, back)
    expected = {"x": "mm", "y": "mm", "z": "mm", "shear": "degree", "cell_shear": "degree",
                "gamma0": "degree", "turn": "degree", "energy_shear": "J", "energy_bending": "J",
                "energy_blankholder": "J", "energy_blankholder_quadrant": "J", "energy_total": "J",
                "orientation": "degree", "pre_shear": "degree", "skew": "degree", "crossover_x": "mm",
                "crossover_y": "mm", "applied_blankholder_force": "N", "friction": "1"}
    for name, units in expected.items():
        assert back[name].attrs["units"] == units, name
    floats = [v for v in back.data_vars if back[v].dtype.kind == "f"]
    assert all("units" in back[v].attrs for v in floats)
    assert back.attrs["mode"] == "energy" and back.attrs["material"] == "twintex3_like"
    assert back.attrs["rings"] == 6 and back.attrs["spacing_mm"] == 5.0


def test_every_data_variable_carries_units_and_long_name():
    ds = drape(Plate(100.0), 5.0, 2)
    missing = [v for v in ds.data_vars if not {"units", "long_name"} <= set(ds[v].attrs)]
    assert missing == []


def test_max_and_min_shear_lines_on_a_plate():
    s, n = 5.0, 8
    ds = drape(Plate(300.0), s, n, orientation=[0.0, 30.0], crossover=[(0.0, 0.0), (20.0, -10.0)])
    lines = max_shear_lines(ds)
    assert lines.distance.dims[-2:] == ("quadrant", "k") or set(lines.distance.dims) >= {"quadrant", "k"}
    k = np.arange(n + 1)
    np.testing.assert_allclose(lines.distance.transpose("realization", "quadrant", "k").values,
                               np.broadcast_to(k * s * np.sqrt(2), (2, 4, n + 1)), atol=1e-9)
    assert list(lines.quadrant.values) == ["++", "-+", "--", "+-"]
    arms = min_shear_lines(ds)
    np.testing.assert_allclose(arms.distance.transpose("realization", "arm", "k").values,
                               np.broadcast_to(k * s, (2, 4, n + 1)), atol=1e-9)


def test_max_shear_lines_on_a_dome_rise_along_k_and_carry_the_quadrant_sign():
    ds = drape(Hemisphere(100.0), 5.0, 12, orientation=[0.0, 20.0])
    lines = max_shear_lines(ds)
    d = lines.distance.values
    assert np.isfinite(d).all()
    assert (np.diff(lines.distance, axis=lines.distance.dims.index("k")) > 0).all()
    shear = lines.shear.isel(k=slice(1, None))
    assert (shear.sel(quadrant=["++", "--"]) > 0).all() and (shear.sel(quadrant=["-+", "+-"]) < 0).all()
    # |shear| grows away from the pole along each diagonal
    assert (np.abs(shear).diff("k") > 0).all()


def test_blocks_of_a_large_batch_give_the_numbers_of_one_block(monkeypatch):
    """drape() solves large batches in blocks of BLOCK realisations (for cache use); the
    split must not change a number, in either mode."""
    import uqdrape.drape.solver as solver

    rng = np.random.default_rng(3)
    args = dict(orientation=rng.uniform(-10, 10, 7), gamma0=rng.normal(0, 3, (7, 8, 8)),
                blankholder_force=rng.uniform(0, 200, 7))
    for mode in ("geodesic", "energy"):
        whole = drape(Hemisphere(100.0), 5.0, 4, mode=mode, material=load_material("ebxhd936_like"), **args)
        monkeypatch.setattr(solver, "BLOCK", 3)
        split = drape(Hemisphere(100.0), 5.0, 4, mode=mode, material=load_material("ebxhd936_like"), **args)
        monkeypatch.undo()
        xr.testing.assert_identical(whole, split)


def test_full_net_cell_shear_equals_the_minimisers_quad_shear():
    """solver.cell_shear (shared unit edges, whole net) and kernels.quad_shear (one cell
    from its corners, used by the minimiser) are two routes to the same cell shear."""
    from uqdrape.drape.kernels import quad_shear
    from uqdrape.drape.solver import cell_shear

    ds = drape(Hemisphere(100.0), 5.0, 8, orientation=20.0, skew=15.0, crossover=(10.0, -5.0))
    P = np.stack([ds.x.values, ds.y.values, ds.z.values], axis=-1)
    whole = cell_shear(P)
    corners = quad_shear(P[:, :-1, :-1], P[:, 1:, :-1], P[:, 1:, 1:], P[:, :-1, 1:], 1.0)
    assert np.abs(whole).max() > 0.1  # a sheared net
    np.testing.assert_allclose(whole, corners, rtol=0, atol=1e-12)


def test_a_node_is_locked_when_a_valid_cell_next_to_it_locks():
    """`locked` (node) = any adjacent `cell_locked` (which follows each branch's own locking
    angle and the zero-energy offset), NaN at invalid nodes."""
    ds = drape(Hemisphere(100.0), 5.0, 20, material=load_material("twintex3_like"))  # shear to 48 deg, locks at 42
    cells = ds.cell_locked.values[0]
    locked = ds.locked.values[0]
    assert 0 < np.nansum(locked) < np.isfinite(locked).sum()  # some, not all, nodes lock
    n = cells.shape[0]
    for a in range(n + 1):
        for b in range(n + 1):
            near = cells[max(a - 1, 0):a + 1, max(b - 1, 0):b + 1]
            if ds.status.values[0, a, b] != Status.OK:
                assert np.isnan(locked[a, b])
            else:
                assert locked[a, b] == float(near.any())


@pytest.mark.parametrize("mode", ["geodesic", "energy"])
def test_drape_status_is_the_drapes_status_without_its_dataset(mode, monkeypatch):
    """``drape_status`` (the placement check of ``uqdrape validate``, issue 41) solves the
    same nets as ``drape`` and gives their status, over several blocks of realisations too,
    with nodes off a small mould."""
    from uqdrape.drape import drape_status
    from uqdrape.drape import solver

    monkeypatch.setattr(solver, "BLOCK", 2)  # three blocks of five realisations
    rng = np.random.default_rng(2)
    options = dict(orientation=rng.uniform(-30, 30, 5), crossover=rng.normal(0, 5, (5, 2)), mode=mode,
                   material=load_material("generic_woven") if mode == "energy" else None,
                   gamma0=rng.normal(0, 2, (5, 24, 24)), blankholder_force=20.0)
    status = drape_status(Hemisphere(radius=25), 5.0, 12, **options)
    expected = drape(Hemisphere(radius=25), 5.0, 12, **options)["status"].values
    assert status.dtype == expected.dtype and np.array_equal(status, expected)
    assert (status != Status.OK).any() and (status == Status.OK).any()
