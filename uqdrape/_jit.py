"""The compilation setting of uqdrape's kernels: numba ``njit`` with numpy's floating-point
error model (x / 0 gives inf or NaN, as in the array code, instead of raising), without the
GIL (so ``on_threads`` can share a batch's realisations among Python threads), and cached to
disk in a folder named by the kernels' sources.

numba stamps a cached function with its own file only, not with the files of the kernels it
calls or of the constants it compiles in: after an edit of ``geometry/compiled.py`` it would
load the old machine code of ``drape/kernels.py``. So the cache folder, ``CACHE_DIR``, is
named by a hash of every module that compiles kernels (imports ``jit`` or ``inline`` from here), of the
package modules those import (transitively) and of numba's version: an edit of any of them
gives a new folder and a fresh compile, in every process (dask workers compute the same name
from the same files). The folder lies under ``$NUMBA_CACHE_DIR`` if set, else in the
package's ``__pycache__`` (a checkout keeps its cache), else under ``$XDG_CACHE_HOME/uqdrape``
(``~/.cache/uqdrape``); with none writable the kernels compile in every process. The
folders of other sources are kept while among the ``KEEP`` last used, then removed.

Finding the kernel sources parses the package's modules for their imports (a tenth of a
second, in every process: ``uqdrape validate`` pays it too). So the name found is kept
beside the folders in a small file named by a hash of every module of the package and
numba's version (``sources-<hash>``, reading them is a few milliseconds): the parse runs
once per state of the package, and any edit of any module parses afresh.
"""

import ast
import contextlib
import functools
import hashlib
import os
import shutil
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numba
import numpy as np
from numba import njit

_OPTIONS = dict(error_model="numpy", nogil=True)
_PACKAGE = Path(__file__).resolve().parent
_PREFIX = "kernels-"
_MEMO = "sources-"
#: Cache folders kept, the current one included (other checkouts, branches, numba versions).
KEEP = 4


def _imported_files(path: Path, tree: ast.Module) -> dict[Path, set[str]]:
    """The package's files that ``path``'s imports name, each with the names imported from it
    (empty for ``import x``)."""
    found: dict[Path, set[str]] = {}

    def add(base: Path, dotted: str, names: set[str]) -> None:
        target = base.joinpath(*dotted.split(".")) if dotted else base
        for module in (target.with_suffix(".py"), target / "__init__.py"):
            if module.is_file():
                found.setdefault(module, set()).update(names)
        for name in names:  # ``from package import module``
            if (target / f"{name}.py").is_file():
                found.setdefault(target / f"{name}.py", set())

    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = path.parent.parents[node.level - 2] if node.level > 1 else path.parent
            add(base, node.module or "", {alias.name for alias in node.names})
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == _PACKAGE.name:
            add(_PACKAGE.parent, node.module, {alias.name for alias in node.names})
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == _PACKAGE.name:
                    add(_PACKAGE.parent, alias.name, set())
    return found


def kernel_sources(package: Path = _PACKAGE) -> list[Path]:
    """The files whose contents the compiled kernels depend on: the modules of ``package``
    that import ``jit`` or ``inline`` from this module, and every package module those import."""
    @functools.cache
    def imports(path: Path) -> dict[Path, set[str]]:
        return _imported_files(path, ast.parse(path.read_bytes(), str(path)))

    this = package / Path(__file__).name
    # Only files that name this module can import from it: parse those, not the package.
    named = [p for p in package.rglob("*.py") if "__pycache__" not in p.parts and this.stem.encode() in p.read_bytes()]
    todo = [p for p in named if {"jit", "inline"} & imports(p).get(this, set())]
    needed = set(todo)
    while todo:
        for module in imports(todo.pop()):
            if module not in needed:
                needed.add(module)
                todo.append(module)
    return sorted(needed)


