"""Both yarn directions per element in the Abaqus, LS-DYNA and Nastran flavours of
``uqdrape export --to fe``, each read back with a small parser of its own card syntax
written here (not uqdrape's), and the element frame rebuilt here from the nodes.

A geodesic drape of a hemisphere (R = 50 mm, s = 5 mm, 10 rings, orientation 15 deg,
skew 10 deg: shear up to about 25 deg) on a made-up mesh of quads (x < 0) and triangles.
"""

import numpy as np
import pytest

from uqdrape.cli import main
from uqdrape.drape import drape
from uqdrape.export import export_fe, levels
from uqdrape.export.fe import ON_NET
from uqdrape.export.result import _ensemble_level
from uqdrape.geometry import build

R, S, RINGS = 50.0, 5.0, 10


@pytest.fixture(scope="module")
def hemi():
    surface = build("hemisphere", radius=R)
    return surface, drape(surface, S, RINGS, orientation=15.0, skew=10.0)


def mixed_mesh(surface, path, half=70.0, cells=28):
    """A plan grid over |x|, |y| <= half lifted onto the mould: quads where x < 0, each other
    cell split into two triangles; saved as Gmsh 2.2."""
    import meshio

    g = np.linspace(-half, half, cells + 1)
    X, Y = np.meshgrid(g, g, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), surface.height(X.ravel(), Y.ravel())])
    idx = np.arange(pts.shape[0]).reshape(X.shape)
    quads, tris = [], []
    for a in range(cells):
        for b in range(cells):
            q = [idx[a, b], idx[a + 1, b], idx[a + 1, b + 1], idx[a, b + 1]]
            if g[a] + g[a + 1] < 0:
                quads.append(q)
            else:
                tris += [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
    meshio.write(path, meshio.Mesh(pts, [("quad", np.array(quads)), ("triangle", np.array(tris))]),
                 file_format="gmsh22")
    return path


def frame(points, corners):
    """Element frame as LS-DYNA and Nastran define it: normal by node order, e1 along n1 -> n2."""
    p = [points[c] for c in corners]
    n = np.cross(p[1] - p[0], p[2] - p[0]) if len(p) == 3 else np.cross(p[2] - p[0], p[3] - p[1])
    n /= np.linalg.norm(n)
    e1 = p[1] - p[0] - np.dot(p[1] - p[0], n) * n
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1), n


def fields_table(path, prefix):
    """{label: {column: value}} of the UQDRAPE-FIELDS comment table."""
    lines = [ln[len(prefix):].strip() for ln in path.read_text().splitlines() if ln.startswith(prefix)]
    start = next(k for k, ln in enumerate(lines) if ln.startswith("UQDRAPE-FIELDS"))
    names = lines[start].split()[1].split(",")
    return {int(row.split(",")[0]): dict(zip(names[1:], map(float, row.split(",")[1:])))
            for row in lines[start + 1:] if row and row[0].isdigit()}


def read_abaqus(path):
    """{distribution name: (default row, {label: 6 floats})}, {orientation: distribution}, unmapped set."""
    dists, orient, unmapped, block, name = {}, {}, [], None, None
    for line in path.read_text().splitlines():
        if line.startswith("**"):
            continue
        if line.startswith("*"):
            words = [w.strip() for w in line.split(",")]
            block = words[0].upper()
            opts = dict(w.split("=", 1) for w in words[1:] if "=" in w)
            name = opts.get("NAME")
            if block == "*DISTRIBUTION":
                dists[name] = [None, {}]
            continue
        f = [v.strip() for v in line.split(",")]
        if block == "*DISTRIBUTION":
            if f[0] == "":
                dists[name][0] = [float(v) for v in f[1:]]
            else:
                dists[name][1][int(f[0])] = [float(v) for v in f[1:]]
        elif block == "*ORIENTATION":
            orient[name] = f[0]
        elif block == "*ELSET":
            unmapped += [int(v) for v in f if v]
    return dists, orient, unmapped


