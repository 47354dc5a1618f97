"""``kinegrasp sweep``: spec validation, numbers equal to evaluate_grasp, resume after a kill."""

from __future__ import annotations

import csv
import math
import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from kinegrasp_env.cli import main
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.montecarlo.sweep import SpecError, SweepSpec, run_sweep
from kinegrasp_env.toolkit.plots import plot_sweep
from kinegrasp_env.world.grasps import grasp_by_index

BASE = {"objects": ["cube"], "grasps": [0], "sigmas": [0.01]}


@pytest.mark.parametrize(("change", "message"), [
    ({"objects": ["teapot"]}, "unknown object 'teapot'"),
    ({"sigmas": [0.01, -0.02]}, "sigma must be finite and >= 0, got -0.02"),
    ({"sigmas": ["big"]}, "sigma 'big' is not a number"),
    ({"colour": "red"}, "unknown key 'colour'"),
    ({"grasps": [0, 40]}, "grasp 40 does not exist for cube"),
    ({"noise": ["cauchy"]}, "unknown noise 'cauchy'"),
    ({"engines": ["gpu"]}, "unknown engine 'gpu'"),
    ({"samples": 0}, "'samples' must be an integer >= 1, got 0"),
    ({"sigmas": []}, "'sigmas' is empty"),
    ({"sigmas": [0.01, 3.5]}, "sigma must be <= pi (3.14159 rad), got 3.5"),
    ({"objects": ["cube", "mug", "cube"]}, "'cube' appears twice in 'objects'"),
    ({"grasps": [0, 1, 0]}, "0 appears twice in 'grasps'"),
    # the one word 'grasps' takes besides indices is named
    ({"grasps": [0, "all"]}, "'grasps' must be \"all\" or a list of grasp indices (integers "
                             ">= 0), got "),
    ({"grasps": "none"}, "'grasps' must be \"all\" or a list of grasp indices"),
    ({"sigmas": [0.01, 0.02, 0.010]}, "0.01 appears twice in 'sigmas'"),
    ({"noise": ["uniform", "uniform"]}, "'uniform' appears twice in 'noise'"),
    ({"engines": ["fast", "pybullet", "fast"]}, "'fast' appears twice in 'engines'"),
])
def test_bad_specs_are_named(change, message):
    with pytest.raises(SpecError, match=message.replace("(", r"\(").replace(")", r"\)")):
        SweepSpec.from_dict({**BASE, **change})


def test_a_folder_given_as_the_spec_is_named(tmp_path):
    with pytest.raises(SpecError, match=f"{tmp_path}: is a folder, not a file"):
        SweepSpec.from_file(tmp_path)


def test_missing_key_and_non_mapping():
    with pytest.raises(SpecError, match="missing key 'sigmas'"):
        SweepSpec.from_dict({"objects": ["cube"]})
    with pytest.raises(SpecError, match="expected a mapping"):
        SweepSpec.from_dict(["cube"])


def test_bad_spec_file_fails_before_any_work(tmp_path, capsys):
    spec = tmp_path / "bad.yaml"
    spec.write_text("objects: [cube, teapot]\nsigmas: [0.01]\n")
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown object 'teapot'" in err[0]
    assert not out.exists()


def test_yaml_numbers_with_an_exponent_are_numbers(tmp_path):
    """YAML 1.1 reads ``1e-2`` (no decimal point) and ``2.5e3`` (no sign) as strings; a spec
    reads them as numbers, as YAML 1.2 and JSON do."""
    path = tmp_path / "spec.yaml"
    path.write_text("objects: [cube]\ngrasps: [0]\nsigmas: [1e-2, 2.5E-2, .5e-1, 0.001, 0]\n"
                    "samples: 2e3\nchunk: 5E+2\n")
    spec = SweepSpec.from_file(path)
    assert spec.sigmas == (0.01, 0.025, 0.05, 0.001, 0.0)
    assert (spec.samples, spec.chunk) == (2000, 500)  # whole numbers count as integers
    path.write_text("objects: [cube]\nsigmas: [0.01]\nsamples: 2.5e2\nchunk: 1e-2\n")
    with pytest.raises(SpecError, match=r"'chunk' must be an integer >= 1, got 0\.01"):
        SweepSpec.from_file(path)
    path.write_text("objects: [cube]\nsigmas: [1e-2, 0.01]\n")
    with pytest.raises(SpecError, match=r"0\.01 appears twice in 'sigmas'"):
        SweepSpec.from_file(path)


