"""`kinegrasp planar`, `ee` and `convergence` from the command line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import run_cli

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli import main
from kinegrasp_env.robot.planar import PlanarArm
from kinegrasp_env.sampling.noise import JointNoise


def test_planar_json_as_specified():
    proc = run_cli("planar", "--links", "2,2", "--q0", "0.0,1.5708", "--sigma", "0.0175",
                   "--samples", "10000", "--seed", "0", "--json")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert {"mean", "cov", "skew", "samples"} <= set(out)
    assert out["samples"] == 10000
    assert np.shape(out["mean"]) == (2,) and np.shape(out["cov"]) == (2, 2)
    assert np.shape(out["skew"]) == (2,)
    mean, cov = PlanarArm((2.0, 2.0)).exact_moments(np.array([0.0, 1.5708]),
                                                    JointNoise(0.0175))
    np.testing.assert_allclose(out["mean"], mean, atol=4 * np.sqrt(cov.diagonal().max() / 1e4))
    np.testing.assert_allclose(out["cov"], cov, rtol=0.1, atol=1e-5)
    again = run_cli("planar", "--links", "2,2", "--q0", "0.0,1.5708", "--sigma", "0.0175",
                    "--samples", "10000", "--seed", "0", "--json")
    assert again.stdout == proc.stdout


@pytest.mark.parametrize(("args", "needle"), [
    (["--sigma", "-1"], "--sigma must be >= 0, got -1"),
    (["--links", "2,2,2", "--q0", "0,1"], "--links has 3 lengths but --q0 has 2 angles"),
    (["--q0", "nan,1"], "'nan' is not a finite number"),
    (["--q0", "0,1x"], "--q0: '1x' is not a number"),
    (["--samples", "0"], "--samples must be >= 1, got 0"),
    (["--links", "2,-1"], "link lengths must be > 0"),
])
def test_planar_bad_input_one_line(args, needle):
    proc = run_cli("planar", *args)
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr


def test_planar_plot(tmp_path, capsys):
    out = tmp_path / "arm.png"
    assert main(["planar", "--samples", "500", "--plot", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_negative_angles_need_no_equals_sign(capsys):
    assert main(["planar", "--q0", "-0.5,1.0", "--samples", "100", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["samples"] == 100


def test_negative_values_are_values():
    """A token that starts like a negative number is a value of the option before it:
    ``--position -0.1 0.6 0`` and ``--table-size -1 0.5`` (gluing the first value to the
    option, as ``--q0 -0.5,1`` was glued, left the others without one), an exponent
    (``-1e-3``), ``-inf`` (refused later as not finite), an abbreviated option, and
    one-value options of every command (``report --grasp -1,2``)."""
    from kinegrasp_env.cli.main import build_parser

    parser = build_parser()
    args = parser.parse_args(["objects", "place", "cube", "--position", "-0.1", "0.6", "0",
                              "--table-size", "-1", "0.5", "--orientation", "0", "0",
                              "-0.6", "0.8"])
    assert (args.position, args.table_size) == (["-0.1", "0.6", "0"], ["-1", "0.5"])
    assert args.orientation == ["0", "0", "-0.6", "0.8"]
    args = parser.parse_args(["objects", "place", "cube", "--pos", "-1e-3", "-inf", "0"])
    assert args.position == ["-1e-3", "-inf", "0"]
    assert parser.parse_args(["planar", "--q0", "-0.5,1"]).q0 == "-0.5,1"
    assert parser.parse_args(["report", "--grasp", "-1,2", "--out", "r.html"]).grasp == "-1,2"
    assert parser.parse_args(["validate", "--grasp", "-1", "2", "--out", "v"]).grasp == [
        "-1", "2"]


def test_ee_of_the_default_robot_json_and_errors(capsys):
    assert main(["ee", "--q0", "0,0.6,0,-1.2,0,0.8,0", "--sigma", "0.0133",
                 "--samples", "20000", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert np.shape(out["cov"]) == (3, 3) and out["samples"] == 20000
    # propagated covariance J Sigma J^T is a first-order check of the sampled one
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.kinematics import Kinematics

    model = load_robot("kuka_sdh").model
    kin, arm = Kinematics(model), np.arange(7)
    q = np.zeros(model.dof)
    q[arm] = [0, 0.6, 0, -1.2, 0, 0.8, 0]
    jac = kin.jacobian(q, "palm")[0, :3][:, arm]
    linear = 0.0133**2 * jac @ jac.T
    # sampling error of a covariance entry ~ sqrt(var_i var_j / n); linearization error small
    se = np.sqrt(np.outer(linear.diagonal(), linear.diagonal()) / 20000)
    assert np.all(np.abs(np.asarray(out["cov"]) - linear) < 5 * se + 0.02 * np.abs(linear))
    assert main(["ee", "--q0", "0,1,2"]) == 2
    assert "needs 7 joint angles, got 3" in capsys.readouterr().err


def test_convergence_figure(tmp_path, capsys):
    out = tmp_path / "conv.png"
    assert main(["convergence", "--out", str(out), "--trials", "2", "--truth-samples", "2000",
                 "--max-samples", "200", "--json"]) == 0
    curves = json.loads(capsys.readouterr().out)
    assert set(curves) == {"2-link planar arm", "KUKA iiwa"}
    assert set(curves["KUKA iiwa"]) == {"0.0033", "0.0133", "0.0233", "0.0333"}
    assert out.exists()


def test_convergence_of_another_robots_arm(tmp_path, capsys):
    """The Panda's arm in the figure (its curves named after it): the mean's error falls as
    the draws grow, about as 1/sqrt(n) (10 to 200 draws: 4.5 times smaller; more than twice
    smaller asked, over 6 trials), and an unknown robot is one line."""
    out = tmp_path / "conv.png"
    assert main(["convergence", "--robot", "panda", "--out", str(out), "--trials", "6",
                 "--truth-samples", "4000", "--max-samples", "200", "--json"]) == 0
    curves = json.loads(capsys.readouterr().out)
    assert set(curves) == {"2-link planar arm", "panda arm"}
    for curve in curves["panda arm"].values():
        assert curve["mean_error"][-1] < 0.5 * curve["mean_error"][0]
    assert main(["convergence", "--robot", "nosuch", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nosuch" in err[0]


# ------------------------------------------------------------------ errors, --help, --version
def _run(capsys, *argv: str) -> tuple[int, list[str]]:
    """Exit status and stderr lines of ``kinegrasp argv`` run in this process."""
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse: usage errors, --help, --version
        code = exc.code
    return code, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize(("argv", "command", "needle"), [
    (["evaluate", "--noise", "cauchy"], "evaluate",
     "argument --noise: invalid choice: 'cauchy' (choose from 'gaussian', 'uniform', "
     "'triangular')"),
    (["evaluate", "--object", "teapot"], "evaluate", "unknown object 'teapot'"),
    (["evaluate", "--engine", "gpu"], "evaluate", "argument --engine: invalid choice: 'gpu'"),
    (["evaluate", "--samplez", "3"], "evaluate", "unrecognized arguments: --samplez 3"),
    (["rank"], "rank", "the following arguments are required: candidates"),
    (["rank", "c.json", "--criterion", "best"], "rank", "argument --criterion: invalid choice"),
    (["sweep", "spec.yaml"], "sweep", "the following arguments are required: --out"),
    (["reproduce", "fig8"], "reproduce", "argument figure: invalid choice: 'fig8'"),
    (["plan", "--object", "teapot"], "plan", "unknown object 'teapot'"),
    (["evaluate", "--backend", "spark"], "evaluate", "argument --backend: invalid choice"),
    (["frobnicate"], None, "argument command: invalid choice: 'frobnicate'"),
])
def test_usage_errors_are_one_line_with_a_help_hint(capsys, argv, command, needle):
    code, err = _run(capsys, *argv)
    prog = "kinegrasp" if command is None else f"kinegrasp {command}"
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith(f"{prog}: error: ") and needle in err[0], err
    assert err[0].endswith(f"(see `{prog} --help`)")


def test_a_usage_error_from_the_shell_is_one_line():
    proc = run_cli("evaluate", "--noise", "cauchy")
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "usage:" not in proc.stderr, proc.stderr


@pytest.mark.parametrize(("argv", "needle"), [
    (["evaluate", "--object", "cube", "--grasp", "12"],
     "--grasp: grasp index 12 out of range: cube has 12 grasps of robot kuka_sdh (0..11)"),
    (["evaluate", "--object", "cube", "--grasp", "-1"], "grasp index -1 out of range"),
    (["evaluate", "--grasp", "one"], "--grasp: 'one' is not an integer"),
    (["evaluate", "--object", "cube", "--sigma", "1e308", "--samples", "10", "--engine",
      "fast"], "--sigma must be <= pi (3.14159 rad), got 1e+308"),
    (["evaluate", "--sigma", "inf"], "--sigma: 'inf' is not a finite number"),
    (["evaluate", "--seed", "-3"], "--seed must be >= 0, got -3"),
    (["evaluate", "--processes", "0"], "--processes must be >= 1, got 0"),
    (["evaluate", "--address", "ray://head:10001"], "--address is for the ray backend"),
    (["planar", "--sigma", "4"], "--sigma must be <= pi"),
    (["plan", "--time-budget", "soon"], "--time-budget: 'soon' is not a number"),
    (["plan", "--time-budget", "-5"], "--time-budget must be > 0, got -5"),
    (["plan", "--max-attempts", "0"], "--max-attempts must be >= 1, got 0"),
    (["plan", "--variants", "-1"], "--variants must be >= 0, got -1"),
    (["plan", "--variants", "two"], "--variants: 'two' is not an integer"),
    (["convergence", "--max-samples", "5"], "--max-samples must be >= 10, got 5"),
])
def test_bad_values_are_one_line(capsys, argv, needle):
    code, err = _run(capsys, *argv)
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith(f"kinegrasp {argv[0]}: error: ") and needle in err[0], err


#: Every command that takes ``--robot``, with the arguments it requires besides.
ROBOT_COMMANDS = {
    "ee": [],
    "convergence": ["--out", "c.png"],
    "evaluate": ["--object", "cube", "--grasp", "0", "--sigma", "0.01", "--samples", "10"],
    "reproduce": ["fig10"],
    "plan": ["--object", "cube"],
    "rank": ["candidates.json"],
    "sweep": ["spec.yaml", "--out", "sweep"],
    "elbow": [],
    "report": ["--out", "report"],
    "sensitivity": ["--noise-spec", "spec.yaml"],
    "validate": ["--out", "validation"],
}


@pytest.mark.parametrize("argv, prefix", [
    (["objects", "place", "cube", "--yaw", "nan"], "kinegrasp objects place: error: --yaw"),
    (["robots", "show", "nosuch", "--out", "x.png"], "kinegrasp robots show: error: "),
    (["objects", "remove", "cube"], "kinegrasp objects remove: error: "),
])
def test_an_actions_errors_name_the_command_and_the_action(capsys, argv, prefix):
    """A command of several actions (``objects place``) names the action in its one-line
    errors, as argparse names it in its usage errors."""
    code, err = _run(capsys, *argv)
    assert code == 2 and len(err) == 1 and err[0].startswith(prefix), err


def test_an_unknown_robot_is_named_first_by_every_command(capsys):
    """``--robot nosuch`` is refused before anything else is looked at (the shipped grasps,
    the input files): one line saying the robot is unknown and naming the known ones."""
    takes_robot = {name for name, sub in _subparsers().items()
                   if any("--robot" in a.option_strings for a in sub._actions)}
    assert takes_robot == set(ROBOT_COMMANDS)
    for command, args in ROBOT_COMMANDS.items():
        code, err = _run(capsys, command, *args, "--robot", "nosuch")
        assert code == 2 and len(err) == 1, (command, err)
        assert err[0].startswith(f"kinegrasp {command}: error: "), err
        assert "unknown robot 'nosuch'; known robots: kuka_sdh, panda" in err[0], err
    code, err = _run(capsys, "plan", "--object", "cube", "--robot", "pand")
    assert code == 2 and "unknown robot 'pand' (did you mean 'panda'?)" in err[0], err


def test_output_paths_are_checked_before_any_work(tmp_path, capsys):
    a_file = tmp_path / "file"
    a_file.write_text("")
    for argv, needle in [
        (["planar", "--plot", str(tmp_path)], f"--plot {tmp_path} is a folder"),
        (["planar", "--plot", str(a_file / "x.png")], f"{a_file} is not a folder"),
        (["convergence", "--out", str(a_file / "c.png")], f"{a_file} is not a folder"),
        (["evaluate", "--plot", str(tmp_path)], "is a folder; give a file name"),
        (["plan", "--out", str(a_file / "g.json")], f"{a_file} is not a folder"),
        (["plan", "--out", ""], "--out is empty; give a file name"),
        (["evaluate", "--plot", ""], "--plot is empty; give a file name"),
        (["evaluate", "--report", str(tmp_path / "e.png")], "give a .html or .htm file"),
        (["elbow", "--plot", ""], "--plot is empty; give a file name"),
        (["reproduce", "table1", "--out", ""], "--out is empty; give a folder name"),
        (["reproduce", "fig9", "--out", " "], "--out is empty; give a folder name"),
        # a command that writes one format refuses a name that says another
        (["report", "--out", str(tmp_path / "r.png")], "give a .html or .htm file"),
        (["rank", str(asset_path("grasps", "kuka_sdh", "cube.json")), "--report",
          str(tmp_path / "r.pdf")], "give a .html or .htm file"),
        (["screenshot", str(a_file), "--out", str(tmp_path / "s.html")], "give a .png file"),
        (["robots", "show", "panda", "--out", str(tmp_path / "p.svg")], "give a .png file"),
        (["rank", str(asset_path("grasps", "kuka_sdh", "cube.json")), "--out",
          str(tmp_path / "r.png")], "give a .csv file"),
    ]:
        code, err = _run(capsys, *argv)
        assert code == 2 and len(err) == 1 and needle in err[0], err
    # an output that is the file a command reads is refused, and the file is kept
    grasps = tmp_path / "grasps.json"
    shutil.copy(asset_path("grasps", "kuka_sdh", "cube.json"), grasps)
    kept = grasps.read_bytes()
    for argv, needle in [
        (["rank", str(grasps), "--out", str(grasps)], "is the candidates file the command"),
        (["rank", str(grasps), "--report", str(grasps)], "is the candidates file the command"),
        (["report", "--grasps", str(grasps), "--out", str(grasps)], "is --grasps the command"),
    ]:
        code, err = _run(capsys, *argv)
        assert code == 2 and len(err) == 1 and needle in err[0], err
    assert grasps.read_bytes() == kept


def _raise(exc: BaseException):
    def command(args):
        raise exc
    return command


@pytest.mark.parametrize("exc", [KeyError("index"), ValueError("shapes do not match"),
                                 FileNotFoundError(2, "No such file", "/assets/x.json"),
                                 IndexError("list index out of range")])
def test_a_bug_is_a_traceback_and_a_hint_to_report_it(capsys, monkeypatch, exc):
    """Only the CLI's own input errors are one line: a KeyError or ValueError from inside
    (a bug) shows its traceback, then asks for a report, exit status 1."""
    from kinegrasp_env.cli import arms

    monkeypatch.setattr(arms, "cmd_planar", _raise(exc))
    code, err = _run(capsys, "planar")
    assert code == 1
    assert err[0] == "Traceback (most recent call last):"
    assert err[-2].startswith(type(exc).__name__)
    assert err[-1] == ("kinegrasp planar: this is a bug in kinegrasp; please report it with "
                       "the command you ran")
    assert not any("error:" in line for line in err)


def test_a_full_disk_is_one_line_not_a_bug(capsys, monkeypatch):
    import errno

    from kinegrasp_env.cli import arms

    full = OSError(errno.ENOSPC, "No space left on device", "/out/x.png")
    monkeypatch.setattr(arms, "cmd_planar", _raise(full))
    code, err = _run(capsys, "planar")
    assert code == 1
    assert err == ["kinegrasp planar: error: [Errno 28] No space left on device: "
                   "'/out/x.png'"]


def test_a_reader_that_stops_early_ends_the_command_quietly():
    """``kinegrasp ... | head``: the reader closes the pipe before the command writes; the
    command stops with SIGPIPE's exit status (141) and says nothing (no traceback, no
    request for a bug report)."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "kinegrasp_env.cli", "planar", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # before the interpreter has started: every write finds no reader
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141, err
    assert err == ""


