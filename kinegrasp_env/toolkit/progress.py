"""One overall progress report for a long command made of cells (evaluations, rounds).

On a terminal: one bar for the whole command (the cell being worked on, draws done of the
total, draws per second, an ETA). Elsewhere (a log file, a pipe): no bar, one plain line per
finished cell, e.g. ``table1: cell 3/20 spray_flask grasp 0 sigma 0.0133: P(FC) 0.980,
410 draws/s, ETA 05:12``.

The rate and the ETA leave the start-up out (worker pool, compiled kernels, engines): they
are measured between reports of finished work, over the later half of the time since the
first report (the warm-up of workers that start late falls out too) and never over less than
:data:`MIN_WINDOW` seconds (work that comes back at once, e.g. results found already done,
would otherwise read as millions of draws per second); until then the line says the rate is
being measured. A total revised on the way (an adaptive run that stops early) is shown with
the first one (``20500/20500 draws (down from 24000)``).
"""

from __future__ import annotations

import bisect
import math
import sys
import time
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from typing import TextIO

from kinegrasp_env.progress_bar import clock_text

#: Shortest span of reports (seconds) a rate is measured over.
MIN_WINDOW = 1.0


def format_eta(seconds: float | None) -> str:
    """``mm:ss`` (``h:mm:ss`` from an hour on), ``?`` when unknown."""
    if seconds is None or not math.isfinite(seconds):
        return "?"
    return clock_text(seconds)


