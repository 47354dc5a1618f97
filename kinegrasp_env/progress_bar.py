"""A progress bar for long runs that also reports where no terminal watches.

:func:`progress_bar` gives tqdm's bar on a terminal. Elsewhere (a log file, a pipe, a cluster
job's output) tqdm shows nothing, so it gives :class:`LineBar` instead: one plain line at most
every :data:`LINE_INTERVAL` seconds (``sweep: 12/40 tasks (30%), 00:47``) and, after a run
that printed one, one at the end (``sweep: 40/40 tasks (100%), done in 02:31``): a run shorter
than that prints nothing, as before. Both take the same calls: ``update(k)``, ``n``, ``total``
(settable), ``close()``, iteration over an iterable.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterable, Iterator
from typing import TextIO

#: Seconds between two progress lines off a terminal.
LINE_INTERVAL = 10.0


def clock_text(seconds: float) -> str:
    """``mm:ss`` (``h:mm:ss`` from an hour on)."""
    seconds = round(max(0.0, seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes:02d}:{secs:02d}"


class LineBar:
    """tqdm's calls, reported as plain lines (module docstring).

    Args:
        iterable: items to iterate over while counting them (optional).
        total: the count of work units (None: unknown; ``len(iterable)`` where it has one).
        desc: what runs, the start of every line; unit: what a unit is called.
        initial: units done already.
        stream: where the lines go (default stderr).
        interval: least seconds between two lines before the last.
        clock: seconds (monotonic), for tests.
    """

    def __init__(self, iterable: Iterable | None = None, *, total: int | None = None,
                 desc: str = "", unit: str = "it", initial: int = 0,
                 stream: TextIO | None = None, interval: float = LINE_INTERVAL,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.iterable = iterable
        if total is None and iterable is not None and hasattr(iterable, "__len__"):
            total = len(iterable)
        self.total, self.desc, self.unit = total, desc, unit
        self.n = int(initial)
        self.stream = sys.stderr if stream is None else stream
        self.interval, self.clock = float(interval), clock
        self.start = self.last = clock()
        self.closed = False
        self.lines = 0  # progress lines printed

    def __iter__(self) -> Iterator:
        for item in self.iterable:
            yield item
            self.update(1)
        self.close()

    def _counted(self) -> str:
        units = self.unit + ("" if self.unit.endswith("s") else "s")
        if self.total is None:
            return f"{self.n} {units}"
        share = f" ({100 * self.n / self.total:.0f}%)" if self.total else ""
        return f"{self.n}/{self.total} {units}{share}"

    def update(self, k: int = 1) -> None:
        """``k`` more units done; a line where :attr:`interval` has passed since the last."""
        self.n += int(k)
        now = self.clock()
        if now - self.last >= self.interval:
            self.last = now
            self.lines += 1
            print(f"{self.desc}: {self._counted()}, {clock_text(now - self.start)}",
                  file=self.stream, flush=True)

    def close(self) -> None:
        """The last line (once, where a progress line came before it): what was done and in
        how long."""
        if self.closed:
            return
        self.closed = True
        if not self.lines:
            return
        print(f"{self.desc}: {self._counted()}, done in "
              f"{clock_text(self.clock() - self.start)}", file=self.stream, flush=True)


def progress_bar(iterable: Iterable | None = None, *, total: int | None = None,
                 desc: str = "", unit: str = "it", initial: int = 0,
                 stream: TextIO | None = None, enabled: bool = True):
    """A bar of ``total`` units (tqdm's arguments): tqdm's on a terminal, a
    :class:`LineBar` elsewhere; ``enabled=False``: tqdm's, silent."""
    from tqdm import tqdm

    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    if not enabled or (isatty is not None and isatty()):
        return tqdm(iterable, total=total, desc=desc, unit=unit, initial=initial, file=stream,
                    disable=not enabled)
    return LineBar(iterable, total=total, desc=desc, unit=unit, initial=initial,
                   stream=stream, interval=LINE_INTERVAL)