def test_version_is_the_installed_package_version(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out == f"kinegrasp {version('kinegrasp-env')}\n"


def _subparsers():
    import argparse

    from kinegrasp_env.cli.main import build_parser

    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def test_every_option_has_help_with_its_default():
    """--help of every command shows every option with help text, and its default when
    it has one (None: no default; a flag: off)."""
    for name, sub in _subparsers().items():
        text = " ".join(sub.format_help().split())
        for action in sub._actions:
            if not action.option_strings or action.dest == "help":
                continue
            assert action.help, f"{name} {action.option_strings[0]} has no help"
            if action.default not in (None, False):
                assert f"(default: {action.default})" in text, \
                    f"{name} {action.option_strings[0]}: default not shown"


def test_help_shows_the_choices_from_their_sources():
    """Choices and defaults in --help equal the catalog's and the library's (the parser keeps
    copies of a few, so that building it imports none of the library's heavy modules)."""
    from kinegrasp_env.cli.common import ENGINE_NAMES
    from kinegrasp_env.montecarlo import grasp_stats
    from kinegrasp_env.montecarlo.draws import OUTCOMES
    from kinegrasp_env.montecarlo.execution import BACKENDS
    from kinegrasp_env.sampling.noise import DISTRIBUTIONS
    from kinegrasp_env.toolkit.ranking import CRITERIA
    from kinegrasp_env.world.grasps import shipped_grasps
    from kinegrasp_env.world.objects import OBJECT_NAMES

    assert ENGINE_NAMES == grasp_stats.ENGINES
    import inspect

    from kinegrasp_env.cli.figure_grasps import FIG7_VARIANTS
    from kinegrasp_env.toolkit.experiments import fig7

    assert FIG7_VARIANTS == inspect.signature(fig7).parameters["variants"].default
    from kinegrasp_env.cli.common import DEFAULT_FRICTION, NUM_EDGES
    from kinegrasp_env.cli.ranking_table import OUTCOME_COLUMNS
    from kinegrasp_env.quality import wrenches

    assert (DEFAULT_FRICTION, NUM_EDGES) == (wrenches.DEFAULT_FRICTION,
                                             wrenches.DEFAULT_NUM_EDGES)
    assert OUTCOME_COLUMNS == OUTCOMES
    subs = _subparsers()

    def braces(names) -> str:
        return "{" + ",".join(names) + "}"

    for name in ("evaluate", "reproduce", "plan"):
        assert f"--object {braces(OBJECT_NAMES)}" in subs[name].format_help()
    for name in ("evaluate", "rank", "reproduce"):
        text = subs[name].format_help()
        assert f"--engine {braces(grasp_stats.ENGINES)}" in text
        assert f"--backend {braces(BACKENDS)}" in text
    for name in ("evaluate", "rank", "planar", "ee"):
        assert f"--noise {braces(DISTRIBUTIONS)}" in subs[name].format_help()
    assert f"--criterion {braces(CRITERIA)}" in subs["rank"].format_help()
    from kinegrasp_env.toolkit.plan_checks import (
        ATTEMPTS_PER_GRASP,
        PlannerSettings,
        attempts_for,
    )

    plan_help = " ".join(subs["plan"].format_help().split())
    assert (f"(default: {ATTEMPTS_PER_GRASP} per grasp asked, at least "
            f"{PlannerSettings.attempts})") in plan_help
    assert [attempts_for(c) for c in (1, 4, 5, 20)] == [200, 200, 250, 1000]
    counts = {len(shipped_grasps(name)) for name in OBJECT_NAMES}
    assert counts == {12}
    from kinegrasp_env.cli import objects as objects_cli
    from kinegrasp_env.world import decompose

    assert (objects_cli.DEFAULT_THRESHOLD, objects_cli.DEFAULT_MAX_PARTS) == (
        decompose.DEFAULT_THRESHOLD, decompose.DEFAULT_MAX_PARTS)
    from kinegrasp_env.cli import elbow as elbow_cli
    from kinegrasp_env.toolkit import elbow_certificate

    assert (elbow_cli.DEFAULT_EPSILON, elbow_cli.DEFAULT_DELTA) == (
        elbow_certificate.DEFAULT_EPSILON, elbow_certificate.DEFAULT_DELTA)
    assert "shipped grasp set of the object (kuka_sdh's: 0..11)" in " ".join(
        subs["evaluate"].format_help().split())


# ------------------------------------------------------------------ a CLI that answers at once
HEAVY = ("numpy", "scipy", "trimesh", "pybullet", "numba", "gymnasium", "matplotlib", "torch",
         "playwright")


def _fresh_modules(code: str, env: dict | None = None) -> set[str]:
    """Top-level modules loaded by ``code`` in a fresh interpreter (it prints nothing)."""
    import os
    import subprocess
    import sys

    probe = (code + "\nimport sys, json\n"
             "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, env={**os.environ, **(env or {})})
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def test_building_the_parser_imports_nothing_heavy():
    """``kinegrasp --help`` (and every command's --help, which the same parser holds) loads
    none of NumPy, SciPy, trimesh, pybullet, numba, Gymnasium, matplotlib: what keeps it
    under a few tenths of a second. Checked in a fresh interpreter's ``sys.modules``."""
    loaded = _fresh_modules("from kinegrasp_env.cli.main import build_parser\n"
                            "p = build_parser()\n"
                            "[s.format_help() for s in p._subparsers._group_actions[0]"
                            ".choices.values()]")
    assert not loaded & set(HEAVY), loaded & set(HEAVY)


def test_gymnasium_ids_registered_when_gymnasium_loads():
    """``import kinegrasp_env`` does not load Gymnasium, yet its IDs are registered the moment
    Gymnasium is imported, in either order, and ``gym.make("kinegrasp_env:...")`` finds them
    (the registry is Gymnasium's own: independent of how the IDs got there)."""
    loaded = _fresh_modules("import kinegrasp_env")
    assert "gymnasium" not in loaded and "numpy" not in loaded
    for code in ("import kinegrasp_env\nimport gymnasium as gym",
                 "import gymnasium as gym\nimport kinegrasp_env",
                 "import kinegrasp_env.envs\nimport gymnasium as gym"):
        _fresh_modules(code + "\nassert all(i in gym.registry for i in kinegrasp_env.ENV_IDS)\n"
                       "assert gym.spec('KineGrasp-v0').entry_point == "
                       "'kinegrasp_env.envs:KineGraspEnv'")
    _fresh_modules("import gymnasium as gym\n"
                   "from gymnasium.envs.registration import load_env_creator\n"
                   "import importlib; importlib.import_module('kinegrasp_env')\n"
                   "assert 'KineGraspSelect-v0' in gym.registry")


def test_the_listing_is_recomputed_whenever_the_catalog_changes(tmp_path, monkeypatch, capsys):
    """``kinegrasp objects`` serves its rows from a disk copy (no geometry loaded), so the
    copy must never be stale: after a placement and after a removal the listing equals the
    catalog computed from scratch (``world.catalog_listing.catalog``, no copy involved); an
    unchanged catalog is served without importing the geometry modules."""
    from kinegrasp_env.world.catalog_cache import cached_catalog
    from kinegrasp_env.world.catalog_listing import catalog

    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    monkeypatch.setenv("KINEGRASP_CACHE", str(tmp_path / "cache"))
    assert cached_catalog() == catalog()
    assert main(["objects", "place", "cube", "--as", "cube_moved", "--position", "0.5", "0.1",
                 "0.1"]) == 0
    rows = cached_catalog()
    assert rows == catalog() and rows[-1]["name"] == "cube_moved"
    assert rows[-1]["position"] == [0.5, 0.1, 0.1]
    env = {"KINEGRASP_HOME": str(tmp_path / "home"), "KINEGRASP_CACHE": str(tmp_path / "cache")}
    loaded = _fresh_modules("from kinegrasp_env.cli.main import main\nimport io, contextlib\n"
                            "with contextlib.redirect_stdout(io.StringIO()):\n"
                            "    main(['objects', '--json'])", env)
    assert not loaded & {"numpy", "trimesh", "numba", "scipy"}, loaded & set(HEAVY)
    assert main(["objects", "remove", "cube_moved"]) == 0
    assert cached_catalog() == catalog() and cached_catalog()[-1]["name"] == "mug"
    capsys.readouterr()


def test_a_compile_is_announced_with_progress(monkeypatch):
    """A real numba compile of a package function (numba's own ``numba:compile`` event) makes
    the report print the once-per-machine notice with an estimate, and, at the end, the count
    and time; compiles of code outside the package are not counted."""
    import io

    import numba

    from kinegrasp_env import kernel_notice

    stream = io.StringIO()
    report = kernel_notice.CompileReport(stream, Path("/nonexistent/numba/key"), cold=True)
    monkeypatch.setattr(kernel_notice.atexit, "register", lambda f: None)
    kernel_notice.attach_report(report)

    def outside(x):
        return x + 1

    def inside(x):
        return x * 2

    inside.__module__ = "kinegrasp_env.probe"
    assert numba.njit(outside)(1) == 2
    assert stream.getvalue() == "" and report.count == 0
    assert numba.njit(inside)(3) == 6
    assert report.count == 1 and report.current == "probe.inside"
    report.finish()
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("kinegrasp: the numerical kernels are compiled on first use, "
                               "once per machine (about 2 minutes on a 2-core machine)")
    assert lines[-1].startswith("kinegrasp: 1 kernels compiled in 0:0")


def test_finish_runs_the_exit_handlers_flushes_and_waits_for_working_threads():
    """The console script's exit (cli.main.finish): the exit status given, every atexit
    handler run, buffered output flushed (a pipe, not a terminal), and a non-daemon thread
    still working finished before the process ends."""
    import subprocess
    import sys

    code = ("import atexit, sys, threading, time\n"
            "from kinegrasp_env.cli.main import finish\n"
            "atexit.register(lambda: print('handler', end=''))\n"
            "def work():\n"
            "    time.sleep(0.3); print('thread ', end='')\n"
            "threading.Thread(target=work).start() if len(sys.argv) > 1 else None\n"
            "print('out ', end='')\n"
            "finish(3)\n")
    for argv, expected in (([], "out handler"), (["thread"], "out thread handler")):
        done = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True,
                              text=True, timeout=60)
        assert (done.returncode, done.stdout) == (3, expected), (argv, done)


@pytest.mark.parametrize(("how", "status", "line"), [
    ("term", 143, "kinegrasp: terminated"), ("ctrl-c", 130, "kinegrasp: interrupted")])
def test_a_stopped_run_says_so_and_leaves_no_worker(how, status, line):
    """SIGTERM to the command, or Ctrl-C (SIGINT to every process of the job, as a terminal
    sends it), in the middle of a run on 2 worker processes: one line, the signal's exit
    status, and no process of the job left (SIGTERM left the pool's workers running; Ctrl-C
    could print an idle worker's traceback: the workers' own signal settings are tested in
    test_execution.py, this run's timing need not catch one idle)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    def as_in_a_terminal():  # a job started in the background (a CI run) ignores SIGINT
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    proc = subprocess.Popen(
        [sys.executable, "-m", "kinegrasp_env.cli", "evaluate", "--object", "spray_flask",
         "--samples", "100000", "--engine", "pybullet", "--processes", "2"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True,
        preexec_fn=as_in_a_terminal)
    time.sleep(6)  # the workers are drawing by then (the whole run takes minutes)
    if how == "term":
        os.kill(proc.pid, signal.SIGTERM)
    else:
        os.killpg(proc.pid, signal.SIGINT)
    err = proc.communicate(timeout=120)[1].decode().strip().splitlines()
    # (a first run on a machine may print the kernels' compile notice before)
    assert proc.returncode == status and err[-1] == line, err
    assert not any("Traceback" in text for text in err), err
    time.sleep(0.5)
    assert _group_processes(proc.pid) == []


def _group_processes(group: int) -> list[int]:
    """The processes still alive in process group ``group`` (Linux: /proc/PID/stat's 5th
    field), zombies left out."""
    from pathlib import Path

    alive = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # gone meanwhile
            continue
        if int(fields[2]) == group and fields[0] != "Z":
            alive.append(int(stat.parent.name))
    return alive


def test_json_output_is_strict_json(capsys):
    """``--json`` writes null where a moment is undefined (one draw has no covariance), never
    NaN, which strict parsers (a browser's JSON.parse) refuse."""
    def strict(text: str) -> dict:
        def refuse(name):
            raise ValueError(f"not JSON: {name}")
        return json.loads(text, parse_constant=refuse)

    assert main(["ee", "--samples", "1", "--json"]) == 0
    shown = strict(capsys.readouterr().out)
    assert shown["skew"] == [None, None, None]


@pytest.mark.parametrize("argv", [
    ["evaluate", "--object", "cube", "--noise-spec", "{file}"],
    ["sensitivity", "--noise-spec", "{file}"],
    ["sweep", "{file}", "--out", "{tmp}/sweep"],
    ["rank", "{file}"],
    ["robots", "add", "{file}"],
])
def test_a_binary_file_given_for_a_text_one_is_one_line(capsys, tmp_path, argv):
    """A mesh (or any binary file) named where a spec, a grasp file or a description goes
    is refused by one reader (``spec_yaml.read_user_text``) in one line naming the file,
    before any work (it was a UnicodeDecodeError traceback from the spec readers)."""
    binary = tmp_path / "mesh.yaml"
    binary.write_bytes(b"solid\x00\x80\x81\xfe binary mesh")
    args = [a.format(file=binary, tmp=tmp_path) for a in argv]
    code, err = _run(capsys, *args)
    assert code == 2 and len(err) == 1, err
    assert f"{binary}: not a text file" in err[0], err
    assert not (tmp_path / "sweep").exists()


@pytest.mark.parametrize("option, value, words", [
    ("--epsilon", "2", "--epsilon must be a margin in [0, 1), got 2"),
    ("--delta", "0", "--delta must be an error level in (0, 1), got 0"),
])
def test_a_certificates_levels_are_refused_alike_by_rank_and_elbow(capsys, tmp_path, option,
                                                                   value, words):
    """``rank --adaptive`` and ``elbow`` check a certificate's margin and error level by the
    library's one rule (``certificates.check_levels``), in the same words (they were worded
    apart, and the adaptive ranking and the elbow search had a rule each)."""
    from kinegrasp_env.toolkit.certificates import check_levels
    from kinegrasp_env.world.grasps import save_grasps, shipped_grasps

    grasps = tmp_path / "g.json"
    save_grasps(shipped_grasps("cube")[:3], grasps)
    for argv in (["rank", str(grasps), "--adaptive", "--out", str(tmp_path / "r.csv")],
                 ["elbow", "--object", "cube", "--grasp", "0"]):
        code, err = _run(capsys, *argv, option, value)
        assert code == 2 and err == [f"kinegrasp {argv[0]}: error: {words}"], err
    with pytest.raises(ValueError, match=r"^delta must be an error level in \(0, 1\), got 1$"):
        check_levels(0.1, 1)


def test_a_sigma_of_minus_zero_is_zero():
    """``--sigma -0`` is accepted as 0 and printed as 0 (it printed "sigma = -0")."""
    import math

    from kinegrasp_env.cli.common import sigma_value

    assert math.copysign(1.0, sigma_value("-0")) == 1.0
