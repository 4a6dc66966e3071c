"""uqdrape's files: one validating TOML reader, one CSV splitter and one atomic writer.

Reading. :func:`read_toml` turns a TOML file into a dict or raises :class:`FileFormatError`
with a one-line message naming the file and the cause (unreadable, too large, not text,
not TOML, nested too deeply), never the file's contents. :class:`Document` (the file) and
:class:`Table` (one of its tables) then check keys and typed values, raising the same
error with ``key`` set to the dotted key, in one style::

    <file>: <key> = <value> is invalid: <why>
    <file>: unknown key <key>; valid keys in [<table>]: <k1>, <k2>, ...
    <file>: <key> is missing: <why>

CSV. :func:`csv_rows` splits a CSV's text into header and numbered rows and
:func:`csv_number` reads a cell; each CSV reader checks its own columns.

Writing. :func:`write_atomic` has a callback write a temporary file beside the target and
renames it into place, so a target exists only complete; :func:`write_text_atomic` and
:func:`write_all` (several files, all or nothing) are built on it.

This module imports only uqdrape.errors (which imports nothing): every other part may use it.
"""

from __future__ import annotations

import contextlib
import csv
import errno
import json
import math
import numbers
import os
import stat
import tomllib
from collections.abc import Callable
from pathlib import Path

from .errors import ParameterError

#: Largest TOML file read (bytes): uqdrape's inputs are a few kB; anything this big is a mistake.
MAX_TOML_BYTES = 10 * 1024 * 1024
#: Deepest nesting of arrays and tables accepted (tomllib itself overflows the stack at a
#: few hundred levels; uqdrape's files use at most four).
MAX_TOML_DEPTH = 50
#: ``default`` of a required key.
REQUIRED = object()


class FileFormatError(ValueError):
    """A problem in an input file. The message is one line naming the file; ``path`` is the
    file, ``key`` the dotted key at fault (None: the file as a whole)."""

    def __init__(self, message: str, path=None, key: str | None = None):
        super().__init__(message)
        self.path = path
        self.key = key


# ----------------------------------------------------------------------------- reading


def read_toml(path, what: str, *, error: type[FileFormatError] = FileFormatError) -> dict:
    """The TOML document of the file ``path`` (``what`` it is, e.g. "study file", for the
    messages). UTF-8, a byte-order mark allowed, or UTF-16 with its mark; at most
    MAX_TOML_BYTES and MAX_TOML_DEPTH levels deep. Any problem raises ``error``."""
    return parse_toml(read_text(path, what, error=error), str(path), error=error, path=Path(path))


def read_text(path, what: str, *, error: type[FileFormatError] = FileFormatError) -> str:
    """The text of the file ``path``: UTF-8 (a byte-order mark allowed) or UTF-16 with its
    mark, at most MAX_TOML_BYTES; anything else raises ``error`` naming the file."""
    path = Path(path)

    def fail(text):
        raise error(f"{path}: {text}", path)

    check_input_file(path, what, MAX_TOML_BYTES, error=error)
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_TOML_BYTES + 1)
    except OSError as err:
        fail(f"cannot read the {what}: {err.strerror or err}")
    if len(data) > MAX_TOML_BYTES:
        fail(f"the {what} is larger than {MAX_TOML_BYTES // 2**20} MB; is it the right file?")
    try:
        text = data.decode("utf-16") if data.startswith((b"\xff\xfe", b"\xfe\xff")) else data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        fail(f"not UTF-8 text: byte 0x{data[err.start]:02x} at offset {err.start} ({err.reason}); "
             f"save the {what} as UTF-8")
    return text


def check_input_file(path, what: str, max_bytes: int, *, error: type[ValueError] = FileFormatError) -> int:
    """The size in bytes of the input file ``path``, checked before it is opened: a
    regular file (a FIFO, device or folder would block or never end) of at most
    ``max_bytes``. Anything else raises ``error`` naming the file, ``what`` it should be
    and the limit; a missing file is left to the reader's own message."""
    path = Path(path)
    try:
        info = path.stat()
    except OSError:
        return 0  # the open that follows names the cause
    if not stat.S_ISREG(info.st_mode):
        kind = "a folder" if stat.S_ISDIR(info.st_mode) else "a pipe" if stat.S_ISFIFO(info.st_mode) else \
            "a device or socket"
        raise _error(error, f"{path}: the {what} is {kind}, not a regular file", path)
    if info.st_size > max_bytes:
        raise _error(error, f"{path}: the {what} is larger than {max_bytes / 2**20:g} MB, the most read; is it "
                            "the right file?", path)
    return info.st_size


