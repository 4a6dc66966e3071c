"""The laminate FE handoff (``uqdrape.export.laminate``, issue 37): every ply's yarn
angles on a shell mesh as composite sections of Abaqus, LS-DYNA and Nastran, Monte Carlo
decks, and the samples' Karhunen-Loeve modes as CF netCDF.

Laminate ensembles are built here as the lead's run lays them out: each ply draped
(geodesic) at rosette + its angle (+ a per-realisation misalignment), put at a force
level and concatenated along ``ply``. Every card file is read back with the small
parsers below (not uqdrape's), the element frame rebuilt from the mesh nodes.
"""

import meshio
import numpy as np
import pytest
import xarray as xr

from uqdrape import schema
from uqdrape.drape import drape
from uqdrape.ensemble import open_ensemble
from uqdrape.export.laminate import export_laminate
from uqdrape.geometry import build
from uqdrape.workflow import run_study

from conftest import assert_cf_compliant, assert_one_line_error, write_study
from test_fe_flavours import frame, nastran_float, read_nastran

ANGLES = (0.0, 45.0, 90.0, -45.0)
FLAVOURS = ("abaqus", "lsdyna", "nastran")


def laminate(surface, spacing, rings, angles=ANGLES, rosette=0.0, misalignment=(0.0,), force=0.0):
    """A laminate ensemble of one force level: ply k draped at rosette + angles[k] +
    misalignment[r] (``spacing``: one, or one per ply), laid out as the run lays one out
    (``uqdrape.ensemble.chunk.drape_laminate``): an attribute that differs between plies
    becomes a ``ply_<attribute>`` coordinate."""
    spacings = np.broadcast_to(spacing, (len(angles),))
    plies = [schema.at_level(drape(surface, s, rings, orientation=rosette + a + np.asarray(misalignment)), force)
             for a, s in zip(angles, spacings)]
    ds = xr.concat(plies, dim=schema.PLY, join="override", combine_attrs="drop_conflicts")
    differ = {f"{schema.PLY_ATTR}{name}": (schema.PLY, [p.attrs[name] for p in plies]) for name in plies[0].attrs
              if name not in ds.attrs}
    return ds.assign_coords({schema.PLY: [f"ply{k}" for k in range(len(angles))],
                             schema.PLY_ANGLE: (schema.PLY, list(angles)), **differ}).assign_attrs(rosette_deg=rosette)


def grid_mesh(path, lift, u, v, roll=True):
    """Quads over the grid ``u`` x ``v`` placed by ``lift(U, V) -> (N, 3)``, node order
    counterclockwise seen from +z; if ``roll``, each quad's started at a random corner (so
    e1 varies) and every third one reversed (its normal points down); as .inp."""
    U, V = np.meshgrid(u, v, indexing="ij")
    points = lift(U.ravel(), V.ravel())
    idx = np.arange(len(points)).reshape(U.shape)
    quads = np.array([[idx[a, b], idx[a + 1, b], idx[a + 1, b + 1], idx[a, b + 1]]
                      for a in range(len(u) - 1) for b in range(len(v) - 1)])
    if roll:
        shifts = np.random.default_rng(1).integers(0, 4, len(quads))
        quads = np.array([np.roll(q, -s)[::-1 if k % 3 == 0 else 1] for k, (q, s) in enumerate(zip(quads, shifts))])
    meshio.write(path, meshio.Mesh(points, [("quad", quads)]), file_format="abaqus")
    return path


def element_frames(path):
    """Element frames (e1, e2, e3) rebuilt from the nodes of the mesh at ``path``, in file order."""
    mesh = meshio.read(path)
    return [frame(mesh.points, list(c)) for b in mesh.cells for c in b.data]


def line_diff(a, b):
    """a - b (deg) for lines: taken into [-90, 90)."""
    return (np.asarray(a) - np.asarray(b) + 90.0) % 180.0 - 90.0


