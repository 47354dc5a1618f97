"""docs/paper_values.yaml holds the paper's own numbers with their sources, and
scripts/paper_side_by_side.py sets them beside this project's CSVs cell by cell."""

from __future__ import annotations

import csv
import importlib.util
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
VALUES = ROOT / "docs" / "paper_values.yaml"


def _script():
    spec = importlib.util.spec_from_file_location("paper_side_by_side",
                                                  ROOT / "scripts" / "paper_side_by_side.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _csv(folder: Path, name: str, rows: list[dict]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / name, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return folder


def test_values_are_the_papers_own_with_their_sources():
    """Table I's 60 values (5 grasps x 4 sigmas x Q mean, Q variance, P(FC)) and Fig. 7's,
    each block naming a source that is listed; no second-hand source is left."""
    values = yaml.safe_load(VALUES.read_text())
    sources = values["sources"]
    table = values["table1"]
    assert table["source"] in sources and "Table I" in table["source"]
    cells = table["cells"]
    assert sorted(cells) == [1, 2, 3, 4, 5]
    assert all(sorted(per) == sorted(table["sigmas"]) for per in cells.values())
    numbers = [v for per in cells.values() for triple in per.values() for v in triple]
    assert len(numbers) == 60 and all(isinstance(v, float) for v in numbers)
    assert all(0.0 <= triple[2] <= 1.0 for per in cells.values() for triple in per.values())
    # spot checks against the paper's Table I
    assert cells[1][0.0033] == [0.026383, 0.000683, 0.5275]
    assert cells[5][0.0333] == [0.087669, 0.002671, 0.3422]
    fig7 = values["fig7"]
    assert fig7["source"] in sources and "Fig. 7" in fig7["source"]
    assert fig7["objects"]["drill"]["robust_p_fc"] == 0.50
    assert fig7["objects"]["spray_flask"]["fragile_p_fc"] == 0.42
    assert "review" not in sources


def test_table1_sets_the_papers_cells_beside_the_runs(tmp_path):
    """Each row: the paper's grasp k beside grasp k-1 here, its Q mean, Q variance and P(FC)
    as printed; the physics column and the per-level summary come from the runs given."""
    side = _script()
    row = {"grasp": "0", "sigma": "0.0033", "q_nominal": "0.0067", "q_mean": "0.0076",
           "q_var": "1.5e-06", "p_fc": "0.999", "p_fc_lo": "0.998", "p_fc_hi": "0.9993",
           "samples": "10000", "q_skew": "-0.9"}
    main = _csv(tmp_path / "t1", "table1.csv", [row])
    phys = _csv(tmp_path / "phys", "table1.csv", [{**row, "p_fc": "0.95", "samples": "100"}])
    same = _csv(tmp_path / "same", "table1.csv", [{**row, "p_fc": "0.97", "samples": "100"}])
    text = side.side_by_side(main, None, None, physics=phys, physics_kinematic=same)
    assert ("| 1 / 0 | 0.0033 | 0.026383 | 0.0076 | 0.000683 | 1.5e-06 | 0.5275 | "
            "0.999 [0.998, 0.999] | 0.950 / 0.970 |") in text
    assert "| 0.0033 | 0.554 (0.476-0.654) | 0.999 (0.999-0.999) | 0.950" in text
    assert "[review]" not in text and "not available here" not in text


def test_pairs_show_fig7s_values_and_what_it_does_not_give(tmp_path):
    side = _script()
    base = {"robot": "kuka_sdh", "object": "drill", "ik_branch": "", "p_fc": "0.9",
            "q_mean": "0.015", "q_std": "0.007", "q_nominal": "0.014", "error": "0.001",
            "samples": "2000", "sigma": "0.0133", "fresh_p_fc_lo": "0.8",
            "fresh_p_fc_hi": "0.9", "fresh_samples": "2000", "selection_p_fc": "0.9",
            "gap": "0.05", "gap_lo": "0.04", "gap_hi": "0.07", "fresh_q_mean": "0.016",
            "fresh_q_var": "5e-05", "fresh_q_skew": "0.2"}
    rows = [{**base, "config": "robust", "id": "0v8", "elbow_angle": "1.5", "fresh_p_fc": "0.9"},
            {**base, "config": "fragile", "id": "0v1", "elbow_angle": "-0.25",
             "fresh_p_fc": "0.85"}]
    fig7 = _csv(tmp_path / "fig7", "fig7.csv", rows)
    text = side.side_by_side(None, fig7, None, only=("pairs",), paper_rows_only=True)
    assert ("| drill | robust P(FC) | 0.50 | 0.900 [0.800, 0.900] (id 0v8, elbow +1.50 rad) |"
            in text)
    assert "(id 0v1, elbow -0.25 rad)" in text
    assert "| drill | robust - fragile | +0.19 | +0.050 [+0.040, +0.070] |" in text
    assert "| drill | Q mean | 0.0982 / 0.0910 (as listed) | 0.016 / 0.016 |" in text
    assert "| drill | sigma (rad), fresh draws per configuration | not given, 10000 |" in text
    assert "Q skewness" not in text  # the paper gives none: left out of the paper rows
