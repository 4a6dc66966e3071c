"""Tests of uqdrape.export and ``uqdrape export``: VTK net and mould, FE-mesh mapping with
the Abaqus orientation table, flat pattern (CSV, DXF), bad input.

Small geodesic drapes (hemisphere R = 50 mm, s = 5 mm, 10 rings) and a made-up
triangulated hemisphere mesh; every file is read back with its own reader.
"""

import textwrap

import ezdxf
import meshio
import numpy as np
import pytest
from scipy.spatial import Delaunay

from uqdrape.cli import main
from uqdrape.drape import drape
from uqdrape.export.directions import dot, unit
from uqdrape.export import export_fe, export_flat, export_vtk, fibre_directions, levels, open_result
from uqdrape.export.directions import fibre_deviation
from uqdrape.export.fe import ON_NET, OFF_NET, map_level
from uqdrape.export.flat import flat_pattern
from uqdrape.export.vtk import mould_mesh
from uqdrape.geometry import build

from conftest import assert_one_line_error
from golden import FE_INTERPOLATION_ERROR_RATIO

R, S, RINGS = 50.0, 5.0, 10


@pytest.fixture(scope="module")
def hemi():
    surface = build("hemisphere", radius=R)
    ds = drape(surface, S, RINGS, orientation=15.0, skew=10.0)
    return surface, ds


def hemisphere_mesh(surface, path, radius_mm=1.6 * R, rings=30, scale=1.0, fmt="gmsh22"):
    """A triangulated hemisphere with flange (Delaunay of a polar plan grid), saved with meshio."""
    r = np.linspace(0, radius_mm, rings + 1)[1:]
    t = np.linspace(0, 2 * np.pi, 6 * rings + 1)[:-1]
    rr, tt = np.meshgrid(r, t, indexing="ij")
    xy = np.concatenate([[[0.0, 0.0]], np.column_stack([(rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel()])])
    points = np.column_stack([xy, surface.height(xy[:, 0], xy[:, 1])]) * scale
    meshio.write(path, meshio.Mesh(points, [("triangle", Delaunay(xy).simplices)]), file_format=fmt)
    return path


# ----------------------------------------------------------------------------- fibre directions


def test_fibre_directions_are_unit_tangent_and_open_to_90_minus_shear(hemi):
    surface, ds = hemi
    level = levels(ds, False)[0]
    d1, d2, n = fibre_directions(level.positions, level.shear, surface)
    ok = np.isfinite(level.shear)
    assert ok.sum() == (ds.status == 0).sum() and np.abs(level.shear[ok]).max() > 10.0
    for d in (d1, d2):
        assert np.abs(np.linalg.norm(d[ok], axis=-1) - 1).max() < 1e-12
        assert np.abs(dot(d, n)[ok]).max() < 1e-9
    angle = np.degrees(np.arccos(dot(d1, d2)))
    assert np.abs(angle - (90.0 - level.shear))[ok].max() < 1e-9
    # they follow the net: within a few degrees of the +i and +j edges at interior nodes
    # clear of the rim's crease (where the mould normal jumps from the wall to the flange)
    P = level.positions
    edge_i, edge_j = unit(P[2:, 1:-1] - P[:-2, 1:-1]), unit(P[1:-1, 2:] - P[1:-1, :-2])
    inner = ok[1:-1, 1:-1] & (np.hypot(P[1:-1, 1:-1, 0], P[1:-1, 1:-1, 1]) < R - S)
    assert np.degrees(np.arccos(dot(d1[1:-1, 1:-1], edge_i)))[inner].max() < 5.0
    assert np.degrees(np.arccos(dot(d2[1:-1, 1:-1], edge_j)))[inner].max() < 5.0


def test_fibre_deviation_is_zero_on_a_plate_at_the_blank_orientation():
    plate = build("plate", half_width=200.0)
    level = levels(drape(plate, S, 6, orientation=30.0), False)[0]
    d1, _, n = fibre_directions(level.positions, level.shear, plate)
    assert np.abs(fibre_deviation(d1, n, 30.0)).max() < 1e-9
    np.testing.assert_allclose(fibre_deviation(d1, n, 10.0), 20.0, atol=1e-9)


# ----------------------------------------------------------------------------- VTK


def test_vtk_round_trip_and_headless_vtk_reader(hemi, tmp_path):
    surface, ds = hemi
    level = levels(ds, False)[0]
    net, mould = export_vtk([level], ds, tmp_path / "hemi")
    assert (net.name, mould.name) == ("hemi.vtu", "hemi-mould.vtu")
    back = meshio.read(net)
    valid = (ds.status.values[0] == 0)
    np.testing.assert_array_equal(back.points, level.positions[valid])
    assert back.cells[0].type == "quad" and len(back.cells[0].data) == (valid[:-1, :-1] & valid[1:, :-1]
                                                                         & valid[1:, 1:] & valid[:-1, 1:]).sum()
    np.testing.assert_array_equal(back.point_data["shear"], level.shear[valid])
    np.testing.assert_array_equal(back.point_data["status"], 0)
    np.testing.assert_array_equal(back.point_data["i"], np.nonzero(valid)[0] - RINGS)
    d1, d2, _ = fibre_directions(level.positions, level.shear, surface)
    np.testing.assert_array_equal(back.point_data["fibre1"], d1[valid])
    np.testing.assert_array_equal(back.point_data["fibre2"], d2[valid])
    m = meshio.read(mould)
    expected = mould_mesh(surface, level.positions)
    np.testing.assert_array_equal(m.points, expected.points)
    np.testing.assert_array_equal(m.points[:, 2], surface.height(m.points[:, 0], m.points[:, 1]))

    vtk = pytest.importorskip("vtk")
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(net))
    reader.Update()
    grid = reader.GetOutput()
    names = {grid.GetPointData().GetArrayName(k) for k in range(grid.GetPointData().GetNumberOfArrays())}
    assert names == {"shear", "status", "locked", "fibre1", "fibre2", "fibre_deviation", "i", "j"}
    assert grid.GetNumberOfPoints() == valid.sum() and grid.GetNumberOfCells() == len(back.cells[0].data)
    assert grid.GetPointData().GetArray("fibre1").GetNumberOfComponents() == 3


