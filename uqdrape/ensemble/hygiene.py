"""A run's processes and its claim on an output folder, so that nothing outlives the run.

* :func:`local_pool`: the local worker processes of a run. Each worker watches the pid of
  the process that started it and exits within half a second of losing it (a SIGKILL of
  ``uqdrape run``, the OOM killer, a closed batch job), ignores SIGINT (the run's own
  process handles Ctrl-C for all of them), and an interrupted or failed run terminates
  its workers instead of waiting for their chunks. :func:`orphaned` tells a worker not to
  commit a chunk file after its run has gone.
* :func:`run_lock`: one run per output folder. The lock file records pid, host and start
  time, and is created whole (written beside, then hard-linked into place: there is no
  moment at which it exists empty); a lock whose process is gone on this host is stale
  and taken over, a live one refuses the second run naming the first, and a lock from
  another host, or one that is not a lock uqdrape wrote, is refused, not guessed about.
  Taken before anything in the folder is touched, so ``--no-resume`` never deletes what
  another live run is writing.
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


#: Largest process id a lock may name (Linux's pid_max ceiling, 2^22).
MAX_PID = 2**22


def _owner(path: Path) -> dict | None:
    """The run a lock file names: {pid, host, started}, or None if the file is not a lock
    uqdrape wrote (hand-edited, truncated, another program's)."""
    try:
        owner = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    ok = (isinstance(owner, dict) and isinstance(owner.get("pid"), int) and not isinstance(owner["pid"], bool)
          and 0 < owner["pid"] <= MAX_PID and isinstance(owner.get("host"), str)
          and isinstance(owner.get("started"), str))
    return owner if ok else None


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
def run_lock(out: Path):
    """Hold ``out/run.lock`` for the duration of a run; raise RunLocked if a live run holds it."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK
    host = socket.gethostname()
    me = {"pid": os.getpid(), "host": host, "started": time.strftime("%Y-%m-%d %H:%M:%S %Z")}
    mine = out / f".{LOCK}.{os.getpid()}.{threading.get_ident()}"
    mine.write_text(json.dumps(me), encoding="utf-8")
    try:
        while True:
            try:
                os.link(mine, path)  # atomic, and the lock has its content from its first moment
                break
            except FileExistsError:
                pass
            owner = _owner(path)
            if owner is None:
                raise RunLocked(errno.EBUSY, f"{LOCK} is not a lock uqdrape wrote; delete it if no run is writing "
                                "to this folder", str(out)) from None
            if owner["host"] != host or _alive(owner["pid"]):
                raise RunLocked(errno.EBUSY, f"another run (pid {owner['pid']} on {owner['host']}, started "
                                f"{owner['started']}) is writing to this folder; wait for it, or use another "
                                f"--out (delete {LOCK} only if that run is certainly gone)", str(out)) from None
            path.unlink(missing_ok=True)  # stale: its run on this host is gone
    finally:
        mine.unlink(missing_ok=True)
    try:
        yield
    finally:
        path.unlink(missing_ok=True)
