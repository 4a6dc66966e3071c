"""Cutting patterns (``uqdrape export --to cut``): the part's edge in the flat blank.

The reference for a hemisphere is the geodesic (Chebyshev) net built here independently:
generators on the two great circles through the pole, every other node the closed-form
intersection of the sphere with the two spheres of radius s about its neighbours
(trilateration), the flat blank (i s, j s). On a fine net (s = 0.25 mm) the cap's edge
is the contour r = a of the nodes' plan radius over (i s, j s), traced by matplotlib:
its length and area are the continuum pattern's to O(s_ref^2).
"""

import ezdxf
import numpy as np
import pytest
from conftest import assert_one_line_error

from uqdrape.cli import main
from uqdrape.drape import drape
from uqdrape.export import export_cut, levels
from uqdrape.export.cutting import perimeter
from uqdrape.geometry.outline import polygon_area
from uqdrape.export.result import _ensemble_level
from uqdrape.geometry import build

R, A = 50.0, 35.0  # sphere radius, plan radius of the part's edge (mm)


def chebyshev_net(radius, s, n):
    """Node positions (2n+1, 2n+1, 3) of the geodesic pin-jointed net on the sphere |X| = radius
    draped from its pole, fibre 1 along x."""
    P = np.full((2 * n + 1, 2 * n + 1, 3), np.nan)
    t = np.arange(-n, n + 1) * 2 * np.arcsin(s / (2 * radius))
    P[:, n] = radius * np.column_stack([np.sin(t), 0 * t, np.cos(t)])
    P[n, :] = radius * np.column_stack([0 * t, np.sin(t), np.cos(t)])
    c = radius ** 2 - s ** 2 / 2  # X.A = X.B = c for |X| = |A| = |B| = radius, |X - A| = |X - B| = s
    for si in (1, -1):
        for sj in (1, -1):
            for d in range(2, 2 * n + 1):
                i = np.arange(max(1, d - n), min(n, d - 1) + 1)
                j = d - i
                I, J = n + si * i, n + sj * j
                a, b, far = P[I - si, J], P[I, J - sj], P[I - si, J - sj]
                ab = np.einsum("kc,kc->k", a, b)
                det = radius ** 4 - ab ** 2
                alpha = c * (radius ** 2 - ab) / det  # = beta, by symmetry of the equations
                base = alpha[:, None] * (a + b)
                axis = np.cross(a, b)
                gamma = np.sqrt((radius ** 2 - np.einsum("kc,kc->k", base, base)) / np.einsum("kc,kc->k", axis, axis))
                x1, x2 = base + gamma[:, None] * axis, base - gamma[:, None] * axis
                pick = (np.linalg.norm(x1 - far, axis=1) > np.linalg.norm(x2 - far, axis=1))[:, None]
                P[I, J] = np.where(pick, x1, x2)
    return P


@pytest.fixture(scope="module")
def reference():
    """(length, area) of the continuum cap pattern, from a 0.25 mm net."""
    from matplotlib.figure import Figure

    s, n = 0.25, 200
    P = chebyshev_net(R, s, n)
    u = s * np.arange(-n, n + 1)
    contour = Figure().add_subplot().contour(u, u, np.hypot(P[..., 0], P[..., 1]).T, [A])
    (loop,) = [p for p in contour.get_paths()[0].to_polygons() if len(p) > 100]
    return perimeter(loop), abs(polygon_area(loop))


def trim_csv(path, vertices=720):
    t = 2 * np.pi * np.arange(vertices) / vertices
    np.savetxt(path, A * np.column_stack([np.cos(t), np.sin(t)]), delimiter=",", header="x_mm,y_mm", comments="")
    return path


def read_cut_csv(path):
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    return lines[0].split(","), np.loadtxt(lines[1:], delimiter=",")