class Progress:
    """Progress of ``total`` draws split into ``cells`` cells.

    Args:
        name: the command, the first word of every line (``table1``, ``rank``).
        total: draws in the whole command (may be revised with :meth:`advance`).
        cells: number of cells.
        word: what a cell is called in the report (``cell``, ``round``).
        stream: where to write (default stderr).
        interactive: a bar (True) or plain lines (False); default: whether ``stream`` is a
            terminal.
        clock: seconds (monotonic), for tests.
    """

    def __init__(self, name: str, total: int, cells: int, *, word: str = "cell",
                 stream: TextIO | None = None, interactive: bool | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.name = name
        self.word = word
        self.total = int(total)
        self.most = self.total  # the first total: what a revised one is shown against
        self.cells = int(cells)
        self.stream = sys.stderr if stream is None else stream
        if interactive is None:
            isatty = getattr(self.stream, "isatty", None)
            interactive = bool(isatty and isatty())
        self.clock = clock
        self.times: list[float] = []  # when each report of new work came
        self.history: list[int] = []  # draws done at each report
        self.done = 0
        self.cells_done = 0
        self.cell_start = 0  # draws done when the current cell began
        self.bar = self._bar() if interactive else None

    def _bar(self):
        from tqdm import tqdm

        class Bar(tqdm):
            """tqdm with our status text (``{status}``) in place of its own rate and ETA."""

            status = ""

            @property
            def format_dict(self) -> dict:
                return {**super().format_dict, "status": self.status}

        return Bar(total=self.total, file=self.stream, desc=self._desc(),
                   bar_format="{desc} {percentage:3.0f}%|{bar}| {status}",
                   dynamic_ncols=True, mininterval=0.2)

    def _desc(self, working: bool = True) -> str:
        """``name: cell k/n``: the cell being worked on (or, at the end, the last one)."""
        k = min(self.cells_done + 1, self.cells) if working else self.cells_done
        return f"{self.name}: {self.word} {k}/{self.cells}"

    # ------------------------------------------------------------------ measurements
    def rate(self) -> float | None:
        """Draws per second over the later half of the time since the first report, and over
        at least :data:`MIN_WINDOW` seconds (so the start-up, the warm-up of late-starting
        workers and work that came back at once fall out); None until the reports span
        that long, except for a run done within it over a tenth of it at least: its mean
        rate since the first report."""
        if len(self.times) < 2:
            return None
        whole = self.times[-1] - self.times[0]
        if self.done >= self.total and MIN_WINDOW / 10 <= whole < MIN_WINDOW:
            return (self.history[-1] - self.history[0]) / whole
        span = max(MIN_WINDOW, whole / 2)
        i = bisect.bisect_right(self.times, self.times[-1] - span) - 1
        if i < 0:
            return None
        elapsed = self.times[-1] - self.times[i]
        return (self.history[-1] - self.history[i]) / elapsed

    def eta(self) -> float | None:
        """Seconds left at the current rate (None while unknown)."""
        rate = self.rate()
        return None if not rate else (self.total - self.done) / rate

    def status(self) -> str:
        """``done/total draws, R draws/s, ETA mm:ss`` (``rate being measured`` until known;
        a revised total with the first one)."""
        draws = f"{self.done}/{self.total} draws"
        if self.total != self.most:
            draws += f" (down from {self.most})"
        rate = self.rate()
        if rate is None:
            return f"{draws}, rate being measured"
        return f"{draws}, {rate:.0f} draws/s, ETA {format_eta(self.eta())}"

    # ------------------------------------------------------------------ reports
    def advance(self, done: int, total: int | None = None) -> None:
        """Draws finished so far in the whole command (absolute); optionally a new total."""
        if total is not None:
            self.total = int(total)
        step, self.done = int(done) - self.done, int(done)
        if step > 0:
            self.times.append(self.clock())
            self.history.append(self.done)
        if self.bar is not None:
            self.bar.total = self.total
            self.bar.status = self.status()
            self.bar.update(step)

    def evaluation(self) -> Callable[[int, int], None]:
        """A ``progress(done, total)`` callback for one cell's evaluation (its own counts)."""
        self.cell_start = self.done

        def report(done: int, _total: int) -> None:
            self.advance(self.cell_start + done)

        return report

    def cell_done(self, text: str) -> None:
        """A cell finished: ``text`` says which and its result (``spray_flask grasp 0 sigma
        0.0133: P(FC) 0.980``)."""
        self.cells_done += 1
        self.cell_start = self.done
        if self.bar is not None:
            self.bar.set_description_str(self._desc(), refresh=True)
            return
        self.stream.write(f"{self.name}: {self.word} {self.cells_done}/{self.cells} {text}, "
                          f"{self.status()}\n")
        self.stream.flush()

    def add_cell(self, draws: int) -> None:
        """A cell not counted at the start (e.g. a direct evaluation a re-weighted batch falls
        back to): one more cell of ``draws`` draws in the totals."""
        self.cells += 1
        self.total += int(draws)
        self.most += int(draws)
        if self.bar is not None:
            self.bar.total = self.total
            self.bar.set_description_str(self._desc(), refresh=True)

    def finish_cell(self, draws: int, text: str) -> None:
        """A cell of ``draws`` draws finished at once (an evaluation that reports no draws on
        the way): its draws counted, then :meth:`cell_done`."""
        self.advance(self.cell_start + int(draws))
        self.cell_done(text)

    def close(self) -> None:
        """End the bar (the next line printed starts on a fresh line)."""
        if self.bar is not None:
            self.bar.status = self.status()
            self.bar.set_description_str(self._desc(working=False), refresh=False)
            self.bar.close()
            self.bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def reported_cell(report: Progress | None, draws: int, label: str, run: Callable):
    """One cell of ``draws`` draws on ``report`` (or on none): ``run(progress)``, called with
    the report's callback for the cell's chunks as they come back (None without a report),
    then the cell done, said as ``label: P(FC) p`` (the result's ``p_fc``). Returns what
    ``run`` returns."""
    result = run(None if report is None else report.evaluation())
    if report is not None:
        report.finish_cell(draws, f"{label}: P(FC) {result.p_fc:.3f}")
    return result


def cell_progress(enabled: bool, name: str, cells: int, samples: int,
                  total: int | None = None) -> AbstractContextManager[Progress | None]:
    """A :class:`Progress` of command ``name`` over ``cells`` cells of ``samples`` draws
    (``total`` draws in all where the cells differ in size), or nothing (``enabled``
    False)."""
    if not enabled:
        return nullcontext(None)
    return Progress(name, cells * samples if total is None else total, cells)
