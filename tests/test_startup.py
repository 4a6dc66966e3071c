"""Start-up matches the work (issue 41): ``uqdrape --help``, a sub-command's help (its
epilog lists the mould kinds from the geometry registry), ``--version`` and ``import
uqdrape`` load none of the numerical stack they do not use, nor ``uqdrape validate`` the
Dataset stack and the parts of SciPy it does not use (each in a fresh interpreter, which
then lists the heavy modules it holds); successive runs share the workers' forkserver and
give the same numbers."""

import argparse
import dataclasses
import json
import multiprocessing
import subprocess
import sys
from pathlib import Path

import psutil
import pytest
import xarray as xr

import uqdrape
from conftest import write_study
from uqdrape.study import load_study

ROOT = Path(uqdrape.__file__).resolve().parents[1]
HEAVY = ("numba", "xarray", "scipy", "dask", "matplotlib", "pandas", "distributed")

PROBE = """import contextlib, io, json, sys
sys.path.insert(0, {root!r})
{code}
print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {heavy!r})))
"""


def heavy_modules(code: str) -> list[str]:
    """The heavy modules a fresh interpreter holds after running ``code``."""
    out = subprocess.run([sys.executable, "-c", PROBE.format(root=str(ROOT), code=code, heavy=HEAVY)],
                         capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(out.stdout.splitlines()[-1])


def cli(*argv) -> str:
    """Code that runs ``uqdrape argv`` with its output swallowed, as far as its exit."""
    return ("from uqdrape.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
            f"    main({list(argv)!r})")


@pytest.mark.parametrize("argv", [("--help",), ("drape", "--help"), ("run", "--help"), ("--version",)])
def test_cli_help_imports_no_numerical_stack(argv):
    assert heavy_modules(cli(*argv)) == []


def test_import_uqdrape_imports_no_numerical_stack():
    assert heavy_modules("import uqdrape") == []


def test_the_probe_sees_an_import():
    """The probe itself can fail: a module the code imports is listed."""
    assert "xarray" in heavy_modules("import xarray")


#: What ``uqdrape validate`` of a study without scalar factors has no use for (issue 41): the
#: Dataset, run and report stack, and the parts of SciPy its checks do not call (numba's own
#: BLAS check, when the placement drape loads the kernels, imports scipy.linalg).
NOT_FOR_VALIDATE = ("xarray", "pandas", "dask", "distributed", "matplotlib", "tqdm", "netCDF4", "scipy.stats",
                    "scipy.special", "scipy.interpolate", "scipy.integrate", "scipy.optimize")

LOADED = """import contextlib, io, json, sys
sys.path.insert(0, {root!r})
from uqdrape.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main({argv!r})
print(json.dumps([code, sorted(m for m in {names!r} if m in sys.modules)]))
"""


@pytest.mark.parametrize("study", ["nosecone-zero-angle", "geodesic"])
def test_validate_loads_neither_the_dataset_stack_nor_scipy_it_does_not_use(tmp_path, study):
    """validate reads the study (its card tabulated in numpy), checks the output folder and
    drapes one realisation for its placement without building the drape's Dataset: in a
    fresh interpreter it exits 0 holding none of NOT_FOR_VALIDATE. The shipped energy study
    with a zero-angle field (the issue's), and a geodesic one with random spacing."""
    path = (ROOT / "studies" / f"{study}.toml" if study != "geodesic"
            else write_study(tmp_path, uncertainty={"spacing": {"cv": 0.01}}))
    out = subprocess.run([sys.executable, "-c", LOADED.format(root=str(ROOT), argv=["validate", str(path)],
                                                              names=NOT_FOR_VALIDATE)],
                         capture_output=True, text=True, check=True, cwd=ROOT)
    assert json.loads(out.stdout.splitlines()[-1]) == [0, []], out.stderr


def test_the_validate_probe_sees_a_module_it_lists(tmp_path):
    """The probe itself can fail: a scalar factor's values come from scipy.stats (the
    placement drape samples it), which is then listed."""
    path = write_study(tmp_path, uncertainty={"friction": {"dist": "normal", "mean": 0.2, "sd": 0.01}})
    out = subprocess.run([sys.executable, "-c", LOADED.format(root=str(ROOT), argv=["validate", str(path)],
                                                              names=NOT_FOR_VALIDATE)],
                         capture_output=True, text=True, check=True, cwd=ROOT)
    code, loaded = json.loads(out.stdout.splitlines()[-1])
    assert code == 0 and "scipy.stats" in loaded, out.stderr


def test_drape_help_lists_every_geometry_kind_and_the_moulds_still_evaluate(capsys):
    """The epilog comes from the geometry registry without loading its kernels; a mould
    made from that registry then loads them on first use."""
    from uqdrape.cli import main
    from uqdrape.geometry import KINDS

    with pytest.raises(SystemExit):
        main(["drape", "--help"])
    epilog = capsys.readouterr().out.split("geometry kinds and their parameters")[1]
    assert [line.split()[0] for line in epilog.splitlines()[1:] if line.strip()] == list(KINDS)
    assert KINDS["hemisphere"](radius=80).height(0.0, 0.0) == pytest.approx(80.0)


def test_the_command_lines_choices_are_the_registries():
    """The parser restates the registries so that ``--help`` imports no engine; each list
    equals the one the engine checks against."""
    from uqdrape.calibration.fit import CRITERIA
    from uqdrape.calibration.likelihood import FAMILIES
    from uqdrape.cli import build_parser
    from uqdrape.export.cards import FLAVOURS
    from uqdrape.schema import BLANKHOLDER_MODELS, MODES
    from uqdrape.study.spec import SENSITIVITY_METHODS
    from uqdrape.workflow.single_shot import EXPORT_FORMATS

    def choices(command, option):
        sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
        return tuple(next(a for a in sub.choices[command]._actions if option in a.option_strings).choices)

    assert choices("drape", "--mode") == MODES
    assert choices("drape", "--blankholder-model") == BLANKHOLDER_MODELS
    assert choices("run", "--method") == SENSITIVITY_METHODS
    assert choices("export", "--to") == EXPORT_FORMATS
    assert choices("export", "--flavour") == tuple(FLAVOURS)
    assert choices("calibrate", "--family") == ("auto", *FAMILIES)
    assert choices("calibrate", "--criterion") == CRITERIA


def _forkservers() -> set[int]:
    """Pids of this process's multiprocessing forkservers."""
    return {p.pid for p in psutil.Process().children() if "forkserver" in " ".join(p.cmdline())}


@pytest.mark.skipif("forkserver" not in multiprocessing.get_all_start_methods(), reason="no forkserver here")
def test_successive_runs_share_a_warm_forkserver_and_give_the_same_numbers_as_in_process(tmp_path):
    """Two local runs from one Python process: the second forks its workers from the
    forkserver the first started (its engine imported once), and both ensembles equal
    the synchronous one bitwise (netCDF variables, coordinates and their attributes)."""
    from uqdrape.ensemble import open_ensemble
    from uqdrape.workflow import run_study

    path = write_study(tmp_path, study={"seed": 5, "realizations": 6, "chunk_size": 3},
                       solver={"mode": "geodesic", "rings": 4}, uncertainty={"spacing": {"cv": 0.01}})
    study = load_study(path)
    inline = run_study(study, scheduler="synchronous", progress=False)
    cold = run_study(dataclasses.replace(study, output_dir=tmp_path / "cold"), workers=2, progress=False)
    servers = _forkservers()
    warm = run_study(dataclasses.replace(study, output_dir=tmp_path / "warm"), workers=2, progress=False)
    assert len(servers) == 1 and _forkservers() == servers
    with open_ensemble(inline) as a, open_ensemble(cold) as b, open_ensemble(warm) as c:
        xr.testing.assert_identical(b.drop_attrs(deep=False), a.drop_attrs(deep=False))
        xr.testing.assert_identical(c.drop_attrs(deep=False), a.drop_attrs(deep=False))
