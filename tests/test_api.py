"""The public Python API (``uqdrape.__all__``): the names are the documented list, ``help``
shows them, ``import uqdrape`` stays light, every function works on a tiny case, and the
README's Python example runs verbatim. The tests use only the installed package and the
shipped examples, so they pass against an installed wheel outside the checkout too
(``tools/check_wheel.py``)."""

from __future__ import annotations

import ast
import json
import pydoc
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import uqdrape as ud
from conftest import assert_one_line_error, study_text, write_study
from uqdrape.cli import main

ROOT = Path(__file__).resolve().parents[1]

#: The README's ten-line Python example (the README carries this text in its ```python
#: block; test_the_readme_python_example_runs_verbatim holds the two together).
README_EXAMPLE = '''\
import uqdrape as ud

# a shipped study, made small: 16 drapes of a 25 x 25 net (about a minute the first time)
study = ud.load_study(ud.copy_example("nosecone-zero-angle", "studies"),
                      {"study.realizations": 16, "solver.rings": 12})
run = ud.run_study(study, out="results/first-run")       # local processes, progress shown
ensemble = ud.open_ensemble(run)                          # lazy xarray Dataset
stats = ud.node_statistics(ensemble, "shear")             # per node: mean, sd, quantiles, limits
stats["sd"].isel(blankholder_force=0).plot()              # the shear's sd map, deg
'''

#: Geodesic drapes of a 50 mm dome, 4 rings, with a random spacing (cv 2 %) and skew (sd 1 deg).
UNCERTAIN = {"spacing": {"cv": 0.02}, "skew": {"dist": "normal", "mean": 0.0, "sd": 1.0}}


def _documented() -> list[str]:
    """The names the module docstring lists under "The Python API", in its order."""
    doc = ud.__doc__.split("The Python API", 1)[1].split("\n\n", 2)[1]
    return [name.strip() for line in doc.splitlines() if line.startswith("    ") for name in line.split(",")]


# -- the names -------------------------------------------------------------------------------

