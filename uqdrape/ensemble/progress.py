"""Progress of a run counted in realisations (or a single drape's rings), with an ETA.

On a terminal a tqdm bar; anywhere else (a log file, CI) a plain line in tqdm's format
at the start, every ``PLAIN_EVERY`` seconds and at the end, so logs hold no carriage returns.
"""

from __future__ import annotations

import sys
import time

from tqdm import tqdm

#: Seconds between the plain lines written when the output is not a terminal.
PLAIN_EVERY = 30.0


class Progress:
    """Realisations drawn ``total`` (``done`` of them already finished by an earlier run).

    ``update(n, name)`` counts n more; with ``verbose`` the finished chunk ``name`` gets a
    line of its own. Nothing is written when ``enabled`` is False. Off a terminal the
    last line (at ``total``) is written only with ``last_line``, so that a short count
    (a single drape's rings) leaves stderr to the command's one-line errors."""

    def __init__(self, total: int, done: int = 0, *, enabled: bool = True, verbose: bool = False,
                 desc: str = "realisations", unit: str = "real", last_line: bool = True, file=None):
        self.file = file or sys.stderr
        self.tty = self.file.isatty()
        self.enabled, self.verbose, self.desc, self.unit, self.last_line = enabled, verbose, desc, unit, last_line
        self.total, self.n, self.start_n = total, done, done
        self.start = self.last = time.monotonic()
        self.bar = tqdm(total=total, initial=done, desc=desc, unit=unit, file=self.file, mininterval=0.5,
                        disable=not (enabled and self.tty))
        if enabled and not self.tty and last_line:  # a log sees the run start at once, not after PLAIN_EVERY s
            print(tqdm.format_meter(done, total, 0.0, prefix=desc, unit=unit, initial=done), file=self.file, flush=True)

    def update(self, n: int, name: str | None = None) -> None:
        self.n += n
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
            rate = (self.n - self.start_n) / max(now - self.start, 1e-9)
            line = tqdm.format_meter(self.n, self.total, now - self.start, prefix=self.desc, unit=self.unit, rate=rate,
                                     initial=self.start_n)
            print(line, file=self.file, flush=True)

    def close(self) -> None:
        self.bar.close()