def test_one_vtk_file_per_force_level(tmp_path):
    surface = build("hemisphere", radius=R)
    ds = drape(surface, S, 5, mode="energy", material=__import__("uqdrape.material").material.load_material(
        "generic_woven"), blankholder_force=[0.0, 100.0])
    paths = export_vtk(levels(ds, False), ds, tmp_path / "sweep")
    assert [p.name for p in paths] == ["sweep-0N.vtu", "sweep-100N.vtu", "sweep-mould.vtu"]
    for p, r in zip(paths, range(2)):
        np.testing.assert_array_equal(meshio.read(p).point_data["shear"], ds.shear.values[r][ds.status.values[r] == 0])


def test_a_drape_file_with_the_old_force_name_still_reads(tmp_path):
    """Issue 35: an older ``uqdrape drape`` file kept the force each drape saw as
    ``blankholder_force``, now an ensemble's level dimension; it reads as
    ``applied_blankholder_force`` (``conventions.RENAMED_VARIABLES``) and its levels are
    still named by force."""
    import netCDF4

    ds = drape(build("hemisphere", radius=R), S, 3, blankholder_force=[0.0, 100.0])
    assert "blankholder_force" not in ds.variables and ds.applied_blankholder_force.attrs["units"] == "N"
    ds.to_netcdf(tmp_path / "old.nc")
    with netCDF4.Dataset(tmp_path / "old.nc", "a") as nc:
        nc.renameVariable("applied_blankholder_force", "blankholder_force")
    back, is_ensemble = open_result(tmp_path / "old.nc")
    assert not is_ensemble and "blankholder_force" not in back.variables
    np.testing.assert_array_equal(back.applied_blankholder_force, [0.0, 100.0])
    assert [level.label for level in levels(back, False)] == ["0N", "100N"]


# ----------------------------------------------------------------------------- FE mapping


def _read_abaqus(path):
    """(default row, {label: 6 numbers}, unmapped labels) of our orientation include."""
    rows, unmapped, block = {}, [], None
    default = None
    for line in path.read_text().splitlines():
        if line.startswith("**"):
            continue
        if line.startswith("*"):
            block = line.split(",")[0].upper()
            continue
        fields = [f.strip() for f in line.split(",")]
        if block == "*DISTRIBUTION":
            if fields[0] == "":
                default = [float(v) for v in fields[1:]]
            else:
                rows[int(fields[0])] = [float(v) for v in fields[1:]]
        elif block == "*ELSET":
            unmapped += [int(v) for v in fields]
    return default, rows, unmapped


