"""``reproduce table1|fig7|fig9 --robot NAME``: the paper's protocols on another robot's grasps.

What each test proves: every cell of Table I and every row of Fig. 9 is ``evaluate --robot``
of that grasp, sigma and seed (the same draws, so equal to the last printed digit): the
experiment evaluates what it says and labels it right; Fig. 7's pair is a robust and a
fragile configuration reported on the same fresh draws, its gap their paired difference, and
its picture is written.
"""

from __future__ import annotations

import csv
import json

import pytest

from kinegrasp_env.cli import main
from kinegrasp_env.world.grasps import shipped_grasps

SAMPLES = "60"


def _evaluate(capsys, grasp: int, sigma: float, obj: str = "cube") -> dict:
    assert main(["evaluate", "--robot", "panda", "--object", obj, "--grasp", str(grasp),
                 "--sigma", f"{sigma:g}", "--samples", SAMPLES, "--engine", "fast",
                 "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_table1_and_fig9_of_a_robot_are_its_evaluations(tmp_path, capsys):
    assert main(["reproduce", "table1", "--robot", "panda", "--object", "cube", "--grasps",
                 "2", "--samples", SAMPLES, "--out", str(tmp_path / "t")]) == 0
    capsys.readouterr()
    rows = list(csv.DictReader((tmp_path / "t" / "table1.csv").open()))
    assert len(rows) == 8 and {r["robot"] for r in rows} == {"panda"}
    assert (tmp_path / "t" / "table1.md").read_text().startswith("Table I, cube (robot panda)")
    for row in rows[::3]:
        shown = _evaluate(capsys, int(row["grasp"]), float(row["sigma"]))
        assert float(row["p_fc"]) == pytest.approx(shown["p_fc"], abs=1e-12)
        assert float(row["q_nominal"]) == pytest.approx(shown["q_nominal"], rel=1e-9)
    assert main(["reproduce", "fig9", "--robot", "panda", "--object", "cube", "--grasps", "2",
                 "--samples", SAMPLES, "--out", str(tmp_path / "f")]) == 0
    capsys.readouterr()
    rows = list(csv.DictReader((tmp_path / "f" / "fig9.csv").open()))
    ids = [g.id for g in shipped_grasps("cube", "panda")[:2]]
    assert [r["id"] for r in rows] == ids
    for index, row in enumerate(rows):
        shown = _evaluate(capsys, index, 0.0033)
        assert float(row["p_fc"]) == pytest.approx(shown["p_fc"], abs=1e-12)
    assert (tmp_path / "f" / "fig9.png").read_bytes()[:4] == b"\x89PNG"


def test_fig7_of_a_robot_reports_its_pair_on_fresh_draws(tmp_path, capsys):
    out = tmp_path / "f7"
    assert main(["reproduce", "fig7", "--robot", "panda", "--object", "cube", "--samples",
                 SAMPLES, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "robust - fragile" in text and "fig7_cube.png" in text
    rows = list(csv.DictReader((out / "fig7.csv").open()))
    assert [r["config"] for r in rows] == ["robust", "fragile"]
    robust, fragile = rows
    assert float(robust["selection_p_fc"]) >= float(fragile["selection_p_fc"])
    gap = float(robust["fresh_p_fc"]) - float(fragile["fresh_p_fc"])
    assert float(robust["gap"]) == pytest.approx(gap, abs=1e-9)
    assert float(robust["gap_lo"]) <= gap <= float(robust["gap_hi"])
    assert (out / "fig7_cube.png").read_bytes()[:4] == b"\x89PNG"
