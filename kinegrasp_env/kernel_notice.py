"""Say so when the compiled kernels are being built, and show how far it has got.

The first run on a machine (or the first after an upgrade) compiles the package's numba
kernels once, which takes a while (``benchmarks/bench_coldstart.py`` times it): later runs
load them from the cache (:mod:`kinegrasp_env.jit`). Without a word that would look like
a hung command. The command line calls :func:`install` before it runs a command; then

* as soon as the kernel module is loaded (before any kernel compiles) and the cache holds no
  kernels of the current sources, one line on the stream says that the kernels are compiled
  once per machine and about how long it takes (as long as the last full compile here took,
  else :data:`TYPICAL_SECONDS`);
* while kernels compile (numba's own ``numba:compile`` event, which fires only on a cache
  miss), a line now and then (:data:`EVERY`) says how many have compiled and for how long;
* at exit, one line with the count and the time, also recorded (``compile_times.json`` next
  to the key folders) for the next estimate.

If the kernels' module was already loaded when :func:`install` was called (a process that
has used them), only compiles that really happen are reported. Nothing is printed when every
kernel comes from the cache.
"""

from __future__ import annotations

import atexit
import itertools
import json
import os
import sys
import threading
import time
from pathlib import Path
from typing import TextIO

from kinegrasp_env.lazy import when_imported

#: Seconds a full first compile of the kernels an evaluation needs takes on a 2-core machine
#: (``benchmarks/bench_coldstart.py``: first run on an empty cache), the estimate before this
#: machine has one of its own.
TYPICAL_SECONDS = 90.0
#: Seconds between progress lines while kernels compile: closer at first, then every 30 s.
EVERY = (5.0, 5.0, 10.0, 10.0, 30.0)
#: File (next to the key folders) with the last full compile's count and seconds.
RECORD = "compile_times.json"


def _fmt(seconds: float) -> str:
    """``m:ss``."""
    seconds = round(seconds)
    return f"{seconds // 60}:{seconds % 60:02d}"


def _about(seconds: float) -> str:
    """``40 seconds``, ``2 minutes``."""
    return f"{round(seconds)} seconds" if seconds < 90 else f"{round(seconds / 60)} minutes"


class CompileReport:
    """Counts the package's kernel compiles (numba events) and reports them on ``stream``."""

    def __init__(self, stream: TextIO | None, cache: Path, cold: bool) -> None:
        self._stream, self.cache, self.cold = stream, cache, cold
        self.pid = os.getpid()  # a pool worker forked from this process reports as one
        self.start: float | None = None
        self.count = 0
        self.current = ""
        self.last_line = 0.0
        self.lock = threading.Lock()
        self.noticed = False
        self.estimate = self._estimate()

    def say(self, line: str) -> None:
        """Write one line (to stderr as it is now, unless a stream was given); a closed or
        broken stream is not this report's business."""
        try:
            print(line, file=self._stream or sys.stderr, flush=True)
        except (OSError, ValueError):
            pass

    # ------------------------------------------------------------------ the estimate
    def _record_file(self) -> Path:
        return self.cache.parent / RECORD

    def _estimate(self) -> tuple[float, int | None]:
        try:
            data = json.loads(self._record_file().read_text())
            return float(data["seconds"]), int(data["kernels"])
        except (OSError, ValueError, KeyError, TypeError):
            return TYPICAL_SECONDS, None

    def notice(self) -> None:
        """The one line that says what is happening and about how long it takes."""
        if self.noticed:
            return
        self.noticed = True
        seconds, kernels = self.estimate
        where = "last time on this machine" if kernels is not None else "on a 2-core machine"
        self.say(f"kinegrasp: the numerical kernels are compiled on first use, once per "
                 f"machine (about {_about(seconds)} {where}); later runs load them from "
                 f"{self.cache.parent}")

    # ------------------------------------------------------------------ numba's events
    def on_start(self, event) -> None:
        dispatcher = event.data.get("dispatcher")
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
        if not module.startswith("kinegrasp_env"):
            return
        if os.getpid() != self.pid:  # a forked pool worker: its own lock, count and clock
            self.lock = threading.Lock()  # (the parent's may have been held at the fork)
            self.pid, self.start, self.count = os.getpid(), None, 0
            self.noticed = True  # the command's own process said it
        with self.lock:
            if self.start is None:
                self.start = time.monotonic()
                self.last_line = self.start
                self.notice()
                self._tick()
            self.count += 1
            self.current = f"{module.removeprefix('kinegrasp_env.')}.{dispatcher.py_func.__name__}"

    def on_end(self, event) -> None:
        pass

    def _tick(self) -> None:
        """A daemon thread that writes a progress line after each pause of :data:`EVERY`."""
        def run() -> None:
            for k in itertools.count():
                time.sleep(EVERY[min(k, len(EVERY) - 1)])
                with self.lock:
                    self.progress_line()

        threading.Thread(target=run, name="kinegrasp-compile-progress", daemon=True).start()

    def progress_line(self) -> None:
        elapsed = time.monotonic() - self.start
        _, kernels = self.estimate
        of = f" of about {kernels}" if kernels else ""
        where = "" if os.getpid() == _main_pid else f" in worker process {os.getpid()}"
        self.say(f"kinegrasp: compiling kernels{where}: {self.count}{of} compiled, "
                 f"{_fmt(elapsed)} elapsed (now {self.current})")

    def finish(self) -> None:
        """The closing line, and the record for the next estimate (only after a first
        compile from an empty cache: a partial one would make a poor estimate)."""
        if self.start is None:
            return
        elapsed = time.monotonic() - self.start
        self.say(f"kinegrasp: {self.count} kernels compiled in {_fmt(elapsed)} (m:ss; stored, "
                 "not compiled again on this machine)")
        if self.cold:
            try:
                self._record_file().write_text(json.dumps({"seconds": round(elapsed, 1),
                                                           "kernels": self.count}))
            except OSError:
                pass


def attach_report(report: CompileReport) -> None:
    """Send this process's numba compile events to ``report`` and its summary to exit."""
    from numba.core import event

    class Listener(event.Listener):
        def on_start(self, ev) -> None:
            report.on_start(ev)

        def on_end(self, ev) -> None:
            report.on_end(ev)

    event.register("numba:compile", Listener())
    atexit.register(report.finish)


def install(stream: TextIO | None = None) -> None:
    """Report kernel compiles of this process on ``stream`` (default stderr); see the module
    docstring. Idempotent."""
    global _installed, _main_pid
    if _installed:
        return
    _installed, _main_pid = True, os.getpid()
    already = "kinegrasp_env.jit" in sys.modules

    def loaded(jit) -> None:
        cache = jit.kernel_cache_dir()
        cold = (not already and os.getpid() == _main_pid
                and not any(cache.glob("**/*.nbi")))
        report = CompileReport(stream, cache, cold)
        if cold:
            report.notice()
        attach_report(report)

    when_imported("kinegrasp_env.jit", loaded)


_installed = False
_main_pid = os.getpid()
