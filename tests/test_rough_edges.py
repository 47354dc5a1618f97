"""What a new user hits in the first hour: output paths that cannot be written, figures in no
known format, more processes than cores, progress lines that tell the truth.

The output checks run each command with a draw count that would take hours: a command that
looked at its output path only after the work would not return within the subprocess
timeout, so returning at once with the one-line error proves the check came first.
"""

from __future__ import annotations

import io
import json
import subprocess
from pathlib import Path

import pytest
from cli_helpers import COMMAND
from clock_helpers import Clock

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli.common import CLIError
from kinegrasp_env.cli.execution_options import available_cores
from kinegrasp_env.cli.main import main
from kinegrasp_env.cli.output_paths import output_file, output_folder
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
    cube = str(asset_path("grasps", "kuka_sdh", "cube.json"))
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


def test_a_missing_folder_is_an_error_and_nothing_is_created(tmp_path, monkeypatch):
    """``--plot DIR/p.png`` with DIR missing outside the current folder: refused before the
    work, DIR not created (was: ``/nonexistent_dir`` made, even at the root). Missing folders
    are made only inside the current folder (the README's ``out/tour/...``); a folder output
    (``reproduce --out``) is the folder named, made when its parent exists. Checking creates
    nothing."""
    missing = tmp_path / "nonexistent_dir"
    proc = _cli("evaluate", "--engine", "fast", "--samples", HOURS_OF_DRAWS,
                "--plot", str(missing / "p.png"))
    assert proc.returncode == 2
    assert proc.stderr.strip() == (
        f"kinegrasp evaluate: error: --plot {missing / 'p.png'}: folder {missing} does not "
        "exist (create it first: only folders inside the current folder are made)")
    assert not missing.exists()
    with pytest.raises(CLIError, match=f"folder {tmp_path / 'a'} does not exist"):
        output_folder(str(tmp_path / "a" / "b"))
    assert output_folder(str(tmp_path / "a")) == tmp_path / "a"
    with pytest.raises(CLIError, match="is a file; give a folder"):
        output_folder(str(asset_path("grasps", "kuka_sdh", "cube.json")))
    monkeypatch.chdir(tmp_path)
    assert output_file("out/tour/p.png", "--plot") == Path("out/tour/p.png")
    assert output_folder("out/a/b") == Path("out/a/b")
    with pytest.raises(CLIError, match="does not exist"):
        output_file("../elsewhere/p.png", "--plot")
    assert sorted(tmp_path.rglob("*")) == []  # checked, nothing created


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

    from kinegrasp_env.cli.execution_options import executor_from
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


# ------------------------------------------------------------------ the environments
def test_the_env_default_engine_is_fast_and_agrees_with_the_reference():
    """The default a user gets is the fast engine, and it is the right default: on the same
    task, seed and draws the reference engine (pybullet) gives the same outcome draw for
    draw (``info["outcomes"]`` counts of 64 draws at two elbow steps; the env's two engines
    of the default robot took the same outcome on 2,400 of 2,400 draws of its shipped grasps,
    3 per object, sigma 0.0133 and 0.0266 rad, 100 draws each: ``python
    benchmarks/robot_agreement.py``; one draw in 64 may differ)."""
    import gymnasium as gym
    import numpy as np

    import kinegrasp_env  # noqa: F401 (registers the IDs)

    fast = gym.make("KineGrasp-v0", n_draws=64).unwrapped
    reference = gym.make("KineGrasp-v0", n_draws=64, engine="pybullet").unwrapped
    assert fast.engine == "fast"
    options = {"object": "spray_flask", "grasp": 2, "sigma": 0.0266}
    for env in (fast, reference):
        env.reset(seed=4, options=options)
    for action in ([0.0, -1.0], [0.6, -1.0]):
        *_, i_fast = fast.step(np.array(action, dtype=np.float32))
        *_, i_ref = reference.step(np.array(action, dtype=np.float32))
        assert i_fast["draw_seed"] == i_ref["draw_seed"]
        differ = sum(abs(i_fast["outcomes"][k] - i_ref["outcomes"][k])
                     for k in i_ref["outcomes"])
        assert differ <= 2, (i_fast["outcomes"], i_ref["outcomes"])  # one draw moved: 2
    fast.close()
    reference.close()


@pytest.fixture(scope="module")
def stepped_envs():
    import gymnasium as gym

    import kinegrasp_env  # noqa: F401

    envs = {"multi": gym.make("KineGrasp-v0", n_draws=4).unwrapped,
            "select": gym.make("KineGraspSelect-v0", n_draws=4).unwrapped,
            "bins": gym.make("KineGraspSelect-v0", n_draws=4, action_bins=4).unwrapped}
    for env in envs.values():
        env.reset(seed=0, options={"object": "cube", "grasp": 0, "sigma": 0.01})
    yield envs
    for env in envs.values():
        env.close()