def local_path(target, name: str) -> Path:
    """``target`` as a path on this machine; a URL raises ParameterError naming the
    argument ``name`` (pathlib would fold ``http://host/x`` into the local folder ``http:/host``)."""
    if isinstance(location(target), str):
        raise ParameterError(name, f"{target}: this command writes files on this machine; give a path (a store "
                             "URL is written by run and design, and read by report and export)")
    return Path(target)


def _error(error: type[ValueError], message: str, path) -> ValueError:
    """``error`` with ``message`` (and ``path``, where it is a FileFormatError)."""
    return error(message, path) if issubclass(error, FileFormatError) else error(message)


#: Most characters of a bad CSV cell quoted in a message.
QUOTED_CELL = 40


def csv_rows(text: str, label: str, *, error: type[FileFormatError] = FileFormatError, path=None):
    """The rows of CSV ``text``, the header first: each ``(line, cells)``, its line in the
    file and its cells stripped; blank and ``#`` comment lines are skipped (so
    ``(line, header), *rows = csv_rows(...)``). No header, or text the csv module cannot
    split, raises ``error`` naming ``label``. Nothing of the text is quoted: a reader
    checks the header before it quotes a cell, so a wrong file is not echoed."""
    numbered = [(n, line) for n, line in enumerate(text.splitlines(), start=1)
                if line.strip() and not line.lstrip().startswith("#")]
    if not numbered:
        raise error(f"{label}: no header line (the file is empty or holds only # comments)", path)
    try:
        cells = list(csv.reader(line for _, line in numbered))
    except csv.Error as err:
        raise error(f"{label}: not a CSV file ({err})", path) from None
    return [(n, [c.strip() for c in row]) for (n, _), row in zip(numbered, cells)]


def csv_number(cell: str) -> float:
    """The finite number in the CSV cell ``cell``; ValueError saying what was expected,
    without the cell (the file may not be the user's: the caller names line and column)."""
    try:
        value = float(cell)
    except ValueError:
        raise ValueError("expected a number") from None
    if not math.isfinite(value):
        raise ValueError("expected a finite number, not inf or nan")
    return value


def parse_toml(text: str, label: str, *, error: type[FileFormatError] = FileFormatError, path=None) -> dict:
    """The TOML document in ``text``; ``label`` names it in the messages of ``error``."""
    def fail(why):
        raise error(f"{label}: {why}", path)

    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        fail(f"not valid TOML: {err}")
    except RecursionError:
        doc = None
    if doc is None or _depth(doc) > MAX_TOML_DEPTH:
        fail(f"arrays or tables nested more than {MAX_TOML_DEPTH} levels deep; uqdrape's files need at most five")
    return doc


def _depth(value) -> int:
    """Nesting depth of dicts and lists (a scalar: 0), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        item, level = stack.pop()
        if isinstance(item, (dict, list)):
            deepest = max(deepest, level + 1)
            stack.extend((v, level + 1) for v in (item.values() if isinstance(item, dict) else item))
    return deepest


def inside(name: str) -> bool:
    """``name`` is a relative path that stays in the folder it is relative to, read as
    written (not absolute, no NUL, no leading '..' once 'a/../' pairs are collapsed).
    Symbolic links inside the folder are the folder owner's and are followed."""
    if "\0" in name or Path(name).is_absolute() or os.path.isabs(name):
        return False
    return os.path.normpath(name).split(os.sep, 1)[0] != os.pardir


