"""The local worker processes of a run, ready to drape as soon as they start.

* Workers are forked from a forkserver (where the platform has one; else spawned) that
  imported the drape engine (``PRELOAD``) once: a new worker does not import numpy, scipy,
  xarray, dask and numba again or set up numba's target (some 3 CPU-seconds each), only
  loads the cached kernels it calls. The forkserver lives as long as the Python process that started it, so
  successive runs, designs and calibration rounds from one Python session start their
  pools warm; :func:`prepare` starts it early, so that its imports overlap the caller's
  (``uqdrape run`` calls it before it imports anything heavy).
* :func:`local_pool`: the local worker processes of a run. Each worker dies with the
  process that started the run (a SIGKILL of ``uqdrape run``, the OOM killer, a closed
  batch job): on Linux the kernel kills it at once when its parent (the run, or the
  forkserver, which the kernel kills with the run's thread that started it) dies
  (``PR_SET_PDEATHSIG``);
  elsewhere it watches its parent's pid and exits within WATCH_INTERVAL. Once orphaned,
  whatever a worker writes to stderr is dropped, so it never prints a BrokenPipeError
  traceback. Workers ignore SIGINT (the run's own process handles Ctrl-C for all of
  them), and an interrupted or failed run terminates its workers instead of waiting for
  their chunks. :func:`orphaned` tells a worker not to commit a chunk file after its run
  has gone. multiprocessing's resource tracker (the process that removes the pool's
  semaphores) would warn of "leaked semaphore objects" after a SIGKILL; it reads
  PYTHONWARNINGS when it starts, which the CLI sets to ignore (``uqdrape.cli``), and
  removes them either way.

Only the standard library is imported here: the CLI calls :func:`prepare` first thing.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import multiprocessing.forkserver
import os
import signal
import sys
import threading
import time
from pathlib import Path

#: What the forkserver imports once for all the workers it forks (``uqdrape._forkserver``:
#: what ties its life to the run's, then the whole drape engine, warmed up).
PRELOAD = ["uqdrape._forkserver"]
#: How often a worker checks that its run is alive where the kernel cannot be asked to
#: kill it with its run (s).
WATCH_INTERVAL = 0.2
#: Linux prctl option: the signal a process gets when the thread that started it dies.
PR_SET_PDEATHSIG = 1

_run: int | None = None  # in a worker: pid of the run that started it
_parent: int | None = None  # in a worker: pid of its parent (the run, or the run's forkserver)


def _context():
    """The start method's context: the forkserver, preloaded, where there is one."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    return context


def prepare() -> None:
    """Start the forkserver (if not running), which then imports ``PRELOAD`` while the
    caller goes on; nothing where workers are spawned."""
    if _context().get_start_method() == "forkserver":
        multiprocessing.forkserver.ensure_running()


def _watch_parent(run: int) -> None:
    """Worker initializer: remember the run's pid and this worker's parent, die with
    them, leave Ctrl-C to the run."""
    global _run, _parent
    _run, _parent = run, os.getppid()
    _release_forkserver()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    sys.stderr = _OrphanMuted(sys.stderr)
    if die_with_parent():
        if orphaned():  # the run died before the kernel was asked
            os._exit(1)
        return

    def watch():
        while not orphaned():
            time.sleep(WATCH_INTERVAL)
        os._exit(1)

    threading.Thread(target=watch, name="uqdrape-parent-watch", daemon=True).start()


def _release_forkserver() -> None:
    """Close a forked worker's copy of the write end of the run's pipe to the forkserver
    (multiprocessing hands it to every worker it forks): the forkserver exits when that
    pipe closes, so it must close when the run dies, not when its last worker does."""
    server = multiprocessing.forkserver._forkserver
    if server._forkserver_alive_fd is not None and _parent != _run:
        os.close(server._forkserver_alive_fd)
        server._forkserver_alive_fd = None


def die_with_parent() -> bool:
    """Ask the kernel to SIGKILL this process when the thread that started it dies (Linux;
    local_pool's opening thread, or the forkserver's only thread). False where it cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        return ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _parent_of(pid: int) -> int | None:
    """The parent pid of process ``pid`` (Linux's /proc), None where it cannot be read."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_bytes()
    except OSError:
        return None
    return int(stat[stat.rindex(b")") + 2:].split()[1])  # after "pid (name)": state, ppid


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
    """True in a worker process whose run has died (False outside local workers): its
    parent has gone, or its parent is the forkserver and no longer the run's child."""
    if _parent is None:
        return False
    if os.getppid() != _parent:
        return True
    return _parent != _run and _parent_of(_parent) not in (_run, None)


@contextlib.contextmanager
def local_pool(workers: int | None):
    """A pool of ``workers`` processes (default: one per CPU) tied to this process."""
    pool = _context().Pool(workers or os.cpu_count(), initializer=_watch_parent, initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        pool.terminate()
        pool.join()
        raise
    pool.close()
    pool.join()
