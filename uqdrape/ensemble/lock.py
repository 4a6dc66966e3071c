"""A run's claim on an output folder (its worker processes: ``uqdrape.pool``).

* :func:`hold_lock`: one run per output location (a folder's :func:`run_lock`, a store's
  ``ZarrStore.lock``). The lock records pid, host and start time, and is created whole
  (a folder's written beside, then hard-linked into place: there is no moment at which it
  exists empty; a store's by exclusive create); a lock whose process is gone on this host
  is stale and taken over, a live one refuses the second run naming the first, and a lock
  from another host, or one that is not a lock uqdrape wrote, is refused, not guessed
  about. Taken before anything in the location is touched, so a run without resuming
  never deletes what another live run is writing.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import socket
import tempfile
import threading
import time
from pathlib import Path

from ..errors import naming


#: The lock of a run, in a folder or a store alike.
LOCK = "run.lock"


class RunLocked(OSError):
    """Another live run writes to the output folder."""


#: Largest process id a lock may name (Linux's pid_max ceiling, 2^22).
MAX_PID = 2**22


def lock_record() -> dict:
    """What a lock says of the run holding it: {pid, host, started}."""
    return {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S %Z")}


def lock_owner(text) -> dict | None:
    """The run a lock's text (str or bytes) names: {pid, host, started}, or None if it is
    not a lock uqdrape wrote (hand-edited, truncated, another program's)."""
    try:
        owner = json.loads(text)
    except (ValueError, RecursionError):
        return None
    ok = (isinstance(owner, dict) and isinstance(owner.get("pid"), int) and not isinstance(owner["pid"], bool)
          and 0 < owner["pid"] <= MAX_PID and isinstance(owner.get("host"), str)
          and isinstance(owner.get("started"), str))
    return owner if ok else None


def stale(owner: dict) -> bool:
    """Whether the run a lock names is gone: its process was on this host and is not
    running (a lock from another host is never guessed about)."""
    return owner["host"] == socket.gethostname() and not _alive(owner["pid"])


def _alive(pid: int) -> bool:
    """Whether process ``pid`` of this host may still be running."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@contextlib.contextmanager
def hold_lock(where, kind: str, create, read, remove):
    """Hold the lock of the run at ``where`` (a ``kind``: "folder", "store") for the block:
    ``create(record)`` makes the lock whole with the bytes given, or raises
    FileExistsError if one exists; ``read()`` its bytes; ``remove()`` deletes it. An
    existing lock of a run gone from this host is taken over (once): inside
    :func:`_takeover`, which one process of this host at a time enters, it is removed only
    if it still is the stale lock read before, so two runs that found the same stale lock
    cannot both remove it and take the location (only runs of this host judge a lock
    stale, so a host-local section is enough). A live run's lock, one from another host,
    or one uqdrape did not write raise RunLocked naming ``where``."""
    taken = False
    while True:
        with contextlib.suppress(FileExistsError):  # else: whose is it, and is it stale?
            create(json.dumps(lock_record()).encode())
            break
        try:
            owner = lock_owner(read())
        except OSError:
            owner = None
        if owner is None:
            raise RunLocked(errno.EBUSY, f"{LOCK} is not a lock uqdrape wrote; delete it if no run is writing "
                            f"to this {kind}", str(where)) from None
        if taken or not stale(owner):
            raise naming(RunLocked(errno.EBUSY, f"another run holds {LOCK} of this {kind} (pid {owner['pid']} "
                                   f"on {owner['host']}, started {owner['started']}); wait for it, or write "
                                   f"elsewhere (delete {LOCK} only if that run is certainly gone)", str(where)),
                         "output_dir") from None
        with _takeover(where):
            try:
                still = lock_owner(read()) == owner
            except OSError:  # gone: another run took it over and has not made its own yet
                still = False
            if still:
                remove()  # stale: its run on this host is gone
        taken = True
    try:
        yield
    finally:
        remove()


@contextlib.contextmanager
def _takeover(where):
    """A section one process of this host at a time enters for the location ``where`` (a
    folder, resolved, or a store URL): flock on a file of the temporary folder named by its
    hash (the file is kept: removing it would let two holders lock two different files)."""
    key = str(where.resolve()) if isinstance(where, Path) else str(where)
    name = hashlib.sha256(key.encode()).hexdigest()[:32]
    fd = os.open(Path(tempfile.gettempdir()) / f"uqdrape-takeover-{name}", os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def run_lock(out: Path):
    """Hold ``out/run.lock`` for the duration of a run (:func:`hold_lock`), created whole:
    written beside, then hard-linked into place, so it never exists empty."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK

    def create(record: bytes):
        mine = out / f".{LOCK}.{os.getpid()}.{threading.get_ident()}"
        mine.write_bytes(record)
        try:
            os.link(mine, path)  # atomic, and the lock has its content from its first moment
        finally:
            mine.unlink(missing_ok=True)

    return hold_lock(out, "folder", create, path.read_bytes, lambda: path.unlink(missing_ok=True))