@pytest.mark.parametrize(("which", "action", "wrong"), [
    ("multi", float("nan"), "got shape ()"),
    ("multi", [float("nan"), 0.0], "(not finite)"),
    ("multi", 0.5, "got shape ()"),
    ("multi", [0.1, 0.2, 0.3], "got shape (3,)"),
    ("multi", [[0.1, 0.2]], "got shape (1, 2)"),
    ("multi", [1.5, 0.0], "[1.5, 0.0] (outside [-1, 1])"),
    ("multi", ["left", "done"], "got ['left', 'done']"),
    ("select", [0.2, 0.3], "got shape (2,)"),
    ("select", [-1.01], "(outside [-1, 1])"),
])
def test_a_bad_action_is_one_line_naming_shape_and_range(stepped_envs, which, action, wrong):
    """NaN, a scalar, a wrong shape, an entry outside [-1, 1], text: a one-line ValueError
    that names the expected shape and range and what was wrong (was: "cannot convert float
    NaN to integer", "index 1 is out of bounds", a (3,) action accepted)."""
    shape = "(2,)" if which == "multi" else "(1,)"
    with pytest.raises(ValueError) as caught:
        stepped_envs[which].step(action)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(f"the action must be a float array of shape {shape} in [-1, 1]")
    assert wrong in message


@pytest.mark.parametrize("action", [4, -1, 1.5, [1, 2]])
def test_a_bad_discrete_action_names_the_bins(stepped_envs, action):
    with pytest.raises(ValueError, match=r"outside Discrete\(4\): the action must be an "
                                         r"integer in 0\.\.3"):
        stepped_envs["bins"].step(action)


def test_good_actions_still_step(stepped_envs):
    """The checks refuse nothing the action space holds (its own samples, its bounds)."""
    import numpy as np

    for env in stepped_envs.values():
        env.action_space.seed(0)
        space = env.action_space
        bounds = (space.high, space.low) if hasattr(space, "high") else (0, space.n - 1)
        for action in (space.sample(), *bounds):
            if isinstance(action, np.ndarray) and space.shape == (2,):
                action = action.copy()
                action[1] = -1.0  # keep the episode going
            env.reset(seed=0)  # (an ended episode refuses a step)
            env.step(action)


# ------------------------------------------------------------------ one grasp-file schema
def _write(path, payload) -> str:
    import json

    path.write_text(json.dumps(payload))
    return str(path)


