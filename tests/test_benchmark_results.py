"""The benchmark scripts' result files (benchmarks/results_file.py): strict JSON (numpy values
as plain numbers, NaN and infinities as null), the default path beside the scripts, the
script's options and the machine facts recorded."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture()
def results_file(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import results_file

    yield results_file
    sys.modules.pop("results_file", None)


def test_a_result_is_strict_json_with_its_settings_and_machine(results_file, tmp_path,
                                                              capsys):
    parser = argparse.ArgumentParser()
    parser.add_argument("--draws", type=int, default=10)
    results_file.add_options(parser, BENCHMARKS / "bench_fk.py")
    args = parser.parse_args(["--draws", "7"])
    assert Path(args.json_out) == BENCHMARKS / "results" / "bench_fk.json"
    record = {"rate": np.float64(1.5), "count": np.int64(3), "bad": float("nan"),
              "inf": np.inf, "rows": [{"x": np.arange(2)}], "settings": results_file.settings(args)}
    out = results_file.write_result(BENCHMARKS / "bench_fk.py", record, tmp_path / "r.json")
    text = out.read_text()
    data = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict JSON {c}"))
    assert data["script"] == "bench_fk.py" and data["rate"] == 1.5 and data["count"] == 3
    assert data["bad"] is None and data["inf"] is None and data["rows"] == [{"x": [0, 1]}]
    assert data["settings"] == {"draws": 7}
    assert data["machine"]["cpu_count"] >= 1 and len(data["machine"]["load_before"]) == 3
    assert f"wrote {out}" in capsys.readouterr().err
