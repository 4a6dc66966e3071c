"""Packaging that tells the truth: every package that uqdrape/ imports (imports inside
functions included) is declared in pyproject's dependencies, every one the tests import in
the dependencies or the test extra; the version is written once; the licence named is the
file shipped. The lower bounds themselves are checked by CI's lowest-versions run."""

import ast
import re
import sys
import tomllib
from importlib.metadata import packages_distributions, requires, version
from pathlib import Path

import uqdrape

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
PROJECT = PYPROJECT["project"]


def _name(requirement: str) -> str:
    """The normalised distribution name of a requirement string (PEP 503)."""
    return re.sub(r"[-_.]+", "-", re.match(r"[A-Za-z0-9._-]+", requirement).group()).lower()


def _declared(requirements, with_their_requirements=False) -> set[str]:
    """Names of the distributions ``requirements`` install: each one, the ones its extras
    (``dask[distributed]``) add and, if asked, its own unconditional requirements."""
    names = set()
    for requirement in requirements:
        name = _name(requirement)
        names.add(name)
        extras = set(re.findall(r"\w+", requirement.partition("[")[2].partition("]")[0]))
        if not extras and not with_their_requirements:
            continue  # an optional extra's package need not be installed to be named
        for sub in requires(name) or []:
            marker = sub.partition(";")[2]
            wanted = re.search(r"extra\s*==\s*['\"](\w+)['\"]", marker)
            if (wanted and wanted.group(1) in extras) or (with_their_requirements and not marker.strip()):
                names.add(_name(sub))
    return names


def _lazy(tree) -> set[int]:
    """ids of the import nodes inside a function of ``tree`` (run only when it is called)."""
    return {id(node) for fn in ast.walk(tree) if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef))
            for node in ast.walk(fn) if isinstance(node, (ast.Import, ast.ImportFrom))}


def _imported(folder: Path, lazy: bool | None = None) -> dict[str, str]:
    """Third-party top-level modules imported by the .py files under ``folder`` (not the
    standard library's, not the checkout's own), each with a file that imports it; with
    ``lazy`` True only the imports inside functions, False only the others."""
    found = {}
    for path in sorted(folder.rglob("*.py")):
        tree = ast.parse(path.read_bytes(), str(path))
        inside = _lazy(tree) if lazy is not None else set()
        for node in ast.walk(tree):
            if lazy is not None and (id(node) in inside) != lazy:
                continue
            if isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                modules = [node.module]
            else:
                continue
            for module in modules:
                top = module.split(".")[0]
                local = top == "uqdrape" or any(ROOT.glob(f"*/{top}.py")) or any(ROOT.glob(f"docs/_ext/{top}.py"))
                if top not in sys.stdlib_module_names and top != "__future__" and not local:
                    found.setdefault(top, str(path.relative_to(ROOT)))
    return found


def _undeclared(imports: dict[str, str], declared: set[str]) -> list[str]:
    providers = packages_distributions()
    return [f"{module} ({where}): from {providers.get(module)}" for module, where in sorted(imports.items())
            if not declared & {_name(d) for d in providers.get(module, [module])}]


def test_every_package_the_code_imports_is_a_declared_dependency():
    """At import time only the dependencies; inside a function (an optional feature, e.g.
    emcee for ``calibrate --posterior``) also an optional extra's."""
    core = _declared(PROJECT["dependencies"])
    extras = set().union(*(_declared(v) for k, v in PROJECT["optional-dependencies"].items() if k != "test"))
    assert _undeclared(_imported(ROOT / "uqdrape", lazy=False), core) == []
    assert _undeclared(_imported(ROOT / "uqdrape", lazy=True), core | extras) == []


def test_every_package_the_tests_import_is_declared_for_the_tests():
    """cfunits counts through cfchecker, which requires it: the tests import it only to
    skip the CF check where its C library is missing."""
    declared = _declared(PROJECT["dependencies"]) | _declared(PROJECT["optional-dependencies"]["test"], True)
    assert _undeclared(_imported(ROOT / "tests"), declared) == []


def test_the_version_is_written_once():
    assert "version" not in PROJECT and PROJECT["dynamic"] == ["version"]
    assert PYPROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "uqdrape._version.__version__"}
    assert version("uqdrape") == uqdrape.__version__


def test_the_licence_named_is_the_file_shipped():
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert PROJECT["license"] == "MIT" and PROJECT["license-files"] == ["LICENSE"]
    assert text.startswith("MIT License\n") and "Copyright (c) 2026 uqdrape developers" in text
