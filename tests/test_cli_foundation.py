"""`kinegrasp planar`, `kuka-ee` and `convergence` from the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_helpers import run_cli

from kinegrasp_env.cli import main
from kinegrasp_env.robot.planar import PlanarArm
from kinegrasp_env.sampling.noise import JointNoise


def test_planar_json_as_specified():
    proc = run_cli("planar", "--links", "2,2", "--q0", "0.0,1.5708", "--sigma", "0.0175",
                   "--samples", "10000", "--seed", "0", "--json")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert {"mean", "cov", "skew", "samples"} <= set(out)
    assert out["samples"] == 10000
    assert np.shape(out["mean"]) == (2,) and np.shape(out["cov"]) == (2, 2)
    assert np.shape(out["skew"]) == (2,)
    mean, cov = PlanarArm((2.0, 2.0)).exact_moments(np.array([0.0, 1.5708]),
                                                    JointNoise(0.0175))
    np.testing.assert_allclose(out["mean"], mean, atol=4 * np.sqrt(cov.diagonal().max() / 1e4))
    np.testing.assert_allclose(out["cov"], cov, rtol=0.1, atol=1e-5)
    again = run_cli("planar", "--links", "2,2", "--q0", "0.0,1.5708", "--sigma", "0.0175",
                    "--samples", "10000", "--seed", "0", "--json")
    assert again.stdout == proc.stdout


@pytest.mark.parametrize(("args", "needle"), [
    (["--sigma", "-1"], "--sigma must be >= 0, got -1"),
    (["--links", "2,2,2", "--q0", "0,1"], "--links has 3 lengths but --q0 has 2 angles"),
    (["--q0", "nan,1"], "'nan' is not a finite number"),
    (["--q0", "0,1x"], "--q0: '1x' is not a number"),
    (["--samples", "0"], "--samples must be >= 1, got 0"),
    (["--links", "2,-1"], "link lengths must be > 0"),
])
def test_planar_bad_input_one_line(args, needle):
    proc = run_cli("planar", *args)
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr


def test_planar_plot(tmp_path, capsys):
    out = tmp_path / "arm.png"
    assert main(["planar", "--samples", "500", "--plot", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_negative_angles_need_no_equals_sign(capsys):
    assert main(["planar", "--q0", "-0.5,1.0", "--samples", "100", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["samples"] == 100


def test_kuka_ee_json_and_errors(capsys):
    assert main(["kuka-ee", "--q0", "0,0.6,0,-1.2,0,0.8,0", "--sigma", "0.0133",
                 "--samples", "20000", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert np.shape(out["cov"]) == (3, 3) and out["samples"] == 20000
    # propagated covariance J Sigma J^T is a first-order check of the sampled one
    from kinegrasp_env.robot.endeffector import _kuka

    kin, arm = _kuka()
    q = np.zeros(kin.model.dof)
    q[arm] = [0, 0.6, 0, -1.2, 0, 0.8, 0]
    jac = kin.jacobian(q, "palm")[0, :3][:, arm]
    linear = 0.0133**2 * jac @ jac.T
    # sampling error of a covariance entry ~ sqrt(var_i var_j / n); linearization error small
    se = np.sqrt(np.outer(linear.diagonal(), linear.diagonal()) / 20000)
    assert np.all(np.abs(np.asarray(out["cov"]) - linear) < 5 * se + 0.02 * np.abs(linear))
    assert main(["kuka-ee", "--q0", "0,1,2"]) == 2
    assert "needs 7 joint angles, got 3" in capsys.readouterr().err


def test_convergence_figure(tmp_path, capsys):
    out = tmp_path / "conv.png"
    assert main(["convergence", "--out", str(out), "--trials", "2", "--truth-samples", "2000",
                 "--max-samples", "200", "--json"]) == 0
    curves = json.loads(capsys.readouterr().out)
    assert set(curves) == {"2-link planar arm", "KUKA iiwa"}
    assert set(curves["KUKA iiwa"]) == {"0.0033", "0.0133", "0.0233", "0.0333"}
    assert out.exists()
