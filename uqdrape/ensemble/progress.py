"""Progress of a run counted in realisations (or a single drape's rings), with an ETA.

On a terminal a tqdm bar; anywhere else (a log file, CI) a plain line in tqdm's format
at the start, every ``PLAIN_EVERY`` seconds and at the end, so logs hold no carriage returns.
The rate, and so the ETA, is that of finished work only; a single drape first says when its
kernels must be compiled, and its rate leaves out the first ring, which carries the compiling.
"""

from __future__ import annotations

import sys
import time

from tqdm import tqdm

from ..drape.solver import COMPILE_S, compile_pending

#: Seconds between the plain lines written when the output is not a terminal.
PLAIN_EVERY = 30.0


class _Bar(tqdm):
    """A tqdm bar whose rate (units/s; 0 shows no ETA) is the ``rate`` callable's."""

    def __init__(self, *args, rate, **kwargs):
        self.rate = rate
        super().__init__(*args, **kwargs)

    @property
    def format_dict(self):
        return {**super().format_dict, "rate": self.rate()}


class Progress:
    """Realisations drawn ``total`` (``done`` of them already finished by an earlier run).

    ``update(n, name)`` counts n more; with ``verbose`` the finished chunk ``name`` gets a
    line of its own. Nothing is written when ``enabled`` is False. Off a terminal the
    last line (at ``total``) is written only with ``last_line``, so that a short count
    (a single drape's rings) leaves stderr to the command's one-line errors. The rate is
    units finished over the time they took, up to the last update; with ``startup`` it
    starts at the first update, whose unit carried one-off work (compiling the kernels),
    so no ETA is shown before two updates. As a context manager it closes on leaving."""

    def __init__(self, total: int, done: int = 0, *, enabled: bool = True, verbose: bool = False,
                 desc: str = "realisations", unit: str = "real", last_line: bool = True, startup: bool = False,
                 file=None):
        self.file = file or sys.stderr
        self.tty = self.file.isatty()
        self.enabled, self.verbose, self.desc, self.unit, self.last_line = enabled, verbose, desc, unit, last_line
        self.total, self.n, self.start_n = total, done, done
        self.began = self.start = self.last = self.updated = time.monotonic()
        self.startup = startup
        self.bar = _Bar(total=total, initial=done, desc=desc, unit=unit, file=self.file, mininterval=0.5,
                        disable=not (enabled and self.tty), rate=self.rate)
        if enabled and not self.tty and last_line:  # a log sees the run start at once, not after PLAIN_EVERY s
            print(tqdm.format_meter(done, total, 0.0, prefix=desc, unit=unit, initial=done), file=self.file, flush=True)

    def rate(self) -> float:
        """Units per second finished since the rate's start, up to the last update; 0 (tqdm
        then shows no ETA) before any."""
        done = self.n - self.start_n
        return done / (self.updated - self.start) if done > 0 and self.updated > self.start else 0.0

    def update(self, n: int, name: str | None = None) -> None:
        self.n += n
        self.updated = time.monotonic()
        if self.startup:  # the rate starts here, after the unit that carried the one-off work
            self.startup, self.start, self.start_n = False, self.updated, self.n
        if not self.enabled:
            return
        if self.verbose and name:
            self.bar.write(f"finished {name}", file=self.file)
        if self.tty:
            self.bar.update(n)
            return
        now = time.monotonic()
        if now - self.last >= PLAIN_EVERY or (self.last_line and self.n >= self.total):
            self.last = now
            line = tqdm.format_meter(self.n, self.total, now - self.began, prefix=self.desc, unit=self.unit,
                                     rate=self.rate(), initial=self.start_n)
            print(line, file=self.file, flush=True)

    def close(self) -> None:
        self.bar.close()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def announce_compiling(mode: str, enabled: bool = True, file=None, prefix: str = "") -> None:
    """Say on ``file`` (stderr) that drapes in ``mode`` will first compile their kernels,
    and about how long it takes, while they are still to be compiled
    (``drape.solver.compile_pending``: not in this process, not in numba's disk cache,
    which a run's local workers share)."""
    if enabled and compile_pending(mode):
        print(f"{prefix}compiling the drape kernels (once, about {COMPILE_S[mode]} s)", file=file or sys.stderr,
              flush=True)


def ring_progress(rings: int, mode: str, enabled: bool = True, file=None) -> Progress:
    """The ring counter of a single drape in ``mode`` (a ``Progress`` of ``rings``, its rate
    from the first ring on), announced, while that mode's kernels are still to be compiled
    (``drape.solver.compile_pending``), by a line saying so and about how long it takes:
    otherwise the counter stands at ring 0 for that long with nothing said."""
    file = file or sys.stderr
    announce_compiling(mode, enabled, file)
    return Progress(rings, enabled=enabled, desc="ring", unit="ring", last_line=False, startup=True, file=file)
