"""Build the wheel and the sdist, check them, and use the wheel as a user would, outside the checkout.

    python tools/check_wheel.py [--quick] [--keep DIR [--reuse]]

1. ``python -m build`` (wheel and sdist) and ``twine check`` on both;
2. the wheel holds every file of ``studies/`` (as ``uqdrape/examples/``) and the material
   cards, and the sdist the files that build the wheel;
3. a fresh virtual environment in a temporary folder outside the checkout installs ONLY
   the wheel (its dependencies from the package index) and pytest;
4. there ``uqdrape examples pan-corner-lock`` copies an example out, ``uqdrape run``
   drapes it end to end (ensemble and report), and ``tests/test_api.py`` (with
   ``tests/conftest.py``, copied beside it) passes against the installed package.

``--quick`` (CI, under a minute): steps 1 and 2, then the wheel alone installed into a
folder outside the checkout (``pip install --no-deps --target``; the dependencies are this
interpreter's), an example copied out of it, and the tests of test_api.py that drape
nothing (QUICK_TESTS) run against it.

Needs ``build`` and ``twine`` in this interpreter (``pip install build twine``). Exits
non-zero at the first failure, saying which step failed; prints each step's time.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The tests of test_api.py that --quick runs: the names, help, docstrings, examples; no drapes.
QUICK_TESTS = "names or help or numpydoc or importing or copy or examples_command or load_study or cards"


def step(what: str, *command, cwd=None, env=None) -> str:
    """Run ``command``, print its time; on failure print its output and stop."""
    start = time.perf_counter()
    done = subprocess.run([str(c) for c in command], cwd=cwd, env=env, capture_output=True, text=True)
    print(f"{what}: {'ok' if done.returncode == 0 else 'FAILED'} ({time.perf_counter() - start:.0f} s)", flush=True)
    if done.returncode:
        print(done.stdout[-4000:], done.stderr[-4000:], sep="\n", file=sys.stderr)
        sys.exit(f"check_wheel: {what} failed (exit {done.returncode})")
    return done.stdout


def tracked(folder: str) -> list[str]:
    """The files git tracks under ``folder`` of the checkout, relative to it."""
    out = subprocess.run(["git", "ls-files", folder], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    return [str(Path(p).relative_to(folder)) for p in out.split()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", metavar="DIR", help="work in DIR and keep it (default: a temporary folder)")
    parser.add_argument("--quick", action="store_true",
                        help="for CI: install the wheel alone into a folder (this interpreter's packages for its "
                             "dependencies), copy an example out, and run the fast tests of test_api.py (no drapes)")
    parser.add_argument("--reuse", action="store_true",
                        help="with --keep: reinstall only the wheel into DIR's venv of an earlier check (its "
                             "dependencies as they are), instead of a fresh venv")
    args = parser.parse_args()
    work = Path(args.keep or tempfile.mkdtemp(prefix="uqdrape-wheel-")).resolve()
    if work.is_relative_to(ROOT):
        sys.exit("check_wheel: the work folder must lie outside the checkout")
    work.mkdir(parents=True, exist_ok=True)
    dist = work / "dist"
    shutil.rmtree(dist, ignore_errors=True)
    step("build wheel and sdist", sys.executable, "-m", "build", "--outdir", dist, ROOT)
    wheel, sdist = next(dist.glob("*.whl")), next(dist.glob("*.tar.gz"))
    step("twine check", sys.executable, "-m", "twine", "check", "--strict", wheel, sdist)

    names = set(zipfile.ZipFile(wheel).namelist())
    missing = [p for p in tracked("studies") if f"uqdrape/examples/{p}" not in names]
    missing += [p for p in tracked("uqdrape/material/cards") if f"uqdrape/material/cards/{p}" not in names]
    if missing:
        sys.exit(f"check_wheel: the wheel lacks {', '.join(missing)}")
    print(f"wheel contents: every file of studies/ and the cards ({len(names)} files)")

    user = work / "user"
    shutil.rmtree(user, ignore_errors=True)
    (user / "tests").mkdir(parents=True)
    for name in ("test_api.py", "conftest.py"):
        shutil.copy(ROOT / "tests" / name, user / "tests" / name)
    if args.quick:  # the wheel alone in a folder of its own, this interpreter's packages for its dependencies
        home = work / "site"
        shutil.rmtree(home, ignore_errors=True)
        step("install the wheel alone (no dependencies) into a folder", sys.executable, "-m", "pip", "install",
             "-q", "--no-deps", "--target", home, wheel)
        python, env = Path(sys.executable), {**os.environ, "PYTHONPATH": str(home)}
        tests = ["-k", QUICK_TESTS]
    else:
        home = work / "venv"
        python, env, tests = home / "bin" / "python", None, []
        if args.reuse and args.keep and python.is_file():
            step("reinstall the wheel alone into the kept venv", python, "-m", "pip", "install", "-q", "--no-deps",
                 "--force-reinstall", wheel)
        else:
            shutil.rmtree(home, ignore_errors=True)
            step("fresh venv", sys.executable, "-m", "venv", home)
            step("install the wheel (dependencies from the index) and pytest", python, "-m", "pip", "install", "-q",
                 wheel, "pytest>=8", "pytest-timeout>=2.2")
    where = step("the installed package", python, "-c", "import uqdrape; print(uqdrape.__file__)", cwd=user, env=env)
    if not Path(where.strip()).is_relative_to(home):
        sys.exit(f"check_wheel: uqdrape imported from {where.strip()}, not {home}")
    uqdrape = [python, "-m", "uqdrape.cli"]
    step("uqdrape examples pan-corner-lock .", *uqdrape, "examples", "pan-corner-lock", ".", cwd=user, env=env)
    if not (user / "meshes" / "pan.stl").is_file():
        sys.exit("check_wheel: the example was copied without its mesh")
    if not args.quick:
        step("uqdrape run pan-corner-lock.toml (ensemble and report)", *uqdrape, "run", "pan-corner-lock.toml", "-q",
             "--out", "results/pan", cwd=user)
        if not (user / "results" / "pan" / "report" / "index.html").is_file():
            sys.exit("check_wheel: the run wrote no report")
    print(step("tests/test_api.py against the installed wheel", python, "-m", "pytest", "-q", "-p", "no:cacheprovider",
               "tests/test_api.py", *tests, cwd=user, env=env).strip().splitlines()[-1])
    if not args.keep:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()