def location(target) -> Path | str:
    """An output location as written: an fsspec URL (``s3://bucket/prefix``,
    ``file:///abs/path``, ``memory://name``) stays a string (a Path would fold its '//'),
    anything else is a Path. The one place a URL is told from a path: the run's storage
    is chosen by it (``uqdrape.ensemble.storage.at``)."""
    return target if isinstance(target, str) and "://" in target else Path(target)


#: fsspec's names of this machine's disk (``LocalFileSystem.protocol``; a test holds them equal).
LOCAL_PROTOCOLS = ("file", "local")


def url_problem(url: str) -> str | None:
    """Why the store URL ``url`` cannot be written, or None: nothing after ``scheme://``
    (``file://`` would put the manifest in the current folder and the data at /data); a
    local disk spelt other than ``file://`` (``local://``, ``FILE://``) or a chained URL
    (``simplecache::file://../x``). A ``file://`` path is held to the rule of a plain path
    (``study.validate``); the other spellings are refused rather than aliased, so that no
    spelling reaches a folder that rule has not checked."""
    scheme, rest = url.split("://", 1)
    valid = "give a plain path, file:///abs/path or s3://bucket/prefix"
    if "::" in url:
        return f"a chained fsspec URL (protocol::URL) is not a store uqdrape writes; {valid}"
    if scheme.lower() in LOCAL_PROTOCOLS and scheme != "file":
        return f"{scheme}:// names this machine's disk; {valid}"
    if not rest.strip("/"):
        return f"a store URL needs a path after {scheme}://, e.g. file:///abs/path or s3://bucket/prefix"
    return None


def json_object(data: bytes, error: Callable[[str], Exception]) -> dict:
    """The JSON object in the UTF-8 ``data``; anything else raises ``error(why)``."""
    try:
        value = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as err:
        raise error(f"not JSON text: {type(err).__name__}") from None
    if not isinstance(value, dict):
        raise error("not a JSON object")
    return value


