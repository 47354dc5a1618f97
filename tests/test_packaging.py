"""The wheel ships the assets, and the installed package finds and loads them."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.expensive
def test_wheel_ships_assets_and_loads_urdf(tmp_path):
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                    "-q", "-w", str(wheels), str(ROOT)], check=True)
    (wheel,) = wheels.glob("kinegrasp_env-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "kinegrasp_env/assets/robots/kuka_sdh.urdf" in names
    assert "kinegrasp_env/assets/robots/kuka_iiwa/meshes/link_7.stl" in names
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target",
                    str(target), str(wheel)], check=True)
    script = (
        "import pybullet, kinegrasp_env.assets as a, kinegrasp_env.robot.default_robot as r\n"
        "from pybullet_utils.bullet_client import BulletClient\n"
        "assert str(a.assets_dir()).startswith(%r), a.assets_dir()\n"
        "c = BulletClient(pybullet.DIRECT)\n"
        "b = c.loadURDF(str(r.urdf_path()), useFixedBase=True)\n"
        "print(c.getNumJoints(b), r.kuka_sdh().dof)\n"
    ).replace("%r", repr(str(target)))
    env = {**os.environ, "PYTHONPATH": str(target)}
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         env=env, cwd=tmp_path, check=True)
    assert out.stdout.split()[-2:] == ["21", "14"]  # pybullet may print "argv[0]=" first


def test_assets_found_from_source_tree():
    from kinegrasp_env.assets import asset_path

    assert asset_path("robots", "kuka_sdh.urdf").is_file()
    with pytest.raises(FileNotFoundError, match=r"asset not found: robots/nope\.urdf"):
        asset_path("robots", "nope.urdf")


def test_composed_urdf_is_up_to_date(tmp_path):
    """The committed URDF is what the generator script writes."""
    sys.path.insert(0, str(ROOT / "assets" / "robots"))
    try:
        import build_kuka_sdh
    finally:
        sys.path.pop(0)
    out = build_kuka_sdh.build(tmp_path / "k.urdf")
    assert out.read_text() == (ROOT / "assets" / "robots" / "kuka_sdh.urdf").read_text()
    hand = build_kuka_sdh.build_hand(tmp_path / "h.urdf")
    assert hand.read_text() == (ROOT / "assets" / "robots" / "sdh_hand.urdf").read_text()
