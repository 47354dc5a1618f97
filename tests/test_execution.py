"""The execution layer: local pool and Ray give the same numbers, and survive dead workers."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import pytest

from kinegrasp_env.cli import main
from kinegrasp_env.montecarlo.execution import MAX_ATTEMPTS, LocalExecutor, make_executor
from kinegrasp_env.world.grasps import save_grasps, shipped_grasps


def _square(x: int) -> int:
    return x * x


def _die_once(task: tuple[int, str]) -> int:
    """Kill the worker process the first time a marker file is missing (then create it)."""
    value, marker = task
    if marker and not os.path.exists(marker):
        Path(marker).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return value * 10


def _always_die(task: int) -> int:
    os.kill(os.getpid(), signal.SIGKILL)
    return task


@pytest.mark.parametrize("processes", [1, 3])
def test_local_map_keeps_task_order_and_as_completed_covers_every_task(processes):
    tasks = list(range(20))
    with LocalExecutor(processes) as ex:
        assert list(ex.map(_square, tasks)) == [t * t for t in tasks]
        pairs = list(ex.as_completed(_square, tasks))
    assert sorted(pairs) == [(t, t * t) for t in tasks]


def test_local_pool_reruns_the_tasks_of_a_killed_worker(tmp_path, capsys):
    tasks = [(i, str(tmp_path / "died") if i == 5 else "") for i in range(12)]
    with LocalExecutor(2) as ex:
        assert list(ex.map(_die_once, tasks)) == [10 * i for i in range(12)]
    assert (tmp_path / "died").exists()
    assert "worker process died" in capsys.readouterr().err


def test_a_task_that_always_kills_its_worker_is_an_error_not_a_loop():
    with LocalExecutor(2) as ex, pytest.raises(RuntimeError, match=f"died {MAX_ATTEMPTS} times"):
        list(ex.map(_always_die, [1, 2]))


def test_bad_backend_settings_are_clear():
    with pytest.raises(ValueError, match="unknown backend 'spark'"):
        make_executor("spark")
    with pytest.raises(ValueError, match="processes must be an integer >= 1, got 0"):
        make_executor("local", 0)
    with pytest.raises(ValueError, match="--address is for the ray backend"):
        make_executor("local", 1, "ray://head:10001")


@pytest.mark.parametrize("count", [0, -3, 2.5, True, "2"])
def test_a_count_of_workers_is_checked_alike_before_ray_starts(monkeypatch, count):
    """Processes and Ray CPUs go through one check (an integer >= 1), in one line naming
    the value, before Ray is imported (a Ray that would start fails the test): Ray itself
    took 0 for all CPUs and raised its own errors deep inside for -3 and 2.5."""
    from kinegrasp_env.montecarlo import execution

    def no_ray():
        raise AssertionError("Ray was started before num_cpus was checked")

    monkeypatch.setattr(execution, "_import_ray", no_ray)
    for make, name in ((lambda: LocalExecutor(count), "processes"),
                       (lambda: execution.RayExecutor(num_cpus=count), "num_cpus")):
        with pytest.raises(ValueError, match=rf"^{name} must be an integer >= 1, got "):
            make()


def test_missing_ray_names_the_extra(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    path = save_grasps(shipped_grasps("cube")[:2], tmp_path / "c.json")
    code = main(["rank", str(path), "--samples", "10", "--backend", "ray",
                 "--out", str(tmp_path / "r.csv")])
    assert code == 2
    assert "pip install 'kinegrasp-env[ray]'" in capsys.readouterr().err
    assert not (tmp_path / "r.csv").exists()


@pytest.fixture(scope="module")
def local_ray():
    """A local Ray instance with 2 CPUs, shared by this module's Ray tests."""
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.mark.expensive
def test_rank_csv_is_byte_identical_on_every_backend(tmp_path, local_ray):
    path = save_grasps(shipped_grasps("cube")[:3], tmp_path / "cube.json")
    outputs = {}
    for name, extra in {"local1": ["--processes", "1"], "local2": ["--processes", "2"],
                        "ray": ["--backend", "ray"]}.items():
        out = tmp_path / f"{name}.csv"
        assert main(["rank", str(path), "--sigma", "0.02", "--samples", "300", "--engine",
                     "fast", "--seed", "3", "--out", str(out), *extra]) == 0
        outputs[name] = out.read_bytes()
    assert outputs["local1"] == outputs["local2"] == outputs["ray"]
    assert outputs["local1"].count(b"\n") == 4


