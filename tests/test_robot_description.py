"""Robot descriptions and the robot catalog.

Independent references: pybullet's own reading of each URDF (``getJointInfo``: names, types,
parents, limits; parent indices for the chains and the leaves), the constants of
``robot/model.py`` for the built-in KUKA, and pybullet_data's untouched Panda for the copy.
The xArm 6 with its gripper (pybullet_data) is added as a user would add it: a description
written here, in a temporary data folder; the library knows none of its names.
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pybullet
import pybullet_data
import pytest
import yaml
from pybullet_utils.bullet_client import BulletClient

from kinegrasp_env.cli.main import main
from kinegrasp_env.robot import default_robot as kuka
from kinegrasp_env.robot.catalog import (
    BUILTIN,
    DEFAULT_ROBOT,
    add_robot,
    load_robot,
    remove_robot,
    robot_names,
    robots_dir,
)
from kinegrasp_env.robot.description import RobotDescriptionError, load_description
from kinegrasp_env.robot.urdf_meshes import resolve_mesh

DATA = Path(pybullet_data.getDataPath())
XARM = DATA / "xarm"
XARM_URDF = XARM / "xarm6_with_gripper.urdf"
#: pybullet's joint type codes.
TYPES = {"revolute": pybullet.JOINT_REVOLUTE, "prismatic": pybullet.JOINT_PRISMATIC,
         "fixed": pybullet.JOINT_FIXED}


@pytest.fixture()
def home(tmp_path, monkeypatch):
    """A data folder of this test's own (the robot catalog lives in it)."""
    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    return tmp_path / "home"


def bullet_tree(urdf: Path) -> dict:
    """pybullet's reading of ``urdf``: per joint (in pybullet's order) its name, type, parent
    link name, child link name, limits; the base link's name."""
    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        body = client.loadURDF(str(urdf), useFixedBase=True)
        base = client.getBodyInfo(body)[0].decode()
        infos = [client.getJointInfo(body, i) for i in range(client.getNumJoints(body))]
    finally:
        client.disconnect()
    child = [info[12].decode() for info in infos]
    return {"base": base, "joints": [
        {"name": info[1].decode(), "type": info[2], "child": child[i],
         "parent": base if info[16] == -1 else child[info[16]],
         "lower": info[8], "upper": info[9]} for i, info in enumerate(infos)]}


def chain_to(tree: dict, link: str) -> list[dict]:
    """pybullet's joints from the base to ``link``, base first."""
    by_child = {j["child"]: j for j in tree["joints"]}
    out = []
    while link in by_child:
        out.append(by_child[link])
        link = by_child[link]["parent"]
    return out[::-1]


def mimic_drivers(urdf: Path) -> dict[str, str]:
    """Mimic joint -> the joint it follows, read from the XML (pybullet does not report it)."""
    return {j.get("name"): j.find("mimic").get("joint")
            for j in ET.parse(urdf).getroot().findall("joint") if j.find("mimic") is not None}


def leaves_moved_by(tree: dict, urdf: Path, hand: tuple[str, ...]) -> set[str]:
    """Links with no child below a joint that a hand joint drives (itself or a mimic)."""
    drivers = mimic_drivers(urdf)
    moved = {j["child"] for j in tree["joints"] if j["type"] != pybullet.JOINT_FIXED
             and drivers.get(j["name"], j["name"]) in hand}
    parents = {j["parent"] for j in tree["joints"]}
    return {j["child"] for j in tree["joints"] if j["child"] not in parents
            and any(k["child"] in moved for k in chain_to(tree, j["child"]))}


# ------------------------------------------------------------------------ built-in robots
def test_kuka_sdh_description_gives_the_paper_robots_layout():
    """The built-in description gives the layout the paper's robot has (7 arm joints, the
    spread and two flexions per finger of three fingers, the iiwa's S-R-S elbow links) and
    the middle of its pre-shape draws' flexions as its open pre-shape; the default robot's
    names are read
    from it."""
    d = load_robot("kuka_sdh")
    assert DEFAULT_ROBOT == "kuka_sdh"
    assert len(d.arm_joints) == 7 and len(d.hand_joints) == 7 and len(d.fingers) == 3
    assert all(len(f.joints) == 2 for f in d.fingers)
    assert d.hand_joints[1:] == tuple(j for f in d.fingers for j in f.joints)
    assert d.arm_angle_links == tuple(d.model.joint(d.arm_joints[i]).child for i in (1, 3, 5))
    assert (kuka.ARM_JOINTS, kuka.HAND_JOINTS, kuka.PALM_LINK) == (d.arm_joints,
                                                                   d.hand_joints, d.palm_link)
    assert kuka.kuka_sdh().actuated == d.model.actuated
    assert [d.open[j] for j in d.hand_joints[1:]] == [-0.55, 0.05] * 3
    assert d.contact_model == "point"