@pytest.mark.parametrize(("text", "where", "what"), [
    # the ':' after 'sigmas' (line 2, column 7) is where the unclosed '[' of line 1 fails
    ("objects: [cube\nsigmas: [0.01]\n", "2:7", "expected ',' or ']', but got ':'"),
    # the indented 'samples' (line 3, column 3) cannot continue the mapping
    ("objects: [cube]\nsigmas: [0.01]\n  samples: 3\n", "3:3", "expected <block end>"),
    ("objects: [cube]\nsigmas: [0.01]\nsigmas: [0.02]\n", "3:1",
     "key 'sigmas' appears twice"),
])
def test_a_yaml_error_is_one_line_with_file_line_and_column(tmp_path, capsys, text, where,
                                                            what):
    spec = tmp_path / "spec.yaml"
    spec.write_text(text)
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"kinegrasp sweep: error: {spec}:{where}: not valid YAML: {what}")
    assert not (tmp_path / "out").exists()


def test_grid_and_task_keys():
    spec = SweepSpec.from_dict({"objects": ["cube", "mug"], "grasps": [1, 2],
                                "sigmas": [0.01, 0.02, 0.03], "noise": ["gaussian", "uniform"],
                                "samples": 100, "chunk": 30})
    assert len(spec.cells()) == 2 * 2 * 3 * 2
    tasks = spec.tasks()
    assert len(tasks) == len(spec.cells()) * 4
    assert len({t.key for t in tasks}) == len(tasks)
    assert [t.size for t in tasks[:4]] == [30, 30, 30, 10]
    assert len(SweepSpec.from_dict({"objects": ["cube"], "sigmas": [0.0]}).cells()) == 12


def test_cells_equal_evaluate_grasp_and_a_rerun_computes_nothing(tmp_path):
    spec = SweepSpec.from_dict({"objects": ["cube"], "grasps": [0, 2], "sigmas": [0.0, 0.02],
                                "noise": ["gaussian", "triangular"], "engines": ["fast"],
                                "samples": 90, "chunk": 40, "seed": 5})
    with LocalExecutor(2) as ex:
        rows, ran, skipped = run_sweep(spec, tmp_path, ex, progress=False)
    assert (ran, skipped) == (len(spec.tasks()), 0)
    for row in rows:
        # the rows evaluate draws (in its own chunks of 250): the sweep's chunks of 40 are
        # rows of the same run
        stats = evaluate_grasp(grasp_by_index("cube", row["grasp"]), sigma=row["sigma"],
                               noise=row["noise"], n=90, seed=5, engine="fast")
        assert row["p_fc"] == stats.p_fc
        assert row["samples"] == stats.n == 90
        assert (row["q_mean"] == pytest.approx(stats.q_mean, rel=1e-12) or
                (math.isnan(row["q_mean"]) and math.isnan(stats.q_mean)))
        if stats.counts["force_closure"] > 1:  # moments merged in another order
            assert row["q_std"] == pytest.approx(stats.q_std, rel=1e-9)
    first = (tmp_path / "summary.csv").read_bytes()
    with LocalExecutor(1) as ex:
        _, ran, skipped = run_sweep(spec, tmp_path, ex, progress=False, plot=plot_sweep)
    assert (ran, skipped) == (0, len(spec.tasks()))
    assert (tmp_path / "summary.csv").read_bytes() == first
    assert (tmp_path / "pfc_vs_sigma_triangular_fast.png").stat().st_size > 0