def read_abaqus(path, frames):
    """({layer orientation: {label: angle deg}}, [(elset, [layer lines])], {elset: labels}):
    each distribution's local-1 vector as an angle from e1 about e3 of ``frames``."""
    dist, sections, elsets, block, name = {}, [], {}, None, None
    for line in path.read_text().splitlines():
        if line.startswith("**"):
            continue
        if line.startswith("*"):
            words = [w.strip() for w in line.split(",")]
            block, opts = words[0].upper(), dict(w.split("=", 1) for w in words[1:] if "=" in w)
            name = opts.get("NAME") or opts.get("ELSET")
            if block == "*SHELL SECTION":
                sections.append((name, []))
            elif block == "*ELSET":
                elsets[name] = []
            elif block == "*DISTRIBUTION":
                dist[name] = {}
            continue
        f = [w.strip() for w in line.split(",")]
        if block == "*DISTRIBUTION" and f[0]:
            e1, e2, _ = frames[int(f[0]) - 1]
            vec = np.array([float(x) for x in f[1:4]])
            dist[name][int(f[0])] = np.degrees(np.arctan2(vec @ e2, vec @ e1))
        elif block == "*ELSET":
            elsets[name] += [int(x) for x in f if x]
        elif block == "*SHELL SECTION":
            sections[-1][1].append(f)
    return dist, sections, elsets


def read_lsdyna_composite(path):
    """{eid: [(mid, thick, b), ...]} of *ELEMENT_SHELL_COMPOSITE and {sid: ids} of *SET_SHELL_LIST (fixed columns)."""
    shells, sets, block, eid, sid = {}, {}, None, None, None
    for line in path.read_text().splitlines():
        if line.startswith("$"):
            continue
        if line.startswith("*"):
            block, sid = line.strip().upper(), None
            continue
        if block == "*ELEMENT_SHELL_COMPOSITE":
            if len(line) <= 48:  # the element card: eid pid n1..n4 in 8 columns
                eid = int(line[:8])
                shells[eid] = []
            else:
                for c in range(0, len(line), 40):
                    shells[eid].append((int(line[c:c + 10]), float(line[c + 10:c + 20]), float(line[c + 20:c + 30])))
        elif block == "*SET_SHELL_LIST":
            if sid is None:
                sid = int(line[:10])
                sets[sid] = []
            else:
                sets[sid] += [int(line[c:c + 10]) for c in range(0, len(line), 10)]
    return shells, sets


def read_pcomp(path):
    """{pid: [(mid, t, theta)]} of the PCOMP entries and {eid: (kind, pid, mcid)} of the elements."""
    pcomp, elements = {}, {}
    for name, f in read_nastran(path):
        if name == "PCOMP":
            plies = f[8:]
            pcomp[int(f[0])] = [(int(plies[c]), nastran_float(plies[c + 1]), nastran_float(plies[c + 2]))
                                for c in range(0, len(plies) - 2, 4)]
        elif name in ("CQUAD4", "CTRIA3"):
            elements[int(f[0])] = (name, int(f[1]), int(f[-1]))
    return pcomp, elements


def layer_angles(layers, flipped=False):
    """{(ply position, yarn): angle} of a layer list from the bottom: yarn 1 before yarn 2
    in each ply, from the top if the element is ``flipped`` (its normal points into the tool)."""
    return {(mid, k % 2 + 1): b for k, (mid, _, b) in enumerate(layers[::-1] if flipped else layers)}


# ----------------------------------------------------------------------------- developable moulds: exact