@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_builtin_descriptions_agree_with_pybullet(name):
    """Joint names, types, parent links and limits of the description's model equal
    pybullet's getJointInfo on the same URDF; the arm is pybullet's chain from the base to
    the palm; the fingertips are pybullet's leaves below the hand joints."""
    d = load_robot(name)
    tree = bullet_tree(d.urdf)
    assert tree["base"] == d.model.base_link
    ours = {j.name: j for j in d.model.joints}
    assert sorted(ours) == sorted(j["name"] for j in tree["joints"])
    for j in tree["joints"]:
        mine = ours[j["name"]]
        assert TYPES[mine.kind] == j["type"], j["name"]
        assert (mine.parent, mine.child) == (j["parent"], j["child"]), j["name"]
        if j["type"] != pybullet.JOINT_FIXED:
            assert (mine.lower, mine.upper) == (j["lower"], j["upper"]), j["name"]
    chain = [j["name"] for j in chain_to(tree, d.palm_link) if j["type"] != pybullet.JOINT_FIXED]
    assert list(d.arm_joints) == chain
    assert set(d.fingertip_links) == leaves_moved_by(tree, d.urdf, d.hand_joints)
    for j in d.hand_joints:
        assert d.model.lower[d.model.actuated.index(j)] <= d.open[j] \
            <= d.model.upper[d.model.actuated.index(j)]


def test_panda_copy_is_pybullet_datas_panda_but_for_visual_meshes():
    """The shipped panda.urdf reads in pybullet exactly as pybullet_data's original: every
    joint's full getJointInfo, every link's dynamics and collision shapes, the collision
    mesh files' bytes (only the visual meshes differ: they point at the collision meshes)."""
    def reading(urdf: Path):
        client = BulletClient(connection_mode=pybullet.DIRECT)
        try:
            body = client.loadURDF(str(urdf), useFixedBase=True)
            n = client.getNumJoints(body)
            joints = [client.getJointInfo(body, i) for i in range(n)]
            dynamics = [client.getDynamicsInfo(body, i) for i in range(-1, n)]
            shapes = [[s[:4] + s[5:] for s in client.getCollisionShapeData(body, i)]
                      for i in range(-1, n)]  # s[4]: the mesh file's path
            files = [[hashlib.sha256(Path(s[4].decode()).read_bytes()).hexdigest()
                      for s in client.getCollisionShapeData(body, i)] for i in range(-1, n)]
        finally:
            client.disconnect()
        return joints, dynamics, shapes, files

    shipped = load_robot("panda").urdf
    assert reading(shipped) == reading(DATA / "franka_panda" / "panda.urdf")
    assert (shipped.parent / "LICENSE.txt").read_bytes() == \
        (DATA / "franka_panda" / "LICENSE.txt").read_bytes()


def test_panda_hand_is_derived_from_the_urdf():
    """One actuated jaw; both jaws are fingers (the second through its mimic joint), and
    closing moves both jaw joints towards their lower limit (0: the jaws together)."""
    d = load_robot("panda")
    assert d.fingertip_links == ("panda_leftfinger", "panda_rightfinger")
    assert [f.joints for f in d.fingers] == [("panda_finger_joint1",), ("panda_finger_joint2",)]
    assert [f.directions for f in d.fingers] == [(-1,), (-1,)]
    assert d.open == {"panda_finger_joint1": 0.04} and d.contact_model == "soft"
    assert all(m.path.is_relative_to(d.urdf.parent) for m in d.meshes)


# ------------------------------------------------------------------- a user's robot: xArm 6
XARM_DESCRIPTION = {
    "name": "xarm6",
    "arm_joints": ["joint1", "joint2", "joint3", "joint4", "joint5", "joint6"],
    "palm_link": "xarm_gripper_base_link",
    "hand_joints": ["drive_joint"],
    "close": {"drive_joint": 1},
    "open": {"drive_joint": 0.0},
    "finger_links": ["left_finger", "right_finger"],
    "contact_model": "soft",
}


