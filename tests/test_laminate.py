"""Laminates: a study's ply book draped ply by ply over one tool (issue 37).

Physics invariants of the plies (nominal directions and no shear on developable moulds, a
90 deg ply equal to the 0 deg ply turned on a dome), the ply batch against single-ply
studies bit for bit, the laminate's run and report, and the errors of bad ply books.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import assert_one_line_error, study_text
from uqdrape.ensemble import drape_laminate, sampled_inputs
from uqdrape.ensemble.chunk import drape_chunk
from uqdrape.files import toml_value
from uqdrape.schema import PLY
from uqdrape.stats import fibre_deviation, laminate_lock
from uqdrape.study import load_study
from uqdrape.study.spec import ply_seed

QUASI_ISOTROPIC = [{"name": name, "angle_deg": angle} for name, angle in
                   (("p0", 0.0), ("p45", 45.0), ("p90", 90.0), ("m45", -45.0))]


def ply_book(plies) -> str:
    """``[[ply]]`` tables of ``plies`` (dicts; a dict value is the ply's sub-table)."""
    lines = []
    for ply in plies:
        lines += ["", "[[ply]]"] + [f"{k} = {toml_value(v)}" for k, v in ply.items() if not isinstance(v, dict)]
        for key, table in ply.items():
            if isinstance(table, dict):
                for name, field in table.items():
                    lines += [f"[ply.{key}.{name}]"] + [f"{k} = {toml_value(v)}" for k, v in field.items()]
    return "\n".join(lines) + "\n"


def laminate_file(tmp_path, plies=QUASI_ISOTROPIC, name="lam", **sections):
    path = tmp_path / f"{name}.toml"
    path.write_text(study_text(tmp_path, name, **sections) + ply_book(plies), encoding="utf-8")
    return path


def laminate(tmp_path, plies=QUASI_ISOTROPIC, realizations=(0,), **sections):
    study = load_study(laminate_file(tmp_path, plies, **sections))
    return study, drape_laminate(study, np.asarray(realizations))


def test_flat_plate_plies_keep_their_angles_without_shear(tmp_path):
    _, ds = laminate(tmp_path, geometry={"kind": "plate", "radius": None}, fabric={"orientation_deg": 15.0})
    assert list(ds[PLY].values) == ["p0", "p45", "p90", "m45"]
    assert np.nanmax(np.abs(ds["cell_shear"].values)) < 1e-9
    dev = fibre_deviation(ds)
    assert np.isfinite(dev.values).all() and np.abs(dev.values).max() < 1e-9
    np.testing.assert_allclose(ds["orientation"].values[:, 0], 15.0 + np.array([0.0, 45.0, 90.0, -45.0]), atol=1e-12)


def test_cylinder_plies_keep_their_angles_in_the_development(tmp_path):
    """On a cylinder along x (developable) every ply is unsheared, and at every node its two
    fibre directions (the central-difference tangents the FE handoff maps) run at the ply's
    angle and 90 deg more from the axis, about the normal, to 1e-9 deg. The net's segments
    are chords: unrolled (u = x, v = R atan2(y, z)), the 0 and 90 deg plies' run at their
    angles exactly, a +-45 deg ply's are one helix whose developed chord angle is off by
    the chord construction's (s / R)^2 / 24 rad (0.024 deg at s / R = 0.1), the same at every
    segment, a quarter of it at half the spacing."""
    from uqdrape.export.directions import fibre_directions
    from uqdrape.geometry import Cylinder

    R = 100.0
    errors = []
    for s in (10.0, 5.0):
        _, ds = laminate(tmp_path, geometry={"kind": "cylinder", "radius": R, "length": 400.0, "axis": "x"},
                         fabric={"spacing_mm": s}, solver={"rings": 6})
        assert np.nanmax(np.abs(ds["cell_shear"].values)) < 1e-9
        for k, nominal in enumerate((0.0, 45.0, 90.0, -45.0)):
            ply = ds.isel({PLY: k, "realization": 0})
            P = np.stack([ply[c].values for c in "xyz"], -1)
            d1, d2, n = fibre_directions(P, ply["shear"].values, Cylinder(R, 400.0))
            axis = np.array([1.0, 0.0, 0.0])
            around = np.cross(n, axis)
            for d, angle in ((d1, nominal), (d2, nominal + 90.0)):
                dev = np.degrees(np.arctan2((d * around).sum(-1), (d * axis).sum(-1))) - angle
                assert np.abs((dev + 90.0) % 180.0 - 90.0).max() < 1e-9, (s, nominal)
        u, v = ds["x"].values, R * np.arctan2(ds["y"].values, ds["z"].values)
        angle = np.degrees(np.arctan2(np.diff(v, axis=-2), np.diff(u, axis=-2)))  # along i, each ply
        err = (angle[:, 0] - np.array([0.0, 45.0, 90.0, -45.0])[:, None, None] + 90.0) % 180.0 - 90.0
        assert np.isfinite(err).all() and np.abs(err[[0, 2]]).max() < 1e-9
        assert np.ptp(np.abs(err[[1, 3]])) < 1e-8  # one helix: the same at every segment
        errors.append(np.abs(err[1]).max())
        np.testing.assert_allclose(np.radians(errors[-1]), (s / R) ** 2 / 24, rtol=(s / R) ** 2)  # + O((s/R)^4)
    np.testing.assert_allclose(errors[0] / errors[1], 4.0, rtol=1e-2)


@pytest.mark.parametrize("mode", ["geodesic", "energy"])
def test_hemisphere_90_ply_is_the_0_ply_turned(tmp_path, mode):
    """On a dome draped from its pole the 90 deg ply is the 0 deg ply turned by 90 deg about
    the axis: the same shear at every node, positions (x, y) -> (-y, x)."""
    _, ds = laminate(tmp_path, QUASI_ISOTROPIC[::2], solver={"mode": mode, "rings": 6},
                     fabric={"material": "ebxhd936_like", "spacing_mm": 5.0}, process={"blankholder_force_N": 0.0})
    p0, p90 = ds.sel({PLY: "p0"}), ds.sel({PLY: "p90"})
    tol = 1e-9 if mode == "geodesic" else 1e-6  # energy: the minimiser's tolerance is 1e-3 deg
    assert np.nanmax(np.abs(p0["shear"].values)) > 1.0  # a sheared drape, not a trivial one
    np.testing.assert_allclose(p90["shear"].values, p0["shear"].values, atol=tol, rtol=0)
    np.testing.assert_allclose(p90["x"].values, -p0["y"].values, atol=tol * 100, rtol=0)
    np.testing.assert_allclose(p90["y"].values, p0["x"].values, atol=tol * 100, rtol=0)


def test_ply_in_the_batch_is_its_single_ply_study_bitwise(tmp_path):
    """An off-centre ply with its own zero-angle field and misalignment, draped in a batch
    with another ply, equals a single-ply study of its fabric, fields and seed bit for bit."""
    field = {"zero_angle": {"mean_deg": 0.5, "sd_deg": 1.5}}
    plies = [{"name": "a", "angle_deg": 30.0},
             {"name": "b", "angle_deg": -60.0, "crossover": [6.0, -4.0], "misalignment_sd_deg": 2.0,
              "uncertainty": field}]
    study, ds = laminate(tmp_path, plies, realizations=(0, 1, 2), study={"realizations": 3},
                         fabric={"orientation_deg": 10.0}, solver={"mode": "energy"},
                         process={"blankholder_force_N": 20.0})
    single = load_study(_write(tmp_path / "single.toml", study_text(
        tmp_path, "single", study={"seed": ply_seed(study.seed, 1), "realizations": 3},
        fabric={"orientation_deg": 10.0 - 60.0, "crossover": [6.0, -4.0]}, solver={"mode": "energy"},
        process={"blankholder_force_N": 20.0},
        uncertainty={**field, "orientation": {"dist": "normal", "mean": -50.0, "sd": 2.0}})))
    one = drape_chunk(single, np.arange(3), 20.0)
    b = ds.sel({PLY: "b"})
    for name in ("x", "y", "z", "shear", "gamma0", "orientation", "status", "energy_total"):
        assert np.array_equal(b[name].values, one[name].values[0], equal_nan=True), name
    assert not np.array_equal(ds["gamma0"].values[0], ds["gamma0"].values[1])  # ply a has no field


def test_shared_process_and_rosette_error(tmp_path):
    """Friction and the rosette's angle are drawn once per realisation for every ply: the
    plies' frictions are equal and their orientations differ by their nominal angles."""
    study, ds = laminate(tmp_path, QUASI_ISOTROPIC[:2], realizations=range(4), study={"realizations": 4},
                         uncertainty={"friction": {"dist": "uniform", "bounds": [0.1, 0.3]},
                                      "orientation": {"dist": "normal", "mean": 0.0, "sd": 1.0}})
    drawn = sampled_inputs(study.shared, np.arange(4))
    for k, angle in enumerate((0.0, 45.0)):
        np.testing.assert_array_equal(ds["friction"].values[k], drawn["friction"])
        np.testing.assert_allclose(ds["orientation"].values[k], drawn["orientation"] + angle, atol=1e-12)
    assert np.ptp(drawn["orientation"]) > 0.1


def test_laminate_run_resume_and_report(tmp_path, unrasterised):
    from uqdrape.api import open_ensemble
    from uqdrape.workflow import run_report, run_study

    path = laminate_file(tmp_path, QUASI_ISOTROPIC, geometry={"radius": 40.0},
                         uncertainty={"zero_angle": {"mean_deg": 0.0, "sd_deg": 3.0}},
                         solver={"rings": 9}, study={"realizations": 6, "chunk_size": 4})
    out = run_study(path, progress=False)
    ds = open_ensemble(out)
    assert ds["shear"].dims == ("blankholder_force", PLY, "realization", "i", "j")
    assert ds.sizes[PLY] == 4 and ds.sizes["realization"] == 6
    again = run_study(path, progress=False)  # resumed: every chunk kept, the same numbers
    assert np.array_equal(open_ensemble(again)["shear"].values, ds["shear"].values, equal_nan=True)
    index = run_report(out)
    summary = json.loads((index.parent / "summary.json").read_text())
    lock = laminate_lock(ds.compute())
    p_any = summary["p_any_ply_locked"]["50"]["p_any"]
    assert p_any == float(lock["p_any"].item())
    assert p_any >= max(max(p["p_locked"]) for p in summary["plies"].values())
    assert p_any > 0  # a 45 mm net on a 40 mm dome comes near the 50 deg lock of generic_woven
    for name, ply in summary["plies"].items():
        assert (index.parent / ply["report"]).is_file(), name
    assert {"tool_lock_map.png", "fibre_deviation_mean.png", "fibre_deviation_sd.png"} <= {
        p.name for p in index.parent.iterdir()}


def _write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("plies, key, valid", [
    ([{"name": "a", "angle_deg": 0.0, "material": "no_such_card"}], "ply.a.material", ("generic_woven",)),
    ([{"name": "a", "angle_deg": 0.0, "crossover": [500.0, 0.0]}], "ply.a.crossover", ("off the tool",)),
    ([{"name": "a", "angle_deg": 0.0}, {"name": "a", "angle_deg": 90.0}], "ply[1].name", ("ply[0]",)),
    ([{"name": "a", "angle_deg": "45"}], "ply.a.angle_deg", ("number",)),
    ([{"name": "a b", "angle_deg": 0.0}], "ply[0].name", ("letters",)),
    ([{"name": "a", "angle_deg": 0.0, "misalignment_sd_deg": -1.0}], "ply.a.misalignment_sd_deg", (">= 0",)),
    ([{"name": "a", "angle_deg": 0.0, "thickness": 0.2}], "ply.a.thickness", ("angle_deg",)),
    ([{"name": "a", "angle_deg": 0.0, "uncertainty": {"spacing": {"cv": 2.0}}}], "ply.a.uncertainty.spacing",
     ("cv",)),
])
def test_bad_ply_books_name_file_ply_and_key(tmp_path, plies, key, valid):
    from uqdrape.study import StudyError

    path = laminate_file(tmp_path, plies)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key=key, valid=valid)


