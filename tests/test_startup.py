"""Start-up matches the work (issue 41): ``uqdrape --help``, a sub-command's help (its
epilog lists the mould kinds from the geometry registry), ``--version`` and ``import
uqdrape`` load none of the numerical stack they do not use. Each runs in a fresh
interpreter, which then lists the heavy modules it holds."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

import uqdrape

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
