"""The shipped examples: the study files of the checkout's ``studies/`` and the data they
use (meshes, shear tests, measurements), installed with the package as ``uqdrape/examples``
(``setup.py`` maps that package onto ``studies/``, so the files live once in git), and
copied out into a folder of the user's by :func:`copy_example` or ``uqdrape examples``.

An example is a study (its file's stem, e.g. ``nosecone-zero-angle``: the study file and
every file it names, such as a mesh) or a data folder (``meshes``, ``sheartests``,
``measurements``, ``cluster``: the folder whole).
"""

from __future__ import annotations

import os
import shutil
import tomllib
from pathlib import Path

from ..errors import naming


def examples_dir() -> Path:
    """The folder of the shipped examples: ``uqdrape/examples`` in an installed package,
    the checkout's ``studies/`` when uqdrape runs from its source tree."""
    here = Path(__file__).resolve().parents[1]
    installed = here / "examples"
    return installed if installed.is_dir() else here.parent / "studies"


def _describe(path: Path) -> str:
    """A study's ``[study] description`` (its name if it has none); a folder's file count."""
    if path.is_dir():
        files = [p for p in path.rglob("*") if p.is_file() and "__pycache__" not in p.parts]
        return f"data folder: {len(files)} file{'s' * (len(files) != 1)} ({', '.join(sorted({p.suffix for p in files if p.suffix}))})"
    head = tomllib.loads(path.read_text(encoding="utf-8")).get("study", {})
    return str(head.get("description") or head.get("name", path.stem))


def _entries() -> dict[str, Path]:
    root = examples_dir()
    studies = {p.stem: p for p in root.glob("*.toml")}
    folders = {p.name: p for p in root.iterdir() if p.is_dir() and p.name != "__pycache__"}
    return dict(sorted({**studies, **folders}.items()))


def list_examples() -> list[tuple[str, str]]:
    """The shipped examples, each as (name, description).

    Returns
    -------
    list of (str, str)
        Sorted by name: the studies (a study file's stem, described by its ``[study]
        description``) and the data folders (``meshes``, ``sheartests``, ...).

    Examples
    --------
    >>> import uqdrape as ud
    >>> names = [name for name, _ in ud.list_examples()]
    >>> "nosecone-zero-angle" in names and "meshes" in names
    True
    """
    return [(name, _describe(path)) for name, path in _entries().items()]


def _referenced(study: Path, root: Path) -> list[Path]:
    """The files under ``root`` that the study file names by a path relative to its folder
    (a mesh's ``path``, a report's ``experimental_csv``)."""
    found, stack = [], [tomllib.loads(study.read_text(encoding="utf-8"))]
    while stack:
        value = stack.pop()
        if isinstance(value, dict):
            stack.extend(value.values())
        elif isinstance(value, list):
            stack.extend(value)
        elif isinstance(value, str) and value and not os.path.isabs(value):
            path = (study.parent / value).resolve()
            if path.is_file() and path.is_relative_to(root.resolve()):
                found.append(path)
    return found


def copy_example(name: str, dest: str | os.PathLike = ".", *, overwrite: bool = False) -> Path:
    """Copy a shipped example into the folder ``dest``.

    A study is copied as its file and every file it names (a mesh, measured points), at
    the same relative paths, so the copy runs where it lies; a data folder is copied
    whole. A file already in ``dest`` with the same content is left as it is; one that
    differs is kept unless ``overwrite``.

    Parameters
    ----------
    name : str
        An example's name (see :func:`list_examples`): a study such as
        ``"nosecone-zero-angle"`` or a data folder such as ``"sheartests"``.
    dest : str or os.PathLike, default "."
        The folder to copy into (made if missing).
    overwrite : bool, default False
        Replace files in ``dest`` that differ from the example's.

    Returns
    -------
    pathlib.Path
        The copied study file (``dest/NAME.toml``) or folder (``dest/NAME``).

    Raises
    ------
    ValueError
        ``name`` is not a shipped example (the message lists them).
    FileExistsError
        A file in ``dest`` differs from the example's and ``overwrite`` is False.

    Examples
    --------
    >>> import tempfile, uqdrape as ud
    >>> path = ud.copy_example("pan-corner-lock", tempfile.mkdtemp())
    >>> sorted(p.name for p in path.parent.rglob("*.*"))
    ['pan-corner-lock.toml', 'pan.stl']
    """
    entries = _entries()
    if name not in entries:
        raise ValueError(f"unknown example {name!r}; valid: {', '.join(entries)}")
    root, source = examples_dir(), entries[name]
    files = ([p for p in source.rglob("*") if p.is_file() and "__pycache__" not in p.parts] if source.is_dir()
             else [source, *_referenced(source, root)])
    dest = Path(dest)
    pairs = [(f, dest / f.resolve().relative_to(root.resolve())) for f in files]
    clash = [str(to) for f, to in pairs if to.exists() and to.read_bytes() != f.read_bytes()]
    if clash and not overwrite:
        raise naming(FileExistsError(f"{clash[0]} exists and differs from the example's; move it or overwrite "
                                     "it"), "overwrite")
    for f, to in pairs:
        to.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(f, to)
    return dest / source.name
