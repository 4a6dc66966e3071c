"""A run's processes and its claim on an output folder, so that nothing outlives the run.

* :func:`local_pool`: the local worker processes of a run. Each worker dies with the
  process that started it (a SIGKILL of ``uqdrape run``, the OOM killer, a closed batch
  job): on Linux the kernel kills it at once (``PR_SET_PDEATHSIG``: the same moment its
  run's pipes close, so it never gets to print a BrokenPipeError traceback); elsewhere it
  watches its parent's pid and exits within WATCH_INTERVAL. Once orphaned, whatever a
  worker writes to stderr is dropped. Workers ignore SIGINT (the run's own process
  handles Ctrl-C for all of them), and an interrupted or failed run terminates its
  workers instead of waiting for their chunks. :func:`orphaned` tells a worker not to
  commit a chunk file after its run has gone. multiprocessing's resource tracker (the
  process that removes the pool's semaphores) would warn of "leaked semaphore objects"
  after a SIGKILL; it reads PYTHONWARNINGS when it starts, which the CLI sets to ignore
  (``uqdrape.cli``), and removes them either way.
* :func:`hold_lock`: one run per output location (a folder's :func:`run_lock`, a store's
  ``ZarrStore.lock``). The lock records pid, host and start time, and is created whole
  (a folder's written beside, then hard-linked into place: there is no moment at which it
  exists empty; a store's by exclusive create); a lock whose process is gone on this host
  is stale and taken over, a live one refuses the second run naming the first, and a lock
  from another host, or one that is not a lock uqdrape wrote, is refused, not guessed
  about. Taken before anything in the location is touched, so ``--no-resume`` never
  deletes what another live run is writing.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import json
import multiprocessing
import os
import signal
import socket
import sys
import threading
import time
from pathlib import Path

#: The lock file in a run folder.
LOCK = "run.lock"
#: How often a worker checks that its run is alive where the kernel cannot be asked to
#: kill it with its run (s).
WATCH_INTERVAL = 0.2
#: Linux prctl option: the signal a process gets when the thread that started it dies.
PR_SET_PDEATHSIG = 1

_parent: int | None = None  # pid of the run that started this worker process


def _watch_parent(parent: int) -> None:
    """Worker initializer: remember the run's pid, die with it, leave Ctrl-C to it."""
    global _parent
    _parent = parent
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    sys.stderr = _OrphanMuted(sys.stderr)
    if _die_with_parent():
        if orphaned():  # the run died before the kernel was asked
            os._exit(1)
        return

    def watch():
        while not orphaned():
            time.sleep(WATCH_INTERVAL)
        os._exit(1)

    threading.Thread(target=watch, name="uqdrape-parent-watch", daemon=True).start()


def _die_with_parent() -> bool:
    """Ask the kernel to SIGKILL this process when the thread that started it dies (Linux;
    local_pool's opening thread holds the pool for its whole life). False where it cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        return ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


class _OrphanMuted:
    """A worker's stderr that says nothing once its run is gone (the run's terminal is the
    user's, and the run can no longer explain what a dying worker prints)."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text):
        return len(text) if orphaned() else self._stream.write(text)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def orphaned() -> bool:
    """True in a worker process whose run has died (False outside local workers)."""
    return _parent is not None and os.getppid() != _parent


@contextlib.contextmanager
def local_pool(workers: int | None):
    """A pool of ``workers`` spawned processes (default: one per CPU) tied to this process."""
    pool = multiprocessing.get_context("spawn").Pool(workers or os.cpu_count(), initializer=_watch_parent,
                                                     initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        pool.terminate()
        pool.join()
        raise
    pool.close()
    pool.join()


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
    existing lock of a run gone from this host is taken over (once); a live run's, one
    from another host, or one uqdrape did not write raise RunLocked naming ``where``."""
    taken = False
    while True:
        try:
            create(json.dumps(lock_record()).encode())
            break
        except FileExistsError:
            pass
        try:
            owner = lock_owner(read())
        except OSError:
            owner = None
        if owner is None:
            raise RunLocked(errno.EBUSY, f"{LOCK} is not a lock uqdrape wrote; delete it if no run is writing "
                            f"to this {kind}", str(where)) from None
        if taken or not stale(owner):
            raise RunLocked(errno.EBUSY, f"another run holds {LOCK} of this {kind} (pid {owner['pid']} on "
                            f"{owner['host']}, started {owner['started']}); wait for it, or use another --out "
                            f"(delete {LOCK} only if that run is certainly gone)", str(where)) from None
        remove()  # stale: its run on this host is gone
        taken = True
    try:
        yield
    finally:
        remove()


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