def test_fe_mapping_on_a_triangulated_hemisphere(hemi, tmp_path):
    surface, ds = hemi
    level = levels(ds, False)[0]
    mesh_path = hemisphere_mesh(surface, tmp_path / "hemi.msh")
    (vtu, inp), (status,) = export_fe([level], ds, mesh_path, tmp_path / "part")
    n_tri = len(meshio.read(mesh_path).cells_dict["triangle"])
    assert len(status) == n_tri  # every element kept
    assert (status == ON_NET).sum() > 500 and (status == OFF_NET).sum() > 500  # the flange is off the net
    back = meshio.read(vtu)
    cd = {k: v[0] for k, v in back.cell_data.items()}
    np.testing.assert_array_equal(cd["map_status"], status)
    on = status == ON_NET
    assert np.isnan(cd["shear"][~on]).all() and np.isfinite(cd["shear"][on]).all()
    assert np.abs(cd["distance_mm"]).max() < 0.5  # the mesh's chords sit just inside the sphere
    # directions: unit, tangent to the mould at the foot point, 90 - shear apart
    from uqdrape.export.fe import centroids, onto_mould, read_surface_mesh
    mesh, blocks = read_surface_mesh(mesh_path)
    xy, _, _ = onto_mould(surface, centroids(mesh, blocks))
    n = surface.normal(xy[:, 0], xy[:, 1])
    e1, e2 = cd["fibre1"][on], cd["fibre2"][on]
    assert np.abs(np.linalg.norm(e1, axis=-1) - 1).max() < 1e-12
    assert max(np.abs(dot(e1, n[on])).max(), np.abs(dot(e2, n[on])).max()) < 1e-9
    assert np.abs(np.degrees(np.arccos(dot(e1, e2))) - (90 - cd["shear"][on])).max() < 1e-9
    # the Abaqus table (its last distribution, yarn 1's) parses back to the element-plane
    # yarns of the VTU, a row for every element; unmapped elements are listed
    default, rows, unmapped = _read_abaqus(inp)
    assert default == [1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    assert sorted(rows) == list(range(1, n_tri + 1))
    table = np.array([rows[k] for k in sorted(rows)])
    np.testing.assert_array_equal(table[on], np.column_stack([cd["yarn1"][on], cd["yarn2"][on]]))
    assert np.abs(dot(table[~on, :3], table[~on, 3:])).max() < 1e-12  # the default: e1, e2
    assert unmapped == list(np.flatnonzero(~on) + 1)


def _smooth(P):
    return 10.0 * np.sin(P[..., 0] / 15.0) * np.cos(P[..., 1] / 20.0)


def test_fe_interpolation_is_linear_exact_and_second_order(tmp_path):
    """Linear barycentric interpolation: exact for a field linear in plan position, and
    its error on a smooth field falls by ~4 when the net spacing halves (O(s^2))."""
    surface = build("hemisphere", radius=R)
    mesh_path = hemisphere_mesh(surface, tmp_path / "hemi.msh", radius_mm=0.6 * R, rings=12)
    from uqdrape.export.fe import centroids, onto_mould, read_surface_mesh
    mesh, blocks = read_surface_mesh(mesh_path)
    c = centroids(mesh, blocks)
    xy, _, _ = onto_mould(surface, c)
    errors = []
    for s, rings in ((4.0, 10), (2.0, 20)):
        level = levels(drape(surface, s, rings), False)[0]
        P = level.positions
        level.shear = 2.0 + 0.3 * P[..., 0] - 0.1 * P[..., 1]
        linear = map_level(level, surface, c, tolerance_mm=s)
        assert (linear["map_status"] == ON_NET).all()
        np.testing.assert_allclose(linear["shear"], 2.0 + 0.3 * xy[:, 0] - 0.1 * xy[:, 1], rtol=0, atol=1e-9)
        level.shear = _smooth(P)
        errors.append(np.abs(map_level(level, surface, c, tolerance_mm=s)["shear"] - _smooth(xy)).max())
    assert 3.0 < errors[0] / errors[1] < 5.0, errors  # about 4: second order
    assert errors[0] / errors[1] == pytest.approx(FE_INTERPOLATION_ERROR_RATIO, rel=1e-6)


# ----------------------------------------------------------------------------- flat pattern


def test_plate_flat_pattern_equals_its_draped_nodes():
    plate = build("plate", half_width=300.0)
    level = levels(drape(plate, S, 8, orientation=30.0, pre_shear=10.0, crossover=(5.0, -3.0)), False)[0]
    flat, p_valid = flat_pattern(level)
    np.testing.assert_allclose(flat, level.positions[..., :2], rtol=0, atol=1e-9)
    assert (p_valid == 1).all()


def test_hemisphere_flat_pattern_keeps_every_segment_and_writes_csv_and_dxf(hemi, tmp_path):
    surface, ds = hemi
    level = levels(ds, False)[0]
    flat, _ = flat_pattern(level)
    valid = np.isfinite(flat).all(-1)
    np.testing.assert_array_equal(valid, ds.status.values[0] == 0)
    for axis in (0, 1):
        seg = np.linalg.norm(np.diff(flat, axis=axis), axis=-1)
        seg = seg[np.isfinite(seg)]
        assert seg.size > 300 and np.abs(seg - S).max() < 1e-12
    nodes_csv, outline_csv, dxf = export_flat([level], tmp_path / "hemi")
    rows = np.loadtxt(nodes_csv, delimiter=",", skiprows=1)
    assert open(nodes_csv).readline().strip() == "i,j,x_mm,y_mm"
    np.testing.assert_array_equal(rows[:, 2:], flat[valid])
    np.testing.assert_array_equal(rows[:, :2], np.argwhere(valid) - RINGS)
    loop = np.loadtxt(outline_csv, delimiter=",", skiprows=1)
    doc = ezdxf.readfile(dxf)
    assert doc.units == ezdxf.units.MM
    points = np.array([tuple(p.dxf.location)[:2] for p in doc.modelspace().query("POINT")])
    np.testing.assert_array_equal(points, flat[valid])
    (poly,) = doc.modelspace().query("LWPOLYLINE")
    assert poly.closed and poly.dxf.layer == "OUTLINE"
    np.testing.assert_array_equal(np.array(poly.get_points("xy")), loop[:, 3:])
    # the outline walks the boundary of the valid net: consecutive vertices are net neighbours
    ij = loop[:, 1:3]
    steps = np.abs(np.diff(np.vstack([ij, ij[:1]]), axis=0)).sum(1)
    assert (steps == 1).all() and len(ij) >= 4 * 2 * RINGS - 4 * 4


def test_random_spacing_flat_pattern_keeps_its_own_segments():
    surface = build("hemisphere", radius=R)
    rng = np.random.default_rng(3)
    n = 6
    seg_i = S * (1 + 0.02 * rng.standard_normal((2 * n, 2 * n + 1)))
    seg_j = S * (1 + 0.02 * rng.standard_normal((2 * n + 1, 2 * n)))
    ds = drape(surface, S, n, seg_i=seg_i, seg_j=seg_j)
    ds["seg_i"] = (("realization", "cell_i", "j"), seg_i[None])
    ds["seg_j"] = (("realization", "i", "cell_j"), seg_j[None])
    flat, _ = flat_pattern(levels(ds, False)[0])
    np.testing.assert_allclose(np.linalg.norm(np.diff(flat, axis=0), axis=-1), seg_i, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(np.diff(flat, axis=1), axis=-1), seg_j, rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------- CLI and bad input


@pytest.fixture(scope="module")
def drape_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("drape") / "hemi"
    assert main(["drape", "--geometry", "hemisphere", "--param", "radius=50", "--spacing", "5",
                 "--rings", "10", "--out", str(out)]) == 0
    return out.with_suffix(".nc")


def test_cli_drape_file_is_cf_encoded_and_records_its_command(drape_file):
    import netCDF4

    with netCDF4.Dataset(drape_file) as nc:
        assert nc.getncattr("history").endswith(f"uqdrape drape --geometry hemisphere --param radius=50 "
                                                f"--spacing 5 --rings 10 --out {drape_file.with_suffix('')}")
        assert nc.getncattr("title").startswith("uqdrape geodesic drape of hemisphere (radius 50 mm")
        assert nc["shear"].getncattr("coordinates") == "x y z"


def test_cli_export_writes_every_format(drape_file, tmp_path, capsys):
    surface = build("hemisphere", radius=R)
    mesh = hemisphere_mesh(surface, tmp_path / "part.inp", fmt="abaqus")
    assert main(["export", str(drape_file), "--to", "vtk", "fe", "flat", "--mesh", str(mesh),
                 "--out", str(tmp_path / "hemi")]) == 0
    out = capsys.readouterr().out
    names = ["hemi.vtu", "hemi-mould.vtu", "hemi-fe.vtu", "hemi-orientations.inp", "hemi-flat-nodes.csv",
             "hemi-flat-outline.csv", "hemi-flat.dxf"]
    assert all((tmp_path / n).is_file() for n in names) and "on the net" in out
    deviation = meshio.read(tmp_path / "hemi.vtu").point_data["fibre_deviation"]
    assert main(["export", str(drape_file), "--to", "vtk", "--reference", "30", "--out", str(tmp_path / "r30")]) == 0
    np.testing.assert_allclose(meshio.read(tmp_path / "r30.vtu").point_data["fibre_deviation"], deviation - 30,
                               atol=1e-9)
    assert not list(tmp_path.glob("*.part*"))


@pytest.mark.parametrize("case", ["missing", "garbage", "volume", "metres"])
def test_cli_bad_mesh_is_one_line_and_writes_nothing(drape_file, tmp_path, capsys, case):
    surface = build("hemisphere", radius=R)
    mesh = tmp_path / "bad.msh"
    if case == "garbage":
        mesh.write_text("$MeshFormat\nthis is not a mesh\n")
    elif case == "volume":
        points = np.array([[0, 0, 50.0], [10, 0, 45], [0, 10, 45], [0, 0, 40]])
        meshio.write(mesh, meshio.Mesh(points, [("tetra", np.array([[0, 1, 2, 3]]))]), file_format="gmsh22")
    elif case == "metres":
        hemisphere_mesh(surface, mesh, scale=1e-3)
    before = sorted(tmp_path.iterdir()) + sorted(drape_file.parent.iterdir())
    capsys.readouterr()
    assert main(["export", str(drape_file), "--to", "vtk", "fe", "flat", "--mesh", str(mesh),
                 "--out", str(tmp_path / "part")]) == 2
    expected = {"missing": "no such mesh file", "garbage": "cannot read it as a mesh", "volume": "volume mesh",
                "metres": "is the mesh in mm"}[case]
    assert_one_line_error(capsys.readouterr().err, file=mesh, valid=[expected])
    after = sorted(tmp_path.iterdir()) + sorted(drape_file.parent.iterdir())
    assert after == before  # nothing written, not even the VTK of the same call


def test_cli_bad_result_is_one_line(tmp_path, capsys):
    assert main(["export", str(tmp_path / "none.nc"), "--to", "vtk"]) == 2
    (tmp_path / "x.nc").write_text("not netcdf")
    assert main(["export", str(tmp_path / "x.nc"), "--to", "vtk"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "no such file" in err[0] and "not a netCDF file" in err[1]


@pytest.mark.slow  # end to end: a sweep run and its export
def test_ensemble_export_per_force_level(tmp_path):
    from uqdrape.workflow import run_study

    study = tmp_path / "tiny.toml"
    study.write_text(textwrap.dedent(f"""
        [study]
        name = "tiny"
        seed = 5
        realizations = 6
        [geometry]
        kind = "hemisphere"
        radius = 50.0
        [fabric]
        material = "generic_woven"
        spacing_mm = 5.0
        [process]
        blankholder_force_N = [0.0, 50.0]
        [solver]
        mode = "geodesic"
        rings = 5
        [uncertainty.spacing]
        cv = 0.01
        [output]
        directory = "{tmp_path / 'run'}"
    """))
    out = run_study(study, scheduler="synchronous", progress=False)
    ds, is_ensemble = open_result(out)
    assert is_ensemble
    paths = export_vtk(levels(ds, True), ds, tmp_path / "ens")
    assert [p.name for p in paths] == ["ens-0N.vtu", "ens-50N.vtu", "ens-mould.vtu"]
    data = meshio.read(paths[0]).point_data
    assert {"shear_mean", "shear_sd", "shear_q05", "shear_q50", "shear_q95", "p_locked", "p_valid"} <= set(data)
    assert (data["shear_sd"] > 0).any() and ((data["p_locked"] >= 0) & (data["p_locked"] <= 1)).all()
    mesh = hemisphere_mesh(build("hemisphere", radius=R), tmp_path / "part.msh", rings=8)
    (vtu, _, _, _), statuses = export_fe(levels(ds, True), ds, mesh, tmp_path / "ens")
    cells = meshio.read(vtu).cell_data
    on = statuses[0] == ON_NET
    assert on.any() and np.isfinite(cells["shear_sd"][0][on]).all() and np.isfinite(cells["p_locked"][0][on]).all()
    flat = export_flat(levels(ds, True), tmp_path / "ens")
    assert [p.name for p in flat][:3] == ["ens-0N-flat-nodes.csv", "ens-0N-flat-outline.csv", "ens-0N-flat.dxf"]


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # meshio's STL format sniffing
def test_fe_mapping_reads_every_mesh_format_alike(hemi, tmp_path):
    surface, ds = hemi
    level = levels(ds, False)[0]
    results = {}
    for suffix, fmt in ((".msh", "gmsh22"), (".inp", "abaqus"), (".vtu", "vtu"), (".stl", "stl")):
        path = hemisphere_mesh(surface, tmp_path / f"part{suffix}", rings=8, fmt=fmt)
        (vtu, _), (status,) = export_fe([level], ds, path, tmp_path / f"out{suffix}")
        results[suffix] = status, meshio.read(vtu).cell_data["fibre1"][0]
    status, fibre = results[".msh"]
    assert (status == ON_NET).any() and (status == OFF_NET).any()
    for suffix, (other_status, other_fibre) in results.items():
        np.testing.assert_array_equal(other_status, status, err_msg=suffix)
        atol = 1e-5 if suffix == ".stl" else 0.0  # STL stores float32 coordinates
        np.testing.assert_allclose(other_fibre, fibre, rtol=0, atol=atol, err_msg=suffix)


def test_abaqus_table_uses_the_input_meshs_own_element_labels(hemi, tmp_path):
    surface, ds = hemi
    path = hemisphere_mesh(surface, tmp_path / "plain.inp", rings=8, fmt="abaqus")
    lines, elements, k = [], False, 0
    for line in path.read_text().splitlines():  # renumber the elements 1001, 1004, 1007, ...
        if line.startswith("*"):
            elements = line.upper().startswith("*ELEMENT")
        elif elements and line.strip():
            line = ",".join([str(1001 + 3 * k)] + line.split(",")[1:])
            k += 1
        lines.append(line)
    renumbered = tmp_path / "renumbered.inp"
    renumbered.write_text("\n".join(lines) + "\n")
    (_, inp), (status,) = export_fe(levels(ds, False), ds, renumbered, tmp_path / "part")
    expected = 1001 + 3 * np.arange(len(status))
    _, rows, unmapped = _read_abaqus(inp)
    assert sorted(rows) == list(expected) and unmapped == list(expected[status != ON_NET])


def test_cli_unwritable_output_is_an_io_error(drape_file, tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    assert main(["export", str(drape_file), "--to", "vtk", "--out", str(blocker / "net")]) == 3
    assert_one_line_error(capsys.readouterr().err, file=blocker)
    assert not list(tmp_path.glob("**/*.part*"))


def test_locate_skips_triangles_seen_edge_on_without_a_warning():
    import warnings

    from uqdrape.export.fe import locate

    tri = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],     # a plan triangle
                    [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]])    # a vertical face: a segment in plan
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a divide-by-zero RuntimeWarning fails the test
        index, weights = locate(np.array([[0.2, 0.2], [0.5, 0.5], [5.0, 5.0]]), tri)
    assert index.tolist() == [0, 0, -1]
    np.testing.assert_allclose(weights[0], [0.6, 0.2, 0.2], rtol=1e-15)