def read_lsdyna(path):
    """Nodes {id: xyz}, shells [(eid, pid, nodes, beta)], the ids of *SET_SHELL_LIST: fixed columns."""
    nodes, shells, sets, block, lines = {}, [], [], None, path.read_text().splitlines()
    k = 0
    while k < len(lines):
        line = lines[k]
        k += 1
        if line.startswith("$"):
            continue
        if line.startswith("*"):
            block, first = line.strip().upper(), True
            continue
        if block == "*NODE":
            nodes[int(line[:8])] = np.array([float(line[8 + 16 * c:24 + 16 * c]) for c in range(3)])
        elif block == "*ELEMENT_SHELL_BETA":
            ids = [int(line[8 * c:8 * c + 8]) for c in range(6)]
            beta = float(lines[k][64:80])
            k += 1
            shells.append((ids[0], ids[1], ids[2:], beta))
        elif block == "*SET_SHELL_LIST":
            if not first:
                sets += [int(line[10 * c:10 * c + 10]) for c in range(len(line) // 10)]
            first = False
    return nodes, shells, sets


def nastran_float(text):
    text = text.strip()
    for k in range(len(text) - 1, 0, -1):  # 1.5+2 / 1.5-2: an exponent without E
        if text[k] in "+-" and text[k - 1] not in "eE":
            return float(text[:k] + "e" + text[k:])
    return float(text)


def read_nastran(path):
    """{card name: [fields]} entries of a large-field bulk data file."""
    entries = []
    for line in path.read_text().splitlines():
        if line.startswith("$") or not line.strip():
            continue
        head = line[:8].strip()
        fields = [line[8 + 16 * c:24 + 16 * c].strip() for c in range((len(line) - 8 + 15) // 16)]
        if head == "*":
            entries[-1][1].extend(fields)
        else:
            entries.append((head.rstrip("*"), fields))
    return entries


def angle_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


@pytest.fixture(scope="module")
def exported(hemi, tmp_path_factory):
    surface, ds = hemi
    folder = tmp_path_factory.mktemp("fe")
    mesh = mixed_mesh(surface, folder / "part.msh")
    paths, (status,) = export_fe(levels(ds, False), ds, mesh, folder / "part",
                                 flavours=("abaqus", "lsdyna", "nastran"))
    assert [p.name for p in paths] == ["part-fe.vtu", "part-orientations.inp", "part-lsdyna.k", "part-nastran.bdf"]
    import meshio

    return dict(zip(("vtu", "abaqus", "lsdyna", "nastran"), paths)), status, meshio.read(mesh), surface


def mesh_cells(mesh):
    """The corner node lists of every cell of the meshio ``mesh``, in file order."""
    return [list(c) for block in mesh.cells for c in block.data]


def test_abaqus_keeps_both_yarns_as_local_1_of_two_orientations(exported):
    """Every element's row read back: both local-1 vectors in the element's plane (the
    frame rebuilt here from meshio's nodes) to 1e-9, 90 deg - shear apart to 1e-9 deg, so
    Abaqus's projection onto the shell and its orthogonalisation of local 2 keep both."""
    paths, status, mesh, _ = exported
    dists, orient, unmapped = read_abaqus(paths["abaqus"])
    assert orient == {"UQDRAPE_YARN1_ORIENTATION": "UQDRAPE_YARN1", "UQDRAPE_YARN2_ORIENTATION": "UQDRAPE_YARN2"}
    cells = mesh_cells(mesh)
    labels = list(range(1, len(cells) + 1))
    assert sorted(dists["UQDRAPE_YARN1"][1]) == labels == sorted(dists["UQDRAPE_YARN2"][1])
    assert unmapped == list(np.flatnonzero(status != ON_NET) + 1) and unmapped
    assert dists["UQDRAPE_YARN1"][0] == [1, 0, 0, 0, 1, 0] and dists["UQDRAPE_YARN2"][0] == [0, 1, 0, -1, 0, 0]
    table = fields_table(paths["abaqus"], "**")
    _, shells, _ = read_lsdyna(paths["lsdyna"])
    worst_unit = worst_plane = worst_angle = 0.0
    for label, corners in zip(labels, cells):
        y1, b1 = np.split(np.array(dists["UQDRAPE_YARN1"][1][label]), 2)
        y2, b2 = np.split(np.array(dists["UQDRAPE_YARN2"][1][label]), 2)
        np.testing.assert_array_equal(b1, y2)  # yarn 1's local 2 towards yarn 2
        np.testing.assert_array_equal(b2, -y1)  # yarn 2's frame: the same local 3
        e1, e2, n = frame(mesh.points, corners)
        worst_unit = max(worst_unit, abs(np.linalg.norm(y1) - 1), abs(np.linalg.norm(y2) - 1))
        worst_plane = max(worst_plane, abs(np.dot(y1, n)), abs(np.dot(y2, n)))
        worst_angle = max(worst_angle, abs(angle_deg(y1, y2) - (90 - table[label]["shear_deg"])))
        beta = np.radians(shells[label - 1][3])  # the same yarn 1 as LS-DYNA's angle
        np.testing.assert_allclose(y1, np.cos(beta) * e1 + np.sin(beta) * e2, rtol=0, atol=1e-9)
        if status[label - 1] != ON_NET:  # the default: the element frame's e1, e2
            np.testing.assert_allclose(np.concatenate([y1, y2]), np.concatenate([e1, e2]), rtol=0, atol=1e-12)
    assert worst_unit < 1e-12 and worst_plane < 1e-9 and worst_angle < 1e-9
    shear = np.array([table[k]["shear_deg"] for k in labels])
    assert np.abs(shear).max() > 15  # the test sees a sheared ply


def test_lsdyna_two_beta_layers_read_back(exported):
    paths, status, mesh, _ = exported
    nodes, shells, unmapped = read_lsdyna(paths["lsdyna"])
    M = len(status)
    assert len(nodes) == len(mesh.points) and len(shells) == 2 * M
    np.testing.assert_allclose(np.array([nodes[k + 1] for k in range(len(nodes))]), mesh.points, rtol=1e-9, atol=1e-9)
    layer1, layer2 = shells[:M], shells[M:]
    offset = layer2[0][0] - layer1[0][0]
    assert offset == 10 ** len(str(M)) and {s[1] for s in layer1} == {1} and {s[1] for s in layer2} == {2}
    table = fields_table(paths["lsdyna"], "$")
    worst_plane = worst_angle = 0.0
    for (eid, _, n1, beta1), (eid2, _, n2, beta2) in zip(layer1, layer2):
        assert eid2 == eid + offset and n1 == n2
        corners = list(dict.fromkeys(n1))  # a triangle repeats its third node
        e1, e2, n = frame(nodes, corners)
        y1 = np.cos(np.radians(beta1)) * e1 + np.sin(np.radians(beta1)) * e2
        y2 = np.cos(np.radians(beta2)) * e1 + np.sin(np.radians(beta2)) * e2
        worst_plane = max(worst_plane, abs(np.dot(y1, n)), abs(np.dot(y2, n)))
        worst_angle = max(worst_angle, abs(angle_deg(y1, y2) - (90 - table[eid]["shear_deg"])))
        assert table[eid]["theta1_deg"] == pytest.approx(beta1, abs=1e-9)
    assert worst_plane < 1e-9 and worst_angle < 1e-9
    off = np.flatnonzero(status != ON_NET) + 1
    assert sorted(unmapped) == sorted(list(off) + list(off + offset))
    assert all(shells[k - 1][3] == 0.0 and shells[M + k - 1][3] == 90.0 for k in off)  # the default


def test_nastran_mcid_axes_read_back_and_agree_with_lsdyna(exported):
    paths, status, mesh, _ = exported
    entries = read_nastran(paths["nastran"])
    grids = {int(f[0]): np.array([nastran_float(v) for v in f[2:5]]) for name, f in entries if name == "GRID"}
    cords = {int(f[0]): (np.array([nastran_float(v) for v in f[5:8]]), np.array([nastran_float(v) for v in f[8:11]]))
             for name, f in entries if name == "CORD2R"}
    elems = [(name, [int(v) for v in f]) for name, f in entries if name in ("CQUAD4", "CTRIA3")]
    M = len(status)
    assert len(grids) == len(mesh.points) and len(elems) == 2 * M == len(cords)
    assert {n for n, _ in elems} == {"CQUAD4", "CTRIA3"}
    table = fields_table(paths["nastran"], "$")
    _, shells, _ = read_lsdyna(paths["lsdyna"])
    yarn = {}
    worst_plane = 0.0
    for (name, f), shell in zip(elems, shells):
        eid, g = f[0], f[2:-1]
        assert len(g) == (4 if name == "CQUAD4" else 3) and f[-1] == eid  # MCID = EID
        z, c = cords[eid]
        e1, e2, n = frame(grids, g)
        x = c - np.dot(c, z) / np.dot(z, z) * z
        yarn[eid] = x / np.linalg.norm(x)
        worst_plane = max(worst_plane, abs(np.dot(yarn[eid], n)))
        beta = np.radians(shell[3])  # the same yarn from LS-DYNA's angle
        np.testing.assert_allclose(yarn[eid], np.cos(beta) * e1 + np.sin(beta) * e2, rtol=0, atol=1e-9)
    assert worst_plane < 1e-9
    offset = elems[M][1][0] - elems[0][1][0]
    errors = [abs(angle_deg(yarn[k], yarn[k + offset]) - (90 - table[k]["shear_deg"])) for k in table]
    assert max(errors) < 1e-9


def test_vtu_carries_the_element_angles_and_area_ratio(exported):
    import meshio

    paths, status, _, surface = exported
    cd = {k: np.concatenate(v) for k, v in meshio.read(paths["vtu"]).cell_data.items()}
    on = status == ON_NET
    np.testing.assert_allclose(cd["area_ratio"][on], np.cos(np.radians(cd["shear"][on])), rtol=0, atol=1e-15)
    turn = (cd["theta2"] - cd["theta1"] + 180.0) % 360.0 - 180.0  # yarn 1 -> yarn 2 about e3
    np.testing.assert_allclose(np.abs(turn[on]), 90.0 - cd["shear"][on], rtol=0, atol=1e-9)
    # the element-plane yarn is the mould-tangent fibre turned by the smallest rotation taking
    # the mould normal onto the element's: it moves by at most the angle between the two
    from uqdrape.export.fe import centroids, onto_mould, read_surface_mesh

    mesh, blocks = read_surface_mesh(paths["vtu"].with_name("part.msh"))
    xy, _, _ = onto_mould(surface, centroids(mesh, blocks))
    mould_n = surface.normal(xy[:, 0], xy[:, 1])
    cells = [c for b in blocks for c in b.data]
    for k in np.flatnonzero(on):
        n = frame(mesh.points, list(cells[k]))[2]
        tilt = min(angle_deg(n, mould_n[k]), angle_deg(-n, mould_n[k]))
        assert angle_deg(cd["yarn1"][k], cd["fibre1"][k]) <= tilt + 1e-9
        assert angle_deg(cd["yarn2"][k], cd["fibre2"][k]) <= tilt + 1e-9


def test_ensemble_angle_percentiles_follow_the_sampled_orientation(tmp_path):
    """Eleven drapes at orientations 10, 12, ..., 30 deg: on a hemisphere the net turns with
    the orientation, so each element's yarn-1 angle has P5 / P50 / P95 at about the angle
    of single drapes at 11, 20 and 29 deg (linear quantiles of the eleven)."""
    surface = build("hemisphere", radius=R)
    orientations = np.arange(10.0, 31.0, 2.0)
    ds = drape(surface, S, 6, orientation=orientations)
    level = _ensemble_level(ds, "")
    assert level.is_ensemble
    mesh = mixed_mesh(surface, tmp_path / "part.msh", half=20.0, cells=8)
    import meshio

    (vtu, _), (status,) = export_fe([level], ds, mesh, tmp_path / "ens")
    cd = {k: np.concatenate(v) for k, v in meshio.read(vtu).cell_data.items()}
    on = status == ON_NET
    assert on.all()
    for q, orientation in ((5, 11.0), (50, 20.0), (95, 29.0)):
        one = drape(surface, S, 6, orientation=orientation)
        (v1, _), _ = export_fe(levels(one, False), one, mesh, tmp_path / f"one{q}")
        single = np.concatenate(meshio.read(v1).cell_data["theta1"])
        assert np.abs(cd[f"theta1_q{q:02d}"] - single).max() < 0.5, q


def test_cli_flavours_and_a_bad_one(hemi, tmp_path, capsys):
    surface, _ = hemi
    mesh = mixed_mesh(surface, tmp_path / "part.msh", half=30.0, cells=6)
    out = tmp_path / "d"
    assert main(["drape", "--geometry", "hemisphere", "--param", "radius=50", "--spacing", "5", "--rings", "10",
                 "--out", str(out), "-q"]) == 0
    assert main(["export", str(out.with_suffix(".nc")), "--to", "fe", "--mesh", str(mesh), "--flavour", "lsdyna",
                 "nastran", "--out", str(tmp_path / "x")]) == 0
    assert (tmp_path / "x-lsdyna.k").is_file() and (tmp_path / "x-nastran.bdf").is_file()
    assert not (tmp_path / "x-orientations.inp").exists()
    with pytest.raises(SystemExit) as stop:
        main(["export", str(out.with_suffix(".nc")), "--to", "fe", "--mesh", str(mesh), "--flavour", "ansys"])
    assert stop.value.code == 2
    assert "invalid choice" in capsys.readouterr().err