def fmt(value) -> str:
    """A value as it would be written in TOML (shortened past 80 characters)."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, str):
        text = json.dumps(value)
    elif isinstance(value, dict):
        text = "{ " + ", ".join(f"{k} = {fmt(v)}" for k, v in value.items()) + " }"
    elif isinstance(value, (list, tuple)):
        text = "[" + ", ".join(fmt(v) for v in value) + "]"
    else:
        text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def is_number(value) -> bool:
    """An int or float, not a bool (TOML's true is not 1)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def to_float(value) -> float:
    """``value`` as a float; NaN where float() refuses it (None, a word, a list)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def is_int(value) -> bool:
    """An int, not a bool."""
    return isinstance(value, int) and not isinstance(value, bool)


class Document:
    """A file being validated: ``label`` names it in messages (default: the path), its folder
    resolves the files it names, ``what`` it is ("study file") for hints; problems raise
    ``error``. ``path`` None: a document that is not a file of its own (``label`` required)."""

    def __init__(self, path, what: str, *, label: str | None = None, error: type[FileFormatError] = FileFormatError):
        self.path = None if path is None else Path(path)
        self.what = what
        self.label = str(path) if label is None else label
        self.folder = None if path is None else self.path.resolve().parent
        self.error = error

    def read(self) -> dict:
        """The file's TOML document (see read_toml)."""
        return read_toml(self.path, self.what, error=self.error)

    def fail(self, text: str, key: str | None = None):
        raise self.error(f"{self.label}: {text}", self.path, key)

    def invalid(self, key: str, value, why: str):
        self.fail(f"{key} = {fmt(value)} is invalid: {why}", key)

    def missing(self, key: str, why: str):
        self.fail(f"{key} is missing: {why}", key)

    def relative_file(self, key: str, value) -> Path:
        """An existing file named by ``value`` relative to this file's folder, and inside it:
        a file read as data names only files beside or below itself (see inside)."""
        if not isinstance(value, str) or not value or self.folder is None:
            self.invalid(key, value, f"must be a file name (relative to the {self.what})")
        if not inside(value):
            self.invalid(key, value, f"must name a file in {self.folder} (the {self.what}'s folder) or below it: "
                                     "absolute paths and '..' are not followed; copy the file there")
        path = self.folder / value
        if not path.is_file():
            self.invalid(key, value, f"file not found: {path}")
        return path


class Table:
    """One table of a Document (``name`` its dotted name; "" for the top level of the file):
    rejects unknown keys (``keys``, or later ``only``), reads typed values."""

    def __init__(self, doc: Document, name: str, data, keys=None):
        self.doc, self.name = doc, name
        if not isinstance(data, dict):
            doc.invalid(name, data, f"{name} must be a table [{name}]")
        self.data = data
        if keys is not None:
            self.only(keys)

    def only(self, keys):
        """Reject keys not in ``keys`` (call it later when the valid keys depend on a value)."""
        where = f"[{self.name}]" if self.name else "the file's top level"
        for key in self.data:
            if key not in keys:
                self.doc.fail(f"unknown key {self.dotted(key)}; valid keys in {where}: {', '.join(keys)}",
                              self.dotted(key))

    def dotted(self, key: str) -> str:
        return f"{self.name}.{key}" if self.name else key

    def has(self, key: str) -> bool:
        return key in self.data

    def table(self, key: str, keys=None) -> Table:
        """The sub-table ``key`` (empty if absent)."""
        return Table(self.doc, self.dotted(key), self.data.get(key, {}), keys)

    def invalid(self, key: str, why: str):
        self.doc.invalid(self.dotted(key), self.data[key], why)

    def raw(self, key: str, default, hint: str):
        """The value as read (``default`` if absent; REQUIRED: missing, ``hint`` says what it must be)."""
        if key in self.data:
            return self.data[key]
        if default is REQUIRED:
            self.doc.missing(self.dotted(key), hint)
        return default

    def number(self, key, default=REQUIRED, *, integer=False, ge=None, gt=None, lt=None):
        """A finite number (an int where ``integer``; else a float) with optional bounds."""
        kind = "an integer" if integer else "a number"
        low = f"{ge} <= " if ge is not None else f"{gt} < " if gt is not None else ""
        if lt is not None:
            hint = f"{key} must be {kind} with {low}{key} < {lt}"
        elif low:
            hint = f"{key} must be {kind} {'>=' if ge is not None else '>'} {ge if ge is not None else gt}"
        else:
            hint = f"{key} must be a finite number" if not integer else f"{key} must be an integer"
        value = self.raw(key, default, hint)
        if key not in self.data:
            return value
        if not (is_int(value) if integer else is_number(value)) or not math.isfinite(value):
            self.invalid(key, hint)
        if (ge is not None and value < ge) or (gt is not None and value <= gt) or (lt is not None and value >= lt):
            self.invalid(key, hint)
        return value if integer else float(value)

    def string(self, key, default=REQUIRED, *, choices=None, hint=None, valid=lambda value: True):
        """A string, one of ``choices`` if given, for which ``valid(value)`` holds if given."""
        hint = hint or (f"{key} must be one of {', '.join(map(json.dumps, choices))}" if choices
                        else f"{key} must be a string")
        value = self.raw(key, default, hint)
        if not isinstance(value, str) or (choices is not None and value not in choices) or not valid(value):
            self.invalid(key, hint)
        return value

    def numbers(self, key, default=REQUIRED, *, length=None, integer=False, hint):
        """A list of finite numbers (ints where ``integer``, else floats) of exactly ``length``
        if given, else non-empty, as a tuple."""
        value = self.raw(key, default, hint)
        if key not in self.data:
            return value
        ok = isinstance(value, list) and len(value) > 0 and (length is None or len(value) == length)
        check = is_int if integer else is_number
        if not ok or not all(check(v) and math.isfinite(v) for v in value):
            self.invalid(key, hint)
        return tuple(value) if integer else tuple(float(v) for v in value)


# ----------------------------------------------------------------------------- writing


def toml_text(doc: dict, header: str = "") -> str:
    """TOML text of a document of tables, numbers, strings, booleans, paths and (nested)
    arrays: plain keys first, then each table in order (``[a.b]`` for sub-tables), with
    ``header`` as leading comment lines. The one TOML writer (cards, study blocks, tests);
    tomli-w would write every array one number a line, which makes a card's curves
    unreadable."""
    lines = [f"# {line}" for line in header.splitlines()]

    def emit(table: dict, prefix: str):
        for key, value in table.items():
            if not isinstance(value, dict):
                lines.append(f"{key} = {toml_value(value)}")
        for key, value in table.items():
            if isinstance(value, dict):
                name = f"{prefix}{key}"
                if any(not isinstance(v, dict) for v in value.values()) or not value:
                    lines.extend(["", f"[{name}]"] if lines else [f"[{name}]"])
                emit(value, name + ".")

    emit(doc, "")
    return "\n".join(lines) + "\n"


def toml_value(value) -> str:
    """TOML text of one value (a number, string, boolean, path or nested array)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return repr(float(value))  # inf and nan are TOML too
    if isinstance(value, (str, Path)):
        return json.dumps(str(value), ensure_ascii=False)  # JSON's escapes are TOML basic-string escapes
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML for {value!r}")



def temporary_path(path, *, keep_suffix: bool = True) -> Path:
    """Where write_atomic writes ``path`` first: ``a.part.vtu`` beside ``a.vtu`` (the suffix
    kept, as meshio and ezdxf pick the format from it), or ``a.nc.part`` (``keep_suffix``
    False: a ``*.nc`` glob never sees an unfinished file)."""
    path = Path(path)
    return path.with_name(f"{path.stem}.part{path.suffix}" if keep_suffix else f"{path.name}.part")


def claim(tmp) -> None:
    """Make the temporary path ``tmp`` a new empty file of this writer: whatever is there
    (a killed writer's file, or a symbolic link planted to redirect the write outside the
    folder) is removed, never followed, and the file is created with O_EXCL|O_NOFOLLOW.
    The rename that follows replaces a link at the target, not the file it points to."""
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp)
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o666))


def check_unlinked(root, name: str) -> None:
    """OSError naming the first folder on the way from the run folder ``root`` to its file or
    folder ``name`` (``name`` included) that is a symbolic link: a run's own folders are
    written in place, and a link planted in a run (folders are copied and resumed) would
    send its files elsewhere. A link at a file's own name is harmless: the rename that
    puts the file in place replaces the link."""
    path = Path(root)
    for part in Path(name).parts:
        path = path / part
        if path.is_symlink() and path.is_dir():
            raise OSError(errno.ELOOP, "a symbolic link to a folder inside the run: a run's own folders are written "
                                       "in place, never through a link; remove the link", str(path))


def write_atomic(path, write: Callable[[Path], object], *, keep_suffix: bool = True) -> Path | None:
    """Have ``write(tmp)`` write the file to a temporary path beside ``path`` (see
    temporary_path; made by claim), then rename it into place, so ``path`` exists only
    complete and an old ``path`` stays until the new one is whole. Any failure (an interrupt too) removes
    the temporary file and is re-raised. ``write`` returning False (exactly) drops the
    finished file and returns None; else returns ``path``. Creates the parent folder."""
    path = Path(path)
    tmp = temporary_path(path, keep_suffix=keep_suffix)
    path.parent.mkdir(parents=True, exist_ok=True)
    claim(tmp)
    try:
        if write(tmp) is False:
            tmp.unlink(missing_ok=True)
            return None
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_text_atomic(path, text: str, *, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (see write_atomic)."""
    return write_atomic(path, lambda tmp: tmp.write_text(text, encoding=encoding))


def write_all(writers: dict[Path, Callable[[Path], None]]) -> list[Path]:
    """Several files, all or nothing: each ``writer(tmp)`` writes its temporary file beside
    its target; only when all have succeeded is each renamed into place; if any fails,
    every temporary file is removed and the error re-raised, so no target is written.
    Returns the target paths."""
    done = []
    try:
        for target, writer in writers.items():
            target = Path(target)
            target.parent.mkdir(parents=True, exist_ok=True)
            tmp = temporary_path(target)
            claim(tmp)
            done.append((tmp, target))
            writer(tmp)
    except BaseException:
        for tmp, _ in done:
            tmp.unlink(missing_ok=True)
        raise
    for tmp, target in done:
        os.replace(tmp, target)
    return [target for _, target in done]