def test_the_reference_net_is_uqdrapes_geodesic_net():
    s, n = 5.0, 10
    P = chebyshev_net(R, s, n)
    ds = drape(build("hemisphere", radius=R), s, n)
    net = np.stack([ds[c].values[0] for c in ("x", "y", "z")], axis=-1)
    inside = np.hypot(P[..., 0], P[..., 1]) < R - s  # nodes whose cells stay on the sphere
    np.testing.assert_allclose(net[inside], P[inside], rtol=0, atol=1e-9)


@pytest.mark.parametrize("s, rings", [(5.0, 10), (2.5, 20)])
def test_hemisphere_cap_pattern_against_the_continuum_net(tmp_path, reference, s, rings):
    surface = build("hemisphere", radius=R)
    ds = drape(surface, s, rings)
    dxf, csv = export_cut(levels(ds, False), ds, tmp_path / "cap", trim=trim_csv(tmp_path / "edge.csv"), ply="P1")
    header, rows = read_cut_csv(csv)
    assert header == ["point", "x_plan_mm", "y_plan_mm", "x_mm", "y_mm"]
    outline = rows[:, 3:5]
    length, area = reference
    # measured (this test's own numbers): length 238.978 / 238.782 mm (1.25 mm: 238.733),
    # area 4527.78 / 4521.23 mm^2 (4519.66) at s = 5 / 2.5 against 238.722 mm and 4519.25
    # mm^2: errors 0.107 / 0.025 / 0.005 % and 0.19 / 0.044 / 0.009 %, second order in s;
    # the 0.25 mm reference moves 4e-6 / 2e-5 (relative) from the 0.5 mm one
    assert perimeter(outline) == pytest.approx(length, rel=0.003 * (s / 5) ** 2)
    assert abs(polygon_area(outline)) == pytest.approx(area, rel=0.003 * (s / 5) ** 2)
    # closed form on the generator y = 0: nodes at R sin(k alpha), chords of s in the blank
    alpha = 2 * np.arcsin(s / (2 * R))
    k = int(np.floor(np.arcsin(A / R) / alpha))
    x_k, x_k1 = R * np.sin(k * alpha), R * np.sin((k + 1) * alpha)
    on_axis = rows[np.isclose(rows[:, 2], 0.0) & (rows[:, 1] > 0)]
    assert on_axis[0, 3] == pytest.approx(s * (k + (A - x_k) / (x_k1 - x_k)), abs=1e-9)
    assert on_axis[0, 4] == pytest.approx(0.0, abs=1e-9)
    doc = ezdxf.readfile(dxf)
    assert len(doc.audit().errors) == 0 and doc.units == ezdxf.units.MM
    layers = {e.dxf.layer for e in doc.modelspace()}
    assert layers == {"CUT", "FIBRE", "SEED", "LABEL"}
    (cut,) = doc.modelspace().query("LWPOLYLINE[layer=='CUT']")
    assert cut.closed
    np.testing.assert_allclose(np.array(cut.get_points("xy")), outline, rtol=0, atol=1e-12)
    texts = [t.dxf.text for t in doc.modelspace().query("TEXT[layer=='LABEL']")]
    assert "P1" in texts and any("origin the seed point, x along fibre 1" in t for t in texts)
    (seed,) = doc.modelspace().query("POINT[layer=='SEED']")
    assert tuple(seed.dxf.location)[:2] == (0.0, 0.0)


def test_pattern_is_in_the_fabric_axes_whatever_the_orientation(tmp_path):
    surface = build("hemisphere", radius=R)
    trim = trim_csv(tmp_path / "edge.csv")
    outlines = []
    for orientation in (0.0, 30.0):
        ds = drape(surface, 5.0, 10, orientation=orientation)
        _, csv = export_cut(levels(ds, False), ds, tmp_path / f"o{orientation:g}", trim=trim)
        outlines.append(read_cut_csv(csv)[1])
    # the same edge point in plan, turned by -30 deg on the sphere, sits at the same fabric position
    plan, turned = outlines[0][:, 1:3], outlines[1][:, 1:3]
    np.testing.assert_allclose(plan, turned, atol=1e-12)
    shift = 60  # 30 deg of 720 vertices
    np.testing.assert_allclose(np.roll(outlines[1][:, 3:5], -shift, axis=0), outlines[0][:, 3:5], atol=1e-6)