def test_an_older_default_robot_store_in_chunks_of_250_is_extended(tmp_path):
    """A store of the default robot by an older kinegrasp records no robot and the plain
    layout; its draws came in the spec's chunks, which at the default chunk of 250 are the
    rows every robot's cells now are: it is extended (nothing recomputed, the same summary),
    and marked with the layout an older kinegrasp refuses; at another chunk it is refused."""
    import json

    from kinegrasp_env.montecarlo.sweep import SWEEP_LAYOUT
    from kinegrasp_env.sampling.noise_model import DRAW_LAYOUT

    spec = SweepSpec.from_dict({"objects": ["cube"], "grasps": [0], "sigmas": [0.02],
                                "engines": ["fast"], "samples": 20})
    assert spec.chunk == 250
    with LocalExecutor(1) as ex:
        run_sweep(spec, tmp_path, ex, progress=False)
        first = (tmp_path / "summary.csv").read_bytes()
        with sqlite3.connect(tmp_path / "results.sqlite") as db:
            db.execute("DELETE FROM meta WHERE key = 'robot'")
            db.execute("UPDATE meta SET value = ? WHERE key = 'draw_layout'",
                       (json.dumps(DRAW_LAYOUT),))
        _, ran, skipped = run_sweep(spec, tmp_path, ex, progress=False)
        assert (ran, skipped) == (0, 1) and (tmp_path / "summary.csv").read_bytes() == first
        with sqlite3.connect(tmp_path / "results.sqlite") as db:
            meta = dict(db.execute("SELECT key, value FROM meta").fetchall())
        assert json.loads(meta["draw_layout"]) == SWEEP_LAYOUT
        assert json.loads(meta["robot"]) == "kuka_sdh"
        other = tmp_path / "other"
        run_sweep(SweepSpec.from_dict({**asdict_spec(spec), "chunk": 10}), other, ex,
                  progress=False)
        with sqlite3.connect(other / "results.sqlite") as db:
            db.execute("DELETE FROM meta WHERE key = 'robot'")
        with pytest.raises(SpecError, match="random draws came in the spec's chunks"):
            run_sweep(SweepSpec.from_dict({**asdict_spec(spec), "chunk": 10}), other, ex,
                      progress=False)


def test_physics_cells_of_another_physics_model_are_refused(tmp_path):
    """A store whose physics-engine cells another version's physics made (it records no
    physics model, or another) is refused in one line, not extended with this version's
    cells; its kinematic cells alone are no reason to refuse it."""
    spec = SweepSpec.from_dict({"objects": ["cube"], "grasps": [0], "sigmas": [0.02],
                                "engines": ["physics"], "samples": 2})
    with LocalExecutor(1) as ex:
        run_sweep(spec, tmp_path, ex, progress=False)
        assert run_sweep(spec, tmp_path, ex, progress=False)[1:] == (0, 1)  # same model: reused
    # a physics cell's nominal Q is the physics closing's, as evaluate's
    row = next(csv.DictReader((tmp_path / "summary.csv").open()))
    alone = evaluate_grasp(grasp_by_index("cube", 0), sigma=0.02, n=2, seed=0,
                           engine="physics")
    assert float(row["q_nominal"]) == pytest.approx(alone.q_nominal, rel=1e-12)
    with LocalExecutor(1) as ex:
        with sqlite3.connect(tmp_path / "results.sqlite") as db:
            db.execute("DELETE FROM meta WHERE key = 'physics_model'")
        with pytest.raises(SpecError, match="physics-engine cells of another physics model"):
            run_sweep(spec, tmp_path, ex, progress=False)
        fast = SweepSpec.from_dict({**asdict_spec(spec), "engines": ["fast"]})
        run_sweep(fast, tmp_path / "fast", ex, progress=False)
        with sqlite3.connect(tmp_path / "fast" / "results.sqlite") as db:
            assert db.execute("SELECT COUNT(*) FROM meta WHERE key = 'physics_model'"
                              ).fetchone()[0] == 0
        assert run_sweep(fast, tmp_path / "fast", ex, progress=False)[1:] == (0, 1)


