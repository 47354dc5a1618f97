"""The holding test and ``kinegrasp validate`` of a description robot: the Panda on the cube.

Independent references: the Panda URDF's ``<limit effort>`` read here with ElementTree (the
motor limits the run states); pybullet's contact forces after the grip (each jaw presses the
pinned object with its motor's effort: the normal forces the solver reports, not the value
the code sets); the kinematic reference closing (``RobotWorld.auto_close``, pybullet closest
points and the pad's patch centre, no dynamics) for the physics closing's contacts.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli.main import main
from kinegrasp_env.closing.generic_reference import RobotWorld
from kinegrasp_env.physics.protocol import HoldProtocol
from kinegrasp_env.physics.robot_agreement import closing_agreement
from kinegrasp_env.physics.robot_hold import RobotHold
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.description import parse_description
from kinegrasp_env.world.grasps import save_grasps, shipped_grasps
from kinegrasp_env.world.objects import load_object

PANDA_URDF = asset_path("robots", "panda", "panda.urdf")
PANDA_YAML = asset_path("robots", "panda", "panda.yaml")
JAWS = ("panda_finger_joint1", "panda_finger_joint2")
#: The physics closing's contacts against the kinematic closing's on the shipped cube grasps
#: at sigma 0 (benchmarks/robot_closing_agreement.py): point distances measured at most
#: 2.62 mm (cube grasp 3; 0.73 mm on every other contact), normals at most 0.003 degrees
#: apart. Tolerances: the measured maxima plus 1 mm and plus 0.5 degree.
POINT_TOL = 2.62e-3 + 1.0e-3
ANGLE_TOL = np.radians(0.003 + 0.5)


def urdf_efforts() -> dict[str, float]:
    root = ET.parse(PANDA_URDF).getroot()
    return {j.get("name"): float(j.find("limit").get("effort")) for j in root.findall("joint")
            if j.find("limit") is not None}


def test_validate_panda_cube_holds_at_sigma_zero(capsys, tmp_path):
    status = main(["validate", "--robot", "panda", "--object", "cube", "--sigma", "0",
                   "--samples", "1", "--kinematic-engine", "pybullet", "--json",
                   "--out", str(tmp_path / "out")])
    out, err = capsys.readouterr()
    assert status == 0, err
    summary = json.loads(out)
    assert summary["settings"]["robot"] == "panda"
    efforts = urdf_efforts()
    assert [(m["joint"], m["effort"], m["unit"], m["source"])
            for m in summary["protocol"]["motors"]] == [(j, efforts[j], "N", "urdf")
                                                       for j in JAWS]
    grasps = summary["grasps"]
    assert len(grasps) == len(shipped_grasps("cube", "panda"))
    for g in grasps:
        assert g["p_fc_kinematic"] == 1.0 and g["p_fc_physics"] == 1.0, g
        assert g["draw_outcomes"][0] in ("held", "dropped"), g  # the grip stood
        assert g["phases"]["rest"] == {"run": 1, "held": 1}, g
        assert g["grip_shift_mm"][0] <= 2.0, g
    assert summary["outcomes"]["held"] >= 3  # cube grasps 0-2 hold through every phase


@pytest.fixture(scope="module")
def cube_worlds():
    description, obj = load_robot("panda"), load_object("cube")
    simulator = RobotHold(description, obj, 0.5, HoldProtocol())
    kinematic = RobotWorld(description, obj)
    yield simulator, kinematic
    simulator.close()
    kinematic.close()


def test_physics_contacts_agree_with_kinematic_closing(cube_worlds):
    simulator, kinematic = cube_worlds
    for grasp in shipped_grasps("cube", "panda"):
        agreement = closing_agreement(simulator, kinematic, grasp.q0)
        assert agreement.start_collision == (False, False)
        assert not agreement.physics_only and not agreement.kinematic_only
        assert len(agreement.pairs) == 2  # one contact per jaw
        assert agreement.max_distance <= POINT_TOL, (grasp.id, agreement)
        assert agreement.max_angle <= ANGLE_TOL, (grasp.id, agreement)


def test_jaws_press_with_their_effort_limits(cube_worlds):
    simulator, _ = cube_worlds
    grasp = shipped_grasps("cube", "panda")[0]
    _, result = simulator.run_draw(grasp.q0)
    efforts = urdf_efforts()
    np.testing.assert_allclose(result.forces_gripped, [efforts[j] for j in JAWS], rtol=0.02)


def test_description_efforts_override_the_urdf():
    data = yaml.safe_load(PANDA_YAML.read_text())
    data["efforts"] = {"panda_finger_joint1": 8.0}
    description = parse_description(data, PANDA_YAML)
    simulator = RobotHold(description, load_object("cube"), 0.5, HoldProtocol())
    try:
        assert [(m.joint, m.effort, m.source) for m in simulator.motors] == [
            (j, 8.0, "description") for j in JAWS]  # the mimic jaw takes its driver's
        _, result = simulator.run_draw(shipped_grasps("cube", "panda")[0].q0)
    finally:
        simulator.close()
    np.testing.assert_allclose(result.forces_gripped, [8.0, 8.0], rtol=0.02)


def test_validate_robot_refusals(capsys, tmp_path):
    grasps = tmp_path / "panda_cube.json"
    save_grasps(shipped_grasps("cube", "panda")[:1], grasps)
    base = ["validate", "--sigma", "0", "--samples", "1", "--out", str(tmp_path / "o")]
    cases = [
        (["--robot", "no_such_robot"], "unknown robot 'no_such_robot'"),
        (["--robot", "panda", "--object", "mug"], "no shipped grasps of 'mug'"),
        (["--robot", "kuka_sdh", "--grasps", str(grasps)], "grasps of robot 'panda'"),
        (["--robot", "panda", "--object", "cube", "--grasp", "9"], "out of range"),
    ]
    for extra, words in cases:
        capsys.readouterr()
        assert main(base + extra) == 2, extra
        err = capsys.readouterr().err.strip()
        assert words in err and len(err.splitlines()) == 1, (extra, err)


def test_validate_draws_are_evaluates_draws(capsys, tmp_path):
    """Validate's kinematic outcomes and Q per draw equal ``evaluate_grasp``'s with the
    same seed and sigma (the draws of ``kinegrasp evaluate --robot``)."""
    from kinegrasp_env.montecarlo.draws import OUTCOMES
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp

    grasp = shipped_grasps("drill", "panda")[0]
    path = tmp_path / "drill.json"
    save_grasps([grasp], path)
    status = main(["validate", "--grasps", str(path), "--sigma", "0.01", "--samples", "3",
                   "--seed", "4", "--kinematic-engine", "pybullet", "--json",
                   "--out", str(tmp_path / "out")])
    out, err = capsys.readouterr()
    assert status == 0, err
    rows = (tmp_path / "out" / "draws.csv").read_text().splitlines()[1:]
    reference = evaluate_grasp(grasp, sigma=0.01, n=3, seed=4).draws
    assert [r.split(",")[4] for r in rows] == [OUTCOMES[k] for k in reference.outcome]
    np.testing.assert_allclose([float(r.split(",")[5]) for r in rows], reference.quality,
                               rtol=1e-5)
    assert json.loads(out)["settings"]["robot"] == "panda"  # the file's robot


def test_validate_robot_on_two_processes_is_the_run_in_one(capsys, tmp_path):
    """Each grasp's draws are the same whichever worker runs them: the draws' CSV of a run on
    two processes equals the run's in one; the summary's first line states the run's mu."""
    for processes in ("1", "2"):
        assert main(["validate", "--robot", "panda", "--object", "cube", "--grasp", "0", "1",
                     "--sigma", "0.01", "--samples", "2", "--processes", processes,
                     "--friction", "0.7", "--out", str(tmp_path / processes)]) == 0
        first = capsys.readouterr().out.splitlines()[0]
        assert first.startswith("validate: robot panda, 2 grasps, sigma 0.01 rad, mu 0.7, ")
    one, two = ((tmp_path / p / "draws.csv").read_text() for p in ("1", "2"))
    assert one == two and len(one.splitlines()) == 5
