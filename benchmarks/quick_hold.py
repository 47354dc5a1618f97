"""The quick holding test against the full one, draw by draw on the same draws: agreement of
the held / not-held verdict (Wilson 95% interval) and CPU seconds per draw.

The quick test (``kinegrasp_env.physics.protocol.QUICK_PROTOCOL`` and the closing's end
``QUICK_MOTORS``) was tuned on other draws (seed 1, joint noise 0 to
0.0066 rad, panda's shipped grasps); these draws (``--seed``, default 100) were not used to
choose it.

* **panda** in pybullet: its shipped grasps of ``--objects``, ``--samples`` draws each at
  every joint noise of ``--sigmas`` (near 0 most hold, at 0.0133 rad most drop);
* **kuka_sdh** in pybullet and in MuJoCo: its first ``--kuka-grasps`` shipped grasps of each
  object, ``--samples`` draws each at ``--sigmas``.

CPU time is this process's (``time.process_time``), so another process on the machine
changes it little; the ratio full / quick is the speed-up per draw. Written as JSON
(``benchmarks/results/quick_hold.json``, rendered on the benchmarks page).

    python benchmarks/quick_hold.py [--objects cube drill] [--samples 3] [--seed 100]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from results_file import add_options, settings, write_result

from kinegrasp_env.montecarlo.hold_engine import RobotHoldEngine
from kinegrasp_env.physics.protocol import HELD, QUICK_PROTOCOL, HoldProtocol
from kinegrasp_env.physics.robot_hold import QUICK_MOTORS
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.world.grasps import shipped_grasps, shipped_objects

FULL = HoldProtocol()


def configurations(grasps, sigmas, samples: int, seed: int) -> np.ndarray:
    """(n, dof) the grasps' q0 with ``samples`` joint-noise draws per sigma (arm joints)."""
    rng = np.random.default_rng(seed)
    rows = []
    for g in grasps:
        for sigma in sigmas:
            q = np.repeat(np.asarray(g.q0, dtype=float)[None], samples, axis=0)
            q[:, :7] += JointNoise(sigma).sample(samples, 7, rng) if sigma > 0 else 0.0
            rows.append(q)
    return np.concatenate(rows)


def timed(run, q: np.ndarray) -> tuple[np.ndarray, float]:
    """(held (n,), CPU seconds) of one holding test over q."""
    start = time.process_time()
    hold = run(q)
    return hold.outcome == HELD, time.process_time() - start


def compare(full: np.ndarray, quick: np.ndarray, full_time: float, quick_time: float) -> dict:
    agree = int((full == quick).sum())
    n = int(full.size)
    return {"draws": n, "held_full": int(full.sum()), "held_quick": int(quick.sum()),
            "agree": agree, "agree_share": agree / n, "agree_ci95": list(wilson_interval(agree, n)),
            "full_s_per_draw": full_time / n, "quick_s_per_draw": quick_time / n,
            "speedup": full_time / quick_time}


def both_tests(make, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(held full, held quick, CPU s full, CPU s quick) of q through the engines
    ``make(protocol, quick)`` builds (each closed after its run)."""
    out = []
    for protocol, quick in ((FULL, False), (QUICK_PROTOCOL, True)):
        engine = make(protocol, quick)
        try:
            out.append(timed(lambda x, e=engine: e.run_hold(x)[1], q))
        finally:
            engine.close()
    (full, t_full), (quick, t_quick) = out
    return full, quick, t_full, t_quick


def gather(parts: list[tuple[np.ndarray, np.ndarray, float, float]]) -> dict:
    return compare(np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
                   sum(p[2] for p in parts), sum(p[3] for p in parts))


def panda(args) -> dict:
    parts = []
    for obj in (o for o in args.objects if o in shipped_objects("panda")):
        q = configurations(shipped_grasps(obj, robot="panda"), args.sigmas, args.samples,
                           args.seed)
        parts.append(both_tests(lambda protocol, quick, o=obj: RobotHoldEngine(
            "panda", o, protocol=protocol, motors=QUICK_MOTORS if quick else None), q))
        print(f"  panda {obj}: {q.shape[0]} draws", file=sys.stderr)
    return gather(parts)


def kuka(args, simulator: str) -> dict:
    parts = []
    for obj in args.objects:
        q = configurations(shipped_grasps(obj)[:args.kuka_grasps], args.sigmas, args.samples,
                           args.seed)
        parts.append(both_tests(lambda protocol, quick, o=obj: RobotHoldEngine(
            "kuka_sdh", o, protocol=protocol, motors=QUICK_MOTORS if quick else None,
            simulator=simulator), q))
        print(f"  kuka_sdh {simulator} {obj}: {q.shape[0]} draws", file=sys.stderr)
    return gather(parts)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=["cube", "spray_flask", "drill", "mug"])
    parser.add_argument("--sigmas", type=float, nargs="+", default=[0.001, 0.0033, 0.0133])
    parser.add_argument("--samples", type=int, default=3)
    parser.add_argument("--kuka-grasps", type=int, default=4)
    parser.add_argument("--seed", type=int, default=100)
    add_options(parser, __file__)
    args = parser.parse_args()
    result = {"panda pybullet": panda(args)}
    for simulator in ("pybullet", "mujoco"):
        result[f"kuka_sdh {simulator}"] = kuka(args, simulator)
    for name, record in result.items():
        lo, hi = record["agree_ci95"]
        print(f"{name:18s} {record['agree']}/{record['draws']} agree [{lo:.2f}, {hi:.2f}], "
              f"held {record['held_full']} / {record['held_quick']}, "
              f"{record['full_s_per_draw']:.3f} -> {record['quick_s_per_draw']:.3f} s/draw "
              f"({record['speedup']:.1f}x)")
    if not args.no_json:
        write_result(__file__, {**result, "settings": settings(args)}, args.json_out)


if __name__ == "__main__":
    main()