@pytest.mark.parametrize("mould", ["plate", "cylinder"])
def test_developable_layup_has_the_nominal_angles_in_every_element(mould, tmp_path):
    """[0/45/90/-45] on a plate (rosette 20 deg) and along a cylinder's axis (rosette 0):
    a geodesic ply of a developable mould keeps its angle to the rosette, so every
    element's yarn angles in every flavour are the ply angle + rosette - the plan angle of
    the element's e1 (plate; negated where the element's normal points down, its layers
    then from ply 4 down to ply 1) or the ply angle (cylinder: its mesh's e1 runs along
    the axis) to 1e-9 deg (LS-DYNA's B: to its 1e-5 deg); realisation r of a plate
    misaligned by d_r has angle + d_r, the median of d (0) in the nominal."""
    if mould == "plate":
        surface, rosette, misalignment = build("plate", half_width=300.0), 20.0, (-2.0, 0.5, 0.0, 1.0, -0.5)
        mesh = grid_mesh(tmp_path / "part.inp", lambda x, y: np.column_stack([x, y, 0 * x]),
                         np.linspace(-30, 30, 7), np.linspace(-25, 25, 6))
    else:
        surface, rosette, misalignment = build("cylinder", radius=100.0, length=400.0), 0.0, (0.0, 0.0)
        mesh = grid_mesh(tmp_path / "part.inp",
                         lambda x, phi: np.column_stack([x, 100 * np.sin(phi), 100 * np.cos(phi)]),
                         np.linspace(-30, 30, 7), np.linspace(-0.3, 0.3, 7), roll=False)
    ds = laminate(surface, 5.0, 16, rosette=rosette, misalignment=misalignment)
    paths = export_laminate(ds, mesh, tmp_path / "lam", flavours=FLAVOURS, thickness_mm=0.25, realizations=2)
    assert sorted(p.name for p in paths) == sorted(
        ["lam-laminate.nc"] + [f"lam{r}-laminate.{x}" for r in ("", "-r0000", "-r0001") for x in ("inp", "k", "bdf")])
    frames = element_frames(mesh)
    plan_e1 = np.array([np.degrees(np.arctan2(e1[1], e1[0])) for e1, _, _ in frames])
    up = np.array([np.sign(e3[2]) for _, _, e3 in frames])
    if mould == "cylinder":
        assert np.abs(plan_e1).max() < 1e-12 and (up > 0).all()  # e1 along the axis
    else:
        assert (up < 0).sum() == -(-len(up) // 3) and len(set(np.round(plan_e1 % 360))) == 4
    labels = np.arange(1, len(frames) + 1)
    for suffix, d in (("", 0.0), ("-r0000", misalignment[0]), ("-r0001", misalignment[1])):
        dist, sections, elsets = read_abaqus(tmp_path / f"lam{suffix}-laminate.inp", frames)
        assert not [e for e in elsets if "UNMAPPED" in e]
        assert elsets["UQDRAPE_LAMINATE"] == list(labels[up > 0])
        assert elsets.get("UQDRAPE_LAMINATE_FLIPPED", []) == list(labels[up < 0])
        shells, _ = read_lsdyna_composite(tmp_path / f"lam{suffix}-laminate.k")
        pcomp, elements = read_pcomp(tmp_path / f"lam{suffix}-laminate.bdf")
        for p, angle in enumerate(ANGLES):
            for yarn in (1, 2):
                expected = up * (angle + rosette + d + 90.0 * (yarn - 1) - plan_e1)
                abaqus = np.array([dist[f"UQDRAPE_P{p + 1}_YARN{yarn}"][k] for k in labels])
                dyna = np.array([layer_angles(shells[k], up[k - 1] < 0)[p + 1, yarn] for k in labels])
                bdf = np.array([layer_angles(pcomp[k], up[k - 1] < 0)[p + 1, yarn] for k in labels])
                assert np.abs(line_diff(abaqus, expected)).max() < 1e-9, (suffix, p, yarn)
                assert np.abs(line_diff(bdf, expected)).max() < 1e-9, (suffix, p, yarn)
                assert np.abs(line_diff(dyna, expected)).max() <= 0.5e-5 + 1e-9, (suffix, p, yarn)
    # each ply's yarns are two layers of half the ply thickness, ply 1 on the tool
    stack = [f"UQDRAPE_P{p}_YARN{y}_ORIENTATION" for p in range(1, 5) for y in (1, 2)]
    bottom_up = [p for p in range(1, 5) for _ in (1, 2)]
    assert [(name, [ln[3] for ln in layers]) for name, layers in sections] == (
        [("UQDRAPE_LAMINATE", stack)] + [("UQDRAPE_LAMINATE_FLIPPED", stack[::-1])] * (mould == "plate"))
    assert {float(ln[0]) for _, layers in sections for ln in layers} == {0.125}
    assert all(ln[2] == ln[3].partition("_YARN")[0] + "_MATERIAL" for _, layers in sections for ln in layers)
    for k in labels:
        order = bottom_up[::-1] if up[k - 1] < 0 else bottom_up
        assert [m for m, _, _ in shells[k]] == order == [m for m, _, _ in pcomp[k]]
        assert {t for _, t, _ in shells[k]} == {0.125} == {t for _, t, _ in pcomp[k]}
        assert elements[k] == ("CQUAD4", k, k)  # PID and MCID = EID


# ----------------------------------------------------------------------------- a sheared ply book


@pytest.fixture(scope="module")
def dome(tmp_path_factory):
    """A hemisphere (R = 50 mm) laminate [0/45/90/-45] at rosette 10 deg, 6 realisations
    misaligned by up to 3 deg, on a triangulated disc reaching past the nets (s = 5 and 4
    mm, 5 rings: some elements off some plies' nets), exported with 3 decks."""
    folder = tmp_path_factory.mktemp("lam")
    surface = build("hemisphere", radius=50.0)
    misalignment = np.random.default_rng(7).uniform(-3.0, 3.0, 6)
    ds = laminate(surface, (5.0, 4.0, 5.0, 4.0), 5, rosette=10.0, misalignment=misalignment)
    assert "spacing_mm" not in ds.attrs and list(ds.ply_spacing_mm.values) == [5.0, 4.0, 5.0, 4.0]
    mesh = tmp_path_factory.mktemp("mesh") / "dome.inp"
    hemisphere_mesh(surface, mesh, radius_mm=34.0, rings=8)
    paths = export_laminate(ds, mesh, folder / "dome", flavours=FLAVOURS, thickness_mm=[0.2, 0.3, 0.2, 0.3],
                            realizations=3, variance=0.95)
    return folder, mesh, xr.load_dataset(folder / "dome-laminate.nc"), paths


def hemisphere_mesh(surface, path, radius_mm, rings):
    """A triangulated disc of radius ``radius_mm`` (polar grid, Delaunay) lifted onto the mould."""
    from scipy.spatial import Delaunay

    r = np.linspace(0, radius_mm, rings + 1)[1:]
    t = np.linspace(0, 2 * np.pi, 6 * rings + 1)[:-1]
    rr, tt = np.meshgrid(r, t, indexing="ij")
    xy = np.concatenate([[[0.0, 0.0]], np.column_stack([(rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel()])])
    points = np.column_stack([xy, surface.height(xy[:, 0], xy[:, 1])])
    meshio.write(path, meshio.Mesh(points, [("triangle", Delaunay(xy).simplices)]), file_format="abaqus")
    return path


def test_realisation_decks_read_back_to_the_ensembles_angles(dome):
    """Deck r of each flavour, read back here, holds the netCDF's angles of realisation r
    (to 1e-9 deg; LS-DYNA to its 1e-5), the defaults 0 / 90 deg where ply p's net of
    realisation r does not reach, and lists exactly those elements as unmapped."""
    folder, mesh, nc, _ = dome
    frames = element_frames(mesh)
    labels = nc.element.values
    reached_some = (nc.p_reached > 0) & (nc.p_reached < 1)
    assert reached_some.any() and (nc.p_reached == 1).any()  # the mesh reaches past some nets
    for r in range(3):
        dist, _, elsets = read_abaqus(folder / f"dome-r{r:04d}-laminate.inp", frames)
        shells, sets = read_lsdyna_composite(folder / f"dome-r{r:04d}-laminate.k")
        pcomp, _ = read_pcomp(folder / f"dome-r{r:04d}-laminate.bdf")
        for p in range(4):
            angles = nc.yarn_angle.isel(realization=r, ply=p).values  # (yarn, element)
            off = labels[np.isnan(angles[0])]
            assert elsets.get(f"UQDRAPE_P{p + 1}_UNMAPPED", []) == list(off) and sets.get(p + 1, []) == list(off)
            for yarn in (1, 2):
                expected = np.where(np.isnan(angles[yarn - 1]), 90.0 * (yarn - 1), angles[yarn - 1])
                abaqus = np.array([dist[f"UQDRAPE_P{p + 1}_YARN{yarn}"][k] for k in labels])
                dyna = np.array([layer_angles(shells[k])[p + 1, yarn] for k in labels])
                bdf = np.array([layer_angles(pcomp[k])[p + 1, yarn] for k in labels])
                assert np.abs(line_diff(abaqus, expected)).max() < 1e-9
                assert np.abs(line_diff(bdf, expected)).max() < 1e-9
                assert np.abs(line_diff(dyna, expected)).max() <= 0.5e-5 + 1e-9
    # the samples differ between realisations: the decks are not all one
    assert float(nc.yarn_angle.std("realization").max()) > 1.0


def test_netcdf_is_cf_and_holds_the_ply_thicknesses_median_and_samples(dome, tmp_path):
    folder, _, nc, _ = dome
    assert dict(nc.sizes) == {"realization": 6, "ply": 4, "yarn": 2, "element": nc.sizes["element"],
                              "mode": nc.sizes["mode"]}
    assert nc.attrs["Conventions"] == "CF-1.8"
    for name in nc.data_vars:
        assert "units" in nc[name].attrs and "long_name" in nc[name].attrs, name
    assert nc.ply_angle.attrs["units"] == "degree" and list(nc.ply_angle.values) == list(ANGLES)
    median = nc.yarn_angle.median("realization")  # the samples lie within 90 deg of it: a plain median
    np.testing.assert_allclose(nc.nominal_yarn_angle, median.where(nc.p_reached > 0), rtol=0, atol=1e-9)
    shells, sets = read_lsdyna_composite(folder / "dome-laminate.k")
    assert {round(t, 6) for layer in shells.values() for _, t, _ in layer} == {0.1, 0.15}
    for p in range(4):  # the nominal's unmapped: the elements no realisation's net reaches
        assert sets.get(p + 1, []) == list(nc.element.values[nc.p_reached.values[p] == 0])
    assert sets
    assert_cf_compliant(folder / "dome-laminate.nc", tmp_path)


def test_karhunen_loeve_modes_reconstruct_the_samples_to_the_stated_variance(dome):
    """samples = mean + scores x modes over the entries every realisation reaches: the
    variance left out is at most 1 - variance (0.05), and one mode fewer would leave more."""
    _, _, nc, _ = dome
    every = np.isfinite(nc.mode_shape.isel(mode=0)).values.ravel()
    X = nc.yarn_angle.values.reshape(6, -1)[:, every]
    modes = nc.mode_shape.values.reshape(nc.sizes["mode"], -1)[:, every]
    mean = nc.mean_yarn_angle.values.ravel()[every]
    np.testing.assert_allclose(modes @ modes.T, np.eye(len(modes)), atol=1e-12)
    total = ((X - mean) ** 2).sum()
    left = ((X - mean - nc.score.values @ modes) ** 2).sum() / total
    assert left <= 1 - 0.95 and 1 <= len(modes) < 5
    fewer = ((X - mean - nc.score.values[:, :-1] @ modes[:-1]) ** 2).sum() / total
    assert fewer > 1 - 0.95
    np.testing.assert_allclose(nc.variance_fraction.sum(), 1 - left, rtol=1e-9)
    np.testing.assert_allclose(nc.eigenvalue, (nc.score ** 2).sum("realization") / 5, rtol=1e-9)


# ----------------------------------------------------------------------------- convergence


def test_mapping_error_is_second_order_in_the_spacing(tmp_path):
    """One ply at 30 deg on a hemisphere (R = 50 mm) draped at s = 4, 2, 1 mm and mapped
    onto one mesh: its element yarn angles' largest error against the same ply draped
    at s = 1/8 mm (brute force: 103 000 nodes) falls as s^p with p within 0.3 of the
    docstring's 2."""
    surface = build("hemisphere", radius=50.0)
    mesh = hemisphere_mesh(surface, tmp_path / "dome.inp", radius_mm=25.0, rings=6)

    def angles(s):
        ds = laminate(surface, s, int(round(40 / s)), angles=(30.0,))
        export_laminate(ds, mesh, tmp_path / f"s{s}", flavours=("lsdyna",), tolerance_mm=1.0)
        return xr.load_dataset(tmp_path / f"s{s}-laminate.nc").yarn_angle.values

    reference = angles(0.125)
    spacings = np.array([4.0, 2.0, 1.0])
    errors = np.array([np.abs(line_diff(angles(s), reference)).max() for s in spacings])
    order = np.polyfit(np.log(spacings), np.log(errors), 1)[0]
    assert abs(order - 2.0) <= 0.3, (errors, order)


def test_a_ply_over_thicker_plies_maps_from_its_offset_surface(tmp_path):
    """Ply 1 lies on the dome's offset by the 3 mm ply 0 (the sphere of R + 3). Mapped onto
    the tool's shell mesh it takes its net above each element along the tool's normal: the
    same angles (to 1e-9 deg) as the ply draped on a dome of R + 3 mapped onto the mesh
    scaled by (R + 3) / R, whose elements have the same frames and lie on that dome."""
    R, d = 50.0, 3.0
    tool = build("hemisphere", radius=R)
    mesh = hemisphere_mesh(tool, tmp_path / "dome.inp", radius_mm=25.0, rings=6)
    big = meshio.read(mesh)
    big.points *= (R + d) / R
    meshio.write(tmp_path / "big.inp", big, file_format="abaqus")
    plies = [schema.at_level(drape(s, 2.0, 20, orientation=30.0), 0.0) for s in (tool, tool.offset(d))]
    ds = xr.concat(plies, dim=schema.PLY, join="override", combine_attrs="drop_conflicts")
    ds = ds.assign_coords({schema.PLY: ["p0", "p1"], schema.PLY_ANGLE: (schema.PLY, [30.0, 30.0]),
                           **{f"{schema.PLY_ATTR}{k}": (schema.PLY, [p.attrs[k] for p in plies])
                              for k in ("mould", "geometry_json")}}).assign_attrs(
        rosette_deg=0.0, mould=plies[0].attrs["mould"], geometry_json=plies[0].attrs["geometry_json"])
    export_laminate(ds, mesh, tmp_path / "thick", flavours=("abaqus",), tolerance_mm=1.0)
    export_laminate(laminate(build("hemisphere", radius=R + d), 2.0, 20, angles=(30.0,)), tmp_path / "big.inp",
                    tmp_path / "alone", flavours=("abaqus",), tolerance_mm=1.0)
    thick = xr.load_dataset(tmp_path / "thick-laminate.nc").yarn_angle.isel(ply=1).values
    alone = xr.load_dataset(tmp_path / "alone-laminate.nc").yarn_angle.isel(ply=0).values
    assert np.isfinite(thick).all()
    assert np.abs(line_diff(thick, alone)).max() < 1e-9


# ----------------------------------------------------------------------------- mesh formats


def keyword_mesh(path, points, quads, eids, solid=False):
    """An LS-DYNA keyword mesh written here: *NODE with node ids 11, 12, ... in fixed
    columns, *ELEMENT_SHELL_THICKNESS (a second card per element) with ``eids``, every
    other element in free format; an *ELEMENT_SOLID if ``solid``."""
    lines = ["*KEYWORD", "$ a hand-made mesh", "*NODE"]
    lines += [f"{k + 11:8d}{x:16.8f}{y:16.8f}{z:16.8f}" for k, (x, y, z) in enumerate(points)]
    lines.append("*ELEMENT_SHELL_THICKNESS")
    for k, (eid, q) in enumerate(zip(eids, quads + 11)):
        lines.append(", ".join(map(str, [eid, 1, *q])) if k % 2 else "".join(f"{v:8d}" for v in [eid, 1, *q]))
        lines.append(f"{0.5:16.3f}{0.5:16.3f}{0.5:16.3f}{0.5:16.3f}")
    if solid:
        lines += ["*ELEMENT_SOLID", "".join(f"{v:8d}" for v in [999, 2, *range(11, 19)])]
    path.write_text("\n".join(lines + ["*END"]) + "\n")
    return path


def test_keyword_and_nastran_meshes_map_as_the_abaqus_one(tmp_path):
    """The same plate mesh as Abaqus .inp, Nastran .bdf and LS-DYNA .k (written here;
    meshio reads no .k): the same angles per element, the .k's elements
    under their EIDs; a .k with solid elements is refused as a volume mesh."""
    surface = build("plate", half_width=300.0)
    ds = laminate(surface, 5.0, 6, angles=(30.0, -60.0), misalignment=(0.0, 2.0))
    inp = grid_mesh(tmp_path / "part.inp", lambda x, y: np.column_stack([x, y, 0 * x]),
                    np.linspace(-20, 20, 5), np.linspace(-20, 20, 4))
    mesh = meshio.read(inp)
    quads = mesh.cells_dict["quad"]
    eids = 100 + 7 * np.arange(len(quads))
    (tmp_path / "part.bdf").write_text("\n".join(  # free-field bulk data (meshio's writer overflows a field)
        ["BEGIN BULK"] + [f"GRID,{k + 1},,{','.join(map(repr, map(float, p)))}" for k, p in enumerate(mesh.points)]
        + [f"CQUAD4,{k + 1},1,{','.join(str(n + 1) for n in q)}" for k, q in enumerate(quads)] + ["ENDDATA\n"]))
    keyword_mesh(tmp_path / "part.k", mesh.points, quads, eids)
    angles = {}
    for suffix in (".inp", ".bdf", ".k"):
        export_laminate(ds, tmp_path / f"part{suffix}", tmp_path / suffix[1:], flavours=("lsdyna",), realizations=2)
        nc = xr.load_dataset(tmp_path / f"{suffix[1:]}-laminate.nc")
        angles[suffix] = nc.yarn_angle.values
        shells, _ = read_lsdyna_composite(tmp_path / f"{suffix[1:]}-laminate.k")
        assert list(nc.element.values) == list(shells) == (list(eids) if suffix == ".k" else
                                                           list(range(1, len(quads) + 1)))
    assert np.isfinite(angles[".inp"]).all() and np.ptp(angles[".inp"][:, 0, 0]) > 1.0
    np.testing.assert_allclose(angles[".bdf"], angles[".inp"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(angles[".k"], angles[".inp"], rtol=0, atol=1e-9)
    solid = keyword_mesh(tmp_path / "solid.k", mesh.points, quads, eids, solid=True)
    with pytest.raises(ValueError, match="volume mesh"):
        export_laminate(ds, solid, tmp_path / "no")


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("case", ["flavour", "volume", "no_ply", "thickness", "realizations", "variance"])
def test_bad_input_is_a_one_line_error_naming_the_argument(case, tmp_path):
    surface = build("plate", half_width=300.0)
    ds = laminate(surface, 5.0, 4, angles=(0.0, 90.0))
    mesh = grid_mesh(tmp_path / "part.inp", lambda x, y: np.column_stack([x, y, 0 * x]),
                     np.linspace(-10, 10, 3), np.linspace(-10, 10, 3))
    args = {"flavours": ("abaqus",), "thickness_mm": 0.2}
    word = {"flavour": "flavours", "volume": "volume mesh", "no_ply": "ds", "thickness": "thickness_mm",
            "realizations": "realizations", "variance": "variance"}[case]
    if case == "flavour":
        args["flavours"] = ("abaqus", "ansys")
    elif case == "volume":
        mesh = tmp_path / "solid.inp"
        tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
        meshio.write(mesh, meshio.Mesh(tet, [("tetra", np.array([[0, 1, 2, 3]]))]), file_format="abaqus")
    elif case == "no_ply":
        ds = ds.isel({schema.PLY: 0})
    elif case == "thickness":
        args["thickness_mm"] = [0.2, 0.0]
    elif case == "realizations":
        args["realizations"] = 2  # the ensemble has 1
    else:
        args["variance"] = 0.0
    with pytest.raises(ValueError) as err:
        export_laminate(ds, mesh, tmp_path / "out", **args)
    assert_one_line_error(str(err.value))
    assert word in str(err.value)
    assert not list(tmp_path.glob("out*"))


def test_each_force_level_gets_its_own_files(tmp_path):
    """Two force levels (0 and 126 N) concatenated along blankholder_force: files per level,
    labelled as ``uqdrape export`` labels levels, each with its own level's angles."""
    surface = build("plate", half_width=300.0)
    ds = xr.concat([laminate(surface, 5.0, 4, angles=(0.0, 90.0), rosette=rosette, force=force)
                    for force, rosette in ((0.0, 0.0), (126.0, 30.0))], dim=schema.FORCE)
    mesh = grid_mesh(tmp_path / "part.inp", lambda x, y: np.column_stack([x, y, 0 * x]),
                     np.linspace(-10, 10, 3), np.linspace(-10, 10, 3), roll=False)
    paths = export_laminate(ds, mesh, tmp_path / "lam", flavours=("lsdyna",))
    assert sorted(p.name for p in paths) == ["lam-0N-laminate.k", "lam-0N-laminate.nc",
                                             "lam-126N-laminate.k", "lam-126N-laminate.nc"]
    for label, rosette in (("0N", 0.0), ("126N", 30.0)):
        nominal = xr.load_dataset(tmp_path / f"lam-{label}-laminate.nc").nominal_yarn_angle.sel(yarn=1).values
        assert np.abs(line_diff(nominal, np.array([[rosette], [90.0 + rosette]]))).max() < 1e-9


def test_a_laminate_runs_ensemble_exports(tmp_path):
    """End to end: a study with a [[ply]] book (plies 0 and 45 deg on a plate, the second at
    4 mm spacing) run, its ensemble opened and exported: every element of every
    realisation has the ply's angle."""
    path = write_study(tmp_path, "lam", geometry={"kind": "plate", "radius": None, "half_width": 300.0})
    path.write_text(path.read_text() + '\n[[ply]]\nname = "zero"\nangle_deg = 0.0\n\n'
                    '[[ply]]\nname = "bias"\nangle_deg = 45.0\nspacing_mm = 4.0\n')
    ds = open_ensemble(run_study(path, scheduler="synchronous", progress=False))
    mesh = grid_mesh(tmp_path / "part.inp", lambda x, y: np.column_stack([x, y, 0 * x]),
                     np.linspace(-10, 10, 4), np.linspace(-10, 10, 4), roll=False)
    export_laminate(ds, mesh, tmp_path / "out", flavours=("nastran",), realizations=1)
    nc = xr.load_dataset(tmp_path / "out-laminate.nc")
    assert list(nc.ply_label.values.astype(str)) == ["zero", "bias"] and (nc.p_reached == 1).all()
    expected = np.array([0.0, 45.0])[None, :, None, None] + np.array([0.0, 90.0])[None, None, :, None]
    assert np.abs(line_diff(nc.yarn_angle.values, expected)).max() < 1e-9