def test_the_public_names_are_the_documented_list():
    assert ud.__all__ == _documented()
    assert len(set(ud.__all__)) == len(ud.__all__) and 20 <= len(ud.__all__) <= 30
    # what IDEs follow (the TYPE_CHECKING import) names the same
    tree = ast.parse(Path(ud.__file__).read_text(encoding="utf-8"))
    typing = next(node for node in tree.body if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING")
    typed = [alias.name for node in ast.walk(typing) if isinstance(node, ast.ImportFrom) for alias in node.names]
    assert sorted(typed) == sorted(ud.__all__)
    assert set(ud.__all__) <= set(dir(ud))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        ud.nope


def test_the_docs_api_page_lists_the_public_names():
    pages = [p for p in (ROOT / "docs").rglob("api*") if p.suffix in (".rst", ".md")] if (ROOT / "docs").is_dir() else []
    if not pages:
        pytest.skip("no docs/api page in this tree (the docs are built from a checkout)")
    text = "\n".join(p.read_text(encoding="utf-8") for p in pages)
    assert [name for name in ud.__all__ if not re.search(rf"\b{name}\b", text)] == []


def test_help_lists_every_name_with_its_documentation():
    text = pydoc.render_doc(ud, renderer=pydoc.plaintext)
    functions = text.split("\nFUNCTIONS\n", 1)[1]
    classes = text.split("\nCLASSES\n", 1)[1].split("\nFUNCTIONS\n", 1)[0]
    for name in ud.__all__:
        obj = getattr(ud, name)
        if isinstance(obj, type):
            assert f"class {name}" in classes, name
        else:
            assert re.search(rf"^    {name}\(", functions, re.M), name


@pytest.mark.parametrize("name", [n for n in ud.__all__ if not isinstance(getattr(ud, n), type)])
def test_each_function_has_a_numpydoc_docstring_with_an_example(name):
    doc = getattr(ud, name).__doc__
    assert doc and "Examples\n    --------" in doc and ">>> " in doc, name
    assert "Returns\n    -------" in doc, name


def test_the_docstring_examples_hold(tmp_path, monkeypatch):
    """Every example that runs on its own (not marked ``+SKIP``) gives what it shows."""
    import doctest

    import uqdrape.api
    import uqdrape.workflow.examples

    monkeypatch.chdir(tmp_path)
    for module in (uqdrape.api, uqdrape.workflow.examples):
        result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
        assert result.failed == 0 and result.attempted > 0, module.__name__


def test_importing_uqdrape_imports_none_of_the_heavy_libraries():
    heavy = ("numba", "xarray", "scipy", "dask", "matplotlib")
    code = ("import sys, uqdrape; assert uqdrape.__all__; "
            f"print(sorted({{m.split('.')[0] for m in sys.modules}} & set({heavy!r})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


# -- the shipped examples -----------------------------------------------------------------------

def test_every_shipped_study_is_listed_and_its_copy_loads(tmp_path):
    examples = dict(ud.list_examples())
    studies = [name for name in examples if not examples[name].startswith("data folder")]
    assert {"meshes", "sheartests", "measurements"} <= set(examples) and len(studies) >= 10
    for name in studies:  # the copy carries the files it names (meshes), so it loads where it lies
        study = ud.load_study(ud.copy_example(name, tmp_path / name))
        assert study.name == name or study.path.stem == name
        assert study.description and study.description in examples[name]


def test_copy_example_copies_a_study_with_its_mesh_and_keeps_a_users_edit(tmp_path):
    path = ud.copy_example("pan-corner-lock", tmp_path)
    assert path == tmp_path / "pan-corner-lock.toml"
    assert sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*") if p.is_file()) == [
        "meshes/pan.stl", "pan-corner-lock.toml"]
    assert ud.copy_example("pan-corner-lock", tmp_path) == path  # the same files again: nothing to refuse
    path.write_text(path.read_text() + "# mine\n")
    with pytest.raises(FileExistsError) as err:
        ud.copy_example("pan-corner-lock", tmp_path)
    assert_one_line_error(str(err.value), file=path, valid=["overwrite it"])
    assert err.value.names == ("overwrite",)  # the argument that gets past it
    assert path.read_text().endswith("# mine\n")
    ud.copy_example("pan-corner-lock", tmp_path, overwrite=True)
    assert not path.read_text().endswith("# mine\n")
    folder = ud.copy_example("sheartests", tmp_path / "data")
    assert folder == tmp_path / "data" / "sheartests" and (folder / "pf-rig.toml").is_file()
    with pytest.raises(ValueError) as err:
        ud.copy_example("nope", tmp_path)
    assert_one_line_error(str(err.value), valid=["'nope'", "nosecone-zero-angle", "meshes"])


def test_the_examples_command_lists_copies_and_refuses_a_clash(tmp_path, capsys):
    assert main(["examples"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in listed] == [name for name, _ in ud.list_examples()]
    assert main(["examples", "nosecone-zero-angle", str(tmp_path)]) == 0
    assert capsys.readouterr().out == f"wrote {tmp_path / 'nosecone-zero-angle.toml'}\n"
    (tmp_path / "nosecone-zero-angle.toml").write_text("# mine\n")
    assert main(["examples", "nosecone-zero-angle", str(tmp_path)]) == 2
    assert_one_line_error(capsys.readouterr().err, valid=["exists and differs", "--overwrite"])
    assert main(["examples", "nosecone-zero-angle", str(tmp_path), "--overwrite"]) == 0
    assert "[study]" in (tmp_path / "nosecone-zero-angle.toml").read_text()


# -- studies, runs and their results ----------------------------------------------------------

def test_load_study_takes_validated_overrides(tmp_path):
    path = ud.copy_example("nosecone-zero-angle", tmp_path)
    study = ud.load_study(path, {"study.realizations": 8, "solver.rings": 10})
    assert isinstance(study, ud.Study) and (study.realizations, study.solver.rings) == (8, 10)
    with pytest.raises(ud.StudyError) as err:
        ud.load_study(path, {"process.friction": -1.0})
    assert_one_line_error(str(err.value), file=path, key="process.friction")


def test_validate_study_checks_the_placement_of_the_first_drape(tmp_path):
    assert ud.validate_study(write_study(tmp_path)).name == "tiny"
    off = write_study(tmp_path, "off", fabric={"crossover": [49.0, 0.0]}, solver={"rings": 30})
    with pytest.raises(ud.StudyError) as err:
        ud.validate_study(off)
    assert_one_line_error(str(err.value), file=off, key="solver.rings", valid=["cannot be placed"])


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A Monte Carlo run of 6 geodesic drapes with a random spacing and skew, into OUT (not
    the study's own folder), by the synchronous scheduler."""
    tmp = tmp_path_factory.mktemp("api")
    path = write_study(tmp, uncertainty=UNCERTAIN)
    out = ud.run_study(path, out=tmp / "elsewhere", scheduler="synchronous", progress=False)
    return path, out


def test_run_study_writes_where_asked_and_the_ensemble_opens_lazily(tiny_run):
    path, out = tiny_run
    assert out == path.parent / "elsewhere" and not (path.parent / "tiny").exists()
    ds = ud.open_ensemble(out)
    assert dict(ds["shear"].sizes) == {"blankholder_force": 1, "realization": 6, "i": 9, "j": 9}
    assert ds["shear"].chunks is not None  # dask-backed
    assert float(ds["skew"].std()) > 0  # the sampled factor, per realisation
    with pytest.raises(FileNotFoundError, match="holds no uqdrape run"):
        ud.open_ensemble(path.parent / "nothing")


def test_statistics_are_those_of_the_drapes(tiny_run):
    ds = ud.open_ensemble(tiny_run[1]).load()
    shear = ds["shear"]
    stats = ud.node_statistics(ds, "shear", quantiles=(0.5,))
    np.testing.assert_allclose(stats["mean"], shear.mean("realization"), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(stats["sd"], shear.std("realization", ddof=1), rtol=1e-10, atol=1e-12)
    assert (stats["mean_lower"] <= stats["mean"]).all() and (stats["mean"] <= stats["mean_upper"]).all()
    threshold = float(abs(shear).quantile(0.9))
    risk = ud.exceedance_probability(ds, threshold)
    np.testing.assert_array_equal(risk["exceed_count"], (abs(shear) > threshold).sum("realization"))
    assert ((risk["probability_lower"] <= risk["probability"]) & (risk["probability"] <= risk["probability_upper"])).all()
    lines = ud.line_statistics(ds)
    assert lines.sizes["quadrant"] == 4 and (lines["count"] == 6).all()
    assert (lines["shear_mean_lower"] <= lines["shear_mean_upper"]).all()
    qois = ud.realization_qois(ds, ["max_abs_shear"])
    np.testing.assert_allclose(qois["max_abs_shear"].isel(blankholder_force=0),
                               abs(shear).isel(blankholder_force=0).max(("i", "j")), rtol=1e-12)


def test_a_run_without_sensitivity_design_or_rare_table_says_so(tiny_run):
    path, out = tiny_run
    assert ud.open_sensitivity(out) is None
    with pytest.raises(FileNotFoundError, match="holds no finished design"):
        ud.open_design(out)
    with pytest.raises(ValueError) as err:
        ud.rare_probability(path, out)
    assert_one_line_error(str(err.value), file=path, valid=["[study] rare"])


def test_report_and_export_of_a_run(tiny_run, tmp_path, unrasterised):
    path, out = tiny_run
    index = ud.write_report(out, tmp_path / "report")
    assert index == tmp_path / "report" / "index.html" and "tiny" in index.read_text()
    written, notes = ud.export_result(out, ["netcdf"], out=tmp_path / "all.nc")
    assert written == [tmp_path / "all.nc"] and notes == []
    with pytest.raises(ValueError) as err:
        ud.export_result(out, ["fe"])
    assert_one_line_error(str(err.value), valid=["needs mesh"])
    with xr.open_dataset(written[0]) as one:
        np.testing.assert_array_equal(one["shear"].values, ud.open_ensemble(out)["shear"].values)


def test_a_morris_run_gives_its_indices(tmp_path):
    path = write_study(tmp_path, "morris", uncertainty=UNCERTAIN, sensitivity={"method": "morris", "base_samples": 10})
    out = ud.run_study(path, scheduler="synchronous", progress=False)
    indices, maps = ud.open_sensitivity(out)
    assert indices.attrs["method"] == "morris" and set(indices["factor"].values) == {"spacing", "skew"}
    assert float(indices["mu_star"].sel(factor="skew", qoi="max_abs_shear").max()) > 0
    assert {"factor", "i", "j"} <= set(maps.dims)


def test_a_blank_holder_design_runs_and_opens(tmp_path):
    """Real energy drapes of a tiny study: the least 95 % quantile of max |shear| over a
    uniform force in [0, 400] N, a few designs."""
    text = study_text(tmp_path, "d", study={"realizations": 8, "chunk_size": 8}, solver={"mode": "energy"},
                      uncertainty={"zero_angle": {"sd_deg": 2.0}})
    path = tmp_path / "d.toml"
    path.write_text(text + '\n[design]\nvariables = "force"\nforce_bounds_N = [0.0, 400.0]\n'
                    'objective = "q95_max_abs_shear"\nstatistic = "estimate"\ntolerance_N = 50.0\n'
                    'max_evaluations = 6\nvalidation_realizations = 8\n', encoding="utf-8")
    design = ud.open_design(ud.run_study(path, scheduler="synchronous", progress=False))
    optimum = float(design.attrs["optimum"])
    assert 0.0 <= optimum <= 400.0 and np.isclose(design["x"].values[:, 0], optimum).any()  # a design evaluated
    assert design.attrs["summary"].startswith("F = ")


def test_a_rare_probability_is_estimated_and_kept(tmp_path):
    rare = {"qoi": "mean_shear_positive", "threshold": 9.0, "cov": 0.3, "max_drapes": 2000}
    path = write_study(tmp_path, "rare", study={"realizations": 2, "rare": rare}, solver={"rings": 6},
                       uncertainty=UNCERTAIN)
    (tmp_path / "runs").mkdir()
    record = ud.rare_probability(path, tmp_path / "runs", progress=False)
    level = record["levels"][0]
    assert 0 < level["probability"] < 1 and level["drapes"] <= 2000 and record["threshold"] == 9.0
    assert json.loads((tmp_path / "runs" / "rare.json").read_text())["levels"] == record["levels"]
    assert ud.rare_probability(path, tmp_path / "runs", progress=False) == record  # kept, not estimated again


# -- single drapes, moulds, cards, calibration ------------------------------------------------------

def test_moulds_analytic_and_mesh(tmp_path):
    dome = ud.mould("hemisphere", radius=80.0)
    assert float(dome.height(0.0, 0.0)) == pytest.approx(80.0) and float(dome.height(200.0, 0.0)) == 0.0
    pan = ud.mould("mesh", path=str(ud.copy_example("meshes", tmp_path) / "pan.stl"))
    assert pan.name == "mesh"
    with pytest.raises(ValueError) as err:
        ud.mould("sphere")
    assert_one_line_error(str(err.value), valid=["'sphere'", "hemisphere", "nose_cone"])


def test_drape_mould_geodesic_and_energy():
    dome = ud.mould("hemisphere", radius=100.0)
    net = ud.drape_mould(dome, spacing=5.0, rings=6)
    shear = net["shear"].isel(realization=0)
    assert dict(shear.sizes) == {"i": 13, "j": 13} and (net["status"] == 0).all()
    np.testing.assert_allclose(shear.values, shear.values[::-1, ::-1], atol=1e-9)  # the dome's symmetry
    card = ud.load_material("ebxhd936_like")
    energy = ud.drape_mould(dome, 5.0, 6, material=card, mode="energy", blankholder_force=50.0)
    assert energy.attrs["mode"] == "energy" and float(energy["energy_shear"][0]) > 0
    with pytest.raises(ValueError) as err:
        ud.drape_mould(dome, spacing=-1.0, rings=6)
    assert_one_line_error(str(err.value), valid=["spacing", "mm"])
    assert "--" not in str(err.value)  # a Python caller is not told a command-line flag


def test_cards_shipped_derived_and_fitted(tmp_path):
    assert "ebxhd936_like" in ud.available_materials()
    card = ud.load_material("ebxhd936_like")
    assert card.locking_angle_deg > 0 and card.name == "ebxhd936_like"
    assert ud.derive_material("fge106hd", tmp_path / "fge.toml").startswith(f"wrote {tmp_path / 'fge.toml'}")
    assert ud.load_material(tmp_path / "fge.toml").locking_angle_deg > 0
    rig = ud.copy_example("sheartests", tmp_path) / "pf-rig.toml"
    assert ud.fit_material(rig, tmp_path / "pf.toml").startswith("wrote")
    fitted = ud.load_material(tmp_path / "pf.toml")
    assert fitted.curve("positive")[1][-1] > 0


def test_calibration_from_fibre_angles(tmp_path):
    csv = ud.copy_example("measurements", tmp_path) / "fibre-angles.csv"
    text = ud.calibrate_fibre_angles(csv, tmp_path / "zero_angle.toml", family="iid")
    assert text.startswith(f"wrote {tmp_path / 'zero_angle.toml'}: iid field")
    block = (tmp_path / "zero_angle.toml").read_text()
    assert "[uncertainty.zero_angle]" in block and "sd_deg" in block


def test_calibration_from_drapes_refuses_an_unknown_key(tmp_path):
    study = write_study(tmp_path)
    part = ud.copy_example("measurements", tmp_path) / "part-1.csv"
    with pytest.raises(ValueError, match="process.nope"):
        ud.calibrate_drapes([part], study, {"process.nope": (0.0, 1.0)}, tmp_path / "out.toml")


# -- the README's example --------------------------------------------------------------------

def _run_example(code: str, folder: Path, monkeypatch) -> tuple[dict, int]:
    """Run ``code`` in ``folder``; its names and the number of figures it drew."""
    import matplotlib.pyplot as plt

    monkeypatch.chdir(folder)
    plt.close("all")
    namespace = {"__name__": "__readme__"}
    exec(compile(code, "README example", "exec"), namespace)
    figures = len(plt.get_fignums())
    plt.close("all")
    return namespace, figures


def test_the_api_example_runs(tmp_path, monkeypatch):
    namespace, figures = _run_example(README_EXAMPLE, tmp_path, monkeypatch)
    assert figures == 1
    stats = namespace["stats"]
    assert isinstance(stats, xr.Dataset) and int(stats["count"].max()) == 16
    assert (tmp_path / "studies" / "nosecone-zero-angle.toml").is_file()
    assert (tmp_path / "results" / "first-run").is_dir()


def test_the_readme_python_example_runs_verbatim(tmp_path, monkeypatch):
    readme = ROOT / "README.md"
    blocks = re.findall(r"^```python\n(.*?)^```", readme.read_text(encoding="utf-8"), re.M | re.S) \
        if readme.is_file() else []
    if not blocks:
        print(f"skipped: {readme} has no ```python block (yet)")
        pytest.skip(f"{readme} has no ```python block")
    if blocks[0] == README_EXAMPLE:  # run by test_the_api_example_runs
        return
    _run_example(blocks[0], tmp_path, monkeypatch)
