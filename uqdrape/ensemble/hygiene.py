"""A run's processes and its claim on an output folder, so that nothing outlives the run.

* :func:`local_pool`: the local worker processes of a run. Each worker watches the pid of
  the process that started it and exits within half a second of losing it (a SIGKILL of
  ``uqdrape run``, the OOM killer, a closed batch job), ignores SIGINT (the run's own
  process handles Ctrl-C for all of them), and an interrupted or failed run terminates
  its workers instead of waiting for their chunks. :func:`orphaned` tells a worker not to
  commit a chunk file after its run has gone.
* :func:`run_lock`: one run per output folder. The lock file records pid, host and start
  time; a lock whose process is gone on this host is stale and taken over, a live one
  refuses the second run naming the first. Taken before anything in the folder is
  touched, so ``--no-resume`` never deletes what another live run is writing.
"""

from __future__ import annotations

import contextlib
import errno
import json
import multiprocessing
import os
import signal
import socket
import threading
import time
from pathlib import Path

#: The lock file in a run folder.
LOCK = "run.lock"
#: How often a worker checks that its run is alive (s).
WATCH_INTERVAL = 0.5

_parent: int | None = None  # pid of the run that started this worker process


def _watch_parent(parent: int) -> None:
    """Worker initializer: remember the run's pid, exit when it is gone, leave Ctrl-C to it."""
    global _parent
    _parent = parent
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch():
        while not orphaned():
            time.sleep(WATCH_INTERVAL)
        os._exit(1)

    threading.Thread(target=watch, name="uqdrape-parent-watch", daemon=True).start()


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


def _alive(owner: dict) -> bool:
    """Whether the lock's owner may still be running (on another host we cannot tell)."""
    if owner.get("host") != socket.gethostname():
        return True
    try:
        os.kill(int(owner["pid"]), 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@contextlib.contextmanager
def run_lock(out: Path):
    """Hold ``out/run.lock`` for the duration of a run; raise RunLocked if a live run holds it."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK
    me = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S %Z")}
    while True:
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            try:
                owner = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                owner = {}  # unreadable or half-written: its writer died at once
            if owner and _alive(owner):
                raise RunLocked(errno.EBUSY, f"another run (pid {owner['pid']} on {owner['host']}, started "
                                f"{owner['started']}) is writing to this folder; wait for it, or use another "
                                f"--out (delete {LOCK} only if that run is certainly gone)", str(out)) from None
            path.unlink(missing_ok=True)  # stale: its run is gone
            continue
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(me, fh)
        break
    try:
        yield
    finally:
        path.unlink(missing_ok=True)
