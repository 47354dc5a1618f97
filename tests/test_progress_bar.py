"""The progress bar off a terminal (``kinegrasp_env.progress_bar``): plain lines at most every
interval, a last line only after a run long enough to have printed one, and the lines a long
command prints where its output goes to a log.

What each test proves: the line schedule and wording against a hand-driven clock; that
a command run with its stderr in a file (no terminal) reports as it goes (it printed nothing
until the result)."""

from __future__ import annotations

import io

import pytest
from clock_helpers import Clock

from kinegrasp_env import progress_bar as bars


def test_lines_come_at_most_every_interval_and_a_short_run_prints_none():
    clock, out = Clock(), io.StringIO()
    bar = bars.LineBar(total=40, desc="sweep", unit="task", stream=out, interval=10.0,
                       clock=clock)
    for step in range(40):
        clock.now = step * 1.0 + 1.0  # one task a second: lines at 10 s, 20 s, 30 s, 40 s
        bar.update(1)
    clock.now = 41.0
    bar.close()
    bar.close()  # once
    assert out.getvalue().splitlines() == [
        "sweep: 10/40 tasks (25%), 00:10", "sweep: 20/40 tasks (50%), 00:20",
        "sweep: 30/40 tasks (75%), 00:30", "sweep: 40/40 tasks (100%), 00:40",
        "sweep: 40/40 tasks (100%), done in 00:41"]
    silent = io.StringIO()
    short = bars.LineBar(total=5, desc="x", stream=silent, clock=Clock())
    short.update(5)
    short.close()
    assert silent.getvalue() == ""  # shorter than the interval: as quiet as before


def test_an_unknown_total_and_an_iterable_are_counted():
    clock, out = Clock(), io.StringIO()
    bar = bars.LineBar(desc="sensitivity", unit="setting", stream=out, interval=0.0,
                       clock=clock)
    bar.update(3)
    assert out.getvalue() == "sensitivity: 3 settings, 00:00\n"
    out = io.StringIO()
    items = list(bars.LineBar(["a", "b"], desc="c", unit="job", stream=out, interval=0.0,
                              clock=Clock()))
    assert items == ["a", "b"] and out.getvalue().splitlines()[-1] == \
        "c: 2/2 jobs (100%), done in 00:00"


def test_a_terminal_gets_tqdm_and_a_log_gets_lines():
    from tqdm import tqdm

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    assert isinstance(bars.progress_bar(total=3, stream=Terminal()), tqdm)
    assert isinstance(bars.progress_bar(total=3, stream=io.StringIO()), bars.LineBar)
    assert isinstance(bars.progress_bar(total=3, stream=io.StringIO(), enabled=False), tqdm)


def test_a_long_command_reports_off_a_terminal(monkeypatch, capsys):
    """``evaluate`` with stderr in a file (pytest's capture: no terminal) prints progress
    lines as the chunks come back, then the result (it printed nothing before it)."""
    from kinegrasp_env.cli import main

    monkeypatch.setattr(bars, "LINE_INTERVAL", 0.0)
    assert main(["evaluate", "--object", "cube", "--grasp", "0", "--samples", "600",
                 "--engine", "fast"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert any(line.startswith("cube grasp 0: ") and "/600 draws" in line for line in err), err
    assert err[-1].startswith("cube grasp 0: 600/600 draws (100%), done in"), err


if __name__ == "__main__":
    pytest.main([__file__])