def test_laminate_refuses_what_is_of_one_ply(tmp_path):
    from uqdrape.study import StudyError

    path = laminate_file(tmp_path, uncertainty={"friction": {"dist": "uniform", "bounds": [0.1, 0.3]},
                                                "orientation": {"dist": "normal", "mean": 0.0, "sd": 1.0}},
                         sensitivity={"method": "sobol", "base_samples": 64})
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key="sensitivity.method", valid=("laminate",))
    path = laminate_file(tmp_path, uncertainty={"skew": {"dist": "normal", "mean": 0.0, "sd": 1.0}})
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key="uncertainty.skew", valid=("friction", "orientation"))


def test_a_ply_the_tool_cannot_hold_is_refused_before_the_run(tmp_path):
    """A ply seeded in the corner of the blank-holder's flange, whose net mostly falls off
    the mould: ``uqdrape validate`` refuses it in one line naming the ply's seed point."""
    plies = [{"name": "ok", "angle_deg": 0.0}, {"name": "edge", "angle_deg": 0.0, "crossover": [95.0, 95.0]}]
    path = laminate_file(tmp_path, plies, geometry={"radius": 50.0}, solver={"rings": 10})
    res = subprocess.run([sys.executable, "-m", "uqdrape.cli", "validate", str(path)], capture_output=True, text=True)
    assert res.returncode != 0
    assert_one_line_error(res.stderr.strip(), file=path, key="ply.edge.crossover")
    assert "ply edge" in res.stderr and not (tmp_path / "lam").exists()


