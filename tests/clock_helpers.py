"""A settable clock for progress reports' tests (``clock.now`` is what it reads)."""

from __future__ import annotations


class Clock:
    """A settable clock: calling it returns ``now`` (seconds)."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now