def sources_key(package: Path = _PACKAGE) -> str:
    """16 hex digits of a SHA-256 over numba's version and the kernel sources (paths
    relative to the package, and contents)."""
    digest = hashlib.sha256(numba.__version__.encode())
    for path in kernel_sources(package):
        digest.update(b"\0" + path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def _package_key(package: Path = _PACKAGE) -> str:
    """16 hex digits of a SHA-256 over numba's version and every module of ``package``
    (paths relative to the package, and contents): the state the kernel sources are found in."""
    digest = hashlib.sha256(numba.__version__.encode())
    for path in sorted(p for p in package.rglob("*.py") if "__pycache__" not in p.parts):
        digest.update(b"\0" + path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def _remembered_key(parents: list[Path], package: Path = _PACKAGE) -> str:
    """``sources_key(package)``, read from the file ``sources-<_package_key>`` in the first
    of ``parents`` holding it, else computed and written to the first writable one."""
    name = _MEMO + _package_key(package)
    for parent in parents:
        try:
            key = (parent / name).read_text(encoding="ascii")
        except (OSError, ValueError):
            continue
        if len(key) == 16 and all(c in "0123456789abcdef" for c in key):
            _used(parent / name)
            return key
    key = sources_key(package)
    for parent in parents:
        if _writable(parent):
            part = None
            try:  # a whole file or none: dask workers start together
                with tempfile.NamedTemporaryFile("w", dir=parent, prefix=".sources", delete=False) as part:
                    part.write(key)
                os.replace(part.name, parent / name)
            except OSError:
                if part is not None:
                    Path(part.name).unlink(missing_ok=True)
                continue
            _prune(parent, _MEMO, parent / name)
            break
    return key


def _used(path: Path) -> None:
    """Mark ``path`` used now (its modification time), if it still exists."""
    with contextlib.suppress(OSError):
        os.utime(path)


def _prune(parent: Path, prefix: str, current: Path) -> None:
    """Remove the entries ``prefix*`` of ``parent`` other than ``current`` past the
    ``KEEP - 1`` last used."""
    siblings = sorted(parent.glob(f"{prefix}*"), key=_last_used, reverse=True)
    for stale in [p for p in siblings if p != current][KEEP - 1:]:
        if stale.is_dir():
            shutil.rmtree(stale, ignore_errors=True)
        else:
            stale.unlink(missing_ok=True)


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def _last_used(folder: Path) -> float:
    """Modification time (s), 0 for a folder another process has just removed."""
    try:
        return folder.stat().st_mtime
    except OSError:
        return 0.0


def _cache_dir() -> Path | None:
    """This source's cache folder (created, its time of use set to now), after removing all
    but the ``KEEP`` last used of its siblings; None if no candidate parent is writable."""
    user_cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "uqdrape"
    parents = [Path(os.environ["NUMBA_CACHE_DIR"])] if os.environ.get("NUMBA_CACHE_DIR") else []
    parents += [_PACKAGE / "__pycache__", user_cache]
    name = _PREFIX + _remembered_key(parents)
    folder = next((p / name for p in parents if _writable(p / name)), None)
    if folder is None:
        return None
    os.utime(folder)
    _prune(folder.parent, _PREFIX, folder)
    return folder


CACHE_DIR = _cache_dir()


def jit(function):
    """``function`` compiled with uqdrape's settings, its machine code cached in CACHE_DIR.

    numba's cache locator reads ``numba.config.CACHE_DIR`` when the dispatcher is made, so it
    is set for that moment only: other numba code in the process keeps its own cache."""
    if CACHE_DIR is None:
        return njit(**_OPTIONS)(function)
    saved, numba.config.CACHE_DIR = numba.config.CACHE_DIR, str(CACHE_DIR)
    try:
        return njit(cache=True, **_OPTIONS)(function)
    finally:
        numba.config.CACHE_DIR = saved


def compiled(kernel) -> bool:
    """Whether ``kernel`` (made by ``jit``) runs without compiling first: compiled in this
    process, or numba's index of its machine code present in the disk cache (its private
    ``_cache_file``; a numba that moves it makes this False, which only costs a needless
    "compiling" line)."""
    if kernel.signatures:
        return True
    index = getattr(getattr(kernel._cache, "_cache_file", None), "_index_path", None)  # none without a cache
    return index is not None and os.path.isfile(index)


def inline(function):
    """``function`` compiled into the code of each compiled caller (numba's
    ``inline="always"``), with uqdrape's settings: for a small helper in a hot loop that
    LLVM's inliner would leave as a call (the node solver's circle point and gap)."""
    return njit(inline="always", **_OPTIONS)(function)


def on_threads(threads, R, call):
    """Call ``call(rows)`` for ``threads`` contiguous slices ``rows`` of range(R), each on
    its own thread (one slice, on this thread, for threads <= 1). Every realisation is
    computed by the same compiled code whatever the split, so results do not depend on it."""
    bounds = np.linspace(0, R, max(min(threads, R), 1) + 1).round().astype(int)
    rows = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]
    if len(rows) == 1:
        call(rows[0])
        return
    with ThreadPoolExecutor(len(rows)) as pool:
        for done in [pool.submit(call, r) for r in rows]:
            done.result()
