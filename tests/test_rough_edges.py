"""What a new user hits in the first hour: output paths that cannot be written, figures in no
known format, more processes than cores, progress lines that tell the truth.

The output checks run each command with a draw count that would take hours: a command that
looked at its output path only after the work would not return within the subprocess
timeout, so returning at once with the one-line error proves the check came first.
"""

from __future__ import annotations

import io
import subprocess

import pytest
from cli_helpers import COMMAND

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli.common import CLIError, available_cores, output_file, output_folder
from kinegrasp_env.toolkit.progress import MIN_WINDOW, Progress

#: Draws that no command finishes within the timeout below.
HOURS_OF_DRAWS = "100000000"
TIMEOUT = 120


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*COMMAND, *args], capture_output=True, text=True, check=False,
                          timeout=TIMEOUT)


#: Stands for a noise-spec file in the argument lists (the ``spec`` fixture writes one).
SPEC = "<spec>"


@pytest.fixture(scope="module")
def spec(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("spec") / "dexnet.yaml"
    path.write_text("preset: dexnet\n")
    return str(path)


def _cases(bad: str, bad_folder: str) -> list[tuple[list[str], str]]:
    """Every command's output options, each given ``bad`` (a file) or ``bad_folder``."""
    cube = str(asset_path("grasps", "cube.json"))
    spec = ["--noise-spec", SPEC]
    many = ["--samples", HOURS_OF_DRAWS]
    return [
        (["evaluate", "--engine", "fast", *many, "--plot", bad], "--plot"),
        (["evaluate", "--engine", "fast", *many, "--report", bad], "--report"),
        (["rank", cube, *many, "--out", bad], "--out"),
        (["rank", cube, *many, "--report", bad], "--report"),
        (["reproduce", "table1", *many, "--out", bad_folder], "--out"),
        (["plan", "--count", "100000", "--out", bad], "--out"),
        (["planar", *many, "--plot", bad], "--plot"),
        (["convergence", "--truth-samples", HOURS_OF_DRAWS, "--out", bad], "--out"),
        (["elbow", *many, "--plot", bad], "--plot"),
        (["elbow", *many, "--report", bad], "--report"),
        (["sensitivity", *spec, *many, "--plot", bad], "--plot"),
        (["report", *many, "--out", bad], "--out"),
        (["objects", "show", "cube", "--plot", bad], "--plot"),
    ]


@pytest.mark.parametrize("case", range(len(_cases("x", "y"))))
def test_an_unwritable_output_is_one_line_before_any_work(case, spec):
    """``/proc/nope/...`` (a folder that cannot exist: /proc refuses new entries): exit 2, one
    line naming the option, the path and why, within the timeout (so before the draws); no
    traceback, no "bug" hint."""
    argv, option = _cases("/proc/nope/out.png", "/proc/nope")[case]
    proc = _cli(*(spec if a == SPEC else a for a in argv))
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and f"{option} /proc/nope" in lines[0], lines
    assert "Traceback" not in proc.stderr and "bug" not in proc.stderr


def test_a_missing_folder_is_an_error_and_nothing_is_created(tmp_path):
    """``--plot DIR/p.png`` with DIR missing: refused before the work, DIR not created (a file
    output is written only into a folder that exists); a folder output (``--out`` of
    ``reproduce``) may be created, with the folders on the path the user named, never
    elsewhere."""
    missing = tmp_path / "nonexistent_dir"
    proc = _cli("evaluate", "--engine", "fast", "--samples", HOURS_OF_DRAWS,
                "--plot", str(missing / "p.png"))
    assert proc.returncode == 2
    assert proc.stderr.strip() == (f"kinegrasp evaluate: error: --plot {missing / 'p.png'}: "
                                   f"folder {missing} does not exist (create it first)")
    assert not missing.exists()
    before = set(tmp_path.rglob("*"))
    assert output_folder(str(tmp_path / "a" / "b")) == tmp_path / "a" / "b"
    assert set(tmp_path.rglob("*")) == before  # checked, not created
    with pytest.raises(CLIError, match="is a file; give a folder"):
        output_folder(str(asset_path("grasps", "cube.json")))


@pytest.mark.parametrize("argv", [
    ["evaluate", "--engine", "fast", "--samples", HOURS_OF_DRAWS],
    ["planar", "--samples", HOURS_OF_DRAWS],
    ["sensitivity", "--noise-spec", SPEC, "--samples", HOURS_OF_DRAWS],
])
def test_an_unknown_figure_format_is_an_error_before_the_work(tmp_path, argv, spec):
    """``--plot x.xyz``: exit 2 at once with the formats matplotlib writes (was: a warning
    after the work, exit 0); the file is not created."""
    target = tmp_path / "x.xyz"
    proc = _cli(*(spec if a == SPEC else a for a in argv), "--plot", str(target))
    assert proc.returncode == 2, proc.stderr
    line = proc.stderr.strip()
    assert "\n" not in line and f"--plot {target}: .xyz is not a figure format" in line
    assert "png" in line and "pdf" in line and "svg" in line
    assert not target.exists()


def test_figure_formats_are_matplotlibs(tmp_path):
    """Each format accepted is one matplotlib really writes (asked for itself:
    ``savefig`` into the file), so the check refuses nothing that would work."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for suffix in ("png", "pdf", "svg", "jpg"):
        path = tmp_path / f"f.{suffix}"
        assert output_file(str(path), "--plot") == path
        fig = plt.figure()
        fig.savefig(path)
        plt.close(fig)
        assert path.stat().st_size > 0
    with pytest.raises(CLIError, match="no extension is not a figure format"):
        output_file(str(tmp_path / "figure"), "--plot")


def test_processes_above_the_cores_are_capped_with_a_warning(capsys):
    """``--processes 1000`` on a machine with fewer cores: one warning line, and the pool has
    exactly as many workers as this process may run on (``os.sched_getaffinity``); the cap is
    stated in --help."""
    import os

    from kinegrasp_env.cli.common import executor_from
    from kinegrasp_env.cli.main import build_parser

    cores = len(os.sched_getaffinity(0))
    assert available_cores() == cores
    args = build_parser().parse_args(["evaluate", "--processes", "1000"])
    with executor_from(args) as executor:
        assert executor.workers == cores
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"kinegrasp: warning: --processes 1000 is more than the {cores} cores this "
                   f"machine gives the command; using {cores}"]
    args = build_parser().parse_args(["evaluate", "--processes", str(cores)])
    with executor_from(args) as executor:
        assert executor.workers == cores
    assert capsys.readouterr().err == ""
    helptext = " ".join(build_parser()._subparsers._group_actions[0].choices["evaluate"]
                        .format_help().split())
    assert "more than this machine's cores is capped to them, with a warning" in helptext


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_a_rate_is_never_measured_over_an_instant():
    """Work that comes back at once (results found already done, two chunks finishing
    together) gave rates like "10736419 draws/s, ETA 00:00": now the rate is stated only
    over at least MIN_WINDOW seconds, and before that the line says it is being measured
    (no "?"). Once measured it is the true rate of the later work (hand count: 500 draws
    in 5 s)."""
    clock, stream = Clock(), io.StringIO()
    report = Progress("table1", 10_000, 10, stream=stream, interactive=False, clock=clock)
    for cell in range(3):  # three cells found done: 1,000 draws each within 3 ms
        clock.now += 0.001
        report.advance(1000 * (cell + 1))
        report.cell_done(f"cell {cell}: P(FC) 0.500")
    assert report.rate() is None
    lines = stream.getvalue().splitlines()
    assert all(line.endswith("draws, rate being measured") for line in lines), lines
    assert "?" not in stream.getvalue() and "draws/s" not in stream.getvalue()
    for step in range(1, 11):  # then 100 draws/s of real work
        clock.now += 0.5
        report.advance(3000 + 50 * step)
    assert report.rate() == pytest.approx(100.0)
    assert report.eta() == pytest.approx((10_000 - 3500) / 100.0)
    assert MIN_WINDOW >= 1.0


def test_a_revised_total_is_shown_against_the_first():
    """An adaptive run that stops early revises its total down: the line shows both, so the
    bar's total and the summary's fixed-n figure never disagree unexplained."""
    clock, stream = Clock(), io.StringIO()
    report = Progress("rank", 24_000, 4, word="round", stream=stream, interactive=False,
                      clock=clock)
    clock.now = 1.0
    report.advance(10_000)
    clock.now = 3.0
    report.advance(20_500, 20_500)
    report.cell_done("0 of 12 candidates undecided")
    assert stream.getvalue() == ("rank: round 1/4 0 of 12 candidates undecided, "
                                 "20500/20500 draws (down from 24000), 5250 draws/s, "
                                 "ETA 00:00\n")