def _ray_workers_running(task_name: str) -> list[int]:
    """PIDs of Ray worker processes whose title says they are running ``task_name``."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            title = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="ignore")
        except OSError:
            continue
        if title.startswith(f"ray::{task_name}"):
            pids.append(int(entry.name))
    return pids


@pytest.mark.expensive
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sweep_survives_a_ray_worker_killed_mid_task(tmp_path, local_ray):
    import threading
    import time

    from kinegrasp_env.montecarlo.execution import RayExecutor
    from kinegrasp_env.montecarlo.sweep import SweepSpec, run_sweep

    spec = SweepSpec.from_dict({"objects": ["cube"], "grasps": [0, 1], "sigmas": [0.01, 0.03],
                                "engines": ["pybullet"], "samples": 120, "chunk": 30})
    killed: list[int] = []
    stop = threading.Event()

    def killer() -> None:
        while not stop.is_set() and not killed:
            pids = _ray_workers_running("run_task")
            if pids:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])
            time.sleep(0.01)

    thread = threading.Thread(target=killer)
    thread.start()
    try:
        with RayExecutor() as ex:
            ray_rows, ran, _ = run_sweep(spec, tmp_path / "ray", ex, progress=False)
    finally:
        stop.set()
        thread.join()
    assert killed, "no Ray worker was caught running a task"
    assert ran == len(spec.tasks())
    with LocalExecutor(1) as ex:
        local_rows, _, _ = run_sweep(spec, tmp_path / "local", ex, progress=False)
    assert (tmp_path / "ray" / "summary.csv").read_bytes() == \
        (tmp_path / "local" / "summary.csv").read_bytes()
    assert [r["p_fc"] for r in ray_rows] == [r["p_fc"] for r in local_rows]
    assert ray_rows[0]["samples"] == 120


def test_unreachable_ray_address_fails_fast_and_clearly(capsys):
    import socket

    pytest.importorskip("ray")
    with socket.socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    code = main(["evaluate", "--object", "cube", "--samples", "10", "--backend", "ray",
                 "--address", f"127.0.0.1:{port}"])
    assert code == 2
    assert f"cannot reach a Ray cluster at '127.0.0.1:{port}'" in capsys.readouterr().err
    with pytest.raises(ValueError, match="must be host:port"):
        make_executor("ray", None, "nonsense")


def _worker_signals(_task) -> tuple:
    return signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)


def test_workers_leave_ctrl_c_to_the_parent():
    """A pool's workers ignore SIGINT (Ctrl-C, sent by a terminal to every process of the
    job, is the parent's to handle: it stops the pool) and end plainly on SIGTERM (not
    through the command's handler, which a forked worker would inherit)."""
    # as in a terminal, with the command's SIGTERM handler (a background job, as a CI run
    # is, starts with SIGINT ignored already)
    previous = (signal.signal(signal.SIGTERM, lambda *_: None),
                signal.signal(signal.SIGINT, signal.default_int_handler))
    try:
        with LocalExecutor(2) as ex:
            seen = set(ex.map(_worker_signals, range(4)))
    finally:
        signal.signal(signal.SIGTERM, previous[0])
        signal.signal(signal.SIGINT, previous[1])
    assert seen == {(signal.SIG_IGN, signal.SIG_DFL)}


def _sleep_long(_task) -> int:
    import time

    time.sleep(60)
    return 0


def test_a_run_stopped_by_ctrl_c_ends_its_workers_at_once():
    """Ctrl-C (KeyboardInterrupt) in the middle of a pool's run: leaving the executor ends
    its workers (SIGTERM) instead of waiting for their tasks; before, a shut-down after a
    signal could leave the workers waiting on the pool's queue and the command's exit
    waiting on them for good (about 1 Ctrl-C in 6). What this checks is the mechanism: the
    workers are gone within seconds although their tasks sleep a minute."""
    import time

    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt), LocalExecutor(2) as ex:
        ex._submit(_sleep_long, 0, None)
        ex._submit(_sleep_long, 1, None)
        processes = list(ex._pool_now()._processes.values())
        time.sleep(0.5)  # the workers have taken their tasks
        raise KeyboardInterrupt
    assert time.monotonic() - start < 15
    assert processes and not any(p.is_alive() for p in processes)