def user_files(tmp_path: Path, layout: str, **changes) -> Path:
    """The xArm description a user writes: ``beside`` (the URDF where pybullet_data has it,
    its package folders beside it), ``absolute`` (a copy of the URDF in the user's folder,
    every mesh given by its absolute path) or ``packages`` (a copy of the URDF in the user's folder,
    the packages given by the ``packages:`` map). Returns the YAML path."""
    folder = tmp_path / "user"
    folder.mkdir(exist_ok=True)
    data = dict(XARM_DESCRIPTION)
    if layout == "beside":
        data["urdf"] = str(XARM_URDF)
    elif layout == "absolute":
        (folder / "urdf").mkdir(exist_ok=True)
        text = XARM_URDF.read_text().replace("package://", f"{XARM.as_posix()}/")
        (folder / "urdf" / "xarm6.urdf").write_text(text)
        data["urdf"] = "urdf/xarm6.urdf"
    else:
        (folder / "urdf").mkdir(exist_ok=True)
        shutil.copyfile(XARM_URDF, folder / "urdf" / "xarm6.urdf")
        data["urdf"] = "urdf/xarm6.urdf"
        data["packages"] = {p: str(XARM / p) for p in ("xarm_description", "xarm_gripper")}
    data.update(changes)
    path = folder / "xarm6.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def snapshot(folder: Path) -> dict[str, str]:
    """Every file under ``folder``: relative path -> SHA-256."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()} if folder.exists() else {}


@pytest.mark.parametrize("layout", ["beside", "absolute", "packages"])
def test_a_user_robot_added_listed_shown_removed(home, tmp_path, capsys, layout):
    """``robots add`` checks and copies the xArm (the user's files unchanged, the entry
    self-contained: every mesh inside it); the description agrees with pybullet's reading;
    ``robots`` lists it; ``robots show`` draws a non-blank PNG; ``robots remove`` deletes it."""
    path = user_files(tmp_path, layout)
    before = snapshot(tmp_path / "user")
    assert main(["robots", "add", str(path)]) == 0
    assert "xarm6: 6 arm joints" in capsys.readouterr().out
    assert snapshot(tmp_path / "user") == before
    if layout != "beside":
        shutil.rmtree(tmp_path / "user")  # the catalog needs none of the user's files

    d = load_robot("xarm6")
    folder = robots_dir() / "xarm6"
    assert d.path.parent == folder
    assert d.meshes and all(m.path.is_relative_to(folder) for m in d.meshes)
    tree = bullet_tree(d.urdf)
    assert list(d.arm_joints) == [j["name"] for j in chain_to(tree, d.palm_link)
                                  if j["type"] != pybullet.JOINT_FIXED]
    assert d.fingertip_links == ("left_finger", "right_finger")
    assert [f.directions for f in d.fingers] == [(1, 1), (1, 1)]  # mimics multiply by +1
    assert [len(f.joints) for f in d.fingers] == [2, 2]

    assert main(["robots", "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    assert list(rows) == ["kuka_sdh", "panda", "xarm6"]
    assert rows["xarm6"] | {"description": None} == {
        "name": "xarm6", "source": "user", "arm_dof": 6, "hand_joints": ["drive_joint"],
        "palm_link": "xarm_gripper_base_link", "fingertips": ["left_finger", "right_finger"],
        "contact_model": "soft", "description": None}
    assert rows["panda"]["source"] == "built-in" and rows["panda"]["arm_dof"] == 7
    assert main(["robots"]) == 0
    table = capsys.readouterr().out.splitlines()
    assert table[0].split()[:2] == ["name", "source"] and table[3].split()[:3] == [
        "xarm6", "user", "6"]

    png = tmp_path / "robot.png"
    assert main(["robots", "show", "xarm6", "--out", str(png)]) == 0
    from PIL import Image

    image = np.asarray(Image.open(png).convert("RGB"), dtype=float)
    background = image[0, 0]
    robot = np.any(np.abs(image - background) > 30, axis=-1)
    # two 640 x 480 panels: the robot, then its hand close up (each with something drawn)
    assert image.shape == (480, 1280, 3), image.shape
    for panel in (robot[:, :640], robot[:, 640:]):
        assert 0.02 < panel.mean() < 0.9, panel.mean()

    assert main(["robots", "remove", "xarm6"]) == 0
    assert not folder.exists() and "xarm6" not in robot_names()
    capsys.readouterr()


def test_the_derived_hand_without_finger_links(home, tmp_path):
    """Without ``finger_links`` every link a hand joint moves is a finger link, and the
    fingertips are pybullet's leaves below the gripper's joints but the two inner knuckles:
    the bars of the four-bar linkages, leaves only because the URDF cuts each closed loop
    open (the pads the description names are the two fingers)."""
    data = {k: v for k, v in XARM_DESCRIPTION.items() if k != "finger_links"}
    path = tmp_path / "x.yaml"
    path.write_text(yaml.safe_dump({**data, "urdf": str(XARM_URDF)}))
    d = load_description(path)
    leaves = leaves_moved_by(bullet_tree(XARM_URDF), XARM_URDF, ("drive_joint",))
    assert leaves == {"left_finger", "right_finger", "left_inner_knuckle",
                      "right_inner_knuckle"}
    assert set(d.fingertip_links) == set(XARM_DESCRIPTION["finger_links"])
    assert leaves <= set(d.finger_links)


def _missing_mesh(tmp_path: Path) -> dict:
    """A packages map whose xarm_description lacks one collision mesh."""
    broken = tmp_path / "broken" / "xarm_description"
    shutil.copytree(XARM / "xarm_description", broken)
    (broken / "meshes" / "xarm6" / "collision" / "link3_vhacd.obj").unlink()
    return {"packages": {"xarm_description": str(broken),
                         "xarm_gripper": str(XARM / "xarm_gripper")}}


def _finger_without_collision(tmp_path: Path) -> dict:
    """The xArm's URDF (its meshes by absolute path) with the collision geometry of the two
    links the left finger's closing joints move removed: a finger that cannot touch."""
    text = XARM_URDF.read_text().replace("package://", f"{XARM.as_posix()}/")
    for name in ("left_outer_knuckle", "left_finger"):
        link = re.search(rf'<link\s+name="{name}"\s*>.*?</link>', text, re.S).group(0)
        text = text.replace(link, re.sub(r"<collision>.*?</collision>", "", link, flags=re.S))
    (tmp_path / "no_collision.urdf").write_text(text)
    return {"urdf": str(tmp_path / "no_collision.urdf")}