def test_ensemble_pattern_has_its_envelope(tmp_path):
    surface = build("hemisphere", radius=R)
    ds = drape(surface, 5.0, 10, orientation=np.linspace(-6.0, 6.0, 9))
    level = _ensemble_level(ds, "")
    dxf, csv = export_cut([level], ds, tmp_path / "ens", trim=trim_csv(tmp_path / "edge.csv"))
    header, rows = read_cut_csv(csv)
    assert header[-3:] == ["offset_q025_mm", "offset_q975_mm", "drapes"] and (rows[:, -1] == 9).all()
    assert (rows[:, -3] <= 0).all() and (rows[:, -2] >= 0).all() and (rows[:, -2] - rows[:, -3]).max() > 0.1
    doc = ezdxf.readfile(dxf)
    assert len(doc.audit().errors) == 0
    inner, outer = doc.modelspace().query("LWPOLYLINE[layer=='ENVELOPE']")
    assert abs(polygon_area(np.array(inner.get_points("xy")))) <= abs(polygon_area(rows[:, 3:5]))
    assert abs(polygon_area(np.array(outer.get_points("xy")))) >= abs(polygon_area(rows[:, 3:5]))
    assert "ENVELOPE: 2.5-97.5 %" in csv.read_text().splitlines()[0]


def test_mould_outline_is_the_default_edge_and_a_plate_has_none(tmp_path, capsys):
    out = tmp_path / "d"
    assert main(["drape", "--geometry", "hemisphere", "--param", "radius=20", "--spacing", "2", "--rings", "20",
                 "--out", str(out), "-q"]) == 0
    assert main(["export", str(out.with_suffix(".nc")), "--to", "cut", "--out", str(tmp_path / "rim")]) == 0
    t = 2 * np.pi * np.arange(720) / 720  # the rim as a trim curve gives the same pattern
    np.savetxt(tmp_path / "rim.csv", 20.0 * np.column_stack([np.cos(t), np.sin(t)]), delimiter=",")
    assert main(["export", str(out.with_suffix(".nc")), "--to", "cut", "--trim", str(tmp_path / "rim.csv"),
                 "--out", str(tmp_path / "trim")]) == 0
    np.testing.assert_array_equal(read_cut_csv(tmp_path / "rim-cut.csv")[1], read_cut_csv(tmp_path / "trim-cut.csv")[1])
    capsys.readouterr()
    plate = tmp_path / "p"
    assert main(["drape", "--geometry", "plate", "--spacing", "5", "--rings", "4", "--out", str(plate), "-q"]) == 0
    assert main(["export", str(plate.with_suffix(".nc")), "--to", "cut"]) == 2
    assert_one_line_error(capsys.readouterr().err, valid=["--trim", "hemisphere", "cone", "nose_cone"])


@pytest.mark.parametrize("text, why", [("x_mm,y_mm\n0,0\n1,1\n", "at least 3"), ("x_mm,y_mm\n0,0\nfoo,1\n2,2\n",
                                       "line 3"), ("0,0\n1,1\n2,2\n", "encloses no area")])
def test_bad_trim_curve_is_one_line_naming_the_file(tmp_path, capsys, text, why):
    out = tmp_path / "d"
    assert main(["drape", "--geometry", "plate", "--spacing", "5", "--rings", "4", "--out", str(out), "-q"]) == 0
    trim = tmp_path / "edge.csv"
    trim.write_text(text)
    assert main(["export", str(out.with_suffix(".nc")), "--to", "cut", "--trim", str(trim)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=trim, valid=[why])
    assert not list(tmp_path.glob("d-cut*"))