def asdict_spec(spec: SweepSpec) -> dict:
    """The spec's settings as a spec mapping (the keys this module's tests set)."""
    return {"objects": list(spec.objects), "grasps": [0], "sigmas": list(spec.sigmas),
            "engines": list(spec.engines), "samples": spec.samples}


def test_more_samples_regrow_a_cells_short_last_chunk(tmp_path):
    """20 draws in chunks of 7 (7, 7, 6), then 30 (7, 7, 7, 7, 2): the short chunk is run
    again at its new size and the two new ones added (3 tasks), so the cell has 30 draws
    and equals evaluate_grasp's 30 (it kept the 6-draw chunk: 29 draws)."""
    base = {"objects": ["cube"], "grasps": [0], "sigmas": [0.02], "engines": ["fast"],
            "chunk": 7, "seed": 3}
    with LocalExecutor(1) as ex:
        run_sweep(SweepSpec.from_dict({**base, "samples": 20}), tmp_path, ex, progress=False)
        (row,), ran, skipped = run_sweep(SweepSpec.from_dict({**base, "samples": 30}),
                                         tmp_path, ex, progress=False)
    assert (ran, skipped) == (3, 2) and row["samples"] == 30
    stats = evaluate_grasp(grasp_by_index("cube", 0), sigma=0.02, n=30, seed=3, engine="fast")
    assert row["p_fc"] == stats.p_fc


def test_other_seed_in_the_same_folder_is_refused(tmp_path):
    spec = {"objects": ["cube"], "grasps": [0], "sigmas": [0.01], "engines": ["fast"],
            "samples": 20, "chunk": 20}
    with LocalExecutor(1) as ex:
        run_sweep(SweepSpec.from_dict(spec), tmp_path, ex, progress=False)
        with pytest.raises(SpecError, match="seed = 0, the spec says 1"):
            run_sweep(SweepSpec.from_dict({**spec, "seed": 1}), tmp_path, ex, progress=False)


def _stored_tasks(path) -> list[str]:
    if not path.exists():
        return []
    try:
        with sqlite3.connect(path) as db:
            return [row[0] for row in db.execute("SELECT key FROM tasks")]
    except sqlite3.OperationalError:  # table not created yet
        return []