def test_laminate_export_writes_each_ply_and_the_handoff(tmp_path):
    """``uqdrape export RUN`` of a laminate: VTK and flat pattern per ply, the laminate
    handoff for --to fe, all in one line of output and no traceback."""
    import meshio

    from uqdrape.workflow import run_study

    path = laminate_file(tmp_path, QUASI_ISOTROPIC[:2], study={"realizations": 2})
    out = run_study(path, progress=False)
    n = 9
    xs = np.linspace(-15.0, 15.0, n)
    X, Y = np.meshgrid(xs, xs)
    points = np.column_stack([X.ravel(), Y.ravel(), np.sqrt(50.0 ** 2 - X.ravel() ** 2 - Y.ravel() ** 2)])
    quads = [[i * n + j, i * n + j + 1, (i + 1) * n + j + 1, (i + 1) * n + j] for i in range(n - 1) for j in range(n - 1)]
    meshio.write(tmp_path / "cap.inp", meshio.Mesh(points, [("quad", np.array(quads))]))
    res = subprocess.run([sys.executable, "-m", "uqdrape.cli", "export", str(out), "--to", "vtk", "flat", "fe",
                          "--mesh", str(tmp_path / "cap.inp"), "--thickness", "0.3", "--realizations", "2"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    names = {p.name for p in (out / "export").iterdir()}
    for ply in ("p0", "p45"):
        assert {f"lam-ply-{ply}.vtu", f"lam-ply-{ply}-flat.dxf"} <= names, names
    assert {"lam-laminate.inp", "lam-laminate.nc", "lam-r0000-laminate.inp", "lam-r0001-laminate.inp"} <= names
    res = subprocess.run([sys.executable, "-m", "uqdrape.cli", "export", str(out), "--to", "fe", "--mesh",
                          str(tmp_path / "cap.inp"), "--thickness", "0"], capture_output=True, text=True)
    assert res.returncode != 0 and "Traceback" not in res.stderr and "thickness" in res.stderr


def test_one_ply_commands_refuse_a_laminate(tmp_path):
    """A served model, a calibration from drapes and a sensitivity sample drape one ply: on
    a laminate each says so in one line naming the study file."""
    from uqdrape.workflow import run_study, serve_study

    path = laminate_file(tmp_path, uncertainty={"friction": {"dist": "uniform", "bounds": [0.1, 0.3]},
                                                "orientation": {"dist": "normal", "mean": 0.0, "sd": 1.0}})
    study = load_study(path)
    for call in (lambda: serve_study(study, port=0), lambda: run_study(study, method="morris", progress=False)):
        with pytest.raises(ValueError) as err:
            call()
        assert_one_line_error(str(err.value), file=path, valid=("laminate", "one ply"))
    assert not (tmp_path / "lam").exists()


def test_a_trimmed_ply_is_the_whole_ply_cut_to_its_edge(tmp_path):
    """A ply with a trim boundary: nodes outside its edge are TRIMMED with no values, cells
    with such a corner have none, every node inside is the untrimmed ply's bit for bit."""
    from uqdrape.drape.status import Status

    (tmp_path / "edge.csv").write_text("x_mm,y_mm\n-12,-8\n15,-8\n15,10\n-12,10\n", encoding="utf-8")
    plies = [{"name": "whole", "angle_deg": 30.0}, {"name": "cut", "angle_deg": 30.0, "trim": "edge.csv"}]
    _, ds = laminate(tmp_path, plies, realizations=(0, 1), study={"realizations": 2},
                     uncertainty={"zero_angle": {"mean_deg": 0.0, "sd_deg": 1.0}})
    whole, cut = ds.sel({PLY: "whole"}), ds.sel({PLY: "cut"})
    x, y = whole["x"].values, whole["y"].values
    inside = (x > -12) & (x < 15) & (y > -8) & (y < 10)
    assert 0 < inside.sum() < inside.size
    assert np.array_equal(cut["status"].values == Status.TRIMMED, ~inside)
    for name in ("x", "z", "shear", "locked"):
        assert np.array_equal(cut[name].values[inside], whole[name].values[inside]), name
        assert np.isnan(cut[name].values[~inside]).all(), name
    corners = inside[:, :-1, :-1] & inside[:, 1:, :-1] & inside[:, :-1, 1:] & inside[:, 1:, 1:]
    assert np.array_equal(np.isfinite(cut["cell_shear"].values), corners)
    assert np.isfinite(cut["gamma0"].values).all()  # the inputs stay as draped


def test_a_bad_trim_names_the_ply_and_key(tmp_path):
    from uqdrape.study import StudyError

    (tmp_path / "edge.csv").write_text("x_mm,y_mm\n0,0\n1,1\n", encoding="utf-8")
    path = laminate_file(tmp_path, [{"name": "a", "angle_deg": 0.0, "trim": "edge.csv"}])
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key="ply.a.trim", valid=("3",))


def test_each_ply_lies_on_the_tool_offset_by_the_plies_below(tmp_path):
    """Plies of 1.5, 1 and 2 mm on a 60 mm dome: ply k lies on the offset sphere of radius
    60 + the thickness below it, and is bitwise the ply of a laminate without thickness on
    a dome of that radius (the offset of a sphere is the sphere grown about its centre); the
    laminate's mould is the tool, each ply's its offset surface."""
    plies = [{**p, "thickness_mm": t} for p, t in zip(QUASI_ISOTROPIC[:3], (1.5, 1.0, 2.0))]
    options = dict(solver={"mode": "energy", "rings": 5}, fabric={"material": "ebxhd936_like"},
                   process={"blankholder_force_N": 30.0})
    study, ds = laminate(tmp_path, plies, geometry={"radius": 60.0}, **options)
    assert [study.ply_offset(k) for k in range(3)] == [0.0, 1.5, 2.5]
    assert ds.attrs["mould"] == "hemisphere (radius 60 mm, flange half width 120 mm)"
    assert list(ds["ply_mould"].values[1:]) == [ds.attrs["mould"][:-1] + f", offset {d:g} mm)" for d in (1.5, 2.5)]
    for k, offset in enumerate((0.0, 1.5, 2.5)):
        ply = ds.isel({PLY: k})
        radius = np.sqrt(ply["x"] ** 2 + ply["y"] ** 2 + ply["z"] ** 2).values
        np.testing.assert_allclose(radius, 60.0 + offset, rtol=0, atol=1e-9)
        thin = tmp_path / f"thin{k}"
        thin.mkdir()
        _, same = laminate(thin, QUASI_ISOTROPIC[:3], geometry={"radius": 60.0 + offset}, **options)
        for name in ("x", "y", "z", "shear", "energy_total"):
            assert np.array_equal(ply[name].values, same.isel({PLY: k})[name].values, equal_nan=True), (k, name)


def test_a_mesh_tool_offsets_its_plies_by_their_distance(tmp_path):
    """On a meshed dome the second ply's nodes lie 0.8 mm from the mesh, to the solver's
    tolerance: the offset is the mesh's distance level set, not a shifted copy."""
    import trimesh

    path = tmp_path / "cap.stl"
    trimesh.creation.icosphere(subdivisions=4, radius=60.0).export(path)
    plies = [{"name": "a", "angle_deg": 0.0, "thickness_mm": 0.8}, {"name": "b", "angle_deg": 45.0}]
    study, ds = laminate(tmp_path, plies, geometry={"kind": "mesh", "radius": None, "path": "cap.stl"},
                         solver={"rings": 5})
    from uqdrape.ensemble.chunk import study_mould

    tool = study_mould(study)
    for k, offset in enumerate((0.0, 0.8)):
        P = np.stack([ds.isel({PLY: k})[c].values.ravel() for c in "xyz"], -1)
        assert (ds.isel({PLY: k})["status"].values == 0).all()
        np.testing.assert_allclose(tool.project(P)[1], offset, rtol=0, atol=1e-8)


@pytest.mark.parametrize("thickness, geometry, key, valid", [
    (("0.3", 0.0), {}, "ply.p0.thickness_mm", ("number",)),
    ((-0.1, 0.0), {}, "ply.p0.thickness_mm", ("0 <= thickness_mm < 10",)),
    ((12.0, 0.0), {}, "ply.p0.thickness_mm", ("0 <= thickness_mm < 10",)),
    ((4.0, 4.0), {"kind": "double_dome", "radius": None}, "ply.p45.thickness_mm",
     ("offset by 8 mm", "concave radius", "5.927 mm")),
])
def test_a_bad_ply_thickness_names_file_ply_and_key(tmp_path, thickness, geometry, key, valid):
    """A thickness that is no length, and a stack whose offset (two 4 mm plies under the
    third) would fold the double dome's valley: one line naming the ply that adds it."""
    from uqdrape.study import StudyError

    plies = [{**p, "thickness_mm": t} for p, t in zip(QUASI_ISOTROPIC, thickness)] + [QUASI_ISOTROPIC[2]]
    path = laminate_file(tmp_path, plies, geometry=geometry)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert_one_line_error(str(err.value), file=path, key=key, valid=valid)