def _mimic_chain(tmp_path: Path) -> dict:
    """The xArm's URDF (its meshes by absolute path) with its right finger joint made a mimic
    of the left one, itself a mimic of the drive joint: a chain of mimic joints."""
    text = XARM_URDF.read_text().replace("package://", f"{XARM.as_posix()}/")
    joint = re.search(r'<joint name="right_finger_joint".*?</joint>', text, re.S).group(0)
    text = text.replace(joint, joint.replace('<mimic joint="drive_joint"',
                                             '<mimic joint="left_finger_joint"'))
    (tmp_path / "mimic_chain.urdf").write_text(text)
    return {"urdf": str(tmp_path / "mimic_chain.urdf")}


def _extra_joint(tmp_path: Path) -> dict:
    """The xArm's URDF with a movable joint hung off its base, on no chain to the hand."""
    text = XARM_URDF.read_text().replace("package://", f"{XARM.as_posix()}/")
    extra = """
  <link name="extra_link"/>
  <joint name="extra_joint" type="revolute">
    <parent link="link_base"/><child link="extra_link"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
</robot>"""
    (tmp_path / "extra.urdf").write_text(re.sub(r"</robot>\s*$", extra, text))
    return {"urdf": str(tmp_path / "extra.urdf")}


BAD = {
    "a chain of mimic joints": (
        _mimic_chain, "urdf", "'right_finger_joint' mimics 'left_finger_joint', itself a "
        "mimic joint of 'drive_joint': make it mimic that joint"),
    "a movable joint on no chain": (
        _extra_joint, "urdf", "'extra_joint' is a movable joint of extra.urdf in neither "
        "arm_joints nor hand_joints: list 'extra_joint' in one of them, or make it a fixed "
        "joint"),
    "finger without collision geometry": (
        _finger_without_collision, "finger_links",
        "the finger ending at 'left_finger' has no collision geometry on the links its "
        "closing joints move (left_outer_knuckle, left_finger"),
    "unknown joint": (lambda t: {"arm_joints": [*XARM_DESCRIPTION["arm_joints"][:5], "joint9"]},
                      "arm_joints", "unknown joint 'joint9'"),
    "broken chain": (lambda t: {"arm_joints": ["joint1", "joint2", "joint4", "joint5",
                                               "joint6"]}, "arm_joints", "is not the chain"),
    "arm out of order": (lambda t: {"arm_joints": ["joint2", "joint1", "joint3", "joint4",
                                                   "joint5", "joint6"]}, "arm_joints",
                         "is not the chain"),
    "hand joint before the palm": (lambda t: {"arm_joints": XARM_DESCRIPTION["arm_joints"][:5],
                                              "hand_joints": ["joint6"],
                                              "close": {"joint6": 1}},
                                   "hand_joints", "'joint6' moves link 'link6'"),
    "a joint beyond the palm in neither list": (
        lambda t: {"arm_joints": XARM_DESCRIPTION["arm_joints"][:5], "palm_link": "link5"},
        "hand_joints", "'joint6' is a movable joint beyond palm_link 'link5' that is in "
        "neither arm_joints nor hand_joints"),
    "close 2": (lambda t: {"close": {"drive_joint": 2}}, "close", "2 is not +1 or -1"),
    "close toward the open limit": (lambda t: {"close": {"drive_joint": -1}}, "close",
                                    "drive_joint: -1 closes toward its lower limit 0, where "
                                    "it opens (0): no travel"),
    "missing mesh": (_missing_mesh, "packages", "link3_vhacd.obj"),
    "mimic as hand joint": (lambda t: {"hand_joints": ["left_finger_joint"],
                                       "close": {"left_finger_joint": 1}}, "hand_joints",
                            "mimic joint"),
    "open beyond the limit": (lambda t: {"open": {"drive_joint": 1.0}}, "open",
                              "outside the joint's limits"),
    "unknown key": (lambda t: {"palm": "link6"}, "palm", "unknown key"),
    "unknown finger link": (lambda t: {"finger_links": ["link5"]}, "finger_links",
                            "'link5' is not moved"),
    "contact model": (lambda t: {"contact_model": "hard"}, "contact_model", "'hard'"),
    "built-in name": (lambda t: {"name": "panda"}, "name", "built-in"),
    "effort not positive": (lambda t: {"efforts": {"drive_joint": -1}}, "efforts",
                            "-1 is not > 0"),
    "no urdf": (lambda t: {"urdf": "nowhere.urdf"}, "urdf", "'nowhere.urdf': no such file"),
    "hand mount on the arm": (lambda t: {"hand_mount": "link5"}, "hand_mount",
                              "'link5' is not a link from the last arm joint's child"),
    "home beyond the limit": (lambda t: {"home": {"joint2": 9.0}}, "home",
                              "joint2: 9 is outside the joint's limits"),
    "home of a hand joint": (lambda t: {"home": {"drive_joint": 0.1}}, "home",
                             "'drive_joint' is not one of arm_joints"),
    "empty arm name": (lambda t: {"arm_name": " "}, "arm_name", "non-empty text"),
    "pre-shape of an arm joint": (lambda t: {"preshapes": [{"joints": ["joint2"],
                                                            "range": [0.0, 0.1]}]},
                                  "preshapes[0]: joints", "'joint2' is not one of hand_joints"),
    "pre-shape beyond the limit": (lambda t: {"preshapes": [{"joints": ["drive_joint"],
                                                             "values": [0.1, 9.0]}]},
                                   "preshapes[0]", "drive_joint: 9 is outside the joint's"),
    "pre-shape range reversed": (lambda t: {"preshapes": [{"joints": ["drive_joint"],
                                                           "range": [0.5, 0.1]}]},
                                 "preshapes[0]: range", "low <= high"),
    "pre-shape with both": (lambda t: {"preshapes": [{"joints": ["drive_joint"],
                                                      "range": [0.0, 0.1], "values": [0.0]}]},
                            "preshapes[0]", "expected {joints"),
    "pre-shape key not a name": (lambda t: {"preshapes": [{"joints": ["drive_joint"],
                                                           "values": [0.0], True: 1}]},
                                 "preshapes[0]", "expected {joints"),
    "pre-shapes not a list": (lambda t: {"preshapes": False}, "preshapes",
                              "expected a list of draws, got False"),
    "home too large for a float": (lambda t: {"home": {"joint2": 10 ** 400}}, "home: joint2",
                                   "is not a finite number"),
    "pre-shape joint twice": (lambda t: {"preshapes": [
        {"joints": ["drive_joint"], "range": [0.0, 0.1]},
        {"joints": ["drive_joint"], "values": [0.2]}]},
        "preshapes[1]: joints", "'drive_joint' is in an earlier draw too"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_description_is_one_line_naming_the_key(home, tmp_path, capsys, case):
    """Each bad description is refused with one line naming the key and the bad value, and
    the catalog (already holding a robot) is left exactly as it was; the command says the
    same in one line with exit status 2."""
    add_robot(user_files(tmp_path, "beside"))
    before = snapshot(home)
    change, key, needle = BAD[case]
    path = user_files(tmp_path, "beside", **change(tmp_path))
    with pytest.raises(RobotDescriptionError) as info:
        add_robot(path, force=True)
    message = str(info.value)
    assert "\n" not in message and f"xarm6.yaml: {key}: " in message and needle in message, \
        message
    assert snapshot(home) == before
    capsys.readouterr()
    assert main(["robots", "add", str(path), "--force"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert snapshot(home) == before


def test_unreadable_files_are_one_line(home, tmp_path, capsys):
    """A missing file, a YAML syntax error, a YAML list and a key given twice (YAML would keep
    the last: the robot was stored under the second name) each give one line, exit 2."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: [unclosed\n")
    listed = tmp_path / "list.yaml"
    listed.write_text("- a\n- b\n")
    twice = tmp_path / "twice.yaml"
    twice.write_text(yaml.safe_dump(XARM_DESCRIPTION) + "name: other\n")
    for path, needle in ((tmp_path / "none.yaml", "none.yaml: no such file"),
                         (bad, "bad.yaml:2:1: not valid YAML"),
                         (listed, "list.yaml: expected a mapping"),
                         (twice, "key 'name' appears twice")):
        assert main(["robots", "add", str(path)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and needle in err, err
    assert not robots_dir().exists()


def test_a_palm_error_is_given_in_the_hand_mounts_frame():
    """The default robot's palm errors are relative to its hand mount (``hand_mount``); a
    description without one takes the last arm joint's child, and the key is checked."""
    kuka = load_robot("kuka_sdh")
    assert kuka.flange_link == kuka.hand_mount == "sdh_base"
    panda = load_robot("panda")
    assert panda.hand_mount == ""
    assert panda.flange_link == panda.model.joint(panda.arm_joints[-1]).child


def test_builtin_names_are_their_descriptions_names():
    assert all(load_robot(name).name == name for name in BUILTIN)


def test_names_taken_and_builtins_are_refused(home, tmp_path):
    path = user_files(tmp_path, "beside")
    add_robot(path)
    with pytest.raises(RobotDescriptionError, match="already in the catalog"):
        add_robot(path)
    add_robot(path, force=True)  # replaced in place
    with pytest.raises(RobotDescriptionError, match="built-in robot and cannot be removed"):
        remove_robot("panda")
    with pytest.raises(RobotDescriptionError, match="unknown robot 'nope'"):
        load_robot("nope")
    assert robot_names() == ("kuka_sdh", "panda", "xarm6")


def test_mesh_paths_resolve_as_urdf_readers_write_them(tmp_path):
    """Relative, absolute, file://, and package:// through the map, a folder of that name
    beside the URDF or beside a folder above it, and a folder above it of that name (the ROS
    layout ``pkg/urdf/robot.urdf`` with ``package://pkg/meshes/...``)."""
    pkg = tmp_path / "ws" / "pkg"
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "meshes").mkdir()
    urdf = pkg / "urdf" / "robot.urdf"
    mesh = pkg / "meshes" / "a.stl"
    mesh.write_text("solid a\nendsolid a\n")
    other = tmp_path / "ws" / "other" / "b.obj"
    other.parent.mkdir()
    other.write_text("v 0 0 0\n")
    mapped = tmp_path / "elsewhere" / "c.obj"
    mapped.parent.mkdir()
    mapped.write_text("v 0 0 0\n")
    packages = {"mapped": mapped.parent}
    assert resolve_mesh("../meshes/a.stl", urdf, {}) == mesh
    assert resolve_mesh(str(mesh), urdf, {}) == mesh
    assert resolve_mesh(f"file://{mesh}", urdf, {}) == mesh
    assert resolve_mesh("package://pkg/meshes/a.stl", urdf, {}) == mesh
    assert resolve_mesh("package://other/b.obj", urdf, {}) == other
    assert resolve_mesh("package://mapped/c.obj", urdf, packages) == mapped
    assert resolve_mesh("package://mapped/c.obj", urdf, {}) is None
    assert resolve_mesh("package://pkg/meshes/none.stl", urdf, {}) is None


def test_home_defaults_to_the_middle_of_each_joints_range(tmp_path):
    """``home``: a given joint keeps its value, every other arm joint sits at the middle of
    its range as pybullet reads the URDF's limits; ``arm_name`` defaults to "<name> arm"; the
    default robot's are the paper's configuration and name."""
    path = user_files(tmp_path, "beside")
    data = {**yaml.safe_load(path.read_text()), "home": {"joint2": 0.25}}
    path.write_text(yaml.safe_dump(data))
    d = load_description(path)
    client = pybullet.connect(pybullet.DIRECT)
    try:
        body = pybullet.loadURDF(str(d.urdf), physicsClientId=client)
        limits = {}
        for i in range(pybullet.getNumJoints(body, physicsClientId=client)):
            info = pybullet.getJointInfo(body, i, physicsClientId=client)
            limits[info[1].decode()] = (info[8], info[9])
    finally:
        pybullet.disconnect(client)
    expected = [0.25 if j == "joint2" else 0.5 * sum(limits[j]) for j in d.arm_joints]
    np.testing.assert_allclose(d.home_arm(), expected, rtol=0, atol=1e-12)
    # a hand joint left out of ``open`` sits at 0 clipped into its limits, not mid-range
    data.pop("open", None)
    path.write_text(yaml.safe_dump(data))
    bare = load_description(path)
    assert bare.open == {j: min(max(0.0, limits[j][0]), limits[j][1]) for j in bare.hand_joints}
    assert d.arm_name == f"{d.name} arm"
    kuka = load_robot("kuka_sdh")
    assert kuka.home_arm().tolist() == [0.0, 0.7, 0.0, -1.3, 0.0, 0.9, 0.0]  # the yaml's
    assert kuka.arm_name == "KUKA iiwa"


def test_a_description_is_read_again_when_its_file_changes(home, tmp_path):
    """The catalog reads a description once per process, and again when its file changes
    (here its size: the contact model named in it) or the robot is removed."""
    add_robot(user_files(tmp_path, "beside"))
    first = load_robot("xarm6")
    assert load_robot("xarm6") is first and first.contact_model == "soft"
    entry = robots_dir() / "xarm6" / "robot.yaml"
    entry.write_text(entry.read_text().replace("contact_model: soft", "contact_model: patch"))
    assert load_robot("xarm6").contact_model == "patch"
    assert main(["robots", "remove", "xarm6"]) == 0
    with pytest.raises(RobotDescriptionError, match="unknown robot 'xarm6'"):
        load_robot("xarm6")


def test_contact_model_defaults_by_finger_count(tmp_path):
    """A description naming no contact model: soft for the xArm's two fingers (two point
    contacts are never in force closure), point for the SDH's three; named, it is kept."""
    data = {k: v for k, v in XARM_DESCRIPTION.items() if k != "contact_model"}
    path = user_files(tmp_path, "beside")
    path.write_text(yaml.safe_dump({**data, "urdf": str(XARM_URDF)}))
    two = load_description(path)
    assert len(two.fingers) == 2 and two.contact_model == "soft"
    path.write_text(yaml.safe_dump({**data, "urdf": str(XARM_URDF), "contact_model": "point"}))
    assert load_description(path).contact_model == "point"
    assert len(load_robot("kuka_sdh").fingers) == 3
    from kinegrasp_env.robot.description import default_contact_model

    assert default_contact_model(3) == "point" and default_contact_model(1) == "point"


def test_hand_frames_of_the_built_in_hands():
    """Worked from the URDFs by hand: the Panda's jaws slide along the hand frame's y axis
    (its finger joints' axes, mirrored), the fingertips lie ahead along z between the finger
    joints' origin (0.0584 m) and Franka's stated flange-to-fingertip length (0.1034 m); the
    SDH's three tips close inwards and towards the palm's z, spaced 120 degrees about it."""
    from kinegrasp_env.robot.hand_frame import hand_frame

    panda = hand_frame(load_robot("panda"))
    np.testing.assert_allclose(panda.approach, [0, 0, 1], atol=1e-6)
    # pybullet's link frames are good to ~1e-8 m over the 1e-3 m closing step: 1e-4 margin
    np.testing.assert_allclose(panda.closing, [[0, -1, 0], [0, 1, 0]], atol=1e-4)
    assert 0.0584 < panda.depth < 0.1034 and panda.opening > 0.08
    sdh = hand_frame(load_robot("kuka_sdh"))
    np.testing.assert_allclose(sdh.approach, [0, 0, 1], atol=1e-6)
    assert np.all(sdh.closing[:, 2] > 0)
    inward = -sdh.tip_centres[:, :2] / np.linalg.norm(sdh.tip_centres[:, :2], axis=1)[:, None]
    assert np.all(np.sum(sdh.closing[:, :2] * inward, axis=1) > 0)
    angles = np.sort(np.degrees(np.arctan2(sdh.tip_centres[:, 1], sdh.tip_centres[:, 0])))
    np.testing.assert_allclose(np.diff(angles), [120, 120], atol=1.0)
    # in words: components that are zero up to rounding print as +0.000, never -0.000
    assert all("-0.000" not in line for line in panda.lines() + sdh.lines())
    assert "approach axis (+0.000, +0.000, +1.000)" in panda.lines()[1]


def test_the_fingertip_centres_are_pybullets_bounding_box_centres():
    """The hand frame's tip centres (the bounding boxes of the tips' collision vertices, taken
    from the URDF's meshes) against pybullet's own AABB of each fingertip link, in the palm
    frame: the Panda's hand is axis-aligned with the world at its arm's zero pose, so both
    boxes are the same box (pybullet's collision margin widens it evenly). 1e-6 m: 1.6e-9
    measured."""
    from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
    from kinegrasp_env.robot.hand_frame import hand_frame

    panda = load_robot("panda")
    frame = hand_frame(panda)
    with RobotReferenceEngine(panda, "cube") as engine:
        world = engine.world
        q = panda.open_configuration()
        q[:panda.arm_dof] = 0.0
        world.set_configuration(q)
        palm_inv = np.linalg.inv(world.link_pose(panda.palm_link))
        for tip, centre in zip(frame.tips, frame.tip_centres, strict=True):
            lo, hi = world.bullet.getAABB(world.bodies["robot"], world.link_index[tip])
            box = (palm_inv @ np.r_[0.5 * (np.array(lo) + np.array(hi)), 1.0])[:3]
            np.testing.assert_allclose(centre, box, atol=1e-6)


def test_preshapes_are_drawn_within_their_draws_and_coupled():
    """The SDH's pre-shape draws (its description): every drawn spread one of the three
    values, each flexion inside its range and shared by the three fingers; the draws cover
    the range (each third of it hit in 300 draws: a uniform draw misses a third with
    probability 3 (2/3)^300); the same generator seed draws the same pre-shapes; a robot
    without ``preshapes`` draws its ``open`` pre-shape and consumes no random numbers."""
    description = load_robot("kuka_sdh")
    hand = description.drawn_configurations(np.random.default_rng(3), 300)[:, 7:]
    spreads = {0.0, np.pi / 3, np.pi / 6}
    assert set(np.round(hand[:, 0], 12)) == {round(v, 12) for v in spreads}
    for columns, (lo, hi) in (((1, 3, 5), (-0.9, -0.2)), ((2, 4, 6), (-0.2, 0.3))):
        block = hand[:, columns]
        assert np.all(block == block[:, :1])
        assert np.all((block >= lo) & (block <= hi))
        thirds = np.floor((block[:, 0] - lo) / (hi - lo) * 3)
        assert set(thirds.astype(int)) == {0, 1, 2}
    again = description.drawn_configurations(np.random.default_rng(3), 300)[:, 7:]
    assert np.array_equal(hand, again)
    panda = load_robot("panda")
    rng = np.random.default_rng(5)
    drawn = panda.drawn_configurations(rng, 4)
    assert np.array_equal(drawn, np.repeat(panda.open_configuration()[None], 4, axis=0))
    assert rng.uniform() == np.random.default_rng(5).uniform()


def test_robots_show_lists_the_preshape_draws(tmp_path, capsys):
    """``robots show`` names each pre-shape draw of a description as written in its YAML
    (the joints, then the values or the range), and says a robot without draws closes from
    its open pre-shape."""
    data = yaml.safe_load(open(load_robot("kuka_sdh").path))
    assert main(["robots", "show", "kuka_sdh", "--out", str(tmp_path / "k.png")]) == 0
    out = capsys.readouterr().out
    for entry in data["preshapes"]:
        numbers = entry.get("values") or entry["range"]
        line = next(x for x in out.splitlines() if x.strip().startswith(", ".join(entry["joints"])))
        assert all(f"{v:g}" in line for v in numbers), line
    assert main(["robots", "show", "panda", "--out", str(tmp_path / "p.png")]) == 0
    assert "the open one (no preshapes)" in capsys.readouterr().out


def test_a_hand_never_in_force_closure_is_said_so(home, tmp_path, capsys):
    """The Panda's jaws scored as point contacts (one contact per jaw: no torque about the
    line through them, never in force closure): ``robots add`` stores the robot and says so
    on stderr; ``plan`` refuses at once in one line (it drew its 200 palm poses and said only
    that none was found); the summary counts a single hand joint in the singular. The xArm's
    fingers touch with two links each: four point contacts can be in force closure, so it
    gets no note."""
    from kinegrasp_env.assets import asset_path

    panda = yaml.safe_load(asset_path("robots", "panda", "panda.yaml").read_text())
    panda.update(name="panda_point", contact_model="point",
                 urdf=str(asset_path("robots", "panda", "panda.urdf")))
    path = tmp_path / "panda_point.yaml"
    path.write_text(yaml.safe_dump(panda))
    capsys.readouterr()
    assert main(["robots", "add", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "1 hand joint, 2 fingers" in out
    assert err.strip() == ("note: two point contacts are never in force closure (they resist "
                           "no torque about the line between them): give contact_model soft "
                           "or patch; plan will find no grasp")
    assert main(["plan", "--robot", "panda_point", "--object", "cube", "--count", "1", "--out",
                 str(tmp_path / "g.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith("never in force closure (they resist no torque "
                                             "about the line between them): give contact_model "
                                             "soft or patch; nothing planned"), err
    assert not (tmp_path / "g.json").exists()
    assert main(["robots", "add", str(user_files(tmp_path, "beside", contact_model="point"))]) \
        == 0
    assert capsys.readouterr().err == ""


def test_a_pre_shape_gives_a_closing_joint_its_travel(home, tmp_path):
    """A closing joint that opens at the limit it closes toward is refused (no travel), but
    not where a pre-shape draws it from elsewhere: the closings start there."""
    bad = user_files(tmp_path, "beside", close={"drive_joint": -1})
    with pytest.raises(RobotDescriptionError, match="no travel"):
        add_robot(bad)
    good = user_files(tmp_path, "beside", close={"drive_joint": -1},
                      preshapes=[{"joints": ["drive_joint"], "range": [0.3, 0.6]}])
    assert add_robot(good)[0].close == {"drive_joint": -1}