@pytest.mark.expensive
def test_killed_sweep_resumes_to_the_uninterrupted_result(tmp_path, capsys):
    spec = tmp_path / "spec.yaml"
    spec.write_text("objects: [cube]\ngrasps: [0, 1, 2]\nsigmas: [0.01, 0.02, 0.03]\n"
                    "engines: [pybullet]\nsamples: 200\nchunk: 25\nseed: 2\n")
    total = 3 * 3 * 8
    killed_dir = tmp_path / "killed"
    store = killed_dir / "results.sqlite"
    process = subprocess.Popen(
        [sys.executable, "-m", "kinegrasp_env.cli", "sweep", str(spec), "--out",
         str(killed_dir), "--processes", "2"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while len(_stored_tasks(store)) < 5 and time.monotonic() < deadline:
            assert process.poll() is None, "the sweep ended before it could be interrupted"
            time.sleep(0.02)
    finally:
        os.killpg(process.pid, signal.SIGKILL)  # the driver and its pool, mid-run
        process.wait()
    done_at_kill = len(_stored_tasks(store))
    assert 5 <= done_at_kill < total
    assert not (killed_dir / "summary.csv").exists()

    assert main(["sweep", str(spec), "--out", str(killed_dir), "--processes", "2"]) == 0
    assert f"{total - done_at_kill} tasks run, {done_at_kill} found finished" in \
        capsys.readouterr().out
    keys = _stored_tasks(store)
    assert len(keys) == len(set(keys)) == total

    assert main(["sweep", str(spec), "--out", str(tmp_path / "whole"), "--processes", "1"]) == 0
    assert (killed_dir / "summary.csv").read_bytes() == \
        (tmp_path / "whole" / "summary.csv").read_bytes()


def test_the_documented_example_spec_is_valid_and_shown_verbatim():
    """The sweeps guide shows docs/sweep_example.yaml as it is, and the spec reads."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    path = root / "docs" / "sweep_example.yaml"
    spec = SweepSpec.from_file(path)
    assert len(spec.tasks()) == 2 * 2 * 2 * 10
    assert path.read_text() in (root / "docs" / "guides" / "sweeps.md").read_text()


def test_a_damaged_store_is_one_line(tmp_path, capsys):
    """A ``results.sqlite`` that is no database (a damaged copy, another program's file) is
    refused in one line naming it, not a traceback."""
    spec = tmp_path / "s.yaml"
    spec.write_text("objects: [cube]\ngrasps: [0]\nsigmas: [0.01]\nsamples: 10\n"
                    "engines: [fast]\n")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "results.sqlite").write_text("garbage\n")
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"kinegrasp sweep: error: {tmp_path / 'out' / 'results.sqlite'} "
                              "is not a sweep store kinegrasp can read (file is not a "
                              "database)"), err


def test_a_fixed_friction_beside_a_drawn_one_is_refused(tmp_path, capsys):
    """A noise model that draws mu per draw (docs/noise_example.yaml's friction source) and a
    fixed mu (the spec's ``friction`` or ``--friction``) are refused in one line, as
    ``evaluate`` refuses them: the cells of that model ignored the fixed mu."""
    import shutil
    from pathlib import Path

    shutil.copy(Path(__file__).resolve().parents[1] / "docs" / "noise_example.yaml",
                tmp_path / "nx.yaml")
    body = ("objects: [cube]\ngrasps: [0]\nsigmas: [0.0133]\nnoise: [gaussian, nx.yaml]\n"
            "engines: [fast]\nsamples: 10\n")
    spec = tmp_path / "s.yaml"
    for text, extra, needle in (
            (body, ["--friction", "0.6"], "--friction and the noise spec's friction source "
                                          "both set mu"),
            (body + "friction: 0.6\n", [], "friction and the friction source of noise "
                                           "'nx-")):
        spec.write_text(text)
        assert main(["sweep", str(spec), "--out", str(tmp_path / "out"), *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert needle in err[-1], err
    assert not (tmp_path / "out").exists()


def test_a_spec_without_a_robot_takes_its_grasp_files_robot(tmp_path):
    """A grasp file names its robot, as for ``evaluate``: a spec that names none sweeps the
    robot of its ``grasp_files`` (the Panda's cube grasps: it refused them as grasps of
    another robot than kuka_sdh); the spec's ``robot`` or ``--robot`` still decides, and
    files of two robots leave the default, whose check names the mismatch."""
    from kinegrasp_env.world.grasps import save_grasps, shipped_grasps

    save_grasps(shipped_grasps("cube", "panda")[:2], tmp_path / "panda.json")
    save_grasps(shipped_grasps("drill")[:2], tmp_path / "sdh.json")
    spec = {"objects": ["cube"], "sigmas": [0.01], "grasp_files": {"cube": "panda.json"}}
    assert SweepSpec.from_dict(spec, base=tmp_path).robot == "panda"
    with pytest.raises(SpecError, match="not of 'kuka_sdh'"):
        SweepSpec.from_dict({**spec, "robot": "kuka_sdh"}, base=tmp_path)
    with pytest.raises(SpecError, match="not of 'kuka_sdh'"):
        SweepSpec.from_dict(spec, base=tmp_path, robot="kuka_sdh")
    both = {**spec, "objects": ["cube", "drill"],
            "grasp_files": {"cube": "panda.json", "drill": "sdh.json"}}
    with pytest.raises(SpecError, match="grasp of robot 'panda', not of 'kuka_sdh'"):
        SweepSpec.from_dict(both, base=tmp_path)
    # a file of an object the spec does not sweep decides nothing (it is refused as such)
    other = {**spec, "grasp_files": {"cube": "panda.json", "drill": "sdh.json"}}
    with pytest.raises(SpecError, match="grasp_files names 'drill', which is not in"):
        SweepSpec.from_dict(other, base=tmp_path)
