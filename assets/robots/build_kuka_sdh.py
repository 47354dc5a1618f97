"""Compose ``kuka_sdh.urdf``: the KUKA LBR iiwa 14 arm with a three-finger SDH-like hand.

Run from anywhere: ``python assets/robots/build_kuka_sdh.py``. The arm is copied verbatim
from ``kuka_iiwa/model.urdf`` (pybullet_data's model, BSD licence kept in that file); the
hand is built here from primitives with the Schunk SDH's published proportions:

* palm: a cylinder of radius 48 mm and height 85 mm on the flange (the SDH base unit);
* three fingers whose bases sit on a circle of radius 38 mm on the palm face (an
  equilateral triangle, 66 mm between bases); finger 3 (the thumb) is fixed, fingers 1 and 2
  turn about axes parallel to the palm normal in a *coupled* spread (finger 2 mimics
  finger 1 with multiplier -1), from 0 (fingers 1 and 2 parallel, opposing the thumb) to
  90 degrees; spread = 60 degrees is the centrical three-finger grasp;
* each finger: knuckle (20 mm), proximal phalanx 86.5 mm, distal phalanx 68.5 mm, both
  capsules of radius 11 mm; flexion limits -90..+90 degrees; positive flexion closes the
  finger towards the palm axis;
* frames: ``palm`` (origin at the centre of the palm face, +z the approach direction) and
  ``f{1,2,3}_tip`` at the end of each distal phalanx.

The hand DOF vector (7) is: spread, f1_proximal, f1_distal, f2_proximal, f2_distal,
f3_proximal, f3_distal.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

HERE = Path(__file__).resolve().parent
ARM_URDF = HERE / "kuka_iiwa" / "model.urdf"
OUT_URDF = HERE / "kuka_sdh.urdf"
HAND_URDF = HERE / "sdh_hand.urdf"

FLANGE_OFFSET = 0.045  # link_7 frame to flange face, metres (mesh extent of link_7)
PALM_RADIUS = 0.048
PALM_HEIGHT = 0.085
FINGER_BASE_RADIUS = 0.038
KNUCKLE_HEIGHT = 0.020
PROXIMAL_LENGTH = 0.0865
DISTAL_LENGTH = 0.0685
PHALANX_RADIUS = 0.011
FLEX_LIMIT = math.pi / 2
SPREAD_LIMIT = (0.0, math.pi / 2)


def _fmt(values) -> str:
    return " ".join(f"{v:.10g}" for v in values)


def _inertial(link: ET.Element, mass: float, com=(0.0, 0.0, 0.0), inertia: float = 1e-5) -> None:
    inertial = ET.SubElement(link, "inertial")
    ET.SubElement(inertial, "origin", rpy="0 0 0", xyz=_fmt(com))
    ET.SubElement(inertial, "mass", value=f"{mass:g}")
    ET.SubElement(
        inertial, "inertia", ixx=f"{inertia:g}", ixy="0", ixz="0", iyy=f"{inertia:g}", iyz="0",
        izz=f"{inertia:g}",
    )


def _shape(link: ET.Element, kind: str, origin_xyz, material: str, **geometry) -> None:
    for tag in ("visual", "collision"):
        element = ET.SubElement(link, tag)
        ET.SubElement(element, "origin", rpy="0 0 0", xyz=_fmt(origin_xyz))
        geom = ET.SubElement(element, "geometry")
        ET.SubElement(geom, kind, **{k: f"{v:.10g}" for k, v in geometry.items()})
        if tag == "visual":
            ET.SubElement(element, "material", name=material)


def _link(robot: ET.Element, name: str) -> ET.Element:
    return ET.SubElement(robot, "link", name=name)


def _joint(robot: ET.Element, name: str, kind: str, parent: str, child: str, xyz, rpy=(0, 0, 0),
           axis=None, limits=None, mimic=None) -> ET.Element:
    joint = ET.SubElement(robot, "joint", name=name, type=kind)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    ET.SubElement(joint, "origin", rpy=_fmt(rpy), xyz=_fmt(xyz))
    if axis is not None:
        ET.SubElement(joint, "axis", xyz=_fmt(axis))
    if limits is not None:
        ET.SubElement(joint, "limit", effort="10", lower=f"{limits[0]:.10g}",
                      upper=f"{limits[1]:.10g}", velocity="1")
    if mimic is not None:
        ET.SubElement(joint, "mimic", joint=mimic[0], multiplier=f"{mimic[1]:g}", offset="0")
    return joint


def add_hand(robot: ET.Element, flange_link: str) -> None:
    """Append the SDH-like hand to ``robot`` under ``flange_link`` (the flange frame)."""
    for name, rgba in (("HandGrey", "0.55 0.57 0.6 1"), ("FingerBlue", "0.2 0.35 0.75 1")):
        material = ET.SubElement(robot, "material", name=name)
        ET.SubElement(material, "color", rgba=rgba)

    base = _link(robot, "sdh_base")
    _inertial(base, 1.9, com=(0, 0, PALM_HEIGHT / 2), inertia=2e-3)
    _shape(base, "cylinder", (0, 0, PALM_HEIGHT / 2), "HandGrey", radius=PALM_RADIUS,
           length=PALM_HEIGHT)
    offset = FLANGE_OFFSET if flange_link != "hand_root" else 0.0
    _joint(robot, "flange_to_sdh", "fixed", flange_link, "sdh_base", (0, 0, offset))

    palm = _link(robot, "palm")
    _inertial(palm, 0.01)
    _joint(robot, "sdh_base_to_palm", "fixed", "sdh_base", "palm", (0, 0, PALM_HEIGHT))

    # (finger, angular position of its base on the palm, yaw of its closing direction at
    #  spread 0, spread joint or None, mimic multiplier)
    fingers = (
        (1, math.pi / 3, math.pi, True, None),
        (2, -math.pi / 3, math.pi, True, ("f1_spread", -1.0)),
        (3, math.pi, 0.0, False, None),
    )
    for index, position_angle, closing_yaw, spreads, mimic in fingers:
        f = f"f{index}"
        base_xyz = (FINGER_BASE_RADIUS * math.cos(position_angle),
                    FINGER_BASE_RADIUS * math.sin(position_angle), 0.0)
        knuckle = _link(robot, f"{f}_knuckle")
        _inertial(knuckle, 0.05)
        _shape(knuckle, "cylinder", (0, 0, KNUCKLE_HEIGHT / 2), "HandGrey", radius=0.014,
               length=KNUCKLE_HEIGHT)
        if spreads:
            lower, upper = SPREAD_LIMIT if mimic is None else (-SPREAD_LIMIT[1], -SPREAD_LIMIT[0])
            _joint(robot, f"{f}_spread", "revolute", "palm", f"{f}_knuckle", base_xyz,
                   rpy=(0, 0, closing_yaw), axis=(0, 0, 1), limits=(lower, upper), mimic=mimic)
        else:
            _joint(robot, f"{f}_base", "fixed", "palm", f"{f}_knuckle", base_xyz,
                   rpy=(0, 0, closing_yaw))

        for phalanx, parent, offset, length in (
            ("proximal", f"{f}_knuckle", KNUCKLE_HEIGHT, PROXIMAL_LENGTH),
            ("distal", f"{f}_proximal", PROXIMAL_LENGTH, DISTAL_LENGTH),
        ):
            link = _link(robot, f"{f}_{phalanx}")
            _inertial(link, 0.1, com=(0, 0, length / 2))
            _shape(link, "capsule", (0, 0, length / 2), "FingerBlue", radius=PHALANX_RADIUS,
                   length=length)
            _joint(robot, f"{f}_{phalanx}", "revolute", parent, f"{f}_{phalanx}", (0, 0, offset),
                   axis=(0, 1, 0), limits=(-FLEX_LIMIT, FLEX_LIMIT))

        tip = _link(robot, f"{f}_tip")
        _inertial(tip, 0.001)
        _joint(robot, f"{f}_distal_to_tip", "fixed", f"{f}_distal", f"{f}_tip",
               (0, 0, DISTAL_LENGTH))


HEADER = ('<?xml version="1.0" ?>\n'
          "<!-- Generated by build_kuka_sdh.py: do not edit by hand. Arm: kuka_iiwa/model.urdf"
          " (BSD licence in that file). -->\n")


def build_hand(out: Path = HAND_URDF) -> Path:
    """Write the hand alone; its root link ``hand_root`` is the flange frame (inertial origin
    at the frame origin, so pybullet's base pose equals the URDF frame pose)."""
    robot = ET.Element("robot", name="sdh_hand")
    root = _link(robot, "hand_root")
    _inertial(root, 0.01)
    add_hand(robot, "hand_root")
    tree = ET.ElementTree(robot)
    ET.indent(tree, space="  ")
    out.write_text(HEADER + ET.tostring(robot, encoding="unicode") + "\n")
    return out


def build(out: Path = OUT_URDF) -> Path:
    """Write the composed URDF and return its path."""
    tree = ET.parse(ARM_URDF)
    robot = tree.getroot()
    robot.set("name", "kuka_iiwa_sdh")
    for mesh in robot.iter("mesh"):
        mesh.set("filename", "kuka_iiwa/" + mesh.get("filename"))
    add_hand(robot, "lbr_iiwa_link_7")
    ET.indent(tree, space="  ")
    out.write_text(HEADER + ET.tostring(robot, encoding="unicode") + "\n")
    return out


if __name__ == "__main__":
    print(build())
    print(build_hand())
