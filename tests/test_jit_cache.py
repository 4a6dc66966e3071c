"""The kernels' disk cache follows their sources (``uqdrape/_jit.py``): a kernel that calls a
kernel of another module is compiled afresh after that module is edited (numba alone stamps
a cached function with its own file only, and would load the old machine code), and is
loaded from the cache while nothing changed. Each run is a new Python process, as a new
run or a dask worker is."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import uqdrape
from uqdrape import _jit

PACKAGE = Path(uqdrape.__file__).parent

CALLER = """from ._jit import jit
from ._probe_callee import scaled


@jit
def caller(x):
    return scaled(x) + 1.0
"""

CALLEE = """from ._jit import jit

SCALE = {scale}


@jit
def scaled(x):
    return SCALE * x
"""

# Prints where the package came from, caller(1.0) and how many calls loaded from the cache.
RUN = ("import uqdrape; from uqdrape._probe_caller import caller; "
       "print(uqdrape.__file__, caller(1.0), sum(caller.stats.cache_hits.values()))")


@pytest.fixture()
def package(tmp_path):
    """A package ``uqdrape`` in tmp_path: the real ``__init__`` and ``_jit``, and two kernel
    modules, the caller and the callee (its SCALE 2.0)."""
    pkg = tmp_path / "uqdrape"
    pkg.mkdir()
    for name in ("__init__.py", "_jit.py"):
        shutil.copy(PACKAGE / name, pkg / name)
    (pkg / "_probe_caller.py").write_text(CALLER)
    (pkg / "_probe_callee.py").write_text(CALLEE.format(scale=2.0))
    return pkg


def python(pkg: Path, code: str) -> str:
    """What ``code`` prints in a new process importing ``pkg``, with the cache in ``pkg``'s
    ``__pycache__`` (no NUMBA_CACHE_DIR)."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["PYTHONPATH"] = str(pkg.parent)
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=pkg.parent, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout


def run(pkg: Path) -> tuple[float, int]:
    """caller(1.0) and the number of cache hits, in a new process (``python``)."""
    source, value, hits = python(pkg, RUN).split()
    assert Path(source).parent == pkg
    return float(value), int(hits)


def test_an_edit_of_a_called_kernel_module_is_compiled_not_loaded_stale(package):
    assert run(package) == (3.0, 0)  # compiled: 2.0 * 1 + 1
    assert run(package) == (3.0, 1)  # loaded from the cache
    # The same size (numba's stamp of a file is its contents, or mtime and size by version).
    (package / "_probe_callee.py").write_text(CALLEE.format(scale=3.0))
    assert run(package) == (4.0, 0)


def test_compiled_tells_whether_a_kernel_must_compile_before_it_runs(package):
    """``_jit.compiled``, which decides a drape's "compiling the drape kernels" line: False
    in a process whose cache is empty, True once the kernel ran there, and True before the
    first call of the next process, which loads the machine code from the cache."""
    probe = ("from uqdrape._jit import compiled; from uqdrape._probe_caller import caller; "
             "before = compiled(caller); caller(1.0); print(before, compiled(caller))")
    assert python(package, probe).split() == ["False", "True"]
    assert python(package, probe).split() == ["True", "True"]


def test_folders_of_other_sources_are_removed_past_the_last_used(package):
    cache = package / "__pycache__"
    old = [cache / f"{_jit._PREFIX}{i:016x}" for i in range(_jit.KEEP + 2)]
    for age, folder in enumerate(old):
        folder.mkdir(parents=True)
        os.utime(folder, (1e9 - age, 1e9 - age))  # old[0] the last used
    run(package)
    kept = sorted(p.name for p in cache.glob(f"{_jit._PREFIX}*"))
    assert len(kept) == _jit.KEEP
    assert set(kept) > {p.name for p in old[:_jit.KEEP - 1]}


def test_every_module_that_compiles_kernels_is_hashed():
    """Read with a regular expression, not the AST walk the key uses."""
    decorated = {p for p in PACKAGE.rglob("*.py") if re.search(r"^@jit\b", p.read_text(), re.M)}
    sources = set(_jit.kernel_sources())
    assert decorated and decorated <= sources, sorted(map(str, decorated - sources))
    assert PACKAGE / "drape" / "ring.py" in sources and PACKAGE / "geometry" / "compiled.py" in sources
    assert PACKAGE / "cli.py" not in sources  # not imported by a kernel module: edits keep the cache


def test_the_sources_found_are_remembered_per_state_of_the_package(package):
    """The kernel sources are parsed out of the package once per state of it (issue 41:
    a tenth of a second of every process), their folder's name kept in ``sources-<hash
    of every module>``: read back while nothing changed; an edit of a module no kernel
    depends on gives a new record but the same folder, whose kernels still load."""
    cache = package / "__pycache__"
    assert run(package) == (3.0, 0)
    memos = list(cache.glob(f"{_jit._MEMO}*"))
    folders = list(cache.glob(f"{_jit._PREFIX}*"))
    assert len(memos) == 1 and len(folders) == 1
    assert folders[0].name == _jit._PREFIX + memos[0].read_text()
    assert run(package) == (3.0, 1)
    assert list(cache.glob(f"{_jit._MEMO}*")) == memos
    (package / "_unrelated.py").write_text("VALUE = 1\n")
    assert run(package) == (3.0, 1)
    assert len(list(cache.glob(f"{_jit._MEMO}*"))) == 2
    assert list(cache.glob(f"{_jit._PREFIX}*")) == folders