def test_a_grasp_file_written_from_the_readme_table_is_read(tmp_path, capsys):
    """A file with the table's fields only (``object`` once at the top, entries with ``id``
    and ``q0``) is read and evaluated; the palm pose left out is the palm at q0, equal to
    the one the shipped file records for the same q0 (its own planner's value, 1e-9 m/rad);
    contacts default to none, Q to 0."""
    import json

    import numpy as np

    from kinegrasp_env.world.grasps import load_grasps, shipped_grasps

    shipped = shipped_grasps("cube")[:2]
    path = _write(tmp_path / "g.json", {"object": "cube", "grasps": [
        {"id": "first", "q0": shipped[0].q0.tolist()}, {"q0": shipped[1].q0.tolist()}]})
    grasps = load_grasps(path)
    assert [g.id for g in grasps] == ["first", "1"] and {g.object for g in grasps} == {"cube"}
    for read, ref in zip(grasps, shipped, strict=True):
        np.testing.assert_allclose(read.palm_pose, ref.palm_pose, atol=1e-9, rtol=0)
        assert read.points.shape == (0, 3) and read.q_nominal == 0.0
    assert main(["evaluate", "--grasps", path, "--grasp", "first", "--samples", "20",
                 "--engine", "fast", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["samples"] == 20


@pytest.mark.parametrize(("entry", "needle"), [
    ({}, "grasp 0: field 'q0' missing (14 joint values, radians or metres: 7 arm, then 7 hand)"),
    ({"id": "a", "q0": [0.0] * 3}, "grasp 0 (id 'a'): field 'q0': q0 must have 14 entries"),
    ({"q0": "zero"}, "grasp 0: field 'q0': expected 14 joint values"),
    ({"object": "teapot", "q0": []}, "grasp 0: field 'object': unknown object 'teapot'"),
    ({"q0": None, "palm_pose": 1}, "grasp 0: field 'q0': q0 must have 14 entries"),
    ({"SHIPPED": True, "palm_pose": [[1, 0], [0, 1]]},
     "grasp 0: field 'palm_pose': must be a finite 4x4 matrix, got shape (2, 2)"),
    ({"SHIPPED": True, "contacts": [{"point": [0, 0], "normal": [0, 0, 1]}]},
     "grasp 0: field 'contacts' entry 0: field 'point': expected 3 finite numbers"),
    ({"SHIPPED": True, "contacts": {"point": 1}}, "grasp 0: field 'contacts': must be a list"),
    ({"SHIPPED": True, "q_nominal": "high"}, "grasp 0: field 'q_nominal': must be a finite"),
    ({"SHIPPED": True, "meta": [1]}, "grasp 0: field 'meta': must be an object"),
])
def test_a_bad_entry_names_the_entry_and_the_field(tmp_path, entry, needle):
    """Every malformed field is refused in one line that names the file, the entry (with its
    id when it has one) and the field (was: "missing or malformed field ('object')" for a
    file whose top level named the object)."""
    from kinegrasp_env.world.grasps import load_grasps, shipped_grasps

    if entry.pop("SHIPPED", False):
        entry = {"q0": shipped_grasps("cube")[0].q0.tolist(), **entry}
    path = _write(tmp_path / "g.json", {"object": "cube", "grasps": [entry]})
    with pytest.raises(ValueError) as caught:
        load_grasps(path)
    message = str(caught.value)
    assert "\n" not in message and message.startswith(f"{path} ") and needle in message


def test_the_documented_table_lists_every_field_the_reader_takes():
    """The schema is documented once: every field name the reader looks up in an entry is a
    row of the palm-poses guide's grasp-file table, and every row is a field that some reader
    takes."""
    import re

    from kinegrasp_env.world import grasps

    readme = (Path(__file__).resolve().parent.parent / "docs" / "guides" / "palm-poses.md"
              ).read_text()
    table = readme[readme.index("| field | where | meaning, units, frame |"):]
    table = table[:table.index("\n\n")]
    documented = set(re.findall(r"`([a-z_0-9]+)`", "\n".join(
        line.split("|")[1] for line in table.splitlines()[2:])))
    source = Path(grasps.__file__).read_text()
    reader = source[source.index("    def from_dict"):source.index("def palm_pose_fields")]
    read = set(re.findall(r"data(?:\.get)?\(?\[?\"([a-z_0-9]+)\"", reader))
    read |= set(re.findall(r"_array_field\(data, \"([a-z_0-9]+)\"", reader))
    assert read <= documented, read - documented
    palm_pose_only = {"position", "quaternion", "pose", "hand", "spread", "elbow", "frame"}
    assert documented - read <= palm_pose_only, documented - read


# ------------------------------------------------------------------ objects add
def _box(path: Path, drop_faces: int = 0) -> Path:
    """A 5 cm box (12 triangles) as STL, with its last ``drop_faces`` triangles removed."""
    import trimesh

    box = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    mesh = trimesh.Trimesh(box.vertices, box.faces[:len(box.faces) - drop_faces], process=False)
    mesh.export(path)
    return path


def test_an_open_mesh_is_warned_about_with_what_the_import_does(tmp_path, caplog):
    """A box without its top (two triangles removed: 4 border edges, an independent count
    of a box's square top) is refused nothing but warned about in one record: how many
    edges are open, that the decomposition remeshes it into a closed solid, slowly, and how
    to check the result; a closed box gives no warning."""
    import logging

    from kinegrasp_env.world.importer import prepare
    from kinegrasp_env.world.meshfile import load_source
    from kinegrasp_env.world.meshprep import open_edges

    caplog.set_level(logging.WARNING, logger="kinegrasp_env.world.importer")
    open_box = _box(tmp_path / "open.stl", drop_faces=2)
    prepared = prepare(load_source(open_box), 1.0, open_box)
    assert open_edges(prepared.mesh) == (4, 0)
    [record] = caplog.records
    text = record.getMessage()
    assert "\n" not in text and "not closed (4 edges on a hole or an open border, 0 " in text
    assert "remeshes it into a closed solid" in text and "kinegrasp objects show" in text
    caplog.clear()
    closed = _box(tmp_path / "closed.stl")
    assert open_edges(prepare(load_source(closed), 1.0, closed).mesh) == (0, 0)
    assert caplog.records == []


def test_an_import_reports_each_stage(tmp_path, monkeypatch, capsys):
    """``objects add`` off a terminal: one line as each stage begins (decomposition,
    deviation, grid), in order, and the import's own result after; the stages are the
    importer's (``STAGES``)."""
    from kinegrasp_env.world import importer

    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    importer.forget()
    assert main(["objects", "add", str(_box(tmp_path / "box.stl")), "--name", "box5"]) == 0
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert lines == [f"  stage {k + 1}/3: {stage}" for k, stage in enumerate(importer.STAGES)]
    assert out.startswith("box5: 1 convex part, ")
    importer.forget()


# ------------------------------------------------------------------ notebooks
def test_notebooks_write_only_into_an_ignored_folder():
    """Every relative file or folder path a notebook's code names (string literals ending
    in a file extension or naming an ``out`` folder; inputs that exist in the repository,
    like the committed policy, excepted) lies below ``out/``, which the setup cell creates and
    git ignores in ``notebooks/`` (asked of git itself: ``git check-ignore``). Executing the
    notebooks then changes no tracked file."""
    import ast
    import json
    import re

    root = Path(__file__).resolve().parent.parent
    folder = root / "notebooks"
    written = re.compile(r"^(out\b|[\w./{}-]+\.(csv|json|png|md|html|txt|npz)$)")
    checked = 0
    for nb in sorted(folder.glob("*.ipynb")):
        cells = json.loads(nb.read_text())["cells"]
        code = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
        tree = ast.parse("\n".join(line for line in code.splitlines()
                                   if not line.lstrip().startswith(("%", "!"))))
        for node in ast.walk(tree):
            if isinstance(node, ast.JoinedStr):
                text = "".join(v.value if isinstance(v, ast.Constant) else "{}"
                               for v in node.values)
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                text = node.value
            else:
                continue
            if "\n" in text or " " in text or not written.match(text) or text.startswith("/"):
                continue
            if text.startswith("{}") or (root / text).exists():
                continue  # a path built on one already checked, or an input
            checked += 1
            assert text == "out" or text.startswith("out/"), f"{nb.name} writes {text!r}"
        assert 'os.makedirs("out", exist_ok=True)' in code, nb.name
    assert checked >= 10
    ignored = subprocess.run(["git", "check-ignore", "-q", "notebooks/out/fig7/fig7.csv"],
                             cwd=root, check=False)
    assert ignored.returncode == 0


# ------------------------------------------------------------------ what the output says
def test_sweep_names_the_figures_it_wrote(tmp_path, capsys):
    """The sweep's last line names each figure it wrote (one per noise x engine), every one
    a file that exists, and no placeholder like ``<noise>`` (was: the literal
    ``pfc_vs_sigma_<noise>_<engine>.png``)."""
    spec = tmp_path / "spec.yaml"
    spec.write_text("objects: [cube]\ngrasps: [0]\nsigmas: [0.0133]\n"
                    "noise: [gaussian, uniform]\nengines: [fast]\nsamples: 20\nchunk: 10\n"
                    "seed: 0\n")
    out = tmp_path / "sweep"
    assert main(["sweep", str(spec), "--out", str(out), "--processes", "1"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert "<" not in last and ">" not in last
    assert last.endswith(f"written in {out}: summary.csv, summary.txt, "
                         "pfc_vs_sigma_gaussian_fast.png, pfc_vs_sigma_uniform_fast.png")
    for name in last.split(": ", 1)[1].split(", "):
        assert (out / name).is_file(), name


def test_counts_take_the_singular_for_one(capsys):
    """"1 angles" and the like: a count of one takes the singular word."""
    from kinegrasp_env.cli.common import plural

    assert [plural(n, "angle") for n in (0, 1, 2)] == ["0 angles", "1 angle", "2 angles"]
    assert main(["planar", "--links", "2", "--q0", "0,1"]) == 2
    assert "--links has 1 length but --q0 has 2 angles" in capsys.readouterr().err


def test_evaluate_says_what_each_number_is(capsys):
    """``evaluate``'s lines carry units and meanings: sigma in radians, Q named (Ferrari-
    Canny, dimensionless, its moments over the force-closure draws) and "error" spelled out
    as nominal - mean, which it is (checked against the JSON's own two numbers)."""
    import json

    argv = ["evaluate", "--object", "cube", "--grasp", "0", "--samples", "40", "--engine",
            "fast"]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == ("cube grasp 0 of robot kuka_sdh, sigma = 0.0133 rad (gaussian), 40 "
                        "draws, friction mu 0.5")
    q_line = lines[2]
    assert q_line.startswith("  Q (Ferrari-Canny, dimensionless, point contacts; mean, std, "
                             "skewness over the force-closure draws): nominal ")
    assert main([*argv, "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    error = float(q_line.rsplit("error (nominal - mean) ", 1)[1])
    assert error == pytest.approx(stats["q_nominal"] - stats["q_mean"], abs=5e-6)


def test_elbow_names_a_file_grasp_by_its_id(tmp_path, capsys):
    """``elbow --grasps FILE --grasp ID``: the summary names the grasp by the id it was chosen
    by (it said "grasp 1", the grasp's place in the file, where the JSON and the page say its
    id); a shipped grasp keeps its index."""
    import dataclasses

    from kinegrasp_env.world.grasps import save_grasps, shipped_grasps

    grasp = dataclasses.replace(shipped_grasps("cube", "panda")[1], id="side_pinch")
    path = save_grasps([shipped_grasps("cube", "panda")[0], grasp], tmp_path / "g.json")
    argv = ["elbow", "--grasps", str(path), "--grasp", "side_pinch", "--samples", "6",
            "--engine", "fast"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "cube grasp side_pinch of robot panda, sigma = " in out, out
    assert main(["elbow", "--robot", "panda", "--object", "cube", "--grasp", "1", "--samples",
                 "6", "--engine", "fast"]) == 0
    assert "cube grasp 1 of robot panda, sigma = " in capsys.readouterr().out
    # the JSON records the figure it wrote, as rank's records its CSV
    plot = tmp_path / "elbow.png"
    assert main([*argv, "--json", "--plot", str(plot)]) == 0
    assert json.loads(capsys.readouterr().out)["plot"] == str(plot) and plot.exists()


def test_the_rank_table_widens_to_its_longest_id(tmp_path, capsys):
    """A candidate id longer than the id column's 8 characters pushed its row out of line."""
    import dataclasses

    from kinegrasp_env.world.grasps import save_grasps, shipped_grasps

    grasps = [dataclasses.replace(g, id=name) for g, name in
              zip(shipped_grasps("cube")[:2], ("a", "a_much_longer_candidate_id"), strict=True)]
    path = save_grasps(grasps, tmp_path / "g.json")
    assert main(["rank", str(path), "--samples", "4", "--engine", "fast", "--out",
                 str(tmp_path / "r.csv")]) == 0
    table = capsys.readouterr().out.splitlines()[:3]
    ends = {line.index("P(FC)") + len("P(FC)") if i == 0 else line.index(".") + 4
            for i, line in enumerate(table)}
    assert len(ends) == 1, table


def test_evaluate_shows_no_nan_for_moments_of_too_few_draws(capsys):
    """One draw at sigma 0 (one force-closure draw): Q's std and skewness are undefined; the
    line shows '-' and says how many draws there were, not 'nan'."""
    assert main(["evaluate", "--object", "cube", "--grasp", "0", "--sigma", "0", "--samples",
                 "1", "--engine", "fast"]) == 0
    line = capsys.readouterr().out.splitlines()[2]
    assert "nan" not in line and "(1 of them: '-' where too few or all equal)" in line, line
    assert ", std -, skewness -, error (nominal - mean) 0.00000" in line, line


def test_a_short_run_ends_with_its_mean_rate():
    """A run done within MIN_WINDOW (four cells of 100 draws, 0.2 s apart) ends its last
    line with the mean rate over its reports (300 draws in 0.6 s: 500 draws/s), not "rate
    being measured"; work that came back at once stays unmeasured (above)."""
    clock, stream = Clock(), io.StringIO()
    report = Progress("table1", 400, 4, stream=stream, interactive=False, clock=clock)
    for cell in range(4):
        clock.now += 0.2
        report.advance(100 * (cell + 1))
        report.cell_done(f"cell {cell}: P(FC) 0.500")
    lines = stream.getvalue().splitlines()
    assert lines[-2].endswith("rate being measured"), lines
    assert lines[-1].endswith("400/400 draws, 500 draws/s, ETA 00:00"), lines


def test_a_tiny_negative_error_prints_as_zero(capsys):
    """``evaluate``'s error (nominal - mean) of a grasp whose draws all close as its nominal
    one is a rounding difference, -1e-12: it printed "-0.00000"."""
    from kinegrasp_env.cli.evaluation_output import Evaluation, print_evaluation

    print_evaluation(Evaluation("cube grasp 0", "sigma 0", 3, 0.5, "point", 1.0, (0.4, 1.0),
                                0.05, 0.05 + 1e-12, 0.0, float("nan"),
                                {"force_closure": 3}))
    out = capsys.readouterr().out
    assert "error (nominal - mean) 0.00000" in out and "-0.0" not in out, out
